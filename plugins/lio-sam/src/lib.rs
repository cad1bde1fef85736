//! Lidar-inertial SLAM in the style of LIO-SAM (Shan, Englot, Meyers, Wang, Ratti and Rus,
//! "LIO-SAM: Tightly-coupled Lidar Inertial Odometry via Smoothing and Mapping", IROS 2020),
//! for a 16-beam lidar and an IMU. [`LioSam::on_point_cloud`] reads like the paper's
//! system figure:
//!
//! 1. IMU preintegration predicts the motion through the sweep ([`motion`]);
//! 2. every point is deskewed to the sweep's start with the pose at its own time
//!    ([`deskew`]);
//! 3. edge and planar features are extracted by curvature along the rings ([`features`]);
//! 4. the features are registered to a local map of recent keyframes ([`registration`],
//!    [`local_map`]);
//! 5. every 1 m or 0.2 rad a keyframe joins the factor graph with a lidar-odometry factor and
//!    an IMU-preintegration factor, and the graph is updated ([`graph`]);
//! 6. loop closures are searched among old nearby keyframes, verified by ICP and added as
//!    robust factors, followed by a full optimisation ([`loop_closure`]);
//! 7. with `[gps] enabled`, GNSS fixes aligned to the map become GPS factors on keyframes
//!    by LIO-SAM's rules, each followed by a full optimisation ([`gnss`]).
//!
//! Outputs: the pose of every sweep as it is registered; at the end, the optimised keyframe
//! trajectory carried to every sweep, the keyframes' features as the map, and loop-closure
//! and refused-fix (`gnss_rejected`) events. Parameters: [`config::Config`], LIO-SAM's defaults where they apply.

pub mod config;
pub mod deskew;
pub mod features;
pub mod gnss;
pub mod graph;
pub mod imu_odometry;
pub mod keyframe;
pub mod local_map;
pub mod loop_closure;
pub mod motion;
pub mod registration;
mod system;

pub use system::LioSam;

plugin_api::export_plugin!(LioSam);
