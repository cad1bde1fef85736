//! GNSS priors per submap: StaticMapping's ENU factors (`IsamOptimizer::AddFrame` and
//! `IsamOptimizer::SolveGpsCorrdAlone` in `back_end/isam_optimizer.cc`), fed one position
//! per submap as `MapBuilder::SubmapProcessing` (`builder/map_builder.cc`) takes it from
//! `DataCollector::InterpolateGps` (`builder/data/data_collector.cc`).
//!
//! **The original.** Fixes become local east-north-up coordinates about the first fixed
//! message (`DataCollector::AddSensorData`, GeographicLib's `LocalCartesian`). Each submap
//! gets the ENU position interpolated at its stamp. Its factor says that the antenna,
//! `map_origin_in_gps · pose_k · tracking_to_gps`, is at that position, with σ = 0.15 m on
//! every axis (`gps_noise_model_`); `map_origin_in_gps` (`GPS_COORD_KEY`, a `Pose3`) is a
//! variable of the graph. Until `gps_factor_init_num` submaps have a cached position and
//! some submap has turned `gps_factor_init_angle_rad` from the first
//! (`AnalyseAllFramePoseForMaxRotation`), the positions are only cached: the turn is what
//! makes the transform observable from the track. Then `SolveGpsCorrdAlone` estimates
//! `map_origin_in_gps` alone: Gauss–Newton (`relativeErrorTol` 1e-6, `maxIterations` 100)
//! over the cached factors, the poses held at their estimates by priors of σ = 0.01, and a
//! prior on the transform about its previous value (identity at first) with σ = 0.2, 0.2,
//! 1.57 rad (rotation about x, y, z) and 20 m. The result enters the graph with a prior of
//! σ = 0.1, 0.1, 0.2 rad and 1 m about it, and the cached factors are added; from then on a
//! factor joins every `gps_factor_sample_step`-th submap, and every iSAM2 update refines
//! the transform together with the poses. At the end every pose is carried into ENU by the
//! estimated transform (`MapBuilder::CalculateCoordTransformToGps`).
//!
//! **Here**, step by step:
//! 1. *Fixes* ([`Epochs`]). The receiver already gives ENU metres from the world's datum,
//!    so the original's geodetic-to-local conversion is not needed. The datum differs from
//!    the original's origin (its first fix) by a constant offset; the solve's prior is put
//!    about the first usable fix so that it says what the original's says (the map's origin
//!    near the first fix). Every epoch is kept in stamp order. An unusable one
//!    ([`plugin_api::Gnss::problem`]) is refused with a `gnss_rejected` event and kept as a
//!    gap, as the original keeps a message that is not fixed. A submap's position is
//!    `InterpolateGps`'s: linear between the fixes either side of its stamp if both are
//!    usable and at most 0.2 s apart; with a single epoch, that epoch if within 1 ms;
//!    nothing outside the fixes' span. Any usable fix (single, float, fixed) counts as the
//!    original's `STATUS_FIX`.
//! 2. *When* ([`Gate`]). The original's rules, unchanged. Like the original, the submap
//!    that opens the gate gives no prior (it is neither cached nor added in `AddFrame`).
//! 3. *The transform* (`enu_from_map`, the original's `map_origin_in_gps`;
//!    [`solve_enu_from_map`]). When the gate opens it is solved from the cached pairs
//!    alone, as `SolveGpsCorrdAlone`: each pair is the antenna in the map frame at the
//!    submap's current estimate, `p_k + R_k · lever` (the original's
//!    `transformFrom(compose(T, pose), lever)`), and the antenna's fix; the cost is
//!    `Σ ‖T · a_k − f_k‖² / 0.15²` plus the original's prior (σ = 0.2, 0.2, 1.57 rad and 20
//!    m, about identity in the local frame of step 1). No IMU orientation is used: the
//!    track's own shape fixes the heading. The parametrisation is the original's, a full
//!    pose, not a rotation about the vertical and a translation: the map frame is the first
//!    submap's lidar frame, tilted by the ground under the robot at the start (about 3° at
//!    the simulated world's S3 start), and a yaw-only transform would leave that tilt for
//!    the priors to fight across the field. Roll and pitch are observable once the track
//!    spans an area (the turn), and before that the prior keeps them near level. The
//!    differences: the poses are held exactly (the original's σ = 0.01 against the fixes'
//!    0.15 changes nothing); Gauss–Newton starts from a closed form (a 2-D Kabsch fit of x,
//!    y and the mean difference of z) so that the map's heading in ENU, which is arbitrary,
//!    cannot trap it (the original starts from identity); the prior's translation error is
//!    the plain difference, not `Pose3`'s logarithm.
//! 4. *Joint refinement, approximated.* The slam_common backends have no factor through a
//!    transform variable ([`Factor::Position`] is GTSAM's `GPSFactor`, a prior in the
//!    graph's own frame), so the transform cannot be a variable of the graph. Instead,
//!    whenever a submap gets a prior, the transform is solved again from every pair (the
//!    cached ones, those added since and the new one) at the submaps' current, already
//!    corrected estimates, under the prior the original's graph keeps on it (σ = 0.1, 0.1,
//!    0.2 rad and 1 m about the first solve). Then every prior already in the graph is
//!    removed ([`Backend::remove`]) and added again through the new transform, with the
//!    lever arm turned by its submap's current rotation, the new prior with them, and the
//!    whole graph is updated. So every prior in the graph is always its fix carried
//!    through the one current transform: none is left behind by a re-solve. This is block
//!    coordinate descent on the original's joint problem (the transform with the poses
//!    held, then the poses with the transform held), one round per prior; its fixed point
//!    is the joint optimum, which it approaches more slowly than a joint solve where the
//!    priors hold the chain tightly, most slowly along the motion that turns the transform
//!    and every submap but the held first one together (only the odometry next to that
//!    submap resists it): what the first solve took in of the drift before the gate is
//!    shed slowly, which turns the map frame and bends the chain at the first submap but
//!    leaves the rest of its shape. At every prior rather than at a cadence, because the
//!    original's transform moves at every factor too, and because the cost stays small: a
//!    solve is a 6 × 6 system over at most one pair per submap, a rebuild one factor per
//!    prior and a full update of a graph of a few hundred submaps (on S3, 161 rebuilds
//!    cost no measurable time next to the front end).
//! 5. *Priors*. A [`Factor::Position`] on the submap's pose: the antenna's fix carried into
//!    the map by the current transform, minus the lever arm turned by the submap's current
//!    rotation ([`slam_common::gnss::body_in_frame`]), with σ = 0.15 m on every axis (the
//!    original ignores the receiver's covariance too). In the original the lever arm turns
//!    with the pose inside the factor; here it is taken at the estimate whenever the prior
//!    is (re)built. Each addition or rebuild goes in with a full update, since it moves the
//!    whole chain as a loop closure does; only a first prior with none before it (the gate
//!    opened on an empty cache) goes in incrementally.
//! 6. *Output*. The trajectory and map stay in the map frame (the first submap's), the
//!    frame every other system reports in (lio-sam's GPS factors do the same). The
//!    original's final move into ENU is not done.
//!
//! [`Factor::Position`]: slam_common::factor_graph::backend::Factor::Position
//! [`Backend::remove`]: slam_common::factor_graph::backend::Backend::remove

