//! A spinning multi-beam lidar (default: Velodyne VLP-16). Every column of beams fires at
//! its own time within the sweep from the pose the robot has at that time, so the robot's
//! motion distorts the scan exactly as on the real sensor; every point carries its ring and
//! its time offset from the scan's stamp, as the ROS driver publishes them.
//!
//! The sweep starts facing backwards (−x) and turns clockwise seen from above, as the
//! VLP-16 does. Range noise is Gaussian with the datasheet's σ; the intensity is the
//! material's near-infrared reflectivity times the cosine of the incidence angle (Lambert),
//! scaled to 0-255.

use nalgebra::{Isometry3, Point3, Vector3};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use super::lidar_footprint::{Footprint, Return, straddles};
use super::{LidarPoint, LidarScan, Message, Scene, Sensor};
use crate::config::{LidarConfig, NoiseProfile};
use crate::raycast::Hit;
use crate::rng::SimRng;

/// Columns cast together as one parallel task.
const COLUMNS_PER_TASK: usize = 64;

#[derive(Debug)]
pub struct LidarSensor {
    cfg: LidarConfig,
    base_from_lidar: Isometry3<f64>,
    /// Unit beam directions in the sensor frame, column-major (`column * rings + ring`).
    directions: Vec<Vector3<f32>>,
    sweep_ns: i64,
    k: u64,
    end_ns: i64,
    rng: SimRng,
}

/// Beam directions of `cfg` in the sensor frame, column-major, with the column azimuths.
pub fn vlp16_directions(cfg: &LidarConfig) -> Vec<Vector3<f32>> {
    let mut dirs = Vec::with_capacity(cfg.columns * cfg.rings);
    for c in 0..cfg.columns {
        let azimuth = std::f64::consts::PI - std::f64::consts::TAU * c as f64 / cfg.columns as f64;
        for r in 0..cfg.rings {
            let f = if cfg.rings == 1 {
                0.5
            } else {
                r as f64 / (cfg.rings - 1) as f64
            };
            let elevation = (cfg.min_elevation_deg
                + f * (cfg.max_elevation_deg - cfg.min_elevation_deg))
                .to_radians();
            dirs.push(Vector3::new(
                (elevation.cos() * azimuth.cos()) as f32,
                (elevation.cos() * azimuth.sin()) as f32,
                elevation.sin() as f32,
            ));
        }
    }
    dirs
}

impl LidarSensor {
    pub fn new(cfg: &LidarConfig, end_ns: i64, rng: SimRng) -> Self {
        Self {
            cfg: cfg.clone(),
            base_from_lidar: cfg.mount.base_from_sensor(),
            directions: vlp16_directions(cfg),
            sweep_ns: (1e9 / cfg.rate_hz).round() as i64,
            k: 0,
            end_ns,
            rng,
        }
    }

    /// The next sweep emitted is the `k`-th (stamp `k` sweep periods). The range noise,
    /// drawn in order from the stream's start, is then not the stream's: for a noise-free
    /// sensor only (`Simulation::lidar_sweep_at`).
    pub(crate) fn start_at(&mut self, k: u64) {
        self.k = k;
    }

    /// The sweep period, ns.
    pub fn sweep_ns(&self) -> i64 {
        self.sweep_ns
    }

    fn stamp(&self, k: u64) -> i64 {
        k as i64 * self.sweep_ns
    }

    /// Time offset of column `c` from the scan's stamp (0 for an instant sweep).
    fn column_offset_ns(&self, c: usize) -> i64 {
        if self.cfg.instant_sweep {
            return 0;
        }
        (self.sweep_ns as f64 * c as f64 / self.cfg.columns as f64).round() as i64
    }

    /// `world_from_lidar` at each column's firing time of the sweep starting at `stamp_ns`.
    pub fn column_poses(&self, scene: &Scene<'_>, stamp_ns: i64) -> Vec<Isometry3<f64>> {
        (0..self.cfg.columns)
            .into_par_iter()
            .map(|c| {
                scene.trajectory.pose(stamp_ns + self.column_offset_ns(c)) * self.base_from_lidar
            })
            .collect()
    }

