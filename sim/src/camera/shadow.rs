//! Sun shadows: an orthographic depth map of everything but the ground, seen from the sun,
//! rendered once per world with the camera's own rasterizer (Williams 1978), looked up with
//! 2x2 percentage-closer filtering (Reeves et al. 1987).

use rayon::prelude::*;

use super::chunks::Chunks;
use super::raster::{SAMPLES_1, ScreenTri, bin_by_band, dot, rasterize_band};
use super::shading::Light;
use crate::world::Material;

/// Texel size of the map, metres.
const TEXEL_M: f32 = 0.015;
const PER_TEXEL: f32 = 1.0 / TEXEL_M;
/// Largest side of the map, texels.
const MAX_SIDE: usize = 4096;
/// Depth bias towards the sun, metres: keeps lit surfaces from shadowing themselves.
const BIAS_M: f32 = 0.03;

#[derive(Debug, Clone)]
pub(crate) struct ShadowMap {
    /// Light-space axes across the map (u, v) and towards the sun (w).
    u: [f32; 3],
    v: [f32; 3],
    w: [f32; 3],
    origin: [f32; 2],
    width: usize,
    /// The map's width and height in texels, as f32 (converting a usize per lookup costs
    /// several instructions).
    size: [f32; 2],
    /// Largest height towards the sun of any caster over each texel, quantised to u16 over
    /// `[w_min, w_min + 65535 * w_step]` (0: none).
    top: Vec<u16>,
    w_min: f32,
    /// `1 / w_step`.
    per_step: f32,
}

impl ShadowMap {
    pub fn build(chunks: &Chunks, light: &Light) -> Self {
        let w = light.sun;
        let helper = if w[2].abs() < 0.99 {
            [0.0, 0.0, 1.0]
        } else {
            [1.0, 0.0, 0.0]
        };
        let u = normalize(cross(&helper, &w));
        let v = cross(&w, &u);
        let casters: Vec<u32> = (0..chunks.tris.len() as u32)
            .filter(|&i| {
                !matches!(
                    chunks.tris[i as usize].material,
                    Material::Soil | Material::Grass
                )
            })
            .collect();
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for &i in &casters {
            for p in &chunks.tris[i as usize].p {
                let (a, b, c) = (dot(&u, p), dot(&v, p), dot(&w, p));
                lo = [lo[0].min(a), lo[1].min(b), lo[2].min(c)];
                hi = [hi[0].max(a), hi[1].max(b), hi[2].max(c)];
            }
        }
        if casters.is_empty() {
            return Self {
                u,
                v,
                w,
                origin: [0.0; 2],
                width: 0,
                size: [0.0; 2],
                top: Vec::new(),
                w_min: 0.0,
                per_step: 1.0,
            };
        }
        let origin = [lo[0] - 2.0 * TEXEL_M, lo[1] - 2.0 * TEXEL_M];
        let side = |k: usize| (((hi[k] - origin[k]) / TEXEL_M).ceil() as usize + 3).min(MAX_SIDE);
        let (width, height) = (side(0), side(1));
        let tris: Vec<ScreenTri> = casters
            .par_iter()
            .filter_map(|&i| {
                let p = &chunks.tris[i as usize].p;
                ScreenTri::new(
                    p.map(|p| (dot(&u, &p) - origin[0]) / TEXEL_M),
                    p.map(|p| (dot(&v, &p) - origin[1]) / TEXEL_M),
                    p.map(|p| dot(&w, &p)),
                    i,
                    (width, height),
                    0.0,
                )
            })
            .collect();
        const BAND: usize = 32;
        let bins = bin_by_band(&tris, height, BAND);
        let mut heights = vec![f32::NEG_INFINITY; width * height];
        let mut ids = vec![u32::MAX; width * height];
        heights
            .par_chunks_mut(width * BAND)
            .zip(ids.par_chunks_mut(width * BAND))
            .zip(bins.par_iter())
            .enumerate()
            .for_each(|(band, ((q, id), list))| {
                rasterize_band(&tris, list, band * BAND, (width, &SAMPLES_1), q, id);
            });
        drop(ids);
        // Quantised upwards (a caster never moves below its true height) in 1..=65535.
        let w_min = lo[2] - 0.01;
        let w_step = ((hi[2] + 0.01 - w_min) / 65534.0).max(1e-6);
        let top = heights
            .par_iter()
            .map(|&h| {
                if h == f32::NEG_INFINITY {
                    0
                } else {
                    (((h - w_min) / w_step).ceil() as u32 + 1).min(65535) as u16
                }
            })
            .collect();
        Self {
            u,
            v,
            w,
            origin,
            width,
            size: [width as f32, height as f32],
            top,
            w_min,
            per_step: 1.0 / w_step,
        }
    }

    /// Fraction of the sun seen from world point `p`, in [0, 1].
    #[inline(always)]
    pub fn lit(&self, p: &[f32; 3]) -> f32 {
        let x = (dot(&self.u, p) - self.origin[0]) * PER_TEXEL - 0.5;
        let y = (dot(&self.v, p) - self.origin[1]) * PER_TEXEL - 0.5;
        if x < 0.0 || y < 0.0 {
            return 1.0;
        }
        // Non-negative here: truncation is the floor.
        let (xi, yi) = (x as i32, y as i32);
        let (x0, y0) = (xi as f32, yi as f32);
        if y0 < 0.0 || x0 + 1.0 >= self.size[0] || y0 + 1.0 >= self.size[1] {
            return 1.0;
        }
        let (fx, fy) = (x - x0, y - y0);
        let k = yi as usize * self.width + xi as usize;
        // The receiver's height in the same quantisation.
        let h = (dot(&self.w, p) + BIAS_M - self.w_min) * self.per_step + 1.0;
        let lit = |i: usize| if f32::from(self.top[i]) > h { 0.0 } else { 1.0 };
        let a = lit(k) * (1.0 - fx) + lit(k + 1) * fx;
        let b = lit(k + self.width) * (1.0 - fx) + lit(k + self.width + 1) * fx;
        a * (1.0 - fy) + b * fy
    }
}

fn cross(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: [f32; 3]) -> [f32; 3] {
    let n = dot(&a, &a).sqrt();
    a.map(|c| c / n)
}
