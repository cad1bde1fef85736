//! The paper's own world (`configs/paper-world.toml`, from LCAS/bacchus_lcas, branch
//! `liosam`): its routes, its fence, its camera pair and its determinism.

use nalgebra::{Point3, Vector3};
use sim::camera::RgbdCamera;
use sim::config::{CameraConfig, DepthRegistration, NoiseProfile, SimConfig};
use sim::raycast::{Bvh, RayCaster};
use sim::rng::stream;
use sim::sensors::Message;
use sim::world::World;
use sim::{SensorSet, Simulation};

fn paper_world() -> SimConfig {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/paper-world.toml");
    SimConfig::from_file(std::path::Path::new(path)).expect("configs/paper-world.toml parses")
}

/// Length of the base's driven path, from the ground truth every 10 ms.
fn driven(sim: &Simulation) -> f64 {
    let step = 10_000_000;
    (step..=sim.duration_ns())
        .step_by(step as usize)
        .map(|t| {
            let (a, b) = (sim.trajectory.pose(t - step), sim.trajectory.pose(t));
            (b.translation.vector - a.translation.vector).xy().norm()
        })
        .sum()
}

/// The four routes as the paper's goal files give them, driven by the controller: within
/// 5 % of the paper's lengths (S0's waypoints alone span 26 m), starting at the spawn pose
/// facing east and ending at the start, turned as send_goals.py turned the robot.
#[test]
fn the_papers_routes_are_driven_at_their_published_lengths() {
    let cfg = paper_world();
    let world = World::from_config(&cfg);
    for (name, paper, end_yaw_deg) in [
        ("s0", 25.0, 180.0),
        ("s1", 48.6, 180.0),
        ("s2", 54.6, 180.0),
        ("s3", 101.2, 180.0),
    ] {
        let sim = Simulation::with_world(&cfg, world.clone(), name, 0).expect("builds");
        let len = driven(&sim);
        eprintln!("{name}: driven {len:.2} m, paper {paper} m");
        assert!(
            (len - paper).abs() / paper < 0.05,
            "{name}: driven {len:.2} m, paper {paper} m"
        );
        let start = sim.trajectory.pose(0);
        assert!(
            (start.translation.vector.xy() - nalgebra::Vector2::new(15.0, -10.15)).norm() < 1e-9,
            "{name} starts at the spawn point"
        );
        let end = sim.trajectory.pose(sim.duration_ns());
        let yaw = end.rotation.euler_angles().2.to_degrees();
        let off = (yaw - end_yaw_deg + 540.0).rem_euclid(360.0) - 180.0;
        assert!(off.abs() < 2.0, "{name} ends facing {yaw:.1}°");
    }
    // S3 drives lanes 11 and 5.2 southwards and lane 8 northwards.
    let sim = Simulation::with_world(&cfg, world, "s3", 0).expect("builds");
    let mut lanes = Vec::new();
    let step = 100_000_000;
    for t in (0..sim.duration_ns()).step_by(step as usize) {
        let (a, b) = (sim.trajectory.pose(t), sim.trajectory.pose(t + step));
        let d = b.translation.vector - a.translation.vector;
        let x = a.translation.x;
        if a.translation.y.abs() < 5.0 && d.norm() > 0.03 {
            let lane = [11.0, 8.0, 5.2].into_iter().find(|l| (x - l).abs() < 0.15);
            if let Some(lane) = lane {
                let entry = (lane, d.y.signum());
                if lanes.last() != Some(&entry) {
                    lanes.push(entry);
                }
            }
        }
    }
    assert_eq!(lanes, [(11.0, -1.0), (8.0, 1.0), (5.2, -1.0)], "S3's lanes");
}

