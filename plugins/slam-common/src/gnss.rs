//! GNSS fixes in a SLAM or filter frame: the alignment robot_localization's
//! `navsat_transform_node` computes (its `computeTransform`, `getRobotOriginWorldPose` and
//! `prepareGpsOdometry`; the documentation's "Integrating GPS Data"), shared by every
//! plugin that takes GNSS (`ekf`, lio-sam, staticmapping, rtabmap), so that all of them put
//! a fix in their frame the same way.
//!
//! The receiver gives the antenna's position in east-north-up metres from the datum, which
//! plays the part of navsat_transform's UTM (both are east-north-up Cartesian frames; over
//! a field the difference is a constant offset). A system's own frame (a SLAM map, a
//! filter's odom) starts wherever the robot started, heading wherever it headed, so one
//! transform `frame_from_enu` ties them: at one instant the body's pose in the frame is
//! known (the estimate) and its heading in ENU is known (the IMU's absolute yaw); the
//! transform is the rotation about the vertical by the difference of the two headings and
//! the translation that puts the body's ENU position (the antenna's minus the lever arm,
//! turned by the body's attitude) on its position in the frame. Only yaw belongs in it: both
//! frames are gravity-aligned, and a tilt at the aligning instant would tilt every later
//! fix (navsat_transform multiplies the full orientation; here roll and pitch are dropped).

use std::collections::VecDeque;

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

/// The heading about the vertical (the z-y-x yaw) of a rotation, rad.
pub fn yaw(r: &UnitQuaternion<f64>) -> f64 {
    let m = r.to_rotation_matrix();
    m[(1, 0)].atan2(m[(0, 0)])
}

/// A usable fix: the antenna's position and covariance in east-north-up, m and m².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    pub stamp_ns: i64,
    pub position_enu_m: Vector3<f64>,
    pub covariance_enu_m2: Matrix3<f64>,
}

/// The antenna's horizontal distance from a sensor, m (`sensor_from_base` the sensor's
/// mount inverted, `base_from_antenna` the receiver's): the spread a fix's position gets
/// as a prior for the sensor's before the heading says which way the lever points.
pub fn horizontal_lever_m(
    sensor_from_base: &Isometry3<f64>,
    base_from_antenna: &Isometry3<f64>,
) -> f64 {
    (sensor_from_base * base_from_antenna)
        .translation
        .vector
        .xy()
        .norm()
}

/// navsat_transform's alignment: `frame_from_enu`, a rotation about the vertical and a
/// translation, from one instant at which the body's position `body_in_frame` and heading
/// `frame_yaw` in the system's frame are estimated and the body's attitude `enu_r_body` in
/// ENU is measured (absolute yaw), with the antenna's lever arm `body_from_antenna` and
/// the fix's antenna position `antenna_enu`.
pub fn frame_from_enu(
    body_in_frame: &Vector3<f64>,
    frame_yaw: f64,
    enu_r_body: &UnitQuaternion<f64>,
    body_from_antenna: &Vector3<f64>,
    antenna_enu: &Vector3<f64>,
) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), frame_yaw - yaw(enu_r_body));
    let body_enu = antenna_enu - enu_r_body * body_from_antenna;
    Isometry3::from_parts(
        Translation3::from(body_in_frame - rotation * body_enu),
        rotation,
    )
}

/// A fix carried into the system's frame: the body's position there (the antenna's minus
/// the lever arm turned by the body's current attitude `frame_r_body`, navsat_transform's
/// `getRobotOriginWorldPose`) and the covariance turned by the transform's rotation
/// (`prepareGpsOdometry`).
pub fn body_in_frame(
    frame_from_enu: &Isometry3<f64>,
    fix: &Fix,
    frame_r_body: &UnitQuaternion<f64>,
    body_from_antenna: &Vector3<f64>,
) -> (Vector3<f64>, Matrix3<f64>) {
    let antenna = frame_from_enu * Point3::from(fix.position_enu_m);
    let r = frame_from_enu.rotation.to_rotation_matrix().into_inner();
    (
        antenna.coords - frame_r_body * body_from_antenna,
        r * fix.covariance_enu_m2 * r.transpose(),
    )
}

