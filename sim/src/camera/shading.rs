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
    /// Linear colour shown where no surface is seen, in place of the sky and tree line.
    pub background: Option<[f32; 3]>,
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
            if let Some(rgb) = self.background {
                return Shaded {
                    rgb,
                    depth: 0.0,
                    cos_incidence: 0.0,
                };
            }
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
    /// [`Shader::shade`]d). The same bits as `shade` gives each, lane by lane (`F4`): a third
    /// of a frame's shadings in a lane of the vineyard are sky, and here one instruction
    /// takes each of their square roots and divisions for four pixels.
    pub fn sky4(&self, u: f32, v: f32) -> Option<[[f32; 3]; 4]> {
        if let Some(rgb) = self.background {
            return Some([rgb; 4]);
        }
        let splat = F4::splat;
        // The rays and their unit vectors' elevation, as in `shade`.
        let d = self.rays4(u, v);
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

    /// Four pixels, columns `u..u + 4` of row `v`, whose samples all see triangle `id`, when it
    /// is ground (soil or grass; `None` otherwise: then each is [`Shader::shade`]d), with
    /// the pixels' mean 1 / z `inv_z`. The same bits as `shade` gives each: the ray, the
    /// plane, the footprint, the light and the haze lane by lane (`F4`), the texture and the
    /// shadow map looked up for each. Nearly half of a frame's shadings are ground, and a
    /// near triangle of it covers many pixels.
    pub fn ground4(&self, u: f32, v: f32, id: u32, inv_z: [f32; 4]) -> Option<[Shaded; 4]> {
        let tri = &self.chunks.tris[id as usize];
        if !matches!(tri.material, Material::Soil | Material::Grass) {
            return None;
        }
        let view = self.view;
        let splat = F4::splat;
        let (zero, one) = (splat(0.0), splat(1.0));
        let d = self.rays4(u, v);
        let dot = |a: &[f32; 3], b: &[F4; 3]| {
            splat(a[0]) * b[0] + splat(a[1]) * b[1] + splat(a[2]) * b[2]
        };
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let inv_len = one / len;
        // As in `shade`: the plane along each ray, the raster's depth where it grazes it.
        let ao = sub(&tri.p[0], &view.origin);
        let facing = dot(&tri.n, &d);
        let depth = splat(super::raster::dot(&tri.n, &ao)) / facing;
        let depth = F4::select(
            depth.is_finite() & depth.gt(zero),
            depth,
            one / F4::new(inv_z),
        );
        let [g1, g2] = &tri.g;
        let w1 = (depth * dot(g1, &d) - splat(super::raster::dot(g1, &ao))).clamp(zero, one);
        let w2 = (depth * dot(g2, &d) - splat(super::raster::dot(g2, &ao))).clamp(zero, one - w1);
        let w = [one - w1 - w2, w1, w2];
        let back = facing.gt(zero);
        let n = tri.n.map(|c| F4::select(back, splat(-c), splat(c)));
        let cos_incidence = (facing.abs() * inv_len).min(one);
        let t = [0, 1, 2].map(|k| {
            (w[0] * splat(tri.t[0][k]) + w[1] * splat(tri.t[1][k]) + w[2] * splat(tri.t[2][k]))
                .to_array()
        });
        let per_m =
            (splat(view.fx) * cos_incidence.max(splat(0.05)).sqrt() / (depth * len)).to_array();
        let point = [0, 1, 2].map(|k| (splat(view.origin[k]) + depth * d[k]).to_array());
        // The texture and the shadow map, pixel by pixel.
        let (mut base, mut relief, mut lit) = ([[0.0f32; 4]; 3], [0.0f32; 4], [1.0f32; 4]);
        for l in 0..4 {
            let (c, r) = self
                .ground
                .sample(tri.material, [t[0][l], t[1][l], t[2][l]], per_m[l]);
            for k in 0..3 {
                base[k][l] = c[k] * c[k];
            }
            relief[l] = r;
            if let Some(shadow) = self.shadow {
                lit[l] = shadow.lit(&[point[0][l], point[1][l], point[2][l]]);
            }
        }
        let light = self.light;
        let ndl =
            n[0] * splat(light.sun[0]) + n[1] * splat(light.sun[1]) + n[2] * splat(light.sun[2]);
        let sun = F4::select(ndl.gt(zero), ndl * F4::new(relief) * F4::new(lit), zero);
        let sky = splat(0.6) + splat(0.4) * n[2];
        let range = depth * len;
        let haze = range / (range + splat(HAZE_M));
        let horizon = sq(HORIZON);
        let rgb = [0, 1, 2].map(|k| {
            let c =
                F4::new(base[k]) * (splat(light.sun_rgb[k]) * sun + splat(light.sky_rgb[k]) * sky);
            (c + (splat(horizon[k]) - c) * haze).to_array()
        });
        let (depth, cos_incidence) = (depth.to_array(), cos_incidence.to_array());
        Some([0, 1, 2, 3].map(|l| Shaded {
            rgb: [rgb[0][l], rgb[1][l], rgb[2][l]],
            depth: depth[l],
            cos_incidence: cos_incidence[l],
        }))
    }

    /// `View::ray` through pixels `(u + l, v)`, lane `l`.
    fn rays4(&self, u: f32, v: f32) -> [F4; 3] {
        let view = self.view;
        let splat = F4::splat;
        let xo = (F4::new([u, u + 1.0, u + 2.0, u + 3.0]) - splat(view.cx)) * splat(view.inv_fx);
        let yo = (splat(v) - splat(view.cy)) * splat(view.inv_fy);
        [0, 1, 2].map(|k| {
            splat(view.axes[0][k]) * xo + splat(view.axes[1][k]) * yo + splat(view.axes[2][k])
        })
    }

    /// The depth and incidence cosine [`Shader::shade`] gives surface `id` (`u32::MAX`:
    /// none, 0 and 0) through `(x, y)`, bit for bit, without its colour: the same
    /// operations in the same order.
    pub fn depth_only(&self, x: f32, y: f32, id: u32, inv_z: f32) -> (f32, f32) {
        if id == u32::MAX {
            return (0.0, 0.0);
        }
        let d = self.view.ray(x, y);
        let len = dot(&d, &d).sqrt();
        let inv_len = 1.0 / len;
        let tri = &self.chunks.tris[id as usize];
        let facing = dot(&tri.n, &d);
        let ao = sub(&tri.p[0], &self.view.origin);
        let depth = dot(&tri.n, &ao) / facing;
        let depth = if depth.is_finite() && depth > 0.0 {
            depth
        } else {
            1.0 / inv_z
        };
        (depth, (facing.abs() * inv_len).min(1.0))
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
                    background: None,
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

    /// Four pixels of one ground triangle at once are the four shaded one by one, bit for
    /// bit: every 50th ground triangle of the default world (soil and grass), seen from a
    /// lane and from a headland, with and without filtering and shadows, through pixel quads
    /// all over the image (the same formulas hold off the triangle, including the raster
    /// fallback where the ray meets its plane behind the camera). Other materials decline.
    #[test]
    fn ground_four_at_once_is_the_ground_one_at_a_time() {
        use crate::camera::shadow::ShadowMap;
        use crate::config::SimConfig;
        use crate::world::World;
        let cfg = SimConfig::default();
        let world = World::build(&cfg.vineyard, &cfg.terrain, cfg.world_seed);
        let chunks = Chunks::build(&world.mesh, 1.0);
        let light = Light::new(50.0, 30.0);
        let ground = GroundTexture::new(&light);
        let shadow = ShadowMap::build(&chunks, &light);
        let k = Intrinsics::from_config(&cfg.sensors.camera);
        let (mut quads, mut declined) = (0, 0);
        let ids: Vec<u32> = (0..chunks.tris.len() as u32).step_by(50).collect();
        for (x, y, yaw, pitch) in [
            (4.0, cfg.vineyard.lane_y(3), 0.05, -0.15),
            (-2.0, 1.0, 1.2, -0.4),
        ] {
            let world_from_optical = Isometry3::from_parts(
                Translation3::new(x, y, world.terrain.height(x, y) + 0.9),
                UnitQuaternion::from_euler_angles(0.0, -pitch, yaw),
            ) * camera_from_optical();
            let view = View::new(&world_from_optical, &k);
            for (filter, shadow) in [(true, Some(&shadow)), (false, None)] {
                let shader = Shader {
                    chunks: &chunks,
                    view: &view,
                    light: &light,
                    shadow,
                    ground: &ground,
                    filter,
                    background: None,
                };
                for (i, &id) in ids.iter().enumerate() {
                    let (u, v) = ((i * 37) % (k.width - 3), (i * 53) % k.height);
                    let (x, y) = (u as u32 as f32, v as u32 as f32);
                    let inv_z = [0.2, 0.5, 0.0, 1.5];
                    let Some(lanes) = shader.ground4(x, y, id, inv_z) else {
                        declined += 1;
                        continue;
                    };
                    quads += 1;
                    for (l, four) in lanes.iter().enumerate() {
                        let one = shader.shade(x + l as f32, y, id, inv_z[l]);
                        let bits = |s: &Shaded| {
                            (
                                s.rgb.map(f32::to_bits),
                                s.depth.to_bits(),
                                s.cos_incidence.to_bits(),
                            )
                        };
                        assert_eq!(
                            bits(four),
                            bits(&one),
                            "triangle {id}, pixel ({}, {v})",
                            u + l
                        );
                    }
                }
            }
        }
        assert!(
            quads > 500 && declined > 500,
            "expected both paths taken: {quads} quads of ground, {declined} declined"
        );
    }
}
