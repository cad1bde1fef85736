//! What the end-to-end plugin tests share: running a plugin through the `vinebench` binary
//! and reading what it wrote. (Each test crate uses a part of it.)
#![allow(dead_code)]

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector2};

/// Where cargo put the test's libraries, the plugins' `.so` among them.
pub fn deps_dir() -> PathBuf {
    std::env::current_exe()
        .expect("test executable")
        .parent()
        .expect("deps directory")
        .to_owned()
}

pub fn json(path: &Path) -> serde_json::Value {
    let t = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Runs the `vinebench` binary with the test build's plugins on its search path.
pub fn vinebench<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(args)
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .output()
        .expect("vinebench runs")
}

/// [`vinebench`], panicking with its stderr, naming `what`, if it fails.
pub fn vinebench_ok(args: &[OsString], what: &str) -> std::process::Output {
    let o = vinebench(args);
    assert!(o.status.success(), "{what} failed: {}", text(&o.stderr));
    o
}

/// Bytes of an output stream as text.
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs `plugin` through the host on a scenario with `params` as its configuration;
/// returns its results folder.
pub fn run(dir: &Path, scenario: &str, plugin: &str, label: &str, params: &str) -> PathBuf {
    run_with(dir, scenario, plugin, label, params, &[])
}

/// [`run`] with extra arguments for `vinebench run` (e.g. `--max-time 80`).
pub fn run_with(
    dir: &Path,
    scenario: &str,
    plugin: &str,
    label: &str,
    params: &str,
    extra: &[&str],
) -> PathBuf {
    let config = dir.join(format!("{label}.toml"));
    std::fs::write(&config, params).expect("write plugin config");
    let out = dir.join(label);
    let mut args: Vec<OsString> = [
        "run",
        "--scenario",
        scenario,
        "--plugin",
        plugin,
        "--plugin-config",
    ]
    .map(OsString::from)
    .to_vec();
    args.extend([config.into(), "--out".into(), out.clone().into()]);
    args.extend(extra.iter().map(OsString::from));
    vinebench_ok(&args, &format!("run {label}"));
    out.join(scenario).join(plugin)
}

/// Runs `plugin` on `scenario` once per `(label, params)` as one bench of that many jobs, so
/// that the runs are fed by one simulation (one camera rendering for all of them) instead of
/// one each; returns their folders in order. The data are the same either way
/// (`bench.rs`: `a_shared_simulation_gives_every_run_its_own_data`).
pub fn run_together(
    dir: &Path,
    scenario: &str,
    plugin: &str,
    (runs, world): (&[(&str, &str)], Option<&Path>),
    extra: &[&str],
) -> Vec<PathBuf> {
    let mut bench = toml::Table::new();
    if let Some(world) = world {
        let world = world.to_str().expect("utf-8 path");
        bench.insert("world".into(), world.into());
    }
    bench.insert(
        "scenarios".into(),
        toml::Value::Array(vec![scenario.into()]),
    );
    bench.insert("jobs".into(), (runs.len() as i64).into());
    let entries = runs
        .iter()
        .map(|(label, params)| {
            let params: toml::Table = params
                .parse()
                .unwrap_or_else(|e| panic!("params of {label}: {e}"));
            let mut entry = toml::Table::new();
            entry.insert("name".into(), plugin.into());
            entry.insert("label".into(), (*label).into());
            entry.insert("params".into(), toml::Value::Table(params));
            toml::Value::Table(entry)
        })
        .collect();
    bench.insert("plugins".into(), toml::Value::Array(entries));
    let file = dir.join(format!("{plugin}-together.toml"));
    std::fs::write(&file, toml::to_string(&bench).expect("toml")).expect("write bench file");
    let out = dir.join(format!("{plugin}-together"));
    let mut args: Vec<OsString> = vec![
        "bench".into(),
        file.into(),
        "--out".into(),
        out.clone().into(),
    ];
    args.extend(extra.iter().map(OsString::from));
    vinebench_ok(&args, &format!("bench of {plugin}"));
    runs.iter()
        .map(|(label, _)| {
            let folder = out.join(scenario).join(label);
            let timing = json(&folder.join("timing.json"));
            assert_eq!(
                timing["source"], "shared simulation",
                "{label} was fed by the shared simulation"
            );
            folder
        })
        .collect()
}

