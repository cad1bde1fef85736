//! GNSS priors per submap: StaticMapping's ENU factors (`IsamOptimizer::AddFrame` and
//! `IsamOptimizer::SolveGpsCorrdAlone` in `back_end/isam_optimizer.cc`), fed one position
//! per submap as `MapBuilder::SubmapProcessing` (`builder/map_builder.cc`) takes it from
//! `DataCollector::InterpolateGps` (`builder/data/data_collector.cc`).
//!
//! **The original.** Fixes become local east-north-up coordinates about the first fixed
//! message (`DataCollector::AddSensorData`, GeographicLib's `LocalCartesian`). Each submap
//! gets the ENU position interpolated at its stamp. Its factor says that the antenna,
//! `map_origin_in_gps · pose_k · tracking_to_gps`, is at that position, with σ = 0.15 m on
//! every axis (`gps_noise_model_`); `map_origin_in_gps` is a variable of the graph. Until
//! `gps_factor_init_num` submaps have a cached position and some submap has turned
//! `gps_factor_init_angle_rad` from the first (`AnalyseAllFramePoseForMaxRotation`), the
//! positions are only cached. Then `map_origin_in_gps` is solved alone (Gauss–Newton over
//! the cached positions with the poses held, `SolveGpsCorrdAlone`), enters the graph with a
//! prior, and the cached factors are added. From then on a factor joins every
//! `gps_factor_sample_step`-th submap. At the end every pose is carried into ENU by the
//! estimated transform (`MapBuilder::CalculateCoordTransformToGps`).
//!
//! **Here**, step by step:
//! 1. *Fixes* ([`Epochs`]). The receiver already gives ENU metres from the world's datum,
//!    so the original's geodetic-to-local conversion is not needed. The datum differs from
//!    the original's origin (its first fix) by a constant offset, and the alignment absorbs
//!    that offset. Every epoch is kept in stamp order. An unusable one
//!    ([`plugin_api::Gnss::problem`]) is refused with a `gnss_rejected` event and kept as a
//!    gap, as the original keeps a message that is not fixed. A submap's position is
//!    `InterpolateGps`'s: linear between the fixes either side of its stamp if both are
//!    usable and at most 0.2 s apart; with a single epoch, that epoch if within 1 ms;
//!    nothing outside the fixes' span. Any usable fix (single, float, fixed) counts as the
//!    original's `STATUS_FIX`.
//! 2. *Alignment* (`map_from_enu`, the inverse of `map_origin_in_gps`). This port uses
//!    navsat_transform's yaw-only alignment ([`slam_common::gnss::frame_from_enu`]) at the
//!    first submap that has a position and an IMU orientation at its stamp. It does not
//!    port the original's solve, for three reasons:
//!    - the slam_common backends have no factor with the transform as a variable (the
//!      original's `transformFrom(compose(T, pose), lever)`). [`Factor::Position`] (GTSAM's
//!      `GPSFactor`) is a prior in the graph's own frame. So the transform must be fixed
//!      before the first prior, whatever computes it, and later fixes cannot refine it as
//!      they do in the original;
//!    - the first submap is held at its pose (σ = 1e-6). Aligning there bakes no drift into
//!      the transform, whereas a solve over the first `gps_factor_init_num` submaps would
//!      take in their drift;
//!    - every plugin that takes GNSS puts a fix into its frame this same way
//!      (`slam_common::gnss`), so the systems differ only in how they fuse the fixes.
//!
//!    The cost: it needs the IMU's absolute heading, which the original does not (its IMU
//!    gives rates only). An error in that heading turns every prior about the aligning
//!    fix, which the original's joint estimate would absorb.
//! 3. *When* ([`Gate`]). The original's rules, unchanged, plus one wait: the gate also
//!    waits for the alignment. Like the original, the submap that opens the gate gives no
//!    prior (it is neither cached nor added in `AddFrame`). With the alignment taken from
//!    the first fix, the wait is no longer needed to make the transform observable. It is
//!    kept to match the original's timing; `gps_factor_init_num = 0` and
//!    `gps_factor_init_angle_rad = 0` start the priors at once.
//! 4. *Priors*. A [`Factor::Position`] on the submap's pose: the antenna's ENU position
//!    carried into the map, minus the lever arm turned by the submap's current rotation
//!    ([`slam_common::gnss::body_in_frame`]), with σ = 0.15 m on every axis (the original
//!    ignores the receiver's covariance too). In the original the lever arm turns with the
//!    pose inside the factor; here it is fixed at the estimate when the prior is added.
//!    The cached priors go in with one full update, since they move the whole chain as a
//!    loop closure does; later ones each go in with an incremental update, like the
//!    original's `IsamUpdate` after each factor.
//! 5. *Output*. The trajectory and map stay in the map frame (the first submap's), the
//!    frame every other system reports in (lio-sam's GPS factors do the same). The
//!    original's final move into ENU is not done.
//!
//! [`Factor::Position`]: slam_common::factor_graph::backend::Factor::Position

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use plugin_api::{Event, EventKind, Gnss as GnssMessage};
use slam_common::factor_graph::backend::{BackendError, Scope};
pub use slam_common::gnss::{Fix, Orientations};
use slam_common::gnss::{body_in_frame, frame_from_enu, yaw};

