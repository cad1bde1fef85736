//! The RTAB-Map-style plugin on the simulator's own data: visual odometry on rendered frames
//! and the wheel + ICP odometry against ground truth, and the plugin as the host runs it —
//! loaded from its `.so` by the `vinebench` binary — with its map and grid checked against
//! the world.

use crate::common::{ate, event_positions, json, loop_events, run_with};
use nalgebra::{Isometry2, Isometry3, Point2, Vector2};
use rtabmap::config::{FeatureConfig, ScanOdometryConfig, VisualOdometryConfig};
use rtabmap::features::{Image, extract};
use rtabmap::scan_odometry::{ScanOdometry, Sweep, planar};
use rtabmap::visual_odometry::{Tracking, VisualOdometry};
use sim::config::Side;
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};
use slam_common::registration::scan2d::points_from_ranges;

const FRAME_NS: i64 = 33_333_333;

/// Where a rendered frame's optical frame truly was, and its features.
type Frame = (Isometry3<f64>, rtabmap::features::Features);

/// Renders `count` consecutive camera frames of S1's first lane at full speed (default
/// world: identical plants, growth stage 3, camera noise on), from t = 20 s: each frame's
/// features and where its optical frame truly was.
fn rendered_frames(count: i64) -> (Vec<Frame>, [f64; 4], Isometry3<f64>) {
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s1", 0).expect("S1 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let base_from_camera = cam.base_from_camera_optical();
    let mut rng = sim::rng::stream(0, "camera");
    let mut intrinsics = [0.0; 4];
    let frames = (0..count)
        .map(|i| {
            let world_from_base = sim.trajectory.pose(20_000_000_000 + i * FRAME_NS);
            let image = cam.render(&world_from_base, &mut rng);
            intrinsics = image.intrinsics;
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
            (world_from_base * base_from_camera, features)
        })
        .collect();
    (frames, intrinsics, base_from_camera)
}

/// Guards the features and PnP the visual odometry and the loop-closure verification rest
/// on: between consecutive rendered frames, GFTT/BRIEF matches (ratio 0.8) and PnP RANSAC
/// (2 px, 300 iterations) recover the relative pose within 1 cm / 0.5° with ≥ 20 inliers;
/// and the frame-to-map odometry tracks all 60 frames (2 s, 1 m) without losing one and
/// ends within 2 cm of the truth.
#[test]
fn pnp_recovers_the_relative_pose_of_rendered_frames() {
    let (frames, intrinsics, base_from_camera) = rendered_frames(60);
    let cfg = rtabmap::pnp::PnpConfig {
        reprojection_px: 2.0,
        iterations: 300,
    };
    let (mut worst_m, mut worst_deg, mut inliers_min) = (0.0f64, 0.0f64, usize::MAX);
    for pair in frames.windows(2) {
        let ((world_from_a, a), (world_from_b, b)) = (&pair[0], &pair[1]);
        let matches =
            rtabmap::matching::match_descriptors(&a.descriptors, &b.descriptors, None, 0.8);
        let (object, pixels): (Vec<_>, Vec<_>) = matches
            .iter()
            .filter_map(|m| a.points[m.query].map(|p| (p, b.pixels[m.train])))
            .unzip();
        let result = rtabmap::pnp::solve(&object, &pixels, intrinsics, None, &cfg)
            .expect("OpenCV")
            .expect("PnP finds a pose");
        let truth = world_from_b.inverse() * world_from_a;
        let error = truth.inverse() * result.camera_from_object;
        worst_m = worst_m.max(error.translation.vector.norm());
        worst_deg = worst_deg.max(error.rotation.angle().to_degrees());
        inliers_min = inliers_min.min(result.inliers.len());
    }
    eprintln!(
        "PnP between consecutive frames: worst error {:.2} mm, {:.3}°, fewest inliers {inliers_min}",
        worst_m * 1e3,
        worst_deg
    );
    assert!(worst_m < 0.01, "relative pose error {worst_m:.4} m");
    assert!(worst_deg < 0.5, "relative pose error {worst_deg:.3}°");
    assert!(inliers_min >= 20, "fewest inliers {inliers_min}");

    let mut vo = VisualOdometry::new(
        VisualOdometryConfig::default(),
        intrinsics,
        640,
        480,
        base_from_camera,
    );
    let mut last = Isometry3::identity();
    for (i, (_, features)) in frames.iter().enumerate() {
        last = match vo.process(i as i64 * FRAME_NS, features).expect("OpenCV") {
            Tracking::Started { odom_from_camera }
            | Tracking::Ok {
                odom_from_camera, ..
            } => odom_from_camera,
            Tracking::Lost { inliers, .. } => panic!("frame {i} lost with {inliers} inliers"),
        };
    }
    let truth = frames[0].0.inverse() * frames[frames.len() - 1].0;
    let estimate = base_from_camera.inverse() * last;
    let drift = (truth.inverse() * estimate).translation.vector.norm();
    eprintln!(
        "visual odometry over {:.2} m: {:.1} mm off",
        truth.translation.vector.norm(),
        drift * 1e3
    );
    assert!(drift < 0.02, "visual odometry drift {drift:.4} m");
}

