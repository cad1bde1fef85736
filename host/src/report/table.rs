//! The format-independent table: ordered columns (one per run), the statistic rows and
//! the failures, shared by every renderer.

use super::{RunRecord, RunStatus};

/// A field of the APE statistics.
type Field = fn(&eval::Statistics) -> f64;

/// The statistic rows of the paper's Table 2, in its order, and the minimum (a row of the
/// paper's table source, commented out there): label and field.
const STATISTICS: [(&str, Field); 6] = [
    ("max", |s| s.max),
    ("mean", |s| s.mean),
    ("median", |s| s.median),
    ("rmse", |s| s.rmse),
    ("std", |s| s.std),
    ("min", |s| s.min),
];
/// Decimals of the statistic rows (metres: millimetre resolution, as in the paper).
const STATISTIC_DECIMALS: usize = 3;
/// Label and decimals of the real-time factor row.
const RTF_LABEL: &str = "RTF";
const RTF_DECIMALS: usize = 1;
/// Labels of the loop-closure rows: accepted, and of those the false ones (judged against
/// ground truth); counts, no decimals.
const LOOPS_LABEL: &str = "loops";
const FALSE_LOOPS_LABEL: &str = "false loops";
/// Label of the final map's wrong joins (`eval::wrong_joins`: whatever the system
/// reported), and of those no accepted loop explains; counts.
const WRONG_JOINS_LABEL: &str = "wrong joins";
const SILENT_JOINS_LABEL: &str = "silent joins";
/// Label and decimals of the Sim(3) scale row and the drift row (percent of the distance
/// travelled over 5–20 m segments).
const SCALE_LABEL: &str = "scale";
const SCALE_DECIMALS: usize = 3;
const DRIFT_LABEL: &str = "drift %";
const DRIFT_DECIMALS: usize = 2;
/// Labels of a localisation run's rows (`vinebench localize`), shown when a column is one:
/// whether it localised within 10 m, seconds to the first correct pose, percent of the time
/// localised, ATE (RMSE, m) of the localised poses in the map frame without re-alignment,
/// and seconds of false localisation (against the truth, against the map) and in a wrong
/// lane.
const LOCALIZATION_ROWS: [(&str, usize); 7] = [
    ("localised", 0),
    ("to localise s", 1),
    ("localised %", 0),
    ("ATE in map", 3),
    ("false s", 1),
    ("false vs map s", 1),
    ("wrong lane s", 1),
];
/// Labels of the reference's rows, in [`super::reference::STATISTICS`] order (the paper
/// prints centimetres: two decimals).
const PAPER_LABELS: [&str; 5] = [
    "paper max",
    "paper mean",
    "paper median",
    "paper rmse",
    "paper std",
];
/// The error-statistic rows come first in [`Table::rows`]; the others (RTF, loops) after.
pub(super) const ERROR_ROWS: usize = STATISTICS.len();

/// One column: the run of one plugin on one scenario.
#[derive(Debug)]
pub(super) struct Column<'a> {
    pub(super) run: &'a RunRecord,
    /// Position of the plugin in the plugin order (its colour in the plots).
    pub(super) plugin_index: usize,
    /// The failure reason on one line; `None` for an ok run.
    pub(super) failure: Option<String>,
}

/// One table cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Cell {
    Value(f64),
    Failed,
    /// The run is ok but the value is missing or not finite.
    Missing,
    /// Nothing to show (a reference row where the paper has no figure).
    Blank,
}

/// One row of cells, one per column.
#[derive(Debug)]
pub(super) struct Row {
    pub(super) label: &'static str,
    pub(super) cells: Vec<Cell>,
    decimals: usize,
}

impl Row {
    /// The text of cell `i`: the value with the row's fixed decimals, `failed` or `n/a`.
    pub(super) fn text(&self, i: usize) -> String {
        match self.cells[i] {
            Cell::Value(v) => format!("{v:.prec$}", prec = self.decimals),
            Cell::Failed => "failed".to_owned(),
            Cell::Missing => "n/a".to_owned(),
            Cell::Blank => String::new(),
        }
    }
}

