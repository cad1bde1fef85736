//! The results on disk, as one typed model that the runner writes and evaluation, report and
//! sweep read: a run's folder ([`RunFolder`]: every file it holds, named in [`files`]), how a
//! run ended ([`RunStatus`], [`RunOutcome`]), a results folder written whole or not at all
//! ([`Staging`]), and a sweep's aggregate ([`aggregate`]).
//!
//! A run's folder, in the order its files are written:
//! - by the worker: `run.toml` (everything that determined the run), `world.toml` (the
//!   resolved simulator configuration, whole), `groundtruth.tum`,
//!   `estimate.tum`, `online.tum` (if the system returned poses during the run), `map.ply`,
//!   `grid.pgm` + `grid.yaml` (if it made them), `events.json` (its events), `timing.json`
//!   ([`Timing`]), and `worker.log` (its standard error);
//! - by evaluation (`runner::evaluate`): `metrics.json` ([`Metrics`]), `events.json` again
//!   with every accepted loop judged ([`JudgedEvent`]), `joins.json` (the final map's
//!   wrong joins and revisits, [`Joins`]), `ape.csv` (the aligned estimate and
//!   its error at every associated pose, [`ApeSeries`]) and `results.mcap`.
//!
//! Nothing here runs a system or draws a page; layers above (`runner`, `sweep`, `report`)
//! meet only through these files.

pub mod aggregate;
mod folder;
pub mod map_file;
mod maps;
mod run;

pub use folder::{
    MARKER, PARTIAL, SWEEP_MARKER, Staging, folder_name, is_sweep_folder, link_latest,
    partial_path, write_atomic,
};
pub use maps::{read_grid, read_ply, write_grid, write_ply};
pub use run::{
    ApeSeries, FramePair, Frames, GnssMetrics, JoinCounts, Joins, JudgedBy, JudgedEvent, Latency,
    LocalizationMetrics, Metrics, PairKind, RunFolder, RunOutcome, RunStatus, Timing, Transform,
    write_json,
};

/// File names inside a run folder.
pub mod files {
    /// The worker's order (removed when the run ends: it holds temporary paths).
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
    /// The GNSS epochs the plugin was fed, `stamp_ns,status` (a plugin that takes GNSS, in
    /// a world with a receiver).
    pub const GNSS: &str = "gnss.csv";
    /// The final map's wrong joins and revisits (`results::Joins`).
    pub const JOINS: &str = "joins.json";
    /// The aligned estimate and its translation error per associated pose.
    pub const APE: &str = "ape.csv";
    /// Ground truth, aligned estimate, map and loops for Foxglove (`dataset::write_results`).
    pub const RESULTS: &str = "results.mcap";
    pub const LOG: &str = "worker.log";
    pub const RUN: &str = "run.toml";
    /// The simulator configuration the run was simulated in, resolved and whole
    /// (`sim::SimConfig::to_toml_string`): `run.toml`'s `world` names its source file, which
    /// may change or stay on another machine.
    pub const WORLD: &str = "world.toml";
    /// Where the sensors really sat in the run: every mount moved by its drawn
    /// `mount_error` (`sim::Simulation::placed_sensors`), beside `world.toml`'s nominal
    /// mounts the system was told; written when a sensor has a `mount_error`.
    pub const PLACED: &str = "placed.toml";
    /// The camera frames of the run's false loops, wrong joins and some true loops, rendered
    /// again at evaluation (`runner::frames`), and their list.
    pub const FRAMES_DIR: &str = "frames";
    pub const FRAMES: &str = "frames.json";
    /// How the run ended (`RunStatus::text`), written as it ends: what lets an interrupted
    /// bench resume without running it again.
    pub const STATUS: &str = "status.txt";
    /// The messages a paced run's bounded queues dropped (`topic,stamp_ns`), written when it
    /// had `queue_size` or given drops.
    pub const DROPPED: &str = "dropped.csv";
    /// The map the plugin saved to localise in later (`results::map_file`).
    pub const SAVED_MAP: &str = "map.bin";
    /// A localisation run's order (`runner::LocalizeSpec`): which map, from which mapping
    /// run, the initial guess and the kidnapping.
    pub const LOCALIZATION: &str = "localization.toml";
    /// The status of every online pose of a localisation run (`stamp_ns,status`, row for
    /// row with `online.tum`).
    pub const POSE_STATUS: &str = "pose_status.csv";
}

/// Hex SHA-256 of some bytes, first 16 digits (64 bits: no collision in any sweep).
pub fn short_hash(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    let digest = sha2::Sha256::digest(bytes);
    digest[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// Hash of the running `vinebench` executable.
pub fn exe_hash() -> anyhow::Result<String> {
    let exe = anyhow::Context::context(std::env::current_exe(), "the vinebench executable")?;
    file_hash(&exe)
}

/// Hex SHA-256 of a file's bytes, first 16 digits.
pub fn file_hash(path: &std::path::Path) -> anyhow::Result<String> {
    let bytes = anyhow::Context::with_context(std::fs::read(path), || path.display().to_string())?;
    Ok(short_hash(&bytes))
}
