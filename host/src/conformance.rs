//! `vinebench check-plugin`: the conformance run a plugin author does before submitting.
//!
//! Each check ([`Check`]) runs in a child process of its own (`vinebench worker --check`),
//! under a timeout, so that a plugin that crashes or hangs fails that check and the next one
//! still runs. A check loads the plugin through its door, creates it with the rig of the
//! world, and feeds it a short simulated route or edge-case input (empty clouds, NaN points,
//! zero-size images, messages of a sensor it did not ask for, stamps out of order, `finish`
//! without data). A plugin passes a check when it neither crashes nor hangs, answers every
//! input with a pose, no pose, or a one-line error, and never returns a non-finite pose; on
//! the short route it must also never fail, and `finish` must return a finite trajectory.
//!
//! The child says what it is about to do (`at ...`) before each call, so a crash is named by
//! the input that caused it, and ends with one `pass ...` or `fail ...` line.

use std::io::{BufRead as _, BufReader, Write as _};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow};
use plugin_api::{
    Gnss, GnssStatus, Imu, LaserScan, LidarPoint, PluginError, PluginInstance, PointCloud, Pose,
    Requirements, RgbdFrame, Rig, SensorKind, WheelOdometry,
};
use sim::sensors::Message;

use crate::runner::worker::{deliver, sensor_set};

/// One check of the conformance list, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Check {
    /// The library loads through its door; name, version and requirements for the params.
    Load,
    /// `create` with the parameters and the rig, then destroyed.
    Create,
    /// A short simulated route of the plugin's own sensors, then `finish`.
    Route,
    /// `finish` with no message before it.
    FinishWithoutData,
    /// Empty clouds and scans, zero-size images, after a short valid start.
    EmptyInput,
    /// NaN and infinite values in every message kind it takes.
    NanInput,
    /// Messages of every sensor kind it did not ask for, and of a sensor not in the rig.
    UnrequestedSensor,
    /// Stamps going backwards and repeating.
    OutOfOrder,
    /// For a plugin that says it can localise (revision 4): the route's saved map (or, for
    /// one that saves none, the world's surveyed grid), the plugin started from it and fed
    /// the route again, every pose with a status.
    Localize,
}

impl Check {
    pub const ALL: [Check; 9] = [
        Check::Load,
        Check::Create,
        Check::Route,
        Check::FinishWithoutData,
        Check::EmptyInput,
        Check::NanInput,
        Check::UnrequestedSensor,
        Check::OutOfOrder,
        Check::Localize,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Check::Load => "load",
            Check::Create => "create",
            Check::Route => "route",
            Check::FinishWithoutData => "finish-without-data",
            Check::EmptyInput => "empty-input",
            Check::NanInput => "nan-input",
            Check::UnrequestedSensor => "unrequested-sensor",
            Check::OutOfOrder => "out-of-order",
            Check::Localize => "localize",
        }
    }

    pub fn from_name(name: &str) -> Option<Check> {
        Check::ALL.into_iter().find(|c| c.name() == name)
    }
}

/// What a check runs on: the plugin, its parameters and the world it is fed from.
#[derive(Debug, Clone)]
pub struct Subject {
    pub plugin: PathBuf,
    pub params_toml: String,
    /// The folder the plugin's relative paths are relative to (`VINEBENCH_BENCH_DIR`).
    pub base_dir: Option<PathBuf>,
    pub world: Option<PathBuf>,
    pub scenario: String,
    /// Simulated seconds of the route check.
    pub route_s: f64,
}

/// How one check ended.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    pub check: Check,
    pub passed: bool,
    /// What happened, one line.
    pub summary: String,
    /// The plugin's own last lines on standard error, when it failed.
    pub messages: Vec<String>,
}

/// Seconds of valid data fed before edge-case input.
const LEAD_IN_S: f64 = 2.0;