use crate::config::GpsConfig;
use crate::graph::SubmapGraph;

/// σ of every axis of a prior, m (`gps_noise_model_ = Isotropic::Sigma(3, 0.15)`).
pub const GPS_SIGMA_M: f64 = 0.15;
/// `InterpolateGps`'s `time_threshold` as `SubmapProcessing` passes it (0.001 s): how
/// near a lone epoch must be.
const LONE_EPOCH_NS: i64 = 1_000_000;
/// Fixes more than this apart are not interpolated between (`delta_time > 0.2`).
const MAX_GAP_NS: i64 = 200_000_000;

/// Every GNSS epoch in stamp order: a usable fix, or `None` for a refused one.
#[derive(Debug, Clone, Default)]
pub struct Epochs {
    epochs: Vec<(i64, Option<Fix>)>,
}

impl Epochs {
    /// Keeps the epoch; a fix that cannot be used becomes a gap and a `gnss_rejected`
    /// event.
    pub fn push(&mut self, gnss: &GnssMessage, events: &mut Vec<Event>) {
        let fix = match (gnss.problem(), gnss.position(), gnss.covariance()) {
            (None, Some(position_enu_m), Some(covariance_enu_m2)) => Some(Fix {
                stamp_ns: gnss.stamp_ns,
                position_enu_m,
                covariance_enu_m2,
            }),
            (problem, ..) => {
                events.push(Event::new(
                    gnss.stamp_ns,
                    EventKind::GnssRejected,
                    format!(
                        "staticmapping: GNSS fix ({}, {} satellites) refused: {}",
                        gnss.status.name(),
                        gnss.satellites,
                        problem.unwrap_or("not usable")
                    ),
                ));
                None
            }
        };
        let at = self.epochs.partition_point(|(t, _)| *t <= gnss.stamp_ns);
        self.epochs.insert(at, (gnss.stamp_ns, fix));
    }

    /// Epochs kept, usable or not.
    pub fn len(&self) -> usize {
        self.epochs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.epochs.is_empty()
    }

