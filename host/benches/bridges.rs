//! What each plugin ABI costs per message: the same messages handed by the host's loader to
//! a plugin that does nothing with them, written in Rust (abi_stable; the fault plugin,
//! whose IMU, lidar and camera callbacks are the trait's defaults), in C
//! (`tests/c-plugin/c_noop.c`) and in Python (`bridge_fixtures.Noop` through the Python
//! bridge, in `target/python-bridge-venv`). Messages as the default rig makes them: an IMU
//! sample, a VLP-16 sweep of 16 × 1800 points and a 640 × 480 RGB-D frame.
//!
//! `cargo bench -p vinebench --bench bridges` (after `bash scripts/setup.sh`).

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use plugin_api::{Imu, LidarPoint, PluginInstance, PointCloud, RgbdFrame, WheelOdometry};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A library cargo built beside this benchmark (its dev-dependencies' cdylibs).
fn deps_lib(stem: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the benchmark's path");
    let path = exe.parent().expect("deps").join(format!(
        "{}{stem}{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    ));
    assert!(path.is_file(), "{} missing", path.display());
    path
}

fn create(path: &Path, params: &str) -> PluginInstance {
    let rig = vinebench::rig::rig(&sim::SimConfig::default());
    plugin_api::load(path)
        .unwrap_or_else(|e| panic!("{e}"))
        .create(params, &rig)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn bridges(c: &mut Criterion) {
    let python_params = format!(
        "module = \"bridge_fixtures\"\nclass = \"Noop\"\npath = [\"{}\", \"{}\"]\nvenv = \"{}\"\n",
        root().join("tests/python-plugin").display(),
        root().join("plugins/python-bridge/python").display(),
        root().join("target/python-bridge-venv").display()
    );
    let mut plugins = [
        ("rust", create(&deps_lib("fault_plugin"), "")),
        ("c", create(Path::new(env!("VINEBENCH_C_NOOP")), "")),
        ("python", create(&deps_lib("python_bridge"), &python_params)),
    ];
    let imu = Imu {
        stamp_ns: 1_000_000_000,
        accel_mps2: [0.1, 0.0, 9.81],
        gyro_rps: [0.0, 0.0, 0.05],
        orientation_xyzw: [0.0; 4],
    };
    let odom = WheelOdometry {
        stamp_ns: 1_000_000_000,
        linear_mps: 0.5,
        angular_rps: 0.0,
        odom_from_base: plugin_api::Pose::new(1_000_000_000, &nalgebra::Isometry3::identity()),
    };
    let points: Vec<LidarPoint> = (0..16 * 1800)
        .map(|i| LidarPoint {
            x: (i % 1800) as f32 * 0.01,
            y: 1.0,
            z: (i / 1800) as f32 * 0.1,
            intensity: 0.5,
            time_s: (i % 1800) as f32 / 18_000.0,
            ring: (i / 1800) as u16,
        })
        .collect();
    let cloud = PointCloud {
        stamp_ns: 1_000_000_000,
        sensor: "velodyne",
        points: &points,
    };
    let (w, h) = (640u32, 480u32);
    let rgb = vec![128u8; (w * h * 3) as usize];
    let depth = vec![2.5f32; (w * h) as usize];
    let frame = RgbdFrame {
        stamp_ns: 1_000_000_000,
        sensor: "camera",
        width: w,
        height: h,
        rgb: &rgb,
        depth_m: &depth,
        intrinsics: [525.0, 525.0, 319.5, 239.5],
    };
    for (message, mut call) in [
        (
            "imu",
            Box::new(|p: &mut PluginInstance| drop(p.on_imu(black_box(&imu))))
                as Box<dyn FnMut(&mut PluginInstance)>,
        ),
        (
            "wheel_odometry",
            Box::new(|p: &mut PluginInstance| drop(p.on_wheel_odometry(black_box(&odom)))),
        ),
        (
            "point_cloud_28800",
            Box::new(|p: &mut PluginInstance| drop(p.on_point_cloud(black_box(&cloud)))),
        ),
        (
            "rgbd_640x480",
            Box::new(|p: &mut PluginInstance| drop(p.on_rgbd(black_box(&frame)))),
        ),
    ] {
        let mut group = c.benchmark_group(format!("per_message/{message}"));
        for (abi, plugin) in &mut plugins {
            group.bench_function(*abi, |b| b.iter(|| call(plugin)));
        }
        group.finish();
    }
}

criterion_group!(benches, bridges);
criterion_main!(benches);
