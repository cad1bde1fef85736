//! The plugin: ORB-SLAM2's three threads — tracking, local mapping, loop closing — run one
//! after the other on each camera frame, so that a run is deterministic.

use std::time::Instant;

use nalgebra::Isometry3;
use plugin_api::{
    Event, EventKind, PluginError, Pose, Requirements, RgbdFrame, Rig, SensorKind, SlamOutput,
    SlamSystem,
};
use slam_common::ba::StereoCamera;
use slam_common::vocabulary::Vocabulary;

use crate::config::Config;
use crate::frame::{Camera, Frame};
use crate::local_mapping::LocalMapping;
use crate::loop_closing::{LoopClosing, Verdict};
use crate::map::Map;
use crate::orb::{OrbExtractor, gray_from_rgb};
use crate::tracking::{Context, Outcome, Tracking};

/// The vocabulary shipped with the plugin (see `plugins/orbslam2/vocabulary/README.md`).
static SHIPPED_VOCABULARY: &[u8] = include_bytes!("../vocabulary/vineyard-k10l6.dbow");

/// A frame's pose as tracking left it: relative to its reference keyframe, so that the
/// final trajectory follows the optimised keyframes (ORB-SLAM2's `mlRelativeFramePoses`).
#[derive(Debug, Clone, Copy)]
struct Record {
    stamp_ns: i64,
    reference_kf: usize,
    camera_from_reference: Isometry3<f64>,
}

/// Durations of the stages, seconds, for the summary printed at the end.
#[derive(Debug, Default)]
struct Timings {
    frame: Vec<f64>,
    local_mapping: Vec<f64>,
    loop_correction: Vec<f64>,
}

fn percentile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

/// ORB-SLAM2-style RGB-D SLAM.
#[derive(Debug)]
pub struct OrbSlam2 {
    cfg: Config,
    camera: Camera,
    fps: u64,
    /// `camera_from_base` (the optical frame): the map frame is the base at the first frame.
    camera_from_base: Isometry3<f64>,
    extractor: OrbExtractor,
    vocabulary: Vocabulary,
    map: Map,
    tracking: Tracking,
    local_mapping: LocalMapping,
    loop_closing: LoopClosing,
    records: Vec<Record>,
    events: Vec<Event>,
    timings: Timings,
}

impl OrbSlam2 {
    fn base_pose(&self, camera_from_world: &Isometry3<f64>) -> Isometry3<f64> {
        camera_from_world.inverse() * self.camera_from_base
    }

    fn stamp_of(&self, kf: usize) -> i64 {
        self.map.keyframes[kf].frame.stamp_ns
    }

    fn loop_event(&mut self, stamp_ns: i64, verdict: Verdict) {
        let event = match verdict {
            Verdict::Accepted {
                current,
                matched,
                inliers,
                projected,
                correction_m,
                correction_rad,
            } => Event::loop_closure(
                stamp_ns,
                EventKind::LoopClosureAccepted,
                [self.stamp_of(current), self.stamp_of(matched)],
                format!(
                    "keyframe {current} (t_ns={}) with keyframe {matched} (t_ns={}): {inliers} inliers, {projected} loop matches; correction {correction_m:.3} m, {:.2} deg",
                    self.stamp_of(current),
                    self.stamp_of(matched),
                    correction_rad.to_degrees()
                ),
            ),
            Verdict::Rejected {
                current,
                matched,
                reason,
            } => Event::loop_closure(
                stamp_ns,
                EventKind::LoopClosureRejected,
                [self.stamp_of(current), self.stamp_of(matched)],
                format!(
                    "keyframe {current} (t_ns={}) with keyframe {matched} (t_ns={}): {reason}",
                    self.stamp_of(current),
                    self.stamp_of(matched)
                ),
            ),
        };
        self.events.push(event);
    }
}

