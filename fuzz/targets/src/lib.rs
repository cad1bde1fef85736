//! The bodies of vinebench's fuzz targets (`docs/fuzzing.md`): one function per parser of
//! the host, each taking arbitrary bytes and handing them to the real parser through its
//! public API. A parser must answer any input with an error, never a panic, a hang or an
//! unbounded allocation; where it accepts an input, the function also checks what it
//! returned (finite poses, increasing stamps, a usable vocabulary), so an accepted absurdity
//! is a finding too.
//!
//! `fuzz/` runs these under libFuzzer (`cargo +nightly fuzz run <target>`); the integration
//! test `tests/corpus.rs` replays the committed seed corpus (`fuzz/corpus/<target>/`) and
//! the regression inputs (`fuzz/regressions/<target>/`) through them on the stable
//! toolchain, in CI.
//!
//! Parsers that only read files (the results folder's readers, the PLY reader) get the bytes
//! in a fresh temporary folder, as the runner's folder would hold them.

use std::path::Path;

use eval::Trajectory;
use nalgebra::Isometry3;
use plugin_api::Event;
use vinebench::dataset::{Assembler, Replay, Topic};
use vinebench::results::{RunFolder, files};

/// A target's body.
pub type Target = fn(&[u8]);

/// Every target: its name (the folder of its corpus and regressions, the fuzz binary) and
/// its body.
pub const TARGETS: &[(&str, Target)] = &[
    ("world_toml", world_toml),
    ("bench_toml", bench_toml),
    ("sweep_toml", sweep_toml),
    ("tum", tum),
    ("kitti", kitti),
    ("g2o", g2o),
    ("mcap_dataset", mcap_dataset),
    ("ros_messages", ros_messages),
    ("vocabulary", vocabulary),
    ("events_toml", events_toml),
    ("events_json", events_json),
    ("run_json", run_json),
    ("ape_csv", ape_csv),
    ("ply", ply),
    ("report_maps", report_maps),
    ("c_door_output", c_door_output),
    ("c_door_answers", c_door_answers),
    ("python_door_output", python_door_output),
    ("saved_map", saved_map),
];

/// A `map.bin` as `vinebench localize` reads it (`results::map_file`): the head and its
/// checks, then the payload as the two formats parsed in this workspace read it (lio-sam's
/// `keyframe-clouds`, the host's `vinebench-grid`); the raw bytes through both as well.
pub fn saved_map(data: &[u8]) {
    if let Ok((head, payload)) = vinebench::results::map_file::decode_map(data, "map.bin", None) {
        let _ =
            slam_common::maps::keyframes::KeyframeMap::from_bytes(&payload, head.format_version);
        let _ = plugin_api::OccupancyGrid::from_map_bytes(&payload);
    }
    for version in 1..=slam_common::maps::keyframes::KEYFRAME_MAP_VERSION {
        let _ = slam_common::maps::keyframes::KeyframeMap::from_bytes(data, version);
    }
    let _ = plugin_api::OccupancyGrid::from_map_bytes(data);
}

/// The C door's host side reading what a C plugin's `finish` hands back, built from the
/// bytes: arrays with their lengths, NULLs with lengths, a grid, events TOML text
/// (`plugin_api::__fuzzing::c_output`).
pub fn c_door_output(data: &[u8]) {
    plugin_api::__fuzzing::c_output(data);
}

/// The C door's host side turning a C plugin's answers into the host's: an arbitrary return
/// code, pose and error text from a message callback, arbitrary (or NULL) requirements
/// text (`plugin_api::__fuzzing::c_answers`).
pub fn c_door_answers(data: &[u8]) {
    plugin_api::__fuzzing::c_answers(data);
}

/// The Python door's host side turning what `bridge.py` hands back from a class's
/// `finish` (poses as 3x4 rows or absent, events with arbitrary kinds and relative poses of
/// 7, 12 or a wrong number of values, a map's bytes, a grid with arbitrary sizes and cells)
/// into the host's output, built from the bytes (`python_bridge::fuzz_python_output`). The
/// values are the ones the bridge's Python half passes on unchecked; CPython itself is
/// linked but not started.
pub fn python_door_output(data: &[u8]) {
    python_bridge::fuzz_python_output(data);
}

/// The name errors give the fuzzed file.
const NAME: &str = "fuzz-input";

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// A fresh folder holding `data` as `file`; dropped, it is removed.
fn folder_with(file: &str, data: &[u8]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary folder");
    std::fs::write(dir.path().join(file), data).expect("write the input");
    dir
}

