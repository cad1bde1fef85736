//! A benchmark matrix from TOML (`configs/paper.toml`): scenarios × plugins, each plugin with
//! its parameter table handed to it verbatim.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};
use serde::{Deserialize, Serialize};

/// Alignment of each estimate to ground truth before APE.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Align {
    None,
    Origin,
    #[default]
    Se3,
    Sim3,
    #[serde(rename = "4dof")]
    FourDof,
}

impl Align {
    /// The alignment a command line or `metrics.json` names (`none`, `origin`, `se3`,
    /// `sim3`, `4dof`: the bench file's spelling).
    pub fn from_name(name: &str) -> Result<Self, String> {
        toml::Value::String(name.to_owned())
            .try_into()
            .map_err(|_| format!("{name}: expected none, origin, se3, sim3 or 4dof"))
    }
}

impl From<Align> for eval::Alignment {
    fn from(a: Align) -> Self {
        match a {
            Align::None => eval::Alignment::None,
            Align::Origin => eval::Alignment::Origin,
            Align::Se3 => eval::Alignment::Se3,
            Align::Sim3 => eval::Alignment::Sim3,
            Align::FourDof => eval::Alignment::FourDof,
        }
    }
}

/// One system of the matrix: a plugin by `name` (searched for) or `path`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PluginEntry {
    pub name: Option<String>,
    pub path: Option<PathBuf>,
    /// Column label in the report (default: the name or the file stem).
    pub label: Option<String>,
    /// How fast the runner feeds it: `"free"` (default, as fast as it takes the messages)
    /// or `"realtime"` (no faster than simulated time, for systems with threads of their own).
    #[serde(default)]
    pub pace: crate::runner::Pace,
    /// Bounded subscriber queues on a paced run, as ROS gives each subscription one:
    /// `queue_size = 5` (every topic) or `queue_size = { lidar = 2, rgbd = 1 }` (those
    /// named); a full queue drops its oldest message (`runner::QueueSize`). Default:
    /// unbounded (nothing is dropped, a slow system falls behind).
    pub queue_size: Option<crate::runner::QueueSize>,
    /// The plugin's parameters, handed to it verbatim as TOML.
    #[serde(default)]
    pub params: toml::Table,
}

impl PluginEntry {
    pub fn label(&self) -> String {
        self.label
            .clone()
            .or_else(|| self.name.clone())
            .or_else(|| {
                self.path
                    .as_ref()
                    .and_then(|p| p.file_stem())
                    .map(|s| s.to_string_lossy().into_owned())
            })
            .unwrap_or_else(|| "plugin".into())
    }
}

/// A `[[plugins]]` entry with its library found.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedPlugin {
    pub label: String,
    pub library: PathBuf,
    pub params_toml: String,
    pub pace: crate::runner::Pace,
    pub queue_size: Option<crate::runner::QueueSize>,
    /// The bench file's folder, absolute: what the plugin's relative paths are relative to.
    pub base_dir: PathBuf,
}

fn default_scenarios() -> Vec<String> {
    ["s0", "s1", "s2", "s3"].map(str::to_owned).to_vec()
}

fn default_share() -> bool {
    true
}

fn default_timeout() -> f64 {
    3600.0
}

fn default_memory() -> u64 {
    8192
}

