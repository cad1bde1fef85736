//! `vinebench bench FILE.toml`: a matrix of scenarios × plugins, the paper's table.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use clap::Args;

use crate::bench_config::BenchConfig;
use crate::cmd::progress::Progress;
use crate::report::load::IndexedRun;
use crate::report::reference;
use crate::results::{RunOutcome, RunStatus, Staging, files};
use crate::runner::{Plan, PlannedRun};

#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The matrix, e.g. configs/paper.toml.
    pub file: PathBuf,
    /// Results folder (default: results/<file stem>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Runs at once (default: the file's `jobs`, else the number of cores); the runs that
    /// share one simulation start together, however many.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Cut every route at this many simulated seconds (overrides the file's `max_time_s`;
    /// default: whole routes). The table then says the routes were cut.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub max_time: Option<f64>,
    /// Exit 0 even when some runs failed (the table says which and why); by default the
    /// exit code is 3 then.
    #[arg(long)]
    pub allow_failures: bool,
    /// Record each scenario once and replay it to every run (the file's `record_once`):
    /// the simulation paid once, recorded ahead at the lowest CPU priority.
    #[arg(long)]
    pub record_once: bool,
    /// The sensors' models, whatever the world file's `profile` says: ideal, paper, typical
    /// or field (configs/profiles/); `vinebench bench configs/paper.toml --profile field`
    /// is the paper bench under the field's troubles.
    #[arg(long, value_parser = crate::cmd::sim_args::parse_profile)]
    pub profile: Option<sim::config::Profile>,
}

/// Runs at once when nobody says: one per core.
pub fn default_jobs() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let max_time_s = crate::cmd::sim_args::max_time_flag(args.max_time)?;
    let cfg = BenchConfig::from_file(&args.file)?;
    anyhow::ensure!(
        !cfg.is_sweep(),
        "{}: has seeds or [axes], which make it a sweep: run it with `vinebench sweep`",
        args.file.display()
    );
    let resolved = cfg.resolve_plugins(&args.file)?;
    let mut labels: Vec<String> = resolved.iter().map(|p| p.label.clone()).collect();
    let mut runs = Vec::new();
    for scenario in &cfg.scenarios {
        for p in &resolved {
            runs.push(PlannedRun {
                scenario: scenario.clone(),
                label: p.label.clone(),
                plugin: p.library.clone(),
                params_toml: p.params_toml.clone(),
                pace: p.pace,
                queue_size: p.queue_size.clone(),
                drops: None,
                base_dir: Some(p.base_dir.clone()),
                localize: None,
                world: None,
            });
        }
    }
    // The localisation runs, after the mapping runs (`bench_in` runs them second).
    let mut scenarios = cfg.scenarios.clone();
    for (i, l) in cfg.localize.iter().enumerate() {
        let (plugin, params_toml, base_dir) = cfg.localize_plugin(i, &resolved, &args.file)?;
        let label = cfg.localize_label(i);
        runs.push(PlannedRun {
            scenario: l.scenario.clone(),
            label: label.clone(),
            plugin,
            params_toml,
            pace: crate::runner::Pace::Free,
            queue_size: None,
            drops: None,
            base_dir: Some(base_dir),
            localize: Some(l.spec()),
            world: l.world.clone(),
        });
        if !labels.contains(&label) {
            labels.push(label);
        }
        if !scenarios.contains(&l.scenario) {
            scenarios.push(l.scenario.clone());
        }
    }
    let stem = args
        .file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bench".into());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join(stem));
    let world = crate::cmd::sim_args::WorkersWorld::new(cfg.world.as_deref(), args.profile, &out)?;
    let plan = Plan {
        world: world.path().map(PathBuf::from),
        seed: cfg.bench_seed(),
        scenarios,
        runs,
        jobs: args.jobs.or(cfg.jobs).unwrap_or_else(default_jobs),
        timeout: Duration::from_secs_f64(cfg.timeout_s),
        memory_limit_mb: cfg.memory_limit_mb,
        alignment: cfg.align.into(),
        dataset: None,
        max_time_s: max_time_s.or(cfg.max_time_s),
        share_simulation: cfg.share_simulation,
        // Beside the results folder, not in it: the results are moved into place whole.
        record_once: (cfg.record_once || args.record_once)
            .then(|| PathBuf::from(format!("{}.recordings", out.display()))),
        bars: true,
    };
    let prior = match &cfg.timing_prior {
        Some(path) => read_timing_prior(path)?,
        None => Costs::new(),
    };
    let outcomes = bench(&plan, &out, &labels, cfg.paper_table.as_deref(), &prior)?;
    failures_exit(&outcomes, args.allow_failures)
}

