//! The optimisations of ORB-SLAM2's `Optimizer` on the shared bundle adjuster
//! (`slam_common::factor_graph::ba`, Levenberg–Marquardt with the point blocks eliminated by the Schur
//! complement): the frame's pose alone, the local bundle adjustment of a new keyframe's
//! covisible neighbourhood, and the global bundle adjustment after a loop.

use std::collections::{BTreeMap, BTreeSet};

use slam_common::factor_graph::ba::{
    self, CHI2_MONO, CHI2_STEREO, Observation, Options, PoseObservation, PoseVar, Problem,
};

use crate::frame::{Camera, Frame};
use crate::map::Map;

/// Pose-only optimisation of a frame against its matches (map points and temporary
/// points fixed), ORB-SLAM2's `PoseOptimization`: 4 rounds of 10 iterations, outliers
/// (χ² above 5.991 mono / 7.815 stereo) excluded between rounds. Marks `frame.outliers`;
/// returns the inliers.
pub fn optimize_frame_pose(camera: &Camera, frame: &mut Frame) -> usize {
    let mut index = Vec::new();
    let mut observations = Vec::new();
    for (i, m) in frame.matches.iter().enumerate() {
        let Some(m) = m else { continue };
        let key = &frame.keys[i];
        index.push(i);
        observations.push(PoseObservation {
            world: m.world,
            pixel: nalgebra::Vector2::new(f64::from(key.u), f64::from(key.v)),
            u_right: (frame.u_right[i] > 0.0).then_some(frame.u_right[i]),
            inv_sigma2: camera.inv_level_sigma2[usize::from(key.octave)],
        });
    }
    frame.outliers.iter_mut().for_each(|o| *o = false);
    if observations.len() < 3 {
        return 0;
    }
    let result = ba::optimize_pose(&camera.stereo, &frame.camera_from_world, &observations);
    frame.camera_from_world = result.camera_from_world;
    for (k, &i) in index.iter().enumerate() {
        frame.outliers[i] = !result.inliers[k];
    }
    result.inlier_count
}

/// What a local BA did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LocalBaStats {
    pub keyframes: usize,
    pub fixed: usize,
    pub points: usize,
    pub observations: usize,
    pub outliers_removed: usize,
}

/// Builds a BA problem over `local` keyframes (free, except the first keyframe of the
/// map), the live points they see, and `fixed` keyframes that also see those points.
struct Built {
    problem: Problem,
    pose_kf: Vec<usize>,
    point_id: Vec<usize>,
    obs_ref: Vec<(usize, usize)>,
}

fn build(map: &Map, camera: &Camera, local: &[usize], fixed: &[usize], points: &[usize]) -> Built {
    let mut pose_of: BTreeMap<usize, usize> = BTreeMap::new();
    let mut poses = Vec::new();
    let mut pose_kf = Vec::new();
    for (&kf, is_fixed) in local
        .iter()
        .map(|k| (k, false))
        .chain(fixed.iter().map(|k| (k, true)))
    {
        pose_of.insert(kf, poses.len());
        poses.push(PoseVar {
            camera_from_world: map.keyframes[kf].pose(),
            fixed: is_fixed || kf == 0,
        });
        pose_kf.push(kf);
    }
    let mut observations = Vec::new();
    let mut obs_ref = Vec::new();
    let mut world = Vec::new();
    for (j, &p) in points.iter().enumerate() {
        world.push(map.points[p].world);
        for (&kf, &i) in &map.points[p].observations {
            let Some(&pose) = pose_of.get(&kf) else {
                continue;
            };
            let frame = &map.keyframes[kf].frame;
            let key = &frame.keys[i];
            observations.push(Observation {
                pose,
                point: j,
                pixel: nalgebra::Vector2::new(f64::from(key.u), f64::from(key.v)),
                u_right: (frame.u_right[i] > 0.0).then_some(frame.u_right[i]),
                inv_sigma2: camera.inv_level_sigma2[usize::from(key.octave)],
                active: true,
            });
            obs_ref.push((kf, p));
        }
    }
    Built {
        problem: Problem {
            camera: camera.stereo,
            poses,
            points: world,
            observations,
        },
        pose_kf,
        point_id: points.to_vec(),
        obs_ref,
    }
}

