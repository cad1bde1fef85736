//! Feature-based RGB-D SLAM in the style of ORB-SLAM2 (Mur-Artal and Tardós, "ORB-SLAM2: an
//! open-source SLAM system for monocular, stereo and RGB-D cameras", T-RO 2017; Mur-Artal,
//! Montiel and Tardós, "ORB-SLAM: a versatile and accurate monocular SLAM system", T-RO
//! 2015; Gálvez-López and Tardós, "Bags of binary words for fast place recognition in image
//! sequences", T-RO 2012).
//!
//! [`OrbSlam2`] reads like the paper's three-thread figure, run one after the other on each
//! frame so that a run is deterministic:
//!
//! 1. **tracking** ([`tracking`]): ORB features ([`orb`]) of the RGB-D frame ([`frame`]),
//!    matched ([`matcher`]) to the last frame by a constant-velocity model or to the
//!    reference keyframe by bag of words, the pose optimised ([`optimizer`]), refined
//!    against the local map; the keyframe decision; relocalisation when lost;
//! 2. **local mapping** ([`local_mapping`]): the keyframe's points and covisibility edges
//!    ([`map`]), recent-point culling, new points by triangulation ([`triangulation`]),
//!    duplicate fusion, local bundle adjustment,
//!    keyframe culling;
//! 3. **loop closing** ([`loop_closing`]): candidates from the keyframe database
//!    ([`database`]) over a DBoW2 vocabulary (`slam_common::place::vocabulary`) trained on another
//!    world, covisibility-group consistency, geometric verification, correction by pose
//!    propagation, point fusion, essential-graph optimisation and a global bundle
//!    adjustment — with no check on the size of the correction, as published.
//!
//! Outputs: the pose of every tracked frame as it is tracked; at the end, every tracked
//! frame carried by its optimised reference keyframe, the map points, and events for
//! tracking lost and recovered and every loop accepted or rejected. Parameters:
//! [`config::Config`] (`configs/orbslam2.toml`).

pub mod config;
pub mod database;
pub mod frame;
pub mod local_mapping;
pub mod loop_closing;
pub mod map;
pub mod matcher;
pub mod optimizer;
pub mod orb;
pub mod saved;
mod system;
pub mod tracking;
pub mod triangulation;

pub use system::OrbSlam2;

plugin_api::export_plugin!(OrbSlam2);
