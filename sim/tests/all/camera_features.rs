//! The RGB-D frames through OpenCV (the `opencv` crate over Debian's libopencv-dev), as a
//! feature-based visual SLAM such as RTAB-Map sees them: driving down a lane of the default
//! world (growth stage 3, identical clones, default noise) at full speed, ORB (1000
//! features) and GFTT (RTAB-Map's defaults) find several hundred features per frame, both
//! well spread over the image (the ground's clods, stones and their shadows hold as many as
//! the canopy), and PnP between frames 1 and 3 apart recovers the ground-truth relative pose
//! within 1 cm / 0.5°.
//!
//! PnP on ORB's own keypoints is printed next to the asserted GFTT/ORB figures (GFTT's
//! corners with ORB descriptors, RTAB-Map's `GFTT/ORB` feature type), not asserted. It used
//! to miss 1 cm in 4 of the 10 pairs, when nearly all of ORB's keypoints lay on leaf
//! silhouettes, where the depth at a keypoint belongs to the leaf or to what is behind it;
//! with keypoints on the ground too, all 10 pairs are within the bounds, the worst at 9 mm.

use std::sync::OnceLock;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use opencv::core::{
    self, DMatch, KeyPoint, Mat, NORM_HAMMING, Point2f, Point3f, Ptr, Vec3b, Vector,
};
use opencv::features2d::{BFMatcher, ORB, ORB_ScoreType};
use opencv::prelude::*;
use opencv::{calib3d, imgproc};
use sim::camera::{RgbdCamera, RgbdImage};
use sim::rng::stream;

/// Frames are anchored at these times of S1 (the robot drives the lane's first leg at its
/// full 0.5 m/s), each with the camera's next frame and the one 3 frames later.
const ANCHORS_S: [f64; 5] = [20.0, 22.5, 25.0, 27.5, 30.0];
const FRAME_OFFSETS: [i64; 3] = [0, 1, 3];

const MIN_FEATURES: usize = 300;
/// Spread: the image is cut into a 4x4 grid and a cell counts as covered when it holds at
/// least `MIN_PER_CELL` keypoints (one stray corner would say nothing about coverage).
const GRID: usize = 4;
const MIN_PER_CELL: usize = 5;
const MIN_COVERED_CELLS: usize = 12;

const ORB_FEATURES: i32 = 1000;
/// RTAB-Map's GFTT defaults (`GFTT/QualityLevel`, `GFTT/MinDistance`, `GFTT/BlockSize`,
/// no Harris; at most 1000 corners).
const GFTT_MAX_CORNERS: i32 = 1000;
const GFTT_QUALITY: f64 = 0.001;
const GFTT_MIN_DISTANCE_PX: f64 = 7.0;
const GFTT_BLOCK_SIZE: i32 = 3;
/// The patch an ORB descriptor of a GFTT corner is computed over (ORB's `patchSize`).
const ORB_PATCH_PX: f32 = 31.0;

const LOWE_RATIO: f32 = 0.8;
const PNP_REPROJECTION_PX: f32 = 2.0;
const PNP_ITERATIONS: i32 = 300;
const PNP_CONFIDENCE: f64 = 0.99;
const MIN_INLIERS: usize = 20;
const MAX_TRANSLATION_ERROR_M: f64 = 0.01;
const MAX_ROTATION_ERROR_DEG: f64 = 0.5;

/// One rendered frame and where its optical frame truly was.
struct Frame {
    t_ns: i64,
    world_from_optical: Isometry3<f64>,
    image: RgbdImage,
}

/// The frames of every anchor (`FRAME_OFFSETS` each), rendered once for both tests.
fn frames() -> &'static [Vec<Frame>] {
    static FRAMES: OnceLock<Vec<Vec<Frame>>> = OnceLock::new();
    FRAMES.get_or_init(|| {
        let cfg = sim::SimConfig::default();
        assert!(
            cfg.vineyard.growth_stage == 3.0 && cfg.vineyard.plant_variation == 0.0,
            "expected the default world at growth stage 3 with identical clones"
        );
        let sim = sim::Simulation::new(&cfg, "s1", 1).expect("scenario s1");
        let cam = RgbdCamera::new(&cfg.sensors.camera, &sim.world);
        let period_ns = (1e9 / cfg.sensors.camera.rate_hz).round() as i64;
        let mut rng = stream(1, "camera");
        ANCHORS_S
            .iter()
            .map(|&anchor_s| {
                let t0_ns = (anchor_s * 1e9) as i64;
                FRAME_OFFSETS
                    .iter()
                    .map(|&k| {
                        let t_ns = t0_ns + k * period_ns;
                        let speed = sim.trajectory.state(t_ns).velocity.norm();
                        assert!(
                            speed > 0.95 * cfg.robot.max_speed_mps,
                            "expected the robot at full speed ({} m/s) at t = {t_ns} ns, got {speed} m/s",
                            cfg.robot.max_speed_mps
                        );
                        let world_from_base = sim.trajectory.pose(t_ns);
                        Frame {
                            t_ns,
                            world_from_optical: world_from_base * cam.base_from_camera_optical(),
                            image: cam.render(&world_from_base, &mut rng),
                        }
                    })
                    .collect()
            })
            .collect()
    })
}

