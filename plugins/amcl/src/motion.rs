//! The odometry motion model (Thrun, Burgard & Fox 2005, §5.4, `sample_motion_model_odometry`)
//! as AMCL applies it: the odometry's motion between two filter updates split into a first
//! rotation, a translation and a second rotation, each disturbed per particle.
//!
//! Two departures of AMCL from the book, kept because they are what AMCL's users run:
//! - the rotations' noise is computed from the rotation folded onto [0, π/2] (a robot driving
//!   backwards is not a robot that turned around), and a translation under 1 cm has no first
//!   rotation;
//! - in the default `diff` model the noise expressions (variances in the book) are passed as
//!   standard deviations; `diff-corrected` takes their square roots, as the book does.

use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::config::OdomModel;
use crate::{Pose2, normalize};

/// The odometry's motion between two updates, decomposed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdomDelta {
    pub rot1: f64,
    pub trans: f64,
    pub rot2: f64,
    /// The rotations folded onto [0, π/2], for the noise.
    rot1_noise: f64,
    rot2_noise: f64,
}

impl OdomDelta {
    /// The motion from odometry pose `old` to `new` (both `odom_from_base`).
    pub fn between(old: &Pose2, new: &Pose2) -> Self {
        let (dx, dy) = (new.x - old.x, new.y - old.y);
        let trans = dx.hypot(dy);
        let rot1 = if trans < 0.01 {
            0.0
        } else {
            normalize(dy.atan2(dx) - old.theta)
        };
        let rot2 = normalize(new.theta - old.theta - rot1);
        let fold = |a: f64| {
            normalize(a)
                .abs()
                .min(normalize(a - std::f64::consts::PI).abs())
        };
        Self {
            rot1,
            trans,
            rot2,
            rot1_noise: fold(rot1),
            rot2_noise: fold(rot2),
        }
    }

    /// A particle at `pose` moved by this motion, disturbed by the model's noise
    /// (`alphas`: AMCL's `odom_alpha1`..`4`).
    pub fn sample(
        &self,
        pose: &Pose2,
        model: OdomModel,
        alphas: [f64; 4],
        rng: &mut impl Rng,
    ) -> Pose2 {
        let [a1, a2, a3, a4] = alphas;
        let t2 = self.trans * self.trans;
        let spread = |expression: f64| match model {
            OdomModel::Diff => expression,
            OdomModel::DiffCorrected => expression.sqrt(),
        };
        let mut draw = |sigma: f64| {
            if sigma > 0.0 {
                Normal::new(0.0, sigma).expect("finite sigma").sample(rng)
            } else {
                0.0
            }
        };
        let rot1 = normalize(self.rot1 - draw(spread(a1 * self.rot1_noise.powi(2) + a2 * t2)));
        let trans = self.trans
            - draw(spread(
                a3 * t2 + a4 * self.rot1_noise.powi(2) + a4 * self.rot2_noise.powi(2),
            ));
        let rot2 = normalize(self.rot2 - draw(spread(a1 * self.rot2_noise.powi(2) + a2 * t2)));
        Pose2::new(
            pose.x + trans * (pose.theta + rot1).cos(),
            pose.y + trans * (pose.theta + rot1).sin(),
            pose.theta + rot1 + rot2,
        )
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn without_noise_a_particle_moves_as_the_odometry_did_in_its_own_frame() {
        let old = Pose2::new(1.0, 2.0, 0.3);
        let new = Pose2::new(1.8, 2.9, 1.1);
        let particle = Pose2::new(-4.0, 7.0, -2.0);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let moved =
            OdomDelta::between(&old, &new).sample(&particle, OdomModel::Diff, [0.0; 4], &mut rng);
        let expected = particle.compose(&old.inverse().compose(&new));
        assert!((moved.x - expected.x).abs() < 1e-12 && (moved.y - expected.y).abs() < 1e-12);
        assert!(normalize(moved.theta - expected.theta).abs() < 1e-12);
        // Backwards: the first rotation is π, folded to 0 for the noise.
        let back = OdomDelta::between(&Pose2::new(0.0, 0.0, 0.0), &Pose2::new(-1.0, 0.0, 0.0));
        assert!((back.rot1.abs() - std::f64::consts::PI).abs() < 1e-12);
        assert!(back.rot1_noise.abs() < 1e-12);
    }

    /// One metre straight on, `odom_alpha3` 0.2 alone: the translation's spread is 0.2 m
    /// under `diff` (the variance expression used as σ) and √0.2 m under `diff-corrected`.
    #[test]
    fn diff_uses_the_variance_as_sigma_and_diff_corrected_its_root() {
        let delta = OdomDelta::between(&Pose2::default(), &Pose2::new(1.0, 0.0, 0.0));
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for (model, sigma) in [
            (OdomModel::Diff, 0.2),
            (OdomModel::DiffCorrected, 0.2f64.sqrt()),
        ] {
            let xs: Vec<f64> = (0..20_000)
                .map(|_| {
                    delta
                        .sample(&Pose2::default(), model, [0.0, 0.0, 0.2, 0.0], &mut rng)
                        .x
                })
                .collect();
            let mean = xs.iter().sum::<f64>() / xs.len() as f64;
            let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64).sqrt();
            assert!((mean - 1.0).abs() < 0.01, "{model:?}: mean {mean}");
            assert!(
                (sd - sigma).abs() < 0.01 * sigma.max(0.2) * 2.0,
                "{model:?}: σ {sd} not {sigma}"
            );
        }
    }
}