/// The runs in column order: scenario by scenario, each with its systems in plugin order.
#[derive(Debug)]
pub(super) struct Table<'a> {
    /// All scenarios in order, including those without runs.
    pub(super) scenarios: Vec<&'a str>,
    pub(super) columns: Vec<Column<'a>>,
    /// Published figures to show beside the runs' (rows `paper max` ..).
    pub(super) reference: Option<&'a super::reference::Reference>,
}

/// `given` followed by the names of `extra` not in it yet, in order of first appearance.
fn ordered<'a>(given: &'a [String], extra: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut names: Vec<&str> = Vec::new();
    for name in given.iter().map(String::as_str).chain(extra) {
        if !names.contains(&name) {
            names.push(name);
        }
    }
    names
}

/// `text` on one line with single spaces; a placeholder if it is blank.
fn one_line(text: &str) -> String {
    let line = text.split_whitespace().collect::<Vec<_>>().join(" ");
    if line.is_empty() {
        "no reason given".to_owned()
    } else {
        line
    }
}

impl<'a> Table<'a> {
    /// Orders `runs` into columns; errors if two runs share a scenario and plugin.
    pub(super) fn new(
        scenarios: &'a [String],
        plugins: &'a [String],
        runs: &'a [RunRecord],
    ) -> anyhow::Result<Self> {
        let scenarios = ordered(scenarios, runs.iter().map(|r| r.scenario.as_str()));
        let plugins = ordered(plugins, runs.iter().map(|r| r.plugin.as_str()));
        let mut columns = Vec::with_capacity(runs.len());
        for &scenario in &scenarios {
            for (plugin_index, &plugin) in plugins.iter().enumerate() {
                let mut matching = runs
                    .iter()
                    .filter(|r| r.scenario == scenario && r.plugin == plugin);
                let Some(run) = matching.next() else {
                    continue;
                };
                anyhow::ensure!(
                    matching.next().is_none(),
                    "two runs of plugin {plugin:?} on scenario {scenario:?}: expected one run per pair"
                );
                let failure = match &run.status {
                    RunStatus::Ok => None,
                    RunStatus::Failed(reason) => Some(one_line(reason)),
                };
                columns.push(Column {
                    run,
                    plugin_index,
                    failure,
                });
            }
        }
        Ok(Self {
            scenarios,
            columns,
            reference: None,
        })
    }

    /// The same table with the published figures of `reference` as extra rows.
    pub(super) fn with_reference(
        mut self,
        reference: Option<&'a super::reference::Reference>,
    ) -> Self {
        self.reference = reference;
        self
    }

    /// The scenarios that have columns, each with the range of its columns.
    pub(super) fn groups(&self) -> Vec<(&'a str, std::ops::Range<usize>)> {
        let mut groups: Vec<(&str, std::ops::Range<usize>)> = Vec::new();
        for (i, column) in self.columns.iter().enumerate() {
            match groups.last_mut() {
                Some((scenario, range)) if *scenario == column.run.scenario => range.end = i + 1,
                _ => groups.push((column.run.scenario.as_str(), i..i + 1)),
            }
        }
        groups
    }