fn assert_finite_pose(pose: &Isometry3<f64>, what: &str) {
    let t = pose.translation.vector;
    let q = pose.rotation.coords;
    assert!(
        t.iter().chain(q.iter()).all(|v| v.is_finite()),
        "{what}: accepted a non-finite pose {pose:?}"
    );
    assert!(
        (q.norm() - 1.0).abs() < 1e-6,
        "{what}: accepted a rotation of norm {}",
        q.norm()
    );
}

fn assert_trajectory(trajectory: &Trajectory, what: &str) {
    assert_eq!(trajectory.stamps.len(), trajectory.poses.len(), "{what}");
    assert!(!trajectory.stamps.is_empty(), "{what}: accepted no pose");
    assert!(
        trajectory.stamps.iter().all(|t| t.is_finite()),
        "{what}: accepted a non-finite stamp"
    );
    assert!(
        trajectory.stamps.windows(2).all(|w| w[0] < w[1]),
        "{what}: accepted stamps that do not increase"
    );
    for pose in &trajectory.poses {
        assert_finite_pose(pose, what);
    }
}

/// The simulator's world configuration (`configs/world.toml`, `--world`):
/// `sim::SimConfig::from_toml_str`, which also validates it.
pub fn world_toml(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let _ = sim::SimConfig::from_toml_str(text, NAME);
}

/// A bench file (`configs/paper.toml`): `BenchConfig::from_toml`, then what `bench` asks of
/// it before it looks for plugins.
pub fn bench_toml(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let Ok(cfg) = vinebench::bench_config::BenchConfig::from_toml(text, Path::new(NAME)) else {
        return;
    };
    let _ = (cfg.bench_seed(), cfg.is_sweep());
    for plugin in &cfg.plugins {
        let _ = (plugin.label(), toml::to_string(&plugin.params));
    }
}

/// A sweep file (`configs/paper-sweep.toml`): the bench file's parser, then the expansion
/// of its axes and seeds over the embedded world, every resolved world checked
/// (`vinebench::sweep::expand`; the plugins are not looked for).
pub fn sweep_toml(data: &[u8]) {
    let Some(text) = text(data) else { return };
    let Ok(cfg) = vinebench::bench_config::BenchConfig::from_toml(text, Path::new(NAME)) else {
        return;
    };
    let _ = vinebench::sweep::expand(&cfg, NAME, sim::DEFAULT_CONFIG_TOML);
}

/// A TUM trajectory (`groundtruth.tum`, `estimate.tum`, `vinebench eval`): `eval::parse_tum`.
pub fn tum(data: &[u8]) {
    let Some(text) = text(data) else { return };
    if let Ok(trajectory) = eval::parse_tum(text, Path::new(NAME)) {
        assert_trajectory(&trajectory, "TUM");
    }
}

/// A KITTI pose file and, after the first NUL byte if any, its times file:
/// `eval::parse_kitti`.
pub fn kitti(data: &[u8]) {
    let (poses, times) = match data.iter().position(|&b| b == 0) {
        Some(at) => (&data[..at], Some(&data[at + 1..])),
        None => (data, None),
    };
    let Some(poses) = text(poses) else { return };
    let times = match times.map(text) {
        Some(None) => return,
        Some(Some(t)) => Some((t, Path::new("fuzz-times"))),
        None => None,
    };
    if let Ok(trajectory) = eval::parse_kitti(poses, Path::new(NAME), times) {
        assert_trajectory(&trajectory, "KITTI");
    }
}

/// A pose graph (g2o, TORO, City10000): `slam_common`'s `posegraph::parse` in each format,
/// then the prior, factors and initial guess a replay builds from it.
pub fn g2o(data: &[u8]) {
    use slam_common::factor_graph::posegraph::{Format, parse};
    let Some(text) = text(data) else { return };
    for format in [Format::Auto, Format::G2o, Format::City10000] {
        let Ok(graph) = parse(NAME, text, format) else {
            continue;
        };
        for pose in graph.vertices.values() {
            assert_finite_pose(pose, "g2o vertex");
        }
        for edge in &graph.edges {
            assert_finite_pose(&edge.from_from_to, "g2o edge");
            assert!(
                edge.sigmas.iter().all(|s| s.is_finite() && *s > 0.0),
                "g2o edge: accepted sigmas {:?}",
                edge.sigmas
            );
        }
        let _ = (graph.factors(), graph.initial_guess());
    }
}

/// A recording (`vinebench record`, `run --dataset`): `dataset::Replay` over the bytes, every
/// sensor's topics decoded, to the end or the first error.
pub fn mcap_dataset(data: &[u8]) {
    let replay = Replay::from_reader(Path::new(NAME), data, sim::SensorSet::ALL);
    for message in replay {
        if message.is_err() {
            break;
        }
    }
}

