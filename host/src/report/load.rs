//! Reads a bench's results back: the runs' index (the runner's outcomes, or `table.json` when
//! a report is rebuilt: the column order and how each run ended) and every run's folder
//! through [`crate::results::RunFolder`] (`metrics.json`, `ape.csv`, the trajectories, the
//! judged loops of `events.json`, `timing.json`, `run.toml`). The bench and `vinebench
//! report DIR` build their pages from this, so a rebuilt report is the bench's.

use std::fmt;
use std::marker::PhantomData;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plugin_api::EventKind;
use serde::Deserialize;
use serde::de::{Deserializer, MapAccess, Visitor};

use super::RunRecord;
use super::plot::LoopSegment;
use crate::results::{RunFolder, RunStatus, files};

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
    max_time_s: Option<f64>,
}

/// A run as the bench's index lists it: the order of the columns and how each run ended.
#[derive(Debug, Clone)]
pub struct IndexedRun {
    pub scenario: String,
    pub plugin: String,
    pub status: RunStatus,
    pub max_time_s: Option<f64>,
}

/// One accepted loop closure as the report lists it.
#[derive(Debug, Clone)]
pub struct AcceptedLoop {
    pub stamp_ns: i64,
    pub detail: String,
    /// The two stamps it joins, if the event carried them.
    pub stamps_ns: Option<[i64; 2]>,
    /// Ground truth's judgement; `None`: not judged.
    pub true_loop: Option<bool>,
    /// What the judgement rests on.
    pub judged_by: Option<crate::results::JudgedBy>,
    pub gt_distance_m: Option<f64>,
    /// The segment on the aligned estimate, when the stamps lie on it.
    pub segment: Option<LoopSegment>,
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
    /// The final map's episodes (`joins.json`); `None` for a run evaluated before them.
    pub joins: Option<crate::results::Joins>,
    /// The camera frames of its false loops, wrong joins and some true loops
    /// (`frames.json`); `None` when none were rendered.
    pub frames: Option<crate::results::Frames>,
    /// Each GNSS epoch fed to the plugin at the truth's top-view position then, with its
    /// fix status by name; `None` for a run without GNSS.
    pub gnss: Option<Vec<(f64, f64, String)>>,
}

impl RunDetail {
    /// The wrong joins as segments between the two true places each joins (top view).
    pub fn wrong_join_segments(&self) -> Vec<LoopSegment> {
        self.joins.as_ref().map_or_else(Vec::new, |j| {
            j.report
                .wrong_joins
                .iter()
                .map(|e| LoopSegment {
                    from: (e.later_place[0], e.later_place[1]),
                    to: (e.earlier_place[0], e.earlier_place[1]),
                    true_loop: false,
                    wrong_join: true,
                })
                .collect()
        })
    }
}

/// One run of the bench.
#[derive(Debug, Clone)]
pub struct LoadedRun {
    /// The table's view of the run (its `estimate_xy` aligned).
    pub record: RunRecord,
    pub dir: PathBuf,
    /// For ok runs.
    pub detail: Option<RunDetail>,
    pub timing: Option<crate::results::Timing>,
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
    /// Reads `dir/table.json` (the bench's index) and the folder of every run it lists.
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
        let (mut scenarios, mut plugins, mut index) = (Vec::new(), Vec::new(), Vec::new());
        for (scenario, entries) in table.0 {
            for (plugin, entry) in entries.0 {
                if !plugins.contains(&plugin) {
                    plugins.push(plugin.clone());
                }
                index.push(IndexedRun {
                    scenario: scenario.clone(),
                    plugin,
                    status: RunStatus::from_text(&entry.status),
                    max_time_s: entry.max_time_s,
                });
            }
            scenarios.push(scenario);
        }
        Self::read(dir, scenarios, plugins, &index)
    }

    /// Reads the folder (`dir/<scenario>/<plugin>`) of every run of `index`; `scenarios`
    /// and `plugins` give the column order.
    pub fn read(
        dir: &Path,
        scenarios: Vec<String>,
        plugins: Vec<String>,
        index: &[IndexedRun],
    ) -> anyhow::Result<Self> {
        let runs = index
            .iter()
            .map(|run| {
                let folder = RunFolder::new(dir.join(&run.scenario).join(&run.plugin));
                load_run(run, &folder)
                    .with_context(|| format!("reading the run {}", folder.dir.display()))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self {
            dir: dir.to_path_buf(),
            scenarios,
            plugins,
            runs,
        })
    }
}

