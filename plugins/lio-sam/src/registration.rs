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
    pub iterations: usize,
    pub edge_matches: usize,
    pub surf_matches: usize,
    /// Directions (of six) too weakly observed in the last iteration.
    pub degenerate_directions: usize,
}

/// Why a sweep was not registered (its pose is then the prediction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// The sweep has fewer edge or planar points than the minimum.
    ScanFeatures,
    /// The local map has.
    MapFeatures,
    /// An iteration matched fewer edges than the minimum.
    EdgeMatches,
    /// An iteration matched fewer planar points than the minimum.
    SurfMatches,
    /// The normal equations could not be solved.
    Solve,
}

impl Refusal {
    /// The trace's name of it.
    pub fn name(self) -> &'static str {
        match self {
            Self::ScanFeatures => "scan_features",
            Self::MapFeatures => "map_features",
            Self::EdgeMatches => "edge_matches",
            Self::SurfMatches => "surf_matches",
            Self::Solve => "solve",
        }
    }
}

/// Refines `initial` (`world_from_lidar` at the sweep's start); refused when the sweep or
/// the map has too few features to register.
pub fn register(
    features: &Features,
    map: &LocalMap,
    initial: &Isometry3<f64>,
    cfg: &MappingConfig,
) -> Result<Registration, Refusal> {
    if features.edges.len() < cfg.min_edge_points || features.surfs.len() < cfg.min_surf_points {
        return Err(Refusal::ScanFeatures);
    }
    if map.corners.len() < cfg.min_edge_points || map.surfs.len() < cfg.min_surf_points {
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
        if edge_matches < cfg.min_edge_points {
            return Err(Refusal::EdgeMatches);
        }
        if surf_matches < cfg.min_surf_points {
            return Err(Refusal::SurfMatches);
        }
        let step = ne.solve(cfg.degeneracy_eigenvalue).ok_or(Refusal::Solve)?;
        pose = apply(&step.delta, &pose);
        result = Registration {
            world_from_lidar: pose,
            iterations: iteration,
            edge_matches,
            surf_matches,
            degenerate_directions: step.degenerate_directions,
        };
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
