//! Visual features of an RGB-D frame: GFTT corners (Shi and Tomasi, "Good features to
//! track", CVPR 1994, through OpenCV) with BRIEF descriptors, and the 3D point of each corner
//! from the registered depth.
//!
//! BRIEF (Calonder, Lepetit, Strecha and Fua, "BRIEF: Binary Robust Independent Elementary
//! Features", ECCV 2010) is computed here rather than by OpenCV because Debian builds OpenCV
//! without the contrib module `xfeatures2d` that holds it. Following the paper: the image is
//! smoothed (a 9x9 box, from an integral image, standing in for the paper's 9x9 Gaussian),
//! and each of the 256 bits compares the smoothed intensity at two points of a 48x48 patch
//! drawn once from the paper's best sampling strategy (G II: both points i.i.d. Gaussian
//! about the centre with σ² = S²/25), from a fixed seed so that descriptors never change.

use std::sync::OnceLock;

use nalgebra::Vector3;
use opencv::core::{self, Mat, Point2f, Vector};
use opencv::imgproc;
use plugin_api::gray_from_rgb;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::config::FeatureConfig;

/// A 256-bit descriptor.
pub type Descriptor = slam_common::place::bow::Descriptor;

/// BRIEF's patch side, px (the paper's S).
const PATCH: i32 = 48;
/// Half the smoothing box, px.
const KERNEL_HALF: i32 = 4;
/// Corners nearer the border than this have no descriptor.
const BORDER: i32 = PATCH / 2 + KERNEL_HALF + 1;

/// The 256 point pairs `(x1, y1, x2, y2)` about the patch centre.
fn test_pairs() -> &'static [[i8; 4]; 256] {
    static PAIRS: OnceLock<[[i8; 4]; 256]> = OnceLock::new();
    PAIRS.get_or_init(|| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x0042_5249_4546); // "BRIEF"
        let sigma = f64::from(PATCH) / 5.0;
        let normal = Normal::new(0.0, sigma).expect("a positive sigma");
        let half = PATCH / 2 - 1;
        let mut pairs = [[0i8; 4]; 256];
        for pair in &mut pairs {
            for v in pair.iter_mut() {
                let x = normal.sample(&mut rng).round() as i32;
                *v = x.clamp(-half, half) as i8;
            }
        }
        pairs
    })
}

/// A frame's features: pixel, descriptor and (where the depth is valid) the point in the
/// camera's optical frame, strongest corner first.
#[derive(Debug, Clone, Default)]
pub struct Features {
    pub pixels: Vec<[f32; 2]>,
    pub descriptors: Vec<Descriptor>,
    pub points: Vec<Option<Vector3<f64>>>,
}

impl Features {
    pub fn len(&self) -> usize {
        self.pixels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pixels.is_empty()
    }

    /// The first `n` (the strongest).
    pub fn truncated(&self, n: usize) -> Features {
        let n = n.min(self.len());
        Features {
            pixels: self.pixels[..n].to_vec(),
            descriptors: self.descriptors[..n].to_vec(),
            points: self.points[..n].to_vec(),
        }
    }
}

/// A registered RGB-D image as the extractor reads it.
#[derive(Debug, Clone, Copy)]
pub struct Image<'a> {
    pub width: usize,
    pub height: usize,
    pub rgb: &'a [u8],
    pub depth_m: &'a [f32],
    /// `[fx, fy, cx, cy]`.
    pub intrinsics: [f64; 4],
}

#[derive(Debug, thiserror::Error)]
pub enum FeatureError {
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
    #[error("frame of {width}x{height} with {rgb} RGB bytes and {depth} depth values")]
    Size {
        width: usize,
        height: usize,
        rgb: usize,
        depth: usize,
    },
}

