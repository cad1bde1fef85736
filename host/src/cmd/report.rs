//! `vinebench report DIR`: rebuilds `report.html` of a bench's or a sweep's results folder
//! from the files in it (the page the bench or sweep wrote at its end). With `--figures
//! OUT` and a run's folder: that run's figures for a document.

use std::path::PathBuf;

use clap::Args;

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// A results folder written by `vinebench bench` or `vinebench sweep`; with --figures,
    /// one run's folder (e.g. RESULTS/s3/orbslam2).
    pub dir: PathBuf,
    /// Write the run's figures into this folder instead: route.svg (the aligned estimate,
    /// its loops and wrong joins over ground truth), error.svg (the error along the route
    /// with the loops and wrong joins marked) and frames/ (the pictures of its false loops
    /// and wrong joins).
    #[arg(long, value_name = "OUT")]
    pub figures: Option<PathBuf>,
    /// With --figures: the system's name in the titles (default: the plugin's).
    #[arg(long, requires = "figures")]
    pub label: Option<String>,
    /// With --figures: the frames made this many times smaller each way (a box filter), for
    /// documents kept in git.
    #[arg(long, requires = "figures", default_value_t = 1)]
    pub frame_scale: u32,
}

pub fn run(args: &ReportArgs) -> anyhow::Result<()> {
    if let Some(out) = &args.figures {
        let run = crate::report::load::load_run_folder(&args.dir, args.label.as_deref())?;
        for path in crate::report::figures::write_run_figures(&run, out, args.frame_scale)? {
            crate::out!("{}", path.display());
        }
        return Ok(());
    }
    let (path, bytes) = crate::report::rebuild_html(&args.dir)?;
    crate::out!("{} ({bytes} bytes)", path.display());
    Ok(())
}
