//! Runs a benchmark matrix: every (scenario, plugin) pair in its own worker process, as many
//! at once as asked, each scored against ground truth as it ends. What a run leaves is its
//! folder ([`crate::results::RunFolder`]); the commands hand those to the report or the sweep.

mod evaluate;
pub mod feed;
mod frames;
pub mod interrupt;
pub mod job;
pub mod localize;
mod loops;
mod queue;
mod record;
pub(crate) mod supervise;
pub mod timing;
pub mod worker;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

pub use evaluate::evaluate;
pub use job::{Job, Pace, QueueSize, check_max_time, route_end_ns};
pub use localize::{GuessSpec, Kidnap, LocalizeSpec, MapSource};
pub use queue::read_drops;
pub use record::recorded_world_text;

use crate::results::{RunFolder, RunOutcome, RunStatus, files};

/// One run of the matrix.
#[derive(Debug, Clone)]
pub struct PlannedRun {
    pub scenario: String,
    pub label: String,
    pub plugin: PathBuf,
    pub params_toml: String,
    pub pace: Pace,
    /// Bounded subscriber queues (paced runs): `None`, unbounded.
    pub queue_size: Option<QueueSize>,
    /// Drop exactly the messages a `dropped.csv` names (`vinebench run --drops`).
    pub drops: Option<PathBuf>,
    /// The folder the plugin's relative paths are relative to (the bench file's): handed
    /// to the worker as `VINEBENCH_BENCH_DIR`. `None`: the current folder.
    pub base_dir: Option<PathBuf>,
    /// A localisation run's map and options (`vinebench localize`); `None`: a mapping run.
    pub localize: Option<LocalizeSpec>,
    /// This run's own world file instead of the plan's (a `[[localize]]` entry's `world`).
    pub world: Option<PathBuf>,
}

/// A resolved matrix.
#[derive(Debug, Clone)]
pub struct Plan {
    pub world: Option<PathBuf>,
    pub seed: u64,
    pub scenarios: Vec<String>,
    pub runs: Vec<PlannedRun>,
    pub jobs: usize,
    pub timeout: Duration,
    pub memory_limit_mb: u64,
    pub alignment: eval::Alignment,
    /// Feed every run from this recording instead of the live simulator.
    pub dataset: Option<PathBuf>,
    /// Cut every route at this simulated time, seconds; `None`: whole routes.
    pub max_time_s: Option<f64>,
    /// Feed the runs of a scenario that need the same sensors from one simulation
    /// ([`feed`]) instead of one per run.
    pub share_simulation: bool,
    /// Record each scenario once into this folder and replay the recording to its runs
    /// ([`record`]: recorded ahead at the lowest CPU priority, removed after its runs)
    /// instead of simulating live; takes the place of `share_simulation`. Not with `dataset`.
    pub record_once: Option<PathBuf>,
    /// Draw a progress bar per run on the terminal (a sweep draws its own instead).
    pub bars: bool,
}

/// Called as each run of a plan ends, with its index in `Plan::runs` and its outcome (its
/// folder evaluated, `job.json` removed), which the callee may move away.
pub type OnDone<'a> = &'a (dyn Fn(usize, &RunOutcome) + Sync);

/// Runs the plan's runs in `work` (one folder per run, `work/<scenario>/<label>`, which
/// must not exist yet), calling `on_done` as each run ends; returns every run's outcome in
/// the plan's order.
pub fn execute(plan: &Plan, work: &Path, on_done: OnDone) -> anyhow::Result<Vec<RunOutcome>> {
    execute_observed(plan, work, &|_| {}, &|_, _| {}, on_done)
}

/// Called as a run moves on, with its index in `Plan::runs` and the fraction of its route
/// fed so far (0 to 1).
pub type OnProgress<'a> = &'a (dyn Fn(usize, f64) + Sync);

/// How the runs start: groups of run indices in the order they start, each with the slots
/// it takes (of the plan's `jobs`), a group's runs together (one shared simulation).
pub type Schedule = Vec<(Vec<usize>, usize)>;

