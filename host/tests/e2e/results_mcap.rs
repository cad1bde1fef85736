//! A run's results.mcap from the outside: written when `vinebench run` scores a real plugin,
//! read by an independent decoder (Foxglove's `mcap` + `mcap-ros2-support`,
//! tests/mcap/check_results.py), it holds the run's own ground truth, its estimate aligned by
//! the very transform its APE used, its map and its loops as metrics.json counts them, and
//! the same run writes the same bytes. The writer's loop colours, an absent map and a bad
//! target are checked on a made-up run through the library.
//!
//! The Python check needs those packages: `source scripts/setup.sh` puts a virtual
//! environment with them first on PATH (scripts/test.sh does). Without them the test fails
//! and says so; it never passes silently.

use std::path::Path;

use eval::{Alignment, ApeOptions, Trajectory};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;
use vinebench::dataset::{JudgedLoop, RunResults, write_results};

use crate::common::{json, loop_events, mcap_check, run_together};

/// Loop closure on a 60 s stretch of S1 (down the row and into the headland): candidates
/// 10 s old or more, every registration accepted, so loops close on the way down and the
/// host judges each one.
const LOOSE_LOOPS: &str = "[loop_closure]\nmin_age_s = 10.0\nmax_fitness = 1000.0\n";
const MAX_TIME: &str = "60";

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("an array: {v}"))
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// A pose of the checker's JSON: stamp, `map_from_base`.
fn pose(v: &Value) -> (i64, Isometry3<f64>) {
    let p = f64s(&v["position"]);
    let q = f64s(&v["orientation"]);
    let rotation =
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[3], q[0], q[1], q[2]));
    (
        v["stamp_ns"].as_i64().expect("stamp_ns"),
        Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rotation),
    )
}

fn stamp_ns(t_s: f64) -> i64 {
    (t_s * 1e9).round() as i64
}

/// Every pose of `path` (the checker's `all`) equals `want` (stamps in seconds), stamp for
/// stamp, to 1e-9 m and 1e-9 in each quaternion component (either sign).
fn assert_path(path: &Value, want: &[(f64, Isometry3<f64>)], what: &str) {
    let got: Vec<(i64, Isometry3<f64>)> = path["all"]
        .as_array()
        .unwrap_or_else(|| panic!("{what}: every pose (--poses)"))
        .iter()
        .map(pose)
        .collect();
    assert_eq!(got.len(), want.len(), "{what}: number of poses");
    for (i, ((t, p), (want_t, want_p))) in got.iter().zip(want).enumerate() {
        let (q, want_q) = (p.rotation.coords, want_p.rotation.coords);
        assert!(
            *t == stamp_ns(*want_t)
                && (p.translation.vector - want_p.translation.vector).norm() < 1e-9
                && (q - want_q).norm().min((q + want_q).norm()) < 1e-9,
            "{what}: pose {i} is {t} ns {p:?}, expected {want_t} s {want_p:?}"
        );
    }
}

/// Every pose of `estimate` moved by `map_from_estimate`, with its stamp.
fn aligned(estimate: &Trajectory, map_from_estimate: &eval::Sim3) -> Vec<(f64, Isometry3<f64>)> {
    estimate
        .stamps
        .iter()
        .zip(&estimate.poses)
        .map(|(&t, p)| (t, map_from_estimate.apply(p)))
        .collect()
}

/// The alignment `metrics.json` names.
fn alignment(name: &str) -> Alignment {
    match name {
        "none" => Alignment::None,
        "origin" => Alignment::Origin,
        "se3" => Alignment::Se3,
        "sim3" => Alignment::Sim3,
        "4dof" => Alignment::FourDof,
        other => panic!("metrics.json alignment {other}"),
    }
}

/// The position of the pose of `poses` (sorted) nearest in time to `t_ns`, the earlier at a
/// tie.
fn nearest(poses: &[(f64, Isometry3<f64>)], t_ns: i64) -> Vector3<f64> {
    let best = poses
        .iter()
        .min_by_key(|(t, _)| (stamp_ns(*t) - t_ns).abs())
        .expect("an estimate");
    best.1.translation.vector
}

