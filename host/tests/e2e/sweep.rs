//! End-to-end checks of `vinebench sweep`: real plugins from their `.so`, run by the real
//! binary on short routes. A sweep killed with SIGKILL mid-run and started again runs only
//! the missing runs and aggregates byte-identically to an uninterrupted one; on a Slurm
//! cluster (a local one in the test command) it aggregates as here.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::common::{deps_dir, json, text, vinebench};

const SWEEP: &str = r#"
scenarios = ["s1"]
seeds = [0, 1]
max_time_s = 5.0

[axes]
"vineyard.growth_stage" = [0, 4]

[[plugins]]
name = "wheel-odometry"
label = "odometry"

[[plugins]]
name = "lio-sam"
label = "lio-sam"
"#;

fn write(dir: &Path, name: &str, toml: &str) -> PathBuf {
    let file = dir.join(name);
    std::fs::write(&file, toml).expect("write sweep file");
    file
}

fn sweep(file: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "sweep",
        file.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ];
    args.extend_from_slice(extra);
    vinebench(&args)
}

fn filed_runs(out: &Path) -> Vec<PathBuf> {
    match std::fs::read_dir(out.join("runs")) {
        Ok(entries) => entries.map(|e| e.expect("entry").path()).collect(),
        Err(_) => Vec::new(),
    }
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The aggregate agrees with the filed runs' own metrics, row by row.
fn check_aggregate(out: &Path) {
    let agg = json(&out.join("sweep.json"));
    let rows = agg["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 4, "2 systems x 2 growth stages: {agg}");
    assert_eq!(
        agg["builds"].as_array().map(Vec::len),
        Some(1),
        "one vinebench build made every run: {}",
        agg["builds"]
    );
    let runs: Vec<(serde_json::Value, serde_json::Value)> = filed_runs(out)
        .iter()
        .map(|d| (json(&d.join("cell.json")), json(&d.join("metrics.json"))))
        .collect();
    assert_eq!(runs.len(), 8);
    for row in rows {
        let stage = row["axes"][0][1].as_str().expect("stage");
        let mine: Vec<f64> = runs
            .iter()
            .filter(|(c, _)| {
                c["label"] == row["system"] && c["point"][0][1].as_str() == Some(stage)
            })
            .map(|(_, m)| m["ape"]["rmse"].as_f64().expect("rmse"))
            .collect();
        assert_eq!(mine.len(), 2, "two seeds per cell: {row}");
        assert_eq!(row["n_ok"], 2);
        assert_eq!(row["n_missing"], 0);
        let mean = (mine[0] + mine[1]) / 2.0;
        let std = ((mine[0] - mean).powi(2) + (mine[1] - mean).powi(2)).sqrt();
        let ate = &row["ate_rmse_m"];
        assert!(
            (ate["mean"].as_f64().expect("mean") - mean).abs() < 1e-12,
            "{row}"
        );
        assert!(
            (ate["std"].as_f64().expect("std") - std).abs() < 1e-12,
            "{row}"
        );
        assert_eq!(ate["min"].as_f64(), Some(mine[0].min(mine[1])));
        assert!(mean > 0.0 && mean < 1.0, "a 5 s route: {row}");
    }
    // Different seeds give different noise, so the odometry's error differs between seeds.
    let odometry_std = rows
        .iter()
        .filter(|r| r["system"] == "odometry")
        .map(|r| r["ate_rmse_m"]["std"].as_f64().expect("std"))
        .fold(0.0, f64::max);
    assert!(odometry_std > 0.0, "seeds change the noise");
    for f in [
        "sweep.md",
        "sweep.csv",
        "speed.csv",
        "plots/s1-ate-vs-vineyard.growth_stage.svg",
        "plots/s1-ate-vs-vineyard.growth_stage.png",
    ] {
        assert!(out.join(f).is_file(), "{f} written");
    }
    // The page: every row's mean ATE as the aggregate has it, the plot inline; it renders
    // in a browser, and `vinebench report` rebuilds it byte for byte.
    let report = out.join("report.html");
    let page = std::fs::read_to_string(&report).expect("report.html");
    for row in rows {
        let ate = &row["ate_rmse_m"];
        let shown = format!(
            "{:.3} ± {:.3}",
            ate["mean"].as_f64().expect("mean"),
            ate["std"].as_f64().expect("std")
        );
        assert!(page.contains(&shown), "{shown} ({row}) not in the page");
    }
    assert!(page.contains("ATE RMSE against vineyard.growth_stage"));
    let o = vinebench(&["report", out.to_str().expect("utf-8")]);
    assert!(o.status.success(), "vinebench report: {}", text(&o.stderr));
    assert!(
        std::fs::read_to_string(&report).expect("report.html") == page,
        "vinebench report rebuilt a different sweep page"
    );
    if let Some(summary) = crate::report::browser_check(&report, &[]) {
        assert!(summary["svgs"].as_u64() >= Some(1), "{summary}");
    }
}

#[test]
fn a_killed_sweep_resumes_and_aggregates_like_an_uninterrupted_one() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let file = write(tmp.path(), "sweep.toml", SWEEP);

    // Uninterrupted.
    let whole = tmp.path().join("whole");
    let o = sweep(&file, &whole, &[]);
    assert!(o.status.success(), "sweep failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    assert!(stdout.contains("8 runs, 0 done, 8 to run"), "{stdout}");
    assert_eq!(
        stdout.matches("/8] s1 ").count(),
        8,
        "a line per run: {stdout}"
    );
    check_aggregate(&whole);

    // Killed with SIGKILL once two runs are filed, one run at a time.
    let cut = tmp.path().join("cut");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args([
            "sweep",
            file.to_str().expect("utf-8"),
            "--jobs",
            "1",
            "--out",
        ])
        .arg(&cut)
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("sweep starts");
    let started = Instant::now();
    while filed_runs(&cut).len() < 2 {
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "no run filed in 5 min"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    child.wait().expect("reaped");
    let filed = filed_runs(&cut).len();
    assert!(
        (2..8).contains(&filed),
        "killed mid-sweep: {filed} runs filed"
    );
    for run in filed_runs(&cut) {
        for f in ["cell.json", "metrics.json", "estimate.tum", "run.toml"] {
            assert!(run.join(f).is_file(), "{} is complete", run.display());
        }
    }
    // Started again: only the missing runs.
    let o = sweep(&file, &cut, &[]);
    assert!(
        o.status.success(),
        "resumed sweep failed: {}",
        text(&o.stderr)
    );
    let stdout = text(&o.stdout);
    let todo = 8 - filed;
    assert!(
        stdout.contains(&format!("8 runs, {filed} done, {todo} to run")),
        "{stdout}"
    );
    assert_eq!(
        stdout.matches(&format!("/{todo}] s1 ")).count(),
        todo,
        "only the missing runs ran: {stdout}"
    );
    assert_eq!(
        std::fs::read_dir(cut.join(".work")).expect(".work").count(),
        0,
        "the killed sweep's work folder is gone"
    );
    check_aggregate(&cut);
    for f in ["sweep.json", "sweep.csv"] {
        assert!(
            bytes(&whole.join(f)) == bytes(&cut.join(f)),
            "{f} differs between the uninterrupted and the resumed sweep"
        );
    }

    // A changed sweep file never mixes the old runs in: other keys, nothing done.
    let changed = write(
        tmp.path(),
        "changed.toml",
        &SWEEP.replace("max_time_s = 5.0", "max_time_s = 4.0"),
    );
    let o = sweep(&changed, &cut, &["--collect"]);
    assert!(o.status.success(), "collect failed: {}", text(&o.stderr));
    let agg = json(&cut.join("sweep.json"));
    for row in agg["rows"].as_array().expect("rows") {
        assert_eq!(row["n_ok"], 0, "{row}");
        assert_eq!(row["n_missing"], 2, "{row}");
    }
    assert!(text(&o.stdout).contains("8 runs are missing"));
}

#[test]
fn bad_sweep_inputs_are_one_line_naming_the_culprit() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let cases = [
        (
            SWEEP.replace("vineyard.growth_stage", "vineyard.growth_stag"),
            "growth_stag",
        ),
        (
            SWEEP.replace("[0, 4]", "[0, 9]"),
            "vineyard.growth_stage = 9",
        ),
        (SWEEP.replace("[0, 4]", "[]"), "non-empty"),
        (SWEEP.replace("[0, 4]", "[{ a = 1 }]"), "is a table"),
        (SWEEP.replace("seeds = [0, 1]", "seeds = [0, 0]"), "seeds"),
        (
            SWEEP.replace("seeds = [0, 1]", "seeds = [0, 1]\nseed = 3"),
            "seed and seeds",
        ),
    ];
    for (k, (toml, culprit)) in cases.iter().enumerate() {
        let file = write(tmp.path(), &format!("bad{k}.toml"), toml);
        let out = tmp.path().join(format!("out{k}"));
        let o = sweep(&file, &out, &[]);
        let err = text(&o.stderr);
        assert!(!o.status.success(), "case {k} accepted");
        assert!(
            err.contains(culprit) && err.contains(&format!("bad{k}.toml")),
            "case {k}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
        assert!(!out.exists(), "case {k} wrote {}", out.display());
    }
    // A bench refuses a sweep file, and a sweep refuses a folder that is not its own.
    let file = write(tmp.path(), "sweep.toml", SWEEP);
    let o = vinebench(&["bench", file.to_str().expect("utf-8")]);
    assert!(!o.status.success() && text(&o.stderr).contains("vinebench sweep"));
    let foreign = tmp.path().join("foreign");
    std::fs::create_dir_all(&foreign).expect("mkdir");
    std::fs::write(foreign.join("notes.txt"), "mine").expect("write");
    let o = sweep(&file, &foreign, &[]);
    assert!(!o.status.success() && text(&o.stderr).contains("not a vinebench sweep folder"));
}

/// A run whose recording could not be made is the host's failure, not the plugin's (here a
/// file-size limit kills `vinebench record`, as a full disk would): the sweep files no run,
/// says why, and started again with room it runs them.
#[test]
fn a_run_whose_recording_failed_is_not_filed_and_runs_on_resume() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let file = write(
        tmp.path(),
        "recorded.toml",
        "scenarios = [\"s1\"]\nseeds = [0]\nmax_time_s = 20.0\nrecord_once = true\n\
         [[plugins]]\nname = \"wheel-odometry\"\nlabel = \"odometry\"\n",
    );
    let out = tmp.path().join("out");
    // 20 s of IMU, odometry and ground truth is some 600 kB; the limit is 100 kB.
    let o = Command::new("sh")
        .args(["-c", "ulimit -f 100 && exec \"$0\" \"$@\""])
        .arg(env!("CARGO_BIN_EXE_vinebench"))
        .args(["sweep", file.to_str().expect("utf-8"), "--out"])
        .arg(&out)
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .output()
        .expect("vinebench runs");
    let err = text(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("could not record s1"), "{err}");
    assert!(filed_runs(&out).is_empty(), "{:?}", filed_runs(&out));
    let o = sweep(&file, &out, &[]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let runs = filed_runs(&out);
    assert_eq!(runs.len(), 1);
    assert_eq!(json(&runs[0].join("cell.json"))["status"], "ok");
}

/// Whether the test command has set up Slurm (`scripts/slurm-local.sh`): then a missing
/// Slurm is a failure, not a reason to skip.
fn slurm_required() -> bool {
    std::env::var_os("VINEBENCH_REQUIRE_SLURM").is_some_and(|v| v == "1")
}

#[test]
fn a_slurm_sweep_aggregates_like_a_local_one() {
    let has_sbatch = Command::new("sbatch")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_sbatch {
        assert!(
            !slurm_required(),
            "VINEBENCH_REQUIRE_SLURM=1 but sbatch does not run"
        );
        eprintln!("skipped: no Slurm here (scripts/test.sh starts a local one)");
        return;
    }
    let tmp = tempfile::tempdir().expect("tempdir");
    let toml = SWEEP.replace("[[plugins]]\nname = \"lio-sam\"\nlabel = \"lio-sam\"\n", "");
    let file = write(tmp.path(), "sweep.toml", &toml);
    let local = tmp.path().join("local");
    let o = sweep(&file, &local, &[]);
    assert!(
        o.status.success(),
        "local sweep failed: {}",
        text(&o.stderr)
    );
    let cluster = tmp.path().join("slurm");
    let o = sweep(&file, &cluster, &["--executor", "slurm", "--poll-s", "1"]);
    assert!(
        o.status.success(),
        "slurm sweep failed: {}\n{}",
        text(&o.stderr),
        text(&o.stdout)
    );
    assert!(text(&o.stdout).contains("submitted Slurm job array"));
    let logs: Vec<PathBuf> = std::fs::read_dir(cluster.join("slurm/0"))
        .expect("slurm/0")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.to_string_lossy().contains("task-"))
        .collect();
    assert_eq!(logs.len(), 4, "one log per array task: {logs:?}");
    for f in ["sweep.json", "sweep.csv"] {
        assert!(
            bytes(&local.join(f)) == bytes(&cluster.join(f)),
            "{f} differs between the local and the Slurm sweep"
        );
    }
    // Collected again later: the same aggregate.
    let before = bytes(&cluster.join("sweep.json"));
    let o = sweep(&file, &cluster, &["--collect"]);
    assert!(o.status.success(), "collect failed: {}", text(&o.stderr));
    assert!(before == bytes(&cluster.join("sweep.json")));
}
