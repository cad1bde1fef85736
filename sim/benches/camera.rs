//! RGB-D camera throughput: frames/s of colour + registered depth (640x480, noise and
//! shadows on) from a pose in a lane of the default world (growth stage 3), all cores, with
//! the default 4x anti-aliasing and filtered materials and with the single-sample renderer
//! (`antialias_samples = 1`, point-sampled materials: the renderer before); the plain
//! timing is repeated in the same world at growth stage 4 (the closed leaf wall).
//! Run: `cargo bench -p vinebench-sim --bench camera`.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use sim::camera::RgbdCamera;
use sim::config::{CameraConfig, SimConfig};
use sim::rng::stream;
use sim::world::World;

fn benches(c: &mut Criterion) {
    let cfg = SimConfig::default();
    let world = World::build(&cfg.vineyard, &cfg.terrain, cfg.world_seed);
    let single_cfg = CameraConfig {
        antialias_samples: 1,
        filter_materials: false,
        ..cfg.sensors.camera.clone()
    };
    let started = Instant::now();
    let camera = RgbdCamera::new(&cfg.sensors.camera, &world);
    eprintln!(
        "scene: {} triangles; camera set up (chunks, shadow map, ground textures generated and \
         lit) in {:.0} ms",
        world.mesh.triangle_count(),
        started.elapsed().as_secs_f64() * 1e3
    );
    let single = RgbdCamera::new(&single_cfg, &world);
    let (x, y) = (4.0, cfg.vineyard.lane_y(3));
    let base = Isometry3::from_parts(
        Translation3::new(x, y, world.terrain.height(x, y)),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05),
    );
    let mut rng = stream(1, "camera");

    // A plain timing first, so the figure is printed whatever criterion's output settings.
    let frames = 60;
    let time = |camera: &RgbdCamera, rng: &mut sim::rng::SimRng| {
        let started = Instant::now();
        for _ in 0..frames {
            black_box(camera.render(&base, rng));
        }
        frames as f64 / started.elapsed().as_secs_f64()
    };
    for (name, cam) in [
        ("4x AA, filtered (default)", &camera),
        ("single sample", &single),
    ] {
        let fps = time(cam, &mut rng);
        eprintln!(
            "rgbd 640x480, {name}: {fps:.1} frames/s ({:.2} ms/frame) on {} threads",
            1e3 / fps,
            rayon::current_num_threads()
        );
    }

    // The same pose at full canopy (about three times the leaf triangles).
    let mut full = cfg.clone();
    full.vineyard.growth_stage = 4.0;
    let world4 = World::build(&full.vineyard, &full.terrain, full.world_seed);
    let started = Instant::now();
    let camera4 = RgbdCamera::new(&full.sensors.camera, &world4);
    // The ground's patches are generated once per process: this camera only lights them.
    let setup4_ms = started.elapsed().as_secs_f64() * 1e3;
    let single4 = RgbdCamera::new(&single_cfg, &world4);
    for (name, cam) in [
        ("4x AA, filtered (default)", &camera4),
        ("single sample", &single4),
    ] {
        let fps4 = time(cam, &mut rng);
        eprintln!(
            "rgbd 640x480, growth stage 4 ({} triangles, camera set up in {setup4_ms:.0} ms), \
             {name}: {fps4:.1} frames/s ({:.2} ms/frame)",
            world4.mesh.triangle_count(),
            1e3 / fps4
        );
    }

    let mut group = c.benchmark_group("camera");
    group.throughput(Throughput::Elements(1));
    group.sample_size(30);
    group.bench_function("rgbd_frame_lane_stage3", |b| {
        b.iter(|| black_box(camera.render(&base, &mut rng)))
    });
    group.bench_function("rgbd_frame_lane_stage3_single_sample", |b| {
        b.iter(|| black_box(single.render(&base, &mut rng)))
    });
    group.finish();
}

criterion_group!(camera, benches);
criterion_main!(camera);
