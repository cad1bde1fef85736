//! One run's folder and the typed files in it.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use eval::{LoopCounts, Statistics, Trajectory};
use plugin_api::Event;
use serde::{Deserialize, Serialize};

use super::files;

/// How one (scenario, system) run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunStatus {
    /// The run finished and was evaluated.
    Ok,
    /// The run did not produce a result; the reason is shown in the reports
    /// (e.g. `"timed out after 600 s"`).
    Failed(String),
}

impl RunStatus {
    /// `"ok"` or `"failed: <reason>"`, as `table.json` and a sweep's `cell.json` hold it.
    pub fn text(&self) -> String {
        match self {
            Self::Ok => "ok".to_owned(),
            Self::Failed(why) => format!("failed: {why}"),
        }
    }

    /// The status of [`Self::text`].
    pub fn from_text(text: &str) -> Self {
        match text {
            "ok" => Self::Ok,
            other => Self::Failed(other.strip_prefix("failed: ").unwrap_or(other).to_owned()),
        }
    }
}

/// How a run of a plan ended, and where its folder is.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    pub scenario: String,
    /// The system's label (`[[plugins]] label`).
    pub label: String,
    pub status: RunStatus,
    /// The route was cut at this simulated time, seconds; `None`: the whole route.
    pub max_time_s: Option<f64>,
    pub folder: RunFolder,
}

/// `metrics.json`: the run's scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// The alignment before APE (`eval::Alignment::name`).
    pub alignment: String,
    /// APE translation of the final trajectory, metres.
    pub ape: Statistics,
    /// APE translation of the poses returned during the run, if any.
    pub online_ape: Option<Statistics>,
    /// The RMSE of the final trajectory's east and north errors alone (aligned as `ape`),
    /// m: what a robot's navigation in the rows needs, apart from the height a 2D system
    /// leaves at 0. Absent in runs scored before it was stored (`vinebench rescore`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub horizontal_rmse_m: Option<f64>,
    /// Loop closures accepted (of those, how many were false and, if any, how many could
    /// not be judged) and rejected.
    pub loops: LoopCounts,
    /// The transform of the APE's alignment (`ape`): ground truth's frame from the
    /// estimate's. Absent in runs evaluated before it was stored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment_transform: Option<Transform>,
    /// The scale of a Sim(3) alignment of the final trajectory, whatever `alignment` is: a
    /// monocular system's scale error shows here (1 for a metric one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sim3_scale: Option<f64>,
    /// KITTI-style drift of the final trajectory over all its 5, 10 and 20 m segments
    /// (`eval::drift`): translation in percent (metres per 100 m), rotation in degrees per
    /// 100 m. Absent when the route is shorter than 5 m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift: Option<eval::SegmentDrift>,
    /// The final map's wrong joins and revisits (`joins.json` holds the episodes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joins: Option<JoinCounts>,
    /// A localisation run's judgement (`vinebench localize`); absent for a mapping run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub localization: Option<LocalizationMetrics>,
    /// What GNSS gave the run and its error while it gave nothing good; absent when the
    /// plugin was fed no fixes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gnss: Option<GnssMetrics>,
}

/// A run's GNSS outages (issue 47): an outage is a stretch without the best status the
/// receiver reached in the run (RTK fixed for an RTK receiver that fixed, a single-point
/// fix for a consumer one), from the last good epoch to the next (or the run's ends).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GnssMetrics {
    /// Epochs fed, and the fraction at the best status.
    pub epochs: u64,
    pub best_status: String,
    pub fraction_best: f64,
    /// The longest outage: its start and length, s.
    pub longest_outage_start_s: f64,
    pub longest_outage_s: f64,
    /// The largest APE (aligned as `ape`) of a pose stamped within the longest outage, m;
    /// absent when no pose falls in it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_error_in_outage_m: Option<f64>,
}

/// A similarity transform as `metrics.json` holds it: `p' = s R p + t`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation_m: [f64; 3],
    /// The rotation as a unit quaternion, x, y, z, w.
    pub rotation_xyzw: [f64; 4],
    pub scale: f64,
}

