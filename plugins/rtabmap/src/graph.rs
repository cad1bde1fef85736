//! The map graph (Labbé and Michaud 2019, §3.3): one pose per location, `map_from_base`,
//! joined by odometry links and loop-closure links, on the shared backend.
//!
//! After a loop closure the whole graph is optimised, and the closure is kept only if no
//! link is then strained beyond `RGBD/OptimizeMaxError` times its standard deviation
//! (translation and rotation judged apart); otherwise its factor is removed and the graph
//! optimised again, which returns every pose to the optimum without the closure (RTAB-Map
//! restores the poses it saved; re-solving does the same on every backend, including GTSAM's
//! ISAM2, which cannot overwrite an estimate it holds). A false loop between two
//! identical-looking rows has to bend many odometry links by metres to be satisfied, which
//! this check sees.
//!
//! Position priors (RTAB-Map's GPS priors, [`crate::gps`]) are self-links: they take no
//! part in that check (RTAB-Map's `graph::computeMaxGraphErrors` skips links from a node to
//! itself), and the first one loosens the first location's anchor, as RTAB-Map's GTSAM
//! optimiser does when the graph holds a GPS prior (`OptimizerGTSAM::optimize`).

use nalgebra::{Isometry3, Vector3, Vector6};
use slam_common::factor_graph::backend::{
    self, Backend, BackendConfig, BackendError, Factor, FactorId, Profiled, Robust, Scope, Value,
    Var,
};

/// Standard deviations of a link: rotation (rad) and translation (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sigmas {
    pub rad: f64,
    pub m: f64,
}

impl Sigmas {
    fn vector(&self) -> Vector6<f64> {
        Vector6::new(self.rad, self.rad, self.rad, self.m, self.m, self.m)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkKind {
    Odometry,
    Loop,
}

#[derive(Debug, Clone, Copy)]
struct Link {
    from: u64,
    to: u64,
    from_from_to: Isometry3<f64>,
    sigmas: Sigmas,
    kind: LinkKind,
}

/// The most strained link after an optimisation, in standard deviations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Strain {
    pub from: u64,
    pub to: u64,
    pub kind: LinkKind,
    /// max(translation error / σ_m, rotation error / σ_rad).
    pub ratio: f64,
}

/// What became of a loop closure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LoopOutcome {
    Accepted(Strain),
    /// Rejected by `optimize_max_error`; the closure is removed and the graph re-optimised
    /// without it: every pose is at the optimum of the graph as it was before the closure
    /// (where it already was if the last update had converged, to the solver's tolerance).
    Rejected(Strain),
}

/// The first node's anchor: the pose it is held at and the factor that holds it.
#[derive(Debug, Clone, Copy)]
struct Root {
    pose: Isometry3<f64>,
    factor: FactorId,
    /// Loosened for position priors.
    loose: bool,
}

/// The first node's anchor: standard deviation of each of its rotations and coordinates
/// (rad, m).
pub const ANCHOR_SIGMA: f64 = 1e-4;

#[derive(Debug)]
pub struct PoseGraph {
    /// Every update timed (`profile_csv`).
    pub backend: Profiled,
    links: Vec<Link>,
    nodes: Vec<u64>,
    optimize_max_error: f64,
    root: Option<(u64, Root)>,
    /// Position priors added.
    priors: usize,
}

