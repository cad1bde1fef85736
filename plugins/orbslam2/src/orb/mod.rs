//! ORB features as ORB-SLAM2 extracts them: FAST corners spread over an image pyramid by a
//! grid of cells and a quadtree, oriented by the intensity centroid, described by rotated
//! BRIEF.
//!
//! The method is that of Rublee, Rabaud, Konolige and Bradski, "ORB: an efficient
//! alternative to SIFT or SURF" (ICCV 2011), with the keypoint distribution of Mur-Artal,
//! Montiel and Tardós, "ORB-SLAM: a versatile and accurate monocular SLAM system" (T-RO 2015,
//! §III) kept by Mur-Artal and Tardós, "ORB-SLAM2: an open-source SLAM system for monocular,
//! stereo and RGB-D cameras" (T-RO 2017), with ORB-SLAM2's parameters:
//!
//! - **Pyramid**: `levels` (8) levels, each `scale_factor` (1.2) smaller than the one below
//!   (sizes rounded), resized from it with OpenCV's bilinear `resize`. Level `l` is asked for
//!   `features · (1 − 1/s) / (1 − (1/s)^levels) · (1/s)^l` keypoints (rounded), the top level
//!   for what remains of `features` (1000).
//! - **FAST** (OpenCV's FAST-9/16 with non-maximum suppression) over the level but for a
//!   border: FAST's ring runs from 16 px in (`EDGE_THRESHOLD − 3`), so corners lie at least
//!   `EDGE_THRESHOLD` = 19 px from the level's edges. The area is cut into cells of about
//!   30 px; a cell keeps the corners FAST finds in it at threshold `ini_th_fast` (20) or,
//!   where there are none, at `min_th_fast` (7). ORB-SLAM2 runs FAST at `ini_th_fast` on each
//!   cell's window (the cell widened by FAST's 3 px radius); here it runs once over the level
//!   and the corners are binned into the cells. That finds the same corners but at cell
//!   borders, where a window cannot see its neighbour's pixels and keeps corners that a
//!   stronger neighbour across the border suppresses (ORB-SLAM2's cells keep ~9% more
//!   corners on the tests' rich texture, all of them at cell borders), and is ~20% faster.
//!   The fallback runs on the windows of the cells left empty, as ORB-SLAM2's does.
//! - **Quadtree** (ORB-SLAM2's `DistributeOctTree`): the area, first cut into
//!   `round(width / height)` columns, is split into quadrants, largest nodes first once the
//!   end is near, until there are as many nodes holding corners as the level's desired count
//!   or no node holds two corners; each node keeps its strongest corner (FAST score). The
//!   count can overshoot the desired one by up to 2 (a split adds up to 3 nodes). Unlike
//!   ORB-SLAM2, nothing is split when the first columns already reach the desired count, and
//!   a round of splits that happens to add no node (every split node's corners fell in one
//!   quadrant) does not end the splitting.
//! - **Orientation**: the angle of the intensity centroid, `atan2(m01, m10)` in degrees in
//!   `[0, 360)` (clockwise on the image, y pointing down, as OpenCV's), over a disc of radius `HALF_PATCH_SIZE` = 15 px (the pixels with
//!   `dx² + dy² ≤ 15·16`, symmetric under 90° rotations as ORB-SLAM2's `umax` table is) on the
//!   level image, not blurred.
//! - **Descriptor**: steered BRIEF with ORB's learned 256-test pattern (Rublee et al.'s rBRIEF,
//!   OpenCV's `bit_pattern_31_`, the pattern ORB-SLAM2 copies), computed by OpenCV's ORB
//!   (`compute` with our keypoints) on each level image. What OpenCV 4.6 does there, read in
//!   `modules/features2d/src/orb.cpp` and checked by the tests below:
//!   * it keeps the keypoint's angle: `compute` only computes orientation when it detects,
//!     and `computeOrbDescriptors` rotates the pattern by `KeyPoint::angle` (degrees). A
//!     keypoint at angle θ and θ + 90° gets different descriptors (85 of 256 bits apart on
//!     average in the test), and in the image turned by 90° the same point at θ + 90° gets
//!     the same descriptor (at most 1 bit apart);
//!   * it blurs: every pyramid level it builds is smoothed by a 7×7 Gaussian of σ = 2
//!     (`BORDER_REFLECT_101`) before the tests are read — exactly ORB-SLAM2's smoothing — so
//!     the level images are passed unblurred (blurring them too would smooth twice). A test
//!     shows it: one bright pixel changes ~14 bits of a flat patch's descriptor, where
//!     unblurred tests could change only those with a point on that pixel (about 0.3 of
//!     the 256 tests' second points per pixel of the 31×31 patch);
//!   * it pads the level by reflection (`BORDER_REFLECT_101`, as ORB-SLAM2's pyramid) and
//!     drops only keypoints nearer the border than its `edgeThreshold`, set to
//!     `EDGE_THRESHOLD` here, so none of ours is dropped; keypoints carry their index (as
//!     `class_id`) through the call all the same, so keypoints and descriptors stay aligned
//!     whatever OpenCV drops.
//!
//! Keypoints come out level by level, in level-0 pixels (their whole level pixel × the level's
//! scale), with their octave, angle, FAST score as response and size `31 × scale`. The same
//! image gives the same keypoints and descriptors in the same order.

