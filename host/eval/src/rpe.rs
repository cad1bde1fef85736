//! Relative pose error (RPE; Sturm et al. 2012, §VI-A, with evo's pair selection): for
//! index pairs `(i, j)` the error pose is `E = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j)` (reference `Q`,
//! estimate `P`). Pairs are chosen on the (aligned) estimate's poses, or the
//! reference's:
//!
//! - frames: `(0, d), (d, 2d), …`, or with all pairs `(i, i + d)` for every `i`;
//! - metres: consecutive poses where the travelled path since the last chosen pose first
//!   reaches `d` (starting at pose 0); with all pairs, for every `i` the pose `j > i` whose
//!   path distance from `i` is closest to `d` (first on ties), kept if within
//!   `rel_tol · d`.

use nalgebra::Isometry3;

use crate::{
    Alignment, EvalError, Pairing, PosePairs, PoseRelation, Sim3, Statistics, Trajectory, align,
};

/// The unit of the RPE step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeltaUnit {
    /// Poses (evo's `--delta_unit f`).
    #[default]
    Frames,
    /// Metres of travelled path (evo's `--delta_unit m`).
    Metres,
}

/// Options of an RPE evaluation (defaults: evo's, i.e. 1 frame, translation part).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RpeOptions {
    /// How poses are paired.
    pub pairing: Pairing,
    /// How the estimate is aligned (changes metre-based pair selection with scale).
    pub alignment: Alignment,
    /// Align on the first `n` pairs only.
    pub n_to_align: Option<usize>,
    /// Which error is computed.
    pub relation: PoseRelation,
    /// The step, in `unit`; frames are truncated to an integer (at least 1).
    pub delta: f64,
    /// The unit of `delta`.
    pub unit: DeltaUnit,
    /// Relative tolerance of metre steps in all-pairs mode (evo's `--delta_tol`, 0.1).
    pub rel_tol: f64,
    /// Use every pose as a start, not only consecutive steps.
    pub all_pairs: bool,
    /// Choose pairs on the reference instead of the estimate.
    pub pairs_from_reference: bool,
}

impl Default for RpeOptions {
    fn default() -> Self {
        Self {
            pairing: Pairing::default(),
            alignment: Alignment::None,
            n_to_align: None,
            relation: PoseRelation::Translation,
            delta: 1.0,
            unit: DeltaUnit::Frames,
            rel_tol: 0.1,
            all_pairs: false,
            pairs_from_reference: false,
        }
    }
}

/// The outcome of an RPE evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct RpeResult {
    /// The associated poses, estimate aligned.
    pub pairs: PosePairs,
    /// The alignment applied to the estimate.
    pub transform: Sim3,
    /// The index pairs `(i, j)` into `pairs` the errors are computed on.
    pub id_pairs: Vec<(usize, usize)>,
    /// One error per index pair.
    pub errors: Vec<f64>,
    /// Statistics of `errors`.
    pub stats: Statistics,
}

/// The index pairs `(i, j)` of `poses` one step `delta` apart (see the module docs).
pub fn rpe_pairs(
    poses: &[Isometry3<f64>],
    delta: f64,
    unit: DeltaUnit,
    rel_tol: f64,
    all_pairs: bool,
) -> Result<Vec<(usize, usize)>, EvalError> {
    let n = poses.len();
    match unit {
        DeltaUnit::Frames => {
            if !delta.is_finite() || delta < 1.0 {
                return Err(EvalError::InvalidOption(format!(
                    "RPE delta must be at least 1 frame, got {delta}"
                )));
            }
            let d = delta as usize;
            Ok(if all_pairs {
                (0..n.saturating_sub(d)).map(|i| (i, i + d)).collect()
            } else {
                let ids: Vec<usize> = (0..n).step_by(d).collect();
                ids.windows(2).map(|w| (w[0], w[1])).collect()
            })
        }
        DeltaUnit::Metres => {
            if !delta.is_finite() || delta <= 0.0 {
                return Err(EvalError::InvalidOption(format!(
                    "RPE delta must be a positive length, got {delta} m"
                )));
            }
            let position = |i: usize| poses[i].translation.vector;
            if all_pairs {
                Ok(all_pairs_by_path(poses, delta, delta * rel_tol))
            } else {
                let mut ids = vec![0];
                let mut path = 0.0;
                for i in 1..n {
                    path += (position(i) - position(i - 1)).norm();
                    if path >= delta {
                        ids.push(i);
                        path = 0.0;
                    }
                }
                Ok(ids.windows(2).map(|w| (w[0], w[1])).collect())
            }
        }
    }
}

/// For every `i`, the `j > i` whose path distance from `i` is closest to `delta` (first
/// on ties), kept if within `tol`; binary search on the accumulated distances.
fn all_pairs_by_path(poses: &[Isometry3<f64>], delta: f64, tol: f64) -> Vec<(usize, usize)> {
    let mut accumulated = Vec::with_capacity(poses.len());
    let mut total = 0.0;
    accumulated.push(total);
    for w in poses.windows(2) {
        total += (w[0].translation.vector - w[1].translation.vector).norm();
        accumulated.push(total);
    }
    let mut pairs = Vec::new();
    for i in 0..accumulated.len().saturating_sub(1) {
        let start = accumulated[i];
        let from_here = |j: usize| accumulated[j] - start;
        let diff = |j: usize| (from_here(j) - delta).abs();
        // First j > i with from_here(j) >= delta; the values below it shrink towards it.
        let upper = i + 1 + accumulated[i + 1..].partition_point(|&a| a - start < delta);
        let mut best = None;
        if upper > i + 1 {
            let mut lower = upper - 1;
            let d = diff(lower);
            while lower > i + 1 && diff(lower - 1) == d {
                lower -= 1;
            }
            best = Some((lower, d));
        }
        if upper < accumulated.len() {
            let d = diff(upper);
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((upper, d));
            }
        }
        if let Some((j, d)) = best
            && d <= tol
        {
            pairs.push((i, j));
        }
    }
    pairs
}

