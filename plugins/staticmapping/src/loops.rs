//! Loop detection as StaticMapping's `LoopDetector` does it, on submaps:
//!
//! 1. candidates: submaps older than `ignore_recent` submaps whose (optimised) position is
//!    within `max_distance_m` horizontally and `max_z_distance_m` vertically;
//! 2. of these, those whose M2DP descriptor ([`slam_common::place::m2dp`]) is similar enough; up
//!    to `candidates` of them spread evenly over the matches, plus the nearest candidate if
//!    it lies within 40 % of `max_distance_m`;
//! 3. a detection must persist: verification starts at the second consecutive submap with
//!    matches (the detector's states no loop → trying → entering → continuous loop;
//!    after leaving a loop, at the third);
//! 4. verification: ICP of the current submap to each candidate from the relative pose of
//!    their estimates (relative height zeroed, as StaticMapping does), kept when the score
//!    exceeds `accepted_min_score`;
//! 5. the loop is added only when at least two verified edges put the current submap at the
//!    same place: within `agree_m` and `agree_rad` of the first edge's.

use nalgebra::{Isometry3, Vector3};
use plugin_api::{Event, EventKind, PluginError, Stages};
use slam_common::place::m2dp::Descriptor;

use crate::config::{DescriptorVariant, IcpConfig, LoopConfig};
use crate::graph::SubmapGraph;
use crate::icp::{self, Reference};
use crate::submap::Submap;

/// The detector's state (`LoopStatus`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Status {
    #[default]
    NoLoop,
    Trying,
    Entering,
    Continuous,
    Leaving,
}

/// The persistence filter of step 3.
#[derive(Debug, Clone, Copy, Default)]
pub struct Persistence {
    pub status: Status,
    detections: usize,
}

impl Persistence {
    /// Advances by one submap that had (`detected`) descriptor matches or not; true when the
    /// matches are to be verified now.
    pub fn step(&mut self, detected: bool, needed: usize) -> bool {
        use Status::*;
        self.status = match (self.status, detected) {
            (NoLoop, true) => {
                self.detections = 1;
                if self.detections >= needed {
                    Entering
                } else {
                    Trying
                }
            }
            (NoLoop, false) => {
                self.detections = 0;
                NoLoop
            }
            (Trying, true) => {
                self.detections += 1;
                if self.detections >= needed {
                    Entering
                } else {
                    Trying
                }
            }
            (Trying, false) => NoLoop,
            (Entering, true) => Continuous,
            (Entering, false) => Trying,
            (Continuous, true) => Continuous,
            (Continuous, false) => {
                self.detections = 0;
                Leaving
            }
            (Leaving, true) => Trying,
            (Leaving, false) => NoLoop,
        };
        self.status == Continuous
    }
}

/// How similar two descriptors are, by the configured variant's measure.
pub fn similarity(a: &Descriptor, b: &Descriptor, variant: DescriptorVariant) -> f64 {
    match variant {
        DescriptorVariant::Paper => a.similarity(b),
        DescriptorVariant::Staticmapping => a.correlation(b),
    }
}

/// Steps 1 and 2: the submaps to verify against `current`, oldest first, nearest last.
pub fn candidates(
    current: usize,
    positions: &[Vector3<f64>],
    descriptors: &[Option<Descriptor>],
    cfg: &LoopConfig,
) -> Vec<usize> {
    let Some(end) = current.checked_sub(cfg.ignore_recent) else {
        return Vec::new();
    };
    let here = positions[current];
    let mut nearest: Option<(usize, f64)> = None;
    let mut matched = Vec::new();
    for j in 0..end {
        let d = positions[j] - here;
        let xy = d.xy().norm();
        if xy > cfg.max_distance_m || d.z.abs() > cfg.max_z_distance_m {
            continue;
        }
        if nearest.is_none_or(|(_, best)| xy < best) {
            nearest = Some((j, xy));
        }
        if let (Some(a), Some(b)) = (&descriptors[current], &descriptors[j])
            && similarity(a, b, cfg.descriptor) > cfg.descriptor_min_score
        {
            matched.push(j);
        }
    }
    if matched.is_empty() {
        return matched;
    }
    let n = cfg.candidates;
    let mut pairs: Vec<usize> = if matched.len() >= 2 * n {
        let step = matched.len() / n;
        (0..n).map(|i| matched[i * step]).collect()
    } else {
        matched.into_iter().take(n).collect()
    };
    if let Some((j, d)) = nearest
        && d < 0.4 * cfg.max_distance_m
        && !pairs.contains(&j)
    {
        pairs.push(j);
    }
    pairs
}

