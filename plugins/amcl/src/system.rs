//! The `amcl` plugin: the filter of this crate behind the plugin contract, localising in an
//! occupancy grid the host hands over (`vinebench localize --grid` with a mapping run's
//! `grid.yaml`, or `--surveyed` with the world's surveyed grid).
//!
//! As a Thorvald's navigation runs AMCL: the two 2D lidars merged into one scan about the
//! base ([`crate::scan`]), the wheel odometry as the motion model's input, a filter update
//! when the robot has moved `update_min_d` or turned `update_min_a`. Between updates the
//! pose is the last estimate moved by the odometry since (AMCL's `map -> odom` transform),
//! returned at every odometry message with the filter's status: localised when the
//! particles' spread is within AMCL's `std_warn_level_*` (its own diagnostic of a
//! converged filter), searching otherwise. AMCL builds no map: it only localises (`vinebench
//! run --plugin amcl` is refused with a line saying so).
//!
//! Parameters: AMCL's under their ROS names ([`AmclConfig`]), e.g. `max_particles = 5000`,
//! `seed = 0`.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use plugin_api::{
    GRID_MAP_FORMAT, GRID_MAP_VERSION, LaserScan, MapStart, OccupancyGrid, Parameters, PluginError,
    Pose, PoseStatus, Requirements, Rig, SensorKind, SlamOutput, SlamSystem, WheelOdometry,
};

use crate::Pose2;
use crate::config::AmclConfig;
use crate::filter::ParticleFilter;
use crate::grid::{Grid, LikelihoodField};
use crate::scan::{Scan, VirtualScan};

impl Parameters for AmclConfig {
    fn check(&self) -> Result<(), String> {
        self.validate()
    }
}

/// A scan kept until its partner from the other scanner arrives.
#[derive(Debug, Clone)]
struct Held {
    stamp_ns: i64,
    angle_min: f64,
    angle_increment: f64,
    range_min: f64,
    range_max: f64,
    ranges: Vec<f32>,
}

/// AMCL localising in a grid.
#[derive(Debug)]
pub struct Amcl {
    field: LikelihoodField,
    filter: ParticleFilter,
    /// The two scanners' names and mounts (`base_from_sensor` in the plane).
    scanners: Vec<(String, Pose2)>,
    /// The latest scan of each scanner not yet used.
    held: Vec<Option<Held>>,
    /// The latest wheel odometry, `odom_from_base` in the plane.
    odom: Option<Pose2>,
    trajectory: Vec<Pose>,
    updates: usize,
}

/// A 3D pose's planar part: x, y and yaw.
fn planar(iso: &Isometry3<f64>) -> Pose2 {
    let (_, _, yaw) = iso.rotation.euler_angles();
    Pose2::new(iso.translation.vector.x, iso.translation.vector.y, yaw)
}

fn pose3(stamp_ns: i64, p: &Pose2) -> Pose {
    Pose::new(
        stamp_ns,
        &Isometry3::from_parts(
            Translation3::new(p.x, p.y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, p.theta),
        ),
    )
}

/// The grid of a [`GRID_MAP_FORMAT`] map, as the filter's.
fn grid_of(start: &MapStart<'_>) -> Result<Grid, PluginError> {
    if start.format != GRID_MAP_FORMAT || start.format_version != GRID_MAP_VERSION {
        return Err(PluginError(format!(
            "amcl localises in an occupancy grid ({GRID_MAP_FORMAT} version {GRID_MAP_VERSION}), not in a {} version {} map; give the mapping run's grid (vinebench localize --grid) or the surveyed one (--surveyed)",
            start.format, start.format_version
        )));
    }
    let g = OccupancyGrid::from_map_bytes(start.map)?;
    if g.origin[2] != 0.0 {
        return Err(PluginError(
            "amcl reads grids whose origin has no rotation (map_server ignores it too)".into(),
        ));
    }
    Grid::new(
        g.resolution_m,
        [g.origin[0], g.origin[1]],
        g.width as usize,
        g.height as usize,
        g.cells,
    )
    .map_err(PluginError)
}

