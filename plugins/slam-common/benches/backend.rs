//! Backend cost, factrs and the native iSAM2 side by side: the per-keyframe incremental update at growing graph sizes (must stay
//! flat), and a full solve of a 2000-keyframe vineyard graph after loop closures.
//!
//! `cargo bench -p vinebench-slam-common --bench backend`

use std::hint::black_box;

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::factor_graph::backend::{
    Backend, BackendConfig, Factor, FactrsBackend, Isam2Backend, Robust, Scope, Value, Var,
};

const ROWS: usize = 8;
const ROW_LEN: usize = 18;
const GAP: usize = 3;

/// Laps of a vineyard, one keyframe per metre: up and down `ROWS` rows 18 m long and
/// 3 m apart, then back along the headland to the start.
fn route(n: usize) -> Vec<Isometry3<f64>> {
    let (l, g) = (ROW_LEN as f64, GAP as f64);
    let mut corners = vec![(0.0, 0.0)];
    for r in 0..ROWS {
        let y = r as f64 * g;
        let (a, b) = if r % 2 == 0 { (0.0, l) } else { (l, 0.0) };
        if r > 0 {
            corners.push((a, y));
        }
        corners.push((b, y));
    }
    corners.push((0.0, 0.0));
    let mut lap = Vec::new();
    for w in corners.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        let steps = (x1 - x0).abs().max((y1 - y0).abs()) as usize;
        let yaw = (y1 - y0).atan2(x1 - x0);
        for i in 0..steps {
            let s = i as f64 / steps as f64;
            let (x, y) = (x0 + s * (x1 - x0), y0 + s * (y1 - y0));
            let z = 0.15 * (0.5 * x).sin() + 0.1 * (0.7 * y).cos();
            lap.push(Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(0.03 * x.sin(), 0.04 * x.cos(), yaw),
            ));
        }
    }
    lap.iter().cycle().take(n).copied().collect()
}

fn lap_len() -> usize {
    ROWS * ROW_LEN + (ROWS - 1) * GAP + (ROWS - 1) * GAP
}

/// Odometry from the truth with noise, and a loop closure every 5th keyframe to the same
/// place one lap earlier (robust, as a plugin would add them).
struct Sim {
    truth: Vec<Isometry3<f64>>,
    rng: ChaCha8Rng,
}

impl Sim {
    fn noisy(&mut self, z: Isometry3<f64>, rot: f64, trans: f64) -> Isometry3<f64> {
        let (r, t) = (
            Normal::new(0.0, rot).expect("sigma"),
            Normal::new(0.0, trans).expect("sigma"),
        );
        let rng = &mut self.rng;
        let tv = Vector3::from_fn(|_, _| t.sample(rng));
        let rv = Vector3::from_fn(|_, _| r.sample(rng));
        z * Isometry3::new(tv, rv)
    }

    /// Adds keyframe `i` (its guess from the current estimate and the odometry).
    fn add_keyframe(&mut self, b: &mut dyn Backend, i: usize) {
        let sig = |r, t| Vector6::new(r, r, r, t, t, t);
        if i == 0 {
            b.insert(Var::Pose(0), Value::Pose(self.truth[0]))
                .expect("insert");
            b.add(Factor::PosePrior {
                key: 0,
                world_from_body: self.truth[0],
                sigmas: sig(1e-3, 1e-3),
            })
            .expect("prior");
            return;
        }
        let z = self.noisy(self.truth[i - 1].inverse() * self.truth[i], 0.01, 0.05);
        let prev = b.pose(i as u64 - 1).expect("previous pose");
        b.insert(Var::Pose(i as u64), Value::Pose(prev * z))
            .expect("insert");
        b.add(Factor::Between {
            from: i as u64 - 1,
            to: i as u64,
            from_from_to: z,
            sigmas: sig(0.01, 0.05),
            robust: Robust::None,
        })
        .expect("odometry");
        let lap = lap_len();
        if i >= lap && i % 5 == 0 {
            let z = self.noisy(self.truth[i - lap].inverse() * self.truth[i], 0.005, 0.02);
            b.add(Factor::Between {
                from: (i - lap) as u64,
                to: i as u64,
                from_from_to: z,
                sigmas: sig(0.005, 0.02),
                robust: Robust::Huber(1.345),
            })
            .expect("closure");
        }
    }
}

