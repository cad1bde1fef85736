//! Local shape of a handful of neighbouring points, as LOAM (Zhang and Singh, RSS 2014)
//! uses them: a line through edge points when one principal direction dominates, a plane
//! through planar points when all of them lie close to it.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// A line through `point` along the unit vector `direction`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub point: Vector3<f64>,
    pub direction: Vector3<f64>,
}

/// The plane `normal · x + offset = 0`, `normal` a unit vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub normal: Vector3<f64>,
    pub offset: f64,
}

impl Line {
    /// Distance of `q` from the line and the unit gradient of that distance.
    pub fn residual(&self, q: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let d = q - self.point;
        let perp = d - self.direction * self.direction.dot(&d);
        let r = perp.norm();
        if r < 1e-12 {
            (0.0, Vector3::zeros())
        } else {
            (r, perp / r)
        }
    }
}

impl Plane {
    pub fn distance(&self, q: &Vector3<f64>) -> f64 {
        self.normal.dot(q) + self.offset
    }
}

fn mean_and_covariance(points: &[Vector3<f64>]) -> (Vector3<f64>, Matrix3<f64>) {
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    let cov = points
        .iter()
        .map(|p| (p - mean) * (p - mean).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    (mean, cov)
}

/// A line if the largest principal variance exceeds `ratio` times the second (LOAM: 3).
pub fn fit_line(points: &[Vector3<f64>], ratio: f64) -> Option<Line> {
    if points.len() < 2 {
        return None;
    }
    let (mean, cov) = mean_and_covariance(points);
    let [_, l1, l0] = eigenvalues(&cov);
    (l0 > ratio * l1.max(0.0) && l0 > 0.0).then(|| Line {
        point: mean,
        direction: eigenvector(&cov, l0),
    })
}

/// The least-squares plane, if every point lies within `max_distance_m` of it (LOAM: 0.2 m).
pub fn fit_plane(points: &[Vector3<f64>], max_distance_m: f64) -> Option<Plane> {
    if points.len() < 3 {
        return None;
    }
    let (mean, cov) = mean_and_covariance(points);
    let [l2, _, _] = eigenvalues(&cov);
    let normal = eigenvector(&cov, l2);
    let plane = Plane {
        normal,
        offset: -normal.dot(&mean),
    };
    points
        .iter()
        .all(|p| plane.distance(p).abs() <= max_distance_m)
        .then_some(plane)
}

/// Eigenvalues of a symmetric 3×3 matrix, ascending, in closed form (Smith, "Eigenvalues
/// of a symmetric 3 × 3 matrix", CACM 1961): an order of magnitude cheaper than an
/// iterative decomposition, which matters when every feature point of every iteration
/// fits a line or a plane.
pub fn eigenvalues(a: &Matrix3<f64>) -> [f64; 3] {
    let p1 = a[(0, 1)].powi(2) + a[(0, 2)].powi(2) + a[(1, 2)].powi(2);
    let q = a.trace() / 3.0;
    let p2 = (a[(0, 0)] - q).powi(2) + (a[(1, 1)] - q).powi(2) + (a[(2, 2)] - q).powi(2) + 2.0 * p1;
    if p2 <= 1e-300 {
        return [q; 3];
    }
    let p = (p2 / 6.0).sqrt();
    let b = (a - Matrix3::identity() * q) / p;
    let r = (b.determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    [smallest, 3.0 * q - largest - smallest, largest]
}

/// A unit eigenvector of the symmetric `a` for its eigenvalue `lambda`: the largest cross
/// product of two rows of `a − λI`, which is orthogonal to both.
pub fn eigenvector(a: &Matrix3<f64>, lambda: f64) -> Vector3<f64> {
    let m = a - Matrix3::identity() * lambda;
    let (r0, r1, r2) = (
        m.row(0).transpose(),
        m.row(1).transpose(),
        m.row(2).transpose(),
    );
    let candidates = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)];
    let best = candidates
        .iter()
        .max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))
        .copied()
        .unwrap_or_default();
    if best.norm_squared() > 1e-24 * m.norm_squared().powi(2).max(1e-300) {
        return best.normalize();
    }
    // λ is (nearly) repeated: fall back to the iterative decomposition.
    let eig = SymmetricEigen::new(*a);
    let i = (0..3)
        .min_by(|&i, &j| {
            (eig.eigenvalues[i] - lambda)
                .abs()
                .total_cmp(&(eig.eigenvalues[j] - lambda).abs())
        })
        .unwrap_or(0);
    eig.eigenvectors.column(i).into_owned().normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_eigen_matches_the_iterative_one() {
        let a = Matrix3::new(2.0, 0.3, -0.1, 0.3, 1.0, 0.05, -0.1, 0.05, 0.02);
        let eig = SymmetricEigen::new(a);
        let mut expected: Vec<f64> = eig.eigenvalues.iter().copied().collect();
        expected.sort_by(f64::total_cmp);
        let got = eigenvalues(&a);
        for (g, e) in got.iter().zip(&expected) {
            assert!((g - e).abs() < 1e-12, "eigenvalues {got:?} vs {expected:?}");
        }
        for lambda in got {
            let v = eigenvector(&a, lambda);
            assert!(
                (a * v - v * lambda).norm() < 1e-10,
                "A v = λ v for λ = {lambda}"
            );
        }
        // A repeated eigenvalue still gives an eigenvector.
        let d = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 3.0));
        let v = eigenvector(&d, 1.0);
        assert!((d * v - v).norm() < 1e-12);
    }

    #[test]
    fn lines_and_planes_are_told_apart() {
        let on_line: Vec<_> = (0..5)
            .map(|i| Vector3::new(1.0, 2.0, i as f64 * 0.1))
            .collect();
        let line = fit_line(&on_line, 3.0).expect("collinear points make a line");
        assert!((line.direction.z.abs() - 1.0).abs() < 1e-9);
        let (r, g) = line.residual(&Vector3::new(1.5, 2.0, 0.7));
        assert!((r - 0.5).abs() < 1e-12 && (g - Vector3::x()).norm() < 1e-12);
        assert!(
            fit_plane(&on_line, 0.2).is_some(),
            "collinear points also lie on a plane"
        );

        let on_plane = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.4)]
            .map(|(x, y)| Vector3::new(x, y, 3.0 + 0.01 * x));
        assert!(
            fit_line(&on_plane, 3.0).is_none(),
            "a square patch is not a line"
        );
        let plane = fit_plane(&on_plane, 0.2).expect("coplanar");
        assert!((plane.distance(&Vector3::new(0.3, 0.3, 4.0)).abs() - 0.997).abs() < 1e-3);
        let mut bent = on_plane.to_vec();
        bent.push(Vector3::new(0.5, 0.5, 4.0));
        assert!(
            fit_plane(&bent, 0.2).is_none(),
            "a point 1 m off the plane rejects it"
        );
    }
}
