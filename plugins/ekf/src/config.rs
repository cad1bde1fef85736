//! The parameters, under robot_localization's names where it has one, with its defaults
//! unless said otherwise.
//!
//! Sources (cra-ros-pkg/robot_localization, branch `ros2` at 1cb9533): the defaults the
//! code declares (`src/ros_filter.cpp`, `src/filter_base.cpp`, `src/navsat_transform.cpp`)
//! and the documented templates `params/ekf.yaml` and `params/navsat_transform.yaml`; the
//! sensor configuration is what a Thorvald in a field runs (LCAS/bacchus_lcas,
//! `mel_amcl/config/rasberry_localisation.yaml`: `two_d_mode: true`, wheel odometry's vx,
//! vy and vyaw, GNSS x and y through navsat_transform_node).
//!
//! The wheel odometry is robot_localization's `odom0`, the IMU its `imu0`; the GNSS, which
//! robot_localization fuses as the odometry navsat_transform_node publishes, is `gnss0`
//! here (its threshold after the `<sensor>_rejection_threshold` pattern).

use plugin_api::Parameters;
use serde::Deserialize;

use crate::filter::{DEFAULT_INITIAL_COVARIANCE, DEFAULT_PROCESS_NOISE};
use crate::state::{NAMES, STATE_SIZE, StateMatrix, StateVector};

/// The plugin's parameters.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Hold the state to the plane (`two_d_mode`; robot_localization's default is false).
    /// True here: the robot is a ground vehicle on the ground, and the Thorvald configs set
    /// it; every measurement then also measures z, roll, pitch and their rates and az as 0.
    pub two_d_mode: bool,
    /// `process_noise_covariance`: 15 values (the diagonal) or 225 (row-major), per second
    /// (the filter adds `Δt · Q`). Default robot_localization's diagonal, 0.05 0.05 0.06
    /// 0.03 0.03 0.06 0.025 0.025 0.04 0.01 0.01 0.02 0.01 0.01 0.015.
    pub process_noise_covariance: Vec<f64>,
    /// `initial_estimate_covariance`: 15 or 225 values; default 1e-9 on the diagonal.
    pub initial_estimate_covariance: Vec<f64>,
    /// `use_dynamic_process_noise_covariance` (false): scale the pose block of Q by the
    /// squared speed.
    pub use_dynamic_process_noise_covariance: bool,
    /// `smooth_lagged_data`: keep `history_length` seconds of states and measurements, and
    /// on a measurement older than the filter's time go back to the state before it and
    /// process everything since again. True here (robot_localization's default is false,
    /// which applies a lagged measurement at the filter's time): a GNSS fix arrives after
    /// its receiver's latency, stamped at its epoch, and applied late it would pull the
    /// estimate back along the track by the distance driven meanwhile.
    pub smooth_lagged_data: bool,
    /// `history_length`, seconds (robot_localization's default 0; 1 s here, many times a
    /// receiver's latency).
    pub history_length: f64,
    /// `gravitational_acceleration`, m/s² (9.80665).
    pub gravitational_acceleration: f64,
    /// `odom0_config`: which of x y z roll pitch yaw vx vy vz vroll vpitch vyaw ax ay az
    /// the wheel odometry measures; default vx, vy (0: the base does not slide) and vyaw,
    /// as Thorvald's configuration. Only velocities: the plugin fuses no odometry pose.
    pub odom0_config: Vec<bool>,
    /// `odom0_twist_rejection_threshold` (Mahalanobis distance; off).
    pub odom0_twist_rejection_threshold: f64,
    /// `imu0_config`: default roll, pitch, yaw (used when the IMU reports an orientation)
    /// and the three angular velocities; set ax, ay, az to fuse its linear acceleration
    /// (off by default, as in most field configurations). No position or linear velocity.
    pub imu0_config: Vec<bool>,
    /// `imu0_relative` (false): the IMU's orientation is absolute, east-north-up.
    pub imu0_relative: bool,
    /// `imu0_remove_gravitational_acceleration`: true here, as the `params/ekf.yaml`
    /// template sets it (the code's default is false); only matters with ax, ay, az fused.
    pub imu0_remove_gravitational_acceleration: bool,
    /// `imu0_pose_rejection_threshold`, `imu0_twist_rejection_threshold`,
    /// `imu0_linear_acceleration_rejection_threshold` (all off).
    pub imu0_pose_rejection_threshold: f64,
    pub imu0_twist_rejection_threshold: f64,
    pub imu0_linear_acceleration_rejection_threshold: f64,
    /// Standard deviation of the IMU's reported roll, pitch and yaw, rad, where the rig's
    /// IMU states none (its noise figures `orientation_roll_pitch_sigma_rad`,
    /// `orientation_yaw_sigma_rad`, which stand in for the message covariance
    /// robot_localization reads). Not a robot_localization parameter: 1°, an Xsens MTi-30
    /// AHRS's yaw accuracy (user manual MT0605P §4.3).
    pub imu0_orientation_sigma_rad: f64,
    /// `gnss0_rejection_threshold`: the GNSS fix's Mahalanobis gate (off, as
    /// robot_localization's thresholds are by default).
    pub gnss0_rejection_threshold: f64,
    /// navsat_transform_node's `magnetic_declination_radians` and `yaw_offset` (0, 0):
    /// added to the IMU's yaw to make it east-referenced.
    pub magnetic_declination_radians: f64,
    pub yaw_offset: f64,
    /// navsat_transform_node's `use_odometry_yaw` (false): take the filter's own yaw as
    /// the heading for the datum, which is right only if that yaw is absolute.
    pub use_odometry_yaw: bool,
}

