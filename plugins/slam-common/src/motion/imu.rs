//! IMU preintegration on the manifold (Forster, Carlone, Dellaert and Scaramuzza,
//! "On-Manifold Preintegration for Real-Time Visual-Inertial Odometry", T-RO 2017, §V–VI):
//! the rotation, velocity and position increments between two instants, expressed in the
//! first instant's body frame so that they do not depend on the (unknown) starting state,
//! with their Jacobians with respect to the biases, so that a new bias estimate corrects
//! them to first order without integrating again (eq. 44).
//!
//! Plugins use it to predict the state at a later time (the initial guess of scan
//! registration, per-point poses for deskewing); the factor graph builds its own IMU
//! factors from the same samples.

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use crate::factor_graph::backend::{ImuBias, ImuSample};

/// Pose and velocity of the IMU: `world_from_imu`, and velocity in the world, m/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavState {
    pub world_from_imu: Isometry3<f64>,
    pub velocity_mps: Vector3<f64>,
}

/// Preintegrated increments ΔR, Δv, Δp over `dt_s`, for the bias `bias` they were
/// integrated with.
#[derive(Debug, Clone, PartialEq)]
pub struct Preintegrated {
    pub dt_s: f64,
    pub delta_r: UnitQuaternion<f64>,
    pub delta_v: Vector3<f64>,
    pub delta_p: Vector3<f64>,
    pub bias: ImuBias,
    d_r_d_bg: Matrix3<f64>,
    d_v_d_ba: Matrix3<f64>,
    d_v_d_bg: Matrix3<f64>,
    d_p_d_ba: Matrix3<f64>,
    d_p_d_bg: Matrix3<f64>,
}

impl Preintegrated {
    pub fn new(bias: ImuBias) -> Self {
        Self {
            dt_s: 0.0,
            delta_r: UnitQuaternion::identity(),
            delta_v: Vector3::zeros(),
            delta_p: Vector3::zeros(),
            bias,
            d_r_d_bg: Matrix3::zeros(),
            d_v_d_ba: Matrix3::zeros(),
            d_v_d_bg: Matrix3::zeros(),
            d_p_d_ba: Matrix3::zeros(),
            d_p_d_bg: Matrix3::zeros(),
        }
    }

    /// Adds one sample (eqs. 24–26 for the increments, Appendix B for the Jacobians).
    pub fn integrate(&mut self, sample: &ImuSample) {
        let dt = sample.dt_s;
        if dt <= 0.0 {
            return;
        }
        let a = sample.accel_mps2 - self.bias.accel_mps2;
        let w = (sample.gyro_rps - self.bias.gyro_rps) * dt;
        let r = self.delta_r.to_rotation_matrix().into_inner();
        let a_hat = a.cross_matrix();
        // Position and velocity first: they use ΔR and ∂ΔR/∂bg at the start of the step.
        self.d_p_d_ba += self.d_v_d_ba * dt - 0.5 * r * dt * dt;
        self.d_p_d_bg += self.d_v_d_bg * dt - 0.5 * r * a_hat * self.d_r_d_bg * dt * dt;
        self.d_v_d_ba -= r * dt;
        self.d_v_d_bg -= r * a_hat * self.d_r_d_bg * dt;
        self.delta_p += self.delta_v * dt + 0.5 * (r * a) * dt * dt;
        self.delta_v += r * a * dt;
        let step = UnitQuaternion::from_scaled_axis(w);
        self.d_r_d_bg = step.to_rotation_matrix().into_inner().transpose() * self.d_r_d_bg
            - right_jacobian(&w) * dt;
        self.delta_r = UnitQuaternion::new_normalize((self.delta_r * step).into_inner());
        self.dt_s += dt;
    }

