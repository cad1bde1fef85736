//! Loop closing (ORB-SLAM, T-RO 2015, §VII; ORB-SLAM2 2017 §IV–V for RGB-D, where scale is
//! observable and the similarity is a rigid transform):
//!
//! 1. **detection**: keyframe-database candidates scoring at least the lowest score between
//!    the keyframe and its covisibles, never its covisibles themselves; a candidate is
//!    accepted once its covisibility group has been consistent over 3 consecutive
//!    keyframes;
//! 2. **geometry**: BoW matches (≥ 20), RANSAC of a rigid transform on their map points
//!    (minimal sets of 3, Horn's closed form; inliers by reprojection in both images,
//!    χ² 9.21), more matches guided by it, a pose optimisation (≥ 20 inliers), then the
//!    map points of the candidate and its covisibles projected into the keyframe
//!    (≥ 40 matches);
//! 3. **correction**: the keyframe and its covisibles moved by the correction, their
//!    points with them; the loop's points fused; the essential graph (spanning tree, loop
//!    edges, covisibility ≥ 100) optimised on the shared backend; a global bundle
//!    adjustment.
//!
//! As published, nothing limits the size of a correction: a false loop that passes the
//! geometric checks bends the map.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3, Vector6,
};
use rand::{Rng, SeedableRng};
use slam_common::factor_graph::backend::{self, BackendConfig, Factor, Robust, Value, Var};

use crate::config::LoopClosingConfig;
use crate::database::KeyFrameDatabase;
use crate::frame::{Camera, Frame};
use crate::map::Map;
use crate::matcher::{self, Source, TH_HIGH};
use crate::optimizer::global_bundle_adjustment;
use slam_common::factor_graph::ba::{self, PoseObservation};
use slam_common::place::vocabulary::Vocabulary;

/// What became of a loop candidate that passed the consistency test.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    Accepted {
        current: usize,
        matched: usize,
        inliers: usize,
        projected: usize,
        /// How far the correction moved the current keyframe, m and rad.
        correction_m: f64,
        correction_rad: f64,
        /// The loop's matches seen in both keyframes, `[u, v]` in the current keyframe then
        /// in the matched one (pixels): what the report draws over the two frames.
        keypoints: Vec<[f32; 4]>,
    },
    Rejected {
        current: usize,
        matched: usize,
        reason: String,
    },
}

#[derive(Debug, Default)]
pub struct LoopClosing {
    pub database: KeyFrameDatabase,
    /// Covisibility groups of the last keyframe's candidates and their consistency.
    groups: Vec<(BTreeSet<usize>, usize)>,
    last_loop_kf: usize,
    /// Seconds of the last correction (graph + global BA), for the timing report.
    pub last_correction_s: Option<f64>,
}

impl LoopClosing {
    /// Looks for a loop at keyframe `kf` and closes it; the keyframe joins the database.
    pub fn process(
        &mut self,
        kf: usize,
        map: &mut Map,
        camera: &Camera,
        cfg: &LoopClosingConfig,
        backend: &BackendConfig,
    ) -> Vec<Verdict> {
        let candidates = self.detect(kf, map, cfg);
        self.database.add(map, kf);
        let mut verdicts = Vec::new();
        for candidate in candidates {
            match verify(kf, candidate, map, camera, cfg) {
                Ok(found) => {
                    let start = std::time::Instant::now();
                    let before = map.keyframes[kf].centre();
                    let before_r = map.keyframes[kf].pose().rotation;
                    correct(map, camera, cfg, backend, kf, candidate, &found);
                    let after = map.keyframes[kf].centre();
                    self.last_correction_s = Some(start.elapsed().as_secs_f64());
                    self.last_loop_kf = kf;
                    self.groups.clear();
                    verdicts.push(Verdict::Accepted {
                        current: kf,
                        matched: candidate,
                        inliers: found.inliers,
                        projected: found.loop_matches.len(),
                        correction_m: (after - before).norm(),
                        correction_rad: before_r.angle_to(&map.keyframes[kf].pose().rotation),
                        keypoints: found.keypoints,
                    });
                    return verdicts;
                }
                Err(reason) => verdicts.push(Verdict::Rejected {
                    current: kf,
                    matched: candidate,
                    reason,
                }),
            }
        }
        verdicts
    }

