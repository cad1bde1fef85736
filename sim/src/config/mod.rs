//! Simulator configuration: one TOML file (`configs/world.toml`) whose every key has a
//! documented default, so the file is optional and any subset of it may be given.
//!
//! Unknown keys are errors (`deny_unknown_fields`), so a misspelt key names itself.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::SimError;

mod profile;
mod route;
mod sensors;

pub use profile::Profile;
pub use route::RouteSpec;
pub use sensors::*;

/// The complete simulator configuration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimConfig {
    /// The sensors' models: `ideal`, `paper` or `typical` (the default), the keys of
    /// `configs/profiles/<name>.toml` under this file's own (see [`Profile`]).
    pub profile: Profile,
    /// Seed of the world's geometry (terrain, plants); the run's seed drives sensor noise.
    pub world_seed: u64,
    /// Ray-casting engine: `bvh` (the simulator's own), `parry` (parry3d, a cross-check) or
    /// `embree` (Intel's Embree 3, with the `embree` feature).
    pub raycaster: RaycasterKind,
    pub vineyard: VineyardConfig,
    pub terrain: TerrainConfig,
    pub robot: RobotConfig,
    pub sensors: SensorsConfig,
    /// Fence panels around the block (the paper's world has 56; ours none).
    pub fence: FenceConfig,
    /// Named routes; `s0`..`s3` reproduce the paper's scenarios, `s4` is ours (the same
    /// lane twice in the same direction).
    pub scenarios: BTreeMap<String, RouteSpec>,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            profile: Profile::Typical,
            world_seed: 1,
            raycaster: RaycasterKind::Bvh,
            vineyard: VineyardConfig::default(),
            terrain: TerrainConfig::default(),
            robot: RobotConfig::default(),
            sensors: SensorsConfig::default(),
            fence: FenceConfig::default(),
            scenarios: RouteSpec::builtin_scenarios(),
        }
    }
}

