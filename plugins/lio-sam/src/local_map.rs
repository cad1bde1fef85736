//! The local map a sweep is registered against (LIO-SAM's extractSurroundingKeyFrames):
//! the edge and planar features of the keyframes near the newest one, thinned to one per
//! few metres, plus every recent keyframe, moved into the world by their current pose
//! estimates, voxel-downsampled and put in k-d trees. It is rebuilt only when the
//! keyframes or their estimates change.

use nalgebra::{Point3, Vector3};
use slam_common::registration::kdtree::KdTree3;
use slam_common::registration::voxel::downsample;

use crate::config::MappingConfig;
use crate::keyframe::KeyframeView;

/// Feature maps in the world frame.
#[derive(Debug, Clone, Default)]
pub struct LocalMap {
    pub corners: KdTree3,
    pub surfs: KdTree3,
}

impl LocalMap {
    /// Builds the map around the last of `keyframes`.
    pub fn build(keyframes: &[KeyframeView<'_>], cfg: &MappingConfig) -> Self {
        let Some(newest) = keyframes.last() else {
            return Self::default();
        };
        let centre = newest.world_from_lidar.translation.vector;
        // Thin the nearby keyframes to one per `keyframe_density_m` voxel (the newest in each).
        let inv = 1.0 / cfg.keyframe_density_m.max(1e-3);
        let mut chosen: Vec<([i64; 3], usize)> = Vec::new();
        for (i, k) in keyframes.iter().enumerate() {
            let p = k.world_from_lidar.translation.vector;
            let recent = (newest.stamp_ns - k.stamp_ns) as f64 * 1e-9 <= cfg.recent_s;
            if recent {
                chosen.push(([i64::MAX, i64::MAX, i as i64], i));
            } else if (p - centre).norm() <= cfg.local_map_radius_m {
                chosen.push((
                    [
                        (p.x * inv).floor() as i64,
                        (p.y * inv).floor() as i64,
                        (p.z * inv).floor() as i64,
                    ],
                    i,
                ));
            }
        }
        chosen.sort_unstable();
        chosen.dedup_by(|later, earlier| {
            let same = later.0 == earlier.0;
            if same {
                earlier.1 = earlier.1.max(later.1);
            }
            same
        });
        let mut corners = Vec::new();
        let mut surfs = Vec::new();
        for &(_, i) in &chosen {
            let k = &keyframes[i];
            let to_world = |p: &Vector3<f64>| (k.world_from_lidar * Point3::from(*p)).coords;
            corners.extend(k.features.edges.iter().map(to_world));
            surfs.extend(k.features.surfs.iter().map(to_world));
        }
        Self {
            corners: KdTree3::new(downsample(&corners, cfg.corner_leaf_m)),
            surfs: KdTree3::new(downsample(&surfs, cfg.surf_leaf_m)),
        }
    }
}
