//! The inner loops of every traversal, the box test of a wide node and the triangle test of a
//! leaf, in two kernels that give the same answers bit for bit: [`Portable`], plain Rust the
//! compiler vectorises (two SSE halves on baseline x86-64, whatever the target has elsewhere)
//! and whose leaves test one triangle after the other, and, on x86-64 CPUs with AVX2,
//! [`Avx2`]: all eight boxes in one instruction per step and the hit mask in one `movmskps`
//! (the auto-vectorised form gathers it in seven), all the triangles of a leaf at once. Both
//! compute every lane with the same IEEE operations in the same order (Rust never fuses a
//! multiply and an add into an FMA on its own, and neither kernel asks for one), so distances,
//! masks and hits are identical; the traversal around them is compiled for AVX2 too (see
//! `Bvh::cast_fan`).

use super::node::{WIDTH, WideNode};
use crate::raycast::brute::better;
use crate::raycast::ray::Ray;
use crate::raycast::triangle::LeafTriangles;

/// One ray's tests, as the traversal needs them.
pub(super) trait Kernel {
    /// The [`WIDTH`] boxes of a node: entry distances, and the bit mask of the boxes the ray
    /// enters within `[t_min, t_max]` (see [`WideNode::intersect`]).
    fn boxes(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32);

    /// The leaf of `n` triangles from `first`: replaces `(best_t, best_id)` by any hit at
    /// `t >= t_min` that is [`better`].
    fn triangles(
        &self,
        tris: &LeafTriangles,
        first: usize,
        n: usize,
        best_t: &mut f32,
        best_id: &mut u32,
    );
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

impl Kernel for Portable {
    #[inline(always)]
    fn boxes(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32) {
        node.intersect(&self.ray, &self.neg, self.t_min, t_max)
    }

    #[inline(always)]
    fn triangles(
        &self,
        tris: &LeafTriangles,
        first: usize,
        n: usize,
        best_t: &mut f32,
        best_id: &mut u32,
    ) {
        for lane in 0..n {
            let Some(t) = tris.get(first, n, lane).intersect(&self.ray) else {
                continue;
            };
            let id = tris.id(first + lane);
            if t >= self.t_min && better(t, id, *best_t, *best_id) {
                *best_t = t;
                *best_id = id;
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) use avx2::{Avx2, HasAvx2};

#[cfg(target_arch = "x86_64")]
mod avx2 {
    #![allow(unsafe_code)]

    use std::arch::x86_64::{
        __m256, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _mm256_add_ps, _mm256_and_ps,
        _mm256_cmp_ps, _mm256_cvtss_f32, _mm256_div_ps, _mm256_loadu_ps, _mm256_max_ps,
        _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_storeu_ps,
        _mm256_sub_ps, _mm256_xor_ps,
    };

    use super::{Kernel, LeafTriangles, WIDTH, WideNode, better};
    use crate::raycast::ray::Ray;
    use crate::raycast::triangle::{BLOCK, PARALLEL_COS};

    const _: () = assert!(
        WIDTH == 8 && BLOCK == 8,
        "the AVX2 kernel tests eight boxes and eight triangles at once"
    );

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
        d: [__m256; 3],
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
                    d: ray.d.map(|x| _mm256_set1_ps(x)),
                    inv: ray.inv_d.map(|x| _mm256_set1_ps(x)),
                    t_min: _mm256_set1_ps(t_min),
                    neg: ray.neg(),
                }
            }
        }
    }