impl PoseGraph {
    pub fn new(cfg: &BackendConfig, optimize_max_error: f64) -> Result<Self, BackendError> {
        Ok(Self {
            backend: Profiled::new(backend::from_config(cfg)?),
            links: Vec::new(),
            nodes: Vec::new(),
            optimize_max_error,
            root: None,
            priors: 0,
        })
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn pose(&self, id: u64) -> Option<Isometry3<f64>> {
        self.backend.pose(id)
    }

    /// Adds the first node, anchored where it is.
    pub fn add_first(
        &mut self,
        id: u64,
        map_from_base: Isometry3<f64>,
    ) -> Result<(), BackendError> {
        self.backend
            .insert(Var::Pose(id), Value::Pose(map_from_base))?;
        let factor = self.backend.add(Factor::PosePrior {
            key: id,
            world_from_body: map_from_base,
            sigmas: Vector6::repeat(ANCHOR_SIGMA),
        })?;
        self.root = Some((
            id,
            Root {
                pose: map_from_base,
                factor,
                loose: false,
            },
        ));
        self.nodes.push(id);
        Ok(())
    }

    /// Adds a prior on node `id`'s position (`sigmas` in m, per axis of the map frame) and
    /// optimises the whole graph, as RTAB-Map does when a new location has a prior link
    /// (`Rtabmap::process`: "prior edge" is one of the reasons to optimise).
    ///
    /// The first one replaces the first node's anchor by one with `root_sigmas`
    /// (`[roll, pitch, yaw, x, y, z]`, rad and m) at the same pose: with the map to be put
    /// where the priors say, the first node may move too (RTAB-Map's GTSAM optimiser sets
    /// its root prior's variances by whether the graph holds a GPS prior, at every batch
    /// optimisation; here the graph is kept between updates, so the anchor is swapped once).
    pub fn add_position_prior(
        &mut self,
        id: u64,
        position: Vector3<f64>,
        sigmas: Vector3<f64>,
        root_sigmas: Vector6<f64>,
    ) -> Result<(), BackendError> {
        if self.backend.pose(id).is_none() {
            return Err(BackendError::MissingVariable(Var::Pose(id)));
        }
        if let Some((root_id, root)) = &mut self.root
            && !root.loose
        {
            if !self.backend.remove(root.factor) {
                return Err(BackendError::Solver(format!(
                    "the first node's anchor {:?} could not be removed",
                    root.factor
                )));
            }
            root.factor = self.backend.add(Factor::PosePrior {
                key: *root_id,
                world_from_body: root.pose,
                sigmas: root_sigmas,
            })?;
            root.loose = true;
        }
        self.backend.add(Factor::Position {
            key: id,
            position,
            sigmas,
        })?;
        self.priors += 1;
        self.backend.update(Scope::Full)?;
        Ok(())
    }

    /// Position priors added.
    pub fn priors(&self) -> usize {
        self.priors
    }

    /// Adds node `to` after node `from` by an odometry link, starting at `from`'s estimate
    /// composed with the link, and updates incrementally.
    pub fn add_odometry(
        &mut self,
        from: u64,
        to: u64,
        from_from_to: Isometry3<f64>,
        sigmas: Sigmas,
    ) -> Result<(), BackendError> {
        let start = self
            .backend
            .pose(from)
            .ok_or(BackendError::MissingVariable(Var::Pose(from)))?
            * from_from_to;
        self.backend.insert(Var::Pose(to), Value::Pose(start))?;
        self.add_link(from, to, from_from_to, sigmas, Robust::None)?;
        self.links.push(Link {
            from,
            to,
            from_from_to,
            sigmas,
            kind: LinkKind::Odometry,
        });
        self.nodes.push(to);
        self.backend.update(Scope::Incremental)?;
        Ok(())
    }

    fn add_link(
        &mut self,
        from: u64,
        to: u64,
        from_from_to: Isometry3<f64>,
        sigmas: Sigmas,
        robust: Robust,
    ) -> Result<FactorId, BackendError> {
        self.backend.add(Factor::Between {
            from,
            to,
            from_from_to,
            sigmas: sigmas.vector(),
            robust,
        })
    }

    /// Adds a loop closure, optimises the whole graph, and keeps the closure only if no link
    /// is strained beyond `optimize_max_error` (0: always keeps it).
    pub fn add_loop(
        &mut self,
        from: u64,
        to: u64,
        from_from_to: Isometry3<f64>,
        sigmas: Sigmas,
    ) -> Result<LoopOutcome, BackendError> {
        let factor = self.add_link(from, to, from_from_to, sigmas, Robust::None)?;
        self.links.push(Link {
            from,
            to,
            from_from_to,
            sigmas,
            kind: LinkKind::Loop,
        });
        self.backend.update(Scope::Full)?;
        let strain = self.worst_link();
        if self.optimize_max_error > 0.0 && strain.ratio > self.optimize_max_error {
            // Backend-neutral restore: without the closure's factor a full optimisation
            // returns to the optimum of the graph as it was (`set_value` is refused by
            // the gtsam backend once ISAM2 holds a variable).
            if !self.backend.remove(factor) {
                return Err(BackendError::Solver(format!(
                    "the rejected loop closure's factor {factor:?} could not be removed"
                )));
            }
            self.links.pop();
            self.backend.update(Scope::Full)?;
            return Ok(LoopOutcome::Rejected(strain));
        }
        Ok(LoopOutcome::Accepted(strain))
    }

    /// The link whose optimised relative pose is farthest from its measurement.
    pub fn worst_link(&self) -> Strain {
        let mut worst = Strain {
            from: 0,
            to: 0,
            kind: LinkKind::Odometry,
            ratio: 0.0,
        };
        for link in &self.links {
            let (Some(a), Some(b)) = (self.backend.pose(link.from), self.backend.pose(link.to))
            else {
                continue;
            };
            let error = link.from_from_to.inverse() * (a.inverse() * b);
            let ratio = (error.translation.vector.norm() / link.sigmas.m)
                .max(error.rotation.angle() / link.sigmas.rad);
            if ratio > worst.ratio {
                worst = Strain {
                    from: link.from,
                    to: link.to,
                    kind: link.kind,
                    ratio,
                };
            }
        }
        worst
    }

    /// Loop links kept so far.
    pub fn loops(&self) -> usize {
        self.links
            .iter()
            .filter(|l| l.kind == LinkKind::Loop)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn step(x: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        )
    }

    /// A square loop of 4 × 5 nodes with odometry that drifts slightly in yaw.
    fn square() -> PoseGraph {
        let mut g = PoseGraph::new(&BackendConfig::default(), 3.0).expect("backend");
        g.add_first(0, Isometry3::identity()).expect("first");
        let sigmas = Sigmas { rad: 0.01, m: 0.02 };
        for i in 1..20u64 {
            let yaw = if i % 5 == 0 {
                std::f64::consts::FRAC_PI_2 + 0.01
            } else {
                0.0
            };
            g.add_odometry(i - 1, i, step(1.0, yaw), sigmas)
                .expect("odometry");
        }
        g
    }

    #[test]
    fn a_true_loop_is_kept_and_a_false_one_rejected_with_the_graph_restored() {
        let mut g = square();
        let before: Vec<_> = (0..20).map(|i| g.pose(i).expect("pose")).collect();
        // False: claims node 17 is where node 2 is, while they are ~3 m apart.
        let outcome = g
            .add_loop(2, 17, Isometry3::identity(), Sigmas { rad: 0.01, m: 0.02 })
            .expect("loop");
        let LoopOutcome::Rejected(strain) = outcome else {
            panic!("expected the false loop rejected, got {outcome:?}");
        };
        assert!(strain.ratio > 3.0);
        for (i, p) in before.iter().enumerate() {
            let q = g.pose(i as u64).expect("pose");
            let d = p.inverse() * q;
            assert!(
                d.translation.vector.norm() < 1e-6 && d.rotation.angle() < 1e-6,
                "node {i} restored: off by {:.2e} m, {:.2e} rad",
                d.translation.vector.norm(),
                d.rotation.angle()
            );
        }
        assert_eq!(g.loops(), 0);
        // True: node 19 is one step before node 0 (the square closes).
        let truth = step(1.0, std::f64::consts::FRAC_PI_2);
        let outcome = g
            .add_loop(19, 0, truth, Sigmas { rad: 0.01, m: 0.02 })
            .expect("loop");
        assert!(
            matches!(outcome, LoopOutcome::Accepted(s) if s.ratio < 3.0),
            "{outcome:?}"
        );
        assert_eq!(g.loops(), 1);
    }
}
