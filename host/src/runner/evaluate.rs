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
use sim::sensors::gnss::FixStatus;

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
        horizontal_rmse_m: Some(horizontal_rmse(&final_.pairs)),
        loops,
        alignment_transform: Some(Transform::from(&final_.transform)),
        sim3_scale,
        drift,
        joins: Some(joins.counts()),
        localization: localization(run, &gt, &options)?,
        gnss: gnss(run, &final_.pairs, &final_.errors)?,
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

/// The run's GNSS outages ([`crate::results::GnssMetrics`]) from its `gnss.csv`, with the
/// APE of the aligned `pairs` (`errors_m`); `None` without the file.
fn gnss(
    run: &RunFolder,
    pairs: &eval::PosePairs,
    errors_m: &[f64],
) -> anyhow::Result<Option<crate::results::GnssMetrics>> {
    let stamps_s = &pairs.stamps;
    let Some(named) = run.read_gnss()? else {
        return Ok(None);
    };
    let mut epochs = Vec::with_capacity(named.len());
    for (stamp_ns, name) in named {
        let Some(status) = FixStatus::from_name(&name) else {
            anyhow::bail!(
                "{}: {name:?} is not a fix status",
                run.path(files::GNSS).display()
            );
        };
        epochs.push((stamp_ns, status));
    }
    let Some(best) = epochs.iter().map(|e| e.1).max() else {
        return Ok(None);
    };
    let (start, end) = match (stamps_s.first(), stamps_s.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return Ok(None),
    };
    // Outages between good epochs, and before the first and after the last.
    let good: Vec<f64> = epochs
        .iter()
        .filter(|e| e.1 == best)
        .map(|e| e.0 as f64 * 1e-9)
        .collect();
    let mut bounds = vec![start];
    bounds.extend(&good);
    bounds.push(end.max(start));
    let (from, to) = bounds
        .windows(2)
        .map(|w| (w[0], w[1]))
        .max_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)))
        .unwrap_or((start, start));
    let worst = stamps_s
        .iter()
        .zip(errors_m)
        .filter(|(t, _)| (from..=to).contains(*t))
        .map(|(_, e)| *e)
        .max_by(f64::total_cmp);
    Ok(Some(crate::results::GnssMetrics {
        epochs: epochs.len() as u64,
        best_status: best.name().to_owned(),
        fraction_best: good.len() as f64 / epochs.len() as f64,
        longest_outage_start_s: from,
        longest_outage_s: to - from,
        worst_error_in_outage_m: worst,
    }))
}

/// The RMSE of the aligned positions' east and north errors alone, m
/// ([`Metrics::horizontal_rmse_m`]).
fn horizontal_rmse(pairs: &eval::PosePairs) -> f64 {
    let squares: f64 = pairs
        .reference
        .iter()
        .zip(&pairs.estimate)
        .map(|(r, e)| {
            (r.translation.vector - e.translation.vector)
                .xy()
                .norm_squared()
        })
        .sum();
    (squares / pairs.reference.len().max(1) as f64).sqrt()
}

/// A localisation run's judgement (`runner::localize`): its online poses and their statuses
/// against its ground truth, in the map's frame put in the world by the mapping run's own
/// alignment (the surveyed grid: the world's frame), judged against the mapping run's
/// estimate too, with the lanes of the run's world. `None` for a mapping run.
fn localization(
    run: &RunFolder,
    gt: &Trajectory,
    options: &ApeOptions,
) -> anyhow::Result<Option<crate::results::LocalizationMetrics>> {
    let Some((spec, map_bytes, load_s)) = super::localize::read_spec(run)? else {
        return Ok(None);
    };
    let online = run.read_online()?.unwrap_or(Trajectory {
        stamps: Vec::new(),
        poses: Vec::new(),
    });
    let statuses = super::localize::read_statuses(&run.path(files::POSE_STATUS))?;
    anyhow::ensure!(
        statuses.len() == online.len(),
        "{}: {} statuses for {} online poses",
        run.path(files::POSE_STATUS).display(),
        statuses.len(),
        online.len()
    );
    let localized = statuses
        .iter()
        .map(|(_, s)| *s == plugin_api::PoseStatus::Localized)
        .collect();
    let (world_from_map, reference) = match &spec.mapping_run {
        None => (Sim3::identity(), None),
        Some(dir) => {
            // A bench's localisation run names its mapping run relative to its own folder.
            let mapping = RunFolder::new(run.dir.join(dir));
            let transform = mapping
                .read_metrics()?
                .alignment_transform
                .with_context(|| {
                    format!(
                        "{}: the mapping run's metrics.json holds no alignment transform; evaluate it again",
                        dir.display()
                    )
                })?;
            let pairs = options
                .pairing
                .pair(&mapping.read_groundtruth()?, &mapping.read_estimate()?)?;
            (transform.to_sim3(), Some(pairs))
        }
    };
    let world = sim::SimConfig::load(Some(&run.path(files::WORLD)))?;
    let lanes = super::localize::lanes(&world.vineyard);
    let report = eval::evaluate_localization(
        gt,
        &eval::LocalizedTrajectory {
            trajectory: online,
            localized,
        },
        &world_from_map,
        reference.as_ref().map(|p| eval::MapReference {
            truth: &p.reference,
            estimate: &p.estimate,
        }),
        lanes.as_ref(),
        spec.kidnap.map(|k| k.at_s),
        &eval::LocalizationCriteria::default(),
    )
    .with_context(|| {
        format!(
            "judging the localisation of {}",
            run.path(files::ONLINE).display()
        )
    })?;
    Ok(Some(crate::results::LocalizationMetrics {
        report,
        map_bytes,
        load_s,
        carried_alignment: spec.mapping_run.is_some(),
    }))
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
