//! Bundle adjustment as ORB-SLAM2 does it (Mur-Artal and Tardós, "ORB-SLAM2: an Open-Source
//! SLAM System for Monocular, Stereo and RGB-D Cameras", IEEE T-RO 33(5), 2017, §"Bundle
//! Adjustment"): Levenberg–Marquardt over keyframe poses and map points with monocular
//! `(u, v)` and stereo `(u, v, u_R)` reprojection residuals, the information `σ⁻² I` of the
//! keypoint's scale level, and a Huber kernel whose threshold is the 95 % χ² quantile
//! (`δ² = 5.991` for two, `7.815` for three degrees of freedom); and the motion-only BA
//! (`PoseOptimization`) that tracks a frame against fixed map points, classifying
//! observations as inliers and outliers between rounds.
//!
//! Each LM step eliminates the points with the Schur complement (Triggs, McLauchlan, Hartley
//! and Fitzgibbon, "Bundle Adjustment — A Modern Synthesis", Vision Algorithms: Theory and
//! Practice, 2000, §6.1): with the normal equations `[B W; Wᵀ C] [δc; δp] = [g_c; g_p]`,
//! where `C` is block-diagonal (one 3×3 block per point), the reduced camera system
//! `(B − W C⁻¹ Wᵀ) δc = g_c − W C⁻¹ g_p` is solved and the points are recovered by
//! back-substitution `δp = C⁻¹ (g_p − Wᵀ δc)`. The reduced system is assembled in 6×6 blocks
//! into an envelope (skyline) matrix, whose Cholesky factor has no fill outside the envelope
//! (Triggs et al. §6.3; George and Liu, "Computer Solution of Large Sparse Positive Definite
//! Systems", 1981, ch. 4), under a reverse Cuthill–McKee ordering of the poses by their
//! covisibility: a trajectory's banded reduced system costs linear time in the number of
//! poses, a fully covisible one falls back to a dense `n³/3`.
//!
//! Conventions (those of g2o's `SE3Expmap` and `EdgeSE3ProjectXYZ`, which ORB-SLAM2 uses):
//!
//! - a pose is `camera_from_world` (`T_cw`), and a point `X` is seen at `p = R X + t` in the
//!   camera frame, x right, y down, z forward;
//! - the residual is measured minus projected: `(u, v) − π(p)` for a monocular observation,
//!   `(u, v, u_R) − (π(p), u − bf / z)` for a stereo one (or RGB-D, whose depth gives a
//!   virtual right coordinate), with `χ² = σ⁻² ‖r‖²`;
//! - a pose is updated on the left, `T ← exp(δ) · T`, with `δ = (ω, υ)`: rotation first,
//!   then translation, and `exp(δ) = (Exp(ω), V(ω) υ)` the exponential of SE(3); so
//!   `∂p/∂δ = [−[p]ₓ  I]` at `δ = 0`. Points are updated additively, `X ← X + δX`;
//! - the cost is `F = Σ ρ(χ²)` over the active observations, with the Huber function
//!   `ρ(s) = s` for `s ≤ δ²` and `2 δ √s − δ²` above, or `ρ(s) = s` without the kernel. The
//!   kernel enters the normal equations by iteratively reweighted least squares: each
//!   observation's information is scaled by `ρ'(χ²)` at the linearisation point (as g2o).
//!
//! Levenberg–Marquardt follows g2o's `OptimizationAlgorithmLevenberg`, which uses Nielsen's
//! damping update (Madsen, Nielsen and Tingleff, "Methods for Non-Linear Least Squares
//! Problems", 2004, §3.2): `λ` is added to the diagonal of the whole normal matrix, starts at
//! `initial_lambda · max diag(H)`, and after a step with gain ratio `ϱ = ΔF / (δᵀ(λ δ + g))`
//! becomes `λ · clamp(1 − (2ϱ − 1)³, 1/3, 2/3)` if `ϱ > 0` (the step is kept; g2o's bounds),
//! else `λ · ν` with `ν` doubling (the step is undone and retried, at most ten times per
//! iteration; ten failures end the optimisation). An accepted step that lowers the cost by
//! less than a `1e-9` fraction ends it too.
//!
//! Everything is sequential and in index order, so results are bit-for-bit reproducible.

use nalgebra::{
    Cholesky, Isometry3, Matrix3, Matrix3x6, Matrix6, Translation3, UnitQuaternion, Vector2,
    Vector3, Vector6,
};

/// The 95 % quantile of χ² with two degrees of freedom: the outlier threshold (and Huber
/// `δ²`) of a monocular observation.
pub const CHI2_MONO: f64 = 5.991;
/// The 95 % quantile of χ² with three degrees of freedom: the outlier threshold (and Huber
/// `δ²`) of a stereo observation.
pub const CHI2_STEREO: f64 = 7.815;

