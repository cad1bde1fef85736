//! The RGB-D camera: a deterministic software rasterizer of the vineyard mesh with
//! procedural materials, sun and sky light, and a Kinect v2 depth-noise model.
//!
//! A frame is made in four stages, each parallel over bands of rows (a fixed partition, so
//! the bytes never depend on the number of threads):
//!
//! 1. `chunks`: the mesh, pre-cut into 1 m cells with bounding boxes, is culled against
//!    the view frustum; the surviving triangles are moved to the optical frame, clipped at
//!    the near plane and projected (`raster`). A pass that would discard what lies beyond
//!    some depth (the colour camera's far clip; a single-sample depth pass beyond its range)
//!    does not rasterize the chunks and triangles wholly beyond it: the same bytes, less work
//!    (tested frame for frame).
//! 2. `raster`: per band of rows, a z-buffer keeps the nearest triangle of each visibility
//!    sample (a visibility buffer: 1/z and a triangle index; ties go to the smaller index).
//!    By default a pixel has 4 samples (`antialias_samples`: Direct3D's standard rotated
//!    grid, as the 4x MSAA of the paper's Gazebo camera; 8 possible); 1 is a single sample
//!    at the pixel centre, the renderer before.
//! 3. `shading` and `msaa`: each distinct triangle among a pixel's samples is shaded once,
//!    at the centroid of the samples it covers, and the pixel is their coverage-weighted
//!    mean in linear light (a pixel inside one triangle is shaded once at its centre, as
//!    without anti-aliasing). Shading intersects the ray with the triangle exactly (so
//!    depth is the true ray-surface distance and texture coordinates are
//!    perspective-correct), looks up the material (`texture`, band-limited to the pixel
//!    footprint by `prefilter` unless `filter_materials = false`; the ground's soil and
//!    grass in mip-mapped textures, `ground`) and lights it: Lambert sun with a shadow map
//!    (`shadow`) and, on the ground, the relief of clods, stones and tufts baked into its
//!    texture; hemispheric sky ambient, aerial haze; pixels with no surface show a sky
//!    gradient and a tree line, its crown box-filtered. Depth is never averaged across an
//!    edge (that would invent the flying pixels a Kinect's driver filters out): it is the
//!    depth of the surface covering most samples, along the pixel's central ray (`msaa`).
//!    Colour gets its zero-mean noise (σ `rgb_sigma` levels) here.
//! 4. `depth_noise`: the range window, edge dropout and axial noise on depth.
//!
//! Frames and conventions:
//! - `world_from_optical = world_from_base * base_from_camera * camera_from_optical`, where
//!   `base_from_camera` is the configured `mount` (x forward, y left, z up, like every
//!   sensor) and the optical frame is z forward, x right, y down (REP 103). The intrinsics
//!   apply in the optical frame: pixel `(u, v)` (integer coordinates are pixel centres,
//!   column `u` from the left, row `v` from the top) sees the ray
//!   `((u - cx) / fx, (v - cy) / fy, 1)`. [`RgbdCamera::base_from_camera_optical`] gives
//!   the whole extrinsic.
//! - `depth_m` is the z coordinate in the optical frame (distance along the optical axis,
//!   not along the ray), as Kinect and ROS depth images (REP 118) report it.
//! - Invalid depth (no return, nearer than `min_depth_m`, farther than `max_depth_m`,
//!   dropped at an edge) is `0.0`, as the Kinect v2 driver reports it: libfreenect2's
//!   registration and OpenNI2 driver write 0 for invalid pixels (`invalidDepth = 0.0` in
//!   OpenKinect/libfreenect2 `OpenNI2-FreenectDriver/src/Registration.hpp`) and
//!   iai_kinect2 publishes them as 0 in its 16UC1 images. (ROS REP 118 would write NaN in a
//!   32FC1 image; a bridge to ROS maps 0 to NaN.)
//! - Depth range: the Kinect v2 is specified for 0.5–4.5 m (libfreenect2 cuts there by
//!   default); it measures out to about 8 m with more noise, where the paper's simulated
//!   camera clips. The defaults report 0.5–8 m (`max_depth_m = 4.5` gives the driver's cut);
//!   colour is rendered to the horizon.
//!
//! Speed (`cargo bench -p vinebench-sim --bench camera`, a lane of the default world at
//! growth stage 3, ~18k of its 77k triangles in the frustum): see the bench's figures, 4x
//! anti-aliasing next to the single-sample renderer. About 15 % of the pixels of a lane see
//! more than one triangle and are shaded 2.3 times on average (1.2 shadings a pixel); of a
//! frame's ~370k shadings along S3 about a third are sky, nearly half ground (soil 27 %, grass
//! 18 %), 9 % bark and 8 % leaves. Where the compiler leaves scalar code scalar, four lanes do
//! the same operations at once (`lanes::F4`, SSE2, the same bits as one at a time): a triangle
//! row's four sample bounds in the raster, four sky pixels above the tree line, and four pixels
//! whose samples all see one ground triangle (ray, plane, footprint, light and haze; the
//! texture and the shadow map are still read pixel by pixel, and those reads, not the
//! arithmetic, are now most of a ground pixel's time). Tried and left out, as slower: the same
//! four-pixel path for every material (1.5 %), and shading a whole row's requests four at a
//! time, any material (3 %); storing the mip levels and the shadow map in cache-line tiles, and
//! rendering the next frame while the stream made the other sensors' messages, made no
//! difference. What does not change from frame to frame is computed once per world (a
//! triangle's unit normal, barycentric gradients and material constants) or once per camera
//! (the ground's textures lit by its sun, about 0.1 s; the patches they come from and the
//! ground tone's noise lattice are generated once per process, another 0.1 s); nothing per
//! pixel divides by an integer. Sample frames: `docs/camera/`.

