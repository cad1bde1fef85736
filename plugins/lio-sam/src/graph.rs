//! The keyframe factor graph (Shan et al. 2020, §III-A and Fig. 1): one pose per keyframe,
//! joined by lidar-odometry factors (the relative pose between consecutive registered
//! keyframes), IMU-preintegration factors (with velocity and bias variables), and robust
//! loop-closure factors; updated incrementally at every keyframe and in full after a loop
//! closure. Poses are `world_from_imu`, the frame IMU factors live in.

use nalgebra::{Isometry3, Vector3, Vector6};
use slam_common::backend::{
    self, Backend, BackendConfig, BackendError, Factor, FactorId, ImuBias, ImuNoise, ImuSample,
    Profiled, Robust, Scope, Value, Var,
};

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
            let tight = Vector6::repeat(1e-3);
            self.backend.add(Factor::PosePrior {
                key: 0,
                world_from_body: registered,
                sigmas: tight,
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
                    sigma_accel: 0.1,
                    sigma_gyro: 0.01,
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
