//! Replaying a [`PoseGraph`] into a [`Backend`], the way a SLAM front end would feed it
//! (incremental) or all at once (batch), timing every update.

use std::collections::BTreeMap;
use std::time::Instant;

use nalgebra::Isometry3;

use super::{PoseGraph, PoseGraphError, chain_from, edges_by_newest_pose, graph_error};
use crate::factor_graph::backend::{Backend, Scope, Value, Var};

/// One backend update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateTiming {
    /// 0-based position of the pose just inserted among the graph's keys (the last one
    /// for a batch replay).
    pub index: usize,
    /// That pose's key.
    pub key: u64,
    /// Factors in the backend when it ran.
    pub factors: usize,
    /// Wall time of the `update` call.
    pub seconds: f64,
}

/// What a replay did and reached.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    pub poses: usize,
    /// Factors added: the prior and one per edge.
    pub factors: usize,
    /// [`graph_error`] at [`PoseGraph::initial_guess`] (the same for both modes).
    pub initial_error: f64,
    /// [`graph_error`] at the backend's final estimate.
    pub final_error: f64,
    /// Wall time of the whole replay: inserts, adds and updates.
    pub seconds: f64,
    pub max_update_s: f64,
    pub updates: Vec<UpdateTiming>,
    /// The backend's final estimate of every pose.
    pub estimate: BTreeMap<u64, Isometry3<f64>>,
}

/// Replays `graph` into an empty `backend`.
///
/// Incremental (`batch == false`), pose by pose in ascending key order: insert the pose
/// with, as initial value, the backend's current estimate of the previous pose composed
/// with the edge joining them (odometry, either direction), else of any earlier pose
/// joined by an edge, else the file's vertex, else the previous pose's estimate; then add
/// every edge whose two ends now exist (and, with the first pose, the prior); then one
/// `update(Scope::Incremental)`.
///
/// Batch: insert every pose at [`PoseGraph::initial_guess`] (vertices, or the odometry
/// chain), add every factor, one `update(Scope::Full)`.
pub fn replay(
    graph: &PoseGraph,
    backend: &mut dyn Backend,
    batch: bool,
) -> Result<ReplayReport, PoseGraphError> {
    let keys = graph.keys();
    let factors = graph.factors();
    let initial = graph.initial_guess();
    let mut updates = Vec::new();
    let start = Instant::now();
    if batch {
        for (&k, v) in &initial {
            backend.insert(Var::Pose(k), Value::Pose(*v))?;
        }
        for f in &factors {
            backend.add(f.clone())?;
        }
        let t = Instant::now();
        backend.update(Scope::Full)?;
        updates.push(UpdateTiming {
            index: keys.len() - 1,
            key: *keys.last().unwrap_or(&0),
            factors: factors.len(),
            seconds: t.elapsed().as_secs_f64(),
        });
    } else {
        let by_pose = edges_by_newest_pose(&graph.edges);
        let mut prev: Option<u64> = None;
        let mut added = 0;
        for (index, &key) in keys.iter().enumerate() {
            let edges = by_pose.get(&key).map(Vec::as_slice).unwrap_or(&[]);
            let value = chain_from(edges, key, prev, |k| backend.pose(k))
                .or_else(|| graph.vertices.get(&key).copied())
                .or_else(|| prev.and_then(|p| backend.pose(p)))
                .unwrap_or_else(Isometry3::identity);
            backend.insert(Var::Pose(key), Value::Pose(value))?;
            if index == 0 {
                if let Some(prior) = graph.prior() {
                    backend.add(prior)?;
                    added += 1;
                }
            }
            for e in edges {
                backend.add(e.factor())?;
                added += 1;
            }
            let t = Instant::now();
            backend.update(Scope::Incremental)?;
            updates.push(UpdateTiming {
                index,
                key,
                factors: added,
                seconds: t.elapsed().as_secs_f64(),
            });
            prev = Some(key);
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let estimate: BTreeMap<u64, Isometry3<f64>> = keys
        .iter()
        .map(|&k| {
            backend
                .pose(k)
                .map(|p| (k, p))
                .ok_or_else(|| PoseGraphError::Graph(format!("backend lost pose {k}")))
        })
        .collect::<Result<_, _>>()?;
    Ok(ReplayReport {
        poses: keys.len(),
        factors: factors.len(),
        initial_error: graph_error(&factors, |k| initial.get(&k).copied())?,
        final_error: graph_error(&factors, |k| estimate.get(&k).copied())?,
        seconds,
        max_update_s: updates.iter().map(|u| u.seconds).fold(0.0, f64::max),
        updates,
        estimate,
    })
}
