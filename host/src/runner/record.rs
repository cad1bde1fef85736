//! Record once, replay to every run (`record_once`): each scenario of a plan is simulated
//! once into an MCAP recording (`vinebench record`, in a child process at the lowest CPU
//! priority) and every run of it is fed that recording, one after another or as many at once
//! as the plan's `jobs` allow, instead of a live simulation per run or one shared among runs
//! that must then start together.
//!
//! What it buys: the simulation's cost is paid once per scenario whatever the number of
//! systems, and a system never shares the cores with a simulation — the next scenario is
//! recorded while the current one's runs replay, at `nice 19`, so that a paced system (the
//! real ORB-SLAM3 with threads of its own) keeps the cores it asks for. The recording is the
//! simulator's own stream (same messages, byte for byte), so a run fed from it gets the same
//! data as a live one, and its pictures of loops can be re-rendered from its world and seed
//! (`timing.json` says `source = "recording"`, not `"dataset"`).
//!
//! Recordings are large (the camera: 64 MB per simulated second); at most `jobs + 1` exist at
//! once, each removed when its last run has ended — kept when a Ctrl-C stopped the plan, so
//! that a resumed sweep replays it instead of simulating again. Their names hash everything
//! that makes their bytes (the world's text, scenario, seed, route limit, sensors and the
//! `vinebench` build), so a kept one is never replayed to a run it does not belong to.
//!
//! A recording leaves the GNSS receiver out: each run that takes GNSS simulates its own
//! receiver as it replays (cheap beside the camera and the lidar) and merges its epochs in
//! where the live stream puts them (`dataset::replay_with_live`), so worlds that differ only
//! in their receiver ([`recorded_world_text`]: a sweep over receivers) replay one recording.
//! Every sensor draws from a stream of its own, so the rest is the same bytes whatever the
//! receiver (tested).

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Condvar, Mutex};
use std::time::Duration;

use sim::SensorSet;

use super::interrupt;

/// One scenario's recording, for the runs of a group.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    pub path: PathBuf,
    pub scenario: String,
    /// Every sensor the group's runs take, and ground truth.
    pub sensors: SensorSet,
}

/// Every sensor of `a` and of `b`.
pub fn union(a: SensorSet, b: SensorSet) -> SensorSet {
    SensorSet {
        ground_truth: a.ground_truth || b.ground_truth,
        imu: a.imu || b.imu,
        wheel_odometry: a.wheel_odometry || b.wheel_odometry,
        lidar: a.lidar || b.lidar,
        scan2d: a.scan2d || b.scan2d,
        rgbd: a.rgbd || b.rgbd,
        gnss: a.gnss || b.gnss,
    }
}

/// How far past a route limit a recording goes, seconds: a run cuts its stream at the first
/// message stamped past the limit, and for a run that merges its GNSS epochs in, that
/// message (a sweep's end comes at most 0.1 s after its stamp) must be in the file, or the
/// merge could pass on an epoch the live stream would have cut.
const PAST_THE_LIMIT_S: f64 = 1.0;

/// The limit a recording for runs cut at `max_time_s` is made with.
pub fn recorded_max_time(max_time_s: Option<f64>) -> Option<f64> {
    max_time_s.map(|t| t + PAST_THE_LIMIT_S)
}

/// What a recording's bytes depend on in `config`: the world without its GNSS receiver,
/// which recordings leave out (see the module's doc), as TOML.
pub fn recorded_world_text(config: &sim::SimConfig) -> String {
    let mut without = config.clone();
    without.sensors.gnss = Default::default();
    without.to_toml_string()
}

/// The sensors a recording for runs that take `sensors` holds: all but GNSS.
pub fn recorded_sensors(sensors: SensorSet) -> SensorSet {
    SensorSet {
        gnss: false,
        ..sensors
    }
}

/// `gt,imu,...`: a sensor set as `vinebench record --sensors` reads it.
pub fn sensor_names(set: SensorSet) -> String {
    [
        (set.ground_truth, "gt"),
        (set.imu, "imu"),
        (set.wheel_odometry, "odom"),
        (set.lidar, "lidar"),
        (set.scan2d, "scan2d"),
        (set.rgbd, "rgbd"),
        (set.gnss, "gnss"),
    ]
    .iter()
    .filter(|(on, _)| *on)
    .map(|(_, name)| *name)
    .collect::<Vec<_>>()
    .join(",")
}

/// Where a scenario's recording goes in `dir`: `<scenario>-seed<seed>-<hash>.mcap`, the hash
/// over what makes its bytes.
pub fn recording_path(
    dir: &Path,
    world_text: &str,
    scenario: &str,
    seed: u64,
    max_time_s: Option<f64>,
    sensors: SensorSet,
    build: &str,
) -> PathBuf {
    let what = format!(
        "vinebench-recording 1\nworld {world_text:?}\nscenario {scenario:?}\nseed {seed}\n\
         max_time {max_time_s:?}\nsensors {}\nbuild {build}\n",
        sensor_names(sensors)
    );
    let hash = crate::results::short_hash(what.as_bytes());
    dir.join(format!("{scenario}-seed{seed}-{hash}.mcap"))
}

