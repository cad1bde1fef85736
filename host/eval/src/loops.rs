//! Loop closures judged against ground truth.
//!
//! A loop closure joins two base poses of the run, at two stamps. It is *true* when, in
//! ground truth, those two poses are within [`LoopCriteria::max_distance_m`] of each other
//! (3D distance between the base origins) and, if the criteria limit it, their headings
//! (yaw, the Z of Z-Y-X Euler angles, so roll and pitch from uneven ground do not count)
//! differ by at most [`LoopCriteria::max_heading_rad`].
//!
//! The default is 1.0 m at any heading: a loop closed by scan or lidar registration
//! between the two directions of one lane (S1: the robot comes back the way it came) joins
//! the same place and is true; identical rows 3 m or more apart are not. 1.0 m and 30°
//! ([`LoopCriteria::same_view`]) asks for the same view as well, which would judge every
//! such reversed loop false. Either way the distance and the heading difference are
//! reported with the verdict.
//!
//! A loop that carries its measured relative pose (`matched_from_current`, as scan
//! matching estimated it) is judged by that measurement instead: true when it agrees with
//! the ground-truth relative pose of the two base poses within
//! [`LoopCriteria::max_relative_error_m`] and [`LoopCriteria::max_relative_error_rad`]
//! (0.5 m and 10° by default: below the 1 m spacing of identical plants along a row and the
//! 3 m between rows, the offsets an aliased match makes). A registration across a lane,
//! 3 m apart and correct, is then true; one that snapped to the wrong plant is false.
//!
//! A loop reported without the poses it joins (a system that only says that its map
//! changed, as ORB-SLAM3's bindings do) is judged by what its correction did to the online
//! estimate ([`judge_correction`]): the position error against ground truth of the last
//! online pose before the event and of the first one after it, both moved into the ground
//! truth's frame by the run's APE alignment. The loop is false when the error grew by more
//! than [`LoopCriteria::max_error_increase_m`] (0.5 m, as for a measured relative pose): a
//! correction towards an aliased place pulls the estimate away from the truth.
//!
//! Ground truth is resampled at each stamp as the association does (linear position,
//! slerp orientation between the bracketing poses); a stamp more than one mean sampling
//! period outside the ground truth's time span cannot be judged.

use serde::{Deserialize, Serialize};

use crate::associate::interpolate;
use crate::trajectory::Trajectory;

/// When a loop closure counts as true.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopCriteria {
    /// Largest distance between the two base poses, metres (inclusive).
    pub max_distance_m: f64,
    /// Largest heading (yaw) difference, radians (inclusive); `None`: any heading.
    pub max_heading_rad: Option<f64>,
    /// A loop with a measured relative pose: its largest translation error against ground
    /// truth, metres (inclusive),
    pub max_relative_error_m: f64,
    /// and its largest rotation error, radians (inclusive).
    pub max_relative_error_rad: f64,
    /// A loop known only by the correction it made: the largest growth of the online
    /// estimate's position error across it, metres (inclusive).
    pub max_error_increase_m: f64,
}

impl Default for LoopCriteria {
    /// 1.0 m, any heading: the same place.
    fn default() -> Self {
        Self {
            max_distance_m: 1.0,
            max_heading_rad: None,
            max_relative_error_m: 0.5,
            max_relative_error_rad: 10f64.to_radians(),
            max_error_increase_m: 0.5,
        }
    }
}

/// A loop judged by the correction it made to the online estimate ([`judge_correction`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectionJudgement {
    /// Position error of the last online pose before the event, metres,
    pub error_before_m: f64,
    /// and of the first one after it.
    pub error_after_m: f64,
    /// The error grew by at most [`LoopCriteria::max_error_increase_m`].
    pub true_loop: bool,
}

/// Judges a loop reported at `stamp_s` without the poses it joins by the online poses just
/// before and just after it (strictly), moved by `map_from_estimate` (the run's APE
/// alignment) into the ground truth's frame. `None` without an online pose on either side
/// within the ground truth's time span.
pub fn judge_correction(
    groundtruth: &Trajectory,
    online: &Trajectory,
    map_from_estimate: &crate::Sim3,
    stamp_s: f64,
    criteria: &LoopCriteria,
) -> Option<CorrectionJudgement> {
    let n = groundtruth.len();
    if n < 2 || !stamp_s.is_finite() {
        return None;
    }
    let (first, last) = (groundtruth.stamps[0], groundtruth.stamps[n - 1]);
    let after = online.stamps.partition_point(|&t| t <= stamp_s);
    let before = online
        .stamps
        .partition_point(|&t| t < stamp_s)
        .checked_sub(1)?;
    if after >= online.len() {
        return None;
    }
    let error = |i: usize| {
        let t = online.stamps[i];
        (first..=last).contains(&t).then(|| {
            let estimate = map_from_estimate.apply(&online.poses[i]);
            (estimate.translation.vector - interpolate(groundtruth, t).translation.vector).norm()
        })
    };
    let (error_before_m, error_after_m) = (error(before)?, error(after)?);
    Some(CorrectionJudgement {
        error_before_m,
        error_after_m,
        true_loop: error_after_m - error_before_m <= criteria.max_error_increase_m,
    })
}

