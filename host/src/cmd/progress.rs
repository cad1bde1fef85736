//! Progress of a bench or sweep: a bar on a terminal, else one line per finished run (so that
//! `vinebench bench FILE > log` says how far it is).

use std::collections::BTreeMap;
use std::io::IsTerminal as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::results::{RunOutcome, RunStatus};

/// Counts finished runs and says so, with an estimate of the time left.
///
/// The estimate: every run has a predicted duration (its route's simulated seconds times
/// its system's wall seconds per simulated second in the previous results, where there
/// are any, else times 1); the finished runs' measured durations (`timing.json`'s
/// `wall_s`) against their predictions scale the predictions of the rest, which share
/// `jobs` slots: time left = max(sum / jobs, the longest). Where the runner said how the
/// runs start ([`Progress::set_schedule`]), a group's runs count as one, as long as its
/// longest prediction, for the slots it takes (a shared simulation's runs end together),
/// and a group with a finished run as ended. Runs measured before predict themselves from
/// the first finished run on; a route length alone cannot tell a camera system's hour from
/// a baseline's seconds.
///
/// Without previous results ([`Progress::by_system`]) each system's speed is measured as it
/// runs instead: its wall seconds per simulated second from its ended runs, else from how
/// far its running ones got in how long (`runner::OnProgress`); a run's time left is its
/// route left times its system's speed, a system not seen yet takes the mean of those seen.
#[derive(Debug)]
pub struct Progress {
    total: usize,
    done: AtomicUsize,
    predicted: Vec<f64>,
    jobs: usize,
    /// Which runs have ended, and the sums of their predicted and measured durations.
    ended: Mutex<(Vec<bool>, f64, f64)>,
    /// Per system: each run's route, simulated seconds, and its system's label; empty when
    /// the predictions came from previous results.
    systems: Vec<(f64, String)>,
    /// Per run: its measured duration once ended, and how far it had got when first and
    /// last seen running (seconds since the start, fraction of its route).
    seen: Mutex<Vec<Seen>>,
    /// How the runs start, once the runner has said (`runner::Schedule`).
    schedule: Mutex<Option<crate::runner::Schedule>>,
    started: Instant,
    /// On a terminal: the bar, or nothing when the runner draws its own per run.
    bar: Option<ProgressBar>,
    terminal: bool,
}

