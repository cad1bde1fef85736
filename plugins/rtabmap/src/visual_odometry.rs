//! RGB-D visual odometry as RTAB-Map's `rgbd_odometry` does it (Labbé and Michaud 2019,
//! §3.1.1): each frame's features are matched to a local map of 3D visual words (frame to
//! map) or to the last keyframe's (frame to frame), the camera pose is solved by PnP RANSAC
//! from those 3D–2D matches, and when the share of inliers falls below a threshold the frame
//! becomes a keyframe and its new features join the map. A constant-velocity guess limits
//! matching to a window around where each word should appear.
//!
//! Tracking is lost when fewer than `min_inliers` agree; after `reset_countdown` lost frames
//! odometry starts afresh from the guessed pose (RTAB-Map's `Odom/ResetCountdown`).

use nalgebra::{Isometry3, Vector3};

use crate::config::{VisualOdometryConfig, VisualStrategy};
use crate::features::{Descriptor, Features};
use crate::matching::{PixelGrid, Window, match_descriptors};
use crate::pnp::{self, PnpConfig};

/// A word of the local map: a 3D point in the odometry frame and its descriptor.
#[derive(Debug, Clone)]
struct Word {
    point: Vector3<f64>,
    descriptor: Descriptor,
    /// The frame that last matched it as an inlier (the oldest go first when full).
    last_seen: u64,
}

/// What a frame did.
#[derive(Debug, Clone, PartialEq)]
pub enum Tracking {
    /// Tracked: the pose, how many inliers out of how many features.
    Ok {
        odom_from_camera: Isometry3<f64>,
        inliers: usize,
        features: usize,
        keyframe: bool,
    },
    /// First frame (or first after a reset): the map starts here.
    Started { odom_from_camera: Isometry3<f64> },
    /// Too few inliers; the guess stands in for the pose. `reset`: the map restarted.
    Lost {
        guess: Isometry3<f64>,
        inliers: usize,
        reset: bool,
    },
}

#[derive(Debug)]
pub struct VisualOdometry {
    cfg: VisualOdometryConfig,
    intrinsics: [f64; 4],
    size: (usize, usize),
    map: Vec<Word>,
    /// The last two tracked poses and stamps, for the constant-velocity guess.
    last: Option<(i64, Isometry3<f64>)>,
    before_last: Option<(i64, Isometry3<f64>)>,
    frame: u64,
    lost_in_a_row: usize,
    /// The pose of the first frame (the camera's mounting, so that the base starts at the
    /// odometry origin).
    start: Isometry3<f64>,
}

impl VisualOdometry {
    pub fn new(
        cfg: VisualOdometryConfig,
        intrinsics: [f64; 4],
        width: usize,
        height: usize,
        start: Isometry3<f64>,
    ) -> Self {
        Self {
            cfg,
            intrinsics,
            size: (width, height),
            map: Vec::new(),
            last: None,
            before_last: None,
            frame: 0,
            lost_in_a_row: 0,
            start,
        }
    }

    pub fn map_size(&self) -> usize {
        self.map.len()
    }

    /// The constant-velocity guess of the camera pose at `stamp_ns`.
    pub fn guess(&self, stamp_ns: i64) -> Isometry3<f64> {
        match (self.before_last, self.last) {
            (Some((t0, p0)), Some((t1, p1))) if t1 > t0 => {
                let step = p0.inverse() * p1;
                let s = (stamp_ns - t1) as f64 / (t1 - t0) as f64;
                p1 * Isometry3::from_parts(
                    (step.translation.vector * s).into(),
                    nalgebra::UnitQuaternion::identity().slerp(&step.rotation, s),
                )
            }
            (_, Some((_, p1))) => p1,
            _ => self.start,
        }
    }

    pub fn process(
        &mut self,
        stamp_ns: i64,
        features: &Features,
    ) -> Result<Tracking, opencv::Error> {
        self.frame += 1;
        let guess = self.guess(stamp_ns);
        if self.map.is_empty() {
            self.restart(stamp_ns, &guess, features);
            return Ok(Tracking::Started {
                odom_from_camera: guess,
            });
        }
        let solved = self.solve(&guess, features)?;
        let inliers = solved.as_ref().map_or(0, |(_, inl, _)| inl.len());
        let Some((odom_from_camera, inlier_matches, matched_train)) =
            solved.filter(|(_, inl, _)| inl.len() >= self.cfg.min_inliers)
        else {
            self.lost_in_a_row += 1;
            let reset =
                self.cfg.reset_countdown > 0 && self.lost_in_a_row >= self.cfg.reset_countdown;
            if reset {
                self.restart(stamp_ns, &guess, features);
            }
            return Ok(Tracking::Lost {
                guess,
                inliers,
                reset,
            });
        };
        self.lost_in_a_row = 0;
        for &(word, _) in &inlier_matches {
            self.map[word].last_seen = self.frame;
        }
        // Of the features that could become words (those with depth).
        let with_depth = features.points.iter().filter(|p| p.is_some()).count();
        let ratio = inlier_matches.len() as f64 / with_depth.max(1) as f64;
        let keyframe = ratio < self.cfg.keyframe_inlier_ratio;
        if keyframe {
            match self.cfg.strategy {
                VisualStrategy::FrameToMap => {
                    self.add_words(&odom_from_camera, features, &matched_train)
                }
                VisualStrategy::FrameToFrame => {
                    self.map.clear();
                    self.add_words(&odom_from_camera, features, &[]);
                }
            }
        }
        self.before_last = self.last;
        self.last = Some((stamp_ns, odom_from_camera));
        Ok(Tracking::Ok {
            odom_from_camera,
            inliers: inlier_matches.len(),
            features: features.len(),
            keyframe,
        })
    }