/// Exit code 3 ([`crate::cmd::Exit`]) when any run failed, unless `allow`.
pub fn failures_exit(outcomes: &[RunOutcome], allow: bool) -> anyhow::Result<()> {
    let failed = outcomes
        .iter()
        .filter(|o| matches!(o.status, RunStatus::Failed(_)))
        .count();
    if failed > 0 && !allow {
        return Err(crate::cmd::Exit::failures(format!(
            "{failed} of {} runs failed (the table says why; --allow-failures to exit 0)",
            outcomes.len()
        ))
        .into());
    }
    Ok(())
}

/// What determines a plan's runs, hashed: an interrupted bench resumes only the same plan.
fn fingerprint(plan: &Plan) -> anyhow::Result<String> {
    use sha2::Digest as _;
    let mut h = sha2::Sha256::new();
    let world = match &plan.world {
        Some(p) => std::fs::read(p).with_context(|| p.display().to_string())?,
        None => b"built-in".to_vec(),
    };
    h.update(&world);
    h.update(format!(
        "{}|{:?}|{:?}|{}|{:?}",
        plan.seed,
        plan.scenarios,
        plan.max_time_s,
        plan.alignment.name(),
        plan.dataset
    ));
    for r in &plan.runs {
        h.update(format!(
            "|{}|{}|{}|{}|{:?}|{:?}|{:?}",
            r.scenario,
            r.label,
            r.plugin.display(),
            r.params_toml,
            r.pace,
            r.localize,
            r.world
        ));
    }
    h.update(env!("CARGO_PKG_VERSION"));
    Ok(format!("{:x}", h.finalize()))
}

/// Runs a plan into the results folder `out` (written whole, then moved into place), writes
/// its reports (with `paper_table`, the published table it reproduces, copied in and shown
/// beside its figures), and prints its table and where the results are. A failed run does
/// not fail the bench: it is in the table with its reason. `prior`: each system's speed for
/// the progress estimate where `out` holds no previous results (a bench file's
/// `timing_prior`; empty: measured as the runs go).
pub fn bench(
    plan: &Plan,
    out: &Path,
    labels: &[String],
    paper_table: Option<&Path>,
    prior: &Costs,
) -> anyhow::Result<Vec<RunOutcome>> {
    crate::runner::interrupt::install();
    if let Some(path) = paper_table {
        // Checked before anything runs.
        reference::Reference::load(path)?;
    }
    let (staging, resumed) = Staging::begin_resumable(out, &fingerprint(plan)?)?;
    let finished = |plan: &Plan, dir: &Path| {
        plan.runs.iter().any(|r| {
            dir.join(&r.scenario)
                .join(&r.label)
                .join(files::STATUS)
                .is_file()
        })
    };
    match bench_in(plan, out, labels, paper_table, prior, staging, resumed) {
        Ok(outcomes) => Ok(outcomes),
        Err((e, Some(staging))) => {
            // A failure of the bench itself: what finished stays for a resume, a folder with
            // nothing finished in it is removed (no half-written results).
            if !finished(plan, staging.dir()) {
                let _ = staging.discard();
            }
            Err(e)
        }
        Err((e, None)) => Err(e),
    }
}