    /// The state after the integrated interval, from the state before it, for gravity
    /// `gravity_mps2` (pointing along −z of the world) and a bias estimate `bias`
    /// (eq. 44's first-order correction from the integration bias).
    pub fn predict(&self, start: &NavState, gravity_mps2: f64, bias: &ImuBias) -> NavState {
        let dba = bias.accel_mps2 - self.bias.accel_mps2;
        let dbg = bias.gyro_rps - self.bias.gyro_rps;
        let delta_r = self.delta_r * UnitQuaternion::from_scaled_axis(self.d_r_d_bg * dbg);
        let delta_v = self.delta_v + self.d_v_d_ba * dba + self.d_v_d_bg * dbg;
        let delta_p = self.delta_p + self.d_p_d_ba * dba + self.d_p_d_bg * dbg;
        let g = Vector3::new(0.0, 0.0, -gravity_mps2);
        let t = self.dt_s;
        let r_i = start.world_from_imu.rotation;
        let p_i = start.world_from_imu.translation.vector;
        let v_i = start.velocity_mps;
        NavState {
            world_from_imu: Isometry3::from_parts(
                Translation3::from(p_i + v_i * t + 0.5 * g * t * t + r_i * delta_p),
                UnitQuaternion::new_normalize((r_i * delta_r).into_inner()),
            ),
            velocity_mps: v_i + g * t + r_i * delta_v,
        }
    }
}

/// The right Jacobian of SO(3) at `phi` (Forster et al. 2017, eq. 8).
pub fn right_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let hat = phi.cross_matrix();
    if theta < 1e-6 {
        return Matrix3::identity() - 0.5 * hat;
    }
    let t2 = theta * theta;
    Matrix3::identity() - (1.0 - theta.cos()) / t2 * hat
        + (theta - theta.sin()) / (t2 * theta) * hat * hat
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body spinning about z at a constant rate while accelerating along its own x:
    /// the closed form is known, and a small bias change must be absorbed to first order.
    #[test]
    fn matches_closed_form_and_corrects_bias_to_first_order() {
        let g = 9.81;
        let omega = 0.3;
        let accel_body = Vector3::new(0.5, 0.0, g); // level: the accelerometer also feels gravity
        let dt = 0.005;
        let n = 400;
        let true_bias = ImuBias {
            accel_mps2: Vector3::new(0.02, -0.01, 0.03),
            gyro_rps: Vector3::new(0.001, -0.002, 0.003),
        };
        let sample = |b: &ImuBias| ImuSample {
            dt_s: dt,
            accel_mps2: accel_body + b.accel_mps2,
            gyro_rps: Vector3::new(0.0, 0.0, omega) + b.gyro_rps,
        };
        let start = NavState {
            world_from_imu: Isometry3::identity(),
            velocity_mps: Vector3::zeros(),
        };

        let mut exact = Preintegrated::new(true_bias);
        let mut wrong = Preintegrated::new(ImuBias::default());
        for _ in 0..n {
            exact.integrate(&sample(&true_bias));
            wrong.integrate(&sample(&true_bias));
        }
        let t = n as f64 * dt;
        let truth_yaw = omega * t;
        // Velocity of a body accelerating at a along its heading that turns at ω: v = a/ω (sin ωt, 1 − cos ωt).
        let truth_v = Vector3::new(
            0.5 / omega * truth_yaw.sin(),
            0.5 / omega * (1.0 - truth_yaw.cos()),
            0.0,
        );
        let predicted = exact.predict(&start, g, &true_bias);
        assert!(
            (predicted.velocity_mps - truth_v).norm() < 2e-3,
            "velocity {:?} vs {truth_v:?}",
            predicted.velocity_mps
        );
        let yaw = predicted.world_from_imu.rotation.euler_angles().2;
        assert!((yaw - truth_yaw).abs() < 1e-9, "yaw {yaw} vs {truth_yaw}");

        // Integrated with a zero bias, corrected to the true one by the Jacobians.
        let corrected = wrong.predict(&start, g, &true_bias);
        let uncorrected = wrong.predict(&start, g, &ImuBias::default());
        let err = |s: &NavState| {
            (s.world_from_imu.translation.vector - predicted.world_from_imu.translation.vector)
                .norm()
        };
        assert!(
            err(&corrected) < 0.05 * err(&uncorrected),
            "first-order correction {} vs none {}",
            err(&corrected),
            err(&uncorrected)
        );
        assert!((corrected.velocity_mps - predicted.velocity_mps).norm() < 1e-3);
    }
}
