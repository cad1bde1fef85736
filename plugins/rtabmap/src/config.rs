//! The plugin's parameters: every key optional, defaults from RTAB-Map's (its parameter names
//! in the doc comments), unknown keys rejected.

use plugin_api::Parameters;
use serde::Deserialize;
use slam_common::factor_graph::backend::BackendConfig;
use slam_common::maps::occupancy::OccupancyGridConfig;
use slam_common::registration::scan2d::Icp2dConfig;

use crate::proximity::ProximityConfig;

/// Where the odometry between locations comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OdometrySource {
    /// RGB-D visual odometry (RTAB-Map's rgbd_odometry).
    Visual,
    /// Wheel odometry as the motion guess, refined by ICP on the front 2D scan (3-DoF), as
    /// the paper ran RTAB-Map.
    WheelIcp,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub odometry: OdometrySource,
    /// The camera's sensor name in the rig.
    pub camera: String,
    /// The 2D scan for ICP odometry and the occupancy grid.
    pub scan: String,
    pub features: FeatureConfig,
    pub visual: VisualOdometryConfig,
    pub icp: ScanOdometryConfig,
    pub memory: MemoryConfig,
    pub loop_closure: LoopClosureConfig,
    pub proximity: ProximityConfig,
    /// Odometry links' standard deviations (the link covariance RTAB-Map takes from its
    /// odometry), per metre travelled plus a floor.
    pub odometry_link: LinkSigmas,
    pub grid: OccupancyGridConfig,
    /// Map cloud: every how many depth pixels (in both directions) one point per location.
    pub map_decimation: usize,
    /// And the voxel the map cloud is thinned to, m.
    pub map_voxel_m: f64,
    pub backend: BackendConfig,
    /// RTAB-Map's `Optimizer/` parameters that this plugin's graph takes (the table
    /// `[Optimizer]`, keys by RTAB-Map's names).
    #[serde(rename = "Optimizer")]
    pub optimizer: OptimizerConfig,
    /// RTAB-Map's `Rtabmap/` parameters that this plugin takes (the table `[Rtabmap]`).
    #[serde(rename = "Rtabmap")]
    pub rtabmap: RtabmapConfig,
    /// Optional: a CSV file to write every graph update's size and time to
    /// (`poses,full,seconds`); a relative path lands in the run's folder.
    pub profile_csv: Option<std::path::PathBuf>,
    /// Optional: a CSV file to write every location's update to: its cost as the memory
    /// limits count it, what they transferred, and the wall and thread CPU time of the
    /// camera frame that made it (`step_ns`, `step_cpu_ns`; written only, they steer
    /// nothing).
    pub locations_csv: Option<std::path::PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            odometry: OdometrySource::WheelIcp,
            camera: "camera".into(),
            scan: "scan_front".into(),
            features: FeatureConfig::default(),
            visual: VisualOdometryConfig::default(),
            icp: ScanOdometryConfig::default(),
            memory: MemoryConfig::default(),
            loop_closure: LoopClosureConfig::default(),
            proximity: ProximityConfig::default(),
            odometry_link: LinkSigmas::default(),
            // RTAB-Map's `Grid/RangeMax`: beyond, a level scan plane draws the uneven ground.
            grid: OccupancyGridConfig {
                max_range_m: 5.0,
                ..OccupancyGridConfig::default()
            },
            map_decimation: 8,
            map_voxel_m: 0.05,
            // factrs until this plugin is measured on the others (docs/backends.md).
            backend: BackendConfig {
                name: "factrs".into(),
                ..BackendConfig::default()
            },
            optimizer: OptimizerConfig::default(),
            rtabmap: RtabmapConfig::default(),
            profile_csv: None,
            locations_csv: None,
        }
    }
}

