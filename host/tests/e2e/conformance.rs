//! The plugin contract end to end: `vinebench check-plugin` on one fixture per door (Rust,
//! C, Python) passing the same list, and on the fault plugin failing with the reason; the C
//! table's revisions; and the CLI a lab scripts (exit codes, a closed pipe, Ctrl-C and
//! resuming, exact plugin names, broken libraries listed).

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::bench::{plugin_lib, workspace_root};
use crate::common::{deps_dir, json, text, vinebench};

/// `check-plugin` with a short route; (exit code, stdout, stderr).
fn check(target: &str, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec![
        "check-plugin",
        target,
        "--route-s",
        "3",
        "--timeout-s",
        "60",
    ];
    args.extend_from_slice(extra);
    let o = vinebench(&args);
    (o.status.code(), text(&o.stdout), text(&o.stderr))
}

/// The lines of a check-plugin listing: (PASS or FAIL, check, summary).
fn verdicts(stdout: &str) -> Vec<(String, String, String)> {
    stdout
        .lines()
        .filter_map(|l| {
            let l = l.trim_start();
            let (verdict, rest) = l.split_once("  ")?;
            if verdict != "PASS" && verdict != "FAIL" {
                return None;
            }
            let rest = rest.trim_start();
            let (name, summary) = rest.split_once(' ')?;
            Some((
                verdict.to_owned(),
                name.to_owned(),
                summary.trim().to_owned(),
            ))
        })
        .collect()
}

const CHECKS: [&str; 9] = [
    "load",
    "create",
    "route",
    "finish-without-data",
    "empty-input",
    "nan-input",
    "unrequested-sensor",
    "out-of-order",
    "localize",
];

/// Every check listed, passed, in order.
fn assert_all_pass(what: &str, code: Option<i32>, stdout: &str, stderr: &str) {
    let v = verdicts(stdout);
    let names: Vec<&str> = v.iter().map(|(_, n, _)| n.as_str()).collect();
    assert_eq!(names, CHECKS, "{what}: the checks listed\n{stdout}");
    for (verdict, name, summary) in &v {
        assert_eq!(
            verdict, "PASS",
            "{what}: {name}: {summary}\n{stdout}{stderr}"
        );
    }
    assert_eq!(code, Some(0), "{what}: exit code\n{stdout}{stderr}");
    assert!(stdout.contains("9 of 9 checks passed"), "{what}: {stdout}");
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// One fixture per door passes the same list: the Rust baseline, the C plugin asking for
/// every sensor (it checks each message's fields against each other and the typed rig, so a
/// layout mismatch fails its route), and the Python fixture asking for every sensor (the
/// same checks from numpy, and a grid and a loop's relative pose back through `finish`).
#[test]
fn one_fixture_per_door_passes_the_same_conformance_list() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (code, out, err) = check(plugin_lib("wheel_odometry").to_str().expect("utf-8"), &[]);
    assert_all_pass("rust", code, &out, &err);
    assert!(out.contains("through the rust door"), "{out}");

    let c = PathBuf::from(env!("VINEBENCH_C_ODOMETRY"));
    let params = write(tmp.path(), "c.toml", "sensors = \"all\"\n");
    let (code, out, err) = check(
        c.to_str().expect("utf-8"),
        &["--params", params.to_str().expect("utf-8")],
    );
    assert_all_pass("c", code, &out, &err);
    assert!(out.contains("through the c door"), "{out}");
    // Its finish's loop brought its matched keypoints through the TOML of `events_toml`.
    assert!(out.contains("2 events (1 with matched keypoints)"), "{out}");
    // requirements_for (revision 2) asked for every sensor, so the route fed them all.
    assert!(
        out.contains("[wheel_odometry, imu, lidar, scan2d, rgbd]"),
        "{out}"
    );
    // Revision 4: it saved its map, started from it, and said "searching" for its first 10
    // poses (VB_POSE_SEARCHING) and "localised" after.
    let localize = verdicts(&out)
        .into_iter()
        .find(|(_, n, _)| n == "localize")
        .expect("localize");
    assert!(
        localize
            .2
            .starts_with("started from its map (odometry-end version 1, 24 bytes)")
            && localize.2.contains(" localised, 10 searching)"),
        "{localize:?}"
    );

    let venv = workspace_root().join("target/python-bridge-venv");
    let bench = format!(
        "[[plugins]]\npath = \"{}\"\nlabel = \"py-conformance\"\n[plugins.params]\nmodule = \"bridge_fixtures\"\nclass = \"Conformance\"\npath = [\"{}\", \"{}\"]\nvenv = \"{}\"\n",
        plugin_lib("python_bridge").display(),
        workspace_root().join("tests/python-plugin").display(),
        workspace_root()
            .join("plugins/python-bridge/python")
            .display(),
        venv.display()
    );
    let file = write(tmp.path(), "py.toml", &bench);
    let (code, out, err) = check(file.to_str().expect("utf-8"), &[]);
    assert_all_pass("python", code, &out, &err);
    assert!(out.contains("py-conformance"), "{out}");
    // The route's finish brought the Python grid and the loop with its relative pose and
    // its matched keypoints.
    let route = verdicts(&out)
        .into_iter()
        .find(|(_, n, _)| n == "route")
        .expect("route");
    assert!(
        route.2.contains("1 events (1 with matched keypoints)"),
        "{}",
        route.2
    );
}

