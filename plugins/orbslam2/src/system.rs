//! The plugin: ORB-SLAM2's three threads — tracking, local mapping, loop closing — run one
//! after the other on each camera frame, so that a run is deterministic.

use std::time::Instant;

use nalgebra::Isometry3;
use plugin_api::{
    Event, EventKind, MapStart, Parameters, PluginError, Pose, PoseStatus, Requirements, RgbdFrame,
    Rig, SavedMap, SensorKind, SlamOutput, SlamSystem, Stages,
};
use slam_common::factor_graph::ba::StereoCamera;
use slam_common::place::vocabulary::Vocabulary;

use crate::config::Config;
use crate::frame::{Camera, Frame};
use crate::local_mapping::LocalMapping;
use crate::loop_closing::{LoopClosing, Verdict};
use crate::map::Map;
use crate::orb::OrbExtractor;
use crate::saved::{ORB_MAP_FORMAT, ORB_MAP_VERSION};
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
    /// Durations of the pipeline's stages, for the summary printed at the end.
    stages: Stages,
    /// Localisation mode: the poses returned, in the loaded map (`None` when mapping).
    localizing: Option<Vec<Pose>>,
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
                keypoints,
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
            )
            .with_matches(keypoints),
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

    fn event(&mut self, stamp_ns: i64, kind: EventKind, detail: String) {
        self.events.push(Event::new(stamp_ns, kind, detail));
    }

    /// Tracking failed on the frame of `keypoints` keypoints, after tracking had held.
    fn lost(&mut self, stamp_ns: i64, keypoints: usize) {
        let detail = format!(
            "{keypoints} keypoints, {} tracked map points",
            self.tracking.inliers
        );
        self.event(stamp_ns, EventKind::TrackingLost, detail);
    }

    /// The loop closing thread on a new keyframe: detection, verification and correction,
    /// each verdict an event.
    fn close_loops(&mut self, stamp_ns: i64, kf: usize) {
        let verdicts = self.loop_closing.process(
            kf,
            &mut self.map,
            &self.camera,
            &self.cfg.loop_closing,
            &self.cfg.backend,
        );
        for verdict in verdicts {
            if matches!(verdict, Verdict::Accepted { .. }) {
                if let Some(s) = self.loop_closing.last_correction_s {
                    self.stages.record("loop_correction", s);
                }
            }
            self.loop_event(stamp_ns, verdict);
        }
    }

    /// Localisation mode's answer to a frame: the tracked pose in the loaded map, or while
    /// lost the last pose returned (the origin before any) for the host to see searching.
    fn localized_pose(&mut self, stamp_ns: i64, frame: &Frame, outcome: &Outcome) -> Pose {
        let poses = self.localizing.as_mut().expect("localisation mode");
        let base = match outcome {
            Outcome::Tracked { .. } => frame.camera_from_world.inverse() * self.camera_from_base,
            _ => poses
                .last()
                .and_then(Pose::isometry)
                .unwrap_or_else(Isometry3::identity),
        };
        let pose = Pose::new(stamp_ns, &base);
        poses.push(pose);
        pose
    }

    /// A tracked frame's pose, kept relative to its reference keyframe so that the final
    /// trajectory follows the optimised keyframes (ORB-SLAM2's `mlRelativeFramePoses`).
    fn record_tracked(&mut self, stamp_ns: i64) -> Pose {
        let (reference_kf, camera_from_reference) = self
            .tracking
            .reference()
            .expect("a tracked frame has a reference keyframe");
        self.records.push(Record {
            stamp_ns,
            reference_kf,
            camera_from_reference,
        });
        let camera_from_world = camera_from_reference * self.map.carried_pose(reference_kf);
        Pose::new(stamp_ns, &self.base_pose(&camera_from_world))
    }
}

/// A camera frame as tracking takes it: its ORB features on the grey image, each with its
/// depth and virtual right coordinate.
fn orb_frame(
    image: &RgbdFrame<'_>,
    extractor: &mut OrbExtractor,
    camera: &Camera,
) -> Result<Frame, PluginError> {
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
    let gray = image.gray();
    let (keys, descriptors) = extractor
        .extract(&gray, w, h)
        .map_err(|e| PluginError::new(format!("ORB extraction: {e}")))?;
    Ok(Frame::new(
        image.stamp_ns,
        camera,
        keys,
        descriptors,
        image.depth_m,
        w,
    ))
}

