//! The plugin: state between messages and the per-sweep pipeline.

use std::fmt::Write as _;

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
use plugin_api::{
    Event, EventKind, Gnss as GnssMessage, Imu, MapStart, Parameters, PluginError, PointCloud,
    Pose, PoseStatus, Requirements, Rig, SavedMap, SensorKind, SlamOutput, SlamSystem,
};
use slam_common::factor_graph::backend::ImuBias;
use slam_common::maps::keyframes::{
    KEYFRAME_MAP_FORMAT, KEYFRAME_MAP_VERSION, KeyframeMap, MapKeyframe, reads_version,
};
use slam_common::maps::localizer::MapLocalizer;
use slam_common::motion::imu::NavState;
use slam_common::registration::voxel::downsample;

use crate::config::Config;
use crate::deskew::{SweepLayout, rings};
use crate::features::{Features, extract};
use crate::gnss::{Gnss, KeyframeState, Orientations, usable, yaw};
use crate::graph::KeyframeGraph;
use crate::imu_odometry::{Correction, ImuOdometry};
use crate::keyframe::KeyframeView;
use crate::local_map::LocalMap;
use crate::loop_closure::{candidate, verify};
use crate::motion::{ImuQueue, Motion, propagate};
use crate::registration::{Registration, register};

/// Sweeps over which the lidar-only motion model measures velocity.
const VELOCITY_BASELINE: usize = 5;

/// A keyframe: when, its features (lidar frame), and its pose as registered.
#[derive(Debug)]
struct Keyframe {
    stamp_ns: i64,
    features: Features,
    registered_world_from_lidar: Isometry3<f64>,
}

/// Every sweep's pose relative to the keyframe it was registered after, so that the final
/// trajectory follows the optimised keyframes.
#[derive(Debug, Clone, Copy)]
struct SweepRecord {
    stamp_ns: i64,
    keyframe: usize,
    keyframe_from_lidar: Isometry3<f64>,
}

/// The columns of `trace_csv`, one line per sweep.
pub const TRACE_HEADER: &str = "stamp_ns,outcome,iterations,scan_edges,scan_surfs,edge_matches,surf_matches,degenerate_directions,degenerate,speed_mps,bias_accel_mps2,bias_gyro_radps,keyframe,loop,reset";

/// One sweep of the trace (`trace_csv`).
#[derive(Debug, Clone)]
struct TraceRow {
    stamp_ns: i64,
    /// `registered`, `first` (the first sweep), or the [`Refusal`]'s name.
    outcome: &'static str,
    registration: Option<Registration>,
    scan_edges: usize,
    scan_surfs: usize,
    speed_mps: f64,
    bias_accel_mps2: f64,
    bias_gyro_radps: f64,
    keyframe: bool,
    loop_closed: bool,
    /// The IMU state failed its check and was reset at this sweep.
    reset: bool,
}

impl TraceRow {
    fn line(&self) -> String {
        let r = self.registration;
        format!(
            "{},{},{},{},{},{},{},{},{},{:.6},{:.6},{:.6},{},{},{}",
            self.stamp_ns,
            self.outcome,
            r.map_or(0, |r| r.iterations),
            self.scan_edges,
            self.scan_surfs,
            r.map_or(0, |r| r.edge_matches),
            r.map_or(0, |r| r.surf_matches),
            r.map_or(0, |r| r.degenerate_directions),
            u8::from(r.is_some_and(|r| r.degenerate)),
            self.speed_mps,
            self.bias_accel_mps2,
            self.bias_gyro_radps,
            u8::from(self.keyframe),
            u8::from(self.loop_closed),
            u8::from(self.reset),
        )
    }
}

/// LIO-SAM-style lidar-inertial SLAM.
#[derive(Debug)]
pub struct LioSam {
    cfg: Config,
    imu_from_lidar: Isometry3<f64>,
    lidar_from_base: Isometry3<f64>,
    /// Sweep duration and columns per sweep, to find a point's column from its time.
    layout: SweepLayout,
    /// IMU messages since the newest keyframe: its preintegration factor and the
    /// prediction from the last sweep both read them.
    imu: ImuQueue,
    /// The IMU state at the last registered sweep, and the bias estimate.
    nav: Option<(i64, NavState)>,
    bias: ImuBias,
    /// The last registered sweeps (`world_from_lidar`), for the constant-velocity model.
    previous: Vec<(i64, Isometry3<f64>)>,
    keyframes: Vec<Keyframe>,
    graph: KeyframeGraph,
    map: LocalMap,
    sweeps: Vec<SweepRecord>,
    events: Vec<Event>,
    last_loop_attempt_ns: i64,
    /// Newer keyframes that already have a loop factor (LIO-SAM's loopIndexContainer).
    looped: Vec<usize>,
    /// One row per sweep when `trace_csv` is set.
    trace: Vec<TraceRow>,
    /// The original's separate IMU odometry (with the IMU on and `imu_factors` off): the
    /// velocity and bias from every registered sweep.
    imu_odometry: Option<ImuOdometry>,
    /// Localisation mode: the saved map's localiser, the guess of the start (`map_from_lidar`)
    /// until the first sweep, the last sweep's features (lidar frame), the last status, and
    /// the poses returned.
    localizer: Option<Localizing>,
    /// GPS factors (`[gps] enabled` and a receiver in the rig): the fixes, their alignment
    /// and LIO-SAM's selection (`gnss.rs`).
    gnss: Option<Gnss>,
    /// The IMU's reported orientations, kept where the GPS alignment or
    /// `useImuHeadingInitialization` needs them.
    orientations: Option<Orientations>,
    /// The last keyframe's marginal position covariance in the map frame (LIO-SAM's
    /// `poseCovariance`), computed after each keyframe while GPS factors are on.
    pose_covariance: Option<Matrix3<f64>>,
    /// The IMU odometry's frame from the map's: the identity until a GPS factor moves the
    /// map, then the inverse of the corrections so far, so that the IMU odometry sees a
    /// continuous track (LIO-SAM feeds it `odometry_incremental`, which never jumps).
    odom_from_world: Isometry3<f64>,
}

