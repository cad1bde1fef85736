//! The base's roll and pitch from a 6-axis IMU: Mahony, Hamel and Pflimlin's explicit
//! complementary filter on SO(3) ("Nonlinear complementary filters on the special orthogonal
//! group", IEEE Transactions on Automatic Control 53(5), 2008), with gravity as the one
//! reference direction. The gyro's rates are integrated; the accelerometer's specific force,
//! less the acceleration the wheels say the base has, points up, and the rotation that
//! turns the estimate's up towards it corrects the rates (gain `k_p`), its integral the
//! gyro's bias (gain `k_i`). Yaw is unobservable from gravity and is not used.

use nalgebra::{UnitQuaternion, Vector3};

/// Standard gravity, m/s².
const GRAVITY: f64 = 9.806_65;

#[derive(Debug, Clone)]
pub struct Tilt {
    k_p: f64,
    k_i: f64,
    /// The base's attitude (world from base; its yaw is arbitrary).
    world_r_base: Option<UnitQuaternion<f64>>,
    gyro_bias: Vector3<f64>,
    last_ns: Option<i64>,
}

impl Tilt {
    pub fn new(k_p: f64, k_i: f64) -> Self {
        Self {
            k_p,
            k_i,
            world_r_base: None,
            gyro_bias: Vector3::zeros(),
            last_ns: None,
        }
    }

    /// One IMU sample in the base frame: angular rate (rad/s), specific force (m/s²), and
    /// the base's own acceleration as the wheels tell it (m/s²), taken out of the specific
    /// force before it is read as gravity.
    pub fn update(
        &mut self,
        stamp_ns: i64,
        gyro: &Vector3<f64>,
        specific_force: &Vector3<f64>,
        base_acceleration: &Vector3<f64>,
    ) {
        let up = specific_force - base_acceleration;
        let Some(world_r_base) = self.world_r_base else {
            // The first sample: gravity alone sets roll and pitch.
            let roll = up.y.atan2(up.z);
            let pitch = (-up.x).atan2(up.y.hypot(up.z));
            self.world_r_base = Some(UnitQuaternion::from_euler_angles(roll, pitch, 0.0));
            self.last_ns = Some(stamp_ns);
            return;
        };
        let dt = self
            .last_ns
            .map_or(0.0, |last| (stamp_ns - last).max(0) as f64 * 1e-9);
        self.last_ns = Some(stamp_ns);
        // Trust the accelerometer only while its norm is near gravity's (no jolt).
        let correction = if up.norm() > 0.0 && (up.norm() - GRAVITY).abs() < 0.1 * GRAVITY {
            let measured = up.normalize();
            let estimated = world_r_base.inverse() * Vector3::z();
            measured.cross(&estimated)
        } else {
            Vector3::zeros()
        };
        self.gyro_bias -= self.k_i * correction * dt;
        let rate = gyro - self.gyro_bias + self.k_p * correction;
        self.world_r_base = Some(world_r_base * UnitQuaternion::from_scaled_axis(rate * dt));
    }

    /// Roll and pitch, rad (ZYX Euler angles); None before the first sample.
    pub fn roll_pitch(&self) -> Option<(f64, f64)> {
        self.world_r_base.map(|q| {
            let (roll, pitch, _) = q.euler_angles();
            (roll, pitch)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A base pitched nose-down by 0.1 rad and rolled by -0.05 rad, at rest, with a gyro
    /// bias of 0.01 rad/s about its y axis: the filter starts from gravity, and the bias
    /// does not drag the pitch away (the integral term learns it).
    #[test]
    fn a_tilted_base_at_rest_keeps_its_tilt_despite_gyro_bias() {
        let truth = UnitQuaternion::from_euler_angles(-0.05, 0.1, 0.3);
        let force = truth.inverse() * Vector3::new(0.0, 0.0, GRAVITY);
        let mut tilt = Tilt::new(0.5, 0.05);
        for k in 0..200 * 120 {
            let t = k * 5_000_000;
            tilt.update(t, &Vector3::new(0.0, 0.01, 0.0), &force, &Vector3::zeros());
        }
        let (roll, pitch) = tilt.roll_pitch().expect("estimated");
        assert!((roll + 0.05).abs() < 1e-3, "roll {roll}");
        assert!((pitch - 0.1).abs() < 1e-3, "pitch {pitch}");
    }

    /// Pitching up and down at 0.5 Hz, the gyro carries the motion the slow accelerometer
    /// correction cannot follow.
    #[test]
    fn it_follows_a_rocking_base() {
        let mut tilt = Tilt::new(0.5, 0.05);
        let (amplitude, w) = (0.05, std::f64::consts::PI);
        let mut worst: f64 = 0.0;
        for k in 0..200 * 20 {
            let s = k as f64 * 0.005;
            let pitch = amplitude * (w * s).sin();
            let rate = amplitude * w * (w * s).cos();
            let force = UnitQuaternion::from_euler_angles(0.0, pitch, 0.0).inverse()
                * Vector3::new(0.0, 0.0, GRAVITY);
            tilt.update(
                k * 5_000_000,
                &Vector3::new(0.0, rate, 0.0),
                &force,
                &Vector3::zeros(),
            );
            if s > 1.0 {
                worst = worst.max((tilt.roll_pitch().expect("estimated").1 - pitch).abs());
            }
        }
        assert!(worst < 2e-3, "worst pitch error {worst}");
    }
}
