//! Writes the seed inputs of the fuzz targets that are derived from vinebench's own output
//! (`fuzz/make-seeds.sh` runs it; `docs/fuzzing.md`):
//!
//! ```text
//! seeds RUN_DIR OUT_CORPUS_DIR RECORDING.mcap...
//! ```
//!
//! - `tum/`, `kitti/`: the first poses of RUN_DIR's `groundtruth.tum`, written back by
//!   `eval::write_tum` and `eval::write_kitti` (the KITTI poses, a NUL, their times file);
//! - `ros_messages/`: the first messages of each recording, as the `ros_messages` target
//!   reads them;
//! - `ply/`: RUN_DIR's `map.ply`, its first points, written by `results::write_ply`;
//! - `report_maps/`: RUN_DIR's map, its first points, with a small occupancy grid written by
//!   `results::write_grid`, as the `report_maps` target reads them;
//! - `saved_map/`: two `map.bin` files, three keyframes of those points and that grid;
//! - `events_json/`, `events_toml/`: events of every kind, written by `RunFolder` (as the
//!   plugin sent them and as judged) and as a plugin's `[[events]]` TOML;
//! - `run_json/`: a sweep's `cell.json`, filed by `sweep::file_run`;
//! - `vocabulary/`: a small vocabulary trained on seeded random descriptors, written by
//!   `Vocabulary::write_to`.

use std::path::{Path, PathBuf};

use fuzz_targets::encode_ros_messages;
use plugin_api::{Event, EventKind};
use vinebench::dataset::{EPOCH_NS, Topic};
use vinebench::results::{JudgedEvent, RunFolder, files};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Poses of the trajectory seeds.
const POSES: usize = 12;
/// Bytes of the messages of one `ros_messages` seed, at most (one message may exceed it).
const MESSAGE_BYTES: usize = 6000;

fn write(out: &Path, target: &str, name: &str, bytes: &[u8]) -> Result<()> {
    let dir = out.join(target);
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join(name), bytes)?;
    println!("{target}/{name}: {} bytes", bytes.len());
    Ok(())
}

fn trajectories(run: &Path, out: &Path) -> Result<()> {
    let mut t = eval::read_tum(run.join(files::GROUNDTRUTH))?;
    t.stamps.truncate(POSES);
    t.poses.truncate(POSES);
    let dir = tempfile::tempdir()?;
    let (tum, kitti, times) = (
        dir.path().join("t.tum"),
        dir.path().join("t.kitti"),
        dir.path().join("t.times"),
    );
    eval::write_tum(&tum, &t)?;
    write(out, "tum", "groundtruth.tum", &std::fs::read(&tum)?)?;
    eval::write_kitti(&kitti, &t, Some(&times))?;
    let mut both = std::fs::read(&kitti)?;
    write(out, "kitti", "poses.kitti", &both)?;
    both.push(0);
    both.extend(std::fs::read(&times)?);
    write(out, "kitti", "poses-and-times.kitti", &both)?;
    Ok(())
}

fn ros_messages(recording: &Path, out: &Path) -> Result<()> {
    let bytes = std::fs::read(recording)?;
    let mut messages = Vec::new();
    let mut size = 0;
    for message in mcap::MessageStream::new(&bytes)? {
        let message = message?;
        let Some(topic) = Topic::from_name(&message.channel.topic) else {
            continue;
        };
        size += message.data.len();
        messages.push((
            topic,
            message.log_time as i64 - EPOCH_NS,
            message.data.into_owned(),
        ));
        if size >= MESSAGE_BYTES {
            break;
        }
    }
    let name = recording.file_stem().ok_or("a recording's name")?;
    write(
        out,
        "ros_messages",
        &format!("{}.bin", name.to_string_lossy()),
        &encode_ros_messages(&messages),
    )
}

fn map(run: &Path, out: &Path) -> Result<()> {
    let points = vinebench::results::read_ply(&run.join(files::MAP))?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join(files::MAP);
    vinebench::results::write_ply(&path, &points[..points.len().min(40)])?;
    write(out, "ply", "map.ply", &std::fs::read(&path)?)?;
    vinebench::results::write_ply(&path, &[])?;
    write(out, "ply", "empty.ply", &std::fs::read(&path)?)?;
    // The report's maps: map.ply, grid.pgm and grid.yaml, as `results` writes them.
    let grid = plugin_api::OccupancyGrid {
        resolution_m: 0.25,
        origin: [-1.0, -0.5, 0.0],
        width: 6,
        height: 4,
        cells: (0..24).map(|i| [-1, 0, 10, 50, 70, 100][i % 6]).collect(),
    };
    let (pgm, yaml) = (
        dir.path().join(files::GRID),
        dir.path().join(files::GRID_YAML),
    );
    vinebench::results::write_grid(&pgm, &yaml, &grid)?;
    let whole = vinebench::results::read_ply(&run.join(files::MAP))?;
    vinebench::results::write_ply(&path, &whole[..whole.len().min(300)])?;
    let maps = fuzz_targets::encode_report_maps(
        &std::fs::read(&path)?,
        &std::fs::read(&pgm)?,
        &std::fs::read(&yaml)?,
    );
    write(out, "report_maps", "map-and-grid.bin", &maps)?;
    // Saved maps (`map.bin`): a lidar system's keyframes and the host's grid, as the worker
    // writes them.
    let keyframes = slam_common::maps::keyframes::KeyframeMap {
        keyframes: (0..3)
            .map(|k| slam_common::maps::keyframes::MapKeyframe {
                map_from_sensor: nalgebra::Isometry3::new(
                    nalgebra::Vector3::new(f64::from(k), 0.5, 0.0),
                    nalgebra::Vector3::new(0.0, 0.0, 0.1 * f64::from(k)),
                ),
                points: whole.iter().take(20).copied().collect(),
            })
            .collect(),
        map_from_enu: Some(nalgebra::Isometry3::new(
            nalgebra::Vector3::new(-3.0, 2.0, 0.0),
            nalgebra::Vector3::new(0.0, 0.0, 0.7),
        )),
    };
    let saved = |format: &str, version: u32, bytes: Vec<u8>| plugin_api::SavedMap {
        format: format.into(),
        version,
        bytes,
    };
    write(
        out,
        "saved_map",
        "keyframes.bin",
        &vinebench::results::map_file::encode_map(
            "lio-sam",
            "0.1.0",
            &saved("keyframe-clouds", keyframes.version(), keyframes.to_bytes()),
        ),
    )?;
    write(
        out,
        "saved_map",
        "grid.bin",
        &vinebench::results::map_file::encode_map(
            "amcl",
            "0.1.0",
            &saved("vinebench-grid", 1, grid.to_map_bytes()),
        ),
    )
}

