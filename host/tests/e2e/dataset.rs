//! `vinebench record` / `export` and `dataset::Replay` from the outside: the recording
//! replays bit for bit as the live stream, is byte-identical run to run, and an independent
//! decoder (Foxglove's `mcap` + `mcap-ros2-support`, tests/mcap/check_mcap.py) reads it as
//! the ROS 2 messages it claims to be, with the simulator's counts and values.
//!
//! The Python check needs those packages: `source scripts/setup.sh` puts a virtual
//! environment with them first on PATH (scripts/test.sh does). Without them the test fails
//! and says so; it never passes silently.

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde_json::Value;
use sim::camera::RgbdImage;
use sim::sensors::{Message, RgbdFrame};
use sim::{SensorSet, SimConfig, Simulation};
use vinebench::dataset::{Recorder, Replay, replay_messages, replay_with_live};

const SECONDS: f64 = 5.0;
const SEED: u64 = 7;
/// What `vinebench record` records by default: every sensor but the camera.
const DEFAULT_SENSORS: SensorSet = SensorSet {
    rgbd: false,
    gnss: false,
    ..SensorSet::ALL
};
/// The camera's recordings are short: 31 frames at 30 Hz (both ends), about 70 MB.
const CAMERA_SECONDS: f64 = 1.0;
const CAMERA_ONLY: SensorSet = SensorSet {
    ground_truth: false,
    imu: false,
    wheel_odometry: false,
    lidar: false,
    scan2d: false,
    rgbd: true,
    gnss: false,
};
const CAMERA_TOPICS: [&str; 3] = [
    "/camera/color/image_raw",
    "/camera/depth/image_raw",
    "/camera/color/camera_info",
];

fn record(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    record_for(dir, name, SECONDS, extra)
}

fn record_for(dir: &Path, name: &str, seconds: f64, extra: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let max_time = seconds.to_string();
    let seed = SEED.to_string();
    let mut args = vec!["record", "--scenario", "s0", "--max-time", &max_time];
    args.extend(["--seed", &seed, "-o", path.to_str().expect("UTF-8 path")]);
    args.extend(extra);
    let out = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(&args)
        .output()
        .expect("vinebench runs");
    assert!(
        out.status.success(),
        "vinebench {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    path
}

fn config() -> SimConfig {
    SimConfig::from_toml_str(sim::DEFAULT_CONFIG_TOML, "world.toml").expect("default config")
}

/// The stream `vinebench record` writes by default, cut where `--max-time` cuts it.
fn live() -> Vec<Message> {
    live_for(SECONDS, DEFAULT_SENSORS)
}

fn live_for(seconds: f64, sensors: SensorSet) -> Vec<Message> {
    let sim = Simulation::new(&config(), "s0", SEED).expect("s0 builds");
    let end = sim.duration_ns().min((seconds * 1e9) as i64);
    sim.stream(sensors)
        .take_while(|m| m.stamp_ns() <= end)
        .collect()
}

/// Bit for bit: a camera frame's depth and intrinsics by their bits (an invalid depth may be
/// NaN, which `==` never equals), every other message by `==`.
fn identical(a: &Message, b: &Message) -> bool {
    let (Message::Rgbd(a), Message::Rgbd(b)) = (a, b) else {
        return a == b;
    };
    // Spelt out whole, so a field added to the image is a compile error here, not skipped.
    let RgbdImage {
        width,
        height,
        rgb,
        depth_m,
        intrinsics,
    } = &a.image;
    let bits = |d: &[f32]| d.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
    a.stamp_ns == b.stamp_ns
        && *width == b.image.width
        && *height == b.image.height
        && *rgb == b.image.rgb
        && bits(depth_m) == bits(&b.image.depth_m)
        && intrinsics.map(f64::to_bits) == b.image.intrinsics.map(f64::to_bits)
}

/// A message for an assertion: a camera frame by its stamp and size, not its megabytes.
fn describe(m: &Message) -> String {
    match m {
        Message::Rgbd(RgbdFrame { stamp_ns, image }) => format!(
            "Rgbd {{ stamp_ns: {stamp_ns}, {} x {}, {} rgb bytes, {} depths, intrinsics: {:?} }}",
            image.width,
            image.height,
            image.rgb.len(),
            image.depth_m.len(),
            image.intrinsics
        ),
        other => format!("{other:?}"),
    }
}

fn assert_same_stream(replayed: &[Message], live: &[Message], what: &str) {
    for (i, (r, l)) in replayed.iter().zip(live).enumerate() {
        assert!(
            identical(r, l),
            "{what}: message {i} differs\nreplayed: {}\nlive:     {}",
            describe(r),
            describe(l)
        );
    }
    assert_eq!(replayed.len(), live.len(), "{what}: number of messages");
}

#[test]
fn replay_gives_back_the_live_stream_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path(), "s0.mcap", &[]);
    let live = live();
    assert!(
        live.iter().any(|m| matches!(m, Message::Lidar(_))),
        "the first {SECONDS} s have lidar sweeps"
    );
    let replayed: Vec<Message> = Replay::open(&path, DEFAULT_SENSORS)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_same_stream(&replayed, &live, "the default sensors");

    // A subset skips the other topics and keeps the order.
    let subset = SensorSet {
        imu: true,
        lidar: true,
        ..SensorSet::default()
    };
    let source = replay_messages(&path, subset).unwrap();
    fn feeds_a_producer_thread(_: &impl Send) {}
    feeds_a_producer_thread(&source);
    let replayed: Vec<Message> = source.collect();
    let expected: Vec<Message> = live
        .into_iter()
        .filter(|m| matches!(m, Message::Imu(_) | Message::Lidar(_)))
        .collect();
    assert_same_stream(&replayed, &expected, "imu and lidar");
}