use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use plugin_api::{Event, Gnss as GnssMessage};
use slam_common::factor_graph::backend::{BackendError, FactorId, Scope};
pub use slam_common::gnss::Fix;
use slam_common::gnss::body_in_frame;

use crate::config::GpsConfig;
use crate::graph::SubmapGraph;

/// σ of every axis of a prior, m (`gps_noise_model_ = Isotropic::Sigma(3, 0.15)`).
pub const GPS_SIGMA_M: f64 = 0.15;
/// `InterpolateGps`'s `time_threshold` as `SubmapProcessing` passes it (0.001 s): how
/// near a lone epoch must be.
const LONE_EPOCH_NS: i64 = 1_000_000;
/// Fixes more than this apart are not interpolated between (`delta_time > 0.2`).
const MAX_GAP_NS: i64 = 200_000_000;
/// `SolveGpsCorrdAlone`'s prior on the transform about its previous value: rotation about
/// x, y, z (rad), then translation (m).
pub const SOLVE_PRIOR_SIGMAS: [f64; 6] = [0.2, 0.2, 1.57, 20.0, 20.0, 20.0];
/// The prior the original's graph keeps on the transform (`GPS_COORD_KEY`) about the first
/// solve; here, the re-solves' prior.
pub const GRAPH_PRIOR_SIGMAS: [f64; 6] = [0.1, 0.1, 0.2, 1.0, 1.0, 1.0];
/// `GaussNewtonParams` as `SolveGpsCorrdAlone` sets them, and GTSAM's default absolute
/// tolerance (on half the sum of squared whitened errors).
const MAX_ITERATIONS: usize = 100;
const RELATIVE_ERROR_TOL: f64 = 1e-6;
const ABSOLUTE_ERROR_TOL: f64 = 1e-5;

/// A prior on `enu_from_map`: its mean and σ (rotation about the mean's x, y, z axes,
/// rad, as `Log(mean⁻¹ · T)`; then translation, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransformPrior {
    pub mean: Isometry3<f64>,
    pub sigmas: [f64; 6],
}

/// One pair of the solve: the antenna in the map frame (`p_k + R_k · lever` at the
/// submap's current estimate) and its fix, the antenna in ENU, m.
pub type Pair = (Vector3<f64>, Vector3<f64>);

/// The inverse of SO(3)'s right Jacobian at `phi`: `d Log(R · exp(δ)) / dδ` at `R = exp(phi)`.
fn right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = phi.cross_matrix();
    let c = if theta < 1e-6 {
        1.0 / 12.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() + 0.5 * k + c * k * k
}

/// The rotation about the vertical and the translation that best carry the map points
/// onto the ENU points in x and y (2-D Kabsch about the centroids), with the mean
/// difference in z; `None` without pairs.
pub fn level_fit(pairs: &[Pair]) -> Option<Isometry3<f64>> {
    if pairs.is_empty() {
        return None;
    }
    let n = pairs.len() as f64;
    let a_mean = pairs.iter().map(|(a, _)| a).sum::<Vector3<f64>>() / n;
    let f_mean = pairs.iter().map(|(_, f)| f).sum::<Vector3<f64>>() / n;
    let (mut sin, mut cos) = (0.0, 0.0);
    for (a, f) in pairs {
        let (a, f) = (a - a_mean, f - f_mean);
        cos += a.x * f.x + a.y * f.y;
        sin += a.x * f.y - a.y * f.x;
    }
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), sin.atan2(cos));
    Some(Isometry3::from_parts(
        Translation3::from(f_mean - rotation * a_mean),
        rotation,
    ))
}

