//! The RTAB-Map-style plugin on the simulator's own data.

use nalgebra::Isometry3;
use rtabmap::config::ScanOdometryConfig;
use rtabmap::scan_odometry::{ScanOdometry, planar};
use sim::sensors::Message;
use sim::{SensorSet, SimConfig, Simulation};
use slam_common::scan2d::points_from_ranges;

#[test]
fn scan_odometry_debug() {
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s0", 0).expect("S0 builds");
    let base_from_scan = config
        .sensors
        .scan2d_front
        .mount_for(sim::config::Side::Front)
        .base_from_sensor();
    let mut cfg = ScanOdometryConfig::default();
    if let Ok(v) = std::env::var("RTAB_ICP") {
        let v: Vec<f64> = v.split(',').map(|x| x.parse().unwrap()).collect();
        cfg.icp.coarse_correspondence_m = v[0];
        cfg.icp.max_correspondence_m = v[1];
        cfg.icp.robust_kernel_m = v[2];
        cfg.key_scan_distance_m = v[3];
        cfg.max_range_m = v[4];
        cfg.max_correction_m = v[5];
    }
    let mut odo = ScanOdometry::new(cfg, &base_from_scan);
    let set = SensorSet {
        wheel_odometry: true,
        scan2d: true,
        ..SensorSet::default()
    };
    let mut prev: Option<(Isometry3<f64>, nalgebra::Isometry2<f64>)> = None;
    let mut n = 0;
    let mut first: Option<(Isometry3<f64>, nalgebra::Isometry2<f64>)> = None;
    let mut last = None;
    for m in sim.stream(set) {
        match m {
            Message::WheelOdometry(w) => odo.on_wheels(w.stamp_ns, &w.odom_from_base),
            Message::Scan2d(s) if s.side.name() == "scan_front" => {
                let points = points_from_ranges(
                    f64::from(s.angle_min_rad),
                    f64::from(s.angle_increment_rad),
                    &s.ranges_m,
                    f64::from(s.range_min_m),
                    f64::from(s.range_max_m),
                );
                let Some(step) = odo.on_scan(s.stamp_ns, &points) else {
                    continue;
                };
                let gt = sim.trajectory.pose(s.stamp_ns);
                if first.is_none() {
                    first = Some((gt, step.odom_from_base));
                }
                if let Some((pgt, pest)) = prev {
                    let dgt = planar(&(pgt.inverse() * gt));
                    let dest = pest.inverse() * step.odom_from_base;
                    let err = (dgt.inverse() * dest).translation.vector.norm();
                    if err > 0.01 || n % 200 == 0 {
                        eprintln!(
                            "t {:.3} gt step {:.4} est step {:.4} err {:.4} registered {} degenerate {} pts {}",
                            s.stamp_ns as f64 * 1e-9,
                            dgt.translation.vector.norm(),
                            dest.translation.vector.norm(),
                            err,
                            step.registered,
                            step.degenerate,
                            points.len()
                        );
                    }
                }
                n += 1;
                prev = Some((gt, step.odom_from_base));
                last = Some((gt, step.odom_from_base));
            }
            _ => {}
        }
    }
    let ((g0, e0), (g1, e1)) = (first.unwrap(), last.unwrap());
    let dgt = planar(&(g0.inverse() * g1));
    let dest = e0.inverse() * e1;
    eprintln!(
        "total gt {:?} est {:?} final error {:.3}",
        dgt.translation.vector,
        dest.translation.vector,
        (dgt.inverse() * dest).translation.vector.norm()
    );
}

#[test]
fn visual_odometry_debug() {
    use rtabmap::config::{FeatureConfig, VisualOdometryConfig};
    use rtabmap::features::{Image, extract};
    use rtabmap::visual_odometry::VisualOdometry;
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s0", 0).expect("S0 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let base_from_camera = cam.base_from_camera_optical();
    let k = sim::camera::Intrinsics::from_config(&config.sensors.camera);
    let mut vo = VisualOdometry::new(
        VisualOdometryConfig::default(),
        [k.fx, k.fy, k.cx, k.cy],
        config.sensors.camera.width,
        config.sensors.camera.height,
        base_from_camera,
    );
    let mut rng = sim::rng::stream(0, "camera");
    let mut first = None;
    for i in 0..90 {
        let t = 5_000_000_000 + i * 33_333_333;
        let gt = sim.trajectory.pose(t);
        let image = cam.render(&gt, &mut rng);
        let img = Image {
            width: image.width,
            height: image.height,
            rgb: &image.rgb,
            depth_m: &image.depth_m,
            intrinsics: image.intrinsics,
        };
        let f = extract(&img, &FeatureConfig::default()).unwrap();
        let with_depth = f.points.iter().filter(|p| p.is_some()).count();
        let tr = vo.process(t, &f).unwrap();
        let gt_cam = gt * base_from_camera;
        let first_gt = *first.get_or_insert(gt_cam);
        let truth = first_gt.inverse() * gt_cam;
        let est = match &tr {
            rtabmap::visual_odometry::Tracking::Ok {
                odom_from_camera, ..
            }
            | rtabmap::visual_odometry::Tracking::Started { odom_from_camera } => {
                base_from_camera.inverse() * odom_from_camera
            }
            rtabmap::visual_odometry::Tracking::Lost { guess, .. } => {
                base_from_camera.inverse() * guess
            }
        };
        eprintln!(
            "{i} feats {} depth {} map {} {:?} err {:.4}",
            f.len(),
            with_depth,
            vo.map_size(),
            match tr {
                rtabmap::visual_odometry::Tracking::Ok {
                    inliers, keyframe, ..
                } => format!("ok {inliers} kf {keyframe}"),
                rtabmap::visual_odometry::Tracking::Lost { inliers, .. } =>
                    format!("lost {inliers}"),
                _ => "start".into(),
            },
            (truth.inverse() * est).translation.vector.norm()
        );
    }
}

#[test]
fn matching_debug() {
    use rtabmap::config::FeatureConfig;
    use rtabmap::features::{Image, extract};
    let config = SimConfig::default();
    let sim = Simulation::new(&config, "s0", 0).expect("S0 builds");
    let cam = sim::camera::RgbdCamera::new(&config.sensors.camera, &sim.world);
    let mut rng = sim::rng::stream(0, "camera");
    let fs: Vec<_> = [5_000_000_000i64, 5_033_333_333]
        .iter()
        .map(|&t| {
            let image = cam.render(&sim.trajectory.pose(t), &mut rng);
            let img = Image {
                width: image.width,
                height: image.height,
                rgb: &image.rgb,
                depth_m: &image.depth_m,
                intrinsics: image.intrinsics,
            };
            let f = extract(&img, &FeatureConfig::default()).unwrap();
            let depths: Vec<f32> = image.depth_m.iter().copied().filter(|d| *d > 0.0).collect();
            eprintln!("valid depth px {} of {}", depths.len(), image.depth_m.len());
            f
        })
        .collect();
    let m = rtabmap::matching::match_descriptors(&fs[0].descriptors, &fs[1].descriptors, None, 0.8);
    eprintln!("matches {}", m.len());
    for x in m.iter().take(10) {
        eprintln!(
            "{:?} {:?} {:?}",
            x, fs[0].pixels[x.query], fs[1].pixels[x.train]
        );
    }
    eprintln!("desc0 {:?}", &fs[0].descriptors[0][..8]);
}
