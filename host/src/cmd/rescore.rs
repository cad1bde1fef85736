//! `vinebench rescore RUN...`: scores finished runs again with this build's evaluation
//! ([`crate::runner::evaluate`]) from what each run kept — its ground truth, estimate,
//! events and GNSS log — without running its system again: `metrics.json`, the judged
//! `events.json`, `joins.json`, the frames, `ape.csv` and `results.mcap` are written anew
//! (each file whole or not at all). For runs scored before a metric existed, or after a
//! fix to the evaluation; `vinebench sweep FILE --collect` or `vinebench report DIR` then
//! aggregates their folder again.

use std::io::Write as _;
use std::path::PathBuf;

use clap::Args;

use crate::bench_config::Align;
use crate::results::{RunFolder, files};

#[derive(Debug, Args)]
pub struct RescoreArgs {
    /// Run folders (each with its `metrics.json`), e.g. `results/my-sweep/runs/*` or
    /// `results/my-bench/s3/*`.
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// Alignment before APE (none, origin, se3, sim3, 4dof); default: each run's own, from
    /// its `metrics.json`.
    #[arg(long)]
    pub align: Option<String>,
}

pub fn run(args: &RescoreArgs) -> anyhow::Result<()> {
    let forced = args.align.as_deref().map(parse_align).transpose()?;
    let mut failed = 0usize;
    for dir in &args.runs {
        match rescore(dir, forced) {
            Ok(line) => crate::out!("{}: {line}", dir.display()),
            Err(e) => {
                failed += 1;
                // Not eprintln!: a closed standard error must not panic.
                let _ = writeln!(std::io::stderr(), "{}: {e:#}", dir.display());
            }
        }
    }
    if failed > 0 {
        return Err(crate::cmd::Exit::failures(format!(
            "{failed} of {} runs not rescored",
            args.runs.len()
        ))
        .into());
    }
    Ok(())
}

fn parse_align(name: &str) -> anyhow::Result<eval::Alignment> {
    Ok(Align::from_name(name).map_err(anyhow::Error::msg)?.into())
}

/// Scores one run again; says what changed in its APE RMSE.
fn rescore(dir: &std::path::Path, forced: Option<eval::Alignment>) -> anyhow::Result<String> {
    let run = RunFolder::new(dir);
    anyhow::ensure!(
        run.path(files::METRICS).is_file(),
        "not a scored run (no {})",
        files::METRICS
    );
    let before = run.read_metrics()?;
    let alignment = match forced {
        Some(a) => a,
        None => parse_align(&before.alignment)
            .map_err(|e| anyhow::anyhow!("{}: alignment {e}", files::METRICS))?,
    };
    crate::runner::evaluate(&run, alignment)?;
    let after = run.read_metrics()?;
    Ok(format!(
        "ATE RMSE {:.4} m → {:.4} m ({}), horizontal {}",
        before.ape.rmse,
        after.ape.rmse,
        alignment.name(),
        after
            .horizontal_rmse_m
            .map_or("–".to_owned(), |h| format!("{h:.4} m"))
    ))
}
