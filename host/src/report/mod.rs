//! Benchmark reports: the paper's Table 2 (APE translation statistics per scenario and
//! system, Hroob et al. 2021) as Markdown, CSV, LaTeX and JSON, and one top-view overlay
//! plot per scenario.
//!
//! [`write_reports`] is the entry point. Every file it writes is a pure function of its
//! inputs (no timestamps, stable order, fixed float formatting), so identical runs give
//! byte-identical reports. One file per output format:
//! - `table.rs`: the format-independent table (columns, rows, cells, failures);
//! - `markdown.rs`, `csv.rs`, `latex.rs`, `json.rs`: the renderers;
//! - `plot.rs`: the overlay plots (PNG and SVG);
//! - `html.rs` (with `load.rs`, which reads a results folder back, and `figures.rs`):
//!   `report.html`, built from the results folder alone, so `vinebench report DIR`
//!   rebuilds exactly what the bench wrote;
//! - `sweep.rs`: a sweep's files from its aggregate.
//!
//! The commands call it ([`write_bench`], [`sweep::write`]) once the runs are in their
//! folders; it reads them through [`crate::results`] and runs nothing.

mod csv;
pub mod figures;
pub mod html;
mod json;
mod latex;
pub mod load;
mod markdown;
pub mod plot;
pub mod reference;
pub mod sweep;
mod table;
#[cfg(test)]
mod tests;

use std::path::Path;

use anyhow::Context as _;

use table::Table;

pub use crate::results::RunStatus;

/// Everything the report needs about one run.
#[derive(Debug, Clone)]
pub struct RunRecord {
    /// Scenario name: `"s0"`..`"s3"` or a user scenario name.
    pub scenario: String,
    /// Column label of the system, e.g. `"wheel-odometry"`.
    pub plugin: String,
    /// How the run ended.
    pub status: RunStatus,
    /// APE translation statistics (metres) of the final trajectory after alignment;
    /// `None` when failed.
    pub ape: Option<eval::Statistics>,
    /// Simulated seconds per wall second of the run (sim + plugin); `None` when failed.
    pub realtime_factor: Option<f64>,
    /// The run's loop closures as judged against ground truth; `None` when failed.
    pub loops: Option<eval::LoopCounts>,
    /// The final map's wrong joins and revisits; `None` when failed or evaluated before
    /// they were counted.
    pub joins: Option<crate::results::JoinCounts>,
    /// The scale of a Sim(3) alignment of the final trajectory; `None` as `joins`.
    pub sim3_scale: Option<f64>,
    /// Translation drift over the route's 5–20 m segments, percent (metres per 100 m);
    /// `None` as `joins`, or on a route shorter than 5 m.
    pub drift_percent: Option<f64>,
    /// Top view (x, y) of the aligned final estimate, for the overlay plot; empty when
    /// failed.
    pub estimate_xy: Vec<(f64, f64)>,
    /// The route was cut at this simulated time, seconds (`--max-time`); `None`: the whole
    /// route, as the paper ran it.
    pub max_time_s: Option<f64>,
    /// A localisation run's judgement (`vinebench localize`); `None` for a mapping run.
    pub localization: Option<crate::results::LocalizationMetrics>,
}

/// Ground truth (x, y) per scenario for the overlay plots.
#[derive(Debug, Clone)]
pub struct ScenarioTruth {
    /// Scenario name, as in [`RunRecord::scenario`].
    pub scenario: String,
    /// Top view of the ground-truth trajectory.
    pub groundtruth_xy: Vec<(f64, f64)>,
}