impl SlamSystem for OrbSlam2 {
    const NAME: &'static str = "orbslam2";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::Rgbd]).localizing()
    }

    /// ORB-SLAM2's localisation mode (`System::ActivateLocalizationMode`, Mur-Artal and
    /// Tardós 2017, §III-F "Localization Mode"): local mapping and loop closing stopped,
    /// tracking against the loaded map's points, relocalisation by bag of words when lost,
    /// visual odometry from the last frame's depth when the map's points are out of view.
    /// ORB-SLAM2 has no pose prior: an initial guess is not used, the first frames are
    /// relocalised like any lost frame.
    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        if (start.format, start.format_version) != (ORB_MAP_FORMAT, ORB_MAP_VERSION) {
            return Err(PluginError::new(format!(
                "orbslam2 reads {ORB_MAP_FORMAT} version {ORB_MAP_VERSION} maps, not {} version {}",
                start.format, start.format_version
            )));
        }
        let mut system = Self::new(config_toml, rig)?;
        let (map, database) =
            crate::saved::from_bytes(start.map, &system.camera, &system.vocabulary)
                .map_err(PluginError::new)?;
        system.map = map;
        system.loop_closing.database = database;
        system.tracking = Tracking::localizing();
        system.localizing = Some(Vec::new());
        Ok(system)
    }

    fn status(&self) -> PoseStatus {
        if self.localizing.is_none() || self.tracking.localized() {
            PoseStatus::Localized
        } else {
            PoseStatus::Searching
        }
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let cfg = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let spec = rig.require(&cfg.camera, SensorKind::Rgbd)?;
        let pinhole = spec.pinhole()?;
        let lens = spec.lens()?;
        let extractor = OrbExtractor::new(cfg.orb)
            .map_err(|e| PluginError::new(format!("ORB extractor: {e}")))?;
        let camera = Camera {
            stereo: StereoCamera {
                fx: pinhole.fx,
                fy: pinhole.fy,
                cx: pinhole.cx,
                cy: pinhole.cy,
                bf: cfg.baseline_m * pinhole.fx,
            },
            width: pinhole.width,
            height: pinhole.height,
            bounds: Camera::image_bounds(&pinhole, lens.as_ref()),
            lens,
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
            stages: Stages::default(),
            localizing: None,
            cfg,
        })
    }

    /// ORB-SLAM2's pipeline on one frame (Mur-Artal and Tardós 2017, Fig. 1): the tracking
    /// thread (ORB extraction, tracking against the local map, the keyframe decision), then,
    /// on a new keyframe, the local mapping and loop closing threads.
    fn on_rgbd(&mut self, image: &RgbdFrame<'_>) -> Result<Option<Pose>, PluginError> {
        let start = Instant::now();
        let stamp_ns = image.stamp_ns;
        let mut frame = self.stages.time("orb", || {
            orb_frame(image, &mut self.extractor, &self.camera)
        })?;
        let ctx = Context {
            cfg: &self.cfg,
            camera: &self.camera,
            vocabulary: &self.vocabulary,
            database: &self.loop_closing.database,
            fps: self.fps,
        };
        let outcome = self.stages.time("tracking", || {
            self.tracking
                .track(&mut frame, &mut self.map, &ctx, &self.camera_from_base)
        });
        if self.localizing.is_some() {
            return Ok(Some(self.localized_pose(stamp_ns, &frame, &outcome)));
        }
        let pose = match outcome {
            Outcome::Tracked {
                keyframe,
                relocalised,
            } => {
                if relocalised {
                    self.event(stamp_ns, EventKind::TrackingRecovered, "relocalised".into());
                }
                if let Some(kf) = keyframe {
                    self.stages.time("local_mapping", || {
                        self.local_mapping.process(
                            kf,
                            &mut self.map,
                            &self.camera,
                            &self.cfg.local_mapping,
                        )
                    });
                    self.close_loops(stamp_ns, kf);
                }
                Some(self.record_tracked(stamp_ns))
            }
            Outcome::Lost { newly: true } => {
                self.lost(stamp_ns, frame.len());
                None
            }
            Outcome::Lost { newly: false } | Outcome::NotInitialized => None,
        };
        self.stages.record("frame", start.elapsed().as_secs_f64());
        Ok(pose)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        if let Some(poses) = &mut self.localizing {
            eprintln!(
                "orbslam2: localised in {} keyframes, {} points; {}",
                self.map.keyframes.len(),
                self.map.points.len(),
                self.stages.summary(),
            );
            return Ok(SlamOutput {
                trajectory: std::mem::take(poses),
                ..SlamOutput::default()
            });
        }
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
        eprintln!(
            "orbslam2: {} keyframes ({} live), {} points; {}",
            self.map.keyframes.len(),
            self.map.live_keyframe_count(),
            self.map.points.iter().filter(|p| !p.bad).count(),
            self.stages.summary(),
        );
        Ok(SlamOutput {
            trajectory,
            map: Some(map_points),
            grid: None,
            events: std::mem::take(&mut self.events),
            saved_map: Some(SavedMap {
                format: ORB_MAP_FORMAT.into(),
                version: ORB_MAP_VERSION,
                bytes: crate::saved::to_bytes(&self.map),
            }),
        })
    }
}
