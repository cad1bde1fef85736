//! What the local map and loop closure need of a keyframe.

use nalgebra::Isometry3;

use crate::features::Features;

/// A keyframe seen through its current estimate: when, where the lidar was, and its
/// features (lidar frame).
#[derive(Debug, Clone, Copy)]
pub struct KeyframeView<'a> {
    pub stamp_ns: i64,
    pub world_from_lidar: Isometry3<f64>,
    pub features: &'a Features,
}
