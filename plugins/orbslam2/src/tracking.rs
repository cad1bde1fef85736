//! Tracking (ORB-SLAM2's `Tracking`, Mur-Artal and Tardós 2017 §III; ORB-SLAM 2015 §V):
//! every frame is matched to the last one with a constant-velocity motion model (or to the
//! reference keyframe by bag of words), its pose optimised, then refined against the local
//! map (keyframes covisible with what it sees); the keyframe decision follows the published
//! rules. When tracking fails the system is lost until relocalisation (BoW candidates from
//! the keyframe database, PnP RANSAC, pose optimisation, a guided search) succeeds.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, Point2f, Point3f, Vector};
use opencv::prelude::*;
use slam_common::place::vocabulary::Vocabulary;

use crate::config::Config;
use crate::database::KeyFrameDatabase;
use crate::frame::{Camera, Frame};
use crate::map::Map;
use crate::matcher::{self, Source};
use crate::optimizer::optimize_frame_pose;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    NotInitialized,
    Ok,
    Lost,
}

/// What tracking made of a frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Too few features to start the map.
    NotInitialized,
    /// Tracked; `keyframe` when a new keyframe was made of it.
    Tracked {
        keyframe: Option<usize>,
        relocalised: bool,
    },
    /// Tracking failed on this frame (`newly` on the first failed frame).
    Lost { newly: bool },
}

/// Everything tracking needs that it does not own.
#[derive(Debug)]
pub struct Context<'a> {
    pub cfg: &'a Config,
    pub camera: &'a Camera,
    pub vocabulary: &'a Vocabulary,
    pub database: &'a KeyFrameDatabase,
    /// Camera frames per second (ORB-SLAM2's `mMaxFrames`).
    pub fps: u64,
}

#[derive(Debug)]
pub struct Tracking {
    pub state: State,
    frame_count: u64,
    last: Option<Frame>,
    /// The last frame's pose relative to its reference keyframe, to follow BA's changes.
    last_from_reference: Option<(usize, Isometry3<f64>)>,
    /// `camera_from_world` of this frame times the inverse of the last one's.
    velocity: Option<Isometry3<f64>>,
    pub reference_kf: Option<usize>,
    last_kf_frame: u64,
    last_reloc_frame: u64,
    local_kfs: Vec<usize>,
    local_points: Vec<usize>,
    /// Map points matched in the current frame (the keyframe decision's count).
    pub inliers: usize,
    /// Localisation mode (ORB-SLAM2's `mbOnlyTracking`): no keyframes are made, the map is
    /// read only.
    pub only_tracking: bool,
    /// In localisation mode, tracking holds by the last frame's depth points with fewer than
    /// 10 map points matched (ORB-SLAM2's `mbVO`): visual odometry, not localised.
    pub vo: bool,
}

impl Default for Tracking {
    fn default() -> Self {
        Self {
            state: State::NotInitialized,
            frame_count: 0,
            last: None,
            last_from_reference: None,
            velocity: None,
            reference_kf: None,
            last_kf_frame: 0,
            last_reloc_frame: 0,
            local_kfs: Vec::new(),
            local_points: Vec::new(),
            inliers: 0,
            only_tracking: false,
            vo: false,
        }
    }
}

impl Tracking {
    /// Tracking for localisation in a loaded map (ORB-SLAM2's `ActivateLocalizationMode`):
    /// lost until relocalisation finds the first frame in the map.
    pub fn localizing() -> Self {
        Self {
            state: State::Lost,
            only_tracking: true,
            ..Self::default()
        }
    }

    /// Whether the last frame was tracked against the map's points (localisation mode: not
    /// lost and not by visual odometry alone).
    pub fn localized(&self) -> bool {
        self.state == State::Ok && !self.vo
    }

