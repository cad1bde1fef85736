//! Wrong joins judged from the final map: places the estimate puts together that the truth
//! keeps apart, whatever the system reported.
//!
//! A loop judge that reads a system's events cannot see a false merge the system reports
//! without stamps, nor one of a system that reports nothing. The final trajectory shows it
//! anyway: two poses far apart in time that the estimate puts within `join_m` of each other
//! while the truth keeps them more than `apart_m` apart are a wrong join of two places, and
//! the reverse (the truth revisits a place, the estimate keeps the two passes more than
//! `apart_m` apart) is a revisit the map missed.
//!
//! Pairs are found with a uniform grid over the positions (cells of `join_m`, so a query
//! reads 3 x 3 cells: linear in the number of poses for a trajectory that does not pile up
//! in one place), after thinning the trajectory to one pose per `sample_m` of true travel.
//! For each later pose the nearest earlier partner is kept; consecutive pairs whose partners
//! advance together are one episode. An episode over at least `min_travel_m` of travel is a
//! **wrong join**: the estimate keeps two stretches of path together. A shorter one is a
//! **crossing**: two drifting paths that cross once, which is drift, reported apart.
//!
//! Distances are between estimate positions, so they are in the estimate's own scale and the
//! same under any rigid alignment. The defaults and why:
//! - `join_m = 1.0`: the distance at which the loop judge calls two base poses one place
//!   (`LoopCriteria`), and about a plant spacing in the paper's rows;
//! - `apart_m = 2.5`: less than the row spacing (3 m in both worlds; 2.5 m would still be a
//!   neighbouring lane's centre with 0.5 m of drift), so joining two lanes counts, while
//!   1.0–2.5 m is a band where neither verdict is given;
//! - `min_gap_s = 30`: at the routes' 0.5 m/s, at least 15 m of travel between the two
//!   poses, so poses of one pass along a lane are never paired with each other (as the
//!   study's prototype, `scripts/study-tables.py`'s `final_map_partner`);
//! - `min_travel_m = 3.0`: two paths crossing at an angle θ stay within `join_m` for
//!   `2 join_m / sin θ` of travel, under 3 m for θ above about 40°; a stretch kept together
//!   over 3 m is a pass laid onto another;
//! - `sample_m = 0.1`: fine beside `join_m`, and 100 k poses of a long run thin to one per
//!   10 cm of travel.

use std::collections::BTreeMap;

use nalgebra::Vector3;

/// The thresholds of [`wrong_joins`]; the module documentation says why each default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JoinCriteria {
    /// The estimate puts two poses together within this, metres.
    pub join_m: f64,
    /// The truth keeps two poses apart beyond this, metres.
    pub apart_m: f64,
    /// The two poses are at least this far apart in time, seconds.
    pub min_gap_s: f64,
    /// An episode over at least this much true travel of its later stretch is a wrong join;
    /// a shorter one a crossing, metres.
    pub min_travel_m: f64,
    /// The trajectory is thinned to one pose per this much true travel, metres.
    pub sample_m: f64,
}

impl Default for JoinCriteria {
    fn default() -> Self {
        Self {
            join_m: 1.0,
            apart_m: 2.5,
            min_gap_s: 30.0,
            min_travel_m: 3.0,
            sample_m: 0.1,
        }
    }
}

/// What kind of episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EpisodeKind {
    /// The estimate keeps two stretches together that the truth keeps apart.
    WrongJoin,
    /// Two drifting paths cross once in the estimate: drift, not a join.
    Crossing,
    /// The truth revisits a place that the estimate keeps apart.
    MissedRevisit,
    /// The truth revisits a place and the estimate agrees.
    Revisit,
}

/// One episode: a stretch of the later path and the earlier stretch it was paired with.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JoinEpisode {
    pub kind: EpisodeKind,
    /// The later stretch, seconds: first and last pose.
    pub later_s: [f64; 2],
    /// The earlier stretch it was paired with, seconds.
    pub earlier_s: [f64; 2],
    /// True travel along the later stretch, metres.
    pub travel_m: f64,
    /// At the episode's closest pair in the estimate: the estimate's distance and the
    /// truth's, metres (for a revisit, at the closest pair in the truth).
    pub estimate_distance_m: f64,
    pub truth_distance_m: f64,
    /// The truth's positions (x, y) of that pair: the later and the earlier place.
    pub later_place: [f64; 2],
    pub earlier_place: [f64; 2],
    /// The stamps of that pair, seconds: later, earlier.
    pub pair_s: [f64; 2],
}