/// The matrix file. Every key but `plugins` is optional.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchConfig {
    #[serde(default = "default_scenarios")]
    pub scenarios: Vec<String>,
    /// Seed of the sensor noise (default 0).
    pub seed: Option<u64>,
    /// Sweeps only (`vinebench sweep`): every cell runs once per seed (instead of `seed`).
    pub seeds: Option<Vec<u64>>,
    /// Sweeps only: world keys by dotted path (`"vineyard.growth_stage" = [0, 2, 4]`), each
    /// with the values it takes; the sweep crosses them all.
    #[serde(default)]
    pub axes: toml::Table,
    /// Sweeps only: named sets of world keys (`[variants.imu-tilt]` with
    /// `"sensors.imu.mount_error.sigma_deg" = 1.0`; an empty `[variants.baseline]` is the
    /// world as it is), each one value of a `variant` axis crossed with the others: one
    /// factor at a time, where `[axes]` crosses every key with every other.
    #[serde(default)]
    pub variants: toml::Table,
    /// Simulator configuration (relative to this file); default: the embedded one.
    pub world: Option<PathBuf>,
    /// Extra directories to search for plugins (relative to this file).
    #[serde(default)]
    pub plugin_dirs: Vec<PathBuf>,
    /// Runs at once (default: the number of cores); the runs that share one simulation
    /// start together, however many.
    pub jobs: Option<usize>,
    /// Wall-clock limit of one run.
    #[serde(default = "default_timeout")]
    pub timeout_s: f64,
    /// Address-space limit of one run.
    #[serde(default = "default_memory")]
    pub memory_limit_mb: u64,
    #[serde(default)]
    pub align: Align,
    /// Cut every route at this simulated time, seconds (default: whole routes, as the
    /// paper ran them); `--max-time` overrides it.
    pub max_time_s: Option<f64>,
    /// Simulate each scenario once for the runs that need the same sensors (the camera's
    /// runs together, the lidar's together) and stream it to their workers, instead of
    /// once per run (default). The data are the same either way.
    #[serde(default = "default_share")]
    pub share_simulation: bool,
    /// Record each scenario once (an MCAP of every sensor its runs take) and replay it to
    /// each run, instead of simulating live (`runner::record`): the simulation's cost paid
    /// once whatever the number of systems, recorded ahead at the lowest CPU priority so that
    /// a paced system has the cores while it runs. Recordings are removed after their runs
    /// (kept on Ctrl-C, for a resumed sweep). `--record-once` sets it.
    #[serde(default)]
    pub record_once: bool,
    /// The published table this bench reproduces (relative to this file; CSV with
    /// `scenario,system,max,mean,median,rmse,std`): its figures are shown beside ours in
    /// the printed table, `table.md` and the report, for the plugins whose label matches.
    pub paper_table: Option<PathBuf>,
    /// Each system's speed in a bench run elsewhere (relative to this file; TOML,
    /// `[wall_s_per_simulated_s]` by label, `scripts/timing-prior.py`): the progress
    /// estimate's prediction where the results folder holds no previous results, rescaled
    /// to this machine by the runs as they end.
    pub timing_prior: Option<PathBuf>,
    pub plugins: Vec<PluginEntry>,
    /// Localisation runs after the mapping runs (`vinebench localize`'s bench form): each
    /// starts a plugin from a map one of this bench's runs built.
    #[serde(default)]
    pub localize: Vec<LocalizeEntry>,
}

/// A `[[localize]]` entry: a plugin started from a map this bench built (its run
/// `map = "scenario/label"`), on `scenario`, in `world` (default: the bench's), e.g. another
/// growth stage of the block.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalizeEntry {
    /// The mapping run, `"scenario/label"` of this bench; absent with `surveyed`.
    pub map: Option<String>,
    pub scenario: String,
    /// Column label (default: the plugin's label, `-in-` and the map's scenario).
    pub label: Option<String>,
    /// The world of the localisation run (relative to this file); default: the bench's.
    pub world: Option<PathBuf>,
    /// Another plugin to localise (name or path); default: the mapping run's, with its
    /// parameters.
    pub plugin: Option<String>,
    /// The plugin's parameters when `plugin` is given.
    #[serde(default)]
    pub params: toml::Table,
    /// The mapping run's occupancy grid instead of its `map.bin` (for `amcl`).
    #[serde(default)]
    pub grid: bool,
    /// The world's surveyed grid instead of a mapping run's map; of `survey_world` where
    /// given (relative to this file).
    #[serde(default)]
    pub surveyed: bool,
    pub survey_world: Option<PathBuf>,
    /// `[x, y, yaw, sigma_xy, sigma_yaw]` in the map's frame; absent: global localisation.
    pub initial_guess: Option<[f64; 5]>,
    /// `[at, skip]` seconds: carried `skip` seconds ahead along the route at `at`.
    pub kidnap: Option<[f64; 2]>,
    /// Sweeps only: the axes (dotted paths, or `variant`) whose every value the localisation
    /// runs take, each map crossed with them; on the other axes, and the seed, a
    /// localisation run is its mapping run's. Empty: each map is localised in in its own
    /// world. E.g. `cross = ["vineyard.growth_stage"]`: a map at every stage, localised at
    /// every stage.
    #[serde(default)]
    pub cross: Vec<String>,
}

impl LocalizeEntry {
    /// The mapping run's scenario and label.
    pub fn map_run(&self) -> Option<(&str, &str)> {
        self.map.as_deref().and_then(|m| m.split_once('/'))
    }

    /// The order for the worker, the mapping run's folder given relative to the
    /// localisation run's (both in one results folder: `../../scenario/label`).
    pub fn spec(&self) -> crate::runner::LocalizeSpec {
        use crate::runner::{GuessSpec, Kidnap, LocalizeSpec, MapSource};
        let mapping_run = self
            .map_run()
            .filter(|_| !self.surveyed)
            .map(|(s, l)| Path::new("..").join("..").join(s).join(l));
        let map = MapSource::of(mapping_run.as_deref(), self.grid, self.survey_world.clone());
        LocalizeSpec {
            map,
            mapping_run,
            initial_guess: self
                .initial_guess
                .map(|[x, y, yaw, sigma_xy_m, sigma_yaw_rad]| GuessSpec {
                    x,
                    y,
                    yaw,
                    sigma_xy_m,
                    sigma_yaw_rad,
                }),
            kidnap: self.kidnap.map(|[at_s, skip_s]| Kidnap { at_s, skip_s }),
        }
    }
}

