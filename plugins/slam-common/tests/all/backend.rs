//! The factor-graph backend from outside the crate: answers known in advance (analytic
//! optima, simulated ground truth), factrs's conventions as seen through our types, and
//! the behaviours the plugins rely on (robust loop closures, removal, windowed updates).

use nalgebra::{Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::factor_graph::backend::{
    Backend, BackendConfig, BackendError, Factor, ImuBias, ImuNoise, ImuSample, Robust, Scope,
    Value, Var, from_config,
};
use std::f64::consts::FRAC_PI_2;

const G: f64 = 9.80511;

fn backend(window: usize, max_iterations: usize) -> Box<dyn Backend> {
    backend_named("factrs", window, max_iterations)
}

fn backend_named(name: &str, window: usize, max_iterations: usize) -> Box<dyn Backend> {
    from_config(&BackendConfig {
        name: name.into(),
        window,
        max_iterations,
        ..BackendConfig::default()
    })
    .unwrap_or_else(|e| panic!("{name} backend: {e}"))
}

/// The behaviours every backend must have, run on each: `mod factrs { #[test] fn … }`.
macro_rules! on_every_backend {
    ($($test:ident),* $(,)?) => {
        mod factrs {
            $(#[test] fn $test() { super::$test("factrs") })*
        }
        mod isam2 {
            $(#[test] fn $test() { super::$test("isam2") })*
        }
    };
}

on_every_backend!(
    two_pose_graph_reaches_the_analytic_optimum,
    factor_error_counts_sigmas_in_the_body_frame_rotation_first,
    vineyard_loop_closures_beat_dead_reckoning,
    imu_at_rest_reads_plus_g_and_stays_put,
    imu_chain_recovers_trajectory_and_bias,
    imu_factor_covariance_matches_the_noise_densities,
    robust_kernel_ignores_a_gross_outlier_loop_and_removal_restores,
    bad_input_is_an_error_not_a_panic,
    position_factor_error_is_in_the_world_frame,
    position_priors_pull_a_drifted_chain_to_them,
    marginal_covariance_grows_along_a_chain_and_shrinks_at_a_position_prior,
    marginal_covariance_of_unknown_or_unconstrained_poses_is_an_error,
);

fn sigmas(rot: f64, trans: f64) -> Vector6<f64> {
    Vector6::new(rot, rot, rot, trans, trans, trans)
}

fn iso(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

/// `p` moved by a random body-frame perturbation.
fn perturb(p: &Isometry3<f64>, rng: &mut ChaCha8Rng, rot: f64, trans: f64) -> Isometry3<f64> {
    let r = Normal::new(0.0, rot).expect("sigma");
    let t = Normal::new(0.0, trans).expect("sigma");
    let mut s = |d: &Normal<f64>| d.sample(rng);
    let delta = Isometry3::new(
        Vector3::new(s(&t), s(&t), s(&t)),
        Vector3::new(s(&r), s(&r), s(&r)),
    );
    p * delta
}

/// One lap of a vineyard-like route, a pose per metre: down row 0, across the headland,
/// back up row 1, and back across to the start; gentle terrain gives roll, pitch and z.
fn lap(row_len: usize, gap: usize) -> Vec<Isometry3<f64>> {
    let mut xy = Vec::new();
    let (l, g) = (row_len as f64, gap as f64);
    let corners = [(0.0, 0.0), (l, 0.0), (l, g), (0.0, g), (0.0, 0.0)];
    for w in corners.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        let n = (x1 - x0).abs().max((y1 - y0).abs()) as usize;
        let yaw = (y1 - y0).atan2(x1 - x0);
        for i in 0..n {
            let s = i as f64 / n as f64;
            xy.push((x0 + s * (x1 - x0), y0 + s * (y1 - y0), yaw));
        }
    }
    xy.iter()
        .map(|&(x, y, yaw)| {
            let z = 0.15 * (0.5 * x).sin() + 0.1 * (0.7 * y).cos();
            iso(x, y, z, 0.03 * (0.9 * x).sin(), 0.04 * (0.6 * x).cos(), yaw)
        })
        .collect()
}

fn rmse(a: &[Isometry3<f64>], b: &[Isometry3<f64>]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p.translation.vector - q.translation.vector).norm_squared())
        .sum();
    (sum / a.len() as f64).sqrt()
}

fn poses(b: &dyn Backend) -> Vec<Isometry3<f64>> {
    b.pose_keys()
        .iter()
        .map(|&k| b.pose(k).expect("pose"))
        .collect()
}

/// A chain with dead-reckoned initial estimates: prior on pose 0, noisy odometry.
fn odometry_chain(
    b: &mut dyn Backend,
    truth: &[Isometry3<f64>],
    rng: &mut ChaCha8Rng,
    odo: (f64, f64),
) -> Vec<Isometry3<f64>> {
    b.insert(Var::Pose(0), Value::Pose(truth[0]))
        .expect("insert");
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: truth[0],
        sigmas: sigmas(1e-3, 1e-3),
    })
    .expect("prior");
    let mut dead = vec![truth[0]];
    for i in 1..truth.len() {
        let z = perturb(&(truth[i - 1].inverse() * truth[i]), rng, odo.0, odo.1);
        let guess = dead[i - 1] * z;
        dead.push(guess);
        b.insert(Var::Pose(i as u64), Value::Pose(guess))
            .expect("insert");
        b.add(Factor::Between {
            from: i as u64 - 1,
            to: i as u64,
            from_from_to: z,
            sigmas: sigmas(odo.0, odo.1),
            robust: Robust::None,
        })
        .expect("odometry");
    }
    dead
}

