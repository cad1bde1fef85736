//! RTAB-Map's GPS priors on its locations (`Optimizer/PriorsIgnored = false`; RTAB-Map's
//! default is `true`, and so is this plugin's). Sources: introlab/rtabmap's corelib
//! (`GPS.h`, `Memory::createSignature`, `Rtabmap::process`, `OptimizerGTSAM::optimize`,
//! `graph::computeMaxGraphErrors`) and introlab/rtabmap_ros (`CoreWrapper::process`,
//! `CoreWrapper::gpsFixAsyncCallback`).
//!
//! **The fix a location takes.** rtabmap_ros keeps the fixes it receives and, when it
//! processes a frame, gives the frame the fix whose stamp is nearest the frame's, if it is
//! less than one detection period (`1 / Rtabmap/DetectionRate`) away, then forgets them
//! all; the frame that becomes a location keeps that fix as its `GPS` (stored per node,
//! `SensorData::gps`). Here fixes come `latency` after their epoch, and a location is made
//! as its camera frame arrives, before the fixes around its stamp have: its choice waits
//! until a fix stamped at or after it arrives (or the next location is made, or the run
//! ends), so that, as in rtabmap_ros processing a frame some time after it was taken, the
//! nearest is chosen from both sides. The fixes are then forgotten.
//!
//! **The fix's error.** rtabmap_ros's `GPS` carries one `error`, m: the square root of the
//! largest of the reported east, north and up variances (10 m when the covariance is
//! unknown, never here: a fix without a usable covariance is refused).
//!
//! **The prior** (`Memory::createSignature`, "GPS prior"): a pose prior on the location at
//! the fix's east and north from the first fix any location took (RTAB-Map's `_gpsOrigin`,
//! with `toENU_WGS84`; here the receiver's own east-north-up from its datum minus the
//! first fix's, the same plane to a millimetre over a field) and at its altitude
//! (ellipsoidal height, not relative to the first fix), with information `1 / error` on x
//! and y, `1 / error` on z when `error > 1` else 1, and `1 / 9999` on the rotations, which
//! marks the prior as position-only ("variance not used >= 9999"): RTAB-Map's optimisers
//! then add a position factor (GTSAM's `XYZFactor`, `slam_common`'s `Factor::Position`).
//! Note the information `1 / error` where `1 / error²` would make `error` a standard
//! deviation: RTAB-Map's x and y variance is `error` itself (m taken as m²), z's is
//! `max(error, 1)`. That is kept: an RTK fix of 1.5 cm error holds a location to 12 cm, a
//! single-point fix of 2.5 m to 1.6 m.
//!
//! **The frame.** No alignment is computed (no navsat_transform, no heading from the IMU,
//! unlike this project's lio-sam and `slam_common::gnss::frame_from_enu`): the priors are
//! in the fixes' frame, and optimising the graph with them moves the whole map into it —
//! the map's rotation about the vertical is resolved by the optimiser from the priors'
//! positions alone, as the robot's track lengthens. To let the graph move, the first
//! location's anchor is loosened when the first prior arrives (`OptimizerGTSAM::optimize`:
//! with a GPS prior in the graph the root prior's variances are yaw 10⁻², x, y, z 2 m²,
//! roll and pitch 10⁻² without gravity links, which this plugin has none of; with
//! `Reg/Force3DoF`, here planar odometry, GTSAM's `Pose2` root prior is x, y 10⁻² m²,
//! yaw 10⁻²; RTAB-Map's g2o optimiser frees the root altogether). The map frame's origin
//! is then the first fix's east and north at the ellipsoid's height 0, its axes east,
//! north and up: after the first priors every pose, the trajectory, the cloud and the grid
//! are in it, and `map_from_odom` jumps as the optimiser turns the map. In 3D nothing but
//! that loosened anchor (σ 0.1 rad) and the weak z of the priors (σ ≥ 1 m) holds the
//! map's roll and pitch: RTAB-Map holds them with gravity links (`Optimizer/GravitySigma`,
//! from the IMU or `Mem/UseOdomGravity`), which this plugin does not have (the shared
//! backend has no attitude factor). Where odometry disagrees strongly with the fixes the
//! optimiser can then lean the map to reconcile them (a test with a gyro bias of 0.01
//! rad/s saw 0.3 rad of roll); planar odometry cannot lean.
//!
//! **When.** A location with a prior makes RTAB-Map optimise the whole graph, as a loop
//! closure does (`Rtabmap::process`, "prior edge"): here the prior is added and the graph
//! optimised in full when the location's fix is chosen. Priors take no part in the
//! `RGBD/OptimizeMaxError` check of loop closures (`graph::computeMaxGraphErrors` skips
//! self-links), though the odometry links they strain do.
//!
//! **Departures.** RTAB-Map puts the prior on the location's pose as if the antenna were
//! at the base; here the antenna's lever arm (the rig's `gnss` mount) is removed with the
//! location's attitude when the prior is made (navsat_transform's
//! `getRobotOriginWorldPose`, `slam_common::gnss::body_in_frame`; the attitude is the
//! graph's heading with odometry's roll and pitch, [`GpsPriors::prior`]): a mast 1.7 m
//! high would otherwise lift the map by 1.7 m and, tilted, shift it sideways. With planar
//! odometry (`Reg/Force3DoF`, `icp.attitude_gain = 0`) RTAB-Map's 2D optimiser constrains
//! x and y only: the prior's z is then the location's own. Fixes that cannot be used (no
//! fix, a position or altitude that is not finite, a covariance that is not positive
//! definite; RTAB-Map logs "Invalid GPS value") are refused when they arrive, each with a
//! `gnss_rejected` event. RTAB-Map's other use of GPS, `Rtabmap/LoopGPS` (loop-closure
//! candidates only within `RGBD/LocalRadius` of the current fix), is not implemented.

