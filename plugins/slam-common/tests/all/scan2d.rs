//! 3-DoF ICP on simulated planar scans: a vineyard row (two lines of trunks with foliage
//! clutter) and a corridor of two walls, scanned like the simulator's front 2D lidar
//! (720 samples over −2.18…2.36 rad, σ = 0.01 m range noise).

use nalgebra::{Isometry2, Vector2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam_common::registration::scan2d::{
    Icp2dConfig, Icp2dTarget, TargetFeature, icp2d, points_from_ranges,
};

const ANGLE_MIN: f64 = -2.18;
const ANGLE_MAX: f64 = 2.36;
const SAMPLES: usize = 720;
const RANGE_MIN: f64 = 0.1;
const RANGE_MAX: f64 = 30.0;

#[derive(Debug, Clone, Copy)]
enum Shape {
    Circle { centre: Vector2<f64>, radius: f64 },
    Segment { a: Vector2<f64>, b: Vector2<f64> },
}

/// Distance along the unit ray `o + t d` to the first surface, if any.
fn cast(shapes: &[Shape], o: &Vector2<f64>, d: &Vector2<f64>) -> Option<f64> {
    let mut best: Option<f64> = None;
    for s in shapes {
        let t = match *s {
            Shape::Circle { centre, radius } => {
                let m = o - centre;
                let b = m.dot(d);
                let disc = b * b - (m.norm_squared() - radius * radius);
                if disc < 0.0 {
                    continue;
                }
                -b - disc.sqrt()
            }
            Shape::Segment { a, b } => {
                let e = b - a;
                let denom = d.x * e.y - d.y * e.x;
                if denom.abs() < 1e-12 {
                    continue;
                }
                let w = a - o;
                let t = (w.x * e.y - w.y * e.x) / denom;
                let u = (w.x * d.y - w.y * d.x) / denom;
                if !(0.0..=1.0).contains(&u) {
                    continue;
                }
                t
            }
        };
        if t > 1e-6 && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best
}

fn increment() -> f64 {
    (ANGLE_MAX - ANGLE_MIN) / (SAMPLES - 1) as f64
}

/// A ROS-style scan (`+inf` for no return) from `world_from_sensor`.
fn scan(shapes: &[Shape], world_from_sensor: &Isometry2<f64>, rng: &mut ChaCha8Rng) -> Vec<f32> {
    let noise = Normal::new(0.0, 0.01).expect("sigma");
    let o = world_from_sensor.translation.vector;
    (0..SAMPLES)
        .map(|i| {
            let a = ANGLE_MIN + i as f64 * increment();
            let d = world_from_sensor.rotation * Vector2::new(a.cos(), a.sin());
            match cast(shapes, &o, &d) {
                Some(t) if (RANGE_MIN..=RANGE_MAX).contains(&t) => (t + noise.sample(rng)) as f32,
                _ => f32::INFINITY,
            }
        })
        .collect()
}

fn points(ranges: &[f32]) -> Vec<Vector2<f64>> {
    points_from_ranges(ANGLE_MIN, increment(), ranges, RANGE_MIN, RANGE_MAX)
}

/// Two rows 3 m apart (y = ±1.5) of trunks of radius 5 cm every metre, with foliage: tufts
/// of 2–8 cm around the rows.
fn vineyard(rng: &mut ChaCha8Rng) -> Vec<Shape> {
    let mut shapes = Vec::new();
    for row in [-1.5, 1.5] {
        for k in -30..=30 {
            shapes.push(Shape::Circle {
                centre: Vector2::new(k as f64, row),
                radius: 0.05,
            });
        }
        for _ in 0..90 {
            shapes.push(Shape::Circle {
                centre: Vector2::new(
                    rng.random_range(-30.0..30.0),
                    row + rng.random_range(-0.25..0.25),
                ),
                radius: rng.random_range(0.02..0.08),
            });
        }
    }
    shapes
}

fn corridor() -> Vec<Shape> {
    [-1.5, 1.5]
        .map(|y| Shape::Segment {
            a: Vector2::new(-80.0, y),
            b: Vector2::new(80.0, y),
        })
        .to_vec()
}

fn errors(estimate: &Isometry2<f64>, truth: &Isometry2<f64>) -> (f64, f64) {
    let err = estimate.inverse() * truth;
    (err.translation.vector.norm(), err.rotation.angle().abs())
}

/// The target scan from the origin, the source after `truth` (`target_from_source`).
fn pair(
    shapes: &[Shape],
    truth: &Isometry2<f64>,
    seed: u64,
) -> (Vec<Vector2<f64>>, Vec<Vector2<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let target = points(&scan(shapes, &Isometry2::identity(), &mut rng));
    let source = points(&scan(shapes, truth, &mut rng));
    (target, source)
}

#[test]
fn recovers_a_motion_along_a_vine_row() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let shapes = vineyard(&mut rng);
    let truth = Isometry2::new(Vector2::new(0.1, 0.02), 2f64.to_radians());
    let config = Icp2dConfig::default();
    for seed in 0..5 {
        let (target, source) = pair(&shapes, &truth, 100 + seed);
        let prepared = Icp2dTarget::new(&target, &config);
        let lines = (0..prepared.len())
            .filter(|&i| matches!(prepared.feature(i), TargetFeature::Line { .. }))
            .count();
        eprintln!(
            "vineyard: {lines} of {} target points on lines",
            prepared.len()
        );
        for initial in [
            Isometry2::identity(),
            truth * Isometry2::new(Vector2::new(-0.06, 0.04), (-1.5f64).to_radians()),
        ] {
            let result = icp2d(&source, &prepared, initial, &config).expect("registered");
            let (dt, dr) = errors(&result.target_from_source, &truth);
            eprintln!(
                "vineyard seed {seed}: error {:.2} mm {:.4} deg, {} inliers ratio {:.2} rmse {:.1} mm, {} iterations, eigenvalues {:?}",
                dt * 1e3,
                dr.to_degrees(),
                result.inliers,
                result.correspondence_ratio,
                result.rmse_m * 1e3,
                result.iterations,
                result.eigenvalues.as_slice()
            );
            assert!(dt < 0.01 && dr < 0.2f64.to_radians(), "{dt} m {dr} rad");
            assert!(result.converged);
            assert!(!result.is_degenerate(), "{:?}", result.eigenvalues);
            assert!(result.correspondence_ratio > 0.6);
            assert!(result.rmse_m < 0.04);
            let info = nalgebra::SymmetricEigen::new(result.information);
            assert!(info.eigenvalues.min() > 0.0, "{:?}", result.information);
        }
    }
}

#[test]
fn corridor_keeps_the_guess_along_the_walls() {
    let truth = Isometry2::new(Vector2::new(0.1, 0.02), 2f64.to_radians());
    let (target, source) = pair(&corridor(), &truth, 7);
    let config = Icp2dConfig::default();
    let prepared = Icp2dTarget::new(&target, &config);
    // Wrong by 0.25 m along the corridor, 3 cm across, 1.5°.
    let initial = Isometry2::new(Vector2::new(0.35, -0.01), 0.5f64.to_radians());
    let result = icp2d(&source, &prepared, initial, &config).expect("registered");
    let lines = (0..prepared.len())
        .filter(|&i| matches!(prepared.feature(i), TargetFeature::Line { .. }))
        .count();
    eprintln!(
        "corridor: {lines} of {} target points on lines",
        prepared.len()
    );
    let pose = result.target_from_source;
    eprintln!(
        "corridor: estimate {:?} (truth {:?}), eigenvalues {:?}, degenerate {:?}",
        pose,
        truth,
        result.eigenvalues.as_slice(),
        result.degenerate_directions
    );
    assert_eq!(result.degenerate_directions.len(), 1);
    let d = result.degenerate_directions[0];
    // Along the walls: the target's x axis seen from the source, Rᵀ x̂.
    assert!(d[1].abs() > 0.99, "{d:?}");
    assert!(
        (pose.translation.x - initial.translation.x).abs() < 0.005,
        "along the corridor the guess stands: {} vs {}",
        pose.translation.x,
        initial.translation.x
    );
    assert!((pose.translation.y - truth.translation.y).abs() < 0.01);
    assert!((pose.rotation.angle() - truth.rotation.angle()).abs() < 0.2f64.to_radians());
    // The information says the same: weak along the walls.
    let along = nalgebra::Vector3::new(0.0, 1.0, 0.0);
    let across = nalgebra::Vector3::new(0.0, 0.0, 1.0);
    assert!(
        along.dot(&(result.information * along))
            < 0.05 * across.dot(&(result.information * across))
    );
}

#[test]
fn rejects_a_far_guess_and_disjoint_scans() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let shapes = vineyard(&mut rng);
    let truth = Isometry2::new(Vector2::new(0.1, 0.02), 2f64.to_radians());
    let (target, source) = pair(&shapes, &truth, 3);
    let config = Icp2dConfig::default();
    let prepared = Icp2dTarget::new(&target, &config);
    let lenient = Icp2dConfig {
        min_correspondences: 0,
        min_correspondence_ratio: 0.0,
        ..config.clone()
    };
    // Half a row spacing sideways: each source row lies between the target's.
    let sideways = truth * Isometry2::new(Vector2::new(0.0, 1.5), 0.0);
    // Turned across the rows.
    let turned = truth * Isometry2::new(Vector2::zeros(), 90f64.to_radians());
    for (name, initial) in [("sideways", sideways), ("turned", turned)] {
        assert_eq!(icp2d(&source, &prepared, initial, &config), None, "{name}");
        if let Some(r) = icp2d(&source, &prepared, initial, &lenient) {
            eprintln!("{name}: ratio {:.3}", r.correspondence_ratio);
            assert!(
                r.correspondence_ratio < 0.2,
                "{name}: {}",
                r.correspondence_ratio
            );
        }
    }
    // A scan of somewhere else: a corridor 4 m wide.
    let elsewhere: Vec<Shape> = [-2.0, 2.0]
        .map(|y| Shape::Segment {
            a: Vector2::new(-50.0, y),
            b: Vector2::new(50.0, y),
        })
        .to_vec();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let other = points(&scan(&elsewhere, &Isometry2::identity(), &mut rng));
    assert_eq!(
        icp2d(&other, &prepared, Isometry2::identity(), &config),
        None,
        "disjoint"
    );
    if let Some(r) = icp2d(&other, &prepared, Isometry2::identity(), &lenient) {
        eprintln!("disjoint: ratio {:.3}", r.correspondence_ratio);
        assert!(
            r.correspondence_ratio < 0.2,
            "disjoint: {}",
            r.correspondence_ratio
        );
    }
}

#[test]
fn registration_is_deterministic_and_identity_on_itself() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let shapes = vineyard(&mut rng);
    let truth = Isometry2::new(Vector2::new(0.1, 0.02), 2f64.to_radians());
    let (target, source) = pair(&shapes, &truth, 5);
    let config = Icp2dConfig::default();
    let a = icp2d(&source, &Icp2dTarget::new(&target, &config), truth, &config);
    let b = icp2d(&source, &Icp2dTarget::new(&target, &config), truth, &config);
    assert!(a.is_some());
    assert_eq!(a, b);
    let same = icp2d(
        &target,
        &Icp2dTarget::new(&target, &config),
        Isometry2::identity(),
        &config,
    )
    .expect("itself");
    let (dt, dr) = errors(&same.target_from_source, &Isometry2::identity());
    assert!(dt < 1e-9 && dr < 1e-9, "{dt} {dr}");
    assert_eq!(same.correspondence_ratio, 1.0);
}
