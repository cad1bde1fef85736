//! The extended Kalman filter of robot_localization's `ekf_localization_node` (Moore &
//! Stouch, "A Generalized Extended Kalman Filter Implementation for the Robot Operating
//! System", IAS-13, 2014, §III–IV; robot_localization's `FilterBase` and `Ekf`).
//!
//! - Motion model: omnidirectional, constant acceleration in 3D. The pose moves by the
//!   body velocity and acceleration rotated into the world, `p' = p + R(rpy)(v Δt +
//!   a Δt²/2)`; the Euler angles by the body rates through the Euler-rate matrix; the
//!   velocity by the acceleration; accelerations and body rates are held.
//! - Prediction: `x' = f(x)`, `P' = F P Fᵀ + Δt Q` with `F` the Jacobian of `f` (derived
//!   here analytically and checked against finite differences) and `Q` the
//!   `process_noise_covariance`, scaled by Δt as robot_localization scales it; optionally
//!   (`use_dynamic_process_noise_covariance`) the pose block of `Q` scaled by the squared
//!   norm of the body twist.
//! - Correction: only the measured variables (`H` selects them), measurement variances
//!   below 1e-9 raised to 1e-9 and negative ones made positive, angle innovations wrapped,
//!   a Mahalanobis gate (rejected when `yᵀ S⁻¹ y ≥ threshold²`), and the Joseph-form
//!   covariance update `(I − KH) P (I − KH)ᵀ + K R Kᵀ`.
//! - The first measurement initialises the measured variables and their covariance (the
//!   rest keep `initial_estimate_covariance`); later ones predict to their stamp, or, if
//!   older than the filter's time, are applied at the filter's time without a prediction
//!   (`FilterBase::processMeasurement`).

use nalgebra::{DMatrix, DVector, Matrix3};

use crate::measurement::Measurement;
use crate::state::{
    AX, PITCH, ROLL, STATE_SIZE, StateMatrix, StateVector, VPITCH, VROLL, VX, VYAW, X, YAW,
    is_angle, wrap_angle,
};

/// What became of a measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outcome {
    /// It was the first: it initialised the filter.
    Initialized,
    /// Fused.
    Fused,
    /// Refused by the Mahalanobis gate.
    Rejected {
        squared_mahalanobis: f64,
        threshold: f64,
    },
    /// Nothing finite to fuse, or a singular innovation covariance.
    Skipped,
}

/// The filter's state, covariance and time: what the lagged-data history saves.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    pub state: StateVector,
    pub covariance: StateMatrix,
    pub last_measurement_ns: i64,
    pub initialized: bool,
}

/// The EKF.
#[derive(Debug, Clone)]
pub struct Ekf {
    pub state: StateVector,
    pub covariance: StateMatrix,
    /// The stamp of the last measurement the filter predicted to.
    pub last_measurement_ns: i64,
    pub initialized: bool,
    process_noise: StateMatrix,
    dynamic_process_noise: bool,
}

/// The smallest measurement variance robot_localization lets through (`Ekf::correct`).
const MIN_VARIANCE: f64 = 1e-9;

/// `R(rpy) = Rz(yaw) Ry(pitch) Rx(roll)` and its derivatives by roll, pitch and yaw.
fn rotation_and_derivatives(roll: f64, pitch: f64, yaw: f64) -> [Matrix3<f64>; 4] {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
    let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
    let rz = Matrix3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0);
    let drx = Matrix3::new(0.0, 0.0, 0.0, 0.0, -sr, -cr, 0.0, cr, -sr);
    let dry = Matrix3::new(-sp, 0.0, cp, 0.0, 0.0, 0.0, -cp, 0.0, -sp);
    let drz = Matrix3::new(-sy, -cy, 0.0, cy, -sy, 0.0, 0.0, 0.0, 0.0);
    [rz * ry * rx, rz * ry * drx, rz * dry * rx, drz * ry * rx]
}

