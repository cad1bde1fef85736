//! The ORB-SLAM2-style plugin as the host runs it — loaded from its `.so` by the `vinebench`
//! binary on the simulator's rendered frames — and its vocabulary on rendered frames.

use crate::common::{ate, json, run_together};

/// s4 drives lane 3 twice in the same direction: the second pass sees the first one's
/// views again. Loop closing must accept at least one loop there that ground truth calls
/// true, and with loop closing the final trajectory must be more accurate than without.
/// The route is cut at 140 s of its 177.5 s: the second pass begins at about 119 s, and the
/// whole route's one accepted loop came at 121 s (one run, seed 0).
#[test]
fn a_true_loop_in_s4_is_accepted_and_lowers_the_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    // One rendering of S4 feeds both runs.
    let folders = run_together(
        dir.path(),
        "s4",
        "orbslam2",
        &[
            ("loops", ""),
            ("no-loops", "[loop_closing]\nenabled = false\n"),
        ],
        &["--max-time", "140"],
    );
    let (with, without) = (&folders[0], &folders[1]);
    let loops = &json(&with.join("metrics.json"))["loops"];
    let accepted = loops["accepted"].as_u64().expect("loops.accepted");
    let false_loops = loops["accepted_false"]
        .as_u64()
        .expect("loops.accepted_false");
    let (ate_with, ate_without) = (ate(with, "estimate.tum"), ate(without, "estimate.tum"));
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

/// How often, along S1's first lane (a frame every 0.5 s, 0.25 m apart at full speed, from
/// 10 s to 40 s), a frame's bag of words under the shipped vocabulary scores highest against
/// its neighbour rather than against any frame 2.5 m or more away.
fn neighbour_wins(plant_variation: f64) -> (usize, usize) {
    use orbslam2::orb::{OrbConfig, OrbExtractor};
    use plugin_api::gray_from_rgb;
    use sim::{SimConfig, Simulation};
    use slam_common::place::vocabulary::Vocabulary;

    let vocabulary = Vocabulary::read_from(
        &mut &include_bytes!("../../../plugins/orbslam2/vocabulary/vineyard-k10l6.dbow")[..],
    )
    .expect("the shipped vocabulary reads");
    let mut config = SimConfig::default();
    config.vineyard.plant_variation = plant_variation;
    let sim = Simulation::new(&config, "s1", 0).expect("S1 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let mut rng = sim::rng::stream(0, "camera");
    let mut extractor = OrbExtractor::new(OrbConfig::default()).expect("ORB");
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
    let wins = (0..bows.len() - 1)
        .filter(|&i| {
            let neighbour = Vocabulary::score(&bows[i], &bows[i + 1]);
            (0..bows.len())
                .filter(|&j| j.abs_diff(i) >= 10)
                .all(|j| Vocabulary::score(&bows[i], &bows[j]) < neighbour)
        })
        .count();
    (wins, bows.len() - 1)
}

/// The shipped vocabulary (trained on world seed 7) on the benchmark's world (seed 1). With
/// every plant unique a frame scores highest against its neighbour for 44 of 59 frames
/// (measured); the test holds at least two thirds. Where it does not, a frame 2.5 m or more
/// down the same row scores higher: posts (every 6 m) and wires repeat, and the camera sees
/// far along the row. With identical plants (printed, not asserted: 36 of 59) the rows also
/// repeat every plant (1 m) — the aliasing the paper blames.
#[test]
fn the_vocabulary_scores_a_frame_highest_against_its_neighbour() {
    let (wins, n) = neighbour_wins(1.0);
    let (wins_identical, _) = neighbour_wins(0.0);
    eprintln!(
        "neighbour scores highest for {wins} of {n} frames with unique plants, {wins_identical} of {n} with identical plants"
    );
    assert!(wins * 3 >= n * 2, "{wins} of {n}");
}