impl SimConfig {
    /// Parses a TOML document over its profile's keys; keys neither leaves out keep their
    /// defaults. Scenarios given in the document are added to (or replace) the built-in
    /// `s0`..`s4`.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, SimError> {
        Self::from_toml_str_as(text, origin, None)
    }

    /// [`Self::from_toml_str`] under `profile` whatever the document's `profile` says
    /// (`None`: the document's).
    pub fn from_toml_str_as(
        text: &str,
        origin: &str,
        profile: Option<Profile>,
    ) -> Result<Self, SimError> {
        let config_error = |message: String| SimError::Config {
            origin: origin.to_owned(),
            message,
        };
        // The document alone first: a misspelt key or a value of the wrong kind is named
        // with its line (the merged table below has no lines).
        let alone: SimConfig = toml::from_str(text)
            .map_err(|e| config_error(e.message().to_owned() + &span_hint(text, e.span())))?;
        let mut file: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            config_error(e.message().to_owned() + &span_hint(text, e.span()))
        })?;
        let profile = profile.unwrap_or(alone.profile);
        file.insert("profile".into(), profile.name().into());
        let mut merged = profile.table();
        profile::overlay(&mut merged, file);
        let mut cfg: SimConfig = toml::Value::Table(merged).try_into().map_err(|e| {
            config_error(format!(
                "under profile \"{}\": {}",
                profile.name(),
                e.message()
            ))
        })?;
        for (name, spec) in RouteSpec::builtin_scenarios() {
            cfg.scenarios.entry(name).or_insert(spec);
        }
        cfg.validate().map_err(|message| SimError::Config {
            origin: origin.to_owned(),
            message,
        })?;
        Ok(cfg)
    }

    /// The configuration in `path`, or without one the embedded defaults
    /// (`configs/world.toml`, [`crate::DEFAULT_CONFIG_TOML`]).
    pub fn load(path: Option<&Path>) -> Result<Self, SimError> {
        Self::load_as(path, None)
    }

    /// [`Self::load`] under `profile` whatever the file's `profile` says (`None`: the file's).
    pub fn load_as(path: Option<&Path>, profile: Option<Profile>) -> Result<Self, SimError> {
        let (text, origin) = match path {
            Some(p) => (
                std::fs::read_to_string(p).map_err(|e| SimError::Io {
                    path: p.to_owned(),
                    source: e,
                })?,
                p.display().to_string(),
            ),
            None => (
                crate::DEFAULT_CONFIG_TOML.to_owned(),
                "configs/world.toml (embedded)".to_owned(),
            ),
        };
        Self::from_toml_str_as(&text, &origin, profile)
    }

    /// The whole configuration as TOML, every key written out (the built-in scenarios
    /// too): reads back with [`Self::from_toml_str`] to an equal configuration, whatever
    /// file it came from and whatever defaults a later version has. A run folder keeps it as
    /// `world.toml`, so the run can be read back (and its frames rendered again) when the
    /// world file has changed or is on another machine.
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a SimConfig is TOML-shaped")
    }

    pub fn from_file(path: &Path) -> Result<Self, SimError> {
        Self::load_as(Some(path), None)
    }

    /// Checks value ranges that serde cannot express; the message names the key.
    pub fn validate(&self) -> Result<(), String> {
        let v = &self.vineyard;
        positive("vineyard.row_length_m", v.row_length_m)?;
        positive("vineyard.row_spacing_m", v.row_spacing_m)?;
        positive("vineyard.plant_spacing_m", v.plant_spacing_m)?;
        positive("vineyard.post_spacing_m", v.post_spacing_m)?;
        if v.rows == 0 {
            return Err("vineyard.rows = 0: need at least one row".into());
        }
        in_range("vineyard.growth_stage", v.growth_stage, 0.0, 4.0)?;
        in_range("vineyard.plant_variation", v.plant_variation, 0.0, 1.0)?;
        if !v.segments.is_empty() {
            positive("vineyard.segment_length_m", v.segment_length_m)?;
        }
        finite_triples("vineyard.segments", &v.segments)?;
        finite_triples("fence.panels", &self.fence.panels)?;
        for (k, size) in self.fence.panel_size_m.iter().enumerate() {
            positive(&format!("fence.panel_size_m[{k}]"), *size)?;
        }
        let t = &self.terrain;
        positive("terrain.wavelength_m", t.wavelength_m)?;
        positive("terrain.bump_wavelength_m", t.bump_wavelength_m)?;
        positive("terrain.cell_m", t.cell_m)?;
        positive("terrain.far_cell_m", t.far_cell_m)?;
        non_negative("terrain.amplitude_m", t.amplitude_m)?;
        non_negative("terrain.bump_amplitude_m", t.bump_amplitude_m)?;
        if let Some(m) = t.relief_margin_m {
            non_negative("terrain.relief_margin_m", m)?;
        }
        let r = &self.robot;
        positive("robot.max_speed_mps", r.max_speed_mps)?;
        positive("robot.max_yaw_rate_rps", r.max_yaw_rate_rps)?;
        positive("robot.max_accel_mps2", r.max_accel_mps2)?;
        positive("robot.max_yaw_accel_rps2", r.max_yaw_accel_rps2)?;
        positive("robot.lookahead_m", r.lookahead_m)?;
        r.vibration.check()?;
        let s = &self.sensors;
        s.gnss.check()?;
        positive("sensors.ground_truth.rate_hz", s.ground_truth.rate_hz)?;
        positive("sensors.imu.rate_hz", s.imu.rate_hz)?;
        non_negative(
            "sensors.imu.orientation_roll_pitch_sigma_rad",
            s.imu.orientation_roll_pitch_sigma_rad,
        )?;
        non_negative(
            "sensors.imu.orientation_yaw_sigma_rad",
            s.imu.orientation_yaw_sigma_rad,
        )?;
        positive("sensors.imu.orientation_tau_s", s.imu.orientation_tau_s)?;
        positive("sensors.wheel_odometry.rate_hz", s.wheel_odometry.rate_hz)?;
        positive("sensors.lidar.rate_hz", s.lidar.rate_hz)?;
        for (k, a) in s.lidar.beam_divergence_mrad.iter().enumerate() {
            in_range(
                &format!("sensors.lidar.beam_divergence_mrad[{k}]"),
                *a,
                0.0,
                100.0,
            )?;
        }
        non_negative("sensors.lidar.echo_separation_m", s.lidar.echo_separation_m)?;
        if s.lidar.columns == 0 || s.lidar.rings == 0 {
            return Err("sensors.lidar: columns and rings must be positive".into());
        }
        for (name, l) in [("front", &s.scan2d_front), ("back", &s.scan2d_back)] {
            positive(&format!("sensors.scan2d_{name}.rate_hz"), l.rate_hz)?;
            if l.samples < 2 {
                return Err(format!(
                    "sensors.scan2d_{name}.samples = {}: need at least 2",
                    l.samples
                ));
            }
        }
        for (name, e) in [
            ("imu", s.imu.mount_error),
            ("lidar", s.lidar.mount_error),
            ("scan2d_front", s.scan2d_front.mount_error),
            ("scan2d_back", s.scan2d_back.mount_error),
            ("camera", s.camera.mount_error),
        ] {
            non_negative(&format!("sensors.{name}.mount_error.sigma_m"), e.sigma_m)?;
            non_negative(
                &format!("sensors.{name}.mount_error.sigma_deg"),
                e.sigma_deg,
            )?;
        }
        for (name, offset) in [
            ("wheel_odometry", s.wheel_odometry.clock_offset_ns),
            ("lidar", s.lidar.clock_offset_ns),
            ("scan2d_front", s.scan2d_front.clock_offset_ns),
            ("scan2d_back", s.scan2d_back.clock_offset_ns),
            ("camera", s.camera.clock_offset_ns),
        ] {
            if !(0..=1_000_000_000).contains(&offset) {
                return Err(format!(
                    "sensors.{name}.clock_offset_ns = {offset}: must be 0 to 1000000000 (1 s)"
                ));
            }
        }
        let c = &s.camera;
        positive("sensors.camera.rate_hz", c.rate_hz)?;
        if c.width < 2 || c.height < 2 {
            return Err("sensors.camera: width and height must be at least 2".into());
        }
        in_range("sensors.camera.hfov_deg", c.hfov_deg, 1.0, 170.0)?;
        positive("sensors.camera.min_depth_m", c.min_depth_m)?;
        if c.max_depth_m <= c.min_depth_m {
            return Err(format!(
                "sensors.camera.max_depth_m = {}: must exceed min_depth_m = {}",
                c.max_depth_m, c.min_depth_m
            ));
        }
        non_negative("sensors.camera.rgb_sigma", c.rgb_sigma)?;
        if let Some(h) = c.depth_hfov_deg {
            in_range("sensors.camera.depth_hfov_deg", h, 1.0, 170.0)?;
        }
        let apart = c.depth_offset_m != [0.0; 3];
        if let Some([w, h]) = c.depth_size
            && (w < 2 || h < 2)
        {
            return Err(format!(
                "sensors.camera.depth_size = [{w}, {h}]: width and height must be at least 2"
            ));
        }
        for (k, v) in c.depth_offset_m.iter().enumerate() {
            in_range(
                &format!("sensors.camera.depth_offset_m[{k}]"),
                *v,
                -0.5,
                0.5,
            )?;
        }
        if (apart || c.depth_size.is_some()) && c.depth_hfov_deg.is_none() {
            return Err(
                "sensors.camera: depth_size and depth_offset_m describe a separate depth camera: \
                 set depth_hfov_deg too"
                    .into(),
            );
        }
        if (apart || c.depth_size.is_some_and(|s| s != [c.width, c.height]))
            && c.depth_registration != DepthRegistration::Registered
        {
            return Err(
                "sensors.camera: a depth camera of another size or centre than the colour \
                 camera's needs depth_registration = \"registered\""
                    .into(),
            );
        }
        if let Some(f) = c.colour_far_clip_m {
            positive("sensors.camera.colour_far_clip_m", f)?;
        }
        if let Some(d) = crate::camera::Distortion::new(c.distortion) {
            for (k, v) in c.distortion.iter().enumerate() {
                in_range(&format!("sensors.camera.distortion[{k}]"), *v, -10.0, 10.0)?;
            }
            if c.depth_hfov_deg.is_some() && c.depth_registration != DepthRegistration::Registered {
                return Err(
                    "sensors.camera.distortion: a lens's raw image takes its depth registered to                      it: set depth_registration = \"registered\""
                        .into(),
                );
            }
            crate::camera::Remap::new(&crate::camera::Intrinsics::from_config(c), &d)
                .map_err(|e| format!("sensors.camera.distortion = {:?}: {e}", c.distortion))?;
        }
        if let Background::Rgb(rgb) = c.background {
            for (k, v) in rgb.iter().enumerate() {
                in_range(&format!("sensors.camera.background[{k}]"), *v, 0.0, 1.0)?;
            }
        }
        non_negative("sensors.camera.edge_dropout_ratio", c.edge_dropout_ratio)?;
        in_range(
            "sensors.camera.sun_elevation_deg",
            c.sun_elevation_deg,
            1.0,
            90.0,
        )?;
        if !matches!(c.antialias_samples, 1 | 4 | 8) {
            return Err(format!(
                "sensors.camera.antialias_samples = {}: must be 1, 4 or 8",
                c.antialias_samples
            ));
        }
        if !matches!(c.depth_antialias_samples, 1 | 4 | 8) {
            return Err(format!(
                "sensors.camera.depth_antialias_samples = {}: must be 1, 4 or 8",
                c.depth_antialias_samples
            ));
        }
        for (name, route) in &self.scenarios {
            route
                .validate()
                .map_err(|e| format!("scenarios.{name}: {e}"))?;
        }
        Ok(())
    }
}

