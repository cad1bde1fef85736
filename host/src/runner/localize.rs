//! Localisation runs (issue 46): a plugin started from a map built earlier, on another
//! route, at another growth stage, answering every message with a pose in that map and its
//! belief (localised or searching), optionally kidnapped on the way.
//!
//! The worker reads the map ([`MapSource`]), starts the plugin with
//! `plugin_api::LoadedPlugin::create_localizing`, writes each online pose's status beside
//! `online.tum` (`pose_status.csv`) and this order (`localization.toml`), and the evaluation
//! ([`evaluate_localization`]) judges the run with `eval::evaluate_localization`, in the
//! mapping run's frame carried over by its own alignment.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plugin_api::{
    GRID_MAP_FORMAT, GRID_MAP_VERSION, InitialGuess, OccupancyGrid, Pose, PoseStatus,
};
use serde::{Deserialize, Serialize};
use sim::sensors::Message;

use crate::results::{RunFolder, files, map_file};

/// The surveyed grid's cell, metres: map_server's and gmapping's common 5 cm.
pub const SURVEY_RESOLUTION_M: f64 = 0.05;

/// Which map a localisation run starts from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum MapSource {
    /// A plugin's own `map.bin` (its mapping run's folder holds it).
    Saved { path: PathBuf },
    /// An occupancy grid as map_server gives one (`grid.yaml` of a mapping run), handed to
    /// the plugin as [`GRID_MAP_FORMAT`].
    Grid { yaml: PathBuf },
    /// The world's surveyed grid at the front 2D lidar's height ([`surveyed_grid`]), in the
    /// world frame: of the world file `world` (the block as it was when surveyed, e.g. at
    /// another growth stage), else of the localisation run's own world.
    Surveyed {
        #[serde(default)]
        world: Option<PathBuf>,
    },
}

impl MapSource {
    /// The map of a mapping run's folder (`None`: the world's surveyed grid, of
    /// `survey_world` where given): its occupancy grid with `grid`, else its `map.bin`.
    pub fn of(mapping_run: Option<&Path>, grid: bool, survey_world: Option<PathBuf>) -> Self {
        match (mapping_run, grid) {
            (None, _) => MapSource::Surveyed {
                world: survey_world,
            },
            (Some(dir), true) => MapSource::Grid {
                yaml: dir.join(files::GRID_YAML),
            },
            (Some(dir), false) => MapSource::Saved {
                path: dir.join(files::SAVED_MAP),
            },
        }
    }
}

/// A guess of the start in the map frame, with its uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuessSpec {
    pub x: f64,
    pub y: f64,
    pub yaw: f64,
    pub sigma_xy_m: f64,
    pub sigma_yaw_rad: f64,
}

/// The robot carried elsewhere on its route without the plugin being told: at `at_s` the
/// stream jumps `skip_s` ahead along the route (the messages between are never sent, the
/// later ones come `skip_s` earlier), so the true pose jumps; the wheel odometry does not
/// (the wheels did not turn while the robot was carried: the kidnapped robot problem of
/// Thrun, Burgard & Fox, *Probabilistic Robotics*, §7.1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Kidnap {
    pub at_s: f64,
    pub skip_s: f64,
}

/// A localisation run's order (`localization.toml` in its folder, which also holds the
/// map's size, `map_bytes`, and the plugin's start time from it, `load_s`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalizeSpec {
    pub map: MapSource,
    /// The mapping run's folder, whose alignment (`metrics.json`) puts the map in the world
    /// and whose estimate judges poses against the map. `None` (the surveyed grid): the
    /// map's frame is the world's.
    #[serde(default)]
    pub mapping_run: Option<PathBuf>,
    #[serde(default)]
    pub initial_guess: Option<GuessSpec>,
    #[serde(default)]
    pub kidnap: Option<Kidnap>,
}

