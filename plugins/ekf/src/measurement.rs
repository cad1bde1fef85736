//! A measurement as robot_localization's filter takes it (`filter_common.h`'s
//! `Measurement`): a full-size vector and covariance of which only the variables its update
//! vector marks are fused, a time stamp, and a Mahalanobis rejection threshold.

use crate::state::{AZ, PITCH, ROLL, STATE_SIZE, StateMatrix, StateVector, VPITCH, VROLL, VZ, Z};

/// Where a measurement came from: the sensor and, for the IMU, which of its three parts
/// (robot_localization splits an IMU message into pose, twist and acceleration
/// measurements, each with its own threshold).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    WheelOdometry,
    ImuOrientation,
    ImuAngularVelocity,
    ImuAcceleration,
    Gnss,
}

/// One measurement of some of the state's variables.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub stamp_ns: i64,
    pub source: Source,
    /// The measured values (entries not in `update` are ignored).
    pub z: StateVector,
    pub covariance: StateMatrix,
    /// Which variables this measurement updates (robot_localization's `update_vector`).
    pub update: [bool; STATE_SIZE],
    /// Mahalanobis distance (in standard deviations) beyond which it is rejected;
    /// `f64::MAX` turns the gate off, robot_localization's default.
    pub rejection_threshold: f64,
}

impl Measurement {
    /// A measurement of nothing yet, at `stamp_ns`.
    pub fn new(stamp_ns: i64, source: Source, rejection_threshold: f64) -> Self {
        Self {
            stamp_ns,
            source,
            z: StateVector::zeros(),
            covariance: StateMatrix::zeros(),
            update: [false; STATE_SIZE],
            rejection_threshold,
        }
    }

    /// Measures variable `i` as `value` with variance `variance`, if `enabled` and both are
    /// finite (robot_localization leaves out a NaN or infinite value the same way).
    pub fn set(&mut self, i: usize, value: f64, variance: f64, enabled: bool) {
        if enabled && value.is_finite() && variance.is_finite() {
            self.z[i] = value;
            self.covariance[(i, i)] = variance;
            self.update[i] = true;
        }
    }

    /// Whether the measurement updates anything.
    pub fn is_empty(&self) -> bool {
        !self.update.iter().any(|&u| u)
    }

    /// `two_d_mode`: robot_localization's `RosFilter::forceTwoD` makes every measurement
    /// also measure z, roll, pitch, vz, vroll, vpitch and az as 0 with variance 1e-6, which
    /// holds the state to the plane. (Rows and columns of those variables are cleared
    /// first, so that no cross-covariance of a 3D measurement survives.)
    pub fn force_two_d(&mut self) {
        for i in [Z, ROLL, PITCH, VZ, VROLL, VPITCH, AZ] {
            self.covariance.row_mut(i).fill(0.0);
            self.covariance.column_mut(i).fill(0.0);
            self.set(i, 0.0, 1e-6, true);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{VX, X};

    #[test]
    fn two_d_mode_measures_the_out_of_plane_variables_as_zero() {
        let mut m = Measurement::new(0, Source::WheelOdometry, f64::MAX);
        assert!(m.is_empty());
        m.set(VX, 1.0, 0.01, true);
        m.set(X, 5.0, 0.01, false);
        m.z[Z] = 3.0;
        m.covariance[(VX, Z)] = 0.5;
        m.force_two_d();
        assert!(m.update[VX] && !m.update[X]);
        for i in [Z, ROLL, PITCH, VZ, VROLL, VPITCH, AZ] {
            assert!(m.update[i], "variable {i} measured");
            assert_eq!((m.z[i], m.covariance[(i, i)]), (0.0, 1e-6));
        }
        assert_eq!(m.covariance[(VX, Z)], 0.0, "cross-covariance cleared");
        assert_eq!(m.z[VX], 1.0);
    }
}