fn config() -> BackendConfig {
    BackendConfig {
        window: 20,
        max_iterations: 10,
        ..BackendConfig::default()
    }
}

/// A graph of `n` keyframes built as a plugin would: one incremental update each.
fn grown<B: Backend>(mut b: B, n: usize, sim: &mut Sim) -> B {
    for i in 0..n {
        sim.add_keyframe(&mut b, i);
        b.update(Scope::Incremental).expect("update");
    }
    b
}

/// The update adding keyframe `n` to a graph of keyframes `0..n`: `kind` "odometry" (`n`
/// not a multiple of 5: one odometry factor) or "loop" (a multiple of 5 past the first
/// lap: odometry and a closure to the same place one lap earlier).
fn incremental_on<B: Backend + Clone>(
    c: &mut Criterion,
    name: &str,
    kind: &str,
    sizes: &[usize],
    make: impl Fn() -> B,
) {
    let mut group = c.benchmark_group(format!("{kind}_update/{name}"));
    group.sample_size(30);
    for &n in sizes {
        let mut sim = Sim {
            truth: route(n + 1),
            rng: ChaCha8Rng::seed_from_u64(1),
        };
        let base = grown(make(), n, &mut sim);
        let mut probe = base.clone();
        sim.add_keyframe(&mut probe, n);
        let report = probe.update(Scope::Incremental).expect("update");
        eprintln!("{name} {kind} update at {n} keyframes: {report:?}");
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |bench, &n| {
            bench.iter_batched(
                || {
                    let mut b = base.clone();
                    let mut s = Sim {
                        truth: sim.truth.clone(),
                        rng: ChaCha8Rng::seed_from_u64(2),
                    };
                    s.add_keyframe(&mut b, n);
                    b
                },
                // Returning the graph keeps dropping it out of the measurement.
                |mut b| {
                    black_box(b.update(Scope::Incremental).expect("update"));
                    b
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

fn incremental(c: &mut Criterion) {
    let odometry = [101, 501, 1001, 2001];
    let loops = [500, 1000, 2000];
    incremental_on(c, "factrs", "odometry", &odometry, || {
        FactrsBackend::new(&config())
    });
    incremental_on(c, "isam2", "odometry", &odometry, || {
        Isam2Backend::new(&config())
    });
    incremental_on(
        c,
        "factrs",
        "loop",
        &loops,
        || FactrsBackend::new(&config()),
    );
    incremental_on(c, "isam2", "loop", &loops, || Isam2Backend::new(&config()));
}

fn full_on<B: Backend + Clone>(c: &mut Criterion, name: &str, mut b: B) {
    let n = 2000;
    let mut sim = Sim {
        truth: route(n),
        rng: ChaCha8Rng::seed_from_u64(1),
    };
    // Dead reckoning plus closures, never optimised: the state after a run of odometry.
    for i in 0..n {
        sim.add_keyframe(&mut b, i);
    }
    let mut probe = b.clone();
    let report = probe.update(Scope::Full).expect("full");
    eprintln!("{name} full solve of {n} keyframes: {report:?}");
    let mut group = c.benchmark_group(format!("full_solve/{name}"));
    group.sample_size(10);
    group.bench_function(BenchmarkId::from_parameter(n), |bench| {
        bench.iter_batched(
            || b.clone(),
            |mut b| {
                black_box(b.update(Scope::Full).expect("full"));
                b
            },
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

fn full(c: &mut Criterion) {
    full_on(c, "factrs", FactrsBackend::new(&config()));
    full_on(c, "isam2", Isam2Backend::new(&config()));
}

criterion_group!(benches, incremental, full);
criterion_main!(benches);
