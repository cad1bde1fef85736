//! A baseline after ROS `robot_localization` as farm robots run it: `ekf_localization_node`
//! fusing wheel odometry, an IMU and (through `navsat_transform_node`) a GNSS receiver, in
//! the plane (`two_d_mode`), as the Thorvald robots of the LCAS field trials do
//! (LCAS/bacchus_lcas, `mel_amcl/config/rasberry_localisation.yaml`).
//!
//! Built from the published method, not from its code:
//! - T. Moore and D. Stouch, "A Generalized Extended Kalman Filter Implementation for the
//!   Robot Operating System", Intelligent Autonomous Systems 13 (IAS-13), 2014: the
//!   15-variable state, the omnidirectional constant-acceleration motion model, partial
//!   measurements selected by per-sensor update vectors, Mahalanobis rejection;
//! - robot_localization's documentation (`state_estimation_nodes`, `navsat_transform_node`,
//!   "Integrating GPS Data"; the `params/ekf.yaml` and `params/navsat_transform.yaml`
//!   templates) for its parameters, defaults and behaviour, read against its source
//!   (cra-ros-pkg/robot_localization, branch `ros2` at 1cb9533: `ekf.cpp`,
//!   `filter_base.cpp`, `ros_filter.cpp`, `navsat_transform.cpp`) where the documentation
//!   is silent, e.g. how Δt scales the process noise, the 1e-9 variance floor, `forceTwoD`.
//!
//! The pipeline, one module per stage: [`sensors`] turns wheel odometry and IMU messages
//! into measurements in the base frame with covariances from the rig's datasheet figures;
//! [`navsat`] aligns the GNSS datum with the filter's frame and turns fixes into position
//! measurements of the base; [`history`] handles measurements older than the filter's time
//! (`smooth_lagged_data`: back to the state before them, then everything again); [`filter`]
//! is the EKF; [`system`] the plugin. Parameters: [`config`].
//!
//! Frames: the filter's world frame is robot_localization's `odom`: the robot starts at its
//! origin; with the IMU's absolute orientation fused (`imu0_relative = false`, the default)
//! its yaw is the east-north-up heading, otherwise the robot starts at the identity. Poses
//! are `map_from_base` with that frame as the map: one after every wheel odometry message
//! (the online trajectory), the same trajectory at `finish`, with a `gnss_rejected` event
//! for every fix refused (no fix, not finite, a covariance that is not positive definite,
//! outside `gnss0_rejection_threshold`; or once, GNSS unusable without a heading).

pub mod config;
pub mod filter;
pub mod history;
pub mod measurement;
pub mod navsat;
pub mod sensors;
pub mod state;
pub mod system;

pub use config::Config;
pub use system::EkfLocalization;