    /// Matches the map to the frame and solves PnP: the pose, the inlier (word, feature)
    /// pairs and which features matched at all.
    #[allow(clippy::type_complexity)]
    fn solve(
        &self,
        guess: &Isometry3<f64>,
        features: &Features,
    ) -> Result<Option<(Isometry3<f64>, Vec<(usize, usize)>, Vec<bool>)>, opencv::Error> {
        let descriptors: Vec<Descriptor> = self.map.iter().map(|w| w.descriptor).collect();
        let camera_from_odom = guess.inverse();
        let [fx, fy, cx, cy] = self.intrinsics;
        let (w, h) = (self.size.0 as f64, self.size.1 as f64);
        let projections: Vec<Option<[f32; 2]>> = self
            .map
            .iter()
            .map(|word| {
                let p = camera_from_odom * nalgebra::Point3::from(word.point);
                let (u, v) = (fx * p.x / p.z + cx, fy * p.y / p.z + cy);
                (p.z > 0.1 && u > -50.0 && v > -50.0 && u < w + 50.0 && v < h + 50.0)
                    .then_some([u as f32, v as f32])
            })
            .collect();
        let radius = self.cfg.guess_window_px as f32;
        let grid = PixelGrid::new(&features.pixels, self.size.0, self.size.1, radius.max(1.0));
        let window = (radius > 0.0).then_some(Window {
            projections: &projections,
            grid: &grid,
            pixels: &features.pixels,
            radius_px: radius,
        });
        let matches = match_descriptors(&descriptors, &features.descriptors, window, self.cfg.nndr);
        let mut matched = vec![false; features.len()];
        for m in &matches {
            matched[m.train] = true;
        }
        let object: Vec<Vector3<f64>> = matches.iter().map(|m| self.map[m.query].point).collect();
        let pixels: Vec<[f32; 2]> = matches.iter().map(|m| features.pixels[m.train]).collect();
        let cfg = PnpConfig {
            reprojection_px: self.cfg.pnp_reprojection_px,
            iterations: self.cfg.pnp_iterations,
        };
        let Some(result) = pnp::solve(&object, &pixels, self.intrinsics, None, &cfg)? else {
            return Ok(None);
        };
        let inliers = result
            .inliers
            .iter()
            .map(|&i| (matches[i].query, matches[i].train))
            .collect();
        Ok(Some((
            result.camera_from_object.inverse(),
            inliers,
            matched,
        )))
    }

    /// A fresh map from this frame at `odom_from_camera`.
    fn restart(&mut self, stamp_ns: i64, odom_from_camera: &Isometry3<f64>, features: &Features) {
        self.map.clear();
        self.add_words(odom_from_camera, features, &[]);
        self.lost_in_a_row = 0;
        self.before_last = None;
        self.last = Some((stamp_ns, *odom_from_camera));
    }

    /// Adds the frame's features with depth that did not match, then drops the words seen
    /// longest ago beyond the map's size.
    fn add_words(
        &mut self,
        odom_from_camera: &Isometry3<f64>,
        features: &Features,
        matched: &[bool],
    ) {
        for (i, point) in features.points.iter().enumerate() {
            let Some(point) = point else { continue };
            if matched.get(i).copied().unwrap_or(false) {
                continue;
            }
            self.map.push(Word {
                point: (odom_from_camera * nalgebra::Point3::from(*point)).coords,
                descriptor: features.descriptors[i],
                last_seen: self.frame,
            });
        }
        if self.map.len() > self.cfg.local_map_size {
            // Among words last seen in the same frame, the ones added earlier go first.
            let mut order: Vec<usize> = (0..self.map.len()).collect();
            order.sort_unstable_by_key(|&i| {
                (
                    std::cmp::Reverse(self.map[i].last_seen),
                    std::cmp::Reverse(i),
                )
            });
            order.truncate(self.cfg.local_map_size);
            order.sort_unstable();
            let old = std::mem::take(&mut self.map);
            let mut keep = order.into_iter().peekable();
            self.map = old
                .into_iter()
                .enumerate()
                .filter_map(|(i, w)| {
                    (keep.peek() == Some(&i)).then(|| {
                        keep.next();
                        w
                    })
                })
                .collect();
        }
    }
}
