use std::time::Instant;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use plugin_api::{
    Event, Imu, MapStart, Mode, Parameters, PluginError, PointCloud, Pose, PoseStatus,
    Requirements, Rig, SavedMap, SensorKind, SlamOutput, SlamSystem, Stages,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use slam_common::maps::keyframes::{
    KEYFRAME_MAP_FORMAT, KEYFRAME_MAP_VERSION, KeyframeMap, MapKeyframe,
};
use slam_common::maps::localizer::MapLocalizer;
use slam_common::place::m2dp::{self, Descriptor, M2dpConfig, Rings};
use slam_common::registration::voxel::downsample;

use crate::config::{Config, DescriptorVariant};
use crate::frontend::{self, Gyro};
use crate::graph::SubmapGraph;
use crate::input::{self, Sweep};
use crate::loops::{LoopCloser, LoopCounts};
use crate::submap::{self, Submap};

/// The offline mapper: collects sweeps and gyroscope samples, builds in `finish`.
#[derive(Debug)]
pub struct StaticMapping {
    cfg: Config,
    rng: ChaCha8Rng,
    sweep_ns: i64,
    imu_from_lidar: UnitQuaternion<f64>,
    lidar_from_base: Isometry3<f64>,
    sweeps: Vec<Sweep>,
    gyro: Vec<Gyro>,
    /// Localisation mode (`vinebench localize`): online, sweep by sweep.
    localizing: Option<Box<Localizing>>,
}

/// A localisation run's state: the front end as odometry, the saved map's localiser, the
/// guess of the start (`map_from_lidar`) until the first sweep, the last status and the
/// poses returned.
#[derive(Debug)]
struct Localizing {
    front_end: frontend::FrontEnd,
    localizer: MapLocalizer,
    guess: Option<Isometry3<f64>>,
    status: PoseStatus,
    trajectory: Vec<Pose>,
}

/// What the offline build did and how long each stage took (`timing_json`).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct BuildReport {
    pub sweeps: usize,
    pub points_kept: usize,
    pub keyframes: usize,
    pub submaps: usize,
    pub front_end_failed_matches: usize,
    pub front_end_mean_score: f64,
    pub submap_matches_accepted: usize,
    pub loop_detections: usize,
    pub loop_verifications: usize,
    pub loop_edges_verified: usize,
    pub loops_accepted: usize,
    pub loop_edges_added: usize,
    pub loops_rejected: usize,
    pub front_end_s: f64,
    pub submaps_s: f64,
    pub m2dp_s: f64,
    pub verification_s: f64,
    pub back_end_s: f64,
    pub total_s: f64,
}

impl BuildReport {
    /// The input, the front end's counts, the loop counts and the stages' times; the
    /// submaps' counts zero.
    fn new(
        sweeps: &[Sweep],
        odometry: &frontend::Odometry,
        loops: &LoopCounts,
        stages: &Stages,
        started: Instant,
    ) -> Self {
        Self {
            sweeps: sweeps.len(),
            points_kept: sweeps.iter().map(|s| s.points.len()).sum(),
            keyframes: odometry.keyframes.len(),
            front_end_failed_matches: odometry.failed_matches,
            front_end_mean_score: odometry.mean_score,
            loop_detections: loops.detections,
            loop_verifications: loops.verifications,
            loop_edges_verified: loops.edges_verified,
            loops_accepted: loops.accepted,
            loop_edges_added: loops.edges_added,
            loops_rejected: loops.rejected,
            front_end_s: stages.total("front_end"),
            submaps_s: stages.total("submaps"),
            m2dp_s: stages.total("m2dp"),
            verification_s: stages.total("verification"),
            back_end_s: stages.total("back_end"),
            total_s: started.elapsed().as_secs_f64(),
            ..Self::default()
        }
    }
}

impl StaticMapping {
    fn m2dp_config(&self) -> M2dpConfig {
        let l = &self.cfg.loop_closure;
        M2dpConfig {
            azimuths: l.m2dp_azimuths,
            elevations: l.m2dp_elevations,
            rings: l.m2dp_rings,
            sectors: l.m2dp_sectors,
            radii: match l.descriptor {
                DescriptorVariant::Paper => Rings::Relative,
                DescriptorVariant::Staticmapping => Rings::Absolute {
                    ring_m: l.staticmapping_ring_m,
                    max_distance_m: l.staticmapping_max_distance_m,
                },
            },
        }
    }

