//! `vinebench worker --job FILE` (hidden): one run in its own process, started by the
//! supervisor of `run` and `bench`.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;

use crate::runner::{Job, worker};

#[derive(Debug, Args)]
pub struct WorkerArgs {
    /// The job file written by the supervisor.
    #[arg(long)]
    pub job: PathBuf,
}

pub fn run(args: &WorkerArgs) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(&args.job).with_context(|| args.job.display().to_string())?;
    let job: Job = serde_json::from_str(&text).with_context(|| args.job.display().to_string())?;
    worker::work(&job)
}
