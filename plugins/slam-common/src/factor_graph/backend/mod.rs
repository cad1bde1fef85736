//! The factor-graph backend every plugin shares: a small interface (variables, factors,
//! update, estimate) so that the pipeline never names the solver, and implementations
//! chosen by name in a plugin's configuration (`backend = "factrs"`).
//!
//! Poses are `world_from_body` isometries; the body is whatever frame the plugin keeps its
//! graph in (for IMU factors: the IMU's frame). Keys are plain integers per kind of
//! variable, so pose 7, velocity 7 and bias 7 belong to the same keyframe.
//!
//! Every backend perturbs a pose on the right, rotation first: `x ⊕ ξ = x·exp(ξ)` with
//! `ξ = (ω, ρ)`, `ω` a rotation about the body's x, y, z axes (rad) and `ρ` a translation
//! along them (m) — GTSAM's `Pose3` chart, factrs's default. [`PoseSigmas`] and the
//! marginal covariances of [`Backend::marginal_covariance`] are in that tangent space.

use nalgebra::{Isometry3, Matrix3, Matrix6, Vector3, Vector6};
use serde::Deserialize;

mod convert;
mod entry;
mod factrs;
mod gtsam;
mod imu;
mod isam2;
mod position;
mod profile;
mod scope;
mod solve;

pub use factrs::FactrsBackend;
pub use isam2::Isam2Backend;
pub use profile::{Profiled, UpdateTiming};

/// Which kind of variable a key names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Var {
    /// `world_from_body`, an SE(3) pose.
    Pose(u64),
    /// Body velocity in the world frame, m/s.
    Velocity(u64),
    /// IMU biases.
    Bias(u64),
}

/// Accelerometer and gyroscope biases.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuBias {
    pub accel_mps2: Vector3<f64>,
    pub gyro_rps: Vector3<f64>,
}

/// One IMU sample to be preintegrated: specific force and angular rate in the IMU frame,
/// held for `dt_s` seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    pub dt_s: f64,
    pub accel_mps2: Vector3<f64>,
    pub gyro_rps: Vector3<f64>,
}

/// Continuous-time IMU noise (Kalibr's convention), and gravity.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuNoise {
    /// m/s²/√Hz
    pub accel_noise_density: f64,
    /// rad/s/√Hz
    pub gyro_noise_density: f64,
    /// m/s³/√Hz
    pub accel_bias_random_walk: f64,
    /// rad/s²/√Hz
    pub gyro_bias_random_walk: f64,
    /// Magnitude of gravity, m/s²; it points along −z of the world.
    pub gravity_mps2: f64,
}

impl Default for ImuNoise {
    /// LIO-SAM's defaults (`imuAccNoise`, `imuGyrNoise`, `imuAccBiasN`, `imuGyrBiasN`,
    /// `imuGravity` in its params.yaml), digits as published.
    #[allow(clippy::excessive_precision)]
    fn default() -> Self {
        Self {
            accel_noise_density: 3.9939570888238808e-03,
            gyro_noise_density: 1.5636343949698187e-03,
            accel_bias_random_walk: 6.4356659353532566e-05,
            gyro_bias_random_walk: 3.5640318696367613e-05,
            gravity_mps2: 9.80511,
        }
    }
}

/// A robust kernel for a factor's whitened residual.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Robust {
    #[default]
    None,
    Huber(f64),
    Cauchy(f64),
}

/// Standard deviations of a 6-DoF pose error: rotation (rad, about x, y, z of the body),
/// then translation (m, x, y, z).
pub type PoseSigmas = Vector6<f64>;

/// A factor. Each names the variables it constrains; every variable must have been
/// inserted before the factor is added.
#[derive(Debug, Clone, PartialEq)]
pub enum Factor {
    /// Anchors a pose.
    PosePrior {
        key: u64,
        world_from_body: Isometry3<f64>,
        sigmas: PoseSigmas,
    },
    /// Anchors a velocity, m/s.
    VelocityPrior {
        key: u64,
        velocity_mps: Vector3<f64>,
        sigma_mps: f64,
    },
    /// Anchors a bias (accelerometer sigma, gyroscope sigma).
    BiasPrior {
        key: u64,
        bias: ImuBias,
        sigma_accel: f64,
        sigma_gyro: f64,
    },
    /// A position-only prior on a pose's translation, in the world frame (a GNSS fix
    /// carried to the body's origin): GTSAM's `GPSFactor` ("prior on position in a
    /// Cartesian frame", `gtsam/navigation/GPSFactor.h`, the factor LIO-SAM's
    /// `addGPSFactor` adds), whose error is `t(x) − position` with `t(x)` the translation
    /// of `world_from_body`, whitened by the diagonal `sigmas` (m, along the world's x, y,
    /// z). Its Jacobian in the tangent space above is `[0  R]`: rotation is left free.
    Position {
        key: u64,
        position: Vector3<f64>,
        sigmas: Vector3<f64>,
    },
    /// Relative pose `from_from_to` (odometry, a loop closure), optionally robust.
    Between {
        from: u64,
        to: u64,
        from_from_to: Isometry3<f64>,
        sigmas: PoseSigmas,
        robust: Robust,
    },
    /// IMU preintegration between two keyframes (Forster et al. 2017): constrains pose,
    /// velocity and bias of `from` and of `to`, and the bias random walk between them.
    /// `samples` are integrated from `from`'s time to `to`'s, with `from`'s bias
    /// estimate at the time the factor is built as the linearisation point.
    Imu {
        from: u64,
        to: u64,
        samples: Vec<ImuSample>,
        noise: ImuNoise,
    },
}

