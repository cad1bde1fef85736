//! The sensors' configuration: ground truth, IMU, wheel odometry, 3D lidar, the two 2D
//! scanners and the RGB-D camera, each with its rate, mount and noise.

use super::*;

/// Which noise a sensor adds: `typical` (a datasheet's figures) or `none` (the paper's
/// noise-free Gazebo sensors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum NoiseProfile {
    #[default]
    Typical,
    None,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct SensorsConfig {
    pub ground_truth: GroundTruthConfig,
    pub imu: ImuConfig,
    pub wheel_odometry: WheelOdometryConfig,
    pub lidar: LidarConfig,
    pub scan2d_front: Scan2dConfig,
    pub scan2d_back: Scan2dConfig,
    pub camera: CameraConfig,
    /// A GNSS receiver on a mast (issue 47; `sensors::gnss`): none unless a world or a
    /// sweep's axes choose a profile; left out of a resolved world without one.
    #[serde(default, skip_serializing_if = "GnssConfig::is_absent")]
    pub gnss: GnssConfig,
}

pub use crate::sensors::gnss::{ErrorModel, GnssConfig, GnssProfile};

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundTruthConfig {
    pub rate_hz: f64,
}

impl Default for GroundTruthConfig {
    fn default() -> Self {
        Self { rate_hz: 100.0 }
    }
}

/// IMU noise as a datasheet (or Kalibr's `imu.yaml`) states it: continuous-time densities.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuConfig {
    pub rate_hz: f64,
    pub mount: Mount,
    pub mount_error: MountError,
    pub noise: NoiseProfile,
    /// Accelerometer white noise density, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// Accelerometer bias random walk, m/s³/√Hz.
    pub accel_bias_random_walk: f64,
    /// Gyroscope white noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Gyroscope bias random walk, rad/s²/√Hz.
    pub gyro_bias_random_walk: f64,
    /// Standard deviation of the turn-on bias, per axis.
    pub accel_bias_initial: f64,
    pub gyro_bias_initial: f64,
    /// `false` (ours): rates and specific force only, as a bare MEMS IMU. `true`: each
    /// sample also carries the IMU's orientation in the world frame, the true one without
    /// noise, as Gazebo's `gazebo_ros_imu_sensor` publishes it (`sensor_imu.xacro` in
    /// LCAS/bacchus_lcas, branch `liosam`: `initialOrientationAsReference` false, noise 0);
    /// LIO-SAM reads it.
    pub reports_orientation: bool,
    /// The reported orientation's error (issue 47: the absolute heading GNSS fusion needs),
    /// one first-order Gauss–Markov process per axis: its σ about roll and pitch and about
    /// yaw, rad, and its correlation time, s. 0 (the default): the true orientation, as the
    /// paper's Gazebo IMU gives it. An AHRS (Xsens MTi-30, user manual MT0605P §4.3): roll
    /// and pitch 0.5° RMS dynamic (0.0087 rad), yaw 1.0° RMS where the magnetic field is
    /// homogeneous and mapped (0.0175 rad); the same manual has the estimates "degrade
    /// slowly (typically a degree every minute)" on the gyros alone, whence τ = 60 s.
    pub orientation_roll_pitch_sigma_rad: f64,
    pub orientation_yaw_sigma_rad: f64,
    pub orientation_tau_s: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        // A typical MEMS IMU (figures in the range of an Xsens MTi-100 / ADIS16448).
        Self {
            rate_hz: 200.0,
            mount: Mount::at(0.0, 0.0, 0.6),
            mount_error: MountError::default(),
            noise: NoiseProfile::Typical,
            accel_noise_density: 2.0e-3,
            accel_bias_random_walk: 3.0e-4,
            gyro_noise_density: 1.7e-4,
            gyro_bias_random_walk: 2.0e-5,
            accel_bias_initial: 0.02,
            gyro_bias_initial: 1.0e-3,
            reports_orientation: false,
            orientation_roll_pitch_sigma_rad: 0.0,
            orientation_yaw_sigma_rad: 0.0,
            orientation_tau_s: 60.0,
        }
    }
}

