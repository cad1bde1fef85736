//! Localisation in a map built earlier, judged against ground truth and against the map.
//!
//! A localisation run starts a system from a map saved by an earlier (mapping) run; the
//! system answers every message with a pose in that map's frame and says whether it
//! believes itself localised or still searching. What a user of a farm robot needs to know
//! is whether, and how soon, it finds itself, how much of the route it stays localised, how
//! far off it is, and above all whether it is ever confidently wrong: a pose flagged
//! localised half a plant spacing off, or in the next lane, is what drives a robot into
//! the vines.
//!
//! The map frame is put into the world by the mapping run's own alignment to ground truth
//! (`world_from_map`, its `metrics.json`), carried over unchanged: the localisation run is
//! not aligned again, so an error of the map counts. Since a map built with an error (a
//! scale error, a drift) would make every pose look wrong against the truth even when the
//! system found the right place in its map, each pose flagged localised is also judged
//! against the map itself: where the mapping run's truth passes within `map_place_m` of this
//! pose's true place, the mapping run's estimate there, moved by the true offset between
//! the two places, is where the map says this place is.
//!
//! Metrics (issue 46):
//! - **success**: the first correct pose (flagged localised and not false, judged against
//!   the map where one is given, else against the truth) within `success_within_m` of true
//!   travel from the start;
//! - the time and true travel to the first pose flagged localised, and to the first correct
//!   one; the fraction of the run's time flagged localised;
//! - **ATE in the map frame without re-alignment**: translation error of the poses flagged
//!   localised, the estimate carried into the world by `world_from_map`;
//! - **false localisations**: episodes of consecutive poses flagged localised more than
//!   `false_position_m` or `false_angle_rad` from the truth (judged twice: against the
//!   truth, and against the map);
//! - **wrong-lane time**: time flagged localised with the estimate between another pair of
//!   rows than the truth;
//! - after a **kidnapping** (the robot carried elsewhere at a known time, the system not
//!   told): the time to the first correct pose after it.
//!
//! A pose holds from its stamp to the next one's (the last one holds for nothing), so
//! fractions and durations are in time, whatever rate the system answers at.
//!
//! The defaults and why:
//! - `success_within_m = 10.0`: the "localised within the first 10 m driven", about
//!   half a lane of the paper's world;
//! - `false_position_m = 0.5`: half a plant spacing (1 m in the paper's world, 0.9–1.2 m in
//!   ours): a pose further off puts the robot's wheels on another plant's place;
//! - `false_angle_rad = 10°`: at 1.5 m ahead (the Thorvald's half length) 10° is 0.26 m
//!   across, half of the 0.5 m above, in a 3 m lane whose free width is about 2 m;
//! - `map_place_m = 0.5`: the mapping run passes a place within this, so the true offset that
//!   moves its estimate to this place is short (a map with a 20 % scale error moves it at
//!   most 0.1 m wrongly).

use nalgebra::{Isometry3, Point2, Vector2};

use crate::associate::interpolate;
use crate::{EvalError, Sim3, Statistics, Trajectory};

/// The thresholds of [`evaluate_localization`]; the module documentation says why each
/// default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalizationCriteria {
    /// A run succeeds when its first correct pose comes within this much true travel.
    pub success_within_m: f64,
    /// A pose flagged localised further than this from where it should be is false, metres.
    pub false_position_m: f64,
    /// ... or turned more than this, radians.
    pub false_angle_rad: f64,
    /// The mapping run must have passed within this of a place to judge a pose there
    /// against the map, metres.
    pub map_place_m: f64,
}

impl Default for LocalizationCriteria {
    fn default() -> Self {
        Self {
            success_within_m: 10.0,
            false_position_m: 0.5,
            false_angle_rad: 10f64.to_radians(),
            map_place_m: 0.5,
        }
    }
}

/// A localisation run's answers: `map_from_base` poses in the map's frame, each with the
/// system's own status (`true`: localised, `false`: searching).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LocalizedTrajectory {
    pub trajectory: Trajectory,
    pub localized: Vec<bool>,
}

