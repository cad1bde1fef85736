//! One run's order, as the supervising process hands it to the worker process.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Everything a worker needs to run one (scenario, plugin) pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Job {
    pub scenario: String,
    /// Simulator configuration file; `None`: the embedded defaults.
    pub world: Option<PathBuf>,
    pub seed: u64,
    /// The plugin library.
    pub plugin: PathBuf,
    /// The plugin's parameter table, handed to it verbatim.
    pub params_toml: String,
    /// Where the worker writes its files.
    pub out_dir: PathBuf,
    /// Address-space limit the worker sets on itself before loading the plugin.
    pub memory_limit_mb: u64,
    /// Feed the plugin from this recording (`vinebench record`) instead of the live
    /// simulator; the scenario and world still give the rig and the nominal duration.
    #[serde(default)]
    pub dataset: Option<PathBuf>,
    /// The dataset is the plan's own recording of this world, scenario and seed
    /// (`record_once`): the very stream the simulator gives, so that the run's pictures may
    /// be rendered again from its world.
    #[serde(default)]
    pub recorded: bool,
    /// Stop feeding at this simulated time, seconds (`--max-time`, `max_time_s`): ground
    /// truth and evaluation then cover the route up to there. `None`: the whole route.
    #[serde(default)]
    pub max_time_s: Option<f64>,
    /// Read the messages from stdin, streamed by the supervisor's shared simulation of the
    /// scenario ([`super::feed`]), instead of simulating here.
    #[serde(default)]
    pub fed: bool,
    /// How fast to feed the plugin ([`Pace`]).
    #[serde(default)]
    pub pace: Pace,
    /// Bounded subscriber queues ([`QueueSize`]; paced runs only): `None` is unbounded.
    #[serde(default)]
    pub queue_size: Option<QueueSize>,
    /// Drop exactly these messages (a run's `dropped.csv`), instead of what the queues drop:
    /// a run replayed with another's drops.
    #[serde(default)]
    pub drops: Option<PathBuf>,
    /// Start the plugin in localisation mode from a saved map ([`super::LocalizeSpec`]).
    #[serde(default)]
    pub localize: Option<super::LocalizeSpec>,
}

/// The topics a queue may be bounded on: every sensor message the plugin is fed.
pub const QUEUE_TOPICS: [&str; 6] = [
    "imu",
    "odom",
    "lidar",
    "scan2d_front",
    "scan2d_back",
    "rgbd",
];

/// A system's subscriber queues, as ROS 1 gives each subscription one (`queue_size` of a
/// `[[plugins]]` entry): `queue_size = 5` bounds every topic, `queue_size = { lidar = 2,
/// rgbd = 1 }` the ones named (the others unbounded). A message that arrives (at its stamp,
/// on the wall clock: paced runs only) while the system is busy waits in its topic's queue;
/// a full queue drops its oldest message, as roscpp's subscription queue does
/// (`ros_comm/clients/roscpp/src/libros/subscription_queue.cpp`: `push` pops the front when
/// `size_ == queue_size`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "queue_size: a number of messages (5), or one per topic ({ lidar = 2, rgbd = 1 })"
)]
pub enum QueueSize {
    All(usize),
    Topics(std::collections::BTreeMap<String, usize>),
}

impl QueueSize {
    /// The bound on `topic`'s queue, if any.
    pub fn of(&self, topic: &str) -> Option<usize> {
        match self {
            QueueSize::All(n) => Some(*n),
            QueueSize::Topics(t) => t.get(topic).copied(),
        }
    }

    /// Every bound at least one, every topic known, and a paced run (a free run's messages
    /// never wait: it takes each when it is ready). The reason when not.
    pub fn check(&self, pace: Pace) -> Result<(), String> {
        if pace != Pace::Realtime {
            return Err(
                "queue_size needs pace = \"realtime\" (a free run's messages never wait)".into(),
            );
        }
        let sizes: Vec<(&str, usize)> = match self {
            QueueSize::All(n) => vec![("every topic", *n)],
            QueueSize::Topics(t) => {
                if let Some(bad) = t.keys().find(|k| !QUEUE_TOPICS.contains(&k.as_str())) {
                    return Err(format!(
                        "queue_size: unknown topic '{bad}' (known: {})",
                        QUEUE_TOPICS.join(", ")
                    ));
                }
                t.iter().map(|(k, v)| (k.as_str(), *v)).collect()
            }
        };
        match sizes.iter().find(|(_, n)| *n == 0) {
            Some((topic, _)) => Err(format!("queue_size of {topic}: must be at least 1")),
            None => Ok(()),
        }
    }
}

/// How fast the worker feeds a plugin (`pace` of a `[[plugins]]` entry).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Pace {
    /// As fast as the plugin takes the messages (the default): the run's length is the
    /// plugin's compute time.
    #[default]
    Free,
    /// No faster than simulated time, as a robot's sensors would deliver them: each message
    /// is handed over no earlier than its stamp after the first message's, on the wall
    /// clock. For systems with threads of their own (ORB-SLAM3's local mapping and loop
    /// closing), whose results depend on how much time those threads get between frames.
    Realtime,
}

/// A route limit must be a positive, finite number of seconds; the reason when not.
pub fn check_max_time(seconds: f64) -> Result<(), &'static str> {
    if seconds.is_finite() && seconds > 0.0 {
        Ok(())
    } else {
        Err("must be a positive number of seconds")
    }
}

/// A route limit in integer nanoseconds (to the nearest).
pub fn max_time_ns(seconds: f64) -> i64 {
    (seconds * 1e9).round() as i64
}

/// Where feeding a route of `duration_ns` stops, ns: its end, or the route limit
/// `max_time_s` (checked) if that comes first.
pub fn route_end_ns(duration_ns: i64, max_time_s: Option<f64>) -> anyhow::Result<i64> {
    let Some(s) = max_time_s else {
        return Ok(duration_ns);
    };
    check_max_time(s).map_err(|why| anyhow::anyhow!("max_time_s = {s}: {why}"))?;
    Ok(duration_ns.min(max_time_ns(s)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    struct Entry {
        queue_size: QueueSize,
    }

    fn parse(text: &str) -> Result<QueueSize, String> {
        toml::from_str::<Entry>(text)
            .map(|e| e.queue_size)
            .map_err(|e| e.message().to_owned())
    }

    /// `queue_size` is a number for every topic or a table by topic, checked for a paced run,
    /// known topics and sizes of at least one; anything else says what it expects.
    #[test]
    fn a_queue_size_is_a_number_or_one_per_topic() {
        let all = parse("queue_size = 5").expect("number");
        assert_eq!((all.of("lidar"), all.of("imu")), (Some(5), Some(5)));
        let some = parse("queue_size = { lidar = 2 }").expect("table");
        assert_eq!((some.of("lidar"), some.of("imu")), (Some(2), None));
        assert_eq!(some.check(Pace::Realtime), Ok(()));
        let err = parse("queue_size = \"five\"").expect_err("a string");
        assert!(err.contains("a number of messages"), "{err}");
        let err = some.check(Pace::Free).expect_err("free");
        assert!(err.contains("realtime"), "{err}");
        let err = parse("queue_size = { lidr = 2 }")
            .expect("parses")
            .check(Pace::Realtime)
            .expect_err("unknown topic");
        assert!(
            err.contains("'lidr'") && err.contains("scan2d_front"),
            "{err}"
        );
        let err = parse("queue_size = { rgbd = 0 }")
            .expect("parses")
            .check(Pace::Realtime)
            .expect_err("zero");
        assert!(err.contains("rgbd") && err.contains("at least 1"), "{err}");
    }
}
