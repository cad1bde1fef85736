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

use serde_json::Value;
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};
use vinebench::dataset::{Replay, replay_messages};

const SECONDS: f64 = 5.0;
const SEED: u64 = 7;
/// Every sensor a recording can hold (the camera's topics are still to come).
const RECORDABLE: SensorSet = SensorSet {
    rgbd: false,
    ..SensorSet::ALL
};

fn record(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let max_time = SECONDS.to_string();
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

/// The stream `vinebench record` writes: every recordable sensor, cut where `--max-time`
/// cuts it.
fn live() -> Vec<Message> {
    let sim = Simulation::new(&config(), "s0", SEED).expect("s0 builds");
    let end = sim.duration_ns().min((SECONDS * 1e9) as i64);
    sim.stream(RECORDABLE)
        .take_while(|m| m.stamp_ns() <= end)
        .collect()
}

fn assert_same_stream(replayed: &[Message], live: &[Message], what: &str) {
    for (i, (r, l)) in replayed.iter().zip(live).enumerate() {
        assert!(
            r == l,
            "{what}: message {i} differs\nreplayed: {r:?}\nlive:     {l:?}"
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
    let replayed: Vec<Message> = Replay::open(&path, RECORDABLE)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert_same_stream(&replayed, &live, "all recordable sensors");

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
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 2, "no temporary files left: {names:?}");
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
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/mcap/check_mcap.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(path)
        .output()
        .expect("python3 on PATH (source scripts/setup.sh)");
    assert!(
        out.status.success(),
        "{} failed (are tests/mcap/requirements.txt installed? `source scripts/setup.sh` \
         puts them first on PATH): {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("check_mcap.py prints JSON")
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

#[test]
fn export_writes_tum_ground_truth_and_kitti_lidar() {
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
}

/// A plugin fed from a recording gives the same results as fed live: the baseline's
/// estimate and metrics are byte-identical.
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
    vinebench(&[&common[..], &[live.to_str().unwrap()]].concat());
    vinebench(&[&common[..], &[replayed.to_str().unwrap(), "--dataset", rec]].concat());
    for f in [
        "estimate.tum",
        "online.tum",
        "groundtruth.tum",
        "metrics.json",
    ] {
        let a = std::fs::read(live.join("s0/wheel-odometry").join(f)).unwrap();
        let b = std::fs::read(replayed.join("s0/wheel-odometry").join(f)).unwrap();
        assert!(a == b, "{f} differs between the live and the replayed run");
    }
}
