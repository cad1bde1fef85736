//! ORB repeatability and matching score between camera frames 0.1, 0.3 and 0.6 m apart
//! along a lane, with the renderer's anti-aliasing and material filtering off (the renderer
//! before) and on, side by side. Run: `cargo bench -p vinebench-sim --bench
//! orb_repeatability`.
//!
//! Definitions after Mikolajczyk et al. 2005, "A comparison of affine region detectors"
//! (IJCV 65) and Mikolajczyk & Schmid 2005, "A performance evaluation of local descriptors"
//! (PAMI 27), with ground truth from the renderer's exact depth and the known poses instead
//! of a homography: a keypoint of frame A is back-projected with A's depth and reprojected
//! into B through the true relative pose. It is in the frames' common part when it lands
//! inside B and is visible there (B's depth at that pixel within 5 % of its reprojected
//! depth: not occluded); likewise B's keypoints into A.
//! - repeatability: keypoints of A in the common part with a keypoint of B within 2.5 px of
//!   their reprojection (each keypoint of B used once), over the smaller of the two
//!   common-part counts;
//! - matching score: descriptor matches (mutual nearest neighbours in Hamming distance)
//!   whose keypoint in B lies within 2.5 px of the reprojection of A's, over the same
//!   smaller count.
//!
//! The detector is OpenCV's ORB with ORB-SLAM2's settings as far as plain `cv::ORB` has
//! them: 1000 features, scale factor 1.2, 8 levels, FAST threshold 20 (ORB-SLAM2's
//! `iniThFAST`; its fallback to 7 in empty cells and its grid distribution are ORB-SLAM2's
//! own extractor, not OpenCV's). Frames: the default world (growth stage 3) along S1's first
//! lane at full speed, five anchors, default sensor noise on the colour images ORB sees.

use nalgebra::{Isometry3, Point3};
use opencv::core::{self, DMatch, KeyPoint, Mat, NORM_HAMMING, Ptr, Vec3b, Vector};
use opencv::features2d::{BFMatcher, ORB, ORB_ScoreType};
use opencv::imgproc;
use opencv::prelude::*;
use sim::camera::{RgbdCamera, RgbdImage};
use sim::config::{CameraConfig, NoiseProfile};
use sim::rng::stream;

const ANCHORS_S: [f64; 5] = [20.0, 22.5, 25.0, 27.5, 30.0];
const BASELINES_M: [f64; 3] = [0.1, 0.3, 0.6];
const PIXEL_TOLERANCE: f64 = 2.5;
const VISIBLE_DEPTH_RATIO: f64 = 0.05;

fn orb() -> Ptr<ORB> {
    ORB::create(1000, 1.2, 8, 31, 0, 2, ORB_ScoreType::HARRIS_SCORE, 31, 20).expect("ORB")
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

/// A frame: what ORB sees (with sensor noise), the exact depth and the optical pose.
struct View {
    keypoints: Vec<[f64; 2]>,
    descriptors: Mat,
    exact: RgbdImage,
    world_from_optical: Isometry3<f64>,
}

fn view(noisy: &RgbdCamera, exact: &RgbdCamera, world_from_base: &Isometry3<f64>) -> View {
    let image = noisy.render(world_from_base, &mut stream(1, "orb-bench"));
    let mut keypoints = Vector::<KeyPoint>::new();
    let mut descriptors = Mat::default();
    orb()
        .detect_and_compute_def(
            &gray(&image),
            &core::no_array(),
            &mut keypoints,
            &mut descriptors,
        )
        .expect("ORB");
    View {
        keypoints: keypoints
            .iter()
            .map(|k| [f64::from(k.pt().x), f64::from(k.pt().y)])
            .collect(),
        descriptors,
        exact: exact.render(world_from_base, &mut stream(1, "orb-bench")),
        world_from_optical: world_from_base * noisy.base_from_camera_optical(),
    }
}

/// Depth of `image` at the pixel nearest `p` (0: none or outside).
fn depth_at(image: &RgbdImage, p: [f64; 2]) -> f64 {
    let (u, v) = (p[0].round(), p[1].round());
    if u < 0.0 || v < 0.0 || u >= image.width as f64 || v >= image.height as f64 {
        return 0.0;
    }
    f64::from(image.depth_m[v as usize * image.width + u as usize])
}

/// Keypoint `p` of `a` in `b`'s image, if it is in the frames' common part.
fn reproject(a: &View, b: &View, p: [f64; 2]) -> Option<[f64; 2]> {
    let z = depth_at(&a.exact, p);
    if z == 0.0 {
        return None;
    }
    let [fx, fy, cx, cy] = a.exact.intrinsics;
    let in_a = Point3::new(z * (p[0] - cx) / fx, z * (p[1] - cy) / fy, z);
    let in_b = b.world_from_optical.inverse() * (a.world_from_optical * in_a);
    if in_b.z <= 0.0 {
        return None;
    }
    let q = [fx * in_b.x / in_b.z + cx, fy * in_b.y / in_b.z + cy];
    let zb = depth_at(&b.exact, q);
    ((zb - in_b.z).abs() <= VISIBLE_DEPTH_RATIO * in_b.z).then_some(q)
}

/// Repeatability and matching score from `a` to `b`, and the common-part counts.
fn scores(a: &View, b: &View) -> (f64, f64, usize, usize) {
    let into_b: Vec<Option<[f64; 2]>> = a.keypoints.iter().map(|&p| reproject(a, b, p)).collect();
    let n_a = into_b.iter().flatten().count();
    let n_b = b
        .keypoints
        .iter()
        .filter(|&&p| reproject(b, a, p).is_some())
        .count();
    let near = |q: [f64; 2], p: [f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]) <= PIXEL_TOLERANCE;
    // Repeated: greedily, each keypoint of B at most once.
    let mut used = vec![false; b.keypoints.len()];
    let mut repeated = 0;
    for q in into_b.iter().flatten() {
        let best = b
            .keypoints
            .iter()
            .enumerate()
            .filter(|&(j, &p)| !used[j] && near(*q, p))
            .min_by(|(_, p1), (_, p2)| {
                let d = |p: &[f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]);
                d(p1).total_cmp(&d(p2))
            });
        if let Some((j, _)) = best {
            used[j] = true;
            repeated += 1;
        }
    }
    // Mutual nearest neighbours in descriptor space.
    let matcher = BFMatcher::new(NORM_HAMMING, true).expect("BFMatcher");
    let mut matches = Vector::<DMatch>::new();
    matcher
        .train_match_def(&a.descriptors, &b.descriptors, &mut matches)
        .expect("match");
    let correct = matches
        .iter()
        .filter(|m| {
            into_b[m.query_idx as usize].is_some_and(|q| near(q, b.keypoints[m.train_idx as usize]))
        })
        .count();
    let common = n_a.min(n_b).max(1) as f64;
    (repeated as f64 / common, correct as f64 / common, n_a, n_b)
}