fn two_pose_graph_reaches_the_analytic_optimum(name: &str) {
    // Guards the sigma order (rotation first), the Between direction and whitening: the
    // problem is linear in x (no rotation anywhere), so its optimum is a weighted mean.
    let mut b = backend_named(name, 10, 20);
    b.insert(Var::Pose(0), Value::Pose(iso(0.3, 0.0, 0.0, 0.0, 0.0, 0.0)))
        .expect("insert");
    b.insert(Var::Pose(1), Value::Pose(iso(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)))
        .expect("insert");
    let (s0, sa, sb) = (0.1, 0.2, 0.3);
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: Isometry3::identity(),
        sigmas: sigmas(1.0, s0),
    })
    .expect("prior");
    b.add(Factor::Between {
        from: 0,
        to: 1,
        from_from_to: iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        sigmas: sigmas(10.0, sa),
        robust: Robust::None,
    })
    .expect("between");
    b.add(Factor::PosePrior {
        key: 1,
        world_from_body: iso(1.2, 0.0, 0.0, 0.0, 0.0, 0.0),
        sigmas: sigmas(0.01, sb),
    })
    .expect("prior");
    b.update(Scope::Full).expect("update");
    // Normal equations of a = x0, c = x1: a/s0² + (a − c + 1)/sa² = 0,
    // (c − a − 1)/sa² + (c − 1.2)/sb² = 0.
    let (w0, wa, wb) = (1.0 / (s0 * s0), 1.0 / (sa * sa), 1.0 / (sb * sb));
    let det = (w0 + wa) * (wa + wb) - wa * wa;
    let a = (-wa * (wa + wb) + wa * (wa + 1.2 * wb)) / det;
    let c = ((w0 + wa) * (wa + 1.2 * wb) - wa * wa) / det;
    let x0 = b.pose(0).expect("pose 0").translation.x;
    let x1 = b.pose(1).expect("pose 1").translation.x;
    assert!((x0 - a).abs() < 1e-6, "x0 = {x0}, expected {a}");
    assert!((x1 - c).abs() < 1e-6, "x1 = {x1}, expected {c}");
}

fn factor_error_counts_sigmas_in_the_body_frame_rotation_first(name: &str) {
    // Guards the conversion to factrs: a pose off by 2σ along its own x axis, and one
    // rotated by 3σ about its z axis, must read as 2 and 3 sigmas.
    let mut b = backend_named(name, 10, 10);
    let start = iso(1.0, 2.0, 0.5, 0.0, 0.0, FRAC_PI_2);
    b.insert(Var::Pose(0), Value::Pose(start)).expect("insert");
    // 2σ = 0.2 m along the body's x, which is the world's y at this heading.
    let moved = start * Translation3::new(1.0 + 0.2, 0.0, 0.0);
    b.insert(Var::Pose(1), Value::Pose(moved)).expect("insert");
    let along = b
        .add(Factor::Between {
            from: 0,
            to: 1,
            from_from_to: iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            sigmas: Vector6::new(0.01, 0.01, 0.01, 0.1, 1e3, 1e3),
            robust: Robust::None,
        })
        .expect("between");
    let e = b.factor_error(along).expect("error");
    assert!(
        (e - 2.0).abs() < 1e-9,
        "0.2 m at σx 0.1 m: {e} σ, expected 2"
    );
    let rotated = start * UnitQuaternion::from_euler_angles(0.0, 0.0, 0.15);
    b.insert(Var::Pose(2), Value::Pose(rotated))
        .expect("insert");
    let prior = b
        .add(Factor::PosePrior {
            key: 2,
            world_from_body: start,
            sigmas: Vector6::new(1e3, 1e3, 0.05, 0.1, 0.1, 0.1),
        })
        .expect("prior");
    let e = b.factor_error(prior).expect("error");
    assert!(
        (e - 3.0).abs() < 1e-9,
        "0.15 rad at σyaw 0.05: {e} σ, expected 3"
    );
}

fn vineyard_loop_closures_beat_dead_reckoning(name: &str) {
    // Guards the pose-graph solve and its noise model: noisy odometry around two rows,
    // closures across the rows every 2 m (the lidar sees the next row) and at the
    // headland; the optimum must be far closer to the truth than dead reckoning, and its
    // χ² must be what the noise model predicts (right sigmas, right whitening).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let truth = lap(18, 3);
    let mut b = backend_named(name, 10, 30);
    let dead = odometry_chain(b.as_mut(), &truth, &mut rng, (0.01, 0.05));
    let n = truth.len();
    let mut closures = vec![(n - 1, 0)];
    // Row 0 at x = k is pose k; row 1 runs back, x = k is pose 21 + 18 − k.
    closures.extend((0..=18).step_by(2).map(|k| (21 + 18 - k, k)));
    for (from, to) in closures {
        let z = perturb(&(truth[from].inverse() * truth[to]), &mut rng, 0.005, 0.02);
        b.add(Factor::Between {
            from: from as u64,
            to: to as u64,
            from_from_to: z,
            sigmas: sigmas(0.005, 0.02),
            // Dead reckoning starts tens of sigmas away from these, where a redescending
            // kernel would switch them off; robust closures are tested below.
            robust: Robust::None,
        })
        .expect("closure");
    }
    let report = b.update(Scope::Full).expect("update");
    let est = poses(b.as_ref());
    let (before, after) = (rmse(&dead, &truth), rmse(&est, &truth));
    eprintln!("vineyard loop: RMSE {after:.3} m vs dead reckoning {before:.3} m, {report:?}");
    assert!(
        after < 0.5 * before,
        "position RMSE {after:.3} m after, {before:.3} m by dead reckoning"
    );
    assert_eq!(report.variables, n, "Full moves every pose");
    // 6 residuals per factor, 6 unknowns per pose: χ² ~ dof ± √(2·dof).
    let dof = 6.0 * (report.factors - report.variables) as f64;
    assert!(
        (report.error_after - dof).abs() < 4.0 * (2.0 * dof).sqrt(),
        "χ² {} for {dof} degrees of freedom (before: {})",
        report.error_after,
        report.error_before
    );
}

