//! Sweeps (`vinebench sweep`): a bench file plus axes — `seeds`, and world keys by their
//! dotted path under `[axes]` — crossed with its scenarios and plugins. Every cell is one run
//! exactly as `vinebench run` makes it, filed under a hash of its resolved configuration
//! (`runs/<key>/`), so that
//! - a run's folder is complete or absent: it is written elsewhere and moved into place
//!   (one `rename`) once evaluated;
//! - a sweep stopped at any moment and started again runs only what is missing;
//! - a changed sweep file, world or plugin gives new keys, so stale runs are never mixed in
//!   (they stay on disk, unused). The `vinebench` build is not part of the key, so that a
//!   rebuilt binary can still aggregate and resume a study; every run records the build
//!   that made it, and the aggregate lists them all and says when there are several.
//!
//! Layout of a sweep folder:
//! - `worlds/<key>.toml`: the resolved simulator configuration of each point of the axes;
//! - `runs/<key>/`: one finished run (the files of a bench's run folder, and `cell.json`);
//! - `.work/`: runs in progress, removed when their process is gone;
//! - `recordings/`: with `record_once`, the recordings of the cells being run (each removed
//!   once its runs end; kept by a stopped sweep, for it to replay when it resumes);
//! - `sweep.json`, `sweep.csv`, `speed.csv`, `sweep.md`, `plots/`: the aggregate
//!   ([`aggregate`]);
//! - `slurm/`: the job arrays submitted ([`slurm`]).

pub mod aggregate;
pub mod slurm;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use serde::{Deserialize, Serialize};

use crate::bench_config::BenchConfig;
use crate::results::{
    RunOutcome, RunStatus, SWEEP_MARKER as MARKER, exe_hash, file_hash, short_hash, write_atomic,
};
use crate::runner::{Plan, PlannedRun};

/// One axis: a world key by its dotted path and the values it takes; or the sweep's
/// `[variants]`, an axis called [`VARIANT`] whose values are the variants' names.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub path: String,
    pub values: Vec<toml::Value>,
    /// The variant axis only: the world keys (dotted path, value) each of its values sets,
    /// in the order of `values`; empty for a key's own axis.
    pub sets: Vec<Vec<(String, toml::Value)>>,
}

/// The name of the axis a sweep's `[variants]` make.
pub const VARIANT: &str = "variant";

impl Axis {
    /// Sets this axis's `value` in a world's `table`.
    fn apply(&self, table: &mut toml::Table, value: &toml::Value) -> Result<(), String> {
        if self.sets.is_empty() {
            return set_dotted(table, &self.path, value.clone());
        }
        let i = self
            .values
            .iter()
            .position(|v| v == value)
            .ok_or_else(|| format!("no variant {}", value_text(value)))?;
        for (path, v) in &self.sets[i] {
            set_dotted(table, path, v.clone())
                .map_err(|why| format!("{} sets \"{path}\": {why}", value_text(value)))?;
        }
        Ok(())
    }
}

/// The `variant` axis of a sweep file's `[variants]` (none without), variants in name order.
fn variant_axis(
    variants: &toml::Table,
    keys: &toml::Table,
    name: &str,
) -> anyhow::Result<Option<Axis>> {
    if variants.is_empty() {
        return Ok(None);
    }
    let mut values = Vec::new();
    let mut sets = Vec::new();
    for (variant, settings) in variants {
        let toml::Value::Table(settings) = settings else {
            anyhow::bail!(
                "{name}: variants.{variant}: give a table of world keys ([variants.{variant}])"
            );
        };
        let mut set = Vec::new();
        for (path, value) in settings {
            if let toml::Value::Table(_) = value {
                anyhow::bail!(
                    "{name}: variants.{variant}.\"{path}\": a table; give each of its keys by its dotted path"
                );
            }
            anyhow::ensure!(
                !keys.contains_key(path),
                "{name}: variants.{variant}.\"{path}\" is also an axis; set it in one place"
            );
            set.push((path.clone(), value.clone()));
        }
        values.push(toml::Value::String(variant.clone()));
        sets.push(set);
    }
    Ok(Some(Axis {
        path: VARIANT.to_owned(),
        values,
        sets,
    }))
}

/// One run of the sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// Hash of the resolved configuration: the run's folder name under `runs/`.
    pub key: String,
    pub scenario: String,
    /// The system's label (`[[plugins]] label`).
    pub label: String,
    pub plugin: PathBuf,
    pub params_toml: String,
    #[serde(default)]
    pub pace: crate::runner::Pace,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub queue_size: Option<crate::runner::QueueSize>,
    /// The sweep file's folder: what the plugin's relative paths are relative to.
    #[serde(default)]
    pub base_dir: Option<PathBuf>,
    pub seed: u64,
    /// The value of every axis (as TOML), in axis order.
    pub point: Vec<(String, String)>,
    /// The resolved world: `worlds/<world>.toml`.
    pub world: String,
    /// A `[[localize]]` run: from which map (absent: a mapping run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub localize: Option<LocalizeCell>,
}

/// The map a sweep's localisation run starts from, and how it is started.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalizeCell {
    /// The mapping run's cell key (`runs/<map>/`); absent for the world's surveyed grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<String>,
    /// The mapping run's occupancy grid instead of its `map.bin`.
    #[serde(default)]
    pub grid: bool,
    /// The surveyed grid's world file; absent: the run's own world.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub survey_world: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_guess: Option<crate::runner::GuessSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kidnap: Option<crate::runner::Kidnap>,
}

impl LocalizeCell {
    /// The worker's order in sweep folder `out`: the mapping run by its absolute path, so
    /// that the run finds it from its work folder and after it is filed.
    pub fn spec(&self, out: &Path) -> anyhow::Result<crate::runner::LocalizeSpec> {
        use crate::runner::{LocalizeSpec, MapSource};
        let mapping_run = self
            .map
            .as_ref()
            .map(|key| std::path::absolute(run_dir(out, key)))
            .transpose()?;
        let map = MapSource::of(mapping_run.as_deref(), self.grid, self.survey_world.clone());
        Ok(LocalizeSpec {
            map,
            mapping_run,
            initial_guess: self.initial_guess,
            kidnap: self.kidnap,
        })
    }
}

