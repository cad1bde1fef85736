//! Proximity detection by space (Labbé and Michaud 2019, §3.3; RTAB-Map's
//! `RGBD/ProximityBySpace`): a new location whose estimated position lies near an older
//! location is registered to it by ICP on their laser scans, from the relative pose the
//! graph predicts. Appearance cannot close such loops when the robot comes back the way it
//! came, its camera looking the other way; the scans of a 264° laser see the same trunks
//! both ways. The link goes through the same `OptimizeMaxError` check as a visual one.

use nalgebra::{Isometry2, Vector2};
use serde::Deserialize;
use slam_common::registration::scan2d::{Icp2dConfig, Icp2dResult, Icp2dTarget, icp2d};

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProximityConfig {
    pub enabled: bool,
    /// Older locations within this distance of the new one's estimate are candidates, m
    /// (`RGBD/LocalRadius` in spirit; ours is tighter, as the guess must be good enough for
    /// ICP among trunks a metre apart).
    pub radius_m: f64,
    /// And only locations at least this much older, s (younger ones are joined by odometry).
    pub min_age_s: f64,
    /// The registration must match at least this share of the new scan's points.
    pub min_correspondence_ratio: f64,
    /// The old location's scan is registered to together with this many neighbours' on
    /// each side.
    pub submap_neighbours: usize,
}

impl Default for ProximityConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            radius_m: 1.0,
            min_age_s: 30.0,
            min_correspondence_ratio: 0.5,
            submap_neighbours: 3,
        }
    }
}

/// A location as proximity detection sees it.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    pub id: u64,
    pub stamp_ns: i64,
    /// The graph's estimate, planar.
    pub map_from_base: Isometry2<f64>,
}

/// The nearest candidate within the radius and old enough, if any.
pub fn nearest(
    new: &Candidate,
    older: impl Iterator<Item = Candidate>,
    cfg: &ProximityConfig,
) -> Option<Candidate> {
    let min_age_ns = (cfg.min_age_s * 1e9) as i64;
    older
        .filter(|c| new.stamp_ns - c.stamp_ns >= min_age_ns)
        .map(|c| {
            let d =
                (c.map_from_base.translation.vector - new.map_from_base.translation.vector).norm();
            (d, c)
        })
        .filter(|(d, _)| *d <= cfg.radius_m)
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.id.cmp(&b.1.id)))
        .map(|(_, c)| c)
}

/// Registers the new location's scan (base frame) to the old one's, from the graph's guess
/// `old_from_new`; the result if it matches enough of the scan and is not degenerate.
pub fn register(
    old_scan: &[Vector2<f64>],
    new_scan: &[Vector2<f64>],
    guess_old_from_new: Isometry2<f64>,
    icp: &Icp2dConfig,
    cfg: &ProximityConfig,
) -> Result<Icp2dResult, String> {
    let target = Icp2dTarget::new(old_scan, icp);
    let result =
        icp2d(new_scan, &target, guess_old_from_new, icp).ok_or("ICP found no registration")?;
    if result.correspondence_ratio < cfg.min_correspondence_ratio {
        return Err(format!(
            "ICP matched {:.0}% of the scan (need {:.0}%)",
            result.correspondence_ratio * 100.0,
            cfg.min_correspondence_ratio * 100.0
        ));
    }
    if result.is_degenerate() {
        return Err("ICP degenerate along the row".into());
    }
    Ok(result)
}