/// A smooth 3D trajectory: position, world_from_body rotation, velocity, body angular
/// rate and specific force (what an ideal IMU reads) at `t`.
struct Motion;

impl Motion {
    fn pos(t: f64) -> Vector3<f64> {
        Vector3::new(
            3.0 * (0.4 * t).sin() + 0.5 * t,
            2.0 * (1.0 - (0.3 * t).cos()),
            0.3 * (0.5 * t).sin(),
        )
    }
    fn rot(t: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(
            0.1 * (0.7 * t).sin(),
            0.08 * (0.5 * t).cos(),
            0.6 * t + 0.3 * (0.2 * t).sin(),
        )
    }
    fn pose(t: f64) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(Self::pos(t)), Self::rot(t))
    }
    fn vel(t: f64) -> Vector3<f64> {
        let h = 1e-5;
        (Self::pos(t + h) - Self::pos(t - h)) / (2.0 * h)
    }
    fn gyro(t: f64) -> Vector3<f64> {
        let h = 1e-5;
        (Self::rot(t - h).inverse() * Self::rot(t + h)).scaled_axis() / (2.0 * h)
    }
    fn accel(t: f64) -> Vector3<f64> {
        let h = 1e-3;
        let a = (Self::pos(t + h) - 2.0 * Self::pos(t) + Self::pos(t - h)) / (h * h);
        Self::rot(t).inverse() * (a + Vector3::new(0.0, 0.0, G))
    }
}

/// Samples at `rate_hz` over [t0, t1), read at each interval's midpoint, plus `bias`.
fn imu_samples(t0: f64, t1: f64, rate_hz: f64, bias: &ImuBias) -> Vec<ImuSample> {
    let n = ((t1 - t0) * rate_hz).round() as usize;
    let dt = (t1 - t0) / n as f64;
    (0..n)
        .map(|i| {
            let t = t0 + (i as f64 + 0.5) * dt;
            ImuSample {
                dt_s: dt,
                accel_mps2: Motion::accel(t) + bias.accel_mps2,
                gyro_rps: Motion::gyro(t) + bias.gyro_rps,
            }
        })
        .collect()
}

fn imu_at_rest_reads_plus_g_and_stays_put(name: &str) {
    // Guards the gravity sign: a level IMU at rest reads +g along its z; factrs's own
    // examples use the opposite sign, which would make this keyframe fall at 2g.
    let mut b = backend_named(name, 10, 20);
    let noise = ImuNoise::default();
    for k in 0..2 {
        b.insert(Var::Pose(k), Value::Pose(Isometry3::identity()))
            .expect("insert");
        b.insert(Var::Velocity(k), Value::Velocity(Vector3::zeros()))
            .expect("insert");
        b.insert(Var::Bias(k), Value::Bias(ImuBias::default()))
            .expect("insert");
    }
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: Isometry3::identity(),
        sigmas: sigmas(1e-3, 1e-3),
    })
    .expect("prior");
    b.add(Factor::VelocityPrior {
        key: 0,
        velocity_mps: Vector3::zeros(),
        sigma_mps: 1e-3,
    })
    .expect("prior");
    b.add(Factor::BiasPrior {
        key: 0,
        bias: ImuBias::default(),
        sigma_accel: 1e-3,
        sigma_gyro: 1e-4,
    })
    .expect("prior");
    let at_rest = ImuSample {
        dt_s: 0.005,
        accel_mps2: Vector3::new(0.0, 0.0, G),
        gyro_rps: Vector3::zeros(),
    };
    let imu = b
        .add(Factor::Imu {
            from: 0,
            to: 1,
            samples: vec![at_rest; 200],
            noise,
        })
        .expect("imu");
    let e = b.factor_error(imu).expect("error");
    assert!(
        e < 1e-6,
        "the state at rest should satisfy the IMU factor: {e} σ"
    );
    b.update(Scope::Full).expect("update");
    let p = b.pose(1).expect("pose").translation.vector;
    assert!(
        p.norm() < 1e-6,
        "pose 1 should stay at the origin, is at {p}"
    );
}