impl From<&eval::Sim3> for Transform {
    fn from(t: &eval::Sim3) -> Self {
        let q = t.rotation.quaternion();
        Self {
            translation_m: t.translation.into(),
            rotation_xyzw: [q.i, q.j, q.k, q.w],
            scale: t.scale,
        }
    }
}

impl Transform {
    /// The transform, back as the evaluation's type (the rotation normalised).
    pub fn to_sim3(&self) -> eval::Sim3 {
        let [x, y, z, w] = self.rotation_xyzw;
        eval::Sim3 {
            rotation: nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                w, x, y, z,
            )),
            translation: self.translation_m.into(),
            scale: self.scale,
        }
    }
}

/// A localisation run's judgement (`eval::evaluate_localization`) with what it cost to start:
/// the map's size and the plugin's start time from it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizationMetrics {
    #[serde(flatten)]
    pub report: eval::LocalizationReport,
    /// The map handed to the plugin, bytes.
    pub map_bytes: u64,
    /// How long the plugin took to start from it, seconds.
    pub load_s: f64,
    /// Whether the map's frame was put in the world by a mapping run's alignment (`false`:
    /// the surveyed grid, in the world frame).
    pub carried_alignment: bool,
}

/// The final map's episodes counted (`eval::wrong_joins`, default criteria).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct JoinCounts {
    /// Stretches of path the estimate keeps together that the truth keeps apart.
    pub wrong_joins: usize,
    /// Of those, the ones no accepted loop explains (`runner::loops`).
    pub silent: usize,
    /// Their travel together, metres.
    pub wrong_join_travel_m: f64,
    /// Two drifting paths crossing once: drift, not a join.
    pub crossings: usize,
    /// True revisits the estimate keeps together, and those it keeps apart.
    pub revisits: usize,
    pub missed_revisits: usize,
    /// The kept share of the revisits' travel; absent without a revisit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revisit_recall: Option<f64>,
}

/// `joins.json`: every episode of the final map (`eval::JoinReport`) and which wrong joins
/// are silent (indices into `wrong_joins`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Joins {
    #[serde(flatten)]
    pub report: eval::JoinReport,
    pub silent: Vec<usize>,
}

impl Joins {
    pub fn counts(&self) -> JoinCounts {
        let r = &self.report;
        JoinCounts {
            wrong_joins: r.wrong_joins.len(),
            silent: self.silent.len(),
            // A fold from +0: an empty `sum` of floats is -0.0.
            wrong_join_travel_m: r.wrong_joins.iter().fold(0.0, |a, e| a + e.travel_m),
            crossings: r.crossings.len(),
            revisits: r.revisits.len(),
            missed_revisits: r.missed_revisits.len(),
            revisit_recall: r.revisit_recall(),
        }
    }
}

/// What an accepted loop's verdict rests on (`runner::loops`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JudgedBy {
    /// The two stamps it carried: the ground-truth distance of the poses it joins.
    Stamps,
    /// The measured relative pose it carried, against ground truth's.
    RelativePose,
    /// Without stamps: the wrong join (false) or kept revisit (true) of the final map that
    /// ends shortly before it (`joins.json`).
    FinalMap,
    /// Without stamps, and the final map showing nothing near it: the online error's jump.
    OnlineError,
}

/// One entry of `events.json` once evaluated: the plugin's event as it sent it (`stamp_ns`,
/// `kind`, `detail`, `loop_stamps_ns` when given) and, for an accepted loop that could be
/// judged, `true_loop` with what it was judged by and on: the ground-truth distance and
/// heading difference of its stamps, its relative pose's error, the final map's episode
/// (index into `joins.json`'s lists) and the online error around it (`runner::loops`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JudgedEvent {
    #[serde(flatten)]
    pub event: Event,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub true_loop: Option<bool>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub judged_by: Option<JudgedBy>,
    /// A loop without stamps: the wrong join of the final map it made (index into
    /// `joins.json`'s `wrong_joins`), if any,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrong_join: Option<usize>,
    /// and the kept true revisit (index into `revisits`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revisit: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gt_distance_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gt_heading_deg: Option<f64>,
    /// For a loop that carried its measured relative pose: that pose's error against
    /// ground truth, metres and degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_error_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relative_error_deg: Option<f64>,
    /// For a loop judged by its correction: the online estimate's position error just
    /// before and just after it, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_before_m: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_after_m: Option<f64>,
}

