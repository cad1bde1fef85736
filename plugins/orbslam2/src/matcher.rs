//! Descriptor matching as ORB-SLAM2's `ORBmatcher` does it (ORB-SLAM, T-RO 2015, §V–VII):
//! by projection (a predicted pixel and a search radius scaled by the keypoint's level), by
//! bag of words (only features under the same vocabulary node, DBoW2's direct index), with
//! a Hamming threshold (50 for BoW and loop searches, 100 for projections), a best/second
//! ratio, and a rotation-consistency check (a 30-bin histogram of the orientation change;
//! only the three fullest bins survive).

use nalgebra::{Isometry3, Vector3};
use slam_common::place::bow::hamming;
use slam_common::place::vocabulary::NodeId;

use crate::frame::{Camera, Descriptor, Frame};
use crate::map::Map;

pub const TH_HIGH: u32 = 100;
pub const TH_LOW: u32 = 50;
const HISTO_LENGTH: usize = 30;

/// A point to match: where it is, what it looks like and at which level it was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Source {
    pub world: Vector3<f64>,
    pub descriptor: Descriptor,
    pub octave: u8,
    pub angle_deg: f32,
    /// The map point, or None for a temporary point of the last frame's depth.
    pub map_point: Option<usize>,
}

/// Orientation-consistency filter: matches are binned by the change of keypoint angle; all
/// but the three fullest bins (a bin below a tenth of the fullest does not count) are
/// dropped. Returns the indices of `rotations` to drop.
pub fn rotation_outliers(rotations: &[(usize, f32)]) -> Vec<usize> {
    let mut bins: Vec<Vec<usize>> = vec![Vec::new(); HISTO_LENGTH];
    for &(i, delta) in rotations {
        let mut r = delta;
        if r < 0.0 {
            r += 360.0;
        }
        let bin = ((r / 360.0 * HISTO_LENGTH as f32).round() as usize) % HISTO_LENGTH;
        bins[bin].push(i);
    }
    let mut order: Vec<usize> = (0..HISTO_LENGTH).collect();
    order.sort_by_key(|&b| (std::cmp::Reverse(bins[b].len()), b));
    let max = bins[order[0]].len();
    let keep: Vec<usize> = order
        .iter()
        .take(3)
        .copied()
        .filter(|&b| !bins[b].is_empty() && bins[b].len() as f64 >= 0.1 * max as f64)
        .collect();
    (0..HISTO_LENGTH)
        .filter(|b| !keep.contains(b))
        .flat_map(|b| bins[b].iter().copied())
        .collect()
}

/// The feature lists two frames hold under the same vocabulary node (DBoW2's direct
/// index), node by node: the candidates of every BoW search.
pub fn common_nodes<'a>(
    a: &'a [(NodeId, Vec<u32>)],
    b: &'a [(NodeId, Vec<u32>)],
) -> Vec<(&'a [u32], &'a [u32])> {
    let (mut ia, mut ib) = (0, 0);
    let mut out = Vec::new();
    while ia < a.len() && ib < b.len() {
        match a[ia].0.cmp(&b[ib].0) {
            std::cmp::Ordering::Less => ia += 1,
            std::cmp::Ordering::Greater => ib += 1,
            std::cmp::Ordering::Equal => {
                out.push((a[ia].1.as_slice(), b[ib].1.as_slice()));
                ia += 1;
                ib += 1;
            }
        }
    }
    out
}

/// Best and second-best Hamming distance over candidates.
fn best_two(
    descriptor: &Descriptor,
    candidates: impl Iterator<Item = (usize, Descriptor)>,
) -> (u32, u32, Option<usize>) {
    let mut best = (u32::MAX, u32::MAX, None);
    for (i, d) in candidates {
        let dist = hamming(descriptor, &d);
        if dist < best.0 {
            best = (dist, best.0, Some(i));
        } else if dist < best.1 {
            best.1 = dist;
        }
    }
    best
}