/// Retries with more damping before an iteration gives up (g2o's default).
const MAX_TRIALS: usize = 10;
/// An accepted step that lowers the cost by less than this fraction ends the optimisation.
const RELATIVE_DECREASE: f64 = 1e-9;

/// Pinhole intrinsics plus `bf` = baseline × fx for the virtual right coordinate of RGB-D /
/// stereo (`u_R = u − bf / z`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoCamera {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub bf: f64,
}

impl StereoCamera {
    /// `(u, v, u_R)` of a point in the camera frame (z forward); None if `z <= 0`.
    pub fn project(&self, p_cam: &Vector3<f64>) -> Option<Vector3<f64>> {
        if p_cam.z.is_nan() || p_cam.z <= 0.0 {
            return None;
        }
        let inv_z = 1.0 / p_cam.z;
        let u = self.fx * p_cam.x * inv_z + self.cx;
        let v = self.fy * p_cam.y * inv_z + self.cy;
        Some(Vector3::new(u, v, u - self.bf * inv_z))
    }

    /// `∂r/∂p` of the residual `r = measured − projected` at the camera-frame point `p`
    /// (`z > 0`); the third row is zero for a monocular observation.
    fn residual_jacobian(&self, p: &Vector3<f64>, stereo: bool) -> Matrix3<f64> {
        let inv_z = 1.0 / p.z;
        let inv_z2 = inv_z * inv_z;
        let du = [self.fx * inv_z, 0.0, -self.fx * p.x * inv_z2];
        let dv = [0.0, self.fy * inv_z, -self.fy * p.y * inv_z2];
        let dur = if stereo {
            [du[0], 0.0, du[2] + self.bf * inv_z2]
        } else {
            [0.0; 3]
        };
        -Matrix3::new(
            du[0], du[1], du[2], dv[0], dv[1], dv[2], dur[0], dur[1], dur[2],
        )
    }

    /// `measured − projected` of the camera-frame point `p`, with a zero third component
    /// for a monocular observation; None if `p` is not in front of the camera.
    fn residual(
        &self,
        p: &Vector3<f64>,
        pixel: &Vector2<f64>,
        u_right: Option<f64>,
    ) -> Option<Vector3<f64>> {
        let proj = self.project(p)?;
        Some(Vector3::new(
            pixel.x - proj.x,
            pixel.y - proj.y,
            u_right.map_or(0.0, |ur| ur - proj.z),
        ))
    }
}

/// One observation of a map point by a keyframe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index into [`Problem::poses`].
    pub pose: usize,
    /// Index into [`Problem::points`].
    pub point: usize,
    /// `(u, v)` measured.
    pub pixel: Vector2<f64>,
    /// Some: stereo (3-D residual, χ²(3) thresholds); None: monocular (2-D).
    pub u_right: Option<f64>,
    /// The information is `inv_sigma2 · I` (ORB-SLAM2: `1/σ²` of the keypoint's octave).
    pub inv_sigma2: f64,
    /// Inactive observations are ignored (outliers of an earlier round).
    pub active: bool,
}

impl Observation {
    fn huber_delta2(&self) -> f64 {
        huber_delta2(self.u_right.is_some())
    }
}

/// A keyframe pose and whether it is held fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseVar {
    pub camera_from_world: Isometry3<f64>,
    pub fixed: bool,
}

/// A bundle-adjustment problem: every pose, point and observation of it. Indices out of
/// range in an observation make [`bundle_adjust`] and [`chi2`] panic.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    pub camera: StereoCamera,
    pub poses: Vec<PoseVar>,
    pub points: Vec<Vector3<f64>>,
    pub observations: Vec<Observation>,
}

/// How [`bundle_adjust`] runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// At most this many LM iterations (linearisations).
    pub iterations: usize,
    /// Huber kernel with `δ = √5.991` (monocular) or `√7.815` (stereo).
    pub robust: bool,
    /// The first damping is `initial_lambda · max diag(H)` (g2o's `tau`); should be positive
    /// (with zero, a rejected step cannot be damped and ends the optimisation).
    pub initial_lambda: f64,
}

impl Default for Options {
    /// Ten iterations with the Huber kernel (ORB-SLAM2's local BA runs five with it, then ten
    /// without it on the inliers), `initial_lambda = 1e-5` (g2o's default `tau`).
    fn default() -> Self {
        Self {
            iterations: 10,
            robust: true,
            initial_lambda: 1e-5,
        }
    }
}

/// What [`bundle_adjust`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Report {
    /// LM iterations run (linearisations; rejected and retried steps are not counted).
    pub iterations: usize,
    /// `Σ ρ(χ²)` (Huber `ρ` if robust, else plain χ²) over the active observations in front
    /// of their camera, before and after.
    pub initial_cost: f64,
    pub final_cost: f64,
}

