//! Association of estimated poses with reference poses by time stamp, as evo does it
//! (Sturm et al. 2012, §IV; evo's `sync` documentation):
//!
//! - the trajectory with fewer poses is matched against the other one (ties: the
//!   estimate is the shorter), so none of the sparser poses are lost;
//! - each stamp of the shorter trajectory is paired with the closest stamp of the longer
//!   one (shifted by the time offset) if they are at most `max_diff` apart; at equal
//!   distance the earlier stamp wins; a pose of the longer trajectory may be used twice;
//! - optionally, instead of snapping to the closest pose, the longer trajectory is
//!   resampled at the matched stamps: linear interpolation of the position and slerp of
//!   the orientation between the bracketing poses (evo's `--sync_method interpolation`).

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

use crate::{EvalError, Trajectory};

/// Options of the association by time stamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Association {
    /// Largest accepted difference of matched stamps, in seconds (evo's `--t_max_diff`).
    pub max_diff: f64,
    /// Added to the estimate's stamps before matching, in seconds (evo's `--t_offset`).
    pub offset: f64,
    /// Resample the denser trajectory at the matched stamps instead of snapping to its
    /// closest pose (evo's `--sync_method interpolation`).
    pub interpolate: bool,
}

impl Default for Association {
    fn default() -> Self {
        Self {
            max_diff: 0.01,
            offset: 0.0,
            interpolate: false,
        }
    }
}

/// How reference and estimate poses are paired.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pairing {
    /// By time stamp (see [`associate`]).
    ByStamp(Association),
    /// By index, for trajectories without stamps (see [`associate_by_index`]).
    ByIndex,
}

impl Default for Pairing {
    fn default() -> Self {
        Self::ByStamp(Association::default())
    }
}

impl Pairing {
    /// Pairs the poses of `reference` and `estimate`.
    pub fn pair(
        &self,
        reference: &Trajectory,
        estimate: &Trajectory,
    ) -> Result<PosePairs, EvalError> {
        match self {
            Self::ByStamp(options) => associate(reference, estimate, options),
            Self::ByIndex => associate_by_index(reference, estimate),
        }
    }
}

/// Associated poses: `reference[i]` and `estimate[i]` belong to the same instant.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PosePairs {
    /// Stamps of the pairs in the reference's time frame, seconds.
    pub stamps: Vec<f64>,
    /// `world_from_body` of the reference.
    pub reference: Vec<Isometry3<f64>>,
    /// `world_from_body` of the estimate (in its own world frame until aligned).
    pub estimate: Vec<Isometry3<f64>>,
}

impl PosePairs {
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.reference.len()
    }

    /// Whether there is no pair.
    pub fn is_empty(&self) -> bool {
        self.reference.is_empty()
    }
}

/// Indices of the best matching stamps: for every stamp of `stamps_1`, the closest stamp
/// of `stamps_2 + offset_2` if it is at most `max_diff` away (ties: the earlier one).
/// Returns the matched indices into `stamps_1` and into `stamps_2`, in order of
/// `stamps_1`.
pub fn matching_time_indices(
    stamps_1: &[f64],
    stamps_2: &[f64],
    max_diff: f64,
    offset_2: f64,
) -> (Vec<usize>, Vec<usize>) {
    let shifted: Vec<f64> = stamps_2.iter().map(|t| t + offset_2).collect();
    let mut ids_1 = Vec::with_capacity(stamps_1.len().min(shifted.len()));
    let mut ids_2 = Vec::with_capacity(ids_1.capacity());
    let (Some(&first), Some(&last)) = (shifted.first(), shifted.last()) else {
        return (ids_1, ids_2);
    };
    if !shifted.windows(2).all(|w| w[1] >= w[0]) {
        // Unsorted stamps: the closest stamp by exhaustive search (first of equals).
        for (i, &t1) in stamps_1.iter().enumerate() {
            let (j, diff) = shifted.iter().map(|t2| (t2 - t1).abs()).enumerate().fold(
                (0, f64::INFINITY),
                |best, (j, d)| if d < best.1 { (j, d) } else { best },
            );
            if diff <= max_diff {
                ids_1.push(i);
                ids_2.push(j);
            }
        }
        return (ids_1, ids_2);
    }
    for (i, &t1) in stamps_1.iter().enumerate() {
        if t1 < first - max_diff || t1 > last + max_diff {
            continue;
        }
        // First stamp after t1, clamped to the last one.
        let upper = shifted
            .partition_point(|&t2| t2 <= t1)
            .min(shifted.len() - 1);
        let diff_upper = shifted[upper] - t1;
        let diff_lower = if upper > 0 {
            t1 - shifted[upper - 1]
        } else {
            f64::INFINITY
        };
        let best = if diff_upper <= max_diff && diff_upper < diff_lower {
            upper
        } else if diff_lower <= max_diff && diff_lower <= diff_upper {
            upper - 1
        } else {
            continue;
        };
        ids_1.push(i);
        ids_2.push(best);
    }
    (ids_1, ids_2)
}

