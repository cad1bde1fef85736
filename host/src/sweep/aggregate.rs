//! A sweep's aggregate ([`crate::results::aggregate::Aggregate`]) from the runs filed in its
//! folder.

use std::path::Path;

use super::{Cell, Sweep, read_filed, run_dir, value_text};
use crate::results::aggregate::{Aggregate, LocalizationSummary, Row, Speed, summarize};
use crate::results::{RunFolder, RunStatus};

/// Reads the runs of every cell of `sweep` from `out/runs`.
pub fn collect(sweep: &Sweep, out: &Path) -> anyhow::Result<Aggregate> {
    // Rows in cell order; cells differ only by seed within a row.
    let mut rows: Vec<(Row, Vec<&Cell>)> = Vec::new();
    for cell in &sweep.cells {
        let same =
            |r: &Row| r.scenario == cell.scenario && r.system == cell.label && r.axes == cell.point;
        match rows.iter_mut().find(|(r, _)| same(r)) {
            Some((_, cells)) => cells.push(cell),
            None => rows.push((
                Row {
                    scenario: cell.scenario.clone(),
                    system: cell.label.clone(),
                    axes: cell.point.clone(),
                    n_ok: 0,
                    n_failed: 0,
                    n_missing: 0,
                    ate_rmse_m: None,
                    loops_accepted: None,
                    loops_false: None,
                    wrong_joins: None,
                    false_join_runs: None,
                    sim3_scale: None,
                    drift_percent: None,
                    failures: Vec::new(),
                    speed: Speed::default(),
                    localization: None,
                },
                vec![cell],
            )),
        }
    }
    let mut out_rows = Vec::with_capacity(rows.len());
    let mut builds = std::collections::BTreeSet::new();
    for (mut row, cells) in rows {
        let (mut ate, mut accepted, mut false_, mut rtf, mut cpu, mut rss) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        let (mut joins, mut scale, mut drift) = (vec![], vec![], vec![]);
        // Runs judged for joins, and of those the ones with a false loop or a wrong join.
        let (mut judged, mut false_join) = (0, 0);
        let localizing = cells.iter().any(|c| c.localize.is_some());
        let mut reports = Vec::new();
        for cell in cells {
            let dir = run_dir(out, &cell.key);
            if !dir.exists() {
                row.n_missing += 1;
                continue;
            }
            let filed = read_filed(&dir)?;
            builds.insert(filed.build.clone());
            if let RunStatus::Failed(why) = RunStatus::from_text(&filed.status) {
                row.n_failed += 1;
                row.failures.push(format!("seed {}: {why}", cell.seed));
                continue;
            }
            let run = RunFolder::new(&dir);
            let metrics = run.read_metrics()?;
            row.n_ok += 1;
            if let Some(l) = metrics.localization {
                reports.push(l.report);
            }
            ate.push(metrics.ape.rmse);
            accepted.push(metrics.loops.accepted as f64);
            false_.push(metrics.loops.accepted_false as f64);
            if let Some(j) = metrics.joins {
                joins.push(j.wrong_joins as f64);
                judged += 1;
                false_join += usize::from(metrics.loops.accepted_false > 0 || j.wrong_joins > 0);
            }
            scale.extend(metrics.sim3_scale);
            drift.extend(metrics.drift.map(|d| d.translation_percent));
            // A run without its timing still counts for accuracy.
            if let Ok(Some(timing)) = run.read_timing() {
                rtf.push(timing.realtime_factor_plugin);
                cpu.extend(timing.cpu_s);
                rss.extend(timing.peak_rss_mb);
            }
        }
        row.ate_rmse_m = summarize(&ate);
        row.loops_accepted = summarize(&accepted);
        row.loops_false = summarize(&false_);
        row.wrong_joins = summarize(&joins);
        row.false_join_runs = eval::Rate::wilson(false_join, judged);
        row.sim3_scale = summarize(&scale);
        row.drift_percent = summarize(&drift);
        row.localization =
            localizing.then(|| LocalizationSummary::of(&reports.iter().collect::<Vec<_>>()));
        row.speed = Speed {
            realtime_factor: summarize(&rtf),
            cpu_s: summarize(&cpu),
            peak_rss_mb: summarize(&rss),
        };
        out_rows.push(row);
    }
    let mut systems: Vec<String> = Vec::new();
    for c in &sweep.cells {
        if !systems.contains(&c.label) {
            systems.push(c.label.clone());
        }
    }
    Ok(Aggregate {
        scenarios: sweep.cfg.scenarios.clone(),
        systems,
        seeds: sweep.seeds.clone(),
        axes: sweep
            .axes
            .iter()
            .map(|a| (a.path.clone(), a.values.iter().map(value_text).collect()))
            .collect(),
        rows: out_rows,
        builds: builds.into_iter().collect(),
    })
}