/// Every episode of a trajectory, by kind.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct JoinReport {
    pub wrong_joins: Vec<JoinEpisode>,
    pub crossings: Vec<JoinEpisode>,
    pub missed_revisits: Vec<JoinEpisode>,
    pub revisits: Vec<JoinEpisode>,
}

impl JoinReport {
    /// True travel over revisits the estimate keeps (`revisits`) over all true revisits
    /// (`revisits` and `missed_revisits`); `None` without any revisit.
    pub fn revisit_recall(&self) -> Option<f64> {
        let kept: f64 = self.revisits.iter().map(|e| e.travel_m).sum();
        let missed: f64 = self.missed_revisits.iter().map(|e| e.travel_m).sum();
        (kept + missed > 0.0).then(|| kept / (kept + missed))
    }
}

/// How long before a map change reported without stamps (a merge, a global adjustment) the
/// later stretch of the wrong join it made may end, seconds: 10 s is 5 m at the routes'
/// 0.5 m/s. A system joins the place it is at when it detects the loop, and reports the
/// change once its correction is done: ORB-SLAM2/3 query the current keyframe, a few
/// keyframes (under a second at their rates) behind the tracker, and correct in a thread of
/// their own; a paced run's queue adds a few seconds more. A join whose later stretch ends
/// earlier than this before the event was there before it, and is some other event's (or
/// nobody's: silent).
pub const EXPLAIN_WINDOW_S: f64 = 10.0;
/// How far after the event an episode's later stretch may begin and still be the event's,
/// seconds: the event's stamp and the pose stamps come from different clocks of the system
/// (a keyframe's stamp against the message that ended the correction).
const EXPLAIN_LEAD_S: f64 = 1.0;

impl JoinEpisode {
    /// Whether this episode's later stretch reaches into the `window_s` before `stamp_s`
    /// (up to [`EXPLAIN_LEAD_S`] after it): the episode a map change reported at `stamp_s`
    /// made.
    pub fn ends_shortly_before(&self, stamp_s: f64, window_s: f64) -> bool {
        self.later_s[0] <= stamp_s + EXPLAIN_LEAD_S && self.later_s[1] >= stamp_s - window_s
    }

    /// Whether a loop reported with its two stamps (later, earlier; seconds) joins this
    /// episode's two stretches, each within `window_s`.
    pub fn joins_stamps(&self, stamps_s: [f64; 2], window_s: f64) -> bool {
        let within = |t: f64, span: [f64; 2]| t >= span[0] - window_s && t <= span[1] + window_s;
        let [a, b] = if stamps_s[0] >= stamps_s[1] {
            stamps_s
        } else {
            [stamps_s[1], stamps_s[0]]
        };
        within(a, self.later_s) && within(b, self.earlier_s)
    }
}

/// What the final map says of a map change reported at one stamp without the poses it joins:
/// the wrong join and the kept revisit whose later stretches end shortly before it
/// ([`EXPLAIN_WINDOW_S`]), as indices into [`JoinReport::wrong_joins`] and
/// [`JoinReport::revisits`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MapChangeVerdict {
    pub wrong_join: Option<usize>,
    pub revisit: Option<usize>,
}

impl MapChangeVerdict {
    /// False when it made a wrong join; true when it kept a true revisit and made no wrong
    /// join; `None` when the final map shows neither near it.
    pub fn true_loop(&self) -> Option<bool> {
        match (self.wrong_join, self.revisit) {
            (Some(_), _) => Some(false),
            (None, Some(_)) => Some(true),
            (None, None) => None,
        }
    }
}

