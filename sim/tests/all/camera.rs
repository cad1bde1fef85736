//! The RGB-D camera from outside the crate: depth against analytic geometry and the BVH ray
//! caster, clones looking identical, determinism, the depth-noise model; plus an ignored
//! test that regenerates the sample frames in docs/camera/.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use sim::camera::{RgbdCamera, RgbdImage, axial_sigma_m, save_depth_png, save_rgb_png};
use sim::config::{CameraConfig, Mount, NoiseProfile, TerrainConfig, VineyardConfig};
use sim::raycast::{Bvh, RayCaster};
use sim::rng::stream;
use sim::world::{Terrain, World};

fn pose(x: f64, y: f64, z: f64, yaw_deg: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
    )
}

fn flat_world(vineyard: &VineyardConfig) -> World {
    World::build_on(vineyard, &TerrainConfig::flat(), Terrain::flat(), 1)
}

fn exact() -> CameraConfig {
    CameraConfig {
        noise: NoiseProfile::None,
        ..CameraConfig::default()
    }
}

/// The world-frame ray (scaled to optical z = 1) and origin of pixel (u, v).
fn pixel_ray(
    cam: &RgbdCamera,
    world_from_base: &Isometry3<f64>,
    u: usize,
    v: usize,
) -> (Point3<f64>, Vector3<f64>) {
    let world_from_optical = world_from_base * cam.base_from_camera_optical();
    let r = cam.intrinsics().ray(u as f64, v as f64);
    (
        world_from_optical * Point3::origin(),
        world_from_optical * Vector3::new(r[0], r[1], r[2]),
    )
}

fn mean_abs_rgb_difference(a: &RgbdImage, b: &RgbdImage) -> f64 {
    let sum: u64 = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .map(|(&x, &y)| u64::from(x.abs_diff(y)))
        .sum();
    sum as f64 / a.rgb.len() as f64
}

#[test]
fn depth_of_a_flat_ground_plane_is_the_ray_plane_distance() {
    let world = flat_world(&VineyardConfig::default());
    let cfg = CameraConfig {
        mount: Mount {
            xyz_m: [0.5, 0.0, 0.66],
            rpy_deg: [0.0, 30.0, 0.0],
        },
        shadows: false,
        ..exact()
    };
    let cam = RgbdCamera::new(&cfg, &world);
    // Outside the block, looking away from it: nothing but ground in view.
    let base = pose(-8.0, -8.0, 0.0, -135.0);
    let image = cam.render(&base, &mut stream(1, "camera"));
    let (mut checked, mut worst) = (0, 0.0f64);
    for v in 0..image.height {
        for u in 0..image.width {
            let (o, d) = pixel_ray(&cam, &base, u, v);
            let expected = if d.z < 0.0 { -o.z / d.z } else { f64::INFINITY };
            let got = f64::from(image.depth_m[v * image.width + u]);
            if (0.501..7.999).contains(&expected) {
                worst = worst.max((got - expected).abs());
                checked += 1;
            } else if !(0.499..8.001).contains(&expected) {
                assert_eq!(
                    got, 0.0,
                    "pixel ({u}, {v}): expected depth {expected} m out of range, so 0"
                );
            }
        }
    }
    assert!(
        checked > 100_000,
        "expected most pixels on the ground, got {checked}"
    );
    assert!(
        worst < 1e-3,
        "expected depth within 1 mm of the ray-plane distance, worst {worst} m"
    );
}

