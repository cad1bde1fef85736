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

use slam_common::bow::Descriptor;

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

/// BT.601 luma of packed RGB8, rounded as OpenCV's `COLOR_RGB2GRAY` (bit for bit).
pub fn gray_from_rgb(rgb: &[u8], width: usize, height: usize) -> Vec<u8> {
    // OpenCV's fixed point for 8-bit images: 0.299, 0.587, 0.114 in 15 bits.
    const R: u32 = 9798;
    const G: u32 = 19235;
    const B: u32 = 3735;
    rgb.chunks_exact(3)
        .take(width * height)
        .map(|p| {
            ((R * u32::from(p[0]) + G * u32::from(p[1]) + B * u32::from(p[2]) + (1 << 14)) >> 15)
                as u8
        })
        .collect()
}

/// A quadtree node: a rectangle of the level and the corners in it, a contiguous run
/// `order[start..end]` of corner indices.
#[derive(Debug, Clone, Copy)]
struct Node {
    x0: f32,
    y0: f32,
    x1: f32,
    y1: f32,
    start: usize,
    end: usize,
}

impl Node {
    fn len(&self) -> usize {
        self.end - self.start
    }

    /// Holds two corners or more and can still separate them (corners sit on whole pixels,
    /// so a node holding two is at least 1 px wide or high).
    fn can_split(&self) -> bool {
        self.len() > 1 && (self.x1 - self.x0 > 0.5 || self.y1 - self.y0 > 0.5)
    }
}

/// ORB-SLAM2's keypoint distribution, with buffers reused across calls.
#[derive(Debug, Default)]
struct QuadTree {
    order: Vec<u32>,
    scratch: Vec<u32>,
    nodes: Vec<Node>,
    next: Vec<Node>,
    largest: Vec<usize>,
}

impl QuadTree {
    /// Indices of the corners kept: the strongest of each node once the area
    /// `[x0, y0, x1, y1]` is split into `target` nodes (or as many as can be), in node order.
    fn distribute(&mut self, corners: &[Corner], area: [f32; 4], target: usize) -> Vec<usize> {
        if corners.is_empty() || target == 0 {
            return Vec::new();
        }
        self.initial_nodes(corners, area);
        while self.nodes.len() < target {
            self.next.clear();
            let mut splittable = 0;
            let mut split_any = false;
            for i in 0..self.nodes.len() {
                let node = self.nodes[i];
                if !node.can_split() {
                    self.next.push(node);
                    continue;
                }
                split_any = true;
                for child in self.split(&node, corners) {
                    if child.len() > 0 {
                        splittable += usize::from(child.can_split());
                        self.next.push(child);
                    }
                }
            }
            std::mem::swap(&mut self.nodes, &mut self.next);
            if self.nodes.len() >= target || !split_any || splittable == 0 {
                break;
            }
            if self.nodes.len() + 3 * splittable > target {
                self.split_largest_until(corners, target);
                break;
            }
        }

        self.nodes
            .iter()
            .map(|n| {
                let mut best = self.order[n.start] as usize;
                for &i in &self.order[n.start + 1..n.end] {
                    if corners[i as usize].score > corners[best].score {
                        best = i as usize;
                    }
                }
                best
            })
            .collect()
    }

    /// The area cut into `round(width / height)` (at least 1) columns, empty ones dropped.
    fn initial_nodes(&mut self, corners: &[Corner], [x0, y0, x1, y1]: [f32; 4]) {
        let n = ((x1 - x0) / (y1 - y0)).round().max(1.0) as usize;
        let w = (x1 - x0) / n as f32;
        let column = |c: &Corner| (((c.x as f32 - x0) / w) as usize).min(n - 1);
        let mut counts = vec![0usize; n + 1];
        for c in corners {
            counts[column(c) + 1] += 1;
        }
        for i in 1..=n {
            counts[i] += counts[i - 1];
        }
        self.order.clear();
        self.order.resize(corners.len(), 0);
        let mut fill = counts.clone();
        for (i, c) in corners.iter().enumerate() {
            let k = column(c);
            self.order[fill[k]] = i as u32;
            fill[k] += 1;
        }
        self.nodes.clear();
        for k in 0..n {
            if counts[k + 1] > counts[k] {
                self.nodes.push(Node {
                    x0: x0 + k as f32 * w,
                    y0,
                    x1: if k + 1 == n {
                        x1
                    } else {
                        x0 + (k + 1) as f32 * w
                    },
                    y1,
                    start: counts[k],
                    end: counts[k + 1],
                });
            }
        }
    }

