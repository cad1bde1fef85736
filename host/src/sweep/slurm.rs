//! The Slurm executor: a sweep's missing runs as job arrays (`sbatch --array`), each task
//! one run through the same worker as a local sweep (`vinebench sweep-task`), its results
//! filed in the sweep folder on the shared file system. The sweep then waits for the
//! arrays (`squeue`) and aggregates; `vinebench sweep --collect` aggregates later.
//!
//! Every submission gets a folder `slurm/<n>/` with
//! - `tasks.json`: the runs, one per array index, with everything a task needs (so a task
//!   does not depend on the sweep file, which may change after submission);
//! - `array.sh`: the batch script;
//! - `task-<job>-<index>.log`: each task's output.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use anyhow::Context as _;
use serde::{Deserialize, Serialize};

use super::{Cell, Sweep, file_run, run_dir, work_dir};
use crate::results::{RunStatus, write_atomic};
use crate::runner::Plan;

/// Slurm's default `MaxArraySize` is 1001: arrays of at most 1000 tasks.
const ARRAY_MAX: usize = 1000;

/// What every task of a submission needs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Tasks {
    /// The sweep folder (absolute).
    pub out: PathBuf,
    pub timeout_s: f64,
    pub memory_limit_mb: u64,
    pub align: crate::bench_config::Align,
    pub max_time_s: Option<f64>,
    /// The submitting executable's hash: a task run by another build (the binary was
    /// replaced after submission) refuses, so that one submission is one build.
    pub exe_hash: String,
    pub cells: Vec<Cell>,
}

/// How to submit.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Tasks of an array running at once (`--array=...%N`); 0: as many as Slurm gives.
    pub at_once: usize,
    /// More `sbatch` options (`--partition=...`, `--account=...`), before the script.
    pub sbatch_args: Vec<String>,
}

fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Submits `cells` as job arrays; returns the job ids.
pub fn submit(
    sweep: &Sweep,
    out: &Path,
    cells: &[&Cell],
    options: &Options,
) -> anyhow::Result<Vec<String>> {
    let out = std::path::absolute(out)?;
    let root = out.join("slurm");
    std::fs::create_dir_all(&root).with_context(|| root.display().to_string())?;
    let n = std::fs::read_dir(&root)?
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u64>().ok())
        .max()
        .map_or(0, |m| m + 1);
    let exe = std::env::current_exe().context("the vinebench executable")?;
    let mut ids = Vec::new();
    for (part, chunk) in cells.chunks(ARRAY_MAX).enumerate() {
        let dir = root.join(format!("{}", n + part as u64));
        std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
        let tasks = Tasks {
            out: out.clone(),
            timeout_s: sweep.cfg.timeout_s,
            memory_limit_mb: sweep.cfg.memory_limit_mb,
            align: sweep.cfg.align,
            max_time_s: sweep.cfg.max_time_s,
            exe_hash: sweep.exe_hash.clone(),
            cells: chunk.iter().map(|c| (*c).clone()).collect(),
        };
        let tasks_path = dir.join("tasks.json");
        write_atomic(
            &tasks_path,
            (serde_json::to_string_pretty(&tasks)? + "\n").as_bytes(),
        )?;
        // A task's wall-clock limit: the run's, plus room for the simulation and scoring.
        let minutes = (sweep.cfg.timeout_s / 60.0).ceil() as u64 + 10;
        let script = format!(
            "#!/bin/bash\n\
             # vinebench sweep {sweep_file}: one run per array task.\n\
             #SBATCH --job-name=vinebench-sweep\n\
             #SBATCH --output={log}\n\
             #SBATCH --cpus-per-task=2\n\
             #SBATCH --mem={mem}M\n\
             #SBATCH --time={minutes}\n\
             exec {exe} sweep-task {tasks} --index \"$SLURM_ARRAY_TASK_ID\"\n",
            sweep_file = sweep.file.display(),
            log = dir.join("task-%A-%a.log").display(),
            mem = sweep.cfg.memory_limit_mb,
            exe = quote(&exe.display().to_string()),
            tasks = quote(&tasks_path.display().to_string()),
        );
        let script_path = dir.join("array.sh");
        write_atomic(&script_path, script.as_bytes())?;
        let mut array = format!("0-{}", chunk.len() - 1);
        if options.at_once > 0 {
            array += &format!("%{}", options.at_once);
        }
        let output = Command::new("sbatch")
            .arg("--parsable")
            .arg(format!("--array={array}"))
            .args(&options.sbatch_args)
            .arg(&script_path)
            .current_dir(&dir)
            .output()
            .context("sbatch: cannot run it (is Slurm installed and on PATH?)")?;
        anyhow::ensure!(
            output.status.success(),
            "sbatch {}: {}",
            script_path.display(),
            String::from_utf8_lossy(&output.stderr).trim()
        );
        // `--parsable` prints `<id>` or `<id>;<cluster>`.
        let id = String::from_utf8_lossy(&output.stdout)
            .trim()
            .split(';')
            .next()
            .unwrap_or("")
            .to_owned();
        anyhow::ensure!(
            !id.is_empty() && id.chars().all(|c| c.is_ascii_digit()),
            "sbatch printed no job id: {:?}",
            String::from_utf8_lossy(&output.stdout)
        );
        ids.push(id);
    }
    Ok(ids)
}

