//! The yardsticks every backend is measured with, computed from its final estimates only.
//!
//! [`graph_error`] is GTSAM's `NonlinearFactorGraph::error(values)`: the sum over factors
//! of ½‖whitened residual‖² (for a robust factor its kernel's loss of the whitened norm,
//! GTSAM's `noiseModel::Robust::loss`), with GTSAM's residuals and `GTSAM_POSE3_EXPMAP`
//! (the default of its CMake build and of its Python wheels):
//! - `PriorFactor<Pose3>`: `Logmap(prior⁻¹·x)`;
//! - `BetweenFactor<Pose3>`: `Logmap(measured⁻¹·(x1⁻¹·x2))`;
//!
//! with `Logmap` the full SE(3) logarithm [`se3_log`] (rotation first, translation part
//! `V⁻¹·t`; Barfoot, "State Estimation for Robotics", 2017, §7.1.9; GTSAM's
//! `Pose3::Logmap`).
//!
//! [`ate_rmse`]: the absolute trajectory error (Sturm et al., "A Benchmark for the
//! Evaluation of RGB-D SLAM Systems", IROS 2012) of the positions after the rigid
//! alignment that minimises it: [`align_se3`] (Horn 1987 / Umeyama 1991 without scale,
//! through the SVD of the cross-covariance) or, for planar graphs, [`align_se2`] (the
//! same problem in the plane, closed form).

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};

use super::PoseGraphError;
use crate::factor_graph::backend::{Factor, PoseSigmas, Robust};

/// The SO(3) logarithm of a unit quaternion as a rotation vector, accurate near zero
/// (angle from `atan2`, not `acos`) and with angle in [0, π].
pub fn so3_log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (w, v) = if q.w < 0.0 {
        (-q.w, -q.imag())
    } else {
        (q.w, q.imag())
    };
    let n = v.norm();
    if n < 1e-12 {
        // θ/n → 2/w.
        return v * (2.0 / w);
    }
    v * (2.0 * n.atan2(w) / n)
}

/// The SE(3) logarithm of `pose` = (R, t): `(ω, V⁻¹·t)` with `ω = log(R)` and
/// `V⁻¹ = I − ½ŵ + c·ŵ²`, `c = (1 − θ/(2·tan(θ/2)))/θ²` (→ 1/12 as θ → 0).
pub fn se3_log(pose: &Isometry3<f64>) -> Vector6<f64> {
    let w = so3_log(&pose.rotation);
    let t = pose.translation.vector;
    let theta = w.norm();
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        (1.0 - theta / (2.0 * (0.5 * theta).tan())) / (theta * theta)
    };
    let wt = w.cross(&t);
    let u = t - 0.5 * wt + c * w.cross(&wt);
    Vector6::new(w.x, w.y, w.z, u.x, u.y, u.z)
}

/// GTSAM's loss of a whitened residual norm `d` (½d² without a kernel).
fn loss(d: f64, robust: Robust) -> f64 {
    match robust {
        Robust::None => 0.5 * d * d,
        Robust::Huber(k) if d.abs() <= k => 0.5 * d * d,
        Robust::Huber(k) => k * (d.abs() - 0.5 * k),
        Robust::Cauchy(k) => 0.5 * k * k * (1.0 + d * d / (k * k)).ln(),
    }
}

fn whitened_norm(xi: &Vector6<f64>, sigmas: &PoseSigmas) -> f64 {
    xi.component_div(sigmas).norm()
}

/// One factor's error in GTSAM's convention (see the module documentation). Only pose
/// priors and between factors can be evaluated.
pub fn factor_error(
    factor: &Factor,
    pose: &impl Fn(u64) -> Option<Isometry3<f64>>,
) -> Result<f64, PoseGraphError> {
    let get =
        |k: u64| pose(k).ok_or_else(|| PoseGraphError::Graph(format!("no estimate of pose {k}")));
    match factor {
        Factor::PosePrior {
            key,
            world_from_body,
            sigmas,
        } => {
            let xi = se3_log(&(world_from_body.inverse() * get(*key)?));
            Ok(loss(whitened_norm(&xi, sigmas), Robust::None))
        }
        Factor::Between {
            from,
            to,
            from_from_to,
            sigmas,
            robust,
        } => {
            let between = get(*from)?.inverse() * get(*to)?;
            let xi = se3_log(&(from_from_to.inverse() * between));
            Ok(loss(whitened_norm(&xi, sigmas), *robust))
        }
        other => Err(PoseGraphError::Graph(format!(
            "graph error: cannot evaluate {other:?}"
        ))),
    }
}

