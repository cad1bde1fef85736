//! Alignment of the estimate to the reference, as evo does it:
//!
//! - `Origin`: left-multiply the estimate by `ref_0 · est_0⁻¹`, so the first poses coincide;
//! - `Se3` / `Sim3`: the least-squares rotation, translation (and scale) between the
//!   associated positions, by Umeyama's method (Umeyama, IEEE PAMI 13(4), 1991, eqs.
//!   34–43), applied as `p ↦ R (s p) + t`, `R_est ↦ R R_est`;
//! - `Scale`: only the Sim(3) scale, applied to the positions (evo's `-s` without `-a`);
//! - `FourDof`: yaw about the world z axis and a translation, for gravity-aligned systems
//!   (Zhang & Scaramuzza, IROS 2018, "posyaw"), in closed form.
//!
//! SE(3), Sim(3), scale and 4-DoF optionally use only the first `n` pairs.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::{EvalError, PosePairs};

/// How the estimate is aligned to the reference before errors are computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Alignment {
    /// No alignment (evo's default).
    #[default]
    None,
    /// First poses made equal (evo's `--align_origin`).
    Origin,
    /// SE(3) Umeyama (evo's `-a`).
    Se3,
    /// Sim(3) Umeyama (evo's `-as`).
    Sim3,
    /// Only the Sim(3) scale (evo's `-s`).
    Scale,
    /// Yaw and translation (4 degrees of freedom).
    FourDof,
}

impl Alignment {
    /// The name the command line, bench files and `metrics.json` give it.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Origin => "origin",
            Self::Se3 => "se3",
            Self::Sim3 => "sim3",
            Self::Scale => "scale",
            Self::FourDof => "4dof",
        }
    }
}

/// A similarity transform `p ↦ R (s p) + t` applied to the estimate (`aligned_from_est`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sim3 {
    /// Rotation `R`.
    pub rotation: UnitQuaternion<f64>,
    /// Translation `t`, metres.
    pub translation: Vector3<f64>,
    /// Scale `s` (1 for rigid alignments).
    pub scale: f64,
}

impl Default for Sim3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Sim3 {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }

    /// Applies the transform to a pose: position `R (s p) + t`, rotation `R R_pose`.
    pub fn apply(&self, pose: &Isometry3<f64>) -> Isometry3<f64> {
        let r = self.rotation.to_rotation_matrix();
        self.apply_with(&r, pose)
    }

    fn apply_with(&self, r: &Rotation3<f64>, pose: &Isometry3<f64>) -> Isometry3<f64> {
        let position = r * (pose.translation.vector * self.scale) + self.translation;
        Isometry3::from_parts(Translation3::from(position), self.rotation * pose.rotation)
    }
}

/// Umeyama's least-squares similarity `y ≈ s R x + t` between corresponding points
/// (Umeyama 1991; rigid if `with_scale` is false, then `s = 1`).
///
/// Errors if fewer than two singular values of the cross-covariance exceed machine
/// epsilon (e.g. all points on one line), as evo does.
pub fn umeyama(
    x: &[Vector3<f64>],
    y: &[Vector3<f64>],
    with_scale: bool,
) -> Result<Sim3, EvalError> {
    assert_eq!(x.len(), y.len(), "umeyama needs corresponding points");
    let n = x.len();
    if n == 0 {
        return Err(EvalError::TooFewPoses {
            what: "Umeyama alignment",
            needed: 1,
            got: 0,
        });
    }
    let inv_n = 1.0 / n as f64;
    let mean_x = x.iter().sum::<Vector3<f64>>() * inv_n;
    let mean_y = y.iter().sum::<Vector3<f64>>() * inv_n;
    let mut sigma_x = 0.0;
    let mut outer_sum = Matrix3::zeros();
    for (xi, yi) in x.iter().zip(y) {
        let dx = xi - mean_x;
        sigma_x += dx.norm_squared();
        outer_sum += (yi - mean_y) * dx.transpose();
    }
    sigma_x *= inv_n;
    let cov = outer_sum * inv_n;
    let svd = cov.svd(true, true);
    let (u, v_t, d) = (
        svd.u.expect("u requested"),
        svd.v_t.expect("v_t requested"),
        svd.singular_values,
    );
    if d.iter().filter(|&&s| s > f64::EPSILON).count() < 2 {
        return Err(EvalError::Degenerate { what: "Umeyama" });
    }
    let mut s = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        s.z = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&s) * v_t;
    let scale = if with_scale { d.dot(&s) / sigma_x } else { 1.0 };
    let translation = mean_y - scale * (r * mean_x);
    Ok(Sim3 {
        rotation: UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
        translation,
        scale,
    })
}