fn main() {
    let cfg = sim::SimConfig::default();
    let sim = sim::Simulation::new(&cfg, "s1", 1).expect("scenario s1");
    let full_speed = 0.95 * cfg.robot.max_speed_mps;
    let renderers = [
        (
            "anti-aliasing off, point-sampled materials (before)",
            1,
            false,
        ),
        ("4x anti-aliasing, point-sampled materials", 4, false),
        ("4x anti-aliasing, filtered materials (default)", 4, true),
    ];
    println!(
        "ORB (OpenCV {}.{}: 1000 features, scale 1.2, 8 levels, FAST 20) between frames along \
         S1's first lane, mean over {} anchors; correspondences within {PIXEL_TOLERANCE} px",
        core::CV_VERSION_MAJOR,
        core::CV_VERSION_MINOR,
        ANCHORS_S.len()
    );
    println!(
        "| renderer | baseline | repeatability | matching score | keypoints in common part (A, B) |"
    );
    println!("|---|---|---|---|---|");
    for (name, samples, filter) in renderers {
        let camera = CameraConfig {
            antialias_samples: samples,
            filter_materials: filter,
            ..cfg.sensors.camera.clone()
        };
        let noisy = RgbdCamera::new(&camera, &sim.world);
        let exact = RgbdCamera::new(
            &CameraConfig {
                noise: NoiseProfile::None,
                ..camera.clone()
            },
            &sim.world,
        );
        for baseline in BASELINES_M {
            let (mut rep, mut ms, mut na, mut nb) = (0.0, 0.0, 0, 0);
            for anchor in ANCHORS_S {
                let t_a = (anchor * 1e9) as i64;
                let t_b = t_a + (baseline / cfg.robot.max_speed_mps * 1e9) as i64;
                for t in [t_a, t_b] {
                    let speed = sim.trajectory.state(t).velocity.norm();
                    assert!(
                        speed > full_speed,
                        "expected the robot at full speed at {t} ns, got {speed} m/s"
                    );
                }
                let a = view(&noisy, &exact, &sim.trajectory.pose(t_a));
                let b = view(&noisy, &exact, &sim.trajectory.pose(t_b));
                let (r, m, n_a, n_b) = scores(&a, &b);
                rep += r;
                ms += m;
                na += n_a;
                nb += n_b;
            }
            let k = ANCHORS_S.len() as f64;
            println!(
                "| {name} | {baseline:.1} m | {:.1} % | {:.1} % | {:.0}, {:.0} |",
                100.0 * rep / k,
                100.0 * ms / k,
                na as f64 / k,
                nb as f64 / k
            );
        }
    }
}