/// χ² (squared whitened residual, no robust kernel) of one observation at the problem's
/// current estimate; `f64::INFINITY` if the point is behind the camera.
pub fn chi2(problem: &Problem, obs: &Observation) -> f64 {
    let pose = &problem.poses[obs.pose].camera_from_world;
    let p = pose
        .transform_point(&problem.points[obs.point].into())
        .coords;
    observation_chi2(&problem.camera, &p, &obs.pixel, obs.u_right, obs.inv_sigma2)
}

fn observation_chi2(
    camera: &StereoCamera,
    p_cam: &Vector3<f64>,
    pixel: &Vector2<f64>,
    u_right: Option<f64>,
    inv_sigma2: f64,
) -> f64 {
    camera
        .residual(p_cam, pixel, u_right)
        .map_or(f64::INFINITY, |r| inv_sigma2 * r.norm_squared())
}

fn huber_delta2(stereo: bool) -> f64 {
    if stereo { CHI2_STEREO } else { CHI2_MONO }
}

/// `(ρ(χ²), ρ'(χ²))` of the Huber kernel with threshold `δ²`, or of the identity if `!robust`.
fn kernel(chi2: f64, delta2: f64, robust: bool) -> (f64, f64) {
    if !robust || chi2 <= delta2 {
        (chi2, 1.0)
    } else {
        let e = chi2.sqrt();
        let delta = delta2.sqrt();
        (2.0 * delta * e - delta2, delta / e)
    }
}

/// The exponential of SE(3) for `δ = (ω, υ)`: `(Exp(ω), V(ω) υ)` with
/// `V = I + (1 − cos θ)/θ² [ω]ₓ + (θ − sin θ)/θ³ [ω]ₓ²`.
fn exp_se3(delta: &Vector6<f64>) -> Isometry3<f64> {
    let omega = Vector3::new(delta[0], delta[1], delta[2]);
    let upsilon = Vector3::new(delta[3], delta[4], delta[5]);
    let theta2 = omega.norm_squared();
    let (a, b) = if theta2 < 1e-6 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = theta2.sqrt();
        (
            (1.0 - theta.cos()) / theta2,
            (theta - theta.sin()) / (theta2 * theta),
        )
    };
    let w = omega.cross_matrix();
    let v = Matrix3::identity() + w * a + w * w * b;
    Isometry3::from_parts(
        Translation3::from(v * upsilon),
        UnitQuaternion::from_scaled_axis(omega),
    )
}

/// `exp(δ) · pose`, renormalised.
fn update_pose(delta: &Vector6<f64>, pose: &Isometry3<f64>) -> Isometry3<f64> {
    let mut out = exp_se3(delta) * pose;
    out.rotation.renormalize();
    out
}

/// The residual's Jacobian with respect to the pose update `δ = (ω, υ)`, given `∂r/∂p` and
/// the camera-frame point `p`: `∂r/∂p · [−[p]ₓ  I]`.
fn pose_jacobian(j_p: &Matrix3<f64>, p: &Vector3<f64>) -> Matrix3x6<f64> {
    let mut j = Matrix3x6::zeros();
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-j_p * p.cross_matrix()));
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(j_p);
    j
}

/// Gain-ratio damping update of Nielsen, as g2o: returns whether the step is kept.
#[derive(Debug, Clone, Copy)]
struct Damping {
    lambda: f64,
    nu: f64,
}

impl Damping {
    fn new(lambda: f64) -> Self {
        Self { lambda, nu: 2.0 }
    }

    /// After a step of gain ratio `rho`: keeps it (`λ` shrinks by `1 − (2ϱ − 1)³` clamped to
    /// `[1/3, 2/3]`) if `rho > 0`, else rejects it (`λ ← λ ν`, `ν ← 2 ν`).
    fn update(&mut self, rho: f64) -> bool {
        if rho > 0.0 && rho.is_finite() {
            let alpha = 1.0 - (2.0 * rho - 1.0).powi(3);
            self.lambda *= alpha.clamp(1.0 / 3.0, 2.0 / 3.0);
            self.nu = 2.0;
            true
        } else {
            self.reject();
            false
        }
    }

    fn reject(&mut self) {
        self.lambda *= self.nu;
        self.nu *= 2.0;
    }
}

/// Residual, χ² and `∂r/∂p` of one observation whose point is at `p` in the camera frame.
#[derive(Debug, Clone, Copy)]
struct Linearised {
    r: Vector3<f64>,
    chi2: f64,
    j_p: Matrix3<f64>,
}

fn linearise_one(
    camera: &StereoCamera,
    p: &Vector3<f64>,
    pixel: &Vector2<f64>,
    u_right: Option<f64>,
    inv_sigma2: f64,
) -> Option<Linearised> {
    let r = camera.residual(p, pixel, u_right)?;
    Some(Linearised {
        r,
        chi2: inv_sigma2 * r.norm_squared(),
        j_p: camera.residual_jacobian(p, u_right.is_some()),
    })
}