/// A localisation run's state (`vinebench localize`).
#[derive(Debug)]
struct Localizing {
    localizer: MapLocalizer,
    /// The antenna's horizontal distance from the lidar, m, when the map is georeferenced
    /// (made with GNSS) and a receiver feeds this run: each fix then a prior for the
    /// global search (`MapLocalizer::gnss_fix`).
    antenna_offset_m: Option<f64>,
    guess: Option<Isometry3<f64>>,
    points: Vec<[f32; 3]>,
    status: PoseStatus,
    trajectory: Vec<Pose>,
}

impl LioSam {
    /// The per-sweep pipeline; returns `world_from_lidar` at the sweep's start.
    fn process(&mut self, cloud: &PointCloud<'_>) -> Result<Isometry3<f64>, PluginError> {
        let start = cloud.stamp_ns;
        let motion = self.predict(start, start + self.layout.sweep_ns);
        let rings = rings(
            cloud.points,
            start,
            self.cfg.deskew.then_some(&motion),
            &self.layout,
        );
        let features = extract(&rings, &self.cfg.features);
        if let Some(l) = &mut self.localizer {
            l.points.clear();
            l.points.extend(
                features
                    .edges
                    .iter()
                    .chain(&features.surfs)
                    .map(|p| [p.x as f32, p.y as f32, p.z as f32]),
            );
        }
        let predicted = motion.at(start).unwrap_or_else(Isometry3::identity);
        let outcome = if self.keyframes.is_empty() {
            None
        } else {
            Some(register(
                &features,
                &self.map,
                &predicted,
                &self.cfg.mapping,
            ))
        };
        let mut world_from_lidar = match outcome {
            Some(Ok(r)) => r.world_from_lidar,
            _ => predicted,
        };
        let mut row = self.cfg.trace_csv.is_some().then(|| TraceRow {
            stamp_ns: start,
            outcome: match outcome {
                None => "first",
                Some(Ok(r)) if r.few_matches => "few_matches",
                Some(Ok(_)) => "registered",
                Some(Err(refusal)) => refusal.name(),
            },
            registration: outcome.and_then(Result::ok),
            scan_edges: features.edges.len(),
            scan_surfs: features.surfs.len(),
            speed_mps: 0.0,
            bias_accel_mps2: 0.0,
            bias_gyro_radps: 0.0,
            keyframe: false,
            loop_closed: false,
            reset: false,
        });
        self.after_registration(start, &world_from_lidar);
        self.align_gnss();
        // The registration left (a direction of) the pose to the prediction.
        let degenerate = match outcome {
            None => false,
            Some(Ok(r)) => r.degenerate || r.few_matches,
            Some(Err(_)) => true,
        };
        if self.correct_imu_state(start, &world_from_lidar, degenerate)?
            && let Some(row) = &mut row
        {
            row.reset = true;
        }
        let loops_before = self.looped.len();
        let keyframe = self.is_keyframe(&world_from_lidar);
        if keyframe
            && let Some(correction) = self.add_keyframe(start, world_from_lidar, features)?
        {
            // A GPS factor moved the map: this sweep is the new keyframe, where it now is.
            world_from_lidar = correction * world_from_lidar;
        }
        if let Some(mut row) = row.take() {
            row.keyframe = keyframe;
            row.loop_closed = self.looped.len() > loops_before;
            if let Some((_, state)) = &self.nav {
                row.speed_mps = state.velocity_mps.norm();
            }
            row.bias_accel_mps2 = self.bias.accel_mps2.norm();
            row.bias_gyro_radps = self.bias.gyro_rps.norm();
            self.trace.push(row);
        }
        let keyframe = self.keyframes.len() - 1;
        let kf = &self.keyframes[keyframe];
        self.sweeps.push(SweepRecord {
            stamp_ns: start,
            keyframe,
            keyframe_from_lidar: kf.registered_world_from_lidar.inverse() * world_from_lidar,
        });
        Ok(world_from_lidar)
    }