fn imu_chain_recovers_trajectory_and_bias(name: &str) {
    // Guards preintegration end to end (gravity, frames, bias Jacobians, noise scaling):
    // exact 200 Hz samples of a smooth 3D motion with a constant bias, keyframes every
    // second tied by IMU factors, pose fixes (as from lidar odometry) at each keyframe,
    // and a start far from the truth; the solve must find velocities and the bias.
    let bias = ImuBias {
        accel_mps2: Vector3::new(0.08, -0.05, 0.1),
        gyro_rps: Vector3::new(0.004, -0.003, 0.002),
    };
    let noise = ImuNoise::default();
    let keyframes = 12;
    let mut b = backend_named(name, 30, 30);
    for k in 0..keyframes {
        let t = k as f64;
        let guess = Motion::pose(t) * Translation3::new(0.3, -0.2, 0.1);
        b.insert(Var::Pose(k), Value::Pose(guess)).expect("insert");
        b.insert(Var::Velocity(k), Value::Velocity(Vector3::zeros()))
            .expect("insert");
        b.insert(Var::Bias(k), Value::Bias(ImuBias::default()))
            .expect("insert");
        b.add(Factor::PosePrior {
            key: k,
            world_from_body: Motion::pose(t),
            sigmas: sigmas(0.01, 0.02),
        })
        .expect("pose fix");
        if k > 0 {
            b.add(Factor::Imu {
                from: k - 1,
                to: k,
                samples: imu_samples(t - 1.0, t, 200.0, &bias),
                noise,
            })
            .expect("imu");
        }
    }
    b.add(Factor::BiasPrior {
        key: 0,
        bias: ImuBias::default(),
        sigma_accel: 1.0,
        sigma_gyro: 0.1,
    })
    .expect("bias prior");
    let report = b.update(Scope::Full).expect("update");
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..keyframes {
        let t = k as f64;
        let p = b.pose(k).expect("pose");
        let dp = (p.translation.vector - Motion::pos(t)).norm();
        let dr = (p.rotation.inverse() * Motion::rot(t)).angle();
        let Some(Value::Velocity(v)) = b.value(Var::Velocity(k)) else {
            panic!("no velocity {k}")
        };
        let dv = (v - Motion::vel(t)).norm();
        worst = (worst.0.max(dp), worst.1.max(dr), worst.2.max(dv));
        assert!(dp < 0.005, "keyframe {k}: position off by {dp:.4} m");
        assert!(dr < 1e-3, "keyframe {k}: rotation off by {dr:.5} rad");
        assert!(dv < 0.01, "keyframe {k}: velocity off by {dv:.4} m/s");
    }
    let Some(Value::Bias(est)) = b.value(Var::Bias(keyframes / 2)) else {
        panic!("no bias")
    };
    let da = (est.accel_mps2 - bias.accel_mps2).norm();
    let dg = (est.gyro_rps - bias.gyro_rps).norm();
    eprintln!(
        "IMU chain: worst position {:.4} m, rotation {:.5} rad, velocity {:.4} m/s; \
         bias error {da:.4} m/s², {dg:.6} rad/s; {report:?}",
        worst.0, worst.1, worst.2
    );
    assert!(
        da < 0.005,
        "accelerometer bias {} vs {}",
        est.accel_mps2,
        bias.accel_mps2
    );
    assert!(
        dg < 2e-4,
        "gyroscope bias {} vs {}",
        est.gyro_rps,
        bias.gyro_rps
    );
}

