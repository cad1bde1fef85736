//! The ORB-SLAM2-style plugin as the host runs it — loaded from its `.so` by the `vinebench`
//! binary on the simulator's rendered frames — and its vocabulary on rendered frames.

mod common;

use std::path::Path;

use common::{ate, json, run};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// A TUM trajectory: seconds and `map_from_base`.
fn read_tum(path: &Path) -> Vec<(f64, Isometry3<f64>)> {
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
fn at(gt: &[(f64, Isometry3<f64>)], t: f64) -> Isometry3<f64> {
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
fn relative_errors(folder: &Path, dt: f64) -> Vec<(f64, f64)> {
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

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Tracking on the rendered frames of S0 (25 m down a lane, identical plants, growth stage
/// 3, camera noise on): every frame tracked, and the relative pose over 1 s (0.5 m at full
/// speed) within 1 cm and 0.5° of the truth, as RMS over every pair of frames 1 s apart
/// (evo's RPE with a 1 s delta; median, p95 and worst printed).
#[test]
fn tracking_on_rendered_frames_follows_the_ground_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let folder = run(dir.path(), "s0", "orbslam2", "orbslam2", "");
    let events = json(&folder.join("events.json"));
    let lost = events
        .as_array()
        .expect("events")
        .iter()
        .filter(|e| e["kind"] == "tracking_lost")
        .count();
    let errors = relative_errors(&folder, 1.0);
    let (m, deg): (Vec<f64>, Vec<f64>) = errors.iter().copied().unzip();
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let (rms_m, rms_deg) = (rms(&m), rms(&deg));
    eprintln!(
        "orbslam2 S0: {} pairs 1 s apart; translation RMS {:.2} mm, p50 {:.2} p95 {:.2} max {:.2} mm; rotation RMS {:.3} deg, p50 {:.3} p95 {:.3} max {:.3} deg; lost {lost}; ATE {:.3} m",
        errors.len(),
        1e3 * rms_m,
        1e3 * quantile(m.clone(), 0.5),
        1e3 * quantile(m.clone(), 0.95),
        1e3 * quantile(m.clone(), 1.0),
        rms_deg,
        quantile(deg.clone(), 0.5),
        quantile(deg.clone(), 0.95),
        quantile(deg.clone(), 1.0),
        ate(&folder, "estimate.tum"),
    );
    assert!(
        errors.len() > 1000,
        "only {} pairs: frames were not tracked",
        errors.len()
    );
    assert_eq!(lost, 0, "tracking was lost");
    assert!(
        rms_m < 0.01,
        "relative translation error over 1 s: RMS {rms_m:.4} m"
    );
    assert!(
        rms_deg < 0.5,
        "relative rotation error over 1 s: RMS {rms_deg:.3} deg"
    );
}

/// s4 drives lane 3 twice in the same direction: the second pass sees the first one's
/// views again. Loop closing must accept at least one loop there that ground truth calls
/// true, and with loop closing the final trajectory must be more accurate than without.
#[test]
fn a_true_loop_in_s4_is_accepted_and_lowers_the_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let with = run(dir.path(), "s4", "orbslam2", "loops", "");
    let without = run(
        dir.path(),
        "s4",
        "orbslam2",
        "no-loops",
        "[loop_closing]\nenabled = false\n",
    );
    let loops = &json(&with.join("metrics.json"))["loops"];
    let accepted = loops["accepted"].as_u64().expect("loops.accepted");
    let false_loops = loops["accepted_false"]
        .as_u64()
        .expect("loops.accepted_false");
    let (ate_with, ate_without) = (ate(&with, "estimate.tum"), ate(&without, "estimate.tum"));
    eprintln!(
        "orbslam2 s4: {accepted} loops accepted ({false_loops} false), ATE {ate_with:.3} m with loop closing, {ate_without:.3} m without"
    );
    assert!(accepted > false_loops, "no true loop accepted: {loops}");
    assert!(
        ate_with < ate_without,
        "loop closing did not lower the error"
    );
    let no_loops = &json(&without.join("metrics.json"))["loops"];
    assert_eq!(
        no_loops["accepted"].as_u64(),
        Some(0),
        "loop closing was off"
    );
}

/// The shipped vocabulary on rendered frames of the benchmark's world (which it was not
/// trained on): along a lane, each frame's bag of words scores highest against its
/// neighbour 0.5 s away, above every frame 5 s or more away.
#[test]
fn the_vocabulary_scores_a_frame_highest_against_its_neighbour() {
    use orbslam2::orb::{OrbConfig, OrbExtractor, gray_from_rgb};
    use sim::{SimConfig, Simulation};
    use slam_common::vocabulary::Vocabulary;

    let vocabulary = Vocabulary::read_from(
        &mut &include_bytes!("../../plugins/orbslam2/vocabulary/vineyard-k10l6.dbow")[..],
    )
    .expect("the shipped vocabulary reads");
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s1", 0).expect("S1 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let mut rng = sim::rng::stream(0, "camera");
    let mut extractor = OrbExtractor::new(OrbConfig::default()).expect("ORB");
    // Every 0.5 s from 10 s to 40 s of S1's first leg (0.25 m apart at full speed).
    let bows: Vec<_> = (0..60)
        .map(|i| {
            let world_from_base = sim.trajectory.pose(10_000_000_000 + i * 500_000_000);
            let image = cam.render(&world_from_base, &mut rng);
            let gray = gray_from_rgb(&image.rgb, image.width, image.height);
            let (_, descriptors) = extractor
                .extract(&gray, image.width, image.height)
                .expect("ORB");
            vocabulary.transform(&descriptors, 4).0
        })
        .collect();
    let mut wins = 0;
    for i in 0..bows.len() - 1 {
        let neighbour = Vocabulary::score(&bows[i], &bows[i + 1]);
        let far = (0..bows.len())
            .filter(|&j| j.abs_diff(i) >= 10)
            .map(|j| Vocabulary::score(&bows[i], &bows[j]))
            .fold(0.0, f64::max);
        if neighbour > far {
            wins += 1;
        }
    }
    eprintln!(
        "neighbour scores highest for {wins} of {} frames",
        bows.len() - 1
    );
    assert!(
        wins * 10 >= (bows.len() - 1) * 9,
        "{wins} of {}",
        bows.len() - 1
    );
}