/// The RPE of each index pair.
pub fn rpe_errors(
    reference: &[Isometry3<f64>],
    estimate: &[Isometry3<f64>],
    id_pairs: &[(usize, usize)],
    relation: PoseRelation,
) -> Vec<f64> {
    assert_eq!(reference.len(), estimate.len(), "RPE needs pose pairs");
    id_pairs
        .iter()
        .map(|&(i, j)| {
            let q_rel = reference[i].inverse() * reference[j];
            let p_rel = estimate[i].inverse() * estimate[j];
            relation.error(&(q_rel.inverse() * p_rel))
        })
        .collect()
}

/// Associates, aligns, selects pairs and computes the RPE of `estimate` against
/// `reference`. Errors if no pair is one step apart.
pub fn evaluate_rpe(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: &RpeOptions,
) -> Result<RpeResult, EvalError> {
    let mut pairs = options.pairing.pair(reference, estimate)?;
    let transform = align(&mut pairs, options.alignment, options.n_to_align)?;
    let poses = if options.pairs_from_reference {
        &pairs.reference
    } else {
        &pairs.estimate
    };
    let id_pairs = rpe_pairs(
        poses,
        options.delta,
        options.unit,
        options.rel_tol,
        options.all_pairs,
    )?;
    let errors = rpe_errors(
        &pairs.reference,
        &pairs.estimate,
        &id_pairs,
        options.relation,
    );
    let stats = Statistics::from_errors(&errors).map_err(|_| {
        EvalError::InvalidOption(format!(
            "no pose pairs {} {} apart among {} poses",
            options.delta,
            match options.unit {
                DeltaUnit::Frames => "frames",
                DeltaUnit::Metres => "m",
            },
            pairs.len()
        ))
    })?;
    Ok(RpeResult {
        pairs,
        transform,
        id_pairs,
        errors,
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// Poses along x at the given positions.
    fn line(xs: &[f64]) -> Vec<Isometry3<f64>> {
        xs.iter()
            .map(|&x| Isometry3::translation(x, 0.0, 0.0))
            .collect()
    }

    #[test]
    fn frame_pairs_consecutive_and_all() {
        let poses = line(&[0.0; 7]);
        assert_eq!(
            rpe_pairs(&poses, 3.0, DeltaUnit::Frames, 0.1, false).unwrap(),
            vec![(0, 3), (3, 6)],
            "expected steps of 3 from 0"
        );
        assert_eq!(
            rpe_pairs(&poses, 5.0, DeltaUnit::Frames, 0.1, true).unwrap(),
            vec![(0, 5), (1, 6)],
            "expected every start with an end 5 frames later"
        );
        assert!(
            rpe_pairs(&poses, 0.5, DeltaUnit::Frames, 0.1, false).is_err(),
            "expected an error for a step below 1 frame"
        );
    }

    #[test]
    fn metre_pairs_consecutive_start_at_zero() {
        // Path 0, 0.4, 0.8, 1.2 (≥ 1 → pick 3, reset), 1.6, 2.0, 2.4 (1.2 since 3 → pick 6).
        let poses = line(&[0.0, 0.4, 0.8, 1.2, 1.6, 2.0, 2.4]);
        assert_eq!(
            rpe_pairs(&poses, 1.0, DeltaUnit::Metres, 0.1, false).unwrap(),
            vec![(0, 3), (3, 6)],
            "expected pairs (0,3), (3,6)"
        );
    }

    #[test]
    fn metre_pairs_all_within_tolerance() {
        // From 0: distances 0.5, 1.05, 1.5 → 1.05 is within 0.1 of 1; from 1: 0.55, 1.0 → j = 3;
        // from 2: 0.45 only → none.
        let poses = line(&[0.0, 0.5, 1.05, 1.5]);
        assert_eq!(
            rpe_pairs(&poses, 1.0, DeltaUnit::Metres, 0.1, true).unwrap(),
            vec![(0, 2), (1, 3)],
            "expected (0,2) and (1,3)"
        );
    }

    #[test]
    fn rpe_of_a_constant_step_error() {
        // The estimate moves 1.1 m per step where the reference moves 1 m: 0.1 m error per pair.
        let reference = line(&[0.0, 1.0, 2.0, 3.0]);
        let estimate = line(&[0.0, 1.1, 2.2, 3.3]);
        let errors = rpe_errors(
            &reference,
            &estimate,
            &[(0, 1), (1, 2), (2, 3)],
            PoseRelation::Translation,
        );
        for e in errors {
            assert!((e - 0.1).abs() < 1e-12, "expected 0.1 m per step, got {e}");
        }
        let turned: Vec<_> = reference
            .iter()
            .enumerate()
            .map(|(i, p)| p * Isometry3::rotation(Vector3::new(0.0, 0.0, 0.01 * i as f64)))
            .collect();
        let angles = rpe_errors(&reference, &turned, &[(0, 2)], PoseRelation::AngleDeg);
        assert!(
            (angles[0] - 0.02f64.to_degrees()).abs() < 1e-10,
            "expected 0.02 rad in degrees, got {}",
            angles[0]
        );
    }
}