mod chunks;
mod depth_noise;
mod distortion;
mod ground;
mod image;
mod intrinsics;
mod lanes;
mod msaa;
mod prefilter;
mod raster;
mod shading;
mod shadow;
mod texture;

use nalgebra::Isometry3;
use rand::Rng;
use rayon::prelude::*;

pub use depth_noise::axial_sigma_m;
pub use distortion::{Distortion, Remap};
pub use image::{RgbdImage, save_depth_png, save_rgb_png, turbo};
pub use intrinsics::{Intrinsics, camera_from_optical};

use crate::config::{Background, CameraConfig, DepthRegistration, NoiseProfile};
use crate::rng::SimRng;
use crate::world::World;
use chunks::Chunks;
use ground::GroundTexture;
use shading::{Light, Shader};
use shadow::ShadowMap;

/// The visibility sample offsets of a pixel for `antialias_samples` samples (1, 4 or 8):
/// `[x, y]` in pixels from the pixel centre, x right and y down (Direct3D's standard
/// patterns; one sample: the centre).
pub fn sample_offsets(samples: usize) -> &'static [[f32; 2]] {
    raster::pattern(samples)
}

/// Rows per parallel band: fixed, so that output never depends on the thread count.
const BAND_ROWS: usize = 8;

/// What one render pass draws.
#[derive(Debug, Clone, Copy)]
struct Pass {
    /// Visibility samples of a pixel.
    pattern: &'static [[f32; 2]],
    /// Nothing beyond this optical-axis depth is drawn (a far clip plane).
    far: Option<f32>,
    /// Chunks and triangles wholly beyond this optical-axis depth are not rasterized: only
    /// where the pass's output is the same without them (`raster::View::culling_beyond`).
    cull_beyond: Option<f32>,
    /// Colour is shaded (else depth only: a depth camera's pass).
    colour: bool,
}

/// An RGB-D camera over one world; built once (cuts the mesh into chunks and, with
/// shadows, renders the sun's shadow map), then renders any number of frames.
#[derive(Debug)]
pub struct RgbdCamera {
    cfg: CameraConfig,
    intrinsics: Intrinsics,
    /// The separate depth camera's, where there is one (`depth_hfov_deg`).
    depth_intrinsics: Option<Intrinsics>,
    base_from_camera_optical: Isometry3<f64>,
    chunks: Chunks,
    light: Light,
    shadow: Option<ShadowMap>,
    ground: GroundTexture,
    /// The colour noise by the sum of its uniforms (`depth_noise::rgb_noise_table`; empty
    /// when `rgb_sigma` is 0).
    rgb_noise: Vec<f32>,
    /// Visibility sample offsets of a pixel (`antialias_samples` of them).
    pattern: &'static [[f32; 2]],
    /// The separate depth camera's (`depth_antialias_samples` of them).
    depth_pattern: &'static [[f32; 2]],
    /// A uniform `background` in linear light (the output's encoding squares back to it).
    background: Option<[f32; 3]>,
    /// Leave out what a pass would only discard (`Pass::cull_beyond`); off only in the test
    /// that shows it changes nothing.
    culling: bool,
    /// A lens that is not a pinhole (`distortion`): the pinhole canvas rendered and where
    /// each raw pixel takes it from.
    remap: Option<Remap>,
}

impl RgbdCamera {
    pub fn new(cfg: &CameraConfig, world: &World) -> Self {
        let chunks = Chunks::build(&world.mesh, 1.0);
        let light = Light::new(cfg.sun_elevation_deg, cfg.sun_azimuth_deg);
        let shadow = cfg.shadows.then(|| ShadowMap::build(&chunks, &light));
        let ground = GroundTexture::new(&light);
        Self {
            cfg: cfg.clone(),
            intrinsics: Intrinsics::from_config(cfg),
            depth_intrinsics: Intrinsics::depth_camera(cfg),
            base_from_camera_optical: cfg.mount.base_from_sensor() * camera_from_optical(),
            chunks,
            light,
            shadow,
            ground,
            rgb_noise: if cfg.rgb_sigma > 0.0 {
                depth_noise::rgb_noise_table(cfg.rgb_sigma as f32)
            } else {
                Vec::new()
            },
            pattern: raster::pattern(cfg.antialias_samples),
            depth_pattern: raster::pattern(cfg.depth_antialias_samples),
            background: match cfg.background {
                Background::Sky(_) => None,
                Background::Rgb(c) => Some(c.map(|x| (x * x) as f32)),
            },
            culling: true,
            remap: Distortion::new(cfg.distortion).map(|d| {
                Remap::new(&Intrinsics::from_config(cfg), &d)
                    .expect("sensors.camera.distortion is checked when the world is read")
            }),
        }
    }

    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// The full extrinsic: mount and the rotation to the optical frame.
    pub fn base_from_camera_optical(&self) -> Isometry3<f64> {
        self.base_from_camera_optical
    }

    pub fn config(&self) -> &CameraConfig {
        &self.cfg
    }

