//! The native iSAM2 backend's incremental machinery (Bayes tree top removal, orphans,
//! re-attachment, fluid relinearisation, wildfire back-substitution) against batch
//! solutions computed independently.

use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::factor_graph::backend::{
    Backend, BackendConfig, Factor, FactorId, Robust, Scope, Value, Var, from_config,
};

fn isam2(wildfire: f64) -> Box<dyn Backend> {
    from_config(&BackendConfig {
        name: "isam2".into(),
        wildfire_threshold: wildfire,
        max_iterations: 50,
        ..BackendConfig::default()
    })
    .expect("isam2")
}

fn sigmas(rot: f64, trans: f64) -> Vector6<f64> {
    Vector6::new(rot, rot, rot, trans, trans, trans)
}

/// A random pose graph: a random walk of `n` poses, odometry between neighbours and, from
/// each pose with probability `p_loop`, a closure to a random earlier pose; measurements
/// noisy (σ 0.02 m, `rot_sigma` rad; `rot_sigma` 0 keeps every rotation the identity,
/// which makes the problem linear in the translations).
struct RandomGraph {
    initial: Vec<Isometry3<f64>>,
    /// (from, to, from_from_to, sigmas)
    edges: Vec<(usize, usize, Isometry3<f64>, Vector6<f64>)>,
}

fn random_graph(seed: u64, n: usize, p_loop: f64, rot_sigma: f64) -> RandomGraph {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let trans = Normal::new(0.0, 0.02).expect("sigma");
    let mut truth = vec![Isometry3::identity()];
    for _ in 1..n {
        let step = Vector3::new(
            rng.random_range(0.5..1.0),
            rng.random_range(-0.5..0.5),
            rng.random_range(-0.2..0.2),
        );
        let turn = if rot_sigma > 0.0 {
            Vector3::new(0.05, -0.04, rng.random_range(-0.6..0.6))
        } else {
            Vector3::zeros()
        };
        let last = *truth.last().expect("non-empty");
        truth.push(last * Isometry3::new(step, turn));
    }
    let rot = Normal::new(0.0, rot_sigma.max(1e-12)).expect("sigma");
    let noisy = |z: Isometry3<f64>, rng: &mut ChaCha8Rng| {
        let dt = Vector3::from_fn(|_, _| trans.sample(rng));
        let dr = if rot_sigma > 0.0 {
            Vector3::from_fn(|_, _| rot.sample(rng))
        } else {
            Vector3::zeros()
        };
        z * Isometry3::new(dt, dr)
    };
    // Without rotation noise, rotations are held stiffly (1e-6 rad) so that the
    // translations decouple from them: the least-squares problem becomes linear.
    let s = sigmas(if rot_sigma > 0.0 { rot_sigma } else { 1e-6 }, 0.02);
    let mut edges = Vec::new();
    let mut initial = vec![truth[0]];
    for i in 1..n {
        let z = noisy(truth[i - 1].inverse() * truth[i], &mut rng);
        initial.push(initial[i - 1] * z);
        edges.push((i - 1, i, z, s));
        if i > 3 && rng.random_bool(p_loop) {
            let j = rng.random_range(0..i - 2);
            let z = noisy(truth[j].inverse() * truth[i], &mut rng);
            edges.push((j, i, z, s));
        }
    }
    RandomGraph { initial, edges }
}

/// Replays the graph pose by pose, one incremental update each; `after` sees the backend
/// after every update with the number of poses so far.
fn replay(
    b: &mut dyn Backend,
    g: &RandomGraph,
    mut after: impl FnMut(&dyn Backend, usize),
) -> Vec<FactorId> {
    let mut ids = Vec::new();
    b.insert(Var::Pose(0), Value::Pose(g.initial[0]))
        .expect("insert");
    ids.push(
        b.add(Factor::PosePrior {
            key: 0,
            world_from_body: g.initial[0],
            sigmas: sigmas(1e-3, 1e-3),
        })
        .expect("prior"),
    );
    b.update(Scope::Incremental).expect("update");
    for i in 1..g.initial.len() {
        let guess =
            b.pose(i as u64 - 1).expect("pose") * (g.initial[i - 1].inverse() * g.initial[i]);
        b.insert(Var::Pose(i as u64), Value::Pose(guess))
            .expect("insert");
        for &(from, to, z, s) in g.edges.iter().filter(|e| e.1 == i) {
            ids.push(
                b.add(Factor::Between {
                    from: from as u64,
                    to: to as u64,
                    from_from_to: z,
                    sigmas: s,
                    robust: Robust::None,
                })
                .expect("edge"),
            );
        }
        b.update(Scope::Incremental).expect("update");
        after(b, i + 1);
    }
    ids
}

/// The least-squares translations of a rotation-free graph with the first `n` poses
/// (prior on pose 0), solved densely: an answer independent of the backend.
fn linear_solution(g: &RandomGraph, n: usize, prior_sigma: f64) -> Vec<Vector3<f64>> {
    let mut h = DMatrix::zeros(3 * n, 3 * n);
    let mut rhs = DVector::zeros(3 * n);
    let w0 = 1.0 / (prior_sigma * prior_sigma);
    for k in 0..3 {
        h[(k, k)] += w0;
        rhs[k] += w0 * g.initial[0].translation.vector[k];
    }
    for &(from, to, z, s) in g.edges.iter().filter(|e| e.1 < n) {
        let w = 1.0 / (s[3] * s[3]);
        for k in 0..3 {
            let (a, b) = (3 * from + k, 3 * to + k);
            h[(a, a)] += w;
            h[(b, b)] += w;
            h[(a, b)] -= w;
            h[(b, a)] -= w;
            rhs[b] += w * z.translation.vector[k];
            rhs[a] -= w * z.translation.vector[k];
        }
    }
    let x = h.cholesky().expect("positive definite").solve(&rhs);
    (0..n)
        .map(|i| Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]))
        .collect()
}