/// Runs every check on `subject`, each in a child process of this executable with
/// `timeout`; `on_outcome` is called as each ends.
pub fn check_all(
    subject: &Subject,
    timeout: Duration,
    on_outcome: &mut dyn FnMut(&Outcome),
) -> anyhow::Result<Vec<Outcome>> {
    let exe = std::env::current_exe().context("cannot find the vinebench executable")?;
    let logs = tempfile_dir()?;
    let mut outcomes = Vec::new();
    for check in Check::ALL {
        // The localize check feeds the route twice (mapping it, then localising on it).
        let limit = match check {
            Check::Localize => timeout * 2,
            _ => timeout,
        };
        let outcome = run_child(&exe, subject, check, limit, &logs)?;
        on_outcome(&outcome);
        let loaded = check != Check::Load || outcome.passed;
        outcomes.push(outcome);
        if !loaded {
            // Nothing else can run on a library that does not load.
            break;
        }
    }
    let _ = std::fs::remove_dir_all(&logs);
    Ok(outcomes)
}

fn tempfile_dir() -> anyhow::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("vinebench-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
    Ok(dir)
}

/// Runs one check in a child and reads how it ended.
fn run_child(
    exe: &Path,
    subject: &Subject,
    check: Check,
    timeout: Duration,
    logs: &Path,
) -> anyhow::Result<Outcome> {
    let log_path = logs.join(format!("{}.log", check.name()));
    let log = std::fs::File::create(&log_path).with_context(|| log_path.display().to_string())?;
    let mut command = Command::new(exe);
    // In a folder of its own, as a run's worker is in its run folder: what a plugin writes
    // to its working folder (ORB-SLAM3's settings files, say) is removed with the check's
    // logs. Its relative paths stay relative to where they were given.
    let base = match &subject.base_dir {
        Some(dir) => dir.clone(),
        None => std::env::current_dir().context("the current folder")?,
    };
    command
        .env("VINEBENCH_BENCH_DIR", base)
        .current_dir(logs)
        .arg("worker")
        .arg("--check")
        .arg(check.name())
        .arg("--plugin")
        .arg(&subject.plugin)
        .arg("--params")
        .arg(&subject.params_toml)
        .arg("--scenario")
        .arg(&subject.scenario)
        .arg("--route-s")
        .arg(subject.route_s.to_string());
    if let Some(world) = &subject.world {
        command.arg("--world").arg(world);
    }
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(log)
        .spawn()
        .context("cannot start a check's process")?;
    let stdout = child.stdout.take().expect("piped");
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let started = Instant::now();
    let mut at = String::from("loading the plugin");
    let mut verdict: Option<(bool, String)> = None;
    let read = |line: String, at: &mut String, verdict: &mut Option<(bool, String)>| {
        if let Some(what) = line.strip_prefix("at ") {
            *at = what.to_owned();
        } else if let Some(s) = line.strip_prefix("pass ") {
            *verdict = Some((true, s.to_owned()));
        } else if let Some(s) = line.strip_prefix("fail ") {
            *verdict = Some((false, s.to_owned()));
        }
    };
    let status = loop {
        while let Ok(line) = rx.try_recv() {
            read(line, &mut at, &mut verdict);
        }
        match child.try_wait()? {
            Some(status) => break Some(status),
            None if started.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            None => std::thread::sleep(Duration::from_millis(10)),
        }
    };
    let _ = reader.join();
    while let Ok(line) = rx.try_recv() {
        read(line, &mut at, &mut verdict);
    }
    let log_text = std::fs::read_to_string(&log_path).unwrap_or_default();
    let messages = |text: &str| -> Vec<String> {
        let lines: Vec<String> = text
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(str::to_owned)
            .collect();
        lines[lines.len().saturating_sub(6)..].to_vec()
    };
    let (passed, summary) = match (status, verdict) {
        (None, _) => (
            false,
            format!("hung: no answer within {} s ({at})", timeout.as_secs_f64()),
        ),
        (Some(status), Some((passed, summary))) if status.success() || !passed => (passed, summary),
        (Some(status), _) => (false, format!("{} ({at})", ended(status, &log_text))),
    };
    Ok(Outcome {
        check,
        passed,
        summary,
        messages: if passed {
            Vec::new()
        } else {
            messages(&log_text)
        },
    })
}

/// How a child that gave no verdict ended.
fn ended(status: std::process::ExitStatus, log: &str) -> String {
    use std::os::unix::process::ExitStatusExt as _;
    match status.signal() {
        Some(11) => "crashed: segmentation fault (SIGSEGV)".into(),
        Some(6) => match log.lines().find(|l| l.contains("panicked at")) {
            Some(p) => format!("aborted after a panic: {}", p.trim()),
            None => "crashed: aborted (SIGABRT)".into(),
        },
        Some(7) => "crashed: bus error (SIGBUS)".into(),
        Some(sig) => format!("crashed: killed by signal {sig}"),
        None => match log.lines().rev().find_map(|l| l.strip_prefix("error: ")) {
            Some(e) => format!("the process ended: {e}"),
            None => format!(
                "the process exited with status {} without a verdict",
                status.code().unwrap_or(-1)
            ),
        },
    }
}