/// The yaw (about z) and translation that best map `x` onto `y` in the least-squares
/// sense: `θ = atan2(Σ (x̃ × ỹ)_z, Σ x̃_xy · ỹ_xy)` on centred points, `t = ȳ - R x̄`.
pub fn align_4dof(x: &[Vector3<f64>], y: &[Vector3<f64>]) -> Result<Sim3, EvalError> {
    assert_eq!(x.len(), y.len(), "align_4dof needs corresponding points");
    if x.is_empty() {
        return Err(EvalError::TooFewPoses {
            what: "4-DoF alignment",
            needed: 1,
            got: 0,
        });
    }
    let inv_n = 1.0 / x.len() as f64;
    let mean_x = x.iter().sum::<Vector3<f64>>() * inv_n;
    let mean_y = y.iter().sum::<Vector3<f64>>() * inv_n;
    let (mut dot, mut cross, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0);
    for (xi, yi) in x.iter().zip(y) {
        let (a, b) = (xi - mean_x, yi - mean_y);
        dot += a.x * b.x + a.y * b.y;
        cross += a.x * b.y - a.y * b.x;
        sxx += a.x * a.x + a.y * a.y;
        syy += b.x * b.x + b.y * b.y;
    }
    if dot.hypot(cross) <= f64::EPSILON * (sxx * syy).sqrt() || sxx == 0.0 || syy == 0.0 {
        return Err(EvalError::Degenerate { what: "4-DoF" });
    }
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), cross.atan2(dot));
    Ok(Sim3 {
        rotation,
        translation: mean_y - rotation * mean_x,
        scale: 1.0,
    })
}