impl LocalizeSpec {
    /// The checks a user's order needs before anything runs; the reason when it fails.
    pub fn check(&self) -> Result<(), String> {
        if let Some(g) = &self.initial_guess {
            let finite = [g.x, g.y, g.yaw].iter().all(|v| v.is_finite());
            let spread = g.sigma_xy_m > 0.0 && g.sigma_yaw_rad > 0.0;
            if !finite || !spread {
                return Err(
                    "initial guess: x, y, yaw finite and both standard deviations positive".into(),
                );
            }
        }
        if let Some(k) = &self.kidnap
            && !(k.at_s >= 0.0 && k.skip_s > 0.0 && (k.at_s + k.skip_s).is_finite())
        {
            return Err("kidnap: at_s >= 0 and skip_s > 0".into());
        }
        Ok(())
    }

    /// The plugin's initial guess, if any.
    pub fn initial_guess(&self) -> Option<InitialGuess> {
        self.initial_guess.map(|g| InitialGuess {
            map_from_base: Pose::new(
                0,
                &nalgebra::Isometry3::new(
                    nalgebra::Vector3::new(g.x, g.y, 0.0),
                    nalgebra::Vector3::new(0.0, 0.0, g.yaw),
                ),
            ),
            sigma_xy_m: g.sigma_xy_m,
            sigma_yaw_rad: g.sigma_yaw_rad,
        })
    }
}

/// The map's bytes, format and version for `plugin` (one line naming the file and the
/// plugin when they cannot be had).
pub fn map_bytes(
    spec: &LocalizeSpec,
    plugin: &str,
    config: &sim::SimConfig,
    world: &sim::world::World,
) -> anyhow::Result<(Vec<u8>, String, u32)> {
    match &spec.map {
        MapSource::Saved { path } => {
            let (head, bytes) = map_file::read_map(path, Some(plugin))
                .map_err(|e| anyhow::anyhow!("{}", map_file::with_plugin(e, plugin)))?;
            Ok((bytes, head.format, head.format_version))
        }
        MapSource::Grid { yaml } => {
            let grid = crate::results::read_grid(yaml)
                .with_context(|| format!("plugin {plugin}'s map"))?;
            Ok((
                grid.to_map_bytes(),
                GRID_MAP_FORMAT.into(),
                GRID_MAP_VERSION,
            ))
        }
        MapSource::Surveyed { world: None } => Ok((
            surveyed_grid(config, world).to_map_bytes(),
            GRID_MAP_FORMAT.into(),
            GRID_MAP_VERSION,
        )),
        MapSource::Surveyed { world: Some(file) } => {
            let surveyed = sim::SimConfig::load(Some(file))?;
            let built = sim::world::World::from_config(&surveyed);
            Ok((
                surveyed_grid(&surveyed, &built).to_map_bytes(),
                GRID_MAP_FORMAT.into(),
                GRID_MAP_VERSION,
            ))
        }
    }
}

/// The world's surveyed grid as the plugin API's occupancy grid, drawn at the front 2D
/// lidar's scan height above the ground (its mount's z in the base frame, whose origin the
/// simulator keeps on the ground: 0.35 m on our Thorvald), as a lab draws a robot's map at
/// its scanners' height.
pub fn surveyed_grid(config: &sim::SimConfig, world: &sim::world::World) -> OccupancyGrid {
    let height = config
        .sensors
        .scan2d_front
        .mount_for(sim::config::Side::Front)
        .xyz_m[2];
    let g = world.surveyed_grid(height, SURVEY_RESOLUTION_M);
    OccupancyGrid {
        resolution_m: g.resolution_m,
        origin: [g.origin[0], g.origin[1], 0.0],
        width: g.width as u32,
        height: g.height as u32,
        cells: g.cells,
    }
}

