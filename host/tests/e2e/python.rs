//! The Python bridge end to end: a Python class hosted by `libpython_bridge.so` in the real
//! host, beside the C plugin doing the same arithmetic; its faults (an exception, a segfault
//! in native code, an array kept past its call) each cost their own run; and the real
//! KISS-ICP and ORB-SLAM3 through it on a short route. The venvs are made by
//! `scripts/setup.sh` (target/python-bridge-venv, target/kiss-icp-venv, target/orbslam3-venv).

use std::path::{Path, PathBuf};

use super::bench::{plugin_lib, run_bench, workspace_root};
use crate::common::{json, text, vinebench};

pub(crate) fn venv(name: &str) -> PathBuf {
    let venv = workspace_root().join("target").join(name);
    assert!(
        venv.join("bin/python").is_file(),
        "{} missing: run `bash scripts/setup.sh`",
        venv.display()
    );
    venv
}

/// A `[[plugins]]` entry hosting `module.class` through the bridge.
pub(crate) fn python_entry(
    label: &str,
    paths: &[PathBuf],
    venv: &Path,
    module: &str,
    class: &str,
    extra: &str,
) -> String {
    let paths: Vec<String> = paths
        .iter()
        .map(|p| format!("\"{}\"", p.display()))
        .collect();
    format!(
        "[[plugins]]\npath = \"{}\"\nlabel = \"{label}\"\n[plugins.params]\nmodule = \"{module}\"\nclass = \"{class}\"\npath = [{}]\nvenv = \"{}\"\n{extra}\n",
        plugin_lib("python_bridge").display(),
        paths.join(", "),
        venv.display()
    )
}

/// The fixtures' module path: tests/python-plugin and the bridge's own `vinebench_plugin.py`.
pub(crate) fn fixture_paths() -> Vec<PathBuf> {
    let root = workspace_root();
    vec![
        root.join("tests/python-plugin"),
        root.join("plugins/python-bridge/python"),
    ]
}

#[test]
fn a_python_plugin_runs_like_a_c_one_and_its_faults_cost_its_own_run() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let venv = venv("python-bridge-venv");
    let paths = fixture_paths();
    let py = |label: &str, class: &str, extra: &str| {
        python_entry(label, &paths, &venv, "bridge_fixtures", class, extra)
    };
    let c = PathBuf::from(env!("VINEBENCH_C_ODOMETRY"));
    let toml = [
        "scenarios = [\"s1\"]\nseed = 3\nmax_time_s = 20.0\njobs = 2\n".to_owned(),
        format!(
            "[[plugins]]\npath = \"{}\"\nlabel = \"c-odometry\"\n",
            c.display()
        ),
        py("py-odometry", "Odometry", "lidar = true"),
        py("py-raise", "Odometry", "fault = \"raise\"\nafter = 100"),
        py(
            "py-segfault",
            "Odometry",
            "fault = \"segfault\"\nafter = 100",
        ),
        py("py-keep", "Keeper", ""),
        py("py-keep-buffer", "BufferKeeper", ""),
        py("py-missing", "NoSuchClass", ""),
    ]
    .concat();
    let (o, out) = run_bench(tmp.path(), "python", &toml);
    assert!(o.status.success(), "bench failed: {}", text(&o.stderr));
    let table = json(&out.join("table.json"));
    let run = |label: &str| table["s1"][label].clone();
    assert_eq!(run("py-odometry")["status"], "ok", "{}", table["s1"]);
    for (label, reason) in [
        (
            "py-raise",
            "bridge_fixtures.Odometry: ValueError: deliberate error at",
        ),
        ("py-segfault", "segmentation fault"),
        ("py-keep", "kept an array of the message past the call"),
        (
            "py-keep-buffer",
            "BufferError: a message's buffer was kept past its call",
        ),
        (
            "py-missing",
            "AttributeError: module 'bridge_fixtures' has no class 'NoSuchClass'",
        ),
    ] {
        let status = run(label)["status"].as_str().unwrap_or_default().to_owned();
        assert!(
            status.starts_with("failed") && status.contains(reason) && !status.contains('\n'),
            "{label}: expected one line naming {reason:?}, got {status:?}"
        );
    }
    // The exception's whole traceback is in the run's log, down to the line that raised it.
    let log = std::fs::read_to_string(out.join("s1/py-raise/worker.log")).expect("worker.log");
    assert!(
        log.contains("Traceback (most recent call last)")
            && log.contains("bridge_fixtures.py")
            && log.contains("in on_wheel_odometry")
            && log.contains("raise ValueError"),
        "{log}"
    );
    // The same midpoint dead reckoning in C and in Python: the same figures.
    let (c_rmse, py_rmse) = (
        run("c-odometry")["rmse"].as_f64().expect("C rmse"),
        run("py-odometry")["rmse"].as_f64().expect("Python rmse"),
    );
    assert!(c_rmse > 0.001, "a real error to compare: {c_rmse}");
    assert!(
        (c_rmse - py_rmse).abs() < 1e-9,
        "C {c_rmse} and Python {py_rmse} differ"
    );
    let dir = out.join("s1").join("py-odometry");
    let poses = std::fs::read_to_string(dir.join("estimate.tum"))
        .expect("estimate")
        .lines()
        .filter(|l| !l.starts_with('#'))
        .count();
    assert!(poses > 900, "{poses} poses over 20 s of 50 Hz odometry");
    // What Python saw of the rig and of the lidar sweeps (the event's detail): 200 sweeps
    // at 10 Hz of the VLP-16 with per-point time up to 0.1 s.
    let events = std::fs::read_to_string(dir.join("events.json")).expect("events");
    assert!(
        events.contains(&format!("python odometry: {poses} poses")),
        "{events}"
    );
    assert!(
        events.contains("rig imu,lidar,rgbd,scan2d,scan2d,wheel_odometry"),
        "{events}"
    );
    let sweeps = events
        .split("sweeps 200: ")
        .nth(1)
        .unwrap_or_else(|| panic!("200 sweeps: {events}"));
    let first: Vec<f64> = sweeps
        .split_whitespace()
        .next()
        .expect("a sweep")
        .trim_end_matches('"')
        .split(',')
        .map(|v| v.parse().expect("number"))
        .collect();
    assert!(first[0] > 5000.0, "points per sweep: {first:?}");
    assert!((2.0..=16.0).contains(&first[1]), "rings: {first:?}");
    assert!(
        (0.09..0.1).contains(&first[2]),
        "last point's time: {first:?}"
    );
    assert!(dir.join("map.ply").exists(), "the Python plugin's map");
    // The run's record says which sensors it asked for: those the class named.
    let run_toml = std::fs::read_to_string(dir.join("run.toml")).expect("run.toml");
    assert!(
        run_toml.contains("sensors = [\"wheel_odometry\", \"lidar\"]"),
        "{run_toml}"
    );

    // Listed by `vinebench plugins` like the others.
    let folder = plugin_lib("python_bridge");
    let listed = vinebench(&[
        "plugins",
        "--plugin-dir",
        folder.parent().expect("deps").to_str().expect("utf-8"),
    ]);
    assert!(
        text(&listed.stdout)
            .lines()
            .any(|l| l.starts_with("python-bridge")),
        "{}",
        text(&listed.stdout)
    );
}

