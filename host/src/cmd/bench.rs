//! `vinebench bench FILE.toml`: a matrix of scenarios × plugins, the paper's table.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;

use crate::bench_config::BenchConfig;
use crate::runner::{Plan, PlannedRun, execute};

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

/// `--max-time` checked: a positive number of seconds, or the error naming the flag.
pub fn max_time_flag(seconds: Option<f64>) -> anyhow::Result<Option<f64>> {
    if let Some(s) = seconds {
        crate::bench_config::check_max_time(s)
            .map_err(|why| anyhow::anyhow!("--max-time {s}: {why}"))?;
    }
    Ok(seconds)
}

pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let max_time_s = max_time_flag(args.max_time)?;
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
    let plan = Plan {
        out: args
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from("results").join(stem)),
        world: cfg.world.clone(),
        seed: cfg.bench_seed(),
        scenarios: cfg.scenarios.clone(),
        labels,
        runs,
        jobs: args.jobs.or(cfg.jobs).unwrap_or_else(default_jobs),
        timeout: Duration::from_secs_f64(cfg.timeout_s),
        memory_limit_mb: cfg.memory_limit_mb,
        alignment: cfg.align.into(),
        dataset: None,
        max_time_s: max_time_s.or(cfg.max_time_s),
        share_simulation: cfg.share_simulation,
        bars: true,
        paper_table: cfg.paper_table.clone(),
    };
    report(&plan).map(drop)
}

/// Executes a plan and prints its table and where the results are. A failed run does not
/// fail the bench: it is in the table with its reason.
pub fn report(plan: &Plan) -> anyhow::Result<crate::runner::Executed> {
    let executed = execute(plan)?;
    println!("{}", executed.table_markdown);
    println!("results: {}", executed.dir.display());
    println!(
        "report: {}",
        executed.dir.join(crate::report::html::REPORT).display()
    );
    Ok(executed)
}