    /// The lidar's motion from the last registered sweep to the end of this one: IMU
    /// preintegration from the last state, or constant velocity without the IMU.
    fn predict(&self, start_ns: i64, end_ns: i64) -> Motion {
        let lidar = |poses: Motion, times: &[i64]| {
            Motion::new(
                times
                    .iter()
                    .filter_map(|t| poses.at(*t).map(|p| (*t, p * self.imu_from_lidar)))
                    .collect(),
            )
        };
        match (&self.nav, self.cfg.use_imu) {
            (Some((t0, state)), true) => {
                let samples = self.imu.samples(*t0, end_ns);
                let (poses, _) = propagate(state, *t0, &samples, &self.bias, self.cfg.gravity_mps2);
                let mut times: Vec<i64> = vec![*t0, start_ns];
                times.extend(
                    samples
                        .iter()
                        .map(|(t, s)| t + (s.dt_s * 1e9).round() as i64)
                        .filter(|t| *t > start_ns),
                );
                times.sort_unstable();
                times.dedup();
                lidar(poses, &times)
            }
            (None, true) => {
                // First sweep: level the world with gravity as the accelerometer sees it.
                let up = self.imu.mean_accel().unwrap_or(Vector3::z());
                let world_r_imu =
                    UnitQuaternion::rotation_between(&up, &Vector3::z()).unwrap_or_default();
                let world_r_imu = self.initial_heading(start_ns, world_r_imu, &Default::default());
                let world_from_imu = Isometry3::from_parts(Vector3::zeros().into(), world_r_imu);
                Motion::new(vec![(start_ns, world_from_imu * self.imu_from_lidar)])
            }
            // The velocity over several sweeps: from only the last two, registration noise
            // feeds back through deskewing and grows into an oscillation.
            (_, false) => match self.previous.as_slice() {
                [] => Motion::new(vec![(
                    start_ns,
                    Isometry3::from_parts(
                        Vector3::zeros().into(),
                        self.initial_heading(
                            start_ns,
                            UnitQuaternion::identity(),
                            &self.imu_from_lidar.rotation,
                        ),
                    ),
                )]),
                [only] => Motion::new(vec![*only]),
                [first, .., last] => Motion::new(vec![*first, *last]),
            },
        }
    }