impl Progress {
    /// A bar with ETA on a terminal (`own_bar`; else the runner's bars show there), one
    /// line per finished run elsewhere. `predicted`: each run's predicted duration, seconds
    /// (`None`: equal); `jobs`: the runs that run at once.
    pub fn new(total: usize, predicted: Option<Vec<f64>>, jobs: usize, own_bar: bool) -> Self {
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
            predicted: predicted.unwrap_or_else(|| vec![1.0; total]),
            jobs: jobs.max(1),
            ended: Mutex::new((vec![false; total], 0.0, 0.0)),
            systems: Vec::new(),
            seen: Mutex::new(vec![Seen::default(); total]),
            schedule: Mutex::new(None),
            started: Instant::now(),
            bar,
            terminal,
        }
    }

    /// Estimates by each system's speed measured as it runs (no previous results): run `i`
    /// is fed `runs[i].0` simulated seconds by the system labelled `runs[i].1`.
    pub fn by_system(mut self, runs: Vec<(f64, String)>) -> Self {
        if runs.len() == self.total {
            self.systems = runs;
        }
        self
    }

    /// Run `index` has been fed the fraction `f` of its route (`runner::OnProgress`).
    pub fn observe(&self, index: usize, f: f64) {
        self.observe_at(index, f, self.started.elapsed().as_secs_f64());
    }

    /// [`Progress::observe`] at `t` seconds since the start.
    fn observe_at(&self, index: usize, f: f64, t: f64) {
        let mut seen = self.seen.lock().expect("no panics while holding the lock");
        if let Some(s) = seen.get_mut(index)
            && f.is_finite()
        {
            s.first.get_or_insert((t, f));
            s.last = Some((t, f));
        }
    }

    /// The time left by each system's measured speed ([`Progress::by_system`]); `None`
    /// while no system's speed is known.
    fn time_left_by_system(&self, ended: &[bool]) -> Option<f64> {
        let seen = self.seen.lock().expect("no panics while holding the lock");
        // Wall seconds per simulated second, per system: its ended runs' (all of them
        // together), else its running runs' progress so far (the one furthest on).
        let mut cost: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
        for (i, (route_s, system)) in self.systems.iter().enumerate() {
            if let Some(wall) = seen[i].measured.filter(|_| ended[i]) {
                let c = cost.entry(system).or_insert((0.0, 0.0));
                *c = (c.0 + wall, c.1 + route_s);
            }
        }
        for (i, (route_s, system)) in self.systems.iter().enumerate() {
            if ended[i] || cost.contains_key(system.as_str()) {
                continue;
            }
            if let (Some((t0, f0)), Some((t1, f1))) = (seen[i].first, seen[i].last)
                && f1 - f0 >= MIN_SEEN
                && t1 > t0
            {
                let fed = (f1 - f0) * route_s;
                let c = cost.entry(system).or_insert((0.0, 0.0));
                if c.1 < fed {
                    *c = (t1 - t0, fed);
                }
            }
        }
        let cost: BTreeMap<&str, f64> = cost
            .into_iter()
            .filter(|(_, (_, s))| *s > 0.0)
            .map(|(k, (w, s))| (k, w / s))
            .collect();
        if cost.is_empty() {
            return None;
        }
        let mean = cost.values().sum::<f64>() / cost.len() as f64;
        let left: Vec<f64> = self
            .systems
            .iter()
            .enumerate()
            .map(|(i, (route_s, system))| {
                if ended[i] {
                    return 0.0;
                }
                let fed = seen[i].last.map_or(0.0, |(_, f)| f.clamp(0.0, 1.0));
                cost.get(system.as_str()).copied().unwrap_or(mean) * route_s * (1.0 - fed)
            })
            .collect();
        Some(self.packed(&left, &|_| true))
    }

    /// The time `left` (each run's, 0 for an ended one) takes on the `jobs` slots: per
    /// group of the runner's schedule that is `open`, its longest run for the slots it takes
    /// (its runs end together), else per run; max(the sum over the slots, the longest).
    fn packed(&self, left: &[f64], open: &dyn Fn(&[usize]) -> bool) -> f64 {
        let schedule = self
            .schedule
            .lock()
            .expect("no panics while holding the lock");
        let (sum, longest) = match schedule.as_ref() {
            Some(groups) => groups
                .iter()
                .filter(|(runs, _)| open(runs))
                .map(|(runs, slots)| {
                    let d = runs
                        .iter()
                        .filter_map(|&i| left.get(i))
                        .copied()
                        .fold(0.0, f64::max);
                    (d * *slots as f64, d)
                })
                .fold((0.0, 0.0), |(s, l), (w, d)| (s + w, f64::max(l, d))),
            None => (left.iter().sum(), left.iter().copied().fold(0.0, f64::max)),
        };
        (sum / self.jobs as f64).max(longest)
    }

    /// How the runs will start (from the runner, before any does).
    pub fn set_schedule(&self, schedule: &crate::runner::Schedule) {
        *self
            .schedule
            .lock()
            .expect("no panics while holding the lock") = Some(schedule.clone());
    }

    /// The time left after run `index` ended having taken `measured_s` (its `wall_s`;
    /// `None`: unknown, its prediction stands), seconds.
    fn time_left(&self, index: usize, measured_s: Option<f64>, elapsed_s: f64, k: usize) -> f64 {
        let mut ended = self.ended.lock().expect("no panics while holding the lock");
        let (flags, predicted_sum, measured_sum) = &mut *ended;
        // An index out of range or already ended (runs that weigh the same, reported in
        // any order): the first run not yet ended.
        let index = if flags.get(index) == Some(&false) {
            index
        } else {
            flags.iter().position(|f| !f).unwrap_or(index)
        };
        if let Some(flag) = flags.get_mut(index) {
            *flag = true;
        }
        if !self.systems.is_empty() {
            if let Some(s) = self
                .seen
                .lock()
                .expect("no panics while holding the lock")
                .get_mut(index)
            {
                s.measured = measured_s.filter(|m| m.is_finite() && *m > 0.0);
            }
            if let Some(left) = self.time_left_by_system(flags) {
                return left;
            }
        }
        let predicted = self.predicted.get(index).copied().unwrap_or(0.0);
        if let Some(m) = measured_s.filter(|m| m.is_finite() && *m > 0.0)
            && predicted > 0.0
        {
            *predicted_sum += predicted;
            *measured_sum += m;
        }
        let left: Vec<f64> = flags
            .iter()
            .zip(&self.predicted)
            .map(|(ended, p)| if *ended { 0.0 } else { *p })
            .collect();
        if *predicted_sum <= 0.0 {
            // Nothing measured: the time so far per run, as many runs again.
            let runs_left = flags.iter().filter(|e| !**e).count();
            return elapsed_s / k as f64 * runs_left as f64 / self.jobs as f64;
        }
        let scale = *measured_sum / *predicted_sum;
        // Per group not yet begun to end: its longest run, for the slots it takes.
        scale
            * self.packed(&left, &|runs| {
                runs.iter().all(|&i| flags.get(i) == Some(&false))
            })
    }

    /// Run `index`, described by `what` (`s0/lio-sam`, a sweep's cell), has ended; an
    /// index past the end: whichever run (they weigh the same).
    pub fn finished(&self, index: usize, what: &str, outcome: &RunOutcome) {
        let k = self.done.fetch_add(1, Ordering::SeqCst) + 1;
        let measured = outcome
            .folder
            .read_timing()
            .ok()
            .flatten()
            .map(|t| t.wall_s);
        let elapsed = self.started.elapsed().as_secs_f64();
        let eta = self.time_left(index, measured, elapsed, k);
        // Never "-0 s".
        let eta = if eta > 0.0 { eta } else { 0.0 };
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

/// What was seen of a run: its measured duration once ended, and (seconds since the start,
/// fraction of its route fed) when first and last seen running.
#[derive(Debug, Clone, Copy, Default)]
struct Seen {
    measured: Option<f64>,
    first: Option<(f64, f64)>,
    last: Option<(f64, f64)>,
}

/// The least progress (a fraction of its route) a running run must have made between two
/// looks before its speed counts.
const MIN_SEEN: f64 = 0.01;

#[cfg(test)]
mod tests {
    use super::*;

    /// Two slots; runs predicted 10, 10, 100 and 100 s. The first, predicted 10 s, took
    /// 20 s: every prediction doubles; 210 s of work is left on two slots, the longest run
    /// 100 s: 2 * max(210 / 2, 100) = 210 s. An unmeasured run leaves the scale as it is.
    #[test]
    fn the_time_left_scales_the_predictions_by_what_was_measured() {
        let p = Progress::new(4, Some(vec![10.0, 10.0, 100.0, 100.0]), 2, false);
        let left = p.time_left(0, Some(20.0), 20.0, 1);
        assert!(
            (left - 2.0 * (210.0f64 / 2.0).max(100.0)).abs() < 1e-9,
            "{left}"
        );
        // The second took its prediction: the scale is (20 + 10) / (10 + 10) = 1.5, and the
        // two 100 s runs left share the two slots: 1.5 * max(200 / 2, 100) = 150.
        let left = p.time_left(1, Some(10.0), 30.0, 2);
        assert!((left - 150.0).abs() < 1e-9, "{left}");
        // One long run left: its own length, however many slots.
        let left = p.time_left(2, None, 200.0, 3);
        assert!((left - 150.0).abs() < 1e-9, "{left}");
        assert_eq!(p.time_left(3, Some(100.0), 300.0, 4), 0.0);
    }

    /// With the runner's schedule a shared group counts once, as its longest run, for the
    /// slots it takes: on two slots, a camera group of two runs (100, 90 s), a lidar group
    /// of three taking both slots (50, 40, 45 s), one unshared run (10 s). The first run
    /// took twice its prediction and its group ends with it: 2 * (50 * 2 + 10 * 1) / 2 =
    /// 110 s are left, where counting runs would say 2 * (90 + 50 + 40 + 45 + 10) / 2.
    #[test]
    fn a_shared_group_counts_as_its_longest_run() {
        let p = Progress::new(6, Some(vec![100.0, 90.0, 50.0, 40.0, 45.0, 10.0]), 2, false);
        p.set_schedule(&vec![(vec![0, 1], 2), (vec![2, 3, 4], 2), (vec![5], 1)]);
        let left = p.time_left(0, Some(200.0), 200.0, 1);
        assert!((left - 110.0).abs() < 1e-9, "{left}");
        // The group's other run ends: nothing changes but the scale ((200 + 90) / 190).
        let left = p.time_left(1, Some(90.0), 200.0, 2);
        assert!((left - 110.0 * 290.0 / 190.0 / 2.0).abs() < 1e-9, "{left}");
        // The lidar group begins to end: the unshared run is left, alone on a slot of two
        // (its own length: max(10 / 2, 10)).
        let left = p.time_left(2, Some(50.0), 300.0, 3);
        assert!((left - 10.0 * 340.0 / 240.0).abs() < 1e-9, "{left}");
    }

    /// Without previous results, each system's speed as measured: lio-sam (routes of 100 s)
    /// seen half way after 100 s costs 2 s a simulated second, and so does the baseline
    /// until one of its runs ends (5 s for a 10 s route: 0.5); two slots.
    #[test]
    fn without_previous_results_each_systems_speed_is_measured_as_it_runs() {
        let p = Progress::new(4, Some(vec![100.0, 100.0, 10.0, 10.0]), 2, false).by_system(
            [
                (100.0, "lio-sam"),
                (100.0, "lio-sam"),
                (10.0, "odom"),
                (10.0, "odom"),
            ]
            .map(|(s, l)| (s, l.to_owned()))
            .to_vec(),
        );
        p.observe_at(0, 0.0, 0.0);
        p.observe_at(2, 0.0, 0.0);
        p.observe_at(0, 0.5, 100.0);
        // Run 2 ends, measured 5 s: lio-sam's runs left are 100 s (half fed) and 200 s,
        // the other baseline 0.5 * 10 = 5 s: max((100 + 200 + 5) / 2, 200).
        let left = p.time_left(2, Some(5.0), 100.0, 1);
        assert!((left - 200.0).abs() < 1e-9, "{left}");
        // Run 0 ends after 210 s: lio-sam's ended run is its measure (2.1 s/s).
        let left = p.time_left(0, Some(210.0), 210.0, 2);
        assert!((left - 210.0).abs() < 1e-9, "{left}");
        // Too little progress says nothing: a fresh estimate without any speed known falls
        // back to the time so far per run.
        let q = Progress::new(2, None, 1, false)
            .by_system(vec![(10.0, "a".to_owned()), (10.0, "b".to_owned())]);
        q.observe_at(0, 0.0, 0.0);
        q.observe_at(0, 0.001, 50.0);
        let left = q.time_left(usize::MAX, None, 30.0, 1);
        assert!((left - 30.0).abs() < 1e-9, "{left}");
    }

    /// Without any measurement the time so far per run stands in; runs of equal weight may
    /// end in any order, each counted once.
    #[test]
    fn without_measurements_the_time_so_far_per_run_stands_in() {
        let p = Progress::new(4, None, 1, false);
        assert!((p.time_left(usize::MAX, None, 30.0, 1) - 90.0).abs() < 1e-9);
        let p = Progress::new(3, None, 1, false);
        assert!((p.time_left(usize::MAX, Some(10.0), 10.0, 1) - 20.0).abs() < 1e-9);
        assert!((p.time_left(usize::MAX, Some(10.0), 20.0, 2) - 10.0).abs() < 1e-9);
    }
}
