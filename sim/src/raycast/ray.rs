//! A ray with the per-ray values every box test needs, computed once.

use nalgebra::{Point3, Vector3};

/// Smallest direction component magnitude used for the inverse direction: a zero component
/// becomes this (keeping its sign), so slab distances stay finite and never NaN.
const MIN_DIR: f32 = 1e-20;

/// Origin, direction and inverse direction as plain arrays.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ray {
    pub o: [f32; 3],
    pub d: [f32; 3],
    pub inv_d: [f32; 3],
}

impl Ray {
    pub fn new(origin: &Point3<f32>, dir: &Vector3<f32>) -> Self {
        let inv = |c: f32| {
            if c.abs() < MIN_DIR {
                1.0 / MIN_DIR.copysign(c)
            } else {
                1.0 / c
            }
        };
        Self {
            o: [origin.x, origin.y, origin.z],
            d: [dir.x, dir.y, dir.z],
            inv_d: [inv(dir.x), inv(dir.y), inv(dir.z)],
        }
    }

    /// Per axis: whether the ray goes towards -axis (so it enters a box through its high
    /// plane).
    #[inline(always)]
    pub fn neg(&self) -> [bool; 3] {
        self.inv_d.map(|x| x < 0.0)
    }
}