/// [`execute`], telling `on_schedule` how the runs will start before any does (a progress
/// estimate follows it: a shared group's runs take as long as its slowest), and
/// `on_progress` how far each has got as it goes (the estimate's measure of a system's speed
/// before any of its runs has ended).
pub fn execute_observed(
    plan: &Plan,
    work: &Path,
    on_schedule: &dyn Fn(&Schedule),
    on_progress: OnProgress,
    on_done: OnDone,
) -> anyhow::Result<Vec<RunOutcome>> {
    let config = sim::SimConfig::load(plan.world.as_deref())?;
    for s in &plan.scenarios {
        if !config.scenarios.contains_key(s) {
            let known: Vec<&str> = config.scenarios.keys().map(String::as_str).collect();
            anyhow::bail!(
                "unknown scenario '{s}' in {} (known: {})",
                plan.world.as_deref().map_or_else(
                    || "the embedded world".to_owned(),
                    |p| p.display().to_string()
                ),
                known.join(", ")
            );
        }
    }
    std::fs::create_dir_all(work).with_context(|| work.display().to_string())?;
    run_all(plan, &config, work, on_schedule, on_progress, on_done)
}

/// Where the runs' progress goes: each run's bar, and the caller's observer.
struct Ticks<'a> {
    bars: Vec<ProgressBar>,
    observe: OnProgress<'a>,
}

impl Ticks<'_> {
    /// Run `i` has been fed the fraction `f` of its route.
    fn tick(&self, i: usize, f: f64) {
        self.bars[i].set_position((f * 1000.0) as u64);
        (self.observe)(i, f);
    }
}

/// Where each scenario of the plan stops, ns: its route's end or the plan's limit.
fn route_ends_ns(
    plan: &Plan,
    config: &sim::SimConfig,
    world: &sim::world::World,
) -> anyhow::Result<Vec<i64>> {
    plan.scenarios
        .iter()
        .map(|s| {
            let sim = sim::Simulation::with_world(config, world.clone(), s, plan.seed)?;
            route_end_ns(sim.duration_ns(), plan.max_time_s)
        })
        .collect()
}

/// The simulated seconds each run of the plan is fed, in the plan's order (to weigh runs
/// in a progress estimate).
pub fn route_seconds(plan: &Plan) -> anyhow::Result<Vec<f64>> {
    let config = sim::SimConfig::load(plan.world.as_deref())?;
    let world = sim::world::World::from_config(&config);
    let ends = route_ends_ns(plan, &config, &world)?;
    Ok(plan
        .runs
        .iter()
        .map(|r| {
            plan.scenarios
                .iter()
                .position(|s| *s == r.scenario)
                .map_or(0.0, |k| ends[k] as f64 * 1e-9)
        })
        .collect())
}