    /// Renders the frame seen from `world_from_base`. Noise draws come from `rng` (one
    /// 64-bit seed per frame, expanded per pixel by a counter-based hash).
    pub fn render(&self, world_from_base: &Isometry3<f64>, rng: &mut SimRng) -> RgbdImage {
        let world_from_optical = world_from_base * self.base_from_camera_optical;
        let seed: u64 = rng.random();
        let noisy = self.cfg.noise == NoiseProfile::Typical;
        let effects = depth_noise::Effects {
            width: self.intrinsics.width,
            min_depth_m: self.cfg.min_depth_m as f32,
            max_depth_m: self.cfg.max_depth_m as f32,
            depth_noise: noisy,
            edge_dropout_ratio: if noisy {
                self.cfg.edge_dropout_ratio as f32
            } else {
                0.0
            },
            rgb_noise: if noisy { &self.rgb_noise } else { &[] },
            seed,
        };
        let Some(remap) = &self.remap else {
            let (rgb, depth_m) =
                self.render_pinhole(&world_from_optical, &self.intrinsics, &effects);
            return self.image(rgb, depth_m);
        };
        // A lens: the pinhole canvas without colour noise, resampled to the raw image, whose
        // pixels then get theirs (as a sensor's pixels do, behind the lens).
        let k = remap.canvas;
        let canvas_effects = depth_noise::Effects {
            width: k.width,
            rgb_noise: &[],
            ..effects
        };
        let (canvas_rgb, canvas_depth) =
            self.render_pinhole(&world_from_optical, &k, &canvas_effects);
        let w = self.intrinsics.width;
        let mut rgb = vec![0u8; 3 * w * self.intrinsics.height];
        rgb.par_chunks_mut(3 * w * BAND_ROWS)
            .enumerate()
            .for_each_init(
                || vec![[0.0f32; 3]; w],
                |row, (band, out)| {
                    for (r, out) in out.chunks_exact_mut(3 * w).enumerate() {
                        let v = band * BAND_ROWS + r;
                        remap.colour_row(&canvas_rgb, v, row);
                        effects.noise_and_quantize_row(v * w, row, out);
                    }
                },
            );
        self.image(rgb, remap.depth(&canvas_depth))
    }

    /// A frame of the configured image (its intrinsics the frame's camera matrix).
    fn image(&self, rgb: Vec<u8>, depth_m: Vec<f32>) -> RgbdImage {
        let k = self.intrinsics;
        RgbdImage {
            width: k.width,
            height: k.height,
            rgb,
            depth_m,
            intrinsics: [k.fx, k.fy, k.cx, k.cy],
        }
    }

    /// A pinhole frame through `k` (the configured image's, or a lens's canvas): colour and
    /// depth with every effect of `effects`.
    fn render_pinhole(
        &self,
        world_from_optical: &Isometry3<f64>,
        k: &Intrinsics,
        effects: &depth_noise::Effects<'_>,
    ) -> (Vec<u8>, Vec<f32>) {
        let (w, h) = (k.width, k.height);
        let far = self.cfg.colour_far_clip_m.map(|f| f as f32);
        let colour = Pass {
            pattern: self.pattern,
            far,
            // Beyond the far clip nothing is drawn: nothing there need be rasterized.
            cull_beyond: far,
            colour: true,
        };
        let (rgb, mut depth, mut cos_incidence) =
            self.pass(world_from_optical, k, &colour, effects);
        if let Some(kd) = &self.depth_intrinsics {
            // The depth camera's own pass. With one sample a pixel's depth is its centre's
            // surface, so one wholly beyond the range (and beyond what edge dropout compares
            // a neighbour with) would only ever give 0: it is not rasterized.
            let depth_pass = Pass {
                pattern: self.depth_pattern,
                far: None,
                cull_beyond: (self.depth_pattern.len() == 1)
                    .then(|| effects.max_depth_m * (1.0 + effects.edge_dropout_ratio.max(0.0))),
                colour: false,
            };
            match self.cfg.depth_registration {
                DepthRegistration::Registered if self.depth_apart() => {
                    // A camera of its own (the Kinect v2's: its own centre and image): the
                    // sensor's effects act on its own image, which is then registered
                    // into the colour camera, as a driver does.
                    let [ox, oy, oz] = self.cfg.depth_offset_m;
                    let world_from_depth_optical =
                        world_from_optical * nalgebra::Translation3::new(ox, oy, oz);
                    let (_, d, c) = self.pass(&world_from_depth_optical, kd, &depth_pass, effects);
                    let own = depth_noise::Effects {
                        width: kd.width,
                        ..*effects
                    };
                    let mut native = vec![0.0f32; kd.width * kd.height];
                    native
                        .par_chunks_mut(kd.width * BAND_ROWS)
                        .enumerate()
                        .for_each(|(band, out)| {
                            own.depth_band(band * BAND_ROWS * kd.width, &d, &c, out);
                        });
                    return (rgb, register_depth(&native, kd, self.cfg.depth_offset_m, k));
                }
                DepthRegistration::Stretched => {
                    // The depth camera's own image, handed over pixel for pixel.
                    let (_, d, c) = self.pass(world_from_optical, kd, &depth_pass, effects);
                    (depth, cos_incidence) = (d, c);
                }
                DepthRegistration::Registered => {
                    // The same centre: registration keeps the rays the depth camera sees,
                    // the columns and rows within its view (row by row: no division per pixel).
                    let c = *k;
                    let (tx, ty) = (
                        (0.5 * kd.width as f64) / kd.fx,
                        (0.5 * kd.height as f64) / kd.fy,
                    );
                    let seen_u: Vec<bool> = (0..w)
                        .map(|u| ((u as f64 - c.cx) / c.fx).abs() <= tx)
                        .collect();
                    for (v, (z, cos)) in depth
                        .chunks_exact_mut(w)
                        .zip(cos_incidence.chunks_exact_mut(w))
                        .enumerate()
                    {
                        let row_seen = ((v as f64 - c.cy) / c.fy).abs() <= ty;
                        for ((z, cos), &seen) in z.iter_mut().zip(cos.iter_mut()).zip(&seen_u) {
                            if !(row_seen && seen) {
                                (*z, *cos) = (0.0, 0.0);
                            }
                        }
                    }
                }
            }
        }
        // 4: depth effects (edge dropout looks at the neighbouring rows).
        let mut depth_m = vec![0.0f32; w * h];
        depth_m
            .par_chunks_mut(w * BAND_ROWS)
            .enumerate()
            .for_each(|(band, out)| {
                effects.depth_band(band * BAND_ROWS * w, &depth, &cos_incidence, out);
            });
        (rgb, depth_m)
    }

