//! The plugin with GPS priors (`Optimizer/PriorsIgnored`): what it asks for, how it is set
//! up, what it makes of broken fixes, and a drive whose drifting odometry the priors
//! correct.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2};
use plugin_api::{GnssStatus, SensorSpec};

use super::*;

const PRIORS_ON: &str = "[Optimizer]\nPriorsIgnored = false\n";
const MS: i64 = 1_000_000;

fn sensor(name: &str, kind: SensorKind, xyz: [f64; 3], intrinsics: &[(&str, f64)]) -> SensorSpec {
    SensorSpec {
        name: name.into(),
        kind,
        rate_hz: 10.0,
        base_from_sensor_xyz: xyz,
        base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
        intrinsics: intrinsics
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect(),
        noise: Default::default(),
    }
}

/// A 32 x 24 camera, the front scan, an IMU, wheels and, with `receiver`, an antenna on a
/// 1.7 m mast.
fn rig(receiver: bool) -> Rig {
    let mut sensors = vec![
        sensor(
            "camera",
            SensorKind::Rgbd,
            [0.3, 0.0, 0.5],
            &[
                ("fx", 30.0),
                ("fy", 30.0),
                ("cx", 16.0),
                ("cy", 12.0),
                ("width", 32.0),
                ("height", 24.0),
            ],
        ),
        sensor("scan_front", SensorKind::Scan2d, [0.4, 0.0, 0.35], &[]),
        sensor("imu", SensorKind::Imu, [0.0, 0.0, 0.2], &[]),
        sensor("wheels", SensorKind::WheelOdometry, [0.0; 3], &[]),
    ];
    if receiver {
        sensors.push(sensor("gnss", SensorKind::Gnss, [0.0, 0.0, 1.7], &[]));
    }
    Rig { sensors }
}

fn fix(stamp_ns: i64, enu: [f64; 3]) -> GnssMessage {
    GnssMessage {
        stamp_ns,
        status: GnssStatus::Fixed,
        satellites: 14,
        position_enu_m: enu,
        covariance_enu_m2: [7e-5, 0.0, 0.0, 0.0, 7e-5, 0.0, 0.0, 0.0, 2.25e-4],
        latitude_deg: 53.27,
        longitude_deg: -0.52,
        altitude_m: enu[2],
        hdop: 0.8,
    }
}

#[test]
fn the_receiver_is_asked_for_only_with_priors_on() {
    // Guards requirements_for: RTAB-Map's default (PriorsIgnored = true) asks for what it
    // always did; `false` adds the GNSS receiver; the name is RTAB-Map's.
    let off = Rtabmap::requirements_for("").expect("defaults");
    assert_eq!(off, Rtabmap::requirements());
    assert!(!off.sensors.contains(&SensorKind::Gnss));
    let ignored = Rtabmap::requirements_for("[Optimizer]\nPriorsIgnored = true\n").expect("true");
    assert!(!ignored.sensors.contains(&SensorKind::Gnss));
    let on = Rtabmap::requirements_for(PRIORS_ON).expect("false");
    assert!(on.sensors.contains(&SensorKind::Gnss));
    assert!(on.sensors.contains(&SensorKind::Rgbd) && on.can_localize);
    let err = Rtabmap::requirements_for("[Optimizer]\npriors_ignored = false\n")
        .expect_err("not RTAB-Map's name");
    assert!(err.0.contains("priors_ignored"), "{err}");
}

#[test]
fn gps_is_set_up_only_with_priors_on_and_a_receiver() {
    // Guards new and localize: the default ignores a receiver; priors on without one run
    // without GPS; with one, the mast is the lever arm; localisation never takes priors.
    let off = Rtabmap::new("", &rig(true)).expect("defaults");
    assert!(off.gps.is_none());
    let without = Rtabmap::new(PRIORS_ON, &rig(false)).expect("no receiver");
    assert!(without.gps.is_none());
    let mut with = Rtabmap::new(PRIORS_ON, &rig(true)).expect("receiver");
    let gps = with.gps.as_mut().expect("gps");
    let prior = gps.prior(
        0,
        &Gps {
            stamp_ns: 0,
            east_north_m: Vector2::new(5.0, 6.0),
            altitude_m: 10.0,
            error_m: 0.01,
        },
        &Isometry3::identity(),
        &Isometry3::identity(),
        false,
    );
    assert!((prior.position - Vector3::new(0.0, 0.0, 8.3)).norm() < 1e-12);
}