use opencv::core::{self, Mat, Ptr, Rect, Size, Vector};
use opencv::features2d::{self, ORB, ORB_ScoreType};
use opencv::imgproc;
use opencv::prelude::*;
use rayon::prelude::*;

use slam_common::place::bow::Descriptor;

mod quadtree;

use quadtree::QuadTree;

/// Keypoints lie at least this far (px) from a level's edges (ORB-SLAM2's `EDGE_THRESHOLD`).
pub const EDGE_THRESHOLD: i32 = 19;
/// The rBRIEF patch side, px (ORB-SLAM2's `PATCH_SIZE`).
pub const PATCH_SIZE: i32 = 31;
/// The orientation disc's radius, px (ORB-SLAM2's `HALF_PATCH_SIZE`).
pub const HALF_PATCH_SIZE: i32 = 15;
/// The radius of FAST's Bresenham circle: corners lie this far inside the image FAST reads.
const FAST_RADIUS: i32 = 3;
/// The side FAST's cells aim at, px (ORB-SLAM2's `W`).
const CELL_PX: i32 = 30;

/// The extractor's parameters; ORB-SLAM2's defaults (its `ORBextractor.*` settings).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrbConfig {
    /// Keypoints wanted per image, over all levels.
    pub features: usize,
    /// Scale between consecutive pyramid levels (> 1).
    pub scale_factor: f64,
    /// Pyramid levels (1 to 32).
    pub levels: usize,
    /// FAST threshold tried first in each cell.
    pub ini_th_fast: i32,
    /// FAST threshold of the cells where `ini_th_fast` finds no corner (≤ `ini_th_fast`).
    pub min_th_fast: i32,
}

impl Default for OrbConfig {
    fn default() -> Self {
        Self {
            features: 1000,
            scale_factor: 1.2,
            levels: 8,
            ini_th_fast: 20,
            min_th_fast: 7,
        }
    }
}

/// A keypoint in level-0 pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyPoint {
    /// Column, level-0 px.
    pub u: f32,
    /// Row, level-0 px.
    pub v: f32,
    /// Pyramid level it was found on.
    pub octave: u8,
    /// Orientation, degrees in `[0, 360)`, clockwise on the image (x right, y down).
    pub angle_deg: f32,
    /// FAST score.
    pub response: f32,
    /// Patch diameter in level-0 px (`PATCH_SIZE` × the level's scale).
    pub size: f32,
}

