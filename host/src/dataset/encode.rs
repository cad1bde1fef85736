//! Simulator messages to ROS 2 messages in CDR (field order as in [`super::schemas`]).

use nalgebra::{Isometry3, Vector3};
use sim::sensors::gnss::{FixStatus, GnssFix};
use sim::sensors::{GroundTruth, ImuSample, LaserScan, LidarScan, RgbdFrame, WheelOdometry};

use super::EPOCH_NS;
use super::cdr::CdrWriter;
use super::topics::{
    BASE_FRAME, CAMERA_FRAME, GNSS_FRAME, IMU_FRAME, LIDAR_FRAME, MAP_FRAME, ODOM_FRAME,
};

/// `sensor_msgs/PointField` datatypes.
pub(crate) const UINT16: u8 = 4;
pub(crate) const FLOAT32: u8 = 7;

/// The point layout of `/points`: name, byte offset, datatype (count 1 each); two bytes of
/// padding after `ring` keep `time` aligned.
pub(crate) const POINT_FIELDS: [(&str, u32, u8); 6] = [
    ("x", 0, FLOAT32),
    ("y", 4, FLOAT32),
    ("z", 8, FLOAT32),
    ("intensity", 12, FLOAT32),
    ("ring", 16, UINT16),
    ("time", 20, FLOAT32),
];
pub(crate) const POINT_STEP: usize = 24;

/// `sensor_msgs/Image` encodings (REP 118 for depth): colour and depth in metres.
pub(crate) const RGB8: &str = "rgb8";
pub(crate) const DEPTH_32FC1: &str = "32FC1";
/// The camera's lens model: `plumb_bob` with all five coefficients zero (a rectified image).
pub(crate) const DISTORTION_MODEL: &str = "plumb_bob";

/// `std_msgs/Header` with the stamp offset by [`EPOCH_NS`].
pub(crate) fn header(w: &mut CdrWriter, stamp_ns: i64, frame_id: &str) {
    let t = stamp_ns + EPOCH_NS;
    w.i32(t.div_euclid(1_000_000_000) as i32);
    w.u32(t.rem_euclid(1_000_000_000) as u32);
    w.string(frame_id);
}

pub(crate) fn vector3(w: &mut CdrWriter, v: &Vector3<f64>) {
    w.f64(v.x);
    w.f64(v.y);
    w.f64(v.z);
}

/// `geometry_msgs/Pose` or `Transform`: translation, then the quaternion as (x, y, z, w).
pub(crate) fn pose(w: &mut CdrWriter, iso: &Isometry3<f64>) {
    vector3(w, &iso.translation.vector);
    let q = iso.rotation.coords; // (i, j, k, w)
    for v in [q.x, q.y, q.z, q.w] {
        w.f64(v);
    }
}

fn zeros(w: &mut CdrWriter, n: usize) {
    for _ in 0..n {
        w.f64(0.0);
    }
}

/// `sensor_msgs/NavSatFix` of a GNSS epoch, in the antenna's frame: the RTK statuses as
/// GBAS_FIX (ground-based augmentation, as u-blox's ROS driver reports RTK), single as FIX,
/// without a fix NO_FIX with NaN coordinates; the covariance diagonal, east-north-up.
pub(crate) fn nav_sat_fix(m: &GnssFix) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(160);
    header(&mut w, m.stamp_ns, GNSS_FRAME);
    let status: i8 = match m.status {
        FixStatus::None => -1,
        FixStatus::Single => 0,
        FixStatus::Float | FixStatus::Fixed => 2,
    };
    w.u8(status as u8);
    w.u16(1); // SERVICE_GPS
    let [lat, lon, alt] = m.geodetic.unwrap_or([f64::NAN; 3]);
    for v in [lat, lon, alt] {
        w.f64(v);
    }
    let [ve, vn, vu] = m.variance_enu_m2;
    for v in [ve, 0.0, 0.0, 0.0, vn, 0.0, 0.0, 0.0, vu] {
        w.f64(v);
    }
    // COVARIANCE_TYPE_DIAGONAL_KNOWN, or UNKNOWN without a fix.
    w.u8(if m.position_enu_m.is_some() { 2 } else { 0 });
    w.finish()
}

