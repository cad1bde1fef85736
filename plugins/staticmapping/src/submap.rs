//! Submaps (StaticMapping's `Submap`): `frame_count` consecutive keyframes merged into the
//! first one's frame and voxel-filtered. Each is matched to the previous submap by
//! [`crate::icp`] from the front end's relative pose; a match scoring below
//! `accepted_min_score` keeps the front end's pose (`MapBuilder::SubmapPairMatch`).

use nalgebra::{Isometry3, Point3, Vector3};
use slam_common::registration::voxel::downsample;

use crate::config::{IcpConfig, SubmapConfig};
use crate::frontend::Keyframe;
use crate::icp::{self, Reference};

#[derive(Debug, Clone)]
pub struct Submap {
    /// Index of its first keyframe; the submap's frame is that keyframe's lidar frame.
    pub first_keyframe: usize,
    pub stamp_ns: i64,
    /// The front end's pose of the first keyframe.
    pub odometry_pose: Isometry3<f64>,
    /// The merged, voxel-filtered cloud in the submap's frame.
    pub cloud: Vec<Vector3<f64>>,
    /// The cloud reduced for matching (box means with normals).
    pub reference: Reference,
}

/// Groups the keyframes into submaps of `frame_count`.
pub fn build(keyframes: &[Keyframe], cfg: &SubmapConfig, icp_cfg: &IcpConfig) -> Vec<Submap> {
    keyframes
        .chunks(cfg.frame_count)
        .enumerate()
        .map(|(i, frames)| {
            let origin = frames[0].world_from_lidar;
            let mut points = Vec::new();
            for kf in frames {
                let submap_from_kf = origin.inverse() * kf.world_from_lidar;
                points.extend(
                    kf.cloud
                        .iter()
                        .map(|p| (submap_from_kf * Point3::from(*p)).coords),
                );
            }
            let cloud = downsample(&points, cfg.voxel_m);
            let reference = Reference::new(&cloud, icp_cfg.knn_normal);
            Submap {
                first_keyframe: i * cfg.frame_count,
                stamp_ns: frames[0].stamp_ns,
                odometry_pose: origin,
                cloud,
                reference,
            }
        })
        .collect()
}

/// The outcome of matching a submap to the one before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubmapMatch {
    /// The matched relative pose, or the front end's if the match was not accepted.
    pub previous_from_current: Isometry3<f64>,
    /// The match's score; None if ICP failed (too few points).
    pub score: Option<f64>,
    pub accepted: bool,
}

/// Matches `current` to `previous` from the front end's relative pose.
pub fn match_to_previous(
    previous: &Submap,
    current: &Submap,
    cfg: &SubmapConfig,
    icp_cfg: &IcpConfig,
) -> SubmapMatch {
    let guess = previous.odometry_pose.inverse() * current.odometry_pose;
    let a = icp::align(&current.cloud, &previous.reference, &guess, icp_cfg);
    let score = a.map(|a| a.score);
    match a {
        Some(a) if a.score >= cfg.accepted_min_score => SubmapMatch {
            previous_from_current: a.reference_from_reading,
            score,
            accepted: true,
        },
        _ => SubmapMatch {
            previous_from_current: guess,
            score,
            accepted: false,
        },
    }
}