fn events(out: &Path) -> Result<()> {
    let rotated = nalgebra::Isometry3::new(
        nalgebra::Vector3::new(0.4, -0.1, 0.0),
        nalgebra::Vector3::new(0.0, 0.0, 0.3),
    );
    let events = vec![
        Event::loop_closure(
            12_500_000_000,
            EventKind::LoopClosureAccepted,
            [12_400_000_000, 3_000_000_000],
            "keyframe 41 to 9, 57 inliers",
        )
        .with_relative_pose(&rotated),
        Event::loop_closure(
            13_000_000_000,
            EventKind::LoopClosureRejected,
            [12_900_000_000, 4_000_000_000],
            "too few inliers",
        ),
        Event::new(15_000_000_000, EventKind::TrackingLost, "no features"),
        Event::new(15_500_000_000, EventKind::TrackingRecovered, "relocalised"),
    ];
    let dir = tempfile::tempdir()?;
    let run = RunFolder::new(dir.path());
    run.write_events(&events)?;
    write(
        out,
        "events_json",
        "events.json",
        &std::fs::read(run.path(files::EVENTS))?,
    )?;
    let judged: Vec<JudgedEvent> = events
        .iter()
        .map(|e| JudgedEvent {
            event: e.clone(),
            true_loop: (e.kind == EventKind::LoopClosureAccepted).then_some(true),
            judged_by: Some(vinebench::results::JudgedBy::Stamps),
            wrong_join: None,
            revisit: None,
            gt_distance_m: Some(0.42),
            gt_heading_deg: Some(17.2),
            relative_error_m: Some(0.03),
            relative_error_deg: Some(0.5),
            error_before_m: None,
            error_after_m: None,
        })
        .collect();
    run.write_judged_events(&judged)?;
    write(
        out,
        "events_json",
        "judged-events.json",
        &std::fs::read(run.path(files::EVENTS))?,
    )?;
    #[derive(serde::Serialize)]
    struct Events<'a> {
        events: &'a [Event],
    }
    write(
        out,
        "events_toml",
        "events.toml",
        toml::to_string(&Events { events: &events })?.as_bytes(),
    )?;
    write(out, "events_toml", "none.toml", b"")
}

/// A sweep's `cell.json`, as `sweep::file_run` files a run.
fn cell(out: &Path) -> Result<()> {
    let sweep = tempfile::tempdir()?;
    let run = sweep.path().join("run");
    std::fs::create_dir_all(&run)?;
    let cell = vinebench::sweep::Cell {
        key: "0123456789abcdef".into(),
        scenario: "s3".into(),
        label: "orbslam2".into(),
        plugin: "/opt/vinebench/libvinebench_orbslam2.so".into(),
        params_toml: "[orb]\nfeatures = 1000\n".into(),
        pace: vinebench::runner::Pace::Free,
        queue_size: None,
        base_dir: Some("/opt/vinebench/configs".into()),
        seed: 2,
        point: vec![
            ("vineyard.growth_stage".into(), "4".into()),
            ("sensors.camera.noise".into(), "\"none\"".into()),
        ],
        world: "fedcba9876543210".into(),
        localize: None,
    };
    std::fs::create_dir_all(sweep.path().join("runs"))?;
    let status = vinebench::results::RunStatus::Failed("timed out after 5 s".into());
    vinebench::sweep::file_run(sweep.path(), &cell, "00ff00ff00ff00ff", &status, &run)?;
    let filed = vinebench::sweep::run_dir(sweep.path(), &cell.key).join("cell.json");
    write(out, "run_json", "cell.json", &std::fs::read(filed)?)
}

fn vocabulary(out: &Path) -> Result<()> {
    use rand::{Rng, SeedableRng};
    use slam_common::place::vocabulary::{TrainConfig, Vocabulary};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let images: Vec<Vec<[u8; 32]>> = (0..4)
        .map(|_| (0..12).map(|_| rng.random()).collect())
        .collect();
    let config = TrainConfig {
        k: 3,
        levels: 2,
        seed: 7,
        max_iterations: 4,
    };
    let trained = Vocabulary::train(&images, &config)?;
    let mut bytes = Vec::new();
    trained.write_to(&mut bytes)?;
    write(out, "vocabulary", "k3l2.voc", &bytes)
}

fn main() -> Result<()> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [run, out, recordings @ ..] = args.as_slice() else {
        return Err("usage: seeds RUN_DIR OUT_CORPUS_DIR RECORDING.mcap...".into());
    };
    trajectories(run, out)?;
    map(run, out)?;
    for recording in recordings {
        ros_messages(recording, out)?;
    }
    events(out)?;
    cell(out)?;
    vocabulary(out)
}