/// Depth against the BVH ray caster, ray by ray. Without anti-aliasing a pixel's depth is
/// the surface its central ray hits. With 4 samples it is that of the surface covering most
/// of the pixel's samples (see `sim::camera`'s doc), which the central ray may miss: a wire
/// or a stem that falls between pixel centres now shows in the pixels it crosses. So the
/// anti-aliased frame is checked against the rays through the pixel's centre and through
/// its four samples: its depth must be that of one of their hits.
#[test]
fn depth_back_projects_onto_the_surface_the_bvh_hits() {
    let cfg = sim::SimConfig::default();
    let world = World::build(&cfg.vineyard, &cfg.terrain, cfg.world_seed);
    let bvh = Bvh::build(&world.mesh);
    let (x, y) = (4.0, cfg.vineyard.lane_y(3));
    let base = pose(x, y, world.terrain.height(x, y), 5.0);
    for samples in [1, 4] {
        let cam = RgbdCamera::new(
            &CameraConfig {
                antialias_samples: samples,
                ..exact()
            },
            &world,
        );
        let image = cam.render(&base, &mut stream(1, "camera"));
        let k = cam.intrinsics();
        let world_from_optical = base * cam.base_from_camera_optical();
        let o = world_from_optical * Point3::origin();
        // The optical-axis depth of the BVH's hit along the ray through image point (x, y).
        let hit_depth = |x: f64, y: f64| {
            let r = k.ray(x, y);
            let d = world_from_optical * Vector3::new(r[0], r[1], r[2]);
            let dir: Vector3<f32> = d.normalize().cast();
            bvh.cast(&o.cast(), &dir, 0.01, 100.0)
                .map(|hit| f64::from(hit.t) / d.norm())
        };
        let (mut valid, mut centre, mut any) = (0usize, 0usize, 0usize);
        for v in (0..image.height).step_by(2) {
            for u in (0..image.width).step_by(2) {
                let z = f64::from(image.depth_m[v * image.width + u]);
                if z == 0.0 {
                    continue;
                }
                valid += 1;
                // 1 cm along the ray, as a depth.
                let tolerance = 0.01
                    / k.ray(u as f64, v as f64)
                        .iter()
                        .map(|c| c * c)
                        .sum::<f64>()
                        .sqrt();
                let agrees =
                    |x: f64, y: f64| hit_depth(x, y).is_some_and(|d| (d - z).abs() < tolerance);
                if agrees(u as f64, v as f64) {
                    centre += 1;
                    any += 1;
                } else if sim::camera::sample_offsets(samples)
                    .iter()
                    .any(|o| agrees(u as f64 + f64::from(o[0]), v as f64 + f64::from(o[1])))
                {
                    any += 1;
                }
            }
        }
        eprintln!(
            "{samples} sample(s): depth agrees with the BVH within 1 cm on {centre} of {valid} \
             valid pixels along the central ray, {any} along the central ray or a sample's"
        );
        assert!(
            valid > 20_000,
            "expected a lane full of surfaces, got {valid} valid pixels"
        );
        let share = any as f64 / valid as f64;
        assert!(
            share >= 0.99,
            "expected >= 99 % of valid pixels within 1 cm of the BVH's hit along a ray of the \
             pixel ({samples} sample(s)), got {:.2} % ({any}/{valid})",
            100.0 * share
        );
    }
}

/// Mean absolute RGB difference over the pixels that see the plant row in front (points
/// over 10 cm above the flat ground and within 2.5 m): the ground is textured in world
/// space and the rows behind differ in number, so only the plants themselves must match.
fn plant_difference(
    cam: &RgbdCamera,
    base: &Isometry3<f64>,
    a: &RgbdImage,
    b: &RgbdImage,
) -> (f64, usize) {
    let (mut sum, mut n) = (0u64, 0usize);
    for v in 0..a.height {
        for u in 0..a.width {
            let i = v * a.width + u;
            let z = f64::from(a.depth_m[i]);
            let (o, d) = pixel_ray(cam, base, u, v);
            if z == 0.0 || z > 2.5 || (o + d * z).z < 0.1 {
                continue;
            }
            n += 1;
            sum += (0..3)
                .map(|c| u64::from(a.rgb[3 * i + c].abs_diff(b.rgb[3 * i + c])))
                .sum::<u64>();
        }
    }
    (sum as f64 / (3 * n.max(1)) as f64, n)
}

