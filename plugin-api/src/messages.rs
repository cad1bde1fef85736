//! Sensor messages as a plugin receives them. Plain `#[repr(C)]` data: time in integer
//! nanoseconds since the start of the run, SI units, sensor-frame coordinates.

use abi_stable::StableAbi;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// A stamped rigid transform (`a_from_b`; which frames is said where it is used).
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub stamp_ns: i64,
    pub translation: [f64; 3],
    /// Unit quaternion, (x, y, z, w).
    pub rotation_xyzw: [f64; 4],
}

impl Pose {
    pub fn new(stamp_ns: i64, pose: &Isometry3<f64>) -> Self {
        let t = pose.translation.vector;
        let q = pose.rotation.coords;
        Self {
            stamp_ns,
            translation: [t.x, t.y, t.z],
            rotation_xyzw: [q.x, q.y, q.z, q.w],
        }
    }

    /// The transform; `None` if it is not finite or its quaternion is not unit length (±1e-6).
    pub fn isometry(&self) -> Option<Isometry3<f64>> {
        let [x, y, z, w] = self.rotation_xyzw;
        let finite = self
            .translation
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite());
        let q = Quaternion::new(w, x, y, z);
        if !finite || (q.norm() - 1.0).abs() > 1e-6 {
            return None;
        }
        let [tx, ty, tz] = self.translation;
        Some(Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::new_normalize(q),
        ))
    }
}

/// One IMU reading in the IMU frame: specific force (≈ +9.81 m/s² up at rest) and angular rate.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq)]
pub struct Imu {
    pub stamp_ns: i64,
    pub accel_mps2: [f64; 3],
    pub gyro_rps: [f64; 3],
    /// The rotation `world_from_imu` as a unit quaternion (x, y, z, w) where the IMU reports
    /// one (the rig's IMU has `intrinsics.reports_orientation = 1`, as the paper's Gazebo
    /// IMU did), else all zeros. Appended last: the fields above keep their places.
    pub orientation_xyzw: [f64; 4],
}

impl Imu {
    /// The reported orientation, `None` where the IMU reports none.
    pub fn orientation(&self) -> Option<UnitQuaternion<f64>> {
        let [x, y, z, w] = self.orientation_xyzw;
        let q = Quaternion::new(w, x, y, z);
        (q.norm() > 0.5).then(|| UnitQuaternion::new_normalize(q))
    }
}

/// Wheel odometry: forward speed and yaw rate of the base from the encoders, and the pose
/// the robot integrated from them (`odom_from_base`, starting at the identity).
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq)]
pub struct WheelOdometry {
    pub stamp_ns: i64,
    pub linear_mps: f64,
    pub angular_rps: f64,
    pub odom_from_base: Pose,
}

/// One lidar return in the sensor frame, at its own firing time.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq, Default)]
pub struct LidarPoint {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    /// Calibrated reflectivity, 0-255.
    pub intensity: f32,
    /// Firing time after the cloud's stamp, seconds.
    pub time_s: f32,
    /// Beam index from the lowest (0) upwards.
    pub ring: u16,
}

/// One revolution of a spinning lidar, stamped at the start of the sweep.
#[derive(Debug, Clone, Copy)]
pub struct PointCloud<'a> {
    pub stamp_ns: i64,
    /// The sensor's name in the [`crate::Rig`].
    pub sensor: &'a str,
    pub points: &'a [LidarPoint],
}

/// A planar scan laid out like ROS `sensor_msgs/LaserScan` (no return: `+inf`).
#[derive(Debug, Clone, Copy)]
pub struct LaserScan<'a> {
    pub stamp_ns: i64,
    pub sensor: &'a str,
    pub angle_min_rad: f32,
    pub angle_increment_rad: f32,
    pub time_increment_s: f32,
    pub range_min_m: f32,
    pub range_max_m: f32,
    pub ranges_m: &'a [f32],
    pub intensities: &'a [f32],
}

/// A registered RGB-D frame: RGB8 row-major, depth in metres (0 or NaN: invalid), pinhole
/// intrinsics `[fx, fy, cx, cy]` in pixels.
#[derive(Debug, Clone, Copy)]
pub struct RgbdFrame<'a> {
    pub stamp_ns: i64,
    pub sensor: &'a str,
    pub width: u32,
    pub height: u32,
    pub rgb: &'a [u8],
    pub depth_m: &'a [f32],
    pub intrinsics: [f64; 4],
}

impl RgbdFrame<'_> {
    /// The colour image in grey, as feature detectors take it ([`gray_from_rgb`]).
    pub fn gray(&self) -> Vec<u8> {
        gray_from_rgb(self.rgb, self.width as usize, self.height as usize)
    }
}