fn gray(image: &RgbdImage) -> Mat {
    let pixels: Vec<Vec3b> = image
        .rgb
        .chunks_exact(3)
        .map(|c| Vec3b::from([c[0], c[1], c[2]]))
        .collect();
    let rgb = Mat::new_rows_cols_with_data(image.height as i32, image.width as i32, &pixels)
        .expect("an RGB Mat over the frame");
    let mut gray = Mat::default();
    imgproc::cvt_color_def(&rgb, &mut gray, imgproc::COLOR_RGB2GRAY).expect("RGB to gray");
    gray
}

/// ORB with 1000 features, otherwise OpenCV's (and RTAB-Map's) defaults.
fn orb() -> Ptr<ORB> {
    ORB::create(
        ORB_FEATURES,
        1.2,
        8,
        31,
        0,
        2,
        ORB_ScoreType::HARRIS_SCORE,
        31,
        20,
    )
    .expect("ORB")
}

/// ORB's own keypoints and their descriptors.
fn orb_features(gray: &Mat) -> (Vector<KeyPoint>, Mat) {
    let mut keypoints = Vector::new();
    let mut descriptors = Mat::default();
    orb()
        .detect_and_compute_def(gray, &core::no_array(), &mut keypoints, &mut descriptors)
        .expect("ORB detect and compute");
    (keypoints, descriptors)
}

fn gftt_corners(gray: &Mat) -> Vector<Point2f> {
    let mut corners = Vector::new();
    imgproc::good_features_to_track(
        gray,
        &mut corners,
        GFTT_MAX_CORNERS,
        GFTT_QUALITY,
        GFTT_MIN_DISTANCE_PX,
        &core::no_array(),
        GFTT_BLOCK_SIZE,
        false,
        0.04,
    )
    .expect("GFTT");
    corners
}

/// GFTT's corners with ORB descriptors (ORB drops the few too near the border).
fn gftt_orb_features(gray: &Mat) -> (Vector<KeyPoint>, Mat) {
    let mut keypoints: Vector<KeyPoint> = gftt_corners(gray)
        .iter()
        .map(|p| KeyPoint::new_point(p, ORB_PATCH_PX, -1.0, 0.0, 0, -1).expect("keypoint"))
        .collect();
    let mut descriptors = Mat::default();
    orb()
        .compute(gray, &mut keypoints, &mut descriptors)
        .expect("ORB descriptors of GFTT corners");
    (keypoints, descriptors)
}

/// Keypoints per cell of a `GRID` x `GRID` grid over the image, row-major.
fn grid_counts(points: &[Point2f], width: usize, height: usize) -> Vec<usize> {
    let mut counts = vec![0; GRID * GRID];
    for p in points {
        let col = ((f64::from(p.x) / width as f64 * GRID as f64) as usize).min(GRID - 1);
        let row = ((f64::from(p.y) / height as f64 * GRID as f64) as usize).min(GRID - 1);
        counts[row * GRID + col] += 1;
    }
    counts
}