impl JoinReport {
    /// The episodes a map change reported at `stamp_s` (seconds) without stamps made: of
    /// several, the one whose later stretch ends nearest the event.
    pub fn map_change(&self, stamp_s: f64) -> MapChangeVerdict {
        let nearest = |episodes: &[JoinEpisode]| {
            episodes
                .iter()
                .enumerate()
                .filter(|(_, e)| e.ends_shortly_before(stamp_s, EXPLAIN_WINDOW_S))
                .min_by(|(_, a), (_, b)| {
                    (a.later_s[1] - stamp_s)
                        .abs()
                        .total_cmp(&(b.later_s[1] - stamp_s).abs())
                })
                .map(|(i, _)| i)
        };
        MapChangeVerdict {
            wrong_join: nearest(&self.wrong_joins),
            revisit: nearest(&self.revisits),
        }
    }

    /// The wrong joins no accepted loop explains: none of `stamped` (a loop's later and
    /// earlier stamp, seconds) joins its two stretches and none of `stampless` (a map
    /// change's stamp, seconds) comes shortly after it. Indices into
    /// [`Self::wrong_joins`].
    pub fn silent(&self, stamped: &[[f64; 2]], stampless: &[f64]) -> Vec<usize> {
        (0..self.wrong_joins.len())
            .filter(|&i| {
                let e = &self.wrong_joins[i];
                !stamped.iter().any(|&s| e.joins_stamps(s, EXPLAIN_WINDOW_S))
                    && !stampless
                        .iter()
                        .any(|&t| e.ends_shortly_before(t, EXPLAIN_WINDOW_S))
            })
            .collect()
    }
}

/// A thinned pose: time, estimate and true position, true travel so far.
#[derive(Debug, Clone, Copy)]
struct Sample {
    t: f64,
    est: Vector3<f64>,
    truth: Vector3<f64>,
    travel: f64,
}

/// A uniform grid over 2D positions (x, y), cells of `cell` metres, holding sample indices
/// in time order.
struct Grid {
    cell: f64,
    cells: BTreeMap<(i64, i64), Vec<usize>>,
}

impl Grid {
    fn new(cell: f64) -> Self {
        Self {
            cell,
            cells: BTreeMap::new(),
        }
    }

    fn key(&self, p: &Vector3<f64>) -> (i64, i64) {
        (
            (p.x / self.cell).floor() as i64,
            (p.y / self.cell).floor() as i64,
        )
    }

    fn insert(&mut self, p: &Vector3<f64>, index: usize) {
        let key = self.key(p);
        self.cells.entry(key).or_default().push(index);
    }

    /// Every index in the 3 x 3 cells around `p`: all within `cell` of it, and some more.
    fn near(&self, p: &Vector3<f64>) -> impl Iterator<Item = usize> + '_ {
        let (cx, cy) = self.key(p);
        (-1..=1)
            .flat_map(move |dx| (-1..=1).map(move |dy| (cx + dx, cy + dy)))
            .filter_map(|k| self.cells.get(&k))
            .flatten()
            .copied()
    }
}

/// One pair of a later and an earlier sample.
#[derive(Debug, Clone, Copy)]
struct Pair {
    later: usize,
    earlier: usize,
}

/// The wrong joins, crossings and revisits of an estimate against the truth at the same
/// stamps: `stamps` in seconds (increasing), `estimate` and `truth` positions, one per stamp.
/// Non-finite positions are skipped.
///
/// # Panics
/// If the three slices differ in length.
pub fn wrong_joins(
    stamps: &[f64],
    estimate: &[Vector3<f64>],
    truth: &[Vector3<f64>],
    criteria: &JoinCriteria,
) -> JoinReport {
    assert!(
        stamps.len() == estimate.len() && stamps.len() == truth.len(),
        "stamps, estimate and truth differ in length"
    );
    let samples = thin(stamps, estimate, truth, criteria.sample_m);
    let mut report = JoinReport::default();
    // Estimate-near pairs: wrong joins and crossings where the truth is apart.
    let wrong = pairs(
        &samples,
        criteria,
        |s| s.est,
        |a, b| (a.truth - b.truth).norm() >= criteria.apart_m,
    );
    for episode in episodes(&samples, &wrong, criteria) {
        let e = describe(&samples, &episode, |s| s.est, criteria, true);
        if e.travel_m >= criteria.min_travel_m {
            report.wrong_joins.push(e);
        } else {
            report.crossings.push(e);
        }
    }
    // Truth-near pairs: revisits, kept or missed by the estimate.
    let missed = pairs(
        &samples,
        criteria,
        |s| s.truth,
        |a, b| (a.est - b.est).norm() >= criteria.apart_m,
    );
    for episode in episodes(&samples, &missed, criteria) {
        report
            .missed_revisits
            .push(describe(&samples, &episode, |s| s.truth, criteria, false));
    }
    let kept = pairs(
        &samples,
        criteria,
        |s| s.truth,
        |a, b| (a.est - b.est).norm() < criteria.apart_m,
    );
    for episode in episodes(&samples, &kept, criteria) {
        report
            .revisits
            .push(describe(&samples, &episode, |s| s.truth, criteria, false));
    }
    report
}

