//! A tile's mip map (Williams 1983, "Pyramidal parametrics"), sampled with trilinear
//! filtering: eight texel reads per sample whatever the distance.

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
        let (u, v) = (u * self.per_texel, v * self.per_texel);
        // Texels per footprint, as a mip level.
        let lod = log2(self.per_texel / per_m) - lod_bias;
        let last = self.levels.len() - 1;
        let t = if !(lod > 0.0) {
            self.bilinear(0, u, v)
        } else if lod >= last as f32 {
            unpack(self.levels[last][0])
        } else {
            let l = lod as usize;
            let f = lod - l as f32;
            let k = 1.0 / (1u32 << l) as f32;
            let a = self.bilinear(l, u * k, v * k);
            let b = self.bilinear(l + 1, u * k * 0.5, v * k * 0.5);
            [0, 1, 2, 3].map(|c| a[c] + (b[c] - a[c]) * f)
        };
        (
            [t[0], t[1], t[2]].map(|c| c * (1.0 / 255.0)),
            t[3] * (MAX_RELIEF / 255.0),
        )
    }

    /// Level `l` at `(u, v)` in its texels, bilinear, wrapping: bytes as floats.
    fn bilinear(&self, l: usize, u: f32, v: f32) -> [f32; 4] {
        let level = &self.levels[l];
        let mask = (SIDE >> l) - 1;
        let ((uf, ui), (vf, vi)) = (floor(u - 0.5), floor(v - 0.5));
        let (fu, fv) = (u - 0.5 - uf, v - 0.5 - vf);
        // Two's complement: masking wraps negative indices too.
        let (i0, j0) = (ui as usize & mask, vi as usize & mask);
        let (i1, j1) = ((i0 + 1) & mask, (j0 + 1) & mask);
        let (row0, row1) = (j0 * (mask + 1), j1 * (mask + 1));
        let (a, b) = (unpack(level[row0 + i0]), unpack(level[row0 + i1]));
        let (c, d) = (unpack(level[row1 + i0]), unpack(level[row1 + i1]));
        [0, 1, 2, 3].map(|k| {
            let top = a[k] + (b[k] - a[k]) * fu;
            let bottom = c[k] + (d[k] - c[k]) * fu;
            top + (bottom - top) * fv
        })
    }
}

fn unpack(t: u32) -> [f32; 4] {
    [0, 8, 16, 24].map(|s| ((t >> s) & 0xff) as f32)
}

/// Linear colour and relief to packed texels.
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
