//! Loop closure (Shan et al. 2020, §III-E): the newest keyframe's nearest keyframe within a
//! search radius that is old enough is a candidate; the newest keyframe's features are
//! registered by ICP to a submap of the candidate's neighbours; a fit better than the
//! fitness threshold becomes a relative-pose factor.

use nalgebra::{Isometry3, Point3, Vector3};
use slam_common::registration::icp::{IcpConfig, IcpTarget, icp};
use slam_common::registration::voxel::downsample;

use crate::config::LoopConfig;
use crate::keyframe::KeyframeView;

/// The nearest old-enough keyframe to the last one, if within the radius.
pub fn candidate(keyframes: &[KeyframeView<'_>], cfg: &LoopConfig) -> Option<usize> {
    let newest = keyframes.last()?;
    let here = newest.world_from_lidar.translation.vector;
    let min_age_ns = (cfg.min_age_s * 1e9) as i64;
    keyframes
        .iter()
        .enumerate()
        .filter(|(_, k)| newest.stamp_ns - k.stamp_ns >= min_age_ns)
        .map(|(i, k)| (i, (k.world_from_lidar.translation.vector - here).norm()))
        .filter(|(_, d)| *d <= cfg.search_radius_m)
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .map(|(i, _)| i)
}

/// A verified loop: the corrected `older_from_newer` of the lidar frames and its fitness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopMatch {
    pub older_from_newer: Isometry3<f64>,
    pub fitness: f64,
}

/// Registers the newest keyframe to the candidate's submap. Err(fitness) when ICP fails or
/// fits worse than the threshold.
pub fn verify(
    keyframes: &[KeyframeView<'_>],
    older: usize,
    cfg: &LoopConfig,
    leaf_m: f64,
) -> Result<LoopMatch, f64> {
    let newest = keyframes.last().ok_or(f64::INFINITY)?;
    let min_age_ns = (cfg.min_age_s * 1e9) as i64;
    let lo = older.saturating_sub(cfg.submap_keyframes);
    let hi = (older + cfg.submap_keyframes).min(keyframes.len() - 1);
    let mut target = Vec::new();
    for k in &keyframes[lo..=hi] {
        if newest.stamp_ns - k.stamp_ns < min_age_ns {
            continue;
        }
        let to_world = |p: &Vector3<f64>| (k.world_from_lidar * Point3::from(*p)).coords;
        target.extend(
            k.features
                .edges
                .iter()
                .chain(&k.features.surfs)
                .map(to_world),
        );
    }
    let mut target = IcpTarget::new(downsample(&target, leaf_m), 5, 0.1);
    let source: Vec<_> = newest
        .features
        .edges
        .iter()
        .chain(&newest.features.surfs)
        .copied()
        .collect();
    let result = icp(
        &source,
        &mut target,
        &newest.world_from_lidar,
        &IcpConfig::default(),
    )
    .ok_or(f64::INFINITY)?;
    if result.fitness > cfg.max_fitness {
        return Err(result.fitness);
    }
    Ok(LoopMatch {
        older_from_newer: keyframes[older].world_from_lidar.inverse() * result.target_from_source,
        fitness: result.fitness,
    })
}