/// A recording made once for runs with different GNSS receivers (`record_once` leaves
/// GNSS out): recorded from a world with a consumer receiver, replayed with an RTK
/// receiver simulated live from the run's own world, it gives exactly the stream that
/// world's live simulation gives, in its order (epochs after their latency, after every
/// other sensor at a tie; lidar sweeps at their end) — and with the consumer receiver,
/// that one's. The rest of the stream does not depend on the receiver.
#[test]
fn a_recording_without_gnss_replays_with_any_receiver_as_its_live_stream() {
    let world = |profile: &str| {
        let text = format!(
            "{}\n[sensors.gnss]\nprofile = \"{profile}\"\n",
            sim::DEFAULT_CONFIG_TOML
        );
        SimConfig::from_toml_str(&text, "world.toml").expect("world with a receiver")
    };
    let (consumer, rtk) = (world("consumer"), world("rtk"));
    let end = (SECONDS * 1e9) as i64;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("without-gnss.mcap");
    let recorded = Simulation::new(&consumer, "s0", SEED).expect("s0");
    let mut recorder =
        Recorder::create(&path, &consumer, DEFAULT_SENSORS, Default::default()).unwrap();
    // A second past the cut, as `record_once` records a cut route: what follows the cut in
    // the live order is in the file, so the merge cuts where the live stream does.
    let recorded_end = end + 1_000_000_000;
    for m in recorded
        .stream(DEFAULT_SENSORS)
        .take_while(|m| m.stamp_ns() <= recorded_end)
    {
        recorder.write(&m).unwrap();
    }
    recorder.finish().unwrap();
    let gnss_only = SensorSet {
        gnss: true,
        ..SensorSet::default()
    };
    for (name, config) in [("rtk", &rtk), ("consumer", &consumer)] {
        let sim = Simulation::new(config, "s0", SEED).expect("s0");
        let live: Vec<Message> = sim
            .stream(SensorSet {
                gnss: true,
                ..DEFAULT_SENSORS
            })
            .take_while(|m| m.stamp_ns() <= end)
            .collect();
        let epochs = live
            .iter()
            .filter(|m| matches!(m, Message::Gnss(_)))
            .count();
        assert!(
            epochs >= 4 * SECONDS as usize,
            "{name}: {epochs} epochs in {SECONDS} s"
        );
        assert!(live.iter().any(|m| matches!(m, Message::Lidar(_))));
        let merged: Vec<Message> = replay_with_live(&path, DEFAULT_SENSORS, sim.stream(gnss_only))
            .unwrap()
            .take_while(|m| m.stamp_ns() <= end)
            .collect();
        assert_same_stream(&merged, &live, name);
    }
}

