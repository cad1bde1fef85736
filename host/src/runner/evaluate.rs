//! Scores a finished run: APE (translation) of the final and of the online trajectory
//! against ground truth, as evo computes it, with the alignment's transform, the Sim(3)
//! scale and the drift per 100 m; the final map's wrong joins and revisits
//! (`eval::wrong_joins`, `joins.json`); and its loop closures judged against ground truth
//! (see `loops.rs`); then writes the run's results.mcap
//! ([`crate::dataset::write_results`]) with the estimate and map aligned by the transform
//! of that APE.

use anyhow::Context as _;
use eval::{Alignment, ApeOptions, Sim3, Trajectory};
use plugin_api::EventKind;

use crate::dataset::{JudgedLoop, RunResults};
use crate::results::{ApeSeries, Joins, JudgedEvent, Metrics, RunFolder, Transform, files};

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
    // The final map's joins, scale and drift, on the associated poses before alignment:
    // distances in the estimate's own scale, the same under any rigid alignment.
    let pairs = options.pairing.pair(&gt, &estimate)?;
    let position = |poses: &[nalgebra::Isometry3<f64>]| -> Vec<nalgebra::Vector3<f64>> {
        poses.iter().map(|p| p.translation.vector).collect()
    };
    let report = eval::wrong_joins(
        &pairs.stamps,
        &position(&pairs.estimate),
        &position(&pairs.reference),
        &eval::JoinCriteria::default(),
    );
    let sim3_scale = eval::align(&mut pairs.clone(), Alignment::Sim3, None)
        .ok()
        .map(|t| t.scale)
        .filter(|s| s.is_finite());
    let drift = eval::drift(
        &pairs.reference,
        &pairs.estimate,
        &eval::DriftOptions::default(),
    )
    .ok()
    .and_then(|d| d.last().copied());
    let events = run.read_events()?;
    let (loops, judged) = super::loops::judge(
        events,
        &gt,
        &eval::LoopCriteria::default(),
        online.as_ref().map(|(trajectory, _)| super::loops::Online {
            trajectory,
            map_from_estimate: &final_.transform,
        }),
        Some(&report),
    );
    let joins = explained(report, &judged);
    run.write_judged_events(&judged)?;
    run.write_joins(&joins)?;
    super::frames::write_frames(run, &judged, &joins)?;
    let metrics = Metrics {
        alignment: alignment.name().to_owned(),
        ape: final_.stats,
        online_ape: online.map(|(_, stats)| stats),
        loops,
        alignment_transform: Some(Transform::from(&final_.transform)),
        sim3_scale,
        drift,
        joins: Some(joins.counts()),
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

/// The final map's episodes with the wrong joins no accepted loop of `judged` explains
/// marked silent (`runner::loops`).
fn explained(report: eval::JoinReport, judged: &[JudgedEvent]) -> Joins {
    let accepted = judged
        .iter()
        .filter(|j| j.event.kind == EventKind::LoopClosureAccepted);
    let stamped: Vec<[f64; 2]> = accepted
        .clone()
        .filter_map(|j| j.event.loop_stamps_ns)
        .map(|s| s.map(|ns| ns as f64 * 1e-9))
        .collect();
    let stampless: Vec<f64> = accepted
        .filter(|j| j.event.loop_stamps_ns.is_none())
        .map(|j| j.event.stamp_ns as f64 * 1e-9)
        .collect();
    let silent = report.silent(&stamped, &stampless);
    Joins { report, silent }
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