    /// Casts every beam of the sweep from its column's pose: `hits[c * rings + r]`, with the
    /// cosine of the angle between the beam and the surface hit.
    pub fn cast_sweep(
        &self,
        scene: &Scene<'_>,
        poses: &[Isometry3<f64>],
    ) -> Vec<Option<(Hit, f32)>> {
        let rings = self.cfg.rings;
        let (t_min, t_max) = (self.cfg.min_range_m as f32, self.cfg.max_range_m as f32);
        let mesh = &scene.world.mesh;
        let mut hits = vec![None; self.directions.len()];
        hits.par_chunks_mut(COLUMNS_PER_TASK * rings)
            .enumerate()
            .for_each(|(task, out)| {
                let mut world_dirs = vec![Vector3::zeros(); rings];
                let mut column_hits = vec![None; rings];
                for (j, column_out) in out.chunks_mut(rings).enumerate() {
                    let c = task * COLUMNS_PER_TASK + j;
                    let world_from_lidar = &poses[c];
                    let origin: Point3<f32> =
                        Point3::from(world_from_lidar.translation.vector.cast());
                    let rot = world_from_lidar
                        .rotation
                        .to_rotation_matrix()
                        .into_inner()
                        .cast::<f32>();
                    let beams = &self.directions[c * rings..(c + 1) * rings];
                    for (w, d) in world_dirs.iter_mut().zip(beams) {
                        *w = rot * d;
                    }
                    scene
                        .caster
                        .cast_fan(&origin, &world_dirs, t_min, t_max, &mut column_hits);
                    // The incidence of each hit (for its intensity), here where it runs in
                    // parallel rather than with the noise, which must be drawn in order.
                    for ((slot, hit), d) in column_out.iter_mut().zip(&column_hits).zip(beams) {
                        *slot = hit.map(|h| {
                            let world_dir =
                                (world_from_lidar.rotation * d.cast::<f64>()).cast::<f32>();
                            (h, mesh.normal(h.triangle as usize).dot(&world_dir).abs())
                        });
                    }
                }
            });
        hits
    }
}

impl LidarSensor {
    /// What each beam of the sweep returns: its central ray's hit, or with a beam divergence
    /// (`beam_divergence_mrad`), for a beam next to a range discontinuity, what its
    /// footprint gives ([`super::lidar_footprint`]).
    fn returns(
        &self,
        scene: &Scene<'_>,
        poses: &[Isometry3<f64>],
        hits: &[Option<(Hit, f32)>],
    ) -> Vec<Option<Return>> {
        let mesh = &scene.world.mesh;
        let mut returns: Vec<Option<Return>> = hits
            .iter()
            .map(|hit| {
                hit.map(|(h, cos_incidence)| Return {
                    range_m: h.t,
                    intensity: 255.0
                        * mesh.materials[h.triangle as usize].nir_reflectivity()
                        * cos_incidence,
                })
            })
            .collect();
        let [dh, dv] = self.cfg.beam_divergence_mrad;
        if dh <= 0.0 && dv <= 0.0 {
            return returns;
        }
        let footprint = Footprint {
            divergence_rad: [dh, dv].map(|a| (a * 1e-3) as f32),
            echo_separation_m: self.cfg.echo_separation_m as f32,
            mode: self.cfg.return_mode,
        };
        let (rings, columns) = (self.cfg.rings, self.cfg.columns);
        let (t_min, t_max) = (self.cfg.min_range_m as f32, self.cfg.max_range_m as f32);
        let range = |i: usize| hits[i].map(|(h, _)| h.t);
        returns
            .par_chunks_mut(rings)
            .enumerate()
            .for_each(|(c, column)| {
                let (left, right) = ((c + columns - 1) % columns, (c + 1) % columns);
                let world_from_lidar = &poses[c];
                let origin: Point3<f32> = Point3::from(world_from_lidar.translation.vector.cast());
                for (r, slot) in column.iter_mut().enumerate() {
                    let i = c * rings + r;
                    if !(straddles(range(i), range(left * rings + r))
                        || straddles(range(i), range(right * rings + r)))
                    {
                        continue;
                    }
                    let dir = (world_from_lidar.rotation * self.directions[i].cast::<f64>())
                        .cast::<f32>();
                    let centre = hits[i].map(|(h, _)| h);
                    *slot = footprint.beam_return(
                        scene.caster,
                        mesh,
                        &origin,
                        &dir,
                        centre,
                        t_min,
                        t_max,
                    );
                }
            });
        returns
    }
}

impl Sensor for LidarSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let end = self.stamp(self.k) + self.sweep_ns;
        (end <= self.end_ns).then_some(end)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = self.stamp(self.k);
        self.k += 1;
        let poses = self.column_poses(scene, stamp_ns);
        let hits = self.cast_sweep(scene, &poses);
        let returns = self.returns(scene, &poses, &hits);
        let rings = self.cfg.rings;
        let noise = Normal::new(0.0, self.cfg.range_sigma_m).expect("range sigma is finite");
        let noisy = self.cfg.noise == NoiseProfile::Typical;
        let mut points = Vec::with_capacity(returns.len());
        for (i, ret) in returns.iter().enumerate() {
            let Some(ret) = ret else {
                continue;
            };
            let (c, ring) = (i / rings, i % rings);
            let dir = self.directions[i];
            let range = if noisy {
                ret.range_m + noise.sample(&mut self.rng) as f32
            } else {
                ret.range_m
            };
            if !(self.cfg.min_range_m as f32..=self.cfg.max_range_m as f32).contains(&range) {
                continue;
            }
            let p = dir * range;
            points.push(LidarPoint {
                x: p.x,
                y: p.y,
                z: p.z,
                intensity: ret.intensity,
                time_s: self.column_offset_ns(c) as f32 * 1e-9,
                ring: ring as u16,
            });
        }
        Message::Lidar(LidarScan {
            stamp_ns,
            sweep_ns: self.sweep_ns,
            points,
        })
    }
}
