//! End-to-end checks of the `vinebench` binary's simulator front end.

use std::path::Path;
use std::process::{Command, Output};

fn vinebench(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(args)
        .output()
        .expect("vinebench runs")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(str::to_owned)
        .collect()
}

/// `simulate --out` writes every file a user expects, with consistent counts, and prints
/// the real-time factor last.
#[test]
fn simulate_dumps_every_sensor_and_reports_the_real_time_factor() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s0");
    let o = vinebench(&[
        "simulate",
        "--scenario",
        "s0",
        "--sensors",
        "gt,imu,odom,lidar,scan2d",
        "--seed",
        "3",
        "--max-time",
        "3",
        "--out",
        out.to_str().expect("utf-8 path"),
    ]);
    assert!(o.status.success(), "simulate failed: {}", stderr(&o));
    let last = stdout(&o).lines().last().unwrap_or_default().to_owned();
    let factor: f64 = last
        .strip_prefix("real-time factor: ")
        .unwrap_or_else(|| panic!("last line should be the real-time factor, got '{last}'"))
        .parse()
        .expect("a number");
    assert!(factor > 0.0, "real-time factor {factor}");
    // Each sensor's cost, making and writing, in wall seconds per simulated second: every
    // sensor asked for, and together no more than the whole run took.
    let cost_line = stdout(&o)
        .lines()
        .find_map(|l| {
            l.strip_prefix("cost, wall s per simulated s: ")
                .map(str::to_owned)
        })
        .expect("a cost line");
    let mut total = 0.0;
    for sensor in ["gt", "imu", "odom", "lidar", "scan_front", "scan_back"] {
        let entry = cost_line
            .split(", ")
            .find(|e| e.split(' ').next() == Some(sensor))
            .unwrap_or_else(|| panic!("{sensor} in '{cost_line}'"));
        let numbers: Vec<f64> = entry.split(' ').filter_map(|w| w.parse().ok()).collect();
        assert_eq!(numbers.len(), 2, "making and writing: {entry}");
        total += numbers.iter().sum::<f64>();
    }
    assert!(
        total > 0.0 && total <= 1.0 / factor + 0.01,
        "{cost_line} against 1/{factor}"
    );

    // 3 s at 100 Hz from t = 0 inclusive.
    let gt = lines(&out.join("groundtruth.tum"));
    assert_eq!(gt.len(), 301, "ground truth lines");
    let fields: Vec<f64> = gt[0]
        .split(' ')
        .map(|f| f.parse().expect("numbers"))
        .collect();
    assert_eq!(fields.len(), 8, "TUM has 8 columns: {}", gt[0]);
    let q_norm = fields[4..].iter().map(|q| q * q).sum::<f64>().sqrt();
    assert!(
        (q_norm - 1.0).abs() < 1e-6,
        "unit quaternion, norm {q_norm}"
    );

    assert_eq!(
        lines(&out.join("imu.csv")).len(),
        1 + 601,
        "imu header + 200 Hz x 3 s + 1"
    );
    assert_eq!(
        lines(&out.join("odom.csv")).len(),
        1 + 151,
        "odom header + 50 Hz x 3 s + 1"
    );
    let times = lines(&out.join("lidar/times.txt"));
    assert_eq!(times.len(), 30, "sweeps completed within 3 s at 10 Hz");
    for i in 0..times.len() {
        let bin = out.join(format!("lidar/{i:06}.bin"));
        let len = std::fs::metadata(&bin).expect("bin exists").len();
        assert!(
            len > 16 * 10_000 && len % 16 == 0,
            "{}: {len} bytes",
            bin.display()
        );
    }
    let front = lines(&out.join("scan_front.csv"));
    let row: Vec<&str> = front.last().expect("rows").split(',').collect();
    assert_eq!(row.len(), 1 + 720, "stamp + 720 ranges");
    let png = std::fs::read(out.join("topview.png")).expect("top view written");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "top view is a PNG");
}

