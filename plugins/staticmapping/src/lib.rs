//! Offline 3D-lidar mapping in the style of StaticMapping (EdwardLiuyc/StaticMapping), the
//! paper's system that "can only construct the map from recorded data". The plugin keeps the
//! stream and builds everything in [`SlamSystem::finish`](plugin_api::SlamSystem::finish),
//! in the order of StaticMapping's map builder:
//!
//! 1. every sweep is range-gated and randomly sampled as it arrives ([`input`]);
//! 2. front end: each sweep, de-skewed, is matched to the last keyframe by
//!    libpointmatcher-style point-to-plane ICP ([`icp`], [`frontend`]);
//! 3. keyframes are merged into submaps of two, each matched to the previous one
//!    ([`submap`]);
//! 4. back end: a pose per submap in the shared factor-graph backend (iSAM2 by default, as
//!    StaticMapping uses GTSAM's iSAM2), a prior on the first, between factors for
//!    consecutive submaps and for loops ([`graph`]);
//! 5. loops: M2DP descriptors of the submaps propose candidates, ICP verifies them, and only
//!    edges that agree are added ([`loops`]);
//! 6. GNSS (off by default, `[gps] use_gps`): a position prior per submap once enough
//!    fixes and a turn are in, as StaticMapping's iSAM optimiser adds its ENU factors
//!    ([`gnss`]);
//! 7. the optimised submap poses are carried to every sweep.
//!
//! Outputs: the trajectory of every sweep, the whole map (voxel-filtered), loop-closure
//! events with both submaps' stamps. Parameters: [`config::Config`].

pub mod config;
pub mod frontend;
pub mod gnss;
pub mod graph;
pub mod icp;
pub mod input;
pub mod loops;
pub mod submap;
mod system;

pub use system::{BuildReport, StaticMapping};

plugin_api::export_plugin!(StaticMapping);