    /// The first sweep's rotation `world_r_frame` turned about the vertical to the IMU's
    /// reported heading (`imu_r_frame` carries the IMU's orientation to the frame's) with
    /// `useImuHeadingInitialization` (LIO-SAM sets the first keyframe's yaw to the IMU's;
    /// roll and pitch stay ours, from gravity); unchanged without it.
    fn initial_heading(
        &self,
        start_ns: i64,
        world_r_frame: UnitQuaternion<f64>,
        imu_r_frame: &UnitQuaternion<f64>,
    ) -> UnitQuaternion<f64> {
        if !self.cfg.gps.use_imu_heading_initialization {
            return world_r_frame;
        }
        let Some(enu_r_imu) = self.orientations.as_ref().and_then(|o| o.at(start_ns)) else {
            return world_r_frame;
        };
        let turn = yaw(&(enu_r_imu * imu_r_frame)) - yaw(&world_r_frame);
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn) * world_r_frame
    }

    /// Until the fixes' frame is aligned with the map's: tries the queued fixes against
    /// the last registered sweeps (navsat_transform's step, `gnss.rs`).
    fn align_gnss(&mut self) {
        let (Some(gnss), Some(orientations)) = (&mut self.gnss, &self.orientations) else {
            return;
        };
        if gnss.map_from_enu().is_some() {
            return;
        }
        let lidar_from_imu = self.imu_from_lidar.inverse();
        let track: Vec<(i64, Isometry3<f64>)> = self
            .previous
            .iter()
            .map(|(t, world_from_lidar)| (*t, world_from_lidar * lidar_from_imu))
            .collect();
        gnss.align(&track, orientations);
    }

    /// Carries the front end into the map as a GPS factor moved it, `correction` =
    /// `world_new_from_world_old` at the newest keyframe (LIO-SAM continues from the
    /// corrected `transformTobeMapped`): the IMU state and the last sweeps move with it,
    /// and the IMU odometry's frame keeps it out (its track stays continuous).
    fn carry(&mut self, correction: &Isometry3<f64>) {
        for (_, p) in &mut self.previous {
            *p = correction * *p;
        }
        if let Some((_, state)) = &mut self.nav {
            state.world_from_imu = correction * state.world_from_imu;
            state.velocity_mps = correction.rotation * state.velocity_mps;
        }
        self.odom_from_world *= correction.inverse();
    }

    /// Carries the IMU state to the registered pose at the sweep's start.
    fn after_registration(&mut self, start_ns: i64, world_from_lidar: &Isometry3<f64>) {
        let world_from_imu = world_from_lidar * self.imu_from_lidar.inverse();
        let velocity = match &self.nav {
            Some((t0, state)) if self.cfg.use_imu => {
                let samples = self.imu.samples(*t0, start_ns);
                propagate(state, *t0, &samples, &self.bias, self.cfg.gravity_mps2)
                    .1
                    .velocity_mps
            }
            _ => Vector3::zeros(),
        };
        self.nav = Some((
            start_ns,
            NavState {
                world_from_imu,
                velocity_mps: velocity,
            },
        ));
        self.previous.push((start_ns, *world_from_lidar));
        if self.previous.len() > VELOCITY_BASELINE {
            self.previous.remove(0);
        }
    }

    /// With the original's separate IMU odometry: corrects it with the registered pose
    /// and takes its velocity and bias; true if it failed its check and was reset (the
    /// velocity is then the lidar's over the last sweeps, the bias zero).
    fn correct_imu_state(
        &mut self,
        start_ns: i64,
        world_from_lidar: &Isometry3<f64>,
        degenerate: bool,
    ) -> Result<bool, PluginError> {
        let Some(estimator) = &mut self.imu_odometry else {
            return Ok(false);
        };
        let Some((_, nav)) = &mut self.nav else {
            return Ok(false);
        };
        let samples = estimator.last_ns().map_or_else(Vec::new, |t0| {
            self.imu
                .samples(t0, start_ns)
                .into_iter()
                .map(|(_, s)| s)
                .collect()
        });
        // In the IMU odometry's own frame, which GPS corrections do not move.
        let odom = self.odom_from_world;
        let world_from_imu = world_from_lidar * self.imu_from_lidar.inverse();
        let correction = estimator
            .correct(
                start_ns,
                &(odom * world_from_imu),
                odom.rotation * nav.velocity_mps,
                degenerate,
                samples,
            )
            .map_err(|e| PluginError::new(format!("IMU odometry: {e}")))?;
        match correction {
            Correction::State { velocity_mps, bias } => {
                nav.velocity_mps = odom.rotation.inverse() * velocity_mps;
                self.bias = bias;
                Ok(false)
            }
            Correction::Reset => {
                self.bias = ImuBias::default();
                nav.velocity_mps = match self.previous.as_slice() {
                    // The lidar's, not the IMU's: they differ by the lever arm's turn.
                    [(t0, first), .., (t1, last)] if t1 > t0 => {
                        (last.translation.vector - first.translation.vector)
                            / ((t1 - t0) as f64 * 1e-9)
                    }
                    _ => Vector3::zeros(),
                };
                Ok(true)
            }
        }
    }

    fn is_keyframe(&self, world_from_lidar: &Isometry3<f64>) -> bool {
        let Some(last) = self.keyframes.last() else {
            return true;
        };
        // Both poses from the front end, so that graph corrections do not count as motion.
        let delta = last.registered_world_from_lidar.inverse() * world_from_lidar;
        delta.translation.vector.norm() >= self.cfg.mapping.keyframe_distance_m
            || delta.rotation.angle() >= self.cfg.mapping.keyframe_angle_rad
    }

    fn keyframe_world_from_lidar(&self, k: usize) -> Isometry3<f64> {
        self.graph.pose(k) * self.imu_from_lidar
    }

    /// Adds a keyframe to the graph (with a GPS factor where LIO-SAM's rules give one),
    /// looks for a loop, and rebuilds the local map. Returns the correction
    /// `world_new_from_world_old` a GPS factor made at this keyframe.
    fn add_keyframe(
        &mut self,
        stamp_ns: i64,
        world_from_lidar: Isometry3<f64>,
        features: Features,
    ) -> Result<Option<Isometry3<f64>>, PluginError> {
        let world_from_imu = world_from_lidar * self.imu_from_lidar.inverse();
        let samples = match self.keyframes.last() {
            Some(prev) if self.cfg.use_imu && self.cfg.imu_factors => {
                self.keyframe_samples(prev.stamp_ns, stamp_ns)
            }
            _ => Vec::new(),
        };
        let velocity = self.nav.map_or(Vector3::zeros(), |(_, s)| s.velocity_mps);
        let gps = match &mut self.gnss {
            Some(gnss) => {
                let n = self.graph.len();
                let state = KeyframeState {
                    stamp_ns,
                    map_from_imu: world_from_imu,
                    first_and_last: (n > 0).then(|| {
                        (
                            self.graph.pose(0).translation.vector,
                            self.graph.pose(n - 1).translation.vector,
                        )
                    }),
                    last_covariance: self.pose_covariance,
                };
                gnss.select(&state, &mut self.events)
            }
            None => None,
        };
        self.graph
            .add_keyframe(
                world_from_imu,
                velocity,
                self.bias,
                samples,
                gps.map(|f| (f.position, f.sigmas)),
            )
            .map_err(|e| PluginError::new(format!("factor graph: {e}")))?;
        let k = self.keyframes.len();
        let correction = gps.map(|_| self.graph.pose(k) * world_from_imu.inverse());
        if let Some(c) = &correction {
            self.carry(c);
        }
        self.keyframes.push(Keyframe {
            stamp_ns,
            features,
            registered_world_from_lidar: correction.unwrap_or_default() * world_from_lidar,
        });
        if self.cfg.loop_closure.enabled {
            self.close_loop(stamp_ns)?;
        }
        if self.gnss.is_some() {
            self.pose_covariance = Some(
                self.graph
                    .position_covariance(k)
                    .map_err(|e| PluginError::new(format!("factor graph: {e}")))?,
            );
        }
        // The state at the newest keyframe, as optimised.
        let k = self.keyframes.len() - 1;
        if let Some(velocity) = self.graph.velocity(k) {
            self.bias = self.graph.bias(k).unwrap_or(self.bias);
            self.nav = Some((
                stamp_ns,
                NavState {
                    world_from_imu: self.graph.pose(k),
                    velocity_mps: velocity,
                },
            ));
        }
        self.rebuild_map();
        Ok(correction)
    }

    /// IMU samples between two keyframes.
    fn keyframe_samples(
        &self,
        t0_ns: i64,
        t1_ns: i64,
    ) -> Vec<slam_common::factor_graph::backend::ImuSample> {
        self.imu
            .samples(t0_ns, t1_ns)
            .into_iter()
            .map(|(_, s)| s)
            .collect()
    }

    fn close_loop(&mut self, stamp_ns: i64) -> Result<(), PluginError> {
        let cfg = self.cfg.loop_closure.clone();
        if (stamp_ns - self.last_loop_attempt_ns) as f64 * 1e-9 < cfg.min_interval_s {
            return Ok(());
        }
        let newer = self.keyframes.len() - 1;
        if self.looped.contains(&newer) {
            return Ok(());
        }
        let views = self.views();
        let Some(older) = candidate(&views, &cfg) else {
            return Ok(());
        };
        let verdict = verify(&views, older, &cfg, self.cfg.mapping.surf_leaf_m);
        drop(views);
        self.last_loop_attempt_ns = stamp_ns;
        match verdict {
            Ok(m) => {
                let imu_older_from_newer =
                    self.imu_from_lidar * m.older_from_newer * self.imu_from_lidar.inverse();
                let sigma = m.fitness.sqrt().max(1e-3);
                self.graph
                    .add_loop(older, newer, imu_older_from_newer, sigma, cfg.robust_scale)
                    .map_err(|e| PluginError::new(format!("factor graph: {e}")))?;
                self.looped.push(newer);
                let mut detail = String::new();
                let _ = write!(
                    detail,
                    "keyframe {newer} to {older}: ICP fitness {:.4} m²",
                    m.fitness
                );
                // The measured relative pose of the two keyframes' base poses, for the
                // host's judgement against ground truth.
                let base_older_from_newer =
                    self.lidar_from_base.inverse() * m.older_from_newer * self.lidar_from_base;
                self.events.push(
                    Event::loop_closure(
                        stamp_ns,
                        EventKind::LoopClosureAccepted,
                        [stamp_ns, self.keyframes[older].stamp_ns],
                        detail,
                    )
                    .with_relative_pose(&base_older_from_newer),
                );
            }
            Err(fitness) => {
                self.events.push(Event::loop_closure(
                    stamp_ns,
                    EventKind::LoopClosureRejected,
                    [stamp_ns, self.keyframes[older].stamp_ns],
                    format!(
                        "keyframe {newer} to {older}: ICP fitness {fitness:.4} m² above {}",
                        cfg.max_fitness
                    ),
                ));
            }
        }
        Ok(())
    }

    fn rebuild_map(&mut self) {
        self.map = LocalMap::build(&self.views(), &self.cfg.mapping);
    }

    /// Every keyframe at its current estimate.
    fn views(&self) -> Vec<KeyframeView<'_>> {
        self.keyframes
            .iter()
            .enumerate()
            .map(|(k, kf)| KeyframeView {
                stamp_ns: kf.stamp_ns,
                world_from_lidar: self.keyframe_world_from_lidar(k),
                features: &kf.features,
            })
            .collect()
    }

    fn base_pose(&self, stamp_ns: i64, world_from_lidar: &Isometry3<f64>) -> Pose {
        Pose::new(stamp_ns, &(world_from_lidar * self.lidar_from_base))
    }
}