/// A bad configuration is one line naming the file and the key, a non-zero exit, and no
/// output folder.
#[test]
fn misspelt_config_key_fails_cleanly_without_output() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let world = tmp.path().join("bad.toml");
    std::fs::write(&world, "[vineyard]\nrowz = 3\n").expect("write");
    let out = tmp.path().join("out");
    let o = vinebench(&[
        "simulate",
        "--scenario",
        "s0",
        "--world",
        world.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(!o.status.success(), "a misspelt key must fail");
    let err = stderr(&o);
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(
        err.contains("bad.toml") && err.contains("rowz"),
        "names file and key: {err}"
    );
    assert!(!out.exists(), "no output folder after a failure");
}

/// s4 (ours: lane 3 twice eastwards, lane 4 between) is a scenario like the paper's:
/// simulated whole from the embedded defaults and recorded by name.
#[test]
fn s4_is_simulated_and_recorded_by_name() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s4");
    let o = vinebench(&[
        "simulate",
        "--scenario",
        "s4",
        "--sensors",
        "gt",
        "--out",
        out.to_str().expect("utf-8 path"),
    ]);
    assert!(o.status.success(), "simulate s4 failed: {}", stderr(&o));
    assert!(
        stdout(&o).contains("scenario s4: 84.3 m in "),
        "s4 drives 84.3 m: {}",
        stdout(&o)
    );
    let gt = lines(&out.join("groundtruth.tum"));
    let last: f64 = gt
        .last()
        .and_then(|l| l.split(' ').next())
        .and_then(|t| t.parse().ok())
        .expect("a stamp");
    assert!(
        (160.0..200.0).contains(&last),
        "84 m at up to 0.5 m/s with two U-turns: {last} s"
    );
    let mcap = tmp.path().join("s4.mcap");
    let o = vinebench(&[
        "record",
        "--scenario",
        "s4",
        "--sensors",
        "gt,odom",
        "--max-time",
        "2",
        "-o",
        mcap.to_str().expect("utf-8 path"),
    ]);
    assert!(o.status.success(), "record s4 failed: {}", stderr(&o));
    let bytes = std::fs::read(&mcap).expect("recording written");
    assert_eq!(&bytes[..8], b"\x89MCAP0\r\n", "an MCAP file");
}

#[test]
fn unknown_scenario_and_sensor_are_named() {
    let o = vinebench(&["simulate", "--scenario", "s9"]);
    assert!(
        !o.status.success()
            && stderr(&o).contains("s9")
            && stderr(&o).contains("s3")
            && stderr(&o).contains("s4"),
        "{}",
        stderr(&o)
    );
    let o = vinebench(&["simulate", "--scenario", "s0", "--sensors", "gt,radar"]);
    assert!(
        !o.status.success() && stderr(&o).contains("radar"),
        "{}",
        stderr(&o)
    );
}

/// The camera is dumped as a TUM RGB-D folder: listed frames, 8-bit colour and 16-bit
/// depth PNGs (metres x 5000).
#[test]
fn simulate_dumps_the_camera_as_tum_rgbd() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("cam");
    let o = vinebench(&[
        "simulate",
        "--scenario",
        "s0",
        "--sensors",
        "gt,rgbd",
        "--max-time",
        "1",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "simulate failed: {}", stderr(&o));
    let rgb = lines(&out.join("rgbd/rgb.txt"));
    let frames: Vec<&String> = rgb.iter().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(frames.len(), 31, "30 Hz over 1 s, both ends included");
    assert_eq!(
        lines(&out.join("rgbd/associations.txt")).len(),
        31,
        "one association per frame"
    );
    let (stamp, file) = frames[10].split_once(' ').expect("timestamp filename");
    assert_eq!(file, format!("rgb/{stamp}.png"), "TUM RGB-D naming");
    let depth = std::fs::read(out.join(format!("rgbd/depth/{stamp}.png"))).expect("depth PNG");
    // IHDR: width, height, bit depth 16, colour type 0 (grayscale).
    assert_eq!(
        &depth[16..26],
        &[0, 0, 2, 128, 0, 0, 1, 224, 16, 0],
        "640x480 16-bit grayscale"
    );
}

