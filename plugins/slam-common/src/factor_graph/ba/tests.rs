use nalgebra::{DMatrix, DVector};

use super::ordering::reverse_cuthill_mckee;
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
