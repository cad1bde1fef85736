//! Progress of a bench or sweep: a bar on a terminal, else one line per finished run (so that
//! `vinebench bench FILE > log` says how far it is).

use std::io::IsTerminal as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::results::{RunOutcome, RunStatus};

/// Counts finished runs and says so.
#[derive(Debug)]
pub struct Progress {
    total: usize,
    done: AtomicUsize,
    /// Each run's weight in the estimate of the time left (its route's simulated seconds),
    /// and the weight of those done.
    weights: Vec<f64>,
    done_weight: Mutex<f64>,
    started: Instant,
    /// On a terminal: the bar, or nothing when the runner draws its own per run.
    bar: Option<ProgressBar>,
    terminal: bool,
}

impl Progress {
    /// A bar with ETA on a terminal (`own_bar`; else the runner's bars show there), one
    /// line per finished run elsewhere. `weights`: each run's share of the work (the time
    /// left is estimated as the time taken so far per unit of weight done); `None`: equal.
    pub fn new(total: usize, weights: Option<Vec<f64>>, own_bar: bool) -> Self {
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
            weights: weights.unwrap_or_else(|| vec![1.0; total]),
            done_weight: Mutex::new(0.0),
            started: Instant::now(),
            bar,
            terminal,
        }
    }

    /// Run `index`, described by `what` (`s0/lio-sam`, a sweep's cell), has ended.
    pub fn finished(&self, index: usize, what: &str, outcome: &RunOutcome) {
        let k = self.done.fetch_add(1, Ordering::SeqCst) + 1;
        let done = {
            let mut w = self
                .done_weight
                .lock()
                .expect("no panics while holding the lock");
            *w += self.weights.get(index).copied().unwrap_or(0.0);
            *w
        };
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
                let all: f64 = self.weights.iter().sum();
                let eta = if done > 0.0 {
                    elapsed / done * (all - done).max(0.0)
                } else {
                    elapsed / k as f64 * (self.total - k) as f64
                };
                crate::out!("{line} (elapsed {elapsed:.0} s, ETA {eta:.0} s)");
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