    /// Splits nodes, the most populated first (ties in node order), until there are
    /// `target` nodes or none can split.
    fn split_largest_until(&mut self, corners: &[Corner], target: usize) {
        loop {
            self.largest.clear();
            self.largest
                .extend((0..self.nodes.len()).filter(|&i| self.nodes[i].can_split()));
            if self.largest.is_empty() {
                return;
            }
            let nodes = &self.nodes;
            self.largest
                .sort_by_key(|&i| std::cmp::Reverse(nodes[i].len()));
            for k in 0..self.largest.len() {
                let i = self.largest[k];
                let node = self.nodes[i];
                let mut first = true;
                for child in self.split(&node, corners) {
                    if child.len() == 0 {
                        continue;
                    }
                    if first {
                        self.nodes[i] = child;
                        first = false;
                    } else {
                        self.nodes.push(child);
                    }
                }
                if self.nodes.len() >= target {
                    return;
                }
            }
        }
    }

    /// The four quadrants of `node` (top-left, top-right, bottom-left, bottom-right), its
    /// run of `order` regrouped by quadrant, keeping the corners' relative order.
    fn split(&mut self, node: &Node, corners: &[Corner]) -> [Node; 4] {
        let mx = 0.5 * (node.x0 + node.x1);
        let my = 0.5 * (node.y0 + node.y1);
        let quadrant = |i: u32| {
            let c = &corners[i as usize];
            usize::from(c.x as f32 >= mx) + 2 * usize::from(c.y as f32 >= my)
        };
        let run = &mut self.order[node.start..node.end];
        let mut counts = [0usize; 4];
        for &i in run.iter() {
            counts[quadrant(i)] += 1;
        }
        let mut fill = [
            0,
            counts[0],
            counts[0] + counts[1],
            counts[0] + counts[1] + counts[2],
        ];
        let starts = fill;
        self.scratch.clear();
        self.scratch.resize(run.len(), 0);
        for &i in run.iter() {
            let q = quadrant(i);
            self.scratch[fill[q]] = i;
            fill[q] += 1;
        }
        run.copy_from_slice(&self.scratch);
        let rect = |q: usize| {
            let (x0, x1) = if q % 2 == 0 {
                (node.x0, mx)
            } else {
                (mx, node.x1)
            };
            let (y0, y1) = if q < 2 { (node.y0, my) } else { (my, node.y1) };
            Node {
                x0,
                y0,
                x1,
                y1,
                start: node.start + starts[q],
                end: node.start + starts[q] + counts[q],
            }
        };
        [rect(0), rect(1), rect(2), rect(3)]
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use opencv::core::{self, Mat, Ptr, Vector};
    use opencv::features2d::{self, ORB, ORB_ScoreType};
    use opencv::imgproc;
    use opencv::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    const W: usize = 640;
    const H: usize = 480;

    /// A seeded texture: a few thousand overlapping discs and axis-aligned rectangles of
    /// random grey levels and sizes (2 to 40 px), smoothed by a 5×5 Gaussian of σ = 1, its
    /// contrast about mid-grey scaled by `contrast`.
    fn texture(width: usize, height: usize, seed: u64, contrast: f64) -> Vec<u8> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut img = vec![128u8; width * height];
        let shapes = width * height / 100;
        for _ in 0..shapes {
            let r = (rng.random_range(2f64.ln()..40f64.ln())).exp();
            let (cx, cy) = (
                rng.random_range(0.0..width as f64),
                rng.random_range(0.0..height as f64),
            );
            let value: u8 = rng.random();
            let disc = rng.random_bool(0.5);
            let (rx, ry) = if disc {
                (r, r)
            } else {
                (r, r * rng.random_range(0.3..3.0))
            };
            let x0 = (cx - rx).max(0.0) as usize;
            let x1 = ((cx + rx).ceil() as usize).min(width);
            let y0 = (cy - ry).max(0.0) as usize;
            let y1 = ((cy + ry).ceil() as usize).min(height);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                    if !disc || dx * dx + dy * dy <= r * r {
                        img[y * width + x] = value;
                    }
                }
            }
        }
        let src = Mat::new_rows_cols_with_data(height as i32, width as i32, &img).unwrap();
        let mut blurred = Mat::default();
        imgproc::gaussian_blur(
            &src,
            &mut blurred,
            Size::new(5, 5),
            1.0,
            1.0,
            core::BORDER_REFLECT_101,
        )
        .unwrap();
        blurred
            .data_bytes()
            .unwrap()
            .iter()
            .map(|&p| (128.0 + (f64::from(p) - 128.0) * contrast).round() as u8)
            .collect()
    }

    /// The image turned 90° clockwise (x right, y down): pixel `(x, y)` goes to
    /// `(height − 1 − y, x)`; the result is `height` wide and `width` high.
    fn rotate_cw(img: &[u8], width: usize, height: usize) -> Vec<u8> {
        let mut out = vec![0u8; img.len()];
        for y in 0..height {
            for x in 0..width {
                out[x * height + (height - 1 - y)] = img[y * width + x];
            }
        }
        out
    }

    fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
        a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
    }

    fn extractor() -> OrbExtractor {
        OrbExtractor::new(OrbConfig::default()).unwrap()
    }

    /// OpenCV's ORB as the extractor sets it up, for probing `compute` directly.
    fn opencv_orb() -> Ptr<ORB> {
        ORB::create(
            1000,
            1.2,
            1,
            EDGE_THRESHOLD,
            0,
            2,
            ORB_ScoreType::FAST_SCORE,
            PATCH_SIZE,
            20,
        )
        .unwrap()
    }

    /// OpenCV's descriptor of one keypoint (at level 0 of `img`), `None` if dropped.
    fn opencv_descriptor(
        orb: &mut Ptr<ORB>,
        img: &[u8],
        width: usize,
        height: usize,
        x: f32,
        y: f32,
        angle: f32,
    ) -> Option<Descriptor> {
        let mat = Mat::new_rows_cols_with_data(height as i32, width as i32, img).unwrap();
        let mut keys: Vector<core::KeyPoint> = Vector::new();
        keys.push(core::KeyPoint::new_coords(x, y, 31.0, angle, 0.0, 0, 0).unwrap());
        let mut desc = Mat::default();
        orb.compute(&mat, &mut keys, &mut desc).unwrap();
        if keys.is_empty() {
            return None;
        }
        let mut d = [0u8; 32];
        d.copy_from_slice(desc.data_bytes().unwrap());
        Some(d)
    }

    #[test]
    fn levels_scales_and_counts_follow_orbslam2() {
        let e = extractor();
        assert_eq!(e.levels(), 8);
        assert_eq!(
            e.features_per_level(),
            &[217, 181, 151, 126, 105, 87, 73, 60]
        );
        for l in 0..8 {
            let s = 1.2f64.powi(l as i32);
            assert!((e.scale_factors()[l] - s).abs() < 1e-12);
            assert!((e.inv_scale_factors()[l] - 1.0 / s).abs() < 1e-12);
            assert!((e.level_sigma2()[l] - s * s).abs() < 1e-12);
            assert!((e.inv_level_sigma2()[l] - 1.0 / (s * s)).abs() < 1e-12);
        }
    }

    #[test]
    fn config_defaults_and_validation() {
        let c: OrbConfig = toml::from_str("features = 500").unwrap();
        assert_eq!(
            c,
            OrbConfig {
                features: 500,
                ..OrbConfig::default()
            }
        );
        assert!(toml::from_str::<OrbConfig>("nfeatures = 500").is_err());
        for bad in [
            OrbConfig {
                scale_factor: 1.0,
                ..OrbConfig::default()
            },
            OrbConfig {
                levels: 0,
                ..OrbConfig::default()
            },
            OrbConfig {
                min_th_fast: 30,
                ..OrbConfig::default()
            },
            OrbConfig {
                ini_th_fast: 0,
                ..OrbConfig::default()
            },
        ] {
            assert!(matches!(OrbExtractor::new(bad), Err(OrbError::Config(_))));
        }
    }

    #[test]
    fn odd_sizes_are_handled() {
        let mut e = extractor();
        assert!(matches!(
            e.extract(&[0; 10], 4, 4),
            Err(OrbError::ImageSize { .. })
        ));
        let (k, d) = e.extract(&[], 0, 0).unwrap();
        assert!(k.is_empty() && d.is_empty());
        // Too small for any keypoint's border.
        let (k, d) = e.extract(&texture(40, 30, 1, 1.0), 40, 30).unwrap();
        assert!(k.is_empty() && d.is_empty());
        // Only the lower levels have room.
        let (k, d) = e.extract(&texture(120, 90, 1, 1.0), 120, 90).unwrap();
        assert_eq!(k.len(), d.len());
        assert!(!k.is_empty());
        assert!(k.iter().all(|k| k.octave <= 4), "{k:?}");
    }

    #[test]
    fn gray_is_opencvs_rgb_to_gray() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let (w, h) = (64, 48);
        let rgb: Vec<u8> = (0..w * h * 3).map(|_| rng.random()).collect();
        let src = Mat::new_rows_cols_with_data(h as i32, (w * 3) as i32, &rgb).unwrap();
        let src = src.reshape(3, h as i32).unwrap();
        let mut gray = Mat::default();
        imgproc::cvt_color_def(&src, &mut gray, imgproc::COLOR_RGB2GRAY).unwrap();
        assert_eq!(gray_from_rgb(&rgb, w, h), gray.data_bytes().unwrap());
    }

    #[test]
    fn rich_texture_gives_about_1000_features_spread_over_all_octaves() {
        let img = texture(W, H, 1, 1.0);
        let mut e = extractor();
        let (keys, desc) = e.extract(&img, W, H).unwrap();
        assert_eq!(keys.len(), desc.len());
        let mut per_octave = [0usize; 8];
        for k in &keys {
            per_octave[usize::from(k.octave)] += 1;
        }
        eprintln!("{} keypoints, per octave {per_octave:?}", keys.len());
        assert!(
            (990..=1016).contains(&keys.len()),
            "{} keypoints",
            keys.len()
        );
        for (l, (&n, &want)) in per_octave.iter().zip(e.features_per_level()).enumerate() {
            assert!(
                n + 10 >= want && n <= want + 2,
                "octave {l}: {n} keypoints for {want} wanted"
            );
        }
        // Spread: a 4x4 grid, a cell covered when it holds at least 5 keypoints.
        let mut grid = [0usize; 16];
        for k in &keys {
            let (i, j) = ((k.u as usize * 4 / W).min(3), (k.v as usize * 4 / H).min(3));
            grid[j * 4 + i] += 1;
        }
        eprintln!("4x4 grid: {grid:?}");
        assert!(grid.iter().filter(|&&n| n >= 5).count() >= 14, "{grid:?}");
        for k in &keys {
            let s = e.scale_factors()[usize::from(k.octave)] as f32;
            let b = EDGE_THRESHOLD as f32 * s;
            assert!(
                k.u >= b - 1e-3 && k.u <= W as f32 - b && k.v >= b - 1e-3 && k.v <= H as f32 - b
            );
            assert!((0.0..360.0).contains(&k.angle_deg));
            assert!(k.response >= 7.0);
            assert!((k.size - 31.0 * s).abs() < 1e-3);
        }
        // No two keypoints of a level at one pixel.
        let mut seen: Vec<(u8, i64, i64)> = keys
            .iter()
            .map(|k| (k.octave, (k.u * 16.0) as i64, (k.v * 16.0) as i64))
            .collect();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), keys.len());
    }

    /// ORB-SLAM2's cells, literally: FAST at `ini` on each cell's window, at `min` where that
    /// finds nothing. Corner pixels, sorted.
    fn per_cell_reference(image: &Mat, area: Rect, ini: i32, min: i32) -> Vec<(i32, i32)> {
        let (n_cols, n_rows) = ((area.width / 30).max(1), (area.height / 30).max(1));
        let (cw, ch) = (
            (area.width + n_cols - 1) / n_cols,
            (area.height + n_rows - 1) / n_rows,
        );
        let mut out = Vec::new();
        let mut kps: Vector<core::KeyPoint> = Vector::new();
        for j in 0..n_rows {
            for i in 0..n_cols {
                let (x0, y0) = (area.x + i * cw, area.y + j * ch);
                let x1 = (x0 + cw + 6).min(area.x + area.width);
                let y1 = (y0 + ch + 6).min(area.y + area.height);
                if x1 - x0 <= 6 || y1 - y0 <= 6 {
                    continue;
                }
                let window = Mat::roi(image, Rect::new(x0, y0, x1 - x0, y1 - y0)).unwrap();
                features2d::fast(&window, &mut kps, ini, true).unwrap();
                if kps.is_empty() {
                    features2d::fast(&window, &mut kps, min, true).unwrap();
                }
                out.extend(
                    kps.iter()
                        .map(|k| (k.pt().x as i32 + x0, k.pt().y as i32 + y0)),
                );
            }
        }
        out.sort_unstable();
        out
    }

    /// One FAST pass per level at `ini_th_fast` finds ORB-SLAM2's per-cell corners but for
    /// a few that only a cell's window keeps, at its border.
    #[test]
    fn detection_matches_orbslam2s_cells() {
        for (contrast, seed) in [(1.0, 2), (0.3, 2), (0.12, 3)] {
            let img = texture(W, H, seed, contrast);
            let mat = Mat::new_rows_cols_with_data(H as i32, W as i32, &img)
                .unwrap()
                .try_clone()
                .unwrap();
            let area = Rect::new(16, 16, W as i32 - 32, H as i32 - 32);
            let reference = per_cell_reference(&mat, area, 20, 7);
            let (mut fast, mut cells, mut corners) = (Vector::new(), Vec::new(), Vec::new());
            detect(&mat, area, 20, 7, &mut fast, &mut cells, &mut corners).unwrap();
            let mut ours: Vec<(i32, i32)> = corners.iter().map(|c| (c.x, c.y)).collect();
            ours.sort_unstable();
            let common = ours
                .iter()
                .filter(|p| reference.binary_search(p).is_ok())
                .count();
            let weak = corners.iter().filter(|c| c.score < 20.0).count();
            eprintln!(
                "contrast {contrast}: {} corners ({weak} of the fallback), ORB-SLAM2's cells {}, \
                 {common} in both",
                ours.len(),
                reference.len()
            );
            assert!(common * 100 >= ours.len() * 97);
            // What only ORB-SLAM2's windows keep lies on a cell's first or last row or column.
            let (n_cols, n_rows) = (area.width / 30, area.height / 30);
            let (cw, ch) = (
                (area.width + n_cols - 1) / n_cols,
                (area.height + n_rows - 1) / n_rows,
            );
            let on_border = |(x, y): (i32, i32)| {
                let (i, j) = ((x - area.x - 3) % cw, (y - area.y - 3) % ch);
                i == 0 || i == cw - 1 || j == 0 || j == ch - 1
            };
            let inside: Vec<_> = reference
                .iter()
                .filter(|p| ours.binary_search(p).is_err() && !on_border(**p))
                .collect();
            assert!(inside.is_empty(), "{inside:?}");
            assert!(reference.len() * 100 <= ours.len() * 115);
        }
    }

    #[test]
    fn low_contrast_falls_back_to_the_low_threshold() {
        let img = texture(W, H, 3, 0.12);
        let strict = OrbConfig {
            min_th_fast: 20,
            ..OrbConfig::default()
        };
        let (few, _) = OrbExtractor::new(strict)
            .unwrap()
            .extract(&img, W, H)
            .unwrap();
        let (keys, desc) = extractor().extract(&img, W, H).unwrap();
        eprintln!(
            "low contrast: {} keypoints at threshold 20 alone, {} with the fallback to 7",
            few.len(),
            keys.len()
        );
        assert_eq!(keys.len(), desc.len());
        assert!(few.len() < 200, "{} keypoints at threshold 20", few.len());
        assert!(
            keys.len() > 800,
            "{} keypoints with the fallback",
            keys.len()
        );
        assert!(keys.iter().filter(|k| k.response < 20.0).count() > keys.len() / 2);
    }

    #[test]
    fn same_image_same_output() {
        let img = texture(W, H, 4, 1.0);
        let mut e = extractor();
        let first = e.extract(&img, W, H).unwrap();
        // Another image in between, then the first again, and a fresh extractor.
        e.extract(&texture(W, H, 5, 1.0), W, H).unwrap();
        assert_eq!(e.extract(&img, W, H).unwrap(), first);
        assert_eq!(extractor().extract(&img, W, H).unwrap(), first);
    }

    /// OpenCV's `compute` steers the pattern by the angle given: 0° and 90° differ, and
    /// turning the image by 90° while adding 90° to the angle gives the same descriptor.
    #[test]
    fn opencv_compute_keeps_the_angle() {
        let img = texture(W, H, 6, 1.0);
        let rot = rotate_cw(&img, W, H);
        let mut orb = opencv_orb();
        let mut worst_same = 0;
        let mut least_different = 256;
        let mut different = Vec::new();
        for (x, y) in [(320, 240), (100, 80), (500, 400), (57, 300)] {
            for angle in [0.0f32, 30.0, 45.0, 90.0, 200.0, 333.3] {
                let d = opencv_descriptor(&mut orb, &img, W, H, x as f32, y as f32, angle).unwrap();
                let turned =
                    opencv_descriptor(&mut orb, &img, W, H, x as f32, y as f32, angle + 90.0)
                        .unwrap();
                let (xr, yr) = ((H - 1 - y) as f32, x as f32);
                let r = opencv_descriptor(&mut orb, &rot, H, W, xr, yr, (angle + 90.0) % 360.0)
                    .unwrap();
                worst_same = worst_same.max(hamming(&d, &r));
                least_different = least_different.min(hamming(&d, &turned));
                different.push(hamming(&d, &turned));
            }
        }
        let mean = different.iter().sum::<u32>() as f64 / different.len() as f64;
        eprintln!(
            "OpenCV compute: same point turned with the image: <= {worst_same} bits apart; \
             angle and angle + 90°: {mean:.0} bits apart on average, >= {least_different}"
        );
        assert!(worst_same <= 8, "{worst_same}");
        assert!(least_different >= 10 && mean >= 60.0, "{different:?}");
    }

    /// OpenCV's `compute` smooths the image before reading the tests: on a flat image, one
    /// bright pixel flips ~10 bits (the tests with a point within the 7×7 kernel of it),
    /// where unsmoothed tests could flip only those with a point on that very pixel (256 of
    /// the tests' points over the 31×31 patch: about 0.3 per pixel).
    #[test]
    fn opencv_compute_blurs() {
        let mut orb = opencv_orb();
        let (w, h) = (101, 101);
        let (cx, cy) = (50usize, 50usize);
        let flat = vec![100u8; w * h];
        let base = opencv_descriptor(&mut orb, &flat, w, h, cx as f32, cy as f32, 0.0).unwrap();
        assert_eq!(base, [0u8; 32], "ties read as 0");
        let mut flips = Vec::new();
        for dy in (-12i32..=12).step_by(2) {
            for dx in (-12i32..=12).step_by(2) {
                let mut img = flat.clone();
                img[(cy as i32 + dy) as usize * w + (cx as i32 + dx) as usize] = 255;
                let d = opencv_descriptor(&mut orb, &img, w, h, cx as f32, cy as f32, 0.0).unwrap();
                flips.push(hamming(&base, &d));
            }
        }
        let mean = flips.iter().sum::<u32>() as f64 / flips.len() as f64;
        let none = flips.iter().filter(|&&f| f == 0).count();
        eprintln!(
            "OpenCV compute, one bright pixel in a flat patch: {mean:.1} bits flipped on \
             average, max {}, {none} of {} positions flip none",
            flips.iter().max().unwrap(),
            flips.len()
        );
        assert!(mean > 4.0, "{mean}");
        assert!(none * 10 < flips.len());
    }

    /// The image turned by 90°: keypoints found at the same place of the scene turn their
    /// angle by 90° and keep their descriptor, and nearest-descriptor matching finds them.
    #[test]
    fn a_quarter_turn_turns_angles_and_keeps_descriptors() {
        let img = texture(W, H, 8, 1.0);
        let rot = rotate_cw(&img, W, H);
        let mut e = extractor();
        let (ka, da) = e.extract(&img, W, H).unwrap();
        let (kb, db) = e.extract(&rot, H, W).unwrap();
        let scales = e.scale_factors().to_vec();
        let level_px = |k: &KeyPoint| {
            let s = scales[usize::from(k.octave)] as f32;
            ((k.u / s).round() as i64, (k.v / s).round() as i64)
        };
        let mut pairs = Vec::new();
        for (i, a) in ka.iter().enumerate() {
            let s = scales[usize::from(a.octave)];
            let level_h = (H as f64 / s).round() as i64;
            let (x, y) = level_px(a);
            let (xr, yr) = (level_h - 1 - y, x);
            if let Some(j) = kb.iter().position(|b| {
                let (xb, yb) = level_px(b);
                b.octave == a.octave && (xb - xr).abs() <= 1 && (yb - yr).abs() <= 1
            }) {
                pairs.push((i, j));
            }
        }
        let mut angle_err: Vec<f32> = pairs
            .iter()
            .map(|&(i, j)| {
                let d = (kb[j].angle_deg - ka[i].angle_deg - 90.0).rem_euclid(360.0);
                d.min(360.0 - d)
            })
            .collect();
        angle_err.sort_by(f32::total_cmp);
        let mut dist: Vec<u32> = pairs
            .iter()
            .map(|&(i, j)| hamming(&da[i], &db[j]))
            .collect();
        dist.sort_unstable();
        let matched = pairs
            .iter()
            .filter(|&&(i, j)| {
                let best = (0..db.len())
                    .min_by_key(|&k| (hamming(&da[i], &db[k]), k))
                    .unwrap();
                best == j
            })
            .count();
        eprintln!(
            "quarter turn: {} of {} keypoints found again; angle error median {:.2}°, 90th \
             percentile {:.2}°; Hamming median {}, 90th percentile {}; nearest descriptor is \
             the counterpart for {matched}",
            pairs.len(),
            ka.len(),
            angle_err[angle_err.len() / 2],
            angle_err[angle_err.len() * 9 / 10],
            dist[dist.len() / 2],
            dist[dist.len() * 9 / 10],
        );
        assert!(pairs.len() * 2 > ka.len(), "{} counterparts", pairs.len());
        assert!(angle_err[angle_err.len() * 9 / 10] < 2.0);
        assert!(dist[dist.len() / 2] <= 5);
        assert!(
            matched * 10 >= pairs.len() * 9,
            "{matched} of {}",
            pairs.len()
        );
    }

    #[test]
    fn quadtree_keeps_the_strongest_of_target_nodes() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let corners: Vec<Corner> = (0..3000)
            .map(|_| Corner {
                x: rng.random_range(16..600),
                y: rng.random_range(16..450),
                score: rng.random_range(7.0..80.0),
            })
            .collect();
        let mut pixels: Vec<(i32, i32)> = corners.iter().map(|c| (c.x, c.y)).collect();
        pixels.sort_unstable();
        pixels.dedup();
        let corners: Vec<Corner> = pixels
            .iter()
            .zip(&corners)
            .map(|(&(x, y), c)| Corner { x, y, ..*c })
            .collect();
        let mut tree = QuadTree::default();
        let area = [16.0, 16.0, 600.0, 450.0];
        for target in [1, 2, 7, 100, 217, 1000] {
            let kept = tree.distribute(&corners, area, target);
            assert!(
                (target..=target + 2).contains(&kept.len()),
                "{} nodes for {target}",
                kept.len()
            );
            let mut unique = kept.clone();
            unique.sort_unstable();
            unique.dedup();
            assert_eq!(unique.len(), kept.len());
        }
        // The single node keeps the strongest corner of all.
        let kept = tree.distribute(&corners, area, 1);
        let strongest = corners.iter().map(|c| c.score).fold(f32::MIN, f32::max);
        assert_eq!(corners[kept[0]].score, strongest);
        // More wanted than there are: every corner.
        let few = &corners[..50];
        assert_eq!(tree.distribute(few, area, 80).len(), 50);
        // Two neighbouring corners alone still split apart.
        let two = [
            Corner {
                x: 100,
                y: 100,
                score: 10.0,
            },
            Corner {
                x: 101,
                y: 100,
                score: 12.0,
            },
        ];
        assert_eq!(tree.distribute(&two, area, 5).len(), 2);
    }

    /// Keypoints that OpenCV's `compute` drops (here: with a wider border than ours) leave
    /// the others with their own descriptors.
    #[test]
    fn keypoints_dropped_by_opencv_keep_the_rest_aligned() {
        let img = texture(W, H, 12, 1.0);
        let (all_keys, all_desc) = extractor().extract(&img, W, H).unwrap();
        let mut e = extractor();
        for w in &mut e.workers {
            w.orb = ORB::create(
                1000,
                1.2,
                1,
                40,
                0,
                2,
                ORB_ScoreType::FAST_SCORE,
                PATCH_SIZE,
                20,
            )
            .unwrap();
        }
        let (keys, desc) = e.extract(&img, W, H).unwrap();
        assert_eq!(keys.len(), desc.len());
        assert!(
            keys.len() < all_keys.len() * 9 / 10,
            "{} of {}",
            keys.len(),
            all_keys.len()
        );
        let mut from = 0;
        for (k, d) in keys.iter().zip(&desc) {
            let i = from + all_keys[from..].iter().position(|a| a == k).unwrap();
            assert_eq!(d, &all_desc[i]);
            from = i + 1;
        }
    }

    /// The paired-row moments are the disc's moments.
    #[test]
    fn ic_angle_is_the_disc_centroid_angle() {
        let img = texture(64, 64, 11, 1.0);
        let e = extractor();
        for (x, y) in [(32, 32), (15, 15), (48, 20), (20, 48)] {
            let (mut m10, mut m01) = (0i64, 0i64);
            for dy in -15i64..=15 {
                for dx in -15i64..=15 {
                    if dx * dx + dy * dy <= 240 {
                        let p = i64::from(
                            img[(y as i64 + dy) as usize * 64 + (x as i64 + dx) as usize],
                        );
                        m10 += dx * p;
                        m01 += dy * p;
                    }
                }
            }
            let want = (m01 as f32)
                .atan2(m10 as f32)
                .to_degrees()
                .rem_euclid(360.0);
            let got = ic_angle(&img, 64, x, y, &e.disc);
            assert!((got - want).abs() < 1e-3, "{got} vs {want}");
        }
        assert_eq!(e.disc[0], 15);
        assert_eq!(e.disc[15], 3);
    }

    #[test]
    fn extractor_is_send() {
        fn send<T: Send>() {}
        send::<OrbExtractor>();
    }

    /// Per-frame time on a textured 640x480 image (printed, not asserted).
    #[test]
    fn timing_640x480() {
        let rgb: Vec<u8> = texture(W, H, 10, 1.0)
            .iter()
            .flat_map(|&g| [g, g.saturating_add(10), g / 2])
            .collect();
        let mut e = extractor();
        for _ in 0..3 {
            e.extract(&gray_from_rgb(&rgb, W, H), W, H).unwrap();
        }
        let n = 20;
        let mut times = Vec::new();
        let mut count = 0;
        for _ in 0..n {
            let t = Instant::now();
            let gray = gray_from_rgb(&rgb, W, H);
            let (k, _) = e.extract(&gray, W, H).unwrap();
            times.push(t.elapsed().as_secs_f64() * 1e3);
            count = k.len();
        }
        times.sort_by(f64::total_cmp);
        eprintln!(
            "640x480, {count} keypoints: gray + extract {:.2} ms median, {:.2} ms min, {:.2} ms \
             max over {n} frames (OpenCV threads: {})",
            times[n / 2],
            times[0],
            times[n - 1],
            core::get_num_threads().unwrap()
        );
    }
}
