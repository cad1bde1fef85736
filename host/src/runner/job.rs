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

/// File names inside a run folder.
pub mod files {
    pub const JOB: &str = "job.json";
    pub const GROUNDTRUTH: &str = "groundtruth.tum";
    pub const ESTIMATE: &str = "estimate.tum";
    pub const ONLINE: &str = "online.tum";
    pub const MAP: &str = "map.ply";
    pub const GRID: &str = "grid.pgm";
    pub const GRID_YAML: &str = "grid.yaml";
    pub const EVENTS: &str = "events.json";
    pub const TIMING: &str = "timing.json";
    pub const METRICS: &str = "metrics.json";
    /// Ground truth, aligned estimate, map and loops for Foxglove (`dataset::write_results`).
    pub const RESULTS: &str = "results.mcap";
    pub const LOG: &str = "worker.log";
    pub const RUN: &str = "run.toml";
}
