//! The RTAB-Map-style plugin on the simulator's own data: visual odometry on rendered frames
//! and the wheel + ICP odometry against ground truth, and the plugin as the host runs it —
//! loaded from its `.so` by the `vinebench` binary — with its map and grid checked against
//! the world.

mod common;

use common::{ate, json, run};
use nalgebra::{Isometry2, Isometry3, Point2, Vector2};
use rtabmap::config::{FeatureConfig, ScanOdometryConfig, VisualOdometryConfig};
use rtabmap::features::{Image, extract};
use rtabmap::scan_odometry::{ScanOdometry, planar};
use rtabmap::visual_odometry::{Tracking, VisualOdometry};
use sim::config::Side;
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};
use slam_common::scan2d::points_from_ranges;

const FRAME_NS: i64 = 33_333_333;

/// Guards the visual odometry's PnP: 2 s of rendered frames in S1's first lane at full speed
/// (default world: identical plants, growth stage 3, camera noise on), tracked frame to map.
/// Every frame-to-frame motion is within 1 cm / 0.5° of the truth, and no frame is lost.
#[test]
fn visual_odometry_follows_rendered_frames_within_1_cm() {
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s1", 0).expect("S1 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let base_from_camera = cam.base_from_camera_optical();
    let k = sim::camera::Intrinsics::from_config(&config.sensors.camera);
    let mut vo = VisualOdometry::new(
        VisualOdometryConfig::default(),
        [k.fx, k.fy, k.cx, k.cy],
        config.sensors.camera.width,
        config.sensors.camera.height,
        base_from_camera,
    );
    let mut rng = sim::rng::stream(0, "camera");
    let mut previous: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
    let (mut worst_m, mut worst_deg, mut inliers_min) = (0.0f64, 0.0f64, usize::MAX);
    for i in 0..60 {
        let t = 20_000_000_000 + i * FRAME_NS;
        let world_from_base = sim.trajectory.pose(t);
        let image = cam.render(&world_from_base, &mut rng);
        let features = extract(
            &Image {
                width: image.width,
                height: image.height,
                rgb: &image.rgb,
                depth_m: &image.depth_m,
                intrinsics: image.intrinsics,
            },
            &FeatureConfig::default(),
        )
        .expect("features");
        let tracking = vo.process(t, &features).expect("OpenCV");
        let odom_from_camera = match tracking {
            Tracking::Started { odom_from_camera } => odom_from_camera,
            Tracking::Ok {
                odom_from_camera,
                inliers,
                ..
            } => {
                inliers_min = inliers_min.min(inliers);
                odom_from_camera
            }
            Tracking::Lost { inliers, .. } => panic!("frame {i} lost with {inliers} inliers"),
        };
        let world_from_camera = world_from_base * base_from_camera;
        if let Some((world_before, odom_before)) = previous {
            let truth = world_before.inverse() * world_from_camera;
            let estimate = odom_before.inverse() * odom_from_camera;
            let error = truth.inverse() * estimate;
            worst_m = worst_m.max(error.translation.vector.norm());
            worst_deg = worst_deg.max(error.rotation.angle().to_degrees());
        }
        previous = Some((world_from_camera, odom_from_camera));
    }
    eprintln!(
        "visual odometry, 60 frames: worst frame-to-frame error {:.2} mm, {:.3}°, fewest inliers {inliers_min}",
        worst_m * 1e3,
        worst_deg
    );
    assert!(worst_m < 0.01, "frame-to-frame error {worst_m:.4} m");
    assert!(worst_deg < 0.5, "frame-to-frame error {worst_deg:.3}°");
    assert!(inliers_min >= 20, "fewest inliers {inliers_min}");
}

/// Runs the wheel + ICP odometry over S0; returns its end-to-end position error, m, with
/// ICP (`icp` true) or on the wheels alone.
fn scan_odometry_error_s0(icp: bool) -> f64 {
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s0", 0).expect("S0 builds");
    let base_from_scan = config
        .sensors
        .scan2d_front
        .mount_for(Side::Front)
        .base_from_sensor();
    let cfg = ScanOdometryConfig {
        max_correction_m: if icp { 0.1 } else { 0.0 },
        ..ScanOdometryConfig::default()
    };
    let mut odometry = ScanOdometry::new(cfg, &base_from_scan);
    let sensors = SensorSet {
        wheel_odometry: true,
        scan2d: true,
        ..SensorSet::default()
    };
    let mut ends: Option<(
        (Isometry3<f64>, Isometry2<f64>),
        (Isometry3<f64>, Isometry2<f64>),
    )> = None;
    for m in sim.stream(sensors) {
        match m {
            Message::WheelOdometry(w) => odometry.on_wheels(w.stamp_ns, &w.odom_from_base),
            Message::Scan2d(s) if s.side == sim::sensors::ScanSide::Front => {
                let points = points_from_ranges(
                    f64::from(s.angle_min_rad),
                    f64::from(s.angle_increment_rad),
                    &s.ranges_m,
                    f64::from(s.range_min_m),
                    f64::from(s.range_max_m),
                );
                let Some(step) = odometry.on_scan(s.stamp_ns, &points) else {
                    continue;
                };
                let now = (sim.trajectory.pose(s.stamp_ns), step.odom_from_base);
                ends = Some(match ends {
                    None => (now, now),
                    Some((first, _)) => (first, now),
                });
            }
            _ => {}
        }
    }
    let ((g0, e0), (g1, e1)) = ends.expect("scans were registered");
    let truth = planar(&(g0.inverse() * g1));
    let estimate = e0.inverse() * e1;
    (truth.inverse() * estimate).translation.vector.norm()
}