#[derive(Debug, thiserror::Error)]
pub enum OrbError {
    #[error("OpenCV: {0}")]
    OpenCv(#[from] opencv::Error),
    #[error("invalid ORB configuration: {0}")]
    Config(String),
    #[error("a {width}x{height} image needs {} bytes, got {len}", width * height)]
    ImageSize {
        width: usize,
        height: usize,
        len: usize,
    },
}

/// A FAST corner on one level, level pixels.
#[derive(Debug, Clone, Copy)]
struct Corner {
    x: i32,
    y: i32,
    score: f32,
}

/// ORB-SLAM2's ORB extractor. Holds the pyramid and scratch buffers, reused across calls.
///
/// Once the pyramid is built, its levels are independent: each has its own worker (buffers
/// and OpenCV `ORB`), the levels run in parallel (rayon) and their keypoints are
/// concatenated in level order, so the output does not depend on the number of threads.
#[derive(Debug)]
pub struct OrbExtractor {
    config: OrbConfig,
    scale: Vec<f64>,
    inv_scale: Vec<f64>,
    sigma2: Vec<f64>,
    inv_sigma2: Vec<f64>,
    /// Keypoints wanted per level.
    per_level: Vec<usize>,
    /// Half-width of the orientation disc on each row `|dy|` = 0..=15.
    disc: [i32; HALF_PATCH_SIZE as usize + 1],
    pyramid: Vec<Mat>,
    workers: Vec<LevelWorker>,
}

/// One pyramid level's extraction state: OpenCV's ORB for the descriptors, scratch buffers,
/// and the level's keypoints and descriptors once extracted.
#[derive(Debug)]
struct LevelWorker {
    orb: Ptr<ORB>,
    fast: Vector<core::KeyPoint>,
    cv_keys: Vector<core::KeyPoint>,
    level_keys: Vec<KeyPoint>,
    descriptors: Mat,
    corners: Vec<Corner>,
    cell_has_corner: Vec<bool>,
    quadtree: QuadTree,
    keys: Vec<KeyPoint>,
    out: Vec<Descriptor>,
}

/// OpenCV's ORB for `compute`: only the descriptor parameters matter, the 31 px patch with
/// the learned pattern (WTA_K 2, 32 bytes) and the border under which keypoints are dropped.
fn descriptor_orb(config: &OrbConfig) -> Result<Ptr<ORB>, OrbError> {
    Ok(ORB::create(
        config.features.min(i32::MAX as usize) as i32,
        config.scale_factor as f32,
        1,
        EDGE_THRESHOLD,
        0,
        2,
        ORB_ScoreType::FAST_SCORE,
        PATCH_SIZE,
        config.ini_th_fast,
    )?)
}

impl OrbExtractor {
    pub fn new(config: OrbConfig) -> Result<Self, OrbError> {
        validate(&config)?;
        let levels = config.levels;
        let mut scale = vec![1.0; levels];
        for l in 1..levels {
            scale[l] = scale[l - 1] * config.scale_factor;
        }
        let inv_scale: Vec<f64> = scale.iter().map(|s| 1.0 / s).collect();
        let sigma2: Vec<f64> = scale.iter().map(|s| s * s).collect();
        let inv_sigma2 = sigma2.iter().map(|s| 1.0 / s).collect();

        let factor = 1.0 / config.scale_factor;
        let mut desired =
            config.features as f64 * (1.0 - factor) / (1.0 - factor.powi(levels as i32));
        let mut per_level = vec![0usize; levels];
        let mut sum = 0usize;
        for n in per_level.iter_mut().take(levels - 1) {
            *n = desired.round() as usize;
            sum += *n;
            desired *= factor;
        }
        per_level[levels - 1] = config.features.saturating_sub(sum);

        let mut disc = [0i32; HALF_PATCH_SIZE as usize + 1];
        let r2 = HALF_PATCH_SIZE * (HALF_PATCH_SIZE + 1);
        for (dy, half) in (0i32..).zip(disc.iter_mut()) {
            *half = (0..=HALF_PATCH_SIZE)
                .rev()
                .find(|dx| dx * dx + dy * dy <= r2)
                .unwrap_or(0);
        }

        let pyramid = (0..levels).map(|_| Mat::default()).collect();
        let workers = (0..levels)
            .map(|_| {
                Ok(LevelWorker {
                    orb: descriptor_orb(&config)?,
                    fast: Vector::new(),
                    cv_keys: Vector::new(),
                    level_keys: Vec::new(),
                    descriptors: Mat::default(),
                    corners: Vec::new(),
                    cell_has_corner: Vec::new(),
                    quadtree: QuadTree::default(),
                    keys: Vec::new(),
                    out: Vec::new(),
                })
            })
            .collect::<Result<_, OrbError>>()?;
        Ok(Self {
            config,
            scale,
            inv_scale,
            sigma2,
            inv_sigma2,
            per_level,
            disc,
            pyramid,
            workers,
        })
    }

