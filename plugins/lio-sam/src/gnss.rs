//! GNSS in the mapping graph: LIO-SAM's GPS factor (`addGPSFactor` in `mapOptmization.cpp`,
//! TixiaoShan/LIO-SAM; Shan et al. 2020, §III-D "GPS factor") and the step the original
//! leaves to robot_localization's `navsat_transform_node`, turning fixes in the receiver's
//! east-north-up frame into the map frame.
//!
//! **Frames.** LIO-SAM's map frame starts at the robot's start; its GPS arrives as
//! odometry already in that frame (navsat_transform with the IMU's heading,
//! `module_navsat.launch`). Here the same step is done inside, once, as navsat_transform
//! does it (its `computeTransform`: the first good fix, the IMU's absolute yaw at that time,
//! the robot's pose in the world frame then, roll and pitch removed): with the fix's
//! antenna position `p_enu`, the IMU's reported orientation `enu_from_imu` and the
//! estimate `map_from_imu` at the fix's time (interpolated between registered sweeps),
//! `map_from_enu` is the rotation about the vertical by `yaw(map_from_imu) −
//! yaw(enu_from_imu)` and the translation that puts `p_enu` on the antenna's map position
//! `map_from_imu · imu_from_antenna`. Later fixes are carried into the map by it, their
//! covariance turned by its rotation (as navsat_transform's `prepareGpsOdometry`), and the
//! antenna's lever arm is removed with the keyframe's rotation (navsat_transform's
//! `getRobotOriginWorldPose`): the factor constrains the graph's body, the IMU.
//!
//! **Which fixes become factors** ([`Gnss::select`]), the original's rules in its order, at
//! each new keyframe (LIO-SAM calls `addGPSFactor` when it saves one):
//! 1. none when no fix is queued, or no keyframe yet;
//! 2. none until the first and the last keyframe are 5 m apart ("wait for system
//!    initialized and settles down");
//! 3. none while the last keyframe's marginal position variance is below
//!    `poseCovThreshold` in both x and y (`poseCovariance(3,3)`, `(4,4)`; here the world
//!    frame's x and y, [`PoseCovariance::translation_world`]);
//! 4. fixes stamped more than 0.2 s before the keyframe are dropped, a fix more than 0.2 s
//!    after it waits; of those within 0.2 s, in order: one whose x or y variance exceeds
//!    `gpsCovThreshold` is skipped (here with a `gnss_rejected` event); z is the
//!    keyframe's own unless `useGpsElevation` (then the fix's, with its variance), its
//!    variance 0.01 m² in the first case; a fix at (0, 0) is skipped ("GPS not properly
//!    initialized"); one within 5 m of the last fix used (the map origin before any) is
//!    skipped; the first left is the factor, with variances floored at 1 m² (`max(noise,
//!    1.0)`: σ ≥ 1 m on every axis, z included), and no more this keyframe.
//!
//! A GPS factor then makes the graph update like a loop closure (`aLoopIsClosed = true`:
//! a full update, and the keyframes' poses corrected). Fixes that cannot be used at all
//! (no fix, a position that is not finite, a covariance that is not positive definite:
//! [`plugin_api::Gnss::problem`]) are refused when they arrive, each with a
//! `gnss_rejected` event.
//!
//! [`PoseCovariance::translation_world`]:
//! slam_common::factor_graph::backend::PoseCovariance::translation_world

use std::collections::VecDeque;

use nalgebra::{Isometry3, Matrix3, Vector3};
use plugin_api::{Event, EventKind, Gnss as GnssMessage};
pub use slam_common::gnss::{Fix, Orientations, yaw};
use slam_common::gnss::{body_in_frame, frame_from_enu};

use crate::config::GpsConfig;
use crate::motion::interpolate;

/// A fix is used for the keyframe stamped within this of it (LIO-SAM's 0.2 s).
const TIME_WINDOW_NS: i64 = 200_000_000;
/// At most one GPS factor per this distance, and none before the keyframes span it, m.
const SPACING_M: f64 = 5.0;
/// The variance of z when the keyframe's own z is used (`noise_z = 0.01`), m².
const OWN_Z_VARIANCE_M2: f64 = 0.01;
/// Every variance is floored at this (`max(noise, 1.0f)`), m².
const VARIANCE_FLOOR_M2: f64 = 1.0;