/// Whether any of the jobs is still queued or running.
fn pending(ids: &[String]) -> anyhow::Result<bool> {
    let output = Command::new("squeue")
        .args(["--noheader", "--format=%i", "--jobs"])
        .arg(ids.join(","))
        .output()
        .context("squeue: cannot run it")?;
    if !output.status.success() {
        // Jobs that ended long ago are unknown to squeue, which then fails.
        let err = String::from_utf8_lossy(&output.stderr);
        if err.contains("Invalid job id") {
            return Ok(false);
        }
        anyhow::bail!("squeue: {}", err.trim());
    }
    Ok(!String::from_utf8_lossy(&output.stdout).trim().is_empty())
}

/// Waits until the jobs have left the queue, calling `on_tick` with the number of the
/// cells' runs filed so far, every `every`.
pub fn wait(
    ids: &[String],
    out: &Path,
    cells: &[&Cell],
    every: Duration,
    on_tick: &dyn Fn(usize),
) -> anyhow::Result<()> {
    loop {
        let filed = cells
            .iter()
            .filter(|c| run_dir(out, &c.key).exists())
            .count();
        on_tick(filed);
        if !pending(ids)? {
            return Ok(());
        }
        std::thread::sleep(every);
    }
}

/// One array task: the run at `index` of a `tasks.json`, filed in the sweep folder.
pub fn run_task(tasks_path: &Path, index: usize) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(tasks_path).with_context(|| tasks_path.display().to_string())?;
    let tasks: Tasks =
        serde_json::from_str(&text).with_context(|| tasks_path.display().to_string())?;
    let cell = tasks.cells.get(index).with_context(|| {
        format!(
            "{}: no task {index} (it has {})",
            tasks_path.display(),
            tasks.cells.len()
        )
    })?;
    let out = &tasks.out;
    anyhow::ensure!(
        crate::results::exe_hash()? == tasks.exe_hash,
        "{}: submitted by another vinebench build than this one ({}); submit the sweep again",
        tasks_path.display(),
        std::env::current_exe()?.display()
    );
    if run_dir(out, &cell.key).exists() {
        crate::out!("{}: already done", cell.describe());
        return Ok(());
    }
    let plan = Plan {
        world: Some(out.join("worlds").join(format!("{}.toml", cell.world))),
        seed: cell.seed,
        scenarios: vec![cell.scenario.clone()],
        runs: vec![cell.planned_run(out)?],
        jobs: 1,
        timeout: Duration::from_secs_f64(tasks.timeout_s),
        memory_limit_mb: tasks.memory_limit_mb,
        alignment: tasks.align.into(),
        dataset: None,
        max_time_s: tasks.max_time_s,
        share_simulation: false,
        // One run a task: nothing to replay to another.
        record_once: None,
        bars: false,
    };
    let job = std::env::var("SLURM_ARRAY_JOB_ID").unwrap_or_else(|_| "task".into());
    let work = work_dir(out, &format!("slurm-{job}-{index}"));
    let filing = std::sync::Mutex::new(Ok(()));
    let outcomes = crate::runner::execute(&plan, &work, &|_, outcome| {
        *filing.lock().expect("no panics while holding the lock") = file_run(
            out,
            cell,
            &tasks.exe_hash,
            &outcome.status,
            &outcome.folder.dir,
        );
    })?;
    filing
        .into_inner()
        .expect("no panics while holding the lock")?;
    let _ = std::fs::remove_dir_all(&work);
    match outcomes.first().map(|r| &r.status) {
        Some(RunStatus::Failed(why)) => {
            crate::out!("{}: failed: {why}", cell.describe())
        }
        _ => crate::out!("{}: ok", cell.describe()),
    }
    Ok(())
}