/// Half the sum of squared whitened errors of the pairs and the prior at `t` (GTSAM's
/// graph error).
fn solve_cost(pairs: &[Pair], prior: &TransformPrior, t: &Isometry3<f64>) -> f64 {
    let fixes: f64 = pairs
        .iter()
        .map(|(a, f)| ((t * Point3::from(*a)).coords - f).norm_squared())
        .sum::<f64>()
        / (GPS_SIGMA_M * GPS_SIGMA_M);
    let e = prior_error(prior, t);
    0.5 * (fixes + e.norm_squared())
}

/// The prior's whitened error at `t`.
fn prior_error(prior: &TransformPrior, t: &Isometry3<f64>) -> Vector6<f64> {
    let phi = (prior.mean.rotation.inverse() * t.rotation).scaled_axis();
    let dt = t.translation.vector - prior.mean.translation.vector;
    let s = &prior.sigmas;
    Vector6::new(
        phi.x / s[0],
        phi.y / s[1],
        phi.z / s[2],
        dt.x / s[3],
        dt.y / s[4],
        dt.z / s[5],
    )
}

/// `SolveGpsCorrdAlone`: the `enu_from_map` that minimises `Σ ‖T · a_k − f_k‖² / 0.15²`
/// over the pairs plus the prior, by Gauss–Newton from [`level_fit`] (the prior's mean
/// without pairs). `T` is perturbed as `(R · exp(ω), t + δ)`.
pub fn solve_enu_from_map(pairs: &[Pair], prior: &TransformPrior) -> Isometry3<f64> {
    let mut t = level_fit(pairs).unwrap_or(prior.mean);
    let mut cost = solve_cost(pairs, prior, &t);
    let w = 1.0 / GPS_SIGMA_M;
    for _ in 0..MAX_ITERATIONS {
        let mut h = Matrix6::<f64>::zeros();
        let mut g = Vector6::<f64>::zeros();
        let r = t.rotation.to_rotation_matrix().into_inner();
        for (a, f) in pairs {
            let e = ((t * Point3::from(*a)).coords - f) * w;
            let mut j = nalgebra::Matrix3x6::<f64>::zeros();
            j.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(-r * a.cross_matrix() * w));
            j.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&(Matrix3::identity() * w));
            h += j.transpose() * j;
            g += j.transpose() * e;
        }
        let e = prior_error(prior, &t);
        let phi = (prior.mean.rotation.inverse() * t.rotation).scaled_axis();
        let mut j = Matrix6::<f64>::zeros();
        let jr = right_jacobian_inverse(&phi);
        for i in 0..3 {
            for c in 0..3 {
                j[(i, c)] = jr[(i, c)] / prior.sigmas[i];
            }
            j[(3 + i, 3 + i)] = 1.0 / prior.sigmas[3 + i];
        }
        h += j.transpose() * j;
        g += j.transpose() * e;
        let Some(step) = h.cholesky().map(|c| c.solve(&(-g))) else {
            break;
        };
        t = Isometry3::from_parts(
            Translation3::from(t.translation.vector + step.fixed_rows::<3>(3)),
            t.rotation * UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(0).into_owned()),
        );
        // GTSAM's `checkConvergence`: a decrease below either tolerance (or an increase).
        let next = solve_cost(pairs, prior, &t);
        let decrease = cost - next;
        let converged = decrease <= ABSOLUTE_ERROR_TOL || decrease <= RELATIVE_ERROR_TOL * cost;
        cost = next;
        if converged {
            break;
        }
    }
    t
}

/// The heading (z-y-x yaw) and the tilt (the angle between the frames' vertical axes) of
/// a rotation, rad.
pub fn yaw_and_tilt(r: &UnitQuaternion<f64>) -> (f64, f64) {
    let z = r * Vector3::z();
    (slam_common::gnss::yaw(r), z.z.clamp(-1.0, 1.0).acos())
}

/// Every GNSS epoch in stamp order: a usable fix, or `None` for a refused one.
#[derive(Debug, Clone, Default)]
pub struct Epochs {
    epochs: Vec<(i64, Option<Fix>)>,
}