    pub fn config(&self) -> &OrbConfig {
        &self.config
    }

    pub fn levels(&self) -> usize {
        self.config.levels
    }

    /// Scale of each level relative to level 0, `scale_factor^l`.
    pub fn scale_factors(&self) -> &[f64] {
        &self.scale
    }

    /// `1 / scale_factor^l`.
    pub fn inv_scale_factors(&self) -> &[f64] {
        &self.inv_scale
    }

    /// Squared scale of each level (ORB-SLAM2's `mvLevelSigma2`).
    pub fn level_sigma2(&self) -> &[f64] {
        &self.sigma2
    }

    /// `1 / level_sigma2` (ORB-SLAM2's `mvInvLevelSigma2`).
    pub fn inv_level_sigma2(&self) -> &[f64] {
        &self.inv_sigma2
    }

    /// Keypoints wanted on each level (ORB-SLAM2's `mnFeaturesPerLevel`).
    pub fn features_per_level(&self) -> &[usize] {
        &self.per_level
    }

    /// Keypoints and their descriptors (index-aligned) of an 8-bit grey image, row-major
    /// `width × height`.
    pub fn extract(
        &mut self,
        gray: &[u8],
        width: usize,
        height: usize,
    ) -> Result<(Vec<KeyPoint>, Vec<Descriptor>), OrbError> {
        if gray.len() != width * height || width > i32::MAX as usize || height > i32::MAX as usize {
            return Err(OrbError::ImageSize {
                width,
                height,
                len: gray.len(),
            });
        }
        let mut keys = Vec::with_capacity(self.config.features + 2 * self.levels());
        let mut descriptors = Vec::with_capacity(keys.capacity());
        if width == 0 || height == 0 {
            return Ok((keys, descriptors));
        }
        let levels = self.build_pyramid(gray, width, height)?;
        let (config, scale, per_level, disc) =
            (&self.config, &self.scale, &self.per_level, &self.disc);
        self.pyramid[..levels]
            .par_iter()
            .zip(&mut self.workers[..levels])
            .enumerate()
            .try_for_each(|(level, (image, worker))| {
                let want = per_level[level];
                worker.extract(config, level, scale[level], want, disc, image)
            })?;
        for worker in &mut self.workers[..levels] {
            keys.append(&mut worker.keys);
            descriptors.append(&mut worker.out);
        }
        Ok((keys, descriptors))
    }