impl Default for Config {
    fn default() -> Self {
        let velocities = |list: &[&str]| NAMES.iter().map(|n| list.contains(n)).collect();
        Self {
            two_d_mode: true,
            process_noise_covariance: DEFAULT_PROCESS_NOISE.to_vec(),
            initial_estimate_covariance: vec![DEFAULT_INITIAL_COVARIANCE; STATE_SIZE],
            use_dynamic_process_noise_covariance: false,
            smooth_lagged_data: true,
            history_length: 1.0,
            gravitational_acceleration: 9.80665,
            odom0_config: velocities(&["vx", "vy", "vyaw"]),
            odom0_twist_rejection_threshold: f64::MAX,
            imu0_config: velocities(&["roll", "pitch", "yaw", "vroll", "vpitch", "vyaw"]),
            imu0_relative: false,
            imu0_remove_gravitational_acceleration: true,
            imu0_pose_rejection_threshold: f64::MAX,
            imu0_twist_rejection_threshold: f64::MAX,
            imu0_linear_acceleration_rejection_threshold: f64::MAX,
            imu0_orientation_sigma_rad: 1f64.to_radians(),
            gnss0_rejection_threshold: f64::MAX,
            magnetic_declination_radians: 0.0,
            yaw_offset: 0.0,
            use_odometry_yaw: false,
        }
    }
}

/// A covariance parameter as a matrix: 15 values are the diagonal, 225 the whole matrix
/// row-major (robot_localization takes either).
fn matrix(key: &str, values: &[f64]) -> Result<StateMatrix, String> {
    if values.iter().any(|v| !v.is_finite()) {
        return Err(format!("{key} must hold finite numbers"));
    }
    let m = match values.len() {
        STATE_SIZE => StateMatrix::from_diagonal(&StateVector::from_column_slice(values)),
        n if n == STATE_SIZE * STATE_SIZE => StateMatrix::from_row_slice(values),
        n => {
            return Err(format!(
                "{key} must have 15 values (the diagonal) or 225 (row-major), got {n}"
            ));
        }
    };
    if m.diagonal().iter().any(|&v| v < 0.0) {
        return Err(format!(
            "{key} must have no negative variance on its diagonal"
        ));
    }
    if (m - m.transpose()).abs().max() > 1e-12 * m.abs().max().max(1.0) {
        return Err(format!("{key} must be symmetric"));
    }
    Ok(m)
}

