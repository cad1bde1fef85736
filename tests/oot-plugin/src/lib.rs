//! The smallest useful plugin: it reports the robot's own wheel odometry as its estimate.

use plugin_api::{PluginError, Pose, Requirements, Rig, SensorKind, SlamOutput, SlamSystem, WheelOdometry, export_plugin};

pub struct EchoOdometry {
    trajectory: Vec<Pose>,
}

impl SlamSystem for EchoOdometry {
    const NAME: &'static str = "oot-odometry";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");

    fn requirements() -> Requirements {
        Requirements::online(&[SensorKind::WheelOdometry])
    }

    fn new(_config_toml: &str, _rig: &Rig) -> Result<Self, PluginError> {
        Ok(Self { trajectory: Vec::new() })
    }

    fn on_wheel_odometry(&mut self, odom: &WheelOdometry) -> Result<Option<Pose>, PluginError> {
        let pose = Pose { stamp_ns: odom.stamp_ns, ..odom.odom_from_base };
        self.trajectory.push(pose);
        Ok(Some(pose))
    }

    fn finish(&mut self) -> Result<SlamOutput, PluginError> {
        Ok(SlamOutput { trajectory: std::mem::take(&mut self.trajectory), ..SlamOutput::default() })
    }
}

export_plugin!(EchoOdometry);