/// Aligns `pairs.estimate` to `pairs.reference` in place and returns the applied
/// transform. `n_to_align` limits SE(3), Sim(3), scale and 4-DoF alignment to the first
/// `n` pairs (all if `None` or larger than the number of pairs).
pub fn align(
    pairs: &mut PosePairs,
    alignment: Alignment,
    n_to_align: Option<usize>,
) -> Result<Sim3, EvalError> {
    if pairs.is_empty() {
        return Err(EvalError::TooFewPoses {
            what: "alignment",
            needed: 1,
            got: 0,
        });
    }
    let n = n_to_align.unwrap_or(pairs.len()).min(pairs.len());
    if n == 0 {
        return Err(EvalError::InvalidOption(
            "n_to_align must be at least 1".into(),
        ));
    }
    let points = |poses: &[Isometry3<f64>]| -> Vec<Vector3<f64>> {
        poses[..n].iter().map(|p| p.translation.vector).collect()
    };
    let transform = match alignment {
        Alignment::None => return Ok(Sim3::identity()),
        Alignment::Origin => {
            let t = pairs.reference[0] * pairs.estimate[0].inverse();
            Sim3 {
                rotation: t.rotation,
                translation: t.translation.vector,
                scale: 1.0,
            }
        }
        Alignment::Se3 | Alignment::Sim3 | Alignment::Scale => {
            let with_scale = alignment != Alignment::Se3;
            let sim3 = umeyama(
                &points(&pairs.estimate),
                &points(&pairs.reference),
                with_scale,
            )?;
            if alignment == Alignment::Scale {
                Sim3 {
                    scale: sim3.scale,
                    ..Sim3::identity()
                }
            } else {
                sim3
            }
        }
        Alignment::FourDof => align_4dof(&points(&pairs.estimate), &points(&pairs.reference))?,
    };
    let r = transform.rotation.to_rotation_matrix();
    for pose in &mut pairs.estimate {
        *pose = transform.apply_with(&r, pose);
    }
    Ok(transform)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<Vector3<f64>> {
        vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(1.0, 1.0, 0.5),
            Vector3::new(0.0, 1.0, 1.0),
        ]
    }

    #[test]
    fn umeyama_recovers_a_known_similarity() {
        let truth = Sim3 {
            rotation: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
            translation: Vector3::new(1.0, -2.0, 3.0),
            scale: 2.5,
        };
        let x = square();
        let y: Vec<_> = x
            .iter()
            .map(|p| truth.rotation * (p * truth.scale) + truth.translation)
            .collect();
        let sim3 = umeyama(&x, &y, true).unwrap();
        assert!(
            (sim3.scale - 2.5).abs() < 1e-12,
            "expected scale 2.5, got {}",
            sim3.scale
        );
        assert!(
            sim3.rotation.angle_to(&truth.rotation) < 1e-12,
            "expected the true rotation"
        );
        assert!(
            (sim3.translation - truth.translation).norm() < 1e-12,
            "expected t = (1,-2,3), got {}",
            sim3.translation
        );
        let se3 = umeyama(&x, &y, false).unwrap();
        assert_eq!(se3.scale, 1.0, "expected scale 1 without scale correction");
    }

    #[test]
    fn umeyama_rejects_collinear_points() {
        let x: Vec<_> = (0..5).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        let err = umeyama(&x, &x, false).unwrap_err();
        assert!(
            err.to_string().contains("degenerate"),
            "expected a degenerate-rank error, got {err}"
        );
    }

    #[test]
    fn four_dof_recovers_yaw_and_translation_only() {
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -2.0);
        let x = square();
        let y: Vec<_> = x
            .iter()
            .map(|p| yaw * p + Vector3::new(0.5, 0.25, -1.0))
            .collect();
        let t = align_4dof(&x, &y).unwrap();
        assert!(t.rotation.angle_to(&yaw) < 1e-12, "expected yaw -2 rad");
        assert!(
            (t.translation - Vector3::new(0.5, 0.25, -1.0)).norm() < 1e-12,
            "expected t = (0.5,0.25,-1)"
        );
    }

    #[test]
    fn origin_alignment_makes_first_poses_equal() {
        let reference =
            vec![Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.0, 0.0, 0.3)); 2];
        let estimate = vec![
            Isometry3::new(Vector3::new(-1.0, 0.0, 0.0), Vector3::new(0.2, 0.0, 0.0)),
            Isometry3::new(Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.2, 0.0, 0.0)),
        ];
        let mut pairs = PosePairs {
            stamps: vec![0.0, 1.0],
            reference: reference.clone(),
            estimate,
        };
        align(&mut pairs, Alignment::Origin, None).unwrap();
        let d = pairs.estimate[0].inverse() * reference[0];
        assert!(
            d.translation.vector.norm() < 1e-12 && d.rotation.angle() < 1e-12,
            "expected est_0 = ref_0 after origin alignment"
        );
        // The second estimate is 1 m along the first's world x; it stays 1 m from the first.
        let gap =
            (pairs.estimate[1].translation.vector - pairs.estimate[0].translation.vector).norm();
        assert!(
            (gap - 1.0).abs() < 1e-12,
            "expected the rigid shape kept (gap 1 m), got {gap}"
        );
    }

    #[test]
    fn four_dof_alignment_keeps_roll_and_pitch_errors() {
        // The estimate is the reference yawed by 1 rad, shifted, and pitched by 0.1 rad in
        // its body frame: 4-DoF alignment removes yaw and shift but not the pitch.
        let reference: Vec<_> = square()
            .iter()
            .map(|p| Isometry3::translation(p.x, p.y, p.z))
            .collect();
        let world = Isometry3::new(Vector3::new(3.0, -1.0, 0.2), Vector3::new(0.0, 0.0, 1.0));
        let pitch = Isometry3::rotation(Vector3::new(0.0, 0.1, 0.0));
        let estimate: Vec<_> = reference.iter().map(|q| world * q * pitch).collect();
        let mut pairs = PosePairs {
            stamps: vec![0.0; 4],
            reference: reference.clone(),
            estimate,
        };
        align(&mut pairs, Alignment::FourDof, None).unwrap();
        for (q, p) in reference.iter().zip(&pairs.estimate) {
            let e = p.inverse() * q;
            assert!(
                (q.translation.vector - p.translation.vector).norm() < 1e-12,
                "expected positions aligned"
            );
            assert!(
                (e.rotation.angle() - 0.1).abs() < 1e-12,
                "expected the 0.1 rad pitch kept, got {}",
                e.rotation.angle()
            );
        }
    }

    #[test]
    fn scale_only_alignment_scales_positions() {
        let reference: Vec<_> = square()
            .iter()
            .map(|p| Isometry3::translation(2.0 * p.x, 2.0 * p.y, 2.0 * p.z))
            .collect();
        let estimate: Vec<_> = square()
            .iter()
            .map(|p| Isometry3::translation(p.x, p.y, p.z))
            .collect();
        let mut pairs = PosePairs {
            stamps: vec![0.0; 4],
            reference,
            estimate,
        };
        let t = align(&mut pairs, Alignment::Scale, None).unwrap();
        assert!(
            (t.scale - 2.0).abs() < 1e-12,
            "expected scale 2, got {}",
            t.scale
        );
        assert_eq!(
            t.rotation,
            UnitQuaternion::identity(),
            "expected no rotation for scale-only"
        );
        assert!(
            (pairs.estimate[2].translation.vector - Vector3::new(2.0, 2.0, 1.0)).norm() < 1e-12,
            "expected (2,2,1)"
        );
    }
}