impl LoopCriteria {
    /// 1.0 m and 30° of heading: the same place seen the same way.
    pub fn same_view() -> Self {
        Self {
            max_heading_rad: Some(30f64.to_radians()),
            ..Self::default()
        }
    }
}

/// Where the two poses a loop joins are in ground truth, and the verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopJudgement {
    /// Distance between the two base poses, metres.
    pub distance_m: f64,
    /// Absolute heading difference, radians, in [0, π].
    pub heading_rad: f64,
    /// The measured relative pose's error against ground truth (translation m, rotation
    /// rad), when the loop carried one.
    pub relative_error: Option<(f64, f64)>,
    /// Within the criteria: the relative pose's error if measured, else the distance and, if
    /// limited, heading.
    pub true_loop: bool,
}

/// Judges the loop closure joining the base poses at `stamps_s` (seconds, in either
/// order: `[current, matched]` when `measured` is given, `matched_from_current`) against
/// `groundtruth`. `None` if the ground truth has fewer than two poses or a
/// stamp lies more than one mean sampling period outside its time span.
pub fn judge_loop(
    groundtruth: &Trajectory,
    stamps_s: [f64; 2],
    measured: Option<&nalgebra::Isometry3<f64>>,
    criteria: &LoopCriteria,
) -> Option<LoopJudgement> {
    let n = groundtruth.len();
    if n < 2 {
        return None;
    }
    let (first, last) = (groundtruth.stamps[0], groundtruth.stamps[n - 1]);
    let period = (last - first) / (n - 1) as f64;
    if stamps_s
        .iter()
        .any(|&t| !t.is_finite() || t < first - period || t > last + period)
    {
        return None;
    }
    let [a, b] = stamps_s.map(|t| interpolate(groundtruth, t));
    let distance_m = (a.translation.vector - b.translation.vector).norm();
    let heading = |p: &nalgebra::Isometry3<f64>| p.rotation.euler_angles().2;
    let heading_rad = wrap_angle(heading(&a) - heading(&b)).abs();
    let relative_error = measured.map(|m| {
        let error = (b.inverse() * a).inverse() * m;
        (error.translation.vector.norm(), error.rotation.angle())
    });
    let true_loop = match relative_error {
        Some((m, rad)) => {
            m <= criteria.max_relative_error_m && rad <= criteria.max_relative_error_rad
        }
        None => {
            distance_m <= criteria.max_distance_m
                && criteria
                    .max_heading_rad
                    .is_none_or(|max| heading_rad <= max)
        }
    };
    Some(LoopJudgement {
        distance_m,
        heading_rad,
        relative_error,
        true_loop,
    })
}

/// `angle` in [-π, π).
fn wrap_angle(angle: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    (angle + PI).rem_euclid(TAU) - PI
}