impl Config {
    pub fn process_noise(&self) -> Result<StateMatrix, String> {
        matrix("process_noise_covariance", &self.process_noise_covariance)
    }

    pub fn initial_covariance(&self) -> Result<StateMatrix, String> {
        matrix(
            "initial_estimate_covariance",
            &self.initial_estimate_covariance,
        )
    }

    /// `odom0_config` as an array.
    pub fn odom_update(&self) -> [bool; STATE_SIZE] {
        std::array::from_fn(|i| self.odom0_config.get(i).copied().unwrap_or(false))
    }

    /// `imu0_config` as an array.
    pub fn imu_update(&self) -> [bool; STATE_SIZE] {
        std::array::from_fn(|i| self.imu0_config.get(i).copied().unwrap_or(false))
    }
}

/// A sensor configuration of 15 flags that may set only `allowed` variables.
fn check_update_vector(
    key: &str,
    flags: &[bool],
    allowed: &[&str],
    what: &str,
) -> Result<(), String> {
    if flags.len() != STATE_SIZE {
        return Err(format!(
            "{key} must have 15 flags (x y z roll pitch yaw vx vy vz vroll vpitch vyaw ax ay az), got {}",
            flags.len()
        ));
    }
    match NAMES
        .iter()
        .zip(flags)
        .find(|(name, on)| **on && !allowed.contains(name))
    {
        Some((name, _)) => Err(format!("{key} sets {name}, which {what}")),
        None => Ok(()),
    }
}

impl Parameters for Config {
    /// As the trait's, with the key named where toml's message does not name it (a value
    /// of the wrong type).
    fn from_toml(text: &str) -> Result<Self, String> {
        let cfg: Self = toml::from_str(text).map_err(|e| {
            let culprit = text.parse::<toml::Table>().ok().and_then(|table| {
                table.into_iter().find_map(|(key, value)| {
                    let alone = toml::Table::from_iter([(key.clone(), value)]);
                    toml::Value::Table(alone)
                        .try_into::<Self>()
                        .err()
                        .map(|_| key)
                })
            });
            match culprit {
                Some(key) if !e.message().contains(&key) => {
                    format!("parameters: {key}: {}", e.message().trim())
                }
                _ => format!("parameters: {}", e.message().trim()),
            }
        })?;
        cfg.check().map_err(|e| format!("parameters: {e}"))?;
        Ok(cfg)
    }

