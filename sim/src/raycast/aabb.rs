//! Axis-aligned boxes: grown during the build, tested against rays during traversal.

/// `a.min(b)` without the NaN handling of [`f32::min`]: one `minss`. Inputs here are never NaN.
#[inline(always)]
pub(crate) fn fmin(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// `a.max(b)` without the NaN handling of [`f32::max`].
#[inline(always)]
pub(crate) fn fmax(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Aabb {
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };

    pub fn of_points(points: &[[f32; 3]]) -> Self {
        let mut b = Self::EMPTY;
        for p in points {
            b.grow_point(p);
        }
        b
    }

    pub fn grow_point(&mut self, p: &[f32; 3]) {
        self.grow(&Aabb { lo: *p, hi: *p });
    }

    pub fn grow(&mut self, other: &Aabb) {
        self.lo = std::array::from_fn(|k| fmin(self.lo[k], other.lo[k]));
        self.hi = std::array::from_fn(|k| fmax(self.hi[k], other.hi[k]));
    }

    pub fn center(&self) -> [f32; 3] {
        std::array::from_fn(|k| 0.5 * (self.lo[k] + self.hi[k]))
    }

    /// Half the surface area (all the SAH needs); 0 for an empty box.
    pub fn half_area(&self) -> f32 {
        let e: [f32; 3] = std::array::from_fn(|k| fmax(self.hi[k] - self.lo[k], 0.0));
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    /// The box grown by a few ulps of its coordinates, so a rounding error in the slab test
    /// cannot lose a triangle lying on a face of the box.
    pub fn padded(&self) -> Self {
        let pad = |c: f32| c.abs() * 4.0 * f32::EPSILON + 1e-30;
        Aabb {
            lo: std::array::from_fn(|k| self.lo[k] - pad(self.lo[k])),
            hi: std::array::from_fn(|k| self.hi[k] + pad(self.hi[k])),
        }
    }
}