/// The motion model over `dt` seconds at `state`: the transfer matrix `A` (so that
/// `f(x) = A(x) x`, robot_localization's `transfer_function_`) and the Jacobian `F` of `f`.
pub fn transfer(state: &StateVector, dt: f64) -> (StateMatrix, StateMatrix) {
    let (roll, pitch, yaw) = (state[ROLL], state[PITCH], state[YAW]);
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let cpi = 1.0 / cp;
    let tp = sp * cpi;
    let [r, dr_droll, dr_dpitch, dr_dyaw] = rotation_and_derivatives(roll, pitch, yaw);

    let mut a = StateMatrix::identity();
    // Position from body velocity and acceleration.
    a.fixed_view_mut::<3, 3>(X, VX).copy_from(&(r * dt));
    a.fixed_view_mut::<3, 3>(X, AX)
        .copy_from(&(r * (0.5 * dt * dt)));
    // Euler angles from body rates.
    a[(ROLL, VROLL)] = dt;
    a[(ROLL, VPITCH)] = sr * tp * dt;
    a[(ROLL, VYAW)] = cr * tp * dt;
    a[(PITCH, VPITCH)] = cr * dt;
    a[(PITCH, VYAW)] = -sr * dt;
    a[(YAW, VPITCH)] = sr * cpi * dt;
    a[(YAW, VYAW)] = cr * cpi * dt;
    // Velocity from acceleration.
    for k in 0..3 {
        a[(VX + k, AX + k)] = dt;
    }

    let mut f = a;
    let v = state.fixed_rows::<3>(VX);
    let acc = state.fixed_rows::<3>(AX);
    let travel = v * dt + acc * (0.5 * dt * dt);
    for (col, d) in [(ROLL, dr_droll), (PITCH, dr_dpitch), (YAW, dr_dyaw)] {
        f.fixed_view_mut::<3, 1>(X, col).copy_from(&(d * travel));
    }
    let (vp, vy) = (state[VPITCH], state[VYAW]);
    f[(ROLL, ROLL)] = 1.0 + (cr * tp * vp - sr * tp * vy) * dt;
    f[(ROLL, PITCH)] = cpi * cpi * (sr * vp + cr * vy) * dt;
    f[(PITCH, ROLL)] = (-sr * vp - cr * vy) * dt;
    f[(YAW, ROLL)] = (cr * cpi * vp - sr * cpi * vy) * dt;
    f[(YAW, PITCH)] = tp * cpi * (sr * vp + cr * vy) * dt;
    (a, f)
}

/// `f(x)` over `dt`: the state moved by the motion model, angles wrapped.
pub fn propagate(state: &StateVector, dt: f64) -> StateVector {
    let (a, _) = transfer(state, dt);
    let mut next = a * state;
    for i in [ROLL, PITCH, YAW] {
        next[i] = wrap_angle(next[i]);
    }
    next
}