/// Each marker's two ends equal `want` (in order) to 1e-9 m.
fn assert_markers(summary: &Value, want: &[(&str, [Vector3<f64>; 2])]) {
    let markers = summary["loop_markers"].as_array().expect("loop_markers");
    assert_eq!(markers.len(), want.len(), "one marker per judged loop");
    for (i, (m, (ns, ends))) in markers.iter().zip(want).enumerate() {
        let got: Vec<Vec<f64>> = m["ends"]
            .as_array()
            .expect("ends")
            .iter()
            .map(f64s)
            .collect();
        assert_eq!(m["ns"], *ns, "marker {i}: {m}");
        for (g, w) in got.iter().zip(ends) {
            assert!(
                (Vector3::new(g[0], g[1], g[2]) - w).norm() < 1e-9,
                "marker {i}: ends {got:?}, expected {ends:?}"
            );
        }
    }
}

/// The vertex count a PLY header declares.
fn ply_vertices(path: &Path) -> (usize, [f32; 3]) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("a PLY header")
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let n = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .and_then(|n| n.parse().ok())
        .expect("element vertex N");
    let first =
        [0, 4, 8].map(|i| f32::from_le_bytes(bytes[end + i..end + i + 4].try_into().unwrap()));
    (n, first)
}

/// Guards results.mcap as a bench writes it for lio-sam on 60 s of S1 (loops and a map):
/// the ground-truth path is groundtruth.tum; the estimate path is estimate.tum aligned by
/// the transform the run's APE used (recomputed here with `eval`, the same rmse as
/// metrics.json), in the metadata too; each loop marker joins the aligned poses nearest its
/// stamps and the markers count as metrics.json's loops; the map has map.ply's points,
/// aligned; a second run of the same bench gives the same bytes and no temporary file is
/// left. The same bench's report.html draws every loop (`crate::report`).
#[test]
fn results_mcap_of_a_lio_sam_run_holds_its_aligned_estimate_map_and_loops() {
    let dir = tempfile::tempdir().expect("temp dir");
    let extra = ["--max-time", MAX_TIME];
    // Two identical runs fed by one simulation: the second checks determinism.
    let folders = run_together(
        dir.path(),
        "s1",
        "lio-sam",
        (&[("a", LOOSE_LOOPS), ("b", LOOSE_LOOPS)], None),
        &extra,
    );
    let (folder, again) = (&folders[0], &folders[1]);
    let results = folder.join("results.mcap");
    let summary = mcap_check(
        "check_results.py",
        &[results.as_os_str(), "--poses".as_ref()],
    );
    assert_eq!(summary["profile"], "ros2");

    let gt = eval::read_tum(folder.join("groundtruth.tum")).expect("groundtruth.tum");
    let estimate = eval::read_tum(folder.join("estimate.tum")).expect("estimate.tum");
    let as_pairs = |t: &Trajectory| -> Vec<(f64, Isometry3<f64>)> {
        t.stamps
            .iter()
            .copied()
            .zip(t.poses.iter().copied())
            .collect()
    };
    assert_path(
        &summary["paths"]["/groundtruth/path"],
        &as_pairs(&gt),
        "/groundtruth/path",
    );

    // The run's alignment, recomputed: the same statistics as metrics.json say it is the
    // transform the run was scored with.
    let metrics = json(&folder.join("metrics.json"));
    let name = metrics["alignment"].as_str().expect("alignment");
    let options = ApeOptions {
        alignment: alignment(name),
        ..ApeOptions::default()
    };
    let ape = eval::evaluate_ape(&gt, &estimate, &options).expect("APE");
    let rmse = metrics["ape"]["rmse"].as_f64().expect("rmse");
    assert!(
        (ape.stats.rmse - rmse).abs() <= 1e-12 * rmse,
        "the recomputed APE ({} m) is the run's ({rmse} m)",
        ape.stats.rmse
    );
    let aligned = aligned(&estimate, &ape.transform);
    assert_path(
        &summary["paths"]["/estimate/path"],
        &aligned,
        "/estimate/path",
    );
    assert_eq!(
        summary["topics"]["/estimate/pose"]["count"].as_u64(),
        Some(estimate.len() as u64),
        "a /estimate/pose per estimated pose (the checker compares them with the path)"
    );
    let meta = &summary["metadata"]["vinebench"];
    let parse = |key: &str| -> Vec<f64> {
        meta[key]
            .as_str()
            .unwrap_or_else(|| panic!("metadata {key}: {meta}"))
            .split(' ')
            .map(|x| x.parse().expect("a number"))
            .collect()
    };
    let q = ape.transform.rotation.coords;
    let t = ape.transform.translation;
    assert_eq!(meta["alignment"], name, "{meta}");
    assert_eq!(parse("alignment_scale"), [ape.transform.scale], "{meta}");
    assert_eq!(
        parse("alignment_rotation_xyzw"),
        [q.x, q.y, q.z, q.w],
        "{meta}"
    );
    assert_eq!(parse("alignment_translation_m"), [t.x, t.y, t.z], "{meta}");

    // Loops: one marker per accepted loop, in the plugin's order, the false ones red.
    let accepted = loop_events(folder, "loop_closure_accepted");
    let loops = &metrics["loops"];
    assert!(
        !accepted.is_empty(),
        "the route closes loops with these settings: {loops}"
    );
    assert!(
        loops.get("unjudged").is_none(),
        "every loop judged: {loops}"
    );
    assert_eq!(
        (
            summary["loops"]["true_loops"].as_u64().expect("count")
                + summary["loops"]["false_loops"].as_u64().expect("count"),
            summary["loops"]["false_loops"].as_u64()
        ),
        (
            loops["accepted"].as_u64().expect("accepted"),
            loops["accepted_false"].as_u64()
        ),
        "markers per namespace vs metrics.json {loops}"
    );
    let want: Vec<(&str, [Vector3<f64>; 2])> = accepted
        .iter()
        .map(|e| {
            let ns = if e.true_loop.expect("judged") {
                "true_loops"
            } else {
                "false_loops"
            };
            (
                ns,
                e.stamps_ns.expect("stamps").map(|s| nearest(&aligned, s)),
            )
        })
        .collect();
    assert_markers(&summary, &want);

    // The map: map.ply's points, aligned.
    let (vertices, first) = ply_vertices(&folder.join("map.ply"));
    assert!(vertices > 0, "lio-sam writes its map");
    assert_eq!(
        summary["map"]["points"].as_u64(),
        Some(vertices as u64),
        "/map points vs map.ply"
    );
    let first_in_map = ape.transform.apply(&Isometry3::translation(
        f64::from(first[0]),
        f64::from(first[1]),
        f64::from(first[2]),
    ));
    let got = f64s(&summary["map"]["first_point"]);
    assert!(
        (Vector3::new(got[0], got[1], got[2]) - first_in_map.translation.vector).norm() < 1e-5,
        "the map's first point {got:?}, expected {first_in_map:?} (aligned, as f32)"
    );

    // Deterministic, and nothing half-written left behind.
    let (a, b) = (
        std::fs::read(&results).expect("results.mcap"),
        std::fs::read(again.join("results.mcap")).expect("results.mcap"),
    );
    assert!(
        a == b,
        "two runs wrote different results.mcap ({} / {} bytes)",
        a.len(),
        b.len()
    );
    let stray: Vec<String> = std::fs::read_dir(folder)
        .expect("run folder")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("tmp"))
        .collect();
    assert!(stray.is_empty(), "temporary files left: {stray:?}");
    eprintln!(
        "lio-sam S1 {MAX_TIME} s: results.mcap {} bytes, {} loops, {vertices} map points",
        a.len(),
        accepted.len()
    );
    let bench = folder
        .parent()
        .and_then(Path::parent)
        .expect("the bench folder");
    crate::report::check_bench_loops(bench, &["a", "b"]);
}