/// The motion model's search (`SearchByProjection(Frame, Frame)`): the last frame's points
/// projected with the predicted pose, searched within `radius` × the level's scale at the
/// level they were seen (one level up or down when the camera moves along its axis, as
/// published for stereo and RGB-D). Sets `current.matches`; returns how many.
pub fn search_motion(
    camera: &Camera,
    current: &mut Frame,
    sources: &[Source],
    radius: f64,
    forward_m: f64,
    check_orientation: bool,
) -> usize {
    let baseline = camera.stereo.bf / camera.stereo.fx;
    let forward = forward_m > baseline;
    let backward = -forward_m > baseline;
    let mut best_for: Vec<Option<(u32, usize)>> = vec![None; current.len()];
    for (s, src) in sources.iter().enumerate() {
        let p = current.camera_from_world * nalgebra::Point3::from(src.world);
        let Some((u, v)) = camera.project(&p.coords) else {
            continue;
        };
        let level = usize::from(src.octave);
        let r = radius * camera.scale_factors[level];
        let top = camera.levels() - 1;
        let (lo, hi) = if forward {
            (level, top)
        } else if backward {
            (0, level)
        } else {
            (level.saturating_sub(1), (level + 1).min(top))
        };
        let candidates = current.features_in_area(camera, u, v, r, lo, hi);
        let (dist, _, best) = best_two(
            &src.descriptor,
            candidates
                .iter()
                .filter(|&&i| current.matches[i].is_none())
                .map(|&i| (i, current.descriptors[i])),
        );
        let Some(i) = best else { continue };
        if dist > TH_HIGH {
            continue;
        }
        // Stereo consistency of the virtual right coordinate.
        if current.u_right[i] > 0.0 {
            let ur = u - camera.stereo.bf / p.z;
            if (ur - current.u_right[i]).abs() > r {
                continue;
            }
        }
        if best_for[i].is_none_or(|(d, _)| dist < d) {
            best_for[i] = Some((dist, s));
        }
    }
    assign(current, sources, &best_for, check_orientation)
}

/// Writes the winning source of each keypoint into the frame, after the orientation check.
fn assign(
    current: &mut Frame,
    sources: &[Source],
    best_for: &[Option<(u32, usize)>],
    check_orientation: bool,
) -> usize {
    let rotations: Vec<(usize, f32)> = best_for
        .iter()
        .enumerate()
        .filter_map(|(i, b)| b.map(|(_, s)| (i, sources[s].angle_deg - current.keys[i].angle_deg)))
        .collect();
    let drop = if check_orientation {
        rotation_outliers(&rotations)
    } else {
        Vec::new()
    };
    let mut n = 0;
    for (i, b) in best_for.iter().enumerate() {
        if let Some((_, s)) = b {
            if drop.contains(&i) {
                continue;
            }
            current.matches[i] = Some(sources[*s]);
            n += 1;
        }
    }
    n
}

/// BoW search between a keyframe and a frame (`SearchByBoW(KeyFrame, Frame)`): for the
/// keyframe's features with a map point, the nearest frame feature under the same node.
pub fn search_bow_frame(map: &Map, kf: usize, current: &mut Frame, ratio: f64) -> usize {
    let k = &map.keyframes[kf].frame;
    let mut best_for: Vec<Option<(u32, usize)>> = vec![None; current.len()];
    let mut sources = Vec::new();
    let (a, b) = (&k.features.entries, &current.features.entries);
    for (na, nb) in common_nodes(a, b) {
        for &fk in na {
            let fk = fk as usize;
            let Some(p) = k.points[fk].and_then(|p| map.resolve(p)) else {
                continue;
            };
            let d = &k.descriptors[fk];
            let (d1, d2, best) = best_two(
                d,
                nb.iter()
                    .map(|&i| i as usize)
                    .filter(|&i| current.matches[i].is_none())
                    .map(|i| (i, current.descriptors[i])),
            );
            let Some(i) = best else { continue };
            if d1 <= TH_LOW
                && f64::from(d1) < ratio * f64::from(d2)
                && best_for[i].is_none_or(|(d, _)| d1 < d)
            {
                best_for[i] = Some((d1, sources.len()));
                let key = &k.keys[fk];
                sources.push(Source {
                    world: map.points[p].world,
                    descriptor: *d,
                    octave: key.octave,
                    angle_deg: key.angle_deg,
                    map_point: Some(p),
                });
            }
        }
    }
    assign(current, &sources, &best_for, true)
}

