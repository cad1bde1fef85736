//! ROS 2 messages in CDR back to simulator messages: the inverse of [`super::encode`], so
//! every value comes back bit for bit.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use sim::camera::RgbdImage;
use sim::sensors::gnss::{FixStatus, GnssFix};
use sim::sensors::{
    GroundTruth, ImuSample, LaserScan, LidarPoint, LidarScan, RgbdFrame, ScanSide, WheelOdometry,
};

use super::DatasetError;
use super::EPOCH_NS;
use super::cdr::CdrReader;
use super::encode::{DEPTH_32FC1, POINT_FIELDS, POINT_STEP, RGB8};

/// `std_msgs/Header`: the stamp in simulated nanoseconds (without [`EPOCH_NS`]) and the frame.
fn header(r: &mut CdrReader<'_>) -> Result<(i64, String), DatasetError> {
    let sec = i64::from(r.i32()?);
    let nanosec = i64::from(r.u32()?);
    let frame = r.string()?;
    Ok((sec * 1_000_000_000 + nanosec - EPOCH_NS, frame))
}

fn vector3(r: &mut CdrReader<'_>) -> Result<Vector3<f64>, DatasetError> {
    Ok(Vector3::new(r.f64()?, r.f64()?, r.f64()?))
}

/// The quaternion is taken as stored, not renormalized, so it is bit-identical.
fn pose(r: &mut CdrReader<'_>) -> Result<Isometry3<f64>, DatasetError> {
    let t = vector3(r)?;
    let (x, y, z, w) = (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
    Ok(Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)),
    ))
}

fn skip_f64(r: &mut CdrReader<'_>, n: usize) -> Result<(), DatasetError> {
    for _ in 0..n {
        r.f64()?;
    }
    Ok(())
}

/// A `sensor_msgs/NavSatFix` as [`super::encode::nav_sat_fix`] writes it: the geodetic
/// position, `None` without a fix.
pub(crate) fn nav_sat_fix(data: &[u8]) -> Result<(i64, Option<[f64; 3]>), DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let status = r.u8()? as i8;
    r.u16()?;
    let geodetic = [r.f64()?, r.f64()?, r.f64()?];
    skip_f64(&mut r, 9)?;
    r.u8()?;
    Ok((stamp_ns, (status >= 0).then_some(geodetic)))
}

/// A `vinebench_msgs/GnssEnu` ([`super::encode::gnss_enu`]) with the geodetic position of
/// the NavSatFix just before it.
pub(crate) fn gnss_enu(
    data: &[u8],
    (fix_stamp_ns, geodetic): (i64, Option<[f64; 3]>),
) -> Result<GnssFix, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    if stamp_ns != fix_stamp_ns {
        return Err(DatasetError::decode(format!(
            "a /gnss/enu at {stamp_ns} ns after a /gnss/fix at {fix_stamp_ns} ns"
        )));
    }
    let status = match r.u8()? {
        0 => FixStatus::None,
        1 => FixStatus::Single,
        2 => FixStatus::Float,
        3 => FixStatus::Fixed,
        other => return Err(DatasetError::decode(format!("GNSS status {other}"))),
    };
    let satellites = r.u32()? as usize;
    let position = vector3(&mut r)?;
    let variance_enu_m2 = [r.f64()?, r.f64()?, r.f64()?];
    let (hdop, vdop) = (r.f64()?, r.f64()?);
    let latency_ns = i64::from(r.i32()?) * 1_000_000_000 + i64::from(r.u32()?);
    let known = |v: f64| (!v.is_nan()).then_some(v);
    Ok(GnssFix {
        stamp_ns,
        status,
        position_enu_m: (status != FixStatus::None).then_some(position),
        variance_enu_m2,
        satellites,
        hdop: known(hdop),
        vdop: known(vdop),
        geodetic,
        latency_ns,
    })
}