    /// A depth camera with a centre or an image of its own (`depth_offset_m`,
    /// `depth_size`): its depth is reprojected, not merely cut to its view.
    fn depth_apart(&self) -> bool {
        self.depth_intrinsics.is_some_and(|kd| {
            self.cfg.depth_offset_m != [0.0; 3]
                || (kd.width, kd.height) != (self.intrinsics.width, self.intrinsics.height)
        })
    }

    /// Steps 1-3 through intrinsics `k` (the configured image size): colour with its noise
    /// (none without `pass.colour`: a depth camera's pass, which shades nothing), depth and
    /// the cosine of incidence without theirs.
    fn pass(
        &self,
        world_from_optical: &Isometry3<f64>,
        k: &Intrinsics,
        pass: &Pass,
        effects: &depth_noise::Effects<'_>,
    ) -> (Vec<u8>, Vec<f32>, Vec<f32>) {
        let (w, h) = (k.width, k.height);
        let Pass {
            pattern,
            far,
            cull_beyond,
            colour,
        } = *pass;
        let mut view = raster::View::new(world_from_optical, k);
        if let Some(z) = cull_beyond.filter(|_| self.culling) {
            view = view.culling_beyond(z);
        }

        // 1: cull and project.
        let visible = self.chunks.visible(&view);
        let tris = raster::project_all(&self.chunks, &visible, &view, raster::reach(pattern));
        let bins = raster::bin_by_band(&tris, h, BAND_ROWS);

        let shader = Shader {
            chunks: &self.chunks,
            view: &view,
            light: &self.light,
            shadow: self.shadow.as_ref(),
            ground: &self.ground,
            filter: self.cfg.filter_materials,
            background: self.background,
        };

        // 2-3: per band, rasterize a visibility buffer (small enough to stay in cache),
        // then shade and resolve it; colour gets its noise here, depth is kept clean for
        // step 4.
        let n = pattern.len();
        let mut rgb = vec![0u8; 3 * w * h];
        let mut depth = vec![0.0f32; w * h];
        let mut cos_incidence = vec![0.0f32; w * h];
        rgb.par_chunks_mut(3 * w * BAND_ROWS)
            .zip(depth.par_chunks_mut(w * BAND_ROWS))
            .zip(cos_incidence.par_chunks_mut(w * BAND_ROWS))
            .zip(bins.par_iter())
            .enumerate()
            .for_each_init(
                // Visibility buffer and a row of linear colour, reused by the bands a
                // worker takes in turn.
                || {
                    (
                        vec![0.0f32; n * w * BAND_ROWS],
                        vec![u32::MAX; n * w * BAND_ROWS],
                        vec![[0.0f32; 3]; w],
                    )
                },
                |(inv_z, ids, linear), (band, (((rgb, z), cos), list))| {
                    let first_row = band * BAND_ROWS;
                    let len = n * z.len();
                    let (inv_z, ids) = (&mut inv_z[..len], &mut ids[..len]);
                    inv_z.fill(0.0);
                    ids.fill(u32::MAX);
                    match pattern.len() {
                        4 => raster::rasterize_band_ms(
                            &tris,
                            list,
                            first_row,
                            (w, &raster::SAMPLES_4),
                            inv_z,
                            ids,
                        ),
                        8 => raster::rasterize_band_ms(
                            &tris,
                            list,
                            first_row,
                            (w, &raster::SAMPLES_8),
                            inv_z,
                            ids,
                        ),
                        _ => {
                            raster::rasterize_band(&tris, list, first_row, (w, pattern), inv_z, ids)
                        }
                    }
                    if let Some(far) = far {
                        // Gazebo's far clip plane: nothing beyond is drawn.
                        let q_min = 1.0 / far;
                        for (q, id) in inv_z.iter().zip(ids.iter_mut()) {
                            if *q < q_min {
                                *id = u32::MAX;
                            }
                        }
                    }
                    if !colour {
                        // A depth camera: the depth `msaa::resolve` would give, no colour.
                        for (r, (z, cos)) in z
                            .chunks_exact_mut(w)
                            .zip(cos.chunks_exact_mut(w))
                            .enumerate()
                        {
                            let y = (first_row + r) as u32 as f32;
                            let (row_ids, row_q) =
                                (&ids[r * n * w..][..n * w], &inv_z[r * n * w..][..n * w]);
                            for u in 0..w {
                                (z[u], cos[u]) = msaa::resolve_depth(
                                    &shader,
                                    pattern,
                                    (u as u32 as f32, y),
                                    &row_ids[u * n..][..n],
                                    &row_q[u * n..][..n],
                                );
                            }
                        }
                        return;
                    }
                    // Row by row: no integer division per pixel.
                    for (r, ((rgb, z), cos)) in rgb
                        .chunks_exact_mut(3 * w)
                        .zip(z.chunks_exact_mut(w))
                        .zip(cos.chunks_exact_mut(w))
                        .enumerate()
                    {
                        let v = first_row + r;
                        // Through u32: exact (a frame is far narrower than 2^24) and one
                        // instruction, where usize to f32 takes several.
                        let y = v as u32 as f32;
                        // The row's samples, `[column][sample]` (one sample: the same).
                        let (row_ids, row_q) =
                            (&ids[r * n * w..][..n * w], &inv_z[r * n * w..][..n * w]);
                        let mut u = 0;
                        while u < w {
                            // Four pixels whose samples all see one surface: sky above the
                            // tree line, or a ground triangle, are shaded at once.
                            let id = row_ids[u * n];
                            if u + 4 <= w && row_ids[u * n..(u + 4) * n].iter().all(|&i| i == id) {
                                let x = u as u32 as f32;
                                if id == u32::MAX {
                                    if let Some(sky) = shader.sky4(x, y) {
                                        linear[u..u + 4].copy_from_slice(&sky);
                                        z[u..u + 4].fill(0.0);
                                        cos[u..u + 4].fill(0.0);
                                        u += 4;
                                        continue;
                                    }
                                } else {
                                    let q = &row_q[u * n..(u + 4) * n];
                                    let inv_z =
                                        [0, 1, 2, 3].map(|l| msaa::mean_q(&q[l * n..][..n]));
                                    if let Some(shaded) = shader.ground4(x, y, id, inv_z) {
                                        for (l, s) in shaded.iter().enumerate() {
                                            linear[u + l] = s.rgb;
                                            z[u + l] = s.depth;
                                            cos[u + l] = s.cos_incidence;
                                        }
                                        u += 4;
                                        continue;
                                    }
                                }
                            }
                            let s = msaa::resolve(
                                &shader,
                                pattern,
                                (u as u32 as f32, y),
                                &row_ids[u * n..][..n],
                                &row_q[u * n..][..n],
                            );
                            linear[u] = s.rgb;
                            z[u] = s.depth;
                            cos[u] = s.cos_incidence;
                            u += 1;
                        }
                        effects.colour_row(v * w, linear, rgb);
                    }
                },
            );

        (rgb, depth, cos_incidence)
    }
}