impl Cell {
    /// The run of this cell in sweep folder `out`.
    pub fn planned_run(&self, out: &Path) -> anyhow::Result<PlannedRun> {
        Ok(PlannedRun {
            scenario: self.scenario.clone(),
            label: self.label.clone(),
            plugin: self.plugin.clone(),
            params_toml: self.params_toml.clone(),
            pace: self.pace,
            queue_size: self.queue_size.clone(),
            drops: None,
            base_dir: self.base_dir.clone(),
            localize: self.localize.as_ref().map(|l| l.spec(out)).transpose()?,
            world: None,
        })
    }

    /// `seed=1 vineyard.growth_stage=2`, for progress lines.
    pub fn describe(&self) -> String {
        let mut s = format!("{} {} seed={}", self.scenario, self.label, self.seed);
        for (path, value) in &self.point {
            s += &format!(" {path}={value}");
        }
        s
    }
}

/// What `cell.json` in a run folder holds: the cell and how its run ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Filed {
    #[serde(flatten)]
    pub cell: Cell,
    /// `"ok"` or `"failed: <reason>"`.
    pub status: String,
    /// Hash of the `vinebench` executable that made the run.
    pub build: String,
}

/// A sweep file, expanded.
#[derive(Debug, Clone)]
pub struct Sweep {
    pub file: PathBuf,
    pub cfg: BenchConfig,
    pub axes: Vec<Axis>,
    /// Resolved worlds by key: their TOML text.
    pub worlds: BTreeMap<String, String>,
    /// Every cell, in a stable order: scenario, plugin, axis values, seed.
    pub cells: Vec<Cell>,
    /// The seeds, in file order.
    pub seeds: Vec<u64>,
    /// Hash of the `vinebench` executable that expanded the sweep: the build of the runs it
    /// makes.
    pub exe_hash: String,
}

/// Sets `path` (dotted) in `table` to `value`, creating tables on the way; refuses to
/// replace a table by a value or to step through a value.
fn set_dotted(table: &mut toml::Table, path: &str, value: toml::Value) -> Result<(), String> {
    let parts: Vec<&str> = path.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err("an empty key in the dotted path".into());
    }
    let (leaf, tables) = parts.split_last().expect("split gives one part at least");
    let mut at = table;
    for part in tables {
        let next = at
            .entry((*part).to_owned())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        at = match next {
            toml::Value::Table(t) => t,
            _ => return Err(format!("'{part}' is a value, not a table")),
        };
    }
    if matches!(at.get(*leaf), Some(toml::Value::Table(_))) {
        return Err(format!("'{leaf}' is a table; give one of its keys"));
    }
    at.insert((*leaf).to_owned(), value);
    Ok(())
}

/// The cartesian product of the axes' values, the last axis varying fastest.
fn points(axes: &[Axis]) -> Vec<Vec<toml::Value>> {
    let mut out = vec![Vec::new()];
    for axis in axes {
        out = out
            .into_iter()
            .flat_map(|p| {
                axis.values.iter().map(move |v| {
                    let mut q = p.clone();
                    q.push(v.clone());
                    q
                })
            })
            .collect();
    }
    out
}

/// A value as TOML, for labels and CSV columns: `2`, `0.5`, `"dense"`.
pub fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => format!("{s:?}"),
        other => other.to_string(),
    }
}

/// A sweep file's axes and seeds, and the world of every point of its axes: everything of a
/// sweep but its plugins.
#[derive(Debug, Clone)]
pub struct Expansion {
    pub axes: Vec<Axis>,
    /// The seeds, in file order.
    pub seeds: Vec<u64>,
    /// Resolved worlds by key: their TOML text.
    pub worlds: BTreeMap<String, String>,
    /// Every point of the axes (last axis fastest) with the key of its world.
    pub points: Vec<(Vec<toml::Value>, String)>,
}

/// Most worlds (points of the axes) a sweep may resolve: each is checked and kept as text.
pub const MAX_WORLDS: usize = 1_000;
/// Most cells (runs) a sweep may have: scenarios x plugins x points x seeds.
pub const MAX_CELLS: usize = 100_000;