impl Epochs {
    /// Keeps the epoch; a fix that cannot be used becomes a gap and a `gnss_rejected`
    /// event.
    pub fn push(&mut self, gnss: &GnssMessage, events: &mut Vec<Event>) {
        let fix = match gnss.usable() {
            Ok((position_enu_m, covariance_enu_m2)) => Some(Fix {
                stamp_ns: gnss.stamp_ns,
                position_enu_m,
                covariance_enu_m2,
            }),
            Err(problem) => {
                events.push(gnss.rejected("staticmapping", problem));
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

    /// The first usable fix in stamp order: the original's local origin.
    pub fn first_fix(&self) -> Option<Fix> {
        self.epochs.iter().find_map(|(_, f)| *f)
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
/// GNSS branch; step 2 of the module's documentation).
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

    /// Submap `k` with its position `fix`, `max_rotation` the submaps' [`max_rotation`]
    /// (asked for only once enough positions are cached): the positions to turn into
    /// priors now (when it opens, the cached ones, maybe none).
    pub fn step(
        &mut self,
        k: usize,
        fix: Fix,
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
        if self.cached.len() < cfg.gps_factor_init_num
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
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GnssCounts {
    /// Submaps that had a position at their stamp.
    pub submaps_with_fix: usize,
    /// Priors in the graph (one per submap; a rebuild does not count again).
    pub priors: usize,
    /// The submap at which the gate opened and the transform was first solved.
    pub opened_at: Option<usize>,
    /// Times the transform was solved (the first and every re-solve).
    pub solves: usize,
    /// Times the priors already in the graph were removed and added again through a
    /// re-solved transform.
    pub rebuilds: usize,
    /// RMS of `‖T · a_k − f_k‖` over the pairs of the last solve, m.
    pub last_rms_m: f64,
}

/// The GNSS side of the build: the epochs, the gate, the transform and the priors in the
/// graph.
#[derive(Debug, Clone)]
pub struct SubmapGnss {
    epochs: Epochs,
    gate: Gate,
    /// The antenna in the lidar frame (the submaps' frame), from the rig.
    lidar_from_antenna: Vector3<f64>,
    /// The first solve (the mean of the re-solves' prior) and the current transform.
    first_solve: Option<Isometry3<f64>>,
    enu_from_map: Option<Isometry3<f64>>,
    /// The priors in the graph: submap, fix, factor; all through `enu_from_map`.
    priors: Vec<(usize, Fix, FactorId)>,
    /// `gnss_rejected` events.
    pub events: Vec<Event>,
    pub counts: GnssCounts,
}

impl SubmapGnss {
    pub fn new(cfg: GpsConfig, lidar_from_antenna: Vector3<f64>) -> Self {
        Self {
            epochs: Epochs::default(),
            gate: Gate::new(cfg),
            lidar_from_antenna,
            first_solve: None,
            enu_from_map: None,
            priors: Vec::new(),
            events: Vec::new(),
            counts: GnssCounts::default(),
        }
    }

    /// The current transform from the fixes' ENU frame into the map, once solved.
    pub fn map_from_enu(&self) -> Option<Isometry3<f64>> {
        self.enu_from_map.map(|t| t.inverse())
    }

    /// The transform's first solve and its current value (`enu_from_map`), once solved.
    pub fn solves(&self) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
        self.first_solve.zip(self.enu_from_map)
    }

    /// The antenna's position in the lidar frame.
    pub fn lidar_from_antenna(&self) -> Vector3<f64> {
        self.lidar_from_antenna
    }

    /// A GNSS epoch ([`Epochs::push`]).
    pub fn push(&mut self, gnss: &GnssMessage) {
        self.epochs.push(gnss, &mut self.events);
    }

    /// The pairs of the solve for `submaps`: the antenna in the map at each submap's
    /// current estimate, and its fix.
    fn pairs(&self, submaps: &[(usize, Fix)], graph: &SubmapGraph) -> Vec<Pair> {
        submaps
            .iter()
            .map(|(j, f)| {
                let antenna = graph.pose(*j) * Point3::from(self.lidar_from_antenna);
                (antenna.coords, f.position_enu_m)
            })
            .collect()
    }

    /// Solves the transform from the pairs of `submaps` under `prior` and keeps it.
    fn solve(&mut self, submaps: &[(usize, Fix)], prior: &TransformPrior, graph: &SubmapGraph) {
        let pairs = self.pairs(submaps, graph);
        let t = solve_enu_from_map(&pairs, prior);
        self.counts.solves += 1;
        self.counts.last_rms_m = if pairs.is_empty() {
            0.0
        } else {
            (pairs
                .iter()
                .map(|(a, f)| ((t * Point3::from(*a)).coords - f).norm_squared())
                .sum::<f64>()
                / pairs.len() as f64)
                .sqrt()
        };
        self.enu_from_map = Some(t);
    }

    /// The GNSS part of `AddFrame` for submap `k`, stamped `stamp_ns`, just added to
    /// `graph` (after its loops): its position, the gate, the first solve when it opens or
    /// the re-solve and the rebuild of the priors when it lets a position through.
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
        let was_open = self.gate.is_open();
        let chosen = self.gate.step(k, fix, || {
            max_rotation((0..=k).map(|j| graph.pose(j).rotation))
        });
        if !self.gate.is_open() {
            return Ok(());
        }
        if !was_open {
            // SolveGpsCorrdAlone: from the cached pairs, about identity in the original's
            // local frame (the first fix as origin).
            self.counts.opened_at = Some(k);
            let origin = self.epochs.first_fix().unwrap_or(fix).position_enu_m;
            let prior = TransformPrior {
                mean: Isometry3::translation(origin.x, origin.y, origin.z),
                sigmas: SOLVE_PRIOR_SIGMAS,
            };
            self.solve(&chosen, &prior, graph);
            self.first_solve = self.enu_from_map;
            return self.add_priors(chosen, graph, Scope::Full);
        }
        if chosen.is_empty() {
            return Ok(());
        }
        // The joint refinement, approximated (step 4): every pair at the current
        // estimates, under the graph's prior about the first solve, then every prior
        // through the new transform.
        let mut submaps: Vec<(usize, Fix)> = self.priors.iter().map(|&(j, f, _)| (j, f)).collect();
        submaps.extend(chosen);
        let prior = TransformPrior {
            mean: self.first_solve.expect("solved when the gate opened"),
            sigmas: GRAPH_PRIOR_SIGMAS,
        };
        self.solve(&submaps, &prior, graph);
        let old: Vec<FactorId> = self.priors.drain(..).map(|(_, _, id)| id).collect();
        let scope = if old.is_empty() {
            Scope::Incremental
        } else {
            self.counts.rebuilds += 1;
            graph.remove_factors(&old);
            Scope::Full
        };
        self.add_priors(submaps, graph, scope)
    }

    /// Adds the priors of `submaps` through the current transform and updates with `scope`.
    fn add_priors(
        &mut self,
        submaps: Vec<(usize, Fix)>,
        graph: &mut SubmapGraph,
        scope: Scope,
    ) -> Result<(), BackendError> {
        let map_from_enu = self.map_from_enu().expect("solved before any prior");
        let targets: Vec<(usize, Vector3<f64>)> = submaps
            .iter()
            .map(|(j, f)| {
                let rotation = graph.pose(*j).rotation;
                let (position, _) =
                    body_in_frame(&map_from_enu, f, &rotation, &self.lidar_from_antenna);
                (*j, position)
            })
            .collect();
        let ids = graph.add_positions(&targets, GPS_SIGMA_M, scope)?;
        self.priors
            .extend(submaps.into_iter().zip(ids).map(|((j, f), id)| (j, f, id)));
        self.counts.priors = self.priors.len();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Matrix3;
    use plugin_api::{EventKind, GnssStatus};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
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
        let mut g = SubmapGnss::new(GpsConfig::default(), Vector3::zeros());
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
        // Guards AddFrame's GNSS branch: cache until gps_factor_init_num are cached and a
        // turn of gps_factor_init_angle_rad; then the cached ones (not the opening
        // submap's); then every gps_factor_sample_step-th submap.
        let cfg = GpsConfig {
            use_gps: true,
            gps_factor_init_num: 3,
            gps_factor_init_angle_rad: 1.5,
            gps_factor_sample_step: 2,
        };
        let mut gate = Gate::new(cfg);
        let mut asked = 0;
        for k in 0..3 {
            let out = gate.step(k, fix(k as i64, k as f64), || {
                asked += 1;
                3.0
            });
            assert!(out.is_empty());
        }
        assert_eq!(asked, 0, "the turn is asked for only with enough cached");
        for k in 3..5 {
            assert!(
                gate.step(k, fix(k as i64, k as f64), || 1.4).is_empty(),
                "no turn yet"
            );
        }
        assert!(!gate.is_open());
        let out = gate.step(5, fix(5, 5.0), || 1.6);
        assert!(gate.is_open());
        let ks: Vec<usize> = out.iter().map(|(k, _)| *k).collect();
        assert_eq!(ks, [0, 1, 2, 3, 4], "the cached, without submap 5");
        assert_eq!(out[3].1.position_enu_m.x, 3.0);
        let later: Vec<usize> = (6..12)
            .flat_map(|k| gate.step(k, fix(k as i64, 0.0), || 0.0))
            .map(|(k, _)| k)
            .collect();
        assert_eq!(later, [6, 8, 10]);
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

    /// A row and its headland turn (the first 36 submaps of [`row_and_back`], what the
    /// gate has seen when it opens), each submap rolling and pitching on the ground.
    fn row_and_turn() -> Vec<Isometry3<f64>> {
        row_and_back()[..36]
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let k = k as f64;
                let wobble =
                    UnitQuaternion::from_euler_angles(0.03 * k.sin(), 0.02 * (0.7 * k).cos(), 0.0);
                Isometry3::from_parts(p.translation, p.rotation * wobble)
            })
            .collect()
    }

    /// The pairs of a track: the antenna (`lever` on each pose) in the map, and in ENU
    /// through `enu_from_map` with uniform noise of ±`noise_m` on every axis.
    fn pairs_of(
        track: &[Isometry3<f64>],
        enu_from_map: &Isometry3<f64>,
        lever: &Vector3<f64>,
        noise_m: f64,
    ) -> Vec<Pair> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        track
            .iter()
            .map(|p| {
                let antenna = p * Point3::from(*lever);
                let noise = Vector3::from_fn(|_, _| rng.random_range(-noise_m..=noise_m));
                (antenna.coords, (enu_from_map * antenna).coords + noise)
            })
            .collect()
    }

    /// `SolveGpsCorrdAlone`'s prior, about the first fix.
    fn prior_about_first(pairs: &[Pair]) -> TransformPrior {
        let o = pairs[0].1;
        TransformPrior {
            mean: Isometry3::translation(o.x, o.y, o.z),
            sigmas: SOLVE_PRIOR_SIGMAS,
        }
    }

    #[test]
    fn the_transform_is_solved_from_a_track_with_a_turn() {
        // Guards solve_enu_from_map: from a row and its turn, with the antenna 0.7 m up
        // and behind on submaps that roll and pitch, it recovers the ENU-to-map transform
        // (any heading, a tilted map frame): exactly without noise and a negligible prior,
        // within a millirad with the original's, and with ±5 cm of noise per axis to a
        // millirad in heading and 10 mrad in tilt (the roll about the row rests on the
        // turn's 6 m, about 3 mrad for one σ); the fixes it carries into the map land on
        // the antennas. The closed-form start is exact for a level transform.
        let lever = Vector3::new(-0.2, 0.0, 0.7);
        let track = row_and_turn();
        for truth in [
            iso(250.0, -80.0, 12.0, 0.03, -0.02, 0.7),
            iso(-40.0, 900.0, -3.0, -0.01, 0.02, 2.9),
            iso(5.0, 5.0, 0.0, 0.0, 0.0, -2.5),
        ] {
            let exact = pairs_of(&track, &truth, &lever, 0.0);
            let negligible = TransformPrior {
                sigmas: [1e6; 6],
                ..prior_about_first(&exact)
            };
            let error = solve_enu_from_map(&exact, &negligible).inverse() * truth;
            assert!(
                error.rotation.angle() < 1e-9 && error.translation.vector.norm() < 1e-7,
                "{truth}: {error}"
            );
            // The original's prior draws the tilt a little towards level.
            let error = solve_enu_from_map(&exact, &prior_about_first(&exact)).inverse() * truth;
            assert!(
                error.rotation.angle() < 1e-3 && error.translation.vector.norm() < 1e-2,
                "{truth}: {error}"
            );
            let noisy = pairs_of(&track, &truth, &lever, 0.05);
            let found = solve_enu_from_map(&noisy, &prior_about_first(&noisy));
            let error = found.inverse() * truth;
            let (yaw_error, tilt_error) = yaw_and_tilt(&error.rotation);
            let worst = exact
                .iter()
                .map(|(a, f)| ((found.inverse() * Point3::from(*f)).coords - a).norm())
                .fold(0.0, f64::max);
            eprintln!(
                "yaw error {:.2e} rad, tilt error {:.2e} rad, worst antenna {:.3} m",
                yaw_error, tilt_error, worst
            );
            assert!(yaw_error.abs() < 1e-3, "{truth}: yaw off by {yaw_error}");
            assert!(tilt_error < 1e-2, "{truth}: tilt off by {tilt_error}");
            assert!(worst < 0.05, "{truth}: an antenna {worst} m off");
        }
        let level = iso(-40.0, 900.0, -3.0, 0.0, 0.0, 2.9);
        let fit = level_fit(&pairs_of(&track, &level, &lever, 0.0)).expect("pairs");
        let error = fit.inverse() * level;
        assert!(error.rotation.angle() < 1e-12 && error.translation.vector.norm() < 1e-9);
        assert!(level_fit(&[]).is_none());
    }

    #[test]
    fn without_pairs_or_an_area_the_prior_holds_what_the_track_cannot_tell() {
        // Guards the prior: with no pair the solve is the prior's mean; along a straight
        // row the roll about the row is unobservable and stays at the prior's (level),
        // while the heading and the rest come from the fixes.
        let prior = TransformPrior {
            mean: iso(3.0, 4.0, 5.0, 0.0, 0.0, 0.0),
            sigmas: SOLVE_PRIOR_SIGMAS,
        };
        assert_eq!(solve_enu_from_map(&[], &prior), prior.mean);
        let truth = iso(250.0, -80.0, 12.0, 0.0, 0.0, 0.7);
        let row: Vec<Isometry3<f64>> = (0..25)
            .map(|i| iso(2.0 * f64::from(i), 0.0, 0.0, 0.0, 0.0, 0.0))
            .collect();
        let pairs = pairs_of(&row, &truth, &Vector3::zeros(), 0.0);
        let found = solve_enu_from_map(&pairs, &prior_about_first(&pairs));
        let error = found.inverse() * truth;
        assert!(
            error.rotation.angle() < 1e-5 && error.translation.vector.norm() < 1e-4,
            "{error}"
        );
    }

    /// How [`run`] finds the transform of its priors.
    #[derive(Debug, Clone, Copy)]
    enum Alignment {
        /// This module's: solved from the track when the gate opens, re-solved at every
        /// prior.
        Solved,
        /// The previous design's, navsat_transform's (`slam_common::gnss::frame_from_enu`):
        /// fixed at submap 0 by an AHRS whose heading is off by this many rad, the priors
        /// through it from the same gate.
        Ahrs(f64),
    }

    /// Runs the submap chain (`truth`, lidar poses in the map frame) through the graph:
    /// the odometry of every step turned by 6 mrad in heading, and with `alignment`, fixes
    /// (`enu_from_map`, the antenna 0.7 m up and 0.2 m behind, ±3 cm of noise) 0.1 s
    /// either side of every submap. The submaps' estimates, the `enu_from_map` the priors
    /// went through (the truth without GNSS), and the GNSS side when solved.
    fn run(
        truth: &[Isometry3<f64>],
        enu_from_map: Isometry3<f64>,
        alignment: Option<Alignment>,
        cfg: GpsConfig,
    ) -> (Vec<Isometry3<f64>>, Isometry3<f64>, Option<SubmapGnss>) {
        let lever = Vector3::new(-0.2, 0.0, 0.7);
        let drift = iso(0.0, 0.0, 0.0, 0.0, 0.0, 0.006);
        let mut g = SubmapGnss::new(cfg.clone(), lever);
        let mut gate = Gate::new(cfg);
        let mut ahrs_frame = None;
        let mut graph = SubmapGraph::new(&BackendConfig::default()).expect("graph");
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (k, p) in truth.iter().enumerate() {
            let t = k as i64 * S;
            let noise = Vector3::from_fn(|_, _| rng.random_range(-0.03..=0.03));
            let antenna = (enu_from_map * p * Point3::from(lever)).coords + noise;
            if k == 0 {
                graph.add_first(*p).expect("first");
            } else {
                let odometry = truth[k - 1].inverse() * p * drift;
                graph.add_next(odometry).expect("next");
            }
            match alignment {
                None => {}
                Some(Alignment::Solved) => {
                    g.push(&message(t - 100 * MS, antenna, 1e-3));
                    g.push(&message(t + 100 * MS, antenna, 1e-3));
                    g.add_submap(k, t, &mut graph).expect("gnss");
                }
                Some(Alignment::Ahrs(heading_error)) => {
                    let f = Fix {
                        stamp_ns: t,
                        position_enu_m: antenna,
                        covariance_enu_m2: Matrix3::identity(),
                    };
                    let map_from_enu = *ahrs_frame.get_or_insert_with(|| {
                        let ahrs = UnitQuaternion::from_euler_angles(0.0, 0.0, heading_error)
                            * (enu_from_map * p).rotation;
                        let pose = graph.pose(k);
                        slam_common::gnss::frame_from_enu(
                            &pose.translation.vector,
                            slam_common::gnss::yaw(&pose.rotation),
                            &ahrs,
                            &lever,
                            &antenna,
                        )
                    });
                    let was_open = gate.is_open();
                    let chosen = gate.step(k, f, || {
                        max_rotation((0..=k).map(|j| graph.pose(j).rotation))
                    });
                    let priors: Vec<(usize, Vector3<f64>)> = chosen
                        .iter()
                        .map(|(j, f)| {
                            let r = graph.pose(*j).rotation;
                            (*j, body_in_frame(&map_from_enu, f, &r, &lever).0)
                        })
                        .collect();
                    let scope = if was_open {
                        Scope::Incremental
                    } else {
                        Scope::Full
                    };
                    graph
                        .add_positions(&priors, GPS_SIGMA_M, scope)
                        .expect("priors");
                }
            }
        }
        let poses = (0..truth.len()).map(|k| graph.pose(k)).collect();
        let used = match alignment {
            None => enu_from_map,
            Some(Alignment::Solved) => g.map_from_enu().expect("solved").inverse(),
            Some(Alignment::Ahrs(_)) => ahrs_frame.expect("aligned").inverse(),
        };
        (
            poses,
            used,
            matches!(alignment, Some(Alignment::Solved)).then_some(g),
        )
    }

    /// How far each submap's estimate is from the truth: `in_map`, in the map frame as
    /// estimated; `in_enu`, both carried into ENU, each by its own transform (how the
    /// original reports the map, `CalculateCoordTransformToGps`); `shape`, after the best
    /// rigid alignment of the estimates onto the truth (Umeyama; how the benchmark
    /// scores a trajectory).
    struct Errors {
        in_map: Vec<f64>,
        in_enu: Vec<f64>,
        shape: Vec<f64>,
    }

    fn errors(
        poses: &[Isometry3<f64>],
        enu_from_map: &Isometry3<f64>,
        truth: &[Isometry3<f64>],
        true_enu_from_map: &Isometry3<f64>,
    ) -> Errors {
        let est: Vec<Vector3<f64>> = poses.iter().map(|p| p.translation.vector).collect();
        let tru: Vec<Vector3<f64>> = truth.iter().map(|p| p.translation.vector).collect();
        let n = est.len() as f64;
        let (me, mt) = (
            est.iter().sum::<Vector3<f64>>() / n,
            tru.iter().sum::<Vector3<f64>>() / n,
        );
        let h: Matrix3<f64> = est
            .iter()
            .zip(&tru)
            .map(|(e, t)| (t - mt) * (e - me).transpose())
            .sum();
        let svd = h.svd(true, true);
        let (u, v_t) = (svd.u.expect("u"), svd.v_t.expect("v"));
        let d = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, (u * v_t).determinant()));
        let r = u * d * v_t;
        Errors {
            in_map: est.iter().zip(&tru).map(|(e, t)| (e - t).norm()).collect(),
            in_enu: poses
                .iter()
                .zip(truth)
                .map(|(p, t)| {
                    ((enu_from_map * p).translation.vector
                        - (true_enu_from_map * t).translation.vector)
                        .norm()
                })
                .collect(),
            shape: est
                .iter()
                .zip(&tru)
                .map(|(e, t)| (r * (e - me) + mt - t).norm())
                .collect(),
        }
    }

