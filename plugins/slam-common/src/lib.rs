//! Algorithms shared by vinebench's SLAM plugins, so that every plugin solves its graph,
//! integrates its IMU and keeps its maps the same way.
//!
//! - [`backend`]: a small factor-graph interface (variables, factors, update, estimate) and
//!   its implementation on factrs, chosen by name from a plugin's configuration;
//! - [`imu`]: on-manifold IMU preintegration and state prediction;
//! - [`kdtree`], [`voxel`]: nearest neighbours and voxel-grid downsampling for maps;
//! - [`geometry`], [`lsq`], [`icp`]: lines and planes from neighbours, Gauss–Newton on SE(3)
//!   with degeneracy handling, point-to-plane ICP;
//! - [`m2dp`]: the M2DP global descriptor of a 3D point cloud (He, Wang and Zhang 2016), for
//!   lidar place recognition;
//! - [`ba`]: ORB-SLAM2's bundle adjustment: sparse Schur-complement Levenberg–Marquardt over
//!   keyframe poses and map points with monocular and stereo reprojection residuals, and the
//!   motion-only pose optimisation with χ² outlier rounds;
//! - [`bow`]: an incremental bag-of-words vocabulary over binary descriptors with tf-idf
//!   scores and RTAB-Map's likelihood, for appearance-based loop-closure detection;
//! - [`vocabulary`]: a trained hierarchical vocabulary of binary words (DBoW2, as ORB-SLAM2
//!   uses it) with tf-idf bag-of-words vectors, the direct index and the L1 score;
//! - [`scan2d`], [`occupancy`]: planar laser scans, 3-DoF point-to-line ICP with degeneracy
//!   handling, and a log-odds 2D occupancy grid in the ROS map_server convention;
//! - [`posegraph`]: g2o/TORO/City10000 pose-graph files replayed through any backend, with
//!   GTSAM's graph error and the ATE as yardsticks (the `graph-replay` binary).

pub mod ba;
pub mod backend;
pub mod bow;
pub mod geometry;
pub mod icp;
pub mod imu;
pub mod kdtree;
pub mod lsq;
pub mod m2dp;
pub mod occupancy;
pub mod posegraph;
pub mod scan2d;
pub mod vocabulary;
pub mod voxel;