/// How often a recording's child is looked at (for Ctrl-C).
const POLL: Duration = Duration::from_millis(100);

/// Records `rec` with `vinebench record` in a child process, `ahead` (while runs replay
/// other recordings) at the lowest CPU priority (`nice -n 19` where there is `nice`), else at
/// the normal one: with nothing replaying there is nothing to yield to; `Err` says why not.
/// Stops the child on Ctrl-C.
pub fn record(
    rec: &Recording,
    world: Option<&Path>,
    seed: u64,
    max_time_s: Option<f64>,
    ahead: bool,
) -> Result<(), String> {
    let exe = std::env::current_exe()
        .map_err(|e| format!("{CANNOT_RECORD}: cannot find the vinebench executable: {e}"))?;
    let mut args: Vec<std::ffi::OsString> = vec![
        "record".into(),
        "--scenario".into(),
        rec.scenario.clone().into(),
        "--seed".into(),
        seed.to_string().into(),
        "--sensors".into(),
        sensor_names(rec.sensors).into(),
        "--output".into(),
        rec.path.clone().into(),
    ];
    if let Some(w) = world {
        args.extend(["--world".into(), w.as_os_str().to_owned()]);
    }
    if let Some(t) = max_time_s {
        args.extend(["--max-time".into(), format!("{t:?}").into()]);
    }
    let spawn = |command: &mut Command| {
        // Its own process group: the terminal's Ctrl-C reaches the supervisor, which stops
        // it (as it does its workers).
        std::os::unix::process::CommandExt::process_group(command, 0);
        command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
    };
    let niced = if ahead {
        spawn(
            Command::new("nice")
                .args(["-n", "19"])
                .arg(&exe)
                .args(&args),
        )
    } else {
        Err(std::io::Error::other("not ahead"))
    };
    let mut child = match niced {
        Ok(child) => child,
        // No `nice` here: the recording at the normal priority.
        Err(_) => spawn(Command::new(&exe).args(&args))
            .map_err(|e| format!("{CANNOT_RECORD}: cannot start `vinebench record`: {e}"))?,
    };
    let mut stderr = child.stderr.take();
    // The child's messages, read as they come so that a chatty child never blocks.
    let reading = std::thread::spawn(move || {
        let mut text = String::new();
        if let Some(s) = stderr.as_mut() {
            let _ = s.read_to_string(&mut text);
        }
        text
    });
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Ok(status),
            Ok(None) if interrupt::interrupted() => {
                let _ = child.kill();
                let _ = child.wait();
                break Err(interrupt::REASON.to_owned());
            }
            Ok(None) => std::thread::sleep(POLL),
            Err(e) => break Err(format!("waiting for `vinebench record`: {e}")),
        }
    };
    let text = reading.join().unwrap_or_default();
    match status {
        Ok(s) if s.success() && rec.path.is_file() => Ok(()),
        Ok(s) => Err(format!(
            "{CANNOT_RECORD} {} ({s}): {}",
            rec.scenario,
            text.lines().last().unwrap_or("no message")
        )),
        Err(why) => {
            // A stopped child leaves its temporary file (`dataset::mcap_file`) behind.
            if let (Some(dir), Some(name)) = (rec.path.parent(), rec.path.file_name()) {
                let prefix = format!(".{}.tmp-", name.to_string_lossy());
                for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
                    if entry.file_name().to_string_lossy().starts_with(&prefix) {
                        let _ = std::fs::remove_file(entry.path());
                    }
                }
            }
            Err(why)
        }
    }
}

/// How the failure of a run whose recording could not be made begins (a full disk, say: the
/// host's doing, not the plugin's, so a sweep does not file the run).
pub const CANNOT_RECORD: &str = "could not record";

/// The recordings of a plan, made in order by one thread ahead of the runs that replay them,
/// at most `limit` on disk at once.
#[derive(Debug)]
pub struct Pipeline {
    state: Mutex<State>,
    changed: Condvar,
    limit: usize,
}

#[derive(Debug)]
struct State {
    /// Each recording's outcome once made (by index in the plan's recordings).
    made: Vec<Option<Result<(), String>>>,
    /// Recordings made (or being made) and not yet removed.
    on_disk: usize,
}

impl Pipeline {
    pub fn new(recordings: usize, limit: usize) -> Self {
        Pipeline {
            state: Mutex::new(State {
                made: vec![None; recordings],
                on_disk: 0,
            }),
            changed: Condvar::new(),
            limit: limit.max(1),
        }
    }

