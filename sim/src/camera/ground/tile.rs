//! A generated patch: `SIDE x SIDE` texels, a height field and an albedo, built from texels
//! that surfaces are laid over one by one; crevices end up darkened by how far they lie below
//! the local mean height (a cheap ambient occlusion). Lengths and heights are in texels.

use rayon::prelude::*;

use super::SIDE;
use crate::camera::texture::lerp;

/// Radius of the box the local mean height is taken over, texels.
const CAVITY_RADIUS: usize = 6;

/// The generated patch, row-major, `SIDE` texels per row.
#[derive(Debug, Clone)]
pub(super) struct Tile {
    /// Height, texels.
    pub height: Vec<f32>,
    /// Albedo, sRGB × 255.
    pub albedo: Vec<[u8; 3]>,
}

/// One texel under construction.
#[derive(Debug, Clone, Copy)]
pub(super) struct Texel {
    pub h: f32,
    pub c: [f32; 3],
}

impl Texel {
    /// Puts a surface of height `h` and colour `c` over a share `cover` of the texel, where
    /// it is higher than what is there (blended over half a texel of height).
    pub fn over(&mut self, h: f32, c: [f32; 3], cover: f32) {
        let a = cover * ((h - self.h) * 2.0 + 0.5).clamp(0.0, 1.0);
        if a > 0.0 {
            self.c = [0, 1, 2].map(|k| lerp(self.c[k], c[k], a));
            self.h = lerp(self.h, h.max(self.h), a);
        }
    }
}

pub(super) fn scale(c: [f32; 3], k: f32) -> [f32; 3] {
    c.map(|x| x * k)
}

/// `(edge − d) / width` clamped to [0, 1]: an anti-aliased inside test.
pub(super) fn inside(d: f32, edge: f32, width: f32) -> f32 {
    ((edge - d) / width).clamp(0.0, 1.0)
}

impl Tile {
    /// The finished tile from its texels: crevices are darkened by `cavity` per texel of
    /// depth below the local mean height (down to `floor`), bumps lightened up to `ceiling`.
    pub fn finish(texels: &[Texel], cavity: f32, floor: f32, ceiling: f32) -> Self {
        let height: Vec<f32> = texels.iter().map(|t| t.h).collect();
        let mean = box_mean(&height, CAVITY_RADIUS);
        let albedo = texels
            .iter()
            .zip(&mean)
            .map(|(t, m)| {
                let c = scale(t.c, (1.0 - cavity * (m - t.h)).clamp(floor, ceiling));
                c.map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
            })
            .collect();
        Self { height, albedo }
    }
}

/// Mean of `v` over the `(2r + 1)²` box around every texel, wrapping (two running sums).
fn box_mean(v: &[f32], r: usize) -> Vec<f32> {
    let n = SIDE;
    let pass = |src: &[f32], stride: usize, step: usize| -> Vec<f32> {
        // Line `l` is `src[l * stride + k * step]` for k in 0..n.
        let mut out = vec![0.0; src.len()];
        out.par_chunks_mut(n).enumerate().for_each(|(l, line)| {
            let at = |k: usize| src[l * stride + (k & (n - 1)) * step];
            let mut sum: f32 = (0..=2 * r).map(|k| at(k + n - r)).sum();
            for (k, out) in line.iter_mut().enumerate() {
                *out = sum / (2 * r + 1) as f32;
                sum += at(k + r + 1) - at(k + n - r);
            }
        });
        out
    };
    // Rows into rows, then columns into rows: transposed twice.
    let rows = pass(v, n, 1);
    let t = pass(&rows, 1, n);
    (0..n * n).map(|k| t[(k % n) * n + k / n]).collect()
}
