//! An RGB-D frame as ORB-SLAM2 sees it (Mur-Artal and Tardós 2017, §III-A): ORB keypoints,
//! each with its depth and the virtual right coordinate `u_R = u − bf / d` that lets the
//! RGB-D frame be treated as a rectified stereo pair; a keypoint is "close" when its depth is
//! below `ThDepth` baselines. Keypoints are bucketed in a grid for area searches.

use nalgebra::{Isometry3, Vector3};
use slam_common::factor_graph::ba::StereoCamera;
use slam_common::place::vocabulary::{BowVector, FeatureVector, Vocabulary};

use crate::matcher::Source;
use crate::orb::KeyPoint;

pub type Descriptor = [u8; 32];

/// ORB-SLAM2's grid for area searches: 64 × 48 cells over the image.
const GRID_COLS: usize = 64;
const GRID_ROWS: usize = 48;

/// The camera and the scale pyramid, shared by every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub stereo: StereoCamera,
    pub width: f64,
    pub height: f64,
    /// Close points: depth below this, m.
    pub close_depth_m: f64,
    pub min_depth_m: f64,
    pub max_depth_m: f64,
    pub scale_factors: Vec<f64>,
    pub level_sigma2: Vec<f64>,
    pub inv_level_sigma2: Vec<f64>,
    /// ln of the scale factor between levels.
    pub log_scale: f64,
}

impl Camera {
    pub fn levels(&self) -> usize {
        self.scale_factors.len()
    }

    /// Projects a point of the camera frame: pixel, or None when behind or outside.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        if p.z <= 0.0 {
            return None;
        }
        let c = &self.stereo;
        let u = c.fx * p.x / p.z + c.cx;
        let v = c.fy * p.y / p.z + c.cy;
        (u >= 0.0 && u < self.width && v >= 0.0 && v < self.height).then_some((u, v))
    }

    /// The point of a pixel at a depth, camera frame.
    pub fn unproject(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        let c = &self.stereo;
        Vector3::new((u - c.cx) * z / c.fx, (v - c.cy) * z / c.fy, z)
    }

    /// The pyramid level a point at `distance` would be seen at, given the largest
    /// distance at which it is scale invariant (`MapPoint::PredictScale`).
    pub fn predict_level(&self, max_distance: f64, distance: f64) -> usize {
        let ratio = max_distance / distance;
        let level = (ratio.ln() / self.log_scale).ceil();
        level.clamp(0.0, (self.levels() - 1) as f64) as usize
    }
}

/// One frame: keypoints with depth, their map points once tracked, and its pose.
#[derive(Debug, Clone)]
pub struct Frame {
    pub stamp_ns: i64,
    pub keys: Vec<KeyPoint>,
    pub descriptors: Vec<Descriptor>,
    /// Depth per keypoint, m; negative: none.
    pub depth: Vec<f64>,
    /// Virtual right coordinate per keypoint, px; negative: none.
    pub u_right: Vec<f64>,
    grid: Vec<Vec<u32>>,
    pub bow: BowVector,
    pub features: FeatureVector,
    /// While tracking: what each keypoint was matched to (a map point, or a temporary
    /// point of the last frame's depth).
    pub matches: Vec<Option<Source>>,
    /// Matches the last pose optimisation rejected.
    pub outliers: Vec<bool>,
    /// Once a keyframe: the map point of each keypoint.
    pub points: Vec<Option<usize>>,
    pub camera_from_world: Isometry3<f64>,
}

impl Frame {
    /// Builds a frame from keypoints, descriptors and the registered depth image.
    pub fn new(
        stamp_ns: i64,
        camera: &Camera,
        keys: Vec<KeyPoint>,
        descriptors: Vec<Descriptor>,
        depth_image: &[f32],
        width: usize,
    ) -> Self {
        let n = keys.len();
        let mut depth = vec![-1.0; n];
        let mut u_right = vec![-1.0; n];
        for (i, k) in keys.iter().enumerate() {
            // The depth at the keypoint's pixel (keypoints are not undistorted: the
            // simulated camera is a pinhole).
            let (u, v) = (k.u.round() as usize, k.v.round() as usize);
            let Some(&d) = depth_image.get(v * width + u) else {
                continue;
            };
            let d = f64::from(d);
            if d.is_finite() && d >= camera.min_depth_m && d <= camera.max_depth_m {
                depth[i] = d;
                u_right[i] = f64::from(k.u) - camera.stereo.bf / d;
            }
        }
        Self::from_parts(stamp_ns, camera, keys, descriptors, depth, u_right)
    }

