//! Wrong joins judged from the final map, whatever the system reports: a Python-door
//! fixture (`bridge_fixtures.Merger`, wheel odometry underneath) that lays lane 4 of S3
//! onto lane 2 (6 m apart in our world) in its final trajectory only, reporting either one
//! accepted loop without stamps or nothing, and the same fixture on S1 reporting a
//! stampless loop on its true return pass.

use serde_json::Value;

use super::bench::run_bench;
use super::python::{fixture_paths, python_entry, venv};
use crate::common::{json, text, vinebench};

/// Runs `bridge_fixtures.Merger` on `scenario` cut at `max_time_s`, one run per (label,
/// params); returns each run's folder.
fn merger_runs(
    dir: &std::path::Path,
    scenario: &str,
    max_time_s: f64,
    runs: &[(&str, &str)],
) -> Vec<std::path::PathBuf> {
    merger_runs_in(dir, scenario, max_time_s, runs, None)
}

/// [`merger_runs`] in `world` (a world file's text), if given.
fn merger_runs_in(
    dir: &std::path::Path,
    scenario: &str,
    max_time_s: f64,
    runs: &[(&str, &str)],
    world: Option<&str>,
) -> Vec<std::path::PathBuf> {
    let venv = venv("python-bridge-venv");
    let paths = fixture_paths();
    let mut toml =
        format!("scenarios = [\"{scenario}\"]\nseed = 0\nmax_time_s = {max_time_s:?}\njobs = 2\n");
    if let Some(text) = world {
        let file = dir.join("world.toml");
        std::fs::write(&file, text).expect("world file");
        toml += &format!("world = \"{}\"\n", file.display());
    }
    for (label, params) in runs {
        toml += &python_entry(label, &paths, &venv, "bridge_fixtures", "Merger", params);
    }
    let (o, out) = run_bench(dir, scenario, &toml);
    assert!(o.status.success(), "bench failed: {}", text(&o.stderr));
    runs.iter()
        .map(|(label, _)| {
            let folder = out.join(scenario).join(label);
            let status = std::fs::read_to_string(folder.join("status.txt")).unwrap_or_default();
            assert_eq!(status.trim(), "ok", "{label}: {status}");
            folder
        })
        .collect()
}

fn accepted_loops(folder: &std::path::Path) -> Vec<Value> {
    json(&folder.join("events.json"))
        .as_array()
        .expect("events.json is a list")
        .iter()
        .filter(|e| e["kind"] == "loop_closure_accepted")
        .cloned()
        .collect()
}

/// From 115 s (x = 1.5 m along lane 4, y = 13.5 m) to the cut at 140 s, the fixture moves its
/// final poses 5.8 m towards lane 2 (y = 7.5 m), which it drove from 0 to 47 s: the final
/// map keeps two stretches 6 m apart in truth within 0.2 m (plus the odometry's drift).
const SHIFT: &str = "shift_from_s = 115.0\nshift_xy = [0.0, -5.8]\n";