fn imu_factor_covariance_matches_the_noise_densities(name: &str) {
    // Guards the mapping of continuous noise densities onto factrs's per-sample
    // covariances (and the workaround for its gyroscope term): with white noise of the
    // stated densities on every sample and the true states, each factor's squared
    // whitened error is χ² with 9 degrees of freedom (the bias part is exactly zero).
    let noise = ImuNoise {
        accel_noise_density: 0.05,
        gyro_noise_density: 0.005,
        ..ImuNoise::default()
    };
    let rate_hz: f64 = 200.0;
    let bias = ImuBias {
        accel_mps2: Vector3::new(0.02, 0.01, -0.03),
        gyro_rps: Vector3::new(0.001, 0.0, -0.002),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let white = |density: f64| Normal::new(0.0, density * rate_hz.sqrt()).expect("sigma");
    let (acc, gyr) = (
        white(noise.accel_noise_density),
        white(noise.gyro_noise_density),
    );
    let mut b = backend_named(name, 10, 10);
    let factors = 60;
    for k in 0..=factors {
        let t = k as f64;
        b.insert(Var::Pose(k), Value::Pose(Motion::pose(t)))
            .expect("insert");
        b.insert(Var::Velocity(k), Value::Velocity(Motion::vel(t)))
            .expect("insert");
        b.insert(Var::Bias(k), Value::Bias(bias)).expect("insert");
    }
    let mut chi2 = Vec::new();
    for k in 1..=factors {
        let t = k as f64;
        let mut samples = imu_samples(t - 1.0, t, rate_hz, &bias);
        for s in &mut samples {
            s.accel_mps2 += Vector3::from_fn(|_, _| acc.sample(&mut rng));
            s.gyro_rps += Vector3::from_fn(|_, _| gyr.sample(&mut rng));
        }
        let id = b
            .add(Factor::Imu {
                from: k - 1,
                to: k,
                samples,
                noise,
            })
            .expect("imu");
        chi2.push(b.factor_error(id).expect("error").powi(2));
    }
    let mean = chi2.iter().sum::<f64>() / chi2.len() as f64;
    // χ²₉ has variance 18: the mean of 60 is 9 ± 0.55.
    eprintln!("IMU χ² per factor: mean {mean:.2} (expected 9)");
    assert!(
        (7.0..11.0).contains(&mean),
        "mean χ² per IMU factor {mean:.2}, expected 9"
    );
}

fn robust_kernel_ignores_a_gross_outlier_loop_and_removal_restores(name: &str) {
    // Guards the robust kernels, factor_error and remove: a loop closure claiming pose 30
    // is 6 m to the side of where odometry puts it. With a Cauchy kernel the trajectory
    // barely moves; without one it is dragged; removing the factor restores the answer.
    let truth: Vec<_> = (0..40)
        .map(|i| iso(i as f64, 0.0, 0.0, 0.0, 0.0, 0.02 * i as f64))
        .collect();
    let lie = iso(3.0, 6.0, 0.0, 0.0, 0.0, 0.5) * (truth[5].inverse() * truth[30]);
    let outlier = |robust| Factor::Between {
        from: 5,
        to: 30,
        from_from_to: lie,
        sigmas: sigmas(0.01, 0.05),
        robust,
    };
    let solve = |extra: Option<Robust>| {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut b = backend_named(name, 10, 50);
        odometry_chain(b.as_mut(), &truth, &mut rng, (0.005, 0.02));
        let id = extra.map(|r| b.add(outlier(r)).expect("outlier"));
        b.update(Scope::Full).expect("update");
        (b, id)
    };
    let (clean, _) = solve(None);
    let reference = poses(clean.as_ref());
    let shift = |b: &dyn Backend| {
        poses(b)
            .iter()
            .zip(&reference)
            .map(|(p, q)| (p.translation.vector - q.translation.vector).norm())
            .fold(0.0, f64::max)
    };
    let (mut robust, id) = solve(Some(Robust::Cauchy(1.0)));
    let id = id.expect("id");
    assert!(
        shift(robust.as_ref()) < 0.05,
        "Cauchy moved the chain by {} m",
        shift(robust.as_ref())
    );
    let e = robust.factor_error(id).expect("error");
    assert!(e > 50.0, "the outlier should be many sigmas off, is {e}");
    let (plain, _) = solve(Some(Robust::None));
    assert!(
        shift(plain.as_ref()) > 0.5,
        "plain least squares moved it only {} m",
        shift(plain.as_ref())
    );
    let (huber, _) = solve(Some(Robust::Huber(1.345)));
    assert!(
        shift(huber.as_ref()) < 0.5 * shift(plain.as_ref()),
        "Huber {} m vs none {} m",
        shift(huber.as_ref()),
        shift(plain.as_ref())
    );

    // RTAB-Map's path: reject the closure, drop it, re-solve.
    assert!(robust.remove(id), "the outlier was there to remove");
    assert!(!robust.remove(id), "it cannot be removed twice");
    assert_eq!(
        robust.factor_error(id),
        None,
        "a removed factor has no error"
    );
    robust.update(Scope::Full).expect("update");
    assert!(
        shift(robust.as_ref()) < 1e-4,
        "after removal off by {} m",
        shift(robust.as_ref())
    );
    // ... or restore the saved estimate exactly.
    let (mut dragged, id) = solve(Some(Robust::None));
    assert!(dragged.remove(id.expect("id")));
    for (k, p) in reference.iter().enumerate() {
        dragged
            .set_value(Var::Pose(k as u64), Value::Pose(*p))
            .expect("restore");
    }
    assert_eq!(poses(dragged.as_ref()), reference, "restored estimate");
}

#[test]
fn incremental_window_holds_old_poses_and_matches_full() {
    // Guards Scope::Incremental: each keyframe arrives with a poor guess (0.3 m and
    // 0.05 rad off the odometry); the window must fix it while older poses stay exactly
    // where they were, the work per update stays bounded, and on an odometry chain the
    // result equals the full solve.
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let truth = lap(18, 3);
    let window = 8;
    let mut inc = backend(window, 10);
    let mut full = backend(window, 10);
    for b in [&mut inc, &mut full] {
        b.insert(Var::Pose(0), Value::Pose(truth[0]))
            .expect("insert");
        b.add(Factor::PosePrior {
            key: 0,
            world_from_body: truth[0],
            sigmas: sigmas(1e-3, 1e-3),
        })
        .expect("prior");
    }
    for i in 1..truth.len() {
        let z = perturb(&(truth[i - 1].inverse() * truth[i]), &mut rng, 0.01, 0.05);
        let prev = inc.pose(i as u64 - 1).expect("previous");
        let guess = prev * z * iso(0.3, -0.2, 0.1, 0.0, 0.0, 0.05);
        for b in [&mut inc, &mut full] {
            b.insert(Var::Pose(i as u64), Value::Pose(guess))
                .expect("insert");
            b.add(Factor::Between {
                from: i as u64 - 1,
                to: i as u64,
                from_from_to: z,
                sigmas: sigmas(0.01, 0.05),
                robust: Robust::None,
            })
            .expect("odometry");
        }
        let before = poses(inc.as_ref());
        let report = inc.update(Scope::Incremental).expect("incremental");
        let after = poses(inc.as_ref());
        let oldest = (i + 1).saturating_sub(window);
        assert_eq!(
            before[..oldest],
            after[..oldest],
            "poses before {oldest} moved at {i}"
        );
        assert!(
            report.variables <= window && report.factors <= window + 1,
            "update {i} solved {} variables, {} factors",
            report.variables,
            report.factors
        );
    }
    full.update(Scope::Full).expect("full");
    let d = poses(inc.as_ref())
        .iter()
        .zip(poses(full.as_ref()))
        .map(|(p, q)| (p.translation.vector - q.translation.vector).norm())
        .fold(0.0, f64::max);
    assert!(d < 1e-4, "incremental and full differ by {d} m");
}

#[test]
fn unknown_backend_name_is_an_error_naming_it() {
    // Guards configuration errors: a misspelt backend must say what was asked for.
    let config = BackendConfig {
        name: "gtsam2".into(),
        ..BackendConfig::default()
    };
    match from_config(&config) {
        Err(e @ BackendError::Unknown(_)) => {
            assert!(e.to_string().contains("\"gtsam2\""), "message: {e}")
        }
        other => panic!("expected Unknown, got {other:?}"),
    }
    let zero = BackendConfig {
        name: "factrs".into(),
        window: 0,
        ..BackendConfig::default()
    };
    assert!(
        matches!(from_config(&zero), Err(BackendError::Invalid(_))),
        "window 0 must be rejected"
    );
}

fn bad_input_is_an_error_not_a_panic(name: &str) {
    // Guards the checks before factrs, which panics on non-positive covariances and on
    // keys it does not know.
    let mut b = backend_named(name, 10, 10);
    b.insert(Var::Pose(0), Value::Pose(Isometry3::identity()))
        .expect("insert");
    assert!(matches!(
        b.insert(Var::Pose(0), Value::Pose(Isometry3::identity())),
        Err(BackendError::Duplicate(Var::Pose(0)))
    ));
    assert!(matches!(
        b.insert(Var::Velocity(0), Value::Pose(Isometry3::identity())),
        Err(BackendError::Invalid(_))
    ));
    let between = |to, sigma| Factor::Between {
        from: 0,
        to,
        from_from_to: Isometry3::identity(),
        sigmas: sigmas(sigma, sigma),
        robust: Robust::None,
    };
    assert!(matches!(
        b.add(between(1, 0.1)),
        Err(BackendError::MissingVariable(Var::Pose(1)))
    ));
    b.insert(Var::Pose(1), Value::Pose(Isometry3::identity()))
        .expect("insert");
    assert!(matches!(
        b.add(between(1, 0.0)),
        Err(BackendError::Invalid(_))
    ));
    assert!(matches!(
        b.add(Factor::Imu {
            from: 0,
            to: 1,
            samples: Vec::new(),
            noise: ImuNoise::default()
        }),
        Err(BackendError::MissingVariable(_) | BackendError::Invalid(_))
    ));
    // No prior: the gauge is free and factrs's Cholesky fails; that is an error and
    // the estimate is left as it was.
    b.add(between(1, 0.1)).expect("between");
    b.set_value(Var::Pose(1), Value::Pose(iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)))
        .expect("set");
    match b.update(Scope::Full) {
        Err(BackendError::Solver(_)) | Ok(_) => {}
        Err(e) => panic!("unexpected error {e}"),
    }
    assert!(
        b.pose(1)
            .is_some_and(|p| p.translation.vector.iter().all(|x| x.is_finite()))
    );
}

