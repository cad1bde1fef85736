//! A tile's mip map (Williams 1983, "Pyramidal parametrics"), sampled with trilinear
//! filtering: eight texel reads per sample whatever the distance, weighted in fixed point
//! as packed bytes (two multiplies per texel).

use super::{MAX_RELIEF, SIDE};
use crate::camera::texture::floor;

#[derive(Debug, Clone)]
pub(super) struct Mips {
    /// Finest first; level `k` is `SIDE >> k` texels a side, row-major. A texel packs the
    /// sRGB albedo × 255 in bytes 0–2 and relief × 255 / `MAX_RELIEF` in byte 3.
    levels: Vec<Vec<u32>>,
    per_texel: f32,
}

impl Mips {
    /// From a tile's albedo (sRGB × 255) and relief, with texels of `texel_m`.
    pub fn new(albedo: &[[u8; 3]], relief: &[f32], texel_m: f32) -> Self {
        let linear = |c: u8| (f32::from(c) * (1.0 / 255.0)).powi(2);
        let mut level: Vec<[f32; 4]> = albedo
            .iter()
            .zip(relief)
            .map(|(c, &r)| [linear(c[0]), linear(c[1]), linear(c[2]), r])
            .collect();
        let mut levels = vec![pack(&level)];
        let mut side = SIDE;
        while side > 1 {
            // Each coarser texel averages four (colour in linear terms).
            let half = side / 2;
            level = (0..half * half)
                .map(|k| {
                    let (i, j) = (2 * (k % half), 2 * (k / half));
                    let at = |di: usize, dj: usize| level[(j + dj) * side + i + di];
                    let q = [at(0, 0), at(1, 0), at(0, 1), at(1, 1)];
                    [0, 1, 2, 3].map(|c| 0.25 * (q[0][c] + q[1][c] + q[2][c] + q[3][c]))
                })
                .collect();
            levels.push(pack(&level));
            side = half;
        }
        Self {
            levels,
            per_texel: 1.0 / texel_m,
        }
    }

    /// Albedo (sRGB) and relief at `(u, v)` metres in the tile's frame, seen with `per_m`
    /// pixel footprints per metre (`lod_bias` mip levels sharper than that footprint).
    pub fn sample(&self, u: f32, v: f32, per_m: f32, lod_bias: f32) -> ([f32; 3], f32) {
        // Finest-level texels, in fixed point with 8 fractional bits.
        let fixed = |x: f32| floor(x * self.per_texel * 256.0).1;
        let (u, v) = (fixed(u), fixed(v));
        // Texels per footprint, as a mip level.
        let lod = log2(self.per_texel / per_m) - lod_bias;
        // Conversions through i32 (exact here): to or from usize each takes several
        // instructions.
        let last = (self.levels.len() - 1) as i32;
        let t = if lod.is_nan() || lod <= 0.0 {
            self.bilinear(0, u, v)
        } else if lod >= last as f32 {
            self.bilinear(last as usize, u, v)
        } else {
            let l = lod as i32;
            let f = ((lod - l as f32) * 256.0) as i32 as u32;
            let l = l as usize;
            let (a, b) = (self.bilinear(l, u, v), self.bilinear(l + 1, u, v));
            // Back to bytes, then weighted as the texels were.
            let byte = |x: u32| (x >> 8) & 0x00ff_00ff;
            [0, 1].map(|k| byte(a[k]) * (256 - f) + byte(b[k]) * f)
        };
        let [rb, ga] = t;
        let scale = 1.0 / 65280.0;
        (
            [rb & 0xffff, ga & 0xffff, rb >> 16].map(|x| x as f32 * scale),
            (ga >> 16) as f32 * (scale * MAX_RELIEF),
        )
    }

    /// Level `l` at finest-level fixed-point `(u, v)`, bilinear, wrapping: the four bytes
    /// weighted in two words (see [`split`]).
    fn bilinear(&self, l: usize, u: i32, v: i32) -> [u32; 2] {
        let level = &self.levels[l];
        let side = SIDE >> l;
        let mask = side - 1;
        // This level's texel centres are at half-integers.
        let (u, v) = ((u >> l) - 128, (v >> l) - 128);
        // Weights in 1/256, adding up to exactly 256.
        let (wu, wv) = ((u & 255) as u32, (v & 255) as u32);
        let w11 = (wu * wv) >> 8;
        let w = [256 + w11 - wu - wv, wu - w11, wv - w11, w11];
        // Two's complement: masking wraps negative indices too.
        let (i0, j0) = ((u >> 8) as usize & mask, (v >> 8) as usize & mask);
        let (i1, j1) = ((i0 + 1) & mask, (j0 + 1) & mask);
        let (row0, row1) = (j0 * side, j1 * side);
        let taps = [
            level[row0 + i0],
            level[row0 + i1],
            level[row1 + i0],
            level[row1 + i1],
        ];
        // The weights add up to 256, so no byte's sum spills into the next.
        taps.iter().zip(w).fold([0, 0], |[rb, ga], (&t, w)| {
            let [x, y] = split(t, w);
            [rb + x, ga + y]
        })
    }
}

/// A packed texel's bytes times `w` (at most 256), as two words of two 16-bit lanes:
/// bytes 0 and 2 in the first, 1 and 3 in the second (one multiply each; "SIMD within a
/// register").
fn split(t: u32, w: u32) -> [u32; 2] {
    [(t & 0x00ff_00ff) * w, ((t >> 8) & 0x00ff_00ff) * w]
}

/// A row-major level, linear colour and relief, to packed texels.
fn pack(level: &[[f32; 4]]) -> Vec<u32> {
    let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u32;
    level
        .iter()
        .map(|t| {
            byte(t[0].sqrt())
                | byte(t[1].sqrt()) << 8
                | byte(t[2].sqrt()) << 16
                | byte(t[3] / MAX_RELIEF) << 24
        })
        .collect()
}

/// `log2(x)` for positive finite `x`, from its exponent and a quadratic in its mantissa
/// (within 0.01; no libm call).
fn log2(x: f32) -> f32 {
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000) - 1.0;
    e as f32 + m * (1.3465 - 0.3465 * m)
}
