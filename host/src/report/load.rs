//! Reads a bench's results folder back: `table.json` (the column order, each run's status
//! and real-time factor) and every run's folder (`metrics.json`, the trajectories, the
//! judged loops of `events.json`, `timing.json`, `run.toml`). `vinebench report DIR` and
//! the bench itself build the HTML report from this, so a rebuilt report is the bench's.

use std::fmt;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use eval::{ApeOptions, LoopCounts, Statistics};
use serde::Deserialize;
use serde::de::{Deserializer, MapAccess, Visitor};

use super::plot::LoopSegment;
use super::{RunRecord, RunStatus};
use crate::runner::files;

/// A JSON object's entries in file order (serde_json's map sorts its keys).
struct Ordered<T>(Vec<(String, T)>);

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Ordered<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for V<T> {
            type Value = Ordered<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry()? {
                    entries.push(entry);
                }
                Ok(Ordered(entries))
            }
        }
        d.deserialize_map(V(PhantomData))
    }
}

/// The part of a `table.json` entry the report needs.
#[derive(Deserialize)]
struct TableEntry {
    status: String,
    realtime_factor: Option<f64>,
    max_time_s: Option<f64>,
}

/// `metrics.json`, as `runner::evaluate` writes it.
#[derive(Deserialize)]
struct MetricsFile {
    alignment: String,
    ape: Statistics,
    loops: LoopCounts,
}

/// The judged events of `events.json` the report draws: accepted loops.
#[derive(Deserialize)]
struct EventEntry {
    stamp_ns: u64,
    kind: String,
    #[serde(default)]
    detail: String,
    loop_stamps_ns: Option<[u64; 2]>,
    true_loop: Option<bool>,
    gt_distance_m: Option<f64>,
}

/// One accepted loop closure as the report lists it.
#[derive(Debug, Clone)]
pub struct AcceptedLoop {
    pub stamp_ns: u64,
    pub detail: String,
    /// The two stamps it joins, if the event carried them.
    pub stamps_ns: Option<[u64; 2]>,
    /// Ground truth's judgement; `None`: not judged.
    pub true_loop: Option<bool>,
    pub gt_distance_m: Option<f64>,
    /// The segment on the aligned estimate, when the stamps lie on it.
    pub segment: Option<LoopSegment>,
}

/// `timing.json`'s latency of one kind of call.
#[derive(Debug, Clone, Deserialize)]
pub struct Latency {
    pub calls: u64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub total_s: f64,
}

/// `timing.json`.
#[derive(Debug, Clone, Deserialize)]
pub struct Timing {
    pub source: Option<String>,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub plugin_s: Option<f64>,
    pub cpu_s: Option<f64>,
    pub peak_rss_mb: Option<f64>,
    pub realtime_factor: Option<f64>,
    pub realtime_factor_plugin: Option<f64>,
    /// Per kind of call (sensor, `finish`), in name order.
    #[serde(default)]
    pub latency: std::collections::BTreeMap<String, Latency>,
}

/// What an ok run's folder holds beyond the table's numbers.
#[derive(Debug, Clone)]
pub struct RunDetail {
    pub alignment: String,
    /// Ground truth's top view.
    pub groundtruth_xy: Vec<(f64, f64)>,
    /// The estimate's top view in its own map frame (the frame of `map.ply`).
    pub estimate_raw_xy: Vec<(f64, f64)>,
    /// Stamps of the associated pairs, seconds, and the APE translation of each.
    pub stamps_s: Vec<f64>,
    pub errors_m: Vec<f64>,
    pub loops: Vec<AcceptedLoop>,
}

/// One run of the bench.
#[derive(Debug, Clone)]
pub struct LoadedRun {
    /// The table's view of the run (its `estimate_xy` aligned).
    pub record: RunRecord,
    pub dir: PathBuf,
    /// For ok runs.
    pub detail: Option<RunDetail>,
    pub timing: Option<Timing>,
    /// The resolved `run.toml`, if written.
    pub run_toml: Option<String>,
}

/// A bench's results folder read back.
#[derive(Debug, Clone)]
pub struct BenchResults {
    pub dir: PathBuf,
    pub scenarios: Vec<String>,
    pub plugins: Vec<String>,
    pub runs: Vec<LoadedRun>,
}

impl BenchResults {
    /// Reads `dir/table.json` and the folder of every run it lists.
    pub fn load(dir: &Path) -> anyhow::Result<Self> {
        let table_path = dir.join("table.json");
        let text = std::fs::read_to_string(&table_path).with_context(|| {
            format!(
                "{}: cannot read (not a bench results folder?)",
                table_path.display()
            )
        })?;
        let table: Ordered<Ordered<TableEntry>> = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a vinebench table", table_path.display()))?;
        let (mut scenarios, mut plugins, mut runs) = (Vec::new(), Vec::new(), Vec::new());
        for (scenario, entries) in table.0 {
            for (plugin, entry) in entries.0 {
                if !plugins.contains(&plugin) {
                    plugins.push(plugin.clone());
                }
                let run_dir = dir.join(&scenario).join(&plugin);
                runs.push(
                    load_run(&scenario, &plugin, &entry, &run_dir)
                        .with_context(|| format!("reading the run {}", run_dir.display()))?,
                );
            }
            scenarios.push(scenario);
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            scenarios,
            plugins,
            runs,
        })
    }
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> anyhow::Result<T> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: malformed", path.display()))
}