/// The ladder end to end: `world --profile` resolves a world under another rung, and the
/// simulator run on what it printed follows that rung. The IMU standing still for its first
/// 2 s reads one value under `ideal` and a noisy one under `typical`.
#[test]
fn world_prints_the_resolved_world_under_a_profile_and_the_simulator_follows_it() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let mut spread = Vec::new();
    for profile in ["ideal", "typical"] {
        let o = vinebench(&["world", "--profile", profile]);
        assert!(o.status.success(), "world: {}", stderr(&o));
        let text = stdout(&o);
        let table: toml::Table = text.parse().expect("world prints TOML");
        assert_eq!(table["profile"].as_str(), Some(profile), "{text}");
        let world = tmp.path().join(format!("{profile}.toml"));
        std::fs::write(&world, &text).expect("write");
        // The still robot's IMU for 1.5 s, in that world given by file or by `--profile`.
        let simulate = |world_args: &[&str], out: &Path| {
            let mut args = vec!["simulate"];
            args.extend_from_slice(world_args);
            args.extend([
                "--scenario",
                "s0",
                "--sensors",
                "imu",
                "--max-time",
                "1.5",
                "--out",
            ]);
            args.push(out.to_str().expect("utf-8"));
            let o = vinebench(&args);
            assert!(
                o.status.success(),
                "simulate {world_args:?}: {}",
                stderr(&o)
            );
        };
        let out = tmp.path().join(profile);
        simulate(&["--world", world.to_str().expect("utf-8")], &out);
        // `--profile` on the simulating commands is the same world.
        let direct = tmp.path().join(format!("{profile}-direct"));
        simulate(&["--profile", profile], &direct);
        assert!(
            std::fs::read(out.join("imu.csv")).expect("imu.csv")
                == std::fs::read(direct.join("imu.csv")).expect("imu.csv"),
            "{profile}: --profile gives the world `world --profile` prints"
        );
        // The still robot's vertical specific force, sample by sample: its spread.
        let az: Vec<f64> = lines(&out.join("imu.csv"))[1..]
            .iter()
            .map(|l| l.split(',').nth(3).expect("az").parse().expect("a number"))
            .collect();
        let mean = az.iter().sum::<f64>() / az.len() as f64;
        let sd = (az.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / az.len() as f64).sqrt();
        spread.push(sd);
    }
    // Under ideal only the rounding of the trajectory's second derivative is left; under
    // typical the accelerometer's white noise, 2e-3 m/s²/√Hz at 200 Hz: σ ≈ 0.02 m/s².
    assert!(spread[0] < 1e-9, "ideal: σ {} m/s² while still", spread[0]);
    assert!(
        (0.01..0.04).contains(&spread[1]),
        "typical: σ {} m/s² while still",
        spread[1]
    );

    let o = vinebench(&["world", "--profile", "gazebo"]);
    assert_eq!(o.status.code(), Some(2), "a usage error");
    assert!(
        stderr(&o).contains("unknown profile 'gazebo'"),
        "{}",
        stderr(&o)
    );
}

/// `run --profile` (as `bench --profile`): the workers read the world resolved under that
/// profile, which the run folder keeps, and the file written for them is gone afterwards.
#[test]
fn a_run_under_another_profile_keeps_its_resolved_world() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("field");
    // The plugin is found on the test build's search path (the helper sets it).
    let o = crate::common::vinebench(&[
        "run",
        "--scenario",
        "s0",
        "--plugin",
        "wheel-odometry",
        "--profile",
        "field",
        "--max-time",
        "2",
        "--align",
        "origin",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "run --profile: {}", stderr(&o));
    let world: toml::Table = std::fs::read_to_string(out.join("s0/wheel-odometry/world.toml"))
        .expect("the run's world")
        .parse()
        .expect("TOML");
    assert_eq!(world["profile"].as_str(), Some("field"));
    assert_eq!(
        world["sensors"]["camera"]["clock_offset_ns"].as_integer(),
        Some(30_000_000),
        "field's keys"
    );
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("tmp")
        .map(|e| e.expect("entry").file_name())
        .filter(|n| n.to_string_lossy().contains(".world-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