    /// Candidates that have been consistent for `cfg.consistency` keyframes.
    fn detect(&mut self, kf: usize, map: &Map, cfg: &LoopClosingConfig) -> Vec<usize> {
        if !cfg.enabled
            || map.live_keyframe_count() <= cfg.min_keyframes
            || kf < self.last_loop_kf + cfg.min_keyframes
        {
            return Vec::new();
        }
        let k = &map.keyframes[kf];
        let connected: BTreeSet<usize> = k.covisibility.keys().copied().chain([kf]).collect();
        let min_score = k
            .covisibility
            .keys()
            .filter(|&&c| !map.keyframes[c].bad)
            .map(|&c| Vocabulary::score(&k.frame.bow, &map.keyframes[c].frame.bow))
            .fold(1.0f64, f64::min);
        let candidates = self.database.candidates(
            map,
            &k.frame.bow,
            &connected,
            min_score,
            cfg.common_words_ratio,
            cfg.group_score_ratio,
        );
        if candidates.is_empty() {
            self.groups.clear();
            return Vec::new();
        }
        let mut current: Vec<(BTreeSet<usize>, usize)> = Vec::new();
        let mut consistent_with = vec![false; self.groups.len()];
        let mut enough = Vec::new();
        for c in candidates {
            let group: BTreeSet<usize> = map.keyframes[c]
                .covisibility
                .keys()
                .copied()
                .chain([c])
                .collect();
            let mut found = false;
            let mut added = false;
            for (g, (previous, n)) in self.groups.iter().enumerate() {
                if group.is_disjoint(previous) {
                    continue;
                }
                found = true;
                let consistency = n + 1;
                if !consistent_with[g] {
                    current.push((group.clone(), consistency));
                    consistent_with[g] = true;
                }
                if consistency >= cfg.consistency && !added {
                    enough.push(c);
                    added = true;
                }
            }
            if !found {
                current.push((group, 0));
            }
        }
        self.groups = current;
        enough
    }
}

/// A verified loop: the corrected pose of the current keyframe and the loop's map points
/// matched in it (keypoint → point).
#[derive(Debug, Clone)]
struct Found {
    corrected: Isometry3<f64>,
    inliers: usize,
    loop_matches: BTreeMap<usize, usize>,
    loop_points: Vec<usize>,
    /// The loop matches whose map point the candidate keyframe itself observes, as pixel
    /// pairs (current, then candidate).
    keypoints: Vec<[f32; 4]>,
}

