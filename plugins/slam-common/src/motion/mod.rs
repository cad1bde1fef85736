//! Motion: how a body moves, and the least squares that estimate it.
//!
//! - [`imu`]: on-manifold IMU preintegration and state prediction;
//! - [`geometry`]: lines and planes fitted to neighbours;
//! - [`lsq`]: Gauss–Newton on SE(3) with degeneracy handling.

pub mod geometry;
pub mod imu;
pub mod lsq;

pub use geometry::{Line, Plane, fit_line, fit_plane};
pub use imu::{NavState, Preintegrated};
pub use lsq::NormalEquations;