fn run_all(
    plan: &Plan,
    config: &sim::SimConfig,
    work: &Path,
    on_schedule: &dyn Fn(&Schedule),
    on_progress: OnProgress,
    on_done: OnDone,
) -> anyhow::Result<Vec<RunOutcome>> {
    let world = sim::world::World::from_config(config);
    // Route lengths in samples of 0.1 s, to start the longest first.
    let lengths: Vec<i64> = route_ends_ns(plan, config, &world)?
        .iter()
        .map(|end| end / 100_000_000 + 1)
        .collect();

    let bars = if plan.bars {
        MultiProgress::new()
    } else {
        MultiProgress::with_draw_target(indicatif::ProgressDrawTarget::hidden())
    };
    let style = ProgressStyle::with_template("{prefix:>28} [{bar:30}] {percent:>3}% {msg}")
        .expect("valid template")
        .progress_chars("=> ");
    let (groups, recordings) = match &plan.record_once {
        Some(dir) if plan.dataset.is_none() => {
            let dir = std::path::absolute(dir)?;
            std::fs::create_dir_all(&dir).with_context(|| dir.display().to_string())?;
            let world_text = recorded_world_text(config);
            // A run with a world of its own replays the plan's recordings only if they are
            // what its own world would record.
            for run in &plan.runs {
                if let Some(own) = &run.world {
                    let own_config = sim::SimConfig::load(Some(own))?;
                    anyhow::ensure!(
                        recorded_world_text(&own_config) == world_text,
                        "{}/{}: its world {} differs from the plan's in more than its GNSS \
                         receiver, so it cannot replay the plan's recordings",
                        run.scenario,
                        run.label,
                        own.display()
                    );
                }
            }
            let build = crate::results::exe_hash()?;
            group_recorded(plan, &lengths, &|scenario, sensors| {
                record::recording_path(
                    &dir,
                    &world_text,
                    scenario,
                    plan.seed,
                    record::recorded_max_time(plan.max_time_s),
                    sensors,
                    &build,
                )
            })
        }
        _ => (group_runs(plan, &lengths), Vec::new()),
    };
    let mut recording_of: Vec<Option<&record::Recording>> = vec![None; plan.runs.len()];
    for g in &groups {
        if let Some(k) = g.recording {
            g.runs
                .iter()
                .for_each(|&i| recording_of[i] = Some(&recordings[k]));
        }
    }
    on_schedule(
        &groups
            .iter()
            .map(|g| (g.runs.clone(), g.runs.len().min(plan.jobs.max(1))))
            .collect(),
    );
    let mut fed = vec![false; plan.runs.len()];
    for g in groups.iter().filter(|g| g.shared) {
        g.runs.iter().for_each(|&i| fed[i] = true);
    }
    let mut dirs: Vec<PathBuf> = Vec::with_capacity(plan.runs.len());
    let mut progress = Vec::with_capacity(plan.runs.len());
    for (i, run) in plan.runs.iter().enumerate() {
        // `work/<scenario>/<label>`; a second run of the same scenario and label (a sweep's
        // cells whose worlds differ only in what they replay alike) `<label>.2`, and so on.
        let mut dir = std::path::absolute(work.join(&run.scenario).join(&run.label))?;
        let mut n = 1;
        while dirs.contains(&dir) {
            n += 1;
            dir = std::path::absolute(work.join(&run.scenario).join(format!("{}.{n}", run.label)))?;
        }
        std::fs::create_dir_all(&dir)?;
        let job = Job {
            scenario: run.scenario.clone(),
            // Absolute: the worker runs in its run folder (see `supervise`).
            world: run
                .world
                .as_ref()
                .or(plan.world.as_ref())
                .map(std::path::absolute)
                .transpose()?,
            seed: plan.seed,
            plugin: std::path::absolute(&run.plugin)?,
            params_toml: run.params_toml.clone(),
            out_dir: dir.clone(),
            memory_limit_mb: plan.memory_limit_mb,
            dataset: match recording_of[i] {
                Some(rec) => Some(rec.path.clone()),
                None => plan.dataset.as_ref().map(std::path::absolute).transpose()?,
            },
            recorded: recording_of[i].is_some(),
            max_time_s: plan.max_time_s,
            fed: fed[i],
            pace: run.pace,
            queue_size: run.queue_size.clone(),
            drops: run.drops.as_ref().map(std::path::absolute).transpose()?,
            localize: run.localize.clone(),
        };
        crate::results::write_json(&dir.join(files::JOB), &job)?;
        let bar = bars.add(ProgressBar::new(1000).with_style(style.clone()));
        bar.set_prefix(format!("{}/{}", run.scenario, run.label));
        dirs.push(dir);
        progress.push(bar);
    }
    let ticks = Ticks {
        bars: progress,
        observe: on_progress,
    };

    // Groups start in order as soon as enough of the `jobs` slots are free (a group with
    // more runs than `jobs` takes them all); a group gives a slot back whenever it has fewer
    // runs left than it holds slots.
    let outcomes: Mutex<Vec<Option<RunOutcome>>> = Mutex::new(vec![None; plan.runs.len()]);
    let free = (Mutex::new(plan.jobs.max(1)), Condvar::new());
    let release = || {
        *free.0.lock().expect("no panics while holding the lock") += 1;
        free.1.notify_all();
    };
    let world = &world;
    let pipeline = record::Pipeline::new(recordings.len(), plan.jobs.max(1) + 1);
    let world_file = plan.world.as_ref().map(std::path::absolute).transpose()?;
    std::thread::scope(|scope| {
        if !recordings.is_empty() {
            let (pipeline, recordings, world_file) = (&pipeline, &recordings, &world_file);
            scope.spawn(move || {
                let refs: Vec<&record::Recording> = recordings.iter().collect();
                pipeline.make_all(&refs, &|rec, ahead| {
                    record::record(
                        rec,
                        world_file.as_deref(),
                        plan.seed,
                        record::recorded_max_time(plan.max_time_s),
                        ahead,
                    )
                });
            });
        }
        for group in &groups {
            let need = group.runs.len().min(plan.jobs.max(1));
            let mut slots = free.0.lock().expect("no panics while holding the lock");
            while *slots < need {
                slots = free
                    .1
                    .wait(slots)
                    .expect("no panics while holding the lock");
            }
            *slots -= need;
            drop(slots);
            let (dirs, ticks, outcomes, release) = (&dirs, &ticks, &outcomes, &release);
            let (pipeline, recordings) = (&pipeline, &recordings);
            if interrupt::interrupted() {
                // Nothing new starts after Ctrl-C; these runs were not run.
                let mut outcomes = outcomes.lock().expect("no panics while holding the lock");
                for &i in &group.runs {
                    outcomes[i] = Some(not_run(&plan.runs[i], &dirs[i], plan));
                }
                drop(outcomes);
                for _ in 0..need {
                    release();
                }
                continue;
            }
            scope.spawn(move || {
                let left = Mutex::new(group.runs.len());
                let done = |i: usize, outcome: RunOutcome| {
                    let bar = &ticks.bars[i];
                    match &outcome.status {
                        RunStatus::Ok => bar.finish_with_message("ok"),
                        RunStatus::Failed(why) => {
                            bar.abandon_with_message(format!("failed: {why}"))
                        }
                    }
                    on_done(i, &outcome);
                    outcomes.lock().expect("no panics while holding the lock")[i] = Some(outcome);
                    let mut left = left.lock().expect("no panics while holding the lock");
                    *left -= 1;
                    if *left < need {
                        release();
                    }
                };
                if group.shared {
                    run_shared(group, plan, config, world, dirs, ticks, &done);
                } else if let Some(k) = group.recording {
                    let outcome = pipeline.wait(k);
                    run_recorded(group, plan, dirs, ticks, need, outcome, &done);
                    pipeline.release(&recordings[k]);
                } else {
                    for &i in &group.runs {
                        let outcome = run_one(plan, i, &dirs[i], ticks);
                        done(i, outcome);
                    }
                }
            });
        }
    });
    if let Some(dir) = &plan.record_once {
        // Gone once empty: every recording was replayed and removed.
        let _ = std::fs::remove_dir(dir);
    }
    Ok(outcomes
        .into_inner()
        .expect("no panics while holding the lock")
        .into_iter()
        .map(|r| r.expect("every run was taken"))
        .collect())
}