impl Ekf {
    /// A filter with these `process_noise_covariance` and `initial_estimate_covariance`.
    pub fn new(
        process_noise: StateMatrix,
        initial_covariance: StateMatrix,
        dynamic_process_noise: bool,
    ) -> Self {
        Self {
            state: StateVector::zeros(),
            covariance: initial_covariance,
            last_measurement_ns: 0,
            initialized: false,
            process_noise,
            dynamic_process_noise,
        }
    }

    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            state: self.state,
            covariance: self.covariance,
            last_measurement_ns: self.last_measurement_ns,
            initialized: self.initialized,
        }
    }

    pub fn restore(&mut self, s: &Snapshot) {
        self.state = s.state;
        self.covariance = s.covariance;
        self.last_measurement_ns = s.last_measurement_ns;
        self.initialized = s.initialized;
    }

    /// The state predicted to `stamp_ns` (the filter unchanged); the state itself if
    /// `stamp_ns` is not later than the filter's time.
    pub fn state_at(&self, stamp_ns: i64) -> StateVector {
        let dt = stamp_ns.saturating_sub(self.last_measurement_ns) as f64 * 1e-9;
        if self.initialized && dt > 0.0 {
            propagate(&self.state, dt)
        } else {
            self.state
        }
    }

    /// Predicts `dt` seconds ahead (`Ekf::predict`).
    pub fn predict(&mut self, dt: f64) {
        let (a, f) = transfer(&self.state, dt);
        let mut q = self.process_noise;
        if self.dynamic_process_noise {
            // `FilterBase::computeDynamicProcessNoiseCovariance`: the pose block scaled by
            // the squared norm of the body twist.
            let speed2 = self.state.fixed_rows::<6>(VX).norm_squared();
            let block = q.fixed_view::<6, 6>(X, X) * speed2;
            q.fixed_view_mut::<6, 6>(X, X).copy_from(&block);
        }
        self.state = a * self.state;
        for i in [ROLL, PITCH, YAW] {
            self.state[i] = wrap_angle(self.state[i]);
        }
        self.covariance = f * self.covariance * f.transpose() + q * dt;
    }

    /// Fuses `m` at the filter's time (`Ekf::correct`).
    pub fn correct(&mut self, m: &Measurement) -> Outcome {
        let indices: Vec<usize> = (0..STATE_SIZE)
            .filter(|&i| m.update[i] && m.z[i].is_finite())
            .collect();
        let n = indices.len();
        if n == 0 {
            return Outcome::Skipped;
        }
        let mut r = DMatrix::<f64>::zeros(n, n);
        let mut innovation = DVector::<f64>::zeros(n);
        let mut h = DMatrix::<f64>::zeros(n, STATE_SIZE);
        for (a, &i) in indices.iter().enumerate() {
            for (b, &j) in indices.iter().enumerate() {
                r[(a, b)] = m.covariance[(i, j)];
            }
            r[(a, a)] = r[(a, a)].abs().max(MIN_VARIANCE);
            h[(a, i)] = 1.0;
            innovation[a] = m.z[i] - self.state[i];
            if is_angle(i) {
                innovation[a] = wrap_angle(innovation[a]);
            }
        }
        if !r.iter().all(|v| v.is_finite()) {
            return Outcome::Skipped;
        }
        let p =
            DMatrix::<f64>::from_column_slice(STATE_SIZE, STATE_SIZE, self.covariance.as_slice());
        let pht = &p * h.transpose();
        let s = &h * &pht + &r;
        let Some(s_inv) = s.try_inverse() else {
            return Outcome::Skipped;
        };
        let squared_mahalanobis = innovation.dot(&(&s_inv * &innovation));
        let threshold = m.rejection_threshold;
        let inside_gate = squared_mahalanobis < threshold * threshold;
        if !inside_gate {
            return Outcome::Rejected {
                squared_mahalanobis,
                threshold,
            };
        }
        let k = &pht * &s_inv;
        let dx = &k * &innovation;
        let gain_residual = DMatrix::<f64>::identity(STATE_SIZE, STATE_SIZE) - &k * &h;
        let p_new = &gain_residual * &p * gain_residual.transpose() + &k * &r * k.transpose();
        for (x, d) in self.state.iter_mut().zip(dx.iter()) {
            *x += d;
        }
        for i in [ROLL, PITCH, YAW] {
            self.state[i] = wrap_angle(self.state[i]);
        }
        self.covariance.copy_from_slice(p_new.as_slice());
        Outcome::Fused
    }

    /// Predicts to `m`'s stamp and fuses it, or initialises the filter with it
    /// (`FilterBase::processMeasurement`).
    pub fn process(&mut self, m: &Measurement) -> Outcome {
        if !self.initialized {
            let measured = |i: &usize| m.update[*i] && m.z[*i].is_finite();
            for i in (0..STATE_SIZE).filter(measured) {
                self.state[i] = m.z[i];
                for j in (0..STATE_SIZE).filter(measured) {
                    if m.covariance[(i, j)].is_finite() {
                        self.covariance[(i, j)] = m.covariance[(i, j)];
                    }
                }
            }
            self.initialized = true;
            self.last_measurement_ns = m.stamp_ns;
            return Outcome::Initialized;
        }
        let delta_ns = m.stamp_ns.saturating_sub(self.last_measurement_ns);
        if delta_ns > 0 {
            self.predict(delta_ns as f64 * 1e-9);
        }
        let outcome = self.correct(m);
        if delta_ns >= 0 {
            self.last_measurement_ns = m.stamp_ns;
        }
        outcome
    }
}

/// The default `process_noise_covariance` diagonal (`FilterBase::reset`, and the
/// `params/ekf.yaml` template): x y z roll pitch yaw vx vy vz vroll vpitch vyaw ax ay az.
pub const DEFAULT_PROCESS_NOISE: [f64; STATE_SIZE] = [
    0.05, 0.05, 0.06, 0.03, 0.03, 0.06, 0.025, 0.025, 0.04, 0.01, 0.01, 0.02, 0.01, 0.01, 0.015,
];