/// What the wheel + ICP odometry did over S0: the end point's planar error, m; the RMS of
/// its height error and of the true height, both relative to the start, m.
struct ScanOdometryRun {
    end_error_m: f64,
    height_error_m: f64,
    height_m: f64,
}

/// Runs the wheel + ICP odometry over S0 as the plugin feeds it (IMU, wheels, timed front
/// scans), with ICP (`icp` true) or on the wheels and IMU alone.
fn scan_odometry_s0(icp: bool) -> ScanOdometryRun {
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
        imu: true,
        ..SensorSet::default()
    };
    let base_r_imu = config.sensors.imu.mount.base_from_sensor().rotation;
    // At every scan: the truth, the planar odometry, and the odometry in 3D.
    let mut poses: Vec<(Isometry3<f64>, Isometry2<f64>, Isometry3<f64>)> = Vec::new();
    for m in sim.stream(sensors) {
        match m {
            Message::WheelOdometry(w) => {
                odometry.on_wheels(w.stamp_ns, w.linear_mps, w.angular_rps)
            }
            Message::Imu(m) => odometry.on_imu(
                m.stamp_ns,
                &(base_r_imu * m.gyro_rps),
                &(base_r_imu * m.accel_mps2),
            ),
            Message::Scan2d(s) if s.side == sim::sensors::ScanSide::Front => {
                let points = points_from_ranges(
                    f64::from(s.angle_min_rad),
                    f64::from(s.angle_increment_rad),
                    &s.ranges_m,
                    f64::from(s.range_min_m),
                    f64::from(s.range_max_m),
                );
                let sweep = Sweep {
                    angle_min_rad: f64::from(s.angle_min_rad),
                    angle_increment_rad: f64::from(s.angle_increment_rad),
                    time_increment_s: f64::from(s.time_increment_s),
                };
                let Some(step) = odometry.on_timed_scan(s.stamp_ns, &points, Some(&sweep)) else {
                    continue;
                };
                let lifted = odometry.lift(&step.odom_from_base);
                poses.push((sim.trajectory.pose(s.stamp_ns), step.odom_from_base, lifted));
            }
            _ => {}
        }
    }
    let (first, last) = (
        poses.first().expect("scans were registered"),
        poses.last().expect("scans were registered"),
    );
    let truth = planar(&(first.0.inverse() * last.0));
    let estimate = first.1.inverse() * last.1;
    let rms = |values: Vec<f64>| {
        (values.iter().map(|v| v * v).sum::<f64>() / values.len().max(1) as f64).sqrt()
    };
    let (z_true, z_odometry) = (first.0.translation.z, first.2.translation.z);
    ScanOdometryRun {
        end_error_m: (truth.inverse() * estimate).translation.vector.norm(),
        height_error_m: rms(poses
            .iter()
            .map(|(g, _, l)| (l.translation.z - z_odometry) - (g.translation.z - z_true))
            .collect()),
        height_m: rms(poses
            .iter()
            .map(|(g, _, _)| g.translation.z - z_true)
            .collect()),
    }
}

