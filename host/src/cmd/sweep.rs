//! `vinebench sweep FILE.toml`: a bench file plus axes (seeds, world keys), every cell one
//! run, resumable, here or on a Slurm cluster; then the aggregate ([`crate::sweep`]).

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};

use crate::cmd::progress::Progress;
use crate::sweep::{self, Sweep, aggregate, slurm};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Executor {
    /// Runs here, `--jobs` at once.
    Local,
    /// Submits the runs as Slurm job arrays and waits for them.
    Slurm,
}

#[derive(Debug, Args)]
pub struct SweepArgs {
    /// The sweep: a bench file with `seeds` and `[axes]` (e.g. configs/sweep-demo.toml).
    pub file: PathBuf,
    /// Sweep folder (default: results/<file stem>); a sweep started again in the same
    /// folder runs only what is missing.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Runs at once (local), or array tasks at once (Slurm; default: no limit).
    #[arg(long)]
    pub jobs: Option<usize>,
    #[arg(long, value_enum, default_value_t = Executor::Local)]
    pub executor: Executor,
    /// Only aggregate the runs already in the folder (e.g. after a Slurm sweep).
    #[arg(long)]
    pub collect: bool,
    /// Cut every route at this many simulated seconds (overrides the file's `max_time_s`).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub max_time: Option<f64>,
    /// An extra option for `sbatch` (repeatable), e.g. `--sbatch-arg=--partition=cpu`.
    #[arg(long = "sbatch-arg", value_name = "OPTION", allow_hyphen_values = true)]
    pub sbatch_args: Vec<String>,
    /// Seconds between two looks at the Slurm queue.
    #[arg(long, default_value_t = 10.0, hide = true)]
    pub poll_s: f64,
    /// Exit 0 even when some runs failed (the aggregate says which and why); by default
    /// the exit code is 3 then.
    #[arg(long)]
    pub allow_failures: bool,
    /// Record each scenario once and replay it to every run (the file's `record_once`):
    /// the simulation paid once, recorded ahead at the lowest CPU priority.
    #[arg(long)]
    pub record_once: bool,
}

/// `vinebench sweep-task TASKS.json --index I`: one array task (started by Slurm).
#[derive(Debug, Args)]
pub struct SweepTaskArgs {
    pub tasks: PathBuf,
    #[arg(long)]
    pub index: usize,
}

pub fn run_task(args: &SweepTaskArgs) -> anyhow::Result<()> {
    slurm::run_task(&args.tasks, args.index)
}

pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    let max_time_s = crate::cmd::sim_args::max_time_flag(args.max_time)?;
    let mut sweep = Sweep::load(&args.file, max_time_s)?;
    sweep.cfg.record_once |= args.record_once;
    let out = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .file
            .file_stem()
            .map_or_else(|| "sweep".into(), |s| s.to_string_lossy().into_owned());
        PathBuf::from("results").join(stem)
    });
    anyhow::ensure!(
        args.poll_s.is_finite() && args.poll_s > 0.0,
        "--poll-s {}: must be positive",
        args.poll_s
    );
    sweep.prepare(&out)?;
    // Why the runs the host failed were not filed (local runs only).
    let mut unfiled = Vec::new();
    if !args.collect {
        let missing = sweep.missing(&out);
        let distinct = sweep
            .cells
            .iter()
            .map(|c| &c.key)
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        crate::out!(
            "{}: {} runs, {} done, {} to run",
            args.file.display(),
            distinct,
            distinct - missing.len(),
            missing.len()
        );
        if !missing.is_empty() {
            // The runs at once, for the estimate of the time left (a Slurm array without
            // a limit: all of them).
            let at_once = match args.executor {
                Executor::Local => args
                    .jobs
                    .or(sweep.cfg.jobs)
                    .unwrap_or_else(crate::cmd::bench::default_jobs),
                Executor::Slurm => match args.jobs {
                    Some(n) if n > 0 => n,
                    _ => missing.len(),
                },
            };
            let progress = Progress::new(missing.len(), None, at_once, true);
            // The mapping runs first, then the localisation runs that start from their maps.
            let (mapping, localizing): (Vec<&sweep::Cell>, Vec<&sweep::Cell>) =
                missing.iter().partition(|c| c.localize.is_none());
            let mut before = 0;
            for phase in [mapping, localizing] {
                if phase.is_empty() {
                    continue;
                }
                let offset = before;
                before += phase.len();
                match args.executor {
                    Executor::Local => {
                        crate::runner::interrupt::install();
                        let jobs = args
                            .jobs
                            .or(sweep.cfg.jobs)
                            .unwrap_or_else(crate::cmd::bench::default_jobs);
                        unfiled.extend(sweep::run_local(
                            &sweep,
                            &out,
                            &phase,
                            jobs,
                            &|cell, outcome| {
                                // Cells finish in any order; they weigh the same, so each
                                // counts as the next unfinished one.
                                progress.finished(usize::MAX, &cell.describe(), outcome)
                            },
                        )?);
                    }
                    Executor::Slurm => {
                        let options = slurm::Options {
                            at_once: args.jobs.unwrap_or(0),
                            sbatch_args: args.sbatch_args.clone(),
                        };
                        let ids = slurm::submit(&sweep, &out, &phase, &options)?;
                        crate::out!("submitted Slurm job array {}", ids.join(", "));
                        slurm::wait(
                            &ids,
                            &out,
                            &phase,
                            Duration::from_secs_f64(args.poll_s),
                            &|filed| progress.set(offset + filed),
                        )?;
                    }
                }
            }
            progress.finish();
        }
    }
    let agg = aggregate::collect(&sweep, &out)?;
    crate::report::sweep::write(&agg, &out)?;
    crate::out!("{}", crate::report::sweep::render_markdown(&agg));
    crate::out!("results: {}", out.display());
    crate::out!(
        "report: {}",
        out.join(crate::report::html::REPORT).display()
    );
    let missing = agg.missing();
    if missing > 0 && !args.collect {
        let why = match unfiled.first() {
            Some(why) => format!("the first because {why}"),
            None => format!("see {}/slurm/*/task-*.log if on Slurm", out.display()),
        };
        anyhow::bail!(
            "{missing} runs did not file a result ({why}); run the sweep again to run them"
        );
    }
    let failed = agg.failed();
    if failed > 0 && !args.allow_failures {
        return Err(crate::cmd::Exit::failures(format!(
            "{failed} runs failed (the aggregate says why; --allow-failures to exit 0)"
        ))
        .into());
    }
    Ok(())
}
