//! IMU preintegration on factrs's [`ImuPreintegrator`] (Forster, Carlone, Dellaert and
//! Scaramuzza, "On-Manifold Preintegration for Real-Time Visual-Inertial Odometry",
//! IEEE T-RO 33(1), 2017): the samples between two keyframes are summarised once, when
//! the factor is added, into a relative-motion measurement with its covariance and the
//! first-order Jacobians that correct it for a change of bias.
//!
//! factrs's conventions, and how [`ImuNoise`] (continuous time, Kalibr's units) is mapped
//! onto them (checked by the IMU tests in `tests/all/backend.rs`):
//! - Its `Gravity` is the gravity *acceleration* in the world frame (`v̇ = g + R·(a − bₐ)`
//!   with `a` the specific force an accelerometer reads, +9.8 m/s² upwards at rest), so a
//!   z-up world uses `Gravity(0, 0, −g)` — what factrs calls `Gravity::down()`, not the
//!   `Gravity::up()` of its examples, whose accelerometer readings have the other sign.
//! - Its `ImuCovariance` is per sample (discrete): each step adds `cov_accel·dt²` to the
//!   velocity covariance and `cov_accel_bias` (no `dt`) to the bias covariance. The
//!   continuous densities therefore become `σ²/dt` for white noise and `σ²·dt` for the
//!   random walks, with `dt` the mean sample period of the factor (factrs fixes the
//!   covariance per preintegrator; a steady IMU rate makes this exact).
//! - In factrs 0.3 the rotation block of the per-step noise uses `cov_gyro_bias` where
//!   the gyroscope's white noise belongs, and adds `cov_winit` with the same Jacobian. We
//!   put the gyroscope's white noise into `cov_winit` (minus what `cov_gyro_bias`
//!   already adds), which makes the rotation covariance what Forster et al. prescribe;
//!   `cov_ainit` is zero, as the accelerometer's white noise is already in `cov_accel`.

use ::factrs::{
    containers::{Factor as FFactor, Key},
    linalg::Matrix3,
    residuals::{Accel, Gravity, Gyro, ImuCovariance, ImuPreintegrator},
};
use nalgebra::Vector3;

use super::{BackendError, ImuBias, ImuNoise, ImuSample, convert};

/// Position integration noise per sample, m²: covers the Euler scheme's discretisation
/// error (GTSAM and LIO-SAM use a similar `integrationCovariance`).
pub(crate) const INTEGRATION_VARIANCE_PER_S: f64 = 1e-8;

/// Preintegrated samples between two keyframes, ready to become a factor at every update
/// (factrs factors are not `Send`, so the backend keeps this instead).
#[derive(Debug, Clone)]
pub(crate) struct Preintegrated {
    preint: ImuPreintegrator,
}

impl Preintegrated {
    /// Integrates `samples` with `bias` (the `from` keyframe's current estimate) as the
    /// linearisation point.
    pub(crate) fn new(
        samples: &[ImuSample],
        noise: &ImuNoise,
        bias: &ImuBias,
    ) -> Result<Self, BackendError> {
        check(samples, noise)?;
        let total_s: f64 = samples.iter().map(|s| s.dt_s).sum();
        let mean_dt = total_s / samples.len() as f64;
        let gravity = Gravity(Vector3::new(0.0, 0.0, -noise.gravity_mps2));
        let mut preint =
            ImuPreintegrator::new(covariance(noise, mean_dt), convert::fbias(bias), gravity);
        for s in samples {
            preint.integrate(&Gyro(s.gyro_rps), &Accel(s.accel_mps2), s.dt_s);
        }
        Ok(Self { preint })
    }

    /// The factor on (pose, velocity, bias) of `from` and of `to`.
    pub(crate) fn factor(&self, from: [Key; 3], to: [Key; 3]) -> FFactor {
        self.preint
            .clone()
            .build_unchecked(from[0], from[1], from[2], to[0], to[1], to[2])
    }
}

/// factrs's per-sample covariances for continuous densities at sample period `dt`.
fn covariance(noise: &ImuNoise, dt: f64) -> ImuCovariance {
    let i = Matrix3::identity();
    let gyro_bias = noise.gyro_bias_random_walk.powi(2) * dt;
    let gyro_white = noise.gyro_noise_density.powi(2) / dt;
    ImuCovariance {
        cov_accel: i * (noise.accel_noise_density.powi(2) / dt),
        cov_gyro: i * gyro_white,
        cov_accel_bias: i * (noise.accel_bias_random_walk.powi(2) * dt),
        cov_gyro_bias: i * gyro_bias,
        cov_integration: i * (INTEGRATION_VARIANCE_PER_S * dt),
        cov_winit: i * (gyro_white - gyro_bias).max(0.0),
        cov_ainit: Matrix3::zeros(),
    }
}

/// factrs panics on a covariance that is not positive definite; these checks rule that
/// out (with positive densities and periods every block of it is positive).
pub(crate) fn check(samples: &[ImuSample], noise: &ImuNoise) -> Result<(), BackendError> {
    if samples.is_empty() {
        return Err(BackendError::Invalid(
            "IMU factor without samples".to_string(),
        ));
    }
    convert::check_positive(
        "IMU noise",
        &[
            noise.accel_noise_density,
            noise.gyro_noise_density,
            noise.accel_bias_random_walk,
            noise.gyro_bias_random_walk,
        ],
    )?;
    convert::check_finite("gravity", &[noise.gravity_mps2])?;
    for s in samples {
        convert::check_positive("IMU sample dt_s", &[s.dt_s])?;
        convert::check_finite("IMU sample", s.accel_mps2.as_slice())?;
        convert::check_finite("IMU sample", s.gyro_rps.as_slice())?;
    }
    Ok(())
}
