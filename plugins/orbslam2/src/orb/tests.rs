use std::time::Instant;

use opencv::core::{self, Mat, Ptr, Vector};
use opencv::features2d::{self, ORB, ORB_ScoreType};
use opencv::imgproc;
use opencv::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use plugin_api::gray_from_rgb;

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
        assert!(k.u >= b - 1e-3 && k.u <= W as f32 - b && k.v >= b - 1e-3 && k.v <= H as f32 - b);
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
                opencv_descriptor(&mut orb, &img, W, H, x as f32, y as f32, angle + 90.0).unwrap();
            let (xr, yr) = ((H - 1 - y) as f32, x as f32);
            let r =
                opencv_descriptor(&mut orb, &rot, H, W, xr, yr, (angle + 90.0) % 360.0).unwrap();
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
                    let p =
                        i64::from(img[(y as i64 + dy) as usize * 64 + (x as i64 + dx) as usize]);
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