/// The fault plugin fails the checks its faults break, naming why: a NaN pose on the route,
/// a segfault as a crash at the input that caused it, a hang as a hang; the exit code is 3.
#[test]
fn a_faulty_plugin_fails_with_the_reason() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let lib = plugin_lib("fault_plugin");
    let lib = lib.to_str().expect("utf-8");
    for (fault, check_name, reason) in [
        ("nan", "route", "non-finite pose"),
        ("segfault", "route", "crashed: segmentation fault"),
        ("hang", "route", "hung: no answer within 5 s"),
    ] {
        let params = write(
            tmp.path(),
            &format!("{fault}.toml"),
            &format!("fault = \"{fault}\"\nafter = 10\n"),
        );
        let o = vinebench(&[
            "check-plugin",
            lib,
            "--params",
            params.to_str().expect("utf-8"),
            "--route-s",
            "3",
            "--timeout-s",
            "5",
        ]);
        let out = text(&o.stdout);
        assert_eq!(
            o.status.code(),
            Some(3),
            "{fault}: {out}{}",
            text(&o.stderr)
        );
        let v = verdicts(&out);
        let failed = v
            .iter()
            .find(|(_, n, _)| n == check_name)
            .unwrap_or_else(|| panic!("{fault}: no {check_name} line\n{out}"));
        assert_eq!(failed.0, "FAIL", "{fault}: {out}");
        assert!(failed.2.contains(reason), "{fault}: {}", failed.2);
        // The checks before it passed: the faults strike after 10 messages.
        assert!(
            v.iter()
                .any(|(verdict, n, _)| verdict == "PASS" && n == "create")
        );
    }
}