/// The mapping run, to judge poses against the map: its true poses (`world_from_base`) and
/// its final estimate (`map_from_base`) at the same instants, pose for pose (e.g. the
/// [`crate::PosePairs`] of its evaluation).
#[derive(Debug, Clone, Copy)]
pub struct MapReference<'a> {
    pub truth: &'a [Isometry3<f64>],
    pub estimate: &'a [Isometry3<f64>],
}

/// The block's lanes: parallel rows in the ground plane, a lane the strip between two
/// neighbouring rows, within the rows' length. Outside it (the headlands) a place has no
/// lane and wrong-lane time is not counted there.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanes {
    /// Unit vector along the rows, world x-y.
    pub along: [f64; 2],
    /// Each row's offset across, along `(along.y, -along.x)` (to the right of `along`),
    /// metres, increasing.
    pub rows: Vec<f64>,
    /// The rows' start and end along `along`, metres.
    pub extent: [f64; 2],
}

impl Lanes {
    /// The lane of a world x-y position (0 between the first two rows), or `None` outside
    /// the rows.
    pub fn lane_of(&self, xy: [f64; 2]) -> Option<usize> {
        let along = Vector2::from(self.along);
        let across = Vector2::new(along.y, -along.x);
        let p = Vector2::from(xy);
        let s = p.dot(&along);
        if !(self.extent[0] <= s && s <= self.extent[1]) {
            return None;
        }
        let c = p.dot(&across);
        let k = self.rows.partition_point(|&r| r <= c);
        (k >= 1 && k < self.rows.len()).then(|| k - 1)
    }
}

/// An episode of consecutive poses flagged localised that are false.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FalseLocalization {
    /// First and last pose of the episode, seconds.
    pub span_s: [f64; 2],
    /// How long the poses held, seconds.
    pub duration_s: f64,
    /// The largest position and angle errors in it, metres and degrees.
    pub max_position_error_m: f64,
    pub max_angle_error_deg: f64,
    /// The truth's place (x, y) at the worst pose.
    pub place: [f64; 2],
}

/// What [`evaluate_localization`] finds.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LocalizationReport {
    pub poses: usize,
    pub localized_poses: usize,
    /// The first correct pose came within `success_within_m` of travel.
    pub success: bool,
    /// Seconds from the first answer, and true travel in metres, to the first pose flagged
    /// localised and to the first correct one.
    pub first_localized_s: Option<f64>,
    pub first_localized_travel_m: Option<f64>,
    pub first_correct_s: Option<f64>,
    pub first_correct_travel_m: Option<f64>,
    /// The share of the run's time flagged localised.
    pub localized_fraction: f64,
    /// Translation error of the poses flagged localised, in the world by the mapping run's
    /// alignment, not aligned again; `None` when none is.
    pub ate_map_frame: Option<Statistics>,
    /// False localisations judged against the truth, and against the map (empty without a
    /// map reference), and their total durations.
    pub false_vs_truth: Vec<FalseLocalization>,
    pub false_vs_map: Vec<FalseLocalization>,
    pub false_vs_truth_s: f64,
    pub false_vs_map_s: f64,
    /// Poses flagged localised that could be judged against the map (the mapping run passed
    /// their true place).
    pub judged_vs_map: usize,
    /// Time flagged localised in another lane than the truth's, seconds (0 without lanes).
    pub wrong_lane_s: f64,
    /// After a kidnapping: seconds to the first correct pose (`None`: none came, or no
    /// kidnapping).
    pub relocalized_after_s: Option<f64>,
}

/// How far a pose is from where it should be: position (metres) and angle (radians).
fn pose_error(expected: &Isometry3<f64>, estimate: &Isometry3<f64>) -> (f64, f64) {
    let delta = expected.inverse() * estimate;
    (delta.translation.vector.norm(), delta.rotation.angle())
}

/// Nearest-neighbour lookup of the mapping run's true positions in the ground plane (a
/// uniform grid of `cell` metres; a query reads the 3 x 3 cells around it).
struct PlaceIndex {
    cell: f64,
    cells: std::collections::BTreeMap<(i64, i64), Vec<usize>>,
    points: Vec<Point2<f64>>,
}

