//! Sensor models. Each sensor knows when its next message is ready and makes it from the
//! ground-truth trajectory and the scene; [`crate::Stream`] merges them in time order.

pub mod gnss;
mod ground_truth;
mod imu;
mod lidar;
pub mod lidar_footprint;
mod messages;
mod rgbd;
mod scan2d;
mod wheel_odometry;

pub use ground_truth::GroundTruthSensor;
pub use imu::ImuSensor;
pub use lidar::{LidarSensor, vlp16_directions};
pub use messages::{
    GroundTruth, ImuSample, LaserScan, LidarPoint, LidarScan, Message, RgbdFrame, ScanSide,
    WheelOdometry,
};
pub use rgbd::RgbdSensor;
pub use scan2d::Scan2dSensor;
pub use wheel_odometry::WheelOdometrySensor;

use crate::raycast::RayCaster;
use crate::robot::Trajectory;
use crate::world::World;

/// What a sensor may look at.
#[derive(Debug, Clone, Copy)]
pub struct Scene<'a> {
    pub world: &'a World,
    pub trajectory: &'a Trajectory,
    pub caster: &'a dyn RayCaster,
}

/// A sensor model.
pub trait Sensor: Send + std::fmt::Debug {
    /// When its next message becomes available (the end of its measurement), or `None` when
    /// the trajectory is over.
    fn next_ready_ns(&self) -> Option<i64>;
    /// Makes that message and moves on to the next.
    fn emit(&mut self, scene: &Scene<'_>) -> Message;
}

/// Time of sample `k` of a sensor at `rate_hz`, in integer nanoseconds.
pub(crate) fn sample_time_ns(k: u64, rate_hz: f64) -> i64 {
    (k as f64 * 1e9 / rate_hz).round() as i64
}