use std::collections::{BTreeMap, VecDeque};

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector2, Vector3, Vector6};
use plugin_api::{Event, Gnss as GnssMessage};
use slam_common::gnss::{Fix, body_in_frame, yaw};

use crate::graph::ANCHOR_SIGMA;

/// RTAB-Map's `GPS` as a location keeps it (`GPS.h`: stamp, longitude, latitude,
/// altitude, error, bearing; the bearing, which rtabmap_ros sets to 0 and the prior's
/// variance 9999 leaves unused, is not kept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gps {
    pub stamp_ns: i64,
    /// The antenna's east and north from the receiver's datum, m.
    pub east_north_m: Vector2<f64>,
    /// The antenna's ellipsoidal height, m.
    pub altitude_m: f64,
    /// `error`, m: the square root of the largest of the east, north and up variances
    /// (`CoreWrapper::gpsFixAsyncCallback`).
    pub error_m: f64,
}

impl Gps {
    /// The fix as RTAB-Map keeps it, or why it cannot be used.
    pub fn from_message(msg: &GnssMessage) -> Result<Self, &'static str> {
        let (p, c) = msg.usable()?;
        if !msg.altitude_m.is_finite() {
            return Err("a fix without a finite altitude");
        }
        let variance = c[(0, 0)].max(c[(1, 1)]).max(c[(2, 2)]);
        Ok(Self {
            stamp_ns: msg.stamp_ns,
            east_north_m: p.xy(),
            altitude_m: msg.altitude_m,
            error_m: variance.sqrt(),
        })
    }

    /// The prior's variances on x, y, z, m²: `error`, `error`, and `error` if above 1 else 1
    /// (`Memory::createSignature`: information `1 / error`, z's 1 up to an error of 1 m).
    pub fn variances(&self) -> Vector3<f64> {
        let e = self.error_m;
        Vector3::new(e, e, if e > 1.0 { e } else { 1.0 })
    }
}

/// Standard deviations `[roll, pitch, yaw, x, y, z]` of the first location's anchor once
/// the graph holds a GPS prior (`OptimizerGTSAM::optimize`): in 3D, variances 10⁻² on the
/// rotations (roll and pitch as without gravity links) and 2 m² on the position; planar
/// (GTSAM's `Pose2`), x, y 10⁻² m² and yaw 10⁻², the rest held as before
/// ([`ANCHOR_SIGMA`]).
pub fn root_sigmas(planar: bool) -> Vector6<f64> {
    let (r, m, held) = (1e-2_f64.sqrt(), 2.0_f64.sqrt(), ANCHOR_SIGMA);
    if planar {
        Vector6::new(held, held, r, r, r, held)
    } else {
        Vector6::new(r, r, r, m, m, m)
    }
}

