//! The sensor rig: every sensor's name, kind, rate, mounting and datasheet figures. It
//! crosses the plugin boundary as TOML text, so new fields never break old plugins.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::system::PluginError;

/// What a sensor measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorKind {
    Imu,
    WheelOdometry,
    Lidar,
    Scan2d,
    Rgbd,
    /// A GNSS receiver (revision 5); in a plugin's rig only where it asks for one and the
    /// world has a receiver, so that plugins built before it never meet the kind.
    Gnss,
}

impl SensorKind {
    pub const ALL: [SensorKind; 6] = [
        SensorKind::Imu,
        SensorKind::WheelOdometry,
        SensorKind::Lidar,
        SensorKind::Scan2d,
        SensorKind::Rgbd,
        SensorKind::Gnss,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Imu => "imu",
            SensorKind::WheelOdometry => "wheel_odometry",
            SensorKind::Lidar => "lidar",
            SensorKind::Scan2d => "scan2d",
            SensorKind::Rgbd => "rgbd",
            SensorKind::Gnss => "gnss",
        }
    }

    /// What a person calls it, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            SensorKind::Imu => "IMU",
            SensorKind::WheelOdometry => "wheel odometry",
            SensorKind::Lidar => "3D lidar",
            SensorKind::Scan2d => "2D scan",
            SensorKind::Rgbd => "RGB-D camera",
            SensorKind::Gnss => "GNSS receiver",
        }
    }
}

/// A pinhole camera's intrinsics as the rig gives them: focal lengths and principal point in
/// pixels, image size in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: f64,
    pub height: f64,
}

impl Pinhole {
    /// `[fx, fy, cx, cy]`.
    pub fn intrinsics(&self) -> [f64; 4] {
        [self.fx, self.fy, self.cx, self.cy]
    }
}

/// One sensor of the rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensorSpec {
    pub name: String,
    pub kind: SensorKind,
    pub rate_hz: f64,
    /// `base_from_sensor` as translation (m) and quaternion (x, y, z, w).
    pub base_from_sensor_xyz: [f64; 3],
    pub base_from_sensor_xyzw: [f64; 4],
    /// Geometry as a datasheet gives it, e.g. `rings`, `columns`, `min_range_m`, `fx`.
    #[serde(default)]
    pub intrinsics: BTreeMap<String, f64>,
    /// Noise as a datasheet gives it, e.g. `range_sigma_m`, `gyro_noise_density`.
    #[serde(default)]
    pub noise: BTreeMap<String, f64>,
}

impl SensorSpec {
    /// The intrinsic parameter `key`, which must be finite and positive.
    pub fn positive(&self, key: &str) -> Result<f64, PluginError> {
        self.intrinsics
            .get(key)
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| {
                PluginError::new(format!(
                    "the {}'s intrinsics lack a positive {key}",
                    match self.kind {
                        SensorKind::Rgbd => "camera",
                        kind => kind.describe(),
                    }
                ))
            })
    }

    /// A camera's pinhole: `fx`, `fy`, `cx`, `cy`, `width` and `height`, each positive.
    pub fn pinhole(&self) -> Result<Pinhole, PluginError> {
        Ok(Pinhole {
            fx: self.positive("fx")?,
            fy: self.positive("fy")?,
            cx: self.positive("cx")?,
            cy: self.positive("cy")?,
            width: self.positive("width")?,
            height: self.positive("height")?,
        })
    }

    pub fn base_from_sensor(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.base_from_sensor_xyzw;
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.base_from_sensor_xyz)),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
        )
    }

    /// Sets the mounting from a transform.
    pub fn with_mount(mut self, base_from_sensor: &Isometry3<f64>) -> Self {
        let t = base_from_sensor.translation.vector;
        let q = base_from_sensor.rotation.coords;
        self.base_from_sensor_xyz = [t.x, t.y, t.z];
        self.base_from_sensor_xyzw = [q.x, q.y, q.z, q.w];
        self
    }
}

/// Every sensor the host simulates.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Rig {
    pub sensors: Vec<SensorSpec>,
}

impl Rig {
    /// The sensor called `name`.
    pub fn sensor(&self, name: &str) -> Option<&SensorSpec> {
        self.sensors.iter().find(|s| s.name == name)
    }

    /// The first sensor of `kind`.
    pub fn first(&self, kind: SensorKind) -> Option<&SensorSpec> {
        self.sensors.iter().find(|s| s.kind == kind)
    }

    /// The sensor called `name`, which must be of `kind`: what a plugin's configuration
    /// names (`camera = "camera"`). The error names both.
    pub fn require(&self, name: &str, kind: SensorKind) -> Result<&SensorSpec, PluginError> {
        self.sensor(name).filter(|s| s.kind == kind).ok_or_else(|| {
            PluginError::new(format!(
                "the rig has no {} called {name:?}",
                kind.describe()
            ))
        })
    }

    /// The first sensor of `kind`, which must exist.
    pub fn require_first(&self, kind: SensorKind) -> Result<&SensorSpec, PluginError> {
        self.first(kind)
            .ok_or_else(|| PluginError::new(format!("the rig has no {}", kind.describe())))
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a rig always serialises")
    }

    pub fn from_toml(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| format!("rig description: {}", e.message()))
    }
}