/// A table of revision 1's size is read without its revision-2 fields, though the library
/// sets them: its `requirements_for` is not asked (the static requirements stand) and it is
/// created through `create`, not `create_with`.
#[test]
fn a_revision_1_c_table_loads_without_its_later_fields() {
    let sensors = |lib: &str| {
        let o = vinebench(&["worker", "--sensors", lib, "--params", "sensors = \"all\""]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        text(&o.stdout).trim().to_owned()
    };
    assert_eq!(
        sensors(env!("VINEBENCH_C_ODOMETRY")),
        "wheel_odometry,imu,lidar,scan2d,rgbd"
    );
    assert_eq!(
        sensors(env!("VINEBENCH_C_ODOMETRY_REVISION_1")),
        "wheel_odometry"
    );
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("rev1");
    let o = vinebench(&[
        "run",
        "--scenario",
        "s1",
        "--plugin",
        env!("VINEBENCH_C_ODOMETRY_REVISION_1"),
        "--max-time",
        "5",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let m = json(&out.join("s1/c-odometry/metrics.json"));
    assert!(m["ape"]["rmse"].as_f64().expect("rmse") < 0.5, "{m}");
}

/// Exit codes: a failed run is 3 (`bench` and `run`), 0 with `--allow-failures`; a bad
/// plugin name is 1 with a "did you mean"; `lio_sam` is refused for `lio-sam`.
#[test]
fn exit_codes_say_what_happened_and_names_match_exactly() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let fault = plugin_lib("fault_plugin");
    let bench = format!(
        "scenarios = [\"s1\"]\nmax_time_s = 5.0\n[[plugins]]\npath = \"{}\"\nlabel = \"ok\"\n[[plugins]]\npath = \"{}\"\nlabel = \"broken\"\n[plugins.params]\nfault = \"panic\"\nafter = 5\n",
        plugin_lib("wheel_odometry").display(),
        fault.display()
    );
    let file = write(tmp.path(), "exit.toml", &bench);
    let out = tmp.path().join("exit");
    let args = |extra: &[&str]| {
        let mut a = vec![
            "bench".to_owned(),
            file.display().to_string(),
            "--out".into(),
            out.display().to_string(),
        ];
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    let o = vinebench(&args(&[]));
    assert_eq!(o.status.code(), Some(3), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("1 of 2 runs failed"),
        "{}",
        text(&o.stderr)
    );
    assert!(out.join("table.md").is_file(), "the results are written");
    let o = vinebench(&args(&["--allow-failures"]));
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));

    let o = vinebench(&[
        "run",
        "--scenario",
        "s0",
        "--plugin",
        "lio_sam",
        "--max-time",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("did you mean 'lio-sam'?"),
        "{}",
        text(&o.stderr)
    );
    let o = vinebench(&[
        "run",
        "--scenario",
        "s0",
        "--plugin",
        "rtabmapp",
        "--max-time",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        text(&o.stderr).contains("did you mean 'rtabmap'?"),
        "{}",
        text(&o.stderr)
    );
}

/// `vinebench bench … | head -1`: the output closes after one line, and the bench still
/// finishes and writes its results; nothing panics.
#[test]
fn a_closed_output_loses_nothing() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let bench = format!(
        "scenarios = [\"s1\", \"s2\"]\nmax_time_s = 5.0\n[[plugins]]\npath = \"{}\"\nlabel = \"odom\"\n",
        plugin_lib("wheel_odometry").display()
    );
    let file = write(tmp.path(), "pipe.toml", &bench);
    let out = tmp.path().join("pipe");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args(["bench", file.to_str().expect("utf-8"), "--out"])
        .arg(&out)
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starts");
    // Read one line, then close the pipe, as `head -1` does.
    let mut stdout = child.stdout.take().expect("piped");
    let mut first = [0u8; 1];
    stdout.read_exact(&mut first).expect("one byte");
    drop(stdout);
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .expect("piped")
        .read_to_string(&mut stderr)
        .expect("stderr");
    let status = child.wait().expect("ends");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(status.success(), "{status}: {stderr}");
    let table = json(&out.join("table.json"));
    assert_eq!(table["s2"]["odom"]["status"], "ok", "{table}");
}

/// The processes whose parent is `pid` (from /proc: procps is not on every machine).
fn children_of(pid: u32) -> Vec<u32> {
    let mut children = Vec::new();
    for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        // `pid (comm) state ppid ...`; comm may hold spaces and parentheses.
        let Some((_, rest)) = stat.rsplit_once(") ") else {
            continue;
        };
        let parent = rest.split_whitespace().nth(1).and_then(|p| p.parse().ok());
        if parent == Some(pid)
            && let Ok(child) = entry.file_name().to_string_lossy().parse()
        {
            children.push(child);
        }
    }
    children
}

/// Ctrl-C during a bench: the run that finished is kept in the partial folder, the hung one
/// is stopped and not filed (its worker stopped by SIGTERM a moment before), the exit code is 130 and the message says where; no results
/// folder appears. The same command then resumes: the finished run is not run again (its
/// files are the very bytes it left), the other one runs.
#[test]
fn ctrl_c_keeps_what_finished_and_the_same_command_resumes() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let fault = plugin_lib("fault_plugin");
    // The slow plugin hangs for at most its timeout: 8 s, enough to interrupt it.
    let bench = format!(
        "scenarios = [\"s1\"]\nmax_time_s = 5.0\nshare_simulation = false\njobs = 2\ntimeout_s = 8.0\n[[plugins]]\npath = \"{}\"\nlabel = \"odom\"\n[[plugins]]\npath = \"{}\"\nlabel = \"slow\"\n[plugins.params]\nfault = \"hang\"\nafter = 5\n",
        plugin_lib("wheel_odometry").display(),
        fault.display()
    );
    let file = tmp.path().join("resume.toml");
    std::fs::write(&file, &bench).expect("write");
    let out = tmp.path().join("resume");
    let partial = tmp.path().join(".resume.partial");
    let spawn = || {
        Command::new(env!("CARGO_BIN_EXE_vinebench"))
            .args(["bench", file.to_str().expect("utf-8"), "--out"])
            .arg(&out)
            .arg("--allow-failures")
            .env("VINEBENCH_PLUGIN_PATH", deps_dir())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starts")
    };
    let mut child = spawn();
    let status_file = partial.join("s1/odom/status.txt");
    let started = Instant::now();
    while !status_file.is_file() {
        assert!(started.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(50));
    }
    // The hung worker is stopped first (as `pkill vinebench` stops every process, workers
    // included, a moment apart), then the bench: the worker's death by SIGTERM is the
    // user's stop, not the plugin's failure, and is not filed either.
    let workers = children_of(child.id());
    assert_eq!(workers.len(), 1, "one running worker: {workers:?}");
    for (signal, pid) in [("-TERM", workers[0]), ("-INT", child.id())] {
        let pid = pid.to_string();
        let signalled = Command::new("kill")
            .args([signal, &pid])
            .status()
            .expect("kill runs");
        assert!(signalled.success());
        // Long enough for the supervisor to see its worker dead before its own stop,
        // well within the grace it gives a worker stopped by a signal.
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .expect("piped")
        .read_to_string(&mut stderr)
        .expect("stderr");
    let status = child.wait().expect("ends");
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("1 of 2 runs finished and are kept in"),
        "{stderr}"
    );
    assert!(!out.exists(), "no results folder yet");
    assert!(
        !partial.join("s1/slow/status.txt").exists(),
        "the interrupted run is not filed"
    );
    let before = std::fs::read(partial.join("s1/odom/estimate.tum")).expect("kept");
    let mtime = std::fs::metadata(partial.join("s1/odom/estimate.tum"))
        .and_then(|m| m.modified())
        .expect("mtime");

    let o = spawn().wait_with_output().expect("ends");
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        stdout.contains("resuming") && stdout.contains("1 of 2 runs already finished"),
        "{stdout}"
    );
    // Only the other run ran: one progress line, for it.
    assert!(stdout.contains("[1/1] s1/slow"), "{stdout}");
    let after = out.join("s1/odom/estimate.tum");
    assert_eq!(std::fs::read(&after).expect("estimate"), before);
    assert_eq!(
        std::fs::metadata(&after)
            .and_then(|m| m.modified())
            .expect("mtime"),
        mtime,
        "the finished run was not run again"
    );
}

