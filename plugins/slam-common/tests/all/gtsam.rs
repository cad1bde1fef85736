//! The "gtsam" backend (GTSAM 4.3's own ISAM2 and CombinedImuFactor through its Python
//! wrapper, plugins/gtsam-backend) against the native backends and against GTSAM's own
//! batch optimum of its pose3example graph.
//!
//! These tests need the bridge library (built beside this test binary by
//! `cargo build --release -p vinebench-gtsam`; cargo builds it with the workspace) and
//! the gtsam wheel (`bash scripts/setup.sh`). Without them they fail, saying which is
//! missing: they never skip.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Matrix6, Quaternion, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::factor_graph::backend::{
    Backend, BackendConfig, Factor, FactorId, ImuBias, ImuNoise, ImuSample, Robust, Scope, Value,
    Var, from_config,
};

const G: f64 = 9.80511;

fn backend(name: &str, max_iterations: usize) -> Box<dyn Backend> {
    from_config(&BackendConfig {
        name: name.into(),
        window: 1000,
        max_iterations,
        ..BackendConfig::default()
    })
    .unwrap_or_else(|e| panic!("{name} backend: {e}"))
}

fn sigmas(rot: f64, trans: f64) -> Vector6<f64> {
    Vector6::new(rot, rot, rot, trans, trans, trans)
}

fn iso(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

fn poses(b: &dyn Backend) -> Vec<Isometry3<f64>> {
    b.pose_keys()
        .into_iter()
        .map(|k| b.pose(k).expect("pose"))
        .collect()
}

/// Largest translation difference (m) and rotation angle (rad) between two trajectories.
fn worst(a: &[Isometry3<f64>], b: &[Isometry3<f64>]) -> (f64, f64) {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold((0.0, 0.0), |(t, r), (p, q)| {
        let dt = (p.translation.vector - q.translation.vector).norm();
        let dr = (p.rotation.inverse() * q.rotation).angle();
        (f64::max(t, dt), f64::max(r, dr))
    })
}

/// A loop of `n` poses on a tilted circle, odometry between neighbours with noise of σ
/// 0.005 rad / 0.02 m (so the loop does not close by itself), a prior on pose 0; the
/// initial estimate is dead reckoning. Returns the truth and the closure (n−1 → 0).
fn noisy_loop(b: &mut dyn Backend, n: usize, seed: u64) -> (Vec<Isometry3<f64>>, Factor) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (rot_n, trans_n) = (
        Normal::new(0.0, 0.005).expect("normal"),
        Normal::new(0.0, 0.02).expect("normal"),
    );
    let truth: Vec<Isometry3<f64>> = (0..n)
        .map(|i| {
            let a = 2.0 * PI * i as f64 / n as f64;
            iso(
                5.0 * a.cos(),
                5.0 * a.sin(),
                0.5 * (2.0 * a).sin(),
                0.1 * a.sin(),
                0.05 * a.cos(),
                a + PI / 2.0,
            )
        })
        .collect();
    let odo_sigmas = sigmas(0.005, 0.02);
    let mut dead = truth[0];
    for (i, t) in truth.iter().enumerate() {
        if i > 0 {
            let noise = Isometry3::new(
                Vector3::from_fn(|_, _| trans_n.sample(&mut rng)),
                Vector3::from_fn(|_, _| rot_n.sample(&mut rng)),
            );
            let z = truth[i - 1].inverse() * t * noise;
            dead *= z;
            b.insert(Var::Pose(i as u64), Value::Pose(dead))
                .expect("insert");
            b.add(Factor::Between {
                from: i as u64 - 1,
                to: i as u64,
                from_from_to: z,
                sigmas: odo_sigmas,
                robust: Robust::None,
            })
            .expect("odometry");
        } else {
            b.insert(Var::Pose(0), Value::Pose(*t)).expect("insert");
            b.add(Factor::PosePrior {
                key: 0,
                world_from_body: *t,
                sigmas: sigmas(1e-3, 1e-3),
            })
            .expect("prior");
        }
    }
    let closure = Factor::Between {
        from: n as u64 - 1,
        to: 0,
        from_from_to: truth[n - 1].inverse() * truth[0],
        sigmas: sigmas(0.01, 0.02),
        robust: Robust::None,
    };
    (truth, closure)
}