    /// StaticMapping's offline build (`docs/systems/staticmapping.md`): front-end odometry
    /// over every sweep, keyframes grouped into submaps, an M2DP descriptor per submap, then
    /// the pose graph, each submap linked to the one before by ICP and its loops detected,
    /// verified and added; the trajectory and map from the optimised submaps.
    pub fn build(&mut self) -> Result<(SlamOutput, BuildReport), PluginError> {
        let started = Instant::now();
        let cfg = &self.cfg;
        let mut stages = Stages::default();
        let odometry = stages.time("front_end", || self.front_end());
        if odometry.keyframes.is_empty() {
            return Err(PluginError::new("no lidar sweep was received"));
        }
        let submaps = stages.time("submaps", || {
            submap::build(&odometry.keyframes, &cfg.submap, &cfg.icp)
        });
        let descriptors = stages.time("m2dp", || self.describe(&submaps));
        let backend_error = |e| PluginError::new(format!("backend: {e}"));
        let mut graph = SubmapGraph::new(&cfg.backend).map_err(backend_error)?;
        stages
            .time("back_end", || graph.add_first(submaps[0].odometry_pose))
            .map_err(backend_error)?;
        let mut loops = LoopCloser::new(
            &cfg.loop_closure,
            &cfg.icp,
            &submaps,
            &descriptors,
            self.lidar_from_base,
        );
        let mut matches_accepted = 0;
        for i in 1..submaps.len() {
            let m = stages.time("submaps", || {
                submap::match_to_previous(&submaps[i - 1], &submaps[i], &cfg.submap, &cfg.icp)
            });
            matches_accepted += usize::from(m.accepted);
            stages
                .time("back_end", || graph.add_next(m.previous_from_current))
                .map_err(backend_error)?;
            if cfg.loop_closure.enabled {
                loops.close(i, &mut graph, &mut stages)?;
            }
        }
        let output = self.output(&odometry, &submaps, &graph, loops.events);
        let report = BuildReport {
            submaps: submaps.len(),
            submap_matches_accepted: matches_accepted,
            ..BuildReport::new(&self.sweeps, &odometry, &loops.counts, &stages, started)
        };
        Ok((output, report))
    }

    /// The front end over every sweep, with the gyroscope if the IMU is used.
    fn front_end(&self) -> frontend::Odometry {
        let cfg = &self.cfg;
        frontend::run(
            &self.sweeps,
            cfg.use_imu.then_some(&self.gyro[..]),
            self.imu_from_lidar,
            self.sweep_ns,
            cfg.input.deskew,
            &cfg.front_end,
            &cfg.icp,
        )
    }

    /// Each submap's M2DP descriptor, when loop closure is on.
    fn describe(&self, submaps: &[Submap]) -> Vec<Option<Descriptor>> {
        if !self.cfg.loop_closure.enabled {
            return vec![None; submaps.len()];
        }
        let m2dp_cfg = self.m2dp_config();
        submaps
            .par_iter()
            .map(|s| m2dp::descriptor(&s.cloud, &m2dp_cfg))
            .collect()
    }

    /// The trajectory (every sweep's pose, carried by its submap's optimised pose) and the
    /// map (the optimised submaps' clouds, voxel-filtered).
    fn output(
        &self,
        odometry: &frontend::Odometry,
        submaps: &[Submap],
        graph: &SubmapGraph,
        events: Vec<Event>,
    ) -> SlamOutput {
        let trajectory = odometry
            .sweeps
            .iter()
            .map(|&(stamp_ns, world_from_lidar, kf)| {
                let s = kf / self.cfg.submap.frame_count;
                let submap_from_lidar = submaps[s].odometry_pose.inverse() * world_from_lidar;
                Pose::new(
                    stamp_ns,
                    &(graph.pose(s) * submap_from_lidar * self.lidar_from_base),
                )
            })
            .collect();
        let mut points = Vec::new();
        for (k, s) in submaps.iter().enumerate() {
            let pose = graph.pose(k);
            points.extend(s.cloud.iter().map(|p| (pose * Point3::from(*p)).coords));
        }
        let map = downsample(&points, self.cfg.submap.map_voxel_m)
            .into_iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        // The map to localise in later: every submap at its optimised pose with its cloud,
        // in the frame of its first keyframe's lidar.
        let saved = KeyframeMap {
            keyframes: submaps
                .iter()
                .enumerate()
                .map(|(k, s)| MapKeyframe {
                    map_from_sensor: graph.pose(k),
                    points: s
                        .cloud
                        .iter()
                        .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                        .collect(),
                })
                .collect(),
        };
        SlamOutput {
            trajectory,
            map: Some(map),
            grid: None,
            events,
            saved_map: Some(SavedMap {
                format: KEYFRAME_MAP_FORMAT.into(),
                version: KEYFRAME_MAP_VERSION,
                bytes: saved.to_bytes(),
            }),
        }
    }
}

impl SlamSystem for StaticMapping {
    const NAME: &'static str = "staticmapping";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    /// Offline when mapping; localisation (`can_localize`) answers every sweep online.
    fn requirements() -> Requirements {
        Requirements {
            sensors: vec![SensorKind::Lidar, SensorKind::Imu],
            mode: Mode::Offline,
            can_localize: true,
        }
    }

