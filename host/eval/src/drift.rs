//! KITTI-style drift (Geiger et al., CVPR 2012, odometry devkit): for start poses every
//! `step` poses and each segment length `L`, the end pose is the first whose reference
//! path distance from the start exceeds `L`; the segment error is
//! `E = (P_s⁻¹ P_e)⁻¹ (Q_s⁻¹ Q_e)` (estimate `P`, reference `Q`); the drift is the mean of
//! `‖t_E‖ / L` in percent and of `angle(E) / L` in degrees per 100 m. The lengths are
//! scaled to short runs (default 5, 10, 20 m instead of KITTI's 100 … 800 m).

use nalgebra::Isometry3;

use crate::{EvalError, PoseRelation};

/// Options of the drift computation.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftOptions {
    /// Segment lengths, metres.
    pub lengths: Vec<f64>,
    /// Poses between segment starts (the devkit uses 10).
    pub step: usize,
}

impl Default for DriftOptions {
    fn default() -> Self {
        Self {
            lengths: vec![5.0, 10.0, 20.0],
            step: 10,
        }
    }
}

/// The drift over the segments of one length (`length` 0: over all segments).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SegmentDrift {
    /// Segment length, metres.
    pub length: f64,
    /// Number of segments of this length.
    pub segments: usize,
    /// Mean translational drift, percent of the length.
    pub translation_percent: f64,
    /// Mean rotational drift, degrees per 100 m.
    pub rotation_deg_per_100m: f64,
}

/// The drift per segment length, for lengths with at least one segment (in the order of
/// `options.lengths`), and as the last entry the mean over all segments with `length`
/// set to 0. Errors if no segment fits in the reference path.
pub fn drift(
    reference: &[Isometry3<f64>],
    estimate: &[Isometry3<f64>],
    options: &DriftOptions,
) -> Result<Vec<SegmentDrift>, EvalError> {
    assert_eq!(reference.len(), estimate.len(), "drift needs pose pairs");
    if options.step == 0 || options.lengths.iter().any(|&l| l.is_nan() || l <= 0.0) {
        return Err(EvalError::InvalidOption(format!(
            "drift needs a step of at least 1 pose and positive lengths, got step {} and lengths {:?}",
            options.step, options.lengths
        )));
    }
    let mut distances = Vec::with_capacity(reference.len());
    let mut total = 0.0;
    for (i, pose) in reference.iter().enumerate() {
        if i > 0 {
            total += (pose.translation.vector - reference[i - 1].translation.vector).norm();
        }
        distances.push(total);
    }
    let mut per_length = Vec::new();
    let (mut all_t, mut all_r, mut all_n) = (0.0, 0.0, 0);
    for &length in &options.lengths {
        let (mut sum_t, mut sum_r, mut n) = (0.0, 0.0, 0);
        for start in (0..reference.len()).step_by(options.step) {
            let target = distances[start] + length;
            let end = start + distances[start..].partition_point(|&d| d <= target);
            if end >= reference.len() {
                continue;
            }
            let delta_ref = reference[start].inverse() * reference[end];
            let delta_est = estimate[start].inverse() * estimate[end];
            let e = delta_est.inverse() * delta_ref;
            sum_t += e.translation.vector.norm() / length;
            sum_r += PoseRelation::AngleDeg.error(&e) / length;
            n += 1;
        }
        if n > 0 {
            per_length.push(SegmentDrift {
                length,
                segments: n,
                translation_percent: 100.0 * sum_t / n as f64,
                rotation_deg_per_100m: 100.0 * sum_r / n as f64,
            });
            all_t += sum_t;
            all_r += sum_r;
            all_n += n;
        }
    }
    if all_n == 0 {
        return Err(EvalError::NoSegments {
            path_length: total,
            shortest: options
                .lengths
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min),
        });
    }
    per_length.push(SegmentDrift {
        length: 0.0,
        segments: all_n,
        translation_percent: 100.0 * all_t / all_n as f64,
        rotation_deg_per_100m: 100.0 * all_r / all_n as f64,
    });
    Ok(per_length)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn two_percent_scale_drift_on_a_straight_line() {
        // Reference: 0.5 m steps along x for 30 m; estimate: 1.02× as far. A segment
        // starts at s and ends at the first pose more than L further, i.e. L + 0.5 m:
        // error 0.02 (L + 0.5), drift 2 % (L + 0.5) / L. No rotation.
        let reference: Vec<_> = (0..=60)
            .map(|i| Isometry3::translation(0.5 * i as f64, 0.0, 0.0))
            .collect();
        let estimate: Vec<_> = (0..=60)
            .map(|i| Isometry3::translation(0.51 * i as f64, 0.0, 0.0))
            .collect();
        let options = DriftOptions {
            lengths: vec![5.0, 10.0],
            step: 10,
        };
        let d = drift(&reference, &estimate, &options).unwrap();
        assert_eq!(d.len(), 3, "expected two lengths and the overall mean");
        // Starts 0, 10, …, 60 (poses): a 5 m segment needs an end ≤ pose 60: starts 0..=40 (5).
        assert_eq!(d[0].segments, 5, "expected 5 segments of 5 m");
        assert!(
            (d[0].translation_percent - 2.0 * 5.5 / 5.0).abs() < 1e-9,
            "expected 2.2 %, got {}",
            d[0].translation_percent
        );
        assert!(
            (d[1].translation_percent - 2.0 * 10.5 / 10.0).abs() < 1e-9,
            "expected 2.1 %, got {}",
            d[1].translation_percent
        );
        assert!(
            d[0].rotation_deg_per_100m.abs() < 1e-9,
            "expected no rotational drift"
        );
    }

    #[test]
    fn yaw_drift_in_degrees_per_100m() {
        // 1 m steps along x; the estimate turns 0.1° per metre about its own z at the
        // same positions in its frame: relative rotation over L metres is 0.1·L°... as
        // the end is L + 1 m away, the error is 0.1 (L + 1)° over L m.
        let reference: Vec<_> = (0..=30)
            .map(|i| Isometry3::translation(i as f64, 0.0, 0.0))
            .collect();
        let estimate: Vec<_> = (0..=30)
            .map(|i| {
                Isometry3::new(
                    Vector3::new(i as f64, 0.0, 0.0),
                    Vector3::new(0.0, 0.0, (0.1 * i as f64).to_radians()),
                )
            })
            .collect();
        let d = drift(
            &reference,
            &estimate,
            &DriftOptions {
                lengths: vec![10.0],
                step: 5,
            },
        )
        .unwrap();
        let expected = 100.0 * 0.1 * 11.0 / 10.0;
        assert!(
            (d[0].rotation_deg_per_100m - expected).abs() < 1e-9,
            "expected {expected} deg/100 m, got {}",
            d[0].rotation_deg_per_100m
        );
    }

    #[test]
    fn too_short_reference_is_an_error() {
        let poses = vec![Isometry3::identity(); 5];
        assert!(
            drift(&poses, &poses, &DriftOptions::default()).is_err(),
            "expected an error when no segment fits"
        );
    }
}
