//! New map points between a keyframe and its covisible neighbours (ORB-SLAM, T-RO 2015,
//! §VI-C; ORB-SLAM2's `CreateNewMapPoints` for stereo and RGB-D): unmatched keypoints under
//! the same vocabulary node are paired when the second lies near the epipolar line of the
//! first; each pair is triangulated (linear DLT, Hartley and Zisserman §12.2) when the rays'
//! parallax beats the depth's own, or else taken from the keypoint's depth; the point must
//! lie in front of both cameras, reproject within χ² 5.991 (7.8 with a right coordinate)
//! and be seen at consistent scales.

use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Vector3};
use slam_common::place::bow::hamming;

use crate::frame::{Camera, Frame};
use crate::map::Map;
use crate::matcher::{TH_LOW, common_nodes, rotation_outliers};

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The fundamental matrix `F12` of two views: `x1ᵀ F12 x2 = 0` for pixels `x1`, `x2` of
/// one point (so `F12ᵀ x1` is the epipolar line of `x1` in view 2).
fn fundamental(camera: &Camera, t1w: &Isometry3<f64>, t2w: &Isometry3<f64>) -> Matrix3<f64> {
    let t12 = t1w * t2w.inverse();
    let r12 = t12.rotation.to_rotation_matrix().into_inner();
    let c = &camera.stereo;
    let k = Matrix3::new(c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
    let k_inv = k.try_inverse().expect("a pinhole is invertible");
    k_inv.transpose() * skew(&t12.translation.vector) * r12 * k_inv
}

/// Distance of keypoint 2 to the epipolar line of keypoint 1, squared, within 3.84 σ².
fn near_epipolar_line(
    f12: &Matrix3<f64>,
    camera: &Camera,
    f1: &Frame,
    i1: usize,
    f2: &Frame,
    i2: usize,
) -> bool {
    let (k1, k2) = (&f1.keys[i1], &f2.keys[i2]);
    let x1 = Vector3::new(f64::from(k1.u), f64::from(k1.v), 1.0);
    let line = f12.transpose() * x1;
    let den = line.x * line.x + line.y * line.y;
    if den == 0.0 {
        return false;
    }
    let num = line.x * f64::from(k2.u) + line.y * f64::from(k2.v) + line.z;
    num * num / den < 3.84 * camera.level_sigma2[usize::from(k2.octave)]
}

/// Unmatched keypoint pairs between `kf1` and `kf2` under the same vocabulary node, best
/// Hamming distance ≤ 50, near the epipolar line, rotation-consistent.
fn search_for_triangulation(
    map: &Map,
    camera: &Camera,
    kf1: usize,
    kf2: usize,
) -> Vec<(usize, usize)> {
    let (k1, k2) = (&map.keyframes[kf1], &map.keyframes[kf2]);
    let (f1, f2) = (&k1.frame, &k2.frame);
    let f12 = fundamental(camera, &f1.camera_from_world, &f2.camera_from_world);
    // The epipole: the centre of camera 1 seen from camera 2.
    let c1_in_2 = f2.camera_from_world * Point3::from(k1.centre());
    let epipole = (c1_in_2.z > 0.0).then(|| {
        let c = &camera.stereo;
        (
            c.fx * c1_in_2.x / c1_in_2.z + c.cx,
            c.fy * c1_in_2.y / c1_in_2.z + c.cy,
        )
    });
    let free = |f: &Frame, i: usize| f.points[i].and_then(|p| map.resolve(p)).is_none();
    let mut taken2 = vec![false; f2.len()];
    let mut pairs = Vec::new();
    let mut rotations = Vec::new();
    let (a, b) = (&f1.features.entries, &f2.features.entries);
    for (na, nb) in common_nodes(a, b) {
        for &i1 in na {
            let i1 = i1 as usize;
            if !free(f1, i1) {
                continue;
            }
            let stereo1 = f1.u_right[i1] >= 0.0;
            let mut best = (TH_LOW + 1, None);
            for &i2 in nb {
                let i2 = i2 as usize;
                if taken2[i2] || !free(f2, i2) {
                    continue;
                }
                let d = hamming(&f1.descriptors[i1], &f2.descriptors[i2]);
                if d > TH_LOW || d > best.0 {
                    continue;
                }
                let stereo2 = f2.u_right[i2] >= 0.0;
                if let (false, false, Some((eu, ev))) = (stereo1, stereo2, epipole) {
                    let k2 = &f2.keys[i2];
                    let (du, dv) = (eu - f64::from(k2.u), ev - f64::from(k2.v));
                    if du * du + dv * dv < 100.0 * camera.scale_factors[usize::from(k2.octave)] {
                        continue;
                    }
                }
                if near_epipolar_line(&f12, camera, f1, i1, f2, i2) {
                    best = (d, Some(i2));
                }
            }
            if let (_, Some(i2)) = best {
                taken2[i2] = true;
                rotations.push((pairs.len(), f1.keys[i1].angle_deg - f2.keys[i2].angle_deg));
                pairs.push((i1, i2));
            }
        }
    }
    let drop = rotation_outliers(&rotations);
    pairs
        .into_iter()
        .enumerate()
        .filter(|(k, _)| !drop.contains(k))
        .map(|(_, p)| p)
        .collect()
}

/// Linear triangulation of one point from two views (pixels and `camera_from_world`).
fn triangulate(
    camera: &Camera,
    f1: &Frame,
    i1: usize,
    f2: &Frame,
    i2: usize,
) -> Option<Vector3<f64>> {
    let c = &camera.stereo;
    let rows = |f: &Frame, i: usize| {
        let t = f.camera_from_world.to_homogeneous();
        let p = Matrix3::new(c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0)
            * t.fixed_view::<3, 4>(0, 0);
        let (u, v) = (f64::from(f.keys[i].u), f64::from(f.keys[i].v));
        (u * p.row(2) - p.row(0), v * p.row(2) - p.row(1))
    };
    let (a0, a1) = rows(f1, i1);
    let (a2, a3) = rows(f2, i2);
    let a = Matrix4::from_rows(&[a0, a1, a2, a3]);
    let svd = a.svd(false, true);
    let v_t = svd.v_t?;
    let (_, min) = svd
        .singular_values
        .iter()
        .enumerate()
        .fold(
            (f64::MAX, 0),
            |acc, (k, &s)| if s < acc.0 { (s, k) } else { acc },
        );
    let x = v_t.row(min);
    (x[3].abs() > 1e-12).then(|| Vector3::new(x[0] / x[3], x[1] / x[3], x[2] / x[3]))
}

/// Whether a world point reprojects onto keypoint `i` of a frame within its χ² bound.
fn reprojects(camera: &Camera, f: &Frame, i: usize, world: &Vector3<f64>) -> bool {
    let p = f.camera_from_world * Point3::from(*world);
    if p.z <= 0.0 {
        return false;
    }
    let c = &camera.stereo;
    let k = &f.keys[i];
    let u = c.fx * p.x / p.z + c.cx;
    let v = c.fy * p.y / p.z + c.cy;
    let (eu, ev) = (u - f64::from(k.u), v - f64::from(k.v));
    let sigma2 = camera.level_sigma2[usize::from(k.octave)];
    if f.u_right[i] >= 0.0 {
        let er = u - c.bf / p.z - f.u_right[i];
        eu * eu + ev * ev + er * er <= 7.8 * sigma2
    } else {
        eu * eu + ev * ev <= 5.991 * sigma2
    }
}

/// Triangulates new points of keyframe `kf` with its `neighbours` best covisibles; returns
/// the new points' ids.
pub fn create_new_points(
    map: &mut Map,
    camera: &Camera,
    kf: usize,
    neighbours: usize,
) -> Vec<usize> {
    let baseline = camera.stereo.bf / camera.stereo.fx;
    let ratio_factor = 1.5 * camera.scale_factors.get(1).copied().unwrap_or(1.2);
    let mut created = Vec::new();
    for kf2 in map.keyframes[kf].best_covisibles(neighbours) {
        if map.keyframes[kf2].bad {
            continue;
        }
        if (map.keyframes[kf2].centre() - map.keyframes[kf].centre()).norm() < baseline {
            continue;
        }
        for (i1, i2) in search_for_triangulation(map, camera, kf, kf2) {
            let (f1, f2) = (&map.keyframes[kf].frame, &map.keyframes[kf2].frame);
            let (o1, o2) = (map.keyframes[kf].centre(), map.keyframes[kf2].centre());
            let ray = |f: &Frame, i: usize| {
                let k = &f.keys[i];
                let d = camera.unproject(f64::from(k.u), f64::from(k.v), 1.0);
                f.camera_from_world.rotation.inverse() * d
            };
            let (r1, r2) = (ray(f1, i1), ray(f2, i2));
            let cos_rays = r1.dot(&r2) / (r1.norm() * r2.norm());
            let stereo_cos = |f: &Frame, i: usize| {
                if f.depth[i] > 0.0 {
                    (2.0 * (baseline / 2.0).atan2(f.depth[i])).cos()
                } else {
                    2.0
                }
            };
            let (cs1, cs2) = (stereo_cos(f1, i1), stereo_cos(f2, i2));
            let (stereo1, stereo2) = (f1.depth[i1] > 0.0, f2.depth[i2] > 0.0);
            let world = if cos_rays < cs1.min(cs2)
                && cos_rays > 0.0
                && (stereo1 || stereo2 || cos_rays < 0.9998)
            {
                triangulate(camera, f1, i1, f2, i2)
            } else if stereo1 && cs1 < cs2 {
                f1.unproject_world(camera, i1)
            } else if stereo2 && cs2 < cs1 {
                f2.unproject_world(camera, i2)
            } else {
                None
            };
            let Some(world) = world else { continue };
            if !world.iter().all(|v| v.is_finite()) {
                continue;
            }
            if !reprojects(camera, f1, i1, &world) || !reprojects(camera, f2, i2, &world) {
                continue;
            }
            // Scale consistency: the distance ratio agrees with the octave ratio.
            let (d1, d2) = ((world - o1).norm(), (world - o2).norm());
            if d1 == 0.0 || d2 == 0.0 {
                continue;
            }
            let ratio_dist = d2 / d1;
            let ratio_octave = camera.scale_factors[usize::from(f1.keys[i1].octave)]
                / camera.scale_factors[usize::from(f2.keys[i2].octave)];
            if ratio_dist * ratio_factor < ratio_octave || ratio_dist > ratio_octave * ratio_factor
            {
                continue;
            }
            let p = map.add_point(camera, world, kf, i1);
            map.add_observation(p, kf2, i2);
            map.compute_distinctive_descriptor(p);
            map.update_normal_and_depth(camera, p);
            created.push(p);
        }
    }
    created
}
