//! Absolute pose error (APE; the absolute trajectory error of Sturm et al. 2012, §VI-B,
//! generalised to evo's pose relations): after association and alignment, the error of
//! pair `i` is the chosen relation of `E_i = P_i⁻¹ Q_i` (estimate `P`, reference `Q`); the
//! translation part is `‖p_i - q_i‖`.

use nalgebra::Isometry3;

use crate::{
    Alignment, EvalError, Pairing, PosePairs, PoseRelation, Sim3, Statistics, Trajectory, align,
};

/// Options of an APE evaluation (defaults: evo's, i.e. stamps within 0.01 s, no
/// alignment, translation part).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ApeOptions {
    /// How poses are paired.
    pub pairing: Pairing,
    /// How the estimate is aligned.
    pub alignment: Alignment,
    /// Align on the first `n` pairs only.
    pub n_to_align: Option<usize>,
    /// Which error is computed.
    pub relation: PoseRelation,
}

/// The outcome of an APE evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct ApeResult {
    /// The associated poses, estimate aligned.
    pub pairs: PosePairs,
    /// The alignment applied to the estimate.
    pub transform: Sim3,
    /// One error per pair.
    pub errors: Vec<f64>,
    /// Statistics of `errors`.
    pub stats: Statistics,
}

/// The APE of each pair of (already aligned) poses.
pub fn ape_errors(
    reference: &[Isometry3<f64>],
    estimate: &[Isometry3<f64>],
    relation: PoseRelation,
) -> Vec<f64> {
    assert_eq!(reference.len(), estimate.len(), "APE needs pose pairs");
    let pairs = reference.iter().zip(estimate);
    match relation {
        PoseRelation::Translation => pairs
            .map(|(q, p)| (p.translation.vector - q.translation.vector).norm())
            .collect(),
        _ => pairs
            .map(|(q, p)| relation.error(&(p.inverse() * q)))
            .collect(),
    }
}

/// Associates, aligns and computes the APE of `estimate` against `reference`.
pub fn evaluate_ape(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: &ApeOptions,
) -> Result<ApeResult, EvalError> {
    let mut pairs = options.pairing.pair(reference, estimate)?;
    let transform = align(&mut pairs, options.alignment, options.n_to_align)?;
    let errors = ape_errors(&pairs.reference, &pairs.estimate, options.relation);
    let stats = Statistics::from_errors(&errors)?;
    Ok(ApeResult {
        pairs,
        transform,
        errors,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn ape_of_a_shifted_and_rotated_estimate() {
        // Estimate = reference shifted by (0.3, 0.4, 0) and turned 0.1 rad about z (in its
        // body frame): translation error 0.5 m, angle 0.1 rad, everywhere.
        let reference: Vec<_> = (0..4)
            .map(|i| {
                Isometry3::new(
                    Vector3::new(i as f64, 0.0, 0.0),
                    Vector3::new(0.0, 0.0, 0.2 * i as f64),
                )
            })
            .collect();
        let estimate: Vec<_> = reference
            .iter()
            .map(|q| {
                Isometry3::translation(0.3, 0.4, 0.0)
                    * q
                    * Isometry3::rotation(Vector3::new(0.0, 0.0, 0.1))
            })
            .collect();
        for e in ape_errors(&reference, &estimate, PoseRelation::Translation) {
            assert!((e - 0.5).abs() < 1e-12, "expected 0.5 m, got {e}");
        }
        for e in ape_errors(&reference, &estimate, PoseRelation::AngleRad) {
            assert!((e - 0.1).abs() < 1e-12, "expected 0.1 rad, got {e}");
        }
    }

    #[test]
    fn se3_alignment_removes_a_rigid_offset() {
        let stamps: Vec<f64> = (0..10).map(|i| i as f64 * 0.1).collect();
        let reference = Trajectory::new(
            stamps.clone(),
            stamps
                .iter()
                .map(|&t| Isometry3::translation(t, (3.0 * t).sin(), 0.2 * t * t))
                .collect(),
        );
        let offset = Isometry3::new(Vector3::new(5.0, -1.0, 2.0), Vector3::new(0.1, 0.2, 0.3));
        let estimate =
            Trajectory::new(stamps, reference.poses.iter().map(|p| offset * p).collect());
        let options = ApeOptions {
            alignment: Alignment::Se3,
            ..Default::default()
        };
        let result = evaluate_ape(&reference, &estimate, &options).unwrap();
        assert_eq!(result.stats.pairs, 10, "expected all 10 poses paired");
        assert!(
            result.stats.max < 1e-12,
            "expected zero error after SE(3) alignment, got {}",
            result.stats.max
        );
        let unaligned = evaluate_ape(&reference, &estimate, &ApeOptions::default()).unwrap();
        assert!(
            unaligned.stats.min > 1.0,
            "expected a large error without alignment, got {}",
            unaligned.stats.min
        );
    }
}
