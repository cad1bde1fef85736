//! What every command that simulates one scenario takes (`simulate`, `record`, `export`,
//! `run`), and the one check of a route limit given on the command line.

use std::path::PathBuf;

use clap::Args;
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
        let config = SimConfig::load(self.world.as_deref())?;
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