    /// Makes the recordings in order (the recorder thread's work), each once fewer than
    /// the limit are on disk; one already there (kept by a stopped plan) is taken as made.
    /// `make` is told whether it records ahead: while another recording is on disk (its runs
    /// replaying it, or about to).
    pub fn make_all(
        &self,
        recordings: &[&Recording],
        make: &dyn Fn(&Recording, bool) -> Result<(), String>,
    ) {
        for (k, rec) in recordings.iter().enumerate() {
            let mut state = self.state.lock().expect("no panics while holding the lock");
            while state.on_disk >= self.limit && !interrupt::interrupted() {
                state = self
                    .changed
                    .wait_timeout(state, POLL)
                    .expect("no panics while holding the lock")
                    .0;
            }
            let ahead = state.on_disk > 0;
            state.on_disk += 1;
            drop(state);
            let outcome = if interrupt::interrupted() {
                Err(interrupt::REASON.to_owned())
            } else if rec.path.is_file() {
                Ok(())
            } else {
                make(rec, ahead)
            };
            self.state
                .lock()
                .expect("no panics while holding the lock")
                .made[k] = Some(outcome);
            self.changed.notify_all();
        }
    }

    /// Waits until recording `k` is made; its outcome.
    pub fn wait(&self, k: usize) -> Result<(), String> {
        let mut state = self.state.lock().expect("no panics while holding the lock");
        loop {
            if let Some(outcome) = &state.made[k] {
                return outcome.clone();
            }
            state = self
                .changed
                .wait(state)
                .expect("no panics while holding the lock");
        }
    }

    /// Recording `k`'s runs have ended: it is removed (unless a Ctrl-C stopped the plan, so
    /// that a resumed sweep replays it), which lets the next one be made.
    pub fn release(&self, rec: &Recording) {
        if !interrupt::interrupted() {
            let _ = std::fs::remove_file(&rec.path);
        }
        let mut state = self.state.lock().expect("no panics while holding the lock");
        state.on_disk = state.on_disk.saturating_sub(1);
        drop(state);
        self.changed.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recordings_name_changes_with_whatever_makes_its_bytes() {
        let dir = Path::new("/r");
        let set: SensorSet = "gt,rgbd".parse().expect("sensors");
        let base = recording_path(dir, "w", "s3", 1, None, set, "b");
        assert!(base.to_string_lossy().starts_with("/r/s3-seed1-"));
        assert_eq!(base, recording_path(dir, "w", "s3", 1, None, set, "b"));
        let lidar: SensorSet = "gt,lidar".parse().expect("sensors");
        for other in [
            recording_path(dir, "w2", "s3", 1, None, set, "b"),
            recording_path(dir, "w", "s1", 1, None, set, "b"),
            recording_path(dir, "w", "s3", 2, None, set, "b"),
            recording_path(dir, "w", "s3", 1, Some(5.0), set, "b"),
            recording_path(dir, "w", "s3", 1, None, lidar, "b"),
            recording_path(dir, "w", "s3", 1, None, set, "b2"),
        ] {
            assert_ne!(base, other);
        }
        assert_eq!(
            sensor_names(SensorSet::ALL),
            "gt,imu,odom,lidar,scan2d,rgbd,gnss"
        );
        assert_eq!(sensor_names(set), "gt,rgbd");
    }

    /// The recorder never has more than its limit on disk: with a limit of 2 and three
    /// recordings, the third waits until the first is released.
    #[test]
    fn the_pipeline_makes_no_more_than_its_limit_ahead() {
        let dir = tempfile::tempdir().expect("tempdir");
        let recs: Vec<Recording> = (0..3)
            .map(|k| Recording {
                path: dir.path().join(format!("{k}.mcap")),
                scenario: format!("s{k}"),
                sensors: SensorSet::ALL,
            })
            .collect();
        let refs: Vec<&Recording> = recs.iter().collect();
        let pipeline = Pipeline::new(recs.len(), 2);
        let made = Mutex::new(Vec::new());
        std::thread::scope(|scope| {
            scope.spawn(|| {
                pipeline.make_all(&refs, &|r, _| {
                    std::fs::write(&r.path, b"x").map_err(|e| e.to_string())?;
                    made.lock().expect("lock").push(r.scenario.clone());
                    Ok(())
                });
            });
            assert_eq!(pipeline.wait(0), Ok(()));
            assert_eq!(pipeline.wait(1), Ok(()));
            std::thread::sleep(Duration::from_millis(300));
            assert_eq!(
                made.lock().expect("lock").len(),
                2,
                "the third waits for a release"
            );
            pipeline.release(&recs[0]);
            assert_eq!(pipeline.wait(2), Ok(()));
            pipeline.release(&recs[1]);
            pipeline.release(&recs[2]);
        });
        assert_eq!(*made.lock().expect("lock"), ["s0", "s1", "s2"]);
        assert!(
            !recs.iter().any(|r| r.path.exists()),
            "each removed once released"
        );
    }
}