impl PlaceIndex {
    fn new(truth: &[Isometry3<f64>], cell: f64) -> Self {
        let points: Vec<Point2<f64>> = truth
            .iter()
            .map(|p| Point2::new(p.translation.x, p.translation.y))
            .collect();
        let mut cells: std::collections::BTreeMap<(i64, i64), Vec<usize>> =
            std::collections::BTreeMap::new();
        for (i, p) in points.iter().enumerate() {
            cells.entry(Self::key(p, cell)).or_default().push(i);
        }
        Self {
            cell,
            cells,
            points,
        }
    }

    fn key(p: &Point2<f64>, cell: f64) -> (i64, i64) {
        ((p.x / cell).floor() as i64, (p.y / cell).floor() as i64)
    }

    /// The nearest point within `cell`, if any (ties: the earliest).
    fn nearest(&self, p: &Point2<f64>) -> Option<usize> {
        let (kx, ky) = Self::key(p, self.cell);
        let mut best: Option<(f64, usize)> = None;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &i in self.cells.get(&(kx + dx, ky + dy)).into_iter().flatten() {
                    let d = (self.points[i] - p).norm();
                    if d <= self.cell && best.is_none_or(|(bd, bi)| d < bd || (d == bd && i < bi)) {
                        best = Some((d, i));
                    }
                }
            }
        }
        best.map(|(_, i)| i)
    }
}

/// Merges per-pose verdicts into episodes: `verdicts[i]` is `Some((position error, angle
/// error))` for a pose flagged localised and judged false, `None` otherwise (correct,
/// searching, or not judged), which ends an episode.
fn episodes(
    verdicts: &[Option<(f64, f64)>],
    stamps: &[f64],
    holds: &[f64],
    places: &[[f64; 2]],
) -> Vec<FalseLocalization> {
    let mut out: Vec<FalseLocalization> = Vec::new();
    let mut open = false;
    for (i, verdict) in verdicts.iter().enumerate() {
        let Some((position, angle)) = *verdict else {
            open = false;
            continue;
        };
        if !open {
            out.push(FalseLocalization {
                span_s: [stamps[i], stamps[i]],
                duration_s: 0.0,
                max_position_error_m: position,
                max_angle_error_deg: angle.to_degrees(),
                place: places[i],
            });
            open = true;
        }
        let e = out.last_mut().expect("an episode is open");
        e.span_s[1] = stamps[i];
        e.duration_s += holds[i];
        if position > e.max_position_error_m {
            e.max_position_error_m = position;
            e.place = places[i];
        }
        e.max_angle_error_deg = e.max_angle_error_deg.max(angle.to_degrees());
    }
    out
}