/// The child's side: runs `check` and prints `pass ...` or `fail ...`; an `Err` is a
/// failure of the check's own set-up (a world that does not load).
pub fn run_check(check: Check, subject: &Subject) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    let verdict = match check_in_process(check, subject, &mut out) {
        Ok(summary) => format!("pass {summary}"),
        Err(Failure(why)) => format!("fail {why}"),
    };
    writeln!(out, "{}", verdict.replace('\n', " ")).ok();
    out.flush().ok();
    Ok(())
}

/// Why a check failed, one line.
#[derive(Debug)]
struct Failure(String);

impl From<anyhow::Error> for Failure {
    fn from(e: anyhow::Error) -> Self {
        Failure(format!("{e:#}"))
    }
}

/// Says what comes next, so that a crash is named by its input.
fn at(out: &mut dyn std::io::Write, what: &str) {
    writeln!(out, "at {what}").ok();
    out.flush().ok();
}

/// A plugin's answer, judged: `Ok(true)` a pose, `Ok(false)` no pose, `Err` the reason it
/// breaks the contract; `error` gets the plugin's error if it gave one.
fn judge(
    answer: Result<Option<Pose>, PluginError>,
    input: &str,
    error: &mut Option<String>,
) -> Result<bool, Failure> {
    match answer {
        Ok(Some(pose)) => {
            if pose.isometry().is_none() {
                return Err(Failure(format!(
                    "returned a non-finite pose or a non-unit quaternion for {input}: {pose:?}"
                )));
            }
            Ok(true)
        }
        Ok(None) => Ok(false),
        Err(e) => {
            let text = e.0.trim();
            if text.is_empty() {
                return Err(Failure(format!("answered {input} with an empty error")));
            }
            if text.contains('\n') {
                return Err(Failure(format!(
                    "answered {input} with an error of {} lines, not one: {:?}",
                    text.lines().count(),
                    text.lines().next().unwrap_or("")
                )));
            }
            *error = Some(text.to_owned());
            Ok(false)
        }
    }
}

/// The plugin, created for a check.
struct Probe<'a> {
    instance: PluginInstance,
    out: &'a mut dyn std::io::Write,
    poses: usize,
    calls: usize,
    /// Poses answered with each status (`PluginInstance::status`).
    localized: usize,
    searching: usize,
}

impl<'a> Probe<'a> {
    fn new(instance: PluginInstance, out: &'a mut dyn std::io::Write) -> Self {
        Self {
            instance,
            out,
            poses: 0,
            calls: 0,
            localized: 0,
            searching: 0,
        }
    }

    /// Feeds `message` described by `input`; `Some(error)` if the plugin answered with one.
    fn feed(
        &mut self,
        input: &str,
        call: impl FnOnce(&mut PluginInstance) -> Result<Option<Pose>, PluginError>,
    ) -> Result<Option<String>, Failure> {
        at(self.out, input);
        self.calls += 1;
        let mut error = None;
        if judge(call(&mut self.instance), input, &mut error)? {
            self.poses += 1;
        }
        Ok(error)
    }

