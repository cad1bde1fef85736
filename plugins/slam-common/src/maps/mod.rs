//! Maps a plugin leaves behind.
//!
//! - [`occupancy`]: a log-odds 2D occupancy grid in the ROS map_server convention.

pub mod occupancy;

pub use occupancy::{Grid, OccupancyGridBuilder, OccupancyGridConfig};