/// A verified loop edge: `target_from_current` and its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    pub target: usize,
    pub target_from_current: Isometry3<f64>,
    pub score: f64,
}

/// Step 4: ICP of the current submap's cloud to the target's, from their estimates.
pub fn verify(
    cloud: &[Vector3<f64>],
    world_from_current: &Isometry3<f64>,
    target: usize,
    target_reference: &Reference,
    world_from_target: &Isometry3<f64>,
    loop_cfg: &LoopConfig,
    icp_cfg: &IcpConfig,
) -> Result<Edge, Option<f64>> {
    let mut guess = world_from_target.inverse() * world_from_current;
    guess.translation.vector.z = 0.0;
    match icp::align(cloud, target_reference, &guess, icp_cfg) {
        Some(a) if a.score > loop_cfg.accepted_min_score => Ok(Edge {
            target,
            target_from_current: a.reference_from_reading,
            score: a.score,
        }),
        Some(a) => Err(Some(a.score)),
        None => Err(None),
    }
}

/// Step 5: whether the edges agree on where the current submap is; otherwise the largest
/// disagreement (m, rad) with the first edge.
pub fn agree(
    edges: &[Edge],
    world_from: impl Fn(usize) -> Isometry3<f64>,
    cfg: &LoopConfig,
) -> Result<(), (f64, f64)> {
    let Some(first) = edges.first() else {
        return Err((f64::INFINITY, f64::INFINITY));
    };
    if edges.len() < 2 {
        return Err((f64::INFINITY, f64::INFINITY));
    }
    let placed = |e: &Edge| world_from(e.target) * e.target_from_current;
    let reference = placed(first);
    let (mut worst_m, mut worst_rad) = (0.0f64, 0.0f64);
    for e in &edges[1..] {
        let d = reference.inverse() * placed(e);
        worst_m = worst_m.max(d.translation.vector.norm());
        worst_rad = worst_rad.max(d.rotation.angle());
    }
    if worst_m > cfg.agree_m || worst_rad > cfg.agree_rad {
        Err((worst_m, worst_rad))
    } else {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verification_starts_at_the_second_consecutive_detection() {
        let mut p = Persistence::default();
        let run: Vec<bool> = [false, true, true, true, false, true, true, true]
            .iter()
            .map(|&d| p.step(d, 1))
            .collect();
        assert_eq!(run, [false, false, true, true, false, false, false, true]);
    }

    #[test]
    fn edges_must_agree() {
        let cfg = LoopConfig::default();
        let at = |x: f64, yaw: f64| {
            Isometry3::from_parts(
                Vector3::new(x, 0.0, 0.0).into(),
                nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            )
        };
        let world = |j: usize| at(j as f64, 0.0);
        // Two targets 1 m apart whose edges place the current submap at x = 5.
        let good = [
            Edge {
                target: 1,
                target_from_current: at(4.0, 0.0),
                score: 0.9,
            },
            Edge {
                target: 2,
                target_from_current: at(3.1, 0.01),
                score: 0.9,
            },
        ];
        assert!(agree(&good, world, &cfg).is_ok());
        let bad = [
            good[0],
            Edge {
                target: 2,
                target_from_current: at(3.5, 0.0),
                score: 0.9,
            },
        ];
        let (m, _) = agree(&bad, world, &cfg).unwrap_err();
        assert!((m - 0.5).abs() < 1e-9);
        assert!(
            agree(&good[..1], world, &cfg).is_err(),
            "one edge is not enough"
        );
    }
}

/// What loop closing did over a build (`timing_json`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoopCounts {
    /// Submaps with detected candidates.
    pub detections: usize,
    /// Candidates verified by ICP.
    pub verifications: usize,
    /// Verified edges.
    pub edges_verified: usize,
    /// Loops whose edges agreed, added to the graph.
    pub accepted: usize,
    /// Edges of the accepted loops.
    pub edges_added: usize,
    /// Loops whose edges disagreed.
    pub rejected: usize,
}