/// The IMU's reported orientations (`enu_from_imu`: the simulator's world is
/// east-north-up) of the last seconds, to look up the absolute heading at a fix's time.
#[derive(Debug, Clone)]
pub struct Orientations {
    history: VecDeque<(i64, UnitQuaternion<f64>)>,
    keep_ns: i64,
    gap_ns: i64,
}

impl Default for Orientations {
    /// Two seconds kept; an orientation at most 50 ms from the time asked for.
    fn default() -> Self {
        Self::new(2_000_000_000, 50_000_000)
    }
}

impl Orientations {
    /// Keeps `keep_ns` of history; [`Orientations::at`] answers within `gap_ns`.
    pub fn new(keep_ns: i64, gap_ns: i64) -> Self {
        Self {
            history: VecDeque::new(),
            keep_ns,
            gap_ns,
        }
    }

    pub fn push(&mut self, stamp_ns: i64, enu_from_imu: UnitQuaternion<f64>) {
        self.history.push_back((stamp_ns, enu_from_imu));
        while self
            .history
            .front()
            .is_some_and(|(t, _)| *t < stamp_ns - self.keep_ns)
        {
            self.history.pop_front();
        }
    }

    /// The reported orientation nearest `t_ns`, if one is close enough.
    pub fn at(&self, t_ns: i64) -> Option<UnitQuaternion<f64>> {
        self.history
            .iter()
            .min_by_key(|(t, _)| (t - t_ns).abs())
            .filter(|(t, _)| (t - t_ns).abs() <= self.gap_ns)
            .map(|(_, q)| *q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A robot at (20, -8) in ENU heading 0.6 rad, slightly tilted, whose estimate puts
    /// it at (1, 2, 0) heading 0.5 rad: the aligning fix maps back onto the estimate, a fix
    /// 1 m further east lands 1 m along the east axis turned by -0.1 rad, and the
    /// covariance turns with it.
    #[test]
    fn the_datum_aligns_with_the_frame_and_fixes_map_into_it() {
        let lever = Vector3::new(-0.3, 0.1, 1.7);
        let enu_r_body = UnitQuaternion::from_euler_angles(0.02, -0.03, 0.6);
        let antenna = Vector3::new(20.0, -8.0, 0.0) + enu_r_body * lever;
        let body = Vector3::new(1.0, 2.0, 0.0);
        let t = frame_from_enu(&body, 0.5, &enu_r_body, &lever, &antenna);
        assert!((yaw(&t.rotation) + 0.1).abs() < 1e-12);

        let frame_r_body = UnitQuaternion::from_euler_angles(0.02, -0.03, 0.5);
        let cov = Matrix3::from_diagonal(&Vector3::new(0.04, 0.01, 0.09));
        let fix = |p: Vector3<f64>| Fix {
            stamp_ns: 0,
            position_enu_m: p,
            covariance_enu_m2: cov,
        };
        let (p, _) = body_in_frame(&t, &fix(antenna), &frame_r_body, &lever);
        assert!((p - body).norm() < 1e-9, "{p}");

        let (p, c) = body_in_frame(
            &t,
            &fix(antenna + Vector3::new(1.0, 0.0, 0.0)),
            &frame_r_body,
            &lever,
        );
        let (s, co) = (-0.1f64).sin_cos();
        assert!((p - body - Vector3::new(co, s, 0.0)).norm() < 1e-9, "{p}");
        assert!((c[(0, 0)] - (0.04 * co * co + 0.01 * s * s)).abs() < 1e-12);
        assert!((c[(0, 1)] - (0.04 - 0.01) * co * s).abs() < 1e-12);
        assert!((c[(2, 2)] - 0.09).abs() < 1e-12);
    }

    #[test]
    fn orientations_answer_near_a_stamp_and_forget_old_ones() {
        let mut o = Orientations::new(1_000, 10);
        for t in (0..=2_000).step_by(20) {
            o.push(
                t,
                UnitQuaternion::from_euler_angles(0.0, 0.0, t as f64 * 1e-3),
            );
        }
        assert!((yaw(&o.at(1_504).unwrap()) - 1.5).abs() < 1e-12);
        assert!(
            o.at(2_011).is_none(),
            "11 ns past the last is beyond the gap"
        );
        assert!(o.at(900).is_none(), "older than the history kept");
        assert!(o.at(1_000).is_some());
    }
}