impl SlamSystem for LioSam {
    const NAME: &'static str = "lio-sam";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::Lidar, SensorKind::Imu]).localizing()
    }

    /// The GNSS receiver too when `[gps] enabled`.
    fn requirements_for(config_toml: &str) -> Result<Requirements, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let mut requirements = Self::requirements();
        if cfg.gps.enabled {
            requirements.sensors.push(SensorKind::Gnss);
        }
        Ok(requirements)
    }

    /// Localisation in a map a mapping run saved: the front end runs as in mapping (its own
    /// loop closure off: the saved map is the reference), and each sweep's features are
    /// registered to the saved keyframes (`slam_common::maps::localizer`).
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        if start.format != KEYFRAME_MAP_FORMAT || !reads_version(start.format_version) {
            return Err(PluginError::new(format!(
                "lio-sam reads {KEYFRAME_MAP_FORMAT} versions 1 to {KEYFRAME_MAP_VERSION} maps, not {} version {}",
                start.format, start.format_version
            )));
        }
        let map =
            KeyframeMap::from_bytes(start.map, start.format_version).map_err(PluginError::new)?;
        let mut system = Self::new(config_toml, rig)?;
        system.cfg.loop_closure.enabled = false;
        // The saved map is the reference: no GPS factors move it. A map made with GNSS
        // keeps its georeference; with a receiver now, each fix is a prior for the global
        // search (the antenna's horizontal offset from the lidar counted in its spread).
        let receiver = system.gnss.take().and(rig.first(SensorKind::Gnss));
        let antenna_offset_m = map.map_from_enu.and(receiver).map(|receiver| {
            slam_common::gnss::horizontal_lever_m(
                &system.lidar_from_base,
                &receiver.base_from_sensor(),
            )
        });
        let guess = start
            .initial_guess
            .and_then(|g| g.map_from_base.isometry())
            .map(|map_from_base| map_from_base * system.lidar_from_base.inverse());
        system.localizer = Some(Localizing {
            localizer: MapLocalizer::new(map, system.cfg.localization.clone()),
            antenna_offset_m,
            guess,
            points: Vec::new(),
            status: PoseStatus::Searching,
            trajectory: Vec::new(),
        });
        Ok(system)
    }

    fn status(&self) -> PoseStatus {
        self.localizer
            .as_ref()
            .map_or(PoseStatus::Localized, |l| l.status)
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let lidar = rig.require_first(SensorKind::Lidar)?;
        let imu = rig.require_first(SensorKind::Imu)?;
        let columns = lidar.intrinsics.get("columns").copied().unwrap_or(1800.0);
        if lidar.rate_hz <= 0.0 || columns < 1.0 {
            return Err(PluginError::new(
                "the lidar's rate and columns must be positive",
            ));
        }
        let imu_noise = cfg.imu.resolve(&imu.noise, cfg.gravity_mps2);
        let base_from_imu = imu.base_from_sensor();
        let reports_orientation = imu.intrinsics.get("reports_orientation") == Some(&1.0);
        let needs_orientation = |what: &str| {
            PluginError::new(format!(
                "lio-sam: {what} needs the IMU's orientation (the world's [sensors.imu] \
                 reports_orientation = true), as LIO-SAM needs a 9-axis IMU"
            ))
        };
        if cfg.gps.use_imu_heading_initialization && !reports_orientation {
            return Err(needs_orientation("[gps] useImuHeadingInitialization"));
        }
        let gnss = match (cfg.gps.enabled, rig.first(SensorKind::Gnss)) {
            (false, _) => None,
            (true, None) => {
                eprintln!(
                    "lio-sam: [gps] enabled, but the world has no GNSS receiver: no GPS factors"
                );
                None
            }
            (true, Some(_)) if !reports_orientation => {
                return Err(needs_orientation(
                    "[gps] enabled (aligning the fixes' east-north-up frame with the map)",
                ));
            }
            (true, Some(receiver)) => {
                let imu_from_antenna = (base_from_imu.inverse() * receiver.base_from_sensor())
                    .translation
                    .vector;
                Some(Gnss::new(cfg.gps.clone(), imu_from_antenna))
            }
        };
        let graph = KeyframeGraph::new(
            &cfg.backend,
            (cfg.use_imu && cfg.imu_factors).then_some(imu_noise),
            cfg.mapping.odometry_sigma_rad,
            cfg.mapping.odometry_sigma_m,
            gnss.is_some(),
        )
        .map_err(|e| PluginError::new(format!("backend: {e}")))?;
        let imu_odometry = (cfg.use_imu && !cfg.imu_factors)
            .then(|| ImuOdometry::new(&cfg.backend, imu_noise))
            .transpose()
            .map_err(|e| PluginError::new(format!("backend: {e}")))?;
        let base_from_lidar = lidar.base_from_sensor();
        let orientations =
            (gnss.is_some() || cfg.gps.use_imu_heading_initialization).then(Orientations::default);
        Ok(Self {
            imu_from_lidar: base_from_imu.inverse() * base_from_lidar,
            lidar_from_base: base_from_lidar.inverse(),
            layout: SweepLayout {
                sweep_ns: (1e9 / lidar.rate_hz).round() as i64,
                columns,
                min_range_m: cfg.features.min_range_m,
                max_range_m: cfg.features.max_range_m,
            },
            imu: ImuQueue::default(),
            nav: None,
            bias: ImuBias::default(),
            previous: Vec::new(),
            keyframes: Vec::new(),
            graph,
            map: LocalMap::default(),
            sweeps: Vec::new(),
            events: Vec::new(),
            last_loop_attempt_ns: i64::MIN / 2,
            looped: Vec::new(),
            trace: Vec::new(),
            imu_odometry,
            localizer: None,
            gnss,
            orientations,
            pose_covariance: None,
            odom_from_world: Isometry3::identity(),
            cfg,
        })
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        if self.cfg.use_imu {
            self.imu.push(*imu);
        }
        if let (Some(orientations), Some(q)) = (&mut self.orientations, imu.orientation()) {
            orientations.push(imu.stamp_ns, q);
        }
        Ok(None)
    }

    /// Queues a usable fix for the next keyframes' GPS factors; refuses one that cannot be
    /// used with a `gnss_rejected` event (never an error). Ignored without `[gps]`.
    fn on_gnss(&mut self, gnss: &GnssMessage) -> Result<Option<Pose>, PluginError> {
        if let Some(l) = &mut self.localizer {
            if let Some(offset_m) = l.antenna_offset_m
                && let Some(fix) = usable(gnss, &mut self.events)
            {
                l.localizer
                    .gnss_fix(&fix.position_enu_m, &fix.covariance_enu_m2, offset_m);
            }
            return Ok(None);
        }
        if let Some(g) = &mut self.gnss {
            g.push(gnss, &mut self.events);
        }
        Ok(None)
    }

    fn on_point_cloud(&mut self, cloud: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        let world_from_lidar = self.process(cloud)?;
        if let Some(k) = self.keyframes.last() {
            self.imu.discard_before(k.stamp_ns);
        }
        let lidar_from_base = self.lidar_from_base;
        if let Some(l) = &mut self.localizer {
            if let Some(guess) = l.guess.take() {
                l.localizer.guess(&guess, &world_from_lidar);
            }
            let found = l.localizer.update(&world_from_lidar, &l.points);
            l.status = if found.localized {
                PoseStatus::Localized
            } else {
                PoseStatus::Searching
            };
            let pose = Pose::new(cloud.stamp_ns, &(found.map_from_sensor * lidar_from_base));
            l.trajectory.push(pose);
            return Ok(Some(pose));
        }
        Ok(Some(self.base_pose(cloud.stamp_ns, &world_from_lidar)))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        if let Some(l) = &mut self.localizer {
            // Localising: the poses in the saved map as returned (no map of its own).
            eprintln!(
                "lio-sam: localised in {} keyframes: {} global searches, {} accepted",
                l.localizer.keyframes(),
                l.localizer.searches,
                l.localizer.relocalizations
            );
            return Ok(SlamOutput {
                trajectory: std::mem::take(&mut l.trajectory),
                ..SlamOutput::default()
            });
        }
        if let Some(g) = &self.gnss {
            eprintln!(
                "lio-sam: {} GPS factors; fixes' frame {}",
                g.factors,
                if g.map_from_enu().is_some() {
                    "aligned"
                } else {
                    "never aligned (no usable fix during a registered sweep)"
                }
            );
        }
        let trajectory = self
            .sweeps
            .iter()
            .map(|s| {
                self.base_pose(
                    s.stamp_ns,
                    &(self.keyframe_world_from_lidar(s.keyframe) * s.keyframe_from_lidar),
                )
            })
            .collect();
        let mut points = Vec::new();
        for k in 0..self.keyframes.len() {
            let pose = self.keyframe_world_from_lidar(k);
            let f = &self.keyframes[k].features;
            points.extend(
                f.edges
                    .iter()
                    .chain(&f.surfs)
                    .map(|p| (pose * nalgebra::Point3::from(*p)).coords),
            );
        }
        let map = downsample(&points, self.cfg.mapping.corner_leaf_m)
            .into_iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        if let Some(path) = &self.cfg.profile_csv {
            self.graph
                .backend
                .write_csv(path)
                .map_err(|e| PluginError::new(format!("profile_csv {}: {e}", path.display())))?;
        }
        if let Some(path) = &self.cfg.trace_csv {
            let mut csv = String::from(TRACE_HEADER);
            csv.push('\n');
            for row in &self.trace {
                csv.push_str(&row.line());
                csv.push('\n');
            }
            std::fs::write(path, csv)
                .map_err(|e| PluginError::new(format!("trace_csv {}: {e}", path.display())))?;
        }
        // The map to localise in later: every keyframe at its optimised pose with its
        // features, in the lidar frame.
        let saved = KeyframeMap {
            keyframes: (0..self.keyframes.len())
                .map(|k| {
                    let f = &self.keyframes[k].features;
                    MapKeyframe {
                        map_from_sensor: self.keyframe_world_from_lidar(k),
                        points: f
                            .edges
                            .iter()
                            .chain(&f.surfs)
                            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                            .collect(),
                    }
                })
                .collect(),
            map_from_enu: self.gnss.as_ref().and_then(Gnss::map_from_enu),
        };
        Ok(SlamOutput {
            trajectory,
            map: Some(map),
            grid: None,
            events: std::mem::take(&mut self.events),
            saved_map: Some(SavedMap {
                format: KEYFRAME_MAP_FORMAT.into(),
                version: saved.version(),
                bytes: saved.to_bytes(),
            }),
        })
    }
}