    /// Tracks one frame. `initial` is the first frame's `camera_from_world` (the map frame).
    pub fn track(
        &mut self,
        frame: &mut Frame,
        map: &mut Map,
        ctx: &Context<'_>,
        initial: &Isometry3<f64>,
    ) -> Outcome {
        self.frame_count += 1;
        if self.state == State::NotInitialized {
            return self.initialise(frame, map, ctx, initial);
        }
        let mut relocalised = false;
        let mut ok = match self.state {
            State::Ok if self.only_tracking => self.track_only(frame, map, ctx, &mut relocalised),
            State::Ok => {
                let recent_reloc = self.frame_count < self.last_reloc_frame + 2;
                let mut ok = false;
                if self.velocity.is_some() && !recent_reloc {
                    ok = self.track_motion_model(frame, map, ctx);
                }
                ok || self.track_reference_keyframe(frame, map, ctx)
            }
            _ => {
                relocalised = self.relocalise(frame, map, ctx);
                if relocalised {
                    self.vo = false;
                }
                relocalised
            }
        };
        if ok && !(self.only_tracking && self.vo) {
            ok = self.track_local_map(frame, map, ctx);
        }
        let was_ok = self.state == State::Ok;
        if !ok {
            self.state = State::Lost;
            self.velocity = None;
            self.last = None;
            return Outcome::Lost { newly: was_ok };
        }
        self.state = State::Ok;
        if relocalised {
            self.last_reloc_frame = self.frame_count;
        }
        if let Some(last) = &self.last {
            self.velocity = Some(frame.camera_from_world * last.camera_from_world.inverse());
        }
        let keyframe = (!self.only_tracking && self.need_new_keyframe(frame, map, ctx))
            .then(|| self.create_keyframe(frame, map, ctx));
        // Points BA may still accept go to the keyframe; the next frame does not use them.
        for (m, out) in frame.matches.iter_mut().zip(&frame.outliers) {
            if *out || m.is_some_and(|s| s.map_point.is_none()) {
                *m = None;
            }
        }
        let reference = self
            .reference_kf
            .expect("tracking has a reference keyframe");
        self.last_from_reference = Some((
            reference,
            frame.camera_from_world * map.keyframes[reference].pose().inverse(),
        ));
        self.last = Some(frame.clone());
        Outcome::Tracked {
            keyframe,
            relocalised,
        }
    }

    /// The pose of the current frame relative to its reference keyframe.
    pub fn reference(&self) -> Option<(usize, Isometry3<f64>)> {
        self.last_from_reference
    }

    /// RGB-D initialisation: the first frame with more than 500 keypoints becomes a
    /// keyframe with a map point at every keypoint that has depth.
    fn initialise(
        &mut self,
        frame: &mut Frame,
        map: &mut Map,
        ctx: &Context<'_>,
        initial: &Isometry3<f64>,
    ) -> Outcome {
        if frame.len() <= 500 {
            return Outcome::NotInitialized;
        }
        frame.camera_from_world = *initial;
        frame.compute_bow(ctx.vocabulary);
        let kf = map.add_keyframe(frame.clone());
        for i in 0..frame.len() {
            if let Some(world) = frame.unproject_world(ctx.camera, i) {
                let p = map.add_point(ctx.camera, world, kf, i);
                frame.matches[i] = Some(source_of(map, frame, i, p));
            }
        }
        self.state = State::Ok;
        self.reference_kf = Some(kf);
        self.last_kf_frame = self.frame_count;
        self.local_kfs = vec![kf];
        self.local_points = map.keyframes[kf]
            .frame
            .points
            .iter()
            .flatten()
            .copied()
            .collect();
        self.last_from_reference = Some((kf, Isometry3::identity()));
        self.last = Some(frame.clone());
        Outcome::Tracked {
            keyframe: Some(kf),
            relocalised: false,
        }
    }