impl SlamSystem for OrbSlam2 {
    const NAME: &'static str = "orbslam2";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::Rgbd])
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let spec = rig
            .sensor(&cfg.camera)
            .filter(|s| s.kind == SensorKind::Rgbd)
            .ok_or_else(|| {
                PluginError::new(format!(
                    "the rig has no RGB-D camera called {:?}",
                    cfg.camera
                ))
            })?;
        let k = |key: &str| {
            spec.intrinsics
                .get(key)
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| {
                    PluginError::new(format!("the camera's intrinsics lack a positive {key}"))
                })
        };
        let (fx, fy, cx, cy) = (k("fx")?, k("fy")?, k("cx")?, k("cy")?);
        let (width, height) = (k("width")?, k("height")?);
        let extractor = OrbExtractor::new(cfg.orb)
            .map_err(|e| PluginError::new(format!("ORB extractor: {e}")))?;
        let camera = Camera {
            stereo: StereoCamera {
                fx,
                fy,
                cx,
                cy,
                bf: cfg.baseline_m * fx,
            },
            width,
            height,
            close_depth_m: cfg.close_depth_m(),
            min_depth_m: cfg.min_depth_m,
            max_depth_m: cfg.max_depth_m,
            scale_factors: extractor.scale_factors().to_vec(),
            level_sigma2: extractor.level_sigma2().to_vec(),
            inv_level_sigma2: extractor.inv_level_sigma2().to_vec(),
            log_scale: cfg.orb.scale_factor.ln(),
        };
        let vocabulary = if cfg.vocabulary.is_empty() {
            Vocabulary::read_from(&mut &SHIPPED_VOCABULARY[..])
                .map_err(|e| PluginError::new(format!("the shipped vocabulary: {e}")))?
        } else {
            Vocabulary::load(std::path::Path::new(&cfg.vocabulary))
                .map_err(|e| PluginError::new(format!("vocabulary {}: {e}", cfg.vocabulary)))?
        };
        Ok(Self {
            fps: spec.rate_hz.round().max(1.0) as u64,
            camera_from_base: spec.base_from_sensor().inverse(),
            camera,
            extractor,
            vocabulary,
            map: Map::default(),
            tracking: Tracking::default(),
            local_mapping: LocalMapping::default(),
            loop_closing: LoopClosing::default(),
            records: Vec::new(),
            events: Vec::new(),
            timings: Timings::default(),
            cfg,
        })
    }

    fn on_rgbd(&mut self, image: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let start = Instant::now();
        let (w, h) = (image.width as usize, image.height as usize);
        if image.rgb.len() != 3 * w * h || image.depth_m.len() != w * h {
            return Err(PluginError::new(format!(
                "camera frame at {} ns: {}x{} but {} colour bytes and {} depths",
                image.stamp_ns,
                w,
                h,
                image.rgb.len(),
                image.depth_m.len()
            )));
        }
        // Tracking thread: ORB extraction and tracking.
        let gray = gray_from_rgb(image.rgb, w, h);
        let (keys, descriptors) = self
            .extractor
            .extract(&gray, w, h)
            .map_err(|e| PluginError::new(format!("ORB extraction: {e}")))?;
        let mut frame = Frame::new(
            image.stamp_ns,
            &self.camera,
            keys,
            descriptors,
            image.depth_m,
            w,
        );
        let initial = self.camera_from_base;
        let ctx = Context {
            cfg: &self.cfg,
            camera: &self.camera,
            vocabulary: &self.vocabulary,
            database: &self.loop_closing.database,
            fps: self.fps,
        };
        let outcome = self
            .tracking
            .track(&mut frame, &mut self.map, &ctx, &initial);
        let pose = match &outcome {
            Outcome::Tracked {
                keyframe,
                relocalised,
            } => {
                if *relocalised {
                    self.events.push(Event::new(
                        image.stamp_ns,
                        EventKind::TrackingRecovered,
                        "relocalised".to_string(),
                    ));
                }
                if let Some(kf) = *keyframe {
                    // Local mapping thread.
                    let lm_start = Instant::now();
                    self.local_mapping.process(
                        kf,
                        &mut self.map,
                        &self.camera,
                        &self.cfg.local_mapping,
                    );
                    self.timings
                        .local_mapping
                        .push(lm_start.elapsed().as_secs_f64());
                    // Loop closing thread.
                    let verdicts = self.loop_closing.process(
                        kf,
                        &mut self.map,
                        &self.camera,
                        &self.cfg.loop_closing,
                        &self.cfg.backend,
                    );
                    for v in verdicts {
                        if matches!(v, Verdict::Accepted { .. }) {
                            if let Some(s) = self.loop_closing.last_correction_s {
                                self.timings.loop_correction.push(s);
                            }
                        }
                        self.loop_event(image.stamp_ns, v);
                    }
                }
                let (reference_kf, camera_from_reference) = self
                    .tracking
                    .reference()
                    .expect("a tracked frame has a reference keyframe");
                self.records.push(Record {
                    stamp_ns: image.stamp_ns,
                    reference_kf,
                    camera_from_reference,
                });
                let camera_from_world = camera_from_reference * self.map.carried_pose(reference_kf);
                Some(Pose::new(
                    image.stamp_ns,
                    &self.base_pose(&camera_from_world),
                ))
            }
            Outcome::Lost { newly } => {
                if *newly {
                    self.events.push(Event::new(
                        image.stamp_ns,
                        EventKind::TrackingLost,
                        format!(
                            "{} keypoints, {} tracked map points",
                            frame.len(),
                            self.tracking.inliers
                        ),
                    ));
                }
                None
            }
            Outcome::NotInitialized => None,
        };
        self.timings.frame.push(start.elapsed().as_secs_f64());
        Ok(pose)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        let trajectory = self
            .records
            .iter()
            .map(|r| {
                let camera_from_world =
                    r.camera_from_reference * self.map.carried_pose(r.reference_kf);
                Pose::new(r.stamp_ns, &self.base_pose(&camera_from_world))
            })
            .collect();
        let map_points = self
            .map
            .points
            .iter()
            .filter(|p| !p.bad && !p.observations.is_empty())
            .map(|p| [p.world.x as f32, p.world.y as f32, p.world.z as f32])
            .collect();
        let t = &self.timings;
        eprintln!(
            "orbslam2: {} keyframes ({} live), {} points; frame p50 {:.1} ms p99 {:.1} ms; local mapping n={} p50 {:.1} ms p99 {:.1} ms; loop corrections n={} max {:.2} s",
            self.map.keyframes.len(),
            self.map.live_keyframe_count(),
            self.map.points.iter().filter(|p| !p.bad).count(),
            1e3 * percentile(&t.frame, 0.5),
            1e3 * percentile(&t.frame, 0.99),
            t.local_mapping.len(),
            1e3 * percentile(&t.local_mapping, 0.5),
            1e3 * percentile(&t.local_mapping, 0.99),
            t.loop_correction.len(),
            t.loop_correction.iter().copied().fold(0.0, f64::max),
        );
        Ok(SlamOutput {
            trajectory,
            map: Some(map_points),
            grid: None,
            events: std::mem::take(&mut self.events),
        })
    }
}