#[test]
fn gtsam_loop_full_solve_matches_factrs_to_1e6() {
    let solve = |name: &str| {
        let mut b = backend(name, 100);
        let (truth, closure) = noisy_loop(b.as_mut(), 10, 11);
        b.add(closure).expect("closure");
        let report = b.update(Scope::Full).expect("update");
        (poses(b.as_ref()), truth, report)
    };
    let (gtsam, truth, g_report) = solve("gtsam");
    let (factrs, _, f_report) = solve("factrs");
    let (dt, dr) = worst(&gtsam, &factrs);
    let (tt, tr) = worst(&gtsam, &truth);
    eprintln!(
        "10-pose loop: gtsam vs factrs {dt:.2e} m, {dr:.2e} rad; gtsam vs truth {tt:.3} m, \
         {tr:.4} rad\n  gtsam {g_report:?}\n  factrs {f_report:?}"
    );
    assert!(
        dt < 1e-6 && dr < 1e-6,
        "gtsam and factrs differ: {dt:e} m, {dr:e} rad"
    );
    // Both report 2 × the nonlinear error (Σ‖r‖²) of the whole graph for a full update.
    assert!(
        (g_report.error_after - f_report.error_after).abs() < 1e-6 * f_report.error_after.max(1.0),
        "χ²: gtsam {} factrs {}",
        g_report.error_after,
        f_report.error_after
    );
    assert!(
        (g_report.error_before - f_report.error_before).abs()
            < 1e-9 * f_report.error_before.max(1.0),
        "χ² before: gtsam {} factrs {}",
        g_report.error_before,
        f_report.error_before
    );
}

#[test]
fn gtsam_loop_full_solve_matches_isam2_to_1e6() {
    let solve = |name: &str| {
        let mut b = backend(name, 100);
        let (_, closure) = noisy_loop(b.as_mut(), 10, 11);
        // Incremental first (as a plugin would, keyframe by keyframe), then the closure
        // and a full update.
        b.update(Scope::Incremental).expect("incremental");
        b.add(closure).expect("closure");
        b.update(Scope::Full).expect("update");
        poses(b.as_ref())
    };
    let (dt, dr) = worst(&solve("gtsam"), &solve("isam2"));
    eprintln!("10-pose loop: gtsam vs isam2 {dt:.2e} m, {dr:.2e} rad");
    assert!(
        dt < 1e-6 && dr < 1e-6,
        "gtsam and isam2 differ: {dt:e} m, {dr:e} rad"
    );
}

#[test]
fn gtsam_removing_the_loop_factor_restores_the_previous_estimate() {
    let mut b = backend("gtsam", 100);
    let (_, closure) = noisy_loop(b.as_mut(), 10, 5);
    b.update(Scope::Incremental).expect("incremental");
    b.update(Scope::Full).expect("full");
    let before = poses(b.as_ref());
    // A robust closure, so that factor_error (which ignores the kernel) is checked too.
    let Factor::Between {
        from,
        to,
        from_from_to,
        sigmas,
        ..
    } = closure
    else {
        unreachable!()
    };
    let id = b
        .add(Factor::Between {
            from,
            to,
            from_from_to,
            sigmas,
            robust: Robust::Huber(1.345),
        })
        .expect("closure");
    let unsolved = b.factor_error(id).expect("closure error");
    b.update(Scope::Full).expect("full");
    let closed = poses(b.as_ref());
    let solved = b.factor_error(id).expect("closure error");
    let (moved, _) = worst(&before, &closed);
    assert!(moved > 0.05, "the closure moved the loop by only {moved} m");
    assert!(
        solved < unsolved,
        "closure error {unsolved} σ before, {solved} σ after"
    );
    assert!(b.remove(id), "remove the closure");
    assert!(!b.remove(id), "a removed factor is unknown");
    assert!(!b.remove(FactorId(9999)), "an unknown factor");
    assert!(b.factor_error(id).is_none());
    let report = b.update(Scope::Full).expect("full");
    let (dt, dr) = worst(&before, &poses(b.as_ref()));
    eprintln!(
        "closure moved the loop by {moved:.3} m (error {unsolved:.1} σ → {solved:.2} σ); \
         removed: back within {dt:.2e} m, {dr:.2e} rad; {report:?}"
    );
    assert!(dt < 1e-6 && dr < 1e-6, "not restored: {dt:e} m, {dr:e} rad");
}