/// `vinebench_msgs/GnssEnu` of a GNSS epoch (see `schemas`): NaN for what is absent.
pub(crate) fn gnss_enu(m: &GnssFix) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(160);
    header(&mut w, m.stamp_ns, GNSS_FRAME);
    w.u8(match m.status {
        FixStatus::None => 0,
        FixStatus::Single => 1,
        FixStatus::Float => 2,
        FixStatus::Fixed => 3,
    });
    w.u32(m.satellites as u32);
    vector3(
        &mut w,
        &m.position_enu_m.unwrap_or(Vector3::repeat(f64::NAN)),
    );
    for v in m.variance_enu_m2 {
        w.f64(v);
    }
    w.f64(m.hdop.unwrap_or(f64::NAN));
    w.f64(m.vdop.unwrap_or(f64::NAN));
    w.i32(m.latency_ns.div_euclid(1_000_000_000) as i32);
    w.u32(m.latency_ns.rem_euclid(1_000_000_000) as u32);
    w.finish()
}

pub(crate) fn imu(m: &ImuSample) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(360);
    header(&mut w, m.stamp_ns, IMU_FRAME);
    match m.orientation {
        Some(q) => {
            for v in [q.i, q.j, q.k, q.w] {
                w.f64(v);
            }
            zeros(&mut w, 9); // known exactly
        }
        None => pose_orientation_unknown(&mut w),
    }
    vector3(&mut w, &m.gyro_rps);
    zeros(&mut w, 9);
    vector3(&mut w, &m.accel_mps2);
    zeros(&mut w, 9);
    w.finish()
}

/// An identity orientation with `covariance[0] = -1`: "no orientation estimate" (REP 145).
fn pose_orientation_unknown(w: &mut CdrWriter) {
    for v in [0.0, 0.0, 0.0, 1.0] {
        w.f64(v);
    }
    w.f64(-1.0);
    zeros(w, 8);
}

pub(crate) fn point_cloud(m: &LidarScan) -> Vec<u8> {
    let n = m.points.len();
    let mut w = CdrWriter::with_capacity(n * POINT_STEP + 256);
    header(&mut w, m.stamp_ns, LIDAR_FRAME);
    w.u32(1); // height: an unordered cloud
    w.u32(n as u32);
    w.seq_len(POINT_FIELDS.len());
    for (name, offset, datatype) in POINT_FIELDS {
        w.string(name);
        w.u32(offset);
        w.u8(datatype);
        w.u32(1);
    }
    w.bool(false); // is_bigendian
    w.u32(POINT_STEP as u32);
    w.u32((n * POINT_STEP) as u32);
    let mut data = Vec::with_capacity(n * POINT_STEP);
    for p in &m.points {
        for v in [p.x, p.y, p.z, p.intensity] {
            data.extend_from_slice(&v.to_le_bytes());
        }
        data.extend_from_slice(&p.ring.to_le_bytes());
        data.extend_from_slice(&[0, 0]);
        data.extend_from_slice(&p.time_s.to_le_bytes());
    }
    w.bytes(&data);
    w.bool(true); // is_dense: the simulator emits returns only, no NaN points
    w.finish()
}

pub(crate) fn laser_scan(m: &LaserScan, frame_id: &str, scan_time_s: f32) -> Vec<u8> {
    let n = m.ranges_m.len();
    let mut w = CdrWriter::with_capacity(8 * n + 128);
    header(&mut w, m.stamp_ns, frame_id);
    let angle_max = m.angle_min_rad + m.angle_increment_rad * n.saturating_sub(1) as f32;
    for v in [
        m.angle_min_rad,
        angle_max,
        m.angle_increment_rad,
        m.time_increment_s,
        scan_time_s,
        m.range_min_m,
        m.range_max_m,
    ] {
        w.f32(v);
    }
    w.f32_seq(&m.ranges_m);
    w.f32_seq(&m.intensities);
    w.finish()
}

