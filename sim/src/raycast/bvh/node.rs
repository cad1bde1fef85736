//! Node layouts: the binary nodes of the build and the 8-wide nodes that are traversed.

use crate::raycast::aabb::{fmax, fmin};
use crate::raycast::ray::Ray;

/// Binary build node: a box and either two children (`count == 0`, `first` = index of their
/// [`NodePair`]) or a leaf of `count` triangles starting at `first` in leaf order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Node {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

impl Node {
    pub fn half_area(&self) -> f32 {
        let e: [f32; 3] = std::array::from_fn(|k| self.hi[k] - self.lo[k]);
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }
}

/// The two children of a binary node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NodePair(pub [Node; 2]);

/// Children per wide node: eight, one AVX2 register of boxes per plane (see [`super::kernel`]).
pub(crate) const WIDTH: usize = 8;

/// [`WIDTH`] children's boxes side by side, lane `i` being child `i` (four cache lines).
/// Child `i` is a node (`child[i]` its index), a leaf (bit `i` of `leaves` set: `count[i]` triangles
/// from `child[i]` in leaf order) or absent (an inverted, empty box no ray enters).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct WideNode {
    /// `lo[axis][lane]`.
    pub lo: [[f32; WIDTH]; 3],
    pub hi: [[f32; WIDTH]; 3],
    pub child: [u32; WIDTH],
    pub count: [u8; WIDTH],
    pub leaves: u32,
}

impl WideNode {
    pub const EMPTY: WideNode = WideNode {
        lo: [[f32::INFINITY; WIDTH]; 3],
        hi: [[f32::NEG_INFINITY; WIDTH]; 3],
        child: [0; WIDTH],
        count: [0; WIDTH],
        leaves: 0,
    };

    pub fn set(&mut self, lane: usize, node: &Node, child: u32) {
        for k in 0..3 {
            self.lo[k][lane] = node.lo[k];
            self.hi[k][lane] = node.hi[k];
        }
        self.child[lane] = child;
        self.count[lane] = u8::try_from(node.count).expect("leaves hold at most MAX_LEAF");
        if node.count > 0 {
            self.leaves |= 1 << lane;
        }
    }

    /// The planes of axis `k` through which a ray enters and leaves the boxes, `(near, far)`:
    /// `hi[k]` first if the ray goes towards -k (`neg[k]`).
    #[inline(always)]
    pub fn planes(&self, neg: &[bool; 3], k: usize) -> (&[f32; WIDTH], &[f32; WIDTH]) {
        if neg[k] {
            (&self.hi[k], &self.lo[k])
        } else {
            (&self.lo[k], &self.hi[k])
        }
    }

    /// Slab test (Williams et al. 2005) of all the boxes at once: entry distances, and a bit
    /// mask of the boxes the ray enters within `[t_min, t_max]`. `neg[k]`: the ray goes
    /// towards -k, so it enters through `hi[k]`; picking the planes by sign instead of min/max
    /// also makes the inverted empty boxes miss.
    #[inline(always)]
    pub fn intersect(
        &self,
        ray: &Ray,
        neg: &[bool; 3],
        t_min: f32,
        t_max: f32,
    ) -> ([f32; WIDTH], u32) {
        let (nx, fx) = self.planes(neg, 0);
        let (ny, fy) = self.planes(neg, 1);
        let (nz, fz) = self.planes(neg, 2);
        let [ox, oy, oz] = ray.o;
        let [ix, iy, iz] = ray.inv_d;
        let mut near = [0.0f32; WIDTH];
        let mut far = [0.0f32; WIDTH];
        for i in 0..WIDTH {
            near[i] = fmax(
                fmax((nx[i] - ox) * ix, (ny[i] - oy) * iy),
                fmax((nz[i] - oz) * iz, t_min),
            );
            far[i] = fmin(
                fmin((fx[i] - ox) * ix, (fy[i] - oy) * iy),
                fmin((fz[i] - oz) * iz, t_max),
            );
        }
        // The sign bit of far - near is set where the box is missed (a -0.0 from a ray that
        // only grazes a face is counted as a miss too: boxes are padded, so nothing inside can
        // be hit there). Gathered without branches.
        let mut missed = [0u32; WIDTH];
        for i in 0..WIDTH {
            missed[i] = (((far[i] - near[i]).to_bits() as i32 >> 31) as u32) & (1 << i);
        }
        let mask = missed.iter().fold(0, |m, &b| m | b) ^ ((1 << WIDTH) - 1);
        (near, mask)
    }
}