/// Wheel odometry: velocities measured by the wheel encoders and integrated in the plane.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct WheelOdometryConfig {
    pub rate_hz: f64,
    pub noise: NoiseProfile,
    /// Relative error of the wheel radius (a constant scale error on speed).
    pub scale_error: f64,
    /// Relative error of the effective track width (a constant scale error on yaw rate).
    pub yaw_scale_error: f64,
    /// Standard deviation of the relative slip on flat ground.
    pub slip_sigma: f64,
    /// Extra relative slip per unit of terrain slope (rise over run) under the robot.
    pub slip_per_slope: f64,
    /// Yaw-rate noise density, rad/s/√Hz, that grows like slip with the slope.
    pub yaw_rate_noise_density: f64,
    /// This sensor's stamps against the IMU's clock, the systems' reference (and ground
    /// truth's): a measurement taken at t is stamped t + offset and becomes available then,
    /// as a sensor on another clock, or stamped on arrival, gives it. Nanoseconds, 0 to 1 s.
    pub clock_offset_ns: i64,
}

impl Default for WheelOdometryConfig {
    fn default() -> Self {
        Self {
            rate_hz: 50.0,
            noise: NoiseProfile::Typical,
            scale_error: 0.01,
            yaw_scale_error: 0.02,
            slip_sigma: 0.01,
            slip_per_slope: 0.5,
            yaw_rate_noise_density: 0.002,
            clock_offset_ns: 0,
        }
    }
}

/// A spinning multi-beam lidar (defaults: Velodyne VLP-16).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarConfig {
    pub rate_hz: f64,
    pub mount: Mount,
    pub mount_error: MountError,
    pub rings: usize,
    pub min_elevation_deg: f64,
    pub max_elevation_deg: f64,
    /// Firings per revolution.
    pub columns: usize,
    pub min_range_m: f64,
    pub max_range_m: f64,
    pub noise: NoiseProfile,
    pub range_sigma_m: f64,
    /// `false` (ours): every column fires at its own time within the sweep, from the pose
    /// the robot has then, and its points carry that time (a real VLP-16). `true`: the
    /// whole sweep is taken at one instant from the pose at its stamp and every point's
    /// time is 0, as Gazebo's `gpu_ray` sensor renders it (`sensor_velodyne_vlp16.xacro`
    /// in LCAS/bacchus_lcas, branch `liosam`): nothing to deskew, and nothing deskews.
    pub instant_sweep: bool,
    /// Full divergence angles of each beam, horizontal (along the scan) and vertical, mrad:
    /// the beam's footprint, sampled by sub-rays where it may straddle an edge, with mixed
    /// pixels where two surfaces in it are too close in range to part
    /// ([`crate::sensors::lidar_footprint`]). `[0, 0]` (the default): thin rays.
    pub beam_divergence_mrad: [f64; 2],
    /// With a divergence: surfaces in one footprint closer in range than this give one
    /// echo at a range between them, m.
    pub echo_separation_m: f64,
    /// With a divergence: the echo reported when a footprint gives several, `strongest`
    /// (the most energy) or `last` (the farthest).
    pub return_mode: crate::sensors::lidar_footprint::ReturnMode,
    /// This sensor's stamps against the IMU's clock, the systems' reference (and ground
    /// truth's): a measurement taken at t is stamped t + offset and becomes available then,
    /// as a sensor on another clock, or stamped on arrival, gives it. Nanoseconds, 0 to 1 s.
    pub clock_offset_ns: i64,
}

impl Default for LidarConfig {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            mount: Mount::at(0.0, 0.0, 1.56),
            mount_error: MountError::default(),
            rings: 16,
            min_elevation_deg: -15.0,
            max_elevation_deg: 15.0,
            columns: 1800,
            min_range_m: 0.9,
            max_range_m: 130.0,
            noise: NoiseProfile::Typical,
            range_sigma_m: 0.008,
            instant_sweep: false,
            beam_divergence_mrad: [0.0, 0.0],
            echo_separation_m: 1.0,
            return_mode: crate::sensors::lidar_footprint::ReturnMode::Strongest,
            clock_offset_ns: 0,
        }
    }
}