fn span_hint(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    span.map(|s| {
        let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
        format!(" (line {line})")
    })
    .unwrap_or_default()
}

fn positive(key: &str, v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("{key} = {v}: must be a positive number"))
    }
}

fn non_negative(key: &str, v: f64) -> Result<(), String> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(format!("{key} = {v}: must be zero or positive"))
    }
}

fn finite_triples(key: &str, list: &[[f64; 3]]) -> Result<(), String> {
    match list.iter().position(|t| t.iter().any(|v| !v.is_finite())) {
        Some(i) => Err(format!(
            "{key}[{i}] = {:?}: every value must be finite",
            list[i]
        )),
        None => Ok(()),
    }
}

fn in_range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), String> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(format!("{key} = {v}: must lie in [{lo}, {hi}]"))
    }
}

/// Which ray caster the sensors use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum RaycasterKind {
    #[default]
    Bvh,
    Parry,
    /// Intel's Embree 3 (the system's libembree3); only in builds with vinebench-sim's
    /// `embree` feature (on by default), else `Simulation::new` refuses it naming the key.
    Embree,
}

/// The vine block: rows along the world x axis, starting at x = 0, the first row at y = 0.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct VineyardConfig {
    pub rows: usize,
    pub row_length_m: f64,
    pub row_spacing_m: f64,
    pub plant_spacing_m: f64,
    pub post_spacing_m: f64,
    pub post_height_m: f64,
    /// Trellis wire heights above the ground; the lowest carries the cordons.
    pub wire_heights_m: Vec<f64>,
    /// Ground beyond the block's rows where the robot turns, on every side.
    pub headland_m: f64,
    /// 0 dormant wood, 1 bud burst, 2 shoots, 3 dense canopy, 4 full canopy with grapes.
    pub growth_stage: f64,
    /// 0: every plant an identical clone (our grid) or every segment an identical clone
    /// (`segments`, the paper's world); 1: every plant's geometry differs.
    pub plant_variation: f64,
    /// The rows as explicit clone segments, as the paper's world builds them: each
    /// `[x, y, yaw_deg]` is the centre of a straight run of plants `segment_length_m` long
    /// in the world frame, its row axis pointing at `yaw_deg` (counter-clockwise from world
    /// x). With `plant_variation = 0` every segment is the same pattern of differing plants
    /// (one vine mesh cloned, so the view repeats every segment); `rows`, `row_length_m`,
    /// `row_spacing_m` then only matter to the lane-based routes. Empty (the default): the
    /// grid of `rows` rows along x. Source: the `vine_t0` models' `<state>` poses in
    /// `bacchus_gazebo/worlds/vineyard_stage0_riseholme_vertical.world` (LCAS/bacchus_lcas,
    /// branch `liosam`).
    pub segments: Vec<[f64; 3]>,
    /// Length of one segment: plants at `plant_spacing_m` (rounded to fit a whole number),
    /// posts at its two ends.
    pub segment_length_m: f64,
}