/// The fence stands about 1.45 m to the robot's right at the start of S0: the lidar's two
/// beams nearest the horizontal see its near face (y = -11.606 for the panels there) at that
/// range, and without the fence they see nothing at that bearing.
#[test]
fn the_lidar_sees_the_fence_beside_the_south_headland() {
    let mut cfg = paper_world();
    cfg.sensors.lidar.noise = NoiseProfile::None;
    let first_scan = |cfg: &SimConfig| {
        let sim = Simulation::new(cfg, "s0", 0).expect("builds");
        let scan = sim
            .stream(SensorSet {
                lidar: true,
                ..SensorSet::default()
            })
            .find_map(|m| match m {
                Message::Lidar(s) => Some(s),
                _ => None,
            })
            .expect("a sweep");
        // The sweep is taken at once from the pose at its stamp (the robot stands still,
        // facing east, rolled a little by the relief).
        let world_from_lidar =
            sim.trajectory.pose(scan.stamp_ns) * cfg.sensors.lidar.mount.base_from_sensor();
        // Points of rings 7 and 8 (-1° and +1°) within 3° of the robot's right (-y).
        scan.points
            .iter()
            .filter(|p| {
                let azimuth = f64::from(p.y.atan2(p.x)).to_degrees();
                (p.ring == 7 || p.ring == 8) && (azimuth + 90.0).abs() < 3.0
            })
            .map(|p| {
                let range = f64::from(p.x.hypot(p.y));
                let world =
                    world_from_lidar * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                (range, world.y)
            })
            .collect::<Vec<_>>()
    };
    let seen = first_scan(&cfg);
    assert!(seen.len() >= 20, "beams to the right: {seen:?}");
    for (range, y) in &seen {
        assert!(
            (1.40..1.60).contains(range) && (y + 11.606).abs() < 0.005,
            "expected the fence's face at y = -11.606, {range:.3} m away; got y = {y:.4}"
        );
    }
    cfg.fence.panels.clear();
    let without = first_scan(&cfg);
    assert!(
        without.iter().all(|(r, _)| *r > 5.0),
        "without the fence nothing stands there: {without:?}"
    );
}

fn exact(mut c: CameraConfig) -> CameraConfig {
    c.noise = NoiseProfile::None;
    c
}

/// Gazebo's colour camera draws nothing beyond its 10 m far clip: every pixel that sees
/// no surface nearer than 10 m (by an unclipped rendering) shows the uniform grey
/// background, and the pixels that see near surfaces are unchanged by the clip.
#[test]
fn colour_beyond_ten_metres_is_the_grey_background() {
    let cfg = paper_world();
    let world = World::from_config(&cfg);
    // Looking west along the south headland from its middle: ground to the horizon.
    let (x, y) = (2.0, -10.15);
    let base = nalgebra::Isometry3::new(
        Vector3::new(x, y, world.terrain.height(x, y)),
        Vector3::z() * std::f64::consts::PI,
    );
    // One sample a pixel: a pixel's colour is then the surface on its central ray alone.
    let clipped_cfg = exact(CameraConfig {
        depth_hfov_deg: None,
        antialias_samples: 1,
        ..cfg.sensors.camera.clone()
    });
    let unclipped_cfg = CameraConfig {
        colour_far_clip_m: None,
        background: sim::config::Background::default(),
        max_depth_m: 200.0,
        ..clipped_cfg.clone()
    };
    let clipped = RgbdCamera::new(&clipped_cfg, &world).render(&base, &mut stream(1, "c"));
    let unclipped = RgbdCamera::new(&unclipped_cfg, &world).render(&base, &mut stream(1, "c"));
    let grey = (0.7f64 * 255.0).round() as u8;
    let (mut far, mut near, mut near_same) = (0, 0, 0);
    for (i, &z) in unclipped.depth_m.iter().enumerate() {
        let (a, b) = (
            &clipped.rgb[3 * i..3 * i + 3],
            &unclipped.rgb[3 * i..3 * i + 3],
        );
        // Away from the clip plane by 0.3 m, so no pixel mixes both sides.
        if z == 0.0 || z > 10.3 {
            far += 1;
            assert_eq!(
                a, [grey; 3],
                "pixel {i} sees {z} m: expected the background"
            );
        } else if z < 9.7 {
            near += 1;
            near_same += usize::from(a == b);
        }
    }
    eprintln!("{far} pixels beyond the clip, {near} nearer ({near_same} unchanged)");
    assert!(
        far > 50_000 && near > 50_000,
        "both kinds of pixel: {far}, {near}"
    );
    assert!(
        near_same as f64 > 0.97 * near as f64,
        "near pixels unchanged: {near_same} of {near}"
    );
}

