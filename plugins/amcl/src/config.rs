//! AMCL's parameters under their ROS names, with AMCL's defaults.
//!
//! Sources (`ros-planning/navigation`, noetic-devel at 9ad6441): the node's parameter
//! defaults (`amcl/src/amcl_node.cpp`) and the dynamic-reconfigure defaults
//! (`amcl/cfg/AMCL.cfg`), which the node applies when it starts; where the two differ the
//! reconfigure default is what a stock launch runs, and is the one here.

use serde::Deserialize;

/// Which odometry motion model (`odom_model_type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
pub enum OdomModel {
    /// AMCL's `diff`: the book's model, with AMCL's variances passed where standard
    /// deviations are expected (the default, so what AMCL's users run).
    #[default]
    #[serde(rename = "diff")]
    Diff,
    /// AMCL's `diff-corrected`: the book's model as written.
    #[serde(rename = "diff-corrected")]
    DiffCorrected,
}

/// The filter's parameters.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AmclConfig {
    /// Fewest and most particles (`min_particles` 100, `max_particles` 5000).
    pub min_particles: usize,
    pub max_particles: usize,
    /// KLD-sampling's error bound and its `z` (`kld_err` 0.01, `kld_z` 0.99; AMCL puts
    /// `kld_z` into Fox's bound as the normal quantile itself).
    pub kld_err: f64,
    pub kld_z: f64,
    /// The filter updates once the odometry has moved this far along x or y, or turned
    /// this much, since its last update (`update_min_d` 0.2 m, `update_min_a` π/6 rad).
    pub update_min_d: f64,
    pub update_min_a: f64,
    /// Laser updates between resamplings (`resample_interval` 2).
    pub resample_interval: usize,
    /// Augmented MCL's averages' rates (`recovery_alpha_slow`, `recovery_alpha_fast`): 0
    /// in `AMCL.cfg`, which turns the random particles off (the node's own 0.001 and 0.1
    /// are what the cfg calls a good value).
    pub recovery_alpha_slow: f64,
    pub recovery_alpha_fast: f64,
    /// The likelihood-field model (`laser_z_hit` 0.95, `laser_z_rand` 0.05,
    /// `laser_sigma_hit` 0.2 m, `laser_likelihood_max_dist` 2.0 m).
    pub laser_z_hit: f64,
    pub laser_z_rand: f64,
    pub laser_sigma_hit: f64,
    pub laser_likelihood_max_dist: f64,
    /// Beams used per scan (`laser_max_beams` 30).
    pub laser_max_beams: usize,
    /// The motion model (`odom_model_type` "diff") and its noise (`odom_alpha1`..`4`, 0.2
    /// each: rotation from rotation, rotation from translation, translation from
    /// translation, translation from rotation).
    pub odom_model_type: OdomModel,
    pub odom_alpha1: f64,
    pub odom_alpha2: f64,
    pub odom_alpha3: f64,
    pub odom_alpha4: f64,
    /// The initial pose's covariance when a guess is given (`initial_cov_xx`, `_yy` 0.25 m²,
    /// `initial_cov_aa` (π/12)² rad²).
    pub initial_cov_xx: f64,
    pub initial_cov_yy: f64,
    pub initial_cov_aa: f64,
    /// The estimate counts as localised when the particle set's standard deviations are at
    /// most these (`std_warn_level_x`, `_y` 0.2 m, `std_warn_level_yaw` 0.1 rad: the levels
    /// above which AMCL's diagnostics warn that its estimate is too uncertain).
    pub std_warn_level_x: f64,
    pub std_warn_level_y: f64,
    pub std_warn_level_yaw: f64,
    /// The seed of the filter's random numbers (not AMCL's: vinebench runs are
    /// reproducible).
    pub seed: u64,
}