fn write_back(map: &mut Map, camera: &Camera, built: &Built) {
    for (k, &kf) in built.pose_kf.iter().enumerate() {
        if !built.problem.poses[k].fixed {
            map.keyframes[kf].frame.camera_from_world = built.problem.poses[k].camera_from_world;
        }
    }
    for (j, &p) in built.point_id.iter().enumerate() {
        if !map.points[p].bad {
            map.points[p].world = built.problem.points[j];
            map.update_normal_and_depth(camera, p);
        }
    }
}

fn is_outlier(problem: &Problem, o: &Observation) -> bool {
    let th = if o.u_right.is_some() {
        CHI2_STEREO
    } else {
        CHI2_MONO
    };
    ba::chi2(problem, o) > th
}

/// Local BA around keyframe `kf` (`LocalBundleAdjustment`): `iterations` robust
/// iterations, outliers excluded, `iterations_after` more without the kernel, then the
/// outliers' observations erased from the map.
pub fn local_bundle_adjustment(
    map: &mut Map,
    camera: &Camera,
    kf: usize,
    iterations: usize,
    iterations_after: usize,
) -> LocalBaStats {
    let mut local = vec![kf];
    local.extend(
        map.keyframes[kf]
            .ordered
            .iter()
            .map(|&(k, _)| k)
            .filter(|&k| !map.keyframes[k].bad),
    );
    let local_set: BTreeSet<usize> = local.iter().copied().collect();
    let mut points = BTreeSet::new();
    for &k in &local {
        for p in map.keyframes[k].frame.points.iter().flatten() {
            if !map.points[*p].bad {
                points.insert(*p);
            }
        }
    }
    let mut fixed = BTreeSet::new();
    for &p in &points {
        for &k in map.points[p].observations.keys() {
            if !local_set.contains(&k) && !map.keyframes[k].bad {
                fixed.insert(k);
            }
        }
    }
    let points: Vec<usize> = points.into_iter().collect();
    let fixed: Vec<usize> = fixed.into_iter().collect();
    let mut built = build(map, camera, &local, &fixed, &points);
    let mut stats = LocalBaStats {
        keyframes: local.len(),
        fixed: fixed.len(),
        points: points.len(),
        observations: built.problem.observations.len(),
        outliers_removed: 0,
    };
    if built.problem.observations.is_empty() {
        return stats;
    }
    ba::bundle_adjust(
        &mut built.problem,
        &Options {
            iterations,
            robust: true,
            ..Options::default()
        },
    );
    let outliers: Vec<bool> = built
        .problem
        .observations
        .iter()
        .map(|o| is_outlier(&built.problem, o))
        .collect();
    for (o, &out) in built.problem.observations.iter_mut().zip(&outliers) {
        o.active = !out;
    }
    ba::bundle_adjust(
        &mut built.problem,
        &Options {
            iterations: iterations_after,
            robust: false,
            ..Options::default()
        },
    );
    let mut erase = Vec::new();
    for (k, o) in built.problem.observations.iter().enumerate() {
        let mut probe = *o;
        probe.active = true;
        if is_outlier(&built.problem, &probe) {
            erase.push(built.obs_ref[k]);
        }
    }
    write_back(map, camera, &built);
    stats.outliers_removed = erase.len();
    for (kf, p) in erase {
        if map.points[p].observations.contains_key(&kf) {
            map.erase_observation(p, kf);
        }
    }
    stats
}

/// Global BA over every live keyframe (the first fixed) and point (`GlobalBundleAdjustemnt`,
/// robust, no outlier removal).
pub fn global_bundle_adjustment(map: &mut Map, camera: &Camera, iterations: usize) {
    let local: Vec<usize> = map.live_keyframes().map(|k| k.id).collect();
    let points: Vec<usize> = (0..map.points.len())
        .filter(|&p| !map.points[p].bad && !map.points[p].observations.is_empty())
        .collect();
    let mut built = build(map, camera, &local, &[], &points);
    if built.problem.observations.is_empty() {
        return;
    }
    ba::bundle_adjust(
        &mut built.problem,
        &Options {
            iterations,
            robust: true,
            ..Options::default()
        },
    );
    write_back(map, camera, &built);
}