/// Judges a localisation run (see the module documentation).
///
/// `truth`: the localisation run's true poses (`world_from_base`), dense enough to be
/// interpolated at the estimate's stamps (the simulator's ground truth); estimate poses
/// outside its time span are left out. `world_from_map`: the mapping run's alignment.
/// `kidnap_s`: when the robot was carried elsewhere, seconds on the estimate's clock.
///
/// Errors if the estimate's statuses do not match its poses, or if no estimate pose lies
/// within the truth's time span.
pub fn evaluate_localization(
    truth: &Trajectory,
    estimate: &LocalizedTrajectory,
    world_from_map: &Sim3,
    map: Option<MapReference<'_>>,
    lanes: Option<&Lanes>,
    kidnap_s: Option<f64>,
    criteria: &LocalizationCriteria,
) -> Result<LocalizationReport, EvalError> {
    let est = &estimate.trajectory;
    if estimate.localized.len() != est.len() {
        return Err(EvalError::CountsDiffer {
            what: "localisation statuses",
            expected: est.len(),
            got: estimate.localized.len(),
        });
    }
    if truth.len() < 2 {
        return Err(EvalError::TooFewPoses {
            what: "localisation's ground truth",
            needed: 2,
            got: truth.len(),
        });
    }
    if let Some(m) = &map
        && m.truth.len() != m.estimate.len()
    {
        return Err(EvalError::CountsDiffer {
            what: "the mapping run's estimate poses beside its true poses",
            expected: m.truth.len(),
            got: m.estimate.len(),
        });
    }
    let (t_first, t_last) = (truth.stamps[0], truth.stamps[truth.len() - 1]);
    let kept: Vec<usize> = (0..est.len())
        .filter(|&i| (t_first..=t_last).contains(&est.stamps[i]))
        .collect();
    if kept.is_empty() {
        return Err(EvalError::TooFewPoses {
            what: "localisation (estimate poses within the ground truth's time span)",
            needed: 1,
            got: 0,
        });
    }
    // True travel from the truth's start, at every truth stamp.
    let mut travel = Vec::with_capacity(truth.len());
    let mut sum = 0.0;
    travel.push(0.0);
    for w in truth.poses.windows(2) {
        sum += (w[1].translation.vector - w[0].translation.vector).norm();
        travel.push(sum);
    }
    let travel_at = |t: f64| {
        let k = truth
            .stamps
            .partition_point(|&s| s < t)
            .clamp(1, truth.len() - 1);
        let (t0, t1) = (truth.stamps[k - 1], truth.stamps[k]);
        let f = if t1 > t0 {
            ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        travel[k - 1] + f * (travel[k] - travel[k - 1])
    };
    let stamps: Vec<f64> = kept.iter().map(|&i| est.stamps[i]).collect();
    let holds: Vec<f64> = (0..kept.len())
        .map(|k| stamps.get(k + 1).map_or(0.0, |next| next - stamps[k]))
        .collect();
    let true_poses: Vec<Isometry3<f64>> = stamps.iter().map(|&t| interpolate(truth, t)).collect();
    let places: Vec<[f64; 2]> = true_poses
        .iter()
        .map(|p| [p.translation.x, p.translation.y])
        .collect();
    let flagged: Vec<bool> = kept.iter().map(|&i| estimate.localized[i]).collect();
    let is_false = |(position, angle): (f64, f64)| {
        position > criteria.false_position_m || angle > criteria.false_angle_rad
    };

    // Against the truth.
    let world_est: Vec<Isometry3<f64>> = kept
        .iter()
        .map(|&i| world_from_map.apply(&est.poses[i]))
        .collect();
    let vs_truth: Vec<(f64, f64)> = true_poses
        .iter()
        .zip(&world_est)
        .map(|(t, e)| pose_error(t, e))
        .collect();
    // Against the map: where the map says this true place is.
    let vs_map: Vec<Option<(f64, f64)>> = match &map {
        None => vec![None; kept.len()],
        Some(m) => {
            let index = PlaceIndex::new(m.truth, criteria.map_place_m);
            kept.iter()
                .zip(&true_poses)
                .map(|(&i, truth_here)| {
                    let place = Point2::new(truth_here.translation.x, truth_here.translation.y);
                    index.nearest(&place).map(|k| {
                        let expected = m.estimate[k] * (m.truth[k].inverse() * truth_here);
                        pose_error(&expected, &est.poses[i])
                    })
                })
                .collect()
        }
    };
    let correct: Vec<bool> = (0..kept.len())
        .map(|k| {
            flagged[k]
                && match (&map, vs_map[k]) {
                    (Some(_), Some(e)) => !is_false(e),
                    (Some(_), None) => false,
                    (None, _) => !is_false(vs_truth[k]),
                }
        })
        .collect();

    let first_localized = flagged.iter().position(|&f| f);
    let first_correct = correct.iter().position(|&c| c);
    let start = stamps[0];
    // Sums start at +0 (an empty `Iterator::sum` of floats is -0, which reads oddly in a
    // results file).
    let total: f64 = holds.iter().fold(0.0, |a, b| a + b);
    let localized_time: f64 = (0..kept.len())
        .filter(|&k| flagged[k])
        .map(|k| holds[k])
        .fold(0.0, |a, b| a + b);
    let errors: Vec<f64> = (0..kept.len())
        .filter(|&k| flagged[k])
        .map(|k| vs_truth[k].0)
        .collect();
    let false_vs_truth = episodes(
        &(0..kept.len())
            .map(|k| (flagged[k] && is_false(vs_truth[k])).then_some(vs_truth[k]))
            .collect::<Vec<_>>(),
        &stamps,
        &holds,
        &places,
    );
    let false_vs_map = episodes(
        &(0..kept.len())
            .map(|k| vs_map[k].filter(|&e| flagged[k] && is_false(e)))
            .collect::<Vec<_>>(),
        &stamps,
        &holds,
        &places,
    );
    let wrong_lane_s = lanes.map_or(0.0, |lanes| {
        (0..kept.len())
            .filter(|&k| flagged[k])
            .filter(|&k| {
                let e = &world_est[k].translation;
                match (lanes.lane_of(places[k]), lanes.lane_of([e.x, e.y])) {
                    (Some(a), Some(b)) => a != b,
                    _ => false,
                }
            })
            .map(|k| holds[k])
            .fold(0.0, |a, b| a + b)
    });
    // Poses stamped at the kidnapping (within a microsecond: stamps are whole nanoseconds
    // carried in seconds) answer data from before it.
    let relocalized_after_s = kidnap_s.and_then(|t| {
        (0..kept.len())
            .find(|&k| stamps[k] > t + 1e-6 && correct[k])
            .map(|k| stamps[k] - t)
    });
    let success = first_correct
        .is_some_and(|k| travel_at(stamps[k]) - travel_at(start) <= criteria.success_within_m);
    Ok(LocalizationReport {
        poses: kept.len(),
        localized_poses: flagged.iter().filter(|&&f| f).count(),
        success,
        first_localized_s: first_localized.map(|k| stamps[k] - start),
        first_localized_travel_m: first_localized.map(|k| travel_at(stamps[k]) - travel_at(start)),
        first_correct_s: first_correct.map(|k| stamps[k] - start),
        first_correct_travel_m: first_correct.map(|k| travel_at(stamps[k]) - travel_at(start)),
        localized_fraction: if total > 0.0 {
            localized_time / total
        } else if flagged.iter().all(|&f| f) {
            1.0
        } else {
            0.0
        },
        ate_map_frame: if errors.is_empty() {
            None
        } else {
            Some(Statistics::from_errors(&errors)?)
        },
        false_vs_truth_s: false_vs_truth.iter().fold(0.0, |a, e| a + e.duration_s),
        false_vs_map_s: false_vs_map.iter().fold(0.0, |a, e| a + e.duration_s),
        false_vs_truth,
        false_vs_map,
        judged_vs_map: (0..kept.len())
            .filter(|&k| flagged[k] && vs_map[k].is_some())
            .count(),
        wrong_lane_s,
        relocalized_after_s,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    use super::*;

    /// A robot driving north up lane `lane` (x = 1.5 + 3 lane) at 0.5 m/s for `seconds`,
    /// poses at 10 Hz, starting at y = 0.
    fn drive(lane: f64, seconds: f64) -> Trajectory {
        let n = (seconds * 10.0) as usize + 1;
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let stamps: Vec<f64> = (0..n).map(|i| i as f64 / 10.0).collect();
        let poses = stamps
            .iter()
            .map(|t| Isometry3::from_parts(Translation3::new(1.5 + 3.0 * lane, 0.5 * t, 0.0), yaw))
            .collect();
        Trajectory::new(stamps, poses)
    }

    /// Rows at x = 0, 3, 6, 9 along y from -5 to 40: lanes 0, 1, 2.
    fn lanes() -> Lanes {
        Lanes {
            along: [0.0, 1.0],
            rows: vec![0.0, 3.0, 6.0, 9.0],
            extent: [-5.0, 40.0],
        }
    }

    fn shifted(t: &Trajectory, dx: f64, dy: f64) -> Trajectory {
        let shift = Isometry3::translation(dx, dy, 0.0);
        Trajectory::new(
            t.stamps.clone(),
            t.poses.iter().map(|p| shift * p).collect(),
        )
    }

    #[test]
    fn a_run_localised_throughout_on_its_place_succeeds_at_once_with_nothing_false() {
        let truth = drive(1.0, 60.0);
        let est = LocalizedTrajectory {
            localized: vec![true; truth.len()],
            trajectory: truth.clone(),
        };
        let map_truth = truth.poses.clone();
        let r = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            Some(MapReference {
                truth: &map_truth,
                estimate: &map_truth,
            }),
            Some(&lanes()),
            None,
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        assert!(r.success);
        assert_eq!(r.first_correct_s, Some(0.0));
        assert_eq!(r.localized_fraction, 1.0);
        assert!(r.ate_map_frame.expect("some").max < 1e-12);
        assert!(r.false_vs_truth.is_empty() && r.false_vs_map.is_empty());
        assert_eq!(r.judged_vs_map, truth.len());
        assert_eq!(r.wrong_lane_s, 0.0);
    }

    #[test]
    fn searching_first_then_localised_counts_the_time_and_travel_to_it() {
        // Searching for the first 12 s (6 m), then localised on the place; then searching
        // again for the last 10 s of 60.
        let truth = drive(0.0, 60.0);
        let localized: Vec<bool> = truth
            .stamps
            .iter()
            .map(|&t| (12.0..50.0).contains(&t))
            .collect();
        let est = LocalizedTrajectory {
            localized,
            trajectory: truth.clone(),
        };
        let r = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            None,
            None,
            None,
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        assert!(r.success, "6 m < 10 m");
        assert!((r.first_localized_s.expect("some") - 12.0).abs() < 1e-9);
        assert!((r.first_localized_travel_m.expect("some") - 6.0).abs() < 1e-9);
        assert!(
            (r.localized_fraction - 38.0 / 60.0).abs() < 1e-9,
            "{}",
            r.localized_fraction
        );
        // Localised only after 24 m: not a success.
        let late = LocalizedTrajectory {
            localized: truth.stamps.iter().map(|&t| t >= 48.0).collect(),
            trajectory: truth.clone(),
        };
        let r = evaluate_localization(
            &truth,
            &late,
            &Sim3::identity(),
            None,
            None,
            None,
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        assert!(!r.success);
        assert!((r.first_correct_travel_m.expect("some") - 24.0).abs() < 1e-9);
    }

    #[test]
    fn a_pose_flagged_localised_in_the_next_lane_is_false_and_wrong_lane() {
        // From 20 s to 30 s the system says localised but puts itself one lane over (3 m
        // east); elsewhere it is right.
        let truth = drive(1.0, 60.0);
        let wrong = shifted(&truth, 3.0, 0.0);
        let poses = (0..truth.len())
            .map(|i| {
                if (20.0..30.0).contains(&truth.stamps[i]) {
                    wrong.poses[i]
                } else {
                    truth.poses[i]
                }
            })
            .collect();
        let est = LocalizedTrajectory {
            localized: vec![true; truth.len()],
            trajectory: Trajectory::new(truth.stamps.clone(), poses),
        };
        let map_truth = truth.poses.clone();
        let r = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            Some(MapReference {
                truth: &map_truth,
                estimate: &map_truth,
            }),
            Some(&lanes()),
            None,
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        for episodes in [&r.false_vs_truth, &r.false_vs_map] {
            assert_eq!(episodes.len(), 1, "{episodes:?}");
            let e = &episodes[0];
            assert!((e.span_s[0] - 20.0).abs() < 1e-9 && (e.span_s[1] - 29.9).abs() < 1e-9);
            assert!((e.duration_s - 10.0).abs() < 1e-6, "{}", e.duration_s);
            assert!((e.max_position_error_m - 3.0).abs() < 1e-9);
        }
        assert!((r.wrong_lane_s - 10.0).abs() < 1e-6, "{}", r.wrong_lane_s);
        assert!(r.success);
    }

    #[test]
    fn a_map_with_a_scale_error_is_judged_by_the_map_not_by_the_truth() {
        // The mapping run's estimate is the truth scaled by 0.8 about the origin (a
        // visual system's depth read wrongly); the localisation run finds itself exactly
        // where that map puts each place. Against the truth (a rigid alignment cannot undo
        // the scale) it is off by up to 20 % of the distance from the origin; against the
        // map it is right.
        let truth = drive(1.0, 60.0);
        let scale = |p: &Isometry3<f64>| {
            Isometry3::from_parts(Translation3::from(p.translation.vector * 0.8), p.rotation)
        };
        let map_truth = truth.poses.clone();
        let map_est: Vec<Isometry3<f64>> = truth.poses.iter().map(scale).collect();
        let est = LocalizedTrajectory {
            localized: vec![true; truth.len()],
            trajectory: Trajectory::new(truth.stamps.clone(), map_est.clone()),
        };
        let r = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            Some(MapReference {
                truth: &map_truth,
                estimate: &map_est,
            }),
            None,
            None,
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        assert!(r.false_vs_map.is_empty(), "{:?}", r.false_vs_map);
        assert!(!r.false_vs_truth.is_empty());
        assert!(r.success, "judged by the map");
        let worst = r
            .false_vs_truth
            .iter()
            .map(|e| e.max_position_error_m)
            .fold(0.0, f64::max);
        // At the end (x 4.5, y 30): 20 % of |(4.5, 30)| = 6.07 m.
        assert!(
            (worst - 0.2 * (4.5f64.powi(2) + 30f64.powi(2)).sqrt()).abs() < 1e-6,
            "{worst}"
        );
    }

    #[test]
    fn a_kidnapped_robot_is_timed_until_it_is_right_again() {
        // Carried 6 m north at 30 s without being told: its odometry keeps it 6 m behind
        // and it keeps saying localised until 37 s, searches until 40 s and is right after.
        let truth = drive(0.0, 60.0);
        let behind = shifted(&truth, 0.0, -6.0);
        let (mut poses, mut localized) = (Vec::new(), Vec::new());
        for (i, &t) in truth.stamps.iter().enumerate() {
            let lost = (30.0..40.0).contains(&t);
            poses.push(if lost {
                behind.poses[i]
            } else {
                truth.poses[i]
            });
            localized.push(!(37.0..40.0).contains(&t));
        }
        let est = LocalizedTrajectory {
            localized,
            trajectory: Trajectory::new(truth.stamps.clone(), poses),
        };
        let r = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            None,
            None,
            Some(30.0),
            &LocalizationCriteria::default(),
        )
        .expect("evaluates");
        assert!((r.relocalized_after_s.expect("some") - 10.0).abs() < 1e-9);
        assert_eq!(r.false_vs_truth.len(), 1);
        assert!(
            (r.false_vs_truth_s - 7.0).abs() < 1e-6,
            "{}",
            r.false_vs_truth_s
        );
    }

    #[test]
    fn the_lane_of_a_place_is_between_its_rows_and_none_on_the_headland() {
        let l = lanes();
        assert_eq!(l.lane_of([1.5, 10.0]), Some(0));
        assert_eq!(l.lane_of([4.5, 10.0]), Some(1));
        assert_eq!(l.lane_of([8.9, 39.0]), Some(2));
        assert_eq!(l.lane_of([4.5, 41.0]), None, "beyond the rows' end");
        assert_eq!(l.lane_of([-1.0, 10.0]), None, "outside the first row");
        assert_eq!(l.lane_of([9.5, 10.0]), None, "outside the last row");
    }

    #[test]
    fn statuses_that_do_not_match_the_poses_are_an_error() {
        let truth = drive(0.0, 10.0);
        let est = LocalizedTrajectory {
            localized: vec![true; 3],
            trajectory: truth.clone(),
        };
        let e = evaluate_localization(
            &truth,
            &est,
            &Sim3::identity(),
            None,
            None,
            None,
            &LocalizationCriteria::default(),
        )
        .expect_err("mismatch");
        assert!(matches!(e, EvalError::CountsDiffer { .. }), "{e}");
        assert_eq!(
            e.to_string(),
            "localisation statuses: 3 where there are 101 poses"
        );
    }
}
