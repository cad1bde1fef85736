//! The keyframe factor graph (Shan et al. 2020, §III-A and Fig. 1): one pose per keyframe,
//! joined by lidar-odometry factors (the relative pose between consecutive registered
//! keyframes), IMU-preintegration factors (with velocity and bias variables), and robust
//! loop-closure factors; updated incrementally at every keyframe and in full after a loop
//! closure. Poses are `world_from_imu`, the frame IMU factors live in.

use nalgebra::{Isometry3, Vector3, Vector6};
use slam_common::factor_graph::backend::{
    self, Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, ImuNoise, ImuSample,
    Profiled, Robust, Scope, Value, Var,
};

/// σ of the prior on the first keyframe's accelerometer bias, m/s², and on its gyroscope
/// bias, rad/s.
const BIAS_PRIOR_ACCEL: f64 = 0.1;
const BIAS_PRIOR_GYRO: f64 = 0.01;

#[derive(Debug)]
pub struct KeyframeGraph {
    /// Every update timed, for the flat-cost check (`profile_csv`).
    pub backend: Profiled,
    imu_noise: Option<ImuNoise>,
    odometry_sigmas: Vector6<f64>,
    keyframes: usize,
}

impl KeyframeGraph {
    /// `imu_noise` None builds a lidar-only graph.
    pub fn new(
        cfg: &BackendConfig,
        imu_noise: Option<ImuNoise>,
        sigma_rad: f64,
        sigma_m: f64,
    ) -> Result<Self, BackendError> {
        Ok(Self {
            backend: Profiled::new(backend::from_config(cfg)?),
            imu_noise,
            odometry_sigmas: Vector6::new(
                sigma_rad, sigma_rad, sigma_rad, sigma_m, sigma_m, sigma_m,
            ),
            keyframes: 0,
        })
    }

    pub fn len(&self) -> usize {
        self.keyframes
    }

    pub fn is_empty(&self) -> bool {
        self.keyframes == 0
    }

    /// Adds keyframe `len()` at its registered pose, with the IMU samples since the previous
    /// keyframe and the state guesses, and updates the graph incrementally.
    pub fn add_keyframe(
        &mut self,
        registered: Isometry3<f64>,
        velocity_mps: Vector3<f64>,
        bias: ImuBias,
        samples: Vec<ImuSample>,
    ) -> Result<(), BackendError> {
        let k = self.keyframes as u64;
        // The sweep was registered to a map built from the current estimates, so it is in
        // their frame: its initial value is the registration itself, and the odometry
        // factor joins it to the previous keyframe's current estimate, as LIO-SAM's
        // addOdomFactor does (not to where that keyframe was first registered).
        self.backend.insert(Var::Pose(k), Value::Pose(registered))?;
        if k == 0 {
            self.backend.add(Factor::PosePrior {
                key: 0,
                world_from_body: registered,
                sigmas: self.first_pose_sigmas(),
            })?;
        } else {
            let from_from_to = self.pose(k as usize - 1).inverse() * registered;
            self.backend.add(Factor::Between {
                from: k - 1,
                to: k,
                from_from_to,
                sigmas: self.odometry_sigmas,
                robust: Robust::None,
            })?;
        }
        if let Some(noise) = self.imu_noise {
            self.backend
                .insert(Var::Velocity(k), Value::Velocity(velocity_mps))?;
            self.backend.insert(Var::Bias(k), Value::Bias(bias))?;
            if k == 0 {
                self.backend.add(Factor::VelocityPrior {
                    key: 0,
                    velocity_mps,
                    sigma_mps: 1.0,
                })?;
                self.backend.add(Factor::BiasPrior {
                    key: 0,
                    bias,
                    sigma_accel: BIAS_PRIOR_ACCEL,
                    sigma_gyro: BIAS_PRIOR_GYRO,
                })?;
            } else {
                self.backend.add(Factor::Imu {
                    from: k - 1,
                    to: k,
                    samples,
                    noise,
                })?;
            }
        }
        self.keyframes += 1;
        self.update(Scope::Incremental)
    }

    /// The prior on the first keyframe's pose: 1 mm and 1 mrad (the gauge), except roll
    /// and pitch with IMU factors. Then the world was levelled by the accelerometer at the
    /// first sweep (the robot stands still), whose turn-on bias is unknown: the level is
    /// only as good as the bias prior, σ_ba / g, until turns make the bias observable and
    /// the IMU factors' gravity can level it again. Held at 1 mrad, a levelling error of
    /// 2-3 mrad (the simulator's 0.02 m/s² bias) stayed, the bias estimate absorbed the
    /// gravity error in the body frame, and after a U-turn it pulled the poses the other
    /// way (S1: lidar + IMU 0.031 m against lidar only 0.022 m on factrs).
    fn first_pose_sigmas(&self) -> Vector6<f64> {
        let mut sigmas = Vector6::repeat(1e-3);
        if let Some(noise) = self.imu_noise {
            let tilt = BIAS_PRIOR_ACCEL / noise.gravity_mps2;
            sigmas[0] = tilt;
            sigmas[1] = tilt;
        }
        sigmas
    }

    /// Adds a loop-closure factor `older_from_newer` with isotropic sigmas and a Cauchy
    /// kernel, and optimises everything.
    pub fn add_loop(
        &mut self,
        older: usize,
        newer: usize,
        older_from_newer: Isometry3<f64>,
        sigma: f64,
        robust_scale: f64,
    ) -> Result<FactorId, BackendError> {
        let id = self.backend.add(Factor::Between {
            from: older as u64,
            to: newer as u64,
            from_from_to: older_from_newer,
            sigmas: Vector6::repeat(sigma),
            robust: Robust::Cauchy(robust_scale),
        })?;
        self.update(Scope::Full)?;
        Ok(id)
    }

    fn update(&mut self, scope: Scope) -> Result<(), BackendError> {
        self.backend.update(scope).map(|_| ())
    }

    /// The estimate of keyframe `k`'s `world_from_imu` (`k` below `len()`).
    pub fn pose(&self, k: usize) -> Isometry3<f64> {
        self.backend
            .pose(k as u64)
            .expect("every keyframe's pose is inserted by add_keyframe")
    }

    pub fn velocity(&self, k: usize) -> Option<Vector3<f64>> {
        match self.backend.value(Var::Velocity(k as u64))? {
            Value::Velocity(v) => Some(v),
            _ => None,
        }
    }

    pub fn bias(&self, k: usize) -> Option<ImuBias> {
        match self.backend.value(Var::Bias(k as u64))? {
            Value::Bias(b) => Some(b),
            _ => None,
        }
    }

    /// How many sigmas a factor is from being satisfied.
    pub fn factor_error(&self, id: FactorId) -> Option<f64> {
        self.backend.factor_error(id)
    }
}
