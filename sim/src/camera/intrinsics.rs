//! The pinhole model and the rotation from the camera body to its optical frame.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};

use crate::config::CameraConfig;

/// Pinhole intrinsics in the optical frame (z forward, x right, y down), in pixels; integer
/// pixel coordinates are pixel centres. No lens distortion (a rectified image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: usize,
    pub height: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// Square pixels, `fx = (width / 2) / tan(hfov / 2)`, principal point at the centre
    /// (`cx = (width - 1) / 2`). For 640x480 at 70°: fx = fy = 457.0, vertical FOV 55.4°.
    pub fn from_config(cfg: &CameraConfig) -> Self {
        Self::with_hfov(cfg, cfg.hfov_deg)
    }

    /// The configured image with a horizontal field of view of `hfov_deg`.
    pub fn with_hfov(cfg: &CameraConfig, hfov_deg: f64) -> Self {
        Self::pinhole(cfg.width, cfg.height, hfov_deg)
    }

    /// A `width` x `height` image with a horizontal field of view of `hfov_deg`, square
    /// pixels, principal point at the centre.
    pub fn pinhole(width: usize, height: usize, hfov_deg: f64) -> Self {
        let fx = 0.5 * width as f64 / (0.5 * hfov_deg.to_radians()).tan();
        Self {
            width,
            height,
            fx,
            fy: fx,
            cx: 0.5 * (width as f64 - 1.0),
            cy: 0.5 * (height as f64 - 1.0),
        }
    }

    /// The separate depth camera's (`depth_hfov_deg`; `depth_size`, else the colour image's).
    pub fn depth_camera(cfg: &CameraConfig) -> Option<Self> {
        let [w, h] = cfg.depth_size.unwrap_or([cfg.width, cfg.height]);
        cfg.depth_hfov_deg.map(|hfov| Self::pinhole(w, h, hfov))
    }

    /// The ray through pixel `(u, v)` in the optical frame, scaled to z = 1: a point at
    /// depth `z` on it is `z * ray(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> [f64; 3] {
        [(u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0]
    }
}

/// `camera_from_optical`: the optical frame's z (forward) is the body's x, its x (right) is
/// the body's -y, its y (down) is the body's -z.
pub fn camera_from_optical() -> Isometry3<f64> {
    #[rustfmt::skip]
    let m = Matrix3::new(
        0.0, 0.0, 1.0,
        -1.0, 0.0, 0.0,
        0.0, -1.0, 0.0,
    );
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
    )
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};

    use super::*;

    #[test]
    fn kinect_like_defaults_and_optical_axes() {
        let k = Intrinsics::from_config(&CameraConfig::default());
        assert!(
            (k.fx - 457.0).abs() < 0.1,
            "expected fx = 457.0 px at 70° over 640 px, got {}",
            k.fx
        );
        assert_eq!(
            (k.cx, k.cy),
            (319.5, 239.5),
            "expected the principal point at the centre"
        );
        let r = camera_from_optical();
        let forward = r * Vector3::z();
        let right = r * Vector3::x();
        let down = r * Vector3::y();
        assert!(
            (forward - Vector3::x()).norm() < 1e-12,
            "optical z must be the body's x"
        );
        assert!(
            (right + Vector3::y()).norm() < 1e-12,
            "optical x must be the body's -y"
        );
        assert!(
            (down + Vector3::z()).norm() < 1e-12,
            "optical y must be the body's -z"
        );
        assert_eq!(
            r * Point3::origin(),
            Point3::origin(),
            "expected a pure rotation"
        );
    }
}