pub(crate) fn odometry(m: &WheelOdometry) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(720);
    header(&mut w, m.stamp_ns, ODOM_FRAME);
    w.string(BASE_FRAME);
    pose(&mut w, &m.odom_from_base);
    zeros(&mut w, 36);
    vector3(&mut w, &Vector3::new(m.linear_mps, 0.0, 0.0));
    vector3(&mut w, &Vector3::new(0.0, 0.0, m.angular_rps));
    zeros(&mut w, 36);
    w.finish()
}

pub(crate) fn pose_stamped(m: &GroundTruth) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(80);
    header(&mut w, m.stamp_ns, MAP_FRAME);
    pose(&mut w, &m.world_from_base);
    w.finish()
}

pub(crate) fn twist_stamped(m: &GroundTruth) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(80);
    header(&mut w, m.stamp_ns, MAP_FRAME);
    vector3(&mut w, &m.velocity_in_world);
    vector3(&mut w, &m.omega_in_base);
    w.finish()
}

/// `tf2_msgs/TFMessage` of `base_link → frame` transforms (`base_from_sensor`), at `stamp_ns`.
pub(crate) fn tf_message(stamp_ns: i64, transforms: &[(&str, Isometry3<f64>)]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(128 * transforms.len());
    w.seq_len(transforms.len());
    for (child, base_from_sensor) in transforms {
        header(&mut w, stamp_ns, BASE_FRAME);
        w.string(child);
        pose(&mut w, base_from_sensor);
    }
    w.finish()
}

/// `sensor_msgs/Image` header fields up to the data: rows of `step` bytes, little-endian.
fn image_header(w: &mut CdrWriter, m: &RgbdFrame, encoding: &str, bytes_per_pixel: usize) {
    header(w, m.stamp_ns, CAMERA_FRAME);
    w.u32(m.image.height as u32);
    w.u32(m.image.width as u32);
    w.string(encoding);
    w.u8(0); // is_bigendian
    w.u32((m.image.width * bytes_per_pixel) as u32);
}

/// The colour image, `rgb8`.
pub(crate) fn color_image(m: &RgbdFrame) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(m.image.rgb.len() + 128);
    image_header(&mut w, m, RGB8, 3);
    w.bytes(&m.image.rgb);
    w.finish()
}

/// The registered depth image, `32FC1` in metres, each value's bits as the camera gave them
/// (invalid pixels included).
pub(crate) fn depth_image(m: &RgbdFrame) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(4 * m.image.depth_m.len() + 128);
    image_header(&mut w, m, DEPTH_32FC1, 4);
    w.f32_as_bytes(&m.image.depth_m);
    w.finish()
}

/// `sensor_msgs/CameraInfo` of a frame: its camera matrix as `k` and `p`, the lens's
/// `plumb_bob` coefficients as `d` (zero: a rectified image), `r` identity (a monocular
/// camera), no binning, the full image as region of interest.
pub(crate) fn camera_info(m: &RgbdFrame, distortion: &[f64; 5]) -> Vec<u8> {
    let [fx, fy, cx, cy] = m.image.intrinsics;
    let mut w = CdrWriter::with_capacity(512);
    header(&mut w, m.stamp_ns, CAMERA_FRAME);
    w.u32(m.image.height as u32);
    w.u32(m.image.width as u32);
    w.string(DISTORTION_MODEL);
    w.seq_len(distortion.len());
    for &v in distortion {
        w.f64(v);
    }
    #[rustfmt::skip]
    let k = [
        fx, 0.0, cx,
        0.0, fy, cy,
        0.0, 0.0, 1.0,
    ];
    #[rustfmt::skip]
    let r = [
        1.0, 0.0, 0.0,
        0.0, 1.0, 0.0,
        0.0, 0.0, 1.0,
    ];
    #[rustfmt::skip]
    let p = [
        fx, 0.0, cx, 0.0,
        0.0, fy, cy, 0.0,
        0.0, 0.0, 1.0, 0.0,
    ];
    for v in k.into_iter().chain(r).chain(p) {
        w.f64(v);
    }
    w.u32(0); // binning_x
    w.u32(0); // binning_y
    for _ in 0..4 {
        w.u32(0); // roi: x_offset, y_offset, height, width (0: the full image)
    }
    w.bool(false); // roi.do_rectify
    w.finish()
}