/// GFTT corners with BRIEF descriptors (`Kp/DetectorStrategy` = GFTT/BRIEF).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FeatureConfig {
    /// `Vis/MaxFeatures` (odometry).
    pub max_features: usize,
    /// `GFTT/QualityLevel`.
    pub quality_level: f64,
    /// `GFTT/MinDistance`, px.
    pub min_distance_px: f64,
    /// `GFTT/BlockSize`.
    pub block_size: i32,
    /// Depth accepted for a feature's 3D point, m (the camera's valid range).
    pub min_depth_m: f64,
    pub max_depth_m: f64,
    /// A feature whose 3x3 depth neighbourhood spans more than this fraction of its depth
    /// lies on a silhouette, where its depth belongs to either side: no 3D point. RTAB-Map
    /// has no such test; 0 disables it.
    pub max_depth_step: f64,
}

impl Default for FeatureConfig {
    fn default() -> Self {
        Self {
            max_features: 1000,
            quality_level: 0.001,
            min_distance_px: 7.0,
            block_size: 3,
            min_depth_m: 0.5,
            max_depth_m: 4.5,
            max_depth_step: 0.05,
        }
    }
}

/// Frame-to-map or frame-to-frame visual odometry (`Odom/Strategy` 0 or 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VisualStrategy {
    FrameToMap,
    FrameToFrame,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VisualOdometryConfig {
    pub strategy: VisualStrategy,
    /// `Vis/CorNNDR`: a match is kept when nearest < ratio × second nearest.
    pub nndr: f32,
    /// `OdomF2M/MaxSize`: words in the local feature map.
    pub local_map_size: usize,
    /// `Vis/CorGuessWinSize`, px: with a motion guess, a map word is matched only to
    /// features within this radius of where the guess projects it (0: everywhere).
    pub guess_window_px: f64,
    /// `Vis/PnPReprojError`, px.
    pub pnp_reprojection_px: f64,
    /// `Vis/Iterations`.
    pub pnp_iterations: i32,
    /// `Vis/MinInliers`.
    pub min_inliers: usize,
    /// `Odom/KeyFrameThr`: a new keyframe (map update) when inliers / features fall below.
    pub keyframe_inlier_ratio: f64,
    /// `Odom/ResetCountdown`: after this many lost frames in a row, odometry restarts from
    /// the last pose with a fresh map (0: never; frames stay lost until matched again).
    pub reset_countdown: usize,
}

impl Default for VisualOdometryConfig {
    fn default() -> Self {
        Self {
            strategy: VisualStrategy::FrameToMap,
            nndr: 0.8,
            local_map_size: 2000,
            guess_window_px: 40.0,
            pnp_reprojection_px: 2.0,
            pnp_iterations: 300,
            min_inliers: 20,
            keyframe_inlier_ratio: 0.3,
            reset_countdown: 1,
        }
    }
}

/// Where the dead-reckoned guess takes its yaw rate from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum YawSource {
    Wheels,
    Imu,
}

