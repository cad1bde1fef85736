//! `vinebench worker --job FILE` (hidden): one run in its own process, started by the
//! supervisor of `run` and `bench`. `vinebench worker --sensors PLUGIN [--params TOML]`
//! prints the sensors a plugin asks for (for those parameters), so the supervisor can share one simulation between runs without
//! loading any plugin into its own process.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;

use crate::runner::{Job, worker};

#[derive(Debug, Args)]
pub struct WorkerArgs {
    /// The job file written by the supervisor.
    #[arg(long, required_unless_present_any = ["sensors", "describe", "check"])]
    pub job: Option<PathBuf>,
    /// Print the sensors this plugin library asks for (one line, comma-separated) and exit.
    #[arg(long, conflicts_with = "job")]
    pub sensors: Option<PathBuf>,
    /// Print the plugin library's name, version and door (tab-separated) and exit.
    #[arg(long, conflicts_with_all = ["job", "sensors"])]
    pub describe: Option<PathBuf>,
    /// Run one check of `vinebench check-plugin` on `--plugin` (crate::conformance).
    #[arg(long, conflicts_with_all = ["job", "sensors", "describe"], requires = "plugin")]
    pub check: Option<String>,
    /// With `--check`: the plugin library.
    #[arg(long)]
    pub plugin: Option<PathBuf>,
    /// With `--check`: the world file (default: the built-in world).
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// With `--check`: the scenario whose route is fed.
    #[arg(long, default_value = "s1")]
    pub scenario: String,
    /// With `--check`: simulated seconds of the route check.
    #[arg(long, default_value_t = 8.0)]
    pub route_s: f64,
    /// With `--sensors` or `--check`: the plugin's parameter table (TOML), for a plugin
    /// whose sensors depend on it.
    #[arg(long, default_value = "")]
    pub params: String,
}

pub fn run(args: &WorkerArgs) -> anyhow::Result<()> {
    if let Some(plugin) = &args.describe {
        let loaded = plugin_api::load(plugin)?;
        crate::out!(
            "{}\t{}\t{}",
            loaded.name,
            loaded.version,
            loaded.door().name()
        );
        return Ok(());
    }
    if let Some(name) = &args.check {
        let check = crate::conformance::check_named(name)?;
        let plugin = args.plugin.as_deref().expect("clap requires --plugin");
        let subject = crate::conformance::subject_from_args(
            plugin,
            &args.params,
            args.world.as_deref(),
            &args.scenario,
            args.route_s,
        )?;
        exit_with_parent();
        return crate::conformance::run_check(check, &subject);
    }
    if let Some(plugin) = &args.sensors {
        let loaded = plugin_api::load(plugin)?;
        let requirements = loaded
            .requirements_for(&args.params)
            .map_err(|e| anyhow::anyhow!("plugin {}: {e}", loaded.name))?;
        let names: Vec<&str> = requirements.sensors.iter().map(|k| k.name()).collect();
        crate::out!("{}", names.join(","));
        return Ok(());
    }
    let path = args
        .job
        .as_ref()
        .expect("clap requires --job without --sensors");
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let job: Job = serde_json::from_str(&text).with_context(|| path.display().to_string())?;
    exit_with_parent();
    worker::work(&job)
}

/// A worker whose supervisor is gone (killed with SIGKILL, which it cannot pass on) has no
/// one to report to: it exits rather than run on unseen. Checked twice a second, since the
/// orphan is adopted by another process and its parent id changes.
fn exit_with_parent() {
    let parent = std::os::unix::process::parent_id();
    std::thread::spawn(move || {
        loop {
            std::thread::sleep(std::time::Duration::from_millis(500));
            if std::os::unix::process::parent_id() != parent {
                eprintln!("the supervising process is gone; stopping");
                // The watchdog thread has no caller to return to: it ends the orphan itself.
                #[allow(clippy::disallowed_methods)]
                std::process::exit(3);
            }
        }
    });
}