/// A planar scanning lidar (defaults: the paper's front and back 2D lidars).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scan2dConfig {
    pub rate_hz: f64,
    /// `None`: the default placement of its side (front: (0.65, 0, 0.35) m looking
    /// forward; back: (-0.65, 0, 0.35) m looking backwards).
    pub mount: Option<Mount>,
    pub mount_error: MountError,
    pub samples: usize,
    pub angle_min_rad: f64,
    pub angle_max_rad: f64,
    pub min_range_m: f64,
    pub max_range_m: f64,
    pub noise: NoiseProfile,
    pub range_sigma_m: f64,
    /// This sensor's stamps against the IMU's clock, the systems' reference (and ground
    /// truth's): a measurement taken at t is stamped t + offset and becomes available then,
    /// as a sensor on another clock, or stamped on arrival, gives it. Nanoseconds, 0 to 1 s.
    pub clock_offset_ns: i64,
}

impl Default for Scan2dConfig {
    fn default() -> Self {
        Self {
            rate_hz: 40.0,
            mount: None,
            mount_error: MountError::default(),
            samples: 720,
            angle_min_rad: -2.18,
            angle_max_rad: 2.36,
            min_range_m: 0.1,
            max_range_m: 30.0,
            noise: NoiseProfile::Typical,
            range_sigma_m: 0.01,
            clock_offset_ns: 0,
        }
    }
}