#[test]
fn broken_fixes_are_events_never_errors_and_ignored_by_default() {
    // Guards on_gnss: with priors on, no fix, a NaN position, a zero covariance and a NaN
    // altitude are refused with gnss_rejected events in the output; with the default
    // (PriorsIgnored = true) every fix is ignored, no event, nothing kept.
    let good = fix(5 * MS, [1.0, 2.0, 3.0]);
    let broken = [
        GnssMessage {
            status: GnssStatus::NoFix,
            ..good
        },
        GnssMessage {
            position_enu_m: [f64::NAN, 2.0, 3.0],
            ..good
        },
        GnssMessage {
            covariance_enu_m2: [0.0; 9],
            ..good
        },
        GnssMessage {
            altitude_m: f64::NAN,
            ..good
        },
    ];
    let mut on = Rtabmap::new(PRIORS_ON, &rig(true)).expect("receiver");
    let mut off = Rtabmap::new("", &rig(true)).expect("defaults");
    for m in broken.iter().chain([&good]) {
        assert_eq!(on.on_gnss(m), Ok(None));
        assert_eq!(off.on_gnss(m), Ok(None));
    }
    let out = on.finish().expect("finish");
    assert_eq!(out.events.len(), 4, "{:?}", out.events);
    assert!(
        out.events
            .iter()
            .all(|e| e.kind == EventKind::GnssRejected && e.detail.starts_with("rtabmap:"))
    );
    assert!(off.finish().expect("finish").events.is_empty());
}

/// The truth of a drive: 0.8 m/s, 25 s straight, a 180° headland turn in 8 s, 25 s back,
/// in ENU from (40, 15) heading 1.1 rad; `map_from_base` every 10 ms.
fn drive() -> Vec<(i64, Isometry3<f64>)> {
    let mut pose = Isometry3::from_parts(
        Translation3::new(40.0, 15.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 1.1),
    );
    let dt = 0.01;
    (0..5800)
        .map(|k| {
            let stamp = k as i64 * 10 * MS;
            let out = (stamp, pose);
            let t = k as f64 * dt;
            let yaw_rate = yaw_rate(t);
            pose *= Isometry3::from_parts(
                Translation3::new(0.8 * dt, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rate * dt),
            );
            out
        })
        .collect()
}

fn yaw_rate(t: f64) -> f64 {
    if (25.0..33.0).contains(&t) {
        std::f64::consts::PI / 8.0
    } else {
        0.0
    }
}

/// What a drive through the plugin gave.
struct Run {
    /// The output trajectory's worst and mean horizontal error against the truth in the
    /// frame it should be in (the fixes', east and north from the first fix taken, with
    /// priors; the start's without), m.
    worst: f64,
    mean: f64,
    /// Its largest height off the (level) truth, m.
    worst_z: f64,
    /// Locations with a GPS prior.
    priors: usize,
    trajectory: Vec<Pose>,
}