impl Default for VineyardConfig {
    fn default() -> Self {
        Self {
            rows: 9,
            row_length_m: 18.0,
            row_spacing_m: 3.0,
            plant_spacing_m: 1.0,
            post_spacing_m: 6.0,
            post_height_m: 1.9,
            wire_heights_m: vec![0.9, 1.3, 1.7],
            headland_m: 6.0,
            growth_stage: 3.0,
            plant_variation: 0.0,
            segments: Vec::new(),
            segment_length_m: 5.75,
        }
    }
}

impl VineyardConfig {
    /// y of the lane centre between row `lane` and row `lane + 1`.
    pub fn lane_y(&self, lane: usize) -> f64 {
        (lane as f64 + 0.5) * self.row_spacing_m
    }

    pub fn lanes(&self) -> usize {
        self.rows.saturating_sub(1)
    }
}

/// Upright boxes around the block: the paper's perimeter fence of wooden panels
/// (`wooden_fence` in `vineyard_stage0_riseholme_vertical.world`, its mesh `fence.dae` on
/// LCAS/bacchus_lcas `master`). Seen by every sensor, with the posts' wood material.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct FenceConfig {
    /// Each `[x, y, yaw_deg]`: a panel's centre on the ground and the direction of its
    /// length. Empty (ours): no fence.
    pub panels: Vec<[f64; 3]>,
    /// Length, thickness and height of a panel.
    pub panel_size_m: [f64; 3],
    /// `false` (the paper's world): every panel is the same mesh with the same wood, as the
    /// 56 copies of `fence.dae` are. `true`: every panel's wood has its own grain and knots
    /// (its texture coordinates moved by a seeded offset of up to 50 m, drawn from the
    /// world seed per panel), its geometry unchanged: the switch that asks whether repeated
    /// panels fool a camera's place recognition.
    pub distinct_panels: bool,
}

impl Default for FenceConfig {
    fn default() -> Self {
        Self {
            panels: Vec::new(),
            panel_size_m: [2.0, 0.15, 1.7],
            distinct_panels: false,
        }
    }
}

