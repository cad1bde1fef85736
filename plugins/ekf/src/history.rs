//! Lagged measurements, as robot_localization's `RosFilter` handles them
//! (`smooth_lagged_data`, `history_length`; `integrateMeasurements`, `revertTo`,
//! `saveFilterState`, `clearExpiredHistory`).
//!
//! With `smooth_lagged_data`, the filter keeps `history_length` seconds of its states
//! (one per distinct stamp, saved after processing) and of the measurements it processed.
//! A measurement stamped before the filter's time sends the filter back to the last state
//! stamped before it; the new measurement and every kept measurement from its stamp on are
//! then processed again in stamp order. If the history does not reach back that far, the
//! filter goes back to its oldest state, as robot_localization does. Without it (or with no
//! history), a lagged measurement is fused at the filter's time without a prediction
//! ([`crate::filter::Ekf::process`]).

use std::collections::VecDeque;

use crate::filter::{Ekf, Outcome, Snapshot};
use crate::measurement::Measurement;

/// The EKF with its history.
#[derive(Debug, Clone)]
pub struct LaggedFilter {
    pub ekf: Ekf,
    smooth: bool,
    history_ns: i64,
    states: VecDeque<Snapshot>,
    measurements: VecDeque<Measurement>,
}

impl LaggedFilter {
    pub fn new(ekf: Ekf, smooth_lagged_data: bool, history_length_s: f64) -> Self {
        Self {
            ekf,
            smooth: smooth_lagged_data,
            history_ns: (history_length_s * 1e9).round() as i64,
            states: VecDeque::new(),
            measurements: VecDeque::new(),
        }
    }

    /// If a measurement stamped `stamp_ns` is lagged and history is kept, goes back to the
    /// last state before it (`RosFilter::revertTo`) and returns the measurements to process
    /// again, oldest first; otherwise changes nothing and returns none.
    pub fn rewind(&mut self, stamp_ns: i64) -> Vec<Measurement> {
        if !self.smooth || !self.ekf.initialized || stamp_ns >= self.ekf.last_measurement_ns {
            return Vec::new();
        }
        let time = stamp_ns.saturating_sub(1);
        let mut oldest_popped = None;
        while self
            .states
            .back()
            .is_some_and(|s| s.last_measurement_ns > time)
        {
            oldest_popped = self.states.pop_back();
        }
        let Some(target) = self.states.back().cloned().or(oldest_popped) else {
            return Vec::new();
        };
        self.ekf.restore(&target);
        let mut replay = Vec::new();
        while self.measurements.back().is_some_and(|m| m.stamp_ns > time) {
            if let Some(m) = self.measurements.pop_back()
                && target.last_measurement_ns <= m.stamp_ns
            {
                replay.push(m);
            }
        }
        replay.reverse();
        replay
    }

    /// Processes the `fresh` measurements together with those `replay` returned by
    /// [`LaggedFilter::rewind`], in stamp order (a fresh one before a replayed one of the
    /// same stamp), keeping the history; returns what became of each fresh one.
    pub fn integrate(&mut self, fresh: Vec<Measurement>, replay: Vec<Measurement>) -> Vec<Outcome> {
        let mut outcomes = vec![Outcome::Skipped; fresh.len()];
        let mut queue: Vec<(Measurement, Option<usize>)> = fresh
            .into_iter()
            .enumerate()
            .map(|(i, m)| (m, Some(i)))
            .chain(replay.into_iter().map(|m| (m, None)))
            .collect();
        queue.sort_by_key(|(m, _)| m.stamp_ns);
        let mut queue = queue.into_iter().peekable();
        while let Some((m, fresh_index)) = queue.next() {
            let outcome = self.ekf.process(&m);
            if let Some(i) = fresh_index {
                outcomes[i] = outcome;
            }
            if self.smooth {
                self.measurements.push_back(m);
                let next_stamp = queue.peek().map(|(m, _)| m.stamp_ns);
                if next_stamp != Some(self.ekf.last_measurement_ns) {
                    self.states.push_back(self.ekf.snapshot());
                }
            }
        }
        if self.smooth {
            let cutoff = self.ekf.last_measurement_ns.saturating_sub(self.history_ns);
            while self
                .measurements
                .front()
                .is_some_and(|m| m.stamp_ns < cutoff)
            {
                self.measurements.pop_front();
            }
            while self
                .states
                .front()
                .is_some_and(|s| s.last_measurement_ns < cutoff)
            {
                self.states.pop_front();
            }
        }
        outcomes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::DEFAULT_PROCESS_NOISE;
    use crate::measurement::Source;
    use crate::state::{StateMatrix, StateVector, VX, X};

    fn filter(smooth: bool) -> LaggedFilter {
        let q = StateMatrix::from_diagonal(&StateVector::from_column_slice(&DEFAULT_PROCESS_NOISE));
        LaggedFilter::new(
            Ekf::new(q, StateMatrix::identity() * 1e-9, false),
            smooth,
            1.0,
        )
    }

    fn speed(stamp_ns: i64, v: f64) -> Measurement {
        let mut m = Measurement::new(stamp_ns, Source::WheelOdometry, f64::MAX);
        m.set(VX, v, 1e-4, true);
        m
    }

    fn position(stamp_ns: i64, x: f64) -> Measurement {
        let mut m = Measurement::new(stamp_ns, Source::Gnss, f64::MAX);
        m.set(X, x, 1e-4, true);
        m
    }

    /// A position arriving late, after speeds stamped later than it: with the history the
    /// result is exactly that of processing everything in stamp order; without it the
    /// measurement is applied at the filter's time, which differs.
    #[test]
    fn a_lagged_measurement_is_processed_as_if_it_had_come_in_order() {
        let stamps = [0, 100_000_000, 200_000_000, 300_000_000];
        let mut in_order = filter(true);
        let mut lagged = filter(true);
        let mut unsmoothed = filter(false);
        for (k, &t) in stamps.iter().enumerate() {
            if k == 2 {
                in_order.integrate(vec![position(150_000_000, 0.5)], Vec::new());
            }
            for f in [&mut in_order, &mut lagged, &mut unsmoothed] {
                f.integrate(vec![speed(t, 1.0)], Vec::new());
            }
        }
        let replay = lagged.rewind(150_000_000);
        assert_eq!(
            replay.len(),
            2,
            "the speeds at 0.2 s and 0.3 s are processed again"
        );
        assert_eq!(lagged.ekf.last_measurement_ns, 100_000_000);
        lagged.integrate(vec![position(150_000_000, 0.5)], replay);
        assert_eq!(lagged.ekf.last_measurement_ns, 300_000_000);
        assert!(
            (lagged.ekf.state - in_order.ekf.state).norm() < 1e-12,
            "smoothed {} in order {}",
            lagged.ekf.state,
            in_order.ekf.state
        );
        assert!(unsmoothed.rewind(150_000_000).is_empty());
        unsmoothed.integrate(vec![position(150_000_000, 0.5)], Vec::new());
        assert!(
            (unsmoothed.ekf.state[X] - in_order.ekf.state[X]).abs() > 0.05,
            "applied at 0.3 s, the 0.15 s position pulls x back: {} vs {}",
            unsmoothed.ekf.state[X],
            in_order.ekf.state[X]
        );
    }
}
