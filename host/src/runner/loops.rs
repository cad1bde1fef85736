//! A run's loop closures judged against ground truth (`eval::judge_loop`). The host uses
//! `LoopCriteria::default()`: true when the two base poses a loop joins are within 1.0 m
//! in ground truth, at any heading — a loop closed by scan registration between the two
//! directions of one lane joins the same place (DESIGN.md's 30° of heading as well,
//! `LoopCriteria::same_view()`, would judge all 33 that rtabmap accepts in S1 false,
//! every one within 0.3 m and 180° apart). The heading difference is reported with every
//! verdict.
//!
//! A loop whose event carries its measured relative pose (`Event::loop_relative_pose`) is
//! judged by that measurement's error against ground truth instead (0.5 m and 10°); the
//! error is reported with the verdict.
//!
//! Every accepted loop is judged from the two stamps its event carries
//! (`Event::loop_stamps_ns`). An accepted loop without stamps (a system that only says its
//! map changed, as ORB-SLAM3's bindings do, or a plugin built before events carried them)
//! is judged by the final map (`eval::wrong_joins`, `JoinReport::map_change`): false when a
//! wrong join's later stretch ends within `eval::EXPLAIN_WINDOW_S` (10 s) before it, true
//! when a kept true revisit does and no wrong join; when the final map shows neither there,
//! by the correction it made to the online estimate (`eval::judge_correction`: false when
//! the position error grew by more than 0.5 m across the event), when the run has online
//! poses on both sides of it. That correction is reported beside the final map's verdict
//! either way (a merge that moves only the final map leaves the online error as it was:
//! ORB-SLAM3 on S3 of the paper's world, 8.0 m before and after). Otherwise, and for stamps
//! outside the ground truth, the loop is counted in `accepted` and in `unjudged`, never in
//! `accepted_false`. Rejected loops are counted, not judged.
//!
//! Wrong joins of the final map that no accepted loop explains (no stamped loop joins their
//! two stretches, no stampless one comes shortly after) are *silent*: a system that reports
//! nothing, or not this, still joined two places that the truth keeps apart.

use eval::{JoinReport, LoopCounts, LoopCriteria, LoopJudgement, Trajectory};
use plugin_api::{Event, EventKind};

use crate::results::{JudgedBy, JudgedEvent};

/// The online estimate and the alignment that moves it into ground truth's frame, for
/// loops judged by their correction.
#[derive(Debug, Clone, Copy)]
pub struct Online<'a> {
    pub trajectory: &'a Trajectory,
    pub map_from_estimate: &'a eval::Sim3,
}