/// Prints the count and spread of `points`; returns what falls short, if anything (the
/// spread only if `spread_asserted`).
fn count_and_spread(
    name: &str,
    t_ns: i64,
    points: &[Point2f],
    image: &RgbdImage,
    spread_asserted: bool,
) -> Vec<String> {
    let counts = grid_counts(points, image.width, image.height);
    let covered = counts.iter().filter(|&&n| n >= MIN_PER_CELL).count();
    eprintln!(
        "t = {:.4} s {name}: {} features, {covered}/{} cells with >= {MIN_PER_CELL}, per cell \
         (rows top to bottom) {:?}",
        t_ns as f64 * 1e-9,
        points.len(),
        GRID * GRID,
        counts.chunks(GRID).collect::<Vec<_>>()
    );
    let mut failures = Vec::new();
    if points.len() < MIN_FEATURES {
        failures.push(format!(
            "expected >= {MIN_FEATURES} {name} features at t = {t_ns} ns, got {}",
            points.len()
        ));
    }
    if spread_asserted && covered < MIN_COVERED_CELLS {
        failures.push(format!(
            "expected {name} features (>= {MIN_PER_CELL} each) in >= {MIN_COVERED_CELLS} of the \
             {} cells of a {GRID}x{GRID} grid at t = {t_ns} ns, got {covered}: {counts:?}",
            GRID * GRID
        ));
    }
    failures
}

/// Every frame's ORB and GFTT features against the bounds; the spread of ORB's only if
/// `orb_spread_asserted`.
fn features_per_frame(orb_spread_asserted: bool) -> Vec<String> {
    let mut failures = Vec::new();
    for frame in frames().iter().flatten() {
        let gray = gray(&frame.image);
        let (keypoints, _) = orb_features(&gray);
        let orb_points: Vec<Point2f> = keypoints.iter().map(|k| k.pt()).collect();
        failures.extend(count_and_spread(
            "ORB",
            frame.t_ns,
            &orb_points,
            &frame.image,
            orb_spread_asserted,
        ));
        let corners = gftt_corners(&gray).to_vec();
        failures.extend(count_and_spread(
            "GFTT",
            frame.t_ns,
            &corners,
            &frame.image,
            true,
        ));
    }
    failures
}