    fn worst(e: &[f64]) -> f64 {
        e.iter().copied().fold(0.0, f64::max)
    }

    fn gps_on() -> GpsConfig {
        GpsConfig {
            use_gps: true,
            ..GpsConfig::default()
        }
    }

    #[test]
    fn gnss_priors_pull_a_drifting_submap_chain_back_to_the_truth() {
        // Guards the whole GNSS side against the graph: a row, a headland turn and the
        // row back, 65 submaps, the odometry drifting 6 mrad of heading per submap. The
        // gate opens in the turn (25 cached and 1.6 rad turned); the transform is solved
        // from the drifted chain, then re-solved at every prior with the corrected one;
        // every submap but the opening one has a prior. Carried into ENU by the estimated
        // transform, as the original reports it, the chain lies on the fixes, and its
        // shape on the truth's. In the map frame it stays turned about the held first
        // submap by what the transform has not shed of the first solve's drift: the
        // re-solves (block coordinate descent) shed it slowly, since the chain they read
        // was bent onto the previous transform.
        let truth = row_and_back();
        let enu_from_map = iso(250.0, -80.0, 12.0, 0.0, 0.0, 0.7);
        let (poses, _, _) = run(&truth, enu_from_map, None, gps_on());
        let dead_reckoned = errors(&poses, &enu_from_map, &truth, &enu_from_map);
        let (poses, used, g) = run(&truth, enu_from_map, Some(Alignment::Solved), gps_on());
        let with_gnss = errors(&poses, &used, &truth, &enu_from_map);
        let g = g.expect("gnss");
        let (first, last) = g.solves().expect("solved");
        let off = |t: &Isometry3<f64>| (t.inverse() * enu_from_map).rotation.angle();
        eprintln!(
            "worst error: {:.2} m dead-reckoned; with GNSS {:.3} m in ENU, {:.3} m in shape, \
             {:.3} m in the map frame; {:?}; first solve off by {:.4} rad, last by {:.4} rad",
            worst(&dead_reckoned.in_enu),
            worst(&with_gnss.in_enu),
            worst(&with_gnss.shape),
            worst(&with_gnss.in_map),
            g.counts,
            off(&first),
            off(&last),
        );
        assert!(worst(&dead_reckoned.in_enu) > 10.0);
        assert!(worst(&dead_reckoned.shape) > 5.0);
        assert!(worst(&with_gnss.in_enu) < 0.15, "{:?}", with_gnss.in_enu);
        assert!(*with_gnss.in_enu.last().expect("end") < 0.1);
        assert!(worst(&with_gnss.shape) < 0.15, "{:?}", with_gnss.shape);
        assert!(off(&first) > 0.08 && off(&last) < 0.075, "{first} {last}");
        assert!(worst(&with_gnss.in_map) < 4.5, "{:?}", with_gnss.in_map);
        let opened = g.counts.opened_at.expect("the gate opened");
        assert!(
            (31..=36).contains(&opened),
            "opened at submap {opened}, not in the turn"
        );
        assert_eq!(g.counts.submaps_with_fix, 65);
        assert_eq!(
            g.counts.priors, 64,
            "every submap but the one opening the gate"
        );
        let later = 64 - opened;
        assert_eq!(g.counts.solves, 1 + later, "the first, then one per prior");
        assert_eq!(g.counts.rebuilds, later);
        assert!(g.counts.last_rms_m < 0.05, "{:?}", g.counts);
        assert!(g.events.is_empty());
    }

