//! Wall-clock durations of a plugin's named stages, so that a main loop can time its
//! pipeline without timing code between its steps:
//!
//! ```ignore
//! let features = self.stages.time("features", || extract(&rings, &self.cfg.features));
//! ...
//! eprintln!("lio-sam: {}", self.stages.summary());
//! ```
//!
//! The closure borrows only what it names (Rust 2021 captures fields disjointly), so a stage
//! can use the plugin's other fields while `self.stages` records it.

use std::time::Instant;

/// Durations (s) per stage, in the order the stages were first seen.
#[derive(Debug, Default, Clone)]
pub struct Stages {
    stages: Vec<(&'static str, Vec<f64>)>,
}

impl Stages {
    /// Runs `stage`, recording its duration under `name`.
    pub fn time<T>(&mut self, name: &'static str, stage: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = stage();
        self.record(name, start.elapsed().as_secs_f64());
        out
    }

    /// Records a duration (s) measured elsewhere under `name`.
    pub fn record(&mut self, name: &'static str, seconds: f64) {
        match self.stages.iter_mut().find(|(n, _)| *n == name) {
            Some((_, samples)) => samples.push(seconds),
            None => self.stages.push((name, vec![seconds])),
        }
    }

    /// The durations recorded under `name` (s), in order; empty if none.
    pub fn samples(&self, name: &str) -> &[f64] {
        self.stages
            .iter()
            .find(|(n, _)| *n == name)
            .map_or(&[], |(_, samples)| samples.as_slice())
    }

    /// Total time (s) recorded under `name`.
    pub fn total(&self, name: &str) -> f64 {
        self.samples(name).iter().sum()
    }

    /// One line: per stage, its count, median, 99th percentile and maximum in ms, and its
    /// total in s: `features n=1500 p50 1.2 ms p99 3.4 ms max 5.0 ms (1.9 s); …`.
    pub fn summary(&self) -> String {
        self.stages
            .iter()
            .map(|(name, samples)| {
                let mut sorted = samples.clone();
                sorted.sort_by(f64::total_cmp);
                let q = |q: f64| 1e3 * sorted[((sorted.len() - 1) as f64 * q).round() as usize];
                format!(
                    "{name} n={} p50 {:.1} ms p99 {:.1} ms max {:.1} ms ({:.1} s)",
                    sorted.len(),
                    q(0.5),
                    q(0.99),
                    q(1.0),
                    samples.iter().sum::<f64>()
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_by_name_in_first_seen_order() {
        let mut stages = Stages::default();
        assert_eq!(stages.time("a", || 7), 7);
        stages.record("b", 0.004);
        stages.record("a", 0.002);
        stages.record("b", 0.001);
        assert_eq!(stages.samples("a").len(), 2);
        assert_eq!(stages.samples("a")[1], 0.002);
        assert_eq!(stages.samples("b"), &[0.004, 0.001]);
        assert!(stages.samples("c").is_empty());
        assert!((stages.total("b") - 0.005).abs() < 1e-15);
        let line = stages.summary();
        assert!(line.starts_with("a n=2 p50 "), "{line}");
        assert!(
            line.ends_with("; b n=2 p50 4.0 ms p99 4.0 ms max 4.0 ms (0.0 s)"),
            "{line}"
        );
    }
}
