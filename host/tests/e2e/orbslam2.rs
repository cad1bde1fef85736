//! The ORB-SLAM2-style plugin as the host runs it — loaded from its `.so` by the `vinebench`
//! binary on the simulator's rendered frames — and its vocabulary on rendered frames.

use crate::common::{ate, json, run_with};

/// s4 drives lane 3 twice in the same direction: the second pass sees the first one's
/// views again. Loop closing must accept at least one loop there that ground truth calls
/// true, and the loop's correction must make the final trajectory more accurate than the
/// poses tracked during the run (`online_ape`: before the loop they carry the drift the
/// correction takes out). The default world with rows half as long (9 m), so that the route
/// is 123.5 s instead of 177.5 s, cut at 100 s: on the whole route the one accepted loop
/// came at 85 s (one run, seed 0: final ATE 0.020 m, as tracked 0.114 m).
#[test]
fn a_true_loop_in_s4_is_accepted_and_lowers_the_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let world = dir.path().join("short-rows.toml");
    std::fs::write(&world, "[vineyard]\nrow_length_m = 9.0\n").expect("write world");
    let with = run_with(
        dir.path(),
        "s4",
        "orbslam2",
        "loops",
        "",
        &[
            "--world",
            world.to_str().expect("utf-8"),
            "--max-time",
            "100",
        ],
    );
    let metrics = json(&with.join("metrics.json"));
    let loops = &metrics["loops"];
    let accepted = loops["accepted"].as_u64().expect("loops.accepted");
    let false_loops = loops["accepted_false"]
        .as_u64()
        .expect("loops.accepted_false");
    let final_rmse = ate(&with, "estimate.tum");
    let online_rmse = metrics["online_ape"]["rmse"]
        .as_f64()
        .expect("online_ape.rmse");
    eprintln!(
        "orbslam2 s4: {accepted} loops accepted ({false_loops} false), ATE {final_rmse:.3} m final, {online_rmse:.3} m as tracked"
    );
    assert!(accepted > false_loops, "no true loop accepted: {loops}");
    assert!(
        final_rmse < online_rmse,
        "the loop's correction did not lower the error"
    );

    // The true loop carries the keypoints it matched, inside the rig camera's frames, and
    // the evaluation drew them over the two frames it joined (`frames/`).
    let events = json(&with.join("events.json"));
    let event = events
        .as_array()
        .expect("a list")
        .iter()
        .find(|e| e["kind"] == "loop_closure_accepted" && e["true_loop"] == true)
        .expect("a true accepted loop");
    let matches = event["loop_matches"].as_array().expect("loop_matches");
    let (w, h) = (640.0, 480.0);
    assert!(matches.len() >= 20, "{} matches", matches.len());
    for m in matches {
        let m: Vec<f64> = m
            .as_array()
            .expect("4 numbers")
            .iter()
            .map(|v| v.as_f64().expect("a number"))
            .collect();
        assert!(
            m.len() == 4
                && m[0] < w
                && m[2] < w
                && m[1] < h
                && m[3] < h
                && m.iter().all(|v| *v >= 0.0),
            "a match outside the 640x480 frames: {m:?}"
        );
    }
    let frames = json(&with.join("frames.json"));
    let pair = frames["pairs"]
        .as_array()
        .expect("pairs")
        .iter()
        .find(|p| p["kind"] == "true_loop")
        .expect("the true loop's pictures");
    assert_eq!(pair["stamps_ns"], event["loop_stamps_ns"], "{pair}");
    let picture = with.join(pair["matches"].as_str().expect("the matches' picture"));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&picture).expect("the matches' PNG"),
    ));
    let info = decoder.read_info().expect("a PNG").info().clone();
    assert_eq!(
        (info.width, info.height),
        (1280, 480),
        "two frames side by side"
    );
    // What they lie on, every match counted once: on our world (no fence), the plants,
    // posts, wires and ground.
    let on = pair["matched_surfaces"]
        .as_object()
        .expect("matched_surfaces");
    assert_eq!(
        on.values()
            .map(|n| n.as_u64().expect("a count"))
            .sum::<u64>(),
        matches.len() as u64,
        "{on:?}"
    );
    assert!(!on.keys().any(|k| k.contains("fence")), "{on:?}");
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
