//! Wheel odometry and IMU messages as robot_localization's measurements, in the base frame,
//! with covariances from the rig's datasheet figures (robot_localization takes them from
//! the messages' covariance fields, which the benchmark's messages do not carry).
//!
//! The covariances, per message, from the figures the simulator draws its noise with:
//! - wheel odometry (`odom` noise): vx with standard deviation `hypot(slip_sigma,
//!   scale_error) · |v|` (the relative slip and the wheel-radius error scale the speed);
//!   vy = 0 with the same variance (the base does not slide sideways, no better than it
//!   rolls); vyaw with variance `yaw_rate_noise_density² · rate_hz + (slip_sigma · ω)²`
//!   (the white noise of one sample, a density times √rate, and the slip on the rate);
//! - IMU (`imu` noise): each angular rate with variance `gyro_noise_density² · rate_hz`,
//!   each acceleration with `accel_noise_density² · rate_hz` (Kalibr's discrete-time
//!   noise); the orientation with the rig's `orientation_roll_pitch_sigma_rad²` and
//!   `orientation_yaw_sigma_rad²` where it states them, else `imu0_orientation_sigma_rad²`.
//!
//! A figure the rig lacks counts as 0, and the filter raises any variance under 1e-9 to
//! 1e-9, as robot_localization does. Biases (the gyro's, the odometry's correlated slip)
//! are not in robot_localization's state and are not modelled.

use nalgebra::{Isometry3, Matrix3, UnitQuaternion, Vector3};
use plugin_api::{Imu, SensorSpec, WheelOdometry};

use crate::config::Config;
use crate::measurement::{Measurement, Source};
use crate::state::{AX, PITCH, ROLL, StateVector, VPITCH, VROLL, VX, VY, VYAW, VZ, YAW};

/// A noise figure of `spec`, 0 when absent or not finite.
fn figure(spec: Option<&SensorSpec>, key: &str) -> f64 {
    spec.and_then(|s| s.noise.get(key).copied())
        .filter(|v| v.is_finite())
        .unwrap_or(0.0)
}

fn rate(spec: Option<&SensorSpec>) -> f64 {
    spec.map(|s| s.rate_hz)
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(0.0)
}

/// Turns wheel odometry into a twist measurement (`odom0`).
#[derive(Debug, Clone)]
pub struct WheelOdometryModel {
    speed_relative_sigma: f64,
    slip_sigma: f64,
    yaw_rate_white_variance: f64,
    update: [bool; 15],
    threshold: f64,
    two_d_mode: bool,
}

impl WheelOdometryModel {
    pub fn new(spec: Option<&SensorSpec>, cfg: &Config) -> Self {
        let slip_sigma = figure(spec, "slip_sigma");
        Self {
            speed_relative_sigma: slip_sigma.hypot(figure(spec, "scale_error")),
            slip_sigma,
            yaw_rate_white_variance: figure(spec, "yaw_rate_noise_density").powi(2) * rate(spec),
            update: cfg.odom_update(),
            threshold: cfg.odom0_twist_rejection_threshold,
            two_d_mode: cfg.two_d_mode,
        }
    }

    /// The body twist the encoders measure: vx, vy = vz = 0, vroll = vpitch = 0, vyaw.
    pub fn measurement(&self, odom: &WheelOdometry) -> Measurement {
        let (v, w) = (odom.linear_mps, odom.angular_rps);
        let mut m = Measurement::new(odom.stamp_ns, Source::WheelOdometry, self.threshold);
        let speed_variance = (self.speed_relative_sigma * v).powi(2);
        let values = [
            (VX, v, speed_variance),
            (VY, 0.0, speed_variance),
            (VZ, 0.0, speed_variance),
            (VROLL, 0.0, self.yaw_rate_white_variance),
            (VPITCH, 0.0, self.yaw_rate_white_variance),
            (
                VYAW,
                w,
                self.yaw_rate_white_variance + (self.slip_sigma * w).powi(2),
            ),
        ];
        for (i, value, variance) in values {
            m.set(i, value, variance, self.update[i]);
        }
        if self.two_d_mode {
            m.force_two_d();
        }
        m
    }
}

/// Turns IMU messages into orientation, angular velocity and acceleration measurements
/// (`imu0`), in the base frame.
#[derive(Debug, Clone)]
pub struct ImuModel {
    base_from_imu: Isometry3<f64>,
    gyro_variance: f64,
    accel_variance: f64,
    /// Roll, pitch, yaw.
    orientation_variance: [f64; 3],
    update: [bool; 15],
    relative: bool,
    remove_gravity: bool,
    gravity: f64,
    thresholds: [f64; 3],
    two_d_mode: bool,
    /// `imu0_relative`: the first orientation, `world_from_base`.
    first_orientation: Option<UnitQuaternion<f64>>,
}