    fn check(&self) -> Result<(), String> {
        self.process_noise()?;
        self.initial_covariance()?;
        check_update_vector(
            "odom0_config",
            &self.odom0_config,
            &["vx", "vy", "vz", "vroll", "vpitch", "vyaw"],
            "wheel odometry does not measure here (only its velocities are fused)",
        )?;
        check_update_vector(
            "imu0_config",
            &self.imu0_config,
            &[
                "roll", "pitch", "yaw", "vroll", "vpitch", "vyaw", "ax", "ay", "az",
            ],
            "an IMU does not measure",
        )?;
        let thresholds = [
            (
                "odom0_twist_rejection_threshold",
                self.odom0_twist_rejection_threshold,
            ),
            (
                "imu0_pose_rejection_threshold",
                self.imu0_pose_rejection_threshold,
            ),
            (
                "imu0_twist_rejection_threshold",
                self.imu0_twist_rejection_threshold,
            ),
            (
                "imu0_linear_acceleration_rejection_threshold",
                self.imu0_linear_acceleration_rejection_threshold,
            ),
            ("gnss0_rejection_threshold", self.gnss0_rejection_threshold),
        ];
        for (key, v) in thresholds {
            if v.is_nan() || v <= 0.0 {
                return Err(format!(
                    "{key} must be a positive Mahalanobis distance, got {v}"
                ));
            }
        }
        let non_negative = [
            ("history_length", self.history_length),
            (
                "imu0_orientation_sigma_rad",
                self.imu0_orientation_sigma_rad,
            ),
        ];
        for (key, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{key} must be a number ≥ 0, got {v}"));
            }
        }
        let finite = [
            (
                "gravitational_acceleration",
                self.gravitational_acceleration,
            ),
            (
                "magnetic_declination_radians",
                self.magnetic_declination_radians,
            ),
            ("yaw_offset", self.yaw_offset),
        ];
        for (key, v) in finite {
            if !v.is_finite() {
                return Err(format!("{key} must be a finite number, got {v}"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{VX, VY, VYAW, YAW};

    #[test]
    fn the_defaults_are_robot_localization_s() {
        let c = Config::from_toml("").expect("an empty table is valid");
        assert_eq!(c, Config::default());
        let q = c.process_noise().expect("valid");
        assert_eq!(q[(0, 0)], 0.05);
        assert_eq!(q[(2, 2)], 0.06);
        assert_eq!(q[(VYAW, VYAW)], 0.02);
        assert_eq!(q[(14, 14)], 0.015);
        assert_eq!(q[(0, 1)], 0.0);
        assert_eq!(
            c.initial_covariance().expect("valid"),
            StateMatrix::identity() * 1e-9
        );
        let odom = c.odom_update();
        assert!(odom[VX] && odom[VY] && odom[VYAW] && odom.iter().filter(|&&f| f).count() == 3);
        assert!(
            c.imu_update()[YAW] && !c.imu_update()[12],
            "no acceleration by default"
        );
        assert!(c.two_d_mode && c.gnss0_rejection_threshold == f64::MAX);
    }

    #[test]
    fn parameters_read_under_their_names_and_bad_ones_are_named() {
        let c = Config::from_toml(
            "two_d_mode = false\ngnss0_rejection_threshold = 5\nhistory_length = 2\n\
             process_noise_covariance = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1]",
        )
        .expect("parses, integers as numbers");
        assert!(!c.two_d_mode);
        assert_eq!(c.gnss0_rejection_threshold, 5.0);
        assert_eq!(c.history_length, 2.0);
        let full: Vec<String> = (0..225)
            .map(|k| {
                if k % 16 == 0 {
                    "0.2".into()
                } else {
                    "0.0".into()
                }
            })
            .collect();
        let c = Config::from_toml(&format!("process_noise_covariance = [{}]", full.join(", ")))
            .expect("225 values");
        assert_eq!(
            c.process_noise().expect("valid"),
            StateMatrix::identity() * 0.2
        );

        for (text, key) in [
            ("two_d_mod = true", "two_d_mod"),
            ("smooth_lagged_data = 1", "smooth_lagged_data"),
            ("imu0_config = \"all\"", "imu0_config"),
            (
                "process_noise_covariance = [0.1, 0.2]",
                "process_noise_covariance",
            ),
            (
                "initial_estimate_covariance = [1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]",
                "initial_estimate_covariance",
            ),
            (
                "gnss0_rejection_threshold = -1.0",
                "gnss0_rejection_threshold",
            ),
            ("history_length = -0.5", "history_length"),
            (
                "odom0_config = [true, false, false, false, false, false, false, false, false, false, false, false, false, false, false]",
                "odom0_config",
            ),
            ("imu0_config = [false]", "imu0_config"),
            (
                "imu0_orientation_sigma_rad = nan",
                "imu0_orientation_sigma_rad",
            ),
        ] {
            let e = Config::from_toml(text).expect_err(text);
            assert!(
                e.contains(key),
                "{text:?} gave {e:?}, which does not name {key}"
            );
            assert!(!e.contains('\n'), "one line: {e:?}");
        }
    }
}
