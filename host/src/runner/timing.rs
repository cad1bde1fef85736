//! What a run cost: wall time of every plugin call (latency percentiles per sensor), the
//! process's CPU time and peak memory, and the real-time factors.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use sim::sensors::Message;

use crate::results::{Latency, Timing as TimingReport};

/// Call durations per message kind.
#[derive(Debug, Default)]
pub struct Timing {
    calls: BTreeMap<&'static str, Vec<u64>>,
}

/// The `q`-quantile of sorted values (nearest rank).
fn quantile(sorted: &[u64], q: f64) -> u64 {
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

impl Timing {
    pub fn record(&mut self, kind: &'static str, took: Duration) {
        self.calls
            .entry(kind)
            .or_default()
            .push(took.as_nanos() as u64);
    }

    pub fn report(
        &self,
        simulated_s: f64,
        wall_s: f64,
        cpu_s: Option<f64>,
        peak_rss_mb: Option<f64>,
    ) -> TimingReport {
        let mut latency = BTreeMap::new();
        let mut plugin_ns = 0u64;
        for (&kind, calls) in &self.calls {
            let mut sorted = calls.clone();
            sorted.sort_unstable();
            let total: u64 = sorted.iter().sum();
            plugin_ns += total;
            let ms = |ns: u64| ns as f64 * 1e-6;
            latency.insert(
                kind.to_owned(),
                Latency {
                    calls: sorted.len(),
                    p50_ms: ms(quantile(&sorted, 0.5)),
                    p90_ms: ms(quantile(&sorted, 0.9)),
                    p99_ms: ms(quantile(&sorted, 0.99)),
                    max_ms: ms(*sorted.last().expect("non-empty")),
                    total_s: total as f64 * 1e-9,
                },
            );
        }
        let plugin_s = plugin_ns as f64 * 1e-9;
        TimingReport {
            source: "simulation".to_owned(),
            simulated_s,
            wall_s,
            plugin_s,
            cpu_s,
            peak_rss_mb,
            realtime_factor: simulated_s / wall_s.max(1e-9),
            realtime_factor_plugin: simulated_s / plugin_s.max(1e-9),
            latency,
            simulation_cost: BTreeMap::new(),
            dropped: BTreeMap::new(),
        }
    }
}

/// Wall time a simulation spent making each sensor's messages: the time to draw each
/// message from the stream, charged to that message's sensor.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct SimulationCost {
    wall: BTreeMap<&'static str, Duration>,
}

impl SimulationCost {
    /// The next message of `stream`, its making charged to its sensor.
    pub fn next_from(&mut self, stream: &mut impl Iterator<Item = Message>) -> Option<Message> {
        let started = Instant::now();
        let message = stream.next()?;
        *self.wall.entry(message.sensor()).or_default() += started.elapsed();
        Some(message)
    }

    /// Wall seconds per simulated second, per sensor.
    pub fn per_simulated_s(&self, simulated_s: f64) -> BTreeMap<String, f64> {
        self.wall
            .iter()
            .map(|(&sensor, wall)| {
                (
                    sensor.to_owned(),
                    wall.as_secs_f64() / simulated_s.max(1e-9),
                )
            })
            .collect()
    }
}

/// User + system CPU seconds of this process (Linux `/proc/self/stat`, 100 ticks/s).
pub fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name, which is in parentheses and may contain spaces.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// Peak resident memory of this process in MiB (Linux `/proc/self/status`, VmHWM).
pub fn process_peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_by_nearest_rank() {
        let mut t = Timing::default();
        for ms in 1..=100 {
            t.record("imu", Duration::from_millis(ms));
        }
        let r = t.report(10.0, 5.0, None, None);
        let l = &r.latency["imu"];
        assert_eq!(
            (l.calls, l.p50_ms, l.p90_ms, l.p99_ms, l.max_ms),
            (100, 50.0, 90.0, 99.0, 100.0)
        );
        assert!(
            (r.plugin_s - 5.05).abs() < 1e-9,
            "sum of 1..100 ms is 5.05 s, got {}",
            r.plugin_s
        );
        assert!(
            (r.realtime_factor - 2.0).abs() < 1e-12,
            "10 s simulated in 5 s"
        );
    }
}