/// Expands the axes and seeds of `cfg`, a sweep file called `name`, over the world whose
/// TOML text is `base_world`; checks every resolved world and that it has the scenarios.
/// A sweep beyond [`MAX_WORLDS`] or [`MAX_CELLS`] is refused before anything is expanded.
pub fn expand(cfg: &BenchConfig, name: &str, base_world: &str) -> anyhow::Result<Expansion> {
    let mut axes: Vec<Axis> = variant_axis(&cfg.variants, &cfg.axes, name)?
        .into_iter()
        .collect();
    for (path, values) in &cfg.axes {
        let values = match values {
            toml::Value::Array(a) if !a.is_empty() => a.clone(),
            _ => anyhow::bail!("{name}: axes.\"{path}\": give a non-empty list of values"),
        };
        // A value may be a list (`"fence.panels" = [[]]`: no fence), not a table: an axis
        // sets one key.
        if let Some(v) = values.iter().find(|v| matches!(v, toml::Value::Table(_))) {
            anyhow::bail!("{name}: axes.\"{path}\": {v} is a table, not a value of one key");
        }
        let distinct: BTreeSet<String> = values.iter().map(value_text).collect();
        anyhow::ensure!(
            distinct.len() == values.len(),
            "{name}: axes.\"{path}\": a value is given twice"
        );
        axes.push(Axis {
            path: path.clone(),
            values,
            sets: Vec::new(),
        });
    }
    let seeds = cfg
        .seeds
        .clone()
        .unwrap_or_else(|| vec![cfg.seed.unwrap_or(0)]);
    anyhow::ensure!(
        seeds.iter().collect::<BTreeSet<_>>().len() == seeds.len(),
        "{name}: seeds: a seed is given twice"
    );
    let worlds = axes
        .iter()
        .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
        .filter(|&n| n <= MAX_WORLDS);
    let Some(worlds) = worlds else {
        anyhow::bail!("{name}: the axes cross into more than {MAX_WORLDS} worlds; split the sweep");
    };
    let cells = [cfg.scenarios.len(), cfg.plugins.len(), seeds.len()]
        .into_iter()
        .try_fold(worlds, usize::checked_mul)
        .filter(|&n| n <= MAX_CELLS);
    anyhow::ensure!(
        cells.is_some(),
        "{name}: scenarios x plugins x {worlds} worlds x seeds is more than {MAX_CELLS} runs; \
         split the sweep"
    );

    let base: toml::Table = base_world
        .parse()
        .map_err(|e: toml::de::Error| anyhow::anyhow!("{name}: world: {}", e.message()))?;
    let mut worlds = BTreeMap::new();
    let mut point_worlds = Vec::new();
    for point in points(&axes) {
        let mut table = base.clone();
        for (axis, value) in axes.iter().zip(&point) {
            axis.apply(&mut table, value)
                .map_err(|why| match axis.sets.is_empty() {
                    true => anyhow::anyhow!("{name}: axes.\"{}\": {why}", axis.path),
                    false => anyhow::anyhow!("{name}: variants: {why}"),
                })?;
        }
        let text = toml::to_string(&table)?;
        let origin = format!(
            "{name} at {}",
            axes.iter()
                .zip(&point)
                .map(|(a, v)| format!("{} = {}", a.path, value_text(v)))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let world = sim::SimConfig::from_toml_str(&text, &origin)?;
        let localized = cfg.localize.iter().map(|l| &l.scenario);
        for s in cfg.scenarios.iter().chain(localized) {
            anyhow::ensure!(
                world.scenarios.contains_key(s),
                "{name}: unknown scenario '{s}' (known: {})",
                world
                    .scenarios
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        // The world resolved, every key stated: its profile's models are in the key (a
        // changed profile file is another world, never a stale run) and in the file the
        // runs read (what they run cannot change with the binary that runs them).
        let text = world.to_toml_string();
        let key = short_hash(text.as_bytes());
        worlds.insert(key.clone(), text);
        point_worlds.push((point, key));
    }
    Ok(Expansion {
        axes,
        seeds,
        worlds,
        points: point_worlds,
    })
}

/// The localisation cells of a sweep's `[[localize]]` entries: each entry's maps (the
/// mapping cells of its `map = "scenario/label"`, or with `surveyed` every point and seed)
/// crossed with every value of its `cross` axes, the other axes and the seed the map's.
/// A crossed localisation run's label says where its map was built
/// (`lio-sam-in-s3@growth_stage=2`).
#[allow(clippy::too_many_arguments)]
fn localize_cells(
    cfg: &BenchConfig,
    file: &Path,
    plugins: &[crate::bench_config::ResolvedPlugin],
    axes: &[Axis],
    point_worlds: &[(Vec<toml::Value>, String)],
    seeds: &[u64],
    mapping: &[Cell],
    max_time: &str,
) -> anyhow::Result<Vec<Cell>> {
    let name = file.display();
    let mut out = Vec::new();
    for (i, l) in cfg.localize.iter().enumerate() {
        let crossed: Vec<usize> = l
            .cross
            .iter()
            .map(|path| {
                axes.iter().position(|a| &a.path == path).ok_or_else(|| {
                    anyhow::anyhow!(
                        "{name}: localize[{i}]: cross: \"{path}\" is not an axis of this sweep (axes: {})",
                        axes.iter()
                            .map(|a| a.path.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
            })
            .collect::<anyhow::Result<_>>()?;
        let (library, params_toml, base_dir) = cfg.localize_plugin(i, plugins, file)?;
        let plugin_hash = file_hash(&library)?;
        let base_label = cfg.localize_label(i);
        let spec = l.spec();
        // The maps: (mapping cell, its point of the axes, its seed).
        let maps: Vec<(Option<&Cell>, Vec<String>, u64)> = match l.map_run() {
            Some((scenario, label)) if !l.surveyed => mapping
                .iter()
                .filter(|c| c.scenario == scenario && c.label == label)
                .map(|c| {
                    (
                        Some(c),
                        c.point.iter().map(|(_, v)| v.clone()).collect(),
                        c.seed,
                    )
                })
                .collect(),
            _ => point_worlds
                .iter()
                .flat_map(|(point, _)| {
                    seeds
                        .iter()
                        .map(move |&s| (None, point.iter().map(value_text).collect(), s))
                })
                .collect(),
        };
        anyhow::ensure!(
            !maps.is_empty(),
            "{name}: localize[{i}]: map = {:?} is not a run of this sweep (scenario/label)",
            l.map.as_deref().unwrap_or_default()
        );
        for (map, map_point, seed) in &maps {
            for (point, world) in point_worlds {
                let text: Vec<String> = point.iter().map(value_text).collect();
                let same = (0..axes.len()).all(|a| crossed.contains(&a) || text[a] == map_point[a]);
                if !same {
                    continue;
                }
                let label = if crossed.is_empty() || map.is_none() {
                    base_label.clone()
                } else {
                    let at: Vec<String> = crossed
                        .iter()
                        .map(|&a| {
                            let short = axes[a].path.rsplit('.').next().unwrap_or_default();
                            format!("{short}={}", map_point[a])
                        })
                        .collect();
                    format!("{base_label}@{}", at.join(","))
                };
                let cell = LocalizeCell {
                    map: map.map(|m| m.key.clone()),
                    grid: l.grid,
                    survey_world: match &spec.map {
                        crate::runner::MapSource::Surveyed { world } => world.clone(),
                        _ => None,
                    },
                    initial_guess: spec.initial_guess,
                    kidnap: spec.kidnap,
                };
                let survey_hash = cell
                    .survey_world
                    .as_ref()
                    .map(|w| file_hash(w))
                    .transpose()?
                    .unwrap_or_default();
                let resolved = format!(
                    "vinebench-sweep-localize 1\nscenario {:?}\nseed {seed}\nplugin {plugin_hash}\n\
                     params {params_toml:?}\nworld {world}\nmax_time {max_time}\nalign {:?}\n\
                     timeout {:?}\nmemory {}\nmap {:?}\ngrid {}\nsurvey {survey_hash}\n\
                     guess {:?}\nkidnap {:?}\n",
                    l.scenario,
                    cfg.align,
                    cfg.timeout_s,
                    cfg.memory_limit_mb,
                    cell.map,
                    cell.grid,
                    cell.initial_guess,
                    cell.kidnap,
                );
                out.push(Cell {
                    key: short_hash(resolved.as_bytes()),
                    scenario: l.scenario.clone(),
                    label,
                    plugin: library.clone(),
                    params_toml: params_toml.clone(),
                    pace: crate::runner::Pace::Free,
                    queue_size: None,
                    base_dir: Some(base_dir.clone()),
                    seed: *seed,
                    point: axes
                        .iter()
                        .zip(&text)
                        .map(|(a, v)| (a.path.clone(), v.clone()))
                        .collect(),
                    world: world.clone(),
                    localize: Some(cell),
                });
            }
        }
    }
    anyhow::ensure!(
        mapping.len() + out.len() <= MAX_CELLS,
        "{name}: the mapping and localisation runs are more than {MAX_CELLS}; split the sweep"
    );
    Ok(out)
}

impl Sweep {
    /// Reads and expands a sweep file; `max_time_s` (`--max-time`) overrides the file's.
    pub fn load(file: &Path, max_time_s: Option<f64>) -> anyhow::Result<Self> {
        let mut cfg = BenchConfig::from_file(file)?;
        if max_time_s.is_some() {
            cfg.max_time_s = max_time_s;
        }
        let name = file.display().to_string();
        let base_text = match &cfg.world {
            Some(p) => std::fs::read_to_string(p).with_context(|| p.display().to_string())?,
            None => sim::DEFAULT_CONFIG_TOML.to_owned(),
        };
        let Expansion {
            axes,
            seeds,
            worlds,
            points: point_worlds,
        } = expand(&cfg, &name, &base_text)?;
        let exe_hash = exe_hash()?;
        let plugins = cfg.resolve_plugins(file)?;
        let plugin_hashes = plugins
            .iter()
            .map(|p| file_hash(&p.library))
            .collect::<anyhow::Result<Vec<_>>>()?;

        let max_time = cfg
            .max_time_s
            .map_or_else(|| "whole route".to_owned(), |s| format!("{s:?}"));
        let mut cells = Vec::new();
        for scenario in &cfg.scenarios {
            for (plugin, plugin_hash) in plugins.iter().zip(&plugin_hashes) {
                for (point, world) in &point_worlds {
                    for &seed in &seeds {
                        // Everything that decides what the run does; not the label, which
                        // only names it.
                        // A paced run is another run; the free pace keeps the keys of
                        // sweeps made before pacing existed. Files a plugin reads by the
                        // paths in its parameters (a Python bridge's module, a vocabulary)
                        // are not hashed: edit one and delete its cells to run them again.
                        let pace = match plugin.pace {
                            crate::runner::Pace::Free => String::new(),
                            crate::runner::Pace::Realtime => "pace realtime\n".to_owned(),
                        };
                        // Likewise bounded queues, new with issue 45.
                        let pace = match &plugin.queue_size {
                            None => pace,
                            Some(q) => format!("{pace}queue {q:?}\n"),
                        };
                        let resolved = format!(
                            "vinebench-sweep-cell 1\nscenario {scenario:?}\nseed {seed}\n\
                             plugin {plugin_hash}\nparams {:?}\nworld {world}\n\
                             max_time {max_time}\nalign {:?}\ntimeout {:?}\nmemory {}\n{pace}",
                            plugin.params_toml, cfg.align, cfg.timeout_s, cfg.memory_limit_mb
                        );
                        cells.push(Cell {
                            key: short_hash(resolved.as_bytes()),
                            scenario: scenario.clone(),
                            label: plugin.label.clone(),
                            plugin: plugin.library.clone(),
                            params_toml: plugin.params_toml.clone(),
                            pace: plugin.pace,
                            queue_size: plugin.queue_size.clone(),
                            base_dir: Some(plugin.base_dir.clone()),
                            seed,
                            point: axes
                                .iter()
                                .zip(point)
                                .map(|(a, v)| (a.path.clone(), value_text(v)))
                                .collect(),
                            world: world.clone(),
                            localize: None,
                        });
                    }
                }
            }
        }
        let localizing = localize_cells(
            &cfg,
            file,
            &plugins,
            &axes,
            &point_worlds,
            &seeds,
            &cells,
            &max_time,
        )?;
        cells.extend(localizing);
        Ok(Self {
            file: file.to_owned(),
            cfg,
            axes,
            worlds,
            cells,
            seeds,
            exe_hash,
        })
    }

    /// Prepares the sweep folder: checks it is one (or empty), writes the resolved worlds
    /// and removes the leftovers of runs whose process is gone.
    pub fn prepare(&self, out: &Path) -> anyhow::Result<()> {
        if out.exists() && !out.join(MARKER).exists() && std::fs::read_dir(out)?.next().is_some() {
            anyhow::bail!(
                "{} exists and is not a vinebench sweep folder; choose another --out",
                out.display()
            );
        }
        for dir in ["worlds", "runs", ".work"] {
            std::fs::create_dir_all(out.join(dir))
                .with_context(|| out.join(dir).display().to_string())?;
        }
        std::fs::File::create(out.join(MARKER))
            .with_context(|| out.join(MARKER).display().to_string())?;
        for (key, text) in &self.worlds {
            let path = out.join("worlds").join(format!("{key}.toml"));
            if !path.exists() {
                write_atomic(&path, text.as_bytes())?;
            }
        }
        remove_orphans(&out.join(".work"))
    }

    /// The cells whose run is not in `runs/` yet, each key once.
    pub fn missing(&self, out: &Path) -> Vec<&Cell> {
        let mut seen = BTreeSet::new();
        self.cells
            .iter()
            .filter(|c| seen.insert(c.key.as_str()))
            .filter(|c| !run_dir(out, &c.key).exists())
            .collect()
    }

    /// One plan per (world, seed) for the given cells, in order of first appearance, so
    /// that the runs of a scenario may share its simulation. With `record_once`, one per
    /// (world as recorded, seed): worlds that differ only in their GNSS receiver, which
    /// recordings leave out, replay the same recordings, each run with its own world
    /// (`runner::record`).
    pub fn plans(
        &self,
        out: &Path,
        cells: &[&Cell],
        jobs: usize,
    ) -> anyhow::Result<Vec<(Plan, Vec<Cell>)>> {
        let mut recorded_as: BTreeMap<&str, String> = BTreeMap::new();
        let mut groups: Vec<((String, u64), Vec<Cell>)> = Vec::new();
        for c in cells {
            let world = if self.cfg.record_once && c.localize.is_none() {
                match recorded_as.get(c.world.as_str()) {
                    Some(k) => k.clone(),
                    None => {
                        let text = self.worlds.get(&c.world).with_context(|| {
                            format!("cell {}: no resolved world {}", c.key, c.world)
                        })?;
                        let config = sim::SimConfig::from_toml_str(text, &c.world)?;
                        let k = format!("recorded {}", record_key(&config));
                        recorded_as.insert(&c.world, k.clone());
                        k
                    }
                }
            } else {
                c.world.clone()
            };
            let k = (world, c.seed);
            match groups.iter_mut().find(|(g, _)| *g == k) {
                Some((_, v)) => v.push((*c).clone()),
                None => groups.push((k, vec![(*c).clone()])),
            }
        }
        groups
            .into_iter()
            .map(|((_, seed), cells)| {
                // The first cell's world (the plan's recordings are made from it).
                let world = cells[0].world.clone();
                let shared = cells.iter().all(|c| c.world == world);
                let mut scenarios: Vec<String> = Vec::new();
                for c in &cells {
                    if !scenarios.contains(&c.scenario) {
                        scenarios.push(c.scenario.clone());
                    }
                }
                Ok((
                    Plan {
                        world: Some(out.join("worlds").join(format!("{world}.toml"))),
                        seed,
                        scenarios,
                        runs: cells
                            .iter()
                            .map(|c| {
                                let mut run = c.planned_run(out)?;
                                if !shared {
                                    run.world =
                                        Some(out.join("worlds").join(format!("{}.toml", c.world)));
                                }
                                Ok(run)
                            })
                            .collect::<anyhow::Result<_>>()?,
                        jobs,
                        timeout: Duration::from_secs_f64(self.cfg.timeout_s),
                        memory_limit_mb: self.cfg.memory_limit_mb,
                        alignment: self.cfg.align.into(),
                        dataset: None,
                        max_time_s: self.cfg.max_time_s,
                        share_simulation: self.cfg.share_simulation,
                        record_once: self.cfg.record_once.then(|| out.join(RECORDINGS)),
                        bars: false,
                    },
                    cells,
                ))
            })
            .collect()
    }
}

/// A short hash of what a recording of `config` depends on
/// (`runner::record::recorded_world_text`).
fn record_key(config: &sim::SimConfig) -> String {
    short_hash(crate::runner::recorded_world_text(config).as_bytes())
}

/// The folder of a sweep's recordings (`record_once`): what a stopped sweep had recorded
/// and not yet replayed, for it to replay when it resumes.
pub const RECORDINGS: &str = "recordings";

/// Where a cell's finished run lives.
pub fn run_dir(out: &Path, key: &str) -> PathBuf {
    out.join("runs").join(key)
}

/// Work folders are named `<host>-<pid>-...`; those of this host whose process is gone
/// are leftovers of a sweep that was stopped.
fn remove_orphans(work: &Path) -> anyhow::Result<()> {
    let host = hostname();
    for entry in std::fs::read_dir(work).with_context(|| work.display().to_string())? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&format!("{host}-")) else {
            continue;
        };
        let pid = rest.split('-').next().unwrap_or("");
        let alive = !pid.is_empty() && Path::new("/proc").join(pid).exists();
        if !alive {
            std::fs::remove_dir_all(entry.path())
                .with_context(|| entry.path().display().to_string())?;
        }
    }
    Ok(())
}

/// This machine's name (Slurm tasks share the folder across machines).
fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .ok()
        .filter(|h| !h.is_empty() && !h.contains('/'))
        .unwrap_or_else(|| "localhost".into())
}

/// A fresh work folder for this process: `.work/<host>-<pid>-<tag>`.
pub fn work_dir(out: &Path, tag: &str) -> PathBuf {
    out.join(".work")
        .join(format!("{}-{}-{tag}", hostname(), std::process::id()))
}

/// Files a finished run: writes its `cell.json` and moves its folder to `runs/<key>`.
/// Another process that filed the same cell first wins; this copy is dropped.
pub fn file_run(
    out: &Path,
    cell: &Cell,
    build: &str,
    status: &RunStatus,
    dir: &Path,
) -> anyhow::Result<()> {
    let filed = Filed {
        cell: cell.clone(),
        status: status.text(),
        build: build.to_owned(),
    };
    let json = serde_json::to_string_pretty(&filed)? + "\n";
    std::fs::write(dir.join("cell.json"), json)
        .with_context(|| dir.join("cell.json").display().to_string())?;
    let target = run_dir(out, &cell.key);
    if target.exists() {
        std::fs::remove_dir_all(dir).with_context(|| dir.display().to_string())?;
        return Ok(());
    }
    std::fs::rename(dir, &target).with_context(|| target.display().to_string())
}

/// Reads a filed run's `cell.json`.
pub fn read_filed(dir: &Path) -> anyhow::Result<Filed> {
    let path = dir.join("cell.json");
    let text = std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
    serde_json::from_str(&text).with_context(|| path.display().to_string())
}

/// Runs `cells` here, `jobs` at once, filing each run as it ends; `on_filed` is called after
/// each with its outcome, its folder where it was filed (for progress). Returns why the
/// runs the host failed (a worker that could not start, a recording that could not be
/// made) were not filed.
pub fn run_local(
    sweep: &Sweep,
    out: &Path,
    cells: &[&Cell],
    jobs: usize,
    on_filed: &(dyn Fn(&Cell, &RunOutcome) + Sync),
) -> anyhow::Result<Vec<String>> {
    let failures = std::sync::Mutex::new(Vec::new());
    let unfiled = std::sync::Mutex::new(Vec::new());
    for (n, (plan, group)) in sweep.plans(out, cells, jobs)?.into_iter().enumerate() {
        let work = work_dir(out, &n.to_string());
        let filed = |i: usize, outcome: &RunOutcome| {
            if let RunStatus::Failed(why) = &outcome.status {
                // Not filed: an interrupted run, or one whose worker could not start or
                // whose recording could not be made (the host's doing, not the plugin's),
                // runs again when the sweep resumes.
                if crate::runner::interrupt::is_interruption(why) {
                    return;
                }
                if crate::runner::supervise::is_start_failure(why) {
                    unfiled
                        .lock()
                        .expect("no panics while holding the lock")
                        .push(why.clone());
                    return;
                }
            }
            let cell = &group[i];
            match file_run(
                out,
                cell,
                &sweep.exe_hash,
                &outcome.status,
                &outcome.folder.dir,
            ) {
                Ok(()) => on_filed(
                    cell,
                    &RunOutcome {
                        folder: crate::results::RunFolder::new(run_dir(out, &cell.key)),
                        ..outcome.clone()
                    },
                ),
                Err(e) => failures
                    .lock()
                    .expect("no panics while holding the lock")
                    .push(format!("{e:#}")),
            }
        };
        crate::runner::execute(&plan, &work, &filed)?;
        std::fs::remove_dir_all(&work).with_context(|| work.display().to_string())?;
        if crate::runner::interrupt::interrupted() {
            return Err(crate::exit::Exit::interrupted(format!(
                "interrupted: the runs filed so far are kept in {}; run the sweep again to resume",
                out.display()
            ))
            .into());
        }
        let failures = failures.lock().expect("no panics while holding the lock");
        if let Some(first) = failures.first() {
            anyhow::bail!("filing a run: {first}");
        }
    }
    Ok(unfiled
        .into_inner()
        .expect("no panics while holding the lock"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With `record_once`, cells whose worlds differ only in their GNSS receiver make one
    /// plan (one recording per scenario), each run with its own world; a world that differs
    /// in anything else, another seed, or no `record_once`, another plan.
    #[test]
    fn worlds_that_differ_only_in_their_receiver_share_a_plan_when_recorded() {
        let plain = sim::DEFAULT_CONFIG_TOML;
        let world = |text: String| {
            sim::SimConfig::from_toml_str(&text, "w")
                .expect("world")
                .to_toml_string()
        };
        let receiver = |profile: &str| {
            world(format!(
                "{plain}\n[sensors.gnss]\nprofile = \"{profile}\"\n"
            ))
        };
        let worlds: BTreeMap<String, String> = [
            ("plain", world(plain.to_owned())),
            ("rtk", receiver("rtk")),
            ("consumer", receiver("consumer")),
            (
                "staged",
                world(plain.replacen("growth_stage = 3.0", "growth_stage = 1.0", 1)),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .collect();
        assert_ne!(worlds["staged"], worlds["plain"]);
        let cell = |world: &str, seed: u64| Cell {
            key: format!("{world}-{seed}"),
            scenario: "s0".into(),
            label: "x".into(),
            plugin: PathBuf::from("x.so"),
            params_toml: String::new(),
            pace: Default::default(),
            queue_size: None,
            base_dir: None,
            seed,
            point: Vec::new(),
            world: world.into(),
            localize: None,
        };
        let cells = vec![
            cell("plain", 0),
            cell("rtk", 0),
            cell("consumer", 0),
            cell("staged", 0),
            cell("rtk", 1),
        ];
        let sweep = |record_once: bool| Sweep {
            file: PathBuf::from("s.toml"),
            cfg: BenchConfig::from_toml(
                &format!(
                    "scenarios = [\"s0\"]\nrecord_once = {record_once}\n[[plugins]]\nname = \"x\"\n"
                ),
                Path::new("s.toml"),
            )
            .expect("bench file"),
            axes: Vec::new(),
            worlds: worlds.clone(),
            cells: cells.clone(),
            seeds: vec![0, 1],
            exe_hash: "h".into(),
        };
        let out = Path::new("/sweep");
        let refs: Vec<&Cell> = cells.iter().collect();
        let shape = |record_once: bool| -> Vec<Vec<(String, Option<PathBuf>)>> {
            sweep(record_once)
                .plans(out, &refs, 2)
                .expect("plans")
                .into_iter()
                .map(|(plan, cells)| {
                    assert_eq!(plan.runs.len(), cells.len());
                    assert_eq!(
                        plan.world.as_deref(),
                        Some(
                            out.join(format!("worlds/{}.toml", cells[0].world))
                                .as_path()
                        ),
                        "the plan's world is its first cell's"
                    );
                    cells
                        .iter()
                        .zip(&plan.runs)
                        .map(|(c, r)| (c.key.clone(), r.world.clone()))
                        .collect()
                })
                .collect()
        };
        let own = |w: &str| Some(out.join(format!("worlds/{w}.toml")));
        assert_eq!(
            shape(true),
            [
                vec![
                    ("plain-0".to_owned(), own("plain")),
                    ("rtk-0".to_owned(), own("rtk")),
                    ("consumer-0".to_owned(), own("consumer")),
                ],
                vec![("staged-0".to_owned(), None)],
                vec![("rtk-1".to_owned(), None)],
            ]
        );
        assert_eq!(
            shape(false),
            ["plain-0", "rtk-0", "consumer-0", "staged-0", "rtk-1"]
                .map(|k| vec![(k.to_owned(), None)])
        );
    }

    #[test]
    fn dotted_paths_set_nested_keys_and_refuse_tables() {
        let mut t: toml::Table = "[vineyard]\nrows = 9\n".parse().expect("toml");
        set_dotted(&mut t, "vineyard.growth_stage", toml::Value::Integer(2)).expect("set");
        set_dotted(&mut t, "terrain.amplitude_m", toml::Value::Float(0.3)).expect("new table");
        assert_eq!(t["vineyard"]["growth_stage"].as_integer(), Some(2));
        assert_eq!(t["vineyard"]["rows"].as_integer(), Some(9));
        assert_eq!(t["terrain"]["amplitude_m"].as_float(), Some(0.3));
        assert!(set_dotted(&mut t, "vineyard", toml::Value::Integer(1)).is_err());
        assert!(set_dotted(&mut t, "vineyard.rows.x", toml::Value::Integer(1)).is_err());
        assert!(set_dotted(&mut t, "vineyard..rows", toml::Value::Integer(1)).is_err());
    }

    #[test]
    fn a_list_value_replaces_the_worlds_list() {
        // `"fence.panels" = [[]]`: the paper's world without its fence.
        let text = include_str!("../../../configs/paper-world.toml");
        let mut t: toml::Table = text.parse().expect("toml");
        let before = sim::SimConfig::from_toml_str(text, "paper-world").expect("world");
        assert_eq!(before.fence.panels.len(), 56);
        set_dotted(&mut t, "fence.panels", toml::Value::Array(Vec::new())).expect("set");
        let after = sim::SimConfig::from_toml_str(&toml::to_string(&t).expect("text"), "no fence")
            .expect("world");
        assert!(after.fence.panels.is_empty());
        assert_eq!(after.vineyard, before.vineyard);
        assert_eq!(value_text(&toml::Value::Array(Vec::new())), "[]");
    }

    /// Every shipped bench and sweep file expands: each world it names or makes with its
    /// axes resolves (the profile ladder moved the worlds' sensor keys; a file whose axes
    /// no longer fit says so here, not hours into a study).
    #[test]
    fn every_shipped_bench_and_sweep_file_expands() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
        let mut files = Vec::new();
        let mut dirs = vec![root.clone()];
        while let Some(dir) = dirs.pop() {
            for entry in std::fs::read_dir(&dir).expect("configs") {
                let path = entry.expect("entry").path();
                if path.is_dir() {
                    dirs.push(path);
                } else if path.extension().is_some_and(|e| e == "toml")
                    && std::fs::read_to_string(&path)
                        .expect("read")
                        .contains("[[plugins]]")
                {
                    files.push(path);
                }
            }
        }
        assert!(files.len() > 30, "{} bench and sweep files", files.len());
        for file in files {
            let name = file.display().to_string();
            let cfg = BenchConfig::from_file(&file).unwrap_or_else(|e| panic!("{name}: {e:#}"));
            let base = match &cfg.world {
                Some(p) => std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{name}: {e}")),
                None => sim::DEFAULT_CONFIG_TOML.to_owned(),
            };
            expand(&cfg, &name, &base).unwrap_or_else(|e| panic!("{e:#}"));
        }
    }

    /// Factors measured alone before they join `field` (so that the figures kept for
    /// `field` stay the profile's until its rung runs again): each must not be in `field`
    /// yet, and every file that has it sets the same values.
    const NOT_IN_FIELD_YET: &[&str] = &["vibration"];

    /// The sensitivity study's variants are the `field` profile's factors: each sets its
    /// keys to `field`'s values (or is one of [`NOT_IN_FIELD_YET`]), and the two-core
    /// study's files (each the factors that touch what its systems read) cover every factor
    /// of the cluster's files.
    #[test]
    fn every_factor_variant_is_the_field_profiles_value() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/study/realism");
        let world = std::fs::read_to_string(dir.join("../../paper-world.toml")).expect("world");
        let field: toml::Table = sim::SimConfig::from_toml_str_as(
            &world,
            "paper world",
            Some(sim::config::Profile::Field),
        )
        .expect("resolves")
        .to_toml_string()
        .parse()
        .expect("TOML");
        let at = |path: &str| {
            path.split('.')
                .try_fold(&toml::Value::Table(field.clone()), |v, k| v.get(k))
                .cloned()
        };
        let mut files = Vec::new();
        let mut pending: BTreeMap<String, (String, toml::Table)> = BTreeMap::new();
        for entry in std::fs::read_dir(&dir).expect("realism") {
            let path = entry.expect("entry").path();
            let name = path
                .file_name()
                .expect("name")
                .to_string_lossy()
                .into_owned();
            let factors = name.starts_with("factors-");
            if (factors || name.starts_with("cluster-")) && name.ends_with(".toml") {
                let cfg = BenchConfig::from_file(&path).expect("sweep file");
                assert!(
                    cfg.variants.len() >= 2,
                    "{name}: typical and a factor at least"
                );
                for (variant, sets) in &cfg.variants {
                    let sets = sets.as_table().expect("table");
                    // The cluster's files name the rung each variant lies over.
                    let rung = sets.get("profile").and_then(toml::Value::as_str);
                    match variant.as_str() {
                        "ideal" | "paper" | "typical" | "field" => {
                            assert_eq!(rung.unwrap_or("typical"), variant, "{name}");
                            assert!(sets.len() <= 1, "{name}: variants.{variant} sets a factor");
                            continue;
                        }
                        _ => assert_eq!(rung.unwrap_or("typical"), "typical", "{name}"),
                    }
                    if NOT_IN_FIELD_YET.contains(&variant.as_str()) {
                        let mut own = sets.clone();
                        own.remove("profile");
                        assert!(
                            own.iter()
                                .any(|(path, value)| at(path).as_ref() != Some(value)),
                            "{name}: variants.{variant} is in `field` now: drop it from \
                             NOT_IN_FIELD_YET"
                        );
                        match pending.get(variant) {
                            Some((first, sets)) => {
                                assert_eq!(sets, &own, "{name} and {first}: variants.{variant}")
                            }
                            None => {
                                pending.insert(variant.clone(), (name.clone(), own));
                            }
                        }
                        continue;
                    }
                    for (path, value) in sets.iter().filter(|(p, _)| *p != "profile") {
                        let mut want = at(path);
                        // `field` keeps floats as floats; the file may write 1.0 as 1.0.
                        if let (Some(toml::Value::Float(f)), toml::Value::Integer(i)) =
                            (&want, value)
                        {
                            assert_eq!(*f, *i as f64, "{name}: variants.{variant}.{path}");
                            want = Some(value.clone());
                        }
                        assert_eq!(
                            want.as_ref(),
                            Some(value),
                            "{name}: variants.{variant}.{path}"
                        );
                    }
                }
                if factors {
                    files.push((name, cfg.variants));
                }
            }
        }
        assert_eq!(files.len(), 3, "{files:?}");
        for variant in NOT_IN_FIELD_YET {
            assert!(pending.contains_key(*variant), "no file measures {variant}");
        }
        let factors = |variants: &toml::Table| -> BTreeSet<String> {
            variants
                .keys()
                .filter(|v| !["ideal", "paper", "typical", "field"].contains(&v.as_str()))
                .cloned()
                .collect()
        };
        let covered: BTreeSet<String> = files.iter().flat_map(|(_, v)| factors(v)).collect();
        let cluster = BenchConfig::from_file(&dir.join("cluster-paper-world.toml")).expect("sweep");
        assert_eq!(
            covered,
            factors(&cluster.variants),
            "every factor in the two-core study"
        );
    }

    /// fuzz/regressions/sweep_toml/a-million-worlds.toml: six axes of ten values, a
    /// million worlds, each resolved and checked before the sweep started (a fuzzer's
    /// timeout); a sweep past the limits is now refused before it expands.
    #[test]
    fn a_sweep_too_large_is_refused_before_it_expands() {
        let sweep = |axes: usize, values: usize, seeds: usize| {
            let mut text = format!(
                "scenarios = [\"s0\"]\nseeds = {:?}\n[axes]\n",
                (0..seeds).collect::<Vec<_>>()
            );
            for a in 0..axes {
                let list: Vec<f64> = (0..values).map(|v| 1.0 + v as f64).collect();
                text += &format!("\"sensors.imu.axis{a}\" = {list:?}\n");
            }
            text += "[[plugins]]\nname = \"x\"\n";
            let cfg = BenchConfig::from_toml(&text, Path::new("big.toml")).expect("bench file");
            expand(&cfg, "big.toml", sim::DEFAULT_CONFIG_TOML)
                .expect_err("too large")
                .to_string()
        };
        let err = sweep(6, 10, 1);
        assert!(err.contains("more than 1000 worlds"), "{err}");
        let err = sweep(3, 10, 101);
        assert!(err.contains("more than 100000 runs"), "{err}");
    }

    /// `[variants]`: one point per variant, each setting only its own keys, crossed with
    /// the axes (the variant outermost); the mistakes a user makes are refused by name.
    #[test]
    fn variants_set_their_own_keys_one_factor_at_a_time() {
        let sweep = |body: &str| {
            let text = format!("scenarios = [\"s0\"]\n{body}\n[[plugins]]\nname = \"x\"\n");
            let cfg = BenchConfig::from_toml(&text, Path::new("v.toml")).expect("bench file");
            expand(&cfg, "v.toml", sim::DEFAULT_CONFIG_TOML)
        };
        let e = sweep(
            "[axes]\n\"vineyard.growth_stage\" = [1, 3]\n\
             [variants.baseline]\n\
             [variants.tilt]\n\"sensors.imu.mount_error.sigma_deg\" = 1.0\n\
             [variants.spot]\n\"sensors.lidar.beam_divergence_mrad\" = [3.0, 1.5]\n\
             \"sensors.lidar.return_mode\" = \"last\"\n",
        )
        .expect("expands");
        assert_eq!(e.axes[0].path, VARIANT);
        assert_eq!(e.points.len(), 6, "three variants x two stages");
        let world = |i: usize| {
            sim::SimConfig::from_toml_str(&e.worlds[&e.points[i].1], "w").expect("resolves")
        };
        let names: Vec<String> = e.points.iter().map(|(p, _)| value_text(&p[0])).collect();
        assert_eq!(
            names,
            [
                "\"baseline\"",
                "\"baseline\"",
                "\"spot\"",
                "\"spot\"",
                "\"tilt\"",
                "\"tilt\""
            ]
        );
        let (base, spot, tilt) = (world(0), world(3), world(4));
        assert_eq!(base.vineyard.growth_stage, 1.0);
        assert_eq!(spot.vineyard.growth_stage, 3.0);
        assert_eq!(base.sensors.imu.mount_error.sigma_deg, 0.0);
        assert_eq!(tilt.sensors.imu.mount_error.sigma_deg, 1.0);
        assert_eq!(
            tilt.sensors.lidar.beam_divergence_mrad,
            [0.0, 0.0],
            "only its own keys"
        );
        assert_eq!(spot.sensors.lidar.beam_divergence_mrad, [3.0, 1.5]);
        assert_eq!(spot.sensors.imu.mount_error.sigma_deg, 0.0);
        assert_ne!(
            e.points[0].1, e.points[4].1,
            "another world, so other run keys"
        );
        // Each world kept resolved: its profile's models are stated, so a changed profile
        // file gives another key and a run reads the world its key names.
        let text = &e.worlds[&e.points[0].1];
        assert!(text.contains("accel_noise_density"), "{text}");
        assert_eq!(
            sim::SimConfig::from_toml_str(text, "w")
                .expect("resolves")
                .to_toml_string(),
            *text
        );

        for (body, says) in [
            ("[variants]\nx = 1", "variants.x: give a table"),
            (
                "[variants.x]\n\"sensors.imu.mount_error\" = { sigma_deg = 1.0 }",
                "a table; give each of its keys",
            ),
            (
                "[axes]\n\"vineyard.growth_stage\" = [1]\n[variants.x]\n\"vineyard.growth_stage\" = 2",
                "is also an axis",
            ),
            (
                "[variants.x]\n\"sensors.imu.no_such_key\" = 1.0",
                "no_such_key",
            ),
        ] {
            let err = format!("{:#}", sweep(body).expect_err(body));
            assert!(err.contains(says), "{body}: {err}");
        }
    }

    #[test]
    fn points_cross_every_axis_last_fastest() {
        let axes = vec![
            Axis {
                path: "a".into(),
                values: vec![1.into(), 2.into()],
                sets: Vec::new(),
            },
            Axis {
                path: "b".into(),
                values: vec!["x".into(), "y".into(), "z".into()],
                sets: Vec::new(),
            },
        ];
        let p: Vec<String> = points(&axes)
            .iter()
            .map(|p| p.iter().map(value_text).collect::<Vec<_>>().join(","))
            .collect();
        assert_eq!(
            p,
            [
                "1,\"x\"", "1,\"y\"", "1,\"z\"", "2,\"x\"", "2,\"y\"", "2,\"z\""
            ]
        );
        assert_eq!(points(&[]), vec![Vec::<toml::Value>::new()]);
    }
}