/// One sample per `step` metres of true travel (the first and the last always).
fn thin(
    stamps: &[f64],
    estimate: &[Vector3<f64>],
    truth: &[Vector3<f64>],
    step: f64,
) -> Vec<Sample> {
    let mut out: Vec<Sample> = Vec::new();
    let mut travel = 0.0;
    let mut last_truth: Option<Vector3<f64>> = None;
    let mut since = f64::INFINITY;
    for k in 0..stamps.len() {
        let (e, g) = (estimate[k], truth[k]);
        if !(e.iter().all(|v| v.is_finite())
            && g.iter().all(|v| v.is_finite())
            && stamps[k].is_finite())
        {
            continue;
        }
        if let Some(prev) = last_truth {
            let d = (g - prev).norm();
            travel += d;
            since += d;
        }
        last_truth = Some(g);
        if since >= step || k + 1 == stamps.len() {
            out.push(Sample {
                t: stamps[k],
                est: e,
                truth: g,
                travel,
            });
            since = 0.0;
        }
    }
    out
}

/// For each later sample, the earlier sample at least `min_gap_s` before it that is nearest
/// by `position` within `join_m` and for which `keep(later, earlier)` holds.
fn pairs(
    samples: &[Sample],
    criteria: &JoinCriteria,
    position: impl Fn(&Sample) -> Vector3<f64>,
    keep: impl Fn(&Sample, &Sample) -> bool,
) -> Vec<Pair> {
    let mut grid = Grid::new(criteria.join_m);
    let mut out = Vec::new();
    let mut inserted = 0;
    for (j, later) in samples.iter().enumerate() {
        // Samples old enough to pair with this one enter the grid as time passes.
        while inserted < j && samples[inserted].t <= later.t - criteria.min_gap_s {
            grid.insert(&position(&samples[inserted]), inserted);
            inserted += 1;
        }
        let p = position(later);
        let best = grid
            .near(&p)
            .map(|i| (i, (position(&samples[i]) - p).norm()))
            .filter(|&(i, d)| d <= criteria.join_m && keep(later, &samples[i]))
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        if let Some((earlier, _)) = best {
            out.push(Pair { later: j, earlier });
        }
    }
    out
}

/// Consecutive pairs whose earlier samples advance along with the later ones, as episodes:
/// a pair continues an episode when its later sample follows the episode's last within
/// `join_m` of travel and its earlier sample is within the later step plus `2 join_m` of
/// travel of the episode's last earlier sample.
fn episodes(samples: &[Sample], pairs: &[Pair], criteria: &JoinCriteria) -> Vec<Vec<Pair>> {
    let mut out: Vec<Vec<Pair>> = Vec::new();
    for &pair in pairs {
        let continues = out.last().and_then(|e| e.last()).is_some_and(|last| {
            let step = samples[pair.later].travel - samples[last.later].travel;
            let moved = (samples[pair.earlier].travel - samples[last.earlier].travel).abs();
            step <= criteria.join_m && moved <= step + 2.0 * criteria.join_m
        });
        if continues {
            out.last_mut().expect("checked").push(pair);
        } else {
            out.push(vec![pair]);
        }
    }
    out
}