/// What a pair of frames shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PairKind {
    FalseLoop,
    TrueLoop,
    WrongJoin,
}

/// One pair of places: the later and the earlier, the stamps of what the sensors saw there
/// and the pictures of it (files relative to the run folder).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FramePair {
    pub kind: PairKind,
    /// Index into `events.json` (loops) or `joins.json`'s `wrong_joins`.
    pub index: usize,
    /// The frames' (or sweeps') stamps, later then earlier, nanoseconds.
    pub stamps_ns: [i64; 2],
    /// The colour frames the system was given, later then earlier; empty for a run without
    /// the camera.
    #[serde(default)]
    pub files: Vec<String>,
    /// The two colour frames side by side with the keypoints the system matched between
    /// them, where its loop event carried `loop_matches`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matches: Option<String>,
    /// What the matched keypoints lie on, as the simulator's rays through them say: the
    /// number of matches per `"later/earlier"` surface pair (`"fence/fence"`, `"leaf/leaf"`,
    /// `"post/leaf"`, ...; `"sky"` where a ray meets nothing).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub matched_surfaces: BTreeMap<String, usize>,
    /// The two lidar sweeps' top views overlaid, the later one placed at the estimate's
    /// relative pose, then at ground truth's; for runs with the lidar.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scans: Vec<String>,
    /// For each of `scans`: the share of the later sweep's points (from above) within 0.2 m
    /// of an earlier sweep's point. A true join overlaps about as well under the estimate as
    /// under the truth; a false one well under the estimate only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scan_overlap: Vec<f64>,
}

/// `frames.json`: the camera frames of a run's false loops, wrong joins and a sample of
/// its true loops, rendered again at evaluation (`runner::frames`) into `frames/`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Frames {
    pub pairs: Vec<FramePair>,
}

/// Latency percentiles of one kind of call, milliseconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Latency {
    pub calls: usize,
    pub p50_ms: f64,
    pub p90_ms: f64,
    pub p99_ms: f64,
    pub max_ms: f64,
    pub total_s: f64,
}

/// `timing.json`: what the run cost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Where the messages came from: `simulation` (the worker's own), `shared simulation`
    /// (the supervisor's, streamed to several workers) or `dataset`.
    pub source: String,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub plugin_s: f64,
    pub cpu_s: Option<f64>,
    pub peak_rss_mb: Option<f64>,
    /// Simulated seconds per wall second, simulator included.
    pub realtime_factor: f64,
    /// Simulated seconds per second spent inside the plugin: the system's own speed (a
    /// shared simulation sets the pace of its whole group).
    pub realtime_factor_plugin: f64,
    /// Per kind of call (sensor, `finish`), in name order.
    pub latency: BTreeMap<String, Latency>,
    /// What the simulation cost per sensor: wall seconds spent making its messages per
    /// simulated second, the simulator's parallel work included (the worker's own
    /// simulation, or the supervisor's when shared, whose cost its whole group shares; empty
    /// for a dataset).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub simulation_cost: BTreeMap<String, f64>,
    /// Messages dropped per topic by the system's bounded queues (`queue_size`) or given
    /// drops; which ones: `dropped.csv`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub dropped: BTreeMap<String, u64>,
}

/// `ape.csv`: the final estimate after alignment and its APE translation error at every pose
/// associated with ground truth, as evaluation computed them: `t_s,x_m,y_m,z_m,error_m`, one
/// line per pose, every number in the shortest text that reads back to the same `f64`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ApeSeries {
    /// Stamps of the associated pairs, seconds.
    pub stamps_s: Vec<f64>,
    /// The aligned estimate's positions, metres, in ground truth's frame.
    pub aligned: Vec<[f64; 3]>,
    /// The translation error of each, metres.
    pub errors_m: Vec<f64>,
}