/// An RGB-D camera (defaults: a Kinect v2 with its depth registered to a 640x480 colour
/// image, as the paper's simulated camera). See [`crate::camera`] for the frames and the
/// noise model.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraConfig {
    pub rate_hz: f64,
    /// `base_from_camera` of the camera body: x forward, y left, z up (like every other
    /// sensor). The image's optical frame (z forward, x right, y down) is rotated from it;
    /// see [`crate::camera::RgbdCamera::base_from_camera_optical`].
    pub mount: Mount,
    pub mount_error: MountError,
    pub width: usize,
    pub height: usize,
    /// Horizontal field of view of the pinhole; square pixels, principal point at the centre.
    pub hfov_deg: f64,
    /// Returns nearer than this are invalid (0).
    pub min_depth_m: f64,
    /// Returns farther than this are invalid (0).
    pub max_depth_m: f64,
    /// `typical`: axial depth noise after Fankhauser et al. 2015, edge dropout, colour noise;
    /// `none`: exact depth and colour (the paper's Gazebo camera).
    pub noise: NoiseProfile,
    /// σ of the zero-mean noise on each colour channel, in 8-bit levels.
    pub rgb_sigma: f64,
    /// A pixel whose depth differs from a 4-neighbour's by more than this fraction of its
    /// own depth is invalidated (time-of-flight "flying pixels"); 0 disables.
    pub edge_dropout_ratio: f64,
    /// Sun direction: elevation above the horizon and azimuth counter-clockwise from world x.
    pub sun_elevation_deg: f64,
    pub sun_azimuth_deg: f64,
    /// Cast shadows from the sun (a shadow map of the vine block, built once).
    pub shadows: bool,
    /// Visibility samples per pixel (coverage anti-aliasing, as the 4x MSAA of the paper's
    /// Gazebo camera): 4 (the standard rotated-grid pattern, the default) or 8 (the
    /// standard 8x pattern); each triangle seen by a pixel's samples is shaded once and
    /// weighted by its coverage. 1: one sample at the pixel centre (no anti-aliasing, the
    /// renderer before). See [`crate::camera`].
    pub antialias_samples: usize,
    /// Band-limit the plants' procedural materials to the pixel footprint (detail finer
    /// than the footprint fades to its mean, thin stripes are box-filtered); `false`:
    /// point-sampled materials, the renderer before. The ground's textures are mip-mapped
    /// either way.
    pub filter_materials: bool,
    /// `None` (ours): depth is rendered with the colour image and registered to it. An
    /// angle: depth comes from a second pinhole of this horizontal field of view at the same
    /// optical centre and resolution (the paper's Gazebo Kinect v2: a 70° `depth` sensor
    /// beside an 84.1° `camera` sensor, both on `kinect2_link`, `sensor_kinect_v2.xacro`
    /// in LCAS/bacchus_lcas, branch `liosam`), delivered as `depth_registration` says.
    pub depth_hfov_deg: Option<f64>,
    /// With `depth_hfov_deg`: the depth camera's own image, `[width, height]` (square
    /// pixels; its vertical field of view follows). `None`: the colour image's size.
    /// Another size needs `depth_registration = "registered"`.
    pub depth_size: Option<[usize; 2]>,
    /// With `depth_hfov_deg`: the depth camera's optical centre in the colour camera's
    /// optical frame (x right, y down, z forward; axes parallel), metres. `[0, 0, 0]`: the
    /// same centre. Non-zero needs `depth_registration = "registered"`: each depth pixel is
    /// then reprojected into the colour image, and what the colour camera sees but the depth
    /// camera does not (behind an edge, from its other viewpoint) has no depth (0).
    pub depth_offset_m: [f64; 3],
    /// With `depth_hfov_deg`: `stretched` delivers the depth image pixel for pixel as the
    /// colour image's, under the colour intrinsics, as the paper's systems read it
    /// (`rgbd_sync` pairs the two topics by time, nothing registers them); `registered`
    /// reprojects it into the colour camera (pixels outside the depth camera's view: 0).
    pub depth_registration: DepthRegistration,
    /// With `depth_hfov_deg`: visibility samples per pixel of the depth camera's own pass (1,
    /// 4 or 8, as `antialias_samples`). 1, the default: one sample at the pixel centre, as
    /// Gazebo's depth camera renders into a float texture made without multisampling
    /// (`DepthCamera::CreateDepthTexture` in gazebo-classic `gazebo/rendering/
    /// DepthCamera.cc` passes no FSAA level, where the colour camera's render texture
    /// asks for 4x).
    pub depth_antialias_samples: usize,
    /// `None` (ours): colour is rendered to the horizon. A distance: the colour camera's
    /// far clip plane (optical-axis depth); beyond it the background shows (Gazebo's
    /// `<clip><far>10.0</far>` of the Kinect's `camera` sensor).
    pub colour_far_clip_m: Option<f64>,
    /// This sensor's stamps against the IMU's clock, the systems' reference (and ground
    /// truth's): a measurement taken at t is stamped t + offset and becomes available then,
    /// as a sensor on another clock, or stamped on arrival, gives it. Nanoseconds, 0 to 1 s.
    pub clock_offset_ns: i64,
    /// What shows where no surface is seen: `"sky"` (ours: a sky gradient and a distant
    /// tree line) or a colour `[r, g, b]` (sRGB, 0-1), uniform (Gazebo's
    /// `<scene><background>0.7 0.7 0.7` in `vineyard_stage0_riseholme_vertical.world`,
    /// which has no sky).
    pub background: Background,
    /// The colour lens's distortion, OpenCV's `plumb_bob` `[k1, k2, p1, p2, k3]` (Brown-Conrady:
    /// radial `1 + k1 r² + k2 r⁴ + k3 r⁶` and tangential `p1`, `p2`, on normalized image
    /// coordinates). Zero (the default): a rectified image, as a driver's `image_rect`
    /// topic gives it. Non-zero: the raw image of such a lens, the frame's `[fx, fy, cx,
    /// cy]` its camera matrix, the coefficients in the rig's camera intrinsics (`k1`...`k3`)
    /// and in `camera_info`'s `d`; the registered depth is registered to the raw colour
    /// image. A Kinect v2's colour camera, from the calibrations of eight units published
    /// with iai_kinect2 (`kinect2_bridge/data/*/calib_color.yaml`, read): k1 0.027 to
    /// 0.083, k2 -0.145 to -0.039, k3 0.001 to 0.070, |p1|, |p2| under 0.003; up to 3-5
    /// pixels at a 640-pixel-wide image's corners.
    #[serde(skip_serializing_if = "no_distortion")]
    pub distortion: [f64; 5],
}

fn no_distortion(d: &[f64; 5]) -> bool {
    *d == [0.0; 5]
}