/// Identifies an added factor so that it can be removed (a rejected loop closure).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FactorId(pub u64);

/// How much of the graph an update may move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Per-keyframe update: the cost must stay flat as the graph grows (warm start and
    /// a window of recent variables; older ones held at their estimate).
    Incremental,
    /// Everything, e.g. after a loop closure.
    Full,
}

/// What an update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateReport {
    /// Variables the solver moved.
    pub variables: usize,
    /// Factors it linearised.
    pub factors: usize,
    pub iterations: usize,
    /// Sum of squared whitened residuals of the factors in scope, before and after (for a
    /// factor with a robust kernel, twice its kernel's cost instead: what the solver
    /// minimises).
    pub error_before: f64,
    pub error_after: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    #[error("unknown backend {0:?} (known: \"isam2\", \"gtsam\", \"factrs\")")]
    Unknown(String),
    #[error("factor refers to {0:?}, which was never inserted")]
    MissingVariable(Var),
    #[error("variable {0:?} inserted twice")]
    Duplicate(Var),
    #[error("solver failed: {0}")]
    Solver(String),
    /// A value, factor or setting the backend cannot use (a non-positive sigma, a
    /// non-finite number, an IMU factor without samples, a value of the wrong kind).
    #[error("invalid input: {0}")]
    Invalid(String),
    /// The backend cannot run on this machine (the "gtsam" backend without its bridge
    /// library, libpython or the gtsam Python package); the message says what to install.
    #[error("backend unavailable: {0}")]
    Unavailable(String),
}

/// A factor graph that grows keyframe by keyframe.
pub trait Backend: Send + std::fmt::Debug {
    /// Adds a variable with its initial estimate.
    fn insert(&mut self, var: Var, initial: Value) -> Result<(), BackendError>;
    fn add(&mut self, factor: Factor) -> Result<FactorId, BackendError>;
    /// Removes a factor; false if there was none with that id.
    fn remove(&mut self, id: FactorId) -> bool;
    /// Optimises and keeps the result as the new estimate.
    fn update(&mut self, scope: Scope) -> Result<UpdateReport, BackendError>;
    /// The current estimate of a variable.
    fn value(&self, var: Var) -> Option<Value>;
    /// Sets the estimate of a variable (e.g. restoring a saved graph).
    fn set_value(&mut self, var: Var, value: Value) -> Result<(), BackendError>;
    /// The whitened residual norm of a factor at the current estimate (√ of its
    /// Mahalanobis error): how many standard deviations it is from being satisfied.
    fn factor_error(&self, id: FactorId) -> Option<f64>;
    /// Every pose key, ascending.
    fn pose_keys(&self) -> Vec<u64>;
    /// The marginal covariance of pose `key` given every factor (GTSAM's
    /// `ISAM2::marginalCovariance`, which LIO-SAM reads after each keyframe): the 6 × 6
    /// covariance of the tangent vector `ξ` of `x ⊕ ξ = x·exp(ξ)` (rotation about the body's
    /// axes first, then translation along them; see the module documentation), at the
    /// linearisation of the factors the backend holds. How each backend computes it:
    /// `"isam2"` and `"gtsam"` from their Bayes tree as of the last update (a pose no update
    /// has taken yet is [`BackendError::Invalid`]), `"factrs"` from every factor linearised
    /// at the current estimate. An unknown key is [`BackendError::MissingVariable`].
    fn marginal_covariance(&self, key: u64) -> Result<PoseCovariance, BackendError>;

    fn pose(&self, key: u64) -> Option<Isometry3<f64>> {
        match self.value(Var::Pose(key))? {
            Value::Pose(p) => Some(p),
            _ => None,
        }
    }
}

