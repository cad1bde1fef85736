//! The plugin's parameters: every key optional, unknown keys rejected. Defaults are
//! ORB-SLAM2's published RGB-D settings (its `TUM*.yaml` files and the constants of its
//! tracking, local mapping and loop closing; names in the doc comments).

use plugin_api::Parameters;
use serde::Deserialize;
use slam_common::factor_graph::backend::BackendConfig;

use crate::orb::OrbConfig;

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// The camera's sensor name in the rig.
    pub camera: String,
    /// `ORBextractor.*`.
    pub orb: OrbConfig,
    /// Virtual stereo baseline of the RGB-D frame, m (`Camera.bf` / `Camera.fx`; TUM's
    /// files have bf = 40 at fx ≈ 517, about 8 cm).
    pub baseline_m: f64,
    /// `ThDepth`: depths below this many baselines are "close" (reliable) points.
    pub th_depth: f64,
    /// Depths outside this range are treated as missing, m.
    pub min_depth_m: f64,
    pub max_depth_m: f64,
    pub tracking: TrackingConfig,
    pub local_mapping: LocalMappingConfig,
    pub loop_closing: LoopClosingConfig,
    /// The vocabulary file; empty: the one shipped in the plugin (trained on another world,
    /// see `plugins/orbslam2/vocabulary/README.md`).
    pub vocabulary: String,
    /// The essential graph's backend (`slam_common::factor_graph::backend`).
    pub backend: BackendConfig,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            camera: "camera".into(),
            orb: OrbConfig::default(),
            baseline_m: 0.08,
            th_depth: 40.0,
            min_depth_m: 0.5,
            max_depth_m: 8.0,
            tracking: TrackingConfig::default(),
            local_mapping: LocalMappingConfig::default(),
            loop_closing: LoopClosingConfig::default(),
            vocabulary: String::new(),
            // factrs until this plugin is measured on the others (docs/backends.md).
            backend: BackendConfig {
                name: "factrs".into(),
                ..BackendConfig::default()
            },
        }
    }
}

/// Tracking (ORB-SLAM2's `Tracking.cc`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackingConfig {
    /// Search radius of the motion model, px at scale 1 (`th = 15` for RGB-D).
    pub motion_radius_px: f64,
    /// Nearest/second ratio of the motion model's matches.
    pub motion_ratio: f64,
    /// Matches below this retry at twice the radius (`nmatches < 20`).
    pub motion_min_matches: usize,
    /// Reference keyframe by BoW: ratio and minimum matches.
    pub bow_ratio: f64,
    pub bow_min_matches: usize,
    /// Local map: at most this many keyframes (80), ratio 0.8, radius multiplier 1.
    pub max_local_keyframes: usize,
    pub local_map_ratio: f64,
    pub local_map_radius: f64,
    /// Inliers to call the frame tracked (30; 50 within a second of relocalisation).
    pub min_inliers: usize,
    pub min_inliers_after_relocalisation: usize,
    /// Keyframe decision: at most `max_frames` (the frame rate) without one, 0 at least.
    pub min_frames: usize,
    /// Tracked/reference ratio under which a keyframe is wanted (0.75 for RGB-D).
    pub th_ref_ratio: f64,
    /// Close-point rule: fewer than this many close points tracked (100) while more than
    /// `close_untracked` (70) could be created.
    pub close_tracked: usize,
    pub close_untracked: usize,
    /// New keyframes make points of at least this many of their closest untracked
    /// features (100), and of all close ones.
    pub new_points_min: usize,
    /// Points the motion model keeps from the last frame's close depth ("visual
    /// odometry" points, `UpdateLastFrame`).
    pub temporal_points: usize,
}

impl Default for TrackingConfig {
    fn default() -> Self {
        Self {
            motion_radius_px: 15.0,
            motion_ratio: 0.9,
            motion_min_matches: 20,
            bow_ratio: 0.7,
            bow_min_matches: 15,
            max_local_keyframes: 80,
            local_map_ratio: 0.8,
            local_map_radius: 1.0,
            min_inliers: 30,
            min_inliers_after_relocalisation: 50,
            min_frames: 0,
            th_ref_ratio: 0.75,
            close_tracked: 100,
            close_untracked: 70,
            new_points_min: 100,
            temporal_points: 100,
        }
    }
}

/// Local mapping (`LocalMapping.cc`, `Optimizer::LocalBundleAdjustment`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LocalMappingConfig {
    /// Recent points found in fewer than this fraction of the frames that saw them are
    /// culled (0.25).
    pub found_ratio: f64,
    /// Recent points with this many observations or fewer two keyframes after their
    /// creation are culled (3 for RGB-D).
    pub min_observations: usize,
    /// Covisible keyframes used to triangulate new points (10 for RGB-D).
    pub triangulation_neighbours: usize,
    /// Duplicate fusion over the 10 best covisibles and their 5 best.
    pub fuse_neighbours: usize,
    pub fuse_second_neighbours: usize,
    /// Local BA: iterations before and after the outlier removal (5 + 10).
    pub ba_iterations: usize,
    pub ba_iterations_after: usize,
    /// Keyframe culling: redundant when this fraction of its close points is seen by at
    /// least `redundant_observers` other keyframes at the same or a finer scale.
    pub redundant_ratio: f64,
    pub redundant_observers: usize,
}