/// The camera's background: the sky, or one colour.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum Background {
    /// `"sky"`.
    Sky(SkyTag),
    /// `[r, g, b]`, sRGB in 0-1.
    Rgb([f64; 3]),
}

/// The one word `"sky"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SkyTag {
    Sky,
}

impl Default for Background {
    fn default() -> Self {
        Background::Sky(SkyTag::Sky)
    }
}

/// How a separately rendered depth image is paired with the colour image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum DepthRegistration {
    /// Depth pixel (u, v) handed over as colour pixel (u, v): the paper's pairing.
    #[default]
    Stretched,
    /// Depth reprojected into the colour camera: pixel (u, v) of both sees the same ray.
    Registered,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            rate_hz: 30.0,
            mount: Mount::at(0.5, 0.0, 0.66),
            mount_error: MountError::default(),
            width: 640,
            height: 480,
            hfov_deg: 70.0,
            min_depth_m: 0.5,
            max_depth_m: 8.0,
            noise: NoiseProfile::Typical,
            rgb_sigma: 2.0,
            edge_dropout_ratio: 0.05,
            sun_elevation_deg: 50.0,
            sun_azimuth_deg: 30.0,
            shadows: true,
            antialias_samples: 4,
            depth_antialias_samples: 1,
            filter_materials: true,
            depth_hfov_deg: None,
            depth_size: None,
            depth_offset_m: [0.0; 3],
            depth_registration: DepthRegistration::Stretched,
            colour_far_clip_m: None,
            clock_offset_ns: 0,
            background: Background::default(),
            distortion: [0.0; 5],
        }
    }
}

/// Which end of the base a 2D scanner sits at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Front,
    Back,
}

impl Scan2dConfig {
    /// The configured mount, or the default placement of `side`.
    pub fn mount_for(&self, side: Side) -> Mount {
        self.mount.unwrap_or(match side {
            Side::Front => Mount::at(0.65, 0.0, 0.35),
            Side::Back => Mount {
                xyz_m: [-0.65, 0.0, 0.35],
                rpy_deg: [0.0, 0.0, 180.0],
            },
        })
    }
}

/// How far a sensor really sits from its `mount`: the error its extrinsic calibration left.
/// The sensor measures from where it really is; every system is told `mount` (the rig, the
/// recording's transforms), as a robot's software only knows its calibration. The error is
/// drawn once per run from the run's seed (its own stream per sensor, so switching it on
/// changes no other draw): a translation along and a rotation about each axis of the
/// sensor's frame, each zero-mean normal. Zero (the default): the sensor sits at `mount`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct MountError {
    /// σ of the offset along each axis, m.
    pub sigma_m: f64,
    /// σ of the rotation about each axis, degrees.
    pub sigma_deg: f64,
}

impl MountError {
    pub fn is_zero(&self) -> bool {
        self.sigma_m == 0.0 && self.sigma_deg == 0.0
    }

    /// `nominal_from_true` for the sensor `tag` in the run of `seed`: where the sensor
    /// really sits, in the frame it is believed to have.
    pub fn draw(&self, seed: u64, tag: &str) -> nalgebra::Isometry3<f64> {
        use rand_distr::{Distribution as _, Normal};
        let mut rng = crate::rng::stream(seed, &format!("mount_error/{tag}"));
        let unit = Normal::new(0.0, 1.0).expect("unit normal");
        let mut draw3 = |sigma: f64| {
            let v: [f64; 3] = std::array::from_fn(|_| sigma * unit.sample(&mut rng));
            nalgebra::Vector3::from(v)
        };
        let t = draw3(self.sigma_m);
        let r = draw3(self.sigma_deg.to_radians());
        nalgebra::Isometry3::new(t, r)
    }

    /// `mount` moved by the error drawn for `tag` under `seed` (unchanged when zero).
    pub fn place(&self, mount: Mount, seed: u64, tag: &str) -> Mount {
        if self.is_zero() {
            return mount;
        }
        let placed = mount.base_from_sensor() * self.draw(seed, tag);
        let (r, p, y) = placed.rotation.euler_angles();
        Mount {
            xyz_m: placed.translation.vector.into(),
            rpy_deg: [r, p, y].map(f64::to_degrees),
        }
    }
}