    impl Kernel for Avx2 {
        /// The operations of [`WideNode::intersect`], lane for lane and in the same order
        /// (`max_ps(a, b)` is `if a > b { a } else { b }` as `fmax` is, and so for min).
        #[inline(always)]
        fn boxes(&self, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32) {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2 (see `new`); the loads and the
            // store read and write `[f32; 8]` arrays, unaligned accesses being allowed.
            unsafe {
                let slab = |plane: &[f32; WIDTH], k: usize| {
                    _mm256_mul_ps(
                        _mm256_sub_ps(_mm256_loadu_ps(plane.as_ptr()), self.o[k]),
                        self.inv[k],
                    )
                };
                let (nx, fx) = node.planes(&self.neg, 0);
                let (ny, fy) = node.planes(&self.neg, 1);
                let (nz, fz) = node.planes(&self.neg, 2);
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

        /// The operations of `Triangle::intersect` (Möller & Trumbore 1997 with the stored
        /// normal), lane for lane and in the same order; `* sign` by ±1 is the same sign flip
        /// as the XOR here, and the division runs for all lanes at once, only once some lane
        /// is hit.
        #[inline(always)]
        fn triangles(
            &self,
            tris: &LeafTriangles,
            first: usize,
            n: usize,
            best_t: &mut f32,
            best_id: &mut u32,
        ) {
            // SAFETY: an `Avx2` exists only on a CPU with AVX2 (see `new`); the loads and the
            // store read and write `[f32; 8]` arrays, unaligned accesses being allowed.
            let (hits, t, t_min) = unsafe {
                // Vector `a` (v0, e1, e2, n) of the leaf's triangles, lane by lane.
                let load = |a: usize| -> [__m256; 3] {
                    std::array::from_fn(|k| _mm256_loadu_ps(tris.row(first, n, 3 * a + k).as_ptr()))
                };
                let dot = |a: &[__m256; 3], b: &[__m256; 3]| {
                    _mm256_add_ps(
                        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
                        _mm256_mul_ps(a[2], b[2]),
                    )
                };
                let cross = |a: &[__m256; 3], b: &[__m256; 3]| {
                    [
                        _mm256_sub_ps(_mm256_mul_ps(a[1], b[2]), _mm256_mul_ps(a[2], b[1])),
                        _mm256_sub_ps(_mm256_mul_ps(a[2], b[0]), _mm256_mul_ps(a[0], b[2])),
                        _mm256_sub_ps(_mm256_mul_ps(a[0], b[1]), _mm256_mul_ps(a[1], b[0])),
                    ]
                };
                let normal = load(3);
                let v0 = load(0);
                let den = dot(&self.d, &normal);
                let c: [__m256; 3] = std::array::from_fn(|k| _mm256_sub_ps(v0[k], self.o[k]));
                let r = cross(&self.d, &c);
                let sign_bit = _mm256_set1_ps(-0.0);
                let abs_den = _mm256_and_ps(den, _mm256_set1_ps(f32::from_bits(0x7fff_ffff)));
                // The sign bit where den < 0: `* sign` flips exactly those lanes.
                let zero = _mm256_set1_ps(0.0);
                let flip = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(den, zero), sign_bit);
                let u = _mm256_xor_ps(_mm256_xor_ps(dot(&load(2), &r), sign_bit), flip);
                let v = _mm256_xor_ps(dot(&load(1), &r), flip);
                let inside = _mm256_and_ps(
                    _mm256_and_ps(
                        _mm256_cmp_ps::<_CMP_GT_OQ>(abs_den, _mm256_set1_ps(PARALLEL_COS)),
                        _mm256_cmp_ps::<_CMP_GE_OQ>(u, zero),
                    ),
                    _mm256_and_ps(
                        _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
                        _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_add_ps(u, v), abs_den),
                    ),
                );
                let hits = _mm256_movemask_ps(inside) as u32 & ((1u32 << n) - 1);
                let mut t = [0.0f32; BLOCK];
                if hits != 0 {
                    _mm256_storeu_ps(t.as_mut_ptr(), _mm256_div_ps(dot(&c, &normal), den));
                }
                (hits, t, _mm256_cvtss_f32(self.t_min))
            };
            let mut rest = hits;
            while rest != 0 {
                let lane = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let id = tris.id(first + lane);
                if t[lane] >= t_min && better(t[lane], id, *best_t, *best_id) {
                    *best_t = t[lane];
                    *best_id = id;
                }
            }
        }
    }
}