#[test]
fn a_merge_reported_without_stamps_is_false_and_an_unreported_one_is_silent() {
    let dir = tempfile::tempdir().expect("tempdir");
    let folders = merger_runs(
        dir.path(),
        "s3",
        140.0,
        &[
            ("merge-stampless", &format!("{SHIFT}event_s = 138.0\n")),
            ("merge-silent", SHIFT),
        ],
    );
    let (stampless, silent) = (&folders[0], &folders[1]);

    // The stampless merge: one accepted loop, false by the final map, its wrong join named;
    // the online error beside it hardly moved (the online poses were never shifted), so
    // the online judge alone would have called it true.
    let metrics = json(&stampless.join("metrics.json"));
    assert_eq!(metrics["loops"]["accepted"], 1, "{metrics}");
    assert_eq!(metrics["loops"]["accepted_false"], 1, "{metrics}");
    assert_eq!(metrics["joins"]["wrong_joins"], 1, "{metrics}");
    assert_eq!(metrics["joins"]["silent"], 0, "{metrics}");
    let event = &accepted_loops(stampless)[0];
    assert_eq!(event["true_loop"], false, "{event}");
    assert_eq!(event["judged_by"], "final_map", "{event}");
    assert_eq!(event["wrong_join"], 0, "{event}");
    let (before, after) = (
        event["error_before_m"]
            .as_f64()
            .expect("online error before"),
        event["error_after_m"].as_f64().expect("online error after"),
    );
    assert!((after - before).abs() < 0.5, "online {before} -> {after}");
    let joins = json(&stampless.join("joins.json"));
    let join = &joins["wrong_joins"][0];
    let (estimate_m, truth_m) = (
        join["estimate_distance_m"]
            .as_f64()
            .expect("estimate distance"),
        join["truth_distance_m"].as_f64().expect("truth distance"),
    );
    assert!(
        estimate_m < 1.0 && (5.5..6.5).contains(&truth_m),
        "joined {estimate_m} m in the estimate, {truth_m} m in truth: {join}"
    );
    let later = join["later_s"][0].as_f64().expect("later stretch");
    let earlier = join["earlier_s"][1].as_f64().expect("earlier stretch");
    assert!(later >= 114.0 && earlier <= 48.0, "{join}");
    // The table's rows carry it.
    let table = std::fs::read_to_string(stampless.join("../../table.md")).expect("table.md");
    assert!(table.contains("| wrong joins "), "{table}");

    // The same join reported by nothing: no loop, one silent wrong join.
    let metrics = json(&silent.join("metrics.json"));
    assert_eq!(metrics["loops"]["accepted"], 0, "{metrics}");
    assert_eq!(metrics["joins"]["wrong_joins"], 1, "{metrics}");
    assert_eq!(metrics["joins"]["silent"], 1, "{metrics}");
    assert_eq!(
        json(&silent.join("joins.json"))["silent"],
        serde_json::json!([0])
    );
}

#[test]
fn a_stampless_loop_on_a_true_return_pass_is_true() {
    let dir = tempfile::tempdir().expect("tempdir");
    // S1 drives lane 3 out (to 50 s) and back along it: from about 72 s on, the return pass
    // is 30 s or more from the places it revisits.
    let folders = merger_runs(dir.path(), "s1", 100.0, &[("return", "event_s = 90.0\n")]);
    let metrics = json(&folders[0].join("metrics.json"));
    assert_eq!(metrics["loops"]["accepted"], 1, "{metrics}");
    assert_eq!(metrics["loops"]["accepted_false"], 0, "{metrics}");
    assert_eq!(metrics["joins"]["wrong_joins"], 0, "{metrics}");
    assert!(
        metrics["joins"]["revisits"].as_u64() >= Some(1),
        "{metrics}"
    );
    let event = &accepted_loops(&folders[0])[0];
    assert_eq!(event["true_loop"], true, "{event}");
    assert_eq!(event["judged_by"], "final_map", "{event}");
    // Beside the ATE: the scale of a metric system and its drift.
    let scale = metrics["sim3_scale"].as_f64().expect("sim3_scale");
    assert!((scale - 1.0).abs() < 0.05, "{metrics}");
    assert!(
        metrics["drift"]["translation_percent"].as_f64().is_some(),
        "{metrics}"
    );
    assert!(
        metrics["alignment_transform"]["rotation_xyzw"].is_array(),
        "{metrics}"
    );
}

