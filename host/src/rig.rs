//! The sensor rig handed to plugins, described from the simulator's configuration.

use std::collections::BTreeMap;

use plugin_api::{Rig, SensorKind, SensorSpec};
use sim::config::{NoiseProfile, Scan2dConfig, Side, SimConfig};

fn spec(name: &str, kind: SensorKind, rate_hz: f64) -> SensorSpec {
    SensorSpec {
        name: name.to_owned(),
        kind,
        rate_hz,
        base_from_sensor_xyz: [0.0; 3],
        base_from_sensor_xyzw: [0.0, 0.0, 0.0, 1.0],
        intrinsics: BTreeMap::new(),
        noise: BTreeMap::new(),
    }
}

fn figures(pairs: &[(&str, f64)]) -> BTreeMap<String, f64> {
    pairs.iter().map(|&(k, v)| (k.to_owned(), v)).collect()
}

fn noise_or_zero(profile: NoiseProfile, pairs: &[(&str, f64)]) -> BTreeMap<String, f64> {
    match profile {
        NoiseProfile::Typical => figures(pairs),
        NoiseProfile::None => pairs.iter().map(|&(k, _)| (k.to_owned(), 0.0)).collect(),
    }
}

fn scan2d(name: &str, cfg: &Scan2dConfig, side: Side) -> SensorSpec {
    SensorSpec {
        intrinsics: figures(&[
            ("samples", cfg.samples as f64),
            ("angle_min_rad", cfg.angle_min_rad),
            ("angle_max_rad", cfg.angle_max_rad),
            ("min_range_m", cfg.min_range_m),
            ("max_range_m", cfg.max_range_m),
        ]),
        noise: noise_or_zero(cfg.noise, &[("range_sigma_m", cfg.range_sigma_m)]),
        ..spec(name, SensorKind::Scan2d, cfg.rate_hz)
    }
    .with_mount(&cfg.mount_for(side).base_from_sensor())
}

/// The rig a plugin that asks for `sensors` is told: [`rig`], and the GNSS receiver where
/// it asks for one and the world has one (revision 5: so that a plugin built before the
/// kind existed never meets it in its rig).
pub fn rig_for(cfg: &SimConfig, sensors: &[SensorKind]) -> Rig {
    let mut rig = rig(cfg);
    let g = &cfg.sensors.gnss;
    if sensors.contains(&SensorKind::Gnss) && !g.is_absent() {
        let [x, y, z] = g.mount_xyz_m;
        let [lat, lon, h] = g.datum;
        // The error model as the datasheets give it: what a fix of each status reports as
        // its own σ (also in every message's covariance).
        let model = |prefix: &str, m: &sim::config::ErrorModel| {
            [
                (format!("{prefix}_sigma_h_m"), m.sigma_h_m),
                (format!("{prefix}_sigma_v_m"), m.sigma_v_m),
            ]
        };
        let mut noise = BTreeMap::new();
        let single = match g.profile {
            sim::config::GnssProfile::Consumer => &g.consumer,
            _ => &g.single,
        };
        for (k, v) in model("fixed", &g.fixed)
            .into_iter()
            .chain(model("float", &g.float))
            .chain(model("single", single))
        {
            noise.insert(k, v);
        }
        rig.sensors.push(
            SensorSpec {
                intrinsics: figures(&[
                    ("datum_latitude_deg", lat),
                    ("datum_longitude_deg", lon),
                    ("datum_altitude_m", h),
                    ("latency_s", g.latency_s),
                    (
                        "rtk",
                        f64::from(u8::from(g.profile == sim::config::GnssProfile::Rtk)),
                    ),
                ]),
                noise,
                ..spec("gnss", SensorKind::Gnss, g.rate_hz)
            }
            .with_mount(&nalgebra::Isometry3::translation(x, y, z)),
        );
    }
    rig
}