pub(crate) fn imu(data: &[u8]) -> Result<ImuSample, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let q = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
    // REP 145: a first covariance of -1 says there is no orientation.
    let known = r.f64()? != -1.0;
    skip_f64(&mut r, 8)?;
    let gyro_rps = vector3(&mut r)?;
    skip_f64(&mut r, 9)?;
    let accel_mps2 = vector3(&mut r)?;
    let orientation =
        known.then(|| UnitQuaternion::new_unchecked(Quaternion::new(q[3], q[0], q[1], q[2])));
    Ok(ImuSample {
        stamp_ns,
        accel_mps2,
        gyro_rps,
        orientation,
    })
}

/// A cloud laid out as `/points` is (see [`POINT_FIELDS`]); `ready_ns` is when the sweep
/// ended (the message's log time), which gives the sweep's duration.
pub(crate) fn point_cloud(data: &[u8], ready_ns: i64) -> Result<LidarScan, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let height = r.u32()?;
    let width = r.u32()? as usize;
    let mut fields = Vec::new();
    for _ in 0..r.seq_len()? {
        let name = r.string()?;
        let offset = r.u32()?;
        let datatype = r.u8()?;
        let count = r.u32()?;
        fields.push((name, offset, datatype, count));
    }
    let expected: Vec<_> = POINT_FIELDS
        .iter()
        .map(|&(n, o, d)| (n.to_owned(), o, d, 1))
        .collect();
    if fields != expected {
        return Err(DatasetError::decode(format!(
            "point fields {fields:?}, expected {expected:?}"
        )));
    }
    let big_endian = r.bool()?;
    let point_step = r.u32()? as usize;
    let _row_step = r.u32()?;
    let bytes = r.bytes()?;
    if height != 1 || big_endian || point_step != POINT_STEP || bytes.len() != width * POINT_STEP {
        return Err(DatasetError::decode(format!(
            "cloud of {height} x {width} points of {point_step} bytes (big-endian: \
             {big_endian}) in {} bytes, expected 1 x N little-endian points of {POINT_STEP}",
            bytes.len()
        )));
    }
    let f32_at = |p: &[u8], o: usize| f32::from_le_bytes(p[o..o + 4].try_into().expect("4"));
    let points = bytes
        .chunks_exact(POINT_STEP)
        .map(|p| LidarPoint {
            x: f32_at(p, 0),
            y: f32_at(p, 4),
            z: f32_at(p, 8),
            intensity: f32_at(p, 12),
            ring: u16::from_le_bytes([p[16], p[17]]),
            time_s: f32_at(p, 20),
        })
        .collect();
    // The sweep lasts from its stamp to when it became available.
    let sweep_ns = ready_ns
        .checked_sub(stamp_ns)
        .filter(|&ns| ns >= 0)
        .ok_or_else(|| {
            DatasetError::decode(format!(
                "cloud stamped {stamp_ns} ns but available at {ready_ns} ns: not a sweep"
            ))
        })?;
    Ok(LidarScan {
        stamp_ns,
        sweep_ns,
        points,
    })
}

pub(crate) fn laser_scan(data: &[u8], side: ScanSide) -> Result<LaserScan, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let angle_min_rad = r.f32()?;
    let _angle_max = r.f32()?;
    let angle_increment_rad = r.f32()?;
    let time_increment_s = r.f32()?;
    let _scan_time = r.f32()?;
    let range_min_m = r.f32()?;
    let range_max_m = r.f32()?;
    Ok(LaserScan {
        stamp_ns,
        side,
        angle_min_rad,
        angle_increment_rad,
        time_increment_s,
        range_min_m,
        range_max_m,
        ranges_m: r.f32_seq()?,
        intensities: r.f32_seq()?,
    })
}

pub(crate) fn odometry(data: &[u8]) -> Result<WheelOdometry, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let _child = r.string()?;
    let odom_from_base = pose(&mut r)?;
    skip_f64(&mut r, 36)?;
    let linear = vector3(&mut r)?;
    let angular = vector3(&mut r)?;
    Ok(WheelOdometry {
        stamp_ns,
        linear_mps: linear.x,
        angular_rps: angular.z,
        odom_from_base,
    })
}