/// A camera run's wrong join gets its two frames: the evaluation renders again, from the
/// run's world.toml and seed, the colour frames at the joined stamps into `frames/`, and the
/// report shows them. S2 drives lane 3 east, then lane 4 (3 m away) west from about 62 s;
/// the fixture moves its final poses from 65 s on 3 m onto lane 3. The camera runs at 2 Hz
/// in this test's world (a cheap stream; the frames are the same renderer's).
#[test]
fn a_camera_runs_wrong_join_gets_its_two_frames_in_the_report() {
    let dir = tempfile::tempdir().expect("tempdir");
    let folders = merger_runs_in(
        dir.path(),
        "s2",
        90.0,
        &[(
            "camera-merge",
            "camera = true\nshift_from_s = 65.0\nshift_xy = [0.0, -3.0]\n",
        )],
        Some("[sensors.camera]\nrate_hz = 2.0\n"),
    );
    let run = &folders[0];
    let metrics = json(&run.join("metrics.json"));
    assert_eq!(metrics["joins"]["wrong_joins"], 1, "{metrics}");
    let frames = json(&run.join("frames.json"));
    let pair = &frames["pairs"][0];
    assert_eq!(pair["kind"], "wrong_join", "{frames}");
    let images: Vec<Vec<u8>> = (0..2)
        .map(|k| {
            let file = pair["files"][k].as_str().expect("a file");
            let bytes = std::fs::read(run.join(file)).expect("the frame");
            let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
            let mut reader = decoder.read_info().expect("a PNG");
            let mut buf = vec![0; reader.output_buffer_size().expect("size")];
            let info = reader.next_frame(&mut buf).expect("its pixels");
            assert_eq!((info.width, info.height), (640, 480), "{file}");
            buf
        })
        .collect();
    assert_ne!(images[0], images[1], "two places, two frames");
    let stamps: Vec<i64> = (0..2)
        .map(|k| pair["stamps_ns"][k].as_i64().expect("stamp"))
        .collect();
    assert!(
        stamps[0] >= 65_000_000_000 && stamps[1] < 50_000_000_000,
        "{pair}"
    );
    let html = std::fs::read_to_string(run.join("../../report.html")).expect("report.html");
    assert!(
        html.contains("s2/camera-merge/frames/wrong-join-0-later.png")
            && html.contains("wrong join #0 of the final map"),
        "the report shows the pair"
    );

    // `report --figures` writes the run's figures for a document: its route with the wrong
    // join, its error along the route with the join's later stretch marked, and the pair.
    let figures = dir.path().join("figures");
    let out = vinebench(&[
        "report",
        run.to_str().expect("utf-8"),
        "--figures",
        figures.to_str().expect("utf-8"),
        "--label",
        "merger",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let listed = text(&out.stdout);
    assert_eq!(
        listed.lines().count(),
        4,
        "route, error and the two frames: {listed}"
    );
    let route = std::fs::read_to_string(figures.join("route.svg")).expect("route.svg");
    assert!(
        route.contains("s2, merger") && route.contains("wrong joins of the final map"),
        "the route names the run and draws its wrong join"
    );
    let error = std::fs::read_to_string(figures.join("error.svg")).expect("error.svg");
    assert!(
        error.contains("wrong joins of the final map (its later stretch) (1)"),
        "the error along the route marks the wrong join"
    );
    assert_eq!(
        std::fs::read(figures.join("frames/wrong-join-0-later.png")).expect("copied"),
        std::fs::read(run.join("frames/wrong-join-0-later.png")).expect("the frame"),
    );
    // Frames half the size each way for a document, every pixel the mean of its block.
    let small = dir.path().join("small");
    let out = vinebench(&[
        "report",
        run.to_str().expect("utf-8"),
        "--figures",
        small.to_str().expect("utf-8"),
        "--frame-scale",
        "2",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let decoder = png::Decoder::new(std::io::Cursor::new(
        std::fs::read(small.join("frames/wrong-join-0-later.png")).expect("the small frame"),
    ));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("its pixels");
    assert_eq!((info.width, info.height), (320, 240));
    let mean =
        |pixels: &[u8]| pixels.iter().map(|&v| f64::from(v)).sum::<f64>() / pixels.len() as f64;
    assert!(
        (mean(&buf) - mean(&images[0])).abs() < 1.0,
        "the same picture, smaller: mean {} against {}",
        mean(&buf),
        mean(&images[0])
    );
    // A folder that is not a run's is named.
    let bad = vinebench(&[
        "report",
        dir.path().to_str().expect("utf-8"),
        "--figures",
        figures.to_str().expect("utf-8"),
    ]);
    assert!(!bad.status.success());
    assert!(
        text(&bad.stderr).contains("no run.toml"),
        "{}",
        text(&bad.stderr)
    );
}