/// Registers the depth image `depth` of camera `from`, whose optical centre sits at
/// `offset` (metres) in the optical frame of camera `to` with its axes parallel, into
/// `to`'s image: each valid pixel (its surface's point, and its footprint: the pixel's four
/// corners at its depth) covers the `to` pixels whose centres fall inside the footprint's
/// projection, the nearest surface winning; a `to` pixel that no footprint covers has no
/// depth (0). What `to` sees past an edge that `from`, from its other viewpoint, does not
/// is left empty, as a Kinect v2 driver's registration leaves it (the shadows of its
/// colour-depth parallax); nothing is interpolated across an edge. The output is depth
/// along `to`'s optical axis.
pub fn register_depth(
    depth: &[f32],
    from: &Intrinsics,
    offset: [f64; 3],
    to: &Intrinsics,
) -> Vec<f32> {
    // Each pixel's footprint in `to`'s pixels, rows in parallel (its four divisions are the
    // cost); then the footprints are drawn, the nearest surface winning, which does not
    // depend on their order.
    let mut footprints = vec![Footprint::NONE; depth.len()];
    // Column u's footprint spans [x_edge[u], x_edge[u + 1]): `u - 0.5` and `(u - 1) + 0.5`
    // are the same number, so each edge is computed once.
    let x_edge: Vec<f64> = (0..=from.width)
        .map(|u| (u as f64 - 0.5 - from.cx) / from.fx)
        .collect();
    footprints
        .par_chunks_mut(from.width)
        .zip(depth.par_chunks_exact(from.width))
        .enumerate()
        .for_each(|(v, (out, row))| {
            let (y0, y1) = (
                (v as f64 - 0.5 - from.cy) / from.fy,
                (v as f64 + 0.5 - from.cy) / from.fy,
            );
            for (u, (f, &z)) in out.iter_mut().zip(row).enumerate() {
                *f = Footprint::of(z, [x_edge[u], x_edge[u + 1]], [y0, y1], offset, to);
            }
        });
    let mut out = vec![f32::INFINITY; to.width * to.height];
    for f in &footprints {
        for vt in f.v[0]..f.v[1] {
            let row = &mut out[vt as usize * to.width..][..to.width];
            for o in &mut row[f.u[0] as usize..f.u[1] as usize] {
                if f.z < *o {
                    *o = f.z;
                }
            }
        }
    }
    for z in &mut out {
        if z.is_infinite() {
            *z = 0.0;
        }
    }
    out
}

/// The `to` pixels a depth pixel covers in [`register_depth`]: columns `u[0]..u[1]`, rows
/// `v[0]..v[1]` (both within the image), at depth `z` along `to`'s axis.
#[derive(Debug, Clone, Copy)]
struct Footprint {
    u: [u32; 2],
    v: [u32; 2],
    z: f32,
}

impl Footprint {
    const NONE: Self = Self {
        u: [0; 2],
        v: [0; 2],
        z: 0.0,
    };

