//! An RGB-D frame as ORB-SLAM2 sees it (Mur-Artal and Tardós 2017, §III-A): ORB keypoints,
//! each with its depth and the virtual right coordinate `u_R = u − bf / d` that lets the
//! RGB-D frame be treated as a rectified stereo pair; a keypoint is "close" when its depth is
//! below `ThDepth` baselines. Keypoints are bucketed in a grid for area searches.

use nalgebra::{Isometry3, Vector3};
use plugin_api::{Lens, Pinhole};
use slam_common::factor_graph::ba::StereoCamera;
use slam_common::place::vocabulary::{BowVector, FeatureVector, Vocabulary};

use crate::matcher::Source;
use crate::orb::KeyPoint;

pub type Descriptor = [u8; 32];

/// OpenCV 3's `undistortPoints` iterations (its default criteria), through which ORB-SLAM2
/// undistorts keypoints.
const UNDISTORT_ITERATIONS: usize = 5;

/// ORB-SLAM2's grid for area searches: 64 × 48 cells over the image.
const GRID_COLS: usize = 64;
const GRID_ROWS: usize = 48;

/// The camera and the scale pyramid, shared by every frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub stereo: StereoCamera,
    pub width: f64,
    pub height: f64,
    /// The raw image's lens (ORB-SLAM2's `Camera.k1`...`k3`, `DistCoef`): keypoints are
    /// undistorted as a frame is built; `None`: a rectified image.
    pub lens: Option<Lens>,
    /// Where keypoints can lie once undistorted, `[min_x, max_x, min_y, max_y]` px
    /// (ORB-SLAM2's `ComputeImageBounds`): the image's own for a rectified one.
    pub bounds: [f64; 4],
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
    /// The undistorted image's bounds for a `width` x `height` raw image through `lens`
    /// (ORB-SLAM2's `Frame::ComputeImageBounds`: its four corners undistorted).
    pub fn image_bounds(pinhole: &Pinhole, lens: Option<&Lens>) -> [f64; 4] {
        let (w, h) = (pinhole.width, pinhole.height);
        let Some(lens) = lens else {
            return [0.0, w, 0.0, h];
        };
        let c = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
            .map(|p| lens.undistort_pixel(pinhole, p, UNDISTORT_ITERATIONS));
        [
            c[0].0.min(c[2].0),
            c[1].0.max(c[3].0),
            c[0].1.min(c[1].1),
            c[2].1.max(c[3].1),
        ]
    }

    fn pinhole(&self) -> Pinhole {
        let c = &self.stereo;
        Pinhole {
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            width: self.width,
            height: self.height,
        }
    }

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
        let [x0, x1, y0, y1] = self.bounds;
        (u >= x0 && u < x1 && v >= y0 && v < y1).then_some((u, v))
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
    /// Builds a frame from keypoints, descriptors and the registered depth image. Through a
    /// lens the keypoints are undistorted (ORB-SLAM2's `UndistortKeyPoints`), each keeping
    /// the depth at its raw pixel (`ComputeStereoFromRGBD` reads the raw keypoint's).
    pub fn new(
        stamp_ns: i64,
        camera: &Camera,
        mut keys: Vec<KeyPoint>,
        descriptors: Vec<Descriptor>,
        depth_image: &[f32],
        width: usize,
    ) -> Self {
        let n = keys.len();
        let mut depth = vec![-1.0; n];
        let mut u_right = vec![-1.0; n];
        let pinhole = camera.pinhole();
        for (i, k) in keys.iter_mut().enumerate() {
            // The depth at the keypoint's raw pixel.
            let (u, v) = (k.u.round() as usize, k.v.round() as usize);
            let d = depth_image.get(v * width + u).copied();
            if let Some(lens) = &camera.lens {
                let (u, v) = lens.undistort_pixel(
                    &pinhole,
                    (f64::from(k.u), f64::from(k.v)),
                    UNDISTORT_ITERATIONS,
                );
                (k.u, k.v) = (u as f32, v as f32);
            }
            let Some(d) = d else {
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
        let [x0, x1, y0, y1] = camera.bounds;
        let cw = (x1 - x0) / GRID_COLS as f64;
        let ch = (y1 - y0) / GRID_ROWS as f64;
        let c0 = ((u - r - x0) / cw).floor().max(0.0) as usize;
        let c1 = (((u + r - x0) / cw).floor() as isize).min(GRID_COLS as isize - 1);
        let r0 = ((v - r - y0) / ch).floor().max(0.0) as usize;
        let r1 = (((v + r - y0) / ch).floor() as isize).min(GRID_ROWS as isize - 1);
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
    let [x0, x1, y0, y1] = camera.bounds;
    let col = ((u - x0) * GRID_COLS as f64 / (x1 - x0)).floor();
    let row = ((v - y0) * GRID_ROWS as f64 / (y1 - y0)).floor();
    (col >= 0.0 && row >= 0.0 && col < GRID_COLS as f64 && row < GRID_ROWS as f64)
        .then(|| row as usize * GRID_COLS + col as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::tests::camera;

    /// Through a lens a keypoint moves to its undistorted pixel, keeps the depth of its raw
    /// one, and the grid spans the undistorted image.
    #[test]
    fn a_lens_frame_undistorts_its_keypoints_and_reads_depth_at_the_raw_pixel() {
        let lens = Lens {
            k1: -0.25,
            k2: 0.05,
            p1: 0.001,
            p2: -0.001,
            k3: 0.0,
        };
        let rectified = camera();
        let pinhole = rectified.pinhole();
        let camera = Camera {
            lens: Some(lens),
            bounds: Camera::image_bounds(&pinhole, Some(&lens)),
            ..rectified.clone()
        };
        let [x0, x1, y0, y1] = camera.bounds;
        assert!(
            x0 < -10.0 && x1 > 650.0 && y0 < -10.0 && y1 > 490.0,
            "barrel distortion: the undistorted image is larger, {:?}",
            camera.bounds
        );
        let key = |u, v| KeyPoint {
            u,
            v,
            octave: 0,
            angle_deg: 0.0,
            response: 1.0,
            size: 31.0,
        };
        // Depth 3 m at the raw corner pixel (600, 40), 1 m everywhere else.
        let mut depth = vec![1.0f32; 640 * 480];
        depth[40 * 640 + 600] = 3.0;
        let keys = vec![key(600.0, 40.0), key(320.0, 240.0)];
        let f = Frame::new(0, &camera, keys.clone(), vec![[0; 32]; 2], &depth, 640);
        let (u, v) = lens.undistort_pixel(&pinhole, (600.0, 40.0), UNDISTORT_ITERATIONS);
        assert!(
            (f64::from(f.keys[0].u) - u).abs() < 1e-3 && (f64::from(f.keys[0].v) - v).abs() < 1e-3,
            "({}, {}) against ({u}, {v})",
            f.keys[0].u,
            f.keys[0].v
        );
        assert!(
            (u - 600.0).hypot(v - 40.0) > 20.0,
            "the lens moves the corner"
        );
        assert_eq!(f.depth[0], 3.0, "the raw pixel's depth");
        assert!((f.u_right[0] - (u - camera.stereo.bf / 3.0)).abs() < 1e-3);
        assert_eq!(f.features_in_area(&camera, u, v, 2.0, 0, 0), vec![0]);
        // Without the lens the same keypoints stay where they were found.
        let plain = Frame::new(0, &rectified, keys, vec![[0; 32]; 2], &depth, 640);
        assert_eq!((plain.keys[0].u, plain.keys[0].v), (600.0, 40.0));
    }
}