fn position_factor_error_is_in_the_world_frame(name: &str) {
    // Guards Factor::Position's frame and whitening (GTSAM's GPSFactor: t(x) − z in the
    // world): a pose facing north (yaw 90°) 0.2 m east of the measured position, with σ
    // 0.1 m east and 1 km otherwise, reads 2 σ; had the error been taken along the body's
    // axes, the 0.2 m would fall on the loose σ and read ~0.
    let mut b = backend_named(name, 10, 10);
    let facing_north = iso(3.2, 4.0, 1.0, 0.0, 0.0, FRAC_PI_2);
    b.insert(Var::Pose(0), Value::Pose(facing_north))
        .expect("insert");
    let id = b
        .add(Factor::Position {
            key: 0,
            position: Vector3::new(3.0, 4.0, 1.0),
            sigmas: Vector3::new(0.1, 1e3, 1e3),
        })
        .expect("position");
    let e = b.factor_error(id).expect("error");
    assert!((e - 2.0).abs() < 1e-9, "0.2 m east at σ 0.1 m: {e} σ");
    // It alone constrains no rotation: with a pose prior loose in translation, the
    // solve moves the translation onto the fix and leaves the rotation where it was.
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: facing_north,
        sigmas: sigmas(1e-3, 1e3),
    })
    .expect("prior");
    b.update(Scope::Full).expect("update");
    let p = b.pose(0).expect("pose");
    assert!(
        (p.translation.x - 3.0).abs() < 1e-6,
        "east {} after the solve",
        p.translation.x
    );
    assert!((p.rotation.inverse() * facing_north.rotation).angle() < 1e-9);
}

fn position_priors_pull_a_drifted_chain_to_them(name: &str) {
    // Guards Factor::Position in a solve: odometry around two vine rows with a heading
    // bias (0.01 rad per metre, a gyroscope's drift) bends dead reckoning metres away;
    // GNSS-like fixes on every fifth pose (σ 0.1 m) must pull the chain back to the truth
    // to a few times their own noise, and leave χ² near where the noise model puts it.
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let truth = lap(18, 3);
    let mut b = backend_named(name, 10, 30);
    b.insert(Var::Pose(0), Value::Pose(truth[0]))
        .expect("insert");
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: truth[0],
        sigmas: sigmas(1e-3, 1e-3),
    })
    .expect("prior");
    let odo = (0.01, 0.05);
    let drift = iso(0.0, 0.0, 0.0, 0.0, 0.0, 0.01);
    let mut dead = vec![truth[0]];
    for i in 1..truth.len() {
        let z = perturb(&(truth[i - 1].inverse() * truth[i]), &mut rng, odo.0, odo.1) * drift;
        dead.push(dead[i - 1] * z);
        b.insert(Var::Pose(i as u64), Value::Pose(dead[i]))
            .expect("insert");
        b.add(Factor::Between {
            from: i as u64 - 1,
            to: i as u64,
            from_from_to: z,
            sigmas: sigmas(odo.0, odo.1),
            robust: Robust::None,
        })
        .expect("odometry");
    }
    let fix_noise = Normal::new(0.0, 0.1).expect("sigma");
    let mut fixes = 0;
    for i in (5..truth.len()).step_by(5) {
        let position =
            truth[i].translation.vector + Vector3::from_fn(|_, _| fix_noise.sample(&mut rng));
        b.add(Factor::Position {
            key: i as u64,
            position,
            sigmas: Vector3::repeat(0.1),
        })
        .expect("fix");
        fixes += 1;
    }
    let report = b.update(Scope::Full).expect("update");
    let est = poses(b.as_ref());
    let (before, after) = (rmse(&dead, &truth), rmse(&est, &truth));
    eprintln!(
        "{name}: drifted chain with {fixes} fixes: RMSE {after:.3} m vs dead reckoning \
         {before:.3} m; {report:?}"
    );
    assert!(before > 1.0, "the drift should be large: {before:.3} m");
    // The bias (1 σ of the odometry per step, systematic) bends the chain between fixes
    // 5 m apart; measured 0.18 m on both native backends.
    assert!(
        after < 0.25 && after < 0.2 * before,
        "RMSE {after:.3} m with fixes of σ 0.1 m, {before:.3} m by dead reckoning"
    );
    // Odometry residuals: 6 per factor; fixes: 3 each; unknowns: 6 per pose. The heading
    // bias is not in the noise model, so only an upper bound: the fixes and odometry
    // agree once the bias is spread over the chain.
    let dof = 6.0 * (truth.len() - 1) as f64 + 6.0 + 3.0 * fixes as f64 - 6.0 * truth.len() as f64;
    assert!(
        report.error_after < dof + 6.0 * (2.0 * dof).sqrt(),
        "χ² {} for {dof} degrees of freedom",
        report.error_after
    );
}

