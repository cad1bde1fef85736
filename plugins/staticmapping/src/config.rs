//! The plugin's parameters: every key optional, unknown keys rejected. Defaults are
//! StaticMapping's (`config/static_mapping_default.xml`, its iSAM optimiser and loop
//! detector sources), with `accumulate_cloud_num = 1` as the paper ran it; each field names
//! the setting it comes from.

use plugin_api::Parameters;
use serde::Deserialize;
use slam_common::factor_graph::backend::BackendConfig;

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Use the IMU's gyroscope for the initial guess of every scan match (`imu_options
    /// use_imu`); off: the constant-velocity model alone.
    pub use_imu: bool,
    /// Seed of the random sampler (`RandomSampler`), so that a run is reproducible.
    pub seed: u64,
    pub input: InputConfig,
    pub icp: IcpConfig,
    pub front_end: FrontEndConfig,
    pub submap: SubmapConfig,
    pub loop_closure: LoopConfig,
    /// GNSS priors per submap (`isam_optimizer_options use_gps` and its `gps_factor_*`),
    /// off by default as in `static_mapping_default.xml`.
    pub gps: GpsConfig,
    /// The shared factor-graph backend. StaticMapping's iSAM2 relinearises every update at a
    /// threshold of 0.01 (`relinearizeThreshold`, `relinearizeSkip`).
    pub backend: BackendConfig,
    /// Optional: a JSON file for the offline build's time split (front end, submap
    /// matching, M2DP, loop verification, back end) and its counts; a relative path lands
    /// in the run's folder.
    pub timing_json: Option<std::path::PathBuf>,
    /// Localisation in a saved map (`vinebench localize`; the original has no such mode):
    /// the front end as odometry, each sweep registered to the saved submaps after a Scan
    /// Context search (`slam_common::maps::localizer`, its defaults LIO-SAM's).
    pub localization: slam_common::maps::localizer::LocalizerConfig,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            use_imu: true,
            seed: 0,
            input: InputConfig::default(),
            icp: IcpConfig::default(),
            front_end: FrontEndConfig::default(),
            submap: SubmapConfig::default(),
            loop_closure: LoopConfig::default(),
            gps: GpsConfig::default(),
            backend: BackendConfig {
                relinearize_threshold: 0.01,
                relinearize_skip: 1,
                ..BackendConfig::default()
            },
            timing_json: None,
            localization: Default::default(),
        }
    }
}

/// What is kept of each sweep (`filters`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputConfig {
    /// `Range min_range`, m. StaticMapping's 4.5 m drops the two vine rows beside the robot
    /// (1.5 m away in a 3 m lane); 1.0 keeps them (the vineyard-friendly value).
    pub min_range_m: f64,
    /// `Range max_range`, m.
    pub max_range_m: f64,
    /// `RandomSampler sampling_rate`: the fraction of points kept.
    pub sampling_rate: f64,
    /// Undistort each sweep linearly by every point's time within it, with the motion
    /// predicted for the sweep.
    pub deskew: bool,
}

impl Default for InputConfig {
    fn default() -> Self {
        Self {
            min_range_m: 4.5,
            max_range_m: 75.0,
            sampling_rate: 0.35,
            deskew: true,
        }
    }
}

/// The point-to-plane ICP of libpointmatcher as StaticMapping configures it
/// (`registrator_options`, `IcpUsingPointMatcher::loadDefaultConfig`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IcpConfig {
    /// `knn_normal_estimate`: the reference cloud's bounding box is split until a box holds
    /// at most this many points; each box gives one point and its normal.
    pub knn_normal: usize,
    /// `dist_outlier_ratio`: the fraction of matches kept, the closest.
    pub trim_ratio: f64,
    /// `max_iteration`.
    pub max_iterations: usize,
    /// `DifferentialTransformationChecker minDiffRotErr`, rad.
    pub min_diff_rot_rad: f64,
    /// `minDiffTransErr`, m.
    pub min_diff_trans_m: f64,
    /// `smoothLength`: the changes averaged over this many last iterations.
    pub smooth_length: usize,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            knn_normal: 7,
            trim_ratio: 0.7,
            max_iterations: 100,
            min_diff_rot_rad: 0.001,
            min_diff_trans_m: 0.01,
            smooth_length: 4,
        }
    }
}

/// Scan-to-keyframe odometry (`front_end_options`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrontEndConfig {
    /// `accumulate_cloud_num`: sweeps per frame. Only 1 is supported (the paper's setting).
    pub accumulate_cloud_num: usize,
    /// `motion_filter translation_range`, m: a new keyframe after this much motion.
    pub keyframe_translation_m: f64,
    /// `motion_filter angle_range`, degrees: or after this much rotation (the sum of the
    /// absolute Euler angles, as StaticMapping measures it).
    pub keyframe_angle_deg: f64,
    /// The span of registered poses the extrapolator takes its velocities from, s
    /// (Cartographer's `pose_queue_duration`). StaticMapping passes 0.001, i.e. the last
    /// two sweeps: measured on S0 (min range 1 m), de-skewing with that velocity fed each
    /// sweep's match error back into the next sweep's distortion, and the front end
    /// oscillated and diverged after 7 s (68 m off at 10 s). Over 0.5 s the velocity's
    /// noise is five times smaller.
    pub pose_queue_s: f64,
}