/// One record of [`ros_messages`]'s input: topic (index into `Topic::ALL`, modulo), when it
/// became available (simulated ns), its CDR bytes.
const ROS_HEAD: usize = 1 + 8 + 4;

/// Encodes messages as [`ros_messages`] reads them (for its seed corpus).
pub fn encode_ros_messages(messages: &[(Topic, i64, Vec<u8>)]) -> Vec<u8> {
    let mut out = Vec::new();
    for (topic, ready_ns, data) in messages {
        let index = Topic::ALL.iter().position(|t| t == topic).expect("a topic") as u8;
        out.push(index);
        out.extend_from_slice(&ready_ns.to_le_bytes());
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(data);
    }
    out
}

/// The ROS 2 messages of a recording or of a shared simulation's stream (`runner::feed`), as
/// `dataset::Assembler` turns them back into simulator messages: records of a topic byte,
/// a little-endian `i64` time and `u32` length, then that many CDR bytes (fewer at the end).
pub fn ros_messages(mut data: &[u8]) {
    let mut assembler = Assembler::default();
    while data.len() >= ROS_HEAD {
        let topic = Topic::ALL[usize::from(data[0]) % Topic::ALL.len()];
        let ready_ns = i64::from_le_bytes(data[1..9].try_into().expect("8 bytes"));
        let len = u32::from_le_bytes(data[9..13].try_into().expect("4 bytes")) as usize;
        let rest = &data[ROS_HEAD..];
        let (message, next) = rest.split_at(len.min(rest.len()));
        data = next;
        if assembler.push(topic, ready_ns, message).is_err() {
            // As the replay and the feed do: the first bad message ends the stream.
            return;
        }
    }
}