    /// `finish`, judged: a one-line error or a trajectory of finite poses.
    fn finish(&mut self, strict: bool) -> Result<String, Failure> {
        at(self.out, "finish");
        match self.instance.finish() {
            Ok(output) => {
                if let Some(bad) = output.trajectory.iter().find(|p| p.isometry().is_none()) {
                    return Err(Failure(format!(
                        "finish returned a non-finite pose: {bad:?}"
                    )));
                }
                if strict && output.trajectory.is_empty() {
                    return Err(Failure("finish returned an empty trajectory".into()));
                }
                if let Some(grid) = &output.grid
                    && grid.cells.len() != grid.width as usize * grid.height as usize
                {
                    return Err(Failure(format!(
                        "finish returned a {}x{} grid with {} cells",
                        grid.width,
                        grid.height,
                        grid.cells.len()
                    )));
                }
                for e in &output.events {
                    if e.loop_relative_pose.is_some() && e.relative_pose().is_none() {
                        return Err(Failure(format!(
                            "finish returned an event at {} ns whose loop_relative_pose is not finite with a unit quaternion",
                            e.stamp_ns
                        )));
                    }
                    if e.loop_matches.is_some() && e.matches().is_none() {
                        return Err(Failure(format!(
                            "finish returned an event at {} ns whose loop_matches are not finite",
                            e.stamp_ns
                        )));
                    }
                }
                let with_matches = output
                    .events
                    .iter()
                    .filter(|e| e.loop_matches.is_some())
                    .count();
                Ok(format!(
                    "finish: {} poses, {} events ({with_matches} with matched keypoints)",
                    output.trajectory.len(),
                    output.events.len()
                ))
            }
            Err(e) if strict => Err(Failure(format!("finish failed: {e}"))),
            Err(e) => {
                let mut error = None;
                judge(Err(e), "finish", &mut error)?;
                Ok(format!(
                    "finish: one-line error \"{}\"",
                    error.unwrap_or_default()
                ))
            }
        }
    }
}

fn check_in_process(
    check: Check,
    subject: &Subject,
    out: &mut dyn std::io::Write,
) -> Result<String, Failure> {
    at(out, "loading the plugin");
    let plugin = plugin_api::load(&subject.plugin).map_err(|e| Failure(e.to_string()))?;
    at(out, "asking its requirements for the parameters");
    let requirements = plugin
        .requirements_for(&subject.params_toml)
        .map_err(|e| Failure(format!("requirements: {e}")))?;
    if check == Check::Load {
        let sensors: Vec<&str> = requirements.sensors.iter().map(|k| k.name()).collect();
        if sensors.is_empty() {
            return Err(Failure("it asks for no sensor".into()));
        }
        return Ok(format!(
            "{} {} through the {} door; {:?} [{}]",
            plugin.name,
            plugin.version,
            plugin.door().name(),
            requirements.mode,
            sensors.join(", ")
        )
        .to_lowercase());
    }
    let config = sim::SimConfig::load(subject.world.as_deref())
        .map_err(|e| Failure(format!("the world: {e}")))?;
    let rig = crate::rig::rig_for(&config, &requirements.sensors);
    if check == Check::Localize {
        return check_localize(&plugin, &requirements, subject, &config, &rig, out);
    }
    at(out, "create");
    let instance = match plugin.create(&subject.params_toml, &rig) {
        Ok(instance) => instance,
        // A plugin that only localises (amcl) is checked localising in the surveyed grid.
        Err(e) if requirements.can_localize => {
            at(
                out,
                "create failed; create_localizing in the world's surveyed grid",
            );
            let world = sim::world::World::from_config(&config);
            let grid = crate::runner::localize::surveyed_grid(&config, &world).to_map_bytes();
            let start = plugin_api::MapStart {
                map: &grid,
                format: plugin_api::GRID_MAP_FORMAT,
                format_version: plugin_api::GRID_MAP_VERSION,
                initial_guess: None,
            };
            plugin
                .create_localizing(&subject.params_toml, &rig, &start)
                .map_err(|l| {
                    Failure(format!(
                        "create failed: {e}; and localising in the surveyed grid: {l}"
                    ))
                })?
        }
        Err(e) => return Err(Failure(format!("create failed: {e}"))),
    };
    let mut probe = Probe::new(instance, out);
    match check {
        Check::Load | Check::Localize => unreachable!("answered above"),
        Check::Create => Ok("created and destroyed".into()),
        Check::Route => {
            let (fed, last) =
                lead_in(&mut probe, subject, &config, &requirements, subject.route_s)?;
            let finish = probe.finish(true)?;
            Ok(format!(
                "{}, first {:.1} s: {fed} messages, {} poses, all finite (last at {:.3} s); {finish}",
                subject.scenario,
                subject.route_s,
                probe.poses,
                last as f64 * 1e-9
            ))
        }
        Check::FinishWithoutData => probe.finish(false),
        Check::EmptyInput | Check::NanInput | Check::UnrequestedSensor | Check::OutOfOrder => {
            let (_, last) = lead_in(&mut probe, subject, &config, &requirements, LEAD_IN_S)?;
            let kinds: Vec<SensorKind> = match check {
                Check::UnrequestedSensor => SensorKind::ALL
                    .into_iter()
                    .filter(|k| !requirements.sensors.contains(k))
                    .collect(),
                _ => requirements.sensors.clone(),
            };
            let edge = edge_input(check, &rig, &kinds, last);
            let count = edge.len();
            if count == 0 {
                return Ok(match check {
                    Check::EmptyInput => {
                        "nothing to feed: none of its sensors' messages has an empty form".into()
                    }
                    _ => "nothing to feed".into(),
                });
            }
            // Unlike a run, an error does not end the input here: every edge case is fed, and
            // each must be answered without a crash, a hang or a bad pose.
            let mut errors: Vec<String> = Vec::new();
            for (k, input) in edge.into_iter().enumerate() {
                let what = format!("{} ({} of {count})", input.describe(), k + 1);
                if let Some(error) = probe.feed(&what, |p| input.deliver(p))? {
                    errors.push(error);
                }
            }
            let finish = probe.finish(false)?;
            let answered = match errors.first() {
                None => "without error or bad pose".to_owned(),
                Some(first) => format!(
                    "{} with a one-line error (first: \"{first}\")",
                    errors.len()
                ),
            };
            Ok(format!("{count} inputs answered, {answered}; {finish}"))
        }
    }
}