/// `/ground_truth`: the stamp and `world_from_base`.
pub(crate) fn pose_stamped(data: &[u8]) -> Result<(i64, Isometry3<f64>), DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    Ok((stamp_ns, pose(&mut r)?))
}

/// `/ground_truth/twist` completes the ground truth whose pose came just before it.
pub(crate) fn twist_stamped(
    data: &[u8],
    pose: (i64, Isometry3<f64>),
) -> Result<GroundTruth, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    if stamp_ns != pose.0 {
        return Err(DatasetError::decode(format!(
            "twist stamped {stamp_ns} ns follows a pose stamped {} ns",
            pose.0
        )));
    }
    Ok(GroundTruth {
        stamp_ns,
        world_from_base: pose.1,
        velocity_in_world: vector3(&mut r)?,
        omega_in_base: vector3(&mut r)?,
    })
}

/// One image of a camera frame, waiting for the rest of the frame.
#[derive(Debug)]
pub(crate) struct Plane<T> {
    pub stamp_ns: i64,
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<T>,
}

/// A `sensor_msgs/Image` of `encoding`, densely packed little-endian rows: the stamp, the
/// size and the data.
fn image<'a>(
    data: &'a [u8],
    encoding: &str,
    bytes_per_pixel: usize,
) -> Result<(i64, usize, usize, &'a [u8]), DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let height = r.u32()? as usize;
    let width = r.u32()? as usize;
    let got_encoding = r.string()?;
    let big_endian = r.u8()?;
    let step = r.u32()? as usize;
    let bytes = r.bytes()?;
    if got_encoding != encoding
        || big_endian != 0
        || step != width * bytes_per_pixel
        || bytes.len() != step * height
    {
        return Err(DatasetError::decode(format!(
            "{got_encoding} image of {width} x {height} pixels, step {step} (big-endian: \
             {big_endian}) in {} bytes, expected a packed little-endian {encoding} image",
            bytes.len()
        )));
    }
    Ok((stamp_ns, width, height, bytes))
}

/// `/camera/color/image_raw`.
pub(crate) fn color_image(data: &[u8]) -> Result<Plane<u8>, DatasetError> {
    let (stamp_ns, width, height, bytes) = image(data, RGB8, 3)?;
    Ok(Plane {
        stamp_ns,
        width,
        height,
        pixels: bytes.to_vec(),
    })
}

/// `/camera/depth/image_raw`: every value's bits as stored.
pub(crate) fn depth_image(data: &[u8]) -> Result<Plane<f32>, DatasetError> {
    let (stamp_ns, width, height, bytes) = image(data, DEPTH_32FC1, 4)?;
    Ok(Plane {
        stamp_ns,
        width,
        height,
        pixels: bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect(),
    })
}