impl Default for FrontEndConfig {
    fn default() -> Self {
        Self {
            accumulate_cloud_num: 1,
            keyframe_translation_m: 1.0,
            keyframe_angle_deg: 1.5,
            pose_queue_s: 0.5,
        }
    }
}

/// Submaps and their matching (`submap_options`, `submap_matcher_options`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SubmapConfig {
    /// `frame_count`: keyframes per submap.
    pub frame_count: usize,
    /// Voxel filter of a submap's cloud, m (`enable_voxel_filter`; 0 = off).
    pub voxel_m: f64,
    /// `accepted_min_score`: a submap-to-submap match below this keeps the front end's
    /// relative pose.
    pub accepted_min_score: f64,
    /// Voxel size of the map returned at the end, m.
    pub map_voxel_m: f64,
}

impl Default for SubmapConfig {
    fn default() -> Self {
        Self {
            frame_count: 2,
            voxel_m: 0.1,
            accepted_min_score: 0.75,
            map_voxel_m: 0.2,
        }
    }
}

/// Which M2DP to compare submaps with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DescriptorVariant {
    /// As published (He, Wang and Zhang 2016): rings scaled to the cloud, cosine similarity.
    Paper,
    /// StaticMapping's: rings of fixed size in metres, |Pearson correlation|.
    Staticmapping,
}

/// Loop detection and verification (`loop_detector_setting`, `LoopDetectorSettings`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoopConfig {
    pub enabled: bool,
    /// `loop_ignore_threshold`: candidates are older than this many submaps.
    pub ignore_recent: usize,
    /// `max_close_loop_distance`, m (horizontal).
    pub max_distance_m: f64,
    /// `max_close_loop_z_distance`, m.
    pub max_z_distance_m: f64,
    /// `m2dp_match_score`: a candidate's descriptor similarity must exceed this.
    pub descriptor_min_score: f64,
    /// `nearest_history_pos_num`: candidates verified, spread over the matches, plus the
    /// nearest.
    pub candidates: usize,
    /// `accept_scan_match_score`: an ICP verification is kept above this score.
    pub accepted_min_score: f64,
    /// Verified edges must agree within this, m, and
    pub agree_m: f64,
    /// this, rad (`LoopDetector::CheckResult`).
    pub agree_rad: f64,
    pub descriptor: DescriptorVariant,
    /// M2DP's projection planes: azimuths × elevations (the paper's p = 4, q = 16).
    pub m2dp_azimuths: usize,
    pub m2dp_elevations: usize,
    /// M2DP's rings and sectors of each plane (the paper's l = 8, t = 16).
    pub m2dp_rings: usize,
    pub m2dp_sectors: usize,
    /// StaticMapping's variant only: ring scale and the farthest point kept, m (its 32 rings
    /// come from these).
    pub staticmapping_ring_m: f64,
    pub staticmapping_max_distance_m: f64,
}

impl Default for LoopConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            ignore_recent: 15,
            max_distance_m: 25.0,
            max_z_distance_m: 1.0,
            descriptor_min_score: 0.96,
            candidates: 5,
            accepted_min_score: 0.75,
            agree_m: 0.25,
            agree_rad: 0.02,
            descriptor: DescriptorVariant::Paper,
            m2dp_azimuths: 4,
            m2dp_elevations: 16,
            m2dp_rings: 8,
            m2dp_sectors: 16,
            staticmapping_ring_m: 0.1,
            staticmapping_max_distance_m: 100.0,
        }
    }
}