#[test]
fn clones_look_identical_and_varied_plants_do_not() {
    // Row 3 plant 2 and row 5 plant 8 stand at the same offset from their posts; each is
    // seen from the same pose relative to its trunk, 2 m away in the lane before it.
    let frame = |variation: f64| {
        let v = VineyardConfig {
            plant_variation: variation,
            ..VineyardConfig::default()
        };
        let world = flat_world(&v);
        let cam = RgbdCamera::new(&exact(), &world);
        let base_for = |row: usize, plant: usize| {
            let site = world
                .plants
                .iter()
                .find(|p| p.row == row && p.index == plant)
                .expect("plant exists");
            pose(site.base.x, site.base.y - 2.0, 0.0, 90.0)
        };
        let (pa, pb) = (base_for(3, 2), base_for(5, 8));
        let a = cam.render(&pa, &mut stream(1, "camera"));
        let b = cam.render(&pb, &mut stream(1, "camera"));
        (
            plant_difference(&cam, &pa, &a, &b),
            mean_abs_rgb_difference(&a, &b),
        )
    };
    let ((clones, n0), clones_all) = frame(0.0);
    let ((varied, n1), varied_all) = frame(1.0);
    eprintln!(
        "mean abs RGB difference on the plant row: clones {clones:.2} ({n0} px), varied \
         {varied:.2} ({n1} px); whole frame: clones {clones_all:.2}, varied {varied_all:.2}"
    );
    assert!(
        n0 > 20_000 && n1 > 20_000,
        "expected the plant row to fill part of the frame"
    );
    assert!(
        clones < 2.0,
        "expected clones to look nearly identical (< 2 levels), got {clones:.2}"
    );
    assert!(
        varied > 5.0 * clones.max(1.0),
        "expected varied plants to differ clearly (> 5x the clones' {clones:.2}), got {varied:.2}"
    );
}

#[test]
fn frames_are_deterministic_for_a_seed_and_any_thread_count() {
    let cfg = sim::SimConfig::default();
    let v = VineyardConfig {
        rows: 3,
        ..cfg.vineyard.clone()
    };
    let world = World::build(&v, &cfg.terrain, 1);
    let cam = RgbdCamera::new(&CameraConfig::default(), &world);
    let base = pose(
        2.0,
        v.lane_y(0),
        world.terrain.height(2.0, v.lane_y(0)),
        0.0,
    );
    let a = cam.render(&base, &mut stream(7, "camera"));
    let b = cam.render(&base, &mut stream(7, "camera"));
    assert!(a == b, "expected identical bytes for the same seed");
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool")
        .install(|| cam.render(&base, &mut stream(7, "camera")));
    assert!(a == one_thread, "expected identical bytes on one thread");
    let c = cam.render(&base, &mut stream(8, "camera"));
    assert!(
        a.rgb != c.rgb,
        "expected another seed to give other colour noise"
    );
    assert!(
        a.depth_m != c.depth_m,
        "expected another seed to give other depth noise"
    );
}

#[test]
fn depth_noise_at_three_metres_matches_the_kinect_v2_model() {
    let world = flat_world(&VineyardConfig::default());
    let down = |noise| CameraConfig {
        mount: Mount {
            xyz_m: [0.0, 0.0, 0.0],
            rpy_deg: [0.0, 90.0, 0.0],
        },
        noise,
        shadows: false,
        ..CameraConfig::default()
    };
    let base = pose(-4.0, -4.0, 3.0, 0.0);
    let noisy = RgbdCamera::new(&down(NoiseProfile::Typical), &world)
        .render(&base, &mut stream(3, "camera"));
    let clean =
        RgbdCamera::new(&down(NoiseProfile::None), &world).render(&base, &mut stream(3, "camera"));
    let (w, h) = (noisy.width, noisy.height);
    let (mut sum, mut sum2, mut model, mut n) = (0.0, 0.0, 0.0, 0.0);
    for v in h / 2 - 60..h / 2 + 60 {
        for u in w / 2 - 60..w / 2 + 60 {
            let i = v * w + u;
            let (z, z0) = (f64::from(noisy.depth_m[i]), f64::from(clean.depth_m[i]));
            assert!(
                z > 0.0 && (z0 - 3.0).abs() < 0.05,
                "expected ground at 3 m at ({u}, {v})"
            );
            let e = z - z0;
            sum += e;
            sum2 += e * e;
            let theta = (u as f64 - 319.5).hypot(v as f64 - 239.5).atan2(457.0);
            model += f64::from(axial_sigma_m(z0 as f32, theta as f32));
            n += 1.0;
        }
    }
    let mean = sum / n;
    let sigma = (sum2 / n - mean * mean).sqrt();
    let expected = model / n;
    eprintln!("depth noise at 3 m: σ {sigma:.5} m, model {expected:.5} m, mean {mean:.6} m");
    assert!(
        (sigma / expected - 1.0).abs() < 0.2,
        "expected σ within 20 % of the model's {expected:.5} m, got {sigma:.5} m"
    );
    assert!(
        mean.abs() < 0.2 * expected,
        "expected zero-mean noise, got a mean of {mean} m"
    );
}