    /// The last frame's matches as sources, its pose moved with its reference keyframe, and
    /// temporary points from its close depth (`UpdateLastFrame`).
    fn last_frame_sources(&mut self, map: &Map, ctx: &Context<'_>) -> Vec<Source> {
        let Some(last) = self.last.as_mut() else {
            return Vec::new();
        };
        if let Some((kf, last_from_ref)) = self.last_from_reference {
            last.camera_from_world = last_from_ref * map.keyframes[kf].pose();
        }
        let mut sources = Vec::new();
        let mut order: Vec<usize> = (0..last.len()).filter(|&i| last.depth[i] > 0.0).collect();
        order.sort_by(|&a, &b| last.depth[a].total_cmp(&last.depth[b]).then(a.cmp(&b)));
        let mut temporal = 0;
        let mut has_point = vec![false; last.len()];
        for (i, m) in last.matches.iter().enumerate() {
            if let Some(p) = m.and_then(|s| s.map_point).and_then(|p| map.resolve(p)) {
                has_point[i] = true;
                let key = &last.keys[i];
                sources.push(Source {
                    world: map.points[p].world,
                    descriptor: map.points[p].descriptor,
                    octave: key.octave,
                    angle_deg: key.angle_deg,
                    map_point: Some(p),
                });
            }
        }
        for i in order {
            if !has_point[i] {
                let key = &last.keys[i];
                let world = last.unproject_world(ctx.camera, i).expect("has depth");
                sources.push(Source {
                    world,
                    descriptor: last.descriptors[i],
                    octave: key.octave,
                    angle_deg: key.angle_deg,
                    map_point: None,
                });
            }
            temporal += 1;
            if last.depth[i] > ctx.camera.close_depth_m
                && temporal > ctx.cfg.tracking.temporal_points
            {
                break;
            }
        }
        sources
    }

    fn track_motion_model(&mut self, frame: &mut Frame, map: &Map, ctx: &Context<'_>) -> bool {
        let sources = self.last_frame_sources(map, ctx);
        let (Some(last), Some(velocity)) = (&self.last, self.velocity) else {
            return false;
        };
        frame.camera_from_world = velocity * last.camera_from_world;
        // How far the camera moves along its axis (the forward/backward level rule).
        let forward_m = (last.camera_from_world * frame.camera_from_world.inverse())
            .translation
            .vector
            .z;
        let t = &ctx.cfg.tracking;
        frame.matches.iter_mut().for_each(|m| *m = None);
        let mut n = matcher::search_motion(
            ctx.camera,
            frame,
            &sources,
            t.motion_radius_px,
            forward_m,
            true,
        );
        if n < t.motion_min_matches {
            frame.matches.iter_mut().for_each(|m| *m = None);
            n = matcher::search_motion(
                ctx.camera,
                frame,
                &sources,
                2.0 * t.motion_radius_px,
                forward_m,
                true,
            );
        }
        if n < t.motion_min_matches {
            return false;
        }
        optimize_frame_pose(ctx.camera, frame);
        let map_matches = discard_outliers(frame, map);
        if self.only_tracking {
            // ORB-SLAM2's localisation mode: fewer than 10 map points is visual odometry,
            // held while more than 20 matches (depth points of the last frame too) remain.
            self.vo = map_matches < 10;
            return frame.matches.iter().flatten().count() > 20;
        }
        map_matches >= 10
    }

    /// Localisation mode's tracking of a frame after a tracked one (ORB-SLAM2's
    /// `Tracking::Track` with `mbOnlyTracking`): with map points in view, the motion model
    /// (or the reference keyframe without a velocity); in visual odometry, both the motion
    /// model and relocalisation, relocalisation preferred when it succeeds.
    fn track_only(
        &mut self,
        frame: &mut Frame,
        map: &mut Map,
        ctx: &Context<'_>,
        relocalised: &mut bool,
    ) -> bool {
        if !self.vo {
            return if self.velocity.is_some() {
                self.track_motion_model(frame, map, ctx)
            } else {
                self.track_reference_keyframe(frame, map, ctx)
            };
        }
        let by_motion = self.velocity.is_some() && self.track_motion_model(frame, map, ctx);
        let motion = (
            frame.matches.clone(),
            frame.outliers.clone(),
            frame.camera_from_world,
            self.vo,
        );
        let reference = self.reference_kf;
        if self.relocalise(frame, map, ctx) {
            self.vo = false;
            *relocalised = true;
            return true;
        }
        self.reference_kf = reference;
        if !by_motion {
            return false;
        }
        (
            frame.matches,
            frame.outliers,
            frame.camera_from_world,
            self.vo,
        ) = motion;
        if self.vo {
            for (m, &out) in frame.matches.iter().zip(&frame.outliers) {
                if let Some(p) = m.and_then(|s| s.map_point).and_then(|p| map.resolve(p)) {
                    if !out {
                        map.points[p].found += 1;
                    }
                }
            }
        }
        true
    }