    /// The antenna's ENU position at `t_ns` (`InterpolateGps`, step 1 of the module's
    /// documentation); the covariance is interpolated alike.
    pub fn at(&self, t_ns: i64) -> Option<Fix> {
        let e = &self.epochs;
        match e.len() {
            0 => None,
            1 => e[0]
                .1
                .filter(|f| (f.stamp_ns - t_ns).abs() <= LONE_EPOCH_NS),
            n => {
                if t_ns < e[0].0 || t_ns > e[n - 1].0 {
                    return None;
                }
                let i = e.partition_point(|(t, _)| *t <= t_ns).clamp(1, n - 1);
                let (a, b) = (e[i - 1].1?, e[i].1?);
                let gap = b.stamp_ns - a.stamp_ns;
                if gap > MAX_GAP_NS {
                    return None;
                }
                if gap <= 0 {
                    return Some(Fix {
                        stamp_ns: t_ns,
                        ..a
                    });
                }
                let u = (t_ns - a.stamp_ns) as f64 / gap as f64;
                Some(Fix {
                    stamp_ns: t_ns,
                    position_enu_m: a.position_enu_m.lerp(&b.position_enu_m, u),
                    covariance_enu_m2: a.covariance_enu_m2 * (1.0 - u) + b.covariance_enu_m2 * u,
                })
            }
        }
    }
}

/// `AnalyseAllFramePoseForMaxRotation`: the largest angle between a submap's x axis and
/// the first submap's, rad (0 for fewer than two).
pub fn max_rotation(mut rotations: impl Iterator<Item = UnitQuaternion<f64>>) -> f64 {
    let Some(first) = rotations.next() else {
        return 0.0;
    };
    let x0 = first * Vector3::x();
    rotations
        .map(|r| (r * Vector3::x()).dot(&x0).clamp(-1.0, 1.0).acos())
        .fold(0.0, f64::max)
}

/// The original's choice of which submaps' positions become priors, and when (`AddFrame`'s
/// GNSS branch; step 3 of the module's documentation).
#[derive(Debug, Clone)]
pub struct Gate {
    cfg: GpsConfig,
    /// `cached_enu_`: submaps and their positions waiting for the gate.
    cached: Vec<(usize, Fix)>,
    /// `calculated_first_gps_coord_`.
    open: bool,
}

impl Gate {
    pub fn new(cfg: GpsConfig) -> Self {
        Self {
            cfg,
            cached: Vec::new(),
            open: false,
        }
    }

    pub fn is_open(&self) -> bool {
        self.open
    }

    /// Submap `k` with its position `fix`, `aligned` whether the ENU frame's transform is
    /// known, `max_rotation` the submaps' [`max_rotation`] (asked for only once enough
    /// positions are cached): the positions to turn into priors now.
    pub fn step(
        &mut self,
        k: usize,
        fix: Fix,
        aligned: bool,
        max_rotation: impl FnOnce() -> f64,
    ) -> Vec<(usize, Fix)> {
        let cfg = &self.cfg;
        if self.open {
            let step = cfg.gps_factor_sample_step;
            return if step <= 1 || k % step == 0 {
                vec![(k, fix)]
            } else {
                Vec::new()
            };
        }
        if !aligned
            || self.cached.len() < cfg.gps_factor_init_num
            || max_rotation() < cfg.gps_factor_init_angle_rad
        {
            self.cached.push((k, fix));
            return Vec::new();
        }
        // As the original: the cached positions, not this submap's.
        self.open = true;
        std::mem::take(&mut self.cached)
    }
}

/// What the GNSS side did over a build (`timing_json`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GnssCounts {
    /// Submaps that had a position at their stamp.
    pub submaps_with_fix: usize,
    /// Priors added.
    pub priors: usize,
    /// The submap whose fix and heading gave the alignment.
    pub aligned_at: Option<usize>,
    /// The submap at which the gate opened.
    pub opened_at: Option<usize>,
}

/// The GNSS side of the build: the epochs, the IMU's headings at the sweeps, the alignment
/// and the gate.
#[derive(Debug, Clone)]
pub struct SubmapGnss {
    epochs: Epochs,
    gate: Gate,
    /// The antenna in the lidar frame (the submaps' frame), from the rig.
    lidar_from_antenna: Vector3<f64>,
    imu_from_lidar: UnitQuaternion<f64>,
    /// The IMU's recent orientations, to note the one at each sweep's stamp.
    orientations: Orientations,
    /// `enu_from_imu` at sweep stamps, in order.
    headings: Vec<(i64, UnitQuaternion<f64>)>,
    map_from_enu: Option<Isometry3<f64>>,
    /// `gnss_rejected` events.
    pub events: Vec<Event>,
    pub counts: GnssCounts,
}

