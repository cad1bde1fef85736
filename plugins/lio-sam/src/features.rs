//! Edge and planar features by curvature along each ring (LOAM, Zhang and Singh, RSS 2014,
//! §V-A; as LIO-SAM's featureExtraction does it): the smoothness of a point is the squared
//! sum of range differences to its ten neighbours on the ring; points on the far side of
//! an occlusion and points seen at a grazing angle are excluded; each ring is split into
//! sectors, each giving its sharpest points as edges and the rest as planar points, with
//! neighbours of a chosen point suppressed so that features spread out.

use nalgebra::Vector3;
use slam_common::registration::voxel::downsample;

use crate::config::FeatureConfig;

/// A point of a sweep after deskewing, in the lidar frame at the sweep's start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingPoint {
    pub p: Vector3<f64>,
    pub range: f64,
    pub column: i32,
}

/// The features of one sweep, in the lidar frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Features {
    pub edges: Vec<Vector3<f64>>,
    pub surfs: Vec<Vector3<f64>>,
}

const HALF: usize = 5;

#[derive(Clone, Copy, PartialEq)]
enum Label {
    Free,
    Picked,
    Edge,
}

/// Extracts features from points grouped by ring, each ring in column order.
pub fn extract(rings: &[Vec<RingPoint>], cfg: &FeatureConfig) -> Features {
    let mut out = Features::default();
    let mut surfs = Vec::new();
    for ring in rings {
        let n = ring.len();
        if n < 2 * HALF + 2 {
            continue;
        }
        let r: Vec<f64> = ring.iter().map(|p| p.range).collect();
        let mut curvature = vec![0.0; n];
        let mut label = vec![Label::Free; n];
        for i in HALF..n - HALF {
            let diff: f64 =
                r[i - HALF..=i + HALF].iter().sum::<f64>() - (2 * HALF + 1) as f64 * r[i];
            curvature[i] = diff * diff;
        }
        mark_unreliable(ring, &r, &mut label);
        let (lo, hi) = (HALF, n - HALF - 1);
        let sectors = cfg.sectors.max(1);
        let mut order: Vec<usize> = Vec::new();
        for s in 0..sectors {
            let start = lo + (hi - lo) * s / sectors;
            let end = lo + (hi - lo) * (s + 1) / sectors;
            if start >= end {
                continue;
            }
            order.clear();
            order.extend(start..end);
            order.sort_by(|&a, &b| curvature[a].total_cmp(&curvature[b]).then(a.cmp(&b)));
            let mut edges = 0;
            for &i in order.iter().rev() {
                if label[i] != Label::Free || curvature[i] <= cfg.edge_threshold {
                    continue;
                }
                if edges == cfg.edges_per_sector {
                    break;
                }
                edges += 1;
                label[i] = Label::Edge;
                out.edges.push(ring[i].p);
                suppress(ring, &mut label, i);
            }
            for &i in &order {
                if label[i] == Label::Free && curvature[i] < cfg.surf_threshold {
                    label[i] = Label::Picked;
                    suppress(ring, &mut label, i);
                }
            }
            surfs.extend(
                (start..end)
                    .filter(|&i| label[i] != Label::Edge)
                    .map(|i| ring[i].p),
            );
        }
    }
    out.surfs = downsample(&surfs, cfg.surf_leaf_m);
    out
}

/// Occluded points (the farther side of a depth jump between neighbouring columns) and
/// points on surfaces nearly parallel to the beam (LOAM's Fig. 4).
fn mark_unreliable(ring: &[RingPoint], r: &[f64], label: &mut [Label]) {
    let n = ring.len();
    for i in HALF..n - HALF - 1 {
        let (d1, d2) = (r[i], r[i + 1]);
        if (ring[i + 1].column - ring[i].column).abs() < 10 {
            if d1 - d2 > 0.3 {
                label[i - HALF..=i].fill(Label::Picked);
            } else if d2 - d1 > 0.3 {
                label[i + 1..=i + 1 + HALF].fill(Label::Picked);
            }
        }
        let (before, after) = ((r[i - 1] - r[i]).abs(), (r[i + 1] - r[i]).abs());
        if before > 0.02 * r[i] && after > 0.02 * r[i] {
            label[i] = Label::Picked;
        }
    }
}

/// Marks the neighbours of a chosen point, up to a gap in columns.
fn suppress(ring: &[RingPoint], label: &mut [Label], i: usize) {
    for l in 1..=HALF {
        if i + l >= ring.len() || (ring[i + l].column - ring[i + l - 1].column).abs() > 10 {
            break;
        }
        if label[i + l] == Label::Free {
            label[i + l] = Label::Picked;
        }
    }
    for l in 1..=HALF {
        if l > i || (ring[i - l + 1].column - ring[i - l].column).abs() > 10 {
            break;
        }
        if label[i - l] == Label::Free {
            label[i - l] = Label::Picked;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ring that sweeps along a flat wall and then across a corner: the corner is an edge,
    /// the wall gives planar points.
    #[test]
    fn a_corner_is_an_edge_and_a_wall_is_planar() {
        let mut ring = Vec::new();
        for c in 0..200 {
            // Wall x = 5 for columns 0..100, then wall y = 5 * (c - 100) / 100 + ... (a corner at column 100).
            let a = -0.6 + c as f64 * 0.006;
            let dir = Vector3::new(a.cos(), a.sin(), 0.0);
            let t_wall = 5.0 / dir.x;
            let t_other = 3.0 / dir.y.max(1e-3);
            let t = if dir.y > 0.0 {
                t_wall.min(t_other)
            } else {
                t_wall
            };
            ring.push(RingPoint {
                p: dir * t,
                range: t,
                column: c,
            });
        }
        let f = extract(
            &[ring],
            &FeatureConfig {
                surf_leaf_m: 0.0,
                ..FeatureConfig::default()
            },
        );
        assert!(!f.edges.is_empty(), "the corner must give an edge");
        for e in &f.edges {
            let near_corner = (e - Vector3::new(5.0, 3.0, 0.0)).norm() < 0.3;
            assert!(near_corner, "edge {e:?} is not at the corner (5, 3)");
        }
        assert!(
            f.surfs.len() > 150,
            "the walls are planar: {} points",
            f.surfs.len()
        );
    }
}