/// An episode's summary; `by_estimate`: its closest pair is the estimate's (else the
/// truth's).
fn describe(
    samples: &[Sample],
    episode: &[Pair],
    position: impl Fn(&Sample) -> Vector3<f64>,
    criteria: &JoinCriteria,
    by_estimate: bool,
) -> JoinEpisode {
    let first = episode.first().expect("an episode has a pair");
    let last = episode.last().expect("an episode has a pair");
    let closest = episode
        .iter()
        .min_by(|a, b| {
            let d = |p: &Pair| (position(&samples[p.later]) - position(&samples[p.earlier])).norm();
            d(a).total_cmp(&d(b))
        })
        .expect("an episode has a pair");
    let (l, e) = (&samples[closest.later], &samples[closest.earlier]);
    let earliest = episode
        .iter()
        .map(|p| samples[p.earlier].t)
        .fold(f64::INFINITY, f64::min);
    let latest = episode
        .iter()
        .map(|p| samples[p.earlier].t)
        .fold(f64::NEG_INFINITY, f64::max);
    // One sample's worth of travel for a single pair, so that an episode is never 0 m.
    let travel = samples[last.later].travel - samples[first.later].travel + criteria.sample_m;
    let kind = match (by_estimate, (l.est - e.est).norm() < criteria.apart_m) {
        (true, _) => EpisodeKind::WrongJoin,
        (false, true) => EpisodeKind::Revisit,
        (false, false) => EpisodeKind::MissedRevisit,
    };
    JoinEpisode {
        kind,
        later_s: [samples[first.later].t, samples[last.later].t],
        earlier_s: [earliest, latest],
        travel_m: travel,
        estimate_distance_m: (l.est - e.est).norm(),
        truth_distance_m: (l.truth - e.truth).norm(),
        later_place: [l.truth.x, l.truth.y],
        earlier_place: [e.truth.x, e.truth.y],
        pair_s: [l.t, e.t],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path of straight legs at 0.5 m/s sampled at 10 Hz: stamps and positions.
    fn path(legs: &[([f64; 2], [f64; 2])]) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let mut stamps = Vec::new();
        let mut points = Vec::new();
        let mut t = 0.0;
        for &(a, b) in legs {
            let (a, b) = (Vector3::new(a[0], a[1], 0.0), Vector3::new(b[0], b[1], 0.0));
            let n = ((b - a).norm() / 0.05).ceil() as usize;
            for k in 0..n {
                stamps.push(t);
                points.push(a + (b - a) * (k as f64 / n as f64));
                t += 0.1;
            }
        }
        (stamps, points)
    }

    /// Down lane 1 (y = 0), a headland turn, back up lane 2 (y = 3): the truth.
    fn two_lanes() -> (Vec<f64>, Vec<Vector3<f64>>) {
        path(&[
            ([0.0, 0.0], [18.0, 0.0]),
            ([18.0, 0.0], [22.0, 0.0]),
            ([22.0, 0.0], [22.0, 3.0]),
            ([22.0, 3.0], [18.0, 3.0]),
            ([18.0, 3.0], [0.0, 3.0]),
        ])
    }

    #[test]
    fn a_lane_laid_onto_its_neighbour_is_one_wrong_join() {
        let (stamps, truth) = two_lanes();
        // The estimate lays lane 2 onto lane 1 (y = 3 becomes y = 0.2) from x = 14 to 4.
        let estimate: Vec<Vector3<f64>> = truth
            .iter()
            .map(|p| {
                if p.y > 2.9 && (4.0..=14.0).contains(&p.x) {
                    Vector3::new(p.x, 0.2, 0.0)
                } else {
                    *p
                }
            })
            .collect();
        let r = wrong_joins(&stamps, &estimate, &truth, &JoinCriteria::default());
        assert_eq!(r.wrong_joins.len(), 1, "{r:#?}");
        let e = &r.wrong_joins[0];
        assert!((9.0..11.5).contains(&e.travel_m), "{e:?}");
        assert!(
            e.estimate_distance_m <= 0.21 && e.truth_distance_m >= 2.9,
            "{e:?}"
        );
        assert!(
            e.later_place[1] > 2.9 && e.earlier_place[1].abs() < 0.1,
            "{e:?}"
        );
        assert!(e.later_s[0] > e.earlier_s[1], "{e:?}");
        assert!(r.crossings.is_empty(), "{r:#?}");
        // The truth revisits nothing (lanes 3 m apart).
        assert!(r.revisits.is_empty() && r.missed_revisits.is_empty());
        assert_eq!(r.revisit_recall(), None);
        // The true trajectory joins nothing.
        let clean = wrong_joins(&stamps, &truth, &truth, &JoinCriteria::default());
        assert_eq!(clean, JoinReport::default());

        // A map change reported just after the joined stretch ends made it; one reported
        // long after, or before the stretch began, did not.
        let end = e.later_s[1];
        assert_eq!(r.map_change(end + 3.0).wrong_join, Some(0));
        assert_eq!(r.map_change(end + 3.0).true_loop(), Some(false));
        assert_eq!(r.map_change(end + 30.0), MapChangeVerdict::default());
        assert_eq!(r.map_change(e.later_s[0] - 5.0).true_loop(), None);
        // Unexplained, it is silent; a stampless change shortly after it, or a stamped loop
        // joining its two stretches, explains it; a stamped loop elsewhere does not.
        assert_eq!(r.silent(&[], &[]), [0]);
        assert!(r.silent(&[], &[end + 3.0]).is_empty());
        let (later, earlier) = (e.pair_s[0], e.pair_s[1]);
        assert!(r.silent(&[[later, earlier]], &[]).is_empty());
        assert!(
            r.silent(&[[earlier, later]], &[]).is_empty(),
            "either order"
        );
        assert_eq!(r.silent(&[[later, earlier - 60.0]], &[end + 30.0]), [0]);
    }

    #[test]
    fn a_true_revisit_is_kept_or_missed() {
        // Down the lane and back along it: the return pass revisits every place.
        let (stamps, truth) = path(&[([0.0, 0.0], [18.0, 0.0]), ([18.0, 0.0], [0.0, 0.0])]);
        let r = wrong_joins(&stamps, &truth, &truth, &JoinCriteria::default());
        assert!(
            r.wrong_joins.is_empty() && r.missed_revisits.is_empty(),
            "{r:#?}"
        );
        assert_eq!(r.revisits.len(), 1, "{r:#?}");
        assert_eq!(r.revisit_recall(), Some(1.0));
        // A map change on the way back joined true places: true.
        let back = r.revisits[0].later_s[1];
        assert_eq!(r.map_change(back).true_loop(), Some(true));
        // The estimate shifts the return pass 3 m sideways: the revisit is missed, and the
        // shifted pass joins nothing that the truth keeps apart.
        let shifted: Vec<Vector3<f64>> = stamps
            .iter()
            .zip(&truth)
            .map(|(&t, p)| {
                if t > 40.0 {
                    p + Vector3::new(0.0, 3.0, 0.0)
                } else {
                    *p
                }
            })
            .collect();
        let r = wrong_joins(&stamps, &shifted, &truth, &JoinCriteria::default());
        assert!(r.wrong_joins.is_empty(), "{r:#?}");
        assert!(!r.missed_revisits.is_empty(), "{r:#?}");
        assert!(r.revisit_recall().expect("revisits") < 0.5, "{r:#?}");
    }

    #[test]
    fn two_drifting_paths_that_cross_once_are_drift_not_a_join() {
        let (stamps, truth) = two_lanes();
        // The estimate of lane 2 drifts across lane 1 at 56 degrees near x = 16.
        let estimate: Vec<Vector3<f64>> = truth
            .iter()
            .map(|p| {
                if p.y > 2.9 && p.x < 18.0 {
                    Vector3::new(p.x, 3.0 - (18.0 - p.x) * 1.5, 0.0)
                } else {
                    *p
                }
            })
            .collect();
        let r = wrong_joins(&stamps, &estimate, &truth, &JoinCriteria::default());
        assert!(r.wrong_joins.is_empty(), "{r:#?}");
        assert_eq!(r.crossings.len(), 1, "{r:#?}");
        assert!(r.crossings[0].travel_m < 3.0, "{:?}", r.crossings[0]);
    }

    #[test]
    fn non_finite_poses_are_skipped_and_empty_input_is_empty() {
        assert_eq!(
            wrong_joins(&[], &[], &[], &JoinCriteria::default()),
            JoinReport::default()
        );
        let (stamps, truth) = two_lanes();
        let mut estimate = truth.clone();
        estimate[10] = Vector3::new(f64::NAN, 0.0, 0.0);
        let r = wrong_joins(&stamps, &estimate, &truth, &JoinCriteria::default());
        assert!(r.wrong_joins.is_empty());
    }
}