/// GNSS priors per submap, StaticMapping's `isam_optimizer_options` (`IsamOptimizerOptions`
/// in `back_end/isam_optimizer.h`, read in `builder/map_builder_options.cc`) under the same
/// names; the method is in [`crate::gnss`]. The defaults are the header's:
/// `static_mapping_default.xml` sets only `use_gps="false"`, and the original's
/// `lidar_imu_gps_default.xml` runs `gps_factor_sample_step = 2` and
/// `gps_factor_init_angle_rad = 1.5`.
///
/// Not carried over: `enable_extrinsic_calib` (a translation error of the tracking-to-GPS
/// lever arm estimated in the graph, `GPS_CALIB_KEY`; the slam_common backends have no
/// factor for it, and the rig's lever arm is exact here) and `loop_detector_setting
/// use_gps` (loop candidates by GNSS distance).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GpsConfig {
    /// `use_gps` (default `false`): ask for the GNSS receiver (the plugin's requirements
    /// name it only then) and add a GNSS prior per submap. The fixes' east-north-up frame
    /// is tied to the map by a transform solved from the track itself, as the original's
    /// `SolveGpsCorrdAlone` ([`crate::gnss`]): no IMU orientation is needed.
    pub use_gps: bool,
    /// `gps_factor_init_num` (25): submaps with a fix cached before any prior is added.
    pub gps_factor_init_num: usize,
    /// `gps_factor_init_angle_rad` (1.6): and the largest angle between any submap's x
    /// axis and the first submap's must reach this, rad (`AnalyseAllFramePoseForMaxRotation`:
    /// a turn).
    pub gps_factor_init_angle_rad: f64,
    /// `gps_factor_sample_step` (1): once started, a prior for every submap whose index is
    /// a multiple of this (0 and 1: every submap).
    pub gps_factor_sample_step: usize,
}

impl Default for GpsConfig {
    fn default() -> Self {
        Self {
            use_gps: false,
            gps_factor_init_num: 25,
            gps_factor_init_angle_rad: 1.6,
            gps_factor_sample_step: 1,
        }
    }
}

impl Parameters for Config {
    fn check(&self) -> Result<(), String> {
        let i = &self.input;
        if !(i.min_range_m >= 0.0 && i.max_range_m > i.min_range_m) {
            return Err(format!(
                "input: need 0 <= min_range_m < max_range_m, got {} and {}",
                i.min_range_m, i.max_range_m
            ));
        }
        if !(i.sampling_rate > 0.0 && i.sampling_rate <= 1.0) {
            return Err(format!(
                "input.sampling_rate must be in (0, 1], got {}",
                i.sampling_rate
            ));
        }
        if self.front_end.accumulate_cloud_num != 1 {
            return Err(format!(
                "front_end.accumulate_cloud_num = {}: only 1 is supported",
                self.front_end.accumulate_cloud_num
            ));
        }
        if !(self.front_end.pose_queue_s >= 0.0 && self.front_end.pose_queue_s.is_finite()) {
            return Err(format!(
                "front_end.pose_queue_s must be a non-negative number, got {}",
                self.front_end.pose_queue_s
            ));
        }
        if self.submap.frame_count == 0 {
            return Err("submap.frame_count must be at least 1".into());
        }
        if self.icp.knn_normal < 3 || self.icp.max_iterations == 0 || self.icp.smooth_length == 0 {
            return Err(
                "icp: knn_normal >= 3, max_iterations >= 1 and smooth_length >= 1 are needed"
                    .into(),
            );
        }
        if !(self.icp.trim_ratio > 0.0 && self.icp.trim_ratio <= 1.0) {
            return Err(format!(
                "icp.trim_ratio must be in (0, 1], got {}",
                self.icp.trim_ratio
            ));
        }
        let angle = self.gps.gps_factor_init_angle_rad;
        if !(angle >= 0.0 && angle.is_finite()) {
            return Err(format!(
                "gps.gps_factor_init_angle_rad must be a non-negative number, got {angle}"
            ));
        }
        if self.loop_closure.candidates == 0 {
            return Err("loop_closure.candidates must be at least 1".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod documented_file {
    //! The documented parameter file must say exactly what the plugin does without one, and a bad value must be refused with a message naming it.

    use super::Config;
    use plugin_api::Parameters;

    #[test]
    fn documented_parameters_are_the_defaults() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/staticmapping.toml"
        );
        let text = std::fs::read_to_string(path).expect("configs/staticmapping.toml exists");
        let parsed = Config::from_toml(&text).expect("configs/staticmapping.toml parses");
        assert_eq!(
            parsed,
            Config::default(),
            "configs/staticmapping.toml differs from the built-in defaults"
        );
    }

    #[test]
    fn a_misspelt_key_is_an_error_naming_it() {
        let err = Config::from_toml("[submap]\nframe_cout = 3\n").expect_err("unknown key");
        assert!(err.contains("frame_cout"), "{err}");
    }

    #[test]
    fn bad_values_are_refused() {
        for (text, names) in [
            ("[input]\nsampling_rate = 0.0\n", "sampling_rate"),
            ("[input]\nmin_range_m = 80.0\n", "min_range_m"),
            (
                "[front_end]\naccumulate_cloud_num = 181\n",
                "accumulate_cloud_num",
            ),
            ("[submap]\nframe_count = 0\n", "frame_count"),
            (
                "[gps]\ngps_factor_init_angle_rad = -1.0\n",
                "gps_factor_init_angle_rad",
            ),
            ("[gps]\nenabled = true\n", "enabled"),
        ] {
            let err = Config::from_toml(text).expect_err(text);
            assert!(err.contains(names), "{text}: {err}");
        }
    }
}
