//! Algorithms shared by vinebench's SLAM plugins, so that every plugin solves its graph,
//! integrates its IMU and keeps its maps the same way.
//!
//! - [`backend`]: a small factor-graph interface (variables, factors, update, estimate) and
//!   its implementation on factrs, chosen by name from a plugin's configuration.

pub mod backend;