/// BT.601 luma of packed RGB8, row-major, rounded as OpenCV's `COLOR_RGB2GRAY` bit for bit
/// (its fixed point for 8-bit images: 0.299, 0.587 and 0.114 in 15 bits;
/// `plugins/orbslam2` tests the equality against OpenCV).
pub fn gray_from_rgb(rgb: &[u8], width: usize, height: usize) -> Vec<u8> {
    const R: u32 = 9798;
    const G: u32 = 19235;
    const B: u32 = 3735;
    rgb.chunks_exact(3)
        .take(width * height)
        .map(|p| {
            ((R * u32::from(p[0]) + G * u32::from(p[1]) + B * u32::from(p[2]) + (1 << 14)) >> 15)
                as u8
        })
        .collect()
}

/// The quality of a GNSS fix (revision 5), best last, as NMEA's GGA orders them.
#[repr(u32)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum GnssStatus {
    /// No fix: the position is NaN.
    NoFix = 0,
    /// A single-point (code) solution: metres.
    Single = 1,
    /// RTK with float ambiguities: decimetres.
    Float = 2,
    /// RTK with fixed ambiguities: centimetres.
    Fixed = 3,
}

impl GnssStatus {
    /// The status's name as it crosses the Python door (`no_fix`, `single`, `float`, `fixed`).
    pub fn name(self) -> &'static str {
        match self {
            Self::NoFix => "no_fix",
            Self::Single => "single",
            Self::Float => "float",
            Self::Fixed => "fixed",
        }
    }
}

/// One GNSS epoch (revision 5): the antenna's position (the rig's `gnss` sensor, its mount
/// the lever arm from the base) as the receiver solved it, stamped at the epoch and
/// delivered after the receiver's latency.
///
/// Positions are in the local east-north-up frame whose origin is the datum (the rig's
/// `gnss` intrinsics `datum_latitude_deg`, `datum_longitude_deg`, `datum_altitude_m`); the
/// same fix is also given in WGS-84, as `sensor_msgs/NavSatFix` has it. Nothing here is
/// checked for the plugin: read it through [`Gnss::position`] and [`Gnss::covariance`],
/// which refuse a fix without a finite position or a covariance that is not symmetric
/// positive definite.
#[repr(C)]
#[derive(StableAbi, Debug, Clone, Copy, PartialEq)]
pub struct Gnss {
    pub stamp_ns: i64,
    pub status: GnssStatus,
    /// Satellites used (above the mask and in view).
    pub satellites: u32,
    /// East, north, up of the antenna from the datum, metres; NaN without a fix.
    pub position_enu_m: [f64; 3],
    /// The reported covariance of `position_enu_m`, row-major 3 x 3, m²; zeros without a fix.
    pub covariance_enu_m2: [f64; 9],
    /// WGS-84 latitude and longitude (degrees) and ellipsoidal height (m); NaN without a fix.
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    pub altitude_m: f64,
    /// Horizontal dilution of precision; NaN under four satellites.
    pub hdop: f64,
}

impl Gnss {
    /// The position, where the status is a fix and every coordinate finite.
    pub fn position(&self) -> Option<nalgebra::Vector3<f64>> {
        let p = nalgebra::Vector3::from(self.position_enu_m);
        (self.status != GnssStatus::NoFix && p.iter().all(|v| v.is_finite())).then_some(p)
    }

    /// The covariance, where it is finite, symmetric and positive definite.
    pub fn covariance(&self) -> Option<nalgebra::Matrix3<f64>> {
        let c = nalgebra::Matrix3::from_row_slice(&self.covariance_enu_m2);
        let finite = c.iter().all(|v| v.is_finite());
        let symmetric = (c - c.transpose()).abs().max() <= 1e-9 * c.abs().max().max(1e-300);
        (finite && symmetric && c.cholesky().is_some()).then_some(c)
    }

    /// Why this fix cannot be used, if it cannot: no fix, a position that is not finite, a
    /// covariance that is not symmetric positive definite. A plugin rejects such a fix
    /// (with a `gnss_rejected` event), never trusts it.
    pub fn problem(&self) -> Option<&'static str> {
        if self.status == GnssStatus::NoFix {
            Some("no fix")
        } else if self.position().is_none() {
            Some("a fix without a finite position")
        } else if self.covariance().is_none() {
            Some("a covariance that is not symmetric positive definite")
        } else {
            None
        }
    }

    /// The fix's antenna position and covariance (east-north-up, m and m²), or why it
    /// cannot be used ([`Gnss::problem`]).
    pub fn usable(&self) -> Result<(nalgebra::Vector3<f64>, nalgebra::Matrix3<f64>), &'static str> {
        match (self.problem(), self.position(), self.covariance()) {
            (None, Some(p), Some(c)) => Ok((p, c)),
            (problem, ..) => Err(problem.unwrap_or("not usable")),
        }
    }

    /// The `gnss_rejected` event a plugin named `plugin` reports for this fix, saying why
    /// (`problem`: [`Gnss::problem`]'s, or the plugin's own reason).
    pub fn rejected(&self, plugin: &str, problem: &str) -> crate::system::Event {
        crate::system::Event::new(
            self.stamp_ns,
            crate::system::EventKind::GnssRejected,
            format!(
                "{plugin}: GNSS fix ({}, {} satellites) refused: {problem}",
                self.status.name(),
                self.satellites
            ),
        )
    }
}
