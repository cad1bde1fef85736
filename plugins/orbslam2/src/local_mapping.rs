//! Local mapping (ORB-SLAM, T-RO 2015, §VI; ORB-SLAM2's `LocalMapping`), run on every new
//! keyframe: its points gain the observation and the covisibility graph its edges; recent
//! points that tracking rarely finds are culled; new points are triangulated with the
//! covisible keyframes ([`crate::triangulation`]); duplicates are fused with the covisible
//! neighbourhood; a local bundle adjustment refines the neighbourhood; keyframes whose
//! close points are nearly all seen by three others at the same or a finer scale are
//! culled.
//!
//! In this plugin local mapping runs after tracking in the same thread, so a keyframe is
//! always fully mapped before the next frame is tracked (deterministic; ORB-SLAM2 runs it
//! in its own thread and may interrupt a local BA).

use std::collections::BTreeSet;

use crate::config::LocalMappingConfig;
use crate::frame::Camera;
use crate::map::Map;
use crate::matcher;
use crate::optimizer::{LocalBaStats, local_bundle_adjustment};
use crate::triangulation::create_new_points;

#[derive(Debug, Default)]
pub struct LocalMapping {
    /// Points created recently, watched by the culling test.
    recent: Vec<usize>,
}

/// What one keyframe's local mapping did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stats {
    pub points_culled: usize,
    pub points_created: usize,
    pub fused: usize,
    pub ba: LocalBaStats,
    pub keyframes_culled: usize,
}

impl LocalMapping {
    /// Maps keyframe `kf`; returns the keyframes culled.
    pub fn process(
        &mut self,
        kf: usize,
        map: &mut Map,
        camera: &Camera,
        cfg: &LocalMappingConfig,
    ) -> (Stats, Vec<usize>) {
        let mut stats = Stats::default();
        self.process_new_keyframe(kf, map, camera);
        stats.points_culled = self.cull_points(kf, map, cfg);
        let created = create_new_points(map, camera, kf, cfg.triangulation_neighbours);
        stats.points_created = created.len();
        self.recent.extend(created);
        stats.fused = search_in_neighbours(kf, map, camera, cfg);
        if map.live_keyframe_count() > 2 {
            stats.ba = local_bundle_adjustment(
                map,
                camera,
                kf,
                cfg.ba_iterations,
                cfg.ba_iterations_after,
            );
        }
        let culled = cull_keyframes(kf, map, camera, cfg);
        stats.keyframes_culled = culled.len();
        (stats, culled)
    }

    fn process_new_keyframe(&mut self, kf: usize, map: &mut Map, camera: &Camera) {
        let points: Vec<(usize, usize)> = map.keyframes[kf]
            .frame
            .points
            .iter()
            .enumerate()
            .filter_map(|(i, p)| p.map(|p| (i, p)))
            .collect();
        for (i, p) in points {
            if map.points[p].bad {
                map.keyframes[kf].frame.points[i] = None;
                continue;
            }
            if map.points[p].first_kf == kf {
                self.recent.push(p);
            } else {
                map.points[p].observations.insert(kf, i);
            }
            map.update_normal_and_depth(camera, p);
            map.compute_distinctive_descriptor(p);
        }
        map.update_connections(kf);
    }

    /// Recent points found in under a quarter of the frames that should have seen them, or
    /// with an observation count of three or less (a keyframe with depth counts two) two
    /// keyframes on, are removed; after three
    /// keyframes a point is no longer recent.
    fn cull_points(&mut self, kf: usize, map: &mut Map, cfg: &LocalMappingConfig) -> usize {
        let mut culled = 0;
        let recent = std::mem::take(&mut self.recent);
        for p in recent {
            let point = &map.points[p];
            let age = kf.saturating_sub(point.first_kf);
            if point.bad {
                continue;
            }
            if point.found_ratio() < cfg.found_ratio
                || (age >= 2 && map.observation_count(p) <= cfg.min_observations)
            {
                map.set_point_bad(p);
                culled += 1;
            } else if age < 3 {
                self.recent.push(p);
            }
        }
        culled
    }
}

/// Fuses duplicates between keyframe `kf` and its neighbourhood (the best covisibles and
/// theirs), both ways (`SearchInNeighbors`), then refreshes the points and the edges.
fn search_in_neighbours(
    kf: usize,
    map: &mut Map,
    camera: &Camera,
    cfg: &LocalMappingConfig,
) -> usize {
    let mut targets = Vec::new();
    let mut set = BTreeSet::from([kf]);
    for n in map.keyframes[kf].best_covisibles(cfg.fuse_neighbours) {
        if map.keyframes[n].bad || !set.insert(n) {
            continue;
        }
        targets.push(n);
    }
    for n in targets.clone() {
        for m in map.keyframes[n].best_covisibles(cfg.fuse_second_neighbours) {
            if !map.keyframes[m].bad && set.insert(m) {
                targets.push(m);
            }
        }
    }
    let mut fused = 0;
    let own: Vec<usize> = map.keyframes[kf]
        .frame
        .points
        .iter()
        .flatten()
        .copied()
        .collect();
    for &t in &targets {
        let pose = map.keyframes[t].pose();
        fused += matcher::fuse(map, camera, t, &pose, &own, 3.0);
    }
    let theirs = map.points_of(&targets);
    let pose = map.keyframes[kf].pose();
    fused += matcher::fuse(map, camera, kf, &pose, &theirs, 3.0);
    let own: Vec<usize> = map.keyframes[kf]
        .frame
        .points
        .iter()
        .flatten()
        .copied()
        .collect();
    for p in own {
        if !map.points[p].bad {
            map.compute_distinctive_descriptor(p);
            map.update_normal_and_depth(camera, p);
        }
    }
    map.update_connections(kf);
    fused
}

/// Culls redundant covisibles of `kf` (`KeyFrameCulling`): a keyframe at least 90 % of
/// whose close points are seen by three other keyframes at the same or a finer scale.
fn cull_keyframes(
    kf: usize,
    map: &mut Map,
    camera: &Camera,
    cfg: &LocalMappingConfig,
) -> Vec<usize> {
    let mut culled = Vec::new();
    for n in map.keyframes[kf].best_covisibles(usize::MAX) {
        let k = &map.keyframes[n];
        if k.bad || k.keep {
            continue;
        }
        let (mut points, mut redundant) = (0usize, 0usize);
        for (i, p) in k.frame.points.iter().enumerate() {
            let Some(p) = p else { continue };
            let point = &map.points[*p];
            if point.bad || !k.frame.is_close(camera, i) {
                continue;
            }
            points += 1;
            if map.observation_count(*p) <= cfg.redundant_observers {
                continue;
            }
            let level = k.frame.keys[i].octave;
            let observers = point
                .observations
                .iter()
                .filter(|&(&o, &j)| {
                    o != n
                        && !map.keyframes[o].bad
                        && map.keyframes[o].frame.keys[j].octave <= level + 1
                })
                .count();
            if observers >= cfg.redundant_observers {
                redundant += 1;
            }
        }
        if points > 0 && redundant as f64 > cfg.redundant_ratio * points as f64 {
            map.set_keyframe_bad(n);
            culled.push(n);
        }
    }
    culled
}