const APE_HEADER: &str = "t_s,x_m,y_m,z_m,error_m";

impl ApeSeries {
    /// The top view of the aligned estimate.
    pub fn aligned_xy(&self) -> Vec<(f64, f64)> {
        self.aligned.iter().map(|p| (p[0], p[1])).collect()
    }

    fn to_csv(&self) -> String {
        let mut out = String::with_capacity(64 * self.stamps_s.len());
        out.push_str(APE_HEADER);
        out.push('\n');
        for ((t, p), e) in self.stamps_s.iter().zip(&self.aligned).zip(&self.errors_m) {
            let _ = writeln!(out, "{t},{},{},{},{e}", p[0], p[1], p[2]);
        }
        out
    }

    fn parse(text: &str) -> anyhow::Result<Self> {
        let mut lines = text.lines();
        anyhow::ensure!(
            lines.next() == Some(APE_HEADER),
            "expected the header line {APE_HEADER}"
        );
        let mut series = Self::default();
        for (i, line) in lines.enumerate() {
            let values: Vec<f64> = line
                .split(',')
                .map(str::parse)
                .collect::<Result<_, _>>()
                .with_context(|| format!("line {}: {line:?}", i + 2))?;
            let [t, x, y, z, e] = values[..] else {
                anyhow::bail!("line {}: expected 5 numbers, found {}", i + 2, values.len());
            };
            series.stamps_s.push(t);
            series.aligned.push([x, y, z]);
            series.errors_m.push(e);
        }
        Ok(series)
    }
}

/// Writes `value` as pretty JSON with a final newline.
pub fn write_json(path: &Path, value: &impl Serialize) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    // Beside it, then renamed over it: an interrupted write leaves the old file whole.
    let mut partial = path.as_os_str().to_owned();
    partial.push(".partial");
    let partial = PathBuf::from(partial);
    std::fs::write(&partial, text + "\n").with_context(|| partial.display().to_string())?;
    std::fs::rename(&partial, path).with_context(|| path.display().to_string())
}

fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> anyhow::Result<T> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: malformed", path.display()))
}

/// One run's folder: where each of its files is, and each file read and written as its type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunFolder {
    pub dir: PathBuf,
}

impl RunFolder {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// The path of one of its [`files`].
    pub fn path(&self, file: &str) -> PathBuf {
        self.dir.join(file)
    }

    pub fn has(&self, file: &str) -> bool {
        self.path(file).exists()
    }

    pub fn read_metrics(&self) -> anyhow::Result<Metrics> {
        read_json(&self.path(files::METRICS))
    }

    pub fn write_metrics(&self, metrics: &Metrics) -> anyhow::Result<()> {
        write_json(&self.path(files::METRICS), metrics)
    }

    /// `timing.json`, if the worker got as far as writing it.
    pub fn read_timing(&self) -> anyhow::Result<Option<Timing>> {
        let path = self.path(files::TIMING);
        path.exists().then(|| read_json(&path)).transpose()
    }

    pub fn write_timing(&self, timing: &Timing) -> anyhow::Result<()> {
        write_json(&self.path(files::TIMING), timing)
    }

    /// `events.json` as the plugin sent it (before evaluation).
    pub fn read_events(&self) -> anyhow::Result<Vec<Event>> {
        read_json(&self.path(files::EVENTS))
    }

    pub fn write_events(&self, events: &[Event]) -> anyhow::Result<()> {
        write_json(&self.path(files::EVENTS), &events)
    }

    /// `events.json` after evaluation.
    pub fn read_judged_events(&self) -> anyhow::Result<Vec<JudgedEvent>> {
        read_json(&self.path(files::EVENTS))
    }

    pub fn write_judged_events(&self, events: &[JudgedEvent]) -> anyhow::Result<()> {
        write_json(&self.path(files::EVENTS), &events)
    }

    /// `frames.json`, if frames were rendered for the run.
    pub fn read_frames(&self) -> anyhow::Result<Option<Frames>> {
        let path = self.path(files::FRAMES);
        path.exists().then(|| read_json(&path)).transpose()
    }