/// The marginal covariance of a pose ([`Backend::marginal_covariance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseCovariance {
    /// Covariance of the tangent vector `ξ = (ω, ρ)` of `x ⊕ ξ = x·exp(ξ)`: rotation about
    /// the body's x, y, z (rad²) in rows and columns 0–2, translation along the body's
    /// x, y, z (m²) in 3–5 — GTSAM's `Pose3` order, so `(3, 3)` and `(4, 4)` are the
    /// entries LIO-SAM's `poseCovariance(3,3)` and `(4,4)` read.
    pub tangent: Matrix6<f64>,
    /// The pose's current estimate, `world_from_body`, whose rotation turns the body-frame
    /// blocks into the world frame.
    pub world_from_body: Isometry3<f64>,
}

impl PoseCovariance {
    /// The translation's covariance in the world frame, m²: to first order `x·exp(ξ)`
    /// moves the translation by `R·ρ`, so it is `R·Σ_ρρ·Rᵀ` (rows and columns: the world's
    /// x, y, z).
    pub fn translation_world(&self) -> Matrix3<f64> {
        let r = self.world_from_body.rotation.to_rotation_matrix();
        let body: Matrix3<f64> = self.tangent.fixed_view::<3, 3>(3, 3).into_owned();
        r.matrix() * body * r.matrix().transpose()
    }

    /// The translation's covariance along the body's axes, m² (the tangent's `ρ` block).
    pub fn translation_body(&self) -> Matrix3<f64> {
        self.tangent.fixed_view::<3, 3>(3, 3).into_owned()
    }

    /// The rotation's covariance about the body's axes, rad² (the tangent's `ω` block).
    pub fn rotation_body(&self) -> Matrix3<f64> {
        self.tangent.fixed_view::<3, 3>(0, 0).into_owned()
    }
}

/// The value of a variable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Pose(Isometry3<f64>),
    Velocity(Vector3<f64>),
    Bias(ImuBias),
}

/// Backend settings from a plugin's configuration (a `[backend]` table).
///
/// `name` chooses the implementation: `"isam2"` (native iSAM2 on a Bayes tree), `"gtsam"`
/// (GTSAM's own ISAM2 through its Python bindings) or `"factrs"` (Levenberg–Marquardt on a
/// window of recent keyframes). The iSAM2 settings are GTSAM's `ISAM2Params` of the same
/// meaning and default; `window` applies to factrs only. For the iSAM2 backends
/// [`Scope::Incremental`] is one iSAM2 update and [`Scope::Full`] an update that
/// relinearises every variable, repeated until the error stops falling (at most
/// `max_iterations` times).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BackendConfig {
    /// Which implementation: "isam2", "gtsam" or "factrs".
    pub name: String,
    /// factrs: keyframes the incremental update may move; older ones are held fixed.
    pub window: usize,
    /// factrs: Levenberg–Marquardt iterations per update; iSAM2: updates of a full one.
    pub max_iterations: usize,
    /// iSAM2: a variable is relinearised when its last step exceeds this (any component
    /// of its tangent vector; GTSAM's `relinearizeThreshold`).
    pub relinearize_threshold: f64,
    /// iSAM2: look for variables to relinearise every this many updates
    /// (`relinearizeSkip`).
    pub relinearize_skip: usize,
    /// iSAM2: partial back-substitution stops below this change of a clique's variables
    /// (`wildfireThreshold`).
    pub wildfire_threshold: f64,
}

impl Default for BackendConfig {
    fn default() -> Self {
        Self {
            // Measured (docs/backends.md): lio-sam's ATE on S0–S3 equal to or
            // below factrs's, its incremental update 0.22 ms p50 against 26 ms.
            name: "isam2".into(),
            window: 20,
            max_iterations: 10,
            relinearize_threshold: 0.1,
            relinearize_skip: 10,
            wildfire_threshold: 0.001,
        }
    }
}

/// Builds the backend a configuration names.
pub fn from_config(config: &BackendConfig) -> Result<Box<dyn Backend>, BackendError> {
    match config.name.as_str() {
        "factrs" if config.window == 0 => Err(BackendError::Invalid(
            "backend window must be at least 1 keyframe".to_string(),
        )),
        "factrs" => Ok(Box::new(FactrsBackend::new(config))),
        "gtsam" => Ok(Box::new(gtsam::GtsamBackend::new(config)?)),
        "isam2" => Ok(Box::new(Isam2Backend::new(config))),
        other => Err(BackendError::Unknown(other.to_string())),
    }
}