/// Steps 1 to 5 over the submaps, one at a time as each joins the graph; every loop
/// accepted or rejected is an event.
#[derive(Debug)]
pub struct LoopCloser<'a> {
    cfg: &'a LoopConfig,
    icp_cfg: &'a IcpConfig,
    submaps: &'a [Submap],
    descriptors: &'a [Option<Descriptor>],
    lidar_from_base: Isometry3<f64>,
    persistence: Persistence,
    pub events: Vec<Event>,
    pub counts: LoopCounts,
}

impl<'a> LoopCloser<'a> {
    pub fn new(
        cfg: &'a LoopConfig,
        icp_cfg: &'a IcpConfig,
        submaps: &'a [Submap],
        descriptors: &'a [Option<Descriptor>],
        lidar_from_base: Isometry3<f64>,
    ) -> Self {
        Self {
            cfg,
            icp_cfg,
            submaps,
            descriptors,
            lidar_from_base,
            persistence: Persistence::default(),
            events: Vec::new(),
            counts: LoopCounts::default(),
        }
    }

    /// Detects, verifies and adds the loops of submap `i`, just added to `graph`; the time
    /// of detection, verification and the graph's update goes to `stages` ("m2dp",
    /// "verification", "back_end").
    pub fn close(
        &mut self,
        i: usize,
        graph: &mut SubmapGraph,
        stages: &mut Stages,
    ) -> Result<(), PluginError> {
        let (lc, submaps) = (self.cfg, self.submaps);
        let positions: Vec<Vector3<f64>> =
            (0..=i).map(|k| graph.pose(k).translation.vector).collect();
        let pairs = stages.time("m2dp", || {
            candidates(i, &positions, &self.descriptors[..=i], lc)
        });
        self.counts.detections += usize::from(!pairs.is_empty());
        if !self.persistence.step(!pairs.is_empty(), 1) {
            return Ok(());
        }
        let edges = stages.time("verification", || {
            let here = graph.pose(i);
            let mut edges = Vec::new();
            for &j in &pairs {
                self.counts.verifications += 1;
                let target = &submaps[j];
                if let Ok(edge) = verify(
                    &submaps[i].cloud,
                    &here,
                    j,
                    &target.reference,
                    &graph.pose(j),
                    lc,
                    self.icp_cfg,
                ) {
                    edges.push(edge);
                }
            }
            edges
        });
        self.counts.edges_verified += edges.len();
        if edges.is_empty() {
            return Ok(());
        }
        let stamp = submaps[i].stamp_ns;
        match agree(&edges, |k| graph.pose(k), lc) {
            Ok(()) => {
                let base_from_lidar = self.lidar_from_base.inverse();
                for e in &edges {
                    self.events.push(
                        Event::loop_closure(
                            stamp,
                            EventKind::LoopClosureAccepted,
                            [stamp, submaps[e.target].stamp_ns],
                            format!(
                                "submap {i} to submap {} (score {:.3}, {} agreeing edges)",
                                e.target,
                                e.score,
                                edges.len()
                            ),
                        )
                        .with_relative_pose(
                            &(base_from_lidar * e.target_from_current * self.lidar_from_base),
                        ),
                    );
                }
                self.counts.accepted += 1;
                self.counts.edges_added += edges.len();
                stages
                    .time("back_end", || {
                        graph.add_loops(i, edges.iter().map(|e| (e.target, e.target_from_current)))
                    })
                    .map_err(|e| PluginError::new(format!("backend: {e}")))?;
            }
            Err((m, rad)) => {
                self.counts.rejected += 1;
                self.events.push(Event::loop_closure(
                    stamp,
                    EventKind::LoopClosureRejected,
                    [stamp, submaps[edges[0].target].stamp_ns],
                    format!(
                        "submap {i}: {} verified edges disagree by {m:.3} m, {rad:.4} rad",
                        edges.len()
                    ),
                ));
            }
        }
        Ok(())
    }
}