/// The paper's depth image is the 70° depth camera's, from the colour camera's centre,
/// handed over pixel for pixel: a pixel's depth is where the 70° camera's ray through it
/// meets the world, not where the colour camera's 84.1° ray does (except near the image
/// centre, where both rays nearly agree); registered, it is the colour camera's ray.
#[test]
fn stretched_depth_is_the_seventy_degree_rendering_from_the_colour_centre() {
    let cfg = paper_world();
    let world = World::from_config(&cfg);
    let bvh = Bvh::build(&world.mesh);
    let (x, y) = (11.0, -6.0);
    let base = nalgebra::Isometry3::new(
        Vector3::new(x, y, world.terrain.height(x, y)),
        Vector3::z() * std::f64::consts::FRAC_PI_2,
    );
    let hits = |reg: DepthRegistration| {
        let cam_cfg = exact(CameraConfig {
            depth_registration: reg,
            ..cfg.sensors.camera.clone()
        });
        let cam = RgbdCamera::new(&cam_cfg, &world);
        let image = cam.render(&base, &mut stream(1, "c"));
        let colour_k = cam.intrinsics();
        let depth_k = sim::camera::Intrinsics::with_hfov(&cam_cfg, 70.0);
        assert_eq!(
            image.intrinsics,
            [colour_k.fx, colour_k.fy, colour_k.cx, colour_k.cy],
            "the frame carries the colour intrinsics"
        );
        let world_from_optical = base * cam.base_from_camera_optical();
        let o: Point3<f32> = (world_from_optical * Point3::origin()).cast();
        // Does the ray through (u, v) of intrinsics k meet the world at optical depth z?
        let agrees = |k: &sim::camera::Intrinsics, u: usize, v: usize, z: f64| {
            let r = k.ray(u as f64, v as f64);
            let d = world_from_optical * Vector3::new(r[0], r[1], r[2]);
            bvh.cast(&o, &d.normalize().cast(), 0.01, 50.0)
                .is_some_and(|h| (f64::from(h.t) / d.norm() - z).abs() < 0.02)
        };
        let (mut valid, mut by_depth, mut by_colour) = (0, 0, 0);
        let w = image.width;
        for v in (0..image.height).step_by(4) {
            // Off-centre columns, where the two intrinsics' rays part by many pixels.
            for u in (0..w).step_by(4).filter(|u| u.abs_diff(w / 2) > 120) {
                let z = f64::from(image.depth_m[v * w + u]);
                if z > 0.0 {
                    valid += 1;
                    by_depth += usize::from(agrees(&depth_k, u, v, z));
                    by_colour += usize::from(agrees(&colour_k, u, v, z));
                }
            }
        }
        eprintln!("{reg:?}: {valid} valid, {by_depth} on the 70° rays, {by_colour} on the 84.1°");
        (valid, by_depth, by_colour)
    };
    let (valid, by_depth, by_colour) = hits(DepthRegistration::Stretched);
    assert!(valid > 2000, "valid off-centre pixels: {valid}");
    assert!(by_depth as f64 > 0.95 * valid as f64 && (by_colour as f64) < 0.5 * valid as f64);
    let (valid, by_depth, by_colour) = hits(DepthRegistration::Registered);
    assert!(valid > 1000, "valid off-centre pixels: {valid}");
    assert!(by_colour as f64 > 0.95 * valid as f64 && (by_depth as f64) < 0.5 * valid as f64);
}