    pub fn write_frames(&self, frames: &Frames) -> anyhow::Result<()> {
        write_json(&self.path(files::FRAMES), frames)
    }

    /// `joins.json`, if the run was evaluated since it was written.
    pub fn read_joins(&self) -> anyhow::Result<Option<Joins>> {
        let path = self.path(files::JOINS);
        path.exists().then(|| read_json(&path)).transpose()
    }

    pub fn write_joins(&self, joins: &Joins) -> anyhow::Result<()> {
        write_json(&self.path(files::JOINS), joins)
    }

    pub fn read_ape(&self) -> anyhow::Result<ApeSeries> {
        let path = self.path(files::APE);
        anyhow::ensure!(
            path.exists(),
            "{}: missing (a run evaluated before vinebench stored its APE: run it again)",
            path.display()
        );
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("{}: cannot read", path.display()))?;
        ApeSeries::parse(&text).with_context(|| path.display().to_string())
    }

    pub fn write_ape(&self, ape: &ApeSeries) -> anyhow::Result<()> {
        let path = self.path(files::APE);
        std::fs::write(&path, ape.to_csv()).with_context(|| path.display().to_string())
    }

    /// The GNSS epochs the plugin was fed (`gnss.csv`): each one's stamp and fix status by
    /// name (`sim::sensors::gnss::FixStatus::name`); `None` for a run without GNSS.
    pub fn read_gnss(&self) -> anyhow::Result<Option<Vec<(i64, String)>>> {
        let path = self.path(files::GNSS);
        let text = match std::fs::read_to_string(&path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| path.display().to_string()),
        };
        let mut epochs = Vec::new();
        for (k, line) in text.lines().enumerate().skip(1) {
            let parsed = line
                .split_once(',')
                .and_then(|(t, s)| Some((t.parse::<i64>().ok()?, s.to_owned())));
            let Some(epoch) = parsed else {
                anyhow::bail!("{} line {}: not stamp_ns,status", path.display(), k + 1);
            };
            epochs.push(epoch);
        }
        Ok(Some(epochs))
    }

    pub fn read_groundtruth(&self) -> anyhow::Result<Trajectory> {
        Ok(eval::read_tum(self.path(files::GROUNDTRUTH))?)
    }

    pub fn read_estimate(&self) -> anyhow::Result<Trajectory> {
        Ok(eval::read_tum(self.path(files::ESTIMATE))?)
    }

    /// `online.tum`, if the system returned poses during the run.
    pub fn read_online(&self) -> anyhow::Result<Option<Trajectory>> {
        let path = self.path(files::ONLINE);
        Ok(path.exists().then(|| eval::read_tum(&path)).transpose()?)
    }

    /// `run.toml`'s text, if written.
    pub fn read_run_toml(&self) -> Option<String> {
        std::fs::read_to_string(self.path(files::RUN)).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ape_series_reads_back_bit_for_bit_and_a_bad_line_is_named() {
        let series = ApeSeries {
            stamps_s: vec![0.1, 1.0 / 3.0],
            aligned: vec![[1e-300, -2.5, f64::MIN_POSITIVE], [0.1 + 0.2, 7.0, -0.0]],
            errors_m: vec![0.0, std::f64::consts::PI],
        };
        let back = ApeSeries::parse(&series.to_csv()).expect("parse");
        let bits = |s: &ApeSeries| -> Vec<u64> {
            s.stamps_s
                .iter()
                .chain(s.aligned.iter().flatten())
                .chain(&s.errors_m)
                .map(|v| v.to_bits())
                .collect()
        };
        assert_eq!(bits(&back), bits(&series));
        let err = format!(
            "{:#}",
            ApeSeries::parse(&format!("{APE_HEADER}\n1,2,3\n")).expect_err("short line")
        );
        assert!(err.contains("line 2: expected 5 numbers, found 3"), "{err}");
    }

    #[test]
    fn status_text_round_trips() {
        for status in [
            RunStatus::Ok,
            RunStatus::Failed("timed out after 5 s".into()),
        ] {
            assert_eq!(RunStatus::from_text(&status.text()), status);
        }
    }
}