/// BoW search between two keyframes (`SearchByBoW(KeyFrame, KeyFrame)`): pairs of
/// keypoints `(i1, i2)` that both have map points.
pub fn search_bow_keyframes(map: &Map, kf1: usize, kf2: usize, ratio: f64) -> Vec<(usize, usize)> {
    let (f1, f2) = (&map.keyframes[kf1].frame, &map.keyframes[kf2].frame);
    let mut best_for: Vec<Option<(u32, usize)>> = vec![None; f2.len()];
    let mut rotations = Vec::new();
    let (a, b) = (&f1.features.entries, &f2.features.entries);
    let mut chosen: Vec<Option<usize>> = vec![None; f1.len()];
    for (na, nb) in common_nodes(a, b) {
        for &i1 in na {
            let i1 = i1 as usize;
            if f1.points[i1].and_then(|p| map.resolve(p)).is_none() {
                continue;
            }
            let (d1, d2, best) = best_two(
                &f1.descriptors[i1],
                nb.iter()
                    .map(|&i| i as usize)
                    .filter(|&i| {
                        best_for[i].is_none() && f2.points[i].and_then(|p| map.resolve(p)).is_some()
                    })
                    .map(|i| (i, f2.descriptors[i])),
            );
            let Some(i2) = best else { continue };
            if d1 <= TH_LOW && f64::from(d1) < ratio * f64::from(d2) {
                best_for[i2] = Some((d1, i1));
                chosen[i1] = Some(i2);
                rotations.push((i1, f1.keys[i1].angle_deg - f2.keys[i2].angle_deg));
            }
        }
    }
    let drop = rotation_outliers(&rotations);
    chosen
        .iter()
        .enumerate()
        .filter(|(i1, c)| c.is_some() && !drop.contains(i1))
        .map(|(i1, c)| (i1, c.expect("filtered")))
        .collect()
}

/// A map point's predicted appearance in a view: pixel, level and the cosine between the
/// viewing ray and the point's mean direction; None when it fails ORB-SLAM2's
/// `isInFrustum` test (behind, outside, beyond its scale-invariance distances, or seen at
/// more than 60° from its mean direction).
pub fn in_frustum(
    map: &Map,
    camera: &Camera,
    camera_from_world: &Isometry3<f64>,
    p: usize,
) -> Option<(f64, f64, usize, f64)> {
    let point = &map.points[p];
    let pc = camera_from_world * nalgebra::Point3::from(point.world);
    let (u, v) = camera.project(&pc.coords)?;
    let centre = camera_from_world.inverse().translation.vector;
    let ray = point.world - centre;
    let distance = ray.norm();
    if distance < 0.8 * point.min_distance || distance > 1.2 * point.max_distance {
        return None;
    }
    let view_cos = ray.dot(&point.normal) / distance;
    if view_cos < 0.5 {
        return None;
    }
    let level = camera.predict_level(point.max_distance, distance);
    Some((u, v, level, view_cos))
}

/// Projects map points into a frame and matches them (`SearchByProjection(Frame,
/// vector<MapPoint*>)`, the local map search); the radius widens for oblique views.
pub fn search_local_points(
    map: &Map,
    camera: &Camera,
    current: &mut Frame,
    candidates: &[(usize, f64, f64, usize, f64)],
    th: f64,
    ratio: f64,
) -> usize {
    let mut n = 0;
    for &(p, u, v, level, view_cos) in candidates {
        let point = &map.points[p];
        let r = th * if view_cos > 0.998 { 2.5 } else { 4.0 } * camera.scale_factors[level];
        let candidates = current.features_in_area(camera, u, v, r, level.saturating_sub(1), level);
        let mut best = (u32::MAX, u32::MAX, None, 0u8, 0u8);
        for i in candidates {
            if current.matches[i]
                .and_then(|m| m.map_point)
                .is_some_and(|q| !map.points[q].observations.is_empty())
            {
                continue;
            }
            if current.u_right[i] > 0.0 {
                let pc = current.camera_from_world * nalgebra::Point3::from(point.world);
                let ur = u - camera.stereo.bf / pc.z;
                if (ur - current.u_right[i]).abs() > r {
                    continue;
                }
            }
            let d = hamming(&point.descriptor, &current.descriptors[i]);
            let octave = current.keys[i].octave;
            if d < best.0 {
                best = (d, best.0, Some(i), octave, best.3);
            } else if d < best.1 {
                best.1 = d;
                best.4 = octave;
            }
        }
        let (d1, d2, Some(i), l1, l2) = best else {
            continue;
        };
        if d1 > TH_HIGH {
            continue;
        }
        if l1 == l2 && f64::from(d1) > ratio * f64::from(d2) {
            continue;
        }
        current.matches[i] = Some(Source {
            world: point.world,
            descriptor: point.descriptor,
            octave: l1,
            angle_deg: current.keys[i].angle_deg,
            map_point: Some(p),
        });
        n += 1;
    }
    n
}

