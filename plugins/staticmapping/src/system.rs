use std::time::Instant;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use plugin_api::{
    Event, Gnss as GnssMessage, Imu, MapStart, Mode, Parameters, PluginError, PointCloud, Pose,
    PoseStatus, Requirements, Rig, SavedMap, SensorKind, SlamOutput, SlamSystem, Stages,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use slam_common::maps::keyframes::{
    KEYFRAME_MAP_FORMAT, KEYFRAME_MAP_VERSION, KeyframeMap, MapKeyframe, reads_version,
};
use slam_common::maps::localizer::MapLocalizer;
use slam_common::place::m2dp::{self, Descriptor, M2dpConfig, Rings};
use slam_common::registration::voxel::downsample;

use crate::config::{Config, DescriptorVariant};
use crate::frontend::{self, Gyro};
use crate::gnss::{GnssCounts, SubmapGnss};
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
    /// GNSS priors per submap (`[gps] use_gps` and a receiver in the rig): the epochs,
    /// the original's gate, the ENU-to-map transform solved from the track (`gnss.rs`).
    gnss: Option<SubmapGnss>,
}

/// A localisation run's state: the front end as odometry, the saved map's localiser, the
/// guess of the start (`map_from_lidar`) until the first sweep, the last status and the
/// poses returned.
#[derive(Debug)]
struct Localizing {
    front_end: frontend::FrontEnd,
    localizer: MapLocalizer,
    /// The antenna's horizontal distance from the lidar, m, when the map is georeferenced
    /// (made with GNSS) and a receiver feeds this run: each fix then a prior for the
    /// global search (`MapLocalizer::gnss_fix`).
    antenna_offset_m: Option<f64>,
    /// Fixes refused (`gnss_rejected`).
    events: Vec<Event>,
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
    /// Submaps with a GNSS position at their stamp, priors in the graph, the submap that
    /// opened the gate (the first solve of the ENU-to-map transform), the solves, the
    /// rebuilds of the priors through a re-solved transform, and the last solve's RMS
    /// residual, m (`gnss::GnssCounts`).
    pub gnss_submaps_with_fix: usize,
    pub gnss_priors: usize,
    pub gnss_opened_at: Option<usize>,
    pub gnss_solves: usize,
    pub gnss_rebuilds: usize,
    pub gnss_last_rms_m: f64,
    pub front_end_s: f64,
    pub submaps_s: f64,
    pub m2dp_s: f64,
    pub verification_s: f64,
    pub back_end_s: f64,
    pub total_s: f64,
}