/// A smooth 3D trajectory and what an ideal IMU on it reads.
struct Motion;

impl Motion {
    fn pos(t: f64) -> Vector3<f64> {
        Vector3::new(
            2.0 * (0.5 * t).sin() + 0.8 * t,
            1.5 * (1.0 - (0.4 * t).cos()),
            0.2 * (0.6 * t).sin(),
        )
    }
    fn rot(t: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(
            0.1 * (0.7 * t).sin(),
            0.08 * (0.5 * t).cos(),
            0.5 * t + 0.2 * (0.3 * t).sin(),
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
    /// Specific force in the body frame: R⁻¹·(p̈ + g·ẑ), +g up at rest.
    fn accel(t: f64) -> Vector3<f64> {
        let h = 1e-3;
        let a = (Self::pos(t + h) - 2.0 * Self::pos(t) + Self::pos(t - h)) / (h * h);
        Self::rot(t).inverse() * (a + Vector3::new(0.0, 0.0, G))
    }
}

/// 200 Hz samples over [t0, t1), each read at its interval's midpoint, plus `bias`.
fn imu_samples(t0: f64, t1: f64, bias: &ImuBias) -> Vec<ImuSample> {
    let n = ((t1 - t0) * 200.0).round() as usize;
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

/// Four keyframes a second apart joined by IMU factors from exact samples (with a constant
/// bias), the first keyframe's pose and velocity known, the bias loosely: the other three
/// keyframes come from the IMU alone, starting from a guess 0.3 m and 0.05 rad off.
fn imu_graph(name: &str, bias: &ImuBias) -> Box<dyn Backend> {
    let mut b = backend(name, 50);
    let keyframes = 4;
    for k in 0..keyframes {
        let t = k as f64;
        let guess = Motion::pose(t) * iso(0.3, -0.2, 0.1, 0.02, -0.03, 0.05);
        b.insert(Var::Pose(k), Value::Pose(guess)).expect("insert");
        b.insert(Var::Velocity(k), Value::Velocity(Vector3::zeros()))
            .expect("insert");
        b.insert(Var::Bias(k), Value::Bias(ImuBias::default()))
            .expect("insert");
        if k > 0 {
            b.add(Factor::Imu {
                from: k - 1,
                to: k,
                samples: imu_samples(t - 1.0, t, bias),
                noise: ImuNoise::default(),
            })
            .expect("imu");
        }
    }
    b.add(Factor::PosePrior {
        key: 0,
        world_from_body: Motion::pose(0.0),
        sigmas: sigmas(1e-3, 1e-3),
    })
    .expect("pose prior");
    b.add(Factor::VelocityPrior {
        key: 0,
        velocity_mps: Motion::vel(0.0),
        sigma_mps: 1e-3,
    })
    .expect("velocity prior");
    b.add(Factor::BiasPrior {
        key: 0,
        bias: *bias,
        sigma_accel: 0.01,
        sigma_gyro: 1e-3,
    })
    .expect("bias prior");
    b
}

#[test]
fn gtsam_imu_keyframes_follow_the_true_motion() {
    let bias = ImuBias {
        accel_mps2: Vector3::new(0.05, -0.04, 0.08),
        gyro_rps: Vector3::new(0.003, -0.002, 0.001),
    };
    let mut b = imu_graph("gtsam", &bias);
    let report = b.update(Scope::Full).expect("update");
    let mut worst_dp = 0.0f64;
    let mut worst_dr = 0.0f64;
    let mut worst_dv = 0.0f64;
    for k in 0..4u64 {
        let t = k as f64;
        let p = b.pose(k).expect("pose");
        let dp = (p.translation.vector - Motion::pos(t)).norm();
        let dr = (p.rotation.inverse() * Motion::rot(t)).angle();
        let Some(Value::Velocity(v)) = b.value(Var::Velocity(k)) else {
            panic!("no velocity {k}")
        };
        let dv = (v - Motion::vel(t)).norm();
        (worst_dp, worst_dr, worst_dv) = (worst_dp.max(dp), worst_dr.max(dr), worst_dv.max(dv));
    }
    eprintln!(
        "IMU keyframes: worst position {worst_dp:.2e} m, rotation {worst_dr:.2e} rad, \
         velocity {worst_dv:.2e} m/s; {report:?}"
    );
    assert!(worst_dp < 0.01, "position off by {worst_dp} m");
    assert!(worst_dr < 2e-3, "rotation off by {worst_dr} rad");
    assert!(worst_dv < 0.01, "velocity off by {worst_dv} m/s");
}

#[test]
fn gtsam_imu_keyframes_match_the_native_backends() {
    let bias = ImuBias {
        accel_mps2: Vector3::new(0.05, -0.04, 0.08),
        gyro_rps: Vector3::new(0.003, -0.002, 0.001),
    };
    let solve = |name: &str| {
        let mut b = imu_graph(name, &bias);
        b.update(Scope::Full).expect("update");
        poses(b.as_ref())
    };
    let reference = solve("gtsam");
    for native in ["factrs", "isam2"] {
        let (dt, dr) = worst(&reference, &solve(native));
        eprintln!("IMU keyframes: gtsam vs {native} {dt:.2e} m, {dr:.2e} rad");
        // Two preintegration implementations (GTSAM's, and factrs's under both native
        // backends) on the same exact samples.
        assert!(
            dt < 1e-3 && dr < 1e-4,
            "gtsam and {native} differ: {dt:e} m, {dr:e} rad"
        );
    }
}

/// One pose of a fixture file: `key tx ty tz qx qy qz qw`.
fn parse_pose(fields: &[&str]) -> Isometry3<f64> {
    let v: Vec<f64> = fields.iter().map(|f| f.parse().expect("number")).collect();
    Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_quaternion(Quaternion::new(v[6], v[3], v[4], v[5])),
    )
}

/// `# name value` from a fixture's header.
fn header_value(text: &str, name: &str) -> f64 {
    text.lines()
        .find_map(|l| l.strip_prefix(&format!("# {name} ")))
        .unwrap_or_else(|| panic!("no {name} in the fixture"))
        .trim()
        .parse()
        .expect("number")
}

#[test]
fn gtsam_pose3example_reaches_gtsams_batch_optimum() {
    let g2o = include_str!("../fixtures/pose3example.txt");
    let fixture = include_str!("../fixtures/pose3example.gtsam.txt");
    let optimum: Vec<Isometry3<f64>> = fixture
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| parse_pose(&l.split_whitespace().collect::<Vec<_>>()[1..]))
        .collect();
    let solve = |name: &str| {
        let mut b = backend(name, 100);
        for line in g2o.lines() {
            let f: Vec<&str> = line.split_whitespace().collect();
            match f.first() {
                Some(&"VERTEX_SE3:QUAT") => {
                    let key = f[1].parse().expect("key");
                    b.insert(Var::Pose(key), Value::Pose(parse_pose(&f[2..9])))
                        .expect("insert");
                }
                Some(&"EDGE_SE3:QUAT") => {
                    // Every edge of this file has the information 10⁴·I: σ = 0.01.
                    let info: Vec<f64> = f[10..].iter().map(|x| x.parse().expect("info")).collect();
                    assert_eq!(info.len(), 21);
                    let diagonal = [0, 6, 11, 15, 18, 20];
                    assert!(
                        info.iter()
                            .enumerate()
                            .all(|(i, &x)| { x == if diagonal.contains(&i) { 1e4 } else { 0.0 } })
                    );
                    b.add(Factor::Between {
                        from: f[1].parse().expect("key"),
                        to: f[2].parse().expect("key"),
                        from_from_to: parse_pose(&f[3..10]),
                        sigmas: sigmas(0.01, 0.01),
                        robust: Robust::None,
                    })
                    .expect("edge");
                }
                _ => {}
            }
        }
        // Pose3SLAMExample_g2o.py's prior: variances 1e-6 (rotation), 1e-4 (translation).
        b.add(Factor::PosePrior {
            key: 0,
            world_from_body: Isometry3::identity(),
            sigmas: sigmas(1e-3, 1e-2),
        })
        .expect("prior");
        let report = b.update(Scope::Full).expect("update");
        (poses(b.as_ref()), report)
    };
    let initial_error = header_value(fixture, "initial_error");
    let final_error = header_value(fixture, "final_error");
    let (gtsam, report) = solve("gtsam");
    let (dt, dr) = worst(&gtsam, &optimum);
    eprintln!(
        "pose3example: gtsam's ISAM2 vs GTSAM's Gauss-Newton {dt:.2e} m, {dr:.2e} rad; \
         error {} → {} (fixture: {initial_error} → {final_error}); {report:?}",
        report.error_before / 2.0,
        report.error_after / 2.0
    );
    assert!(
        dt < 1e-6 && dr < 1e-6,
        "{dt:e} m, {dr:e} rad from GTSAM's optimum"
    );
    assert!((report.error_before / 2.0 - initial_error).abs() < 1e-9 * initial_error);
    assert!((report.error_after / 2.0 - final_error).abs() < 1e-9 * final_error);
}

/// A helix-like route, a pose per metre, with noisy odometry (σ 0.005 rad, 0.02 m) and a
/// prior on pose 0: pose `i` and its odometry factor added by `add`.
struct Chain {
    truth: Vec<Isometry3<f64>>,
    odometry: Vec<Isometry3<f64>>,
    dead: Vec<Isometry3<f64>>,
}

impl Chain {
    fn new(n: usize, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (rot_n, trans_n) = (
            Normal::new(0.0, 0.005).expect("normal"),
            Normal::new(0.0, 0.02).expect("normal"),
        );
        let truth: Vec<Isometry3<f64>> = (0..n)
            .map(|i| {
                let s = i as f64;
                iso(
                    8.0 * (0.08 * s).sin(),
                    8.0 * (1.0 - (0.08 * s).cos()),
                    0.3 * (0.2 * s).sin(),
                    0.05 * (0.3 * s).sin(),
                    0.04 * (0.25 * s).cos(),
                    0.08 * s,
                )
            })
            .collect();
        let mut odometry = vec![Isometry3::identity()];
        let mut dead = vec![truth[0]];
        for i in 1..n {
            let noise = Isometry3::new(
                Vector3::from_fn(|_, _| trans_n.sample(&mut rng)),
                Vector3::from_fn(|_, _| rot_n.sample(&mut rng)),
            );
            let z = truth[i - 1].inverse() * truth[i] * noise;
            dead.push(dead[i - 1] * z);
            odometry.push(z);
        }
        Self {
            truth,
            odometry,
            dead,
        }
    }