    /// A frame from its keypoints, descriptors, and each keypoint's depth and right
    /// coordinate (negative: none), as a saved map holds them; unmatched, at the identity.
    pub fn from_parts(
        stamp_ns: i64,
        camera: &Camera,
        keys: Vec<KeyPoint>,
        descriptors: Vec<Descriptor>,
        depth: Vec<f64>,
        u_right: Vec<f64>,
    ) -> Self {
        let n = keys.len();
        let mut grid = vec![Vec::new(); GRID_COLS * GRID_ROWS];
        for (i, k) in keys.iter().enumerate() {
            if let Some(c) = cell_of(camera, f64::from(k.u), f64::from(k.v)) {
                grid[c].push(i as u32);
            }
        }
        Self {
            stamp_ns,
            keys,
            descriptors,
            depth,
            u_right,
            grid,
            bow: BowVector::default(),
            features: FeatureVector::default(),
            matches: vec![None; n],
            points: vec![None; n],
            outliers: vec![false; n],
            camera_from_world: Isometry3::identity(),
        }
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Computes the bag of words once (the direct index 4 levels above the words).
    pub fn compute_bow(&mut self, vocabulary: &Vocabulary) {
        if self.bow.entries.is_empty() && !self.descriptors.is_empty() {
            let (bow, features) = vocabulary.transform(&self.descriptors, 4);
            self.bow = bow;
            self.features = features;
        }
    }

    /// Whether a keypoint's depth is close (reliable).
    pub fn is_close(&self, camera: &Camera, i: usize) -> bool {
        self.depth[i] > 0.0 && self.depth[i] < camera.close_depth_m
    }

    /// The world point of a keypoint with depth.
    pub fn unproject_world(&self, camera: &Camera, i: usize) -> Option<Vector3<f64>> {
        let z = self.depth[i];
        (z > 0.0).then(|| {
            let k = &self.keys[i];
            let p = camera.unproject(f64::from(k.u), f64::from(k.v), z);
            self.camera_from_world
                .inverse_transform_point(&p.into())
                .coords
        })
    }

    /// The camera centre in the world.
    pub fn centre(&self) -> Vector3<f64> {
        self.camera_from_world.inverse().translation.vector
    }

    /// Keypoints within `r` px of (u, v) on levels `min_level..=max_level`.
    pub fn features_in_area(
        &self,
        camera: &Camera,
        u: f64,
        v: f64,
        r: f64,
        min_level: usize,
        max_level: usize,
    ) -> Vec<usize> {
        let cw = camera.width / GRID_COLS as f64;
        let ch = camera.height / GRID_ROWS as f64;
        let c0 = ((u - r) / cw).floor().max(0.0) as usize;
        let c1 = (((u + r) / cw).floor() as isize).min(GRID_COLS as isize - 1);
        let r0 = ((v - r) / ch).floor().max(0.0) as usize;
        let r1 = (((v + r) / ch).floor() as isize).min(GRID_ROWS as isize - 1);
        let mut out = Vec::new();
        if c1 < 0 || r1 < 0 {
            return out;
        }
        for row in r0..=(r1 as usize) {
            for col in c0..=(c1 as usize) {
                for &i in &self.grid[row * GRID_COLS + col] {
                    let k = &self.keys[i as usize];
                    let level = usize::from(k.octave);
                    if level < min_level || level > max_level {
                        continue;
                    }
                    let (du, dv) = (f64::from(k.u) - u, f64::from(k.v) - v);
                    if du.abs() < r && dv.abs() < r {
                        out.push(i as usize);
                    }
                }
            }
        }
        out
    }
}

fn cell_of(camera: &Camera, u: f64, v: f64) -> Option<usize> {
    let col = (u * GRID_COLS as f64 / camera.width).floor();
    let row = (v * GRID_ROWS as f64 / camera.height).floor();
    (col >= 0.0 && row >= 0.0 && col < GRID_COLS as f64 && row < GRID_ROWS as f64)
        .then(|| row as usize * GRID_COLS + col as usize)
}
