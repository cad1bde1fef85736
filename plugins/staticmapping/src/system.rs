use std::time::Instant;

use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};
use plugin_api::{
    Event, EventKind, Imu, Mode, PluginError, PointCloud, Pose, Requirements, Rig, SensorKind,
    SlamOutput, SlamSystem,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use slam_common::m2dp::{self, Descriptor, M2dpConfig, Rings};
use slam_common::voxel::downsample;

use crate::config::{Config, DescriptorVariant};
use crate::frontend::{self, Gyro};
use crate::graph::SubmapGraph;
use crate::input::{self, Sweep};
use crate::loops::{self, Persistence};
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

fn seconds_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
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

    /// The whole offline build: trajectory, map, events and the report.
    pub fn build(&mut self) -> Result<(SlamOutput, BuildReport), PluginError> {
        let started = Instant::now();
        let cfg = &self.cfg;
        let mut report = BuildReport {
            sweeps: self.sweeps.len(),
            points_kept: self.sweeps.iter().map(|s| s.points.len()).sum(),
            ..BuildReport::default()
        };
        let t = Instant::now();
        let odometry = frontend::run(
            &self.sweeps,
            &self.gyro,
            self.imu_from_lidar,
            self.sweep_ns,
            cfg,
        );
        report.front_end_s = seconds_since(t);
        report.keyframes = odometry.keyframes.len();
        report.front_end_failed_matches = odometry.failed_matches;
        report.front_end_mean_score = odometry.mean_score;
        if odometry.keyframes.is_empty() {
            return Err(PluginError::new("no lidar sweep was received"));
        }

        let t = Instant::now();
        let submaps = submap::build(&odometry.keyframes, cfg);
        report.submaps = submaps.len();
        report.submaps_s += seconds_since(t);

        let t = Instant::now();
        let m2dp_cfg = self.m2dp_config();
        let descriptors: Vec<Option<Descriptor>> = if cfg.loop_closure.enabled {
            submaps
                .par_iter()
                .map(|s| m2dp::descriptor(&s.cloud, &m2dp_cfg))
                .collect()
        } else {
            vec![None; submaps.len()]
        };
        report.m2dp_s = seconds_since(t);

        let backend_error = |e| PluginError::new(format!("backend: {e}"));
        let mut graph = SubmapGraph::new(&cfg.backend).map_err(backend_error)?;
        let t = Instant::now();
        graph
            .add_first(submaps[0].odometry_pose)
            .map_err(backend_error)?;
        report.back_end_s += seconds_since(t);
        let mut loops = LoopCloser {
            cfg,
            submaps: &submaps,
            descriptors: &descriptors,
            lidar_from_base: self.lidar_from_base,
            persistence: Persistence::default(),
            events: Vec::new(),
        };
        for i in 1..submaps.len() {
            let t = Instant::now();
            let m = submap::match_to_previous(&submaps[i - 1], &submaps[i], cfg);
            report.submaps_s += seconds_since(t);
            report.submap_matches_accepted += usize::from(m.accepted);
            let t = Instant::now();
            graph
                .add_next(m.previous_from_current)
                .map_err(backend_error)?;
            report.back_end_s += seconds_since(t);
            if cfg.loop_closure.enabled {
                loops.close(i, &mut graph, &mut report)?;
            }
        }
        let events = loops.events;

        let trajectory = odometry
            .sweeps
            .iter()
            .map(|&(stamp_ns, world_from_lidar, kf)| {
                let s = kf / cfg.submap.frame_count;
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
        let map = downsample(&points, cfg.submap.map_voxel_m)
            .into_iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect();
        report.total_s = seconds_since(started);
        Ok((
            SlamOutput {
                trajectory,
                map: Some(map),
                grid: None,
                events,
            },
            report,
        ))
    }
}

/// Loop detection, verification and insertion over the submaps, one at a time.
struct LoopCloser<'a> {
    cfg: &'a Config,
    submaps: &'a [Submap],
    descriptors: &'a [Option<Descriptor>],
    lidar_from_base: Isometry3<f64>,
    persistence: Persistence,
    events: Vec<Event>,
}

impl LoopCloser<'_> {
    /// Detects, verifies and adds the loops of submap `i`, just added to `graph`.
    fn close(
        &mut self,
        i: usize,
        graph: &mut SubmapGraph,
        report: &mut BuildReport,
    ) -> Result<(), PluginError> {
        let (cfg, submaps, descriptors) = (self.cfg, self.submaps, self.descriptors);
        let lidar_from_base = &self.lidar_from_base;
        let (persistence, events) = (&mut self.persistence, &mut self.events);
        let lc = &cfg.loop_closure;
        let positions: Vec<Vector3<f64>> =
            (0..=i).map(|k| graph.pose(k).translation.vector).collect();
        let t = Instant::now();
        let pairs = loops::candidates(i, &positions, &descriptors[..=i], lc);
        report.m2dp_s += seconds_since(t);
        report.loop_detections += usize::from(!pairs.is_empty());
        if !persistence.step(!pairs.is_empty(), 1) {
            return Ok(());
        }
        let t = Instant::now();
        let here = graph.pose(i);
        let mut edges = Vec::new();
        for &j in &pairs {
            report.loop_verifications += 1;
            if let Ok(edge) = loops::verify(
                &submaps[i].cloud,
                &here,
                j,
                &submaps[j].reference,
                &graph.pose(j),
                lc,
                &cfg.icp,
            ) {
                edges.push(edge);
            }
        }
        report.verification_s += seconds_since(t);
        report.loop_edges_verified += edges.len();
        if edges.is_empty() {
            return Ok(());
        }
        let stamp = submaps[i].stamp_ns;
        match loops::agree(&edges, |k| graph.pose(k), lc) {
            Ok(()) => {
                for e in &edges {
                    let base_from_lidar = lidar_from_base.inverse();
                    events.push(
                        Event::loop_closure(
                            stamp,
                            EventKind::LoopClosureAccepted,
                            [stamp, submaps[e.target].stamp_ns],
                            format!(
                                "submap {i} to submap {} (score {:.3}, {} agreeing edges)",
                                e.target,
                                e.score,
                                edges.len()
                            ),
                        )
                        .with_relative_pose(
                            &(base_from_lidar * e.target_from_current * lidar_from_base),
                        ),
                    );
                }
                report.loops_accepted += 1;
                report.loop_edges_added += edges.len();
                let t = Instant::now();
                graph
                    .add_loops(i, edges.iter().map(|e| (e.target, e.target_from_current)))
                    .map_err(|e| PluginError::new(format!("backend: {e}")))?;
                report.back_end_s += seconds_since(t);
            }
            Err((m, rad)) => {
                report.loops_rejected += 1;
                let first = edges[0];
                events.push(Event::loop_closure(
                    stamp,
                    EventKind::LoopClosureRejected,
                    [stamp, submaps[first.target].stamp_ns],
                    format!(
                        "submap {i}: {} verified edges disagree by {m:.3} m, {rad:.4} rad",
                        edges.len()
                    ),
                ));
            }
        }
        Ok(())
    }
}

impl SlamSystem for StaticMapping {
    const NAME: &'static str = "staticmapping";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements {
            sensors: vec![SensorKind::Lidar, SensorKind::Imu],
            mode: Mode::Offline,
        }
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg =
            Config::parse(config_toml).map_err(|e| PluginError::new(format!("parameters: {e}")))?;
        let lidar = rig
            .first(SensorKind::Lidar)
            .ok_or_else(|| PluginError::new("the rig has no 3D lidar"))?;
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
        self.sweeps.push(input::filter(
            cloud.stamp_ns,
            cloud.points,
            &self.cfg.input,
            &mut self.rng,
        ));
        Ok(None)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
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
