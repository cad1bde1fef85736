//! The camera frames of a run's false loops, wrong joins and a sample of its true loops,
//! rendered again into the run folder so that the report can show the two places a system
//! joined as it saw them (`frames/`, listed in `frames.json`).
//!
//! The simulator is deterministic: from the run's `world.toml`, scenario and seed,
//! `sim::Simulation::rgbd_frame_at` gives the very frame the stream gave at a stamp, noise
//! included, without keeping any frame during the run. Only for runs whose system took the
//! camera and whose data came from the simulation (a `--dataset` replay's frames are the
//! recording's, which this does not read).

use anyhow::Context as _;
use serde::Deserialize;

use crate::results::{FramePair, Frames, Joins, JudgedEvent, PairKind, RunFolder, files};

/// True loops drawn per run, beside every false one: a sample to compare against.
const TRUE_SAMPLE: usize = 2;

/// What `run.toml` says that decides the frames.
#[derive(Debug, Deserialize)]
struct RunToml {
    scenario: String,
    seed: u64,
    plugin: PluginToml,
}

#[derive(Debug, Deserialize)]
struct PluginToml {
    #[serde(default)]
    sensors: Vec<String>,
}

/// The pairs worth drawing: every false stamped loop, every wrong join, the first
/// [`TRUE_SAMPLE`] true stamped loops.
fn wanted(judged: &[JudgedEvent], joins: &Joins) -> Vec<(PairKind, usize, [i64; 2])> {
    let mut out = Vec::new();
    let mut true_drawn = 0;
    for (i, j) in judged.iter().enumerate() {
        let (Some(stamps), Some(verdict)) = (j.event.loop_stamps_ns, j.true_loop) else {
            continue;
        };
        if !verdict && j.event.kind == plugin_api::EventKind::LoopClosureAccepted {
            out.push((PairKind::FalseLoop, i, stamps));
        } else if verdict && true_drawn < TRUE_SAMPLE {
            out.push((PairKind::TrueLoop, i, stamps));
            true_drawn += 1;
        }
    }
    for (i, e) in joins.report.wrong_joins.iter().enumerate() {
        let ns = e.pair_s.map(|s| (s * 1e9).round() as i64);
        out.push((PairKind::WrongJoin, i, ns));
    }
    out
}

/// Renders the frames of `run`'s loops and joins into `frames/` and writes `frames.json`;
/// does nothing for a run without the camera, without anything to draw, or fed from a
/// recording.
pub fn write_frames(run: &RunFolder, judged: &[JudgedEvent], joins: &Joins) -> anyhow::Result<()> {
    let wanted = wanted(judged, joins);
    if wanted.is_empty() || !run.has(files::WORLD) {
        return Ok(());
    }
    let Some(text) = run.read_run_toml() else {
        return Ok(());
    };
    let run_toml: RunToml = toml::from_str(&text)
        .with_context(|| format!("{}: unreadable", run.path(files::RUN).display()))?;
    if !run_toml.plugin.sensors.iter().any(|s| s == "rgbd") {
        return Ok(());
    }
    if let Some(timing) = run.read_timing()?
        && timing.source == "dataset"
    {
        return Ok(());
    }
    let world_path = run.path(files::WORLD);
    let config = sim::SimConfig::from_file(&world_path)
        .with_context(|| format!("{}: the run's world", world_path.display()))?;
    let simulation = sim::Simulation::new(&config, &run_toml.scenario, run_toml.seed)
        .with_context(|| format!("rebuilding {} for its frames", run_toml.scenario))?;
    let dir = run.path(files::FRAMES_DIR);
    std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
    let mut frames = Frames::default();
    for (kind, index, stamps) in wanted {
        let name = match kind {
            PairKind::FalseLoop => "false-loop",
            PairKind::TrueLoop => "true-loop",
            PairKind::WrongJoin => "wrong-join",
        };
        let mut stamps_ns = [0; 2];
        let mut names: [String; 2] = Default::default();
        let mut complete = true;
        for (k, which) in ["later", "earlier"].into_iter().enumerate() {
            let Some(frame) = simulation.rgbd_frame_at(stamps[k]) else {
                complete = false;
                break;
            };
            let file = format!("{name}-{index}-{which}.png");
            sim::camera::save_rgb_png(&dir.join(&file), &frame.image)
                .with_context(|| dir.join(&file).display().to_string())?;
            stamps_ns[k] = frame.stamp_ns;
            names[k] = format!("{}/{file}", files::FRAMES_DIR);
        }
        if complete {
            frames.pairs.push(FramePair {
                kind,
                index,
                stamps_ns,
                files: names,
            });
        }
    }
    run.write_frames(&frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Joins holding one wrong join of two stretches (seconds) and its closest pair.
    fn one_wrong_join(later_s: [f64; 2], earlier_s: [f64; 2], pair_s: [f64; 2]) -> Joins {
        let mut joins = Joins::default();
        joins.report.wrong_joins.push(eval::JoinEpisode {
            kind: eval::EpisodeKind::WrongJoin,
            later_s,
            earlier_s,
            travel_m: 5.0,
            estimate_distance_m: 0.1,
            truth_distance_m: 5.8,
            later_place: [0.0, 0.0],
            earlier_place: [5.8, 0.0],
            pair_s,
        });
        joins
    }

    #[test]
    fn every_false_loop_and_wrong_join_and_two_true_loops_are_wanted() {
        use plugin_api::{Event, EventKind};
        let judged_loop = |stamps: [i64; 2], verdict: bool| JudgedEvent {
            event: Event::loop_closure(stamps[0], EventKind::LoopClosureAccepted, stamps, "x"),
            true_loop: Some(verdict),
            judged_by: None,
            wrong_join: None,
            revisit: None,
            gt_distance_m: None,
            gt_heading_deg: None,
            relative_error_m: None,
            relative_error_deg: None,
            error_before_m: None,
            error_after_m: None,
        };
        let judged = vec![
            judged_loop([10, 1], true),
            judged_loop([20, 2], false),
            judged_loop([30, 3], true),
            judged_loop([40, 4], true),
        ];
        let joins = one_wrong_join([100.0, 110.0], [5.0, 15.0], [105.0, 10.0]);
        let w = wanted(&judged, &joins);
        assert_eq!(
            w,
            [
                (PairKind::TrueLoop, 0, [10, 1]),
                (PairKind::FalseLoop, 1, [20, 2]),
                (PairKind::TrueLoop, 2, [30, 3]),
                (PairKind::WrongJoin, 0, [105_000_000_000, 10_000_000_000]),
            ]
        );
    }

    /// Nothing is drawn, and nothing written, for a run without the camera.
    #[test]
    fn a_run_without_a_world_or_a_camera_gets_no_frames() {
        let dir = tempfile::tempdir().expect("tempdir");
        let run = RunFolder::new(dir.path());
        let joins = one_wrong_join([1.0, 2.0], [0.0, 0.5], [1.5, 0.2]);
        write_frames(&run, &[], &joins).expect("no world: nothing to do");
        std::fs::write(run.path(files::WORLD), "").expect("world");
        std::fs::write(
            run.path(files::RUN),
            "scenario = \"s0\"\nseed = 0\n[plugin]\nsensors = [\"lidar\"]\n",
        )
        .expect("run.toml");
        write_frames(&run, &[], &joins).expect("no camera: nothing to do");
        assert!(!run.path(files::FRAMES).exists());
        assert!(!run.path(files::FRAMES_DIR).exists());
    }
}