/// [`Check::Localize`]: the route mapped and its map saved (a plugin that saves none, or
/// cannot map, gets the world's surveyed grid), then the plugin started from that map and fed
/// the route again; it must start, answer with finite poses, and say a status with each.
fn check_localize(
    plugin: &plugin_api::LoadedPlugin,
    requirements: &Requirements,
    subject: &Subject,
    config: &sim::SimConfig,
    rig: &Rig,
    out: &mut dyn std::io::Write,
) -> Result<String, Failure> {
    if !requirements.can_localize {
        return Ok("does not say it can localise (can_localize): nothing to check".into());
    }
    at(out, "create, to map the route");
    let saved = match plugin.create(&subject.params_toml, rig) {
        Ok(instance) => {
            let mut probe = Probe::new(instance, &mut *out);
            lead_in(&mut probe, subject, config, requirements, subject.route_s)?;
            at(probe.out, "finish, for the saved map");
            let output = probe
                .instance
                .finish()
                .map_err(|e| Failure(format!("finish of the mapping route failed: {e}")))?;
            if let Some(m) = &output.saved_map
                && m.format.trim().is_empty()
            {
                return Err(Failure("the saved map's format has no name".into()));
            }
            output.saved_map
        }
        // A plugin that only localises (amcl) maps nothing.
        Err(_) => None,
    };
    let (bytes, format, version, what) = match saved {
        Some(m) => {
            let what = format!(
                "its map ({} version {}, {} bytes)",
                m.format,
                m.version,
                m.bytes.len()
            );
            (m.bytes, m.format, m.version, what)
        }
        None => {
            let world = sim::world::World::from_config(config);
            let grid = crate::runner::localize::surveyed_grid(config, &world);
            (
                grid.to_map_bytes(),
                plugin_api::GRID_MAP_FORMAT.to_owned(),
                plugin_api::GRID_MAP_VERSION,
                "the world's surveyed grid (it saved no map)".to_owned(),
            )
        }
    };
    at(out, "create_localizing");
    let start = plugin_api::MapStart {
        map: &bytes,
        format: &format,
        format_version: version,
        initial_guess: None,
    };
    let instance = plugin
        .create_localizing(&subject.params_toml, rig, &start)
        .map_err(|e| Failure(format!("could not start from {what}: {e}")))?;
    let mut probe = Probe::new(instance, out);
    let (fed, _) = lead_in(&mut probe, subject, config, requirements, subject.route_s)?;
    let finish = probe.finish(true)?;
    Ok(format!(
        "started from {what}; {fed} messages, {} poses ({} localised, {} searching); {finish}",
        probe.poses, probe.localized, probe.searching
    ))
}