/// A straight chain facing north (yaw 90°): pose 0 known to 1 cm, odometry 1 m forward
/// with σ 0.1 m along the body's x, 0.02 m across (y), 0.05 m up, and a rotation so well
/// known (1e-6 rad) that the translation's covariance is the sum of the steps' (linear).
const CHAIN_SIGMA_X: f64 = 0.1;
const CHAIN_SIGMA_Y: f64 = 0.02;
const CHAIN_SIGMA_Z: f64 = 0.05;
const CHAIN_SIGMA_0: f64 = 0.01;

fn north(i: usize) -> Isometry3<f64> {
    iso(0.0, i as f64, 0.0, 0.0, 0.0, FRAC_PI_2)
}

fn add_chain_pose(b: &mut dyn Backend, i: usize) {
    b.insert(Var::Pose(i as u64), Value::Pose(north(i)))
        .expect("insert");
    if i == 0 {
        b.add(Factor::PosePrior {
            key: 0,
            world_from_body: north(0),
            sigmas: sigmas(1e-6, CHAIN_SIGMA_0),
        })
        .expect("prior");
    } else {
        b.add(Factor::Between {
            from: i as u64 - 1,
            to: i as u64,
            from_from_to: north(i - 1).inverse() * north(i),
            sigmas: Vector6::new(
                1e-6,
                1e-6,
                1e-6,
                CHAIN_SIGMA_X,
                CHAIN_SIGMA_Y,
                CHAIN_SIGMA_Z,
            ),
            robust: Robust::None,
        })
        .expect("odometry");
    }
}

/// `|a − e| ≤ tol·e` for every pair.
fn close(what: &str, actual: &[f64], expected: &[f64], tol: f64) {
    for (a, e) in actual.iter().zip(expected) {
        assert!(
            (a - e).abs() <= tol * e.abs(),
            "{what}: {actual:?}, expected {expected:?}"
        );
    }
}

fn marginal_covariance_grows_along_a_chain_and_shrinks_at_a_position_prior(name: &str) {
    // Guards Backend::marginal_covariance against the analytic answer and its convention:
    // along the chain the translation variance is σ₀² + n·σ² per axis, in the body frame
    // (rows 3–5 of the tangent: forward = x, across = y) and, turned by the heading, in
    // the world's (forward = north = y, across = east = x); a position prior of σ_p on the
    // last pose then gives, per world axis, 1/(1/v + 1/σ_p²). Relative tolerance 1e-6:
    // the problem is linear (the rotation's 1e-6 rad adds ~1e-9 m² at 20 m).
    let mut b = backend_named(name, 100, 10);
    let mut last_east = 0.0;
    for i in 0..=20 {
        add_chain_pose(b.as_mut(), i);
        b.update(Scope::Incremental).expect("update");
        let cov = b.marginal_covariance(i as u64).expect("marginal");
        let n = i as f64;
        let v = |s: f64| CHAIN_SIGMA_0.powi(2) + n * s * s;
        let body = cov.translation_body();
        close(
            &format!("{name}: body translation variances at pose {i}"),
            &[body[(0, 0)], body[(1, 1)], body[(2, 2)]],
            &[v(CHAIN_SIGMA_X), v(CHAIN_SIGMA_Y), v(CHAIN_SIGMA_Z)],
            1e-6,
        );
        assert_eq!(cov.tangent[(3, 3)], body[(0, 0)]);
        let world = cov.translation_world();
        close(
            &format!("{name}: world translation variances at pose {i}"),
            &[world[(0, 0)], world[(1, 1)], world[(2, 2)]],
            &[v(CHAIN_SIGMA_Y), v(CHAIN_SIGMA_X), v(CHAIN_SIGMA_Z)],
            1e-6,
        );
        assert!(world[(0, 1)].abs() < 1e-9, "east-north {}", world[(0, 1)]);
        assert!(world[(0, 0)] > last_east, "grows along the chain");
        last_east = world[(0, 0)];
    }
    let before = b
        .marginal_covariance(20)
        .expect("marginal")
        .translation_world();
    let sigma_p = 0.3;
    b.add(Factor::Position {
        key: 20,
        position: north(20).translation.vector,
        sigmas: Vector3::repeat(sigma_p),
    })
    .expect("fix");
    b.update(Scope::Incremental).expect("update");
    let after = b
        .marginal_covariance(20)
        .expect("marginal")
        .translation_world();
    let fused = |v: f64| 1.0 / (1.0 / v + 1.0 / (sigma_p * sigma_p));
    eprintln!(
        "{name}: pose 20 world variances {:.4} {:.4} {:.4} m², after a σ {sigma_p} m fix \
         {:.4} {:.4} {:.4} m²",
        before[(0, 0)],
        before[(1, 1)],
        before[(2, 2)],
        after[(0, 0)],
        after[(1, 1)],
        after[(2, 2)]
    );
    close(
        &format!("{name}: world variances after the fix"),
        &[after[(0, 0)], after[(1, 1)], after[(2, 2)]],
        &[
            fused(before[(0, 0)]),
            fused(before[(1, 1)]),
            fused(before[(2, 2)]),
        ],
        1e-6,
    );
    assert!((0..3).all(|k| after[(k, k)] < before[(k, k)]), "shrinks");
    // The fix at pose 20 reaches back: pose 10's along-track variance shrinks too.
    let middle = b
        .marginal_covariance(10)
        .expect("marginal")
        .translation_world();
    assert!(middle[(1, 1)] < CHAIN_SIGMA_0.powi(2) + 10.0 * CHAIN_SIGMA_X.powi(2));
}