/// Ground height field: smooth seeded noise plus an optional constant slope.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct TerrainConfig {
    /// Peak amplitude of the long undulations.
    pub amplitude_m: f64,
    pub wavelength_m: f64,
    /// Peak amplitude of the short bumps that make the robot roll and pitch.
    pub bump_amplitude_m: f64,
    pub bump_wavelength_m: f64,
    /// Constant slope along x and along y, in degrees.
    pub slope_deg: [f64; 2],
    /// Ground modelled around the block, beyond the headlands.
    pub margin_m: f64,
    /// Size of the ground mesh's cells over the block and its headlands.
    pub cell_m: f64,
    /// Size of the cells beyond the headlands (rounded to a multiple of `cell_m`).
    pub far_cell_m: f64,
    /// `None` (ours): the relief goes on to the edge of the modelled ground. A distance:
    /// the relief covers the block and its headlands and this much more, then fades over
    /// 2 m to a flat plane at z = 0 (the paper's world: a relief mesh over a flat
    /// 200 × 200 m ground plane, `grass_ground_plane` and `heightmap` in
    /// `vineyard_stage0_riseholme_vertical.world`).
    pub relief_margin_m: Option<f64>,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            amplitude_m: 0.15,
            wavelength_m: 10.0,
            bump_amplitude_m: 0.03,
            bump_wavelength_m: 2.5,
            slope_deg: [0.0, 0.0],
            margin_m: 30.0,
            cell_m: 0.5,
            far_cell_m: 2.0,
            relief_margin_m: None,
        }
    }
}

impl TerrainConfig {
    /// A perfectly flat ground plane at z = 0.
    pub fn flat() -> Self {
        Self {
            amplitude_m: 0.0,
            bump_amplitude_m: 0.0,
            slope_deg: [0.0, 0.0],
            ..Self::default()
        }
    }
}

/// The Thorvald-like base and its path-following controller.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotConfig {
    /// Wheel contact points in the base frame: (±x, ±y).
    pub wheel_x_m: f64,
    pub wheel_y_m: f64,
    pub wheel_radius_m: f64,
    pub max_speed_mps: f64,
    pub max_yaw_rate_rps: f64,
    pub max_accel_mps2: f64,
    pub max_yaw_accel_rps2: f64,
    /// Limit on the change of acceleration, which keeps it continuous.
    pub max_jerk_mps3: f64,
    /// Pure-pursuit look-ahead distance.
    pub lookahead_m: f64,
    /// Time the robot stands still before moving and after arriving.
    pub still_s: f64,
    /// The body's vibration as the wheels roll (`robot::vibration`); none by default, and
    /// then left out of a resolved world (which reads as it did before the key).
    #[serde(skip_serializing_if = "VibrationConfig::is_off")]
    pub vibration: VibrationConfig,
}

/// The body's vibration (`robot::vibration`): per motion, the RMS within each frequency
/// band at the reference wheel speed. Empty RMS lists (the default): no vibration.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct VibrationConfig {
    /// Band edges, Hz, ascending: `n + 1` edges for `n` bands.
    pub bands_hz: Vec<f64>,
    /// Acceleration RMS per band along the base's x, y and z, m/s² (empty: none).
    pub accel_rms_mps2: [Vec<f64>; 3],
    /// Angular rate RMS per band about the base's x, y and z (roll, pitch, yaw), rad/s.
    pub rate_rms_rps: [Vec<f64>; 3],
    /// The wheel speed the RMS figures were measured at, m/s.
    pub reference_speed_mps: f64,
    /// The amplitude grows as (speed / reference)^exponent.
    pub speed_exponent: f64,
    /// Cosines per band in the synthesis (Shinozuka & Deodatis 1991).
    pub components_per_band: usize,
}

impl Default for VibrationConfig {
    fn default() -> Self {
        Self {
            bands_hz: vec![0.5, 2.0, 5.0, 10.0, 25.0],
            accel_rms_mps2: Default::default(),
            rate_rms_rps: Default::default(),
            reference_speed_mps: 0.5,
            speed_exponent: 1.0,
            components_per_band: 8,
        }
    }
}

impl VibrationConfig {
    /// Whether no band moves the body.
    pub fn is_off(&self) -> bool {
        !self.is_on()
    }

    /// Whether any band moves the body.
    pub fn is_on(&self) -> bool {
        self.accel_rms_mps2
            .iter()
            .chain(&self.rate_rms_rps)
            .any(|bands| bands.iter().any(|&r| r != 0.0))
    }

