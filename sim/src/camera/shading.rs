//! Per-pixel shading of the visibility buffer: exact ray-triangle intersection, material,
//! Lambert sun with shadows (times the ground's relief), hemispheric sky ambient, aerial
//! haze, and a sky gradient.

use super::chunks::Chunks;
use super::ground::GroundTexture;
use super::prefilter;
use super::raster::{View, dot, sub};
use super::shadow::ShadowMap;
use super::texture::{Surface, albedo, tree_line};
use crate::world::Material;

/// Sun and sky light, linear RGB.
#[derive(Debug, Clone)]
pub(crate) struct Light {
    /// Unit vector towards the sun, world frame.
    pub sun: [f32; 3],
    sun_rgb: [f32; 3],
    sky_rgb: [f32; 3],
}

impl Light {
    pub fn new(elevation_deg: f64, azimuth_deg: f64) -> Self {
        let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        Self {
            sun: [
                (e.cos() * a.cos()) as f32,
                (e.cos() * a.sin()) as f32,
                e.sin() as f32,
            ],
            sun_rgb: [1.25, 1.20, 1.08],
            sky_rgb: [0.36, 0.42, 0.52],
        }
    }
}

/// Sky colours (sRGB) at the horizon and the zenith.
const HORIZON: [f32; 3] = [0.80, 0.85, 0.91];
const ZENITH: [f32; 3] = [0.33, 0.53, 0.84];
/// Distance over which haze reaches 63 % (metres).
const HAZE_M: f32 = 180.0;

/// One pixel's colour (linear RGB), optical-axis depth (0: no surface) and the cosine of
/// the angle between the ray and the surface normal.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shaded {
    pub rgb: [f32; 3],
    pub depth: f32,
    pub cos_incidence: f32,
}

#[derive(Debug)]
pub(crate) struct Shader<'a> {
    pub chunks: &'a Chunks,
    pub view: &'a View,
    pub light: &'a Light,
    pub shadow: Option<&'a ShadowMap>,
    pub ground: &'a GroundTexture,
    /// Band-limit the materials to the pixel footprint (`prefilter`).
    pub filter: bool,
}

fn sq(c: [f32; 3]) -> [f32; 3] {
    c.map(|x| x * x)
}

