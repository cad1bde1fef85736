//! The map: keyframes and map points, the covisibility graph (keyframes joined by the
//! number of points they both see), its spanning tree, and the bookkeeping ORB-SLAM2's
//! `KeyFrame` and `MapPoint` classes do (Mur-Artal, Montiel and Tardós, ORB-SLAM, T-RO 2015,
//! §III-B–D): a point's representative descriptor, viewing direction and scale-invariance
//! distances; erasing a keyframe re-parents its children in the spanning tree.
//!
//! Keyframes and points live in vectors indexed by id and are never removed, only flagged
//! bad, so ids are stable and iteration is deterministic.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Isometry3, Vector3};
use slam_common::place::bow::hamming;

use crate::frame::{Camera, Descriptor, Frame};

/// Covisibility edges need this many shared points (ORB-SLAM2's `th = 15`).
const COVISIBILITY_MIN: usize = 15;

#[derive(Debug, Clone)]
pub struct KeyFrame {
    pub id: usize,
    /// The frame it was made from; its `points` are the keyframe's map points.
    pub frame: Frame,
    /// Shared map points with other keyframes (edges of at least 15, or the best one).
    pub covisibility: BTreeMap<usize, usize>,
    /// `covisibility` ordered by weight, heaviest first (ties by id).
    pub ordered: Vec<(usize, usize)>,
    pub parent: Option<usize>,
    pub children: BTreeSet<usize>,
    pub loop_edges: BTreeSet<usize>,
    pub bad: bool,
    /// Set when culled: this keyframe's pose relative to its parent, to carry frames.
    pub camera_from_parent: Option<Isometry3<f64>>,
    /// Never culled (the first keyframe, and both ends of a loop).
    pub keep: bool,
}

impl KeyFrame {
    pub fn pose(&self) -> Isometry3<f64> {
        self.frame.camera_from_world
    }

    pub fn centre(&self) -> Vector3<f64> {
        self.frame.centre()
    }

    /// The `n` most covisible keyframes.
    pub fn best_covisibles(&self, n: usize) -> Vec<usize> {
        self.ordered.iter().take(n).map(|&(k, _)| k).collect()
    }

    /// Covisible keyframes with at least `w` shared points.
    pub fn covisibles_by_weight(&self, w: usize) -> Vec<usize> {
        self.ordered
            .iter()
            .take_while(|&&(_, n)| n >= w)
            .map(|&(k, _)| k)
            .collect()
    }
}

#[derive(Debug, Clone)]
pub struct MapPoint {
    pub world: Vector3<f64>,
    pub descriptor: Descriptor,
    /// Keyframe → keypoint index.
    pub observations: BTreeMap<usize, usize>,
    /// Mean viewing direction (unit).
    pub normal: Vector3<f64>,
    /// Scale-invariance distances (`mfMinDistance`, `mfMaxDistance`).
    pub min_distance: f64,
    pub max_distance: f64,
    pub reference_kf: usize,
    pub first_kf: usize,
    /// Frames that should have seen it and frames that matched it.
    pub visible: u32,
    pub found: u32,
    pub bad: bool,
    pub replaced_by: Option<usize>,
}

impl MapPoint {
    pub fn found_ratio(&self) -> f64 {
        f64::from(self.found) / f64::from(self.visible.max(1))
    }
}

#[derive(Debug, Clone, Default)]
pub struct Map {
    pub keyframes: Vec<KeyFrame>,
    pub points: Vec<MapPoint>,
}

impl Map {
    pub fn live_keyframes(&self) -> impl Iterator<Item = &KeyFrame> {
        self.keyframes.iter().filter(|k| !k.bad)
    }

    pub fn live_keyframe_count(&self) -> usize {
        self.live_keyframes().count()
    }