impl Default for AmclConfig {
    fn default() -> Self {
        Self {
            min_particles: 100,
            max_particles: 5000,
            kld_err: 0.01,
            kld_z: 0.99,
            update_min_d: 0.2,
            update_min_a: std::f64::consts::PI / 6.0,
            resample_interval: 2,
            recovery_alpha_slow: 0.0,
            recovery_alpha_fast: 0.0,
            laser_z_hit: 0.95,
            laser_z_rand: 0.05,
            laser_sigma_hit: 0.2,
            laser_likelihood_max_dist: 2.0,
            laser_max_beams: 30,
            odom_model_type: OdomModel::Diff,
            odom_alpha1: 0.2,
            odom_alpha2: 0.2,
            odom_alpha3: 0.2,
            odom_alpha4: 0.2,
            initial_cov_xx: 0.25,
            initial_cov_yy: 0.25,
            initial_cov_aa: (std::f64::consts::PI / 12.0).powi(2),
            std_warn_level_x: 0.2,
            std_warn_level_y: 0.2,
            std_warn_level_yaw: 0.1,
            seed: 0,
        }
    }
}

impl AmclConfig {
    /// One line naming the first parameter out of its range.
    pub fn validate(&self) -> Result<(), String> {
        let positive = [
            ("kld_err", self.kld_err),
            ("update_min_d", self.update_min_d),
            ("update_min_a", self.update_min_a),
            ("laser_sigma_hit", self.laser_sigma_hit),
            ("laser_likelihood_max_dist", self.laser_likelihood_max_dist),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("{name} must be a positive number, got {v}"));
            }
        }
        let non_negative = [
            ("kld_z", self.kld_z),
            ("recovery_alpha_slow", self.recovery_alpha_slow),
            ("recovery_alpha_fast", self.recovery_alpha_fast),
            ("laser_z_hit", self.laser_z_hit),
            ("laser_z_rand", self.laser_z_rand),
            ("odom_alpha1", self.odom_alpha1),
            ("odom_alpha2", self.odom_alpha2),
            ("odom_alpha3", self.odom_alpha3),
            ("odom_alpha4", self.odom_alpha4),
            ("initial_cov_xx", self.initial_cov_xx),
            ("initial_cov_yy", self.initial_cov_yy),
            ("initial_cov_aa", self.initial_cov_aa),
            ("std_warn_level_x", self.std_warn_level_x),
            ("std_warn_level_y", self.std_warn_level_y),
            ("std_warn_level_yaw", self.std_warn_level_yaw),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be a number ≥ 0, got {v}"));
            }
        }
        if self.min_particles == 0 || self.min_particles > self.max_particles {
            return Err(format!(
                "min_particles ({}) must be at least 1 and at most max_particles ({})",
                self.min_particles, self.max_particles
            ));
        }
        if self.resample_interval == 0 || self.laser_max_beams < 2 {
            return Err(format!(
                "resample_interval ({}) must be at least 1 and laser_max_beams ({}) at least 2",
                self.resample_interval, self.laser_max_beams
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_read_under_their_ros_names_and_bad_ones_are_named() {
        let c: AmclConfig =
            toml::from_str("max_particles = 2000\nodom_model_type = \"diff-corrected\"")
                .expect("parses");
        assert_eq!(c.max_particles, 2000);
        assert_eq!(c.odom_model_type, OdomModel::DiffCorrected);
        assert_eq!(c.min_particles, 100, "the rest keep AMCL's defaults");
        c.validate().expect("valid");
        assert!(
            toml::from_str::<AmclConfig>("max_particle = 1").is_err(),
            "unknown key"
        );
        let bad = AmclConfig {
            laser_sigma_hit: 0.0,
            ..AmclConfig::default()
        };
        assert!(bad.validate().unwrap_err().contains("laser_sigma_hit"));
        let bad = AmclConfig {
            min_particles: 6000,
            ..AmclConfig::default()
        };
        assert!(bad.validate().unwrap_err().contains("min_particles"));
    }
}