impl Amcl {
    /// Merges the held scans into one and updates the filter at the latest odometry.
    fn update(&mut self) {
        let Some(odom) = self.odom else { return };
        let scans: Vec<Scan<'_>> = self
            .held
            .iter()
            .zip(&self.scanners)
            .filter_map(|(h, (_, mount))| {
                h.as_ref().map(|h| Scan {
                    base_from_sensor: *mount,
                    angle_min: h.angle_min,
                    angle_increment: h.angle_increment,
                    range_min: h.range_min,
                    range_max: h.range_max,
                    ranges: &h.ranges,
                })
            })
            .collect();
        let Some(finest) = scans
            .iter()
            .map(|s| s.angle_increment.abs())
            .filter(|a| *a > 0.0)
            .min_by(f64::total_cmp)
        else {
            return;
        };
        let range_max = scans.iter().map(|s| s.range_max).fold(0.0, f64::max);
        let range_min = scans
            .iter()
            .map(|s| s.range_min)
            .fold(f64::INFINITY, f64::min);
        let merged = VirtualScan::full_turn(
            (std::f64::consts::TAU / finest).round().max(8.0) as usize,
            range_min,
            range_max,
        );
        let ranges = merged.merge(&scans);
        let beams = merged.end_points(&ranges);
        if self.filter.update(&odom, &beams, range_max, &self.field) {
            self.updates += 1;
        }
        self.held.iter_mut().for_each(|h| *h = None);
    }
}

impl SlamSystem for Amcl {
    const NAME: &'static str = "amcl";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::WheelOdometry, SensorKind::Scan2d]).localizing()
    }

    fn new(_config_toml: &str, _rig: &Rig) -> Result<Self, PluginError> {
        Err(PluginError(
            "amcl builds no map, it only localises in one: run it with vinebench localize (--grid with a mapping run's grid, or --surveyed)".into(),
        ))
    }

    fn localize(config_toml: &str, rig: &Rig, start: &MapStart<'_>) -> Result<Self, PluginError> {
        let cfg = AmclConfig::from_toml(config_toml).map_err(PluginError)?;
        let field = LikelihoodField::new(grid_of(start)?, cfg.laser_likelihood_max_dist);
        let filter = match start.initial_guess {
            None => ParticleFilter::global(cfg.clone(), &field),
            Some(guess) => {
                let mean =
                    planar(&guess.map_from_base.isometry().ok_or_else(|| {
                        PluginError("the initial guess is not a valid pose".into())
                    })?);
                let guessed = AmclConfig {
                    initial_cov_xx: guess.sigma_xy_m.powi(2),
                    initial_cov_yy: guess.sigma_xy_m.powi(2),
                    initial_cov_aa: guess.sigma_yaw_rad.powi(2),
                    ..cfg.clone()
                };
                ParticleFilter::at(guessed, mean)
            }
        }
        .map_err(PluginError)?;
        let scanners: Vec<(String, Pose2)> = rig
            .sensors
            .iter()
            .filter(|s| s.kind == SensorKind::Scan2d)
            .map(|s| (s.name.clone(), planar(&s.base_from_sensor())))
            .collect();
        if scanners.is_empty() {
            return Err(PluginError("amcl needs a 2D lidar in the rig".into()));
        }
        Ok(Self {
            field,
            filter,
            held: vec![None; scanners.len()],
            scanners,
            odom: None,
            trajectory: Vec::new(),
            updates: 0,
        })
    }

    fn status(&self) -> PoseStatus {
        if self.updates > 0 && self.filter.estimate().localized {
            PoseStatus::Localized
        } else {
            PoseStatus::Searching
        }
    }

    fn on_wheel_odometry(&mut self, m: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        let iso = m
            .odom_from_base
            .isometry()
            .ok_or_else(|| PluginError("wheel odometry pose is not finite".into()))?;
        let odom = planar(&iso);
        self.odom = Some(odom);
        let pose = pose3(m.stamp_ns, &self.filter.pose_now(&odom));
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn on_laser_scan(&mut self, s: &LaserScan<'_>) -> Result<Option<Pose>, PluginError> {
        let Some(k) = self.scanners.iter().position(|(n, _)| n == s.sensor) else {
            return Ok(None);
        };
        self.held[k] = Some(Held {
            stamp_ns: s.stamp_ns,
            angle_min: f64::from(s.angle_min_rad),
            angle_increment: f64::from(s.angle_increment_rad),
            range_min: f64::from(s.range_min_m),
            range_max: f64::from(s.range_max_m),
            ranges: s.ranges_m.to_vec(),
        });
        // Merge when every scanner has a scan within a tenth of a second of this one (the
        // merger's time window), the others' older ones dropped.
        let fresh = |h: &Option<Held>| {
            h.as_ref()
                .is_some_and(|h| (s.stamp_ns - h.stamp_ns).abs() <= 100_000_000)
        };
        if self.held.iter().all(fresh) {
            self.update();
        }
        Ok(None)
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        Ok(SlamOutput {
            trajectory: std::mem::take(&mut self.trajectory),
            ..SlamOutput::default()
        })
    }
}

plugin_api::export_plugin!(Amcl);