/// One run folder read back on its own (`vinebench report --figures`): its scenario from
/// `run.toml`, its status from `status.txt`, its name `label` or else its plugin's.
pub fn load_run_folder(dir: &Path, label: Option<&str>) -> anyhow::Result<LoadedRun> {
    #[derive(Deserialize)]
    struct RunToml {
        scenario: String,
        plugin: PluginToml,
    }
    #[derive(Deserialize)]
    struct PluginToml {
        name: Option<String>,
    }
    let folder = RunFolder::new(dir);
    let text = folder
        .read_run_toml()
        .with_context(|| format!("{}: no run.toml (not a run folder?)", dir.display()))?;
    let run_toml: RunToml = toml::from_str(&text)
        .with_context(|| format!("{}: unreadable", folder.path(files::RUN).display()))?;
    let status_path = folder.path(files::STATUS);
    let status = std::fs::read_to_string(&status_path)
        .with_context(|| format!("{}: cannot read", status_path.display()))?;
    let run = IndexedRun {
        scenario: run_toml.scenario,
        plugin: label
            .map(str::to_owned)
            .or(run_toml.plugin.name)
            .unwrap_or_else(|| "system".to_owned()),
        status: RunStatus::from_text(status.trim()),
        max_time_s: None,
    };
    load_run(&run, &folder)
}

fn load_run(run: &IndexedRun, folder: &RunFolder) -> anyhow::Result<LoadedRun> {
    let timing = folder.read_timing()?;
    let run_toml = folder.read_run_toml();
    let mut record = RunRecord {
        scenario: run.scenario.clone(),
        plugin: run.plugin.clone(),
        status: run.status.clone(),
        ape: None,
        realtime_factor: None,
        loops: None,
        joins: None,
        sim3_scale: None,
        drift_percent: None,
        estimate_xy: Vec::new(),
        max_time_s: run.max_time_s,
        localization: None,
    };
    if run.status != RunStatus::Ok {
        return Ok(LoadedRun {
            record,
            dir: folder.dir.clone(),
            detail: None,
            timing,
            run_toml,
        });
    }
    let metrics = folder.read_metrics()?;
    let ape = folder.read_ape()?;
    let gt = folder.read_groundtruth()?;
    let estimate = folder.read_estimate()?;
    let xy = |p: &nalgebra::Isometry3<f64>| (p.translation.x, p.translation.y);
    let aligned = ape.aligned_xy();
    let loops = folder
        .read_judged_events()?
        .into_iter()
        .filter(|e| e.event.kind == EventKind::LoopClosureAccepted)
        .map(|e| {
            let segment = e.event.loop_stamps_ns.and_then(|[a, b]| {
                let at = |ns: i64| nearest(&ape.stamps_s, ns as f64 * 1e-9).map(|i| aligned[i]);
                Some(LoopSegment {
                    from: at(a)?,
                    to: at(b)?,
                    true_loop: e.true_loop?,
                    wrong_join: false,
                })
            });
            AcceptedLoop {
                stamp_ns: e.event.stamp_ns,
                detail: e.event.detail,
                stamps_ns: e.event.loop_stamps_ns,
                true_loop: e.true_loop,
                judged_by: e.judged_by,
                gt_distance_m: e.gt_distance_m,
                segment,
            }
        })
        .collect();
    record.ape = Some(metrics.ape);
    // The system's own speed: a shared simulation sets the pace of its whole group, and the
    // simulator's time is not the system's.
    record.realtime_factor = timing.as_ref().map(|t| t.realtime_factor_plugin);
    record.loops = Some(metrics.loops);
    record.joins = metrics.joins;
    record.sim3_scale = metrics.sim3_scale;
    record.drift_percent = metrics.drift.map(|d| d.translation_percent);
    record.localization = metrics.localization;
    record.estimate_xy = aligned;
    let detail = RunDetail {
        alignment: metrics.alignment,
        groundtruth_xy: gt.poses.iter().map(xy).collect(),
        estimate_raw_xy: estimate.poses.iter().map(xy).collect(),
        stamps_s: ape.stamps_s,
        errors_m: ape.errors_m,
        loops,
        joins: folder.read_joins()?,
        frames: folder.read_frames()?,
        gnss: folder.read_gnss()?.map(|epochs| {
            epochs
                .into_iter()
                .filter_map(|(ns, status)| {
                    let k = nearest(&gt.stamps, ns as f64 * 1e-9)?;
                    let (x, y) = xy(&gt.poses[k]);
                    Some((x, y, status))
                })
                .collect()
        }),
    };
    Ok(LoadedRun {
        record,
        dir: folder.dir.clone(),
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
