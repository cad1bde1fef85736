//! The messages the simulator emits. Time is integer nanoseconds from the start of the run;
//! all quantities SI.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

/// Ground-truth pose of the base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundTruth {
    pub stamp_ns: i64,
    pub world_from_base: Isometry3<f64>,
    /// Linear velocity of the base origin (world frame) and angular velocity (base frame).
    pub velocity_in_world: Vector3<f64>,
    pub omega_in_base: Vector3<f64>,
}

/// One IMU reading in the IMU frame: specific force (gravity included, so ≈ +9.81 m/s² up
/// at rest) and angular rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    pub stamp_ns: i64,
    pub accel_mps2: Vector3<f64>,
    pub gyro_rps: Vector3<f64>,
    /// The rotation `world_from_imu`, where the IMU reports one (`reports_orientation`).
    pub orientation: Option<UnitQuaternion<f64>>,
}

/// Wheel odometry: the base's forward speed and yaw rate from the wheel encoders, and the
/// pose integrated from them in the odometry frame (starting at the identity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelOdometry {
    pub stamp_ns: i64,
    pub linear_mps: f64,
    pub angular_rps: f64,
    pub odom_from_base: Isometry3<f64>,
}

/// One lidar return in the sensor frame at its own firing time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct LidarPoint {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    /// Calibrated reflectivity, 0-255 as the VLP-16 reports it.
    pub intensity: f32,
    /// Firing time relative to the scan's stamp, seconds (≥ 0).
    pub time_s: f32,
    /// Beam index from the lowest (0) upwards.
    pub ring: u16,
}

/// One revolution of the 3D lidar. Stamped at the start of the sweep; available at its end.
#[derive(Debug, Clone, PartialEq)]
pub struct LidarScan {
    pub stamp_ns: i64,
    pub sweep_ns: i64,
    pub points: Vec<LidarPoint>,
}

/// Which 2D scanner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ScanSide {
    Front,
    Back,
}

impl ScanSide {
    pub fn name(self) -> &'static str {
        match self {
            ScanSide::Front => "scan_front",
            ScanSide::Back => "scan_back",
        }
    }
}

/// A planar scan, laid out like ROS `sensor_msgs/LaserScan`: no return is `+inf` (REP 117).
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    pub stamp_ns: i64,
    pub side: ScanSide,
    pub angle_min_rad: f32,
    pub angle_increment_rad: f32,
    pub time_increment_s: f32,
    pub range_min_m: f32,
    pub range_max_m: f32,
    pub ranges_m: Vec<f32>,
    pub intensities: Vec<f32>,
}

/// One frame of the RGB-D camera (see [`crate::camera`] for its frames and conventions).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    pub stamp_ns: i64,
    pub image: crate::camera::RgbdImage,
}

/// Anything the simulator emits.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    GroundTruth(GroundTruth),
    Imu(ImuSample),
    WheelOdometry(WheelOdometry),
    Lidar(LidarScan),
    Scan2d(LaserScan),
    Rgbd(RgbdFrame),
    /// A GNSS epoch, stamped at the epoch, available `latency_ns` later.
    Gnss(super::gnss::GnssFix),
}

impl Message {
    /// The measurement's reference time (for a sweep, its start).
    pub fn stamp_ns(&self) -> i64 {
        match self {
            Message::GroundTruth(m) => m.stamp_ns,
            Message::Imu(m) => m.stamp_ns,
            Message::WheelOdometry(m) => m.stamp_ns,
            Message::Lidar(m) => m.stamp_ns,
            Message::Scan2d(m) => m.stamp_ns,
            Message::Rgbd(m) => m.stamp_ns,
            Message::Gnss(m) => m.stamp_ns,
        }
    }

    /// Moves the stamp by `ns` (a sensor on a clock of its own: `clock_offset_ns`); a
    /// sweep's points keep their times relative to its stamp.
    pub fn shift_stamp(&mut self, ns: i64) {
        let stamp = match self {
            Message::GroundTruth(m) => &mut m.stamp_ns,
            Message::Imu(m) => &mut m.stamp_ns,
            Message::WheelOdometry(m) => &mut m.stamp_ns,
            Message::Lidar(m) => &mut m.stamp_ns,
            Message::Scan2d(m) => &mut m.stamp_ns,
            Message::Rgbd(m) => &mut m.stamp_ns,
            Message::Gnss(m) => &mut m.stamp_ns,
        };
        *stamp += ns;
    }

    /// Short name of the sensor, as used on the command line and in file names.
    pub fn sensor(&self) -> &'static str {
        match self {
            Message::GroundTruth(_) => "gt",
            Message::Imu(_) => "imu",
            Message::WheelOdometry(_) => "odom",
            Message::Lidar(_) => "lidar",
            Message::Scan2d(m) => m.side.name(),
            Message::Rgbd(_) => "rgbd",
            Message::Gnss(_) => "gnss",
        }
    }
}
