//! `vinebench world`: the world a run would see, every key resolved (the built-in defaults,
//! the profile's keys, the file's own), as TOML on standard output: the `world.toml` a run
//! folder keeps. `--profile` puts the world under another rung of the ladder; the output
//! can be given to `run --world` as it is.

use std::path::PathBuf;

use clap::Args;
use sim::SimConfig;
use sim::config::Profile;

#[derive(Debug, Args)]
pub struct WorldArgs {
    /// Simulator configuration (configs/world.toml shape); defaults are built in.
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// The sensors' models, whatever the file's `profile` says: ideal, paper, typical or field
    /// (configs/profiles/).
    #[arg(long, value_parser = crate::cmd::sim_args::parse_profile)]
    pub profile: Option<Profile>,
}

pub fn run(args: &WorldArgs) -> anyhow::Result<()> {
    let config = SimConfig::load_as(args.world.as_deref(), args.profile)?;
    crate::out!("{}", config.to_toml_string().trim_end());
    Ok(())
}
