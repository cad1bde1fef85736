//! Scan-to-map registration (LOAM's mapping step as LIO-SAM runs it, Shan et al. 2020
//! §III-D): each edge point is matched to a line through its nearest map edges, each planar
//! point to a plane through its nearest map planar points, and the sweep's pose is refined
//! by Gauss–Newton on point-to-line and point-to-plane distances, weighted as LOAM does,
//! with correspondences searched again at every iteration and degenerate directions left
//! at the prediction.

use nalgebra::{Isometry3, Point3, Vector3};
use slam_common::motion::geometry::{Line, Plane, fit_line, fit_plane};
use slam_common::motion::lsq::{NormalEquations, apply, converged};
use slam_common::registration::kdtree::{KdTree3, Neighbour};

use crate::config::MappingConfig;
use crate::features::Features;
use crate::local_map::LocalMap;

/// The outcome of registering one sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    pub world_from_lidar: Isometry3<f64>,
    /// Iterations that updated the pose.
    pub iterations: usize,
    pub edge_matches: usize,
    pub surf_matches: usize,
    /// Directions (of six) too weakly observed in the last iteration.
    pub degenerate_directions: usize,
    /// Whether the first iteration found a direction too weakly observed: LIO-SAM's
    /// `isDegenerate`, decided once per sweep at iteration 0 of `LMOptimization`.
    pub degenerate: bool,
    /// Registration stopped because an iteration matched fewer than
    /// `cfg.min_matches` points; the pose is the one reached before it (the prediction
    /// if at the first iteration).
    pub few_matches: bool,
}

/// Why a sweep was not registered (its pose is then the prediction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// The sweep has no more edge or planar points than the minimum.
    ScanFeatures,
    /// The local map is empty.
    MapFeatures,
}

impl Refusal {
    /// The trace's name of it.
    pub fn name(self) -> &'static str {
        match self {
            Self::ScanFeatures => "scan_features",
            Self::MapFeatures => "map_features",
        }
    }
}

/// Refines `initial` (`world_from_lidar` at the sweep's start) as LIO-SAM's
/// `scan2MapOptimization` does (`mapOptmization.cpp`): a sweep registers only if it has
/// more edge and planar points than `min_edge_points` and `min_surf_points`
/// (`edgeFeatureMinValidNum`, `surfFeatureMinValidNum`); an iteration with fewer than
/// `min_matches` correspondences in all (LIO-SAM's hard-coded 50 in `LMOptimization`)
/// leaves the pose where the iterations before it took it. Refused when the sweep has too
/// few features or the map none.
pub fn register(
    features: &Features,
    map: &LocalMap,
    initial: &Isometry3<f64>,
    cfg: &MappingConfig,
) -> Result<Registration, Refusal> {
    if features.edges.len() <= cfg.min_edge_points || features.surfs.len() <= cfg.min_surf_points {
        return Err(Refusal::ScanFeatures);
    }
    if map.corners.is_empty() && map.surfs.is_empty() {
        return Err(Refusal::MapFeatures);
    }
    let mut pose = *initial;
    let mut nb = Vec::with_capacity(cfg.neighbours);
    let mut patch = Vec::with_capacity(cfg.neighbours);
    let mut lines: Vec<Option<Line>> = vec![None; features.edges.len()];
    let mut planes: Vec<Option<Plane>> = vec![None; features.surfs.len()];
    let mut searched_at: Option<Isometry3<f64>> = None;
    let mut result = Registration {
        world_from_lidar: pose,
        iterations: 0,
        edge_matches: 0,
        surf_matches: 0,
        degenerate_directions: 0,
        degenerate: false,
        few_matches: false,
    };
    for iteration in 1..=cfg.max_iterations {
        // Lines and planes are local: search again only once the sweep has moved enough
        // since the last search to reach other map points.
        let moved = searched_at.is_none_or(|at| {
            let d = at.inverse() * pose;
            d.translation.vector.norm() + d.rotation.angle() * RESEARCH_LEVER_M
                > cfg.research_distance_m
        });
        if moved {
            for (p, line) in features.edges.iter().zip(&mut lines) {
                let q = (pose * Point3::from(*p)).coords;
                *line = neighbours(&map.corners, &q, cfg, &mut nb, &mut patch)
                    .then(|| fit_line(&patch, 3.0))
                    .flatten();
            }
            for (p, plane) in features.surfs.iter().zip(&mut planes) {
                let q = (pose * Point3::from(*p)).coords;
                *plane = neighbours(&map.surfs, &q, cfg, &mut nb, &mut patch)
                    .then(|| fit_plane(&patch, 0.2))
                    .flatten();
            }
            searched_at = Some(pose);
        }
        let mut ne = NormalEquations::default();
        let mut edge_matches = 0;
        for (p, line) in features.edges.iter().zip(&lines) {
            let Some(line) = line else { continue };
            let q = (pose * Point3::from(*p)).coords;
            let (r, g) = line.residual(&q);
            let s = 1.0 - 0.9 * r;
            if s > 0.1 {
                ne.add(p, &(pose.rotation.inverse() * g), r, s * s);
                edge_matches += 1;
            }
        }
        let mut surf_matches = 0;
        for (p, plane) in features.surfs.iter().zip(&planes) {
            let Some(plane) = plane else { continue };
            let q = (pose * Point3::from(*p)).coords;
            let r = plane.distance(&q);
            let s = 1.0 - 0.9 * r.abs() / p.norm().sqrt();
            if s > 0.1 {
                ne.add(p, &(pose.rotation.inverse() * plane.normal), r, s * s);
                surf_matches += 1;
            }
        }
        result.edge_matches = edge_matches;
        result.surf_matches = surf_matches;
        // The same correspondences would be found again from the same pose: LIO-SAM's
        // later iterations change nothing either.
        if edge_matches + surf_matches < cfg.min_matches {
            result.few_matches = true;
            break;
        }
        let Some(step) = ne.solve(cfg.degeneracy_eigenvalue) else {
            break;
        };
        if iteration == 1 {
            result.degenerate = step.degenerate_directions > 0;
        }
        pose = apply(&step.delta, &pose);
        result.world_from_lidar = pose;
        result.iterations = iteration;
        result.degenerate_directions = step.degenerate_directions;
        // LIO-SAM stops below 0.05° and 0.05 cm.
        if converged(&step.delta, 0.05_f64.to_radians(), 5e-4) {
            break;
        }
    }
    Ok(result)
}

/// The lever arm that turns a rotation into a point displacement when deciding whether to
/// search correspondences again: a typical feature range.
const RESEARCH_LEVER_M: f64 = 10.0;

/// The `cfg.neighbours` nearest map points of `q`, if the farthest is close enough.
fn neighbours(
    tree: &KdTree3,
    q: &Vector3<f64>,
    cfg: &MappingConfig,
    nb: &mut Vec<Neighbour>,
    patch: &mut Vec<Vector3<f64>>,
) -> bool {
    tree.nearest(q, cfg.neighbours, cfg.max_neighbour_distance_sq, nb);
    if nb.len() < cfg.neighbours {
        return false;
    }
    patch.clear();
    patch.extend(nb.iter().map(|n| *tree.point(n.index)));
    true
}
