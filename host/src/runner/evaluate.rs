//! Scores a finished run: APE (translation) of the final and of the online trajectory
//! against ground truth, as evo computes it, and its loop closures judged against ground
//! truth (see `loops.rs`); then writes the run's results.mcap
//! ([`crate::dataset::write_results`]) with the estimate and map aligned by the transform
//! of that APE.

use anyhow::Context as _;
use eval::{Alignment, ApeOptions, Sim3, Trajectory};
use plugin_api::EventKind;

use crate::dataset::{JudgedLoop, RunResults};
use crate::results::{ApeSeries, JudgedEvent, Metrics, RunFolder, files};

/// Evaluates the run in `run`: writes its metrics.json, rewrites its events.json with the
/// judgement of every accepted loop, and writes its ape.csv and results.mcap.
pub fn evaluate(run: &RunFolder, alignment: Alignment) -> anyhow::Result<()> {
    let gt = run.read_groundtruth()?;
    let options = ApeOptions {
        alignment,
        ..ApeOptions::default()
    };
    let estimate = run.read_estimate()?;
    let final_ = eval::evaluate_ape(&gt, &estimate, &options)
        .with_context(|| format!("evaluating {}", run.path(files::ESTIMATE).display()))?;
    let online = match run.read_online()? {
        Some(trajectory) => {
            let stats = eval::evaluate_ape(&gt, &trajectory, &options)?.stats;
            Some((trajectory, stats))
        }
        None => None,
    };
    let events = run.read_events()?;
    let (loops, judged) = super::loops::judge(
        events,
        &gt,
        &eval::LoopCriteria::default(),
        online.as_ref().map(|(trajectory, _)| super::loops::Online {
            trajectory,
            map_from_estimate: &final_.transform,
        }),
    );
    run.write_judged_events(&judged)?;
    let metrics = Metrics {
        alignment: alignment.name().to_owned(),
        ape: final_.stats,
        online_ape: online.map(|(_, stats)| stats),
        loops,
    };
    run.write_metrics(&metrics)?;
    run.write_ape(&ApeSeries {
        stamps_s: final_.pairs.stamps.clone(),
        aligned: final_
            .pairs
            .estimate
            .iter()
            .map(|p| p.translation.vector.into())
            .collect(),
        errors_m: final_.errors.clone(),
    })?;
    write_results(
        run,
        &gt,
        &estimate,
        &metrics.alignment,
        &final_.transform,
        &judged,
    )
}

/// Writes `dir`'s results.mcap: the ground truth, the estimate and map.ply (if any) moved
/// into the ground truth's frame by `map_from_estimate` (the APE's alignment), and every
/// judged accepted loop.
fn write_results(
    run: &RunFolder,
    groundtruth: &Trajectory,
    estimate: &Trajectory,
    alignment: &str,
    map_from_estimate: &Sim3,
    judged: &[JudgedEvent],
) -> anyhow::Result<()> {
    let map_points = if run.has(files::MAP) {
        Some(crate::results::read_ply(&run.path(files::MAP))?)
    } else {
        None
    };
    let loops: Vec<JudgedLoop> = judged
        .iter()
        .filter(|j| j.event.kind == EventKind::LoopClosureAccepted)
        .filter_map(|j| {
            Some(JudgedLoop {
                stamps_ns: j.event.loop_stamps_ns?,
                true_loop: j.true_loop?,
            })
        })
        .collect();
    crate::dataset::write_results(
        &run.path(files::RESULTS),
        &RunResults {
            groundtruth,
            estimate,
            alignment,
            map_from_estimate,
            map_points: map_points.as_deref(),
            loops: &loops,
        },
    )?;
    Ok(())
}