    /// Localisation in a map a mapping run saved (its optimised submaps): the front end
    /// runs online as odometry, and each sweep's kept points are registered to the saved
    /// submaps (`slam_common::maps::localizer`: Scan Context search, ICP verification).
    /// StaticMapping itself has no localisation mode; this composes its front end with the
    /// localiser lio-sam uses, so that the two lidar systems differ by their maps and their
    /// odometry, not by the localiser.
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        if (start.format, start.format_version) != (KEYFRAME_MAP_FORMAT, KEYFRAME_MAP_VERSION) {
            return Err(PluginError::new(format!(
                "staticmapping reads {KEYFRAME_MAP_FORMAT} version {KEYFRAME_MAP_VERSION} maps, not {} version {}",
                start.format, start.format_version
            )));
        }
        let map = KeyframeMap::from_bytes(start.map).map_err(PluginError::new)?;
        let mut system = Self::new(config_toml, rig)?;
        let cfg = &system.cfg;
        let guess = start
            .initial_guess
            .and_then(|g| g.map_from_base.isometry())
            .map(|map_from_base| map_from_base * system.lidar_from_base.inverse());
        system.localizing = Some(Box::new(Localizing {
            front_end: frontend::FrontEnd::new(
                system.imu_from_lidar,
                system.sweep_ns,
                cfg.input.deskew,
                &cfg.front_end,
                &cfg.icp,
            )
            .without_history(),
            localizer: MapLocalizer::new(map, cfg.localization.clone()),
            guess,
            status: PoseStatus::Searching,
            trajectory: Vec::new(),
        }));
        Ok(system)
    }

    fn status(&self) -> PoseStatus {
        self.localizing
            .as_ref()
            .map_or(PoseStatus::Localized, |l| l.status)
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let lidar = rig.require_first(SensorKind::Lidar)?;
        if lidar.rate_hz <= 0.0 {
            return Err(PluginError::new("the lidar's rate must be positive"));
        }
        let base_from_lidar = lidar.base_from_sensor();
        let imu_from_lidar = rig
            .first(SensorKind::Imu)
            .map(|imu| (imu.base_from_sensor().inverse() * base_from_lidar).rotation)
            .unwrap_or_else(UnitQuaternion::identity);
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            sweep_ns: (1e9 / lidar.rate_hz).round() as i64,
            imu_from_lidar,
            lidar_from_base: base_from_lidar.inverse(),
            sweeps: Vec::new(),
            gyro: Vec::new(),
            localizing: None,
            cfg,
        })
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        if self.cfg.use_imu {
            self.gyro.push(Gyro {
                stamp_ns: imu.stamp_ns,
                rate_rps: Vector3::from(imu.gyro_rps),
            });
        }
        Ok(None)
    }

    fn on_point_cloud(&mut self, cloud: &PointCloud<'_>) -> Result<Option<Pose>, PluginError> {
        let sweep = input::filter(cloud.stamp_ns, cloud.points, &self.cfg.input, &mut self.rng);
        let Some(l) = &mut self.localizing else {
            self.sweeps.push(sweep);
            return Ok(None);
        };
        let gyro = self.cfg.use_imu.then_some(&self.gyro[..]);
        let (odom_from_lidar, points) = l.front_end.step(&sweep, gyro);
        // The gyroscope is read from the sweep's start on: older samples can go.
        let keep = self.gyro.partition_point(|g| g.stamp_ns < sweep.stamp_ns);
        self.gyro.drain(..keep.saturating_sub(1));
        if let Some(guess) = l.guess.take() {
            l.localizer.guess(&guess, &odom_from_lidar);
        }
        let points: Vec<[f32; 3]> = points
            .iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        let found = l.localizer.update(&odom_from_lidar, &points);
        l.status = if found.localized {
            PoseStatus::Localized
        } else {
            PoseStatus::Searching
        };
        let pose = Pose::new(
            cloud.stamp_ns,
            &(found.map_from_sensor * self.lidar_from_base),
        );
        l.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        if let Some(l) = &mut self.localizing {
            eprintln!(
                "staticmapping: localised in {} submaps: {} global searches, {} accepted",
                l.localizer.keyframes(),
                l.localizer.searches,
                l.localizer.relocalizations
            );
            return Ok(SlamOutput {
                trajectory: std::mem::take(&mut l.trajectory),
                ..SlamOutput::default()
            });
        }
        let (output, report) = self.build()?;
        if let Some(path) = &self.cfg.timing_json {
            let text = serde_json::to_string_pretty(&report)
                .map_err(|e| PluginError::new(format!("timing_json: {e}")))?;
            std::fs::write(path, text + "\n")
                .map_err(|e| PluginError::new(format!("timing_json {}: {e}", path.display())))?;
        }
        Ok(output)
    }
}
