//! Runs a benchmark matrix: every (scenario, plugin) pair in its own worker process, as many
//! at once as asked, each scored against ground truth; then the report. Results are written
//! under a temporary name and moved into place when complete.

mod evaluate;
pub mod job;
mod loops;
mod outputs;
mod supervise;
mod timing;
pub mod worker;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

pub use evaluate::{Metrics, alignment_name, evaluate};
pub use job::{Job, files};

use crate::report::{RunRecord, RunStatus, ScenarioTruth};

/// Marks a folder as a vinebench results folder, so a rerun may replace it.
const MARKER: &str = ".vinebench-results";

/// One run of the matrix.
#[derive(Debug, Clone)]
pub struct PlannedRun {
    pub scenario: String,
    pub label: String,
    pub plugin: PathBuf,
    pub params_toml: String,
}

/// A resolved matrix.
#[derive(Debug, Clone)]
pub struct Plan {
    pub out: PathBuf,
    pub world: Option<PathBuf>,
    pub seed: u64,
    pub scenarios: Vec<String>,
    pub labels: Vec<String>,
    pub runs: Vec<PlannedRun>,
    pub jobs: usize,
    pub timeout: Duration,
    pub memory_limit_mb: u64,
    pub alignment: eval::Alignment,
    /// Feed every run from this recording instead of the live simulator.
    pub dataset: Option<PathBuf>,
    /// Cut every route at this simulated time, seconds; `None`: whole routes.
    pub max_time_s: Option<f64>,
}

/// What came out of a whole matrix.
#[derive(Debug)]
pub struct Executed {
    pub dir: PathBuf,
    pub table_markdown: String,
    pub records: Vec<RunRecord>,
}

fn temp_sibling(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "results".into());
    out.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Runs the plan and writes its results folder.
pub fn execute(plan: &Plan) -> anyhow::Result<Executed> {
    if plan.out.exists()
        && !plan.out.join(MARKER).exists()
        && std::fs::read_dir(&plan.out)?.next().is_some()
    {
        anyhow::bail!(
            "{} exists and is not a vinebench results folder; choose another --out",
            plan.out.display()
        );
    }
    let config = crate::cmd::simulate::load_config(plan.world.as_deref())?;
    // Check the scenarios before starting anything.
    for s in &plan.scenarios {
        if !config.scenarios.contains_key(s) {
            let known: Vec<&str> = config.scenarios.keys().map(String::as_str).collect();
            anyhow::bail!("unknown scenario '{s}' (known: {})", known.join(", "));
        }
    }
    let tmp = temp_sibling(&plan.out);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp)?;
    }
    std::fs::create_dir_all(&tmp).with_context(|| tmp.display().to_string())?;
    let written = run_all(plan, &config, &tmp).and_then(|(records, truths)| {
        let table =
            crate::report::write_reports(&tmp, &plan.scenarios, &plan.labels, &records, &truths)?;
        std::fs::File::create(tmp.join(MARKER))?;
        Ok((records, table))
    });
    let (records, table) = match written {
        Ok(v) => v,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(e);
        }
    };
    if plan.out.exists() {
        std::fs::remove_dir_all(&plan.out).with_context(|| plan.out.display().to_string())?;
    }
    std::fs::rename(&tmp, &plan.out).with_context(|| plan.out.display().to_string())?;
    link_latest(&plan.out);
    Ok(Executed {
        dir: plan.out.clone(),
        table_markdown: table,
        records,
    })
}

/// Points `latest` beside the results folder at it (best effort: a missing link loses nothing).
fn link_latest(out: &Path) {
    let (Some(parent), Some(name)) = (out.parent(), out.file_name()) else {
        return;
    };
    let link = parent.join("latest");
    if link.is_symlink() {
        let _ = std::fs::remove_file(&link);
    }
    if !link.exists() {
        let _ = std::os::unix::fs::symlink(name, &link);
    }
}