/// The stream with the kidnapping applied: messages stamped in `(at, at + skip]` dropped,
/// later ones moved `skip` earlier; the wheel odometry after it continues from where it was
/// at `at` (`odom_from_base` moved by the odometry's own motion since the window's last
/// message), since the wheels did not turn while the robot was carried: the true pose jumps,
/// the odometry does not.
pub fn kidnapped(
    source: impl Iterator<Item = Message>,
    kidnap: Option<Kidnap>,
) -> impl Iterator<Item = Message> {
    let window = kidnap.map(|k| {
        let at = (k.at_s * 1e9).round() as i64;
        (at, at + (k.skip_s * 1e9).round() as i64)
    });
    // The odometry at `at` and at the window's end.
    let mut odom_at: Option<nalgebra::Isometry3<f64>> = None;
    let mut odom_end: Option<nalgebra::Isometry3<f64>> = None;
    source.filter_map(move |mut m| {
        let Some((at, end)) = window else {
            return Some(m);
        };
        let t = m.stamp_ns();
        if t <= at {
            if let Message::WheelOdometry(o) = &m {
                odom_at = Some(o.odom_from_base);
            }
            return Some(m);
        }
        if t <= end {
            if let Message::WheelOdometry(o) = &m {
                odom_end = Some(o.odom_from_base);
            }
            return None;
        }
        m.shift_stamp(at - end);
        if let (Message::WheelOdometry(o), Some(before), Some(after)) = (&mut m, odom_at, odom_end)
        {
            o.odom_from_base = before * after.inverse() * o.odom_from_base;
        }
        Some(m)
    })
}

/// `pose_status.csv`: one `stamp_ns,status` row per online pose.
pub fn write_statuses(dir: &Path, stamps: &[i64], statuses: &[PoseStatus]) -> anyhow::Result<()> {
    let mut text = String::from("stamp_ns,status\n");
    for (stamp, status) in stamps.iter().zip(statuses) {
        text.push_str(&format!("{stamp},{}\n", status.name()));
    }
    let path = dir.join(files::POSE_STATUS);
    std::fs::write(&path, text).with_context(|| path.display().to_string())
}

/// The statuses of `pose_status.csv`, in order.
pub fn read_statuses(path: &Path) -> anyhow::Result<Vec<(i64, PoseStatus)>> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    text.lines()
        .skip(1)
        .enumerate()
        .map(|(i, line)| {
            let bad = || anyhow::anyhow!("{}: line {}: {line:?}", path.display(), i + 2);
            let (stamp, status) = line.split_once(',').ok_or_else(bad)?;
            Ok((
                stamp.parse().map_err(|_| bad())?,
                PoseStatus::from_name(status).map_err(|_| bad())?,
            ))
        })
        .collect()
}

/// A run folder's `localization.toml`, if it is a localisation run: the order, the map's
/// size (bytes) and the plugin's start time from it (s).
pub fn read_spec(run: &RunFolder) -> anyhow::Result<Option<(LocalizeSpec, u64, f64)>> {
    if !run.has(files::LOCALIZATION) {
        return Ok(None);
    }
    #[derive(Deserialize)]
    struct Record {
        #[serde(flatten)]
        spec: LocalizeSpec,
        map_bytes: u64,
        load_s: f64,
    }
    let path = run.path(files::LOCALIZATION);
    let text = std::fs::read_to_string(&path).with_context(|| path.display().to_string())?;
    let r: Record = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.message().trim()))?;
    Ok(Some((r.spec, r.map_bytes, r.load_s)))
}

