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

/// A camera's lens as the rig gives it: OpenCV's `plumb_bob` coefficients (`k1`, `k2`,
/// `p1`, `p2`, `k3` among the camera's intrinsics; absent: the frames are rectified, a
/// pinhole's). Its frames are then the lens's raw images and their `[fx, fy, cx, cy]` its
/// camera matrix, as ROS's `camera_info` `k` and `d` describe a raw image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lens {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Lens {
    /// Where the lens puts the normalized image point `(x, y)` (`X/Z`, `Y/Z`): `plumb_bob`'s
    /// radial `1 + k1 r² + k2 r⁴ + k3 r⁶` and tangential `p1`, `p2` terms.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// The pixel `(u, v)` of a raw image of camera `k` moved to where a pinhole would have
    /// seen its ray: OpenCV's `undistortPoints` fixed-point iteration, `iterations` times
    /// (OpenCV 3's default is 5, which ORB-SLAM2 uses through it).
    pub fn undistort_pixel(
        &self,
        k: &Pinhole,
        (u, v): (f64, f64),
        iterations: usize,
    ) -> (f64, f64) {
        let (x0, y0) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
        let (mut x, mut y) = (x0, y0);
        for _ in 0..iterations {
            let r2 = x * x + y * y;
            let inv_radial = 1.0 / (1.0 + ((self.k3 * r2 + self.k2) * r2 + self.k1) * r2);
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            x = (x0 - dx) * inv_radial;
            y = (y0 - dy) * inv_radial;
        }
        (k.fx * x + k.cx, k.fy * y + k.cy)
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

    /// A camera's lens: `None` when its intrinsics carry no `k1`...`k3` (or all zero: a
    /// rectified image); an error when only some are there or one is not finite.
    pub fn lens(&self) -> Result<Option<Lens>, PluginError> {
        let keys = ["k1", "k2", "p1", "p2", "k3"];
        let got: Vec<Option<f64>> = keys
            .iter()
            .map(|k| self.intrinsics.get(*k).copied())
            .collect();
        if got.iter().all(Option::is_none) {
            return Ok(None);
        }
        let mut d = [0.0; 5];
        for ((slot, value), key) in d.iter_mut().zip(&got).zip(keys) {
            *slot = value.filter(|v| v.is_finite()).ok_or_else(|| {
                PluginError::new(format!(
                    "the camera's lens lacks a finite {key} (a lens gives k1, k2, p1, p2 and k3)"
                ))
            })?;
        }
        let [k1, k2, p1, p2, k3] = d;
        Ok((d != [0.0; 5]).then_some(Lens { k1, k2, p1, p2, k3 }))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(extra: &[(&str, f64)]) -> SensorSpec {
        let mut intrinsics: BTreeMap<String, f64> = [
            ("fx", 355.0),
            ("fy", 355.0),
            ("cx", 319.5),
            ("cy", 239.5),
            ("width", 640.0),
            ("height", 480.0),
        ]
        .iter()
        .map(|&(k, v)| (k.to_owned(), v))
        .collect();
        intrinsics.extend(extra.iter().map(|&(k, v)| (k.to_owned(), v)));
        SensorSpec {
            name: "camera".into(),
            kind: SensorKind::Rgbd,
            rate_hz: 30.0,
            base_from_sensor_xyz: [0.0; 3],
            base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
            intrinsics,
            noise: BTreeMap::new(),
        }
    }

    /// A lens is all five coefficients or none; undistorting a pixel finds the pinhole
    /// pixel the lens moved there.
    #[test]
    fn a_lens_is_read_whole_and_undistorts_its_pixels() {
        assert_eq!(camera(&[]).lens().unwrap(), None);
        let zero = [
            ("k1", 0.0),
            ("k2", 0.0),
            ("p1", 0.0),
            ("p2", 0.0),
            ("k3", 0.0),
        ];
        assert_eq!(camera(&zero).lens().unwrap(), None, "zeros: rectified");
        let err = camera(&[("k1", 0.07)]).lens().unwrap_err().to_string();
        assert!(err.contains("finite k2"), "{err}");
        let kinect = [
            ("k1", 0.0717),
            ("k2", -0.1355),
            ("p1", 0.0016),
            ("p2", 0.0024),
            ("k3", 0.0595),
        ];
        let spec = camera(&kinect);
        let lens = spec.lens().unwrap().expect("a lens");
        let k = spec.pinhole().unwrap();
        // A pinhole pixel, moved by the lens (plumb_bob), and back.
        let (xd, yd) = lens.distort((500.0 - k.cx) / k.fx, (350.0 - k.cy) / k.fy);
        let raw = (k.fx * xd + k.cx, k.fy * yd + k.cy);
        assert!(
            (raw.0 - 600.0).hypot(raw.1 - 40.0) > 1.0,
            "the lens moves it"
        );
        let (u, v) = lens.undistort_pixel(&k, raw, 20);
        assert!(
            (u - 500.0).abs() < 1e-6 && (v - 350.0).abs() < 1e-6,
            "raw {raw:?} undistorted to ({u}, {v})"
        );
    }
}