#[test]
fn the_same_run_records_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let a = std::fs::read(record(dir.path(), "a.mcap", &[])).unwrap();
    let b = std::fs::read(record(dir.path(), "b.mcap", &[])).unwrap();
    assert!(
        a == b,
        "two recordings of one run differ ({} / {} bytes)",
        a.len(),
        b.len()
    );
    // The camera renders in parallel bands; its frames must not depend on the scheduling.
    let camera = ["--sensors", "rgbd"];
    let a = std::fs::read(record_for(dir.path(), "ca.mcap", 0.5, &camera)).unwrap();
    let b = std::fs::read(record_for(dir.path(), "cb.mcap", 0.5, &camera)).unwrap();
    assert!(
        a == b,
        "two camera recordings of one run differ ({} / {} bytes)",
        a.len(),
        b.len()
    );
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 4, "no temporary files left: {names:?}");
}

#[test]
fn a_damaged_or_missing_file_is_one_line_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path(), "s0.mcap", &["--sensors", "imu"]);
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let err = match replay_messages(&cut, SensorSet::ALL) {
        Ok(_) => panic!("a truncated file replays"),
        Err(e) => format!("{e:#}"),
    };
    assert!(err.contains("cut.mcap") && !err.contains('\n'), "{err}");

    let missing = dir.path().join("no/such/dir/out.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(["record", "--scenario", "s0", "--max-time", "0.1", "-o"])
        .arg(&missing)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "recording into a missing folder succeeds"
    );
    assert!(
        stderr.contains("out.mcap") && stderr.trim().lines().count() == 1,
        "{stderr}"
    );
}

/// Runs tests/mcap/check_mcap.py with the `python3` first on PATH.
fn python_check(path: &Path) -> Value {
    crate::common::mcap_check("check_mcap.py", &[path])
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// JSON numbers go through a decimal text: equal to a few ulps.
fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(b.abs())
}

#[test]
fn an_independent_ros2_decoder_reads_the_recording() {
    let dir = tempfile::tempdir().unwrap();
    let path = record(dir.path(), "s0.mcap", &[]);
    let summary = python_check(&path);
    let topics = &summary["topics"];
    assert_eq!(summary["profile"], "ros2");

    // Counts: the live stream's, at the configured rates.
    let live = live();
    let count = |f: fn(&Message) -> bool| live.iter().filter(|m| f(m)).count() as u64;
    let cfg = config();
    let rates = &cfg.sensors;
    let expected = [
        (
            "/imu",
            count(|m| matches!(m, Message::Imu(_))),
            rates.imu.rate_hz,
        ),
        (
            "/points",
            count(|m| matches!(m, Message::Lidar(_))),
            rates.lidar.rate_hz,
        ),
        (
            "/odom",
            count(|m| matches!(m, Message::WheelOdometry(_))),
            rates.wheel_odometry.rate_hz,
        ),
        (
            "/ground_truth",
            count(|m| matches!(m, Message::GroundTruth(_))),
            rates.ground_truth.rate_hz,
        ),
        (
            "/scan_front",
            count(|m| matches!(m, Message::Scan2d(s) if s.side.name() == "scan_front")),
            rates.scan2d_front.rate_hz,
        ),
    ];
    for (topic, n, rate_hz) in expected {
        assert_eq!(topics[topic]["count"], n, "{topic} count");
        let per_s = n as f64 / SECONDS;
        assert!(
            (per_s - rate_hz).abs() <= rate_hz * 0.05 + 1.0 / SECONDS,
            "{topic}: {n} messages in {SECONDS} s, expected {rate_hz} Hz"
        );
    }
    assert_eq!(
        topics["/imu"]["count"], 1001,
        "IMU at 200 Hz for 5 s, both ends"
    );
    assert_eq!(topics["/points"]["count"], 50, "lidar at 10 Hz for 5 s");
    assert_eq!(topics["/tf_static"]["count"], 1);
    assert_eq!(
        topics["/ground_truth/twist"]["count"],
        topics["/ground_truth"]["count"]
    );

    // First values, decoded independently, against the live stream.
    let first = |f: fn(&Message) -> bool| live.iter().find(|m| f(m)).expect("present").clone();
    let Message::Imu(imu) = first(|m| matches!(m, Message::Imu(_))) else {
        unreachable!()
    };
    let py = &topics["/imu"]["first"];
    assert_eq!(py["stamp_ns"], imu.stamp_ns);
    assert_eq!(py["orientation_covariance0"], -1.0);
    for (got, want) in f64s(&py["linear_acceleration"])
        .iter()
        .zip(imu.accel_mps2.iter())
    {
        assert!(close(*got, *want), "IMU accel {got} vs {want}");
    }
    for (got, want) in f64s(&py["angular_velocity"])
        .iter()
        .zip(imu.gyro_rps.iter())
    {
        assert!(close(*got, *want), "IMU gyro {got} vs {want}");
    }

    let Message::Lidar(scan) = first(|m| matches!(m, Message::Lidar(_))) else {
        unreachable!()
    };
    let py = &topics["/points"]["first"];
    assert_eq!(
        py["stamp_ns"], scan.stamp_ns,
        "a cloud is stamped at its sweep's start"
    );
    assert_eq!(
        py["log_time_ns"],
        scan.stamp_ns + scan.sweep_ns,
        "and logged at its end"
    );
    assert_eq!(py["width"], scan.points.len());
    let p = scan.points[0];
    let point = &py["first_point"];
    for (name, want) in [
        ("x", p.x),
        ("y", p.y),
        ("z", p.z),
        ("intensity", p.intensity),
        ("time", p.time_s),
    ] {
        let got = point[name].as_f64().unwrap() as f32;
        assert_eq!(got, want, "first point's {name}");
    }
    assert_eq!(point["ring"], p.ring);

    let Message::GroundTruth(gt) = first(|m| matches!(m, Message::GroundTruth(_))) else {
        unreachable!()
    };
    let py = f64s(&topics["/ground_truth"]["first"]["position"]);
    for (got, want) in py.iter().zip(gt.world_from_base.translation.vector.iter()) {
        assert!(close(*got, *want), "ground truth position {got} vs {want}");
    }

    let Message::WheelOdometry(odom) = first(|m| matches!(m, Message::WheelOdometry(_))) else {
        unreachable!()
    };
    let py = &topics["/odom"]["first"];
    assert_eq!(py["child_frame_id"], "base_link");
    assert!(close(py["angular_z"].as_f64().unwrap(), odom.angular_rps));

    let tf = &topics["/tf_static"]["first"];
    let lidar_z = f64s(&tf["velodyne"]["translation"])[2];
    assert_eq!(
        lidar_z, cfg.sensors.lidar.mount.xyz_m[2],
        "base_link → velodyne height"
    );
    assert_eq!(tf["laser_back"]["parent"], "base_link");
}