/// Runs that are started together; `shared`: fed by one simulation in this process.
#[derive(Debug, Clone, PartialEq)]
struct Group {
    runs: Vec<usize>,
    shared: bool,
    sensors: Vec<sim::SensorSet>,
    /// The recording its runs replay (`record_once`), by index in the plan's recordings.
    recording: Option<usize>,
}

/// A worker that takes no message for this long is cut off from its group's simulation
/// (at most a quarter of the run's timeout: the group waits that long for a hung worker,
/// which its groupmates' own timeouts must absorb).
const STALL: Duration = Duration::from_secs(300);

/// Which runs share a simulation, in the order they start.
///
/// With sharing on (no dataset), all the runs of one scenario whose plugins need the same
/// expensive sensor (the camera; else the 3D lidar; else neither) are fed by one simulation,
/// however many they are: a second group would simulate the same scenario again, which
/// costs more than the runs' sharing the cores (a group starts when `jobs` slots, or as many
/// as it has runs, are free). The camera's groups start first, then the lidar's, longest
/// routes first, so that the long runs do not end up alone at the end. A plugin whose
/// sensors cannot be read (it fails to load) runs alone, to fail in its own worker.
fn group_runs(plan: &Plan, lengths: &[i64]) -> Vec<Group> {
    let share = plan.share_simulation && plan.dataset.is_none();
    let mut probed: BTreeMap<(&Path, &str), Option<sim::SensorSet>> = BTreeMap::new();
    let sensors: Vec<Option<sim::SensorSet>> = plan
        .runs
        .iter()
        .map(|r| {
            // A paced run simulates alone: in a shared stream it would hold the others
            // back to its pace.
            if !share || r.pace == Pace::Realtime {
                return None;
            }
            *probed
                .entry((r.plugin.as_path(), r.params_toml.as_str()))
                .or_insert_with(|| probe_sensors(r))
        })
        .collect();
    let scenario_len = |s: &str| scenario_len(plan, lengths, s);
    // (camera, lidar, route length, scenario): runs with the same key may share.
    let mut keyed: BTreeMap<(bool, bool, i64, &str), Vec<usize>> = BTreeMap::new();
    let mut groups = Vec::new();
    for (i, run) in plan.runs.iter().enumerate() {
        match sensors[i] {
            Some(set) => keyed
                .entry((
                    !set.rgbd,
                    !set.lidar,
                    -scenario_len(&run.scenario),
                    &run.scenario,
                ))
                .or_default()
                .push(i),
            None => groups.push(Group {
                runs: vec![i],
                shared: false,
                sensors: Vec::new(),
                recording: None,
            }),
        }
    }
    let mut shared: Vec<Group> = keyed
        .into_values()
        .map(|runs| Group {
            // A run alone simulates in its own worker, as without sharing.
            shared: runs.len() > 1,
            sensors: runs.iter().map(|&i| sensors[i].expect("keyed")).collect(),
            recording: None,
            runs,
        })
        .collect();
    shared.append(&mut groups);
    shared
}

