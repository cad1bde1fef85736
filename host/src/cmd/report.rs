//! `vinebench report DIR`: rebuilds `report.html` of a bench's or a sweep's results folder
//! from the files in it (the page the bench or sweep wrote at its end).

use std::path::PathBuf;

use clap::Args;

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// A results folder written by `vinebench bench` or `vinebench sweep`.
    pub dir: PathBuf,
}

pub fn run(args: &ReportArgs) -> anyhow::Result<()> {
    let (path, bytes) = crate::report::rebuild_html(&args.dir)?;
    crate::out!("{} ({bytes} bytes)", path.display());
    Ok(())
}
