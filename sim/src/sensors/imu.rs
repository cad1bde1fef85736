//! IMU: specific force and angular rate at the IMU's mounting point from the trajectory's
//! analytic derivatives, plus white noise and bias random walk in the discrete form of the
//! continuous-time model (Kalibr's "IMU Noise Model"; Trawny & Roumeliotis 2005): per
//! sample σ_d = σ_c·√rate for white noise and σ_b·√Δt for the bias step.

use nalgebra::{Isometry3, Vector3};
use rand_distr::{Distribution, StandardNormal};

use super::{ImuSample, Message, Scene, Sensor, sample_time_ns};
use crate::config::{ImuConfig, NoiseProfile};
use crate::rng::SimRng;
use crate::robot::{GRAVITY, rotation};

#[derive(Debug)]
pub struct ImuSensor {
    cfg: ImuConfig,
    base_from_imu: Isometry3<f64>,
    k: u64,
    end_ns: i64,
    rng: SimRng,
    accel_bias: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    /// The reported orientation's error (roll, pitch, yaw; unit-variance Gauss–Markov
    /// states) and its own generator, drawn from the IMU's only where it has an error, so
    /// that an IMU without one streams what it did before.
    orientation_error: Option<(Vector3<f64>, SimRng)>,
}

fn gaussian3(rng: &mut SimRng, sigma: f64) -> Vector3<f64> {
    Vector3::from_fn(|_, _| {
        sigma * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, rng)
    })
}

impl ImuSensor {
    pub fn new(cfg: &ImuConfig, end_ns: i64, mut rng: SimRng) -> Self {
        let noisy = cfg.noise == NoiseProfile::Typical;
        let (accel_bias, gyro_bias) = if noisy {
            (
                gaussian3(&mut rng, cfg.accel_bias_initial),
                gaussian3(&mut rng, cfg.gyro_bias_initial),
            )
        } else {
            (Vector3::zeros(), Vector3::zeros())
        };
        let orientation_error = (cfg.reports_orientation
            && (cfg.orientation_roll_pitch_sigma_rad > 0.0 || cfg.orientation_yaw_sigma_rad > 0.0))
            .then(|| {
                let mut own =
                    <SimRng as rand::SeedableRng>::seed_from_u64(rand::Rng::random(&mut rng));
                (gaussian3(&mut own, 1.0), own)
            });
        Self {
            orientation_error,
            cfg: cfg.clone(),
            base_from_imu: cfg.mount.base_from_sensor(),
            k: 0,
            end_ns,
            rng,
            accel_bias,
            gyro_bias,
        }
    }

    /// The noise-free reading at `t_ns`: (specific force, angular rate) in the IMU frame.
    pub fn ideal(&self, scene: &Scene<'_>, t_ns: i64) -> (Vector3<f64>, Vector3<f64>) {
        let s = scene.trajectory.state(t_ns);
        let world_r_base = rotation(&s.world_from_base);
        let lever = self.base_from_imu.translation.vector;
        let (w, a) = (s.omega_in_base, s.alpha_in_base);
        let accel_of_imu =
            s.acceleration + world_r_base * (a.cross(&lever) + w.cross(&w.cross(&lever)));
        let specific_force_world = accel_of_imu + Vector3::new(0.0, 0.0, GRAVITY);
        let imu_from_world = (world_r_base * rotation(&self.base_from_imu)).transpose();
        let base_r_imu = rotation(&self.base_from_imu);
        (
            imu_from_world * specific_force_world,
            base_r_imu.transpose() * w,
        )
    }
}

impl Sensor for ImuSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let t = sample_time_ns(self.k, self.cfg.rate_hz);
        (t <= self.end_ns).then_some(t)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> Message {
        let stamp_ns = sample_time_ns(self.k, self.cfg.rate_hz);
        self.k += 1;
        let (mut accel, mut gyro) = self.ideal(scene, stamp_ns);
        if self.cfg.noise == NoiseProfile::Typical {
            let dt = 1.0 / self.cfg.rate_hz;
            let sqrt_rate = self.cfg.rate_hz.sqrt();
            accel += self.accel_bias
                + gaussian3(&mut self.rng, self.cfg.accel_noise_density * sqrt_rate);
            gyro +=
                self.gyro_bias + gaussian3(&mut self.rng, self.cfg.gyro_noise_density * sqrt_rate);
            self.accel_bias +=
                gaussian3(&mut self.rng, self.cfg.accel_bias_random_walk * dt.sqrt());
            self.gyro_bias += gaussian3(&mut self.rng, self.cfg.gyro_bias_random_walk * dt.sqrt());
        }
        let mut orientation = self
            .cfg
            .reports_orientation
            .then(|| scene.trajectory.pose(stamp_ns).rotation * self.base_from_imu.rotation);
        if let (Some(q), Some((state, rng))) =
            (orientation.as_mut(), self.orientation_error.as_mut())
        {
            // x_k = φ x_{k-1} + √(1-φ²) w_k per axis, the error applied in the world frame
            // (a heading error turns about the vertical).
            let phi = (-1.0 / (self.cfg.rate_hz * self.cfg.orientation_tau_s)).exp();
            *state = *state * phi + gaussian3(rng, (1.0 - phi * phi).sqrt());
            let (rp, yaw) = (
                self.cfg.orientation_roll_pitch_sigma_rad,
                self.cfg.orientation_yaw_sigma_rad,
            );
            let error = nalgebra::UnitQuaternion::from_euler_angles(
                rp * state.x,
                rp * state.y,
                yaw * state.z,
            );
            *q = error * *q;
        }
        Message::Imu(ImuSample {
            stamp_ns,
            accel_mps2: accel,
            gyro_rps: gyro,
            orientation,
        })
    }
}
