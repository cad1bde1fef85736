//! Scores a finished run: APE (translation) of the final and of the online trajectory
//! against ground truth, as evo computes it, and its loop closures judged against ground
//! truth (see `loops.rs`); then writes the run's results.mcap
//! ([`crate::dataset::write_results`]) with the estimate and map aligned by the transform
//! of that APE.

use std::path::Path;

use anyhow::Context as _;
use eval::{Alignment, ApeOptions, LoopCounts, Sim3, Statistics, Trajectory};
use plugin_api::EventKind;
use serde::Serialize;

use super::job::files;
use super::loops::JudgedEvent;
use crate::dataset::{JudgedLoop, RunResults};

/// metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    pub alignment: String,
    /// APE translation of the final trajectory, metres.
    pub ape: Statistics,
    /// APE translation of the poses returned during the run, if any.
    pub online_ape: Option<Statistics>,
    /// Loop closures accepted (of those, how many were false and, if any, how many could
    /// not be judged) and rejected.
    pub loops: LoopCounts,
}

/// The scores and the aligned final estimate's top view.
#[derive(Debug, Clone)]
pub struct Scored {
    pub metrics: Metrics,
    pub estimate_xy: Vec<(f64, f64)>,
}

pub fn alignment_name(a: Alignment) -> &'static str {
    match a {
        Alignment::None => "none",
        Alignment::Origin => "origin",
        Alignment::Se3 => "se3",
        Alignment::Sim3 => "sim3",
        Alignment::Scale => "scale",
        Alignment::FourDof => "4dof",
    }
}

/// The alignment named by [`alignment_name`] (as `metrics.json` records it).
pub fn alignment_from_name(name: &str) -> Option<Alignment> {
    [
        Alignment::None,
        Alignment::Origin,
        Alignment::Se3,
        Alignment::Sim3,
        Alignment::Scale,
        Alignment::FourDof,
    ]
    .into_iter()
    .find(|&a| alignment_name(a) == name)
}

/// Evaluates the run in `dir`, writes its metrics.json, rewrites its events.json with
/// the judgement of every accepted loop and writes its results.mcap.
pub fn evaluate(dir: &Path, alignment: Alignment) -> anyhow::Result<Scored> {
    let gt = eval::read_tum(dir.join(files::GROUNDTRUTH))?;
    let options = ApeOptions {
        alignment,
        ..ApeOptions::default()
    };
    let estimate = eval::read_tum(dir.join(files::ESTIMATE))?;
    let final_ = eval::evaluate_ape(&gt, &estimate, &options)
        .with_context(|| format!("evaluating {}", dir.join(files::ESTIMATE).display()))?;
    let online_path = dir.join(files::ONLINE);
    let online = if online_path.exists() {
        let trajectory = eval::read_tum(&online_path)?;
        let stats = eval::evaluate_ape(&gt, &trajectory, &options)?.stats;
        Some((trajectory, stats))
    } else {
        None
    };
    let events_path = dir.join(files::EVENTS);
    let events: Vec<plugin_api::Event> = serde_json::from_str(
        &std::fs::read_to_string(&events_path)
            .with_context(|| events_path.display().to_string())?,
    )
    .with_context(|| events_path.display().to_string())?;
    let (loops, judged) = super::loops::judge(
        events,
        &gt,
        &eval::LoopCriteria::default(),
        online.as_ref().map(|(trajectory, _)| super::loops::Online {
            trajectory,
            map_from_estimate: &final_.transform,
        }),
    );
    super::worker::write_json(&events_path, &judged)?;
    let metrics = Metrics {
        alignment: alignment_name(alignment).to_owned(),
        ape: final_.stats,
        online_ape: online.map(|(_, stats)| stats),
        loops,
    };
    super::worker::write_json(&dir.join(files::METRICS), &metrics)?;
    write_results(
        dir,
        &gt,
        &estimate,
        &metrics.alignment,
        &final_.transform,
        &judged,
    )?;
    let estimate_xy = final_
        .pairs
        .estimate
        .iter()
        .map(|p| (p.translation.x, p.translation.y))
        .collect();
    Ok(Scored {
        metrics,
        estimate_xy,
    })
}

/// Writes `dir`'s results.mcap: the ground truth, the estimate and map.ply (if any) moved
/// into the ground truth's frame by `map_from_estimate` (the APE's alignment), and every
/// judged accepted loop.
fn write_results(
    dir: &Path,
    groundtruth: &Trajectory,
    estimate: &Trajectory,
    alignment: &str,
    map_from_estimate: &Sim3,
    judged: &[JudgedEvent],
) -> anyhow::Result<()> {
    let map_path = dir.join(files::MAP);
    let map_points = if map_path.exists() {
        Some(super::outputs::read_ply(&map_path)?)
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
        &dir.join(files::RESULTS),
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
