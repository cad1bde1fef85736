//! Four `f32` lanes that compute exactly what Rust's scalar operations compute lane by lane,
//! NaN included: [`F4::max`] and [`F4::min`] are `f32::max` and `f32::min` (a NaN operand
//! yields the other), [`F4::clamp`] is `f32::clamp` (NaN passes through), comparisons are
//! false on NaN; division and square root are IEEE's, as in scalar code. On x86-64 they are
//! SSE2 instructions (every x86-64 CPU has them); elsewhere the same operations one lane
//! after the other. The rasterizer's per-row set-up, where the compiler left most of the
//! scalar code scalar, and the shading of four sky or ground pixels at once run on them.
//!
//! Signed zeros: `f32::max(0.0, -0.0)` may return either; these do not promise which one
//! either (no caller can tell: they only add to, compare or truncate the result).

/// Four `f32` lanes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct F4(imp::V);

/// A lane mask from a comparison.
#[derive(Debug, Clone, Copy)]
pub(crate) struct M4(imp::V);

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod imp {
    //! SSE2, part of the x86-64 baseline (the `cfg` checks the build enables it). Every
    //! `unsafe` block below only calls an SSE or SSE2 intrinsic on values (no pointers):
    //! sound wherever the build runs.
    #![allow(unsafe_code)]
    use std::arch::x86_64::*;

    pub(super) type V = __m128;

    pub(super) fn from_array(a: [f32; 4]) -> V {
        unsafe { _mm_setr_ps(a[0], a[1], a[2], a[3]) }
    }

    pub(super) fn to_array(v: V) -> [f32; 4] {
        // SAFETY: `__m128` and `[f32; 4]` have the same size, and every bit pattern is valid
        // for both.
        unsafe { std::mem::transmute::<V, [f32; 4]>(v) }
    }

    pub(super) fn splat(x: f32) -> V {
        unsafe { _mm_set1_ps(x) }
    }

    pub(super) fn add(a: V, b: V) -> V {
        unsafe { _mm_add_ps(a, b) }
    }

    pub(super) fn sub(a: V, b: V) -> V {
        unsafe { _mm_sub_ps(a, b) }
    }

    pub(super) fn mul(a: V, b: V) -> V {
        unsafe { _mm_mul_ps(a, b) }
    }

    /// `b` where `m`, else `a`.
    pub(super) fn select(m: V, b: V, a: V) -> V {
        unsafe { _mm_or_ps(_mm_and_ps(m, b), _mm_andnot_ps(m, a)) }
    }

    /// `maxps(a, b)` is `a > b ? a : b`: `b` when either is NaN, so only a NaN `b` needs
    /// mending (to `a`, as `f32::max`).
    pub(super) fn max(a: V, b: V) -> V {
        unsafe { select(_mm_cmpunord_ps(b, b), a, _mm_max_ps(a, b)) }
    }

    /// As [`max`], `a < b ? a : b`.
    pub(super) fn min(a: V, b: V) -> V {
        unsafe { select(_mm_cmpunord_ps(b, b), a, _mm_min_ps(a, b)) }
    }

    /// `f32::clamp`: `x < lo ? lo : x` is `maxps(lo, x)`, then `x > hi ? hi : x` is
    /// `minps(hi, x)`; a NaN `x` fails both comparisons and passes through.
    pub(super) fn clamp(x: V, lo: V, hi: V) -> V {
        unsafe { _mm_min_ps(hi, _mm_max_ps(lo, x)) }
    }

    pub(super) fn div(a: V, b: V) -> V {
        unsafe { _mm_div_ps(a, b) }
    }

    pub(super) fn sqrt(a: V) -> V {
        unsafe { _mm_sqrt_ps(a) }
    }

    pub(super) fn ge(a: V, b: V) -> V {
        unsafe { _mm_cmpge_ps(a, b) }
    }

    pub(super) fn gt(a: V, b: V) -> V {
        unsafe { _mm_cmpgt_ps(a, b) }
    }

    pub(super) fn lt(a: V, b: V) -> V {
        unsafe { _mm_cmplt_ps(a, b) }
    }

    /// Clears the sign bits.
    pub(super) fn abs(a: V) -> V {
        unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), a) }
    }

    pub(super) fn le(a: V, b: V) -> V {
        unsafe { _mm_cmple_ps(a, b) }
    }

    pub(super) fn and(a: V, b: V) -> V {
        unsafe { _mm_and_ps(a, b) }
    }

    pub(super) fn all(m: V) -> bool {
        unsafe { _mm_movemask_ps(m) == 0b1111 }
    }

    /// The largest lane that is not NaN (`-inf` if none).
    pub(super) fn max_lane(v: V) -> f32 {
        let v = unsafe { select(_mm_cmpord_ps(v, v), v, _mm_set1_ps(f32::NEG_INFINITY)) };
        let v = unsafe { _mm_max_ps(v, _mm_movehl_ps(v, v)) };
        let v = unsafe { _mm_max_ps(v, _mm_shuffle_ps::<0b01>(v, v)) };
        unsafe { _mm_cvtss_f32(v) }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
mod imp {
    //! The same, a lane at a time; a mask lane is all ones (as a float: NaN) or zero.

    pub(super) type V = [f32; 4];

    fn mask(b: bool) -> f32 {
        f32::from_bits(if b { u32::MAX } else { 0 })
    }

    fn on(m: f32) -> bool {
        m.to_bits() != 0
    }

    pub(super) fn from_array(a: [f32; 4]) -> V {
        a
    }

    pub(super) fn to_array(v: V) -> [f32; 4] {
        v
    }

    pub(super) fn splat(x: f32) -> V {
        [x; 4]
    }

    fn zip(a: V, b: V, f: impl Fn(f32, f32) -> f32) -> V {
        [0, 1, 2, 3].map(|k| f(a[k], b[k]))
    }

    pub(super) fn add(a: V, b: V) -> V {
        zip(a, b, |a, b| a + b)
    }

    pub(super) fn sub(a: V, b: V) -> V {
        zip(a, b, |a, b| a - b)
    }

    pub(super) fn mul(a: V, b: V) -> V {
        zip(a, b, |a, b| a * b)
    }

    pub(super) fn select(m: V, b: V, a: V) -> V {
        [0, 1, 2, 3].map(|k| if on(m[k]) { b[k] } else { a[k] })
    }

    pub(super) fn max(a: V, b: V) -> V {
        zip(a, b, f32::max)
    }

    pub(super) fn min(a: V, b: V) -> V {
        zip(a, b, f32::min)
    }

    pub(super) fn clamp(x: V, lo: V, hi: V) -> V {
        [0, 1, 2, 3].map(|k| x[k].clamp(lo[k], hi[k]))
    }

    pub(super) fn div(a: V, b: V) -> V {
        zip(a, b, |a, b| a / b)
    }

    pub(super) fn sqrt(a: V) -> V {
        a.map(f32::sqrt)
    }

    pub(super) fn ge(a: V, b: V) -> V {
        zip(a, b, |a, b| mask(a >= b))
    }

    pub(super) fn gt(a: V, b: V) -> V {
        zip(a, b, |a, b| mask(a > b))
    }

    pub(super) fn lt(a: V, b: V) -> V {
        zip(a, b, |a, b| mask(a < b))
    }

    pub(super) fn abs(a: V) -> V {
        a.map(f32::abs)
    }

    pub(super) fn le(a: V, b: V) -> V {
        zip(a, b, |a, b| mask(a <= b))
    }

    pub(super) fn and(a: V, b: V) -> V {
        zip(a, b, |a, b| f32::from_bits(a.to_bits() & b.to_bits()))
    }

    pub(super) fn all(m: V) -> bool {
        m.into_iter().all(on)
    }

    pub(super) fn max_lane(v: V) -> f32 {
        v.into_iter().fold(f32::NEG_INFINITY, f32::max)
    }
}

impl F4 {
    #[inline(always)]
    pub fn new(a: [f32; 4]) -> Self {
        Self(imp::from_array(a))
    }

    #[inline(always)]
    pub fn splat(x: f32) -> Self {
        Self(imp::splat(x))
    }

    #[inline(always)]
    pub fn to_array(self) -> [f32; 4] {
        imp::to_array(self.0)
    }

    /// `f32::max` lane by lane.
    #[inline(always)]
    pub fn max(self, other: Self) -> Self {
        Self(imp::max(self.0, other.0))
    }

    /// `f32::min` lane by lane.
    #[inline(always)]
    pub fn min(self, other: Self) -> Self {
        Self(imp::min(self.0, other.0))
    }

    /// `f32::clamp` lane by lane (`lo <= hi` in every lane).
    #[inline(always)]
    pub fn clamp(self, lo: Self, hi: Self) -> Self {
        Self(imp::clamp(self.0, lo.0, hi.0))
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        Self(imp::sqrt(self.0))
    }

    #[inline(always)]
    pub fn ge(self, other: Self) -> M4 {
        M4(imp::ge(self.0, other.0))
    }

    #[inline(always)]
    pub fn gt(self, other: Self) -> M4 {
        M4(imp::gt(self.0, other.0))
    }

    #[inline(always)]
    pub fn lt(self, other: Self) -> M4 {
        M4(imp::lt(self.0, other.0))
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Self(imp::abs(self.0))
    }

    /// `f32::is_finite` lane by lane (`abs < inf`).
    #[inline(always)]
    pub fn is_finite(self) -> M4 {
        self.abs().lt(Self::splat(f32::INFINITY))
    }

    #[inline(always)]
    pub fn le(self, other: Self) -> M4 {
        M4(imp::le(self.0, other.0))
    }

    /// The lanes of `self` where `m` holds, of `other` elsewhere.
    #[inline(always)]
    pub fn select(m: M4, yes: Self, no: Self) -> Self {
        Self(imp::select(m.0, yes.0, no.0))
    }

    /// `fold(-inf, f32::max)` over the lanes: the largest that is not NaN.
    #[inline(always)]
    pub fn max_lane(self) -> f32 {
        imp::max_lane(self.0)
    }
}

impl M4 {
    /// Whether every lane holds.
    #[inline(always)]
    pub fn all(self) -> bool {
        imp::all(self.0)
    }
}

/// `impl std::ops::$op for $lanes` through `imp::$f`, lane by lane.
macro_rules! lane_op {
    ($lanes:ident, $op:ident, $method:ident, $f:ident) => {
        impl std::ops::$op for $lanes {
            type Output = Self;

            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                Self(imp::$f(self.0, other.0))
            }
        }
    };
}