/// Wheel odometry refined by ICP against a local map of recent scans (`Odom/Strategy` 0 with
/// `Reg/Strategy` 1, `Reg/Force3DoF`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScanOdometryConfig {
    /// The guess's yaw rate: the IMU's gyro (as a robot's odometry usually fuses it) or the
    /// wheels'.
    pub yaw_source: YawSource,
    pub icp: Icp2dConfig,
    /// `OdomF2M/ScanMaxSize`: points in the local scan map.
    pub local_map_size: usize,
    /// A scan joins the local map after the robot moved this far, m, or turned, rad
    /// (`Odom/ScanKeyFrameThr` in spirit).
    pub key_scan_distance_m: f64,
    pub key_scan_angle_rad: f64,
    /// Correction of the guess beyond which ICP is not believed and the guess is kept, m and
    /// rad (scans come at 40 Hz: the guess is off by millimetres, a bigger correction is a
    /// wrong match along a row of look-alike trunks).
    pub max_correction_m: f64,
    pub max_correction_rad: f64,

    /// Returns farther than this are not registered, m (`Icp/RangeMax`; 0: all). At 0.35 m
    /// above uneven ground, a level scan plane meets the ground a few metres out, where it
    /// draws contours that move with the robot's pitch and roll rather than with the world;
    /// `max_segment_m` drops those, and farther returns then help: they see the row ends
    /// during a headland turn and more trunks along a row. End-point errors on S0–S3 (mean
    /// of seeds 0–7): 4 m 0.14–0.51 m, 7 m 0.07–0.12, 10 m 0.02–0.10, 15 m 0.02–0.08, at
    /// about 35, 80, 115 and 165 µs per scan. In a headland turn, fewer than the 20 narrow
    /// returns ICP needs lie within 10 m, and the wheels slip on the headland's slope
    /// unchecked: S3's last turn added 0.16 m of error within 2 s at 10 m (plugin ATE, seed
    /// 0: 0.076 m at 10 m, 0.038 m at 15 m).
    pub max_range_m: f64,
    /// Returns on a surface wider than this, m, are not registered (0: all are). The scan is
    /// cut where consecutive returns cannot lie on one surface (adaptive breakpoints, with
    /// `breakpoint_incidence_rad` and `breakpoint_sigma_m`; see
    /// `scan_odometry::narrow_returns`). The upright objects of a vine row at scan height,
    /// trunks (≤ 0.09 m) and posts (≤ 0.12 m square), make segments at most 0.17 m wide;
    /// the scan plane meeting rising ground draws contours metres long, and where it grazes
    /// a bump, arcs of 0.3–0.5 m (0.4 m and above let enough of them through to lose S1
    /// and S3). Walls and hedges are dropped too. RTAB-Map has no such filter.
    pub max_segment_m: f64,
    /// The breakpoint detector's incidence limit λ, rad (Borges and Aldon's 10°), and range
    /// noise σ, m: consecutive returns lie on one surface when their gap is at most
    /// `r sin Δφ / sin(λ − Δφ) + 3σ`.
    pub breakpoint_incidence_rad: f64,
    pub breakpoint_sigma_m: f64,
    /// Moves every return to where the scanner was at the scan's stamp, by the guess's
    /// motion over the sweep (`deskewing` of RTAB-Map's `icp_odometry`; see
    /// [`crate::scan_odometry::ScanOdometry::on_timed_scan`]).
    pub deskew: bool,
    /// Roll and pitch from the IMU ([`crate::attitude::Tilt`], Mahony's filter with these
    /// gains, 1/s and 1/s²), and the height the wheels climb on the slope they give, so that
    /// the odometry follows uneven ground in 3D rather than in the plane (`Reg/Force3DoF`
    /// still holds for the registration). `attitude_gain` 0: planar odometry, z = 0, as the
    /// paper ran RTAB-Map.
    pub attitude_gain: f64,
    pub attitude_bias_gain: f64,
    /// The height relaxes back to the start's over this distance travelled, m (0: never):
    /// a tilt error of ε climbs ε per metre, 0.2 % for the default IMU's turn-on
    /// accelerometer bias, which unchecked lifts S3's end by a quarter of a metre; a field
    /// is level over tens of metres.
    pub height_leak_m: f64,
}

impl Default for ScanOdometryConfig {
    fn default() -> Self {
        Self {
            yaw_source: YawSource::Imu,
            icp: Icp2dConfig::default(),
            local_map_size: 4000,
            key_scan_distance_m: 0.1,
            key_scan_angle_rad: 0.05,
            max_correction_m: 0.1,
            max_correction_rad: 0.05,
            max_range_m: 15.0,
            max_segment_m: 0.25,
            breakpoint_incidence_rad: 0.17,
            breakpoint_sigma_m: 0.01,
            deskew: true,
            attitude_gain: 0.5,
            attitude_bias_gain: 0.02,
            height_leak_m: 20.0,
        }
    }
}