/// Regenerates docs/camera/*.png: `cargo test -p vinebench-sim --release --test all --
/// --ignored camera::sample_frames`.
#[test]
#[ignore = "writes docs/camera/*.png"]
fn sample_frames() {
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/camera");
    std::fs::create_dir_all(&out).expect("docs/camera");
    let cfg = sim::SimConfig::default();
    for stage in [1.0, 4.0] {
        for variation in [0.0, 1.0] {
            let v = VineyardConfig {
                growth_stage: stage,
                plant_variation: variation,
                ..cfg.vineyard.clone()
            };
            let world = World::build(&v, &cfg.terrain, cfg.world_seed);
            // Noise-free colour keeps the PNGs small (σ = 2 levels is invisible anyway);
            // depth keeps its noise and edge dropout.
            let cam = RgbdCamera::new(&cfg.sensors.camera, &world);
            let clean = RgbdCamera::new(&exact(), &world);
            let (x, y) = (3.0, v.lane_y(3) - 0.2);
            let base = pose(x, y, world.terrain.height(x, y), 4.0);
            let image = cam.render(&base, &mut stream(1, "camera"));
            let mut colour = clean.render(&base, &mut stream(1, "camera"));
            // 64 levels per channel: invisible, and halves the committed PNGs.
            colour.rgb.iter_mut().for_each(|c| *c = (*c & !3) | 2);
            let name = format!("stage{stage}_variation{variation}");
            save_rgb_png(&out.join(format!("{name}_rgb.png")), &colour).expect("rgb png");
            save_depth_png(&out.join(format!("{name}_depth.png")), &image, 8.0).expect("depth png");
            if stage == 4.0 && variation == 0.0 {
                // The renderer before: one sample a pixel, point-sampled materials.
                let before = CameraConfig {
                    antialias_samples: 1,
                    filter_materials: false,
                    ..exact()
                };
                let mut colour =
                    RgbdCamera::new(&before, &world).render(&base, &mut stream(1, "camera"));
                colour.rgb.iter_mut().for_each(|c| *c = (*c & !3) | 2);
                save_rgb_png(&out.join(format!("{name}_rgb_single_sample.png")), &colour)
                    .expect("rgb png");
            }
        }
    }
}

/// A world whose only geometry is two walls facing the camera (the default mount on a base
/// at the origin, looking along world x): a near wall of bark, 6 m ahead of the lens, over
/// the left part of the image up to a slanted edge, and a far wall of grapes 7 m ahead
/// behind everything. At these ranges both materials are filtered to their mean colour, the
/// sun (from behind the camera) lights both alike and there are no shadows: each wall is
/// one flat colour (but for a trace of haze), so an edge pixel's colour is known.
struct TwoWalls {
    world: World,
    /// The edge's ends in the image (pixels), near wall on the left of the line from the
    /// first to the second.
    edge: [[f64; 2]; 2],
}

const NEAR_DEPTH_M: f64 = 6.0;
const FAR_DEPTH_M: f64 = 7.0;

