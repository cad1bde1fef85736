//! `vinebench run`: one plugin on one scenario, in a worker process, with its results folder.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context as _;
use clap::Args;

use crate::bench_config::Align;
use crate::cmd::sim_args::SimArgs;
use crate::runner::{Plan, PlannedRun};

#[derive(Debug, Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub sim: SimArgs,
    /// Plugin name (searched for) or path to its library.
    #[arg(long)]
    pub plugin: String,
    /// The plugin's parameters (TOML), handed to it verbatim. Relative paths in it (a Python
    /// class's `path` and `venv`, say) are relative to this file's folder, as in a bench file.
    #[arg(long)]
    pub plugin_config: Option<PathBuf>,
    /// The run's label: its folder's name and its column in the table (default: the
    /// plugin's name).
    #[arg(long)]
    pub label: Option<String>,
    /// How fast to feed the plugin: `free` (as fast as it takes the messages) or `realtime`
    /// (no faster than simulated time), as a bench file's `pace`.
    #[arg(long, default_value = "free")]
    pub pace: String,
    /// Bound every topic's subscriber queue to this many messages (needs `--pace
    /// realtime`): a message arriving while the plugin is busy beyond it drops the oldest,
    /// as a ROS subscriber does; which were dropped: the run's `dropped.csv`.
    #[arg(long, value_name = "N")]
    pub queue_size: Option<usize>,
    /// Drop exactly the messages this `dropped.csv` (of an earlier run) names: that run's
    /// drops again, whatever this one's speed.
    #[arg(long, value_name = "FILE")]
    pub drops: Option<PathBuf>,
    /// Exit 0 even when the run failed (the results folder says why).
    #[arg(long)]
    pub allow_failures: bool,
    /// Results folder (default: results/run).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value_t = 3600.0)]
    pub timeout_s: f64,
    #[arg(long, default_value_t = 8192)]
    pub memory_limit_mb: u64,
    /// Alignment before APE: none, origin, se3, sim3, 4dof.
    #[arg(long, default_value = "se3")]
    pub align: String,
    /// Feed the plugin from this recording (`vinebench record`, same world and scenario)
    /// instead of the live simulator.
    #[arg(long, value_name = "FILE.mcap")]
    pub dataset: Option<PathBuf>,
    /// More directories to search for plugins.
    #[arg(long = "plugin-dir")]
    pub plugin_dirs: Vec<PathBuf>,
}

pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    run_with(args, None)
}

/// `vinebench run`, or with `localize` a localisation run (`vinebench localize`).
pub fn run_with(
    args: &RunArgs,
    localize: Option<crate::runner::LocalizeSpec>,
) -> anyhow::Result<()> {
    let max_time_s = args.sim.max_time_s()?;
    let dirs = crate::plugins::search_path(&args.plugin_dirs);
    let path = crate::plugins::resolve(&args.plugin, &dirs)?;
    let (params_toml, base_dir) = match &args.plugin_config {
        Some(p) => (
            std::fs::read_to_string(p).with_context(|| p.display().to_string())?,
            crate::plugins::folder_of(p)?,
        ),
        // The worker runs in its run folder: without a file, relative paths are relative
        // to where `vinebench run` was started.
        None => (String::new(), std::env::current_dir()?),
    };
    let pace: crate::runner::Pace = toml::Value::String(args.pace.clone())
        .try_into()
        .map_err(|_| anyhow::anyhow!("--pace {}: expected free or realtime", args.pace))?;
    let queue_size = args.queue_size.map(crate::runner::QueueSize::All);
    if let Some(q) = &queue_size {
        q.check(pace)
            .map_err(|why| anyhow::anyhow!("--queue-size: {why}"))?;
    }
    if let Some(d) = &args.drops {
        crate::runner::read_drops(d)?;
    }
    let align = Align::from_name(&args.align).map_err(|e| anyhow::anyhow!("--align {e}"))?;
    anyhow::ensure!(
        args.timeout_s.is_finite() && args.timeout_s > 0.0,
        "--timeout-s {}: must be positive",
        args.timeout_s
    );
    let label = match &args.label {
        Some(label) => {
            anyhow::ensure!(
                !label.is_empty() && !label.contains(['/', '\\']) && label != "." && label != "..",
                "--label {label:?}: must be a folder name (no slashes)"
            );
            label.clone()
        }
        None => plugin_label(&args.plugin),
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results/run"));
    let world =
        crate::cmd::sim_args::WorkersWorld::new(args.sim.world.as_deref(), args.sim.profile, &out)?;
    let plan = Plan {
        world: world.path().map(PathBuf::from),
        seed: args.sim.seed,
        scenarios: vec![args.sim.scenario.clone()],
        runs: vec![PlannedRun {
            scenario: args.sim.scenario.clone(),
            label: label.clone(),
            plugin: path,
            params_toml,
            pace,
            queue_size,
            drops: args.drops.clone(),
            base_dir: Some(base_dir),
            localize,
            world: None,
        }],
        jobs: 1,
        timeout: Duration::from_secs_f64(args.timeout_s),
        memory_limit_mb: args.memory_limit_mb,
        alignment: align.into(),
        dataset: args.dataset.clone(),
        max_time_s,
        // One run: nothing to share.
        share_simulation: false,
        record_once: None,
        bars: true,
    };
    let outcomes = crate::cmd::bench::bench(
        &plan,
        &out,
        std::slice::from_ref(&label),
        None,
        &Default::default(),
    )?;
    // One run: its failure is the command's failure (the results folder is still written).
    match outcomes.first().map(|r| &r.status) {
        Some(crate::results::RunStatus::Failed(why)) if !args.allow_failures => Err(
            crate::cmd::Exit::failures(format!("{label} on {} failed: {why}", args.sim.scenario))
                .into(),
        ),
        _ => Ok(()),
    }
}

/// A column label for a plugin given by name or path.
pub fn plugin_label(name_or_path: &str) -> String {
    let stem = std::path::Path::new(name_or_path)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| name_or_path.to_owned());
    stem.strip_prefix(std::env::consts::DLL_PREFIX)
        .unwrap_or(&stem)
        .replace('_', "-")
}
