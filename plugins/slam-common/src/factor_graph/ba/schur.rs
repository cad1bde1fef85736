//! The normal equations in Schur form and the damped step: the points eliminated by the
//! Schur complement, the reduced camera system solved, the points back-substituted.

use super::*;

/// The normal equations `H δ = g` (`H = Jᵀ W J`, `g = −Jᵀ W r`) in Schur form.
#[derive(Debug)]
pub(super) struct Normal {
    /// Per pose rank: the diagonal block `B` and `g_c`.
    pub(super) pose_h: Vec<Matrix6<f64>>,
    pub(super) pose_g: Vec<Vector6<f64>>,
    /// Per point slot: `C` and `g_p`.
    pub(super) point_h: Vec<Matrix3<f64>>,
    pub(super) point_g: Vec<Vector3<f64>>,
    /// Per usable observation: `Wᵀ = w J_pᵀ J_c` (unused for a fixed pose).
    pub(super) wt: Vec<Matrix3x6<f64>>,
}

impl Normal {
    pub(super) fn new(structure: &Structure) -> Self {
        Self {
            pose_h: vec![Matrix6::zeros(); structure.pose_index.len()],
            pose_g: vec![Vector6::zeros(); structure.pose_index.len()],
            point_h: vec![Matrix3::zeros(); structure.points()],
            point_g: vec![Vector3::zeros(); structure.points()],
            wt: vec![Matrix3x6::zeros(); structure.obs.len()],
        }
    }

    pub(super) fn linearise(
        &mut self,
        problem: &Problem,
        structure: &Structure,
        poses: &[Isometry3<f64>],
        points: &[Vector3<f64>],
        robust: bool,
    ) {
        self.pose_h.fill(Matrix6::zeros());
        self.pose_g.fill(Vector6::zeros());
        let rotations: Vec<Matrix3<f64>> = poses
            .iter()
            .map(|pose| *pose.rotation.to_rotation_matrix().matrix())
            .collect();
        for s in 0..structure.points() {
            let x = points[structure.point_index[s]];
            let mut c = Matrix3::zeros();
            let mut gp = Vector3::zeros();
            for k in structure.point_obs(s) {
                let obs = &problem.observations[structure.obs[k]];
                let p = poses[obs.pose].transform_point(&x.into()).coords;
                // Every usable observation is in front at an accepted estimate.
                let Some(lin) =
                    linearise_one(&problem.camera, &p, &obs.pixel, obs.u_right, obs.inv_sigma2)
                else {
                    self.wt[k] = Matrix3x6::zeros();
                    continue;
                };
                let w = obs.inv_sigma2 * kernel(lin.chi2, obs.huber_delta2(), robust).1;
                let jx = lin.j_p * rotations[obs.pose];
                c += w * jx.tr_mul(&jx);
                gp -= w * jx.tr_mul(&lin.r);
                if let Some(rank) = structure.obs_rank[k] {
                    let jc = pose_jacobian(&lin.j_p, &p);
                    self.pose_h[rank] += w * jc.tr_mul(&jc);
                    self.pose_g[rank] -= w * jc.tr_mul(&lin.r);
                    self.wt[k] = w * jx.tr_mul(&jc);
                }
            }
            self.point_h[s] = c;
            self.point_g[s] = gp;
        }
    }

    pub(super) fn max_diagonal(&self) -> f64 {
        let poses = self
            .pose_h
            .iter()
            .flat_map(|h| (0..6).map(move |i| h[(i, i)]));
        let points = self
            .point_h
            .iter()
            .flat_map(|h| (0..3).map(move |i| h[(i, i)]));
        poses.chain(points).fold(0.0, f64::max)
    }
}

/// A step: one update per pose rank and per point slot.
#[derive(Debug, Clone)]
pub(super) struct Step {
    pub(super) poses: Vec<Vector6<f64>>,
    pub(super) points: Vec<Vector3<f64>>,
}

impl Step {
    /// The decrease of the cost that the linear model predicts, `δᵀ(λ δ + g)`.
    pub(super) fn predicted_decrease(&self, normal: &Normal, lambda: f64) -> f64 {
        let poses = self
            .poses
            .iter()
            .zip(&normal.pose_g)
            .map(|(d, g)| d.dot(&(g + lambda * d)));
        let points = self
            .points
            .iter()
            .zip(&normal.point_g)
            .map(|(d, g)| d.dot(&(g + lambda * d)));
        poses.chain(points).sum()
    }
}

/// The reduced camera system and scratch space for solving damped normal equations.
#[derive(Debug)]
pub(super) struct SchurSolver {
    pub(super) reduced: Envelope,
    pub(super) c_inv: Vec<Matrix3<f64>>,
    /// `C⁻¹ Wᵀ` of the observations of one point.
    pub(super) yt: Vec<Matrix3x6<f64>>,
}

impl SchurSolver {
    pub(super) fn new(structure: &Structure) -> Self {
        Self {
            reduced: Envelope::new(structure.first.clone()),
            c_inv: vec![Matrix3::zeros(); structure.points()],
            yt: Vec::new(),
        }
    }

    /// Solves `(H + λ I) δ = g`; None if a block is not positive definite or the result is
    /// not finite.
    pub(super) fn solve(
        &mut self,
        structure: &Structure,
        normal: &Normal,
        lambda: f64,
    ) -> Option<Step> {
        let reduced = &mut self.reduced;
        reduced.clear();
        for (rank, h) in normal.pose_h.iter().enumerate() {
            *reduced.block_mut(rank, rank) = h + Matrix6::identity() * lambda;
        }
        let mut rhs = normal.pose_g.clone();
        for s in 0..structure.points() {
            let c = normal.point_h[s] + Matrix3::identity() * lambda;
            let c_inv = Cholesky::new(c)?.inverse();
            self.c_inv[s] = c_inv;
            let range = structure.point_obs(s);
            self.yt.clear();
            self.yt
                .extend(normal.wt[range.clone()].iter().map(|wt| c_inv * wt));
            let gp = &normal.point_g[s];
            for (i, k1) in range.clone().enumerate() {
                let Some(r1) = structure.obs_rank[k1] else {
                    continue;
                };
                rhs[r1] -= self.yt[i].tr_mul(gp);
                for (j, k2) in range.clone().enumerate() {
                    let Some(r2) = structure.obs_rank[k2] else {
                        continue;
                    };
                    if r2 <= r1 {
                        // Block (r2, r1) of the upper triangle: −W₂ C⁻¹ W₁ᵀ.
                        *reduced.block_mut(r1, r2) -= self.yt[j].tr_mul(&normal.wt[k1]);
                    }
                }
            }
        }
        if !reduced.factor() {
            return None;
        }
        reduced.solve(&mut rhs);
        let points: Vec<Vector3<f64>> = (0..structure.points())
            .map(|s| {
                let mut b = normal.point_g[s];
                for k in structure.point_obs(s) {
                    if let Some(rank) = structure.obs_rank[k] {
                        b -= normal.wt[k] * rhs[rank];
                    }
                }
                self.c_inv[s] * b
            })
            .collect();
        let finite = rhs.iter().all(|d| d.iter().all(|x| x.is_finite()))
            && points.iter().all(|d| d.iter().all(|x| x.is_finite()));
        finite.then_some(Step { poses: rhs, points })
    }
}
