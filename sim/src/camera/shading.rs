//! Per-pixel shading of the visibility buffer: exact ray-triangle intersection, material,
//! Lambert sun with shadows (times the ground's relief), hemispheric sky ambient, aerial
//! haze, and a sky gradient.

use super::chunks::Chunks;
use super::ground::GroundTexture;
use super::lanes::F4;
use super::prefilter;
use super::raster::{View, dot, sub};
use super::shadow::ShadowMap;
use super::texture::{Surface, TREE_LINE_TOP, albedo, tree_line};
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
    /// The colour of four pixels, columns `u..u + 4` of row `v`, whose samples all see the
    /// sky, where all four look above the tree line (`None` otherwise: then each is
    /// [`Shader::shade`]d). The same bits as `shade` gives each, lane by lane (`F4`); a third
    /// of a frame's shadings in a lane of the vineyard are sky, and their square roots and
    /// division, four at once, cost what one did.
    pub fn sky4(&self, u: f32, v: f32) -> Option<[[f32; 3]; 4]> {
        let view = self.view;
        let splat = F4::splat;
        // `View::ray` and the unit ray's elevation, as in `shade`.
        let xo = (F4::new([u, u + 1.0, u + 2.0, u + 3.0]) - splat(view.cx)) * splat(view.inv_fx);
        let yo = (splat(v) - splat(view.cy)) * splat(view.inv_fy);
        let d = [0, 1, 2].map(|k| {
            splat(view.axes[0][k]) * xo + splat(view.axes[1][k]) * yo + splat(view.axes[2][k])
        });
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let up = d[2] * (splat(1.0) / len);
        // Above the tree line's band of elevations (see `texture::tree_crown`): sky only.
        if !up.gt(splat(TREE_LINE_TOP)).all() {
            return None;
        }
        // `sky`, lane by lane.
        let f = up.max(splat(0.0)).sqrt();
        let c = [0, 1, 2].map(|k| {
            let c = splat(HORIZON[k]) + splat(ZENITH[k] - HORIZON[k]) * f;
            (c * c).to_array()
        });
        Some([0, 1, 2, 3].map(|l| [c[0][l], c[1][l], c[2][l]]))
    }

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::intrinsics::{Intrinsics, camera_from_optical};
    use crate::config::CameraConfig;
    use crate::world::Mesh;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// Four sky pixels at once are the four shaded one by one, bit for bit, at every pitch
    /// from the ground to the zenith; near the tree line the vector path declines.
    #[test]
    fn sky_four_at_once_is_the_sky_one_at_a_time() {
        let chunks = Chunks::build(&Mesh::new(), 1.0);
        let light = Light::new(50.0, 30.0);
        let ground = GroundTexture::new(&light);
        let k = Intrinsics::from_config(&CameraConfig::default());
        let (mut four, mut declined) = (0, 0);
        for pitch_deg in [-40.0f64, -5.0, 0.0, 3.0, 20.0, 60.0, 89.0] {
            let world_from_optical = Isometry3::from_parts(
                Translation3::new(1.0, 2.0, 0.7),
                UnitQuaternion::from_euler_angles(0.0, -pitch_deg.to_radians(), 0.3),
            ) * camera_from_optical();
            let view = View::new(&world_from_optical, &k);
            for filter in [true, false] {
                let shader = Shader {
                    chunks: &chunks,
                    view: &view,
                    light: &light,
                    shadow: None,
                    ground: &ground,
                    filter,
                };
                for v in (0..k.height).step_by(7) {
                    for u in (0..k.width - 3).step_by(5) {
                        let (x, y) = (u as u32 as f32, v as u32 as f32);
                        let Some(lanes) = shader.sky4(x, y) else {
                            declined += 1;
                            continue;
                        };
                        four += 1;
                        for (l, rgb) in lanes.iter().enumerate() {
                            let one = shader.shade(x + l as f32, y, u32::MAX, 0.0).rgb;
                            assert_eq!(
                                rgb.map(f32::to_bits),
                                one.map(f32::to_bits),
                                "pixel ({}, {v}) at pitch {pitch_deg}",
                                u + l
                            );
                        }
                    }
                }
            }
        }
        assert!(
            four > 1000 && declined > 1000,
            "expected both paths taken: {four} quads at once, {declined} declined"
        );
    }
}