/// A GPS prior on a location's position in the map frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prior {
    pub id: u64,
    pub position: Vector3<f64>,
    pub sigmas: Vector3<f64>,
}

/// The fixes, the location waiting for its own, the fix every location took, and the
/// origin of the priors' frame.
#[derive(Debug, Clone)]
pub struct GpsPriors {
    base_from_antenna: Vector3<f64>,
    /// One detection period, ns: a location takes a fix less than this from its stamp.
    window_ns: i64,
    /// Fixes received since the last location took one, in stamp order.
    fixes: VecDeque<Gps>,
    /// The newest location, still choosing its fix: id and stamp.
    waiting: Option<(u64, i64)>,
    /// RTAB-Map's `_gpsOrigin`: the first fix a location took, east and north.
    origin: Option<Vector2<f64>>,
    /// The fix every location took (RTAB-Map's GPS per node).
    taken: BTreeMap<u64, Gps>,
}

impl GpsPriors {
    /// `base_from_antenna`: the receiver's mount; `detection_rate_hz`:
    /// `Rtabmap/DetectionRate`.
    pub fn new(base_from_antenna: Vector3<f64>, detection_rate_hz: f64) -> Self {
        Self {
            base_from_antenna,
            window_ns: (1e9 / detection_rate_hz).round() as i64,
            fixes: VecDeque::new(),
            waiting: None,
            origin: None,
            taken: BTreeMap::new(),
        }
    }

    /// Keeps a usable fix, or refuses one with a `gnss_rejected` event. Returns the waiting
    /// location and its fix if this fix settles its choice (stamped at or after it).
    pub fn push(&mut self, msg: &GnssMessage, events: &mut Vec<Event>) -> Option<(u64, Gps)> {
        match Gps::from_message(msg) {
            Ok(gps) => {
                let at = self.fixes.partition_point(|f| f.stamp_ns <= gps.stamp_ns);
                self.fixes.insert(at, gps);
                // None waiting: only fixes within a period of the newest can serve the next
                // location (whose stamp is later than what has arrived).
                if self.waiting.is_none() {
                    let newest = self.fixes.back().map_or(i64::MIN, |f| f.stamp_ns);
                    while self
                        .fixes
                        .front()
                        .is_some_and(|f| f.stamp_ns < newest - self.window_ns)
                    {
                        self.fixes.pop_front();
                    }
                }
                self.settle(false)
            }
            Err(problem) => {
                events.push(msg.rejected("rtabmap", problem));
                None
            }
        }
    }

    /// A new location `id` at `stamp_ns` will take a fix. Returns the previous waiting
    /// location and the fix it takes now, if any; the new one waits for a fix stamped at
    /// or after it, unless one has arrived already (then it is returned instead).
    pub fn location(&mut self, id: u64, stamp_ns: i64) -> Vec<(u64, Gps)> {
        let mut settled: Vec<_> = self.settle(true).into_iter().collect();
        self.waiting = Some((id, stamp_ns));
        settled.extend(self.settle(false));
        settled
    }

    /// The run ends: the waiting location takes the nearest fix there is.
    pub fn finish(&mut self) -> Option<(u64, Gps)> {
        self.settle(true)
    }

    /// Settles the waiting location's choice if a fix stamped at or after it has arrived,
    /// or `now`: the nearest fix less than a period from its stamp, if any; then every fix
    /// is forgotten (rtabmap_ros clears its fixes at every frame it processes).
    fn settle(&mut self, now: bool) -> Option<(u64, Gps)> {
        let (id, stamp) = self.waiting?;
        if !now && self.fixes.back().is_none_or(|f| f.stamp_ns < stamp) {
            return None;
        }
        self.waiting = None;
        let nearest = self
            .fixes
            .iter()
            .min_by_key(|f| (f.stamp_ns - stamp).abs())
            .filter(|f| (f.stamp_ns - stamp).abs() < self.window_ns)
            .copied();
        self.fixes.clear();
        let gps = nearest?;
        self.taken.insert(id, gps);
        Some((id, gps))
    }

