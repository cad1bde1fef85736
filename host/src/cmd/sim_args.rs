//! What every command that simulates one scenario takes (`simulate`, `record`, `export`,
//! `run`), and the one check of a route limit given on the command line.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use clap::Args;
use sim::config::Profile;
use sim::{SimConfig, Simulation};

/// Scenario, world, seed and route limit.
#[derive(Debug, Clone, Args)]
pub struct SimArgs {
    /// Scenario: s0, s1, s2, s3 or a route named in the world file.
    #[arg(long)]
    pub scenario: String,
    /// Simulator configuration (configs/world.toml shape); defaults are built in.
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// The sensors' models, whatever the world file's `profile` says: ideal, paper, typical
    /// or field (configs/profiles/).
    #[arg(long, value_parser = parse_profile)]
    pub profile: Option<Profile>,
    /// Seed of all sensor noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Stop after this many simulated seconds (default: the whole route).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub max_time: Option<f64>,
}

/// A scenario's simulation, ready to stream.
#[derive(Debug)]
pub struct Simulated {
    pub config: SimConfig,
    pub sim: Simulation,
    /// Where the stream stops: the route's end or the limit, ns.
    pub end_ns: i64,
}

impl SimArgs {
    /// `--max-time` checked.
    pub fn max_time_s(&self) -> anyhow::Result<Option<f64>> {
        max_time_flag(self.max_time)
    }

    /// Loads the world and starts the scenario's simulation.
    pub fn simulate(&self) -> anyhow::Result<Simulated> {
        let max_time_s = self.max_time_s()?;
        let config = SimConfig::load_as(self.world.as_deref(), self.profile)?;
        let sim = Simulation::new(&config, &self.scenario, self.seed)?;
        let end_ns = crate::runner::route_end_ns(sim.duration_ns(), max_time_s)?;
        Ok(Simulated {
            config,
            sim,
            end_ns,
        })
    }
}

/// `--max-time` checked: a positive number of seconds, or the error naming the flag.
pub fn max_time_flag(seconds: Option<f64>) -> anyhow::Result<Option<f64>> {
    if let Some(s) = seconds {
        crate::runner::check_max_time(s).map_err(|why| anyhow::anyhow!("--max-time {s}: {why}"))?;
    }
    Ok(seconds)
}

/// A profile's name from the command line, or the error naming the known ones.
pub fn parse_profile(name: &str) -> Result<Profile, String> {
    Profile::ALL
        .into_iter()
        .find(|p| p.name() == name)
        .ok_or_else(|| {
            let names: Vec<&str> = Profile::ALL.iter().map(|p| p.name()).collect();
            format!("unknown profile '{name}' (known: {})", names.join(", "))
        })
}

/// A world put under another profile (`--profile`) for the worker processes to read: the
/// world resolved, written beside the results folder `out` (`<out>.world-<profile>.toml`),
/// removed when dropped. Without a profile, the world file as it is.
#[derive(Debug)]
pub struct WorkersWorld {
    path: Option<PathBuf>,
    written: bool,
}

impl WorkersWorld {
    pub fn new(world: Option<&Path>, profile: Option<Profile>, out: &Path) -> anyhow::Result<Self> {
        let Some(profile) = profile else {
            return Ok(Self {
                path: world.map(Path::to_owned),
                written: false,
            });
        };
        let config = SimConfig::load_as(world, Some(profile))?;
        let path = PathBuf::from(format!("{}.world-{}.toml", out.display(), profile.name()));
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
        }
        crate::results::write_atomic(&path, config.to_toml_string().as_bytes())?;
        Ok(Self {
            path: Some(path),
            written: true,
        })
    }

    /// The world file the workers read (`None`: the built-in world).
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }
}

impl Drop for WorkersWorld {
    fn drop(&mut self) {
        if let (true, Some(p)) = (self.written, &self.path) {
            let _ = std::fs::remove_file(p);
        }
    }
}
