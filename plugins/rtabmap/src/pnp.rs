//! Camera pose from 3D–2D correspondences: OpenCV's `solvePnPRansac` (RANSAC over minimal
//! solutions, then Levenberg–Marquardt on the inliers), as RTAB-Map estimates visual
//! odometry and verifies loop closures (`Vis/EstimationType` = PnP).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;
use opencv::core::{self, Mat, Point2f, Point3f, Vector};
use opencv::prelude::*;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpConfig {
    pub reprojection_px: f64,
    pub iterations: i32,
}

/// A pose and which correspondences agree with it.
#[derive(Debug, Clone, PartialEq)]
pub struct PnpResult {
    /// Maps the object points into the camera's optical frame.
    pub camera_from_object: Isometry3<f64>,
    /// Indices into the correspondences, ascending.
    pub inliers: Vec<usize>,
}

/// `None` when fewer than 6 correspondences or RANSAC finds no pose. The inliers are
/// counted again at the returned pose (the final refinement on RANSAC's inliers can move
/// it), so that they always agree with it. `guess`, if any, seeds RANSAC
/// (`useExtrinsicGuess`); OpenCV's iterative minimal solver can run away from a guess, so
/// callers that have one should still check the result against it.
pub fn solve(
    object: &[Vector3<f64>],
    pixels: &[[f32; 2]],
    intrinsics: [f64; 4],
    guess: Option<&Isometry3<f64>>,
    cfg: &PnpConfig,
) -> Result<Option<PnpResult>, opencv::Error> {
    assert_eq!(object.len(), pixels.len(), "one pixel per object point");
    if object.len() < 6 {
        return Ok(None);
    }
    let object: Vector<Point3f> = object
        .iter()
        .map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    let image: Vector<Point2f> = pixels.iter().map(|p| Point2f::new(p[0], p[1])).collect();
    let pixels = image.as_slice();
    let [fx, fy, cx, cy] = intrinsics;
    let k = Mat::from_slice_2d(&[[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])?;
    let (mut rvec, mut tvec) = match guess {
        Some(g) => {
            let r = g.rotation.scaled_axis();
            let t = g.translation.vector;
            (
                Mat::from_slice(&[r.x, r.y, r.z])?.try_clone()?,
                Mat::from_slice(&[t.x, t.y, t.z])?.try_clone()?,
            )
        }
        None => (Mat::default(), Mat::default()),
    };
    let mut inliers = Mat::default();
    let solved = calib3d::solve_pnp_ransac(
        &object,
        &image,
        &k,
        &core::no_array(),
        &mut rvec,
        &mut tvec,
        guess.is_some(),
        cfg.iterations,
        cfg.reprojection_px as f32,
        0.99,
        &mut inliers,
        calib3d::SOLVEPNP_ITERATIVE,
    )?;
    if !solved {
        return Ok(None);
    }
    let vec3 = |m: &Mat| -> Result<Vector3<f64>, opencv::Error> {
        Ok(Vector3::new(
            *m.at::<f64>(0)?,
            *m.at::<f64>(1)?,
            *m.at::<f64>(2)?,
        ))
    };
    let (r, t) = (vec3(&rvec)?, vec3(&tvec)?);
    if !(r.iter().chain(t.iter()).all(|v| v.is_finite())) {
        return Ok(None);
    }
    let camera_from_object =
        Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
    let limit_sq = cfg.reprojection_px * cfg.reprojection_px;
    let indices = object
        .iter()
        .zip(pixels)
        .enumerate()
        .filter(|(_, (p, px))| {
            let q = camera_from_object
                * nalgebra::Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            q.z > 0.0 && {
                let (u, v) = (fx * q.x / q.z + cx, fy * q.y / q.z + cy);
                (u - f64::from(px.x)).powi(2) + (v - f64::from(px.y)).powi(2) <= limit_sq
            }
        })
        .map(|(i, _)| i)
        .collect();
    Ok(Some(PnpResult {
        camera_from_object,
        inliers: indices,
    }))
}