impl BuildReport {
    /// The input, the front end's counts, the loop and GNSS counts and the stages' times;
    /// the submaps' counts zero.
    fn new(
        sweeps: &[Sweep],
        odometry: &frontend::Odometry,
        loops: &LoopCounts,
        gnss: &GnssCounts,
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
            gnss_submaps_with_fix: gnss.submaps_with_fix,
            gnss_priors: gnss.priors,
            gnss_opened_at: gnss.opened_at,
            gnss_solves: gnss.solves,
            gnss_rebuilds: gnss.rebuilds,
            gnss_last_rms_m: gnss.last_rms_m,
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
    /// the pose graph, each submap linked to the one before by ICP, its loops detected,
    /// verified and added, then its GNSS prior if the gate lets one through (`gnss.rs`);
    /// the trajectory and map from the optimised submaps.
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
        if let Some(g) = &mut self.gnss {
            stages
                .time("back_end", || {
                    g.add_submap(0, submaps[0].stamp_ns, &mut graph)
                })
                .map_err(backend_error)?;
        }
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
            if let Some(g) = &mut self.gnss {
                stages
                    .time("back_end", || {
                        g.add_submap(i, submaps[i].stamp_ns, &mut graph)
                    })
                    .map_err(backend_error)?;
            }
        }
        let mut events = loops.events;
        let gnss_counts = match &mut self.gnss {
            Some(g) => {
                events.append(&mut g.events);
                g.counts
            }
            None => GnssCounts::default(),
        };
        let output = self.output(&odometry, &submaps, &graph, events);
        let report = BuildReport {
            submaps: submaps.len(),
            submap_matches_accepted: matches_accepted,
            ..BuildReport::new(
                &self.sweeps,
                &odometry,
                &loops.counts,
                &gnss_counts,
                &stages,
                started,
            )
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
            map_from_enu: self.gnss.as_ref().and_then(SubmapGnss::map_from_enu),
        };
        SlamOutput {
            trajectory,
            map: Some(map),
            grid: None,
            events,
            saved_map: Some(SavedMap {
                format: KEYFRAME_MAP_FORMAT.into(),
                version: saved.version(),
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

    /// The GNSS receiver too when `[gps] use_gps`.
    fn requirements_for(config_toml: &str) -> Result<Requirements, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let mut requirements = Self::requirements();
        if cfg.gps.use_gps {
            requirements.sensors.push(SensorKind::Gnss);
        }
        Ok(requirements)
    }

    /// Localisation in a map a mapping run saved (its optimised submaps): the front end
    /// runs online as odometry, and each sweep's kept points are registered to the saved
    /// submaps (`slam_common::maps::localizer`: Scan Context search, ICP verification).
    /// StaticMapping itself has no localisation mode; this composes its front end with the
    /// localiser lio-sam uses, so that the two lidar systems differ by their maps and their
    /// odometry, not by the localiser.
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        if start.format != KEYFRAME_MAP_FORMAT || !reads_version(start.format_version) {
            return Err(PluginError::new(format!(
                "staticmapping reads {KEYFRAME_MAP_FORMAT} versions 1 to {KEYFRAME_MAP_VERSION} maps, not {} version {}",
                start.format, start.format_version
            )));
        }
        let map =
            KeyframeMap::from_bytes(start.map, start.format_version).map_err(PluginError::new)?;
        let mut system = Self::new(config_toml, rig)?;
        // The saved map is the reference: no GNSS prior moves it; a map made with GNSS
        // keeps its georeference, and with a receiver now each fix is a prior for the
        // global search, as lio-sam's.
        let receiver = system.gnss.take().and(rig.first(SensorKind::Gnss));
        let antenna_offset_m = map.map_from_enu.and(receiver).map(|receiver| {
            slam_common::gnss::horizontal_lever_m(
                &system.lidar_from_base,
                &receiver.base_from_sensor(),
            )
        });
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
            antenna_offset_m,
            events: Vec::new(),
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
        let imu = rig.first(SensorKind::Imu);
        let imu_from_lidar = imu
            .map(|imu| (imu.base_from_sensor().inverse() * base_from_lidar).rotation)
            .unwrap_or_else(UnitQuaternion::identity);
        let gnss = match (cfg.gps.use_gps, rig.first(SensorKind::Gnss)) {
            (false, _) => None,
            (true, None) => {
                eprintln!(
                    "staticmapping: [gps] use_gps, but the world has no GNSS receiver: no GNSS priors"
                );
                None
            }
            (true, Some(receiver)) => {
                // No IMU orientation needed: the transform is solved from the track.
                let lidar_from_antenna = (base_from_lidar.inverse() * receiver.base_from_sensor())
                    .translation
                    .vector;
                Some(SubmapGnss::new(cfg.gps.clone(), lidar_from_antenna))
            }
        };
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(cfg.seed),
            sweep_ns: (1e9 / lidar.rate_hz).round() as i64,
            imu_from_lidar,
            lidar_from_base: base_from_lidar.inverse(),
            sweeps: Vec::new(),
            gyro: Vec::new(),
            localizing: None,
            gnss,
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

    /// Keeps the epoch for the submaps' GNSS priors; refuses one that cannot be used with
    /// a `gnss_rejected` event (never an error). Ignored without `[gps] use_gps`.
    fn on_gnss(&mut self, gnss: &GnssMessage) -> Result<Option<Pose>, PluginError> {
        if let Some(l) = &mut self.localizing {
            if let Some(offset_m) = l.antenna_offset_m {
                match gnss.usable() {
                    Ok((p, c)) => l.localizer.gnss_fix(&p, &c, offset_m),
                    Err(problem) => l
                        .events
                        .push(gnss.rejected("staticmapping (a localisation prior)", problem)),
                }
            }
            return Ok(None);
        }
        if let Some(g) = &mut self.gnss {
            g.push(gnss);
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
                events: std::mem::take(&mut l.events),
                ..SlamOutput::default()
            });
        }
        let (output, report) = self.build()?;
        if let Some(g) = &self.gnss {
            eprintln!(
                "staticmapping: {} GNSS priors ({} submaps with a fix; gate opened at submap \
                 {:?}; {} solves of the ENU-to-map transform, {} rebuilds of the priors, last \
                 RMS residual {:.3} m)",
                report.gnss_priors,
                report.gnss_submaps_with_fix,
                report.gnss_opened_at,
                report.gnss_solves,
                report.gnss_rebuilds,
                report.gnss_last_rms_m,
            );
            if let Some((first, last)) = g.solves() {
                let angles = |t: &Isometry3<f64>| {
                    let (yaw, tilt) = crate::gnss::yaw_and_tilt(&t.rotation);
                    format!(
                        "yaw {:.2}°, tilt {:.2}°",
                        yaw.to_degrees(),
                        tilt.to_degrees()
                    )
                };
                let moved = first.inverse() * last;
                eprintln!(
                    "staticmapping: enu_from_map first solve {}, last {}: moved {:.3}° and \
                     {:.3} m",
                    angles(&first),
                    angles(&last),
                    moved.rotation.angle().to_degrees(),
                    moved.translation.vector.norm()
                );
            }
        }
        if let Some(path) = &self.cfg.timing_json {
            let text = serde_json::to_string_pretty(&report)
                .map_err(|e| PluginError::new(format!("timing_json: {e}")))?;
            std::fs::write(path, text + "\n")
                .map_err(|e| PluginError::new(format!("timing_json {}: {e}", path.display())))?;
        }
        Ok(output)
    }
}