fn marginal_covariance_of_unknown_or_unconstrained_poses_is_an_error(name: &str) {
    // Guards the errors: no such pose; a pose whose gauge is free (no prior) is an error,
    // not a panic or a NaN matrix.
    let mut b = backend_named(name, 10, 10);
    assert!(matches!(
        b.marginal_covariance(3),
        Err(BackendError::MissingVariable(Var::Pose(3)))
    ));
    b.insert(Var::Pose(0), Value::Pose(Isometry3::identity()))
        .expect("insert");
    b.insert(Var::Pose(1), Value::Pose(iso(1.0, 0.0, 0.0, 0.0, 0.0, 0.0)))
        .expect("insert");
    b.add(Factor::Position {
        key: 1,
        position: Vector3::new(1.0, 0.0, 0.0),
        sigmas: Vector3::repeat(0.1),
    })
    .expect("fix");
    // A position alone leaves the rotation free: the solve or the marginal must say so.
    let _ = b.update(Scope::Full);
    match b.marginal_covariance(1) {
        Err(BackendError::Solver(_) | BackendError::Invalid(_)) => {}
        other => panic!("expected an error, got {other:?}"),
    }
    assert!(matches!(
        b.add(Factor::Position {
            key: 1,
            position: Vector3::new(f64::NAN, 0.0, 0.0),
            sigmas: Vector3::repeat(0.1),
        }),
        Err(BackendError::Invalid(_))
    ));
    assert!(matches!(
        b.add(Factor::Position {
            key: 1,
            position: Vector3::zeros(),
            sigmas: Vector3::new(0.1, 0.0, 0.1),
        }),
        Err(BackendError::Invalid(_))
    ));
}

/// The 6 × 6 difference relative to the reference's Frobenius norm.
fn relative_difference(a: &Matrix6<f64>, reference: &Matrix6<f64>) -> f64 {
    (a - reference).norm() / reference.norm()
}

#[test]
fn marginal_covariance_agrees_between_isam2_and_factrs() {
    // Guards the two native computations of the marginal against each other on a
    // nonlinear graph: the vineyard lap with noisy odometry, a closure across the rows and
    // GNSS-like fixes, solved in full. iSAM2 reads it from its Bayes tree at its last
    // linearisation point θ, factrs from the whole graph linearised at its estimate θ ⊕ δ,
    // δ the last full-update step. That step is what the stopping rule (an error decrease
    // under 1e-6 of χ² ≈ 2·10²) allows, at most ~0.02 σ whitened, i.e. ~1e-3 m and rad
    // here, and the Jacobians change relatively by as much over lever arms of metres: so
    // 1e-3 relative (measured: 1e-5 to 2e-5; pose 0, pinned by its prior, ~1e-8), while a
    // wrong block order, frame or factor would be O(1) off.
    let build = |name: &str| {
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let truth = lap(18, 3);
        let mut b = backend_named(name, 10, 30);
        odometry_chain(b.as_mut(), &truth, &mut rng, (0.01, 0.05));
        b.add(Factor::Between {
            from: 30,
            to: 8,
            from_from_to: truth[30].inverse() * truth[8],
            sigmas: sigmas(0.005, 0.02),
            robust: Robust::None,
        })
        .expect("closure");
        for i in [10, 25, 40] {
            b.add(Factor::Position {
                key: i,
                position: truth[i as usize].translation.vector,
                sigmas: Vector3::new(0.3, 0.3, 1.0),
            })
            .expect("fix");
        }
        b.update(Scope::Full).expect("update");
        b
    };
    let (isam2, factrs) = (build("isam2"), build("factrs"));
    let last = *isam2.pose_keys().last().expect("poses");
    for key in [last, 20, 0] {
        let a = isam2
            .marginal_covariance(key)
            .expect("isam2 marginal")
            .tangent;
        let f = factrs
            .marginal_covariance(key)
            .expect("factrs marginal")
            .tangent;
        let d = relative_difference(&a, &f);
        eprintln!("pose {key}: isam2 vs factrs marginal differ by {d:.2e} (relative)");
        assert!(d < 1e-3, "pose {key}: {d:e}\n{a}\n{f}");
    }
}