/// [`bench`] in its staging folder; on failure the error and the folder, if still held.
fn bench_in(
    plan: &Plan,
    out: &Path,
    labels: &[String],
    paper_table: Option<&Path>,
    prior: &Costs,
    staging: Staging,
    resumed: bool,
) -> Result<Vec<RunOutcome>, (anyhow::Error, Option<Staging>)> {
    macro_rules! tri {
        ($e:expr) => {
            match $e {
                Ok(v) => v,
                Err(e) => return Err((anyhow::Error::from(e), Some(staging))),
            }
        };
    }
    if let Some(path) = paper_table {
        // Copied so that the folder reports alone.
        let copy = staging.dir().join(reference::FILE);
        tri!(std::fs::copy(path, &copy).with_context(|| copy.display().to_string()));
    }
    // Runs a resumed folder already holds (their status written as they ended) are kept;
    // the others (never started, or interrupted) run now.
    let mut kept: Vec<Option<RunOutcome>> = vec![None; plan.runs.len()];
    for (i, run) in plan.runs.iter().enumerate() {
        let dir = staging.dir().join(&run.scenario).join(&run.label);
        let folder = crate::results::RunFolder::new(&dir);
        match std::fs::read_to_string(folder.path(files::STATUS)) {
            Ok(text) if resumed => {
                kept[i] = Some(RunOutcome {
                    scenario: run.scenario.clone(),
                    label: run.label.clone(),
                    status: RunStatus::from_text(text.trim()),
                    max_time_s: plan.max_time_s,
                    folder,
                });
            }
            _ if dir.exists() => {
                tri!(std::fs::remove_dir_all(&dir).with_context(|| dir.display().to_string()));
            }
            _ => {}
        }
    }
    let todo: Vec<usize> = (0..plan.runs.len())
        .filter(|&i| kept[i].is_none())
        .collect();
    if resumed {
        crate::out!(
            "resuming {}: {} of {} runs already finished",
            crate::results::partial_path(out).display(),
            plan.runs.len() - todo.len(),
            plan.runs.len()
        );
    }
    // Mapping runs first, then the localisation runs that start from their maps (each alone:
    // a kidnapping changes its stream, and its world may be its own).
    let mut ran = Vec::with_capacity(todo.len());
    for localizing in [false, true] {
        let phase: Vec<usize> = todo
            .iter()
            .copied()
            .filter(|&i| plan.runs[i].localize.is_some() == localizing)
            .collect();
        if phase.is_empty() || crate::runner::interrupt::interrupted() {
            continue;
        }
        let sub = Plan {
            runs: phase.iter().map(|&i| plan.runs[i].clone()).collect(),
            share_simulation: plan.share_simulation && !localizing,
            record_once: plan.record_once.clone().filter(|_| !localizing),
            ..plan.clone()
        };
        ran.extend(
            tri!(run_phase(&sub, out, staging.dir(), prior))
                .into_iter()
                .zip(phase),
        );
    }
    for (outcome, i) in ran {
        kept[i] = Some(outcome);
    }
    // A phase not started because of Ctrl-C: its runs are interrupted ones.
    let outcomes: Vec<RunOutcome> = kept
        .into_iter()
        .zip(&plan.runs)
        .map(|(o, run)| {
            o.unwrap_or_else(|| RunOutcome {
                scenario: run.scenario.clone(),
                label: run.label.clone(),
                status: RunStatus::Failed(crate::runner::interrupt::REASON.to_owned()),
                max_time_s: plan.max_time_s,
                folder: crate::results::RunFolder::new(
                    staging.dir().join(&run.scenario).join(&run.label),
                ),
            })
        })
        .collect();
    if crate::runner::interrupt::interrupted() {
        return Err((interrupted(staging, out, &outcomes), None));
    }
    let index: Vec<IndexedRun> = outcomes
        .iter()
        .map(|o| IndexedRun {
            scenario: o.scenario.clone(),
            plugin: o.label.clone(),
            status: o.status.clone(),
            max_time_s: o.max_time_s,
        })
        .collect();
    let name = crate::results::folder_name(out);
    let table = tri!(crate::report::write_bench(
        staging.dir(),
        &name,
        &plan.scenarios,
        labels,
        &index
    ));
    let dir = staging.commit().map_err(|e| (e, None))?;
    crate::out!("{table}");
    crate::out!("results: {}", dir.display());
    crate::out!(
        "report: {}",
        dir.join(crate::report::html::REPORT).display()
    );
    Ok(outcomes)
}

/// Runs `sub`'s runs in `dir` with a progress display; their outcomes in order.
fn run_phase(sub: &Plan, out: &Path, dir: &Path, prior: &Costs) -> anyhow::Result<Vec<RunOutcome>> {
    // Each run's predicted duration: its route's length times its system's cost in the
    // previous results at `out`, if any, else in `prior` (Progress says how the estimate
    // uses them); neither: each system's speed is measured as it runs.
    let route_s = crate::runner::route_seconds(sub).ok();
    let mut costs = previous_costs(out);
    if costs.is_empty() {
        costs = prior.clone();
    }
    let predicted = route_s.as_ref().map(|route_s| {
        let fallback = if costs.is_empty() {
            1.0
        } else {
            costs.values().sum::<f64>() / costs.len() as f64
        };
        sub.runs
            .iter()
            .zip(route_s)
            .map(|(run, s)| s * costs.get(&run.label).copied().unwrap_or(fallback))
            .collect()
    });
    let mut progress = Progress::new(sub.runs.len(), predicted, sub.jobs, false);
    if let Some(route_s) = route_s.filter(|_| costs.is_empty()) {
        progress = progress.by_system(
            route_s
                .into_iter()
                .zip(&sub.runs)
                .map(|(s, run)| (s, run.label.clone()))
                .collect(),
        );
    }
    crate::runner::execute_observed(
        sub,
        dir,
        &|schedule| progress.set_schedule(schedule),
        &|i, f| progress.observe(i, f),
        &|i, outcome| {
            progress.finished(
                i,
                &format!("{}/{}", outcome.scenario, outcome.label),
                outcome,
            );
        },
    )
}