/// A scenario's route length in `lengths` (0 if unknown).
fn scenario_len(plan: &Plan, lengths: &[i64], scenario: &str) -> i64 {
    plan.scenarios
        .iter()
        .position(|x| x == scenario)
        .and_then(|k| lengths.get(k))
        .copied()
        .unwrap_or(0)
}

/// With `record_once`: one group per scenario, longest route first, whose runs replay one
/// recording of every sensor they take; a plugin whose sensors cannot be read (it fails to
/// load) runs alone on the live simulation, to fail in its own worker.
fn group_recorded(
    plan: &Plan,
    lengths: &[i64],
    path: &dyn Fn(&str, sim::SensorSet) -> PathBuf,
) -> (Vec<Group>, Vec<record::Recording>) {
    let mut probed: BTreeMap<(&Path, &str), Option<sim::SensorSet>> = BTreeMap::new();
    let mut by_scenario: BTreeMap<(i64, &str), Vec<(usize, sim::SensorSet)>> = BTreeMap::new();
    let mut alone = Vec::new();
    for (i, run) in plan.runs.iter().enumerate() {
        let sensors = *probed
            .entry((run.plugin.as_path(), run.params_toml.as_str()))
            .or_insert_with(|| probe_sensors(run));
        match sensors {
            Some(set) => by_scenario
                .entry((-scenario_len(plan, lengths, &run.scenario), &run.scenario))
                .or_default()
                .push((i, set)),
            None => alone.push(Group {
                runs: vec![i],
                shared: false,
                sensors: Vec::new(),
                recording: None,
            }),
        }
    }
    let mut groups = Vec::new();
    let mut recordings = Vec::new();
    for ((_, scenario), runs) in by_scenario {
        let sensors = runs.iter().fold(
            sim::SensorSet {
                ground_truth: true,
                ..sim::SensorSet::default()
            },
            |all, &(_, set)| record::union(all, record::recorded_sensors(set)),
        );
        groups.push(Group {
            runs: runs.iter().map(|&(i, _)| i).collect(),
            shared: false,
            sensors: runs.iter().map(|&(_, set)| set).collect(),
            recording: Some(recordings.len()),
        });
        recordings.push(record::Recording {
            path: path(scenario, sensors),
            scenario: scenario.to_owned(),
            sensors,
        });
    }
    groups.append(&mut alone);
    (groups, recordings)
}