    /// A point's observation count as ORB-SLAM2 keeps it: an observation with a right
    /// coordinate (depth) counts twice, as a stereo pair.
    pub fn observation_count(&self, p: usize) -> usize {
        self.points[p]
            .observations
            .iter()
            .map(|(&kf, &i)| {
                if self.keyframes[kf].frame.u_right[i] >= 0.0 {
                    2
                } else {
                    1
                }
            })
            .sum()
    }

    /// The point a (possibly replaced) point stands for now, if it is not bad.
    pub fn resolve(&self, mut p: usize) -> Option<usize> {
        for _ in 0..64 {
            let point = &self.points[p];
            match point.replaced_by {
                Some(q) => p = q,
                None => return (!point.bad).then_some(p),
            }
        }
        None
    }

    /// The live points the keyframes see, each once, in the order first met.
    pub fn points_of(&self, keyframes: &[usize]) -> Vec<usize> {
        let mut seen = BTreeSet::new();
        keyframes
            .iter()
            .flat_map(|&kf| self.keyframes[kf].frame.points.iter().flatten())
            .filter_map(|&p| self.resolve(p))
            .filter(|&p| seen.insert(p))
            .collect()
    }

    /// Adds a keyframe made from a frame; its points gain the observations.
    pub fn add_keyframe(&mut self, frame: Frame) -> usize {
        let id = self.keyframes.len();
        let observed: Vec<(usize, usize)> = frame
            .points
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (p, i)))
            .collect();
        self.keyframes.push(KeyFrame {
            id,
            frame,
            covisibility: BTreeMap::new(),
            ordered: Vec::new(),
            parent: None,
            children: BTreeSet::new(),
            loop_edges: BTreeSet::new(),
            bad: false,
            camera_from_parent: None,
            keep: id == 0,
        });
        for (p, i) in observed {
            if self.points[p].bad {
                self.keyframes[id].frame.points[i] = None;
                continue;
            }
            self.points[p].observations.insert(id, i);
        }
        id
    }

    /// A new point seen by keypoint `i` of keyframe `kf`.
    pub fn add_point(
        &mut self,
        camera: &Camera,
        world: Vector3<f64>,
        kf: usize,
        i: usize,
    ) -> usize {
        let id = self.points.len();
        let descriptor = self.keyframes[kf].frame.descriptors[i];
        self.points.push(MapPoint {
            world,
            descriptor,
            observations: BTreeMap::from([(kf, i)]),
            normal: Vector3::z(),
            min_distance: 0.0,
            max_distance: 0.0,
            reference_kf: kf,
            first_kf: kf,
            visible: 1,
            found: 1,
            bad: false,
            replaced_by: None,
        });
        self.keyframes[kf].frame.points[i] = Some(id);
        self.update_normal_and_depth(camera, id);
        id
    }

    pub fn add_observation(&mut self, p: usize, kf: usize, i: usize) {
        self.points[p].observations.insert(kf, i);
        self.keyframes[kf].frame.points[i] = Some(p);
    }

    /// Removes keyframe `kf`'s observation of `p`; a point left with an observation count
    /// of two or less (one keyframe with depth) is bad (as ORB-SLAM2's `EraseObservation`).
    pub fn erase_observation(&mut self, p: usize, kf: usize) {
        let point = &mut self.points[p];
        if let Some(i) = point.observations.remove(&kf) {
            if self.keyframes[kf].frame.points[i] == Some(p) {
                self.keyframes[kf].frame.points[i] = None;
            }
        }
        let point = &mut self.points[p];
        if point.reference_kf == kf {
            if let Some((&k, _)) = point.observations.iter().next() {
                point.reference_kf = k;
            }
        }
        if self.observation_count(p) <= 2 {
            self.set_point_bad(p);
        }
    }

    pub fn set_point_bad(&mut self, p: usize) {
        let observations = std::mem::take(&mut self.points[p].observations);
        self.points[p].bad = true;
        for (kf, i) in observations {
            if self.keyframes[kf].frame.points[i] == Some(p) {
                self.keyframes[kf].frame.points[i] = None;
            }
        }
    }

    /// Replaces point `old` by `new` in every keyframe that saw `old`.
    pub fn replace(&mut self, old: usize, new: usize) {
        if old == new || self.points[old].bad {
            return;
        }
        let observations = std::mem::take(&mut self.points[old].observations);
        let (visible, found) = (self.points[old].visible, self.points[old].found);
        self.points[old].bad = true;
        self.points[old].replaced_by = Some(new);
        for (kf, i) in observations {
            if self.points[new].observations.contains_key(&kf) {
                if self.keyframes[kf].frame.points[i] == Some(old) {
                    self.keyframes[kf].frame.points[i] = None;
                }
            } else {
                self.add_observation(new, kf, i);
            }
        }
        self.points[new].visible += visible;
        self.points[new].found += found;
        self.compute_distinctive_descriptor(new);
    }

    /// The observation's descriptor with the least median distance to the others.
    pub fn compute_distinctive_descriptor(&mut self, p: usize) {
        let descriptors: Vec<Descriptor> = self.points[p]
            .observations
            .iter()
            .filter(|(kf, _)| !self.keyframes[**kf].bad)
            .map(|(&kf, &i)| self.keyframes[kf].frame.descriptors[i])
            .collect();
        if descriptors.is_empty() {
            return;
        }
        let mut best = (u32::MAX, 0);
        for (a, da) in descriptors.iter().enumerate() {
            let mut d: Vec<u32> = descriptors.iter().map(|db| hamming(da, db)).collect();
            d.sort_unstable();
            let median = d[(d.len() - 1) / 2];
            if median < best.0 {
                best = (median, a);
            }
        }
        self.points[p].descriptor = descriptors[best.1];
    }

    /// Mean viewing direction and the scale-invariance distances from the reference
    /// keyframe's observation.
    pub fn update_normal_and_depth(&mut self, camera: &Camera, p: usize) {
        let point = &self.points[p];
        if point.bad || point.observations.is_empty() {
            return;
        }
        let mut normal = Vector3::zeros();
        let mut n = 0;
        for &kf in point.observations.keys() {
            let d = point.world - self.keyframes[kf].centre();
            if d.norm() > 0.0 {
                normal += d.normalize();
                n += 1;
            }
        }
        let reference = point.reference_kf;
        let Some(&i) = point.observations.get(&reference) else {
            return;
        };
        let distance = (point.world - self.keyframes[reference].centre()).norm();
        let level = usize::from(self.keyframes[reference].frame.keys[i].octave);
        let level_scale = camera.scale_factors[level];
        let top = camera.scale_factors[camera.levels() - 1];
        let point = &mut self.points[p];
        if n > 0 {
            point.normal = (normal / n as f64).normalize();
        }
        point.max_distance = distance * level_scale;
        point.min_distance = point.max_distance / top;
    }

    /// Recomputes a keyframe's covisibility edges from the points it sees, and makes the
    /// heaviest one its parent in the spanning tree if it has none.
    pub fn update_connections(&mut self, kf: usize) {
        let mut counts: BTreeMap<usize, usize> = BTreeMap::new();
        for p in self.keyframes[kf].frame.points.iter().flatten() {
            let point = &self.points[*p];
            if point.bad {
                continue;
            }
            for &other in point.observations.keys() {
                if other != kf && !self.keyframes[other].bad {
                    *counts.entry(other).or_default() += 1;
                }
            }
        }
        if counts.is_empty() {
            return;
        }
        let best = counts
            .iter()
            .max_by_key(|&(k, n)| (*n, std::cmp::Reverse(*k)))
            .map(|(&k, &n)| (k, n))
            .expect("not empty");
        let mut edges: BTreeMap<usize, usize> = counts
            .into_iter()
            .filter(|&(_, n)| n >= COVISIBILITY_MIN)
            .collect();
        if edges.is_empty() {
            edges.insert(best.0, best.1);
        }
        for (&other, &n) in &edges {
            self.add_connection(other, kf, n);
        }
        self.keyframes[kf].covisibility = edges;
        self.order(kf);
        if self.keyframes[kf].parent.is_none() && kf != 0 {
            let parent = self.keyframes[kf].ordered[0].0;
            self.keyframes[kf].parent = Some(parent);
            self.keyframes[parent].children.insert(kf);
        }
    }

    fn add_connection(&mut self, kf: usize, other: usize, weight: usize) {
        self.keyframes[kf].covisibility.insert(other, weight);
        self.order(kf);
    }

    fn order(&mut self, kf: usize) {
        let k = &mut self.keyframes[kf];
        k.ordered = k.covisibility.iter().map(|(&a, &b)| (a, b)).collect();
        k.ordered.sort_by_key(|&(id, w)| (std::cmp::Reverse(w), id));
    }

    /// Points of a keyframe with an observation count of at least `min_observations`.
    pub fn tracked_points(&self, kf: usize, min_observations: usize) -> usize {
        self.keyframes[kf]
            .frame
            .points
            .iter()
            .flatten()
            .filter(|&&p| !self.points[p].bad && self.observation_count(p) >= min_observations)
            .count()
    }

    /// Removes a keyframe from the graph (ORB-SLAM2's `KeyFrame::SetBadFlag`): its points
    /// lose the observation, its covisibility edges go, and its children are re-parented,
    /// each to the candidate it shares most points with, starting from its own parent.
    pub fn set_keyframe_bad(&mut self, kf: usize) {
        if self.keyframes[kf].keep || self.keyframes[kf].bad {
            return;
        }
        let neighbours: Vec<usize> = self.keyframes[kf].covisibility.keys().copied().collect();
        for other in neighbours {
            self.keyframes[other].covisibility.remove(&kf);
            self.order(other);
        }
        let points: Vec<usize> = self.keyframes[kf]
            .frame
            .points
            .iter()
            .flatten()
            .copied()
            .collect();
        for p in points {
            self.erase_observation(p, kf);
        }
        self.keyframes[kf].covisibility.clear();
        self.keyframes[kf].ordered.clear();
        let parent = self.keyframes[kf]
            .parent
            .expect("only the first keyframe has no parent");
        let mut candidates = BTreeSet::from([parent]);
        let mut children = std::mem::take(&mut self.keyframes[kf].children);
        while !children.is_empty() {
            let mut best: Option<(usize, usize, usize)> = None; // (weight, child, parent)
            for &child in &children {
                for (&c, &w) in &self.keyframes[child].covisibility {
                    if candidates.contains(&c) && best.is_none_or(|b| w > b.0) {
                        best = Some((w, child, c));
                    }
                }
            }
            let Some((_, child, new_parent)) = best else {
                break;
            };
            self.keyframes[child].parent = Some(new_parent);
            self.keyframes[new_parent].children.insert(child);
            candidates.insert(child);
            children.remove(&child);
        }
        for child in children {
            self.keyframes[child].parent = Some(parent);
            self.keyframes[parent].children.insert(child);
        }
        self.keyframes[parent].children.remove(&kf);
        let camera_from_parent =
            self.keyframes[kf].pose() * self.keyframes[parent].pose().inverse();
        let k = &mut self.keyframes[kf];
        k.camera_from_parent = Some(camera_from_parent);
        k.bad = true;
    }

    /// The pose of a keyframe, following culled keyframes to a live ancestor.
    pub fn carried_pose(&self, mut kf: usize) -> Isometry3<f64> {
        let mut camera_from_kf = Isometry3::identity();
        while self.keyframes[kf].bad {
            let k = &self.keyframes[kf];
            camera_from_kf *= k
                .camera_from_parent
                .expect("a culled keyframe keeps its offset");
            kf = k.parent.expect("a culled keyframe has a parent");
        }
        camera_from_kf * self.keyframes[kf].pose()
    }
}