/// The camera's frames come back from a recording exactly as the simulator rendered them:
/// colour bytes, depth bits (invalid pixels included) and intrinsics, in stream order among
/// every other sensor. No plugin in the workspace consumes the camera yet, so this compares
/// the replayed stream with the live one message by message (what a plugin would be fed).
#[test]
fn the_camera_replays_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = record_for(
        dir.path(),
        "all.mcap",
        CAMERA_SECONDS,
        &["--sensors", "all"],
    );
    let live = live_for(CAMERA_SECONDS, SensorSet::ALL);
    let frames: Vec<&RgbdFrame> = live
        .iter()
        .filter_map(|m| match m {
            Message::Rgbd(f) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(frames.len(), 31, "30 Hz for {CAMERA_SECONDS} s, both ends");
    assert!(
        frames
            .iter()
            .any(|f| f.image.depth_m.iter().any(|z| *z == 0.0 || z.is_nan())),
        "the frames have invalid depth pixels, so their encoding is exercised"
    );
    let replayed: Vec<Message> = Replay::open(&path, SensorSet::ALL)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_same_stream(&replayed, &live, "every sensor with the camera");

    // The camera alone, as a plugin that needs only it is fed.
    let replayed: Vec<Message> = replay_messages(&path, CAMERA_ONLY).unwrap().collect();
    let expected: Vec<Message> = live
        .into_iter()
        .filter(|m| matches!(m, Message::Rgbd(_)))
        .collect();
    assert_same_stream(&replayed, &expected, "the camera alone");
}

fn u64s(v: &Value) -> Vec<u64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_u64().expect("an integer"))
        .collect()
}