/// Runs a recorded group's runs on their recording once it is made (`made`: its outcome),
/// `at_once` of them at a time; if it could not be made, each fails with the reason.
fn run_recorded(
    group: &Group,
    plan: &Plan,
    dirs: &[PathBuf],
    ticks: &Ticks,
    at_once: usize,
    made: Result<(), String>,
    done: &(dyn Fn(usize, RunOutcome) + Sync),
) {
    if let Err(why) = made {
        for &i in &group.runs {
            done(
                i,
                finish_run(&plan.runs[i], &dirs[i], plan, Err(why.clone())),
            );
        }
        return;
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..at_once.max(1) {
            scope.spawn(|| {
                loop {
                    let n = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    let Some(&i) = group.runs.get(n) else {
                        break;
                    };
                    let outcome = if interrupt::interrupted() {
                        not_run(&plan.runs[i], &dirs[i], plan)
                    } else {
                        run_one(plan, i, &dirs[i], ticks)
                    };
                    done(i, outcome);
                }
            });
        }
    });
}

/// The sensors a run's plugin library asks for with its parameters, read in a child process
/// (`vinebench worker --sensors`) so that no plugin is ever loaded into the supervisor;
/// `None` if that fails.
fn probe_sensors(run: &PlannedRun) -> Option<sim::SensorSet> {
    let exe = std::env::current_exe().ok()?;
    let mut command = std::process::Command::new(exe);
    if let Some(dir) = &run.base_dir {
        command.env("VINEBENCH_BENCH_DIR", dir);
    }
    let mut child = command
        .arg("worker")
        .arg("--sensors")
        .arg(&run.plugin)
        .arg("--params")
        .arg(&run.params_toml)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .ok()?;
    let started = std::time::Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) if status.success() => break,
            Ok(None) if started.elapsed() < Duration::from_secs(60) => {
                std::thread::sleep(Duration::from_millis(10));
            }
            _ => {
                let _ = child.kill();
                let _ = child.wait();
                return None;
            }
        }
    }
    let mut out = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take()?, &mut out).ok()?;
    let mut kinds = Vec::new();
    for name in out.trim().split(',').filter(|n| !n.is_empty()) {
        kinds.push(
            *plugin_api::SensorKind::ALL
                .iter()
                .find(|k| k.name() == name)?,
        );
    }
    Some(worker::sensor_set(&kinds))
}