/// Locations and memory management.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MemoryConfig {
    /// `Rtabmap/DetectionRate`, Hz: a new location at most this often.
    pub detection_rate_hz: f64,
    /// `RGBD/LinearUpdate`, m and `RGBD/AngularUpdate`, rad: and only after moving this far.
    pub linear_update_m: f64,
    pub angular_update_rad: f64,
    /// `Kp/MaxFeatures`: visual words per location, the strongest corners.
    pub max_words: usize,
    /// `Mem/STMSize`: the newest locations, never loop-closure candidates.
    pub short_term_memory: usize,
    /// `Rtabmap/MemoryThr`: working-memory locations beyond which the oldest go to
    /// long-term memory and stop being candidates (0: unlimited).
    pub working_memory_limit: usize,
    /// `Rtabmap/TimeThr`, counted instead of timed so that a run does not depend on the
    /// machine (see [`crate::memory`]): when quantising a new location costs more than this
    /// many descriptor-to-word comparisons (its descriptors times the vocabulary's words),
    /// the two oldest working-memory locations go to long-term memory (0: unlimited).
    /// Calibrated on this project's 2-core machine (`locations_csv`, S3, thread CPU time): a
    /// location's frame costs about 15 ms plus 5–6.5 ns per comparison, so the default 6 M
    /// keeps it near 50 ms, under half of the 100 ms real-time goal, leaving room for a
    /// loaded machine.
    pub comparison_limit: u64,
    /// `Kp/NndrRatio`: a descriptor joins an existing word when nearest < ratio × second.
    pub word_nndr: f32,
    /// The vocabulary's search radius, as the multi-index hash's probe radius `r`: words
    /// within `16 (r + 1)` bits are found exactly, so a descriptor farther than
    /// `word_nndr × 16 (r + 1)` from every word is a new word (see `slam_common::place::bow`).
    /// BRIEF descriptors of one corner seen 0.5 m apart differ by 30–50 bits.
    pub word_probe_radius: u32,
}

impl Default for MemoryConfig {
    fn default() -> Self {
        Self {
            detection_rate_hz: 1.0,
            linear_update_m: 0.1,
            angular_update_rad: 0.1,
            max_words: 500,
            short_term_memory: 10,
            working_memory_limit: 0,
            comparison_limit: 6_000_000,
            word_nndr: 0.8,
            word_probe_radius: 3,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoopClosureConfig {
    pub enabled: bool,
    /// `Rtabmap/LoopThr`: the posterior a hypothesis needs.
    pub hypothesis_threshold: f64,
    /// `Bayes/VirtualPlacePriorThr`: probability that the new location stays new.
    pub virtual_place_prior: f64,
    /// `Bayes/PredictionLC`: transition probabilities to the virtual place, the same
    /// location, its neighbours 1, 2, … away.
    pub prediction: Vec<f64>,
    /// `Vis/MinInliers` for geometric verification.
    pub min_inliers: usize,
    /// `RGBD/OptimizeMaxError`: after optimising with a new loop closure, if any link's error
    /// exceeds this many standard deviations the closure is rejected and the graph restored
    /// (0: never reject).
    pub optimize_max_error: f64,
    /// Smallest standard deviations of a loop link (its variance comes from the PnP
    /// inliers' errors), rad and m.
    pub min_sigma_rad: f64,
    pub min_sigma_m: f64,
}

impl Default for LoopClosureConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            hypothesis_threshold: 0.11,
            virtual_place_prior: 0.9,
            prediction: vec![
                0.1, 0.36, 0.30, 0.16, 0.062, 0.0151, 0.00255, 0.000324, 2.5e-05, 1.3e-06, 4.8e-08,
                1.2e-09, 1.9e-11, 2.2e-13, 1.7e-15, 1.0e-17, 4.9e-20, 1.4e-22, 2.4e-25, 3.0e-28,
                2.6e-31,
            ],
            min_inliers: 20,
            optimize_max_error: 3.0,
            min_sigma_rad: 0.005,
            min_sigma_m: 0.01,
        }
    }
}