fn worst_position_gap(b: &dyn Backend, reference: &[Vector3<f64>]) -> f64 {
    reference
        .iter()
        .enumerate()
        .map(|(i, r)| (b.pose(i as u64).expect("pose").translation.vector - r).norm())
        .fold(0.0, f64::max)
}

#[test]
fn every_incremental_update_equals_the_batch_solution_of_a_linear_graph() {
    // Guards the Bayes tree itself: on a graph that is linear (no rotations), exact
    // back-substitution (wildfire 0) must give the batch least-squares answer after
    // every update, however the loop closures reshape the tree.
    for seed in 0..4 {
        let g = random_graph(seed, 120, 0.25, 0.0);
        let mut b = isam2(0.0);
        let mut worst = 0.0f64;
        let mut checked = 0;
        replay(b.as_mut(), &g, |b, n| {
            if n % 7 == 0 || n == g.initial.len() {
                let gap = worst_position_gap(b, &linear_solution(&g, n, 1e-3));
                worst = worst.max(gap);
                checked += 1;
            }
        });
        eprintln!(
            "seed {seed}: {} edges, worst gap to the batch solution over {checked} checks: {worst:.2e} m",
            g.edges.len()
        );
        assert!(
            worst < 1e-6,
            "seed {seed}: {worst:.3e} m from the batch solution"
        );
    }
}

#[test]
fn wildfire_stays_within_its_threshold_of_the_exact_solution() {
    // Guards partial back-substitution: skipping subtrees whose separators moved less
    // than the threshold leaves the estimate within a small multiple of it.
    let g = random_graph(11, 150, 0.2, 0.0);
    let mut b = isam2(0.001);
    let mut worst = 0.0f64;
    replay(b.as_mut(), &g, |b, n| {
        worst = worst.max(worst_position_gap(b, &linear_solution(&g, n, 1e-3)));
    });
    eprintln!("wildfire 0.001: worst gap {worst:.2e} m");
    assert!(worst < 0.01, "{worst:.3e} m from the exact solution");
}

#[test]
fn incremental_replay_then_full_reaches_the_batch_optimum_of_a_nonlinear_graph() {
    // Guards relinearisation on a graph with rotations: the incremental replay with
    // GTSAM's default parameters ends near the optimum, and one full update reaches the
    // batch optimum of an independent solver (factrs, Levenberg–Marquardt).
    for seed in 0..3 {
        let g = random_graph(100 + seed, 100, 0.2, 0.01);
        let mut b = isam2(0.001);
        replay(b.as_mut(), &g, |_, _| {});
        let mut reference = from_config(&BackendConfig {
            name: "factrs".into(),
            max_iterations: 200,
            ..BackendConfig::default()
        })
        .expect("factrs");
        replay(reference.as_mut(), &g, |_, _| {});
        reference.update(Scope::Full).expect("full");
        let target: Vec<Vector3<f64>> = (0..g.initial.len())
            .map(|i| reference.pose(i as u64).expect("pose").translation.vector)
            .collect();
        let incremental = worst_position_gap(b.as_ref(), &target);
        let report = b.update(Scope::Full).expect("full");
        let full = worst_position_gap(b.as_ref(), &target);
        let rot = (0..g.initial.len() as u64)
            .map(|i| {
                let (p, q) = (b.pose(i).expect("pose"), reference.pose(i).expect("pose"));
                (p.rotation.inverse() * q.rotation).angle()
            })
            .fold(0.0, f64::max);
        eprintln!(
            "seed {seed}: incremental {incremental:.2e} m from the batch optimum, after a full update {full:.2e} m / {rot:.2e} rad ({} iterations)",
            report.iterations
        );
        assert!(incremental < 0.05, "incremental replay {incremental} m off");
        assert!(
            full < 1e-5 && rot < 1e-6,
            "full update {full} m, {rot} rad off"
        );
    }
}

#[test]
fn removing_a_loop_closure_restores_the_previous_estimate() {
    // Guards factor removal through the tree: the cliques of the removed factor's
    // variables are re-eliminated without it, and the estimate returns to what it was.
    let g = random_graph(21, 80, 0.1, 0.0);
    let mut b = isam2(0.0);
    replay(b.as_mut(), &g, |_, _| {});
    let before: Vec<Isometry3<f64>> = (0..80).map(|i| b.pose(i).expect("pose")).collect();
    let lie = Isometry3::from_parts(
        Translation3::new(2.0, -1.0, 0.3),
        UnitQuaternion::identity(),
    ) * (g.initial[10].inverse() * g.initial[70]);
    let id = b
        .add(Factor::Between {
            from: 10,
            to: 70,
            from_from_to: lie,
            sigmas: sigmas(1e-3, 0.02),
            robust: Robust::None,
        })
        .expect("loop");
    b.update(Scope::Incremental).expect("update");
    let dragged = (0..80)
        .map(|i| {
            (b.pose(i).expect("pose").translation.vector - before[i as usize].translation.vector)
                .norm()
        })
        .fold(0.0, f64::max);
    assert!(
        dragged > 0.1,
        "the false loop moved the graph only {dragged} m"
    );
    assert!(b.remove(id));
    b.update(Scope::Incremental).expect("update");
    let back = (0..80)
        .map(|i| {
            (b.pose(i).expect("pose").translation.vector - before[i as usize].translation.vector)
                .norm()
        })
        .fold(0.0, f64::max);
    eprintln!("false loop moved the graph {dragged:.3} m; after removal {back:.2e} m from before");
    assert!(
        back < 1e-6,
        "after removal {back} m from the previous estimate"
    );
}