    fn track_reference_keyframe(
        &mut self,
        frame: &mut Frame,
        map: &Map,
        ctx: &Context<'_>,
    ) -> bool {
        let Some(reference) = self.reference_kf else {
            return false;
        };
        frame.compute_bow(ctx.vocabulary);
        frame.matches.iter_mut().for_each(|m| *m = None);
        let n = matcher::search_bow_frame(map, reference, frame, ctx.cfg.tracking.bow_ratio);
        if n < ctx.cfg.tracking.bow_min_matches {
            return false;
        }
        if let Some(last) = &self.last {
            frame.camera_from_world = last.camera_from_world;
        } else {
            frame.camera_from_world = map.keyframes[reference].pose();
        }
        optimize_frame_pose(ctx.camera, frame);
        discard_outliers(frame, map) >= 10
    }

    /// The local map: keyframes that see the frame's points, their best covisibles,
    /// children and parents (at most `max_local_keyframes`), and their points; the one
    /// sharing most points becomes the reference keyframe.
    fn update_local_map(&mut self, frame: &Frame, map: &Map, ctx: &Context<'_>) {
        let mut counts: BTreeMap<usize, usize> = BTreeMap::new();
        for m in frame.matches.iter().flatten() {
            if let Some(p) = m.map_point.and_then(|p| map.resolve(p)) {
                for &kf in map.points[p].observations.keys() {
                    *counts.entry(kf).or_default() += 1;
                }
            }
        }
        if counts.is_empty() {
            return;
        }
        let max_kfs = ctx.cfg.tracking.max_local_keyframes;
        let mut order: Vec<(usize, usize)> = counts
            .into_iter()
            .filter(|&(k, _)| !map.keyframes[k].bad)
            .collect();
        order.sort_by_key(|&(k, n)| (std::cmp::Reverse(n), k));
        let Some(&(best, _)) = order.first() else {
            return;
        };
        let mut local: Vec<usize> = order.iter().map(|&(k, _)| k).collect();
        let mut set: BTreeSet<usize> = local.iter().copied().collect();
        let first = local.clone();
        for kf in first {
            if local.len() >= max_kfs {
                break;
            }
            let k = &map.keyframes[kf];
            let neighbour = k
                .best_covisibles(10)
                .into_iter()
                .find(|n| !map.keyframes[*n].bad && !set.contains(n));
            let child = k
                .children
                .iter()
                .copied()
                .find(|n| !map.keyframes[*n].bad && !set.contains(n));
            let parent = k.parent.filter(|n| !set.contains(n));
            for extra in [neighbour, child, parent].into_iter().flatten() {
                if set.insert(extra) {
                    local.push(extra);
                }
            }
        }
        local.truncate(max_kfs);
        self.reference_kf = Some(best);
        self.local_points = map.points_of(&local);
        self.local_kfs = local;
    }

    fn track_local_map(&mut self, frame: &mut Frame, map: &mut Map, ctx: &Context<'_>) -> bool {
        self.update_local_map(frame, map, ctx);
        let mut matched = BTreeSet::new();
        for m in frame.matches.iter().flatten() {
            if let Some(p) = m.map_point.and_then(|p| map.resolve(p)) {
                map.points[p].visible += 1;
                matched.insert(p);
            }
        }
        let mut candidates = Vec::new();
        for &p in &self.local_points {
            if matched.contains(&p) || map.points[p].bad {
                continue;
            }
            if let Some((u, v, level, view_cos)) =
                matcher::in_frustum(map, ctx.camera, &frame.camera_from_world, p)
            {
                map.points[p].visible += 1;
                candidates.push((p, u, v, level, view_cos));
            }
        }
        let recent_reloc = self.frame_count < self.last_reloc_frame + 2;
        let th = ctx.cfg.tracking.local_map_radius * if recent_reloc { 5.0 } else { 1.0 };
        matcher::search_local_points(
            map,
            ctx.camera,
            frame,
            &candidates,
            th,
            ctx.cfg.tracking.local_map_ratio,
        );
        optimize_frame_pose(ctx.camera, frame);
        let mut inliers = 0;
        for (m, &out) in frame.matches.iter().zip(&frame.outliers) {
            if out {
                continue;
            }
            if let Some(p) = m.and_then(|s| s.map_point).and_then(|p| map.resolve(p)) {
                map.points[p].found += 1;
                if !map.points[p].observations.is_empty() {
                    inliers += 1;
                }
            }
        }
        self.inliers = inliers;
        let fps = ctx.fps;
        let min = if self.frame_count < self.last_reloc_frame + fps && self.last_reloc_frame > 0 {
            ctx.cfg.tracking.min_inliers_after_relocalisation
        } else {
            ctx.cfg.tracking.min_inliers
        };
        inliers >= min
    }