/// `/camera/color/camera_info` completes the frame whose colour and depth images came just
/// before it; the intrinsics are its `k`.
pub(crate) fn camera_info(
    data: &[u8],
    color: Plane<u8>,
    depth: Plane<f32>,
) -> Result<RgbdFrame, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    let height = r.u32()? as usize;
    let width = r.u32()? as usize;
    let _distortion_model = r.string()?;
    let d = r.seq_len()?;
    skip_f64(&mut r, d)?;
    let mut k = [0.0; 9];
    for v in &mut k {
        *v = r.f64()?;
    }
    let sizes = [
        (color.stamp_ns, color.width, color.height),
        (depth.stamp_ns, depth.width, depth.height),
    ];
    if sizes.iter().any(|&s| s != (stamp_ns, width, height)) {
        return Err(DatasetError::decode(format!(
            "camera info of {width} x {height} pixels stamped {stamp_ns} ns follows a colour \
             image of {} x {} stamped {} ns and a depth image of {} x {} stamped {} ns",
            color.width, color.height, color.stamp_ns, depth.width, depth.height, depth.stamp_ns
        )));
    }
    Ok(RgbdFrame {
        stamp_ns,
        image: RgbdImage {
            width,
            height,
            rgb: color.pixels,
            depth_m: depth.pixels,
            intrinsics: [k[0], k[4], k[2], k[5]],
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::encode;

    fn frame() -> RgbdFrame {
        RgbdFrame {
            stamp_ns: 33_333_333,
            image: RgbdImage {
                width: 3,
                height: 2,
                rgb: (0..18).map(|i| i * 14).collect(),
                // Invalid depth however a camera may report it, and NaN with a payload.
                depth_m: vec![
                    0.0,
                    -0.0,
                    f32::from_bits(0x7fc0_1234),
                    f32::INFINITY,
                    1.5,
                    f32::MIN_POSITIVE,
                ],
                intrinsics: [457.007_362_157_476_7, 457.1, 1.0 / 3.0, 0.5],
            },
        }
    }

    #[test]
    fn a_camera_frame_comes_back_bit_for_bit() {
        let f = frame();
        let color = color_image(&encode::color_image(&f)).unwrap();
        let depth = depth_image(&encode::depth_image(&f)).unwrap();
        let back = camera_info(&encode::camera_info(&f, &[0.0; 5]), color, depth).unwrap();
        let bits = |d: &[f32]| d.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
        assert_eq!(back.stamp_ns, f.stamp_ns);
        assert_eq!((back.image.width, back.image.height), (3, 2));
        assert_eq!(back.image.rgb, f.image.rgb);
        assert_eq!(bits(&back.image.depth_m), bits(&f.image.depth_m));
        assert_eq!(
            back.image.intrinsics.map(f64::to_bits),
            f.image.intrinsics.map(f64::to_bits)
        );
    }

    /// A lens's coefficients are `camera_info`'s `d`, after its size and model.
    #[test]
    fn camera_info_carries_the_lens() {
        let lens = [0.0717, -0.1355, 0.0016, 0.0024, 0.0595];
        let bytes = encode::camera_info(&frame(), &lens);
        let mut r = CdrReader::new(&bytes).unwrap();
        header(&mut r).unwrap();
        assert_eq!((r.u32().unwrap(), r.u32().unwrap()), (2, 3));
        assert_eq!(r.string().unwrap(), "plumb_bob");
        assert_eq!(r.seq_len().unwrap(), 5);
        let d: Vec<f64> = (0..5).map(|_| r.f64().unwrap()).collect();
        assert_eq!(d, lens);
    }

    #[test]
    fn a_frame_of_mismatched_parts_is_refused() {
        let f = frame();
        let mut later = frame();
        later.stamp_ns += 1;
        let color = color_image(&encode::color_image(&f)).unwrap();
        let depth = depth_image(&encode::depth_image(&later)).unwrap();
        let err = camera_info(&encode::camera_info(&f, &[0.0; 5]), color, depth).unwrap_err();
        assert!(err.to_string().contains("33333334"), "{err}");
        // A depth image is not a colour image.
        let err = color_image(&encode::depth_image(&f)).unwrap_err();
        assert!(err.to_string().contains("32FC1"), "{err}");
    }

    /// fuzz/regressions/ros_messages/sweep-overflow.bin: a cloud stamped long before it
    /// became available, whose sweep duration overflowed `i64`.
    #[test]
    fn a_cloud_available_before_its_stamp_or_absurdly_late_is_refused() {
        let scan = LidarScan {
            stamp_ns: -EPOCH_NS,
            sweep_ns: 0,
            points: Vec::new(),
        };
        let bytes = encode::point_cloud(&scan);
        let err = point_cloud(&bytes, i64::MAX).expect_err("sweep overflows");
        assert!(err.to_string().contains("not a sweep"), "{err}");
        assert!(
            point_cloud(&bytes, -EPOCH_NS - 1).is_err(),
            "negative sweep"
        );
        assert_eq!(point_cloud(&bytes, -EPOCH_NS + 5).unwrap().sweep_ns, 5);
    }
}