/// The block's lanes of a vineyard: its rows as lines in the ground plane (the grid's rows
/// along x, or the paper's world's segments grouped by their offset across).
pub fn lanes(v: &sim::config::VineyardConfig) -> Option<eval::Lanes> {
    if v.segments.is_empty() {
        if v.rows < 2 {
            return None;
        }
        // Rows along +x at y = k * spacing; across is (along.y, -along.x) = -y.
        let mut rows: Vec<f64> = (0..v.rows).map(|k| -(k as f64) * v.row_spacing_m).collect();
        rows.sort_by(f64::total_cmp);
        return Some(eval::Lanes {
            along: [1.0, 0.0],
            rows,
            extent: [0.0, v.row_length_m],
        });
    }
    let yaw = v.segments[0][2].to_radians();
    let along = [yaw.cos(), yaw.sin()];
    let across = [along[1], -along[0]];
    let mut offsets: Vec<f64> = v
        .segments
        .iter()
        .map(|s| s[0] * across[0] + s[1] * across[1])
        .collect();
    offsets.sort_by(f64::total_cmp);
    // Segments of one row share its offset (within a tenth of the spacing).
    let mut rows: Vec<f64> = Vec::new();
    for o in offsets {
        match rows.last() {
            Some(&last) if o - last < 0.1 * v.row_spacing_m.max(0.5) => {}
            _ => rows.push(o),
        }
    }
    let half = 0.5 * v.segment_length_m;
    let (lo, hi) = v
        .segments
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            let c = s[0] * along[0] + s[1] * along[1];
            (lo.min(c - half), hi.max(c + half))
        });
    (rows.len() >= 2).then_some(eval::Lanes {
        along,
        rows,
        extent: [lo, hi],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};
    use sim::sensors::{GroundTruth, WheelOdometry};

    /// A robot driving along x at 1 m/s, odometry and truth every 0.1 s for 10 s.
    fn drive() -> Vec<Message> {
        (0..=100)
            .flat_map(|k| {
                let stamp_ns = k * 100_000_000;
                let pose = Isometry3::translation(0.1 * k as f64, 0.0, 0.0);
                [
                    Message::GroundTruth(GroundTruth {
                        stamp_ns,
                        world_from_base: pose,
                        velocity_in_world: Vector3::x(),
                        omega_in_base: Vector3::zeros(),
                    }),
                    Message::WheelOdometry(WheelOdometry {
                        stamp_ns,
                        linear_mps: 1.0,
                        angular_rps: 0.0,
                        odom_from_base: pose,
                    }),
                ]
            })
            .collect()
    }

    /// Kidnapped at 3 s for 4 s: nothing stamped in (3, 7] s is sent, later messages come
    /// 4 s earlier, the truth jumps 4 m and the odometry goes on from its 3 s reading.
    #[test]
    fn a_kidnapping_moves_the_truth_and_not_the_odometry() {
        let out: Vec<Message> = kidnapped(
            drive().into_iter(),
            Some(Kidnap {
                at_s: 3.0,
                skip_s: 4.0,
            }),
        )
        .collect();
        assert_eq!(out.len(), 2 * (101 - 40));
        let stamps: Vec<i64> = out.iter().map(Message::stamp_ns).collect();
        assert!(stamps.windows(2).all(|w| w[1] - w[0] <= 100_000_000));
        let at = |t_ns: i64, truth: bool| -> f64 {
            out.iter()
                .find_map(|m| match m {
                    Message::GroundTruth(g) if truth && g.stamp_ns == t_ns => {
                        Some(g.world_from_base.translation.x)
                    }
                    Message::WheelOdometry(o) if !truth && o.stamp_ns == t_ns => {
                        Some(o.odom_from_base.translation.x)
                    }
                    _ => None,
                })
                .expect("a message at that stamp")
        };
        assert!((at(3_000_000_000, true) - 3.0).abs() < 1e-9);
        assert!(
            (at(3_100_000_000, true) - 7.1).abs() < 1e-9,
            "the truth jumps"
        );
        assert!(
            (at(3_100_000_000, false) - 3.1).abs() < 1e-9,
            "the odometry does not"
        );
        assert!((at(6_000_000_000, false) - 6.0).abs() < 1e-9);
        let untouched: Vec<Message> = kidnapped(drive().into_iter(), None).collect();
        assert_eq!(untouched, drive());
    }
}
