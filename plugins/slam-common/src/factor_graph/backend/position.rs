//! [`Factor::Position`](super::Factor::Position) for factrs, which has no position-only
//! factor: a custom residual on an `SE3`, `r = t(x) − z` (GTSAM's `GPSFactor`,
//! `evaluateError` = `p.translation() − measured`), differentiated by factrs's forward-mode
//! automatic differentiation like its own residuals. With factrs's right perturbation
//! `x·exp(ξ)` its Jacobian is `[0  R]`, GTSAM's.

use ::factrs::{
    linalg::{Const, ForwardProp, Numeric, VectorX},
    residuals::Residual1,
    variables::SE3,
};
use nalgebra::Vector3;

/// `t(x) − measured`, in the world frame, metres.
#[derive(Debug, Clone)]
pub(crate) struct PositionResidual {
    measured: Vector3<f64>,
}

impl PositionResidual {
    pub(crate) fn new(measured: Vector3<f64>) -> Self {
        Self { measured }
    }
}

#[factrs::mark]
impl Residual1 for PositionResidual {
    type Differ = ForwardProp<Const<6>>;
    type V1 = SE3;
    type DimIn = Const<6>;
    type DimOut = Const<3>;

    fn residual1<T: Numeric>(&self, v: SE3<T>) -> VectorX<T> {
        let t = v.xyz();
        VectorX::from_iterator(3, (0..3).map(|i| t[i] - T::from(self.measured[i])))
    }
}