#[test]
fn an_independent_ros2_decoder_reads_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let path = record_for(
        dir.path(),
        "rgbd.mcap",
        CAMERA_SECONDS,
        &["--sensors", "rgbd"],
    );
    let summary = python_check(&path);
    let topics = &summary["topics"];
    let mut names: Vec<&str> = topics
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    names.sort_unstable();
    let mut expected_names = CAMERA_TOPICS.to_vec();
    expected_names.push("/tf_static");
    expected_names.sort_unstable();
    assert_eq!(
        names, expected_names,
        "the camera's topics and the static TF"
    );

    // Counts and stamps: 30 Hz for the whole duration, both ends, as the live stream has them.
    let cfg = config();
    let cam = &cfg.sensors.camera;
    let live: Vec<RgbdFrame> = live_for(CAMERA_SECONDS, CAMERA_ONLY)
        .into_iter()
        .map(|m| match m {
            Message::Rgbd(f) => f,
            other => panic!("a camera-only stream has {}", describe(&other)),
        })
        .collect();
    let stamps: Vec<u64> = live.iter().map(|f| f.stamp_ns as u64).collect();
    let n = (cam.rate_hz * CAMERA_SECONDS).round() as usize + 1;
    assert_eq!(stamps.len(), n, "{} Hz for {CAMERA_SECONDS} s", cam.rate_hz);
    for (k, &stamp) in stamps.iter().enumerate() {
        let want = (k as f64 * 1e9 / cam.rate_hz).round() as u64;
        assert_eq!(stamp, want, "frame {k} is stamped k / rate");
    }
    for topic in CAMERA_TOPICS {
        assert_eq!(topics[topic]["count"], n, "{topic} count");
        assert_eq!(
            u64s(&topics[topic]["stamps_ns"]),
            stamps,
            "{topic} header stamps"
        );
    }

    // The first frame's images, decoded independently, against the live frame.
    let first = &live[0].image;
    let frame = "camera_color_optical_frame";
    for (topic, encoding, bytes_per_pixel) in [
        ("/camera/color/image_raw", "rgb8", 3),
        ("/camera/depth/image_raw", "32FC1", 4),
    ] {
        let py = &topics[topic]["first"];
        assert_eq!(py["frame_id"], frame, "{topic} frame");
        assert_eq!(py["encoding"], encoding, "{topic} encoding");
        assert_eq!(py["height"], first.height, "{topic} height");
        assert_eq!(py["width"], first.width, "{topic} width");
        assert_eq!(py["is_bigendian"], 0, "{topic} is little-endian");
        assert_eq!(
            py["step"],
            first.width * bytes_per_pixel,
            "{topic} step: packed rows"
        );
        assert_eq!(
            py["data_len"],
            first.width * first.height * bytes_per_pixel,
            "{topic} data length"
        );
    }
    let byte_sum: u64 = first.rgb.iter().map(|&b| u64::from(b)).sum();
    assert_eq!(
        topics["/camera/color/image_raw"]["first"]["byte_sum"], byte_sum,
        "the colour bytes"
    );
    let py = &topics["/camera/depth/image_raw"]["first"];
    let zeros = first.depth_m.iter().filter(|&&z| z == 0.0).count();
    let nans = first.depth_m.iter().filter(|z| z.is_nan()).count();
    assert_eq!(py["zero_pixels"], zeros, "invalid depth as 0, as emitted");
    assert_eq!(py["nan_pixels"], nans, "invalid depth as NaN, as emitted");
    assert!(
        py["first_valid_pixel"].is_u64(),
        "the first frame has a valid depth pixel"
    );
    let samples = py["sample_bits"].as_object().unwrap();
    assert_eq!(samples.len(), 4, "four sampled depth pixels: {samples:?}");
    for (index, bits) in samples {
        let i: usize = index.parse().unwrap();
        assert_eq!(
            bits.as_u64(),
            Some(u64::from(first.depth_m[i].to_bits())),
            "depth pixel {i}: bits of {}",
            first.depth_m[i]
        );
    }

    // The camera info: the rig's pinhole, no distortion.
    let rig = vinebench::rig::rig(&cfg);
    let spec = rig
        .sensors
        .iter()
        .find(|s| s.name == "camera")
        .expect("the rig has the camera");
    let k = |name: &str| spec.intrinsics[name];
    let (fx, fy, cx, cy) = (k("fx"), k("fy"), k("cx"), k("cy"));
    let py = &topics["/camera/color/camera_info"]["first"];
    assert_eq!(py["frame_id"], frame);
    assert_eq!(py["height"], first.height);
    assert_eq!(py["width"], first.width);
    assert_eq!(py["distortion_model"], "plumb_bob");
    assert_eq!(f64s(&py["d"]), vec![0.0; 5], "no distortion");
    let want_k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0];
    let want_p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    for (name, want) in [("k", &want_k[..]), ("p", &want_p[..])] {
        let got = f64s(&py[name]);
        assert_eq!(got.len(), want.len(), "{name} length");
        for (g, w) in got.iter().zip(want) {
            assert!(
                close(*g, *w),
                "camera info {name}: {got:?}, expected {want:?}"
            );
        }
    }
    assert_eq!(
        f64s(&py["r"]),
        vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        "r: identity"
    );

    // The static TF: base_link → the optical frame, as the rig gives the camera, and in the
    // optical convention: z along the body's forward (x), y along its down (-z).
    let tf = &topics["/tf_static"]["first"][frame];
    assert_eq!(tf["parent"], "base_link");
    for (got, want) in f64s(&tf["translation"])
        .iter()
        .zip(spec.base_from_sensor_xyz)
    {
        assert!(close(*got, want), "camera translation {got} vs {want}");
    }
    let q = f64s(&tf["rotation"]);
    for (got, want) in q.iter().zip(spec.base_from_sensor_xyzw) {
        assert!(close(*got, want), "camera rotation {got} vs {want}");
    }
    let base_from_optical =
        UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]));
    let base_from_body = cam.mount.base_from_sensor().rotation;
    for (optical_axis, body_axis, what) in [
        (
            Vector3::z(),
            Vector3::x(),
            "optical z is the body's forward",
        ),
        (Vector3::x(), -Vector3::y(), "optical x is the body's right"),
        (Vector3::y(), -Vector3::z(), "optical y is the body's down"),
    ] {
        let d = base_from_optical * optical_axis - base_from_body * body_axis;
        assert!(d.norm() < 1e-12, "{what}: off by {d:?}");
    }
}