fn load_run(
    scenario: &str,
    plugin: &str,
    entry: &TableEntry,
    dir: &Path,
) -> anyhow::Result<LoadedRun> {
    let timing = dir
        .join(files::TIMING)
        .exists()
        .then(|| read_json::<Timing>(&dir.join(files::TIMING)))
        .transpose()?;
    let run_toml = std::fs::read_to_string(dir.join(files::RUN)).ok();
    let mut record = RunRecord {
        scenario: scenario.to_owned(),
        plugin: plugin.to_owned(),
        status: RunStatus::Ok,
        ape: None,
        realtime_factor: entry.realtime_factor,
        loops: None,
        estimate_xy: Vec::new(),
        max_time_s: entry.max_time_s,
    };
    if entry.status != "ok" {
        let reason = entry
            .status
            .strip_prefix("failed: ")
            .unwrap_or(&entry.status);
        record.status = RunStatus::Failed(reason.to_owned());
        return Ok(LoadedRun {
            record,
            dir: dir.to_path_buf(),
            detail: None,
            timing,
            run_toml,
        });
    }
    let metrics: MetricsFile = read_json(&dir.join(files::METRICS))?;
    let alignment = crate::runner::alignment_from_name(&metrics.alignment).with_context(|| {
        format!(
            "{}: unknown alignment {:?}",
            dir.join(files::METRICS).display(),
            metrics.alignment
        )
    })?;
    let gt = eval::read_tum(dir.join(files::GROUNDTRUTH))?;
    let estimate = eval::read_tum(dir.join(files::ESTIMATE))?;
    let ape = eval::evaluate_ape(
        &gt,
        &estimate,
        &ApeOptions {
            alignment,
            ..ApeOptions::default()
        },
    )
    .with_context(|| format!("evaluating {}", dir.join(files::ESTIMATE).display()))?;
    let xy = |p: &nalgebra::Isometry3<f64>| (p.translation.x, p.translation.y);
    let aligned: Vec<(f64, f64)> = ape.pairs.estimate.iter().map(xy).collect();
    let stamps_s = ape.pairs.stamps.clone();
    let events: Vec<EventEntry> = read_json(&dir.join(files::EVENTS))?;
    let loops = events
        .into_iter()
        .filter(|e| e.kind == "loop_closure_accepted")
        .map(|e| {
            let segment = e.loop_stamps_ns.and_then(|[a, b]| {
                let at = |ns: u64| nearest(&stamps_s, ns as f64 * 1e-9).map(|i| aligned[i]);
                Some(LoopSegment {
                    from: at(a)?,
                    to: at(b)?,
                    true_loop: e.true_loop?,
                })
            });
            AcceptedLoop {
                stamp_ns: e.stamp_ns,
                detail: e.detail,
                stamps_ns: e.loop_stamps_ns,
                true_loop: e.true_loop,
                gt_distance_m: e.gt_distance_m,
                segment,
            }
        })
        .collect();
    record.ape = Some(metrics.ape);
    record.loops = Some(metrics.loops);
    record.estimate_xy = aligned;
    let detail = RunDetail {
        alignment: metrics.alignment,
        groundtruth_xy: gt.poses.iter().map(xy).collect(),
        estimate_raw_xy: estimate.poses.iter().map(xy).collect(),
        stamps_s,
        errors_m: ape.errors,
        loops,
    };
    Ok(LoadedRun {
        record,
        dir: dir.to_path_buf(),
        detail: Some(detail),
        timing,
        run_toml,
    })
}

/// The index of the stamp nearest `t` within 0.5 s, in sorted `stamps`.
fn nearest(stamps: &[f64], t: f64) -> Option<usize> {
    let i = stamps.partition_point(|&s| s < t);
    [i.checked_sub(1), (i < stamps.len()).then_some(i)]
        .into_iter()
        .flatten()
        .min_by(|&a, &b| (stamps[a] - t).abs().total_cmp(&(stamps[b] - t).abs()))
        .filter(|&k| (stamps[k] - t).abs() <= 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_stamp_within_half_a_second() {
        let s = [0.0, 1.0, 2.0];
        assert_eq!(nearest(&s, 1.4), Some(1));
        assert_eq!(nearest(&s, 1.6), Some(2));
        assert_eq!(nearest(&s, -0.4), Some(0));
        assert_eq!(nearest(&s, 2.7), None);
        assert_eq!(nearest(&[], 0.0), None);
    }

    #[test]
    fn ordered_objects_keep_file_order() {
        let o: Ordered<u32> = serde_json::from_str(r#"{"s3": 1, "s0": 2, "b": 3}"#).unwrap();
        let keys: Vec<_> = o.0.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(keys, ["s3", "s0", "b"]);
    }
}
