//! Maps a plugin leaves behind.
//!
//! - [`occupancy`]: a log-odds 2D occupancy grid in the ROS map_server convention;
//! - [`keyframes`]: a lidar map saved to localise in later (keyframe poses and clouds);
//! - [`localizer`]: localisation in such a map (Scan Context, then ICP to a submap).

pub mod keyframes;
pub mod localizer;
pub mod occupancy;

pub use occupancy::{Grid, OccupancyGridBuilder, OccupancyGridConfig};
