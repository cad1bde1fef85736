//! Deskewing (Shan et al. 2020, §III-B; LIO-SAM's imageProjection): a spinning lidar takes
//! a tenth of a second per sweep, during which the robot moves and turns, so every point is
//! moved from the sensor's pose at its own firing time to the pose at the sweep's start.
//! Points are grouped by ring in column order, as feature extraction needs them.

use nalgebra::{Isometry3, Point3, Vector3};
use plugin_api::LidarPoint;

use crate::features::RingPoint;
use crate::motion::Motion;

/// How a sweep is laid out, from the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepLayout {
    pub sweep_ns: i64,
    pub columns: f64,
    pub min_range_m: f64,
    pub max_range_m: f64,
}

/// The sweep's points by ring, in the lidar frame at `start_ns`: moved with `motion`
/// (`world_from_lidar` over time) when given, as measured otherwise.
pub fn rings(
    points: &[LidarPoint],
    start_ns: i64,
    motion: Option<&Motion>,
    layout: &SweepLayout,
) -> Vec<Vec<RingPoint>> {
    let n_rings = points
        .iter()
        .map(|p| p.ring as usize + 1)
        .max()
        .unwrap_or(0);
    let mut out: Vec<Vec<RingPoint>> = vec![Vec::new(); n_rings];
    let start_inv = motion.and_then(|m| m.at(start_ns)).map(|p| p.inverse());
    // A column fires all rings at once: one relative pose per distinct time.
    let mut cached: Option<(f32, Isometry3<f64>)> = None;
    let sweep_s = layout.sweep_ns as f64 * 1e-9;
    for p in points {
        let raw = Vector3::new(p.x as f64, p.y as f64, p.z as f64);
        let range = raw.norm();
        if !(layout.min_range_m..=layout.max_range_m).contains(&range) {
            continue;
        }
        let point = match (motion, &start_inv) {
            (Some(m), Some(inv)) => {
                let rel = match cached {
                    Some((t, rel)) if t == p.time_s => rel,
                    _ => {
                        let t_ns = start_ns + (p.time_s as f64 * 1e9).round() as i64;
                        let rel = m.at(t_ns).map_or_else(Isometry3::identity, |at| inv * at);
                        cached = Some((p.time_s, rel));
                        rel
                    }
                };
                (rel * Point3::from(raw)).coords
            }
            _ => raw,
        };
        let column = (p.time_s as f64 / sweep_s * layout.columns).round() as i32;
        out[p.ring as usize].push(RingPoint {
            p: point,
            range,
            column,
        });
    }
    out
}
