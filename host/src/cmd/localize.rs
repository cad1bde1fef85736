//! `vinebench localize`: a plugin started from a map built earlier (a mapping run's
//! `map.bin` or `grid.yaml`, or the world's surveyed grid), on a route and world of the
//! user's choosing, judged as a localisation run (`runner::localize`, issue 46).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;

use crate::cmd::run::RunArgs;
use crate::cmd::sim_args::SimArgs;
use crate::results::files;
use crate::runner::{GuessSpec, Kidnap, LocalizeSpec, MapSource};

#[derive(Debug, Args)]
pub struct LocalizeArgs {
    /// The mapping run's folder (`results/run/s3/rtabmap`, or a results folder holding one
    /// run): its plugin localises in its `map.bin`, in the world it was driven in, unless
    /// `--plugin`, `--world` or `--grid` say otherwise.
    #[arg(long, value_name = "RUN_DIR", required_unless_present = "surveyed")]
    pub map: Option<PathBuf>,
    /// Localise in the mapping run's occupancy grid (`grid.yaml`, `grid.pgm`) instead of its
    /// `map.bin`: for a plugin that localises in a 2D grid (`--plugin amcl`).
    #[arg(long, requires = "map")]
    pub grid: bool,
    /// Localise in the world's surveyed grid (at the 2D lidars' height) instead of a mapping
    /// run's map: what a lab builds from a survey.
    #[arg(long, conflicts_with = "map")]
    pub surveyed: bool,
    /// With `--surveyed`: survey this world file (the block as it was when surveyed, e.g. at
    /// another growth stage) instead of the run's own world.
    #[arg(long, value_name = "FILE", requires = "surveyed")]
    pub survey_world: Option<PathBuf>,
    #[command(flatten)]
    pub sim: SimArgs,
    /// Plugin name or library (default: the mapping run's).
    #[arg(long)]
    pub plugin: Option<String>,
    /// The plugin's parameters, TOML (default: the mapping run's).
    #[arg(long)]
    pub plugin_config: Option<PathBuf>,
    /// A guess of the start in the map's frame, `x,y,yaw,sigma_xy,sigma_yaw` (m, rad);
    /// without one the start is unknown (global localisation).
    #[arg(long, value_name = "X,Y,YAW,SXY,SYAW", allow_hyphen_values = true)]
    pub initial_guess: Option<String>,
    /// Kidnap the robot: at `AT` seconds carry it `SKIP` seconds ahead along its route
    /// without telling the plugin: the truth jumps, the wheel odometry does not.
    #[arg(long, value_name = "AT,SKIP")]
    pub kidnap: Option<String>,
    /// The run's label (default: the plugin's name).
    #[arg(long)]
    pub label: Option<String>,
    /// Exit 0 even when the run failed (the results folder says why).
    #[arg(long)]
    pub allow_failures: bool,
    /// Results folder (default: results/localize).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value_t = 3600.0)]
    pub timeout_s: f64,
    #[arg(long, default_value_t = 8192)]
    pub memory_limit_mb: u64,
    /// More directories to search for plugins.
    #[arg(long = "plugin-dir")]
    pub plugin_dirs: Vec<PathBuf>,
}

/// The one run folder under `dir` (itself, or its single `scenario/label` run).
fn mapping_run(dir: &Path) -> anyhow::Result<PathBuf> {
    if dir.join(files::RUN).is_file() {
        return Ok(std::path::absolute(dir)?);
    }
    let mut found = Vec::new();
    for scenario in std::fs::read_dir(dir).with_context(|| dir.display().to_string())? {
        let scenario = scenario?.path();
        if !scenario.is_dir() {
            continue;
        }
        for run in std::fs::read_dir(&scenario)? {
            let run = run?.path();
            if run.join(files::RUN).is_file() {
                found.push(run);
            }
        }
    }
    match found.as_slice() {
        [one] => Ok(std::path::absolute(one)?),
        [] => anyhow::bail!(
            "--map {}: not a run folder (no run.toml in it or below)",
            dir.display()
        ),
        _ => anyhow::bail!(
            "--map {}: {} runs in it; name one (e.g. {})",
            dir.display(),
            found.len(),
            found[0].display()
        ),
    }
}

fn numbers<const N: usize>(flag: &str, text: &str, shape: &str) -> anyhow::Result<[f64; N]> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("{flag} {text}: expected {shape}"))?;
    values
        .try_into()
        .map_err(|_| anyhow::anyhow!("{flag} {text}: expected {shape}"))
}