    /// The footprint of a pixel of depth `z` (0: none) spanning `[x[0], x[1]) x [y[0], y[1])`
    /// in normalised image coordinates of the camera at `offset` in `to`'s optical frame: a
    /// `to` pixel is covered where its centre lies inside the footprint's projection.
    #[inline]
    fn of(z: f32, x: [f64; 2], y: [f64; 2], offset: [f64; 3], to: &Intrinsics) -> Self {
        if z <= 0.0 {
            return Self::NONE;
        }
        let z = f64::from(z);
        let zt = z + offset[2];
        if zt <= 0.0 {
            return Self::NONE;
        }
        let a = x.map(|x| to.fx * (z * x + offset[0]) / zt + to.cx);
        let b = y.map(|y| to.fy * (z * y + offset[1]) / zt + to.cy);
        let (tw, th) = (to.width as i64, to.height as i64);
        let within = |lo: f64, hi: f64, n: i64| {
            let start = ceil_i64(lo).clamp(0, n);
            [start, ceil_i64(hi).clamp(start, n)].map(|c| c as u32)
        };
        Self {
            u: within(a[0], a[1], tw),
            v: within(b[0], b[1], th),
            z: zt as f32,
        }
    }
}

/// `x.ceil() as i64`, without a libm call (baseline x86-64 has no SSE4.1 `roundsd`): the
/// same for every finite `x` within i64's range.
fn ceil_i64(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) < x {
        i.saturating_add(1)
    } else {
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SimConfig;
    use crate::simulation::Simulation;

    /// Two depth images equal bit for bit.
    fn same_bits(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits())
    }

    /// [`register_depth`] as first written, one pixel at a time: the footprint's corners
    /// and the drawing in one loop, `f64::ceil` (the reference the faster one must match).
    fn register_depth_one_by_one(
        depth: &[f32],
        from: &Intrinsics,
        offset: [f64; 3],
        to: &Intrinsics,
    ) -> Vec<f32> {
        let (tw, th) = (to.width as i64, to.height as i64);
        let mut out = vec![f32::INFINITY; to.width * to.height];
        for (v, row) in depth.chunks_exact(from.width).enumerate() {
            let y0 = (v as f64 - 0.5 - from.cy) / from.fy;
            let y1 = (v as f64 + 0.5 - from.cy) / from.fy;
            for (u, &z) in row.iter().enumerate() {
                let (z, zt) = (f64::from(z), f64::from(z) + offset[2]);
                if z <= 0.0 || zt <= 0.0 {
                    continue;
                }
                let x0 = (u as f64 - 0.5 - from.cx) / from.fx;
                let x1 = (u as f64 + 0.5 - from.cx) / from.fx;
                let a0 = to.fx * (z * x0 + offset[0]) / zt + to.cx;
                let a1 = to.fx * (z * x1 + offset[0]) / zt + to.cx;
                let b0 = to.fy * (z * y0 + offset[1]) / zt + to.cy;
                let b1 = to.fy * (z * y1 + offset[1]) / zt + to.cy;
                let (ua, ub) = ((a0.ceil() as i64).max(0), (a1.ceil() as i64).min(tw));
                let (va, vb) = ((b0.ceil() as i64).max(0), (b1.ceil() as i64).min(th));
                for vt in va..vb {
                    for ut in ua..ub {
                        let o = &mut out[(vt * tw + ut) as usize];
                        *o = o.min(zt as f32);
                    }
                }
            }
        }
        out.iter()
            .map(|&z| if z.is_infinite() { 0.0 } else { z })
            .collect()
    }

    /// Registration is the same bits as the one-pixel-at-a-time reference: random depth
    /// images (holes, surfaces from 5 cm to 30 m, neighbours far apart) through the Kinect
    /// v2's geometry and through offsets along every axis, including ones that put the
    /// depth camera ahead of near surfaces and footprints beyond the colour image's edges.
    #[test]
    fn registration_is_the_one_pixel_at_a_time_reference_bit_for_bit() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(45);
        let cases = [
            (
                Intrinsics::pinhole(512, 424, 70.1),
                Intrinsics::pinhole(640, 480, 84.1),
            ),
            (
                Intrinsics::pinhole(512, 424, 70.1),
                Intrinsics::pinhole(640, 480, 60.0),
            ),
            (
                Intrinsics::pinhole(160, 120, 90.0),
                Intrinsics::pinhole(200, 150, 50.0),
            ),
        ];
        let offsets = [
            [-0.0517, 0.0, 0.0],
            [0.03, -0.02, 0.01],
            [-0.2, 0.1, -0.3],
            [0.0, 0.0, 0.0],
        ];
        let mut covered = 0;
        for (from, to) in &cases {
            for offset in offsets {
                let depth: Vec<f32> = (0..from.width * from.height)
                    .map(|_| match rng.random_range(0..10) {
                        0 => 0.0,
                        1 => rng.random_range(0.05..0.5),
                        _ => rng.random_range(0.5..30.0),
                    })
                    .collect();
                let fast = register_depth(&depth, from, offset, to);
                let reference = register_depth_one_by_one(&depth, from, offset, to);
                assert!(same_bits(&fast, &reference), "{offset:?}");
                covered += fast.iter().filter(|&&z| z > 0.0).count();
            }
        }
        assert!(
            covered > 100_000,
            "the images were registered: {covered} pixels"
        );
    }

    /// The depth camera's image of a post 0.1 m wide 1 m ahead of a wall 4 m ahead, both
    /// traced exactly from its own centre (0.0517 m to the colour camera's left, the
    /// Kinect v2's), registered into the colour camera: the post and the wall keep their
    /// depths, and beside the post's right edge the colour camera sees wall that the depth
    /// camera cannot: a band without depth as wide as the parallax, fx · b · (1/z₁ − 1/z₂)
    /// = 17.7 px. Nowhere else in the depth camera's view is a pixel left empty.
    #[test]
    fn registration_leaves_the_parallax_shadow_beside_an_edge_and_nothing_else() {
        let colour = Intrinsics::pinhole(640, 480, 70.0);
        let depth = Intrinsics::pinhole(512, 424, 70.1);
        let (b, z_post, z_wall, half) = (0.0517, 1.0, 4.0, 0.05);
        let offset = [-b, 0.0, 0.0];
        // The depth camera's image: each pixel's central ray from its own centre.
        let mut img = vec![0.0f32; depth.width * depth.height];
        for v in 0..depth.height {
            for u in 0..depth.width {
                let [xr, _, _] = depth.ray(u as f64, v as f64);
                // Where the ray crosses z = z_post, in the colour camera's frame.
                let x_at_post = offset[0] + z_post * xr;
                img[v * depth.width + u] = if x_at_post.abs() <= half {
                    z_post as f32
                } else {
                    z_wall as f32
                };
            }
        }
        let out = register_depth(&img, &depth, offset, &colour);
        let (w, h) = (colour.width, colour.height);
        let row = &out[(h / 2) * w..][..w];
        let margin = 12; // the two cameras' views differ by a few columns at the borders
        let col = |x_over_z: f64| colour.fx * x_over_z + colour.cx;
        let (post_l, post_r) = (col(-half / z_post), col(half / z_post));
        let mut holes = Vec::new();
        for (u, &z) in row.iter().enumerate().take(w - margin).skip(margin) {
            let u_f = u as f64;
            if z == 0.0 {
                holes.push(u);
            } else if u_f > post_l + 1.0 && u_f < post_r - 1.0 {
                assert_eq!(z, z_post as f32, "the post at column {u}");
            } else if u_f < post_l - 1.0 || u_f > post_r + 20.0 {
                assert_eq!(z, z_wall as f32, "the wall at column {u}");
            }
        }
        let expected = colour.fx * b * (1.0 / z_post - 1.0 / z_wall);
        assert!(
            (holes.len() as f64 - expected).abs() <= 1.5,
            "a shadow of {} px (columns {holes:?}), the parallax gives {expected:.1} px",
            holes.len()
        );
        assert!(
            holes.iter().all(|&u| (u as f64) > post_r - 1.0),
            "the shadow lies right of the post (right edge at {post_r:.1}): {holes:?}"
        );
        // Every row alike: no pixel empty away from the post's right edge.
        let stray = (margin..h - margin)
            .flat_map(|v| (margin..w - margin).map(move |u| (u, v)))
            .filter(|&(u, v)| out[v * w + u] == 0.0)
            .filter(|&(u, _)| !(post_r - 1.0..post_r + expected + 2.0).contains(&(u as f64)))
            .count();
        assert_eq!(stray, 0, "empty pixels away from the edge");

        // The same camera at the same centre gives back its image, bit for bit.
        let same = register_depth(&img, &depth, [0.0; 3], &depth);
        assert!(same_bits(&same, &img));
    }

    /// A Kinect v2 as `field` has it (its depth camera's own 512 x 424 image, 51.7 mm
    /// beside the colour camera) renders S3's frames with about as much depth as the same
    /// depth camera at the colour camera's centre, less its parallax shadows, and the same
    /// colour; the frame is the same for the same seed.
    #[test]
    fn a_depth_camera_apart_renders_registered_frames() {
        let cfg = SimConfig::default();
        let sim = Simulation::new(&cfg, "s3", 7).expect("s3");
        let world = World::from_config(&cfg);
        let same_centre = CameraConfig {
            depth_hfov_deg: Some(70.1),
            depth_registration: DepthRegistration::Registered,
            ..cfg.sensors.camera.clone()
        };
        let apart = CameraConfig {
            depth_size: Some([512, 424]),
            depth_offset_m: [-0.0517, 0.0, 0.0],
            ..same_centre.clone()
        };
        let (a, b) = (
            RgbdCamera::new(&apart, &world),
            RgbdCamera::new(&same_centre, &world),
        );
        assert!(a.depth_apart() && !b.depth_apart());
        let pose = sim.trajectory.pose(45_000_000_000);
        let render = |cam: &RgbdCamera| cam.render(&pose, &mut crate::rng::stream(3, "frame"));
        let (fa, fb) = (render(&a), render(&b));
        assert_eq!(fa.rgb, fb.rgb, "the colour image does not change");
        assert_eq!(fa.depth_m.len(), fb.depth_m.len());
        let valid = |f: &RgbdImage| f.depth_m.iter().filter(|&&z| z > 0.0).count() as f64;
        let (va, vb) = (valid(&fa), valid(&fb));
        assert!(
            vb > 100_000.0 && va > 0.85 * vb && va < 1.02 * vb,
            "valid depth pixels: apart {va}, same centre {vb}"
        );
        let again = render(&a);
        assert!(same_bits(&again.depth_m, &fa.depth_m));
    }

    /// Leaving out what lies wholly beyond a pass's reach changes no byte of any frame: the
    /// colour pass clipped at its far plane (4 samples a pixel), and a separate depth
    /// camera's single-sample pass beyond its range and what edge dropout compares (noise
    /// and dropout on), along a stretch of S3 of the default world looking down its lanes.
    #[test]
    fn culling_beyond_a_passs_reach_changes_no_byte() {
        let cfg = SimConfig::default();
        let sim = Simulation::new(&cfg, "s3", 7).expect("s3");
        let world = World::from_config(&cfg);
        let cam_cfg = CameraConfig {
            colour_far_clip_m: Some(6.0),
            depth_hfov_deg: Some(70.0),
            depth_registration: DepthRegistration::Stretched,
            depth_antialias_samples: 1,
            ..cfg.sensors.camera.clone()
        };
        assert!(cam_cfg.edge_dropout_ratio > 0.0 && cam_cfg.noise == NoiseProfile::Typical);
        let culled = RgbdCamera::new(&cam_cfg, &world);
        let whole = RgbdCamera {
            culling: false,
            ..RgbdCamera::new(&cam_cfg, &world)
        };
        let mut rng = crate::rng::stream(1, "cull");
        let (mut frames, mut valid) = (0, 0);
        for t_s in [20, 45, 70, 95] {
            let pose = sim.trajectory.pose(t_s * 1_000_000_000);
            let seed: u64 = rng.random();
            let a = culled.render(&pose, &mut crate::rng::stream(seed, "frame"));
            let b = whole.render(&pose, &mut crate::rng::stream(seed, "frame"));
            assert_eq!(a.rgb, b.rgb, "colour at {t_s} s");
            assert!(same_bits(&a.depth_m, &b.depth_m), "depth at {t_s} s");
            frames += 1;
            valid += a.depth_m.iter().filter(|&&z| z > 0.0).count();
        }
        assert_eq!(frames, 4);
        assert!(valid > 100_000, "{valid} valid depth pixels in 4 frames");
        // And culling leaves something out: the chunks a pass rasterizes.
        let pose = sim.trajectory.pose(45_000_000_000);
        let world_from_optical = pose * culled.base_from_camera_optical;
        let view = raster::View::new(&world_from_optical, &culled.intrinsics);
        let all = culled.chunks.visible(&view).len();
        let near = culled.chunks.visible(&view.culling_beyond(6.0)).len();
        assert!(
            (near as f64) < 0.7 * all as f64,
            "{near} of {all} chunks within 6 m"
        );
    }

    /// A lens's raw frame puts each surface where the lens model says: a raw pixel's depth,
    /// back-projected along its undistorted ray and projected through the pinhole, lands on
    /// the same surface in the pinhole frame from the same pose; along the pixel's own
    /// (distorted) ray, as a system that ignores the lens would read it, far less often.
    #[test]
    fn a_lens_puts_each_surface_where_its_model_says() {
        let cfg = SimConfig::default();
        let sim = Simulation::new(&cfg, "s3", 7).expect("s3");
        let world = World::from_config(&cfg);
        let pinhole_cfg = CameraConfig {
            noise: NoiseProfile::None,
            ..cfg.sensors.camera.clone()
        };
        // Stronger than a Kinect v2's colour lens (k1 0.03-0.08), so that ignoring it shows.
        let lens_cfg = CameraConfig {
            distortion: [-0.25, 0.05, 0.001, -0.001, 0.0],
            ..pinhole_cfg.clone()
        };
        let (pinhole, lens) = (
            RgbdCamera::new(&pinhole_cfg, &world),
            RgbdCamera::new(&lens_cfg, &world),
        );
        let d = Distortion::new(lens_cfg.distortion).unwrap();
        let k = pinhole.intrinsics();
        assert_eq!(
            lens.intrinsics(),
            k,
            "the raw frame keeps the configured camera matrix"
        );
        let (mut lens_hits, mut naive_hits, mut n) = (0usize, 0usize, 0usize);
        for t_s in [30, 60] {
            let pose = sim.trajectory.pose(t_s * 1_000_000_000);
            let raw = lens.render(&pose, &mut crate::rng::stream(1, "frame"));
            let pin = pinhole.render(&pose, &mut crate::rng::stream(1, "frame"));
            assert_eq!((raw.width, raw.height), (k.width, k.height));
            // Whether the point of ray (x, y) at depth z is the pinhole frame's surface there.
            let on_surface = |x: f64, y: f64, z: f64| {
                let (u, v) = ((k.fx * x + k.cx).round(), (k.fy * y + k.cy).round());
                if u < 0.0 || v < 0.0 || u >= k.width as f64 || v >= k.height as f64 {
                    return None;
                }
                let zp = f64::from(pin.depth_m[v as usize * k.width + u as usize]);
                Some(zp > 0.0 && (zp - z).abs() < 0.02 * z)
            };
            for v in (0..k.height).step_by(3) {
                for u in (0..k.width).step_by(3) {
                    let z = f64::from(raw.depth_m[v * k.width + u]);
                    let (xd, yd) = ((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy);
                    let (x, y) = d.undistort(xd, yd).unwrap();
                    // Only where the lens moves the pixel by 3 pixels or more.
                    if z <= 0.0 || ((x - xd) * k.fx).hypot((y - yd) * k.fy) < 3.0 {
                        continue;
                    }
                    let (Some(a), Some(b)) = (on_surface(x, y, z), on_surface(xd, yd, z)) else {
                        continue;
                    };
                    n += 1;
                    lens_hits += usize::from(a);
                    naive_hits += usize::from(b);
                }
            }
        }
        let (lens_rate, naive_rate) = (lens_hits as f64 / n as f64, naive_hits as f64 / n as f64);
        assert!(n > 2000, "only {n} pixels the lens moves by 3 px or more");
        assert!(
            lens_rate > 0.9 && naive_rate < lens_rate - 0.15,
            "on the pinhole frame's surface: {lens_rate:.3} along the undistorted rays, \
             {naive_rate:.3} along the raw pixels' own (n = {n})"
        );
    }
}