/// Each system's wall seconds per simulated second, by label.
pub type Costs = std::collections::BTreeMap<String, f64>;

/// What a bench file's `timing_prior` holds: each system's wall seconds per simulated second
/// in a bench run elsewhere (`scripts/timing-prior.py` writes it from a results folder).
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TimingPrior {
    wall_s_per_simulated_s: Costs,
}

/// Reads a `timing_prior` file; a missing or malformed file, or a speed that is not a
/// positive number, is an error naming it.
pub fn read_timing_prior(path: &Path) -> anyhow::Result<Costs> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let prior: TimingPrior = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message()))?;
    for (label, cost) in &prior.wall_s_per_simulated_s {
        anyhow::ensure!(
            cost.is_finite() && *cost > 0.0,
            "{}: {label} = {cost}: a speed must be a positive number of wall seconds per \
             simulated second",
            path.display()
        );
    }
    Ok(prior.wall_s_per_simulated_s)
}

/// Each system's wall seconds per simulated second in the results already at `out` (a
/// previous bench of the same name: `out/<scenario>/<label>/timing.json`), all of
/// its runs there (their wall time over their simulated time); empty where there are none.
fn previous_costs(out: &Path) -> Costs {
    let mut sums: std::collections::BTreeMap<String, (f64, f64)> = Default::default();
    let Ok(scenarios) = std::fs::read_dir(out) else {
        return Default::default();
    };
    for scenario in scenarios.flatten() {
        let Ok(runs) = std::fs::read_dir(scenario.path()) else {
            continue;
        };
        for run in runs.flatten() {
            let folder = crate::results::RunFolder::new(run.path());
            if let Ok(Some(t)) = folder.read_timing()
                && t.simulated_s > 0.0
                && t.wall_s.is_finite()
            {
                let entry = sums
                    .entry(run.file_name().to_string_lossy().into_owned())
                    .or_default();
                entry.0 += t.wall_s;
                entry.1 += t.simulated_s;
            }
        }
    }
    sums.into_iter()
        .map(|(label, (wall, simulated))| (label, wall / simulated))
        .collect()
}

/// After Ctrl-C: keeps the partial folder if any run finished (the same command resumes
/// it), else removes it; the error says which.
fn interrupted(staging: Staging, out: &Path, outcomes: &[RunOutcome]) -> anyhow::Error {
    let finished = outcomes
        .iter()
        .filter(|o| !matches!(&o.status, RunStatus::Failed(why) if crate::runner::interrupt::is_interruption(why)))
        .count();
    let partial = staging.dir().to_owned();
    let message = if finished == 0 {
        match staging.discard() {
            Ok(()) => format!(
                "interrupted before any run finished: removed {}",
                partial.display()
            ),
            Err(e) => format!("interrupted; could not remove {}: {e:#}", partial.display()),
        }
    } else {
        format!(
            "interrupted: {finished} of {} runs finished and are kept in {}; run the same command again to resume (the other runs), or remove that folder; {} is unchanged",
            outcomes.len(),
            partial.display(),
            out.display()
        )
    };
    crate::cmd::Exit::interrupted(message).into()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `timing_prior` file is read by label; a malformed one, an unknown key or a speed
    /// that is not positive is an error naming the file.
    #[test]
    fn a_timing_prior_is_read_or_refused_by_name() {
        let dir = tempfile::tempdir().expect("tempdir");
        let write = |text: &str| {
            let path = dir.path().join("prior.toml");
            std::fs::write(&path, text).expect("write");
            path
        };
        let prior = read_timing_prior(&write(
            "# made elsewhere\n[wall_s_per_simulated_s]\n\"lio-sam\" = 0.09\nrtabmap = 1.5\n",
        ))
        .expect("a good prior");
        assert_eq!(prior.len(), 2);
        assert_eq!(prior["lio-sam"], 0.09);
        assert_eq!(prior["rtabmap"], 1.5);
        for (text, says) in [
            ("[wall_s_per_simulated_s]\nx = 0.0\n", "x = 0"),
            ("[wall_s_per_simulated_s]\nx = -1.0\n", "x = -1"),
            ("[wall_s_per_simulated_s]\nx = \"fast\"\n", "invalid type"),
            ("[speeds]\nx = 1.0\n", "unknown field"),
        ] {
            let err = format!("{:#}", read_timing_prior(&write(text)).expect_err(text));
            assert!(
                err.contains("prior.toml") && err.contains(says),
                "{text}: {err}"
            );
        }
        let missing = dir.path().join("none.toml");
        let err = format!("{:#}", read_timing_prior(&missing).expect_err("missing"));
        assert!(err.contains("none.toml"), "{err}");
    }
}
