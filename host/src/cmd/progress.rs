//! Progress of a bench or sweep: a bar on a terminal, else one line per finished run (so that
//! `vinebench bench FILE > log` says how far it is).

use std::io::IsTerminal as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::results::{RunOutcome, RunStatus};

/// Counts finished runs and says so.
#[derive(Debug)]
pub struct Progress {
    total: usize,
    done: AtomicUsize,
    started: Instant,
    /// On a terminal: the bar, or nothing when the runner draws its own per run.
    bar: Option<ProgressBar>,
    terminal: bool,
}

impl Progress {
    /// A bar with ETA on a terminal (`own_bar`; else the runner's bars show there), one
    /// line per finished run elsewhere.
    pub fn new(total: usize, own_bar: bool) -> Self {
        let terminal = std::io::stderr().is_terminal();
        let bar = (terminal && own_bar).then(|| {
            let bar = ProgressBar::new(total as u64);
            bar.set_style(
                ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {pos}/{len} runs, ETA {eta}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            bar
        });
        Self {
            total,
            done: AtomicUsize::new(0),
            started: Instant::now(),
            bar,
            terminal,
        }
    }

    /// One run, described by `what` (`s0/lio-sam`, a sweep's cell), has ended.
    pub fn finished(&self, what: &str, outcome: &RunOutcome) {
        let k = self.done.fetch_add(1, Ordering::SeqCst) + 1;
        let result = match &outcome.status {
            RunStatus::Ok => match outcome.folder.read_metrics() {
                Ok(m) => format!("ok, ATE RMSE {:.3} m", m.ape.rmse),
                Err(_) => "ok".to_owned(),
            },
            RunStatus::Failed(why) => format!("failed: {why}"),
        };
        let line = format!("[{k}/{}] {what}: {result}", self.total);
        match &self.bar {
            Some(bar) => {
                bar.println(line);
                bar.inc(1);
            }
            None if self.terminal => {}
            None => {
                let elapsed = self.started.elapsed().as_secs_f64();
                let eta = elapsed / k as f64 * (self.total - k) as f64;
                println!("{line} (elapsed {elapsed:.0} s, ETA {eta:.0} s)");
            }
        }
    }

    /// `filed` runs are done (a Slurm sweep, which sees them appear).
    pub fn set(&self, filed: usize) {
        if let Some(bar) = &self.bar {
            bar.set_position(filed as u64);
        }
    }

    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}
