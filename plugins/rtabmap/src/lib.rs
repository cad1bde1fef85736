//! Appearance-based RGB-D SLAM in the style of RTAB-Map (Labbé and Michaud, "RTAB-Map as an
//! open-source lidar and visual simultaneous localization and mapping library for
//! large-scale and long-term online operation", J. Field Robotics 2019).
//!
//! [`Rtabmap`] reads like the method:
//!
//! 1. odometry ([`visual_odometry`]: GFTT/BRIEF features ([`features`]) matched frame to map
//!    and solved by PnP RANSAC ([`pnp`]); or [`scan_odometry`]: wheel odometry refined by
//!    ICP on the front 2D scan, as the paper ran RTAB-Map);
//! 2. once a second, if the robot moved, a new location with the strongest visual words of
//!    its image, quantised into an incremental vocabulary ([`memory`]);
//! 3. loop-closure detection: tf-idf likelihoods of the locations in working memory and a
//!    discrete Bayes filter over them ([`bayes`]); a hypothesis above the threshold is
//!    verified by PnP between the two images;
//! 4. proximity detection ([`proximity`]): a location near an older one in the graph is
//!    registered to it by ICP on their laser scans;
//! 5. the graph of locations on the shared backend ([`graph`]): a loop closure is kept only
//!    if, after optimisation, no link is strained beyond `OptimizeMaxError`;
//! 6. with `Optimizer/PriorsIgnored = false` (off by default, as in RTAB-Map), a GPS prior
//!    on every location that has a fix, which puts the map in the fixes' frame ([`gps`]).
//!
//! Outputs: the odometry poses as they come (corrected by the graph), and at the end the
//! trajectory carried by the optimised locations, a point cloud from the locations' depth,
//! a 2D occupancy grid from their scans, and an event for every loop closure accepted or
//! rejected and every loss of visual tracking. Parameters: [`config::Config`], RTAB-Map's
//! defaults where they apply (`configs/rtabmap.toml`).

pub mod attitude;
pub mod bayes;
pub mod config;
pub mod features;
pub mod gps;
pub mod graph;
pub mod matching;
pub mod memory;
pub mod pnp;
pub mod proximity;
pub mod rectify;
pub mod scan_odometry;
mod system;
pub mod visual_odometry;

pub use system::Rtabmap;

plugin_api::export_plugin!(Rtabmap);