/// Associates `estimate` with `reference` by time stamp (see the module documentation).
///
/// Errors if no stamps match, or if interpolation is asked for and the denser
/// trajectory has fewer than two poses.
pub fn associate(
    reference: &Trajectory,
    estimate: &Trajectory,
    options: &Association,
) -> Result<PosePairs, EvalError> {
    let estimate_longer = estimate.len() > reference.len();
    let (short, long) = if estimate_longer {
        (reference, estimate)
    } else {
        (estimate, reference)
    };
    let offset_long = if estimate_longer {
        options.offset
    } else {
        -options.offset
    };
    let (ids_short, ids_long) =
        matching_time_indices(&short.stamps, &long.stamps, options.max_diff, offset_long);
    if ids_short.is_empty() {
        return Err(EvalError::NoMatches {
            max_diff: options.max_diff,
            offset: options.offset,
        });
    }
    let short_poses: Vec<_> = ids_short.iter().map(|&i| short.poses[i]).collect();
    let (long_stamps, long_poses): (Vec<f64>, Vec<_>) = if options.interpolate {
        if long.len() < 2 {
            return Err(EvalError::TooFewPoses {
                what: "interpolation",
                needed: 2,
                got: long.len(),
            });
        }
        ids_short
            .iter()
            .map(|&i| {
                let t = short.stamps[i] - offset_long;
                (t, interpolate(long, t))
            })
            .unzip()
    } else {
        ids_long
            .iter()
            .map(|&j| (long.stamps[j], long.poses[j]))
            .unzip()
    };
    Ok(if estimate_longer {
        PosePairs {
            stamps: ids_short.iter().map(|&i| short.stamps[i]).collect(),
            reference: short_poses,
            estimate: long_poses,
        }
    } else {
        PosePairs {
            stamps: long_stamps,
            reference: long_poses,
            estimate: short_poses,
        }
    })
}

/// Pairs poses by index, for trajectories without time stamps (e.g. KITTI without a
/// times file). Errors if the lengths differ.
pub fn associate_by_index(
    reference: &Trajectory,
    estimate: &Trajectory,
) -> Result<PosePairs, EvalError> {
    if reference.len() != estimate.len() {
        return Err(EvalError::LengthMismatch {
            reference: reference.len(),
            estimate: estimate.len(),
        });
    }
    Ok(PosePairs {
        stamps: reference.stamps.clone(),
        reference: reference.poses.clone(),
        estimate: estimate.poses.clone(),
    })
}