/// A made-up run: ground truth along x at 10 Hz for 10 s, the estimate the same path turned
/// and shifted (so the SE(3) alignment is exact), stamps 5 ms off the truth's.
fn made_up_run() -> (Trajectory, Trajectory) {
    let stamps: Vec<f64> = (0..=100).map(|i| f64::from(i) * 0.1).collect();
    let truth: Vec<Isometry3<f64>> = stamps
        .iter()
        .map(|&t| {
            Isometry3::new(
                Vector3::new(t, 0.2 * t.sin(), 0.05 * t),
                Vector3::z() * 0.1 * t,
            )
        })
        .collect();
    let estimate_from_map = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::z() * 0.7);
    let est_stamps: Vec<f64> = stamps.iter().map(|t| t + 0.005).collect();
    let estimate = truth.iter().map(|p| estimate_from_map * p).collect();
    (
        Trajectory::new(stamps, truth),
        Trajectory::new(est_stamps, estimate),
    )
}

/// Guards the loop colours and the optional map through the independent decoder: a true
/// and a false loop become a green and a red marker in their namespaces, between the
/// aligned estimate poses nearest their stamps; without a map there is no /map; without
/// loops /loops is an empty array; a file that cannot be written is an error naming it.
#[test]
fn results_mcap_draws_false_loops_red_and_leaves_out_an_absent_map() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (gt, estimate) = made_up_run();
    let options = ApeOptions {
        alignment: Alignment::Se3,
        ..ApeOptions::default()
    };
    let ape = eval::evaluate_ape(&gt, &estimate, &options).expect("APE");
    assert!(ape.stats.max < 1e-9, "the made-up estimate aligns exactly");
    let loops = [
        JudgedLoop {
            stamps_ns: [9_000_000_000, 1_000_000_000],
            true_loop: true,
        },
        JudgedLoop {
            stamps_ns: [8_010_000_000, 2_000_000_000],
            true_loop: false,
        },
    ];
    let run = RunResults {
        groundtruth: &gt,
        estimate: &estimate,
        alignment: "se3",
        map_from_estimate: &ape.transform,
        map_points: None,
        loops: &loops,
    };
    let path = dir.path().join("results.mcap");
    let size = write_results(&path, &run).expect("write");
    assert_eq!(size, std::fs::metadata(&path).expect("written").len());
    let summary = mcap_check("check_results.py", &[path.as_os_str(), "--poses".as_ref()]);
    assert!(
        summary["topics"].get("/map").is_none(),
        "{}",
        summary["topics"]
    );
    assert_eq!(summary["map"], Value::Null);
    assert_eq!(
        summary["loops"],
        serde_json::json!({"true_loops": 1, "false_loops": 1})
    );
    // The nearest estimated poses: 9.005 s and 1.005 s; 8.005 s (8.01 s is nearer it than
    // 8.105 s) and 2.005 s.
    let aligned = aligned(&estimate, &ape.transform);
    let at = |k: usize| aligned[k].1.translation.vector;
    assert_markers(
        &summary,
        &[
            ("true_loops", [at(90), at(10)]),
            ("false_loops", [at(80), at(20)]),
        ],
    );
    assert_path(
        &summary["paths"]["/estimate/path"],
        &aligned,
        "/estimate/path",
    );

    let no_loops = RunResults { loops: &[], ..run };
    write_results(&path, &no_loops).expect("rewrite");
    let summary = mcap_check("check_results.py", &[&path]);
    assert_eq!(
        summary["topics"]["/loops"]["count"], 1,
        "{}",
        summary["topics"]
    );
    assert_eq!(
        summary["loops"],
        serde_json::json!({"true_loops": 0, "false_loops": 0})
    );

    let missing = dir.path().join("no-such-folder").join("results.mcap");
    let err = write_results(&missing, &run)
        .expect_err("no folder to write in")
        .to_string();
    assert!(
        err.contains("no-such-folder/results.mcap") && err.lines().count() == 1,
        "{err}"
    );
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .expect("temp dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(
        names.len(),
        1,
        "only results.mcap, no temporary file: {names:?}"
    );
}