impl SubmapGnss {
    pub fn new(
        cfg: GpsConfig,
        lidar_from_antenna: Vector3<f64>,
        imu_from_lidar: UnitQuaternion<f64>,
    ) -> Self {
        Self {
            epochs: Epochs::default(),
            gate: Gate::new(cfg),
            lidar_from_antenna,
            imu_from_lidar,
            orientations: Orientations::default(),
            headings: Vec::new(),
            map_from_enu: None,
            events: Vec::new(),
            counts: GnssCounts::default(),
        }
    }

    pub fn map_from_enu(&self) -> Option<Isometry3<f64>> {
        self.map_from_enu
    }

    /// The antenna's position in the lidar frame.
    pub fn lidar_from_antenna(&self) -> Vector3<f64> {
        self.lidar_from_antenna
    }

    /// A GNSS epoch ([`Epochs::push`]).
    pub fn push(&mut self, gnss: &GnssMessage) {
        self.epochs.push(gnss, &mut self.events);
    }

    /// An IMU's reported orientation `enu_from_imu`.
    pub fn orientation(&mut self, stamp_ns: i64, enu_from_imu: UnitQuaternion<f64>) {
        self.orientations.push(stamp_ns, enu_from_imu);
    }

    /// A sweep stamped `stamp_ns` arrived: its heading is noted if the IMU gave one near
    /// it (a sweep arrives at its end, so the IMU has reported past its start).
    pub fn sweep(&mut self, stamp_ns: i64) {
        if let Some(q) = self.orientations.at(stamp_ns) {
            let at = self.headings.partition_point(|(t, _)| *t <= stamp_ns);
            self.headings.insert(at, (stamp_ns, q));
        }
    }

    fn heading_at(&self, stamp_ns: i64) -> Option<UnitQuaternion<f64>> {
        self.headings
            .binary_search_by_key(&stamp_ns, |(t, _)| *t)
            .ok()
            .map(|i| self.headings[i].1)
    }

    /// The GNSS part of `AddFrame` for submap `k`, stamped `stamp_ns`, just added to
    /// `graph` (after its loops): its position, the alignment if it is the first, the gate,
    /// and the priors it lets through.
    pub fn add_submap(
        &mut self,
        k: usize,
        stamp_ns: i64,
        graph: &mut SubmapGraph,
    ) -> Result<(), BackendError> {
        let Some(fix) = self.epochs.at(stamp_ns) else {
            return Ok(());
        };
        self.counts.submaps_with_fix += 1;
        if self.map_from_enu.is_none()
            && let Some(enu_from_imu) = self.heading_at(stamp_ns)
        {
            let map_from_lidar = graph.pose(k);
            self.map_from_enu = Some(frame_from_enu(
                &map_from_lidar.translation.vector,
                yaw(&map_from_lidar.rotation),
                &(enu_from_imu * self.imu_from_lidar),
                &self.lidar_from_antenna,
                &fix.position_enu_m,
            ));
            self.counts.aligned_at = Some(k);
        }
        let was_open = self.gate.is_open();
        let chosen = self.gate.step(k, fix, self.map_from_enu.is_some(), || {
            max_rotation((0..=k).map(|j| graph.pose(j).rotation))
        });
        let Some(map_from_enu) = self.map_from_enu else {
            return Ok(());
        };
        if !was_open && self.gate.is_open() {
            self.counts.opened_at = Some(k);
        }
        let priors: Vec<(usize, Vector3<f64>)> = chosen
            .iter()
            .map(|(j, f)| {
                let rotation = graph.pose(*j).rotation;
                let (position, _) =
                    body_in_frame(&map_from_enu, f, &rotation, &self.lidar_from_antenna);
                (*j, position)
            })
            .collect();
        self.counts.priors += priors.len();
        let scope = if was_open {
            Scope::Incremental
        } else {
            Scope::Full
        };
        graph.add_positions(&priors, GPS_SIGMA_M, scope)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Point3, Translation3};
    use plugin_api::GnssStatus;
    use slam_common::factor_graph::backend::BackendConfig;