/// The pose of `trajectory` (at least two poses) at time `t`: linear interpolation of the
/// position and slerp of the orientation between the bracketing poses, clamped to the
/// first and last pose outside the time span.
pub(crate) fn interpolate(trajectory: &Trajectory, t: f64) -> Isometry3<f64> {
    let n = trajectory.len();
    let next = trajectory
        .stamps
        .partition_point(|&s| s < t)
        .clamp(1, n - 1);
    let (t0, t1) = (trajectory.stamps[next - 1], trajectory.stamps[next]);
    let dt = t1 - t0;
    let fraction = if dt > 0.0 {
        ((t - t0) / dt).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (a, b) = (&trajectory.poses[next - 1], &trajectory.poses[next]);
    let p0 = a.translation.vector;
    let position = p0 + fraction * (b.translation.vector - p0);
    Isometry3::from_parts(
        Translation3::from(position),
        slerp(&a.rotation, &b.rotation, fraction),
    )
}

/// Spherical linear interpolation along the shorter arc (Shoemake 1985), returning the
/// first rotation when the two are (numerically) equal.
fn slerp(q0: &UnitQuaternion<f64>, q1: &UnitQuaternion<f64>, fraction: f64) -> UnitQuaternion<f64> {
    const EPS: f64 = 4.0 * f64::EPSILON;
    if fraction == 0.0 {
        return *q0;
    }
    if fraction == 1.0 {
        return *q1;
    }
    let (a, mut b) = (q0.coords, q1.coords);
    let mut d = a.dot(&b);
    if (d.abs() - 1.0).abs() < EPS {
        return *q0;
    }
    if d < 0.0 {
        d = -d;
        b = -b;
    }
    let angle = d.acos();
    if angle.abs() < EPS {
        return *q0;
    }
    let inv_sin = 1.0 / angle.sin();
    let coords =
        a * ((1.0 - fraction) * angle).sin() * inv_sin + b * (fraction * angle).sin() * inv_sin;
    UnitQuaternion::new_normalize(Quaternion::from(coords))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trajectory(stamps: &[f64]) -> Trajectory {
        let poses = stamps
            .iter()
            .map(|&t| Isometry3::translation(t, 0.0, 0.0))
            .collect();
        Trajectory::new(stamps.to_vec(), poses)
    }

    #[test]
    fn closest_stamp_within_max_diff_and_earlier_on_ties() {
        // 1.0 is closest to 1.005 (0.005 < 0.01 to 0.99); 2.5 matches 2.5 exactly; 3.0 has
        // nothing within 0.01.
        let (a, b) = matching_time_indices(
            &[1.0, 2.5, 3.0],
            &[0.99, 1.005, 2.5, 2.5125, 3.02],
            0.01,
            0.0,
        );
        assert_eq!(
            a,
            vec![0, 1],
            "expected stamps 1.0 and 2.5 matched, 3.0 unmatched"
        );
        assert_eq!(
            b,
            vec![1, 2],
            "expected 1.0→1.005 and 2.5→2.5 (exact match)"
        );
        // Exact tie (0.25 away on both sides, representable): the earlier stamp wins.
        let (_, b) = matching_time_indices(&[1.0], &[0.75, 1.25], 0.5, 0.0);
        assert_eq!(b, vec![0], "expected the earlier stamp on an exact tie");
    }

    #[test]
    fn offset_shifts_the_second_stamps() {
        let (a, b) = matching_time_indices(&[10.0, 11.0], &[0.0, 1.0], 0.01, 10.0);
        assert_eq!(
            (a, b),
            (vec![0, 1], vec![0, 1]),
            "expected 0+10→10 and 1+10→11"
        );
    }

    #[test]
    fn shorter_trajectory_is_matched_and_no_match_is_an_error() {
        let reference = trajectory(&[0.0, 0.1, 0.2, 0.3, 0.4]);
        let estimate = trajectory(&[0.101, 0.305]);
        let pairs = associate(&reference, &estimate, &Association::default()).unwrap();
        assert_eq!(
            pairs.stamps,
            vec![0.1, 0.3],
            "expected reference stamps 0.1 and 0.3"
        );
        assert_eq!(
            pairs.estimate[1].translation.x, 0.305,
            "expected the estimate at 0.305"
        );
        let far = trajectory(&[5.0]);
        let err = associate(&reference, &far, &Association::default()).unwrap_err();
        assert!(
            err.to_string().contains("no matching timestamps"),
            "expected a no-match error, got {err}"
        );
    }

    #[test]
    fn pairing_by_index_needs_equal_lengths() {
        let a = trajectory(&[0.0, 1.0]);
        let pairs = Pairing::ByIndex.pair(&a, &trajectory(&[5.0, 6.0])).unwrap();
        assert_eq!(
            pairs.stamps,
            vec![0.0, 1.0],
            "expected the reference stamps"
        );
        assert_eq!(
            pairs.estimate[1].translation.x, 6.0,
            "expected the second estimate second"
        );
        let err = associate_by_index(&a, &trajectory(&[0.0])).unwrap_err();
        assert!(
            err.to_string().contains("2 poses but estimate has 1"),
            "expected a length mismatch, got {err}"
        );
    }

    #[test]
    fn interpolation_resamples_the_denser_trajectory() {
        let mut reference = trajectory(&[0.0, 1.0, 2.0]);
        reference.poses[2].rotation = UnitQuaternion::from_euler_angles(0.0, 0.0, 1.0);
        let estimate = trajectory(&[1.5]);
        let options = Association {
            max_diff: 0.6,
            interpolate: true,
            ..Default::default()
        };
        let pairs = associate(&reference, &estimate, &options).unwrap();
        assert_eq!(pairs.stamps, vec![1.5], "expected the estimate's stamp");
        let r = &pairs.reference[0];
        assert!(
            (r.translation.x - 1.5).abs() < 1e-15,
            "expected x = 1.5, got {}",
            r.translation.x
        );
        assert!(
            (r.rotation.angle() - 0.5).abs() < 1e-12,
            "expected half of the 1 rad yaw, got {}",
            r.rotation.angle()
        );
    }

    #[test]
    fn slerp_takes_the_shorter_arc() {
        let a = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2);
        let b = UnitQuaternion::new_unchecked(
            -UnitQuaternion::from_euler_angles(0.0, 0.0, 0.6).into_inner(),
        );
        let mid = slerp(&a, &b, 0.5);
        assert!(
            (mid.euler_angles().2 - 0.4).abs() < 1e-12,
            "expected yaw 0.4, got {}",
            mid.euler_angles().2
        );
    }
}
