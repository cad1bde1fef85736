//! LIO-SAM's second estimator, the IMU odometry (`imuPreintegration.cpp`, class
//! `IMUPreintegration`; Shan et al. 2020, §III-B and Fig. 1): a small factor graph of the
//! IMU's pose, velocity and bias at every mapped sweep, joined by IMU-preintegration factors
//! (Forster et al. 2017, with the bias random walk between states), each pose held by a
//! loose prior at the pose scan-to-map registration gave. It is what estimates the velocity
//! and the bias from which the next sweep is predicted and deskewed; the mapping graph
//! (`graph.rs`) then keeps no IMU factors, as LIO-SAM's released `mapOptmization.cpp`.
//!
//! As the original:
//! - the first correction (and the first after a reset) anchors the pose (σ 1e-2 rad and
//!   m, `priorPoseNoise`), a zero velocity with σ 1e4 m/s (`priorVelNoise`: unknown) and a
//!   zero bias with σ 1e-3 (`priorBiasNoise`);
//! - later corrections hold the pose with σ 0.05 rad / 0.1 m (`correctionNoise`), or
//!   1 rad / 1 m when registration found a degenerate direction (`correctionNoise2`, from
//!   the `isDegenerate` flag `mapOptmization.cpp` sends in the odometry's covariance), so
//!   that a sweep whose position along a row is only the prediction does not teach the IMU
//!   state that prediction back;
//! - `failureDetection`: a speed above 30 m/s or a bias above 1 (m/s² or rad/s) in norm
//!   resets the estimator, which starts again at the next correction.
//!
//! Unlike the original, a sweep that was not registered at all (too few features) is held
//! by the loose prior too (the original keeps the last sweep's flag), and the graph is not
//! restarted every 100 corrections: the original restarts it with the marginal covariances
//! of the last state as priors, which our backends do not give; incremental updates keep the
//! cost per correction flat on the chain (LIO-SAM does it for speed).

use nalgebra::{Isometry3, Vector3, Vector6};
use slam_common::factor_graph::backend::{
    self, Backend, BackendConfig, BackendError, Factor, ImuBias, ImuNoise, ImuSample, Scope, Value,
    Var,
};

/// `priorPoseNoise`, rad and m.
const PRIOR_POSE_SIGMA: f64 = 1e-2;
/// `priorVelNoise`, m/s.
const PRIOR_VELOCITY_SIGMA: f64 = 1e4;
/// `priorBiasNoise`, m/s² and rad/s.
const PRIOR_BIAS_SIGMA: f64 = 1e-3;
/// `correctionNoise`: rotation (rad), translation (m).
const CORRECTION_SIGMAS: [f64; 2] = [0.05, 0.1];
/// `correctionNoise2`, for a degenerate registration.
const DEGENERATE_SIGMAS: [f64; 2] = [1.0, 1.0];
/// `failureDetection`: speed (m/s) and bias norms (m/s², rad/s) beyond which the estimate
/// is thrown away.
const MAX_SPEED_MPS: f64 = 30.0;
const MAX_BIAS: f64 = 1.0;

/// What a correction gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Correction {
    /// The estimate at the corrected sweep.
    State {
        velocity_mps: Vector3<f64>,
        bias: ImuBias,
    },
    /// The estimate failed its check and was thrown away; the next correction starts
    /// again from the priors.
    Reset,
}

/// The IMU odometry's graph (None before its first correction and after a reset).
#[derive(Debug)]
pub struct ImuOdometry {
    config: BackendConfig,
    noise: ImuNoise,
    graph: Option<Box<dyn Backend>>,
    /// The next key.
    key: u64,
    /// The newest state's time and bias (the preintegration's linearisation point).
    last: Option<(i64, ImuBias)>,
}

impl ImuOdometry {
    pub fn new(config: &BackendConfig, noise: ImuNoise) -> Result<Self, BackendError> {
        // Fails here, not at the first sweep, on a bad backend name.
        backend::from_config(config)?;
        Ok(Self {
            config: config.clone(),
            noise,
            graph: None,
            key: 0,
            last: None,
        })
    }