/// Every sensor the simulator can stream, with its datasheet figures, but the GNSS
/// receiver ([`rig_for`]).
pub fn rig(cfg: &SimConfig) -> Rig {
    let s = &cfg.sensors;
    let imu = SensorSpec {
        noise: noise_or_zero(
            s.imu.noise,
            &[
                ("accel_noise_density", s.imu.accel_noise_density),
                ("accel_bias_random_walk", s.imu.accel_bias_random_walk),
                ("gyro_noise_density", s.imu.gyro_noise_density),
                ("gyro_bias_random_walk", s.imu.gyro_bias_random_walk),
                // The reported orientation's error (0 where it reports none or exactly).
                (
                    "orientation_roll_pitch_sigma_rad",
                    s.imu.orientation_roll_pitch_sigma_rad,
                ),
                ("orientation_yaw_sigma_rad", s.imu.orientation_yaw_sigma_rad),
            ],
        ),
        intrinsics: figures(&[(
            "reports_orientation",
            f64::from(u8::from(s.imu.reports_orientation)),
        )]),
        ..spec("imu", SensorKind::Imu, s.imu.rate_hz)
    }
    .with_mount(&s.imu.mount.base_from_sensor());
    let odom = SensorSpec {
        intrinsics: figures(&[
            ("wheel_x_m", cfg.robot.wheel_x_m),
            ("wheel_y_m", cfg.robot.wheel_y_m),
            ("wheel_radius_m", cfg.robot.wheel_radius_m),
        ]),
        noise: noise_or_zero(
            s.wheel_odometry.noise,
            &[
                ("scale_error", s.wheel_odometry.scale_error),
                ("slip_sigma", s.wheel_odometry.slip_sigma),
                (
                    "yaw_rate_noise_density",
                    s.wheel_odometry.yaw_rate_noise_density,
                ),
            ],
        ),
        ..spec("odom", SensorKind::WheelOdometry, s.wheel_odometry.rate_hz)
    };
    let lidar = SensorSpec {
        intrinsics: figures(&[
            ("rings", s.lidar.rings as f64),
            ("columns", s.lidar.columns as f64),
            ("min_elevation_deg", s.lidar.min_elevation_deg),
            ("max_elevation_deg", s.lidar.max_elevation_deg),
            ("min_range_m", s.lidar.min_range_m),
            ("max_range_m", s.lidar.max_range_m),
        ]),
        noise: noise_or_zero(s.lidar.noise, &[("range_sigma_m", s.lidar.range_sigma_m)]),
        ..spec("lidar", SensorKind::Lidar, s.lidar.rate_hz)
    }
    .with_mount(&s.lidar.mount.base_from_sensor());
    let cam = &s.camera;
    let k = sim::camera::Intrinsics::from_config(cam);
    let mut camera_figures = vec![
        ("width", cam.width as f64),
        ("height", cam.height as f64),
        ("fx", k.fx),
        ("fy", k.fy),
        ("cx", k.cx),
        ("cy", k.cy),
        ("min_depth_m", cam.min_depth_m),
        ("max_depth_m", cam.max_depth_m),
    ];
    if cam.distortion != [0.0; 5] {
        // A lens's raw image: its plumb_bob coefficients (absent: a rectified image).
        camera_figures.extend(
            ["k1", "k2", "p1", "p2", "k3"]
                .into_iter()
                .zip(cam.distortion),
        );
    }
    let camera = SensorSpec {
        intrinsics: figures(&camera_figures),
        noise: noise_or_zero(cam.noise, &[("rgb_sigma", cam.rgb_sigma)]),
        ..spec("camera", SensorKind::Rgbd, cam.rate_hz)
    }
    // The intrinsics apply in the optical frame (z forward, x right, y down).
    .with_mount(&(cam.mount.base_from_sensor() * sim::camera::camera_from_optical()));
    Rig {
        sensors: vec![
            camera,
            imu,
            odom,
            lidar,
            scan2d("scan_front", &s.scan2d_front, Side::Front),
            scan2d("scan_back", &s.scan2d_back, Side::Back),
        ],
    }
}