/// A run's loop closures: `metrics.json`'s `"loops"`.
///
/// Every accepted loop counts in `accepted`; of those, the ones judged false also in
/// `accepted_false`, and the ones that could not be judged (no stamps, as from a plugin
/// built before loop events carried them, or stamps outside the ground truth) in
/// `unjudged` instead, which is written only when not zero. Rejected loops are counted,
/// not judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct LoopCounts {
    pub accepted: usize,
    pub accepted_false: usize,
    pub rejected: usize,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub unjudged: usize,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl LoopCounts {
    /// Counts one accepted loop with its judgement (`None`: not judged).
    pub fn add_accepted(&mut self, judgement: Option<&LoopJudgement>) {
        self.add_accepted_verdict(judgement.map(|j| j.true_loop));
    }

    /// Counts one accepted loop with its verdict (`None`: not judged).
    pub fn add_accepted_verdict(&mut self, true_loop: Option<bool>) {
        self.accepted += 1;
        match true_loop {
            Some(false) => self.accepted_false += 1,
            Some(true) => {}
            None => self.unjudged += 1,
        }
    }

    /// Counts one rejected loop.
    pub fn add_rejected(&mut self) {
        self.rejected += 1;
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::*;

    /// 0.01 s apart (100 Hz): x = t, y = 0, yaw = t / 10 rad, with a little roll.
    fn groundtruth() -> Trajectory {
        let stamps: Vec<f64> = (0..=1000).map(|i| f64::from(i) * 0.01).collect();
        let poses = stamps
            .iter()
            .map(|&t| {
                Isometry3::from_parts(
                    Translation3::new(t, 0.0, 0.1 * t),
                    UnitQuaternion::from_euler_angles(0.05, 0.0, 0.1 * t),
                )
            })
            .collect();
        Trajectory::new(stamps, poses)
    }

    /// A correction judged by the online error on either side: the estimate was 0.2 m off
    /// before; pulled 0.3 m further off it is still true (growth 0.3 m), pulled 1 m off it is
    /// false; without an online pose after the event it cannot be judged.
    #[test]
    fn a_correction_is_judged_by_how_much_it_moved_the_estimate_off_the_truth() {
        let gt = groundtruth();
        let online = |after_offset: f64| {
            let stamps = vec![4.0, 4.5, 5.0];
            let poses = stamps
                .iter()
                .map(|&t| {
                    // The pose at the event's own stamp is neither side's: far off, so
                    // that taking it for either would change the verdict.
                    let off = match t {
                        4.0 => 0.2,
                        4.5 => 5.0,
                        _ => after_offset,
                    };
                    Isometry3::translation(t, off, 0.1 * t)
                })
                .collect();
            Trajectory::new(stamps, poses)
        };
        let identity = crate::Sim3::identity();
        let small = judge_correction(&gt, &online(0.5), &identity, 4.5, &LoopCriteria::default())
            .expect("judged");
        assert!((small.error_before_m - 0.2).abs() < 1e-9, "{small:?}");
        assert!((small.error_after_m - 0.5).abs() < 1e-9, "{small:?}");
        assert!(small.true_loop);
        let big = judge_correction(&gt, &online(1.2), &identity, 4.5, &LoopCriteria::default())
            .expect("judged");
        assert!(!big.true_loop, "{big:?}");
        // Moved into ground truth's frame first: an alignment that shifts y by -1 m makes
        // the 1.2 m pose 0.2 m off and the 0.2 m one 0.8 m off, an improvement.
        let shift = crate::Sim3 {
            translation: Vector3::new(0.0, -1.0, 0.0),
            ..crate::Sim3::identity()
        };
        let aligned = judge_correction(&gt, &online(1.2), &shift, 4.5, &LoopCriteria::default())
            .expect("judged");
        assert!(aligned.true_loop && aligned.error_after_m < aligned.error_before_m);
        assert_eq!(
            judge_correction(&gt, &online(1.2), &identity, 5.0, &LoopCriteria::default()),
            None
        );
    }

    #[test]
    fn distance_and_heading_are_interpolated_between_samples() {
        let j = judge_loop(
            &groundtruth(),
            [2.005, 2.505],
            None,
            &LoopCriteria::same_view(),
        )
        .expect("inside the span");
        // 0.5 m along x and 0.05 m up; 0.05 rad of yaw.
        assert!((j.distance_m - 0.5f64.hypot(0.05)).abs() < 1e-9, "{j:?}");
        assert!((j.heading_rad - 0.05).abs() < 1e-9, "{j:?}");
        assert!(j.true_loop);
    }

    #[test]
    fn limits_are_inclusive_and_either_one_makes_a_loop_false() {
        let gt = groundtruth();
        let loose = LoopCriteria {
            max_distance_m: 1.0,
            max_heading_rad: Some(1.0),
            ..LoopCriteria::default()
        };
        // 0.9 m along x, 0.09 m up: 0.9045 m.
        let near = judge_loop(&gt, [1.0, 1.9], None, &loose).expect("judged");
        assert!(near.true_loop, "{near:?}");
        let far = judge_loop(&gt, [1.0, 2.1], None, &loose).expect("judged");
        assert!(!far.true_loop && far.distance_m > 1.0, "{far:?}");
        let exactly = LoopCriteria {
            max_distance_m: near.distance_m,
            max_heading_rad: Some(near.heading_rad),
            ..LoopCriteria::default()
        };
        assert!(
            judge_loop(&gt, [1.0, 1.9], None, &exactly)
                .expect("judged")
                .true_loop
        );
        let strict_heading = LoopCriteria {
            max_distance_m: 1.0,
            max_heading_rad: Some(0.08),
            ..LoopCriteria::default()
        };
        let turned = judge_loop(&gt, [1.0, 1.9], None, &strict_heading).expect("judged");
        assert!(
            !turned.true_loop && (turned.heading_rad - 0.09).abs() < 1e-9,
            "{turned:?}"
        );
        let any_heading = LoopCriteria {
            max_heading_rad: None,
            ..strict_heading
        };
        assert!(
            judge_loop(&gt, [1.0, 1.9], None, &any_heading)
                .expect("judged")
                .true_loop
        );
    }

    #[test]
    fn heading_wraps_around_pi() {
        let at = |yaw: f64| Isometry3::new(Vector3::zeros(), Vector3::z() * yaw);
        let gt = Trajectory::new(vec![0.0, 1.0], vec![at(3.0), at(-3.0)]);
        let j = judge_loop(&gt, [0.0, 1.0], None, &LoopCriteria::same_view()).expect("judged");
        assert!(
            (j.heading_rad - (std::f64::consts::TAU - 6.0)).abs() < 1e-9,
            "{j:?}"
        );
        assert!(j.true_loop);
    }

    #[test]
    fn stamps_outside_the_ground_truth_are_not_judged() {
        let gt = groundtruth();
        let c = LoopCriteria::default();
        // Within one period (0.01 s) of the ends: the end pose.
        assert!(judge_loop(&gt, [-0.005, 10.005], None, &c).is_some());
        assert_eq!(judge_loop(&gt, [-0.5, 1.0], None, &c), None);
        assert_eq!(judge_loop(&gt, [1.0, 10.5], None, &c), None);
        assert_eq!(judge_loop(&gt, [1.0, f64::NAN], None, &c), None);
        assert_eq!(
            judge_loop(&Trajectory::default(), [0.0, 0.0], None, &c),
            None
        );
    }

    #[test]
    fn counts_split_accepted_loops_into_false_and_unjudged() {
        let verdict = |true_loop| LoopJudgement {
            distance_m: 0.0,
            heading_rad: 0.0,
            relative_error: None,
            true_loop,
        };
        let mut counts = LoopCounts::default();
        counts.add_accepted(Some(&verdict(true)));
        counts.add_accepted(Some(&verdict(false)));
        counts.add_accepted(None);
        counts.add_rejected();
        assert_eq!(
            counts,
            LoopCounts {
                accepted: 3,
                accepted_false: 1,
                rejected: 1,
                unjudged: 1
            }
        );
        assert_eq!(
            serde_json::to_value(LoopCounts {
                unjudged: 0,
                ..counts
            })
            .expect("json"),
            serde_json::json!({"accepted": 3, "accepted_false": 1, "rejected": 1})
        );
    }

    /// A loop with a measured relative pose is judged by it: 3 m apart (across a lane) and
    /// measured right is true; 0.2 m apart but measured a plant spacing (1 m) off is false.
    #[test]
    fn a_measured_relative_pose_is_judged_against_ground_truth() {
        let gt = groundtruth();
        let truth = |a: f64, b: f64| {
            let at = |t: f64| interpolate(&gt, t);
            at(b).inverse() * at(a)
        };
        let criteria = LoopCriteria::default();
        let right = truth(4.0, 1.0) * Isometry3::translation(0.05, -0.03, 0.0);
        let j = judge_loop(&gt, [4.0, 1.0], Some(&right), &criteria).expect("judged");
        assert!(j.distance_m > 2.9, "{j:?}");
        assert!(j.true_loop, "3 m apart, measured within 6 cm: {j:?}");
        let (m, _) = j.relative_error.expect("measured");
        assert!((m - 0.05f64.hypot(0.03)).abs() < 1e-9, "{j:?}");
        let aliased = truth(1.2, 1.0) * Isometry3::translation(1.0, 0.0, 0.0);
        let j = judge_loop(&gt, [1.2, 1.0], Some(&aliased), &criteria).expect("judged");
        assert!(!j.true_loop && j.distance_m < 0.25, "{j:?}");
        let turned = truth(1.2, 1.0) * Isometry3::rotation(Vector3::z() * 0.2);
        let j = judge_loop(&gt, [1.2, 1.0], Some(&turned), &criteria).expect("judged");
        assert!(!j.true_loop, "11.5° off: {j:?}");
    }
}