fn two_walls() -> TwoWalls {
    use sim::world::{Material, Mesh};
    let mut world = flat_world(&VineyardConfig {
        rows: 1,
        ..VineyardConfig::default()
    });
    let mut mesh = Mesh::new();
    // The lens is at x = 0.5 m (the mount), so the walls stand at 6.5 m and 7.5 m.
    let (xn, xf) = (0.5 + NEAR_DEPTH_M as f32, 0.5 + FAR_DEPTH_M as f32);
    let v = |m: &mut Mesh, x: f32, y: f32, z: f32| m.push_vertex(Point3::new(x, y, z));
    let far = [
        v(&mut mesh, xf, -40.0, -20.0),
        v(&mut mesh, xf, 40.0, -20.0),
        v(&mut mesh, xf, 0.0, 40.0),
    ];
    mesh.push_triangle(far, Material::Grape);
    let (bottom, top) = ([1.0f32, -20.0], [-0.5f32, 20.0]);
    let near = [
        v(&mut mesh, xn, bottom[0], bottom[1]),
        v(&mut mesh, xn, top[0], top[1]),
        v(&mut mesh, xn, 40.0, 0.0),
    ];
    mesh.push_triangle(near, Material::Bark);
    world.mesh = mesh;
    // The edge in the image: u = cx - fx y / depth, v = cy - fy (z - 0.66) / depth.
    let k = sim::camera::Intrinsics::from_config(&CameraConfig::default());
    let project = |[y, z]: [f32; 2]| {
        let d = NEAR_DEPTH_M;
        [
            k.cx - k.fx * f64::from(y) / d,
            k.cy - k.fy * (f64::from(z) - 0.66) / d,
        ]
    };
    TwoWalls {
        world,
        edge: [project(bottom), project(top)],
    }
}

fn wall_camera(samples: usize) -> CameraConfig {
    CameraConfig {
        antialias_samples: samples,
        shadows: false,
        sun_azimuth_deg: 180.0,
        ..exact()
    }
}

impl TwoWalls {
    /// Signed distance (pixels) of image point `p` from the edge, positive on the near
    /// wall's side.
    fn side(&self, p: [f64; 2]) -> f64 {
        let [a, b] = self.edge;
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        // The near wall lies to the left (smaller u) of the edge as drawn upwards.
        ((p[0] - a[0]) * ey - (p[1] - a[1]) * ex) / ex.hypot(ey)
    }
}

fn linear(byte: u8) -> f64 {
    (f64::from(byte) / 255.0).powi(2)
}

/// The 4x MSAA resolve on an edge between two known colours: every pixel the edge crosses
/// shows the coverage-weighted mean (in linear light) of the two walls' colours, `k / 4` of
/// the near wall's for `k` of its 4 samples on the near wall; its depth is that of the wall
/// covering most samples (ties to the nearer), never a depth between the walls.
#[test]
fn an_edge_pixel_is_the_coverage_weighted_blend_of_the_two_surfaces() {
    let scene = two_walls();
    let cam = RgbdCamera::new(&wall_camera(4), &scene.world);
    let image = cam.render(&pose(0.0, 0.0, 0.0, 0.0), &mut stream(1, "camera"));
    let pattern = sim::camera::sample_offsets(4);
    let (w, h) = (image.width, image.height);
    let px = |u: usize, v: usize| &image.rgb[3 * (v * w + u)..3 * (v * w + u) + 3];
    let (mut per_k, mut worst) = ([0usize; 5], 0.0f64);
    for v in 2..h - 2 {
        for u in 4..w - 4 {
            let centre = [u as f64, v as f64];
            let sides: Vec<f64> = pattern
                .iter()
                .map(|o| scene.side([centre[0] + f64::from(o[0]), centre[1] + f64::from(o[1])]))
                .collect();
            let k = sides.iter().filter(|&&s| s > 0.0).count();
            let depth = f64::from(image.depth_m[v * w + u]);
            let expected_depth = if k >= 2 { NEAR_DEPTH_M } else { FAR_DEPTH_M };
            assert!(
                (depth - expected_depth).abs() < 1e-4,
                "pixel ({u}, {v}) with {k} of 4 samples on the near wall: expected depth \
                 {expected_depth} m, got {depth} m"
            );
            if !(1..=3).contains(&k) || sides.iter().any(|s| s.abs() < 0.01) {
                continue;
            }
            per_k[k] += 1;
            // The walls' colours 4 columns away on either side, wholly inside each.
            let (near, far) = (px(u - 4, v), px(u + 4, v));
            assert!(
                scene.side([u as f64 - 4.0, v as f64]) > 1.0
                    && scene.side([u as f64 + 4.0, v as f64]) < -1.0,
                "expected the reference pixels inside the walls"
            );
            let share = k as f64 / 4.0;
            for c in 0..3 {
                let expected =
                    255.0 * (share * linear(near[c]) + (1.0 - share) * linear(far[c])).sqrt();
                let got = f64::from(px(u, v)[c]);
                worst = worst.max((got - expected).abs());
            }
        }
    }
    let (near, far) = (px(10, 240), px(630, 240));
    eprintln!(
        "edge pixels by near-wall samples (1, 2, 3 of 4): {:?}; worst difference from the \
         coverage-weighted blend {worst:.2} levels; walls {near:?} and {far:?}",
        &per_k[1..4]
    );
    assert!(
        near.iter().zip(far).map(|(a, b)| a.abs_diff(*b)).max() > Some(25),
        "expected walls of clearly different colours, got {near:?} and {far:?}"
    );
    assert!(
        per_k[1..4].iter().all(|&n| n >= 50),
        "expected at least 50 edge pixels of each coverage, got {:?}",
        &per_k[1..4]
    );
    // Quantisation of the pixel and of its two references: about a level at most.
    assert!(
        worst <= 1.5,
        "expected edge pixels within 1.5 levels of the coverage-weighted blend, worst {worst:.2}"
    );
}