/// Projects map points into keyframe `kf` at pose `camera_from_world` and merges them
/// with what the keyframe sees (`Fuse`): a keypoint with a point already gets the point
/// with more observations; a free keypoint gets the projected point. Returns the
/// replacements `(old, new)` made and observations added.
pub fn fuse(
    map: &mut Map,
    camera: &Camera,
    kf: usize,
    camera_from_world: &Isometry3<f64>,
    points: &[usize],
    th: f64,
) -> usize {
    let mut n = 0;
    for &p in points {
        let Some(p) = map.resolve(p) else { continue };
        if map.points[p].observations.contains_key(&kf) {
            continue;
        }
        let Some((u, v, level, _)) = in_frustum(map, camera, camera_from_world, p) else {
            continue;
        };
        let point = &map.points[p];
        let pc = camera_from_world * nalgebra::Point3::from(point.world);
        let r = th * camera.scale_factors[level];
        let frame = &map.keyframes[kf].frame;
        let mut best = (u32::MAX, None);
        for i in frame.features_in_area(camera, u, v, r, 0, camera.levels() - 1) {
            let key = &frame.keys[i];
            let kl = usize::from(key.octave);
            if kl + 1 < level || kl > level {
                continue;
            }
            // Reprojection error against the keypoint's level (χ² 7.815 for stereo, 5.991 mono).
            let (eu, ev) = (u - f64::from(key.u), v - f64::from(key.v));
            let inv = camera.inv_level_sigma2[kl];
            if frame.u_right[i] > 0.0 {
                let er = u - camera.stereo.bf / pc.z - frame.u_right[i];
                if (eu * eu + ev * ev + er * er) * inv > 7.815 {
                    continue;
                }
            } else if (eu * eu + ev * ev) * inv > 5.991 {
                continue;
            }
            let d = hamming(&point.descriptor, &frame.descriptors[i]);
            if d < best.0 {
                best = (d, Some(i));
            }
        }
        let (d, Some(i)) = best else { continue };
        if d > TH_LOW {
            continue;
        }
        match frame.points[i].and_then(|q| map.resolve(q)) {
            Some(q) => {
                if map.observation_count(q) > map.observation_count(p) {
                    map.replace(p, q);
                } else {
                    map.replace(q, p);
                }
            }
            None => map.add_observation(p, kf, i),
        }
        n += 1;
    }
    n
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::orb::KeyPoint;
    use rand::{Rng, SeedableRng};
    use slam_common::factor_graph::ba::StereoCamera;
    use slam_common::place::vocabulary::{TrainConfig, Vocabulary};

    pub(crate) fn camera() -> Camera {
        let scale_factors: Vec<f64> = (0..8).map(|l| 1.2f64.powi(l)).collect();
        Camera {
            stereo: StereoCamera {
                fx: 457.0,
                fy: 457.0,
                cx: 320.0,
                cy: 240.0,
                bf: 0.08 * 457.0,
            },
            width: 640.0,
            height: 480.0,
            lens: None,
            bounds: [0.0, 640.0, 0.0, 480.0],
            close_depth_m: 3.2,
            min_depth_m: 0.5,
            max_depth_m: 8.0,
            level_sigma2: scale_factors.iter().map(|s| s * s).collect(),
            inv_level_sigma2: scale_factors.iter().map(|s| 1.0 / (s * s)).collect(),
            scale_factors,
            log_scale: 1.2f64.ln(),
        }
    }

    /// 400 random keypoints with random descriptors at 2 m, and a vocabulary of them.
    pub(crate) fn scene() -> (Camera, Frame, Vocabulary) {
        let camera = camera();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let keys: Vec<KeyPoint> = (0..400)
            .map(|_| KeyPoint {
                u: rng.random_range(20.0..620.0),
                v: rng.random_range(20.0..460.0),
                octave: rng.random_range(0..3),
                angle_deg: rng.random_range(0.0..360.0),
                response: 1.0,
                size: 31.0,
            })
            .collect();
        let descriptors: Vec<Descriptor> = (0..400).map(|_| rng.random()).collect();
        let depth = vec![2.0f32; 640 * 480];
        let vocabulary = Vocabulary::train(
            std::slice::from_ref(&descriptors),
            &TrainConfig {
                k: 10,
                levels: 3,
                ..TrainConfig::default()
            },
        )
        .expect("trains");
        let mut frame = Frame::new(0, &camera, keys, descriptors, &depth, 640);
        frame.compute_bow(&vocabulary);
        (camera, frame, vocabulary)
    }

    /// A keyframe whose every keypoint has a map point from its depth.
    pub(crate) fn keyframe(map: &mut Map, camera: &Camera, frame: &Frame) -> usize {
        let kf = map.add_keyframe(frame.clone());
        for i in 0..frame.len() {
            let world = frame.unproject_world(camera, i).expect("depth");
            map.add_point(camera, world, kf, i);
        }
        kf
    }

    #[test]
    fn bow_search_pairs_a_keyframe_with_its_copy() {
        let (camera, frame, _) = scene();
        let mut map = Map::default();
        let a = keyframe(&mut map, &camera, &frame);
        let b = keyframe(&mut map, &camera, &frame);
        let pairs = search_bow_keyframes(&map, a, b, 0.75);
        assert_eq!(pairs.len(), 400, "every keypoint under its own node");
        assert!(pairs.iter().all(|(i, j)| i == j));
    }

    #[test]
    fn motion_search_finds_the_last_frames_points_where_they_project() {
        let (camera, frame, _) = scene();
        let mut map = Map::default();
        let kf = keyframe(&mut map, &camera, &frame);
        let sources: Vec<Source> = (0..frame.len())
            .map(|i| {
                let p = map.keyframes[kf].frame.points[i].expect("a point");
                Source {
                    world: map.points[p].world,
                    descriptor: map.points[p].descriptor,
                    octave: frame.keys[i].octave,
                    angle_deg: frame.keys[i].angle_deg,
                    map_point: Some(p),
                }
            })
            .collect();
        // The camera moved 1 cm sideways: points project 2.3 px over, within the radius.
        let keys = frame
            .keys
            .iter()
            .map(|k| KeyPoint {
                u: k.u - 2.285,
                ..*k
            })
            .collect();
        let depth = vec![2.0f32; 640 * 480];
        let mut current = Frame::new(1, &camera, keys, frame.descriptors.clone(), &depth, 640);
        current.camera_from_world = Isometry3::translation(-0.01, 0.0, 0.0);
        let n = search_motion(&camera, &mut current, &sources, 15.0, 0.0, true);
        assert!(n >= 395, "{n} of 400 matched");
        let right = current
            .matches
            .iter()
            .enumerate()
            .filter(|(i, m)| m.and_then(|m| m.map_point) == map.keyframes[kf].frame.points[*i])
            .count();
        assert_eq!(right, n, "every match is the keypoint's own point");
    }

    #[test]
    fn rotation_check_keeps_the_three_fullest_bins() {
        let mut rotations: Vec<(usize, f32)> = (0..50).map(|i| (i, 10.0)).collect();
        rotations.extend((50..70).map(|i| (i, -20.0)));
        rotations.extend((70..72).map(|i| (i, 180.0)));
        rotations.extend((72..74).map(|i| (i, 90.0)));
        let drop = rotation_outliers(&rotations);
        assert_eq!(drop.len(), 4, "the two small bins go: {drop:?}");
        assert!(drop.iter().all(|&i| i >= 70));
    }
}