lane_op!(M4, BitAnd, bitand, and);
lane_op!(F4, Add, add, add);
lane_op!(F4, Sub, sub, sub);
lane_op!(F4, Mul, mul, mul);
lane_op!(F4, Div, div, div);

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Lane by lane, the same bits as the scalar operations (both zeros compare equal: which
    /// one `max` and `min` return is unspecified; so do any two NaNs), on random values mixed
    /// with NaN, infinities and zeros.
    #[test]
    fn lanes_compute_what_scalar_rust_computes() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let special = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e30,
        ];
        let draw = |rng: &mut rand_chacha::ChaCha8Rng| {
            [0; 4].map(|_| {
                if rng.random_bool(0.3) {
                    special[rng.random_range(0..special.len())]
                } else {
                    rng.random_range(-10.0..10.0f32)
                }
            })
        };
        let same = |a: f32, b: f32| {
            a.to_bits() == b.to_bits() || (a == 0.0 && b == 0.0) || (a.is_nan() && b.is_nan())
        };
        for _ in 0..20_000 {
            let (a, b) = (draw(&mut rng), draw(&mut rng));
            let (lo, hi) = {
                let (x, y) = (draw(&mut rng), draw(&mut rng));
                let fix = |v: f32| if v.is_nan() { 0.0 } else { v };
                (
                    [0, 1, 2, 3].map(|k| fix(x[k]).min(fix(y[k]))),
                    [0, 1, 2, 3].map(|k| fix(x[k]).max(fix(y[k]))),
                )
            };
            let (va, vb) = (F4::new(a), F4::new(b));
            let max = va.max(vb).to_array();
            let min = va.min(vb).to_array();
            let clamp = va.clamp(F4::new(lo), F4::new(hi)).to_array();
            let sum = (va + vb).to_array();
            let diff = (va - vb).to_array();
            let prod = (va * vb).to_array();
            let quot = (va / vb).to_array();
            let root = va.sqrt().to_array();
            let strict = F4::select(va.gt(vb), va, vb).to_array();
            let less = F4::select(va.lt(vb), va, vb).to_array();
            let abs = va.abs().to_array();
            let finite = F4::select(va.is_finite(), va, vb).to_array();
            let picked = F4::select(va.ge(vb) & va.le(F4::splat(5.0)), va, vb).to_array();
            assert_eq!(
                va.ge(vb).all(),
                (0..4).all(|k| a[k] >= b[k]),
                "all lanes of {a:?} >= {b:?}"
            );
            for k in 0..4 {
                let case = format!("lane {k}: a {}, b {}", a[k], b[k]);
                assert!(same(max[k], a[k].max(b[k])), "max, {case}: {}", max[k]);
                assert!(same(min[k], a[k].min(b[k])), "min, {case}: {}", min[k]);
                let c = a[k].clamp(lo[k], hi[k]);
                assert!(same(clamp[k], c), "clamp, {case}: {} against {c}", clamp[k]);
                assert!(same(sum[k], a[k] + b[k]), "add, {case}");
                assert!(same(diff[k], a[k] - b[k]), "sub, {case}");
                assert!(same(prod[k], a[k] * b[k]), "mul, {case}");
                assert!(same(quot[k], a[k] / b[k]), "div, {case}");
                assert!(same(root[k], a[k].sqrt()), "sqrt, {case}");
                let p = if a[k] > b[k] { a[k] } else { b[k] };
                assert!(same(strict[k], p), "gt, {case}");
                let p = if a[k] < b[k] { a[k] } else { b[k] };
                assert!(same(less[k], p), "lt, {case}");
                assert!(same(abs[k], a[k].abs()), "abs, {case}");
                let f = if a[k].is_finite() { a[k] } else { b[k] };
                assert!(same(finite[k], f), "is_finite, {case}");
                let p = if a[k] >= b[k] && a[k] <= 5.0 {
                    a[k]
                } else {
                    b[k]
                };
                assert!(same(picked[k], p), "select, {case}");
            }
            let m = va.max_lane();
            let expected = a.into_iter().fold(f32::NEG_INFINITY, f32::max);
            assert!(
                same(m, expected),
                "max_lane of {a:?}: {m}, expected {expected}"
            );
        }
    }
}
