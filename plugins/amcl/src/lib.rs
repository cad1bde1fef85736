//! Monte Carlo localisation in an occupancy grid after ROS AMCL (the `amcl` package of
//! `ros-planning/navigation`, what a Thorvald's navigation runs on its two 2D lidars): the
//! core of issue 46's `amcl` baseline, which localises in a grid built earlier (rtabmap's
//! from a mapping run, or the world's surveyed grid).
//!
//! Implemented from the published methods and AMCL's documented behaviour, not from its
//! code:
//! - Thrun, Burgard & Fox, *Probabilistic Robotics* (2005): the odometry motion model
//!   (`sample_motion_model_odometry`, §5.4), the likelihood-field range model (§6.4) and
//!   augmented MCL's recovery by random particles (§8.3.5);
//! - Fox, "Adapting the sample size in particle filters through KLD-sampling", IJRR 22(12),
//!   2003: the number of particles from the histogram's occupied bins;
//! - AMCL's parameters and defaults (the ROS wiki's `amcl` page and the package's
//!   `cfg/AMCL.cfg`), and where AMCL departs from the book, the departure, named where it is
//!   made (the beams' likelihoods summed as cubes, the KLD bound's `z`, the `diff` model's
//!   variances used as standard deviations).
//!
//! [`grid`] holds the map and its distance field, [`motion`] the odometry model, [`filter`]
//! the particle filter and its estimate, [`scan`] the two 2D lidars merged into one scan,
//! [`config`] the parameters, [`system`] the plugin.

pub mod config;
pub mod filter;
pub mod grid;
pub mod motion;
pub mod scan;
pub mod system;

/// A pose in the plane: position (metres) and heading (radians, in (-π, π]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    pub x: f64,
    pub y: f64,
    pub theta: f64,
}

impl Pose2 {
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self {
            x,
            y,
            theta: normalize(theta),
        }
    }

    /// `self ⊕ other`: `other`, given in this pose's frame, in the frame this pose is in.
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            self.theta + other.theta,
        )
    }

    /// The inverse transform: `self.inverse().compose(self)` is the identity.
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            -c * self.x - s * self.y,
            s * self.x - c * self.y,
            -self.theta,
        )
    }

    /// A point given in this pose's frame, in the frame this pose is in.
    pub fn transform(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.theta.sin_cos();
        [self.x + c * p[0] - s * p[1], self.y + s * p[0] + c * p[1]]
    }
}

/// An angle in (-π, π].
pub fn normalize(a: f64) -> f64 {
    let mut a = a % std::f64::consts::TAU;
    if a <= -std::f64::consts::PI {
        a += std::f64::consts::TAU;
    } else if a > std::f64::consts::PI {
        a -= std::f64::consts::TAU;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn composing_a_pose_with_its_inverse_gives_the_identity() {
        let p = Pose2::new(1.5, -2.0, 2.8);
        let q = p.compose(&p.inverse());
        assert!(
            q.x.abs() < 1e-12 && q.y.abs() < 1e-12 && q.theta.abs() < 1e-12,
            "{q:?}"
        );
        let r = Pose2::new(0.3, 0.4, -3.0);
        let back = p.inverse().compose(&p.compose(&r));
        assert!((back.x - r.x).abs() < 1e-12 && (back.y - r.y).abs() < 1e-12);
        assert!((normalize(back.theta - r.theta)).abs() < 1e-12);
        assert_eq!(normalize(3.0 * std::f64::consts::PI), std::f64::consts::PI);
    }
}