/// Runs a group's workers together, fed by one simulation of their scenario.
fn run_shared(
    group: &Group,
    plan: &Plan,
    config: &sim::SimConfig,
    world: &sim::world::World,
    dirs: &[PathBuf],
    ticks: &Ticks,
    done: &(dyn Fn(usize, RunOutcome) + Sync),
) {
    let scenario = &plan.runs[group.runs[0]].scenario;
    // Start every worker; one that cannot start fails alone.
    let mut started = Vec::new();
    let mut subscribers = Vec::new();
    for (k, &i) in group.runs.iter().enumerate() {
        match supervise::spawn(&dirs[i], true, plan.runs[i].base_dir.as_deref()) {
            Ok((child, Some(stdin))) => {
                started.push((i, child));
                subscribers.push(feed::Subscriber {
                    sensors: group.sensors[k],
                    input: stdin,
                });
            }
            Ok((mut child, None)) => {
                let _ = child.kill();
                let _ = child.wait();
                done(
                    i,
                    finish_run(&plan.runs[i], &dirs[i], plan, Err("no stdin".into())),
                );
            }
            Err(why) => done(i, finish_run(&plan.runs[i], &dirs[i], plan, Err(why))),
        }
    }
    let simulation = sim::Simulation::with_world(config, world.clone(), scenario, plan.seed);
    let end_ns = plan.max_time_s.map(job::max_time_ns);
    let stall = STALL.min(plan.timeout / 4);
    // The shared simulation's cost, which each run's timing.json notes (its group shares it).
    let cost = Arc::new(OnceLock::<timing::SimulationCost>::new());
    let done_now = |i: usize, outcome: Result<(), String>| {
        if outcome.is_ok()
            && let Some(cost) = cost.get()
        {
            note_simulation_cost(&dirs[i], cost);
        }
        done(i, finish_run(&plan.runs[i], &dirs[i], plan, outcome));
    };
    let feed_cost = Arc::clone(&cost);
    std::thread::scope(|scope| {
        let feeding = scope.spawn(move || match simulation {
            Ok(sim) => feed::Feed {
                end_ns,
                stall,
                wire_details: crate::dataset::WireDetails::new(config),
                cost: feed_cost,
            }
            .run(&sim, subscribers),
            Err(e) => Err(format!("{e}")),
        });
        let done_now = &done_now;
        let watched: Vec<_> = started
            .into_iter()
            .map(|(i, child)| {
                scope.spawn(move || {
                    let on_progress = |f: f64| ticks.tick(i, f);
                    let outcome = supervise::watch(
                        child,
                        &dirs[i],
                        plan.timeout,
                        plan.memory_limit_mb,
                        &on_progress,
                    );
                    // A run that ended well is reported as it ends, whatever its groupmates
                    // do; a failure waits for the simulation's account of it (a worker cut
                    // off as stalled), below.
                    match outcome {
                        Ok(()) => {
                            done_now(i, Ok(()));
                            None
                        }
                        Err(why) => Some((i, why)),
                    }
                })
            })
            .collect();
        let failed: Vec<(usize, usize, String)> = watched
            .into_iter()
            .enumerate()
            .filter_map(|(k, w)| {
                w.join()
                    .expect("a watcher does not panic")
                    .map(|(i, why)| (k, i, why))
            })
            .collect();
        let deliveries = feeding
            .join()
            .map_err(|_| "the simulation panicked".to_owned());
        for (k, i, why) in failed {
            let why = match &deliveries {
                _ if interrupt::is_interruption(&why) => why,
                Ok(Ok(d)) => match d.get(k) {
                    Some(feed::Delivery::Stalled { .. }) => format!(
                        "{why} (it took no data for {} s and was cut off from the shared simulation)",
                        stall.as_secs()
                    ),
                    _ => why,
                },
                Ok(Err(sim_failed)) | Err(sim_failed) => {
                    format!("{why} (the shared simulation failed: {sim_failed})")
                }
            };
            done_now(i, Err(why));
        }
    });
}

/// Runs run `i` of the plan in its own worker, in its folder `dir`.
fn run_one(plan: &Plan, i: usize, dir: &Path, ticks: &Ticks) -> RunOutcome {
    let run = &plan.runs[i];
    let on_progress = |f: f64| ticks.tick(i, f);
    let outcome = supervise::supervise(
        dir,
        run.base_dir.as_deref(),
        plan.timeout,
        plan.memory_limit_mb,
        &on_progress,
    );
    finish_run(run, dir, plan, outcome)
}

