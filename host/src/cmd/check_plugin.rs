//! `vinebench check-plugin TARGET`: the conformance checks of [`crate::conformance`] on one
//! plugin (a name on the search path or a library's path, with `--params FILE`) or on every
//! `[[plugins]]` entry of a bench file (each with its own parameters), printed as a pass /
//! fail list with the plugin's own messages under each failure.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use clap::Args;

use crate::bench_config::BenchConfig;
use crate::cmd::Exit;
use crate::conformance::{Outcome, Subject, check_all};

#[derive(Debug, Args)]
pub struct CheckPluginArgs {
    /// A plugin's name (searched for), a library's path, or a bench file (.toml) whose
    /// `[[plugins]]` entries are checked each with its own parameters.
    pub target: String,
    /// The plugin's parameters (TOML), handed to it verbatim; relative paths in it are
    /// relative to this file's folder. Not with a bench file.
    #[arg(long, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Simulator configuration whose rig and route feed the plugin (default: built in).
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// The scenario whose route the route check feeds.
    #[arg(long, default_value = "s1")]
    pub scenario: String,
    /// Simulated seconds of the route check.
    #[arg(long, value_name = "SECONDS", default_value_t = 8.0)]
    pub route_s: f64,
    /// A check that takes longer than this, seconds, has hung.
    #[arg(long, default_value_t = 120.0)]
    pub timeout_s: f64,
    /// More directories to search for plugins.
    #[arg(long = "plugin-dir")]
    pub plugin_dirs: Vec<PathBuf>,
}

/// One plugin to check and how to name it.
struct Target {
    label: String,
    subject: Subject,
}

pub fn run(args: &CheckPluginArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.timeout_s.is_finite() && args.timeout_s > 0.0,
        "--timeout-s {}: must be positive",
        args.timeout_s
    );
    anyhow::ensure!(
        args.route_s.is_finite() && args.route_s > 0.0,
        "--route-s {}: must be positive",
        args.route_s
    );
    // The world and scenario are checked here, so that a typo is one line, not a failed
    // check per plugin.
    let config = sim::SimConfig::load(args.world.as_deref())?;
    if !config.scenarios.contains_key(&args.scenario) {
        let known: Vec<&str> = config.scenarios.keys().map(String::as_str).collect();
        anyhow::bail!(
            "--scenario {}: unknown (known: {})",
            args.scenario,
            known.join(", ")
        );
    }
    let world = args.world.as_ref().map(std::path::absolute).transpose()?;
    let subject = |plugin: PathBuf, params_toml: String, base_dir: Option<PathBuf>| Subject {
        plugin,
        params_toml,
        base_dir,
        world: world.clone(),
        scenario: args.scenario.clone(),
        route_s: args.route_s,
    };
    let targets: Vec<Target> = if args.target.ends_with(".toml") {
        anyhow::ensure!(
            args.params.is_none(),
            "--params: a bench file gives each plugin its parameters"
        );
        let file = Path::new(&args.target);
        let cfg = BenchConfig::from_file(file)?;
        cfg.resolve_plugins(file)?
            .into_iter()
            .map(|p| Target {
                label: p.label,
                subject: subject(p.library, p.params_toml, Some(p.base_dir)),
            })
            .collect()
    } else {
        let dirs = crate::plugins::search_path(&args.plugin_dirs);
        let library = crate::plugins::resolve(&args.target, &dirs)?;
        let (params_toml, base_dir) = match &args.params {
            Some(p) => (
                std::fs::read_to_string(p).with_context(|| p.display().to_string())?,
                Some(crate::plugins::folder_of(p)?),
            ),
            None => (String::new(), None),
        };
        vec![Target {
            label: crate::cmd::run::plugin_label(&args.target),
            subject: subject(library, params_toml, base_dir),
        }]
    };
    let timeout = Duration::from_secs_f64(args.timeout_s);
    let (mut passed, mut failed) = (0, 0);
    for target in &targets {
        crate::out!("{} ({})", target.label, target.subject.plugin.display());
        let outcomes = check_all(&target.subject, timeout, &mut |o: &Outcome| {
            crate::out!(
                "  {}  {:<20} {}",
                if o.passed { "PASS" } else { "FAIL" },
                o.check.name(),
                o.summary
            );
            for line in &o.messages {
                crate::out!("        | {line}");
            }
        })?;
        let failures = outcomes.iter().filter(|o| !o.passed).count();
        passed += outcomes.len() - failures;
        failed += failures;
        if outcomes.len() < crate::conformance::Check::ALL.len() {
            crate::out!("  (the other checks need a library that loads)");
        }
    }
    crate::out!("{passed} of {} checks passed", passed + failed);
    if failed > 0 {
        return Err(Exit::failures(format!("check-plugin: {failed} check(s) failed")).into());
    }
    Ok(())
}
