//! A sweep's aggregate (`sweep.json`): per cell without the seed (scenario, system, point of
//! the axes), the number of runs ok / failed / missing and mean ± std, min, max and the 95 %
//! interval of the mean of ATE RMSE, accepted and false loops, wrong joins, Sim(3) scale and
//! drift; the share of runs with a false loop or wrong join with its Wilson interval; and
//! (kept apart, as they depend on the machine) real-time
//! factor, CPU time and peak memory. `sweep::aggregate::collect` makes it from the runs'
//! folders; `report::sweep` writes and reads its files.
//!
//! Standard deviations are the sample's (n − 1 in the denominator), absent for n < 2.

use serde::{Deserialize, Serialize};

/// mean ± std, min, max of some numbers, and the 95 % t interval of the mean.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub mean: f64,
    pub std: Option<f64>,
    pub min: f64,
    pub max: f64,
    /// `eval::mean_interval95`: absent for n < 2 (and in aggregates written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval95: Option<[f64; 2]>,
}

/// The summary of `xs` (in the given order, so sums are reproducible); `None` if empty.
pub fn summarize(xs: &[f64]) -> Option<Summary> {
    if xs.is_empty() {
        return None;
    }
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let std = (xs.len() > 1)
        .then(|| (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt());
    Some(Summary {
        mean,
        std,
        min: xs.iter().copied().fold(f64::INFINITY, f64::min),
        max: xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        interval95: eval::mean_interval95(xs),
    })
}

/// One row of the aggregate.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Row {
    pub scenario: String,
    pub system: String,
    /// The value of every axis, as TOML text, in axis order.
    pub axes: Vec<(String, String)>,
    pub n_ok: usize,
    pub n_failed: usize,
    /// Runs not (yet) in `runs/`.
    pub n_missing: usize,
    pub ate_rmse_m: Option<Summary>,
    pub loops_accepted: Option<Summary>,
    pub loops_false: Option<Summary>,
    /// The final map's wrong joins per run (runs evaluated before they were counted left
    /// out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrong_joins: Option<Summary>,
    /// The ok runs with a false loop or a wrong join, of those judged for both: the rate
    /// and its 95 % Wilson interval.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub false_join_runs: Option<eval::Rate>,
    /// The Sim(3) scale and the drift (metres per 100 m) per run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sim3_scale: Option<Summary>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift_percent: Option<Summary>,
    /// `seed: reason` of each failed run.
    pub failures: Vec<String>,
    #[serde(skip)]
    pub speed: Speed,
    /// A row of localisation runs (`[[localize]]`): their judgement over the seeds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub localization: Option<LocalizationSummary>,
}

/// A localisation row over its ok runs (issue 46; `eval::LocalizationReport` per run).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LocalizationSummary {
    /// Runs whose first correct pose came within 10 m of travel, of the ok runs, with the
    /// rate's 95 % Wilson interval.
    pub success: Option<eval::Rate>,
    /// Seconds to the first pose flagged localised, over the runs that had one.
    pub first_localized_s: Option<Summary>,
    /// Share of the run's time flagged localised.
    pub localized_fraction: Option<Summary>,
    /// RMSE of the localised poses' error in the map frame, not re-aligned, metres, over the
    /// runs with a localised pose.
    pub ate_map_frame_m: Option<Summary>,
    /// False localisations per run (episodes), judged against the map and against the
    /// truth.
    pub false_vs_map: Option<Summary>,
    pub false_vs_truth: Option<Summary>,
    /// Seconds localised in another lane than the truth's, per run.
    pub wrong_lane_s: Option<Summary>,
    /// After a kidnapping: seconds to the first correct pose, over the runs that had one.
    pub relocalized_after_s: Option<Summary>,
}

impl LocalizationSummary {
    /// The summary of these runs' reports.
    pub fn of(reports: &[&eval::LocalizationReport]) -> Self {
        let each = |f: &dyn Fn(&eval::LocalizationReport) -> Option<f64>| -> Option<Summary> {
            summarize(&reports.iter().filter_map(|r| f(r)).collect::<Vec<_>>())
        };
        Self {
            success: eval::Rate::wilson(
                reports.iter().filter(|r| r.success).count(),
                reports.len(),
            ),
            first_localized_s: each(&|r| r.first_localized_s),
            localized_fraction: each(&|r| Some(r.localized_fraction)),
            ate_map_frame_m: each(&|r| r.ate_map_frame.as_ref().map(|s| s.rmse)),
            false_vs_map: each(&|r| Some(r.false_vs_map.len() as f64)),
            false_vs_truth: each(&|r| Some(r.false_vs_truth.len() as f64)),
            wrong_lane_s: each(&|r| Some(r.wrong_lane_s)),
            relocalized_after_s: each(&|r| r.relocalized_after_s),
        }
    }
}

/// What depends on the machine: kept out of `sweep.json` and `sweep.csv`.
#[derive(Debug, Clone, Default)]
pub struct Speed {
    pub realtime_factor: Option<Summary>,
    pub cpu_s: Option<Summary>,
    pub peak_rss_mb: Option<Summary>,
}

/// The aggregate of a sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Aggregate {
    pub scenarios: Vec<String>,
    pub systems: Vec<String>,
    pub seeds: Vec<u64>,
    /// Every axis with its values as TOML text.
    pub axes: Vec<(String, Vec<String>)>,
    pub rows: Vec<Row>,
    /// Hashes of the `vinebench` builds that made the runs found, sorted.
    pub builds: Vec<String>,
}

impl Aggregate {
    /// The rows of mapping runs on `scenario` (not localisation runs).
    pub fn mapping_rows<'a>(&'a self, scenario: &'a str) -> impl Iterator<Item = &'a Row> + 'a {
        self.rows
            .iter()
            .filter(move |r| r.scenario == scenario && r.localization.is_none())
    }

    /// Runs not in `runs/` yet, over all rows.
    pub fn missing(&self) -> usize {
        self.rows.iter().map(|r| r.n_missing).sum()
    }

    /// Runs that failed, over all rows.
    pub fn failed(&self) -> usize {
        self.rows.iter().map(|r| r.n_failed).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summaries_use_the_sample_deviation() {
        let s = summarize(&[1.0, 2.0, 3.0, 4.0]).expect("four numbers");
        assert_eq!(s.mean, 2.5);
        assert!((s.std.expect("n > 1") - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!((s.min, s.max), (1.0, 4.0));
        assert_eq!(s.interval95, eval::mean_interval95(&[1.0, 2.0, 3.0, 4.0]));
        let one = summarize(&[0.7]).expect("one number");
        assert_eq!((one.mean, one.std, one.min, one.max), (0.7, None, 0.7, 0.7));
        assert_eq!(one.interval95, None);
        assert_eq!(summarize(&[]), None);
    }
}