/// The outcome of a run that was not started because of Ctrl-C.
fn not_run(run: &PlannedRun, dir: &Path, plan: &Plan) -> RunOutcome {
    let folder = RunFolder::new(dir);
    let _ = std::fs::remove_file(folder.path(files::JOB));
    RunOutcome {
        scenario: run.scenario.clone(),
        label: run.label.clone(),
        status: RunStatus::Failed(interrupt::REASON.to_owned()),
        max_time_s: plan.max_time_s,
        folder,
    }
}

/// A run's outcome once its worker has ended: scored if it succeeded; its status written
/// unless it was interrupted (an interrupted run counts as not run).
/// Adds a shared simulation's per-sensor cost to a finished run's `timing.json` (the worker
/// wrote it without: it only read the stream). A run without one is left as it is.
fn note_simulation_cost(dir: &Path, cost: &timing::SimulationCost) {
    let folder = RunFolder::new(dir);
    if let Ok(Some(mut t)) = folder.read_timing() {
        t.simulation_cost = cost.per_simulated_s(t.simulated_s);
        let _ = folder.write_timing(&t);
    }
}

fn finish_run(
    run: &PlannedRun,
    dir: &Path,
    plan: &Plan,
    outcome: Result<(), String>,
) -> RunOutcome {
    let folder = RunFolder::new(dir);
    // The order held a temporary path; run.toml keeps what determined the run.
    let _ = std::fs::remove_file(folder.path(files::JOB));
    let status = match outcome
        .and_then(|()| evaluate(&folder, plan.alignment).map_err(|e| format!("evaluation: {e:#}")))
    {
        Ok(()) => RunStatus::Ok,
        Err(why) => RunStatus::Failed(why),
    };
    let interrupted = matches!(&status, RunStatus::Failed(why) if interrupt::is_interruption(why));
    if !interrupted {
        let _ = std::fs::write(folder.path(files::STATUS), status.text());
    }
    RunOutcome {
        scenario: run.scenario.clone(),
        label: run.label.clone(),
        status,
        max_time_s: plan.max_time_s,
        folder,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With `record_once`, a run whose own world differs from the plan's in more than its
    /// GNSS receiver cannot replay the plan's recordings: refused by name before anything
    /// runs or is recorded.
    #[test]
    fn a_run_whose_world_differs_in_more_than_its_receiver_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let plan_world = dir.path().join("plan.toml");
        std::fs::write(&plan_world, sim::DEFAULT_CONFIG_TOML).expect("world");
        let staged = dir.path().join("staged.toml");
        std::fs::write(
            &staged,
            sim::DEFAULT_CONFIG_TOML.replacen("growth_stage = 3.0", "growth_stage = 1.0", 1),
        )
        .expect("world");
        let plan = Plan {
            world: Some(plan_world),
            seed: 0,
            scenarios: vec!["s0".into()],
            runs: vec![PlannedRun {
                scenario: "s0".into(),
                label: "x".into(),
                plugin: dir.path().join("x.so"),
                params_toml: String::new(),
                pace: Pace::Free,
                queue_size: None,
                drops: None,
                base_dir: None,
                localize: None,
                world: Some(staged.clone()),
            }],
            jobs: 1,
            timeout: Duration::from_secs(60),
            memory_limit_mb: 1024,
            alignment: eval::Alignment::Se3,
            dataset: None,
            max_time_s: Some(1.0),
            share_simulation: false,
            record_once: Some(dir.path().join("recordings")),
            bars: false,
        };
        let err = execute(&plan, &dir.path().join("work"), &|_, _| {})
            .expect_err("a world that records otherwise");
        let err = format!("{err:#}");
        assert!(
            err.contains("s0/x") && err.contains("staged.toml") && err.contains("GNSS receiver"),
            "{err}"
        );
        let recordings = std::fs::read_dir(dir.path().join("recordings"))
            .map(|d| d.count())
            .unwrap_or(0);
        assert_eq!(recordings, 0, "nothing recorded");
    }
}