    /// The time of the newest state, from which the next correction's IMU samples run.
    pub fn last_ns(&self) -> Option<i64> {
        self.last.map(|(t, _)| t)
    }

    /// Corrects the estimate with the registered `world_from_imu` at `t_ns`: `samples` are
    /// the IMU's since [`Self::last_ns`] (ignored at the first correction), `predicted` the
    /// IMU-propagated velocity there (the new state's initial value), `degenerate` whether
    /// registration left a direction to the prediction.
    pub fn correct(
        &mut self,
        t_ns: i64,
        world_from_imu: &Isometry3<f64>,
        predicted_velocity_mps: Vector3<f64>,
        degenerate: bool,
        samples: Vec<ImuSample>,
    ) -> Result<Correction, BackendError> {
        let (graph, last) = match (&mut self.graph, self.last) {
            (Some(graph), Some(last)) if !samples.is_empty() => (graph, last),
            _ => return self.start(t_ns, world_from_imu, predicted_velocity_mps),
        };
        let k = self.key;
        graph.insert(Var::Pose(k), Value::Pose(*world_from_imu))?;
        graph.insert(Var::Velocity(k), Value::Velocity(predicted_velocity_mps))?;
        graph.insert(Var::Bias(k), Value::Bias(last.1))?;
        graph.add(Factor::Imu {
            from: k - 1,
            to: k,
            samples,
            noise: self.noise,
        })?;
        let [rot, trans] = if degenerate {
            DEGENERATE_SIGMAS
        } else {
            CORRECTION_SIGMAS
        };
        graph.add(Factor::PosePrior {
            key: k,
            world_from_body: *world_from_imu,
            sigmas: Vector6::new(rot, rot, rot, trans, trans, trans),
        })?;
        graph.update(Scope::Incremental)?;
        let velocity_mps = match graph.value(Var::Velocity(k)) {
            Some(Value::Velocity(v)) => v,
            _ => predicted_velocity_mps,
        };
        let bias = match graph.value(Var::Bias(k)) {
            Some(Value::Bias(b)) => b,
            _ => last.1,
        };
        self.key += 1;
        self.last = Some((t_ns, bias));
        if !velocity_mps.iter().all(|x| x.is_finite())
            || velocity_mps.norm() > MAX_SPEED_MPS
            || bias.accel_mps2.norm() > MAX_BIAS
            || bias.gyro_rps.norm() > MAX_BIAS
        {
            self.graph = None;
            self.last = None;
            return Ok(Correction::Reset);
        }
        Ok(Correction::State { velocity_mps, bias })
    }

