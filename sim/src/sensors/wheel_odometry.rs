//! Wheel odometry of a skid-steered base: encoder speed and yaw rate with a constant scale
//! error and a slip that wanders slowly (a first-order Gauss–Markov process with a one-second
//! correlation time) and grows with the slope under the robot; the pose is integrated in
//! the plane from the measured rates, as the robot's own odometry node does. Riding over
//! bumps, the wheels' path is longer than its projection, so even noise-free odometry
//! over-estimates distance on uneven ground, as on a real machine.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand_distr::{Distribution, StandardNormal};

use super::{Message, Scene, Sensor, WheelOdometry, sample_time_ns};
use crate::config::{NoiseProfile, WheelOdometryConfig};
use crate::rng::SimRng;
use crate::robot::rotation;

/// Integration sub-steps per message, so that the pose follows the continuous motion.
const SUBSTEPS: usize = 10;
/// Correlation time of the slip process.
const SLIP_TAU_S: f64 = 1.0;

#[derive(Debug)]
pub struct WheelOdometrySensor {
    cfg: WheelOdometryConfig,
    k: u64,
    end_ns: i64,
    rng: SimRng,
    slip: f64,
    x: f64,
    y: f64,
    yaw: f64,
}

impl WheelOdometrySensor {
    pub fn new(cfg: &WheelOdometryConfig, end_ns: i64, rng: SimRng) -> Self {
        Self {
            cfg: cfg.clone(),
            k: 0,
            end_ns,
            rng,
            slip: 0.0,
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
        }
    }

    fn normal(&mut self) -> f64 {
        StandardNormal.sample(&mut self.rng)
    }
}

/// True forward speed (along the base's x axis) and yaw rate (about its z axis) at `t_ns`,
/// as the wheels roll: the spline's, without the body's vibration on its tyres.
fn true_rates(scene: &Scene<'_>, t_ns: i64) -> (f64, f64) {
    let s = scene.trajectory.nominal_state(t_ns);
    let forward = rotation(&s.world_from_base) * Vector3::x();
    (s.velocity.dot(&forward), s.omega_in_base.z)
}

impl Sensor for WheelOdometrySensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let t = sample_time_ns(self.k, self.cfg.rate_hz);
        (t <= self.end_ns).then_some(t)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = sample_time_ns(self.k, self.cfg.rate_hz);
        let prev_ns = if self.k == 0 {
            stamp_ns
        } else {
            sample_time_ns(self.k - 1, self.cfg.rate_hz)
        };
        self.k += 1;
        let noisy = self.cfg.noise == NoiseProfile::Typical;
        let (speed_gain, yaw_gain, yaw_noise) = if noisy {
            let pose = scene.trajectory.nominal_pose(stamp_ns);
            let slope = scene
                .world
                .terrain
                .gradient(pose.translation.x, pose.translation.y)
                .norm();
            let roughness = 1.0 + self.cfg.slip_per_slope * slope / self.cfg.slip_sigma.max(1e-9);
            let dt = 1.0 / self.cfg.rate_hz;
            let decay = (-dt / SLIP_TAU_S).exp();
            let n = self.normal();
            self.slip = decay * self.slip
                + (1.0 - decay * decay).sqrt() * self.cfg.slip_sigma * roughness * n;
            let yaw_sigma = self.cfg.yaw_rate_noise_density * self.cfg.rate_hz.sqrt() * roughness;
            let m = self.normal();
            (
                (1.0 + self.cfg.scale_error) * (1.0 - self.slip),
                1.0 + self.cfg.yaw_scale_error,
                yaw_sigma * m,
            )
        } else {
            (1.0, 1.0, 0.0)
        };
        // Integrate the measured rates over the interval (midpoint rule on sub-steps).
        let span = stamp_ns - prev_ns;
        for i in 0..SUBSTEPS {
            let t_mid = prev_ns + (span as f64 * (i as f64 + 0.5) / SUBSTEPS as f64).round() as i64;
            let (v, w) = true_rates(scene, t_mid);
            let h = span as f64 * 1e-9 / SUBSTEPS as f64;
            let dyaw = (w * yaw_gain + yaw_noise) * h;
            let mid = self.yaw + 0.5 * dyaw;
            self.x += v * speed_gain * h * mid.cos();
            self.y += v * speed_gain * h * mid.sin();
            self.yaw += dyaw;
        }
        let (v, w) = true_rates(scene, stamp_ns);
        Message::WheelOdometry(WheelOdometry {
            stamp_ns,
            linear_mps: v * speed_gain,
            angular_rps: w * yaw_gain + yaw_noise,
            odom_from_base: Isometry3::from_parts(
                Translation3::new(self.x, self.y, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, self.yaw),
            ),
        })
    }
}