/// Feeds the first `seconds` of the route with the plugin's own sensors; the messages fed
/// and the last stamp. Any error fails: a plugin must run a normal route.
fn lead_in(
    probe: &mut Probe<'_>,
    subject: &Subject,
    config: &sim::SimConfig,
    requirements: &Requirements,
    seconds: f64,
) -> Result<(usize, i64), Failure> {
    let sim = sim::Simulation::new(config, &subject.scenario, 0)
        .map_err(|e| Failure(format!("the simulation: {e}")))?;
    let end_ns = crate::runner::route_end_ns(sim.duration_ns(), Some(seconds))?;
    let mut points = Vec::new();
    let mut fed = 0;
    let mut last = 0;
    let mut next_mark = 0;
    for message in sim.stream(sensor_set(&requirements.sensors)) {
        if matches!(message, Message::GroundTruth(_)) {
            continue;
        }
        let stamp = message.stamp_ns();
        if stamp > end_ns {
            break;
        }
        if stamp >= next_mark {
            at(
                probe.out,
                &format!("the route at t = {:.1} s", stamp as f64 * 1e-9),
            );
            next_mark = stamp + 1_000_000_000;
        }
        probe.calls += 1;
        let answer = deliver(&mut probe.instance, &message, &mut points);
        let input = format!(
            "the route's {} at {:.3} s",
            message.sensor(),
            stamp as f64 * 1e-9
        );
        let mut error = None;
        if judge(answer, &input, &mut error)? {
            probe.poses += 1;
            match probe.instance.status() {
                plugin_api::PoseStatus::Localized => probe.localized += 1,
                plugin_api::PoseStatus::Searching => probe.searching += 1,
            }
        }
        if let Some(e) = error {
            return Err(Failure(format!("failed on {input}: {e}")));
        }
        fed += 1;
        last = stamp;
    }
    Ok((fed, last))
}