    /// Fills the pyramid; returns how many levels are not empty.
    fn build_pyramid(
        &mut self,
        gray: &[u8],
        width: usize,
        height: usize,
    ) -> Result<usize, OrbError> {
        let base = Mat::new_rows_cols_with_data(height as i32, width as i32, gray)?;
        base.copy_to(&mut self.pyramid[0])?;
        for level in 1..self.levels() {
            let s = self.inv_scale[level];
            let size = Size::new(
                (width as f64 * s).round() as i32,
                (height as f64 * s).round() as i32,
            );
            if size.width < 1 || size.height < 1 {
                return Ok(level);
            }
            let (below, this) = self.pyramid.split_at_mut(level);
            imgproc::resize(
                &below[level - 1],
                &mut this[0],
                size,
                0.0,
                0.0,
                imgproc::INTER_LINEAR,
            )?;
        }
        Ok(self.levels())
    }
}

impl LevelWorker {
    /// The keypoints and descriptors of one level (`image`, at `scale` of level 0) into
    /// `self.keys` and `self.out`.
    fn extract(
        &mut self,
        config: &OrbConfig,
        level: usize,
        scale: f64,
        want: usize,
        disc: &[i32],
        image: &Mat,
    ) -> Result<(), OrbError> {
        self.keys.clear();
        self.out.clear();
        let (cols, rows) = (image.cols(), image.rows());
        // FAST reads [lo, hi) on each axis; its corners lie in [lo + 3, hi - 3).
        let lo = EDGE_THRESHOLD - FAST_RADIUS;
        let (hi_x, hi_y) = (cols - lo, rows - lo);
        if want == 0 || hi_x - lo <= 2 * FAST_RADIUS || hi_y - lo <= 2 * FAST_RADIUS {
            return Ok(());
        }
        let area = Rect::new(lo, lo, hi_x - lo, hi_y - lo);
        detect(
            image,
            area,
            config.ini_th_fast,
            config.min_th_fast,
            &mut self.fast,
            &mut self.cell_has_corner,
            &mut self.corners,
        )?;

        let bounds = [lo as f32, lo as f32, hi_x as f32, hi_y as f32];
        let kept = self.quadtree.distribute(&self.corners, bounds, want);

        if kept.is_empty() {
            return Ok(());
        }
        let data = image.data_bytes()?;
        let step = cols as usize;
        let scale = scale as f32;
        self.level_keys.clear();
        self.cv_keys.clear();
        for (index, &c) in kept.iter().enumerate() {
            let corner = self.corners[c];
            let angle = ic_angle(data, step, corner.x as usize, corner.y as usize, disc);
            self.level_keys.push(KeyPoint {
                u: corner.x as f32 * scale,
                v: corner.y as f32 * scale,
                octave: level as u8,
                angle_deg: angle,
                response: corner.score,
                size: PATCH_SIZE as f32 * scale,
            });
            // Level pixels at octave 0 of a one-level pyramid: the level image itself.
            self.cv_keys.push(core::KeyPoint::new_coords(
                corner.x as f32,
                corner.y as f32,
                PATCH_SIZE as f32,
                angle,
                corner.score,
                0,
                index as i32,
            )?);
        }
        self.orb
            .compute(image, &mut self.cv_keys, &mut self.descriptors)?;
        if self.cv_keys.is_empty() {
            return Ok(());
        }
        debug_assert_eq!(self.descriptors.cols(), 32);
        let bytes = self.descriptors.data_bytes()?;
        // The keypoints OpenCV kept, in the order of their descriptors.
        for (k, row) in self.cv_keys.iter().zip(bytes.chunks_exact(32)) {
            self.keys.push(self.level_keys[k.class_id() as usize]);
            let mut d = [0u8; 32];
            d.copy_from_slice(row);
            self.out.push(d);
        }
        Ok(())
    }
}

fn validate(c: &OrbConfig) -> Result<(), OrbError> {
    let err = |m: String| Err(OrbError::Config(m));
    if !(c.scale_factor.is_finite() && c.scale_factor > 1.0) {
        return err(format!("scale_factor {} is not above 1", c.scale_factor));
    }
    if !(1..=32).contains(&c.levels) {
        return err(format!("levels {} is not in 1..=32", c.levels));
    }
    if !(1..=255).contains(&c.ini_th_fast) || !(1..=255).contains(&c.min_th_fast) {
        return err(format!(
            "FAST thresholds {} and {} are not in 1..=255",
            c.ini_th_fast, c.min_th_fast
        ));
    }
    if c.min_th_fast > c.ini_th_fast {
        return err(format!(
            "min_th_fast {} is above ini_th_fast {}",
            c.min_th_fast, c.ini_th_fast
        ));
    }
    Ok(())
}

/// The FAST corners of `area` as ORB-SLAM2 finds them, into `corners` (level pixels): `area`
/// is cut into `n_cols × n_rows` cells of about `CELL_PX` (the area's width and height over
/// `CELL_PX`, rounded down, at least 1); a cell's corners are those FAST finds with threshold
/// `ini` in the cell widened by FAST's radius (3 px: the window ORB-SLAM2 runs FAST on), or,
/// where there are none, with threshold `min`.
///
/// FAST at `ini` runs once over `area` rather than once per cell: the same corners but at the
/// cells' borders, where a per-cell FAST cannot see across the border and keeps a few
/// corners that a stronger neighbour in the next cell suppresses here. FAST at `min` runs on
/// the windows of the cells left without corners, as in ORB-SLAM2.
fn detect(
    image: &Mat,
    area: Rect,
    ini: i32,
    min: i32,
    fast: &mut Vector<core::KeyPoint>,
    cell_has_corner: &mut Vec<bool>,
    corners: &mut Vec<Corner>,
) -> Result<(), OrbError> {
    fn push_corners(corners: &mut Vec<Corner>, fast: &Vector<core::KeyPoint>, ox: i32, oy: i32) {
        corners.extend(fast.iter().map(|k| {
            let p = k.pt();
            Corner {
                x: p.x.round() as i32 + ox,
                y: p.y.round() as i32 + oy,
                score: k.response(),
            }
        }));
    }
    let lines = |length: i32| {
        let n = (length / CELL_PX).max(1);
        (n, (length + n - 1) / n)
    };
    let (n_cols, cell_w) = lines(area.width);
    let (n_rows, cell_h) = lines(area.height);

    corners.clear();
    features2d::fast(&Mat::roi(image, area)?, fast, ini, true)?;
    push_corners(corners, fast, area.x, area.y);
    if min >= ini {
        return Ok(());
    }
    // Cell (i, j) holds the corners of x in area.x + 3 + [i, i + 1) * cell_w, and so of y.
    cell_has_corner.clear();
    cell_has_corner.resize((n_cols * n_rows) as usize, false);
    for c in corners.iter() {
        let i = ((c.x - area.x - FAST_RADIUS) / cell_w).clamp(0, n_cols - 1);
        let j = ((c.y - area.y - FAST_RADIUS) / cell_h).clamp(0, n_rows - 1);
        cell_has_corner[(j * n_cols + i) as usize] = true;
    }
    for j in 0..n_rows {
        for i in 0..n_cols {
            if cell_has_corner[(j * n_cols + i) as usize] {
                continue;
            }
            let (x0, y0) = (area.x + i * cell_w, area.y + j * cell_h);
            let x1 = (x0 + cell_w + 2 * FAST_RADIUS).min(area.x + area.width);
            let y1 = (y0 + cell_h + 2 * FAST_RADIUS).min(area.y + area.height);
            if x1 - x0 <= 2 * FAST_RADIUS || y1 - y0 <= 2 * FAST_RADIUS {
                continue;
            }
            let window = Rect::new(x0, y0, x1 - x0, y1 - y0);
            features2d::fast(&Mat::roi(image, window)?, fast, min, true)?;
            push_corners(corners, fast, x0, y0);
        }
    }
    Ok(())
}

/// Intensity-centroid orientation (Rosin 1999, as in ORB) of the disc about `(x, y)`,
/// degrees in `[0, 360)`. Rows `y ± v` are taken in pairs: their sum weighs `m10`, their
/// difference `m01`.
fn ic_angle(img: &[u8], step: usize, x: usize, y: usize, disc: &[i32]) -> f32 {
    let r = HALF_PATCH_SIZE as usize;
    let centre = y * step + x;
    let mut m10 = 0i32;
    let mut m01 = 0i32;
    for (i, &p) in img[centre - r..=centre + r].iter().enumerate() {
        m10 += (i as i32 - r as i32) * i32::from(p);
    }
    for v in 1..=r {
        let half = disc[v] as usize;
        let below = &img[centre + v * step - half..=centre + v * step + half];
        let above = &img[centre - v * step - half..=centre - v * step + half];
        let (mut diff, mut moment) = (0i32, 0i32);
        for (dx, (&b, &a)) in (-(half as i32)..).zip(below.iter().zip(above)) {
            let (b, a) = (i32::from(b), i32::from(a));
            diff += b - a;
            moment += dx * (b + a);
        }
        m10 += moment;
        m01 += v as i32 * diff;
    }
    let mut angle = (m01 as f32).atan2(m10 as f32).to_degrees();
    if angle < 0.0 {
        angle += 360.0;
    }
    if angle >= 360.0 {
        angle -= 360.0;
    }
    angle
}

#[cfg(test)]
mod tests;