/// GFTT corners with BRIEF descriptors and depth.
pub fn extract(image: &Image<'_>, cfg: &FeatureConfig) -> Result<Features, FeatureError> {
    let (w, h) = (image.width, image.height);
    if image.rgb.len() != w * h * 3 || image.depth_m.len() != w * h {
        return Err(FeatureError::Size {
            width: w,
            height: h,
            rgb: image.rgb.len(),
            depth: image.depth_m.len(),
        });
    }
    let gray = gray_from_rgb(image.rgb, image.width, image.height);
    let gray_mat = Mat::new_rows_cols_with_data(h as i32, w as i32, &gray)?;
    let mut corners: Vector<Point2f> = Vector::new();
    imgproc::good_features_to_track(
        &gray_mat,
        &mut corners,
        cfg.max_features as i32,
        cfg.quality_level,
        cfg.min_distance_px,
        &core::no_array(),
        cfg.block_size,
        false,
        0.04,
    )?;
    let integral = integral(&gray, w, h);
    let mut features = Features::default();
    for corner in corners.iter() {
        let (u, v) = (corner.x.round() as i32, corner.y.round() as i32);
        if u < BORDER || v < BORDER || u >= w as i32 - BORDER || v >= h as i32 - BORDER {
            continue;
        }
        features.pixels.push([corner.x, corner.y]);
        features.descriptors.push(brief(&integral, w + 1, u, v));
        features
            .points
            .push(back_project(image, corner.x, corner.y, cfg));
    }
    Ok(features)
}

/// Summed-area table, `(w + 1) x (h + 1)`, row-major.
fn integral(bytes: &[u8], w: usize, h: usize) -> Vec<u32> {
    let stride = w + 1;
    let mut table = vec![0u32; stride * (h + 1)];
    for y in 0..h {
        let mut row_sum = 0u32;
        for x in 0..w {
            row_sum += u32::from(bytes[y * w + x]);
            table[(y + 1) * stride + x + 1] = table[y * stride + x + 1] + row_sum;
        }
    }
    table
}

/// The box sum of the 9x9 window centred on `(x, y)`.
fn box_sum(table: &[u32], stride: usize, x: i32, y: i32) -> u32 {
    let (x0, y0) = ((x - KERNEL_HALF) as usize, (y - KERNEL_HALF) as usize);
    let (x1, y1) = (
        (x + KERNEL_HALF + 1) as usize,
        (y + KERNEL_HALF + 1) as usize,
    );
    table[y1 * stride + x1] + table[y0 * stride + x0]
        - table[y0 * stride + x1]
        - table[y1 * stride + x0]
}

fn brief(table: &[u32], stride: usize, u: i32, v: i32) -> Descriptor {
    let mut d = [0u8; 32];
    for (bit, p) in test_pairs().iter().enumerate() {
        let a = box_sum(table, stride, u + i32::from(p[0]), v + i32::from(p[1]));
        let b = box_sum(table, stride, u + i32::from(p[2]), v + i32::from(p[3]));
        if a < b {
            d[bit / 8] |= 1 << (bit % 8);
        }
    }
    d
}

/// The point at pixel `(x, y)` in the optical frame, from the depth of the pixel it falls
/// in; `None` where the depth is invalid, out of range or on a silhouette.
fn back_project(image: &Image<'_>, x: f32, y: f32, cfg: &FeatureConfig) -> Option<Vector3<f64>> {
    let (u, v) = (x.round() as usize, y.round() as usize);
    let (w, h) = (image.width, image.height);
    if u == 0 || v == 0 || u + 1 >= w || v + 1 >= h {
        return None;
    }
    let z = f64::from(image.depth_m[v * w + u]);
    if !(z.is_finite() && z >= cfg.min_depth_m && z <= cfg.max_depth_m) {
        return None;
    }
    if cfg.max_depth_step > 0.0 {
        for dv in [v - 1, v, v + 1] {
            for du in [u - 1, u, u + 1] {
                let n = f64::from(image.depth_m[dv * w + du]);
                if !n.is_finite() || n <= 0.0 || (n - z).abs() > cfg.max_depth_step * z {
                    return None;
                }
            }
        }
    }
    let [fx, fy, cx, cy] = image.intrinsics;
    Some(Vector3::new(
        z * (f64::from(x) - cx) / fx,
        z * (f64::from(y) - cy) / fy,
        z,
    ))
}

pub use slam_common::place::bow::hamming;
