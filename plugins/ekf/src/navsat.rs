//! GNSS fixes as position measurements of the base in the filter's frame, after
//! robot_localization's `navsat_transform_node` (its documentation's "Integrating GPS
//! Data" and `src/navsat_transform.cpp`'s `computeTransform`, `getRobotOriginUtmPose`,
//! `getRobotOriginWorldPose` and `prepareGpsOdometry`).
//!
//! navsat_transform works in UTM; here the receiver already gives east-north-up metres
//! from the datum, which plays UTM's part (both are east-north-up Cartesian frames; over a
//! field the difference is a constant offset).
//!
//! 1. Alignment, once, at the first usable fix for which a heading is known: the base's
//!    position in ENU is the antenna's minus the lever arm rotated by the base's attitude
//!    (the IMU's orientation, whose yaw is absolute, plus `magnetic_declination_radians`
//!    and `yaw_offset`); with the heading that makes `enu_from_base`, and with the
//!    filter's pose at the same instant `odom_from_base`, each with its yaw only, so
//!    `odom_from_enu = odom_from_base · enu_from_base⁻¹`. (navsat_transform multiplies the
//!    filter's full orientation, which tilts the transform if the robot stood tilted at
//!    that instant; both frames are gravity-aligned, so only yaw belongs in it.) The fix
//!    that defines the transform is not fused: its innovation is zero by construction.
//! 2. Every later fix: the antenna's position in odom, minus the lever arm rotated by the
//!    base's current attitude, measures the base's x and y (and z outside `two_d_mode`);
//!    the fix's covariance rotated into odom is the measurement's.
//!
//! Both steps are `slam_common::gnss`'s, which the SLAM plugins share.
//!
//! navsat_transform needs an absolute heading. Without one (an IMU that reports no
//! orientation, and `use_odometry_yaw` false) the plugin waits, and if the rig's IMU
//! cannot report one, never fuses GNSS (the system says so once, [`crate::system`]).

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
use slam_common::gnss::{Fix, body_in_frame, frame_from_enu};

use crate::measurement::{Measurement, Source};
use crate::state::{StateVector, X, Y, YAW, Z};

/// The datum's alignment and the conversion of fixes.
#[derive(Debug, Clone)]
pub struct NavSat {
    /// The antenna in the base frame (the rig's `base_from_sensor` of the `gnss` sensor).
    lever_arm: Vector3<f64>,
    two_d_mode: bool,
    threshold: f64,
    odom_from_enu: Option<Isometry3<f64>>,
}

impl NavSat {
    pub fn new(base_from_antenna: &Isometry3<f64>, two_d_mode: bool, threshold: f64) -> Self {
        Self {
            lever_arm: base_from_antenna.translation.vector,
            two_d_mode,
            threshold,
            odom_from_enu: None,
        }
    }

    /// The transform from the datum's ENU frame to the filter's, once aligned.
    pub fn odom_from_enu(&self) -> Option<&Isometry3<f64>> {
        self.odom_from_enu.as_ref()
    }

    /// Aligns the datum with the filter's frame (navsat_transform's `computeTransform`):
    /// `antenna_enu` the fix, `enu_r_base` the base's attitude in ENU with its heading
    /// corrected, `state` the filter's state at the fix's stamp.
    pub fn align(
        &mut self,
        antenna_enu: &Vector3<f64>,
        enu_r_base: &UnitQuaternion<f64>,
        state: &StateVector,
    ) {
        self.odom_from_enu = Some(frame_from_enu(
            &Vector3::new(state[X], state[Y], state[Z]),
            state[YAW],
            enu_r_base,
            &self.lever_arm,
            antenna_enu,
        ));
    }

    /// The fix as a measurement of the base's position (navsat_transform's
    /// `prepareGpsOdometry` with `getRobotOriginWorldPose`); `None` before alignment.
    /// `odom_r_base` is the base's current attitude in the filter's frame.
    pub fn measurement(
        &self,
        stamp_ns: i64,
        antenna_enu: &Vector3<f64>,
        covariance_enu: &Matrix3<f64>,
        odom_r_base: &UnitQuaternion<f64>,
    ) -> Option<Measurement> {
        let odom_from_enu = self.odom_from_enu?;
        let fix = Fix {
            stamp_ns,
            position_enu_m: *antenna_enu,
            covariance_enu_m2: *covariance_enu,
        };
        let (base_odom, covariance) =
            body_in_frame(&odom_from_enu, &fix, odom_r_base, &self.lever_arm);
        let axes = if self.two_d_mode { 2 } else { 3 };
        let mut m = Measurement::new(stamp_ns, Source::Gnss, self.threshold);
        for a in 0..axes {
            m.set(X + a, base_odom[a], covariance[(a, a)], true);
            for b in (0..axes).filter(|&b| b != a) {
                m.covariance[(X + a, X + b)] = covariance[(a, b)];
            }
        }
        if self.two_d_mode {
            m.force_two_d();
        }
        Some(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::ROLL;
    use nalgebra::Translation3;

    /// A robot at (20, -8) in ENU heading 0.6 rad, whose filter believes it is at (1, 2)
    /// heading 0.5 rad in odom: a fix there, with its antenna behind and above the base,
    /// maps back onto the filter's pose, and a fix 1 m further east lands 1 m along the
    /// rotated east axis in odom.
    #[test]
    fn the_datum_aligns_with_the_filter_and_fixes_map_into_odom() {
        let lever = Vector3::new(-0.3, 0.1, 1.7);
        let mut navsat = NavSat::new(
            &Isometry3::from_parts(Translation3::from(lever), UnitQuaternion::identity()),
            true,
            f64::MAX,
        );
        let enu_r_base = UnitQuaternion::from_euler_angles(0.02, -0.03, 0.6);
        let antenna = Vector3::new(20.0, -8.0, 0.0) + enu_r_base * lever;
        let mut state = StateVector::zeros();
        state[X] = 1.0;
        state[Y] = 2.0;
        state[YAW] = 0.5;
        state[ROLL] = 0.0;
        assert!(
            navsat
                .measurement(0, &antenna, &Matrix3::identity(), &enu_r_base)
                .is_none()
        );
        navsat.align(&antenna, &enu_r_base, &state);

        let odom_r_base = UnitQuaternion::from_euler_angles(0.02, -0.03, 0.5);
        let cov = Matrix3::from_diagonal(&Vector3::new(0.04, 0.01, 0.09));
        let m = navsat
            .measurement(1, &antenna, &cov, &odom_r_base)
            .expect("aligned");
        assert!(
            (m.z[X] - 1.0).abs() < 1e-9 && (m.z[Y] - 2.0).abs() < 1e-9,
            "{}",
            m.z
        );
        assert!(m.update[X] && m.update[Y] && m.z[Z] == 0.0);

        let east = antenna + Vector3::new(1.0, 0.0, 0.0);
        let m = navsat
            .measurement(2, &east, &cov, &odom_r_base)
            .expect("aligned");
        let (s, c) = (-0.1f64).sin_cos();
        assert!((m.z[X] - (1.0 + c)).abs() < 1e-9 && (m.z[Y] - (2.0 + s)).abs() < 1e-9);
        // The east variance 0.04 and north 0.01 rotated by -0.1 rad.
        let want_xx = 0.04 * c * c + 0.01 * s * s;
        assert!((m.covariance[(X, X)] - want_xx).abs() < 1e-12);
        assert!((m.covariance[(X, Y)] - (0.04 - 0.01) * c * s).abs() < 1e-12);
    }
}
