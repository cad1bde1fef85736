//! A planar scanning lidar (the paper's front and back 2D lidars). Each sample fires at its
//! own time as the mirror turns (`time_increment`), from the robot's pose at that time.
//! Output follows ROS `sensor_msgs/LaserScan`: no return within range is `+inf` (REP 117).

use nalgebra::{Isometry3, Point3, Vector3};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use super::{LaserScan, Message, ScanSide, Scene, Sensor, sample_time_ns};
use crate::config::{NoiseProfile, Scan2dConfig};
use crate::raycast::Hit;
use crate::rng::SimRng;

/// Samples cast together as one parallel task.
const SAMPLES_PER_TASK: usize = 90;

#[derive(Debug)]
pub struct Scan2dSensor {
    cfg: Scan2dConfig,
    side: ScanSide,
    base_from_scanner: Isometry3<f64>,
    angle_increment: f64,
    time_increment_s: f64,
    k: u64,
    end_ns: i64,
    rng: SimRng,
}

impl Scan2dSensor {
    pub fn new(cfg: &Scan2dConfig, side: ScanSide, end_ns: i64, rng: SimRng) -> Self {
        let angle_increment = (cfg.angle_max_rad - cfg.angle_min_rad) / (cfg.samples - 1) as f64;
        let config_side = match side {
            ScanSide::Front => crate::config::Side::Front,
            ScanSide::Back => crate::config::Side::Back,
        };
        Self {
            cfg: cfg.clone(),
            side,
            base_from_scanner: cfg.mount_for(config_side).base_from_sensor(),
            angle_increment,
            // The mirror turns once per scan period.
            time_increment_s: angle_increment / std::f64::consts::TAU / cfg.rate_hz,
            k: 0,
            end_ns,
            rng,
        }
    }

    /// Origin and unit direction (world frame) of sample `i` of the sweep stamped `stamp_ns`.
    fn ray(&self, scene: &Scene<'_>, stamp_ns: i64, i: usize) -> (Point3<f32>, Vector3<f32>) {
        let t = stamp_ns + (i as f64 * self.time_increment_s * 1e9).round() as i64;
        let world_from_scanner = scene.trajectory.pose(t) * self.base_from_scanner;
        let angle = self.cfg.angle_min_rad + i as f64 * self.angle_increment;
        let dir = world_from_scanner.rotation * Vector3::new(angle.cos(), angle.sin(), 0.0);
        (
            Point3::from(world_from_scanner.translation.vector.cast()),
            dir.cast(),
        )
    }

    fn sweep_ns(&self) -> i64 {
        (self.time_increment_s * (self.cfg.samples - 1) as f64 * 1e9).round() as i64
    }
}

impl Sensor for Scan2dSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let end = sample_time_ns(self.k, self.cfg.rate_hz) + self.sweep_ns();
        (end <= self.end_ns).then_some(end)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = sample_time_ns(self.k, self.cfg.rate_hz);
        self.k += 1;
        let noise = Normal::new(0.0, self.cfg.range_sigma_m).expect("range sigma is finite");
        let noisy = self.cfg.noise == NoiseProfile::Typical;
        let (t_min, t_max) = (self.cfg.min_range_m as f32, self.cfg.max_range_m as f32);
        let mesh = &scene.world.mesh;
        // Cast in parallel chunks of consecutive samples, each from its own pose; keep the
        // hit with its incidence cosine. Noise is added afterwards in sample order.
        let mut hits: Vec<Option<(Hit, f32)>> = vec![None; self.cfg.samples];
        hits.par_chunks_mut(SAMPLES_PER_TASK)
            .enumerate()
            .for_each(|(task, out)| {
                for (j, slot) in out.iter_mut().enumerate() {
                    let (origin, dir) = self.ray(scene, stamp_ns, task * SAMPLES_PER_TASK + j);
                    let hit = scene.caster.cast(&origin, &dir, t_min, t_max);
                    *slot = hit.map(|h| (h, mesh.normal(h.triangle as usize).dot(&dir).abs()));
                }
            });
        let mut ranges = Vec::with_capacity(self.cfg.samples);
        let mut intensities = Vec::with_capacity(self.cfg.samples);
        for hit in hits {
            let (range, intensity) = match hit {
                Some((h, cos)) => {
                    let r = if noisy {
                        h.t + noise.sample(&mut self.rng) as f32
                    } else {
                        h.t
                    };
                    if (t_min..=t_max).contains(&r) {
                        let material = mesh.materials[h.triangle as usize];
                        (r, 255.0 * material.nir_reflectivity() * cos)
                    } else {
                        (f32::INFINITY, 0.0)
                    }
                }
                None => (f32::INFINITY, 0.0),
            };
            ranges.push(range);
            intensities.push(intensity);
        }
        Message::Scan2d(LaserScan {
            stamp_ns,
            side: self.side,
            angle_min_rad: self.cfg.angle_min_rad as f32,
            angle_increment_rad: self.angle_increment as f32,
            time_increment_s: self.time_increment_s as f32,
            range_min_m: t_min,
            range_max_m: t_max,
            ranges_m: ranges,
            intensities,
        })
    }
}