/// FNV-1a, 64 bits: the vocabulary file's checksum (`place::vocabulary`'s format).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| {
        (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A bag-of-words vocabulary file (ORB-SLAM2's, `orbslam2-vocabulary`):
/// `slam_common::place::vocabulary::Vocabulary::read_from`, twice: on the bytes as they are,
/// and with their last 8 bytes replaced by the checksum of the others, so that mutations
/// get past the checksum to the tree's checks. A vocabulary it accepts must then quantise
/// descriptors (taken from the input) as ORB-SLAM2 does.
pub fn vocabulary(data: &[u8]) {
    use slam_common::place::vocabulary::Vocabulary;
    let mut fixed = data.to_vec();
    if let Some(body) = data.len().checked_sub(8) {
        let hash = fnv1a(&data[..body]);
        fixed[body..].copy_from_slice(&hash.to_le_bytes());
    }
    for bytes in [data, &fixed[..]] {
        let Ok(vocabulary) = Vocabulary::read_from(&mut &bytes[..]) else {
            continue;
        };
        let descriptors: Vec<[u8; 32]> = bytes
            .chunks_exact(32)
            .take(64)
            .map(|c| c.try_into().expect("32 bytes"))
            .collect();
        for levels_up in [0, 1, 2, 64] {
            let _ = vocabulary.transform(&descriptors, levels_up);
        }
        for d in &descriptors {
            let (_, weight) = vocabulary.word_of(d);
            assert!(weight.is_finite() && weight >= 0.0, "word weight {weight}");
        }
    }
}

/// `plugin_api`'s events as a plugin hands them to the host through its door: TOML
/// `[[events]]` tables (the same shape as `plugin_api`'s own `events_from_toml`, which is
/// not public), then what the host asks of each event.
pub fn events_toml(data: &[u8]) {
    #[derive(serde::Deserialize)]
    struct Events {
        #[serde(default)]
        events: Vec<Event>,
    }
    let Some(text) = text(data) else { return };
    let Ok(parsed) = toml::from_str::<Events>(text) else {
        return;
    };
    for event in &parsed.events {
        check_event(event);
    }
}

fn check_event(event: &Event) {
    let _ = event.kind.is_loop_closure();
    if let Some(pose) = event.relative_pose() {
        assert_finite_pose(&pose, "an event's relative pose");
    }
}

/// A run's `events.json`, as the plugin's events (`RunFolder::read_events`) and as judged
/// (`RunFolder::read_judged_events`).
pub fn events_json(data: &[u8]) {
    let dir = folder_with(files::EVENTS, data);
    let run = RunFolder::new(dir.path());
    if let Ok(events) = run.read_events() {
        events.iter().for_each(check_event);
    }
    if let Ok(events) = run.read_judged_events() {
        events.iter().for_each(|e| check_event(&e.event));
    }
}

/// The JSON files of a run's folder that the report and the sweep read back: the same bytes
/// as `metrics.json` (`RunFolder::read_metrics`), `timing.json` (`read_timing`) and a
/// sweep's `cell.json` (`sweep::read_filed`).
pub fn run_json(data: &[u8]) {
    let dir = folder_with(files::METRICS, data);
    std::fs::write(dir.path().join(files::TIMING), data).expect("write timing.json");
    std::fs::write(dir.path().join("cell.json"), data).expect("write cell.json");
    let run = RunFolder::new(dir.path());
    let _ = run.read_metrics();
    let _ = run.read_timing();
    let _ = vinebench::sweep::read_filed(dir.path());
}

/// A run's `ape.csv` (the aligned estimate and its error per pose): `RunFolder::read_ape`.
pub fn ape_csv(data: &[u8]) {
    let dir = folder_with(files::APE, data);
    if let Ok(ape) = RunFolder::new(dir.path()).read_ape() {
        assert_eq!(ape.stamps_s.len(), ape.aligned.len());
        assert_eq!(ape.stamps_s.len(), ape.errors_m.len());
        let _ = ape.aligned_xy();
    }
}

/// A plugin's map as the worker wrote it (`map.ply`): `results::read_ply`.
pub fn ply(data: &[u8]) {
    let dir = folder_with(files::MAP, data);
    let _ = vinebench::results::read_ply(&dir.path().join(files::MAP));
}

/// A plugin's map and occupancy grid as a bench's report reads and draws them: the input
/// split into `map.ply` and `grid.pgm` (each a little-endian `u32` length, then its bytes)
/// and `grid.yaml` (the rest), each left out when its part is missing, in the folder of
/// one ok run, and the bench's page built
/// (`report::html::bench_page`, which reads them through its map and grid charts).
pub fn report_maps(data: &[u8]) {
    use vinebench::report::RunRecord;
    use vinebench::report::load::{BenchResults, LoadedRun, RunDetail};
    let mut data = data;
    let dir = tempfile::tempdir().expect("a temporary folder");
    let run_dir = dir.path().join("s3").join("fuzz");
    std::fs::create_dir_all(&run_dir).expect("the run's folder");
    let write = |file: &str, part: &[u8]| {
        std::fs::write(run_dir.join(file), part).expect("write the input");
    };
    if let Some(ply) = take_part(&mut data) {
        write(files::MAP, ply);
        if let Some(pgm) = take_part(&mut data) {
            write(files::GRID, pgm);
            write(files::GRID_YAML, data);
        }
    }
    let xy = vec![(0.0, 0.0), (1.0, 0.5), (2.0, 0.0)];
    let errors = vec![0.1, 0.2, 0.1];
    let record = RunRecord {
        scenario: "s3".into(),
        plugin: "fuzz".into(),
        status: vinebench::results::RunStatus::Ok,
        ape: eval::Statistics::from_errors(&errors).ok(),
        realtime_factor: Some(1.0),
        loops: Some(eval::LoopCounts::default()),
        joins: Some(vinebench::results::JoinCounts::default()),
        sim3_scale: Some(1.0),
        drift_percent: Some(0.5),
        estimate_xy: xy.clone(),
        max_time_s: None,
        localization: None,
    };
    let detail = RunDetail {
        alignment: "se3".into(),
        groundtruth_xy: xy.clone(),
        estimate_raw_xy: xy,
        stamps_s: vec![0.0, 1.0, 2.0],
        errors_m: errors,
        loops: Vec::new(),
        joins: None,
        frames: None,
        gnss: None,
    };
    let results = BenchResults {
        dir: dir.path().to_path_buf(),
        scenarios: vec!["s3".into()],
        plugins: vec!["fuzz".into()],
        runs: vec![LoadedRun {
            record,
            dir: run_dir,
            detail: Some(detail),
            timing: None,
            run_toml: None,
        }],
    };
    let _ = vinebench::report::html::bench_page(&results, NAME);
}

/// The next part of a [`report_maps`] input: a little-endian `u32` length, then that many
/// bytes (fewer at the end); `None` when not even the length is left.
fn take_part<'a>(data: &mut &'a [u8]) -> Option<&'a [u8]> {
    let len = u32::from_le_bytes(data.get(..4)?.try_into().ok()?) as usize;
    let rest = &data[4..];
    let (part, next) = rest.split_at(len.min(rest.len()));
    *data = next;
    Some(part)
}

/// Encodes a map, a grid image and its YAML as [`report_maps`] reads them (for its seeds).
pub fn encode_report_maps(ply: &[u8], pgm: &[u8], yaml: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    for part in [ply, pgm] {
        out.extend_from_slice(&(part.len() as u32).to_le_bytes());
        out.extend_from_slice(part);
    }
    out.extend_from_slice(yaml);
    out
}