    /// The prior of location `id` from the fix it took, with its pose `map_from_base` in
    /// the graph now and `odom_from_base` in odometry (for the lever arm; planar: its z
    /// too). The first fix taken is the frame's origin.
    ///
    /// The lever arm turns with the location's heading in the graph and its roll and pitch
    /// in odometry, which the IMU keeps level with gravity, as the fixes' frame is: not
    /// with the graph's roll and pitch, which early on, while a few priors along a short
    /// track leave the map's turn to the optimiser and the first location's anchor, can
    /// lean by tenths of a radian, and would lean a 1.7 m mast sideways by decimetres in
    /// a prior that stays.
    pub fn prior(
        &mut self,
        id: u64,
        gps: &Gps,
        map_from_base: &Isometry3<f64>,
        odom_from_base: &Isometry3<f64>,
        planar: bool,
    ) -> Prior {
        let about_z = |a: f64| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a);
        let odom_r_base = odom_from_base.rotation;
        let attitude =
            about_z(yaw(&map_from_base.rotation)) * about_z(-yaw(&odom_r_base)) * odom_r_base;
        let origin = *self.origin.get_or_insert(gps.east_north_m);
        // The priors' frame from the receiver's: east and north from the first fix, up as
        // the ellipsoidal height (the fix's up replaced by its altitude below).
        let frame_from_enu = Isometry3::translation(-origin.x, -origin.y, 0.0);
        let fix = Fix {
            stamp_ns: gps.stamp_ns,
            position_enu_m: Vector3::new(gps.east_north_m.x, gps.east_north_m.y, gps.altitude_m),
            covariance_enu_m2: Matrix3::from_diagonal(&gps.variances()),
        };
        let (mut position, variances) =
            body_in_frame(&frame_from_enu, &fix, &attitude, &self.base_from_antenna);
        if planar {
            position.z = map_from_base.translation.z;
        }
        Prior {
            id,
            position,
            sigmas: variances.diagonal().map(f64::sqrt),
        }
    }

    /// The fix location `id` took, if it took one.
    pub fn taken(&self, id: u64) -> Option<&Gps> {
        self.taken.get(&id)
    }

    /// Locations that took a fix.
    pub fn priors(&self) -> usize {
        self.taken.len()
    }

    /// The first fix's east and north from the receiver's datum, the priors' origin.
    pub fn origin(&self) -> Option<Vector2<f64>> {
        self.origin
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};
    use plugin_api::{EventKind, GnssStatus};
    use slam_common::factor_graph::backend::BackendConfig;

    use super::*;
    use crate::config::LinkSigmas;
    use crate::graph::{PoseGraph, Sigmas};

    const MS: i64 = 1_000_000;
    const S: i64 = 1_000_000_000;

    /// A fix of the antenna at `enu` (altitude its up: the datum at height 0) with
    /// variances east, north, up.
    fn message(stamp_ns: i64, enu: Vector3<f64>, variances: [f64; 3]) -> GnssMessage {
        let [ve, vn, vu] = variances;
        GnssMessage {
            stamp_ns,
            status: GnssStatus::Fixed,
            satellites: 14,
            position_enu_m: enu.into(),
            covariance_enu_m2: [ve, 0.0, 0.0, 0.0, vn, 0.0, 0.0, 0.0, vu],
            latitude_deg: 53.27,
            longitude_deg: -0.52,
            altitude_m: enu.z,
            hdop: 0.8,
        }
    }

    const RTK: [f64; 3] = [7e-5, 7e-5, 2.25e-4];

    fn at(stamp_ns: i64, east: f64) -> GnssMessage {
        message(stamp_ns, Vector3::new(east, 0.0, 0.0), RTK)
    }

    #[test]
    fn a_location_takes_the_nearest_fix_from_either_side_within_a_period() {
        // Guards the choice (rtabmap_ros's nearest fix within 1 / DetectionRate, waiting for
        // the fixes after the location) and the forgetting after it.
        let mut g = GpsPriors::new(Vector3::zeros(), 1.0);
        let mut events = Vec::new();
        let mut push = |g: &mut GpsPriors, m: GnssMessage| g.push(&m, &mut events);
        for k in 0..=5 {
            assert_eq!(push(&mut g, at(k * 200 * MS, k as f64)), None);
        }
        // A location at 1.07 s: the fix of 1.0 s has arrived, the one of 1.2 s not yet.
        assert!(g.location(0, 1070 * MS).is_empty());
        let (id, gps) = push(&mut g, at(1200 * MS, 6.0)).expect("settled by a later fix");
        assert_eq!(
            (id, gps.stamp_ns),
            (0, 1000 * MS),
            "0.07 s before beats 0.13 s after"
        );
        // At 2.13 s: the fix of 2.2 s is the nearer, though it arrives after the location.
        for k in 7..=10 {
            assert_eq!(push(&mut g, at(k * 200 * MS, k as f64)), None);
        }
        assert!(g.location(1, 2130 * MS).is_empty());
        let (id, gps) = push(&mut g, at(2200 * MS, 11.0)).expect("settled");
        assert_eq!((id, gps.stamp_ns), (1, 2200 * MS));
        // The fixes were forgotten: a location at 3.5 s takes the next to arrive (3.9 s,
        // within a period); one at 5 s, whose only fix (5.2 s... none) never comes, none.
        assert!(g.location(2, 3500 * MS).is_empty());
        let (id, gps) = push(&mut g, at(3900 * MS, 19.0)).expect("settled");
        assert_eq!((id, gps.stamp_ns), (2, 3900 * MS));
        assert!(g.location(3, 5 * S).is_empty());
        assert_eq!(g.finish(), None, "no fix since location 2's");
        assert_eq!(g.priors(), 3);
        assert_eq!(g.taken(1).map(|f| f.east_north_m.x), Some(11.0));
        assert!(g.taken(3).is_none());
        // A fix more than a period from the waiting location settles it without a fix.
        assert!(g.location(4, 8 * S).is_empty());
        assert_eq!(
            push(&mut g, at(9100 * MS, 40.0)),
            None,
            "1.1 s after location 4"
        );
        assert!(g.taken(4).is_none());
        // A fix already after a new location's stamp settles it at once.
        assert_eq!(push(&mut g, at(10 * S, 50.0)), None);
        let settled = g.location(5, 9900 * MS);
        assert_eq!(settled.len(), 1);
        assert_eq!((settled[0].0, settled[0].1.stamp_ns), (5, 10 * S));
        assert!(events.is_empty());
    }

    #[test]
    fn the_prior_has_rtabmaps_variances_origin_and_altitude() {
        // Guards Memory::createSignature's prior: x, y variance = error, z = max(error, 1),
        // error = sqrt of the largest variance; x, y from the first fix, z the altitude;
        // and the lever arm removed with the location's heading in the graph and roll and
        // pitch in odometry.
        let lever = Vector3::new(0.0, 0.0, 1.7);
        let mut g = GpsPriors::new(lever, 1.0);
        let first = Gps::from_message(&message(
            0,
            Vector3::new(100.0, -40.0, 51.7),
            [0.01, 0.04, 0.09],
        ))
        .expect("usable");
        assert!((first.error_m - 0.3).abs() < 1e-12);
        assert_eq!(first.variances(), Vector3::new(0.3, 0.3, 1.0));
        let level = Isometry3::identity();
        let p = g.prior(0, &first, &level, &level, false);
        assert!((p.position - Vector3::new(0.0, 0.0, 50.0)).norm() < 1e-12);
        assert!((p.sigmas - Vector3::new(0.3f64.sqrt(), 0.3f64.sqrt(), 1.0)).norm() < 1e-12);
        assert_eq!(g.origin(), Some(Vector2::new(100.0, -40.0)));
        // A single-point fix (variance 6.25 m² up): error 2.5, z variance 2.5 too. The
        // location rolled 0.1 rad in odometry, heading 0.7 there and π/2 in the graph,
        // which leans it by 0.3 rad more: the mast leans 1.7 sin 0.1 toward +x (the
        // base's -y turned by π/2), the graph's lean ignored.
        let single = Gps::from_message(&message(
            S,
            Vector3::new(103.0, -36.0, 52.0),
            [1.6, 1.6, 6.25],
        ))
        .expect("usable");
        let half_pi = std::f64::consts::FRAC_PI_2;
        let rolled = Isometry3::from_parts(
            Translation3::new(3.0, 4.0, 0.0),
            UnitQuaternion::from_euler_angles(0.4, 0.0, half_pi),
        );
        let odom = Isometry3::from_parts(
            Translation3::new(-7.0, 2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, 0.0, 0.7),
        );
        let p = g.prior(1, &single, &rolled, &odom, false);
        let expected = Vector3::new(3.0 - 1.7 * 0.1f64.sin(), 4.0, 52.0 - 1.7 * 0.1f64.cos());
        assert!((p.position - expected).norm() < 1e-12, "{}", p.position);
        assert!((p.sigmas - Vector3::repeat(2.5f64.sqrt())).norm() < 1e-12);
        // Planar (RTAB-Map's 2D optimiser: x and y only): z is the location's own.
        let p = g.prior(1, &single, &rolled, &odom, true);
        assert_eq!(p.position.z, 0.0);
        assert_eq!(root_sigmas(true)[2], 0.1);
        assert_eq!(root_sigmas(false)[5], 2.0f64.sqrt());
    }

    #[test]
    fn unusable_fixes_are_refused_with_an_event_and_never_kept() {
        // Guards Gnss::problem's cases and RTAB-Map's finite-altitude check.
        let mut g = GpsPriors::new(Vector3::zeros(), 1.0);
        let mut events = Vec::new();
        let good = at(S, 1.0);
        let no_fix = GnssMessage {
            status: GnssStatus::NoFix,
            ..good
        };
        let nan = GnssMessage {
            position_enu_m: [f64::NAN, 0.0, 0.0],
            ..good
        };
        let flat = GnssMessage {
            covariance_enu_m2: [0.0; 9],
            ..good
        };
        let no_altitude = GnssMessage {
            altitude_m: f64::NAN,
            ..good
        };
        for m in [no_fix, nan, flat, no_altitude] {
            assert_eq!(g.push(&m, &mut events), None);
        }
        assert_eq!(events.len(), 4);
        assert!(events.iter().all(|e| e.kind == EventKind::GnssRejected));
        assert!(events[0].detail.contains("no fix"), "{}", events[0].detail);
        assert!(
            events[3].detail.contains("altitude"),
            "{}",
            events[3].detail
        );
        assert!(g.location(0, S).is_empty());
        assert_eq!(g.finish(), None, "nothing was kept");
        assert_eq!(g.priors(), 0);
    }

    /// Truth: a serpentine of three 40 m rows 3 m apart, a location every metre, in ENU
    /// from (40, 15) heading 1.1 rad. `map_from_base` of location `k`.
    fn serpentine() -> Vec<Isometry3<f64>> {
        let mut poses = vec![Isometry3::from_parts(
            Translation3::new(40.0, 15.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 1.1),
        )];
        let step = |yaw: f64| {
            Isometry3::from_parts(
                Translation3::new(1.0, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            )
        };
        for row in 0..3 {
            for _ in 0..40 {
                poses.push(poses.last().unwrap() * step(0.0));
            }
            if row < 2 {
                // A headland turn: 180° over 5 steps, the rows 3 m apart side by side.
                let sign = if row % 2 == 0 { 1.0 } else { -1.0 };
                for _ in 0..5 {
                    let turn = Isometry3::from_parts(
                        Translation3::new(0.0, sign * 0.6, 0.0),
                        UnitQuaternion::from_euler_angles(
                            0.0,
                            0.0,
                            sign * std::f64::consts::PI / 5.0,
                        ),
                    );
                    poses.push(poses.last().unwrap() * turn);
                }
            }
        }
        poses
    }

    /// The locations of a serpentine whose odometry drifts (4 mrad of heading and 1 % of
    /// length per metre) in a graph on `backend`; with GPS priors from fixes of the
    /// antenna 1.7 m up at every location (RTK: 1.5 cm error, a few cm of noise). Returns
    /// the worst and the mean horizontal error against the truth in the frame the graph
    /// should be in: the fixes' (east, north from the first fix) with priors, the first
    /// location's without.
    fn drifting_chain(backend: &str, priors: bool) -> (f64, f64, PoseGraph) {
        let cfg = BackendConfig {
            name: backend.into(),
            ..BackendConfig::default()
        };
        let mut graph = PoseGraph::new(&cfg, 3.0).expect("backend");
        let truth = serpentine();
        let lever = Vector3::new(0.0, 0.0, 1.7);
        let mut gps = GpsPriors::new(lever, 1.0);
        let link = LinkSigmas::default();
        let drift = Isometry3::from_parts(
            Translation3::new(0.01, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.004),
        );
        let mut odom = Isometry3::identity();
        let mut events = Vec::new();
        for (k, t) in truth.iter().enumerate() {
            let id = k as u64;
            if k == 0 {
                graph.add_first(id, odom).expect("first");
            } else {
                let step = truth[k - 1].inverse() * t * drift;
                let d = step.translation.vector.norm();
                let sigmas = Sigmas {
                    rad: link.rad_floor + link.rad_per_m * d,
                    m: link.m_floor + link.m_per_m * d,
                };
                graph
                    .add_odometry(id - 1, id, step, sigmas)
                    .expect("odometry");
                odom *= step;
            }
            if !priors {
                continue;
            }
            let stamp = k as i64 * S;
            let noise = Vector3::new((k as f64 * 1.3).sin(), (k as f64 * 0.7).cos(), 0.0) * 0.02;
            let antenna = t * nalgebra::Point3::from(lever);
            let settled = gps.location(id, stamp);
            assert!(settled.is_empty());
            let (id, fix) = gps
                .push(
                    &message(stamp + 50 * MS, antenna.coords + noise, RTK),
                    &mut events,
                )
                .expect("settled");
            let map_from_base = graph.pose(id).expect("pose");
            let prior = gps.prior(id, &fix, &map_from_base, &odom, false);
            graph
                .add_position_prior(id, prior.position, prior.sigmas, root_sigmas(false))
                .expect("prior");
        }
        assert!(events.is_empty());
        let frame_from_truth = match gps.origin() {
            Some(o) => Isometry3::translation(-o.x, -o.y, 0.0),
            None => truth[0].inverse(),
        };
        let errors: Vec<f64> = truth
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let expected = (frame_from_truth * t).translation.vector;
                let got = graph.pose(k as u64).expect("pose").translation.vector;
                (got - expected).xy().norm()
            })
            .collect();
        let worst = errors.iter().copied().fold(0.0, f64::max);
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        eprintln!("{backend}, priors {priors}: worst {worst:.3} m, mean {mean:.3} m");
        (worst, mean, graph)
    }

    #[test]
    fn gps_priors_pull_a_drifting_graph_onto_the_fixes_frame() {
        // Guards the priors in the graph: without them the serpentine's odometry drifts by
        // metres; with them every location lies within decimetres of the truth in the
        // fixes' frame, whose 1.1 rad turn from the odometry's the optimiser resolved from
        // positions alone (no heading given), the first location's anchor loosened; z is
        // the base's (the mast removed), not the antenna's. (The "gtsam" backend, ISAM2's
        // Gauss-Newton, stops short here: 1.07 m worst at the second headland, mean 0.10 m.)
        for backend in ["factrs", "isam2"] {
            let (worst, _, _) = drifting_chain(backend, false);
            assert!(worst > 5.0, "{backend}: odometry alone drifts ({worst} m)");
            let (worst, mean, graph) = drifting_chain(backend, true);
            assert!(
                worst < 0.25 && mean < 0.1,
                "{backend}: {worst} m, mean {mean} m"
            );
            assert_eq!(graph.priors(), serpentine().len());
            let first = graph.pose(0).expect("pose");
            let yaw = first.rotation.euler_angles().2;
            // (The loosened anchor's yaw, σ 0.1 rad about the odometry's 0, still holds the
            // first location back by a few hundredths.)
            assert!(
                (yaw - 1.1).abs() < 0.08,
                "{backend}: the map turned by {yaw} rad"
            );
            assert!(
                first.translation.z.abs() < 0.1,
                "{backend}: z {}",
                first.translation.z
            );
        }
    }
}