/// `vinebench plugins` lists a library that exports the C symbol but cannot be used (here
/// one claiming another ABI version) with the reason, not silently.
#[test]
fn broken_libraries_are_listed_with_their_reason() {
    let v99 = Path::new(env!("VINEBENCH_C_ODOMETRY_V99"));
    let o = vinebench(&[
        "plugins",
        "--plugin-dir",
        v99.parent().expect("folder").to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.starts_with("(broken)"))
        .unwrap_or_else(|| panic!("no broken line:\n{out}"));
    assert!(line.contains("C ABI version 99"), "{line}");
    assert!(
        out.lines()
            .any(|l| l.starts_with("wheel-odometry\t") && l.contains("\tRust\t")),
        "{out}"
    );
}

/// In a shared simulation, a run that ends well is reported as it ends, while a hung
/// groupmate is still running: the line does not wait for the other's timeout.
#[test]
fn a_finished_run_is_reported_while_its_groupmate_hangs() {
    use std::io::BufRead as _;
    let tmp = tempfile::tempdir().expect("tempdir");
    let bench = format!(
        "scenarios = [\"s1\"]\nmax_time_s = 5.0\njobs = 2\ntimeout_s = 30.0\n[[plugins]]\npath = \"{}\"\nlabel = \"odom\"\n[[plugins]]\npath = \"{}\"\nlabel = \"slow\"\n[plugins.params]\nfault = \"hang\"\nafter = 5\n",
        plugin_lib("wheel_odometry").display(),
        plugin_lib("fault_plugin").display()
    );
    let file = write(tmp.path(), "group.toml", &bench);
    let mut child = Command::new(env!("CARGO_BIN_EXE_vinebench"))
        .args([
            "bench",
            file.to_str().expect("utf-8"),
            "--allow-failures",
            "--out",
        ])
        .arg(tmp.path().join("group"))
        .env("VINEBENCH_PLUGIN_PATH", deps_dir())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("starts");
    let mut lines = std::io::BufReader::new(child.stdout.take().expect("piped")).lines();
    let first = lines.next().expect("a line").expect("text");
    assert!(first.starts_with("[1/2] s1/odom: ok"), "{first}");
    assert!(
        child.try_wait().expect("status").is_none(),
        "the hung run is still going when the good one is reported"
    );
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    assert!(child.wait().expect("ends").success());
    assert!(
        rest.iter()
            .any(|l| l.starts_with("[2/2] s1/slow: failed: timed out")),
        "{rest:?}"
    );
}

/// Bounded subscriber queues (`queue_size`): a system slower than its topic (the fault
/// plugin taking 30 ms over each 50 Hz wheel odometry message), paced, with a queue of one
/// misses messages, each one either delivered or listed in `dropped.csv`; a free run given
/// that file drops exactly those and gives the same trajectory, byte for byte. A queue on a
/// free run, or of size 0, is one line naming it.
#[test]
fn a_bounded_queue_drops_what_a_slow_system_misses_and_its_drops_replay() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let lib = plugin_lib("fault_plugin");
    let lib = lib.to_str().expect("utf-8");
    let slow = write(tmp.path(), "slow.toml", "work_ms = 30\n");
    let fast = write(tmp.path(), "fast.toml", "");
    let run = |label: &str, params: &Path, extra: &[&str]| {
        let out = tmp.path().join(label);
        let mut args = vec![
            "run",
            "--scenario",
            "s0",
            "--max-time",
            "3",
            "--plugin",
            lib,
            "--label",
            label,
            "--plugin-config",
            params.to_str().expect("utf-8"),
            "--out",
            out.to_str().expect("utf-8"),
        ];
        args.extend_from_slice(extra);
        let o = vinebench(&args);
        (o, out.join("s0").join(label))
    };
    let lines = |p: &Path| {
        std::fs::read_to_string(p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .count()
    };
    let (o, all) = run("all", &fast, &[]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let total = lines(&all.join("estimate.tum"));
    assert!(!all.join("dropped.csv").exists(), "no queue, no drops file");

    let (o, queued) = run(
        "queued",
        &slow,
        &["--pace", "realtime", "--queue-size", "1"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let delivered = lines(&queued.join("estimate.tum"));
    let dropped = lines(&queued.join("dropped.csv")) - 1;
    let timing = json(&queued.join("timing.json"));
    assert_eq!(
        timing["dropped"]["odom"].as_u64(),
        Some(dropped as u64),
        "{timing}"
    );
    // Each call takes at least 30 ms: over the 3 s the stream lasts at most 3 / 0.03 + 1
    // calls start, and when it ends at most the one message its queue holds is left.
    assert!(
        delivered <= 3000 / 30 + 2,
        "{delivered} of {total} delivered"
    );
    assert!(dropped > 0, "{dropped} of {total} dropped");
    assert_eq!(
        delivered + dropped,
        total,
        "every message delivered or dropped"
    );

    let drops = queued.join("dropped.csv");
    let (o, replayed) = run(
        "replayed",
        &fast,
        &["--drops", drops.to_str().expect("utf-8")],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    for f in ["estimate.tum", "dropped.csv"] {
        assert_eq!(
            std::fs::read(replayed.join(f)).expect("replayed file"),
            std::fs::read(queued.join(f)).expect("queued file"),
            "{f}: the same drops give the same run"
        );
    }

    for (extra, culprit) in [
        (&["--queue-size", "1"][..], "realtime"),
        (
            &["--pace", "realtime", "--queue-size", "0"][..],
            "at least 1",
        ),
    ] {
        let (o, _) = run("bad", &fast, extra);
        let err = text(&o.stderr);
        assert!(
            !o.status.success() && err.contains(culprit),
            "{extra:?}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    }
}