/// A GPS factor for the new keyframe: the body's (IMU's) position in the map frame and
/// its sigmas, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsFactor {
    pub stamp_ns: i64,
    pub position: Vector3<f64>,
    pub sigmas: Vector3<f64>,
}

/// What [`Gnss::select`] needs of the graph.
#[derive(Debug, Clone, Copy)]
pub struct KeyframeState {
    /// The new keyframe's stamp and registered `map_from_imu`.
    pub stamp_ns: i64,
    pub map_from_imu: Isometry3<f64>,
    /// The first and the last keyframe's current positions (before the new one), if any.
    pub first_and_last: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The last keyframe's marginal position covariance in the map frame, m².
    pub last_covariance: Option<Matrix3<f64>>,
}

/// A fix as the plugin uses it, or `None` with a `gnss_rejected` event saying why not (no
/// fix, a position that is not finite, a covariance that is not positive definite).
pub fn usable(gnss: &GnssMessage, events: &mut Vec<Event>) -> Option<Fix> {
    match gnss.usable() {
        Ok((position_enu_m, covariance_enu_m2)) => Some(Fix {
            stamp_ns: gnss.stamp_ns,
            position_enu_m,
            covariance_enu_m2,
        }),
        Err(problem) => {
            events.push(gnss.rejected("lio-sam", problem));
            None
        }
    }
}

/// The GNSS side of the mapping: the queue of fixes, the alignment, and LIO-SAM's
/// selection.
#[derive(Debug, Clone)]
pub struct Gnss {
    cfg: GpsConfig,
    imu_from_antenna: Vector3<f64>,
    queue: VecDeque<Fix>,
    map_from_enu: Option<Isometry3<f64>>,
    /// LIO-SAM's `static PointType lastGPSPoint`, zero at the start.
    last_point: Vector3<f64>,
    /// GPS factors added.
    pub factors: usize,
}

impl Gnss {
    /// `imu_from_antenna`: the antenna's position in the IMU frame (the rig's `gnss` mount
    /// carried into the IMU's).
    pub fn new(cfg: GpsConfig, imu_from_antenna: Vector3<f64>) -> Self {
        Self {
            cfg,
            imu_from_antenna,
            queue: VecDeque::new(),
            map_from_enu: None,
            last_point: Vector3::zeros(),
            factors: 0,
        }
    }

    pub fn map_from_enu(&self) -> Option<Isometry3<f64>> {
        self.map_from_enu
    }

    /// Queues a fix, or refuses one that cannot be used with a `gnss_rejected` event.
    pub fn push(&mut self, gnss: &GnssMessage, events: &mut Vec<Event>) {
        if let Some(fix) = usable(gnss, events) {
            // Fixes arrive in the order of their availability; keep the queue in stamp
            // order all the same (the original's is in arrival order).
            let at = self.queue.partition_point(|f| f.stamp_ns <= fix.stamp_ns);
            self.queue.insert(at, fix);
        }
    }

    /// Until the transform is known: the first queued fix stamped within the span of
    /// `track` (`map_from_imu` of the last registered sweeps, in time order) gives it, with
    /// the pose interpolated at the fix's time and the IMU's orientation nearest it. True
    /// when the transform was found now.
    pub fn align(&mut self, track: &[(i64, Isometry3<f64>)], orientations: &Orientations) -> bool {
        if self.map_from_enu.is_some() {
            return false;
        }
        let (Some(first), Some(last)) = (track.first(), track.last()) else {
            return false;
        };
        for fix in &self.queue {
            if fix.stamp_ns < first.0 {
                continue;
            }
            if fix.stamp_ns > last.0 {
                break;
            }
            let Some(enu_from_imu) = orientations.at(fix.stamp_ns) else {
                continue;
            };
            let map_from_imu = match track.len() {
                1 => track[0].1,
                n => {
                    let i = track
                        .partition_point(|(t, _)| *t <= fix.stamp_ns)
                        .clamp(1, n - 1);
                    let ((t0, a), (t1, b)) = (track[i - 1], track[i]);
                    let u = (fix.stamp_ns - t0) as f64 / (t1 - t0).max(1) as f64;
                    interpolate(&a, &b, u)
                }
            };
            self.map_from_enu = Some(frame_from_enu(
                &map_from_imu.translation.vector,
                yaw(&map_from_imu.rotation),
                &enu_from_imu,
                &self.imu_from_antenna,
                &fix.position_enu_m,
            ));
            return true;
        }
        false
    }