#[test]
fn orb_and_gftt_find_several_hundred_features_and_gftt_spreads_them() {
    let failures = features_per_frame(false);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// OpenCV's ORB keeps its 1000 best corners by Harris score over the whole image, with no
/// bucketing by cell, so the ground's texture has to compete with leaves against the sky.
/// It used to lose everywhere (6 to 9 of 16 cells covered, no keypoint below the canopy).
/// The ground's sunlit clods, stones and their shadows now have about the canopy's contrast
/// (mean 8x8-pixel grey-level σ 35–39 in image rows 300..480, the canopy's 32–36 in rows
/// 120..240) and take keypoints all over it: 12 to 15 of the 16 cells are covered (the two
/// middle cells of the top row hold only sky and wires; the far ground at the sides, partly
/// in the vines' shade, is the weakest).
#[test]
fn orb_features_are_well_spread() {
    let failures = features_per_frame(true);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The point seen at `pt` in `image`'s optical frame, from the depth of the pixel it falls
/// in; `None` where depth is invalid (0).
fn back_project(image: &RgbdImage, pt: Point2f) -> Option<Point3<f64>> {
    let (u, v) = (pt.x.round() as usize, pt.y.round() as usize);
    if u >= image.width || v >= image.height {
        return None;
    }
    let z = f64::from(image.depth_m[v * image.width + u]);
    if z <= 0.0 {
        return None;
    }
    let [fx, fy, cx, cy] = image.intrinsics;
    Some(Point3::new(
        z * (f64::from(pt.x) - cx) / fx,
        z * (f64::from(pt.y) - cy) / fy,
        z,
    ))
}

/// Outcome of PnP from frame `a` to frame `b`.
struct Pnp {
    matches: usize,
    with_depth: usize,
    inliers: usize,
    b_from_a: Isometry3<f64>,
}

/// Matches (Hamming brute force, Lowe's ratio), frame `a`'s matched keypoints with valid
/// depth in `a`'s optical frame against their pixels in `b`, RANSAC PnP (EPnP on minimal
/// samples, then Levenberg-Marquardt on the inliers): `camera_b_from_camera_a`.
fn pnp(a: &RgbdImage, b: &RgbdImage, features: fn(&Mat) -> (Vector<KeyPoint>, Mat)) -> Pnp {
    let (kp_a, des_a) = features(&gray(a));
    let (kp_b, des_b) = features(&gray(b));
    let matcher = BFMatcher::new(NORM_HAMMING, false).expect("BFMatcher");
    let mut knn: Vector<Vector<DMatch>> = Vector::new();
    matcher
        .knn_train_match_def(&des_a, &des_b, &mut knn, 2)
        .expect("k-NN match");
    let good: Vec<DMatch> = knn
        .iter()
        .filter_map(|pair| match (pair.get(0), pair.get(1)) {
            (Ok(best), Ok(second)) => {
                (best.distance < LOWE_RATIO * second.distance).then_some(best)
            }
            (Ok(only), Err(_)) => Some(only),
            _ => None,
        })
        .collect();
    let mut object: Vector<Point3f> = Vector::new();
    let mut pixels: Vector<Point2f> = Vector::new();
    for m in &good {
        let pa = kp_a.get(m.query_idx as usize).expect("query keypoint").pt();
        let pb = kp_b.get(m.train_idx as usize).expect("train keypoint").pt();
        if let Some(p) = back_project(a, pa) {
            object.push(Point3f::new(p.x as f32, p.y as f32, p.z as f32));
            pixels.push(pb);
        }
    }
    let [fx, fy, cx, cy] = a.intrinsics;
    let k = Mat::from_slice_2d(&[[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]).expect("K");
    let (mut rvec, mut tvec, mut inliers) = (Mat::default(), Mat::default(), Mat::default());
    let solved = calib3d::solve_pnp_ransac(
        &object,
        &pixels,
        &k,
        &core::no_array(),
        &mut rvec,
        &mut tvec,
        false,
        PNP_ITERATIONS,
        PNP_REPROJECTION_PX,
        PNP_CONFIDENCE,
        &mut inliers,
        calib3d::SOLVEPNP_ITERATIVE,
    )
    .expect("solvePnPRansac");
    assert!(
        solved,
        "expected solvePnPRansac to find a pose from {} points",
        object.len()
    );
    let vec3 = |m: &Mat| {
        Vector3::new(
            *m.at::<f64>(0).expect("x"),
            *m.at::<f64>(1).expect("y"),
            *m.at::<f64>(2).expect("z"),
        )
    };
    Pnp {
        matches: good.len(),
        with_depth: object.len(),
        inliers: inliers.rows() as usize,
        b_from_a: Isometry3::from_parts(
            Translation3::from(vec3(&tvec)),
            UnitQuaternion::from_scaled_axis(vec3(&rvec)),
        ),
    }
}

/// Prints PnP's figures from `a` to `b`; returns what falls short, if anything.
fn pnp_against_truth(
    name: &str,
    a: &Frame,
    b: &Frame,
    features: fn(&Mat) -> (Vector<KeyPoint>, Mat),
) -> Vec<String> {
    let result = pnp(&a.image, &b.image, features);
    let truth = b.world_from_optical.inverse() * a.world_from_optical;
    let error = truth.inverse() * result.b_from_a;
    let translation_error_m = error.translation.vector.norm();
    let rotation_error_deg = error.rotation.angle().to_degrees();
    eprintln!(
        "{name} t = {:.4} s -> {:.4} s: moved {:.1} mm, {:.3}°; {} matches, {} with depth, \
         {} inliers; error {:.2} mm, {:.3}°",
        a.t_ns as f64 * 1e-9,
        b.t_ns as f64 * 1e-9,
        truth.translation.vector.norm() * 1e3,
        truth.rotation.angle().to_degrees(),
        result.matches,
        result.with_depth,
        result.inliers,
        translation_error_m * 1e3,
        rotation_error_deg
    );
    let pair = format!("{name} between frames at {} ns and {} ns", a.t_ns, b.t_ns);
    let mut failures = Vec::new();
    if result.inliers < MIN_INLIERS {
        failures.push(format!(
            "expected >= {MIN_INLIERS} PnP inliers {pair}, got {}",
            result.inliers
        ));
    }
    if translation_error_m >= MAX_TRANSLATION_ERROR_M {
        failures.push(format!(
            "expected a translation error < {MAX_TRANSLATION_ERROR_M} m {pair}, got \
             {translation_error_m} m"
        ));
    }
    if rotation_error_deg >= MAX_ROTATION_ERROR_DEG {
        failures.push(format!(
            "expected a rotation error < {MAX_ROTATION_ERROR_DEG}° {pair}, got \
             {rotation_error_deg}°"
        ));
    }
    failures
}

#[test]
fn pnp_between_frames_recovers_the_true_relative_pose() {
    let (mut failures, mut orb_only) = (Vec::new(), Vec::new());
    for group in frames() {
        for b in &group[1..] {
            failures.extend(pnp_against_truth(
                "GFTT/ORB",
                &group[0],
                b,
                gftt_orb_features,
            ));
            orb_only.extend(pnp_against_truth("ORB", &group[0], b, orb_features));
        }
    }
    eprintln!(
        "ORB keypoints (printed, not asserted): {} pair(s) short of the bounds",
        orb_only.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