pub fn run(args: &LocalizeArgs) -> anyhow::Result<()> {
    let mapping = args.map.as_deref().map(mapping_run).transpose()?;
    let run_toml: Option<toml::Table> = mapping
        .as_ref()
        .map(|dir| -> anyhow::Result<toml::Table> {
            let path = dir.join(files::RUN);
            let text =
                std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
            toml::from_str(&text)
                .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message().trim()))
        })
        .transpose()?;
    let mapped_plugin = run_toml
        .as_ref()
        .and_then(|t| t.get("plugin"))
        .and_then(|p| p.as_table());
    let plugin = match (&args.plugin, mapped_plugin) {
        (Some(p), _) => p.clone(),
        (None, Some(p)) => p
            .get("path")
            .or_else(|| p.get("name"))
            .and_then(|v| v.as_str())
            .context("the mapping run's run.toml names no plugin; give --plugin")?
            .to_owned(),
        (None, None) => anyhow::bail!("--surveyed needs --plugin (e.g. amcl)"),
    };
    let map = match (&mapping, args.grid) {
        (None, _) => MapSource::Surveyed {
            world: args
                .survey_world
                .as_deref()
                .map(std::path::absolute)
                .transpose()?,
        },
        (Some(dir), true) => {
            let yaml = dir.join(files::GRID_YAML);
            anyhow::ensure!(
                yaml.is_file(),
                "--map {} --grid: the run saved no occupancy grid ({} is missing)",
                dir.display(),
                files::GRID_YAML
            );
            MapSource::Grid { yaml }
        }
        (Some(dir), false) => {
            let path = dir.join(files::SAVED_MAP);
            anyhow::ensure!(
                path.is_file(),
                "--map {}: the run saved no map ({} is missing: its plugin cannot localise, or it ran before maps were saved); --grid uses its occupancy grid",
                dir.display(),
                files::SAVED_MAP
            );
            MapSource::Saved { path }
        }
    };
    // The map checked whole before anything runs: a damaged or foreign one leaves no
    // results. Whose it must be: the mapping run's plugin, unless another is named (whose
    // name only its worker learns: it checks again there).
    let expected = match (&args.plugin, mapped_plugin) {
        (None, Some(p)) => p.get("name").and_then(|v| v.as_str()).map(str::to_owned),
        _ => None,
    };
    match &map {
        MapSource::Saved { path } => {
            let who = expected.clone().unwrap_or_else(|| plugin.clone());
            crate::results::map_file::read_map(path, expected.as_deref()).map_err(|e| {
                anyhow::anyhow!("{}", crate::results::map_file::with_plugin(e, &who))
            })?;
        }
        MapSource::Grid { yaml } => {
            crate::results::read_grid(yaml)?;
        }
        MapSource::Surveyed { world: Some(file) } => {
            sim::SimConfig::load(Some(file))?;
        }
        MapSource::Surveyed { world: None } => {}
    }
    let initial_guess = args
        .initial_guess
        .as_deref()
        .map(|text| {
            let [x, y, yaw, sigma_xy_m, sigma_yaw_rad] =
                numbers::<5>("--initial-guess", text, "x,y,yaw,sigma_xy,sigma_yaw")?;
            Ok::<_, anyhow::Error>(GuessSpec {
                x,
                y,
                yaw,
                sigma_xy_m,
                sigma_yaw_rad,
            })
        })
        .transpose()?;
    let kidnap = args
        .kidnap
        .as_deref()
        .map(|text| {
            let [at_s, skip_s] = numbers::<2>("--kidnap", text, "at,skip (seconds)")?;
            Ok::<_, anyhow::Error>(Kidnap { at_s, skip_s })
        })
        .transpose()?;
    let spec = LocalizeSpec {
        map,
        mapping_run: mapping.clone(),
        initial_guess,
        kidnap,
    };
    spec.check().map_err(|why| anyhow::anyhow!("{why}"))?;

    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results/localize"));
    // The mapping run's parameters, when the plugin is its own and no file is given.
    let params_file = match (&args.plugin_config, mapped_plugin, &args.plugin) {
        (Some(p), _, _) => Some(p.clone()),
        (None, Some(p), None) => match p.get("params").and_then(|v| v.as_table()) {
            Some(params) if !params.is_empty() => {
                // Read once when the run starts; removed when this command ends.
                let path = std::env::temp_dir().join(format!(
                    "vinebench-mapping-params-{}.toml",
                    std::process::id()
                ));
                std::fs::write(&path, toml::to_string(params)?)
                    .with_context(|| path.display().to_string())?;
                Some(path)
            }
            _ => None,
        },
        _ => None,
    };
    let mut sim = args.sim.clone();
    if sim.world.is_none()
        && let Some(dir) = &mapping
    {
        // The world the map was built in, resolved (`world.toml` of the mapping run).
        sim.world = Some(dir.join(files::WORLD));
    }
    let label = args
        .label
        .clone()
        .unwrap_or_else(|| crate::cmd::run::plugin_label(&plugin));
    let run_args = RunArgs {
        sim,
        plugin,
        plugin_config: params_file,
        label: Some(label),
        pace: "free".into(),
        queue_size: None,
        drops: None,
        allow_failures: args.allow_failures,
        out: Some(out),
        timeout_s: args.timeout_s,
        memory_limit_mb: args.memory_limit_mb,
        align: "se3".into(),
        dataset: None,
        plugin_dirs: args.plugin_dirs.clone(),
    };
    let result = crate::cmd::run::run_with(&run_args, Some(spec));
    if args.plugin_config.is_none()
        && let Some(p) = &run_args.plugin_config
    {
        let _ = std::fs::remove_file(p);
    }
    result
}
