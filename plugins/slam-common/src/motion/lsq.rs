//! Gauss–Newton on SE(3) for point-to-feature residuals, with the degeneracy handling of
//! Zhang, Kaess and Singh ("On Degeneracy of Optimization-based State Estimation
//! Problems", ICRA 2016) that LOAM and LIO-SAM use: directions of the normal matrix whose
//! eigenvalue is below a threshold are not updated, so that a scan that cannot fix a
//! direction (a featureless corridor, a vine row seen end-on) leaves the prior guess there.
//!
//! The update is a right perturbation about the sensor, `world_from_x ← world_from_x ∘
//! (Exp(δθ), δt)`, as LOAM linearises about the sensor's own origin, so that the
//! eigen-directions of the normal matrix — and with them the degeneracy test — do not
//! depend on where the world's origin is. A point `p` (in the frame `x`) moves by
//! `R (δθ × p + δt)`, and a scalar residual with gradient `g = ∂r/∂q` at `q = world_from_x ·
//! p` has the Jacobian `[(p × gₓ)ᵀ, gₓᵀ]` with `gₓ = Rᵀ g`.

use nalgebra::{
    Isometry3, Matrix6, SymmetricEigen, Translation3, UnitQuaternion, Vector3, Vector6,
};

/// The normal equations `H δ = b` accumulated from weighted scalar residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalEquations {
    pub h: Matrix6<f64>,
    pub b: Vector6<f64>,
    /// Σ w r².
    pub cost: f64,
    pub count: usize,
}

impl Default for NormalEquations {
    fn default() -> Self {
        Self {
            h: Matrix6::zeros(),
            b: Vector6::zeros(),
            cost: 0.0,
            count: 0,
        }
    }
}

/// The outcome of one solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// `[δθ; δt]`.
    pub delta: Vector6<f64>,
    /// How many of the six directions were too weakly observed to update.
    pub degenerate_directions: usize,
}

impl NormalEquations {
    /// Adds residual `r` of the point `p` (in the frame `x`), whose gradient rotated into
    /// that frame is `g_in_x`, with weight `w`.
    pub fn add(&mut self, p: &Vector3<f64>, g_in_x: &Vector3<f64>, r: f64, w: f64) {
        let g = g_in_x;
        let c = p.cross(g);
        let j = Vector6::new(c.x, c.y, c.z, g.x, g.y, g.z);
        self.h += w * j * j.transpose();
        self.b -= w * r * j;
        self.cost += w * r * r;
        self.count += 1;
    }

    pub fn merge(mut self, other: &Self) -> Self {
        self.h += other.h;
        self.b += other.b;
        self.cost += other.cost;
        self.count += other.count;
        self
    }

    /// Solves for the update, leaving out directions whose eigenvalue of `H` is below
    /// `min_eigenvalue`. None if nothing could be solved.
    pub fn solve(&self, min_eigenvalue: f64) -> Option<Step> {
        if self.count < 6 {
            return None;
        }
        let eig = SymmetricEigen::new(self.h);
        let mut delta = Vector6::zeros();
        let mut degenerate = 0;
        for i in 0..6 {
            let lambda = eig.eigenvalues[i];
            let v = eig.eigenvectors.column(i);
            if lambda < min_eigenvalue.max(1e-12) {
                degenerate += 1;
                continue;
            }
            delta += v * (v.dot(&self.b) / lambda);
        }
        delta.iter().all(|x| x.is_finite()).then_some(Step {
            delta,
            degenerate_directions: degenerate,
        })
    }
}

/// Applies an update `[δθ; δt]` to `world_from_x` (on the right, in the frame `x`).
pub fn apply(delta: &Vector6<f64>, world_from_x: &Isometry3<f64>) -> Isometry3<f64> {
    let rot = UnitQuaternion::from_scaled_axis(Vector3::new(delta[0], delta[1], delta[2]));
    let step = Isometry3::from_parts(Translation3::new(delta[3], delta[4], delta[5]), rot);
    let mut out = world_from_x * step;
    out.rotation.renormalize();
    out
}

/// True when an update is small enough to stop: rotation below `rot_rad`, translation
/// below `trans_m`.
pub fn converged(delta: &Vector6<f64>, rot_rad: f64, trans_m: f64) -> bool {
    delta.fixed_rows::<3>(0).norm() < rot_rad && delta.fixed_rows::<3>(3).norm() < trans_m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three orthogonal planes fix all six degrees of freedom; Gauss–Newton on
    /// point-to-plane residuals recovers a known offset.
    #[test]
    fn recovers_an_offset_from_three_planes() {
        let truth = Isometry3::from_parts(
            Translation3::new(0.2, -0.1, 0.05),
            UnitQuaternion::from_euler_angles(0.02, -0.01, 0.05),
        );
        let mut points = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                let (u, v) = (i as f64 * 0.3 + 0.5, j as f64 * 0.3 + 0.5);
                points.push((Vector3::new(0.0, u, v), Vector3::x()));
                points.push((Vector3::new(u, 0.0, v), Vector3::y()));
                points.push((Vector3::new(u, v, 0.0), Vector3::z()));
            }
        }
        // Points on the planes x=0, y=0, z=0 of the world, seen from `truth`.
        let seen: Vec<_> = points
            .iter()
            .map(|(p, n)| (truth.inverse() * nalgebra::Point3::from(*p), *n))
            .collect();
        let mut estimate = Isometry3::identity();
        for _ in 0..10 {
            let mut ne = NormalEquations::default();
            for (p, n) in &seen {
                let q = (estimate * p).coords;
                ne.add(
                    &p.coords,
                    &(estimate.rotation.inverse() * n),
                    n.dot(&q),
                    1.0,
                );
            }
            let step = ne.solve(1e-6).expect("well conditioned");
            assert_eq!(step.degenerate_directions, 0);
            estimate = apply(&step.delta, &estimate);
        }
        let err = estimate.inverse() * truth;
        assert!(
            err.translation.vector.norm() < 1e-9 && err.rotation.angle() < 1e-9,
            "residual offset {err:?}"
        );
    }

    /// A single plane observes only three directions; the other three stay put.
    #[test]
    fn leaves_unobserved_directions_alone() {
        let mut ne = NormalEquations::default();
        for i in 0..20 {
            let q = Vector3::new(i as f64 * 0.1, (i % 5) as f64 * 0.2, 0.1);
            ne.add(&q, &Vector3::z(), 0.1, 1.0);
        }
        let step = ne.solve(1e-3).expect("partly observed");
        assert_eq!(
            step.degenerate_directions, 3,
            "a plane fixes z, roll and pitch only"
        );
        assert!(
            step.delta[3].abs() < 1e-9 && step.delta[4].abs() < 1e-9 && step.delta[2].abs() < 1e-9,
            "{:?}",
            step.delta
        );
    }
}