#[cfg(test)]
mod tests {
    use plugin_api::{EventKind, Gnss, GnssStatus, SensorSpec};

    use super::*;

    fn sensor(kind: SensorKind, xyz: [f64; 3], intrinsics: &[(&str, f64)]) -> SensorSpec {
        SensorSpec {
            name: kind.name().into(),
            kind,
            rate_hz: 10.0,
            base_from_sensor_xyz: xyz,
            base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
            intrinsics: intrinsics
                .iter()
                .map(|(k, v)| (k.to_string(), *v))
                .collect(),
            noise: Default::default(),
        }
    }

    fn rig(orientation: bool, receiver: bool) -> Rig {
        let mut sensors = vec![
            sensor(SensorKind::Lidar, [0.0, 0.0, 1.0], &[("columns", 1800.0)]),
            sensor(
                SensorKind::Imu,
                [0.0, 0.0, 0.6],
                &[("reports_orientation", f64::from(u8::from(orientation)))],
            ),
        ];
        if receiver {
            sensors.push(sensor(SensorKind::Gnss, [-0.2, 0.0, 1.7], &[]));
        }
        Rig { sensors }
    }

    const GPS_ON: &str = "[gps]\nenabled = true\n";

    #[test]
    fn the_receiver_is_asked_for_only_with_gps_on() {
        // Guards requirements_for: GNSS joins the sensors with `[gps] enabled`, not by
        // default (plugins without it never meet the kind), and LIO-SAM's names parse.
        let off = LioSam::requirements_for("").expect("defaults");
        assert!(!off.sensors.contains(&SensorKind::Gnss));
        assert_eq!(off, LioSam::requirements());
        let on = LioSam::requirements_for(
            "[gps]\nenabled = true\nuseGpsElevation = true\ngpsCovThreshold = 0.5\n\
             poseCovThreshold = 4.0\nuseImuHeadingInitialization = false\n",
        )
        .expect("gps");
        assert!(on.sensors.contains(&SensorKind::Gnss));
        assert!(on.sensors.contains(&SensorKind::Lidar) && on.can_localize);
        assert!(LioSam::requirements_for("[gps]\nuse_gps = true\n").is_err());
    }