/// Horn's closed form (J. Opt. Soc. Am. A 4(4), 1987) through the SVD of the
/// cross-covariance (Umeyama 1991 without scale): the rigid `a_from_b` best mapping `b` onto `a`.
pub fn rigid_from_points(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<Isometry3<f64>> {
    let n = a.len() as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (pa, pb) in a.iter().zip(b) {
        h += (pb - cb) * (pa - ca).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = v_t.transpose() * d * u.transpose();
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = ca - rotation * cb;
    Some(Isometry3::from_parts(Translation3::from(t), rotation))
}

/// Geometric verification of candidate `c` for keyframe `kf`.
fn verify(
    kf: usize,
    c: usize,
    map: &Map,
    camera: &Camera,
    cfg: &LoopClosingConfig,
) -> Result<Found, String> {
    let pairs = matcher::search_bow_keyframes(map, kf, c, 0.75);
    if pairs.len() < cfg.min_bow_matches {
        return Err(format!(
            "{} BoW matches (< {})",
            pairs.len(),
            cfg.min_bow_matches
        ));
    }
    let (f1, f2) = (&map.keyframes[kf].frame, &map.keyframes[c].frame);
    let (t1, t2) = (f1.camera_from_world, f2.camera_from_world);
    // Map points of each side in its own camera frame.
    let p1: Vec<Vector3<f64>> = pairs
        .iter()
        .map(|&(i1, _)| {
            t1 * Point3::from(
                map.points[map.resolve(f1.points[i1].expect("matched")).expect("live")].world,
            )
        })
        .map(|p| p.coords)
        .collect();
    let p2: Vec<Vector3<f64>> = pairs
        .iter()
        .map(|&(_, i2)| {
            t2 * Point3::from(
                map.points[map.resolve(f2.points[i2].expect("matched")).expect("live")].world,
            )
        })
        .map(|p| p.coords)
        .collect();
    let inlier = |t12: &Isometry3<f64>, k: usize| -> bool {
        let (i1, i2) = pairs[k];
        let in1 = t12 * Point3::from(p2[k]);
        let in2 = t12.inverse() * Point3::from(p1[k]);
        let ok = |frame: &Frame, i: usize, p: &Vector3<f64>| {
            let Some((u, v)) = camera.project(p) else {
                return false;
            };
            let key = &frame.keys[i];
            let e = Vector2::new(u - f64::from(key.u), v - f64::from(key.v));
            e.norm_squared() < 9.21 * camera.level_sigma2[usize::from(key.octave)]
        };
        ok(f1, i1, &in1.coords) && ok(f2, i2, &in2.coords)
    };
    // RANSAC, 300 iterations at most, seeded by the pair of keyframes (deterministic).
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64((kf as u64) << 32 | c as u64);
    let mut best: Option<(usize, Isometry3<f64>)> = None;
    for _ in 0..300 {
        let pick: [usize; 3] = std::array::from_fn(|_| rng.random_range(0..pairs.len()));
        if pick[0] == pick[1] || pick[1] == pick[2] || pick[0] == pick[2] {
            continue;
        }
        let a: Vec<_> = pick.iter().map(|&k| p1[k]).collect();
        let b: Vec<_> = pick.iter().map(|&k| p2[k]).collect();
        let Some(t12) = rigid_from_points(&a, &b) else {
            continue;
        };
        let n = (0..pairs.len()).filter(|&k| inlier(&t12, k)).count();
        if best.is_none_or(|(m, _)| n > m) {
            best = Some((n, t12));
        }
    }
    let Some((_, t12)) = best.filter(|&(n, _)| n >= cfg.min_inliers) else {
        return Err(format!(
            "RANSAC: {} inliers (< {})",
            best.map_or(0, |b| b.0),
            cfg.min_inliers
        ));
    };
    // Guided matching: the candidate's points projected into the keyframe with t12.
    let mut matched: BTreeMap<usize, usize> = pairs
        .iter()
        .map(|&(i1, i2)| {
            (
                i1,
                map.resolve(f2.points[i2].expect("matched")).expect("live"),
            )
        })
        .collect();
    let scw = t12 * t2;
    let mut probe = f1.clone();
    probe.matches.iter_mut().for_each(|m| *m = None);
    for (&i, &p) in &matched {
        probe.matches[i] = Some(source(map, p, f1, i));
    }
    probe.camera_from_world = scw;
    guided(
        map,
        camera,
        &mut probe,
        f2.points.iter().flatten().filter_map(|&p| map.resolve(p)),
        7.5,
    );
    for (i, m) in probe.matches.iter().enumerate() {
        if let Some(p) = m.and_then(|m| m.map_point) {
            matched.entry(i).or_insert(p);
        }
    }
    // Pose optimisation of the keyframe against the candidate's points (fixed scale).
    let obs: Vec<(usize, PoseObservation)> = matched
        .iter()
        .map(|(&i, &p)| {
            let key = &f1.keys[i];
            (
                i,
                PoseObservation {
                    world: map.points[p].world,
                    pixel: Vector2::new(f64::from(key.u), f64::from(key.v)),
                    u_right: (f1.u_right[i] > 0.0).then_some(f1.u_right[i]),
                    inv_sigma2: camera.inv_level_sigma2[usize::from(key.octave)],
                },
            )
        })
        .collect();
    let only: Vec<PoseObservation> = obs.iter().map(|(_, o)| *o).collect();
    let result = ba::optimize_pose(&camera.stereo, &scw, &only);
    if result.inlier_count < cfg.min_inliers {
        return Err(format!(
            "pose optimisation: {} inliers (< {})",
            result.inlier_count, cfg.min_inliers
        ));
    }
    let corrected = result.camera_from_world;
    let mut loop_matches: BTreeMap<usize, usize> = obs
        .iter()
        .zip(&result.inliers)
        .filter(|(_, ok)| **ok)
        .map(|((i, _), _)| (*i, matched[i]))
        .collect();
    // The loop's map points (the candidate and its covisibles) projected with the
    // corrected pose (radius 10).
    let mut loop_kfs = vec![c];
    loop_kfs.extend(
        map.keyframes[c]
            .best_covisibles(usize::MAX)
            .into_iter()
            .filter(|&k| !map.keyframes[k].bad),
    );
    let loop_points = map.points_of(&loop_kfs);
    let mut probe = f1.clone();
    probe.matches.iter_mut().for_each(|m| *m = None);
    for (&i, &p) in &loop_matches {
        probe.matches[i] = Some(source(map, p, f1, i));
    }
    probe.camera_from_world = corrected;
    guided(map, camera, &mut probe, loop_points.iter().copied(), 10.0);
    for (i, m) in probe.matches.iter().enumerate() {
        if let Some(p) = m.and_then(|m| m.map_point) {
            loop_matches.entry(i).or_insert(p);
        }
    }
    if loop_matches.len() < cfg.min_projected_matches {
        return Err(format!(
            "{} matches of the loop's map points (< {})",
            loop_matches.len(),
            cfg.min_projected_matches
        ));
    }
    let keypoints = loop_matches
        .iter()
        .filter_map(|(&i, &p)| {
            let j = *map.points[map.resolve(p)?].observations.get(&c)?;
            let (a, b) = (&f1.keys[i], &map.keyframes[c].frame.keys[j]);
            Some([a.u, a.v, b.u, b.v])
        })
        .collect();
    Ok(Found {
        corrected,
        inliers: result.inlier_count,
        loop_matches,
        loop_points,
        keypoints,
    })
}

fn source(map: &Map, p: usize, frame: &Frame, i: usize) -> Source {
    Source {
        world: map.points[p].world,
        descriptor: map.points[p].descriptor,
        octave: frame.keys[i].octave,
        angle_deg: frame.keys[i].angle_deg,
        map_point: Some(p),
    }
}

/// Projects points into a probe frame at its pose and matches them to its free keypoints
/// within `th` × the level's scale (Hamming ≤ 100), as `SearchByProjection` with a pose.
fn guided(
    map: &Map,
    camera: &Camera,
    probe: &mut Frame,
    points: impl Iterator<Item = usize>,
    th: f64,
) {
    let taken: BTreeSet<usize> = probe
        .matches
        .iter()
        .flatten()
        .filter_map(|m| m.map_point)
        .collect();
    for p in points {
        if taken.contains(&p) {
            continue;
        }
        let Some((u, v, level, _)) = matcher::in_frustum(map, camera, &probe.camera_from_world, p)
        else {
            continue;
        };
        let r = th * camera.scale_factors[level];
        let point = &map.points[p];
        let mut best = (u32::MAX, None);
        for i in probe.features_in_area(camera, u, v, r, 0, camera.levels() - 1) {
            if probe.matches[i].is_some() {
                continue;
            }
            let d = slam_common::place::bow::hamming(&point.descriptor, &probe.descriptors[i]);
            if d < best.0 {
                best = (d, Some(i));
            }
        }
        if let (d, Some(i)) = best {
            if d <= TH_HIGH / 2 {
                probe.matches[i] = Some(source(map, p, probe, i));
            }
        }
    }
}

/// Closes the loop: poses and points of the keyframe's neighbourhood corrected, loop points
/// fused, essential graph optimised, global BA.
fn correct(
    map: &mut Map,
    camera: &Camera,
    cfg: &LoopClosingConfig,
    backend_cfg: &BackendConfig,
    kf: usize,
    loop_kf: usize,
    found: &Found,
) {
    // Connections before the correction, to find the new (loop) links afterwards.
    let mut connected = vec![kf];
    connected.extend(
        map.keyframes[kf]
            .best_covisibles(usize::MAX)
            .into_iter()
            .filter(|&k| !map.keyframes[k].bad),
    );
    let old_pose: BTreeMap<usize, Isometry3<f64>> = connected
        .iter()
        .map(|&k| (k, map.keyframes[k].pose()))
        .collect();
    let twc = old_pose[&kf].inverse();
    let corrected: BTreeMap<usize, Isometry3<f64>> = connected
        .iter()
        .map(|&k| (k, old_pose[&k] * twc * found.corrected))
        .collect();
    // Points seen by the neighbourhood move with it.
    let mut moved = BTreeSet::new();
    for &k in &connected {
        for p in map.keyframes[k].frame.points.clone().into_iter().flatten() {
            if map.points[p].bad || !moved.insert(p) {
                continue;
            }
            let local = old_pose[&k] * Point3::from(map.points[p].world);
            map.points[p].world = (corrected[&k].inverse() * local).coords;
            map.points[p].reference_kf = k;
        }
    }
    for &k in &connected {
        map.keyframes[k].frame.camera_from_world = corrected[&k];
    }
    for &p in &moved {
        map.update_normal_and_depth(camera, p);
    }
    // Fuse the loop's points matched in the keyframe, then into the whole neighbourhood.
    for (&i, &p) in &found.loop_matches {
        let Some(p) = map.resolve(p) else { continue };
        match map.keyframes[kf].frame.points[i].and_then(|q| map.resolve(q)) {
            Some(q) if q != p => map.replace(q, p),
            Some(_) => {}
            None => {
                if !map.points[p].observations.contains_key(&kf) {
                    map.add_observation(p, kf, i);
                    map.compute_distinctive_descriptor(p);
                }
            }
        }
    }
    for &k in &connected {
        let pose = map.keyframes[k].pose();
        matcher::fuse(map, camera, k, &pose, &found.loop_points, 4.0);
    }
    let before: BTreeMap<usize, BTreeSet<usize>> = connected
        .iter()
        .map(|&k| (k, map.keyframes[k].covisibility.keys().copied().collect()))
        .collect();
    let mut loop_links: Vec<(usize, usize)> = Vec::new();
    for &k in &connected {
        map.update_connections(k);
        for &n in map.keyframes[k].covisibility.keys() {
            if !before[&k].contains(&n) && !connected.contains(&n) {
                loop_links.push((k, n));
            }
        }
    }
    map.keyframes[kf].loop_edges.insert(loop_kf);
    map.keyframes[loop_kf].loop_edges.insert(kf);
    map.keyframes[kf].keep = true;
    map.keyframes[loop_kf].keep = true;
    loop_links.push((kf, loop_kf));
    optimize_essential_graph(
        map,
        camera,
        cfg,
        backend_cfg,
        loop_kf,
        &loop_links,
        &old_pose,
    );
    global_bundle_adjustment(map, camera, cfg.global_ba_iterations);
}

/// The essential graph (ORB-SLAM 2015 §VII-D): every keyframe, with edges along the
/// spanning tree, the loop edges, the new loop links and covisibility edges of weight ≥ 100,
/// each measuring the relative pose before this optimisation (for the corrected
/// neighbourhood, the poses before the correction where the edge leaves it). The loop
/// keyframe is held fixed. Points follow their reference keyframe.
fn optimize_essential_graph(
    map: &mut Map,
    camera: &Camera,
    cfg: &LoopClosingConfig,
    backend_cfg: &BackendConfig,
    fixed: usize,
    loop_links: &[(usize, usize)],
    uncorrected: &BTreeMap<usize, Isometry3<f64>>,
) {
    let Ok(mut graph) = backend::from_config(backend_cfg) else {
        return;
    };
    let live: Vec<usize> = map.live_keyframes().map(|k| k.id).collect();
    let pose_before: BTreeMap<usize, Isometry3<f64>> =
        live.iter().map(|&k| (k, map.keyframes[k].pose())).collect();
    for &k in &live {
        let _ = graph.insert(Var::Pose(k as u64), Value::Pose(pose_before[&k].inverse()));
    }
    let sigmas = Vector6::from_element(1.0);
    let _ = graph.add(Factor::PosePrior {
        key: fixed as u64,
        world_from_body: pose_before[&fixed].inverse(),
        sigmas: Vector6::from_element(1e-6),
    });
    let mut edges: BTreeSet<(usize, usize)> = BTreeSet::new();
    let links: BTreeSet<(usize, usize)> = loop_links
        .iter()
        .map(|&(a, b)| (a.min(b), a.max(b)))
        .collect();
    for &k in &live {
        let kfm = &map.keyframes[k];
        let mut add = |a: usize, b: usize| {
            if a != b && !map.keyframes[b].bad {
                edges.insert((a.min(b), a.max(b)));
            }
        };
        if let Some(p) = kfm.parent {
            add(k, p);
        }
        for &l in &kfm.loop_edges {
            add(k, l);
        }
        for n in kfm.covisibles_by_weight(cfg.essential_min_weight) {
            add(k, n);
        }
    }
    edges.extend(links.iter().copied());
    for (a, b) in edges {
        // The measured relative pose: across a new loop link, the corrected poses; else
        // the poses before the correction, so the correction spreads along the graph.
        let is_link = links.contains(&(a, b));
        let pose = |k: usize| {
            if is_link {
                pose_before[&k]
            } else {
                uncorrected.get(&k).copied().unwrap_or(pose_before[&k])
            }
        };
        let a_from_b = pose(a) * pose(b).inverse();
        let _ = graph.add(Factor::Between {
            from: a as u64,
            to: b as u64,
            from_from_to: a_from_b,
            sigmas,
            robust: Robust::None,
        });
    }
    if graph.update(backend::Scope::Full).is_err() {
        return;
    }
    for &k in &live {
        if let Some(world_from_camera) = graph.pose(k as u64) {
            map.keyframes[k].frame.camera_from_world = world_from_camera.inverse();
        }
    }
    for p in 0..map.points.len() {
        if map.points[p].bad {
            continue;
        }
        let r = map.points[p].reference_kf;
        if map.keyframes[r].bad {
            continue;
        }
        let local = pose_before[&r] * Point3::from(map.points[p].world);
        map.points[p].world = (map.keyframes[r].pose().inverse() * local).coords;
        map.update_normal_and_depth(camera, p);
    }
}
