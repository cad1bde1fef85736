//! The floor every SLAM plugin must beat: dead reckoning in the plane from the wheel
//! encoders' forward speed, with the yaw rate from the wheels or from the IMU's gyro (the
//! usual fix for skid-steer bases, whose wheel yaw rate is poor). Also the smallest example
//! of a plugin.
//!
//! Parameters (all optional): `yaw_source = "wheels" | "imu"`.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use plugin_api::{
    Imu, Parameters, PluginError, Pose, Requirements, Rig, SensorKind, SlamOutput, SlamSystem,
    WheelOdometry, export_plugin,
};
use serde::Deserialize;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
enum YawSource {
    #[default]
    Wheels,
    Imu,
}

#[derive(Debug, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
struct Config {
    yaw_source: YawSource,
}

impl Parameters for Config {}

/// Planar dead reckoning.
#[derive(Debug)]
pub struct WheelOdometryBaseline {
    yaw_source: YawSource,
    /// Rotation from the IMU frame to the base frame, to read the yaw rate about base z.
    base_r_imu: UnitQuaternion<f64>,
    /// Heading integrated from the gyro, and its value at the previous odometry message.
    imu_yaw: f64,
    imu_yaw_at_odom: f64,
    last_imu_ns: Option<i64>,
    last_odom_ns: Option<i64>,
    x: f64,
    y: f64,
    yaw: f64,
    trajectory: Vec<Pose>,
}

impl WheelOdometryBaseline {
    fn pose(&self, stamp_ns: i64) -> Pose {
        let iso = Isometry3::from_parts(
            Translation3::new(self.x, self.y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, self.yaw),
        );
        Pose::new(stamp_ns, &iso)
    }
}

impl SlamSystem for WheelOdometryBaseline {
    const NAME: &'static str = "wheel-odometry";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::WheelOdometry, SensorKind::Imu])
    }

    fn new(config_toml: &str, rig: &Rig) -> Result<Self, PluginError> {
        let config = Config::from_toml(config_toml).map_err(PluginError::new)?;
        let base_r_imu = match config.yaw_source {
            YawSource::Imu => {
                rig.first(SensorKind::Imu)
                    .ok_or_else(|| PluginError::new("yaw_source = \"imu\" but the rig has no IMU"))?
                    .base_from_sensor()
                    .rotation
            }
            YawSource::Wheels => UnitQuaternion::identity(),
        };
        Ok(Self {
            yaw_source: config.yaw_source,
            base_r_imu,
            imu_yaw: 0.0,
            imu_yaw_at_odom: 0.0,
            last_imu_ns: None,
            last_odom_ns: None,
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            trajectory: Vec::new(),
        })
    }

    fn on_imu(&mut self, imu: &Imu) -> Result<Option<Pose>, PluginError> {
        // A non-finite reading is dropped, as a robot's filter drops it; the next one
        // integrates over the gap.
        if !imu.gyro_rps.iter().all(|v| v.is_finite()) {
            return Ok(None);
        }
        if let Some(last) = self.last_imu_ns {
            let dt = (imu.stamp_ns - last) as f64 * 1e-9;
            self.imu_yaw += (self.base_r_imu * Vector3::from(imu.gyro_rps)).z * dt;
        }
        self.last_imu_ns = Some(imu.stamp_ns);
        Ok(None)
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        // Non-finite speeds are dropped (no pose with them); the next reading integrates over
        // the gap.
        if !(odom.linear_mps.is_finite() && odom.angular_rps.is_finite()) {
            return Ok(None);
        }
        if let Some(last) = self.last_odom_ns {
            let dt = (odom.stamp_ns - last) as f64 * 1e-9;
            let dyaw = match self.yaw_source {
                YawSource::Wheels => odom.angular_rps * dt,
                YawSource::Imu => self.imu_yaw - self.imu_yaw_at_odom,
            };
            let mid = self.yaw + 0.5 * dyaw;
            self.x += odom.linear_mps * dt * mid.cos();
            self.y += odom.linear_mps * dt * mid.sin();
            self.yaw += dyaw;
        }
        self.imu_yaw_at_odom = self.imu_yaw;
        self.last_odom_ns = Some(odom.stamp_ns);
        let pose = self.pose(odom.stamp_ns);
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        Ok(SlamOutput {
            trajectory: std::mem::take(&mut self.trajectory),
            ..SlamOutput::default()
        })
    }
}

export_plugin!(WheelOdometryBaseline);
