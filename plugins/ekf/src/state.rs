//! The filter's state vector, in robot_localization's order (`filter_common.h`'s
//! `StateMembers`; Moore & Stouch 2014, §III): pose in the world frame, then velocities and
//! linear accelerations in the body frame.
//!
//! `x y z roll pitch yaw vx vy vz vroll vpitch vyaw ax ay az`: metres, radians, m/s, rad/s
//! (body rates about the base's axes) and m/s².

use nalgebra::{Isometry3, SMatrix, SVector, Translation3, UnitQuaternion};

/// Number of state variables.
pub const STATE_SIZE: usize = 15;

pub const X: usize = 0;
pub const Y: usize = 1;
pub const Z: usize = 2;
pub const ROLL: usize = 3;
pub const PITCH: usize = 4;
pub const YAW: usize = 5;
pub const VX: usize = 6;
pub const VY: usize = 7;
pub const VZ: usize = 8;
pub const VROLL: usize = 9;
pub const VPITCH: usize = 10;
pub const VYAW: usize = 11;
pub const AX: usize = 12;
pub const AY: usize = 13;
pub const AZ: usize = 14;

/// The variables' names, as robot_localization's configuration comments list them.
pub const NAMES: [&str; STATE_SIZE] = [
    "x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "vroll", "vpitch", "vyaw", "ax", "ay",
    "az",
];

pub type StateVector = SVector<f64, STATE_SIZE>;
pub type StateMatrix = SMatrix<f64, STATE_SIZE, STATE_SIZE>;

/// Whether variable `i` is an angle (its innovations and values are wrapped).
pub fn is_angle(i: usize) -> bool {
    matches!(i, ROLL | PITCH | YAW)
}

/// An angle in [-π, π], as robot_localization's `clampRotation` keeps them.
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if (-PI..=PI).contains(&a) {
        a
    } else {
        (a + PI).rem_euclid(TAU) - PI
    }
}

/// The pose `world_from_base` the state holds (rotation `Rz(yaw) Ry(pitch) Rx(roll)`, ROS's
/// `setRPY`, which is nalgebra's `from_euler_angles`).
pub fn pose(state: &StateVector) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(state[X], state[Y], state[Z]),
        UnitQuaternion::from_euler_angles(state[ROLL], state[PITCH], state[YAW]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_into_minus_pi_to_pi() {
        use std::f64::consts::PI;
        for (a, want) in [
            (0.5, 0.5),
            (PI + 0.1, -PI + 0.1),
            (-PI - 0.1, PI - 0.1),
            (7.0, 7.0 - 2.0 * PI),
        ] {
            assert!(
                (wrap_angle(a) - want).abs() < 1e-12,
                "{a} wrapped to {}",
                wrap_angle(a)
            );
        }
    }
}
