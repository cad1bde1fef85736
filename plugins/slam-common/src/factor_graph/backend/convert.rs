//! Conversions between the backend's types (nalgebra isometries, [`ImuBias`], sigmas,
//! [`Robust`]) and factrs's, and the checks that keep bad input from reaching factrs
//! (which panics on it).
//!
//! factrs's conventions, checked by the tests in `tests/all/backend.rs`:
//! - `SE3` is `world_from_body` stored as (unit quaternion, translation); `compose` is the
//!   usual product, so `SE3::from_rot_trans(R, t)` is `Isometry3::from_parts(t, R)`.
//! - Tangent vectors put rotation first, then translation, and perturbations act on the
//!   right (in the body frame): `x ⊕ ξ = x·exp(ξ)`, `x ⊖ y = log(y⁻¹·x)` (unless the
//!   crate's `left` feature is on, which this workspace does not enable).
//! - `ImuBias` tangent order is gyroscope first, then accelerometer.

use ::factrs::{
    noise::GaussianNoise,
    residuals::{Accel, Gyro},
    variables::{ImuBias as FBias, SE3, SO3, VectorVar3},
};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3, Vector6};

use super::{BackendError, ImuBias, PoseSigmas, Value};

/// `world_from_body` as a factrs pose.
pub(crate) fn se3_from_iso(iso: &Isometry3<f64>) -> SE3 {
    let q = iso.rotation.quaternion();
    SE3::from_rot_trans(SO3::from_xyzw(q.i, q.j, q.k, q.w), iso.translation.vector)
}

/// A factrs pose back as `world_from_body` (the quaternion is renormalised).
pub(crate) fn iso_from_se3(se3: &SE3) -> Isometry3<f64> {
    let r = se3.rot();
    let q = UnitQuaternion::from_quaternion(Quaternion::new(r.w(), r.x(), r.y(), r.z()));
    Isometry3::from_parts(Translation3::from(se3.xyz().into_owned()), q)
}

pub(crate) fn fbias(b: &ImuBias) -> FBias {
    FBias::new(Gyro(b.gyro_rps), Accel(b.accel_mps2))
}

pub(crate) fn bias_from_f(b: &FBias) -> ImuBias {
    ImuBias {
        accel_mps2: *b.accel(),
        gyro_rps: *b.gyro(),
    }
}

pub(crate) fn fvel(v: &Vector3<f64>) -> VectorVar3 {
    VectorVar3::from(*v)
}

/// Diagonal noise for a 6-DoF pose error; our `PoseSigmas` and factrs both put rotation
/// first, so no reordering.
pub(crate) fn pose_noise(sigmas: &PoseSigmas) -> GaussianNoise<6> {
    GaussianNoise::from_vec_sigma(sigmas.as_view())
}

/// Diagonal noise for a bias error in factrs's order: gyroscope, then accelerometer.
pub(crate) fn bias_noise(sigma_accel: f64, sigma_gyro: f64) -> GaussianNoise<6> {
    let (a, g) = (sigma_accel, sigma_gyro);
    GaussianNoise::from_vec_sigma(Vector6::new(g, g, g, a, a, a).as_view())
}

fn positive(what: &str, x: f64) -> Result<(), BackendError> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(BackendError::Invalid(format!(
            "{what} must be positive and finite, got {x}"
        )))
    }
}

pub(crate) fn check_positive(what: &str, xs: &[f64]) -> Result<(), BackendError> {
    xs.iter().try_for_each(|&x| positive(what, x))
}

pub(crate) fn check_finite(what: &str, xs: &[f64]) -> Result<(), BackendError> {
    match xs.iter().find(|x| !x.is_finite()) {
        None => Ok(()),
        Some(x) => Err(BackendError::Invalid(format!("{what} is not finite ({x})"))),
    }
}

pub(crate) fn check_pose(what: &str, p: &Isometry3<f64>) -> Result<(), BackendError> {
    check_finite(what, p.translation.vector.as_slice())?;
    check_finite(what, p.rotation.coords.as_slice())
}

pub(crate) fn check_value(v: &Value) -> Result<(), BackendError> {
    match v {
        Value::Pose(p) => check_pose("pose", p),
        Value::Velocity(v) => check_finite("velocity", v.as_slice()),
        Value::Bias(b) => {
            check_finite("accelerometer bias", b.accel_mps2.as_slice())?;
            check_finite("gyroscope bias", b.gyro_rps.as_slice())
        }
    }
}