#[test]
fn export_writes_tum_ground_truth_tum_rgbd_and_kitti_lidar() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("export");
    let out = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args([
            "export",
            "--scenario",
            "s0",
            "--max-time",
            "1",
            "--seed",
            "7",
            "--out",
        ])
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tum = std::fs::read_to_string(out_dir.join("groundtruth.tum")).unwrap();
    assert_eq!(
        tum.lines().count(),
        101,
        "ground truth at 100 Hz for 1 s, both ends"
    );
    assert_eq!(
        tum.lines().next().unwrap().split(' ').count(),
        8,
        "t x y z qx qy qz qw"
    );
    let times = std::fs::read_to_string(out_dir.join("lidar/times.txt")).unwrap();
    assert_eq!(times.lines().count(), 10, "one line per sweep");
    let sim = Simulation::new(&config(), "s0", 7).unwrap();
    let Some(Message::Lidar(scan)) = sim
        .stream(SensorSet {
            lidar: true,
            ..SensorSet::default()
        })
        .next()
    else {
        panic!("a sweep")
    };
    let bin = std::fs::read(out_dir.join("lidar/000000.bin")).unwrap();
    assert_eq!(
        bin.len(),
        scan.points.len() * 16,
        "x, y, z, reflectance as f32"
    );
    assert_eq!(
        f32::from_le_bytes(bin[..4].try_into().unwrap()),
        scan.points[0].x
    );
    // The camera as a TUM RGB-D sequence, with the intrinsics and mount of the simulated
    // frames in camera.yaml.
    let read = |p: &str| std::fs::read_to_string(out_dir.join(p)).unwrap();
    let pairs: Vec<String> = read("rgbd/associations.txt")
        .lines()
        .map(str::to_owned)
        .collect();
    assert_eq!(pairs.len(), 31, "30 Hz over 1 s, both ends: {pairs:?}");
    let (stamp, _) = pairs[0].split_once(' ').expect("timestamp filename");
    assert!(out_dir.join(format!("rgbd/rgb/{stamp}.png")).is_file());
    assert!(out_dir.join(format!("rgbd/depth/{stamp}.png")).is_file());
    let Some(Message::Rgbd(frame)) = sim
        .stream(SensorSet {
            rgbd: true,
            ..SensorSet::default()
        })
        .next()
    else {
        panic!("a camera frame")
    };
    let yaml = read("rgbd/camera.yaml");
    let key = |k: &str| -> f64 {
        yaml.lines()
            .find_map(|l| l.strip_prefix(&format!("{k}: ")))
            .unwrap_or_else(|| panic!("{k} in\n{yaml}"))
            .parse()
            .unwrap_or_else(|e| panic!("{k}: {e}"))
    };
    let [fx, fy, cx, cy] = frame.image.intrinsics;
    assert_eq!(
        [
            key("Camera.fx"),
            key("Camera.fy"),
            key("Camera.cx"),
            key("Camera.cy")
        ],
        [fx, fy, cx, cy]
    );
    assert_eq!(key("Camera.width"), frame.image.width as f64);
    assert_eq!(key("Camera.height"), frame.image.height as f64);
    assert_eq!(key("Camera.fps"), config().sensors.camera.rate_hz);
    assert_eq!(key("DepthMapFactor"), 5000.0);
    let mount =
        config().sensors.camera.mount.base_from_sensor() * sim::camera::camera_from_optical();
    let data: Vec<f64> = yaml
        .split_once("data: [")
        .and_then(|(_, rest)| rest.split_once(']'))
        .expect("base_from_camera data")
        .0
        .split(',')
        .map(|v| v.trim().parse().expect("number"))
        .collect();
    let m = mount.to_homogeneous();
    for (k, v) in data.iter().enumerate() {
        assert!(
            (v - m[(k / 4, k % 4)]).abs() < 1e-8,
            "base_from_camera[{k}] = {v}"
        );
    }
}

