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

mod envelope;
mod lm;
mod motion_only;
mod ordering;
mod schur;
#[cfg(test)]
mod tests;

use envelope::Envelope;
pub use lm::bundle_adjust;
pub use motion_only::{PoseObservation, PoseOnly, optimize_pose};
use ordering::Structure;
use schur::{Normal, SchurSolver};

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