/// GTSAM's `graph.error(values)` over `factors`, with `pose` giving each pose's
/// estimate.
pub fn graph_error(
    factors: &[Factor],
    pose: impl Fn(u64) -> Option<Isometry3<f64>>,
) -> Result<f64, PoseGraphError> {
    factors.iter().map(|f| factor_error(f, &pose)).sum()
}

/// The rigid transform `T` minimising Σ‖T·pᵢ − qᵢ‖² (Horn/Umeyama without scale).
/// `None` with fewer than 3 points or a degenerate (collinear) configuration.
pub fn align_se3(p: &[Vector3<f64>], q: &[Vector3<f64>]) -> Option<Isometry3<f64>> {
    if p.len() != q.len() || p.len() < 3 {
        return None;
    }
    let n = p.len() as f64;
    let pm = p.iter().sum::<Vector3<f64>>() / n;
    let qm = q.iter().sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = p
        .iter()
        .zip(q)
        .map(|(a, b)| (a - pm) * (b - qm).transpose())
        .sum();
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    // Rank < 2: the rotation about the points' line is undetermined.
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if s[1] <= 1e-12 * s[0].max(1e-300) {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = qm - rot * pm;
    Some(Isometry3::from_parts(Translation3::from(t), rot))
}

/// The rotation about z and translation in the xy plane minimising Σ‖T·pᵢ − qᵢ‖² over
/// the xy components (z is left as is). `None` with fewer than 2 points.
pub fn align_se2(p: &[Vector3<f64>], q: &[Vector3<f64>]) -> Option<Isometry3<f64>> {
    if p.len() != q.len() || p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let pm = p.iter().sum::<Vector3<f64>>() / n;
    let qm = q.iter().sum::<Vector3<f64>>() / n;
    let (mut dot, mut cross) = (0.0, 0.0);
    for (a, b) in p.iter().zip(q) {
        let (a, b) = (a - pm, b - qm);
        dot += a.x * b.x + a.y * b.y;
        cross += a.x * b.y - a.y * b.x;
    }
    let rot = UnitQuaternion::from_euler_angles(0.0, 0.0, cross.atan2(dot));
    let mut t = qm - rot * pm;
    t.z = 0.0;
    Some(Isometry3::from_parts(Translation3::from(t), rot))
}

/// ATE RMSE (m) of `estimate` against `truth` over the keys both have, after the best
/// rigid alignment of the estimate onto the truth (planar: in the plane). Also returns
/// how many poses were compared.
pub fn ate_rmse(
    estimate: &BTreeMap<u64, Isometry3<f64>>,
    truth: &BTreeMap<u64, Isometry3<f64>>,
    planar: bool,
) -> Result<(f64, usize), PoseGraphError> {
    let (p, q): (Vec<_>, Vec<_>) = estimate
        .iter()
        .filter_map(|(k, e)| Some((e.translation.vector, truth.get(k)?.translation.vector)))
        .unzip();
    let align = if planar {
        align_se2(&p, &q)
    } else {
        align_se3(&p, &q)
    };
    let t = align.ok_or_else(|| {
        PoseGraphError::Graph(format!(
            "cannot align {} estimated poses to the ground truth",
            p.len()
        ))
    })?;
    let sq: f64 = p
        .iter()
        .zip(&q)
        .map(|(a, b)| (t * nalgebra::Point3::from(*a) - nalgebra::Point3::from(*b)).norm_squared())
        .sum();
    Ok(((sq / p.len() as f64).sqrt(), p.len()))
}
