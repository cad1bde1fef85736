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

#[test]
fn depth_back_projects_onto_the_surface_the_bvh_hits() {
    let cfg = sim::SimConfig::default();
    let world = World::build(&cfg.vineyard, &cfg.terrain, cfg.world_seed);
    let cam = RgbdCamera::new(&exact(), &world);
    let bvh = Bvh::build(&world.mesh);
    let (x, y) = (4.0, cfg.vineyard.lane_y(3));
    let base = pose(x, y, world.terrain.height(x, y), 5.0);
    let image = cam.render(&base, &mut stream(1, "camera"));
    let (mut valid, mut agree) = (0usize, 0usize);
    for v in (0..image.height).step_by(2) {
        for u in (0..image.width).step_by(2) {
            let z = f64::from(image.depth_m[v * image.width + u]);
            if z == 0.0 {
                continue;
            }
            valid += 1;
            let (o, d) = pixel_ray(&cam, &base, u, v);
            let range = z * d.norm();
            let dir: Vector3<f32> = d.normalize().cast();
            if let Some(hit) = bvh.cast(&o.cast(), &dir, 0.01, 100.0) {
                if (f64::from(hit.t) - range).abs() < 0.01 {
                    agree += 1;
                }
            }
        }
    }
    assert!(
        valid > 20_000,
        "expected a lane full of surfaces, got {valid} valid pixels"
    );
    let share = agree as f64 / valid as f64;
    eprintln!("depth agrees with the BVH within 1 cm on {agree} of {valid} valid pixels");
    assert!(
        share >= 0.99,
        "expected >= 99 % of valid pixels within 1 cm of the BVH's hit, got {:.2} % ({agree}/{valid})",
        100.0 * share
    );
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

/// Regenerates docs/camera/*.png: `cargo test -p vinebench-sim --release --test camera --
/// --ignored sample_frames`.
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
        }
    }
}