/// Where all samples of a pixel see one triangle, anti-aliasing changes nothing: the pixel
/// is shaded once at its centre, exactly as the single-sample renderer shades it.
#[test]
fn a_pixel_inside_one_triangle_is_the_single_sample_shading() {
    let scene = two_walls();
    let base = pose(0.0, 0.0, 0.0, 0.0);
    let aa = RgbdCamera::new(&wall_camera(4), &scene.world).render(&base, &mut stream(1, "camera"));
    let single =
        RgbdCamera::new(&wall_camera(1), &scene.world).render(&base, &mut stream(1, "camera"));
    let (mut inside, mut differ) = (0usize, 0usize);
    for v in 0..aa.height {
        for u in 0..aa.width {
            // Farther than a pixel's half-diagonal from the edge: all samples on one side.
            if scene.side([u as f64, v as f64]).abs() < 0.75 {
                continue;
            }
            inside += 1;
            let i = v * aa.width + u;
            if aa.rgb[3 * i..3 * i + 3] != single.rgb[3 * i..3 * i + 3]
                || aa.depth_m[i] != single.depth_m[i]
            {
                differ += 1;
            }
        }
    }
    assert!(
        inside > 300_000,
        "expected most pixels inside a wall, got {inside}"
    );
    assert_eq!(
        differ, 0,
        "expected every pixel inside a wall to equal the single-sample render, {differ} of \
         {inside} differ"
    );
    let edge_differs = (0..aa.rgb.len())
        .filter(|&i| aa.rgb[i] != single.rgb[i])
        .count();
    assert!(
        edge_differs > 0,
        "expected the edge pixels to differ with anti-aliasing"
    );
}

/// Frames (anti-aliased or not, with noise) hashed on thread pools of 1, 2 and 3 threads
/// along S3: the bytes never depend on the thread count.
#[test]
fn frames_hash_the_same_on_one_two_and_three_threads() {
    use std::hash::{DefaultHasher, Hash, Hasher};
    let cfg = sim::SimConfig::default();
    let sim = sim::Simulation::new(&cfg, "s3", 1).expect("scenario s3");
    for samples in [1, 4] {
        let cam = RgbdCamera::new(
            &CameraConfig {
                antialias_samples: samples,
                ..cfg.sensors.camera.clone()
            },
            &sim.world,
        );
        let hashes: Vec<u64> = [1, 2, 3]
            .iter()
            .map(|&threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("pool");
                let mut hasher = DefaultHasher::new();
                let mut rng = stream(5, "camera");
                for t_s in [3.0, 40.0, 120.0] {
                    let image = pool
                        .install(|| cam.render(&sim.trajectory.pose((t_s * 1e9) as i64), &mut rng));
                    image.rgb.hash(&mut hasher);
                    for z in &image.depth_m {
                        z.to_bits().hash(&mut hasher);
                    }
                }
                hasher.finish()
            })
            .collect();
        eprintln!("antialias_samples = {samples}: frame hashes on 1, 2, 3 threads {hashes:x?}");
        assert!(
            hashes.iter().all(|&h| h == hashes[0]),
            "expected the same frames on 1, 2 and 3 threads with {samples} sample(s), got {hashes:x?}"
        );
    }
}
