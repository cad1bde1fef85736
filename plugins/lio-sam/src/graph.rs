//! The keyframe factor graph (Shan et al. 2020, §III-A and Fig. 1): one pose per keyframe,
//! joined by lidar-odometry factors (the relative pose between consecutive registered
//! keyframes), IMU-preintegration factors (with velocity and bias variables), GPS factors
//! (a position prior on a keyframe, §III-D) and robust loop-closure factors; updated
//! incrementally at every keyframe and in full after a loop closure or a GPS factor.
//! Poses are `world_from_imu`, the frame IMU factors live in.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Matrix3, Vector3, Vector6};
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
    /// GPS factors will come: the first keyframe's heading and position are left to them.
    gps: bool,
}

impl KeyframeGraph {
    /// `imu_noise` None builds a lidar-only graph; `gps` a graph that GPS factors will
    /// place (see `first_pose_sigmas`).
    pub fn new(
        cfg: &BackendConfig,
        imu_noise: Option<ImuNoise>,
        sigma_rad: f64,
        sigma_m: f64,
        gps: bool,
    ) -> Result<Self, BackendError> {
        Ok(Self {
            backend: Profiled::new(backend::from_config(cfg)?),
            imu_noise,
            odometry_sigmas: Vector6::new(
                sigma_rad, sigma_rad, sigma_rad, sigma_m, sigma_m, sigma_m,
            ),
            keyframes: 0,
            gps,
        })
    }

    pub fn len(&self) -> usize {
        self.keyframes
    }

    pub fn is_empty(&self) -> bool {
        self.keyframes == 0
    }

    /// Adds keyframe `len()` at its registered pose, with the IMU samples since the previous
    /// keyframe and the state guesses, and a GPS factor on it if one is given (its
    /// position of the IMU in the world frame and sigmas, m), and updates the graph:
    /// incrementally, or in full after a GPS factor (LIO-SAM's `aLoopIsClosed`).
    pub fn add_keyframe(
        &mut self,
        registered: Isometry3<f64>,
        velocity_mps: Vector3<f64>,
        bias: ImuBias,
        samples: Vec<ImuSample>,
        gps: Option<(Vector3<f64>, Vector3<f64>)>,
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
        if let Some((position, sigmas)) = gps {
            self.backend.add(Factor::Position {
                key: k,
                position,
                sigmas,
            })?;
        }
        self.keyframes += 1;
        self.update(match gps {
            Some(_) => Scope::Full,
            None => Scope::Incremental,
        })
    }

    /// The marginal covariance of keyframe `k`'s position in the world frame, m²
    /// (LIO-SAM's `poseCovariance = isam->marginalCovariance(last)`, its translation
    /// block turned into the world frame).
    pub fn position_covariance(&self, k: usize) -> Result<Matrix3<f64>, BackendError> {
        Ok(self
            .backend
            .marginal_covariance(k as u64)?
            .translation_world())
    }

    /// The prior on the first keyframe's pose: 1 mm and 1 mrad (the gauge), except roll
    /// and pitch with IMU factors. Then the world was levelled by the accelerometer at the
    /// first sweep (the robot stands still), whose turn-on bias is unknown: the level is
    /// only as good as the bias prior, σ_ba / g, until turns make the bias observable and
    /// the IMU factors' gravity can level it again. Held at 1 mrad, a levelling error of
    /// 2-3 mrad (the simulator's 0.02 m/s² bias) stayed, the bias estimate absorbed the
    /// gravity error in the body frame, and after a U-turn it pulled the poses the other
    /// way (S1: lidar + IMU 0.031 m against lidar only 0.022 m on factrs).
    ///
    /// With GPS factors coming, the heading and the position take LIO-SAM's own prior
    /// (`addOdomFactor`'s `priorNoise`, variances π² rad² in yaw and 1e8 m² in position):
    /// the map is placed and turned by the GPS factors, and the marginal covariance the
    /// `poseCovThreshold` rule reads starts large, so that fixes are taken from the start
    /// and again wherever the estimate has drifted. Held at 1 mm, it would grow only with
    /// the odometry's noise and reach 25 m² after hundreds of metres.
    fn first_pose_sigmas(&self) -> Vector6<f64> {
        let mut sigmas = Vector6::repeat(1e-3);
        if let Some(noise) = self.imu_noise {
            let tilt = BIAS_PRIOR_ACCEL / noise.gravity_mps2;
            sigmas[0] = tilt;
            sigmas[1] = tilt;
        }
        if self.gps {
            sigmas[2] = PI;
            for s in sigmas.iter_mut().skip(3) {
                *s = 1e4;
            }
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