/// The default `initial_estimate_covariance` diagonal (`FilterBase::reset`).
pub const DEFAULT_INITIAL_COVARIANCE: f64 = 1e-9;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Source;
    use crate::state::{VY, Y};

    fn some_state() -> StateVector {
        StateVector::from_column_slice(&[
            1.0, -2.0, 0.3, 0.2, -0.3, 2.5, 1.2, -0.4, 0.1, 0.05, -0.2, 0.6, 0.3, -0.1, 0.2,
        ])
    }

    /// The analytic Jacobian is the derivative of the motion model: a sign or a factor
    /// wrong anywhere shows as a difference far above the finite-difference error.
    #[test]
    fn the_jacobian_matches_finite_differences() {
        let x = some_state();
        let dt = 0.1;
        let (_, f) = transfer(&x, dt);
        let h = 1e-6;
        for j in 0..STATE_SIZE {
            let (mut plus, mut minus) = (x, x);
            plus[j] += h;
            minus[j] -= h;
            let (ap, _) = transfer(&plus, dt);
            let (am, _) = transfer(&minus, dt);
            let column = (ap * plus - am * minus) / (2.0 * h);
            for i in 0..STATE_SIZE {
                assert!(
                    (column[i] - f[(i, j)]).abs() < 1e-7,
                    "dF[{i}]/dx[{j}]: numeric {} analytic {}",
                    column[i],
                    f[(i, j)]
                );
            }
        }
    }

    #[test]
    fn a_robot_driving_forward_moves_along_its_heading() {
        let mut x = StateVector::zeros();
        x[YAW] = std::f64::consts::FRAC_PI_2;
        x[VX] = 2.0;
        x[VYAW] = 0.0;
        let next = propagate(&x, 0.5);
        assert!(
            (next[X]).abs() < 1e-12 && (next[Y] - 1.0).abs() < 1e-12,
            "{next}"
        );
    }

    #[test]
    fn the_covariance_grows_by_dt_times_q_and_a_measurement_shrinks_it() {
        let q = StateMatrix::from_diagonal(&StateVector::from_column_slice(&DEFAULT_PROCESS_NOISE));
        let mut ekf = Ekf::new(q, StateMatrix::identity() * 1e-9, false);
        let mut m = Measurement::new(0, Source::WheelOdometry, f64::MAX);
        m.set(VX, 0.0, 1e-4, true);
        assert_eq!(ekf.process(&m), Outcome::Initialized);
        let mut m2 = Measurement::new(100_000_000, Source::WheelOdometry, f64::MAX);
        m2.set(VY, 0.0, 1e-4, true);
        ekf.process(&m2);
        // x's variance: 1e-9 + 0.1 s · 0.05 + the velocity's contribution (1e-4 · 0.01).
        assert!(
            (ekf.covariance[(X, X)] - (1e-9 + 0.005 + 1e-6)).abs() < 1e-8,
            "{}",
            ekf.covariance[(X, X)]
        );
        assert!(ekf.covariance[(VY, VY)] < 1e-4, "fused vy");
        assert_eq!(ekf.last_measurement_ns, 100_000_000);
    }

    #[test]
    fn the_gate_rejects_beyond_its_threshold_and_leaves_the_state() {
        let mut ekf = Ekf::new(StateMatrix::zeros(), StateMatrix::identity(), false);
        ekf.initialized = true;
        // Innovation 3 with S = 1 + 1: squared distance 4.5.
        let mut m = Measurement::new(0, Source::Gnss, 2.0);
        m.set(X, 3.0, 1.0, true);
        let before = ekf.snapshot();
        match ekf.process(&m) {
            Outcome::Rejected {
                squared_mahalanobis,
                ..
            } => assert!((squared_mahalanobis - 4.5).abs() < 1e-12),
            other => panic!("expected a rejection, got {other:?}"),
        }
        assert_eq!(ekf.snapshot(), before);
        m.rejection_threshold = 2.2;
        assert_eq!(ekf.process(&m), Outcome::Fused);
        assert!(
            (ekf.state[X] - 1.5).abs() < 1e-12,
            "half way: {}",
            ekf.state[X]
        );
    }
}
