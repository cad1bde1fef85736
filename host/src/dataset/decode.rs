//! ROS 2 messages in CDR back to simulator messages: the inverse of [`super::encode`], so
//! every value comes back bit for bit.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use sim::sensors::{
    GroundTruth, ImuSample, LaserScan, LidarPoint, LidarScan, ScanSide, WheelOdometry,
};

use super::DatasetError;
use super::EPOCH_NS;
use super::cdr::CdrReader;
use super::encode::{POINT_FIELDS, POINT_STEP};

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

pub(crate) fn imu(data: &[u8]) -> Result<ImuSample, DatasetError> {
    let mut r = CdrReader::new(data)?;
    let (stamp_ns, _) = header(&mut r)?;
    skip_f64(&mut r, 4 + 9)?; // orientation and its covariance
    let gyro_rps = vector3(&mut r)?;
    skip_f64(&mut r, 9)?;
    let accel_mps2 = vector3(&mut r)?;
    Ok(ImuSample {
        stamp_ns,
        accel_mps2,
        gyro_rps,
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
    Ok(LidarScan {
        stamp_ns,
        sweep_ns: ready_ns - stamp_ns,
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