/// The same configuration and seed give the same world and the same stream.
#[test]
fn the_papers_world_is_deterministic() {
    let cfg = paper_world();
    let digest = |seed: u64| {
        let sim = Simulation::new(&cfg, "s3", seed).expect("builds");
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut n = 0usize;
        for m in sim
            .stream(SensorSet::ALL)
            .take_while(|m| m.stamp_ns() < 400_000_000)
        {
            for b in format!("{m:?}").bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
            }
            n += 1;
        }
        (sim.world.mesh.triangle_count(), h, n)
    };
    let (a, b, c) = (digest(5), digest(5), digest(6));
    assert_eq!(a, b, "same seed, same world and stream");
    assert!(a.2 > 400, "0.4 s at 1 kHz IMU: {} messages", a.2);
    assert_eq!(a.0, c.0, "the world does not depend on the run's seed");
    assert_ne!(a.1, c.1, "another seed, other noise");
}

/// Segments are clones: with plant_variation = 0 every segment's plants are the first
/// segment's, moved; with 1 they differ; within a segment plants differ either way.
#[test]
fn segments_are_clones_of_one_another() {
    let mut cfg = paper_world();
    let local = |w: &World, i: usize| w.plant_local_vertices(i);
    let world = World::from_config(&cfg);
    let per = world.plants.iter().filter(|p| p.row == 0).count();
    assert_eq!(per, 6, "six plants in 5.75 m");
    assert_eq!(world.plants.len(), 26 * 6);
    let diff = |a: &[Point3<f32>], b: &[Point3<f32>]| {
        if a.len() != b.len() {
            return f32::INFINITY;
        }
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f32::max)
    };
    for s in 1..26 {
        for i in 0..per {
            let d = diff(&local(&world, i), &local(&world, s * per + i));
            assert!(d < 1e-3, "segment {s} plant {i} differs by {d} m");
        }
    }
    assert!(diff(&local(&world, 0), &local(&world, 1)) > 0.01);
    cfg.vineyard.plant_variation = 1.0;
    let varied = World::from_config(&cfg);
    assert!(diff(&local(&varied, 0), &local(&varied, per)) > 0.01);
}

/// The paper's Gazebo IMU: 1 kHz, noise-free, and its orientation is the true one.
#[test]
fn the_imu_reports_the_true_orientation_at_a_kilohertz() {
    let cfg = paper_world();
    let sim = Simulation::new(&cfg, "s1", 0).expect("builds");
    let base_from_imu = cfg.sensors.imu.mount.base_from_sensor();
    let mut n = 0;
    for m in sim.stream(SensorSet {
        imu: true,
        ..SensorSet::default()
    }) {
        let Message::Imu(m) = m else { continue };
        assert_eq!(m.stamp_ns, n * 1_000_000, "1 kHz");
        let q = m
            .orientation
            .expect("the paper's IMU reports its orientation");
        let truth = (sim.trajectory.pose(m.stamp_ns) * base_from_imu).rotation;
        assert!(
            q.angle_to(&truth) < 1e-12,
            "at {} ns: {}",
            m.stamp_ns,
            q.angle_to(&truth)
        );
        n += 1;
        if m.stamp_ns > 30_000_000_000 {
            break;
        }
    }
    assert!(n > 30_000, "{n} samples");
    let mut ours = cfg.clone();
    ours.sensors.imu.reports_orientation = false;
    let sim = Simulation::new(&ours, "s1", 0).expect("builds");
    let first = sim
        .stream(SensorSet {
            imu: true,
            ..SensorSet::default()
        })
        .find_map(|m| match m {
            Message::Imu(m) => Some(m),
            _ => None,
        })
        .expect("a sample");
    assert_eq!(first.orientation, None, "switched off, no orientation");
}