/// Guards the paper's odometry for RTAB-Map: over S0's 25 m, ICP on the front scan (returns
/// within 4 m) keeps the wheels' drift small.
#[test]
fn icp_on_the_front_scan_refines_wheel_odometry() {
    let (wheels, refined) = (scan_odometry_error_s0(false), scan_odometry_error_s0(true));
    eprintln!("S0 end-point error: wheels {wheels:.3} m, wheels + ICP {refined:.3} m");
    assert!(refined < 0.1, "wheels + ICP end-point error {refined:.3} m");
    assert!(
        refined < 0.5 * wheels,
        "ICP must refine the wheels: {refined:.3} m against {wheels:.3} m"
    );
}

/// An occupancy grid in map_server form: (resolution, origin, width, height, cells with 0 =
/// occupied (black) … 254 = free (white), 205 unknown).
fn read_grid(folder: &std::path::Path) -> (f64, [f64; 2], usize, usize, Vec<u8>) {
    let yaml = std::fs::read_to_string(folder.join("grid.yaml")).expect("grid.yaml");
    let field = |key: &str| {
        yaml.lines()
            .find_map(|l| l.strip_prefix(key))
            .unwrap_or_else(|| panic!("grid.yaml lacks {key}: {yaml}"))
            .trim()
            .to_owned()
    };
    let resolution: f64 = field("resolution:").parse().expect("resolution");
    let origin: Vec<f64> = field("origin:")
        .trim_matches(|c| c == '[' || c == ']')
        .split(',')
        .map(|v| v.trim().parse().expect("origin value"))
        .collect();
    let pgm = std::fs::read(folder.join("grid.pgm")).expect("grid.pgm");
    let header: Vec<&[u8]> = pgm.splitn(4, |b| *b == b'\n').collect();
    assert_eq!(header[0], b"P5", "binary PGM");
    let size: Vec<usize> = std::str::from_utf8(header[1])
        .expect("size")
        .split(' ')
        .map(|v| v.parse().expect("size value"))
        .collect();
    let pixels = header[3].to_vec();
    assert_eq!(pixels.len(), size[0] * size[1], "PGM size");
    (resolution, [origin[0], origin[1]], size[0], size[1], pixels)
}

/// Guards the plugin end to end in the paper's odometry mode: loaded from its `.so`, on S0
/// it meets the paper's RTAB-Map figure (0.09 m), and its occupancy grid (from the front
/// scans at the optimised locations) puts the occupied cells on the vine rows of the world.
#[test]
fn plugin_runs_s0_and_its_grid_lies_on_the_rows() {
    let dir = tempfile::tempdir().expect("temp dir");
    let folder = run(dir.path(), "s0", "rtabmap", "wheel-icp", "");
    let error = ate(&folder, "estimate.tum");
    eprintln!("S0 ATE {error:.3} m");
    assert!(error < 0.09, "S0 ATE {error:.3} m");
    let timing = json(&folder.join("timing.json"));
    assert!(
        timing["latency"]["rgbd"]["calls"].as_u64().unwrap_or(0) > 1000,
        "every camera frame reaches the plugin: {timing}"
    );

    // The map frame is the robot's start pose; the rows lie along x at y = 3 k in the world.
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s0", 0).expect("S0 builds");
    let world_from_map = planar(&sim.trajectory.pose(0));
    let v = &config.vineyard;
    let (resolution, origin, width, height, cells) = read_grid(&folder);
    let (mut on_rows, mut in_block) = (0usize, 0usize);
    for row in 0..height {
        for col in 0..width {
            // PGM rows run from the top, map_server's from the origin corner.
            if cells[row * width + col] != 0 {
                continue;
            }
            let map = Vector2::new(
                origin[0] + (col as f64 + 0.5) * resolution,
                origin[1] + ((height - 1 - row) as f64 + 0.5) * resolution,
            );
            let world = world_from_map * Point2::from(map);
            if !(1.0..v.row_length_m - 1.0).contains(&world.x) {
                continue;
            }
            in_block += 1;
            let k = (world.y / v.row_spacing_m).round();
            if (world.y - k * v.row_spacing_m).abs() < 0.3 {
                on_rows += 1;
            }
        }
    }
    let share = on_rows as f64 / in_block.max(1) as f64;
    eprintln!("grid: {in_block} occupied cells among the rows, {on_rows} within 0.3 m of a row");
    assert!(
        in_block > 200,
        "too few occupied cells among the rows: {in_block}"
    );
    assert!(
        share > 0.9,
        "only {:.0}% of occupied cells lie on rows",
        share * 100.0
    );
}