    fn check(&self) -> Result<(), String> {
        if !self.is_on() {
            return Ok(());
        }
        let b = &self.bands_hz;
        if b.len() < 2
            || b[0] <= 0.0
            || b.iter().any(|f| !f.is_finite())
            || b.windows(2).any(|w| w[1] <= w[0])
        {
            return Err(format!(
                "robot.vibration.bands_hz = {b:?}: need at least two ascending positive edges"
            ));
        }
        for (name, lists) in [
            ("accel_rms_mps2", &self.accel_rms_mps2),
            ("rate_rms_rps", &self.rate_rms_rps),
        ] {
            for (axis, bands) in lists.iter().enumerate() {
                if !bands.is_empty() && bands.len() != b.len() - 1 {
                    return Err(format!(
                        "robot.vibration.{name}[{axis}] has {} values: one per band ({}) or none",
                        bands.len(),
                        b.len() - 1
                    ));
                }
                for (k, r) in bands.iter().enumerate() {
                    non_negative(&format!("robot.vibration.{name}[{axis}][{k}]"), *r)?;
                }
            }
        }
        positive(
            "robot.vibration.reference_speed_mps",
            self.reference_speed_mps,
        )?;
        in_range(
            "robot.vibration.speed_exponent",
            self.speed_exponent,
            0.0,
            4.0,
        )?;
        if !(1..=256).contains(&self.components_per_band) {
            return Err(format!(
                "robot.vibration.components_per_band = {}: must be 1 to 256",
                self.components_per_band
            ));
        }
        Ok(())
    }
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            wheel_x_m: 0.549,
            wheel_y_m: 0.449,
            wheel_radius_m: 0.2,
            max_speed_mps: 0.5,
            max_yaw_rate_rps: 0.5,
            max_accel_mps2: 1.0,
            max_yaw_accel_rps2: 1.0,
            max_jerk_mps3: 4.0,
            lookahead_m: 0.8,
            still_s: 2.0,
            vibration: VibrationConfig::default(),
        }
    }
}

/// A sensor's mounting: translation (m) and roll, pitch, yaw (deg) of `base_from_sensor`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Mount {
    pub xyz_m: [f64; 3],
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

impl Mount {
    pub fn at(x: f64, y: f64, z: f64) -> Self {
        Self {
            xyz_m: [x, y, z],
            rpy_deg: [0.0; 3],
        }
    }

    pub fn base_from_sensor(&self) -> nalgebra::Isometry3<f64> {
        let [x, y, z] = self.xyz_m;
        let [r, p, yw] = self.rpy_deg.map(f64::to_radians);
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(r, p, yw),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A world states its GNSS receiver under `[sensors.gnss]`; one without a receiver
    /// leaves it out of its resolved file (so that its key is what it was before GNSS), and
    /// a bad value is refused naming its key.
    #[test]
    fn a_gnss_receiver_is_stated_checked_and_absent_by_default() {
        let plain = SimConfig::from_toml_str(crate::DEFAULT_CONFIG_TOML, "world").expect("world");
        assert_eq!(plain.sensors.gnss.profile, GnssProfile::None);
        assert!(!plain.to_toml_string().contains("gnss"));
        let text = format!(
            "{}\n[sensors.gnss]\nprofile = \"rtk\"\nrate_hz = 10.0\n",
            crate::DEFAULT_CONFIG_TOML
        );
        let rtk = SimConfig::from_toml_str(&text, "rtk").expect("rtk world");
        assert_eq!(rtk.sensors.gnss.profile, GnssProfile::Rtk);
        assert_eq!(rtk.sensors.gnss.rate_hz, 10.0);
        let again = SimConfig::from_toml_str(&rtk.to_toml_string(), "again").expect("reads back");
        assert_eq!(again, rtk);
        let bad = text.replace("rate_hz = 10.0", "rate_hz = -1.0");
        let err = SimConfig::from_toml_str(&bad, "bad")
            .expect_err("refused")
            .to_string();
        assert!(err.contains("sensors.gnss.rate_hz"), "{err}");
    }

    /// The documented file and the built-in defaults must never disagree.
    #[test]
    fn shipped_world_toml_equals_the_defaults() {
        let parsed = SimConfig::from_toml_str(crate::DEFAULT_CONFIG_TOML, "configs/world.toml")
            .expect("shipped file parses");
        assert_eq!(
            parsed,
            SimConfig::default(),
            "configs/world.toml and SimConfig::default() differ"
        );
    }

    /// Every shipped world under every profile, written out whole, reads back to the same
    /// configuration.
    #[test]
    fn a_written_world_reads_back_equal() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs");
        let mut worlds = vec![SimConfig::default()];
        for name in ["paper-world.toml", "world.toml"] {
            let text = std::fs::read_to_string(Path::new(root).join(name)).expect("read");
            for profile in Profile::ALL {
                let mut table: toml::Table = text.parse().expect("parses");
                table.insert("profile".into(), profile.name().into());
                let text = toml::to_string(&table).expect("text");
                worlds.push(SimConfig::from_toml_str(&text, name).expect("shipped world parses"));
            }
        }
        for world in worlds {
            let text = world.to_toml_string();
            let back = SimConfig::from_toml_str(&text, "written").expect("reads back");
            assert_eq!(back, world, "{text}");
        }
    }