    /// LIO-SAM's `addGPSFactor` at a new keyframe (the rules are in this module's
    /// documentation): the factor to add, if any; fixes skipped for their covariance are
    /// reported as `gnss_rejected` events.
    pub fn select(&mut self, kf: &KeyframeState, events: &mut Vec<Event>) -> Option<GpsFactor> {
        // Fixes the original would pop at its next walk are never used by a later
        // keyframe: drop them now, so that the queue stays short while rules 1-3 hold.
        let oldest = kf.stamp_ns - TIME_WINDOW_NS;
        while self.queue.front().is_some_and(|f| f.stamp_ns < oldest) {
            self.queue.pop_front();
        }
        if self.queue.is_empty() {
            return None;
        }
        let (first, last) = kf.first_and_last?;
        if (first - last).norm() < SPACING_M {
            return None;
        }
        let cov = kf.last_covariance?;
        let threshold = self.cfg.pose_cov_threshold_m2;
        if cov[(0, 0)] < threshold && cov[(1, 1)] < threshold {
            return None;
        }
        while let Some(fix) = self.queue.front().copied() {
            if fix.stamp_ns > kf.stamp_ns + TIME_WINDOW_NS {
                break;
            }
            self.queue.pop_front();
            // Before the transform is known the fix has no place in the map (the
            // original's navsat_transform publishes nothing before it either).
            let Some(map_from_enu) = self.map_from_enu else {
                continue;
            };
            let (mut position, covariance) = body_in_frame(
                &map_from_enu,
                &fix,
                &kf.map_from_imu.rotation,
                &self.imu_from_antenna,
            );
            let (noise_x, noise_y) = (covariance[(0, 0)], covariance[(1, 1)]);
            let gate = self.cfg.gps_cov_threshold_m2;
            if noise_x > gate || noise_y > gate {
                events.push(Event::new(
                    fix.stamp_ns,
                    EventKind::GnssRejected,
                    format!(
                        "lio-sam: GNSS fix with x, y variances {noise_x:.3}, {noise_y:.3} m² \
                         above gpsCovThreshold {gate} m²"
                    ),
                ));
                continue;
            }
            let mut noise_z = covariance[(2, 2)];
            if !self.cfg.use_gps_elevation {
                position.z = kf.map_from_imu.translation.z;
                noise_z = OWN_Z_VARIANCE_M2;
            }
            if position.x.abs() < 1e-6 && position.y.abs() < 1e-6 {
                continue;
            }
            if (position - self.last_point).norm() < SPACING_M {
                continue;
            }
            self.last_point = position;
            let sigmas =
                Vector3::new(noise_x, noise_y, noise_z).map(|v| v.max(VARIANCE_FLOOR_M2).sqrt());
            self.factors += 1;
            return Some(GpsFactor {
                stamp_ns: fix.stamp_ns,
                position,
                sigmas,
            });
        }
        None
    }

    /// Fixes waiting.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};
    use plugin_api::{EventKind, Gnss as GnssMessage, GnssStatus};
    use slam_common::factor_graph::backend::{BackendConfig, ImuBias};

    use super::*;
    use crate::config::GpsConfig;
    use crate::graph::KeyframeGraph;

    const S: i64 = 1_000_000_000;