/// Judges every accepted loop of `events` against `groundtruth` by `criteria` (a loop
/// without stamps by the final map's `joins`, if given, and by its correction of `online`,
/// if given); returns the counts and the events with their judgements, in the plugin's
/// order.
pub fn judge(
    events: Vec<Event>,
    groundtruth: &Trajectory,
    criteria: &LoopCriteria,
    online: Option<Online<'_>>,
    joins: Option<&JoinReport>,
) -> (LoopCounts, Vec<JudgedEvent>) {
    let mut counts = LoopCounts::default();
    let judged = events
        .into_iter()
        .map(|event| {
            let mut correction = None;
            let mut map_change = None;
            let judgement: Option<LoopJudgement> = match event.kind {
                EventKind::LoopClosureAccepted => {
                    let judgement = event.loop_stamps_ns.and_then(|stamps| {
                        eval::judge_loop(
                            groundtruth,
                            stamps.map(|ns| ns as f64 * 1e-9),
                            event.relative_pose().as_ref(),
                            criteria,
                        )
                    });
                    if event.loop_stamps_ns.is_none() {
                        let stamp_s = event.stamp_ns as f64 * 1e-9;
                        map_change = joins.map(|j| j.map_change(stamp_s));
                        correction = online.and_then(|o| {
                            eval::judge_correction(
                                groundtruth,
                                o.trajectory,
                                o.map_from_estimate,
                                stamp_s,
                                criteria,
                            )
                        });
                    }
                    judgement
                }
                EventKind::LoopClosureRejected => {
                    counts.add_rejected();
                    None
                }
                // Tracking events, and kinds appended to the registry later, are not judged.
                _ => None,
            };
            let by_map = map_change.and_then(|m| m.true_loop());
            let (true_loop, judged_by) = if let Some(j) = judgement {
                let by = if j.relative_error.is_some() {
                    JudgedBy::RelativePose
                } else {
                    JudgedBy::Stamps
                };
                (Some(j.true_loop), Some(by))
            } else if let Some(verdict) = by_map {
                (Some(verdict), Some(JudgedBy::FinalMap))
            } else if let Some(c) = correction {
                (Some(c.true_loop), Some(JudgedBy::OnlineError))
            } else {
                (None, None)
            };
            if event.kind == EventKind::LoopClosureAccepted {
                counts.add_accepted_verdict(true_loop);
            }
            JudgedEvent {
                event,
                true_loop,
                judged_by,
                wrong_join: map_change.and_then(|m| m.wrong_join),
                revisit: map_change.and_then(|m| m.revisit),
                error_before_m: correction.map(|c| c.error_before_m),
                error_after_m: correction.map(|c| c.error_after_m),
                gt_distance_m: judgement.map(|j| j.distance_m),
                gt_heading_deg: judgement.map(|j| j.heading_rad.to_degrees()),
                relative_error_m: judgement.and_then(|j| j.relative_error).map(|e| e.0),
                relative_error_deg: judgement
                    .and_then(|j| j.relative_error)
                    .map(|e| e.1.to_degrees()),
            }
        })
        .collect();
    (counts, judged)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Vector3};

    use super::*;

    const S: i64 = 1_000_000_000;

    /// A lane driven east along y = 0 (x = t m for t in 0…10 s), back west along
    /// y = 0.5 (10…20 s, x = 20 - t), then east again along y = 0.3 (20…30 s,
    /// x = t - 20). 100 Hz.
    fn groundtruth() -> Trajectory {
        let stamps: Vec<f64> = (0..=3000).map(|i| f64::from(i) * 0.01).collect();
        let poses = stamps
            .iter()
            .map(|&t| {
                let (x, y, yaw) = if t <= 10.0 {
                    (t, 0.0, 0.0)
                } else if t <= 20.0 {
                    (20.0 - t, 0.5, std::f64::consts::PI)
                } else {
                    (t - 20.0, 0.3, 0.0)
                };
                Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw)
            })
            .collect();
        Trajectory::new(stamps, poses)
    }

    fn accepted(current: i64, matched: i64) -> Event {
        Event::loop_closure(
            current,
            EventKind::LoopClosureAccepted,
            [current, matched],
            "test",
        )
    }

    #[test]
    fn accepted_loops_are_judged_by_distance_and_heading() {
        let events = vec![
            // Same place, same heading, 0.3 m across the lane: true.
            accepted(25 * S, 5 * S),
            // Same heading, 2 m along the lane: false by distance.
            accepted(25 * S, 3 * S),
            // 0.5 m apart but facing the other way: false by heading (same view asked).
            accepted(15 * S, 5 * S),
            // A rejected loop: counted, not judged, even if it is false.
            Event::loop_closure(26 * S, EventKind::LoopClosureRejected, [26 * S, S], "x"),
            // An accepted loop from a plugin that sends no stamps: counted, not judged.
            Event::new(27 * S, EventKind::LoopClosureAccepted, "old plugin"),
            Event::new(28 * S, EventKind::TrackingLost, "dark"),
        ];
        let (counts, judged) = judge(
            events.clone(),
            &groundtruth(),
            &LoopCriteria::same_view(),
            None,
            None,
        );
        assert_eq!(
            counts,
            LoopCounts {
                accepted: 4,
                accepted_false: 2,
                rejected: 1,
                unjudged: 1
            }
        );
        let verdicts: Vec<Option<bool>> = judged.iter().map(|j| j.true_loop).collect();
        assert_eq!(
            verdicts,
            [Some(true), Some(false), Some(false), None, None, None]
        );
        let distances: Vec<f64> = judged[..3]
            .iter()
            .map(|j| j.gt_distance_m.expect("judged"))
            .collect();
        for (d, want) in distances.iter().zip([0.3, 2f64.hypot(0.3), 0.5]) {
            assert!((d - want).abs() < 1e-9, "{distances:?}");
        }
        let headings: Vec<f64> = judged[..3]
            .iter()
            .map(|j| j.gt_heading_deg.expect("judged"))
            .collect();
        for (h, want) in headings.iter().zip([0.0, 0.0, 180.0]) {
            assert!((h - want).abs() < 1e-9, "{headings:?}");
        }
        assert_eq!(
            judged.iter().map(|j| j.event.clone()).collect::<Vec<_>>(),
            events
        );
        // The host's default: the same place at any heading, so the reversed loop is true.
        let (counts, judged) = judge(events, &groundtruth(), &LoopCriteria::default(), None, None);
        assert_eq!(
            counts,
            LoopCounts {
                accepted: 4,
                accepted_false: 1,
                rejected: 1,
                unjudged: 1
            }
        );
        assert_eq!(judged[2].true_loop, Some(true));
        assert!((judged[2].gt_heading_deg.expect("judged") - 180.0).abs() < 1e-9);
    }

    /// A loop sent with its measured relative pose is judged by it, whatever the distance:
    /// 2 m along the lane measured right is true, the same place measured 1 m off is false;
    /// events.json carries the error.
    #[test]
    fn a_measured_relative_pose_decides_the_verdict() {
        let gt = groundtruth();
        // At 25 s: x = 5, y = 0.3; at 3 s: x = 3, y = 0; both facing east.
        let truth = Isometry3::translation(2.0, 0.3, 0.0);
        let events = vec![
            accepted(25 * S, 3 * S).with_relative_pose(&truth),
            accepted(25 * S, 5 * S).with_relative_pose(&Isometry3::translation(1.0, 0.3, 0.0)),
        ];
        let (counts, judged) = judge(events, &gt, &LoopCriteria::default(), None, None);
        assert_eq!(
            (counts.accepted, counts.accepted_false),
            (2, 1),
            "{counts:?}"
        );
        assert_eq!(judged[0].true_loop, Some(true));
        assert!(judged[0].relative_error_m.expect("measured") < 1e-9);
        assert_eq!(judged[1].true_loop, Some(false));
        assert!((judged[1].relative_error_m.expect("measured") - 1.0).abs() < 1e-9);
        let json = serde_json::to_value(&judged).expect("json");
        assert!(json[1]["relative_error_m"].as_f64().is_some(), "{json}");
        assert_eq!(json[1]["loop_relative_pose"][0], 1.0, "{json}");
    }

    #[test]
    fn events_json_carries_the_stamps_and_the_verdict() {
        let events = vec![
            accepted(25 * S, 5 * S),
            Event::new(27 * S, EventKind::LoopClosureAccepted, "old plugin"),
        ];
        let (_, judged) = judge(events, &groundtruth(), &LoopCriteria::default(), None, None);
        let json = serde_json::to_value(&judged).expect("json");
        assert_eq!(json[0]["stamp_ns"], 25 * S);
        assert_eq!(json[0]["kind"], "loop_closure_accepted");
        assert_eq!(
            json[0]["loop_stamps_ns"],
            serde_json::json!([25 * S, 5 * S])
        );
        assert_eq!(json[0]["true_loop"], true);
        assert!((json[0]["gt_distance_m"].as_f64().expect("distance") - 0.3).abs() < 1e-9);
        assert_eq!(
            json[1],
            serde_json::json!({
                "stamp_ns": 27 * S,
                "kind": "loop_closure_accepted",
                "detail": "old plugin"
            })
        );
    }
}