    /// The columns of `scenario`.
    pub(super) fn columns_of<'t>(
        &'t self,
        scenario: &'t str,
    ) -> impl Iterator<Item = &'t Column<'a>> + 't {
        self.columns
            .iter()
            .filter(move |c| c.run.scenario == scenario)
    }

    /// The rows `max`, `mean`, `median`, `rmse`, `std`, `min`, `scale`, `drift %`, `RTF`,
    /// `loops`, `false loops`, `wrong joins` and `silent joins`.
    pub(super) fn rows(&self) -> Vec<Row> {
        let cell = |column: &Column, value: Option<f64>| match (&column.failure, value) {
            (Some(_), _) => Cell::Failed,
            (None, Some(v)) if v.is_finite() => Cell::Value(v),
            (None, _) => Cell::Missing,
        };
        let mut rows: Vec<Row> = STATISTICS
            .iter()
            .map(|&(label, field)| Row {
                label,
                cells: self
                    .columns
                    .iter()
                    .map(|c| cell(c, c.run.ape.as_ref().map(field)))
                    .collect(),
                decimals: STATISTIC_DECIMALS,
            })
            .collect();
        rows.push(Row {
            label: SCALE_LABEL,
            cells: self
                .columns
                .iter()
                .map(|c| cell(c, c.run.sim3_scale))
                .collect(),
            decimals: SCALE_DECIMALS,
        });
        rows.push(Row {
            label: DRIFT_LABEL,
            cells: self
                .columns
                .iter()
                .map(|c| cell(c, c.run.drift_percent))
                .collect(),
            decimals: DRIFT_DECIMALS,
        });
        rows.push(Row {
            label: RTF_LABEL,
            cells: self
                .columns
                .iter()
                .map(|c| cell(c, c.run.realtime_factor))
                .collect(),
            decimals: RTF_DECIMALS,
        });
        type Count = fn(&eval::LoopCounts) -> usize;
        let counts: [(&'static str, Count); 2] = [
            (LOOPS_LABEL, |l| l.accepted),
            (FALSE_LOOPS_LABEL, |l| l.accepted_false),
        ];
        for (label, count) in counts {
            rows.push(Row {
                label,
                cells: self
                    .columns
                    .iter()
                    .map(|c| cell(c, c.run.loops.as_ref().map(|l| count(l) as f64)))
                    .collect(),
                decimals: 0,
            });
        }
        type JoinCount = fn(&crate::results::JoinCounts) -> usize;
        let joins: [(&'static str, JoinCount); 2] = [
            (WRONG_JOINS_LABEL, |j| j.wrong_joins),
            (SILENT_JOINS_LABEL, |j| j.silent),
        ];
        for (label, count) in joins {
            rows.push(Row {
                label,
                cells: self
                    .columns
                    .iter()
                    .map(|c| cell(c, c.run.joins.as_ref().map(|j| count(j) as f64)))
                    .collect(),
                decimals: 0,
            });
        }
        if self.columns.iter().any(|c| c.run.localization.is_some()) {
            for (k, &(label, decimals)) in LOCALIZATION_ROWS.iter().enumerate() {
                rows.push(Row {
                    label,
                    cells: self
                        .columns
                        .iter()
                        .map(|c| {
                            let Some(l) = &c.run.localization else {
                                return cell(c, None);
                            };
                            let r = &l.report;
                            cell(
                                c,
                                match k {
                                    0 => Some(f64::from(u8::from(r.success))),
                                    1 => r.first_correct_s,
                                    2 => Some(100.0 * r.localized_fraction),
                                    3 => r.ate_map_frame.as_ref().map(|s| s.rmse),
                                    4 => Some(r.false_vs_truth_s),
                                    5 => Some(r.false_vs_map_s),
                                    _ => Some(r.wrong_lane_s),
                                },
                            )
                        })
                        .collect(),
                    decimals,
                });
            }
        }
        if let Some(reference) = self.reference {
            for (k, label) in PAPER_LABELS.into_iter().enumerate() {
                rows.push(Row {
                    label,
                    cells: self
                        .columns
                        .iter()
                        .map(|c| {
                            reference
                                .get(&c.run.scenario, &c.run.plugin)
                                .map_or(Cell::Blank, |v| Cell::Value(v[k]))
                        })
                        .collect(),
                    decimals: 2,
                });
            }
        }
        rows
    }

    /// The ok runs with accepted loops that could not be judged: (scenario, plugin, how
    /// many).
    pub(super) fn unjudged_loops(&self) -> impl Iterator<Item = (&'a str, &'a str, usize)> {
        self.columns.iter().filter_map(|c| {
            c.run
                .loops
                .filter(|l| l.unjudged > 0)
                .map(|l| (c.run.scenario.as_str(), c.run.plugin.as_str(), l.unjudged))
        })
    }

    /// The line saying the routes were cut short (`max_time_s`; a bench has one limit for
    /// all its runs), so nobody takes the table for the paper's; `None` when every route
    /// ran whole.
    pub(super) fn cut_note(&self) -> Option<String> {
        let max = self.columns.iter().find_map(|c| c.run.max_time_s)?;
        Some(format!(
            "Routes cut at {max} s of simulated time (max_time_s): every run covers its route \
             up to there only. This is not the paper's table, which runs the full routes."
        ))
    }

    /// The failed runs in column order: (scenario, plugin, reason on one line).
    pub(super) fn failures(&self) -> impl Iterator<Item = (&'a str, &'a str, &str)> {
        self.columns.iter().filter_map(|c| {
            c.failure
                .as_deref()
                .map(|reason| (c.run.scenario.as_str(), c.run.plugin.as_str(), reason))
        })
    }
}
