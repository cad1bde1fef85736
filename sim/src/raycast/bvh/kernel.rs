//! The box test of a wide node, the inner loop of every traversal, in two kernels that give
//! the same answers bit for bit: [`Portable`], plain Rust the compiler vectorises (two SSE
//! halves on baseline x86-64, whatever the target has elsewhere), and, on x86-64 CPUs with
//! AVX2, [`Avx2`], all eight boxes in one instruction per step and the hit mask in one
//! `movmskps` (the auto-vectorised form gathers it in seven). Both compute every lane with the
//! same IEEE operations in the same order, so the distances and masks are identical; the
//! traversal around them is compiled for AVX2 too (see `Bvh::cast_fan`), still without FMA,
//! which Rust never fuses on its own, so the triangle tests round the same way as well.

use super::node::{WIDTH, WideNode};
use crate::raycast::ray::Ray;

/// Tests a ray against the [`WIDTH`] boxes of a node: entry distances, and the bit mask of
/// the boxes the ray enters within `[t_min, t_max]` (see [`WideNode::intersect`]).
pub(super) trait BoxTest {
    fn test(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32);
}

/// [`WideNode::intersect`] for one ray.
pub(super) struct Portable {
    ray: Ray,
    neg: [bool; 3],
    t_min: f32,
}

impl Portable {
    #[inline(always)]
    pub fn new(ray: &Ray, t_min: f32) -> Self {
        Self {
            ray: *ray,
            neg: ray.neg(),
            t_min,
        }
    }
}

impl BoxTest for Portable {
    #[inline(always)]
    fn test(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32) {
        node.intersect(&self.ray, &self.neg, self.t_min, t_max)
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) use avx2::{Avx2, HasAvx2};

#[cfg(target_arch = "x86_64")]
mod avx2 {
    #![allow(unsafe_code)]

    use std::arch::x86_64::{
        __m256, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps,
        _mm256_set1_ps, _mm256_storeu_ps, _mm256_sub_ps,
    };

    use super::{BoxTest, WIDTH, WideNode};
    use crate::raycast::ray::Ray;

    const _: () = assert!(WIDTH == 8, "the AVX2 kernel tests eight boxes at once");

    /// Proof that the CPU running us has AVX2: only [`HasAvx2::detect`] makes one.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub(in crate::raycast::bvh) struct HasAvx2(());

    impl HasAvx2 {
        pub fn detect() -> Option<Self> {
            std::arch::is_x86_feature_detected!("avx2").then_some(Self(()))
        }
    }

    /// [`WideNode::intersect`] with the ray's values broadcast to eight lanes once.
    pub(in crate::raycast::bvh) struct Avx2 {
        o: [__m256; 3],
        inv: [__m256; 3],
        t_min: __m256,
        neg: [bool; 3],
    }

    impl Avx2 {
        #[inline(always)]
        pub fn new(ray: &Ray, t_min: f32, _cpu: HasAvx2) -> Self {
            // SAFETY: `_cpu` proves the CPU has AVX2 (hence AVX).
            unsafe {
                Self {
                    o: ray.o.map(|x| _mm256_set1_ps(x)),
                    inv: ray.inv_d.map(|x| _mm256_set1_ps(x)),
                    t_min: _mm256_set1_ps(t_min),
                    neg: ray.neg(),
                }
            }
        }
    }

    impl BoxTest for Avx2 {
        /// The operations of [`WideNode::intersect`], lane for lane and in the same order
        /// (`max_ps(a, b)` is `if a > b { a } else { b }` as `fmax` is, and so for min).
        #[inline(always)]
        fn test(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32) {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2 (see `new`); the loads and the
            // store read and write `[f32; 8]` arrays, unaligned accesses being allowed.
            unsafe {
                let slab = |plane: &[f32; WIDTH], k: usize| {
                    _mm256_mul_ps(
                        _mm256_sub_ps(_mm256_loadu_ps(plane.as_ptr()), self.o[k]),
                        self.inv[k],
                    )
                };
                let planes = |k: usize| {
                    if self.neg[k] {
                        (&node.hi[k], &node.lo[k])
                    } else {
                        (&node.lo[k], &node.hi[k])
                    }
                };
                let (nx, fx) = planes(0);
                let (ny, fy) = planes(1);
                let (nz, fz) = planes(2);
                let near = _mm256_max_ps(
                    _mm256_max_ps(slab(nx, 0), slab(ny, 1)),
                    _mm256_max_ps(slab(nz, 2), self.t_min),
                );
                let far = _mm256_min_ps(
                    _mm256_min_ps(slab(fx, 0), slab(fy, 1)),
                    _mm256_min_ps(slab(fz, 2), _mm256_set1_ps(t_max)),
                );
                // Sign bits of far - near: the missed boxes, as in `WideNode::intersect`.
                let missed = _mm256_movemask_ps(_mm256_sub_ps(far, near)) as u32;
                let mut dist = [0.0f32; WIDTH];
                _mm256_storeu_ps(dist.as_mut_ptr(), near);
                (dist, missed ^ ((1 << WIDTH) - 1))
            }
        }
    }
}
