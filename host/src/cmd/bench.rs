//! `vinebench bench FILE.toml`: a matrix of scenarios × plugins, the paper's table.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use clap::Args;

use crate::bench_config::BenchConfig;
use crate::cmd::progress::Progress;
use crate::report::load::IndexedRun;
use crate::report::reference;
use crate::results::{RunOutcome, Staging};
use crate::runner::{Plan, PlannedRun};

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The matrix, e.g. configs/paper.toml.
    pub file: PathBuf,
    /// Results folder (default: results/<file stem>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Runs at once (default: the file's `jobs`, else the number of cores); the runs that
    /// share one simulation start together, however many.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Cut every route at this many simulated seconds (overrides the file's `max_time_s`;
    /// default: whole routes). The table then says the routes were cut.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub max_time: Option<f64>,
}

/// Runs at once when nobody says: one per core.
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let max_time_s = crate::cmd::sim_args::max_time_flag(args.max_time)?;
    let cfg = BenchConfig::from_file(&args.file)?;
    anyhow::ensure!(
        !cfg.is_sweep(),
        "{}: has seeds or [axes], which make it a sweep: run it with `vinebench sweep`",
        args.file.display()
    );
    let resolved = cfg.resolve_plugins(&args.file)?;
    let labels: Vec<String> = resolved.iter().map(|p| p.label.clone()).collect();
    let mut runs = Vec::new();
    for scenario in &cfg.scenarios {
        for p in &resolved {
            runs.push(PlannedRun {
                scenario: scenario.clone(),
                label: p.label.clone(),
                plugin: p.library.clone(),
                params_toml: p.params_toml.clone(),
                pace: p.pace,
                base_dir: Some(p.base_dir.clone()),
            });
        }
    }
    let stem = args
        .file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bench".into());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join(stem));
    let plan = Plan {
        world: cfg.world.clone(),
        seed: cfg.bench_seed(),
        scenarios: cfg.scenarios.clone(),
        runs,
        jobs: args.jobs.or(cfg.jobs).unwrap_or_else(default_jobs),
        timeout: Duration::from_secs_f64(cfg.timeout_s),
        memory_limit_mb: cfg.memory_limit_mb,
        alignment: cfg.align.into(),
        dataset: None,
        max_time_s: max_time_s.or(cfg.max_time_s),
        share_simulation: cfg.share_simulation,
        bars: true,
    };
    bench(&plan, &out, &labels, cfg.paper_table.as_deref()).map(drop)
}

/// Runs a plan into the results folder `out` (written whole, then moved into place), writes
/// its reports (with `paper_table`, the published table it reproduces, copied in and shown
/// beside its figures), and prints its table and where the results are. A failed run does
/// not fail the bench: it is in the table with its reason.
pub fn bench(
    plan: &Plan,
    out: &Path,
    labels: &[String],
    paper_table: Option<&Path>,
) -> anyhow::Result<Vec<RunOutcome>> {
    let staging = Staging::begin(out)?;
    if let Some(path) = paper_table {
        // Checked before anything runs; copied so that the folder reports alone.
        reference::Reference::load(path)?;
        let copy = staging.dir().join(reference::FILE);
        std::fs::copy(path, &copy).with_context(|| copy.display().to_string())?;
    }
    // Weighed by route length: the runs of a bench differ in length more than in speed.
    let weights = crate::runner::route_seconds(plan).ok();
    let progress = Progress::new(plan.runs.len(), weights, false);
    let outcomes = crate::runner::execute(plan, staging.dir(), &|i, outcome| {
        progress.finished(
            i,
            &format!("{}/{}", outcome.scenario, outcome.label),
            outcome,
        );
    })?;
    let index: Vec<IndexedRun> = outcomes
        .iter()
        .map(|o| IndexedRun {
            scenario: o.scenario.clone(),
            plugin: o.label.clone(),
            status: o.status.clone(),
            max_time_s: o.max_time_s,
        })
        .collect();
    let name = crate::results::folder_name(out);
    let table = crate::report::write_bench(staging.dir(), &name, &plan.scenarios, labels, &index)?;
    let dir = staging.commit()?;
    println!("{table}");
    println!("results: {}", dir.display());
    println!(
        "report: {}",
        dir.join(crate::report::html::REPORT).display()
    );
    Ok(outcomes)
}