/// The real KISS-ICP (its defaults and the vineyard configuration) and the real ORB-SLAM3
/// (paced to real time) through the bridge on 10 s of S1, beside our orbslam2 and lio-sam.
#[test]
fn the_real_kiss_icp_and_orbslam3_run_through_the_bridge() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let adapters = vec![workspace_root().join("plugins/python-bridge/adapters")];
    // ORB-SLAM3 reads its vocabulary as DBoW2 text: ours, exported as the README says.
    let vocabulary = tmp.path().join("orbslam3-vocabulary.txt");
    let ours = slam_common::place::vocabulary::Vocabulary::load(
        &workspace_root().join("plugins/orbslam2/vocabulary/vineyard-k10l6.dbow"),
    )
    .expect("our vocabulary");
    let mut file = std::fs::File::create(&vocabulary).expect("create");
    ours.write_dbow2_text(&mut file).expect("export");
    drop(file);
    let kiss = venv("kiss-icp-venv");
    let orb = venv("orbslam3-venv");
    let toml = [
        "scenarios = [\"s1\"]\nseed = 0\nmax_time_s = 10.0\njobs = 2\n".to_owned(),
        python_entry(
            "kiss-icp",
            &adapters,
            &kiss,
            "kiss_icp_adapter",
            "KissIcp",
            "",
        ),
        python_entry(
            "kiss-icp-vineyard",
            &adapters,
            &kiss,
            "kiss_icp_adapter",
            "KissIcp",
            "max_range = 30.0",
        ),
        python_entry(
            "orbslam3",
            &adapters,
            &orb,
            "orbslam3_adapter",
            "OrbSlam3",
            &format!("vocabulary = \"{}\"", vocabulary.display()),
        )
        .replace("[plugins.params]", "pace = \"realtime\"\n[plugins.params]"),
        format!(
            "[[plugins]]\npath = \"{}\"\nlabel = \"lio-sam\"\n",
            plugin_lib("lio_sam").display()
        ),
    ]
    .concat();
    let (o, out) = run_bench(tmp.path(), "peers", &toml);
    assert!(o.status.success(), "bench failed: {}", text(&o.stderr));
    let table = json(&out.join("table.json"));
    let run = |label: &str| table["s1"][label].clone();
    for label in ["kiss-icp", "kiss-icp-vineyard", "orbslam3", "lio-sam"] {
        assert_eq!(run(label)["status"], "ok", "{label}: {}", table["s1"]);
    }
    let rmse = |label: &str| run(label)["rmse"].as_f64().expect("rmse");
    // ORB-SLAM3 tracks this lane to centimetres, as our orbslam2 does.
    assert!(rmse("orbslam3") < 0.1, "orbslam3 {}", rmse("orbslam3"));
    // KISS-ICP gives a pose per sweep (100 in 10 s), at the sweep's last point.
    let sweeps = std::fs::read_to_string(out.join("s1/kiss-icp/estimate.tum"))
        .expect("estimate")
        .lines()
        .filter(|l| !l.starts_with('#'))
        .count();
    assert_eq!(sweeps, 100);
    // KISS-ICP (no IMU) slips along the identical rows here: the vineyard configuration
    // stayed within 1.7 m over 30 s of this lane when measured, its defaults within 3 m
    // (configs/peers.toml's whole routes: README). These bounds catch a run that lost the
    // route altogether (a wrong frame or time convention in the adapter), not a tuning.
    assert!(
        rmse("kiss-icp-vineyard") < 5.0,
        "{}",
        rmse("kiss-icp-vineyard")
    );
    assert!(rmse("kiss-icp") < 10.0, "{}", rmse("kiss-icp"));
    // Paced to simulated time: the ORB-SLAM3 run took at least the route's 10 s.
    let timing = json(&out.join("s1/orbslam3/timing.json"));
    let wall = timing["wall_s"].as_f64().unwrap_or_default();
    assert!(wall >= 10.0, "paced run's wall time {wall} s: {timing}");
}