    #[test]
    fn an_ahrs_heading_error_no_longer_enters() {
        // Guards the point of solving the transform from the track, on the drifting chain
        // above, with the map frame level or tilted 2° (a robot standing on a bump at the
        // start, on level ground). The previous design aligned ENU with the map at submap
        // 0 by the AHRS's heading, yaw only: 1° of heading error (the simulated IMU's σ)
        // turned every prior, and the map frame's tilt was left out. The solve reads no
        // heading and takes the tilt in: the chain is pulled back onto the truth in ENU
        // and in shape either way. For the record, the previous design's heading error
        // turned the map frame about submap 0 (over 0.5 m at the far end) but, the priors'
        // transform being rigid, hardly bent the chain's shape.
        let level = iso(250.0, -80.0, 12.0, 0.0, 0.0, 0.7);
        let tilted = iso(250.0, -80.0, 12.0, 0.035, -0.02, 0.7);
        let on_level_ground: Vec<Isometry3<f64>> = row_and_back()
            .iter()
            .map(|p| tilted.inverse() * level * p)
            .collect();
        let one_degree = Some(Alignment::Ahrs(1f64.to_radians()));
        for (name, truth, enu_from_map) in [
            ("level", row_and_back(), level),
            ("tilted", on_level_ground, tilted),
        ] {
            let (poses, used, g) = run(&truth, enu_from_map, Some(Alignment::Solved), gps_on());
            let solved = errors(&poses, &used, &truth, &enu_from_map);
            let (poses, used, _) = run(&truth, enu_from_map, one_degree, gps_on());
            let ahrs = errors(&poses, &used, &truth, &enu_from_map);
            let (_, tilt) = yaw_and_tilt(&(used.inverse() * enu_from_map).rotation);
            eprintln!(
                "{name}: solved {:.3} m in ENU, {:.3} m in shape ({:?}); the AHRS 1° off: \
                 {:.3} m in the map frame, {:.3} m in shape, its transform's tilt off by \
                 {:.4} rad",
                worst(&solved.in_enu),
                worst(&solved.shape),
                g.expect("gnss").counts,
                worst(&ahrs.in_map),
                worst(&ahrs.shape),
                tilt
            );
            assert!(worst(&solved.in_enu) < 0.15, "{name}: {:?}", solved.in_enu);
            assert!(*solved.in_enu.last().expect("end") < 0.1, "{name}");
            assert!(worst(&solved.shape) < 0.15, "{name}: {:?}", solved.shape);
            assert!(worst(&ahrs.in_map) > 0.5, "{name}: {:?}", ahrs.in_map);
        }
    }