/// Regenerates docs/paper-world/frames: `cargo test -p vinebench-sim --release --test all --
/// --ignored paper_world::sample_frames`. Noise-free colour (as docs/camera) and the depth
/// as delivered, at the same moments of S0 and S3 in the paper's world and in ours.
#[test]
#[ignore = "writes docs/paper-world/*.png"]
fn sample_frames() {
    use sim::camera::{save_depth_png, save_rgb_png};
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/paper-world");
    std::fs::create_dir_all(&out).expect("docs/paper-world");
    for (world_name, cfg) in [("paper", paper_world()), ("ours", SimConfig::default())] {
        let world = World::from_config(&cfg);
        let cam = RgbdCamera::new(&cfg.sensors.camera, &world);
        let clean = RgbdCamera::new(&exact(cfg.sensors.camera.clone()), &world);
        // S0 in its middle; S3 a third of the way (in a lane in both worlds).
        for (scenario, fraction) in [("s0", 0.5), ("s3", 0.33)] {
            let sim = Simulation::with_world(&cfg, world.clone(), scenario, 0).expect("builds");
            let t = (sim.duration_ns() as f64 * fraction) as i64;
            let base = sim.trajectory.pose(t);
            let image = cam.render(&base, &mut stream(1, "camera"));
            let mut colour = clean.render(&base, &mut stream(1, "camera"));
            colour.rgb.iter_mut().for_each(|c| *c = (*c & !3) | 2);
            let name = format!("{world_name}_{scenario}");
            save_rgb_png(&out.join(format!("{name}_rgb.png")), &colour).expect("rgb png");
            save_depth_png(&out.join(format!("{name}_depth.png")), &image, 8.0).expect("png");
        }
    }
}

/// The depth camera's pass shades no colour but gives the depth the colour pass gives, bit
/// for bit: a separate depth camera with the colour camera's own field of view delivers the
/// registered depth image exactly.
#[test]
fn a_depth_pass_gives_the_colour_passes_depth_bit_for_bit() {
    let cfg = paper_world();
    let world = World::from_config(&cfg);
    let (x, y) = (8.0, 2.0);
    let base = nalgebra::Isometry3::new(
        Vector3::new(x, y, world.terrain.height(x, y) + 0.02),
        Vector3::new(0.02, -0.01, 1.4),
    );
    for samples in [1, 4] {
        let one = CameraConfig {
            depth_hfov_deg: None,
            antialias_samples: samples,
            ..cfg.sensors.camera.clone()
        };
        let two = CameraConfig {
            depth_hfov_deg: Some(one.hfov_deg),
            depth_registration: DepthRegistration::Stretched,
            depth_antialias_samples: samples,
            ..one.clone()
        };
        let a = RgbdCamera::new(&one, &world).render(&base, &mut stream(3, "c"));
        let b = RgbdCamera::new(&two, &world).render(&base, &mut stream(3, "c"));
        let valid = a.depth_m.iter().filter(|&&z| z > 0.0).count();
        assert!(valid > 100_000, "{valid} valid pixels");
        assert!(
            a.depth_m
                .iter()
                .zip(&b.depth_m)
                .all(|(p, q)| p.to_bits() == q.to_bits()),
            "{samples} sample(s): the depth pass differs from the colour pass"
        );
        assert_eq!(a.rgb, b.rgb, "the colour is the colour pass's");
    }
}

/// `fence.distinct_panels` changes the panels' wood only: the same geometry and the same
/// texture everywhere else, and each panel's texture coordinates moved by its own offset
/// (with the switch off, every panel has the same ones, as the paper's copies of one mesh).
#[test]
fn distinct_fence_panels_differ_in_texture_only() {
    let same = paper_world();
    let mut distinct = same.clone();
    distinct.fence.distinct_panels = true;
    let (a, b) = (World::from_config(&same), World::from_config(&distinct));
    assert_eq!(a.mesh.vertices, b.mesh.vertices, "geometry unchanged");
    assert_eq!(a.mesh.triangles, b.mesh.triangles);
    assert_eq!(a.mesh.materials, b.mesh.materials);
    // The panels are the last vertices built: 8 each.
    let panels = same.fence.panels.len();
    assert!(panels > 10, "the paper's fence has {panels} panels");
    let first_panel = a.mesh.vertices.len() - 8 * panels;
    assert_eq!(
        a.mesh.tex[..first_panel],
        b.mesh.tex[..first_panel],
        "the rest of the world keeps its texture"
    );
    let panel_tex =
        |w: &World, k: usize| w.mesh.tex[first_panel + 8 * k..first_panel + 8 * (k + 1)].to_vec();
    for k in 1..panels {
        assert_eq!(panel_tex(&a, k), panel_tex(&a, 0), "identical panels: {k}");
        assert_ne!(panel_tex(&b, k), panel_tex(&b, 0), "distinct panels: {k}");
    }
}