#[cfg(test)]
mod tests {
    use plugin_api::{EventKind, GnssStatus, LidarPoint, SensorSpec};

    use super::*;

    const MS: i64 = 1_000_000;
    const GPS_ON: &str = "[gps]\nuse_gps = true\n";

    fn sensor(kind: SensorKind, xyz: [f64; 3], xyzw: [f64; 4], orientation: bool) -> SensorSpec {
        SensorSpec {
            name: kind.name().into(),
            kind,
            rate_hz: 10.0,
            base_from_sensor_xyz: xyz,
            base_from_sensor_xyzw: xyzw,
            intrinsics: [(
                "reports_orientation".to_string(),
                f64::from(u8::from(orientation)),
            )]
            .into_iter()
            .collect(),
            noise: Default::default(),
        }
    }

    /// A lidar yawed 90° on the base, an IMU, and a receiver if `receiver`.
    fn rig(orientation: bool, receiver: bool) -> Rig {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let mut sensors = vec![
            sensor(SensorKind::Lidar, [0.5, 0.0, 1.0], [0.0, 0.0, h, h], false),
            sensor(
                SensorKind::Imu,
                [0.0, 0.0, 0.6],
                [0.0, 0.0, 0.0, 1.0],
                orientation,
            ),
        ];
        if receiver {
            sensors.push(sensor(
                SensorKind::Gnss,
                [-0.2, 0.0, 1.7],
                [0.0, 0.0, 0.0, 1.0],
                false,
            ));
        }
        Rig { sensors }
    }

    fn epoch(stamp_ns: i64, status: GnssStatus, enu: [f64; 3], variance: f64) -> GnssMessage {
        GnssMessage {
            stamp_ns,
            status,
            satellites: 12,
            position_enu_m: enu,
            covariance_enu_m2: [variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance],
            latitude_deg: 52.0,
            longitude_deg: 5.0,
            altitude_m: 40.0,
            hdop: 0.9,
        }
    }

    #[test]
    fn the_receiver_is_asked_for_only_with_use_gps() {
        // Guards requirements_for: GNSS joins the sensors with `[gps] use_gps` only, and
        // the original's names parse while others are refused.
        let off = StaticMapping::requirements_for("").expect("defaults");
        assert_eq!(off, StaticMapping::requirements());
        assert!(!off.sensors.contains(&SensorKind::Gnss));
        let on = StaticMapping::requirements_for(
            "[gps]\nuse_gps = true\ngps_factor_init_num = 10\ngps_factor_sample_step = 2\n\
             gps_factor_init_angle_rad = 1.5\n",
        )
        .expect("gps");
        assert!(on.sensors.contains(&SensorKind::Gnss));
        assert!(on.sensors.contains(&SensorKind::Lidar) && on.sensors.contains(&SensorKind::Imu));
        assert_eq!((on.mode, on.can_localize), (Mode::Offline, true));
        assert!(StaticMapping::requirements_for("[gps]\nenabled = true\n").is_err());
    }

    #[test]
    fn use_gps_needs_no_imu_heading_and_does_without_a_receiver() {
        // Guards the set-up: the transform is solved from the track, so an IMU that
        // reports no orientation is enough; a world without a receiver leaves GNSS off;
        // the lever arm is the antenna's mount seen from the (yawed) lidar.
        for orientation in [false, true] {
            let with = StaticMapping::new(GPS_ON, &rig(orientation, true)).expect("receiver");
            let lever = with.gnss.as_ref().expect("gnss").lidar_from_antenna();
            assert!(
                (lever - Vector3::new(0.0, 0.7, 0.7)).norm() < 1e-12,
                "{lever}"
            );
        }
        let without = StaticMapping::new(GPS_ON, &rig(true, false)).expect("no receiver");
        assert!(without.gnss.is_none());
        let off = StaticMapping::new("", &rig(false, true)).expect("gps off");
        assert!(off.gnss.is_none());
    }