/// Writes the reports of a benchmark into `dir` (created if needed) and returns the
/// Markdown table (the content of `table.md`) for the caller to print.
///
/// Files:
/// - `table.md`, `table.csv`, `table.tex`: the paper's Table 2 layout. Rows `max`, `mean`,
///   `median`, `rmse`, `std`, `min` (metres, 3 decimals), `scale` (of a Sim(3) alignment, 3
///   decimals), `drift %` (metres per 100 m over 5–20 m segments, 2 decimals), `RTF` (the
///   system's real-time factor: simulated seconds per
///   second spent in its calls, `finish` included, so the same whether or not its
///   simulation was shared; 1 decimal), `loops` (loop closures accepted), `false loops` (of
///   those, the ones ground truth shows false: a measured relative pose off by more than
///   0.5 m or 10°, or without one, joining poses more than 1 m apart; without stamps, a
///   wrong join of the final map shortly before), `wrong joins` (the final map's, whatever
///   the system reported: `eval::wrong_joins`) and `silent joins` (of those, the ones no
///   accepted loop explains); one column per
///   (scenario, plugin) run, all systems of the first
///   scenario, then of the next, under a two-level header (scenario, then system). A
///   failed run shows `failed` in its cells and its reason below the table (Markdown: a
///   "Failed runs" list; LaTeX: a footnote line; CSV: a last `status` row). A value that
///   is missing although the run is ok shows `n/a`. Accepted loops that could not be
///   judged (no stamps) are listed below the Markdown table. When the routes were cut
///   (`max_time_s`), a line below the Markdown table and the LaTeX table says so: such a
///   table is not the paper's.
/// - `table.json`: `{"<scenario>": {"<plugin>": {"status": "ok" | "failed: <reason>",
///   "rmse", "mean", "median", "max", "min", "std", "realtime_factor", "loops_accepted",
///   "loops_false"}}}` with full f64 precision (and `"loops_unjudged"` when not zero); a
///   failed run has only `status` (see `json.rs`). A run on a cut route also has
///   `"max_time_s"`.
/// - `plots/<scenario>.png` and `.svg`: ground truth in black under every ok system's
///   aligned estimate in the system's colour, and a legend below the plot (colour
///   swatches in the PNG, which has no font; swatches and names in the SVG). File names
///   keep ASCII letters, digits, `.`, `-` and `_` of the scenario name; any other
///   character becomes `_`.
///
/// With `reference` (the published table the bench reproduces), rows `paper max` ..
/// `paper std` follow: each column's published figures, blank where it has none.
///
/// Column order: `scenarios` and `plugins` as given, then any scenario or plugin that
/// only appears in `runs`, in order of first appearance. A (scenario, plugin) pair
/// without a run has no column. A plugin keeps its colour (by position in that order)
/// across all plots. Truths of scenarios without a plot are ignored.
///
/// Errors if two runs share a scenario and plugin, if two scenario names map to the same
/// plot file name, or if a file cannot be written (the error names the file).
pub fn write_reports(
    dir: &Path,
    scenarios: &[String],
    plugins: &[String],
    runs: &[RunRecord],
    truths: &[ScenarioTruth],
    reference: Option<&reference::Reference>,
) -> anyhow::Result<String> {
    let table = Table::new(scenarios, plugins, runs)?.with_reference(reference);
    write_tables(dir, &table, truths)
}

/// Writes the tables and plots of `table` into `dir`; returns `table.md`'s text.
fn write_tables(dir: &Path, table: &Table, truths: &[ScenarioTruth]) -> anyhow::Result<String> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the results folder {}", dir.display()))?;
    let markdown = markdown::render(table);
    write_file(&dir.join("table.md"), &markdown)?;
    write_file(&dir.join("table.csv"), &csv::render(table))?;
    write_file(&dir.join("table.tex"), &latex::render(table))?;
    write_file(&dir.join("table.json"), &json::render(table)?)?;
    plot::write_plots(&dir.join("plots"), table, truths)?;
    Ok(markdown)
}

/// Writes every report of a bench whose runs are in `dir` (`dir/<scenario>/<label>`, each
/// as `index` lists it; `paper.csv` in `dir` if the bench reproduces a published table):
/// the tables and plots of [`write_reports`] and `report.html` (titled `name`), all from
/// the runs' folders. Returns the table for a terminal: one block per scenario.
///
/// The plots' ground truth is the scenario's first finished run's `groundtruth.tum`, drawn
/// as the page draws it.
pub fn write_bench(
    dir: &Path,
    name: &str,
    scenarios: &[String],
    labels: &[String],
    index: &[load::IndexedRun],
) -> anyhow::Result<String> {
    let results = load::BenchResults::read(dir, scenarios.to_vec(), labels.to_vec(), index)?;
    let reference = reference::Reference::in_folder(dir)?;
    let records: Vec<RunRecord> = results.runs.iter().map(|r| r.record.clone()).collect();
    let truths: Vec<ScenarioTruth> = scenarios
        .iter()
        .filter_map(|s| {
            let detail = results
                .runs
                .iter()
                .filter(|r| &r.record.scenario == s)
                .find_map(|r| r.detail.as_ref())?;
            Some(ScenarioTruth {
                scenario: s.clone(),
                groundtruth_xy: figures::decimate(&detail.groundtruth_xy, figures::MAX_LINE_POINTS),
            })
        })
        .collect();
    let table = Table::new(scenarios, labels, &records)?.with_reference(reference.as_ref());
    write_tables(dir, &table, &truths)?;
    html::write_page(dir, &html::bench_page(&results, name)?)?;
    Ok(markdown::render_blocks(&table))
}

/// Rebuilds `report.html` of the results folder `dir`, a bench's or a sweep's (which has
/// the sweep marker); returns its path and size in bytes.
pub fn rebuild_html(dir: &Path) -> anyhow::Result<(std::path::PathBuf, u64)> {
    anyhow::ensure!(dir.is_dir(), "{}: no such results folder", dir.display());
    let bytes = if crate::results::is_sweep_folder(dir) {
        html::write_sweep_report(dir, &sweep::read(dir)?)?
    } else {
        let name = dir
            .canonicalize()
            .ok()
            .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| dir.display().to_string());
        html::write_bench_report(dir, &name)?
    };
    Ok((dir.join(html::REPORT), bytes))
}

fn write_file(path: &Path, contents: &str) -> anyhow::Result<()> {
    std::fs::write(path, contents).with_context(|| format!("writing {}", path.display()))
}