impl Default for LocalMappingConfig {
    fn default() -> Self {
        Self {
            found_ratio: 0.25,
            min_observations: 3,
            triangulation_neighbours: 10,
            fuse_neighbours: 10,
            fuse_second_neighbours: 5,
            ba_iterations: 5,
            ba_iterations_after: 10,
            redundant_ratio: 0.9,
            redundant_observers: 3,
        }
    }
}

/// Loop closing (`LoopClosing.cc`, `KeyFrameDatabase.cc`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoopClosingConfig {
    pub enabled: bool,
    /// No detection while the map has fewer keyframes or within this many of the last
    /// loop (10).
    pub min_keyframes: usize,
    /// Candidates share at least this fraction of the most common words (0.8).
    pub common_words_ratio: f64,
    /// Covisibility groups scoring at least this fraction of the best group (0.75).
    pub group_score_ratio: f64,
    /// Consecutive consistent detections needed (3).
    pub consistency: usize,
    /// BoW matches to try a candidate (20); inliers after the pose optimisation (20);
    /// matches after projecting the loop's map points (40).
    pub min_bow_matches: usize,
    pub min_inliers: usize,
    pub min_projected_matches: usize,
    /// Essential graph: covisibility edges of at least this weight (100).
    pub essential_min_weight: usize,
    /// Global BA iterations after a loop (10).
    pub global_ba_iterations: usize,
}

impl Default for LoopClosingConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            min_keyframes: 10,
            common_words_ratio: 0.8,
            group_score_ratio: 0.75,
            consistency: 3,
            min_bow_matches: 20,
            min_inliers: 20,
            min_projected_matches: 40,
            essential_min_weight: 100,
            global_ba_iterations: 10,
        }
    }
}

impl Config {
    /// Depth below which a point is close (`mThDepth`), m.
    pub fn close_depth_m(&self) -> f64 {
        self.th_depth * self.baseline_m
    }
}

impl Parameters for Config {
    fn check(&self) -> Result<(), String> {
        let positive = [
            ("baseline_m", self.baseline_m),
            ("th_depth", self.th_depth),
            ("min_depth_m", self.min_depth_m),
            ("max_depth_m", self.max_depth_m),
            ("orb.scale_factor", self.orb.scale_factor - 1.0),
            ("tracking.motion_radius_px", self.tracking.motion_radius_px),
            ("tracking.local_map_radius", self.tracking.local_map_radius),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be positive (scale_factor above 1)"));
            }
        }
        let ratios = [
            ("tracking.motion_ratio", self.tracking.motion_ratio),
            ("tracking.bow_ratio", self.tracking.bow_ratio),
            ("tracking.local_map_ratio", self.tracking.local_map_ratio),
            ("tracking.th_ref_ratio", self.tracking.th_ref_ratio),
            ("local_mapping.found_ratio", self.local_mapping.found_ratio),
            (
                "local_mapping.redundant_ratio",
                self.local_mapping.redundant_ratio,
            ),
            (
                "loop_closing.common_words_ratio",
                self.loop_closing.common_words_ratio,
            ),
            (
                "loop_closing.group_score_ratio",
                self.loop_closing.group_score_ratio,
            ),
        ];
        for (name, v) in ratios {
            if !(v > 0.0 && v <= 1.0) {
                return Err(format!("{name} must be in (0, 1], got {v}"));
            }
        }
        if self.min_depth_m >= self.max_depth_m {
            return Err("min_depth_m must be below max_depth_m".into());
        }
        if self.orb.levels == 0 || self.orb.features == 0 {
            return Err("orb.levels and orb.features must be at least 1".into());
        }
        if self.loop_closing.consistency == 0 {
            return Err("loop_closing.consistency must be at least 1".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_file_lists_every_default() {
        let text = include_str!("../../../configs/orbslam2.toml");
        assert_eq!(Config::from_toml(text).expect("parses"), Config::default());
    }

    #[test]
    fn bad_values_are_one_line_naming_the_key() {
        let e = Config::from_toml("[tracking]\nbow_ratio = 1.5").expect_err("ratio above 1");
        assert!(e.contains("tracking.bow_ratio"), "{e}");
        let e = Config::from_toml("[tracking]\nunknown = 1").expect_err("unknown key");
        assert!(e.contains("unknown"), "{e}");
    }
}