impl ImuModel {
    pub fn new(spec: Option<&SensorSpec>, cfg: &Config) -> Self {
        Self {
            base_from_imu: spec.map_or_else(Isometry3::identity, |s| s.base_from_sensor()),
            gyro_variance: figure(spec, "gyro_noise_density").powi(2) * rate(spec),
            accel_variance: figure(spec, "accel_noise_density").powi(2) * rate(spec),
            orientation_variance: {
                // The rig's figures of the reported orientation where it states them (what
                // robot_localization reads from the message's covariance), else the
                // parameter.
                let sigma = |key: &str| {
                    Some(figure(spec, key))
                        .filter(|v| *v > 0.0)
                        .unwrap_or(cfg.imu0_orientation_sigma_rad)
                };
                let (rp, yaw) = (
                    sigma("orientation_roll_pitch_sigma_rad"),
                    sigma("orientation_yaw_sigma_rad"),
                );
                [rp * rp, rp * rp, yaw * yaw]
            },
            update: cfg.imu_update(),
            relative: cfg.imu0_relative,
            remove_gravity: cfg.imu0_remove_gravitational_acceleration,
            gravity: cfg.gravitational_acceleration,
            thresholds: [
                cfg.imu0_pose_rejection_threshold,
                cfg.imu0_twist_rejection_threshold,
                cfg.imu0_linear_acceleration_rejection_threshold,
            ],
            two_d_mode: cfg.two_d_mode,
            first_orientation: None,
        }
    }

    /// The base's absolute orientation `world_from_base` (east-north-up) from the IMU's
    /// `world_from_imu`, if it reports one.
    pub fn base_orientation(&self, imu: &Imu) -> Option<UnitQuaternion<f64>> {
        imu.orientation()
            .map(|world_from_imu| world_from_imu * self.base_from_imu.rotation.inverse())
    }

    /// The measurements of one message: orientation (when reported), angular velocity,
    /// linear acceleration, each only if `imu0_config` asks for it. `state` is the
    /// filter's, for gravity without a reported orientation and the lever arm's
    /// centripetal term.
    pub fn measurements(&mut self, imu: &Imu, state: &StateVector) -> Vec<Measurement> {
        let mut out = Vec::with_capacity(3);
        let base_r_imu = self.base_from_imu.rotation;
        let orientation = self.base_orientation(imu);
        if let Some(world_from_base) = orientation
            && self.update[ROLL..=YAW].iter().any(|&u| u)
        {
            let measured = if self.relative {
                // `imu0_relative`: relative to the first orientation.
                let first = *self.first_orientation.get_or_insert(world_from_base);
                first.inverse() * world_from_base
            } else {
                world_from_base
            };
            let (roll, pitch, yaw) = measured.euler_angles();
            let mut m = Measurement::new(imu.stamp_ns, Source::ImuOrientation, self.thresholds[0]);
            for (k, (i, value)) in [(ROLL, roll), (PITCH, pitch), (YAW, yaw)]
                .into_iter()
                .enumerate()
            {
                m.set(i, value, self.orientation_variance[k], self.update[i]);
            }
            out.push(m);
        }

        let rotate = |v: [f64; 3]| base_r_imu * Vector3::from(v);
        let rotate_cov = |variance: f64| {
            let r: Matrix3<f64> = base_r_imu.to_rotation_matrix().into_inner();
            r * Matrix3::from_diagonal_element(variance) * r.transpose()
        };
        if self.update[VROLL..=VYAW].iter().any(|&u| u) {
            let w = rotate(imu.gyro_rps);
            let cov = rotate_cov(self.gyro_variance);
            let mut m =
                Measurement::new(imu.stamp_ns, Source::ImuAngularVelocity, self.thresholds[1]);
            set_block(&mut m, VROLL, &w, &cov, &self.update);
            out.push(m);
        }
        if self.update[AX..AX + 3].iter().any(|&u| u) {
            let mut a = rotate(imu.accel_mps2);
            // The lever arm's centripetal acceleration, with the filter's body rates.
            let w = state.fixed_rows::<3>(VROLL).into_owned();
            let r = self.base_from_imu.translation.vector;
            a -= w.cross(&w.cross(&r));
            if self.remove_gravity {
                let world_from_base = match orientation {
                    Some(q) => q,
                    None => {
                        UnitQuaternion::from_euler_angles(state[ROLL], state[PITCH], state[YAW])
                    }
                };
                a -= world_from_base.inverse() * Vector3::new(0.0, 0.0, self.gravity);
            }
            let cov = rotate_cov(self.accel_variance);
            let mut m = Measurement::new(imu.stamp_ns, Source::ImuAcceleration, self.thresholds[2]);
            set_block(&mut m, AX, &a, &cov, &self.update);
            out.push(m);
        }
        if self.two_d_mode {
            for m in &mut out {
                m.force_two_d();
            }
        }
        out
    }
}