/// Guards the paper's odometry for RTAB-Map: over S0's 25 m, ICP on the front scan keeps
/// the wheels' drift small; and the IMU's tilt with the wheels gives the height of the
/// uneven ground, which planar odometry (z = 0) misses entirely.
#[test]
fn icp_on_the_front_scan_refines_wheel_odometry() {
    let (wheels, refined) = (scan_odometry_s0(false), scan_odometry_s0(true));
    let (wheels_end, end) = (wheels.end_error_m, refined.end_error_m);
    eprintln!(
        "S0 end-point error: wheels {wheels_end:.3} m, wheels + ICP {end:.3} m; height error \
         RMS {:.3} m against a true height RMS of {:.3} m",
        refined.height_error_m, refined.height_m
    );
    assert!(end < 0.1, "wheels + ICP end-point error {end:.3} m");
    assert!(
        end < 0.5 * wheels_end,
        "ICP must refine the wheels: {end:.3} m against {wheels_end:.3} m"
    );
    assert!(
        refined.height_m > 0.03,
        "S0 is uneven: true height RMS {:.3} m",
        refined.height_m
    );
    assert!(
        refined.height_error_m < 0.5 * refined.height_m,
        "height error RMS {:.3} m against a true height RMS of {:.3} m",
        refined.height_error_m,
        refined.height_m
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
    // The first half of S0 (58.6 s): the first row and the turn into the next.
    let max_time_s = 30.0;
    let folder = run_with(
        dir.path(),
        "s0",
        "rtabmap",
        "wheel-icp",
        "",
        &["--max-time", &max_time_s.to_string()],
    );
    let error = ate(&folder, "estimate.tum");
    eprintln!("S0 (first {max_time_s} s) ATE {error:.3} m");
    assert!(error < 0.09, "S0 ATE {error:.3} m");
    let timing = json(&folder.join("timing.json"));
    let frames = (max_time_s * SimConfig::default().sensors.camera.rate_hz).floor() as u64;
    assert!(
        timing["latency"]["rgbd"]["calls"].as_u64().unwrap_or(0) >= frames,
        "every camera frame ({frames}) reaches the plugin: {timing}"
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

/// Guards loop closure in S1, where the robot comes back along the row it went down: its
/// camera then looks the other way, so the loops are closed by proximity (ICP of the laser
/// scans near the graph's estimate). Loaded from its `.so`, the plugin accepts loop closures
/// there, and every accepted one joins places truly within a metre of each other. (On this
/// route the odometry is already good, and the loops did not lower the error measurably
/// when a run without them was compared.) Memory management is on as by default: the comparison
/// limit (`Rtabmap/TimeThr`, counted) moves the oldest locations to long-term memory, and no
/// location is quantised against much more than the limit allows.
#[test]
fn true_loops_are_closed_in_s1() {
    let dir = tempfile::tempdir().expect("temp dir");
    // The first 85 s of S1 (of 115): the way down the lane and 25 s of the way back, where
    // the loops come (the first at 74 s when measured).
    let with = run_with(
        dir.path(),
        "s1",
        "rtabmap",
        "with-loops",
        "locations_csv = \"locations.csv\"\n",
        &["--max-time", "85"],
    );
    let accepted = loop_events(&with, "loop_closure_accepted");
    assert!(
        accepted.len() >= 5,
        "few loop closures accepted in S1: {accepted:?}"
    );
    for event in &accepted {
        let (a, b) = event_positions(&with, event).expect("the loop's two stamps");
        assert!(
            (a - b).norm() < 1.0 && event.true_loop == Some(true),
            "a false loop was accepted ({:.2} m apart, judged {:?}): {}",
            (a - b).norm(),
            event.true_loop,
            event.detail
        );
    }
    let loops = &json(&with.join("metrics.json"))["loops"];
    assert_eq!(
        loops["accepted"].as_u64(),
        Some(accepted.len() as u64),
        "{loops}"
    );
    assert_eq!(loops["accepted_false"].as_u64(), Some(0), "{loops}");
    assert!(loops.get("unjudged").is_none(), "{loops}");
    eprintln!(
        "S1: {} loops accepted; ATE {:.3} m",
        accepted.len(),
        ate(&with, "estimate.tum")
    );

    // location,stamp_ns,descriptors,new_words,vocabulary_words,comparisons,transferred,
    // working_memory,...
    let csv = std::fs::read_to_string(with.join("locations.csv")).expect("locations.csv");
    let rows: Vec<Vec<u64>> = csv
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .take(8)
                .map(|v| v.parse().expect("an integer"))
                .collect()
        })
        .collect();
    let limit = rtabmap::config::MemoryConfig::default().comparison_limit;
    let transferred: u64 = rows.iter().map(|r| r[6]).sum();
    let worst = rows.iter().map(|r| r[5]).max().unwrap_or(0);
    let wm = rows.iter().map(|r| r[7]).max().unwrap_or(0);
    eprintln!(
        "S1: {} locations, {transferred} moved to LTM, WM at most {wm}, at most {worst} comparisons (limit {limit})",
        rows.len()
    );
    assert!(rows.len() > 50, "a location a second: {}", rows.len());
    assert!(transferred > 0, "the comparison limit binds on S1");
    // One location's words past the limit at most (500 descriptors, under 500 new words).
    assert!(worst <= limit + 500 * 500, "{worst} comparisons");
}

/// What identical rows do to a graph, forced: S3's locations (one per second, odometry links
/// from the ground truth with the plugin's default link sigmas) and one loop closure between
/// a place in the first lane and the place at the same distance along the third lane, driven
/// the same way — the pair identical plants make look alike; its link says the robot was
/// back where it had been (the 6 m between the lanes missing). `OptimizeMaxError` (3.0)
/// rejects it and the graph, re-optimised without it, returns to every pose it had — on
/// each backend (factrs, isam2, and GTSAM's ISAM2, which cannot have estimates overwritten);
/// without the check it is kept and bends the map by metres. A true loop between the same
/// two places is kept.
#[test]
fn a_false_loop_between_identical_rows_is_rejected() {
    use rtabmap::graph::{LoopOutcome, PoseGraph, Sigmas};
    use rtabmap::scan_odometry::spatial;

    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s3", 0).expect("S3 builds");
    let poses: Vec<Isometry3<f64>> = (0..)
        .map(|k: i64| k * 1_000_000_000)
        .take_while(|t| *t < sim.duration_ns())
        .map(|t| spatial(&planar(&sim.trajectory.pose(t))))
        .collect();
    let links = rtabmap::config::LinkSigmas::default();
    let build = |backend: &str, optimize_max_error: f64| {
        let cfg = slam_common::factor_graph::backend::BackendConfig {
            name: backend.into(),
            ..Default::default()
        };
        let mut g = PoseGraph::new(&cfg, optimize_max_error)
            .unwrap_or_else(|e| panic!("{backend} backend: {e}"));
        g.add_first(0, poses[0]).expect("first");
        for k in 1..poses.len() {
            let link = poses[k - 1].inverse() * poses[k];
            let d = link.translation.vector.norm();
            let sigmas = Sigmas {
                rad: links.rad_floor + links.rad_per_m * d,
                m: links.m_floor + links.m_per_m * d,
            };
            g.add_odometry(k as u64 - 1, k as u64, link, sigmas)
                .expect("odometry");
        }
        g
    };
    // A place mid-row in the first lane driven, and the place nearest to it along the rows
    // in the lane two further on.
    let lane_y = |k: usize| config.vineyard.lane_y(k);
    let first_lane = (0..config.vineyard.lanes())
        .find(|&l| {
            poses
                .iter()
                .any(|p| (p.translation.y - lane_y(l)).abs() < 0.2)
        })
        .expect("S3 drives a lane");
    let mid_x = 0.5 * config.vineyard.row_length_m;
    let nearest = |lane: usize| {
        (0..poses.len())
            .filter(|&k| (poses[k].translation.y - lane_y(lane)).abs() < 0.2)
            .min_by(|&a, &b| {
                (poses[a].translation.x - mid_x)
                    .abs()
                    .total_cmp(&(poses[b].translation.x - mid_x).abs())
            })
            .expect("a location in the lane")
    };
    let (old, new) = (nearest(first_lane), nearest(first_lane + 2));
    let heading = |k: usize| poses[k].rotation.euler_angles().2;
    assert!(
        (heading(old) - heading(new)).abs() < 0.2,
        "lanes two apart are driven the same way"
    );
    let truth = poses[old].inverse() * poses[new];
    let lateral = lane_y(first_lane + 2) - lane_y(first_lane);
    let false_link = Isometry3::translation(
        truth.translation.x,
        truth.translation.y - lateral * heading(old).cos(),
        0.0,
    ) * truth.rotation;
    let sigmas = Sigmas { rad: 0.01, m: 0.02 };
    let error_of = |g: &PoseGraph| {
        let sq: f64 = (0..poses.len())
            .map(|k| {
                (g.pose(k as u64).expect("pose").translation.vector - poses[k].translation.vector)
                    .norm_squared()
            })
            .sum();
        (sq / poses.len() as f64).sqrt()
    };

    let mut kept = None;
    for backend in ["isam2", "gtsam", "factrs"] {
        let mut checked = build(backend, 3.0);
        let before: Vec<_> = (0..poses.len())
            .map(|k| checked.pose(k as u64).expect("pose"))
            .collect();
        let outcome = checked
            .add_loop(old as u64, new as u64, false_link, sigmas)
            .unwrap_or_else(|e| panic!("{backend}: {e}"));
        let LoopOutcome::Rejected(s) = outcome else {
            panic!("{backend}: the false loop was kept: {outcome:?}");
        };
        let (dt, dr) = (0..poses.len()).fold((0.0f64, 0.0f64), |(t, r), k| {
            let d = before[k].inverse() * checked.pose(k as u64).expect("pose");
            (
                t.max(d.translation.vector.norm()),
                r.max(d.rotation.angle()),
            )
        });
        eprintln!(
            "{backend}: rejected at {:.1} sigma; poses restored within {dt:.1e} m, {dr:.1e} rad",
            s.ratio
        );
        assert!(
            dt < 1e-6 && dr < 1e-6,
            "{backend}: every pose restored, off by {dt:.2e} m, {dr:.2e} rad"
        );
        assert_eq!(checked.loops(), 0, "{backend}");
        kept = Some((checked, s));
    }
    // The last, factrs, goes on to the true loop.
    let (mut checked, strain) = kept.expect("checked on a backend");

    let mut unchecked = build("factrs", 0.0);
    let clean = error_of(&unchecked);
    let outcome = unchecked
        .add_loop(old as u64, new as u64, false_link, sigmas)
        .expect("loop");
    assert!(matches!(outcome, LoopOutcome::Accepted(_)), "{outcome:?}");
    let bent = error_of(&unchecked);
    eprintln!(
        "false loop {old}-{new}: rejected at {:.1} sigma; without the check the map's RMS error goes from {clean:.3} m to {bent:.3} m",
        strain.ratio
    );
    assert!(bent > 0.5, "the false loop bends the map: {bent:.3} m");

    let outcome = checked
        .add_loop(old as u64, new as u64, truth, sigmas)
        .expect("loop");
    assert!(
        matches!(outcome, LoopOutcome::Accepted(s) if s.ratio < 3.0),
        "true loop: {outcome:?}"
    );
}

/// A lens's raw frames end to end: the world's camera gets a lens (stronger than a Kinect
/// v2's colour lens, so that it shows), the rig reports it, and rtabmap on visual odometry
/// scores better when it rectifies the frames (`Rtabmap/ImagesAlreadyRectified = false`)
/// than when it takes them as rectified (RTAB-Map's default), one shared simulation feeding
/// both runs.
#[test]
fn rectifying_a_lenss_raw_frames_beats_taking_them_as_rectified() {
    let dir = tempfile::tempdir().expect("temp dir");
    let world = dir.path().join("lens.toml");
    std::fs::write(
        &world,
        "[sensors.camera]\ndistortion = [-0.25, 0.05, 0.001, -0.001, 0.0]\n",
    )
    .expect("write world");
    let visual = "odometry = \"visual\"\n";
    let runs = crate::common::run_together(
        dir.path(),
        "s0",
        "rtabmap",
        (
            &[
                (
                    "rectifies",
                    &format!("{visual}[Rtabmap]\nImagesAlreadyRectified = false\n"),
                ),
                ("takes-as-rectified", visual),
            ],
            Some(&world),
        ),
        &["--max-time", "20"],
    );
    let (rectified, raw) = (ate(&runs[0], "estimate.tum"), ate(&runs[1], "estimate.tum"));
    eprintln!("S0 (first 20 s) through a lens: ATE {rectified:.3} m rectified, {raw:.3} m raw");
    assert!(
        rectified < 0.1 && raw > 1.5 * rectified,
        "ATE {rectified:.3} m rectifying, {raw:.3} m taking raw frames as rectified"
    );
}
