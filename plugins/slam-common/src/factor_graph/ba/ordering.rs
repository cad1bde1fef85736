//! Which observations, poses and points a bundle adjustment takes, and the order of the
//! poses in its reduced camera system: reverse Cuthill–McKee over their covisibility.

use super::*;

/// Which observations, poses and points take part, and the layout of the reduced system.
#[derive(Debug)]
pub(super) struct Structure {
    /// The usable observations (active, point in front of its camera at the start), grouped
    /// by point slot, in observation order within a point.
    pub(super) obs: Vec<usize>,
    /// `obs[point_start[s]..point_start[s + 1]]` observe the point of slot `s`.
    pub(super) point_start: Vec<usize>,
    /// The problem's index of the point of each slot.
    pub(super) point_index: Vec<usize>,
    /// The problem's index of the pose of each rank (block row of the reduced system).
    pub(super) pose_index: Vec<usize>,
    /// The rank of the pose of each usable observation (aligned with `obs`), None if fixed.
    pub(super) obs_rank: Vec<Option<usize>>,
    /// The first block column of each block row of the reduced system's envelope.
    pub(super) first: Vec<usize>,
}

impl Structure {
    pub(super) fn new(problem: &Problem) -> Self {
        let mut obs: Vec<usize> = problem
            .observations
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                let pose = &problem.poses[o.pose].camera_from_world;
                let p = pose.transform_point(&problem.points[o.point].into());
                o.active && problem.camera.project(&p.coords).is_some()
            })
            .map(|(i, _)| i)
            .collect();
        // Stable: observation order within a point.
        obs.sort_by_key(|&o| problem.observations[o].point);

        let mut point_start = Vec::new();
        let mut point_index = Vec::new();
        for (k, &o) in obs.iter().enumerate() {
            let point = problem.observations[o].point;
            if point_index.last() != Some(&point) {
                point_start.push(k);
                point_index.push(point);
            }
        }
        point_start.push(obs.len());

        // Non-fixed observed poses get slots in index order, then ranks by reverse
        // Cuthill–McKee over covisibility.
        let mut observed = vec![false; problem.poses.len()];
        for &o in &obs {
            observed[problem.observations[o].pose] = true;
        }
        let mut slot_of_pose = vec![None; problem.poses.len()];
        let mut slot_pose = Vec::new();
        for (pose, var) in problem.poses.iter().enumerate() {
            if observed[pose] && !var.fixed {
                slot_of_pose[pose] = Some(slot_pose.len());
                slot_pose.push(pose);
            }
        }
        let slots_of_point = |s: usize, of: &dyn Fn(usize) -> Option<usize>| {
            let mut v: Vec<usize> = obs[point_start[s]..point_start[s + 1]]
                .iter()
                .filter_map(|&o| of(problem.observations[o].pose))
                .collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        let mut adjacency = vec![Vec::new(); slot_pose.len()];
        for s in 0..point_index.len() {
            let slots = slots_of_point(s, &|pose| slot_of_pose[pose]);
            for &a in &slots {
                adjacency[a].extend(slots.iter().copied().filter(|&b| b != a));
            }
        }
        for list in &mut adjacency {
            list.sort_unstable();
            list.dedup();
        }
        let order = reverse_cuthill_mckee(&adjacency);
        let mut rank_of_slot = vec![0; order.len()];
        for (rank, &slot) in order.iter().enumerate() {
            rank_of_slot[slot] = rank;
        }
        let pose_index: Vec<usize> = order.iter().map(|&slot| slot_pose[slot]).collect();
        let rank_of_pose = |pose: usize| slot_of_pose[pose].map(|slot| rank_of_slot[slot]);
        let obs_rank = obs
            .iter()
            .map(|&o| rank_of_pose(problem.observations[o].pose))
            .collect();

        let mut first: Vec<usize> = (0..pose_index.len()).collect();
        for s in 0..point_index.len() {
            let ranks = slots_of_point(s, &rank_of_pose);
            if let Some(&lowest) = ranks.first() {
                for &r in &ranks {
                    first[r] = first[r].min(lowest);
                }
            }
        }

        Self {
            obs,
            point_start,
            point_index,
            pose_index,
            obs_rank,
            first,
        }
    }

    pub(super) fn points(&self) -> usize {
        self.point_index.len()
    }

    pub(super) fn point_obs(&self, s: usize) -> std::ops::Range<usize> {
        self.point_start[s]..self.point_start[s + 1]
    }

    /// `Σ ρ(χ²)` over the usable observations; infinite if one of them is behind its camera.
    pub(super) fn cost(
        &self,
        problem: &Problem,
        poses: &[Isometry3<f64>],
        points: &[Vector3<f64>],
        robust: bool,
    ) -> f64 {
        let mut total = 0.0;
        for &o in &self.obs {
            let obs = &problem.observations[o];
            let p = poses[obs.pose].transform_point(&points[obs.point].into());
            let chi2 = observation_chi2(
                &problem.camera,
                &p.coords,
                &obs.pixel,
                obs.u_right,
                obs.inv_sigma2,
            );
            if chi2 == f64::INFINITY {
                return f64::INFINITY;
            }
            total += kernel(chi2, obs.huber_delta2(), robust).0;
        }
        total
    }
}

/// Reverse Cuthill–McKee: an ordering (position → node) of an undirected graph, given as
/// sorted adjacency lists, that keeps neighbours close. Each component is started from a
/// node of least degree, neighbours are queued by increasing degree; ties by index.
pub(super) fn reverse_cuthill_mckee(adjacency: &[Vec<usize>]) -> Vec<usize> {
    let n = adjacency.len();
    let mut visited = vec![false; n];
    let mut order = Vec::with_capacity(n);
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&v| (adjacency[v].len(), v));
    let mut next = Vec::new();
    for &start in &by_degree {
        if visited[start] {
            continue;
        }
        visited[start] = true;
        order.push(start);
        let mut head = order.len() - 1;
        while head < order.len() {
            let v = order[head];
            head += 1;
            next.clear();
            next.extend(adjacency[v].iter().copied().filter(|&u| !visited[u]));
            next.sort_by_key(|&u| (adjacency[u].len(), u));
            for &u in &next {
                visited[u] = true;
                order.push(u);
            }
        }
    }
    order.reverse();
    order
}