/// Runs the drive through the plugin: wheels at 50 Hz, a gyro biased by 0.005 rad/s at
/// 100 Hz, empty scans at 10 Hz, blank camera frames at 2 Hz and, with `fix_delay`, fixes
/// of the antenna at 5 Hz arriving that many 10 ms steps after their epoch (before it if
/// negative, as if the frames came late), with 2 cm of noise.
fn run(config: &str, fix_delay: Option<i64>) -> Run {
    let truth = drive();
    let mut system = Rtabmap::new(config, &rig(true)).expect("system");
    let ranges = [f32::INFINITY; 16];
    let (rgb, depth) = (vec![0u8; 32 * 24 * 3], vec![0f32; 32 * 24]);
    for (k, (stamp, _)) in truth.iter().enumerate() {
        let (stamp, t) = (*stamp, k as f64 * 0.01);
        system
            .on_imu(&Imu {
                stamp_ns: stamp,
                accel_mps2: [0.0, 0.0, 9.81],
                gyro_rps: [0.0, 0.0, yaw_rate(t) + 0.005],
                orientation_xyzw: [0.0; 4],
            })
            .expect("imu");
        if k % 2 == 0 {
            system
                .on_wheel_odometry(&WheelOdometry {
                    stamp_ns: stamp,
                    linear_mps: 0.8,
                    angular_rps: yaw_rate(t),
                    odom_from_base: Pose::new(stamp, &Isometry3::identity()),
                })
                .expect("wheels");
        }
        if k % 10 == 0 {
            system
                .on_laser_scan(&LaserScan {
                    stamp_ns: stamp,
                    sensor: "scan_front",
                    angle_min_rad: -1.5,
                    angle_increment_rad: 0.2,
                    time_increment_s: 0.0,
                    range_min_m: 0.1,
                    range_max_m: 20.0,
                    ranges_m: &ranges,
                    intensities: &[],
                })
                .expect("scan");
        }
        if k % 50 == 0 {
            system
                .on_rgbd(&RgbdFrame {
                    stamp_ns: stamp,
                    sensor: "camera",
                    width: 32,
                    height: 24,
                    rgb: &rgb,
                    depth_m: &depth,
                    intrinsics: [30.0, 30.0, 16.0, 12.0],
                })
                .expect("frame");
        }
        if let Some(delay) = fix_delay
            && (k as i64 - delay).rem_euclid(20) == 0
            && let Some(&(epoch, then)) = truth.get((k as i64 - delay) as usize)
        {
            let antenna = then * Point3::new(0.0, 0.0, 1.7);
            let noise = 0.02 * Vector3::new((k as f64).sin(), (k as f64 * 0.3).cos(), 0.0);
            system
                .on_gnss(&fix(epoch, (antenna.coords + noise).into()))
                .expect("gnss");
        }
    }
    let origin = system.gps.as_ref().and_then(|g| g.origin());
    let priors = system.gps.as_ref().map_or(0, |g| g.priors());
    let out = system.finish().expect("finish");
    let frame_from_truth = match origin {
        Some(o) => Isometry3::translation(-o.x, -o.y, 0.0),
        None => truth[0].1.inverse(),
    };
    let errors: Vec<Vector3<f64>> = out
        .trajectory
        .iter()
        .map(|p| {
            let k = (p.stamp_ns / (10 * MS)) as usize;
            Vector3::from(p.translation) - (frame_from_truth * truth[k].1).translation.vector
        })
        .collect();
    assert!(errors.len() > 500, "{} poses", errors.len());
    let worst = errors.iter().map(|e| e.xy().norm()).fold(0.0, f64::max);
    let mean = errors.iter().map(|e| e.xy().norm()).sum::<f64>() / errors.len() as f64;
    let worst_z = errors.iter().map(|e| e.z.abs()).fold(0.0, f64::max);
    eprintln!(
        "{config:?}: {priors} priors, worst {worst:.3} m, mean {mean:.3} m, z within {worst_z:.3} m"
    );
    Run {
        worst,
        mean,
        worst_z,
        priors,
        trajectory: out.trajectory,
    }
}

#[test]
fn gps_priors_correct_a_drifting_drive_and_change_nothing_by_default() {
    // Guards the whole path (on_gnss, the fix each location takes, the lever arm, the
    // priors and the full optimisations): a gyro bias of 0.005 rad/s turns the odometry by
    // 0.29 rad over the drive and puts it metres off; with the priors every output pose
    // lies within decimetres of the truth in the fixes' frame, 1.1 rad from odometry's,
    // level, the mast removed; in 3D and planar (`Reg/Force3DoF`), and with the fixes
    // ahead of the frames (a location then takes its fix at once). The default ignores the
    // same fixes: its output is the odometry's, as without them.
    let ignored = run("", Some(5));
    assert_eq!(ignored.priors, 0);
    assert!(
        ignored.worst > 2.5,
        "odometry alone drifts: {} m",
        ignored.worst
    );
    let without = run("", None);
    assert_eq!(
        ignored.trajectory, without.trajectory,
        "the default ignores the fixes"
    );
    let planar = format!("{PRIORS_ON}[icp]\nattitude_gain = 0.0\n");
    for (config, delay) in [(PRIORS_ON, 5), (&planar, 5), (PRIORS_ON, -5)] {
        let r = run(config, Some(delay));
        assert!(
            r.priors >= 55,
            "{config:?}: a prior per location: {}",
            r.priors
        );
        assert!(
            r.worst < 0.3 && r.mean < 0.1 && r.worst_z < 0.1,
            "{config:?}: worst {} m, mean {} m, z within {} m",
            r.worst,
            r.mean,
            r.worst_z
        );
    }
}