    /// ORB-SLAM2's `NeedNewKeyFrame` for RGB-D, with local mapping always idle (it runs
    /// after tracking, in the same thread).
    fn need_new_keyframe(&self, frame: &Frame, map: &Map, ctx: &Context<'_>) -> bool {
        let t = &ctx.cfg.tracking;
        let keyframes = map.live_keyframe_count();
        let fps = ctx.fps;
        if self.frame_count < self.last_reloc_frame + fps && keyframes > fps as usize {
            return false;
        }
        let min_obs = if keyframes <= 2 { 2 } else { 3 };
        let reference = self.reference_kf.expect("a reference keyframe");
        let ref_matches = map.tracked_points(reference, min_obs);
        let (mut tracked_close, mut untracked_close) = (0, 0);
        for i in 0..frame.len() {
            if frame.is_close(ctx.camera, i) {
                let tracked =
                    !frame.outliers[i] && frame.matches[i].is_some_and(|m| m.map_point.is_some());
                if tracked {
                    tracked_close += 1;
                } else {
                    untracked_close += 1;
                }
            }
        }
        let need_close = tracked_close < t.close_tracked && untracked_close > t.close_untracked;
        let th_ref = if keyframes < 2 { 0.4 } else { t.th_ref_ratio };
        let since = self.frame_count - self.last_kf_frame;
        let c1a = since >= fps;
        let c1b = since >= t.min_frames as u64;
        let c1c = (self.inliers as f64) < ref_matches as f64 * 0.25 || need_close;
        let c2 = ((self.inliers as f64) < ref_matches as f64 * th_ref || need_close)
            && self.inliers > 15;
        (c1a || c1b || c1c) && c2
    }

    /// Makes the frame a keyframe, with new points at its untracked keypoints from the
    /// closest depth (all close ones, at least `new_points_min`).
    fn create_keyframe(&mut self, frame: &mut Frame, map: &mut Map, ctx: &Context<'_>) -> usize {
        frame.compute_bow(ctx.vocabulary);
        for i in 0..frame.len() {
            frame.points[i] = frame.matches[i]
                .and_then(|m| m.map_point)
                .and_then(|p| map.resolve(p));
        }
        let kf = map.add_keyframe(frame.clone());
        let mut order: Vec<usize> = (0..frame.len()).filter(|&i| frame.depth[i] > 0.0).collect();
        order.sort_by(|&a, &b| frame.depth[a].total_cmp(&frame.depth[b]).then(a.cmp(&b)));
        let mut n = 0;
        for i in order {
            let has_point = map.keyframes[kf].frame.points[i].is_some();
            if !has_point {
                let world = frame.unproject_world(ctx.camera, i).expect("has depth");
                let p = map.add_point(ctx.camera, world, kf, i);
                frame.matches[i] = Some(source_of(map, frame, i, p));
                frame.outliers[i] = false;
            }
            n += 1;
            if frame.depth[i] > ctx.camera.close_depth_m && n > ctx.cfg.tracking.new_points_min {
                break;
            }
        }
        self.reference_kf = Some(kf);
        self.last_kf_frame = self.frame_count;
        kf
    }