    /// A sweep of a box room 12 m across with a floor, seen from its middle.
    fn room() -> Vec<LidarPoint> {
        let mut points = Vec::new();
        let mut push = |x: f64, y: f64, z: f64| {
            points.push(LidarPoint {
                x: x as f32,
                y: y as f32,
                z: z as f32,
                intensity: 0.0,
                time_s: 0.0,
                ring: 0,
            });
        };
        for i in 0..60 {
            for j in 0..15 {
                let u = -6.0 + 0.2 * f64::from(i);
                let z = -1.0 + 0.25 * f64::from(j);
                push(6.0, u, z);
                push(-6.0, u, z);
                push(u, 6.0, z);
                push(u, -6.5, z);
            }
            for j in 0..60 {
                push(-6.0 + 0.2 * f64::from(i), -6.0 + 0.2 * f64::from(j), -1.0);
            }
        }
        points
    }

    #[test]
    fn broken_fixes_are_events_and_good_ones_give_the_first_submap_a_position() {
        // Guards on_gnss and the build: NaN, no fix and a zero covariance come out as
        // gnss_rejected events, never an error or a panic; the fixes either side of the
        // first sweep give its submap a position, cached (one submap opens no gate, so
        // nothing is solved); without `[gps]` fixes are ignored. The IMU's orientation,
        // reported with a heading error of 0.3 rad or not at all, changes nothing.
        let run = |config: &str, orientation: Option<[f64; 4]>| {
            let mut system =
                StaticMapping::new(config, &rig(orientation.is_some(), true)).expect("system");
            let points = room();
            let imu = |stamp_ns: i64| Imu {
                stamp_ns,
                accel_mps2: [0.0, 0.0, 9.81],
                gyro_rps: [0.0; 3],
                orientation_xyzw: orientation.unwrap_or([0.0; 4]),
            };
            let gnss = |s: &mut StaticMapping, e: GnssMessage| s.on_gnss(&e).expect("on_gnss");
            gnss(
                &mut system,
                epoch(950 * MS, GnssStatus::Fixed, [5.0, 5.0, 1.0], 1e-4),
            );
            for k in 0..=30 {
                system.on_imu(&imu(900 * MS + 10 * k * MS)).expect("imu");
            }
            gnss(
                &mut system,
                epoch(1050 * MS, GnssStatus::Float, [5.0, 5.0, 1.0], 1e-2),
            );
            for stamp in [1000 * MS, 1100 * MS] {
                let cloud = PointCloud {
                    stamp_ns: stamp,
                    sensor: "lidar",
                    points: &points,
                };
                assert_eq!(system.on_point_cloud(&cloud), Ok(None));
            }
            let nan = epoch(1150 * MS, GnssStatus::Single, [f64::NAN, 1.0, 2.0], 1.0);
            let no_fix = GnssMessage {
                status: GnssStatus::NoFix,
                ..nan
            };
            let flat = epoch(1170 * MS, GnssStatus::Fixed, [1.0, 2.0, 3.0], 0.0);
            for e in [nan, no_fix, flat] {
                gnss(&mut system, e);
            }
            system.build().expect("build")
        };
        let (h, w) = (0.15f64.sin(), 0.15f64.cos());
        let (output, report) = run(GPS_ON, Some([0.0, 0.0, h, w]));
        let kinds: Vec<EventKind> = output.events.iter().map(|e| e.kind).collect();
        assert_eq!(kinds, vec![EventKind::GnssRejected; 3]);
        assert_eq!(report.submaps, 1);
        assert_eq!(report.gnss_submaps_with_fix, 1);
        assert_eq!(
            (
                report.gnss_priors,
                report.gnss_opened_at,
                report.gnss_solves
            ),
            (0, None, 0)
        );
        let (without, _) = run(GPS_ON, None);
        assert_eq!(without.trajectory, output.trajectory);
        assert_eq!(without.events.len(), 3);
        let (output, report) = run("", Some([0.0, 0.0, 0.0, 1.0]));
        assert!(output.events.is_empty());
        assert_eq!(report.gnss_submaps_with_fix, 0);
    }
}
