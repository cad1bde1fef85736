//! Motion-only bundle adjustment (ORB-SLAM2's `PoseOptimization`): one frame's pose
//! against fixed map points, observations classified as inliers and outliers between rounds.

use super::*;

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
    pub(super) fn chi2(&self, camera: &StereoCamera, pose: &Isometry3<f64>) -> f64 {
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
pub(super) const POSE_ROUNDS: usize = 4;
pub(super) const POSE_ITERATIONS: usize = 10;
/// Rounds with the Huber kernel.
pub(super) const POSE_ROBUST_ROUNDS: usize = 2;

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
pub(super) fn pose_lm(
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