    use super::*;

    const S: i64 = 1_000_000_000;
    const MS: i64 = 1_000_000;

    fn iso(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )
    }

    fn message(stamp_ns: i64, enu: Vector3<f64>, variance: f64) -> GnssMessage {
        let c = Matrix3::from_diagonal_element(variance);
        GnssMessage {
            stamp_ns,
            status: GnssStatus::Fixed,
            satellites: 14,
            position_enu_m: enu.into(),
            covariance_enu_m2: c.as_slice().try_into().expect("9"),
            latitude_deg: 52.0,
            longitude_deg: 5.0,
            altitude_m: 40.0,
            hdop: 0.8,
        }
    }

    fn fix(stamp_ns: i64, x: f64) -> Fix {
        Fix {
            stamp_ns,
            position_enu_m: Vector3::new(x, 0.0, 0.0),
            covariance_enu_m2: Matrix3::identity(),
        }
    }

    #[test]
    fn positions_are_interpolated_only_between_close_usable_fixes() {
        // Guards InterpolateGps's rules: linear within a gap of 0.2 s, nothing across a
        // longer gap or a refused epoch, nothing outside the span, a lone epoch within 1 ms.
        let mut e = Epochs::default();
        let mut events = Vec::new();
        let at = |x: f64| Vector3::new(x, 2.0 * x, 1.0);
        e.push(&message(S, at(10.0), 0.01), &mut events);
        assert_eq!(e.at(S + MS).map(|f| f.position_enu_m), Some(at(10.0)));
        assert!(e.at(S + 2 * MS).is_none(), "a lone epoch 2 ms away");
        // Pushed out of order: kept in stamp order.
        e.push(&message(S + 200 * MS, at(12.0), 0.03), &mut events);
        e.push(&message(S + 100 * MS, at(11.0), 0.01), &mut events);
        let f = e.at(S + 150 * MS).expect("between two fixes 0.1 s apart");
        assert!((f.position_enu_m - at(11.5)).norm() < 1e-12);
        assert!((f.covariance_enu_m2[(0, 0)] - 0.02).abs() < 1e-12);
        assert_eq!(f.stamp_ns, S + 150 * MS);
        assert_eq!(e.at(S + 200 * MS).map(|f| f.position_enu_m), Some(at(12.0)));
        assert!(e.at(S - MS).is_none() && e.at(S + 201 * MS).is_none());
        // A gap of 0.3 s, then a refused epoch between two good ones.
        e.push(&message(S + 500 * MS, at(15.0), 0.01), &mut events);
        assert!(e.at(S + 300 * MS).is_none(), "0.3 s apart");
        e.push(&message(S + 600 * MS, at(f64::NAN), 0.01), &mut events);
        e.push(&message(S + 700 * MS, at(17.0), 0.01), &mut events);
        assert!(e.at(S + 550 * MS).is_none() && e.at(S + 650 * MS).is_none());
        assert_eq!(e.len(), 6);
        assert_eq!(events.len(), 1);
        assert_eq!(events[0].kind, EventKind::GnssRejected);
    }

    #[test]
    fn unusable_fixes_are_refused_with_events() {
        // Guards Gnss::problem's cases: no fix, a NaN position, a zero covariance.
        let mut g = SubmapGnss::new(
            GpsConfig::default(),
            Vector3::zeros(),
            UnitQuaternion::identity(),
        );
        let mut no_fix = message(1, Vector3::repeat(f64::NAN), 0.0);
        no_fix.status = GnssStatus::NoFix;
        g.push(&no_fix);
        g.push(&message(2, Vector3::new(f64::NAN, 0.0, 0.0), 1.0));
        g.push(&message(3, Vector3::new(1.0, 0.0, 0.0), 0.0));
        g.push(&message(4, Vector3::new(1.0, 0.0, 0.0), 0.5));
        g.push(&message(5, Vector3::new(1.0, 0.0, 0.0), 0.5));
        assert_eq!(g.events.len(), 3);
        assert!(g.events.iter().all(|e| e.kind == EventKind::GnssRejected));
        assert!(
            g.events[0].detail.contains("no fix"),
            "{}",
            g.events[0].detail
        );
        // Refused epochs are gaps: nothing from one to the next fix.
        assert!(g.epochs.at(2).is_none() && g.epochs.at(3).is_none());
        assert!(g.epochs.at(4).is_some() && g.epochs.at(5).is_some());
    }

    #[test]
    fn max_rotation_is_the_largest_turn_of_the_x_axis_from_the_first() {
        let yaws = [0.3, 0.5, -1.0, 1.1, 0.2];
        let r = max_rotation(
            yaws.iter()
                .map(|&y| UnitQuaternion::from_euler_angles(0.0, 0.0, y)),
        );
        assert!((r - 1.3).abs() < 1e-9, "{r}");
        // A pitch turns the x axis too; a roll does not.
        let r = max_rotation(
            [(0.0, 0.0), (0.9, 0.0), (0.0, 0.4)]
                .iter()
                .map(|&(roll, pitch)| UnitQuaternion::from_euler_angles(roll, pitch, 0.0)),
        );
        assert!((r - 0.4).abs() < 1e-9, "{r}");
        assert_eq!(max_rotation(std::iter::empty()), 0.0);
    }

    #[test]
    fn the_gate_caches_until_enough_fixes_and_a_turn_then_samples() {
        // Guards AddFrame's GNSS branch: cache until gps_factor_init_num are cached, a
        // turn of gps_factor_init_angle_rad and the alignment; then the cached ones (not
        // the opening submap's); then every gps_factor_sample_step-th submap.
        let cfg = GpsConfig {
            use_gps: true,
            gps_factor_init_num: 3,
            gps_factor_init_angle_rad: 1.5,
            gps_factor_sample_step: 2,
        };
        let mut gate = Gate::new(cfg);
        let mut asked = 0;
        for k in 0..3 {
            let out = gate.step(k, fix(k as i64, k as f64), true, || {
                asked += 1;
                3.0
            });
            assert!(out.is_empty());
        }
        assert_eq!(asked, 0, "the turn is asked for only with enough cached");
        assert!(
            gate.step(3, fix(3, 3.0), true, || 1.4).is_empty(),
            "no turn yet"
        );
        assert!(
            gate.step(4, fix(4, 4.0), false, || 2.0).is_empty(),
            "not aligned"
        );
        assert!(!gate.is_open());
        let out = gate.step(5, fix(5, 5.0), true, || 1.6);
        assert!(gate.is_open());
        let ks: Vec<usize> = out.iter().map(|(k, _)| *k).collect();
        assert_eq!(ks, [0, 1, 2, 3, 4], "the cached, without submap 5");
        assert_eq!(out[3].1.position_enu_m.x, 3.0);
        let later: Vec<usize> = (6..12)
            .flat_map(|k| gate.step(k, fix(k as i64, 0.0), true, || 0.0))
            .map(|(k, _)| k)
            .collect();
        assert_eq!(later, [6, 8, 10]);
    }

    #[test]
    fn the_alignment_goes_through_the_lidar_mount_and_the_lever_arm() {
        // Guards the composition around frame_from_enu: the IMU's orientation turned into
        // the lidar's by imu_from_lidar (a lidar yawed 90° on the IMU), the lever arm in
        // the lidar frame, the submap's pose tilted. The transform found must carry every
        // later fix onto the true lidar position.
        let enu_from_map = iso(300.0, -120.0, 15.0, 0.0, 0.0, 0.8);
        let imu_from_lidar = UnitQuaternion::from_euler_angles(0.0, 0.0, 1.0);
        let lever = Vector3::new(-0.3, 0.2, 0.9);
        let truth = [
            iso(0.0, 0.0, 0.0, 0.04, -0.02, 0.3),
            iso(5.0, 3.0, 0.2, -0.03, 0.05, 1.2),
        ];
        let antenna = |p: &Isometry3<f64>| (enu_from_map * p * Point3::from(lever)).coords;
        let mut g = SubmapGnss::new(GpsConfig::default(), lever, imu_from_lidar);
        for (k, p) in truth.iter().enumerate() {
            let t = k as i64 * S;
            g.push(&message(t - 50 * MS, antenna(p), 1e-4));
            g.push(&message(t + 50 * MS, antenna(p), 1e-4));
            let enu_from_imu = (enu_from_map * p).rotation * imu_from_lidar.inverse();
            g.orientation(t, enu_from_imu);
            g.sweep(t);
        }
        let mut graph = SubmapGraph::new(&BackendConfig::default()).expect("graph");
        graph.add_first(truth[0]).expect("first");
        g.add_submap(0, 0, &mut graph).expect("submap 0");
        assert_eq!(g.counts.aligned_at, Some(0));
        let found = g.map_from_enu().expect("aligned");
        let error = found * enu_from_map;
        assert!(
            error.translation.vector.norm() < 1e-9 && error.rotation.angle() < 1e-9,
            "{error}"
        );
        let f = g.epochs.at(S).expect("fix");
        let (p, _) = body_in_frame(&found, &f, &truth[1].rotation, &lever);
        assert!((p - truth[1].translation.vector).norm() < 1e-9, "{p}");
    }

    /// A row and back with a headland turn: `(lidar poses in the map frame)`, 2 m apart.
    fn row_and_back() -> Vec<Isometry3<f64>> {
        let mut poses = Vec::new();
        for i in 0..30 {
            poses.push(iso(2.0 * f64::from(i), 0.0, 0.0, 0.0, 0.0, 0.0));
        }
        // A half circle of radius 3 m about (58, 3) in 6 steps.
        for i in 1..=6 {
            let a = std::f64::consts::PI * f64::from(i) / 6.0;
            poses.push(iso(
                58.0 + 3.0 * a.sin(),
                3.0 - 3.0 * a.cos(),
                0.0,
                0.0,
                0.0,
                a,
            ));
        }
        for i in 1..30 {
            poses.push(iso(
                58.0 - 2.0 * f64::from(i),
                6.0,
                0.0,
                0.0,
                0.0,
                std::f64::consts::PI,
            ));
        }
        poses
    }

    /// Runs the submap chain through the graph: the odometry of every step turned by
    /// `drift_rad` in heading, and with `gnss`, fixes 0.1 s either side of every submap.
    fn run(gnss: Option<GpsConfig>) -> (Vec<f64>, Option<SubmapGnss>) {
        let truth = row_and_back();
        let enu_from_map = iso(250.0, -80.0, 12.0, 0.0, 0.0, 0.7);
        let lever = Vector3::new(-0.2, 0.0, 0.7);
        let drift = iso(0.0, 0.0, 0.0, 0.0, 0.0, 0.006);
        let mut g = gnss.map(|cfg| SubmapGnss::new(cfg, lever, UnitQuaternion::identity()));
        let mut graph = SubmapGraph::new(&BackendConfig::default()).expect("graph");
        for (k, p) in truth.iter().enumerate() {
            let t = k as i64 * S;
            if let Some(g) = &mut g {
                // A few centimetres of error, deterministic.
                let noise =
                    Vector3::new(0.03 * (k as f64 * 1.3).sin(), 0.03 * (k as f64).cos(), 0.0);
                let antenna = (enu_from_map * p * Point3::from(lever)).coords + noise;
                g.push(&message(t - 100 * MS, antenna, 1e-3));
                g.push(&message(t + 100 * MS, antenna, 1e-3));
                g.orientation(t, (enu_from_map * p).rotation);
                g.sweep(t);
            }
            if k == 0 {
                graph.add_first(*p).expect("first");
            } else {
                let odometry = truth[k - 1].inverse() * p * drift;
                graph.add_next(odometry).expect("next");
            }
            if let Some(g) = &mut g {
                g.add_submap(k, t, &mut graph).expect("gnss");
            }
        }
        let errors = truth
            .iter()
            .enumerate()
            .map(|(k, p)| (graph.pose(k).translation.vector - p.translation.vector).norm())
            .collect();
        (errors, g)
    }

    #[test]
    fn gnss_priors_pull_a_drifting_submap_chain_back_to_the_truth() {
        // Guards the whole GNSS side against the graph: a row, a headland turn and the
        // row back, 65 submaps, the odometry drifting 6 mrad of heading per submap. The
        // gate opens in the turn (25 cached and 1.6 rad turned); then every submap but the
        // opening one has a prior, and the chain lies on the fixes.
        let (dead_reckoned, _) = run(None);
        let (with_gnss, g) = run(Some(GpsConfig {
            use_gps: true,
            ..GpsConfig::default()
        }));
        let g = g.expect("gnss");
        let worst = |e: &[f64]| e.iter().copied().fold(0.0, f64::max);
        eprintln!(
            "worst error: {:.2} m dead-reckoned, {:.3} m with GNSS; {:?}",
            worst(&dead_reckoned),
            worst(&with_gnss),
            g.counts
        );
        assert!(worst(&dead_reckoned) > 10.0, "{}", worst(&dead_reckoned));
        assert!(worst(&with_gnss) < 0.15, "{with_gnss:?}");
        assert!(*with_gnss.last().expect("end") < 0.1);
        let opened = g.counts.opened_at.expect("the gate opened");
        assert!(
            (31..=36).contains(&opened),
            "opened at submap {opened}, not in the turn"
        );
        assert_eq!(g.counts.aligned_at, Some(0));
        assert_eq!(g.counts.submaps_with_fix, 65);
        assert_eq!(
            g.counts.priors, 64,
            "every submap but the one opening the gate"
        );
        assert!(g.events.is_empty());
    }

    #[test]
    fn without_a_turn_the_gate_stays_shut() {
        // Guards gps_factor_init_angle_rad: the straight row alone never turns 1.6 rad,
        // so no prior is added and the chain keeps its drift; with the angle at 0 the
        // priors start after 25 cached.
        let straight = |angle: f64| {
            let cfg = GpsConfig {
                use_gps: true,
                gps_factor_init_angle_rad: angle,
                ..GpsConfig::default()
            };
            let mut g = SubmapGnss::new(cfg, Vector3::zeros(), UnitQuaternion::identity());
            let mut graph = SubmapGraph::new(&BackendConfig::default()).expect("graph");
            for k in 0..30usize {
                let t = k as i64 * S;
                let p = iso(2.0 * k as f64, 0.0, 0.0, 0.0, 0.0, 0.0);
                g.push(&message(t - 100 * MS, p.translation.vector, 1e-3));
                g.push(&message(t + 100 * MS, p.translation.vector, 1e-3));
                g.orientation(t, UnitQuaternion::identity());
                g.sweep(t);
                if k == 0 {
                    graph.add_first(p).expect("first");
                } else {
                    graph
                        .add_next(iso(2.0, 0.0, 0.0, 0.0, 0.0, 0.01))
                        .expect("next");
                }
                g.add_submap(k, t, &mut graph).expect("gnss");
            }
            (g.counts, graph.pose(29).translation.y)
        };
        let (shut, y) = straight(1.6);
        assert_eq!((shut.priors, shut.opened_at), (0, None));
        assert!(y > 3.0, "the drift stays: y = {y}");
        let (open, y) = straight(0.0);
        assert_eq!(open.opened_at, Some(25));
        assert_eq!(open.priors, 29);
        assert!(y.abs() < 0.2, "pulled back: y = {y}");
    }
}