    /// `typical` restates the built-in defaults: a world without `profile` and one with
    /// `profile = "typical"` are the same world.
    #[test]
    fn the_typical_profile_is_the_defaults() {
        let alone = SimConfig::from_toml_str(Profile::Typical.toml(), "typical.toml")
            .expect("the profile parses as a world");
        assert_eq!(alone, SimConfig::default());
        for profile in Profile::ALL {
            SimConfig::from_toml_str(profile.toml(), profile.name())
                .unwrap_or_else(|e| panic!("configs/profiles/{}.toml: {e}", profile.name()));
        }
    }

    /// A profile's keys lie under the world file's: what the file leaves out comes from the
    /// profile, what it states wins, and everything else keeps the defaults.
    #[test]
    fn a_profile_lies_under_the_world_files_keys() {
        let text = "profile = \"paper\"\n[sensors.imu]\nrate_hz = 400.0\n\
                    mount = { xyz_m = [0.1, 0.0, 1.0] }\n[vineyard]\nrows = 5\n";
        let cfg = SimConfig::from_toml_str(text, "w.toml").expect("parses");
        let imu = &cfg.sensors.imu;
        assert_eq!(cfg.profile, Profile::Paper);
        assert_eq!(imu.rate_hz, 400.0, "the file's key wins");
        assert_eq!(imu.noise, NoiseProfile::None, "the profile's key");
        assert!(imu.reports_orientation, "the profile's key");
        assert_eq!(imu.mount.xyz_m, [0.1, 0.0, 1.0]);
        assert_eq!(cfg.sensors.camera.depth_hfov_deg, Some(70.0));
        assert_eq!(cfg.vineyard.rows, 5);
        assert_eq!(cfg.sensors.wheel_odometry, WheelOdometryConfig::default());

        let ideal = SimConfig::from_toml_str("profile = \"ideal\"\n", "w.toml").expect("parses");
        let s = &ideal.sensors;
        for (name, noise) in [
            ("imu", s.imu.noise),
            ("wheel_odometry", s.wheel_odometry.noise),
            ("lidar", s.lidar.noise),
            ("scan2d_front", s.scan2d_front.noise),
            ("scan2d_back", s.scan2d_back.noise),
            ("camera", s.camera.noise),
        ] {
            assert_eq!(
                noise,
                NoiseProfile::None,
                "ideal leaves noise on the {name}"
            );
        }
        let typical = SimConfig::default();
        assert_eq!(
            (s.lidar.instant_sweep, s.camera.width, s.imu.rate_hz),
            (
                typical.sensors.lidar.instant_sweep,
                typical.sensors.camera.width,
                typical.sensors.imu.rate_hz
            ),
            "ideal keeps the typical sensors' geometry and timing"
        );
    }