    fn iso(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    fn message(stamp_ns: i64, enu: [f64; 3], variance: f64) -> GnssMessage {
        let c = Matrix3::from_diagonal_element(variance);
        GnssMessage {
            stamp_ns,
            status: GnssStatus::Fixed,
            satellites: 14,
            position_enu_m: enu,
            covariance_enu_m2: c.transpose().as_slice().try_into().expect("9"),
            latitude_deg: 52.0,
            longitude_deg: 5.0,
            altitude_m: 40.0,
            hdop: 0.8,
        }
    }

    /// A receiver whose fixes' frame is the map's (aligned on a fix at the origin with
    /// the IMU at the origin, heading 0), with `lever` the antenna in the IMU frame.
    fn aligned(cfg: GpsConfig, lever: Vector3<f64>) -> Gnss {
        let mut g = Gnss::new(cfg, lever);
        let mut events = Vec::new();
        g.push(&message(0, [lever.x, lever.y, lever.z], 1e-4), &mut events);
        let mut o = Orientations::default();
        o.push(0, UnitQuaternion::identity());
        assert!(g.align(&[(0, Isometry3::identity())], &o));
        let t = g.map_from_enu().expect("aligned");
        assert!(t.translation.vector.norm() < 1e-12 && t.rotation.angle() < 1e-12);
        assert!(events.is_empty());
        g
    }

    fn keyframe(stamp_ns: i64, map_from_imu: Isometry3<f64>, cov: f64) -> KeyframeState {
        KeyframeState {
            stamp_ns,
            map_from_imu,
            first_and_last: Some((Vector3::zeros(), Vector3::new(20.0, 0.0, 0.0))),
            last_covariance: Some(Matrix3::from_diagonal_element(cov)),
        }
    }

    #[test]
    fn the_alignment_recovers_a_known_map_from_enu_through_a_tilted_imu() {
        // Guards navsat_transform's step: yaw from the IMU against the estimate's yaw (the
        // tilt must not leak into it), translation through the lever arm.
        let truth = iso(12.0, -7.0, 3.0, 0.0, 0.0, 0.7);
        let map_from_imu = iso(4.0, 2.0, 0.4, 0.08, -0.05, 2.1);
        let enu_from_imu = truth.inverse() * map_from_imu;
        let lever = Vector3::new(-0.2, 0.1, 1.1);
        let antenna_enu = enu_from_imu * nalgebra::Point3::from(lever);
        let found = frame_from_enu(
            &map_from_imu.translation.vector,
            yaw(&map_from_imu.rotation),
            &enu_from_imu.rotation,
            &lever,
            &antenna_enu.coords,
        );
        assert!((found.translation.vector - truth.translation.vector).norm() < 1e-9);
        assert!((found.rotation.inverse() * truth.rotation).angle() < 1e-9);
    }

    #[test]
    fn the_alignment_interpolates_the_pose_at_the_fixs_time() {
        // Guards the time alignment: a fix between two registered sweeps uses the pose
        // interpolated at its stamp, not the nearest sweep's (0.5 m away here).
        let mut g = Gnss::new(GpsConfig::default(), Vector3::zeros());
        let mut events = Vec::new();
        g.push(&message(S / 20, [100.0, 50.0, 2.0], 1e-4), &mut events);
        let mut o = Orientations::default();
        o.push(S / 20, UnitQuaternion::identity());
        let track = [
            (0, iso(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
            (S / 10, iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
        ];
        assert!(g.align(&track, &o));
        let t = g.map_from_enu().expect("aligned");
        let fix_in_map = t * nalgebra::Point3::new(100.0, 50.0, 2.0);
        assert!((fix_in_map.coords - Vector3::new(0.5, 0.0, 0.0)).norm() < 1e-9);
        // Not again: the transform is computed once.
        assert!(!g.align(&track, &o));
    }

    #[test]
    fn unusable_fixes_are_refused_with_an_event_never_queued() {
        // Guards Gnss::problem's cases: no fix, a NaN position, a zero covariance.
        let mut g = Gnss::new(GpsConfig::default(), Vector3::zeros());
        let mut events = Vec::new();
        let mut no_fix = message(1, [f64::NAN; 3], 0.0);
        no_fix.status = GnssStatus::NoFix;
        g.push(&no_fix, &mut events);
        g.push(&message(2, [f64::NAN, 0.0, 0.0], 1.0), &mut events);
        g.push(&message(3, [1.0, 0.0, 0.0], 0.0), &mut events);
        assert_eq!(g.queued(), 0);
        assert_eq!(events.len(), 3);
        assert!(events.iter().all(|e| e.kind == EventKind::GnssRejected));
        assert!(events[0].detail.contains("no fix"), "{}", events[0].detail);
        g.push(&message(4, [1.0, 0.0, 0.0], 0.5), &mut events);
        assert_eq!((g.queued(), events.len()), (1, 3));
    }

    #[test]
    fn selection_follows_lio_sams_add_gps_factor_rules() {
        // Guards the rules of addGPSFactor in its order (gnss.rs's documentation).
        let mut g = aligned(GpsConfig::default(), Vector3::zeros());
        let mut events = Vec::new();
        let t = 100 * S;
        let pose = iso(10.0, 0.0, 0.7, 0.0, 0.0, 0.0);
        g.push(&message(t, [10.0, 0.2, 9.0], 1e-4), &mut events);
        // Keyframes less than 5 m apart: nothing, the fix stays.
        let mut near = keyframe(t, pose, 100.0);
        near.first_and_last = Some((Vector3::zeros(), Vector3::new(3.0, 0.0, 0.0)));
        assert_eq!(g.select(&near, &mut events), None);
        // The pose is known well enough (25 m² not reached in x nor y): nothing.
        assert_eq!(g.select(&keyframe(t, pose, 24.0), &mut events), None);
        assert_eq!(g.queued(), 1);
        // Otherwise the fix, z the keyframe's, every variance floored at 1 m².
        let f = g
            .select(&keyframe(t, pose, 30.0), &mut events)
            .expect("factor");
        assert_eq!(f.position, Vector3::new(10.0, 0.2, 0.7));
        assert_eq!(f.sigmas, Vector3::repeat(1.0));
        assert_eq!(g.factors, 1);
        // A fix too noisy (x variance 3 m² > 2 m²) is refused with an event; one within
        // 5 m of the last used is skipped; a fix 0.3 s early is dropped, one 0.3 s late
        // waits; then one 6 m on is taken.
        let t = 200 * S;
        g.push(
            &message(t - 3 * S / 10, [30.0, 0.0, 0.0], 1e-4),
            &mut events,
        );
        g.push(&message(t - S / 10, [20.0, 0.0, 0.0], 3.0), &mut events);
        g.push(&message(t, [13.0, 0.0, 0.0], 1e-4), &mut events);
        g.push(
            &message(t + 3 * S / 10, [40.0, 0.0, 0.0], 1e-4),
            &mut events,
        );
        assert_eq!(g.select(&keyframe(t, pose, 30.0), &mut events), None);
        assert_eq!(events.len(), 1);
        assert_eq!(events[0].kind, EventKind::GnssRejected);
        assert!(
            events[0].detail.contains("gpsCovThreshold"),
            "{}",
            events[0].detail
        );
        assert_eq!(g.queued(), 1, "the late fix waits");
        g.push(
            &message(t + 4 * S / 10, [16.5, 0.0, 0.0], 1e-4),
            &mut events,
        );
        let later = t + 4 * S / 10;
        let f = g
            .select(&keyframe(later, pose, 30.0), &mut events)
            .expect("factor");
        assert_eq!(f.position.x, 40.0, "the first in the window, 30 m on");
        assert_eq!(g.queued(), 1, "one factor per keyframe: the next fix waits");
    }

    #[test]
    fn elevation_and_the_lever_arm() {
        // Guards useGpsElevation (the fix's z, its variance floored at 1 m²) and the
        // lever arm removed with the keyframe's rotation: an antenna 1 m above the IMU,
        // the IMU rolled 90° (its z along the map's −y).
        let cfg = GpsConfig {
            use_gps_elevation: true,
            ..GpsConfig::default()
        };
        let lever = Vector3::new(0.0, 0.0, 1.0);
        let mut g = aligned(cfg, lever);
        let mut events = Vec::new();
        let mut fix = message(10 * S, [20.0, 5.0, 3.0], 1e-4);
        fix.covariance_enu_m2[8] = 4.0;
        g.push(&fix, &mut events);
        let rolled = iso(20.0, 6.0, 3.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0);
        let f = g
            .select(&keyframe(10 * S, rolled, 30.0), &mut events)
            .expect("factor");
        assert!(
            (f.position - Vector3::new(20.0, 6.0, 3.0)).norm() < 1e-9,
            "{}",
            f.position
        );
        assert!((f.sigmas - Vector3::new(1.0, 1.0, 2.0)).norm() < 1e-12);
    }

    #[test]
    fn gps_factors_follow_the_marginal_covariance_of_a_drifting_keyframe_chain() {
        // Guards the rules and the graph together: keyframes 1 m apart along a row whose
        // registration drifts in heading (3 mrad per keyframe), fixes of 2 cm at 10 Hz.
        // With LIO-SAM's loose first prior the first keyframes' marginal is far above
        // 25 m², so the first fix is taken as soon as the keyframes span 5 m (keyframe 6),
        // and more every 5 m while the heading is loose; each pulls its keyframe onto the
        // fix (σ 1 m, the floor); once the fixes pin the heading the marginal falls under
        // 25 m² and the factors pause, as in LIO-SAM.
        let cfg = BackendConfig {
            relinearize_skip: 1,
            ..BackendConfig::default()
        };
        let mut graph = KeyframeGraph::new(&cfg, None, 1e-3, 1e-2, true).expect("graph");
        let mut g = aligned(GpsConfig::default(), Vector3::zeros());
        let mut events = Vec::new();
        let mut registered = Isometry3::identity();
        let mut covariance: Option<Matrix3<f64>> = None;
        let mut with_factor = Vec::new();
        let mut paused = false;
        let mut spanned = None;
        for k in 0..60usize {
            if k > 0 {
                // The front end registers against the corrected map: the last keyframe's
                // estimate and a drifting step.
                registered = graph.pose(k - 1) * iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.003);
            }
            let stamp = k as i64 * S;
            for j in 0..10 {
                let t = stamp - S / 2 + j * S / 10;
                g.push(
                    &message(t, [t as f64 / S as f64, 0.0, 0.0], 4e-4),
                    &mut events,
                );
            }
            let state = KeyframeState {
                stamp_ns: stamp,
                map_from_imu: registered,
                first_and_last: (k > 0).then(|| {
                    (
                        graph.pose(0).translation.vector,
                        graph.pose(k - 1).translation.vector,
                    )
                }),
                last_covariance: covariance,
            };
            if let Some((first, last)) = state.first_and_last
                && spanned.is_none()
                && (first - last).norm() >= 5.0
            {
                spanned = Some(k);
            }
            let factor = g.select(&state, &mut events);
            graph
                .add_keyframe(
                    registered,
                    Vector3::zeros(),
                    ImuBias::default(),
                    Vec::new(),
                    factor.map(|f| (f.position, f.sigmas)),
                )
                .expect("keyframe");
            let cov = graph.position_covariance(k).expect("covariance");
            if k == 0 {
                assert!(cov[(0, 0)] > 1e6, "the loose prior: {cov}");
            }
            if let Some(f) = factor {
                let off = (graph.pose(k).translation.vector - f.position).xy().norm();
                assert!(off < 1.5, "keyframe {k}: {off} m from its fix");
                with_factor.push(k);
            } else if with_factor.len() >= 2 {
                let before = covariance.expect("covariance");
                paused |= before[(0, 0)] < 25.0 && before[(1, 1)] < 25.0;
            }
            covariance = Some(cov);
        }
        eprintln!("GPS factors at keyframes {with_factor:?}");
        assert!(events.is_empty(), "{events:?}");
        assert_eq!(
            with_factor.first().copied(),
            spanned,
            "the first as soon as the keyframes span 5 m"
        );
        assert!(
            with_factor.windows(2).all(|w| w[1] - w[0] >= 5),
            "at most one per 5 m"
        );
        assert!(with_factor.len() >= 2, "{with_factor:?}");
        assert!(paused, "the factors pause once the pose is known to 25 m²");
    }
}