impl BenchConfig {
    pub fn from_file(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
        Self::from_toml(&text, path)
    }

    /// Parses the text of a bench file at `path`: relative paths in it are resolved against
    /// its folder, and errors name it; nothing is read from disk.
    pub fn from_toml(text: &str, path: &Path) -> anyhow::Result<Self> {
        let mut cfg: BenchConfig = toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start].matches('\n').count() + 1);
            let at = line.map(|l| format!(" (line {l})")).unwrap_or_default();
            anyhow::anyhow!("{}: {}{at}", path.display(), e.message())
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        cfg.world = cfg.world.map(|w| base.join(w));
        cfg.paper_table = cfg.paper_table.map(|p| base.join(p));
        cfg.timing_prior = cfg.timing_prior.map(|p| base.join(p));
        cfg.plugin_dirs = cfg.plugin_dirs.iter().map(|d| base.join(d)).collect();
        for p in &mut cfg.plugins {
            p.path = p.path.as_ref().map(|q| base.join(q));
        }
        for l in &mut cfg.localize {
            l.world = l
                .world
                .as_ref()
                .map(|w| std::path::absolute(base.join(w)))
                .transpose()?;
            l.survey_world = l
                .survey_world
                .as_ref()
                .map(|w| std::path::absolute(base.join(w)))
                .transpose()?;
        }
        cfg.validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(cfg)
    }

    /// Every `[[plugins]]` entry found on the search path: (label, library, parameters as
    /// TOML), in file order. `file` names the culprit in the error.
    pub fn resolve_plugins(&self, file: &Path) -> anyhow::Result<Vec<ResolvedPlugin>> {
        let dirs = crate::plugins::search_path(&self.plugin_dirs);
        let base_dir = match file.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => std::path::absolute(dir),
            _ => std::env::current_dir(),
        }
        .with_context(|| file.display().to_string())?;
        self.plugins
            .iter()
            .map(|entry| {
                let what = entry
                    .name
                    .clone()
                    .or_else(|| entry.path.as_ref().map(|p| p.display().to_string()))
                    .unwrap_or_default();
                let library = crate::plugins::resolve(&what, &dirs)
                    .with_context(|| file.display().to_string())?;
                if let Some(q) = &entry.queue_size {
                    q.check(entry.pace).map_err(|why| {
                        anyhow::anyhow!("{}: plugin {}: {why}", file.display(), entry.label())
                    })?;
                }
                Ok(ResolvedPlugin {
                    label: entry.label(),
                    library,
                    params_toml: toml::to_string(&entry.params)?,
                    pace: entry.pace,
                    queue_size: entry.queue_size.clone(),
                    base_dir: base_dir.clone(),
                })
            })
            .collect()
    }

    /// The seed of a bench (not a sweep).
    pub fn bench_seed(&self) -> u64 {
        self.seed.unwrap_or(0)
    }

    /// Whether the file has a sweep's keys (`seeds`, `[axes]`, `[variants]`).
    pub fn is_sweep(&self) -> bool {
        self.seeds.is_some() || !self.axes.is_empty() || !self.variants.is_empty()
    }

    fn validate(&self) -> anyhow::Result<()> {
        if self.seed.is_some() && self.seeds.is_some() {
            bail!("seed and seeds: give one of them");
        }
        if self.seeds.as_ref().is_some_and(Vec::is_empty) {
            bail!("seeds: empty list");
        }
        if self.scenarios.is_empty() {
            bail!("scenarios: empty list");
        }
        if self.plugins.is_empty() {
            bail!("plugins: no [[plugins]] entry");
        }
        if !(self.timeout_s.is_finite() && self.timeout_s > 0.0) {
            bail!(
                "timeout_s = {}: must be a positive number of seconds",
                self.timeout_s
            );
        }
        if let Some(s) = self.max_time_s {
            crate::runner::check_max_time(s)
                .map_err(|why| anyhow::anyhow!("max_time_s = {s}: {why}"))?;
        }
        if self.memory_limit_mb < 64 {
            bail!(
                "memory_limit_mb = {}: must be at least 64",
                self.memory_limit_mb
            );
        }
        let mut labels = std::collections::BTreeSet::new();
        for (i, p) in self.plugins.iter().enumerate() {
            if p.name.is_some() == p.path.is_some() {
                bail!("plugins[{i}]: give exactly one of name or path");
            }
            if !labels.insert(p.label()) {
                bail!(
                    "plugins[{i}]: label '{}' used twice; give each entry its own label",
                    p.label()
                );
            }
        }
        for (i, l) in self.localize.iter().enumerate() {
            let at = format!("localize[{i}]");
            match (l.map_run(), l.surveyed) {
                (None, false) => bail!(
                    "{at}: map = \"scenario/label\" of one of this bench's runs (or surveyed = true)"
                ),
                (Some((s, label)), false) => {
                    if !self.scenarios.iter().any(|x| x == s) || !labels.contains(label) {
                        bail!(
                            "{at}: map = \"{s}/{label}\" is not a run of this bench (scenario/label)"
                        );
                    }
                }
                (Some(_), true) => bail!("{at}: give map or surveyed = true, not both"),
                (None, true) if l.plugin.is_none() => {
                    bail!("{at}: surveyed = true needs plugin (e.g. \"amcl\")")
                }
                (None, true) => {}
            }
            if l.grid && l.surveyed {
                bail!("{at}: grid and surveyed: give one");
            }
            if self.is_sweep() && l.world.is_some() {
                bail!(
                    "{at}: world: in a sweep a localisation run's world is a point of the axes (cross = [...] names the axes it crosses)"
                );
            }
            if !self.is_sweep() && !l.cross.is_empty() {
                bail!("{at}: cross is for sweeps (seeds or [axes]); a bench names its world");
            }
            l.spec()
                .check()
                .map_err(|why| anyhow::anyhow!("{at}: {why}"))?;
            if !labels.insert(self.localize_label(i)) {
                bail!(
                    "{at}: label '{}' used twice; give each entry its own label",
                    self.localize_label(i)
                );
            }
        }
        Ok(())
    }

    /// The plugin of `[[localize]]` entry `i` as resolved: another plugin by name or path
    /// with its own parameters, or the mapping run's with its parameters; `resolved` are
    /// this file's `[[plugins]]` resolved, `file` this file.
    pub fn localize_plugin(
        &self,
        i: usize,
        resolved: &[ResolvedPlugin],
        file: &Path,
    ) -> anyhow::Result<(PathBuf, String, PathBuf)> {
        let l = &self.localize[i];
        match (&l.plugin, l.map_run()) {
            (Some(p), _) => {
                let dirs = crate::plugins::search_path(&self.plugin_dirs);
                let library = crate::plugins::resolve(p, &dirs)
                    .with_context(|| format!("{}: localize[{i}]", file.display()))?;
                let base = resolved
                    .first()
                    .map(|r| r.base_dir.clone())
                    .unwrap_or_else(|| PathBuf::from("."));
                Ok((library, toml::to_string(&l.params)?, base))
            }
            (None, Some((_, label))) => {
                let r = resolved
                    .iter()
                    .find(|r| r.label == label)
                    .expect("checked when the file was read");
                Ok((r.library.clone(), r.params_toml.clone(), r.base_dir.clone()))
            }
            (None, None) => unreachable!("checked when the file was read"),
        }
    }

    /// The column label of `[[localize]]` entry `i`.
    pub fn localize_label(&self, i: usize) -> String {
        let l = &self.localize[i];
        if let Some(label) = &l.label {
            return label.clone();
        }
        let who = match (&l.plugin, l.map_run()) {
            (Some(p), _) => crate::cmd::run::plugin_label(p),
            (None, Some((_, label))) => label.to_owned(),
            (None, None) => "localize".to_owned(),
        };
        match l.map_run() {
            Some((scenario, _)) if !l.surveyed => format!("{who}-in-{scenario}"),
            _ => format!("{who}-in-survey"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(head: &str) -> anyhow::Result<BenchConfig> {
        let dir = tempfile::tempdir()?;
        let file = dir.path().join("m.toml");
        std::fs::write(&file, format!("{head}\n[[plugins]]\nname = \"x\"\n"))?;
        BenchConfig::from_file(&file)
    }

    #[test]
    fn max_time_is_optional_and_must_be_positive() {
        assert_eq!(parse("").expect("no limit").max_time_s, None);
        assert_eq!(
            parse("max_time_s = 20").expect("integer").max_time_s,
            Some(20.0)
        );
        assert_eq!(
            parse("max_time_s = 2.5").expect("float").max_time_s,
            Some(2.5)
        );
        for bad in ["0", "-3.0", "nan", "inf"] {
            let err = parse(&format!("max_time_s = {bad}"))
                .expect_err("a non-positive limit is refused")
                .to_string();
            assert!(
                err.contains("m.toml")
                    && err.contains("max_time_s")
                    && err.contains("positive")
                    && !err.contains('\n'),
                "one line naming the file and the key: {err}"
            );
        }
    }
}