fn run_all(
    plan: &Plan,
    config: &sim::SimConfig,
    tmp: &Path,
) -> anyhow::Result<(Vec<RunRecord>, Vec<ScenarioTruth>)> {
    // Ground truth of each scenario for the plots: the trajectory alone is cheap.
    let world = sim::world::World::build(&config.vineyard, &config.terrain, config.world_seed);
    let mut truths = Vec::new();
    for s in &plan.scenarios {
        let sim = sim::Simulation::with_world(config, world.clone(), s, plan.seed)?;
        let step = 100_000_000;
        let end_ns = worker::end_ns(sim.duration_ns(), plan.max_time_s)?;
        let xy = (0..=end_ns / step)
            .map(|k| {
                let p = sim.trajectory.pose(k * step).translation.vector;
                (p.x, p.y)
            })
            .collect();
        truths.push(ScenarioTruth {
            scenario: s.clone(),
            groundtruth_xy: xy,
        });
    }

    let bars = MultiProgress::new();
    let style = ProgressStyle::with_template("{prefix:>28} [{bar:30}] {percent:>3}% {msg}")
        .expect("valid template")
        .progress_chars("=> ");
    let mut dirs = Vec::with_capacity(plan.runs.len());
    let mut progress = Vec::with_capacity(plan.runs.len());
    for run in &plan.runs {
        let dir = std::path::absolute(tmp.join(&run.scenario).join(&run.label))?;
        std::fs::create_dir_all(&dir)?;
        let job = Job {
            scenario: run.scenario.clone(),
            // Absolute: the worker runs in its run folder (see `supervise`).
            world: plan.world.as_ref().map(std::path::absolute).transpose()?,
            seed: plan.seed,
            plugin: std::path::absolute(&run.plugin)?,
            params_toml: run.params_toml.clone(),
            out_dir: dir.clone(),
            memory_limit_mb: plan.memory_limit_mb,
            dataset: plan.dataset.as_ref().map(std::path::absolute).transpose()?,
            max_time_s: plan.max_time_s,
        };
        worker::write_json(&dir.join(files::JOB), &job)?;
        let bar = bars.add(ProgressBar::new(1000).with_style(style.clone()));
        bar.set_prefix(format!("{}/{}", run.scenario, run.label));
        dirs.push(dir);
        progress.push(bar);
    }

    let next = AtomicUsize::new(0);
    let records: Mutex<Vec<Option<RunRecord>>> = Mutex::new(vec![None; plan.runs.len()]);
    std::thread::scope(|scope| {
        for _ in 0..plan.jobs.clamp(1, plan.runs.len().max(1)) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(run) = plan.runs.get(i) else { break };
                    let bar = &progress[i];
                    let record = run_one(run, &dirs[i], plan, bar);
                    match &record.status {
                        RunStatus::Ok => bar.finish_with_message("ok"),
                        RunStatus::Failed(why) => {
                            bar.abandon_with_message(format!("failed: {why}"))
                        }
                    }
                    records.lock().expect("no panics while holding the lock")[i] = Some(record);
                }
            });
        }
    });
    let records = records
        .into_inner()
        .expect("no panics while holding the lock")
        .into_iter()
        .map(|r| r.expect("every run was taken"))
        .collect();
    Ok((records, truths))
}

fn run_one(run: &PlannedRun, dir: &Path, plan: &Plan, bar: &ProgressBar) -> RunRecord {
    let failed = |why: String| RunRecord {
        scenario: run.scenario.clone(),
        plugin: run.label.clone(),
        status: RunStatus::Failed(why),
        ape: None,
        realtime_factor: None,
        loops: None,
        estimate_xy: Vec::new(),
        max_time_s: plan.max_time_s,
    };
    let on_progress = |f: f64| bar.set_position((f * 1000.0) as u64);
    let outcome = supervise::supervise(dir, plan.timeout, plan.memory_limit_mb, &on_progress);
    // The order held a temporary path; run.toml keeps what determined the run.
    let _ = std::fs::remove_file(dir.join(files::JOB));
    if let Err(why) = outcome {
        return failed(why);
    }
    let scored = match evaluate(dir, plan.alignment) {
        Ok(s) => s,
        Err(e) => return failed(format!("evaluation: {e:#}")),
    };
    let realtime_factor = std::fs::read_to_string(dir.join(files::TIMING))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v["realtime_factor"].as_f64());
    RunRecord {
        scenario: run.scenario.clone(),
        plugin: run.label.clone(),
        status: RunStatus::Ok,
        ape: Some(scored.metrics.ape),
        realtime_factor,
        loops: Some(scored.metrics.loops),
        estimate_xy: scored.estimate_xy,
        max_time_s: plan.max_time_s,
    }
}