    /// The shipped worlds climb the ladder: neither restates a key its profile sets, so that
    /// `profile` alone decides the sensors' models.
    #[test]
    fn shipped_worlds_leave_the_models_to_their_profile() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs");
        for name in ["paper-world.toml", "world.toml"] {
            let text = std::fs::read_to_string(Path::new(root).join(name)).expect("read");
            let mine = leaves(&toml::Value::Table(text.parse().expect("parses")), "");
            for profile in Profile::ALL {
                let keys = leaves(&toml::Value::Table(profile.table()), "");
                let both: Vec<_> = keys.intersection(&mine).collect();
                assert!(
                    both.is_empty(),
                    "{name} restates {both:?} of {}",
                    profile.name()
                );
            }
        }
    }

    fn leaves(value: &toml::Value, prefix: &str) -> std::collections::BTreeSet<String> {
        match value {
            toml::Value::Table(t) => t
                .iter()
                .flat_map(|(k, v)| leaves(v, &format!("{prefix}{k}.")))
                .collect(),
            _ => std::collections::BTreeSet::from([prefix.trim_end_matches('.').to_owned()]),
        }
    }

    #[test]
    fn an_unknown_profile_is_named() {
        let e = SimConfig::from_toml_str("profile = \"gazebo\"\n", "w.toml").expect_err("name");
        let msg = e.to_string();
        assert!(
            msg.contains("w.toml") && msg.contains("gazebo") && msg.contains("line 1"),
            "{msg}"
        );
    }

    #[test]
    fn misspelt_key_is_named_with_its_line() {
        let e = SimConfig::from_toml_str("[vineyard]\nrows = 9\nrow_lenght_m = 3.0\n", "my.toml")
            .expect_err("typo");
        let msg = e.to_string();
        assert!(
            msg.contains("my.toml") && msg.contains("row_lenght_m") && msg.contains("line 3"),
            "{msg}"
        );
    }

    #[test]
    fn out_of_range_value_is_named() {
        let e = SimConfig::from_toml_str("[vineyard]\nplant_variation = 1.5\n", "w.toml")
            .expect_err("range");
        assert!(
            e.to_string().contains("vineyard.plant_variation = 1.5"),
            "{e}"
        );
    }

    /// A lens is named by its key when it folds, is not a number, or meets a depth image
    /// that is not registered to it; a Kinect v2's calibrated lens is taken.
    #[test]
    fn a_lens_that_cannot_be_rendered_is_named() {
        for (text, says) in [
            (
                "[sensors.camera]\nhfov_deg = 120.0\ndistortion = [-0.6, 0.0, 0.0, 0.0, 0.0]\n",
                "sensors.camera.distortion = [-0.6, 0.0, 0.0, 0.0, 0.0]",
            ),
            (
                "[sensors.camera]\ndistortion = [0.07, nan, 0.0, 0.0, 0.0]\n",
                "sensors.camera.distortion[1] = NaN",
            ),
            (
                "[sensors.camera]\ndepth_hfov_deg = 70.1\ndistortion = [0.07, -0.13, 0.0, 0.0, 0.06]\n",
                "set depth_registration = \"registered\"",
            ),
        ] {
            let e = SimConfig::from_toml_str(text, "w.toml").expect_err(text);
            assert!(e.to_string().contains(says), "{text}: {e}");
        }
        let kinect = "[sensors.camera]\nhfov_deg = 84.1\n\
                      distortion = [0.0717, -0.1355, 0.0016, 0.0024, 0.0595]\n";
        let cfg = SimConfig::from_toml_str(kinect, "w.toml").expect("a Kinect v2's lens");
        let text = toml::to_string(&cfg).expect("serialises");
        assert!(text.contains("distortion = ["), "{text}");
        let plain = toml::to_string(&SimConfig::default()).expect("serialises");
        assert!(
            !plain.contains("distortion"),
            "a pinhole's world text is as before"
        );
    }

    /// A depth camera of its own is described whole, and only registration can pair it.
    #[test]
    fn a_depth_camera_apart_needs_its_view_and_registration() {
        for (text, says) in [
            (
                "[sensors.camera]\ndepth_offset_m = [-0.05, 0.0, 0.0]\n",
                "set depth_hfov_deg too",
            ),
            (
                "[sensors.camera]\ndepth_hfov_deg = 70.1\ndepth_size = [512, 424]\n",
                "needs depth_registration = \"registered\"",
            ),
            (
                "[sensors.camera]\ndepth_hfov_deg = 70.1\ndepth_offset_m = [0.9, 0.0, 0.0]\n\
                 depth_registration = \"registered\"\n",
                "sensors.camera.depth_offset_m[0] = 0.9",
            ),
        ] {
            let e = SimConfig::from_toml_str(text, "w.toml").expect_err(says);
            assert!(e.to_string().contains(says), "{e}");
        }
        let field = SimConfig::from_toml_str("profile = \"field\"\n", "w.toml").expect("field");
        assert_eq!(field.sensors.camera.depth_size, Some([512, 424]));
    }

    #[test]
    fn partial_file_keeps_other_defaults_and_adds_routes() {
        let text = "[scenarios.mine]\nkind = \"waypoints\"\npoints = [[0.0, 1.5], [5.0, 1.5]]\n";
        let cfg = SimConfig::from_toml_str(text, "w.toml").expect("parses");
        assert_eq!(cfg.vineyard, VineyardConfig::default());
        assert!(
            cfg.scenarios.contains_key("mine")
                && cfg.scenarios.contains_key("s3")
                && cfg.scenarios.contains_key("s4"),
            "{:?}",
            cfg.scenarios.keys()
        );
    }

    #[test]
    fn lane_sequence_needs_lanes_and_a_change_of_lane() {
        for (lanes, expected) in [
            ("[]", "scenarios.mine: lanes = []"),
            ("[3, 3]", "scenarios.mine: lanes: lane 3 twice in a row"),
        ] {
            let text = format!(
                "[scenarios.mine]\nkind = \"lane_sequence\"\nlanes = {lanes}\novershoot_m = 1.0\n"
            );
            let e = SimConfig::from_toml_str(&text, "w.toml").expect_err(lanes);
            assert!(e.to_string().contains(expected), "{e}");
        }
    }
}