    #[test]
    fn gps_needs_the_imus_heading_and_does_without_a_receiver() {
        // Guards the set-up: the alignment needs the IMU's orientation (an error saying
        // so), a world without a receiver leaves GPS off, and the lever arm is the
        // antenna's mount seen from the IMU.
        let err = LioSam::new(GPS_ON, &rig(false, true)).expect_err("no orientation");
        assert!(err.0.contains("reports_orientation"), "{err}");
        let err = LioSam::new(
            "[gps]\nuseImuHeadingInitialization = true\n",
            &rig(false, false),
        )
        .expect_err("no orientation");
        assert!(err.0.contains("useImuHeadingInitialization"), "{err}");
        let without = LioSam::new(GPS_ON, &rig(true, false)).expect("no receiver");
        assert!(without.gnss.is_none());
        let with = LioSam::new(GPS_ON, &rig(true, true)).expect("receiver");
        assert!(with.gnss.is_some() && with.orientations.is_some());
        let off = LioSam::new("", &rig(false, true)).expect("gps off");
        assert!(off.gnss.is_none() && off.orientations.is_none());
    }

    #[test]
    fn a_broken_fix_is_an_event_not_an_error() {
        // Guards on_gnss: NaN, no fix and a zero covariance are refused with
        // gnss_rejected events in the output, never an error or a panic; without
        // `[gps]` fixes are ignored.
        let mut system = LioSam::new(GPS_ON, &rig(true, true)).expect("receiver");
        let fix = Gnss {
            stamp_ns: 5,
            status: GnssStatus::Float,
            satellites: 9,
            position_enu_m: [f64::NAN, 1.0, 2.0],
            covariance_enu_m2: [0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.04],
            latitude_deg: f64::NAN,
            longitude_deg: f64::NAN,
            altitude_m: f64::NAN,
            hdop: 1.2,
        };
        assert_eq!(system.on_gnss(&fix), Ok(None));
        let no_fix = Gnss {
            status: GnssStatus::NoFix,
            ..fix
        };
        assert_eq!(system.on_gnss(&no_fix), Ok(None));
        let flat = Gnss {
            position_enu_m: [1.0, 2.0, 3.0],
            covariance_enu_m2: [0.0; 9],
            ..fix
        };
        assert_eq!(system.on_gnss(&flat), Ok(None));
        let output = system.finish().expect("finish");
        let kinds: Vec<EventKind> = output.events.iter().map(|e| e.kind).collect();
        assert_eq!(kinds, vec![EventKind::GnssRejected; 3]);
        let mut off = LioSam::new("", &rig(true, true)).expect("gps off");
        assert_eq!(off.on_gnss(&fix), Ok(None));
        assert!(off.finish().expect("finish").events.is_empty());
    }
}