    fn add(&self, b: &mut dyn Backend, i: usize) {
        b.insert(Var::Pose(i as u64), Value::Pose(self.dead[i]))
            .expect("insert");
        if i == 0 {
            b.add(Factor::PosePrior {
                key: 0,
                world_from_body: self.truth[0],
                sigmas: sigmas(1e-3, 1e-2),
            })
            .expect("prior");
        } else {
            b.add(Factor::Between {
                from: i as u64 - 1,
                to: i as u64,
                from_from_to: self.odometry[i],
                sigmas: sigmas(0.005, 0.02),
                robust: Robust::None,
            })
            .expect("odometry");
        }
    }
}

fn fix(chain: &Chain, i: usize) -> Factor {
    // 0.4 m off the truth, as a biased single-point fix would be.
    Factor::Position {
        key: i as u64,
        position: chain.truth[i].translation.vector + Vector3::new(0.4, -0.3, 0.2),
        sigmas: Vector3::new(0.5, 0.5, 1.0),
    }
}

#[test]
fn gtsam_position_priors_match_the_native_backends() {
    // Guards the "gtsam" backend's position factor (GTSAM's GPSFactor) against ours on
    // the same graph: the three optima must agree, and the fixes must have moved the
    // chain by far more (so that a factor silently dropped would show). 1e-5 m / 1e-6
    // rad: the native full updates stop once an iteration lowers the error by less than
    // 1e-6 of it, GTSAM's loop at 1e-14; on this graph that leaves iSAM2 1.7e-6 m short
    // of GTSAM's optimum, five orders below the fixes' pull.
    let chain = Chain::new(40, 3);
    let solve = |name: &str, fixes: bool| {
        let mut b = backend(name, 100);
        for i in 0..chain.truth.len() {
            chain.add(b.as_mut(), i);
        }
        let mut ids = Vec::new();
        if fixes {
            for i in [10, 20, 30, 39] {
                ids.push(b.add(fix(&chain, i)).expect("fix"));
            }
        }
        // Before the solve the fixes' whitened errors (factor_error, GTSAM's through
        // sqrt(2·error)) are those of dead reckoning: the same numbers on every backend.
        let errors: Vec<f64> = ids
            .iter()
            .map(|&id| b.factor_error(id).expect("error"))
            .collect();
        b.update(Scope::Full).expect("update");
        (poses(b.as_ref()), errors)
    };
    let (reference, reference_errors) = solve("gtsam", true);
    let (moved, _) = worst(&reference, &solve("gtsam", false).0);
    assert!(moved > 0.1, "the fixes moved the chain by only {moved} m");
    for native in ["isam2", "factrs"] {
        let (native_poses, errors) = solve(native, true);
        for (g, n) in reference_errors.iter().zip(&errors) {
            assert!(
                (g - n).abs() < 1e-9 * g,
                "fix error: gtsam {g} σ, {native} {n} σ"
            );
        }
        let (dt, dr) = worst(&reference, &native_poses);
        eprintln!(
            "chain with fixes: gtsam vs {native} {dt:.2e} m, {dr:.2e} rad (fixes moved it {moved:.3} m)"
        );
        assert!(
            dt < 1e-5 && dr < 1e-6,
            "gtsam and {native} differ: {dt:e} m, {dr:e} rad"
        );
    }
}

#[test]
fn gtsam_marginal_covariance_grows_shrinks_and_matches_the_native_backends() {
    // Guards ISAM2::marginalCovariance through the bridge (its 6 × 6 order, rotation then
    // translation in the body frame, and the row-major transfer) against the native
    // backends' marginals: the newest pose's translation variance grows along the
    // odometry chain and falls after a position prior, and the three agree. All three
    // linearise at the same optimum after a full solve (their estimates agree to ~1e-6,
    // the test above), so their matrices differ by the Jacobians' change over such steps
    // (measured: ~1e-13 on the odometry chain, whose dead reckoning is its optimum; 2e-7
    // after the fix); 1e-4 leaves a margin while a transposed or reordered block would be
    // O(1) off.
    let chain = Chain::new(30, 9);
    let mut backends: Vec<(&str, Box<dyn Backend>)> = ["gtsam", "isam2", "factrs"]
        .into_iter()
        .map(|name| (name, backend(name, 100)))
        .collect();
    let difference = |a: &Matrix6<f64>, b: &Matrix6<f64>| (a - b).norm() / b.norm();
    let mut previous = 0.0;
    let mut added = 0;
    for stage in [10, 20, 30] {
        let newest = stage as u64 - 1;
        let mut covs = Vec::new();
        for (name, b) in &mut backends {
            for i in added..stage {
                chain.add(b.as_mut(), i);
            }
            b.update(Scope::Full).expect("update");
            covs.push((*name, b.marginal_covariance(newest).expect("marginal")));
        }
        added = stage;
        let (_, gtsam) = covs[0];
        let trace = gtsam.translation_world().trace();
        eprintln!("pose {newest}: translation variance (trace) {trace:.5} m²");
        assert!(
            trace > previous,
            "grows along the chain: {trace} after {previous}"
        );
        previous = trace;
        for (name, cov) in &covs[1..] {
            let d = difference(&cov.tangent, &gtsam.tangent);
            eprintln!("  gtsam vs {name}: {d:.2e} relative");
            assert!(
                d < 1e-4,
                "pose {newest}: gtsam vs {name} {d:e}\n{}\n{}",
                gtsam.tangent,
                cov.tangent
            );
        }
    }
    let mut covs = Vec::new();
    for (name, b) in &mut backends {
        b.add(fix(&chain, 29)).expect("fix");
        b.update(Scope::Full).expect("update");
        covs.push((*name, b.marginal_covariance(29).expect("marginal")));
    }
    let (_, gtsam) = covs[0];
    let trace = gtsam.translation_world().trace();
    eprintln!("pose 29 after a fix: translation variance (trace) {trace:.5} m²");
    assert!(
        trace < previous,
        "shrinks after the fix: {trace} from {previous}"
    );
    for (name, cov) in &covs[1..] {
        let d = difference(&cov.tangent, &gtsam.tangent);
        eprintln!("  gtsam vs {name}: {d:.2e} relative");
        assert!(d < 1e-4, "after the fix: gtsam vs {name} {d:e}");
    }
}