/// RTAB-Map's `Optimizer/` group, as far as this plugin's graph goes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimizerConfig {
    /// `Optimizer/PriorsIgnored` (RTAB-Map's default `true`): "ignore prior constraints
    /// (global pose or GPS) while optimizing". `false`: the GNSS receiver is asked for and
    /// every location with a fix gets RTAB-Map's GPS prior on its position, which expresses
    /// the map in the fixes' east-north-up frame ([`crate::gps`]). `true`: no receiver is
    /// asked for and fixes that arrive all the same are ignored.
    #[serde(rename = "PriorsIgnored")]
    pub priors_ignored: bool,
}

/// RTAB-Map's `Rtabmap/` group, as far as this plugin goes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RtabmapConfig {
    /// `Rtabmap/ImagesAlreadyRectified` (RTAB-Map's default `true`): the images are taken
    /// as rectified, whatever lens the camera reports. `false`: a camera with a lens (the
    /// rig's `k1`...`k3`) has each frame rectified first, colour bilinearly and depth from
    /// the nearest raw pixel (RTAB-Map's `CameraModel::rectifyImage`/`rectifyDepth`).
    #[serde(rename = "ImagesAlreadyRectified")]
    pub images_already_rectified: bool,
}

impl Default for RtabmapConfig {
    fn default() -> Self {
        Self {
            images_already_rectified: true,
        }
    }
}

impl Default for OptimizerConfig {
    fn default() -> Self {
        Self {
            priors_ignored: true,
        }
    }
}

/// Standard deviations of an odometry link: `floor + per_m × distance`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkSigmas {
    pub rad_floor: f64,
    pub rad_per_m: f64,
    pub m_floor: f64,
    pub m_per_m: f64,
}

impl Default for LinkSigmas {
    fn default() -> Self {
        Self {
            rad_floor: 0.001,
            rad_per_m: 0.002,
            m_floor: 0.005,
            m_per_m: 0.01,
        }
    }
}

impl Parameters for Config {
    fn check(&self) -> Result<(), String> {
        let positive = [
            ("memory.detection_rate_hz", self.memory.detection_rate_hz),
            (
                "visual.pnp_reprojection_px",
                self.visual.pnp_reprojection_px,
            ),
            ("features.quality_level", self.features.quality_level),
            (
                "loop_closure.min_sigma_rad",
                self.loop_closure.min_sigma_rad,
            ),
            ("loop_closure.min_sigma_m", self.loop_closure.min_sigma_m),
            ("map_voxel_m", self.map_voxel_m),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be positive, got {v}"));
            }
        }
        let non_negative = [
            ("icp.max_range_m", self.icp.max_range_m),
            ("icp.max_segment_m", self.icp.max_segment_m),
            ("icp.attitude_gain", self.icp.attitude_gain),
            ("icp.attitude_bias_gain", self.icp.attitude_bias_gain),
            ("icp.height_leak_m", self.icp.height_leak_m),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be 0 or more, got {v}"));
            }
        }
        if self.loop_closure.prediction.len() < 2 {
            return Err("loop_closure.prediction needs at least 2 values".into());
        }
        if self.memory.word_probe_radius > slam_common::place::bow::MAX_PROBE_RADIUS
            || !(self.memory.word_nndr > 0.0 && self.memory.word_nndr <= 1.0)
        {
            return Err(format!(
                "memory.word_probe_radius must be at most {} and memory.word_nndr in (0, 1]",
                slam_common::place::bow::MAX_PROBE_RADIUS
            ));
        }
        if self.map_decimation == 0 || self.memory.max_words == 0 || self.features.max_features == 0
        {
            return Err(
                "map_decimation, memory.max_words and features.max_features must be at least 1"
                    .into(),
            );
        }
        Ok(())
    }
}