/// Sets three consecutive variables from `first` with their covariance block, those the
/// update vector selects.
fn set_block(
    m: &mut Measurement,
    first: usize,
    v: &Vector3<f64>,
    cov: &Matrix3<f64>,
    update: &[bool; 15],
) {
    for a in 0..3 {
        if !update[first + a] {
            continue;
        }
        m.set(first + a, v[a], cov[(a, a)], true);
        for b in (0..3).filter(|&b| b != a && update[first + b]) {
            m.covariance[(first + a, first + b)] = cov[(a, b)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{AY, AZ};
    use nalgebra::Translation3;
    use plugin_api::{Pose, SensorKind};
    use std::collections::BTreeMap;

    fn imu_spec() -> SensorSpec {
        SensorSpec {
            name: "imu".into(),
            kind: SensorKind::Imu,
            rate_hz: 200.0,
            base_from_sensor_xyz: [0.0; 3],
            base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
            intrinsics: BTreeMap::from([("reports_orientation".into(), 1.0)]),
            noise: BTreeMap::from([
                ("gyro_noise_density".into(), 1.7e-4),
                ("accel_noise_density".into(), 2.0e-3),
            ]),
        }
        .with_mount(&Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.6),
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        ))
    }

    /// An IMU mounted turned by 90° about z: its orientation, rates and acceleration come
    /// out in the base frame, and the variances are the datasheet's densities times √rate.
    #[test]
    fn imu_readings_are_rotated_into_the_base_frame() {
        let cfg = Config {
            // roll pitch yaw, the three rates, the three accelerations.
            imu0_config: (0..15).map(|i| i >= 3 && !(6..9).contains(&i)).collect(),
            two_d_mode: false,
            ..Config::default()
        };
        let mut model = ImuModel::new(Some(&imu_spec()), &cfg);
        let heading = 0.7;
        let world_from_imu =
            UnitQuaternion::from_euler_angles(0.0, 0.0, heading + std::f64::consts::FRAC_PI_2);
        let q = world_from_imu.coords;
        // In the IMU frame the base's forward axis is -y.
        let imu = Imu {
            stamp_ns: 5,
            accel_mps2: [0.0, -0.5, 9.80665],
            gyro_rps: [0.0, 0.0, 0.3],
            orientation_xyzw: [q.x, q.y, q.z, q.w],
        };
        let ms = model.measurements(&imu, &StateVector::zeros());
        assert_eq!(ms.len(), 3);
        assert!(
            (ms[0].z[YAW] - heading).abs() < 1e-12,
            "base yaw {}",
            ms[0].z[YAW]
        );
        assert!((ms[1].z[VYAW] - 0.3).abs() < 1e-12);
        let gyro_var = 1.7e-4f64.powi(2) * 200.0;
        assert!((ms[1].covariance[(VYAW, VYAW)] - gyro_var).abs() < 1e-18);
        assert!(
            (ms[2].z[AX] - 0.5).abs() < 1e-9,
            "forward acceleration {}",
            ms[2].z[AX]
        );
        assert!(
            ms[2].z[AY].abs() < 1e-9 && ms[2].z[AZ].abs() < 1e-9,
            "gravity removed"
        );
    }

    #[test]
    fn wheel_odometry_measures_its_velocities_with_datasheet_variances() {
        let spec = SensorSpec {
            name: "odom".into(),
            kind: SensorKind::WheelOdometry,
            rate_hz: 50.0,
            base_from_sensor_xyz: [0.0; 3],
            base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
            intrinsics: BTreeMap::new(),
            noise: BTreeMap::from([
                ("slip_sigma".into(), 0.01),
                ("scale_error".into(), 0.01),
                ("yaw_rate_noise_density".into(), 0.002),
            ]),
        };
        let model = WheelOdometryModel::new(Some(&spec), &Config::default());
        let m = model.measurement(&WheelOdometry {
            stamp_ns: 7,
            linear_mps: 2.0,
            angular_rps: 0.5,
            odom_from_base: Pose::new(7, &Isometry3::identity()),
        });
        assert_eq!((m.z[VX], m.z[VY], m.z[VYAW]), (2.0, 0.0, 0.5));
        assert!((m.covariance[(VX, VX)] - 2.0 * 0.0004).abs() < 1e-12);
        assert!(
            (m.covariance[(VYAW, VYAW)] - (0.002f64.powi(2) * 50.0 + 0.005f64.powi(2))).abs()
                < 1e-12
        );
        assert!(
            m.update[VZ] && m.covariance[(VZ, VZ)] == 1e-6,
            "two_d_mode holds vz to 0"
        );
        assert_eq!(m.stamp_ns, 7);
    }
}
