//! Algorithms shared by vinebench's SLAM plugins, so that every plugin solves its graph,
//! integrates its IMU and keeps its maps the same way. One folder per domain; each
//! re-exports its main types, and its modules stay public for the rest.
//!
//! - [`factor_graph`]: the backend interface and its solvers, pose-graph replay, bundle
//!   adjustment;
//! - [`place`]: place recognition: the incremental [`place::Dictionary`] (RTAB-Map), the
//!   trained [`place::Vocabulary`] (DBoW2), the M2DP lidar descriptor;
//! - [`registration`]: k-d trees, voxel grids, 3D and 2D ICP;
//! - [`maps`]: the 2D occupancy grid;
//! - [`gnss`]: GNSS fixes carried into a system's frame (navsat_transform's alignment);
//! - [`motion`]: IMU preintegration, line and plane fits, Gauss–Newton on SE(3).

pub mod factor_graph;
pub mod gnss;
pub mod maps;
pub mod motion;
pub mod place;
pub mod registration;