/// A plugin fed from a recording gives the same results as fed live: the baseline's
/// estimate and metrics are byte-identical, over the whole route and cut by `--max-time`
/// (the recording holds the whole route: the replay honours the limit).
#[test]
fn a_plugin_fed_from_a_recording_matches_the_live_run() {
    let dir = tempfile::tempdir().unwrap();
    let recording = dir.path().join("s0.mcap");
    let vinebench = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_vinebench"))
            .args(args)
            .env(
                "VINEBENCH_PLUGIN_PATH",
                std::env::current_exe().unwrap().parent().unwrap(),
            )
            .output()
            .expect("vinebench runs");
        assert!(
            o.status.success(),
            "vinebench {args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    let rec = recording.to_str().unwrap();
    vinebench(&[
        "record",
        "--scenario",
        "s0",
        "--seed",
        "3",
        "--sensors",
        "gt,imu,odom",
        "-o",
        rec,
    ]);
    let (live, replayed) = (dir.path().join("live"), dir.path().join("replayed"));
    let common = [
        "run",
        "--scenario",
        "s0",
        "--seed",
        "3",
        "--plugin",
        "wheel-odometry",
        "--out",
    ];
    let cut = ["--max-time", "10"];
    let (live_cut, replayed_cut) = (dir.path().join("live-cut"), dir.path().join("replayed-cut"));
    vinebench(&[&common[..], &[live.to_str().unwrap()]].concat());
    vinebench(&[&common[..], &[replayed.to_str().unwrap(), "--dataset", rec]].concat());
    vinebench(&[&common[..], &[live_cut.to_str().unwrap()], &cut].concat());
    vinebench(
        &[
            &common[..],
            &[replayed_cut.to_str().unwrap(), "--dataset", rec],
            &cut,
        ]
        .concat(),
    );
    for (live, replayed, what) in [
        (&live, &replayed, "whole"),
        (&live_cut, &replayed_cut, "cut"),
    ] {
        for f in [
            "estimate.tum",
            "online.tum",
            "groundtruth.tum",
            "metrics.json",
        ] {
            let a = std::fs::read(live.join("s0/wheel-odometry").join(f)).unwrap();
            let b = std::fs::read(replayed.join("s0/wheel-odometry").join(f)).unwrap();
            assert!(
                a == b,
                "{f} differs between the live and the replayed run ({what} route)"
            );
        }
    }
    let gt =
        std::fs::read_to_string(replayed_cut.join("s0/wheel-odometry/groundtruth.tum")).unwrap();
    let last: f64 = gt
        .lines()
        .last()
        .and_then(|l| l.split(' ').next())
        .and_then(|t| t.parse().ok())
        .expect("a stamp");
    assert!(
        (9.98..=10.0).contains(&last),
        "the replay of the whole route cut at 10 s: ground truth ends at {last} s"
    );
}