/// One edge-case message.
#[derive(Debug)]
enum Input {
    Imu(Imu, &'static str),
    Odometry(WheelOdometry, &'static str),
    Gnss(Gnss, &'static str),
    Cloud {
        stamp_ns: i64,
        sensor: String,
        points: Vec<LidarPoint>,
        what: &'static str,
    },
    Scan {
        stamp_ns: i64,
        sensor: String,
        ranges: Vec<f32>,
        intensities: Vec<f32>,
        what: &'static str,
    },
    Frame {
        stamp_ns: i64,
        sensor: String,
        width: u32,
        height: u32,
        rgb: Vec<u8>,
        depth: Vec<f32>,
        intrinsics: [f64; 4],
        what: &'static str,
    },
}

impl Input {
    fn describe(&self) -> String {
        let (kind, what, stamp) = match self {
            Input::Imu(m, what) => ("IMU reading", *what, m.stamp_ns),
            Input::Odometry(m, what) => ("wheel odometry", *what, m.stamp_ns),
            Input::Gnss(m, what) => ("GNSS fix", *what, m.stamp_ns),
            Input::Cloud { stamp_ns, what, .. } => ("point cloud", *what, *stamp_ns),
            Input::Scan { stamp_ns, what, .. } => ("laser scan", *what, *stamp_ns),
            Input::Frame { stamp_ns, what, .. } => ("RGB-D frame", *what, *stamp_ns),
        };
        format!("{what} {kind} at {stamp} ns")
    }

    fn deliver(&self, p: &mut PluginInstance) -> Result<Option<Pose>, PluginError> {
        match self {
            Input::Imu(m, _) => p.on_imu(m),
            Input::Odometry(m, _) => p.on_wheel_odometry(m),
            Input::Gnss(m, _) => p.on_gnss(m),
            Input::Cloud {
                stamp_ns,
                sensor,
                points,
                ..
            } => p.on_point_cloud(&PointCloud {
                stamp_ns: *stamp_ns,
                sensor,
                points,
            }),
            Input::Scan {
                stamp_ns,
                sensor,
                ranges,
                intensities,
                ..
            } => p.on_laser_scan(&LaserScan {
                stamp_ns: *stamp_ns,
                sensor,
                angle_min_rad: -std::f32::consts::PI,
                angle_increment_rad: if ranges.is_empty() {
                    0.0
                } else {
                    2.0 * std::f32::consts::PI / ranges.len() as f32
                },
                time_increment_s: 0.0,
                range_min_m: 0.05,
                range_max_m: 30.0,
                ranges_m: ranges,
                intensities,
            }),
            Input::Frame {
                stamp_ns,
                sensor,
                width,
                height,
                rgb,
                depth,
                intrinsics,
                ..
            } => p.on_rgbd(&RgbdFrame {
                stamp_ns: *stamp_ns,
                sensor,
                width: *width,
                height: *height,
                rgb,
                depth_m: depth,
                intrinsics: *intrinsics,
            }),
        }
    }
}

/// The rig's name for the first sensor of `kind`, or a stand-in.
fn sensor_name(rig: &Rig, kind: SensorKind) -> String {
    rig.first(kind)
        .map_or_else(|| kind.name().to_owned(), |s| s.name.clone())
}

/// A plausible message of `kind` at `stamp_ns`, with `n` elements (points, ranges; a frame
/// is the rig camera's size, or empty for `n = 0`), each value passed through `value` (to
/// make some NaN).
fn message(
    rig: &Rig,
    kind: SensorKind,
    stamp_ns: i64,
    n: usize,
    value: &dyn Fn(usize, f64) -> f64,
    what: &'static str,
) -> Input {
    let sensor = sensor_name(rig, kind);
    match kind {
        SensorKind::Imu => Input::Imu(
            Imu {
                stamp_ns,
                accel_mps2: [value(0, 0.0), value(1, 0.0), value(2, 9.81)],
                gyro_rps: [value(3, 0.0), value(4, 0.0), value(5, 0.0)],
                orientation_xyzw: [0.0; 4],
            },
            what,
        ),
        SensorKind::WheelOdometry => Input::Odometry(
            WheelOdometry {
                stamp_ns,
                linear_mps: value(0, 0.3),
                angular_rps: value(1, 0.0),
                odom_from_base: Pose {
                    stamp_ns,
                    translation: [value(2, 0.0), 0.0, 0.0],
                    rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
                },
            },
            what,
        ),
        // An RTK fix near the datum, 2 cm per axis.
        SensorKind::Gnss => Input::Gnss(
            Gnss {
                stamp_ns,
                status: GnssStatus::Fixed,
                satellites: 12,
                position_enu_m: [value(0, 1.0), value(1, 2.0), value(2, 1.7)],
                covariance_enu_m2: std::array::from_fn(|i| {
                    value(3 + i, if i % 4 == 0 { 4e-4 } else { 0.0 })
                }),
                latitude_deg: value(12, 53.268642),
                longitude_deg: value(13, -0.524509),
                altitude_m: value(14, 1.7),
                hdop: 0.8,
            },
            what,
        ),
        SensorKind::Lidar => Input::Cloud {
            stamp_ns,
            sensor,
            points: (0..n)
                .map(|i| {
                    let a = i as f64 * 0.01;
                    LidarPoint {
                        x: value(i, 5.0 * a.cos()) as f32,
                        y: (5.0 * a.sin()) as f32,
                        z: ((i % 16) as f64 * 0.1 - 0.8) as f32,
                        intensity: 50.0,
                        time_s: (i as f64 * 1e-5) as f32,
                        ring: (i % 16) as u16,
                    }
                })
                .collect(),
            what,
        },
        SensorKind::Scan2d => Input::Scan {
            stamp_ns,
            sensor,
            ranges: (0..n).map(|i| value(i, 5.0) as f32).collect(),
            intensities: vec![100.0; n],
            what,
        },
        SensorKind::Rgbd => {
            // The rig's image size (a host never sends another), or 0 x 0 for `n = 0`.
            let pinhole = rig.first(SensorKind::Rgbd).and_then(|s| s.pinhole().ok());
            let intrinsics = pinhole.map_or([525.0, 525.0, 319.5, 239.5], |p| p.intrinsics());
            let (w, h) = match (n, pinhole) {
                (0, _) => (0, 0),
                (_, Some(p)) => (p.width as usize, p.height as usize),
                (_, None) => (640, 480),
            };
            Input::Frame {
                stamp_ns,
                sensor,
                width: w as u32,
                height: h as u32,
                rgb: (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect(),
                depth: (0..w * h).map(|i| value(i, 2.0) as f32).collect(),
                intrinsics,
                what,
            }
        }
    }
}

/// The edge-case inputs of `check` for the sensor `kinds`, stamped after `last_ns`.
fn edge_input(check: Check, rig: &Rig, kinds: &[SensorKind], last_ns: i64) -> Vec<Input> {
    let mut inputs = Vec::new();
    let mut t = last_ns;
    let mut next = || {
        t += 10_000_000;
        t
    };
    let plain = |_: usize, v: f64| v;
    for &kind in kinds {
        match check {
            Check::EmptyInput => match kind {
                SensorKind::Lidar | SensorKind::Scan2d | SensorKind::Rgbd => {
                    inputs.push(message(rig, kind, next(), 0, &plain, "an empty"));
                }
                // A fix's empty forms: a fix without a position, one with a zero
                // covariance, and no fix at all.
                SensorKind::Gnss => {
                    let mut without = message(rig, kind, next(), 0, &plain, "a position-less");
                    let mut zero = message(rig, kind, next(), 0, &plain, "a zero-covariance");
                    let mut none = message(rig, kind, next(), 0, &plain, "a no-fix");
                    if let (Input::Gnss(a, _), Input::Gnss(b, _), Input::Gnss(c, _)) =
                        (&mut without, &mut zero, &mut none)
                    {
                        a.position_enu_m = [f64::NAN; 3];
                        b.covariance_enu_m2 = [0.0; 9];
                        c.status = GnssStatus::NoFix;
                        c.position_enu_m = [f64::NAN; 3];
                        c.covariance_enu_m2 = [0.0; 9];
                    }
                    inputs.extend([without, zero, none]);
                }
                // Fixed-size messages have no empty form.
                SensorKind::Imu | SensorKind::WheelOdometry => {}
            },
            Check::NanInput => {
                let nan = |i: usize, v: f64| if i % 3 == 0 { f64::NAN } else { v };
                let inf = |i: usize, v: f64| if i % 5 == 1 { f64::INFINITY } else { v };
                inputs.push(message(rig, kind, next(), 64, &nan, "a NaN-valued"));
                inputs.push(message(rig, kind, next(), 64, &inf, "an infinity-valued"));
            }
            Check::UnrequestedSensor => {
                inputs.push(message(rig, kind, next(), 64, &plain, "an unrequested"));
            }
            Check::OutOfOrder => {
                // One second back, then the same stamp twice.
                let back = last_ns - 1_000_000_000;
                inputs.push(message(rig, kind, back, 64, &plain, "a one-second-old"));
                let again = next();
                inputs.push(message(rig, kind, again, 64, &plain, "a"));
                inputs.push(message(rig, kind, again, 64, &plain, "a repeated-stamp"));
            }
            Check::Load
            | Check::Create
            | Check::Route
            | Check::FinishWithoutData
            | Check::Localize => {}
        }
    }
    if check == Check::UnrequestedSensor {
        // A sensor the rig does not have, of a kind the plugin takes.
        if let Some(&kind) = [SensorKind::Lidar, SensorKind::Scan2d, SensorKind::Rgbd]
            .iter()
            .find(|k| !kinds.contains(k))
        {
            let mut m = message(rig, kind, next(), 64, &plain, "an unknown sensor's");
            match &mut m {
                Input::Cloud { sensor, .. }
                | Input::Scan { sensor, .. }
                | Input::Frame { sensor, .. } => *sensor = "not_in_the_rig".into(),
                Input::Imu(..) | Input::Odometry(..) | Input::Gnss(..) => {}
            }
            inputs.push(m);
        }
    }
    inputs
}

/// Parses what `vinebench worker --check` gets into a [`Subject`].
pub fn subject_from_args(
    plugin: &Path,
    params: &str,
    world: Option<&Path>,
    scenario: &str,
    route_s: f64,
) -> anyhow::Result<Subject> {
    anyhow::ensure!(
        route_s.is_finite() && route_s > 0.0,
        "--route-s {route_s}: must be positive"
    );
    Ok(Subject {
        plugin: plugin.to_owned(),
        params_toml: params.to_owned(),
        base_dir: None,
        world: world.map(Path::to_owned),
        scenario: scenario.to_owned(),
        route_s,
    })
}

/// The check called `name`, or an error listing them.
pub fn check_named(name: &str) -> anyhow::Result<Check> {
    Check::from_name(name).ok_or_else(|| {
        let known: Vec<&str> = Check::ALL.iter().map(|c| c.name()).collect();
        anyhow!("unknown check {name:?} (known: {})", known.join(", "))
    })
}