    /// A new graph anchored at `world_from_imu` with a zero bias and an unknown velocity
    /// (a zero mean with σ 1e4 m/s), as the original initialises (and re-initialises after
    /// a failure); `velocity_mps` is only the initial value and what the state reports until
    /// the next correction estimates it.
    fn start(
        &mut self,
        t_ns: i64,
        world_from_imu: &Isometry3<f64>,
        velocity_mps: Vector3<f64>,
    ) -> Result<Correction, BackendError> {
        let mut graph = backend::from_config(&self.config)?;
        let bias = ImuBias::default();
        graph.insert(Var::Pose(0), Value::Pose(*world_from_imu))?;
        graph.insert(Var::Velocity(0), Value::Velocity(velocity_mps))?;
        graph.insert(Var::Bias(0), Value::Bias(bias))?;
        graph.add(Factor::PosePrior {
            key: 0,
            world_from_body: *world_from_imu,
            sigmas: Vector6::repeat(PRIOR_POSE_SIGMA),
        })?;
        graph.add(Factor::VelocityPrior {
            key: 0,
            velocity_mps: Vector3::zeros(),
            sigma_mps: PRIOR_VELOCITY_SIGMA,
        })?;
        graph.add(Factor::BiasPrior {
            key: 0,
            bias,
            sigma_accel: PRIOR_BIAS_SIGMA,
            sigma_gyro: PRIOR_BIAS_SIGMA,
        })?;
        graph.update(Scope::Incremental)?;
        self.graph = Some(graph);
        self.key = 1;
        self.last = Some((t_ns, bias));
        Ok(Correction::State { velocity_mps, bias })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    const SWEEP_NS: i64 = 100_000_000;

    /// A level IMU at rest or at constant velocity: gravity's reaction only, 100 Hz, for
    /// one sweep.
    fn samples() -> Vec<ImuSample> {
        vec![
            ImuSample {
                dt_s: 0.01,
                accel_mps2: Vector3::new(0.0, 0.0, ImuNoise::default().gravity_mps2),
                gyro_rps: Vector3::zeros(),
            };
            10
        ]
    }

    fn at(x: f64) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(x, 0.0, 0.0), Default::default())
    }

    /// Corrects with a robot moving at 1 m/s along x for `n` sweeps; the last velocity.
    fn drive(odometry: &mut ImuOdometry, n: i64) -> Vector3<f64> {
        let mut velocity = Vector3::zeros();
        for k in 0..n {
            let t = k * SWEEP_NS;
            let samples = if k == 0 { Vec::new() } else { samples() };
            match odometry
                .correct(t, &at(t as f64 * 1e-9), velocity, false, samples)
                .expect("correct")
            {
                Correction::State { velocity_mps, .. } => velocity = velocity_mps,
                Correction::Reset => panic!("reset at sweep {k}"),
            }
        }
        velocity
    }

    fn odometry() -> ImuOdometry {
        ImuOdometry::new(
            &crate::config::Config::default().backend,
            ImuNoise::default(),
        )
        .expect("backend")
    }

    #[test]
    fn the_velocity_is_learnt_from_the_registered_poses() {
        let mut odometry = odometry();
        let velocity = drive(&mut odometry, 30);
        assert!(
            (velocity - Vector3::x()).norm() < 0.05,
            "velocity {velocity:?} after 3 s at 1 m/s"
        );
    }

    /// A sweep whose registration jumps 0.5 m ahead: held by the tight correction prior it
    /// pulls the velocity; flagged degenerate (its position only the prediction, as along a
    /// row), it moves it far less.
    #[test]
    fn a_degenerate_registration_teaches_the_velocity_less() {
        let pulled = |degenerate: bool| {
            let mut odometry = odometry();
            let v = drive(&mut odometry, 30);
            let t = 30 * SWEEP_NS;
            match odometry
                .correct(t, &at(t as f64 * 1e-9 + 0.5), v, degenerate, samples())
                .expect("correct")
            {
                Correction::State { velocity_mps, .. } => (velocity_mps - Vector3::x()).norm(),
                Correction::Reset => panic!("reset"),
            }
        };
        let (tight, loose) = (pulled(false), pulled(true));
        assert!(tight > 0.1, "the jump moved the velocity by {tight} m/s");
        assert!(
            loose < tight / 10.0,
            "degenerate: {loose} m/s against {tight} m/s"
        );
    }

    /// LIO-SAM's failure detection: a registration 10 km off makes the velocity absurd; the
    /// estimator says so, forgets its state, and the next correction starts it again.
    #[test]
    fn an_absurd_estimate_resets_and_the_next_correction_starts_again() {
        let mut odometry = odometry();
        let v = drive(&mut odometry, 30);
        let t = 30 * SWEEP_NS;
        let outcome = odometry
            .correct(t, &at(1e4), v, false, samples())
            .expect("correct");
        assert_eq!(outcome, Correction::Reset);
        assert_eq!(odometry.last_ns(), None);
        let next = odometry
            .correct(t + SWEEP_NS, &at(3.1), v, false, Vec::new())
            .expect("correct");
        assert_eq!(
            next,
            Correction::State {
                velocity_mps: v,
                bias: ImuBias::default()
            }
        );
        assert_eq!(odometry.last_ns(), Some(t + SWEEP_NS));
    }
}
