//! Pose-graph files (g2o, TORO, GTSAM's City10000) replayed through any [`Backend`], and
//! the yardsticks that make the backends comparable: GTSAM's graph error evaluated on
//! the final estimates, and the ATE of the positions after alignment. The
//! `graph-replay` binary is a thin command line over this module.
//!
//! - [`parse`]: reads a file into a [`PoseGraph`]: poses lifted to SE(3), between edges
//!   with diagonal sigmas in our rotation-first order, the prior the file's kind gets;
//! - [`eval`]: SE(3) logarithm, GTSAM's `NonlinearFactorGraph::error`, Horn/Umeyama
//!   alignment in SE(3) and SE(2), ATE RMSE;
//! - [`replay`]: incremental (pose by pose) and batch replay into a backend, with timings.
//!
//! [`Backend`]: crate::factor_graph::backend::Backend

use std::collections::BTreeMap;

use nalgebra::Isometry3;

use crate::factor_graph::backend::{BackendError, Factor, PoseSigmas, Robust};

pub mod eval;
pub mod parse;
pub mod replay;

pub use eval::{ate_rmse, graph_error, se3_log};
pub use parse::{Format, parse, read, read_trajectory};
pub use replay::{ReplayReport, UpdateTiming, replay};

/// One relative-pose measurement of a file: GTSAM's `BetweenFactor<Pose3>(from, to,
/// from_from_to, noise)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Edge {
    pub from: u64,
    pub to: u64,
    /// The pose of `to` in `from`'s frame, `from⁻¹·to`.
    pub from_from_to: Isometry3<f64>,
    /// Rotation first (rad), then translation (m), as [`PoseSigmas`].
    pub sigmas: PoseSigmas,
    /// 1-based line of the file it came from.
    pub line: usize,
}

/// A pose graph as read from a file, in SE(3).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraph {
    /// The file was planar (`VERTEX2`/`EDGE2`/`EDGE_SE2`, City10000): poses were lifted
    /// to SE(3) with z = 0 and yaw = θ (see [`parse`]).
    pub planar: bool,
    /// The file's `VERTEX*` values, if it has any.
    pub vertices: BTreeMap<u64, Isometry3<f64>>,
    /// The edges in file order.
    pub edges: Vec<Edge>,
    /// Sigmas of the prior that anchors the first pose (see [`parse`] for the values).
    pub prior_sigmas: PoseSigmas,
}

impl PoseGraph {
    /// Every pose key (vertices and edge ends), ascending.
    pub fn keys(&self) -> Vec<u64> {
        let mut keys: Vec<u64> = self.vertices.keys().copied().collect();
        keys.extend(self.edges.iter().flat_map(|e| [e.from, e.to]));
        keys.sort_unstable();
        keys.dedup();
        keys
    }

    /// The prior on the first (smallest) key, at its initial value: the file's vertex,
    /// else the identity (GTSAM's examples put it at `Pose3()`; every GTSAM dataset's
    /// first vertex is the identity). `None` for an empty graph.
    pub fn prior(&self) -> Option<Factor> {
        let key = *self.keys().first()?;
        Some(Factor::PosePrior {
            key,
            world_from_body: self
                .vertices
                .get(&key)
                .copied()
                .unwrap_or_else(Isometry3::identity),
            sigmas: self.prior_sigmas,
        })
    }

    /// The factors a replay adds: the prior first, then one between factor per edge in
    /// file order.
    pub fn factors(&self) -> Vec<Factor> {
        self.prior()
            .into_iter()
            .chain(self.edges.iter().map(Edge::factor))
            .collect()
    }

    /// The initial estimate of a batch replay: each pose's vertex; a pose without one is
    /// its predecessor's value composed with the edge joining them (an odometry chain),
    /// or composed with any edge to a smaller key, or the identity when it has neither.
    pub fn initial_guess(&self) -> BTreeMap<u64, Isometry3<f64>> {
        let keys = self.keys();
        let by_pose = edges_by_newest_pose(&self.edges);
        let mut out = BTreeMap::new();
        let mut prev: Option<u64> = None;
        for &key in &keys {
            let value = self.vertices.get(&key).copied().unwrap_or_else(|| {
                by_pose
                    .get(&key)
                    .and_then(|edges| chain_from(edges, key, prev, |k| out.get(&k).copied()))
                    .unwrap_or_else(Isometry3::identity)
            });
            out.insert(key, value);
            prev = Some(key);
        }
        out
    }
}

impl Edge {
    /// The edge as a non-robust between factor.
    pub fn factor(&self) -> Factor {
        Factor::Between {
            from: self.from,
            to: self.to,
            from_from_to: self.from_from_to,
            sigmas: self.sigmas,
            robust: Robust::None,
        }
    }

    /// `key`'s pose from the other end's pose `other` (which must be one of the edge's
    /// ends).
    fn pose_of(&self, key: u64, other: &Isometry3<f64>) -> Isometry3<f64> {
        if key == self.to {
            other * self.from_from_to
        } else {
            other * self.from_from_to.inverse()
        }
    }

    fn other(&self, key: u64) -> u64 {
        if key == self.to { self.from } else { self.to }
    }
}

/// Edges grouped by the larger of their two keys: the pose after whose insertion both
/// ends exist.
pub(crate) fn edges_by_newest_pose(edges: &[Edge]) -> BTreeMap<u64, Vec<&Edge>> {
    let mut out: BTreeMap<u64, Vec<&Edge>> = BTreeMap::new();
    for e in edges {
        out.entry(e.from.max(e.to)).or_default().push(e);
    }
    out
}

/// `key`'s pose composed from a known neighbour: the edge to `prev` when there is one
/// (odometry), else the first edge to another known pose.
pub(crate) fn chain_from(
    edges: &[&Edge],
    key: u64,
    prev: Option<u64>,
    known: impl Fn(u64) -> Option<Isometry3<f64>>,
) -> Option<Isometry3<f64>> {
    let odometry = prev.and_then(|p| {
        edges
            .iter()
            .find(|e| e.other(key) == p && e.from != e.to)
            .and_then(|e| Some(e.pose_of(key, &known(p)?)))
    });
    odometry.or_else(|| {
        edges.iter().find_map(|e| {
            let other = e.other(key);
            (other != key)
                .then(|| known(other))
                .flatten()
                .map(|o| e.pose_of(key, &o))
        })
    })
}

/// What can go wrong reading or replaying a graph.
#[derive(Debug, thiserror::Error)]
pub enum PoseGraphError {
    /// A malformed or unsupported line (1-based line number).
    #[error("{path}:{line}: {message}")]
    Line {
        path: String,
        line: usize,
        message: String,
    },
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// The graph as a whole cannot be used (empty, mixed planar and spatial lines, a
    /// factor naming a pose without an estimate).
    #[error("{0}")]
    Graph(String),
    #[error(transparent)]
    Backend(#[from] BackendError),
}