/// ATE of a TUM trajectory against ground truth (SE(3) alignment), from `vinebench eval`.
pub fn ate(folder: &Path, file: &str) -> f64 {
    let o = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(["eval", "--align", "se3", "--json"])
        .arg(folder.join("groundtruth.tum"))
        .arg(folder.join(file))
        .output()
        .expect("vinebench eval runs");
    assert!(
        o.status.success(),
        "eval failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("json")["rmse"]
        .as_f64()
        .expect("rmse")
}

/// A loop-closure event as the host wrote it to events.json.
#[derive(Debug, Clone)]
pub struct LoopEvent {
    pub detail: String,
    /// The two base-pose stamps the loop joins, `[current, matched]`, if the plugin gave them.
    pub stamps_ns: Option<[i64; 2]>,
    /// The host's judgement against ground truth (accepted loops with stamps only).
    pub true_loop: Option<bool>,
    /// The error of the loop's measured relative pose against ground truth, m, when the
    /// plugin sent one.
    pub relative_error_m: Option<f64>,
}

/// A run's loop-closure events of one kind (`loop_closure_accepted`, …), in order.
pub fn loop_events(folder: &Path, kind: &str) -> Vec<LoopEvent> {
    json(&folder.join("events.json"))
        .as_array()
        .expect("events are a list")
        .iter()
        .filter(|e| e["kind"] == kind)
        .map(|e| LoopEvent {
            detail: e["detail"].as_str().expect("detail").to_owned(),
            stamps_ns: e["loop_stamps_ns"]
                .as_array()
                .map(|s| [0, 1].map(|i| s[i].as_i64().expect("loop stamps are integers"))),
            true_loop: e["true_loop"].as_bool(),
            relative_error_m: e["relative_error_m"].as_f64(),
        })
        .collect()
}

/// The ground-truth positions (x, y) of the two base poses a loop event joins, read from
/// the run's groundtruth.tum (the first pose at or after each stamp).
pub fn event_positions(folder: &Path, event: &LoopEvent) -> Option<(Vector2<f64>, Vector2<f64>)> {
    let [a, b] = event.stamps_ns?.map(|ns| ns as f64 * 1e-9);
    let text = std::fs::read_to_string(folder.join("groundtruth.tum")).expect("groundtruth.tum");
    let poses: Vec<[f64; 3]> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse().expect("number"))
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    let at = |t: f64| {
        let k = poses.partition_point(|p| p[0] < t).min(poses.len() - 1);
        Vector2::new(poses[k][1], poses[k][2])
    };
    Some((at(a), at(b)))
}

/// A TUM trajectory: seconds and `map_from_base`.
pub fn read_tum(path: &Path) -> Vec<(f64, Isometry3<f64>)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|x| x.parse().expect("number"))
                .collect();
            let pose = Isometry3::from_parts(
                Translation3::new(v[1], v[2], v[3]),
                UnitQuaternion::from_quaternion(Quaternion::new(v[7], v[4], v[5], v[6])),
            );
            (v[0], pose)
        })
        .collect()
}

/// The ground truth at `t`, interpolated (100 Hz poses; frames fall between them).
pub fn at(gt: &[(f64, Isometry3<f64>)], t: f64) -> Isometry3<f64> {
    let k = gt.partition_point(|p| p.0 < t).clamp(1, gt.len() - 1);
    let ((t0, a), (t1, b)) = (gt[k - 1], gt[k]);
    let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let translation = a.translation.vector.lerp(&b.translation.vector, s);
    Isometry3::from_parts(
        Translation3::from(translation),
        a.rotation.slerp(&b.rotation, s),
    )
}

/// Relative pose errors of the online estimate over `dt` seconds: translation (m) and
/// rotation (deg) of every pair of tracked frames `dt` apart.
pub fn relative_errors(folder: &Path, dt: f64) -> Vec<(f64, f64)> {
    let gt = read_tum(&folder.join("groundtruth.tum"));
    let est = read_tum(&folder.join("online.tum"));
    let mut out = Vec::new();
    for (i, &(t, a)) in est.iter().enumerate() {
        let Some(&(u, b)) = est[i..].iter().find(|(u, _)| *u >= t + dt - 1e-3) else {
            break;
        };
        if (u - t - dt).abs() > 0.02 {
            continue;
        }
        let truth = at(&gt, t).inverse() * at(&gt, u);
        let error = truth.inverse() * (a.inverse() * b);
        out.push((
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        ));
    }
    out
}

/// Runs `tests/mcap/<script>` (an independent check with Foxglove's MCAP reader and ROS 2
/// decoder) on `args` with the `python3` first on PATH; returns the JSON it prints. Fails,
/// saying how to get the decoder, if the script fails or cannot run.
pub fn mcap_check<S: AsRef<std::ffi::OsStr>>(script: &str, args: &[S]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/mcap")
        .join(script);
    let out = Command::new("python3")
        .arg(&script)
        .args(args)
        .output()
        .expect("python3 on PATH (source scripts/setup.sh)");
    assert!(
        out.status.success(),
        "{} failed (are tests/mcap/requirements.txt installed? `source scripts/setup.sh` \
         puts them first on PATH): {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{} prints JSON: {e}", script.display()))
}

pub fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}
