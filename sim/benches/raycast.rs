//! Ray-casting and lidar throughput on the default vineyard (growth stage 3, ~77k
//! triangles): rays/s of one thread for the BVH, for Intel's Embree 3 (single rays, and fans of a column
//! in packets of 4, 8 and 16; feature `embree`) and for parry3d, and VLP-16 scans/s of the
//! full sensor model (all cores). Run: `cargo bench -p vinebench-sim --bench raycast`.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{Point3, Vector3};
use sim::config::SimConfig;
use sim::raycast::{Bvh, Hit, ParryCaster, RayCaster};
use sim::sensors::{LidarSensor, Sensor, vlp16_directions};
use sim::{Simulation, rng};
#[cfg(feature = "embree")]
use {
    embree::{Packet, SceneOptions},
    sim::raycast::EmbreeCaster,
};

/// One sweep of lidar rays from a pose in the middle of a lane, cast on one thread.
fn sweep(
    caster: &dyn RayCaster,
    origin: &Point3<f32>,
    dirs: &[Vector3<f32>],
    out: &mut [Option<Hit>],
) -> usize {
    for (d, o) in dirs.chunks(16).zip(out.chunks_mut(16)) {
        caster.cast_fan(origin, d, 0.9, 130.0, o);
    }
    out.iter().filter(|h| h.is_some()).count()
}

fn benches(c: &mut Criterion) {
    let cfg = SimConfig::default();
    let sim = Simulation::new(&cfg, "s3", 0).expect("s3 builds");
    let mesh = &sim.world.mesh;
    eprintln!("scene: {} triangles", mesh.triangle_count());
    let dirs = vlp16_directions(&cfg.sensors.lidar);
    let pose = sim.trajectory.pose(20_000_000_000);
    let origin: Point3<f32> =
        Point3::from((pose.translation.vector + Vector3::new(0.0, 0.0, 1.56)).cast());
    let mut out = vec![None; dirs.len()];

    let mut group = c.benchmark_group("rays_one_thread");
    group.throughput(Throughput::Elements(dirs.len() as u64));
    let bvh = Bvh::build(mesh);
    eprintln!(
        "bvh: AVX2 kernel {}",
        if bvh.uses_avx2() {
            "on"
        } else {
            "off (not this CPU)"
        }
    );
    group.bench_function("bvh", |b| {
        b.iter(|| black_box(sweep(&bvh, &origin, &dirs, &mut out)))
    });
    // The kernel of CPUs without AVX2, on this one.
    let portable = bvh.clone().portable();
    group.bench_function("bvh_portable", |b| {
        b.iter(|| black_box(sweep(&portable, &origin, &dirs, &mut out)))
    });
    // Embree as `raycaster = "embree"` builds it (spatial-split SAH on one thread), the same
    // rays and range gate: one rtcIntersect1 per ray, then each column in packets.
    #[cfg(feature = "embree")]
    for (name, packet) in [
        ("embree", Packet::Single),
        ("embree_x4", Packet::X4),
        ("embree_x8", Packet::X8),
        ("embree_x16", Packet::X16),
    ] {
        let embree = EmbreeCaster::with_options(mesh, SceneOptions::default(), packet)
            .expect("Embree builds the default world");
        group.bench_function(name, |b| {
            b.iter(|| black_box(sweep(&embree, &origin, &dirs, &mut out)))
        });
    }
    let parry = ParryCaster::build(mesh);
    group.sample_size(10);
    group.bench_function("parry3d", |b| {
        b.iter(|| black_box(sweep(&parry, &origin, &dirs, &mut out)))
    });
    group.finish();

    let mut group = c.benchmark_group("vlp16_scan_all_threads");
    group.throughput(Throughput::Elements(1));
    group.bench_function("scan", |b| {
        let scene = sim.scene();
        let mut lidar = LidarSensor::new(
            &cfg.sensors.lidar,
            sim.duration_ns(),
            rng::stream(0, "lidar"),
        );
        b.iter(|| {
            if lidar.next_ready_ns().is_none() {
                lidar = LidarSensor::new(
                    &cfg.sensors.lidar,
                    sim.duration_ns(),
                    rng::stream(0, "lidar"),
                );
            }
            black_box(lidar.emit(&scene))
        });
    });
    group.finish();

    let mut group = c.benchmark_group("scene_build");
    group.sample_size(10);
    group.bench_function("bvh_build", |b| {
        b.iter(|| black_box(Bvh::build(mesh).node_count()))
    });
    #[cfg(feature = "embree")]
    group.bench_function("embree_build", |b| {
        b.iter(|| black_box(EmbreeCaster::build(mesh).expect("Embree builds")))
    });
    group.finish();
}

criterion_group!(raycast, benches);
criterion_main!(raycast);