impl Shader<'_> {
    /// The surface `id` (`u32::MAX`: none) seen through image point `(x, y)` (pixel
    /// coordinates; integers are pixel centres); `inv_z` is the rasterizer's 1 / z there, the
    /// fallback when the ray grazes the surface's plane.
    pub fn shade(&self, x: f32, y: f32, id: u32, inv_z: f32) -> Shaded {
        let d = self.view.ray(x, y);
        let len = dot(&d, &d).sqrt();
        let inv_len = 1.0 / len;
        if id == u32::MAX {
            let unit = d.map(|x| x * inv_len);
            // Far away: mostly the haze colour.
            let hazy = |c: [f32; 3]| {
                let t = sq(c);
                let h = sq(HORIZON);
                [0, 1, 2].map(|k| t[k] + (h[k] - t[k]) * 0.45)
            };
            let rgb = if self.filter {
                // The crown line box-filtered over the pixel (about 1 / fy of elevation).
                match prefilter::tree_line(&unit, self.view.inv_fy) {
                    Some((c, cover)) if cover < 1.0 => {
                        let (t, s) = (hazy(c), sky(unit[2]));
                        [0, 1, 2].map(|k| s[k] + (t[k] - s[k]) * cover)
                    }
                    Some((c, _)) => hazy(c),
                    None => sky(unit[2]),
                }
            } else {
                tree_line(&unit).map_or_else(|| sky(unit[2]), hazy)
            };
            return Shaded {
                rgb,
                depth: 0.0,
                cos_incidence: 0.0,
            };
        }
        let tri = &self.chunks.tris[id as usize];
        let a = tri.p[0];
        let o = self.view.origin;
        // The ray meets the triangle's plane at `o + depth d`; with `d` scaled to optical
        // z = 1, `depth` is the optical-axis depth. The barycentric weights come from the
        // triangle's precomputed weight gradients.
        let mut n = tri.n;
        let facing = dot(&n, &d);
        let ao = sub(&a, &o);
        let depth = dot(&n, &ao) / facing;
        // Seen edge-on, the plane intersection is unreliable: fall back to the raster depth.
        let depth = if depth.is_finite() && depth > 0.0 {
            depth
        } else {
            1.0 / inv_z
        };
        // `g · (o + depth d - a)`, arranged so that only the last step waits for the division.
        let [g1, g2] = &tri.g;
        let w1 = (depth * dot(g1, &d) - dot(g1, &ao)).clamp(0.0, 1.0);
        let w2 = (depth * dot(g2, &d) - dot(g2, &ao)).clamp(0.0, 1.0 - w1);
        let w = [1.0 - w1 - w2, w1, w2];
        let back = facing > 0.0;
        if back {
            n = n.map(|x| -x);
        }
        let cos_incidence = (facing.abs() * inv_len).min(1.0);
        let t = [0, 1, 2].map(|k| w[0] * tri.t[0][k] + w[1] * tri.t[1][k] + w[2] * tri.t[2][k]);
        let surface = Surface {
            material: tri.material,
            t,
            w,
            k: tri.k,
            back,
            // Geometric mean of the footprint's axes: at grazing angles it is stretched in
            // one direction only, and blurring both would wash the ground out.
            per_m: self.view.fx * cos_incidence.max(0.05).sqrt() / (depth * len),
            filtered: self.filter,
        };
        let (base, relief) = albedo(&surface, self.ground);
        let point = [0, 1, 2].map(|k| o[k] + depth * d[k]);
        let l = &self.light;
        let mut ndl = dot(&n, &l.sun);
        if tri.material == Material::Leaf && ndl < 0.0 {
            // Sunlight through the leaf from behind.
            ndl *= -0.35;
        }
        let sun = if ndl > 0.0 {
            ndl * relief * self.shadow.map_or(1.0, |s| s.lit(&point))
        } else {
            0.0
        };
        let sky = 0.6 + 0.4 * n[2];
        let mut rgb = [0, 1, 2].map(|k| base[k] * (l.sun_rgb[k] * sun + l.sky_rgb[k] * sky));
        // 1 - exp(-d / HAZE_M) to first order, without a libm call.
        let range = depth * len;
        let haze = range / (range + HAZE_M);
        let horizon = sq(HORIZON);
        for k in 0..3 {
            rgb[k] += (horizon[k] - rgb[k]) * haze;
        }
        Shaded {
            rgb,
            depth,
            cos_incidence,
        }
    }
}

impl Shader<'_> {
    /// Depth and incidence cosine of triangle `id`'s plane along the ray through `(x, y)`;
    /// `fallback` where the ray grazes the plane.
    pub fn depth_at(&self, x: f32, y: f32, id: u32, fallback: (f32, f32)) -> (f32, f32) {
        let d = self.view.ray(x, y);
        let tri = &self.chunks.tris[id as usize];
        let facing = dot(&tri.n, &d);
        let depth = dot(&tri.n, &sub(&tri.p[0], &self.view.origin)) / facing;
        if depth.is_finite() && depth > 0.0 {
            let len = dot(&d, &d).sqrt();
            (depth, (facing.abs() * (1.0 / len)).min(1.0))
        } else {
            fallback
        }
    }
}

/// Sky radiance (linear) in a direction of elevation sine `up`.
fn sky(up: f32) -> [f32; 3] {
    let f = up.max(0.0).sqrt();
    let c = [0, 1, 2].map(|k| HORIZON[k] + (ZENITH[k] - HORIZON[k]) * f);
    sq(c)
}