// ------------------------------------------------------------------------------------------
// Full bundle adjustment.

/// Which observations, poses and points take part, and the layout of the reduced system.
#[derive(Debug)]
struct Structure {
    /// The usable observations (active, point in front of its camera at the start), grouped
    /// by point slot, in observation order within a point.
    obs: Vec<usize>,
    /// `obs[point_start[s]..point_start[s + 1]]` observe the point of slot `s`.
    point_start: Vec<usize>,
    /// The problem's index of the point of each slot.
    point_index: Vec<usize>,
    /// The problem's index of the pose of each rank (block row of the reduced system).
    pose_index: Vec<usize>,
    /// The rank of the pose of each usable observation (aligned with `obs`), None if fixed.
    obs_rank: Vec<Option<usize>>,
    /// The first block column of each block row of the reduced system's envelope.
    first: Vec<usize>,
}

impl Structure {
    fn new(problem: &Problem) -> Self {
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

    fn points(&self) -> usize {
        self.point_index.len()
    }

    fn point_obs(&self, s: usize) -> std::ops::Range<usize> {
        self.point_start[s]..self.point_start[s + 1]
    }

    /// `Σ ρ(χ²)` over the usable observations; infinite if one of them is behind its camera.
    fn cost(
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
fn reverse_cuthill_mckee(adjacency: &[Vec<usize>]) -> Vec<usize> {
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

/// The normal equations `H δ = g` (`H = Jᵀ W J`, `g = −Jᵀ W r`) in Schur form.
#[derive(Debug)]
struct Normal {
    /// Per pose rank: the diagonal block `B` and `g_c`.
    pose_h: Vec<Matrix6<f64>>,
    pose_g: Vec<Vector6<f64>>,
    /// Per point slot: `C` and `g_p`.
    point_h: Vec<Matrix3<f64>>,
    point_g: Vec<Vector3<f64>>,
    /// Per usable observation: `Wᵀ = w J_pᵀ J_c` (unused for a fixed pose).
    wt: Vec<Matrix3x6<f64>>,
}

impl Normal {
    fn new(structure: &Structure) -> Self {
        Self {
            pose_h: vec![Matrix6::zeros(); structure.pose_index.len()],
            pose_g: vec![Vector6::zeros(); structure.pose_index.len()],
            point_h: vec![Matrix3::zeros(); structure.points()],
            point_g: vec![Vector3::zeros(); structure.points()],
            wt: vec![Matrix3x6::zeros(); structure.obs.len()],
        }
    }

    fn linearise(
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

    fn max_diagonal(&self) -> f64 {
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
struct Step {
    poses: Vec<Vector6<f64>>,
    points: Vec<Vector3<f64>>,
}

impl Step {
    /// The decrease of the cost that the linear model predicts, `δᵀ(λ δ + g)`.
    fn predicted_decrease(&self, normal: &Normal, lambda: f64) -> f64 {
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
struct SchurSolver {
    reduced: Envelope,
    c_inv: Vec<Matrix3<f64>>,
    /// `C⁻¹ Wᵀ` of the observations of one point.
    yt: Vec<Matrix3x6<f64>>,
}

impl SchurSolver {
    fn new(structure: &Structure) -> Self {
        Self {
            reduced: Envelope::new(structure.first.clone()),
            c_inv: vec![Matrix3::zeros(); structure.points()],
            yt: Vec::new(),
        }
    }

    /// Solves `(H + λ I) δ = g`; None if a block is not positive definite or the result is
    /// not finite.
    fn solve(&mut self, structure: &Structure, normal: &Normal, lambda: f64) -> Option<Step> {
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

/// A symmetric block matrix (6×6 blocks) stored by its upper triangle within an envelope:
/// block column `i` holds the blocks of rows `first[i]..=i` contiguously (slot `(i, j)` is
/// block `(j, i)`, `j ≤ i`). [`Envelope::factor`] overwrites it with the upper Cholesky
/// factor `R` (`S = Rᵀ R`), which has no fill outside the envelope.
#[derive(Debug, Clone)]
struct Envelope {
    first: Vec<usize>,
    start: Vec<usize>,
    blocks: Vec<Matrix6<f64>>,
    /// `R_ii⁻¹` after factorisation.
    inv_diag: Vec<Matrix6<f64>>,
}

impl Envelope {
    fn new(first: Vec<usize>) -> Self {
        let mut start = Vec::with_capacity(first.len() + 1);
        start.push(0);
        for (i, &f) in first.iter().enumerate() {
            debug_assert!(f <= i);
            start.push(start[i] + i + 1 - f);
        }
        let total = start[first.len()];
        Self {
            inv_diag: vec![Matrix6::zeros(); first.len()],
            blocks: vec![Matrix6::zeros(); total],
            first,
            start,
        }
    }

    fn index(&self, i: usize, j: usize) -> usize {
        debug_assert!(
            self.first[i] <= j && j <= i,
            "({i}, {j}) outside the envelope"
        );
        self.start[i] + j - self.first[i]
    }

    /// Block `(j, i)`, `j ≤ i`, of the upper triangle.
    fn block_mut(&mut self, i: usize, j: usize) -> &mut Matrix6<f64> {
        let k = self.index(i, j);
        &mut self.blocks[k]
    }

    fn clear(&mut self) {
        self.blocks.fill(Matrix6::zeros());
    }

    /// Cholesky factorisation in place, column by column (`R_ji = R_jj⁻ᵀ (S_ji − Σ_{k<j}
    /// R_kjᵀ R_ki)`); false if the matrix is not positive definite.
    fn factor(&mut self) -> bool {
        for i in 0..self.first.len() {
            let fi = self.first[i];
            let col_i = self.start[i];
            for j in fi..i {
                let fj = self.first[j];
                let col_j = self.start[j];
                let mut acc = self.blocks[col_i + j - fi];
                for k in fi.max(fj)..j {
                    acc -= self.blocks[col_j + k - fj].tr_mul(&self.blocks[col_i + k - fi]);
                }
                self.blocks[col_i + j - fi] = self.inv_diag[j].tr_mul(&acc);
            }
            let mut acc = self.blocks[col_i + i - fi];
            for r in &self.blocks[col_i..col_i + i - fi] {
                acc -= r.tr_mul(r);
            }
            let Some(chol) = Cholesky::new(acc) else {
                return false;
            };
            let l = chol.l();
            let Some(l_inv) = l.solve_lower_triangular(&Matrix6::identity()) else {
                return false;
            };
            self.blocks[col_i + i - fi] = l.transpose();
            self.inv_diag[i] = l_inv.transpose();
        }
        true
    }

    /// Solves `Rᵀ R x = b` in place after [`Envelope::factor`].
    fn solve(&self, b: &mut [Vector6<f64>]) {
        let n = self.first.len();
        for i in 0..n {
            let fi = self.first[i];
            let mut acc = b[i];
            for (r, y) in self.blocks[self.start[i]..self.start[i] + i - fi]
                .iter()
                .zip(&b[fi..i])
            {
                acc -= r.tr_mul(y);
            }
            b[i] = self.inv_diag[i].tr_mul(&acc);
        }
        for i in (0..n).rev() {
            let fi = self.first[i];
            let x = self.inv_diag[i] * b[i];
            b[i] = x;
            for (r, y) in self.blocks[self.start[i]..self.start[i] + i - fi]
                .iter()
                .zip(&mut b[fi..i])
            {
                *y -= r * x;
            }
        }
    }
}

/// Optimises the non-fixed poses and all points in place by Levenberg–Marquardt over the
/// observations that are active and in front of their camera at the start (the others are
/// ignored throughout; a step that would move a point behind a camera observing it is
/// rejected). Points without such an observation, and non-fixed poses that observe none,
/// are left as they are; points seen only from fixed poses are optimised.
pub fn bundle_adjust(problem: &mut Problem, options: &Options) -> Report {
    let structure = Structure::new(problem);
    let mut poses: Vec<Isometry3<f64>> =
        problem.poses.iter().map(|p| p.camera_from_world).collect();
    let mut points = problem.points.clone();
    let mut cost = structure.cost(problem, &poses, &points, options.robust);
    let initial_cost = cost;
    let mut iterations = 0;
    if structure.points() > 0 {
        let mut normal = Normal::new(&structure);
        let mut solver = SchurSolver::new(&structure);
        let mut damping: Option<Damping> = None;
        'iterations: while iterations < options.iterations {
            iterations += 1;
            normal.linearise(problem, &structure, &poses, &points, options.robust);
            let damping = damping.get_or_insert_with(|| {
                Damping::new(options.initial_lambda * normal.max_diagonal())
            });
            let mut accepted = false;
            for _ in 0..MAX_TRIALS {
                let lambda = damping.lambda;
                let Some(step) = solver.solve(&structure, &normal, lambda) else {
                    damping.reject();
                    continue;
                };
                let predicted = step.predicted_decrease(&normal, lambda);
                if predicted.is_nan() || predicted <= 0.0 {
                    // A zero step: the gradient vanishes.
                    break 'iterations;
                }
                let mut trial_poses = poses.clone();
                for (d, &pose) in step.poses.iter().zip(&structure.pose_index) {
                    trial_poses[pose] = update_pose(d, &poses[pose]);
                }
                let mut trial_points = points.clone();
                for (d, &point) in step.points.iter().zip(&structure.point_index) {
                    trial_points[point] += d;
                }
                let trial_cost =
                    structure.cost(problem, &trial_poses, &trial_points, options.robust);
                if damping.update((cost - trial_cost) / predicted) {
                    let decrease = cost - trial_cost;
                    poses = trial_poses;
                    points = trial_points;
                    cost = trial_cost;
                    accepted = true;
                    if decrease <= RELATIVE_DECREASE * (cost + decrease) {
                        break 'iterations;
                    }
                    break;
                }
            }
            if !accepted {
                break;
            }
        }
        for &pose in &structure.pose_index {
            problem.poses[pose].camera_from_world = poses[pose];
        }
        for &point in &structure.point_index {
            problem.points[point] = points[point];
        }
    }
    Report {
        iterations,
        initial_cost,
        final_cost: cost,
    }
}

// ------------------------------------------------------------------------------------------
// Motion-only bundle adjustment.

/// An observation of a fixed map point by the frame whose pose [`optimize_pose`] estimates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseObservation {
    /// The map point in the world frame.
    pub world: Vector3<f64>,
    /// `(u, v)` measured.
    pub pixel: Vector2<f64>,
    /// Some: stereo, None: monocular.
    pub u_right: Option<f64>,
    /// The information is `inv_sigma2 · I`.
    pub inv_sigma2: f64,
}

impl PoseObservation {
    fn chi2(&self, camera: &StereoCamera, pose: &Isometry3<f64>) -> f64 {
        let p = pose.transform_point(&self.world.into()).coords;
        observation_chi2(camera, &p, &self.pixel, self.u_right, self.inv_sigma2)
    }
}

/// The result of [`optimize_pose`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseOnly {
    pub camera_from_world: Isometry3<f64>,
    /// Per observation: whether it passed the χ² test after the last round.
    pub inliers: Vec<bool>,
    pub inlier_count: usize,
}

/// Rounds of motion-only optimisation, and LM iterations per round (ORB-SLAM2's).
const POSE_ROUNDS: usize = 4;
const POSE_ITERATIONS: usize = 10;
/// Rounds with the Huber kernel.
const POSE_ROBUST_ROUNDS: usize = 2;

/// Pose-only optimisation (ORB-SLAM2's `PoseOptimization`): the points are fixed; four rounds
/// of ten LM iterations, each round starting again from `initial` with the observations
/// that passed the χ² test of the round before (all in the first round). After each round
/// every observation, including those left out of it, is tested anew at the round's pose:
/// χ² above [`CHI2_MONO`] / [`CHI2_STEREO`] (or the point behind the camera) makes it an
/// outlier for the next round, at or below readmits it. The Huber kernel is used in the first
/// two rounds only. As ORB-SLAM2, with fewer than ten observations only one round is run,
/// and with fewer than three the pose is not optimised (`initial` is returned with no
/// inliers).
pub fn optimize_pose(
    camera: &StereoCamera,
    initial: &Isometry3<f64>,
    observations: &[PoseObservation],
) -> PoseOnly {
    let n = observations.len();
    if n < 3 {
        return PoseOnly {
            camera_from_world: *initial,
            inliers: vec![false; n],
            inlier_count: 0,
        };
    }
    let mut inliers = vec![true; n];
    let mut pose = *initial;
    for round in 0..POSE_ROUNDS {
        pose = pose_lm(
            camera,
            initial,
            observations,
            &inliers,
            round < POSE_ROBUST_ROUNDS,
            POSE_ITERATIONS,
        );
        for (inlier, obs) in inliers.iter_mut().zip(observations) {
            *inlier = obs.chi2(camera, &pose) <= huber_delta2(obs.u_right.is_some());
        }
        if n < 10 {
            break;
        }
    }
    let inlier_count = inliers.iter().filter(|&&i| i).count();
    PoseOnly {
        camera_from_world: pose,
        inliers,
        inlier_count,
    }
}

/// Levenberg–Marquardt on one pose from `initial` over the observations selected by `used`
/// that are in front of the camera at `initial`.
fn pose_lm(
    camera: &StereoCamera,
    initial: &Isometry3<f64>,
    observations: &[PoseObservation],
    used: &[bool],
    robust: bool,
    iterations: usize,
) -> Isometry3<f64> {
    let used: Vec<&PoseObservation> = observations
        .iter()
        .zip(used)
        .filter(|&(obs, &u)| u && obs.chi2(camera, initial).is_finite())
        .map(|(obs, _)| obs)
        .collect();
    if used.is_empty() {
        return *initial;
    }
    let cost = |pose: &Isometry3<f64>| {
        let mut total = 0.0;
        for obs in &used {
            let chi2 = obs.chi2(camera, pose);
            if chi2 == f64::INFINITY {
                return f64::INFINITY;
            }
            total += kernel(chi2, huber_delta2(obs.u_right.is_some()), robust).0;
        }
        total
    };
    let mut pose = *initial;
    let mut f = cost(&pose);
    let mut damping: Option<Damping> = None;
    for _ in 0..iterations {
        let mut h = Matrix6::zeros();
        let mut g = Vector6::zeros();
        for obs in &used {
            let p = pose.transform_point(&obs.world.into()).coords;
            let Some(lin) = linearise_one(camera, &p, &obs.pixel, obs.u_right, obs.inv_sigma2)
            else {
                continue;
            };
            let w =
                obs.inv_sigma2 * kernel(lin.chi2, huber_delta2(obs.u_right.is_some()), robust).1;
            let jc = pose_jacobian(&lin.j_p, &p);
            h += w * jc.tr_mul(&jc);
            g -= w * jc.tr_mul(&lin.r);
        }
        let damping = damping.get_or_insert_with(|| {
            Damping::new(Options::default().initial_lambda * h.diagonal().max())
        });
        let mut accepted = false;
        let mut converged = false;
        for _ in 0..MAX_TRIALS {
            let lambda = damping.lambda;
            let Some(chol) = Cholesky::new(h + Matrix6::identity() * lambda) else {
                damping.reject();
                continue;
            };
            let delta = chol.solve(&g);
            let predicted = delta.dot(&(g + lambda * delta));
            if predicted.is_nan() || predicted <= 0.0 {
                converged = true;
                break;
            }
            let trial = update_pose(&delta, &pose);
            let trial_cost = cost(&trial);
            if damping.update((f - trial_cost) / predicted) {
                converged = f - trial_cost <= RELATIVE_DECREASE * f;
                pose = trial;
                f = trial_cost;
                accepted = true;
                break;
            }
        }
        if !accepted || converged {
            break;
        }
    }
    pose
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::*;

    fn camera() -> StereoCamera {
        StereoCamera {
            fx: 520.0,
            fy: 515.0,
            cx: 320.0,
            cy: 240.0,
            bf: 40.0,
        }
    }

    fn pose() -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        )
    }

    fn residual_at(pose: &Isometry3<f64>, x: &Vector3<f64>, stereo: bool) -> Vector3<f64> {
        let p = pose.transform_point(&(*x).into()).coords;
        let u_right = stereo.then_some(300.0);
        camera()
            .residual(&p, &Vector2::new(330.0, 250.0), u_right)
            .expect("in front")
    }

    /// The analytic Jacobians of the residual with respect to the left pose update and the
    /// point agree with central differences, for stereo and monocular observations.
    #[test]
    fn jacobians_match_finite_differences() {
        let x = Vector3::new(0.4, 0.7, 4.0);
        let pose = pose();
        let h = 1e-6;
        for stereo in [true, false] {
            let p = pose.transform_point(&x.into()).coords;
            let j_p = camera().residual_jacobian(&p, stereo);
            let jc = pose_jacobian(&j_p, &p);
            let jx = j_p * pose.rotation.to_rotation_matrix().matrix();
            for i in 0..6 {
                let mut d = Vector6::zeros();
                d[i] = h;
                let plus = residual_at(&update_pose(&d, &pose), &x, stereo);
                let minus = residual_at(&update_pose(&(-d), &pose), &x, stereo);
                let numeric = (plus - minus) / (2.0 * h);
                let analytic = jc.column(i);
                assert!(
                    (numeric - analytic).norm() < 1e-5 * (1.0 + analytic.norm()),
                    "pose column {i} stereo {stereo}: {numeric:?} vs {analytic:?}"
                );
            }
            for i in 0..3 {
                let mut d = Vector3::zeros();
                d[i] = h;
                let numeric = (residual_at(&pose, &(x + d), stereo)
                    - residual_at(&pose, &(x - d), stereo))
                    / (2.0 * h);
                let analytic = jx.column(i);
                assert!(
                    (numeric - analytic).norm() < 1e-5 * (1.0 + analytic.norm()),
                    "point column {i} stereo {stereo}: {numeric:?} vs {analytic:?}"
                );
            }
            if !stereo {
                assert_eq!(jc.row(2).norm(), 0.0);
                assert_eq!(jx.row(2).norm(), 0.0);
            }
        }
    }

    /// `exp` is a one-parameter subgroup (`exp(δ) = exp(δ/2)²`), with rotation `Exp(ω)`, pure
    /// translations mapping to themselves, and continuity across the small-angle branch.
    #[test]
    fn exp_se3_is_the_group_exponential() {
        let delta = Vector6::new(0.3, -0.5, 0.8, 1.0, 2.0, -0.5);
        let full = exp_se3(&delta);
        let half = exp_se3(&(delta / 2.0));
        let twice = half * half;
        assert!((full.translation.vector - twice.translation.vector).norm() < 1e-12);
        assert!(full.rotation.angle_to(&twice.rotation) < 1e-12);
        assert!(
            full.rotation
                .angle_to(&UnitQuaternion::from_scaled_axis(Vector3::new(
                    0.3, -0.5, 0.8
                )))
                < 1e-12
        );
        let t = exp_se3(&Vector6::new(0.0, 0.0, 0.0, 1.0, 2.0, 3.0));
        assert_eq!(t.translation.vector, Vector3::new(1.0, 2.0, 3.0));
        assert_eq!(t.rotation.angle(), 0.0);
        // Either side of θ² = 1e-6.
        let dir = Vector3::new(0.6, 0.0, 0.8);
        let below = exp_se3(&Vector6::new(
            dir.x * 0.999e-3,
            0.0,
            dir.z * 0.999e-3,
            1.0,
            2.0,
            3.0,
        ));
        let above = exp_se3(&Vector6::new(
            dir.x * 1.001e-3,
            0.0,
            dir.z * 1.001e-3,
            1.0,
            2.0,
            3.0,
        ));
        assert!((below.translation.vector - above.translation.vector).norm() < 1e-5);
    }

    /// The envelope Cholesky of a block matrix with a banded pattern plus one far block (a
    /// loop closure) solves the same system as a dense Cholesky.
    #[test]
    fn envelope_cholesky_matches_dense() {
        let n = 7;
        let mut pattern = vec![vec![false; n]; n];
        for (i, row) in pattern.iter_mut().enumerate() {
            row[i] = true;
            row[i.saturating_sub(1)] = true;
        }
        pattern[6][1] = true;
        let first: Vec<usize> = (0..n)
            .map(|i| (0..=i).find(|&j| pattern[i][j]).unwrap_or(i))
            .collect();
        // A deterministic, diagonally dominant symmetric matrix with that pattern.
        let mut dense = DMatrix::<f64>::zeros(6 * n, 6 * n);
        let mut seed = 1u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for i in 0..n {
            for j in 0..=i {
                if !pattern[i][j] {
                    continue;
                }
                for a in 0..6 {
                    for b in 0..6 {
                        let v = next();
                        dense[(6 * j + a, 6 * i + b)] = v;
                        dense[(6 * i + b, 6 * j + a)] = v;
                    }
                }
            }
        }
        for k in 0..6 * n {
            dense[(k, k)] = 20.0 + next();
        }
        let mut env = Envelope::new(first);
        for i in 0..n {
            for j in env.first[i]..=i {
                *env.block_mut(i, j) = dense.fixed_view::<6, 6>(6 * j, 6 * i).into_owned();
            }
        }
        assert!(env.factor());
        let b_dense = DVector::from_fn(6 * n, |k, _| (k as f64 * 0.37).sin());
        let mut b: Vec<Vector6<f64>> = (0..n)
            .map(|i| b_dense.fixed_rows::<6>(6 * i).into_owned())
            .collect();
        env.solve(&mut b);
        let x = dense.cholesky().expect("positive definite").solve(&b_dense);
        for (i, bi) in b.iter().enumerate() {
            assert!((bi - x.fixed_rows::<6>(6 * i)).norm() < 1e-12, "block {i}");
        }
    }

    /// An indefinite matrix is refused.
    #[test]
    fn envelope_cholesky_refuses_indefinite() {
        let mut env = Envelope::new(vec![0, 0]);
        *env.block_mut(0, 0) = Matrix6::identity();
        *env.block_mut(1, 1) = Matrix6::identity();
        *env.block_mut(1, 0) = Matrix6::identity() * 2.0;
        assert!(!env.factor());
    }

    /// RCM turns a shuffled path into a band: neighbours on the path end up adjacent.
    #[test]
    fn rcm_orders_a_shuffled_path() {
        // The path 0-1-2-3-4-5 relabelled.
        let label = [3, 0, 5, 1, 4, 2];
        let mut adjacency = vec![Vec::new(); 6];
        for w in label.windows(2) {
            adjacency[w[0]].push(w[1]);
            adjacency[w[1]].push(w[0]);
        }
        for list in &mut adjacency {
            list.sort_unstable();
        }
        let order = reverse_cuthill_mckee(&adjacency);
        let mut position = [0; 6];
        for (p, &v) in order.iter().enumerate() {
            position[v] = p;
        }
        for w in label.windows(2) {
            assert_eq!(position[w[0]].abs_diff(position[w[1]]), 1, "{order:?}");
        }
    }

    #[test]
    fn huber_kernel_is_continuous_with_matching_slope() {
        let d2 = CHI2_MONO;
        let (below, wb) = kernel(d2 - 1e-9, d2, true);
        let (above, wa) = kernel(d2 + 1e-9, d2, true);
        assert!((below - above).abs() < 1e-8 && (wb - wa).abs() < 1e-8);
        let (rho, w) = kernel(4.0 * d2, d2, true);
        assert!((rho - 3.0 * d2).abs() < 1e-12 && (w - 0.5).abs() < 1e-12);
        assert_eq!(kernel(4.0 * d2, d2, false), (4.0 * d2, 1.0));
    }
}