    #[test]
    fn without_a_turn_the_gate_stays_shut() {
        // Guards gps_factor_init_angle_rad: the straight row alone never turns 1.6 rad,
        // so no prior is added and the chain keeps its drift; with the angle at 0 the
        // priors start after 25 cached, and the chain carried into ENU by the transform
        // solved from the bent row lies on the fixes (the truth's ENU is the map).
        let straight = |angle: f64| {
            let cfg = GpsConfig {
                use_gps: true,
                gps_factor_init_angle_rad: angle,
                ..GpsConfig::default()
            };
            let mut g = SubmapGnss::new(cfg, Vector3::zeros());
            let mut graph = SubmapGraph::new(&BackendConfig::default()).expect("graph");
            for k in 0..30usize {
                let t = k as i64 * S;
                let p = iso(2.0 * k as f64, 0.0, 0.0, 0.0, 0.0, 0.0);
                g.push(&message(t - 100 * MS, p.translation.vector, 1e-3));
                g.push(&message(t + 100 * MS, p.translation.vector, 1e-3));
                if k == 0 {
                    graph.add_first(p).expect("first");
                } else {
                    graph
                        .add_next(iso(2.0, 0.0, 0.0, 0.0, 0.0, 0.01))
                        .expect("next");
                }
                g.add_submap(k, t, &mut graph).expect("gnss");
            }
            let enu_from_map = g
                .map_from_enu()
                .map_or(Isometry3::identity(), |t| t.inverse());
            (g.counts, (enu_from_map * graph.pose(29)).translation.y)
        };
        let (shut, y) = straight(1.6);
        assert_eq!((shut.priors, shut.opened_at, shut.solves), (0, None, 0));
        assert!(y > 3.0, "the drift stays: y = {y}");
        assert_eq!(shut.submaps_with_fix, 30);
        let (open, y) = straight(0.0);
        assert_eq!(open.opened_at, Some(25));
        assert_eq!((open.priors, open.solves, open.rebuilds), (29, 5, 4));
        assert!(y.abs() < 0.2, "pulled back: y = {y}");
    }
}
