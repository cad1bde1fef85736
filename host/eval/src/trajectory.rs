//! A time-stamped trajectory: `world_from_body` poses with stamps in seconds.

use nalgebra::{Isometry3, Point3};

/// A trajectory: pose `i` (`world_from_body`) was taken at `stamps[i]` seconds.
///
/// Readers guarantee equal lengths, finite values and strictly increasing stamps.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Time stamps in seconds, strictly increasing.
    pub stamps: Vec<f64>,
    /// `world_from_body` poses, one per stamp.
    pub poses: Vec<Isometry3<f64>>,
}

impl Trajectory {
    /// A trajectory from stamps and poses of equal length.
    ///
    /// # Panics
    /// If the lengths differ (a bug in the caller).
    pub fn new(stamps: Vec<f64>, poses: Vec<Isometry3<f64>>) -> Self {
        assert_eq!(stamps.len(), poses.len(), "one stamp per pose");
        Self { stamps, poses }
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// Whether there is no pose.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Positions of the body in the world frame.
    pub fn positions(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        self.poses
            .iter()
            .map(|p| Point3::from(p.translation.vector))
    }

    /// Length of the polyline through the positions, in metres.
    pub fn path_length(&self) -> f64 {
        self.poses
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .sum()
    }
}
