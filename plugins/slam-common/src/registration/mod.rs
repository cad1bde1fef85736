//! Registration: aligning scans to each other and to maps.
//!
//! - [`kdtree`]: nearest neighbours in 2D and 3D;
//! - [`voxel`]: voxel-grid downsampling of a point cloud;
//! - [`icp`]: point-to-plane ICP of a cloud against a map (lines and planes from its
//!   neighbours, with degeneracy handling);
//! - [`scan2d`]: planar laser scans and 3-DoF point-to-line ICP with degeneracy handling.

pub mod icp;
pub mod kdtree;
pub mod scan2d;
pub mod voxel;

pub use icp::{IcpConfig, IcpResult, IcpTarget, icp};
pub use kdtree::{KdTree, KdTree2, KdTree3, Neighbour};
pub use scan2d::{Icp2dConfig, Icp2dResult, Icp2dTarget, icp2d};