    /// Relocalisation: BoW candidates, matched by BoW (ratio 0.75, ≥ 15), PnP RANSAC, pose
    /// optimisation, and a guided search of the candidate's points when inliers are short
    /// of 50.
    fn relocalise(&mut self, frame: &mut Frame, map: &mut Map, ctx: &Context<'_>) -> bool {
        frame.compute_bow(ctx.vocabulary);
        let candidates = ctx
            .database
            .candidates(map, &frame.bow, &BTreeSet::new(), 0.0, 0.8, 0.75);
        for kf in candidates {
            frame.matches.iter_mut().for_each(|m| *m = None);
            if matcher::search_bow_frame(map, kf, frame, 0.75) < 15 {
                continue;
            }
            let (object, pixels): (Vec<Vector3<f64>>, Vec<[f32; 2]>) = frame
                .matches
                .iter()
                .zip(&frame.keys)
                .filter_map(|(m, k)| m.map(|m| (m.world, [k.u, k.v])))
                .unzip();
            let Ok(Some(pose)) = pnp_ransac(&object, &pixels, ctx.camera) else {
                continue;
            };
            frame.camera_from_world = pose;
            let mut inliers = optimize_frame_pose(ctx.camera, frame);
            if inliers < 10 {
                continue;
            }
            discard_outliers(frame, map);
            if inliers < 50 {
                let points: Vec<usize> = map.keyframes[kf]
                    .frame
                    .points
                    .iter()
                    .flatten()
                    .filter_map(|&p| map.resolve(p))
                    .collect();
                let matched: BTreeSet<usize> = frame
                    .matches
                    .iter()
                    .flatten()
                    .filter_map(|m| m.map_point)
                    .collect();
                let candidates: Vec<_> = points
                    .into_iter()
                    .filter(|p| !matched.contains(p))
                    .filter_map(|p| {
                        matcher::in_frustum(map, ctx.camera, &frame.camera_from_world, p)
                            .map(|(u, v, l, c)| (p, u, v, l, c))
                    })
                    .collect();
                matcher::search_local_points(map, ctx.camera, frame, &candidates, 10.0 / 2.5, 0.9);
                inliers = optimize_frame_pose(ctx.camera, frame);
                discard_outliers(frame, map);
            }
            if inliers >= 50 {
                self.reference_kf = Some(kf);
                return true;
            }
        }
        false
    }
}

/// Drops the matches the pose optimisation rejected; counts those with map points that
/// keyframes observe.
fn discard_outliers(frame: &mut Frame, map: &Map) -> usize {
    let mut n = 0;
    for (m, out) in frame.matches.iter_mut().zip(frame.outliers.iter_mut()) {
        if *out {
            *m = None;
            *out = false;
        } else if let Some(p) = m.and_then(|s| s.map_point) {
            if !map.points[p].observations.is_empty() {
                n += 1;
            }
        }
    }
    n
}

fn source_of(map: &Map, frame: &Frame, i: usize, p: usize) -> Source {
    Source {
        world: map.points[p].world,
        descriptor: map.points[p].descriptor,
        octave: frame.keys[i].octave,
        angle_deg: frame.keys[i].angle_deg,
        map_point: Some(p),
    }
}

/// OpenCV's `solvePnPRansac` (EPnP minimal sets, reprojection 5.991 px² at level 0 as
/// ORB-SLAM2's PnPsolver): `camera_from_world`, or None.
pub fn pnp_ransac(
    object: &[Vector3<f64>],
    pixels: &[[f32; 2]],
    camera: &Camera,
) -> Result<Option<Isometry3<f64>>, opencv::Error> {
    if object.len() < 6 {
        return Ok(None);
    }
    let obj: Vector<Point3f> = object
        .iter()
        .map(|p| Point3f::new(p.x as f32, p.y as f32, p.z as f32))
        .collect();
    let img: Vector<Point2f> = pixels.iter().map(|p| Point2f::new(p[0], p[1])).collect();
    let c = &camera.stereo;
    let k = Mat::from_slice_2d(&[[c.fx, 0.0, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]])?;
    let (mut rvec, mut tvec, mut inliers) = (Mat::default(), Mat::default(), Mat::default());
    let found = calib3d::solve_pnp_ransac(
        &obj,
        &img,
        &k,
        &Mat::default(),
        &mut rvec,
        &mut tvec,
        false,
        300,
        5.991f32.sqrt(),
        0.99,
        &mut inliers,
        calib3d::SOLVEPNP_EPNP,
    )?;
    if !found || inliers.rows() < 10 {
        return Ok(None);
    }
    let r = Vector3::new(
        *rvec.at::<f64>(0)?,
        *rvec.at::<f64>(1)?,
        *rvec.at::<f64>(2)?,
    );
    let t = Vector3::new(
        *tvec.at::<f64>(0)?,
        *tvec.at::<f64>(1)?,
        *tvec.at::<f64>(2)?,
    );
    let pose = Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
    Ok(Some(pose))
}
