//! Point-to-plane ICP (Chen and Medioni, "Object modelling by registration of multiple range
//! images", 1992), used to verify loop closures: the source points are matched to their
//! nearest target point within a gate, each target point carrying the normal of a plane
//! fitted to its neighbours, and the pose is refined by Gauss–Newton. The fitness score is
//! PCL's: the mean squared distance from each source point to its nearest target point.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::motion::geometry::fit_plane;
use crate::motion::lsq::{NormalEquations, apply, converged};
use crate::registration::kdtree::KdTree3;

/// A target cloud ready for ICP: its k-d tree and the normal at each point where the
/// neighbourhood is planar, fitted the first time a source point is matched to it (most
/// target points never are).
#[derive(Debug, Clone)]
pub struct IcpTarget {
    tree: KdTree3,
    normals: Vec<Option<Option<Vector3<f64>>>>,
    neighbours: usize,
    max_plane_distance_m: f64,
}

impl IcpTarget {
    pub fn new(points: Vec<Vector3<f64>>, neighbours: usize, max_plane_distance_m: f64) -> Self {
        let normals = vec![None; points.len()];
        Self {
            tree: KdTree3::new(points),
            normals,
            neighbours,
            max_plane_distance_m,
        }
    }

    /// The normal at target point `i`, if its neighbourhood is planar.
    fn normal(
        &mut self,
        i: usize,
        found: &mut Vec<crate::registration::kdtree::Neighbour>,
        patch: &mut Vec<Vector3<f64>>,
    ) -> Option<Vector3<f64>> {
        if let Some(n) = self.normals[i] {
            return n;
        }
        let p = *self.tree.point(i);
        self.tree.nearest(&p, self.neighbours, 1.0, found);
        patch.clear();
        patch.extend(found.iter().map(|n| *self.tree.point(n.index)));
        let n = fit_plane(patch, self.max_plane_distance_m).map(|pl| pl.normal);
        self.normals[i] = Some(n);
        n
    }

    pub fn len(&self) -> usize {
        self.tree.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpConfig {
    pub max_iterations: usize,
    /// Correspondences farther apart than this are ignored while solving.
    pub max_correspondence_m: f64,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            max_iterations: 30,
            max_correspondence_m: 1.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpResult {
    pub target_from_source: Isometry3<f64>,
    /// Mean squared nearest-neighbour distance of the source points at the result, m².
    pub fitness: f64,
    /// Source points with a correspondence within the gate at the result.
    pub inliers: usize,
    pub converged: bool,
}

/// Refines `initial` (`target_from_source`).
pub fn icp(
    source: &[Vector3<f64>],
    target: &mut IcpTarget,
    initial: &Isometry3<f64>,
    config: &IcpConfig,
) -> Option<IcpResult> {
    if source.len() < 6 || target.is_empty() {
        return None;
    }
    let gate_sq = config.max_correspondence_m * config.max_correspondence_m;
    let mut pose = *initial;
    let mut done = false;
    let (mut found, mut patch) = (Vec::new(), Vec::new());
    for _ in 0..config.max_iterations {
        let mut ne = NormalEquations::default();
        for p in source {
            let q = (pose * Point3::from(*p)).coords;
            let Some(nb) = target.tree.nearest_one(&q, gate_sq) else {
                continue;
            };
            let Some(n) = target.normal(nb.index, &mut found, &mut patch) else {
                continue;
            };
            let r = n.dot(&(q - target.tree.point(nb.index)));
            ne.add(p, &(pose.rotation.inverse() * n), r, 1.0);
        }
        let step = ne.solve(1e-6)?;
        pose = apply(&step.delta, &pose);
        if converged(&step.delta, 1e-5, 1e-4) {
            done = true;
            break;
        }
    }
    let mut sum = 0.0;
    let mut inliers = 0;
    for p in source {
        let q = (pose * Point3::from(*p)).coords;
        if let Some(nb) = target.tree.nearest_one(&q, f64::INFINITY) {
            sum += nb.distance_sq;
            inliers += usize::from(nb.distance_sq <= gate_sq);
        }
    }
    Some(IcpResult {
        target_from_source: pose,
        fitness: sum / source.len() as f64,
        inliers,
        converged: done,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A corner of a room (floor and two walls, with a step) seen from a shifted pose is
    /// brought back onto itself, and the fitness says so.
    #[test]
    fn aligns_a_shifted_corner() {
        let mut target = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (u, v) = (i as f64 * 0.1, j as f64 * 0.1);
                target.push(Vector3::new(
                    u,
                    v,
                    if u > 2.0 && v > 2.0 { 0.3 } else { 0.0 },
                ));
                target.push(Vector3::new(0.0, u, v * 0.5));
                target.push(Vector3::new(u, 0.0, v * 0.5));
            }
        }
        let truth = Isometry3::from_parts(
            Translation3::new(0.15, -0.2, 0.05),
            UnitQuaternion::from_euler_angles(0.0, 0.01, 0.06),
        );
        let source: Vec<_> = target
            .iter()
            .step_by(2)
            .map(|p| (truth.inverse() * Point3::from(*p)).coords)
            .collect();
        let mut prepared = IcpTarget::new(target, 5, 0.05);
        let result = icp(
            &source,
            &mut prepared,
            &Isometry3::identity(),
            &IcpConfig::default(),
        )
        .expect("enough points");
        let err = result.target_from_source.inverse() * truth;
        assert!(
            err.translation.vector.norm() < 1e-3 && err.rotation.angle() < 1e-3,
            "error {err:?}"
        );
        assert!(result.fitness < 1e-4, "fitness {}", result.fitness);
        let start = icp(
            &source,
            &mut prepared,
            &Isometry3::identity(),
            &IcpConfig {
                max_iterations: 0,
                ..IcpConfig::default()
            },
        )
        .expect("scored");
        assert!(
            start.fitness > 10.0 * result.fitness,
            "before {} after {}",
            start.fitness,
            result.fitness
        );
    }
}
