//! A run's results as an MCAP file of ROS 2 messages (`results.mcap` in every scored run
//! folder), to open beside the run's sensor recording (`vinebench record`) in Foxglove: the
//! truth and the aligned estimate as paths, the estimated pose moving along the timeline,
//! the map and the loop closures. The same MCAP `ros2` profile, `ros2msg` schemas and CDR
//! encoding as the recording (see the module [`super`]).
//!
//! | topic | type | logged at | content |
//! |---|---|---|---|
//! | `/groundtruth/path` | `nav_msgs/msg/Path` | first ground-truth stamp | every pose of groundtruth.tum (`map_from_base`), each at its stamp |
//! | `/estimate/path` | `nav_msgs/msg/Path` | first ground-truth stamp | every pose of estimate.tum, aligned to the ground truth (below), each at its stamp |
//! | `/estimate/pose` | `geometry_msgs/msg/PoseStamped` | its stamp | the same aligned poses, one message each |
//! | `/map` | `sensor_msgs/msg/PointCloud2` | first ground-truth stamp | map.ply's points, aligned: fields x, y, z `FLOAT32` at 0, 4, 8, `point_step` 12, little-endian, one row, dense; absent without map.ply |
//! | `/loops` | `visualization_msgs/msg/MarkerArray` | first ground-truth stamp | a `LINE_LIST` marker per judged accepted loop, between the aligned estimate poses nearest in time to its two stamps: namespace `true_loops` green, `false_loops` red, ids from 0 in each; empty without loops |
//!
//! Frames: every header's frame is `map`, the ground truth's world frame as the recording
//! names it (its `/ground_truth` is in `map` too).
//!
//! Time: header stamps and log times are simulated time offset by [`super::EPOCH_NS`], as
//! in the recording, so that the files share one timeline. The paths, map and loops are
//! single messages logged at the first ground-truth stamp, so a viewer shows them from the
//! start of playback; their channels are latched (transient local) for `ros2 bag play`.
//! Messages are written in log-time order.
//!
//! Alignment: the estimate and the map are moved into `map` by the very transform the run's
//! APE was computed with (`eval::ApeResult::transform`, `map_from_estimate`, of the run's
//! alignment), applied to every pose as `eval::Sim3::apply` does (`p ↦ R (s p) + t`,
//! `R_pose ↦ R R_pose`) and to every map point as `p ↦ R (s p) + t`. A metadata record
//! `vinebench` holds the alignment's name and that transform.
//!
//! Loops: an accepted loop the host could not judge (no stamps, or stamps outside the
//! ground truth; metrics.json `loops.unjudged`) is not drawn.

use std::collections::BTreeMap;
use std::path::Path;

use eval::{Sim3, Trajectory};
use nalgebra::{Isometry3, Vector3};

use super::DatasetError;
use super::cdr::CdrWriter;
use super::encode::{FLOAT32, header, pose, vector3};
use super::mcap_file::McapFile;
use super::topics::MAP_FRAME;

const GROUNDTRUTH_PATH_TOPIC: &str = "/groundtruth/path";
const ESTIMATE_PATH_TOPIC: &str = "/estimate/path";
const ESTIMATE_POSE_TOPIC: &str = "/estimate/pose";
const MAP_TOPIC: &str = "/map";
const LOOPS_TOPIC: &str = "/loops";
const TRUE_LOOPS_NS: &str = "true_loops";
const FALSE_LOOPS_NS: &str = "false_loops";

const PATH_TYPE: &str = "nav_msgs/msg/Path";
const POSE_TYPE: &str = "geometry_msgs/msg/PoseStamped";
const CLOUD_TYPE: &str = "sensor_msgs/msg/PointCloud2";
const MARKERS_TYPE: &str = "visualization_msgs/msg/MarkerArray";

/// `visualization_msgs/Marker` constants.
const LINE_LIST: i32 = 5;
const ADD: i32 = 0;
/// Width of a loop's line (the marker's `scale.x`), metres.
const LOOP_LINE_WIDTH_M: f64 = 0.05;
/// RGBA of a true and of a false loop's line.
const GREEN: [f32; 4] = [0.0, 1.0, 0.0, 1.0];
const RED: [f32; 4] = [1.0, 0.0, 0.0, 1.0];
/// Bytes per point of `/map`: x, y, z as `f32`.
const MAP_POINT_STEP: usize = 12;

/// An accepted loop closure as the host judged it: the two base-pose stamps it joins
/// (`plugin_api::Event::loop_stamps_ns`) and whether ground truth confirms it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JudgedLoop {
    pub stamps_ns: [i64; 2],
    pub true_loop: bool,
}

/// What a scored run's results file shows.
#[derive(Debug, Clone, Copy)]
pub struct RunResults<'a> {
    /// groundtruth.tum: `map_from_base`.
    pub groundtruth: &'a Trajectory,
    /// estimate.tum, as the plugin gave it (in its own world frame).
    pub estimate: &'a Trajectory,
    /// The run's alignment, as metrics.json names it.
    pub alignment: &'a str,
    /// The transform the run's APE aligned the estimate with.
    pub map_from_estimate: &'a Sim3,
    /// map.ply's points, in the estimate's world frame; `None`: the run has no map.
    pub map_points: Option<&'a [[f32; 3]]>,
    /// The judged accepted loops, in the plugin's order.
    pub loops: &'a [JudgedLoop],
}

/// A trajectory's poses with their stamps in nanoseconds (TUM stamps are seconds).
fn stamped(
    trajectory: &Trajectory,
    map_from: impl Fn(&Isometry3<f64>) -> Isometry3<f64>,
) -> Vec<(i64, Isometry3<f64>)> {
    trajectory
        .stamps
        .iter()
        .zip(&trajectory.poses)
        .map(|(&t, p)| ((t * 1e9).round() as i64, map_from(p)))
        .collect()
}

/// Writes `path` (under a temporary name, renamed when complete); returns its size in bytes.
pub fn write_results(path: &Path, run: &RunResults<'_>) -> Result<u64, DatasetError> {
    let groundtruth = stamped(run.groundtruth, |p| *p);
    let estimate = stamped(run.estimate, |p| run.map_from_estimate.apply(p));
    let Some(&(first_ns, _)) = groundtruth.first() else {
        return Err(DatasetError::invalid(path, "no ground-truth pose to write"));
    };
    if estimate.is_empty() {
        return Err(DatasetError::invalid(path, "no estimated pose to write"));
    }
    let map = run
        .map_points
        .map(|points| map_cloud(path, first_ns, points, run.map_from_estimate))
        .transpose()?;

    let mut file = McapFile::create(path)?;
    let groundtruth_path = file.channel(GROUNDTRUTH_PATH_TOPIC, PATH_TYPE, true)?;
    let estimate_path = file.channel(ESTIMATE_PATH_TOPIC, PATH_TYPE, true)?;
    let estimate_pose = file.channel(ESTIMATE_POSE_TOPIC, POSE_TYPE, false)?;
    let map_channel = match map {
        Some(_) => Some(file.channel(MAP_TOPIC, CLOUD_TYPE, true)?),
        None => None,
    };
    let loops = file.channel(LOOPS_TOPIC, MARKERS_TYPE, true)?;
    file.metadata("vinebench", metadata(run))?;

    // In log-time order: any estimated pose before the first ground-truth stamp, the
    // one-shot messages, the other poses.
    let split = estimate.partition_point(|(t, _)| *t < first_ns);
    for (t, p) in &estimate[..split] {
        file.put(estimate_pose, *t, &pose_stamped(*t, p))?;
    }
    file.put(
        groundtruth_path,
        first_ns,
        &nav_path(first_ns, &groundtruth),
    )?;
    file.put(estimate_path, first_ns, &nav_path(first_ns, &estimate))?;
    if let (Some(channel), Some(cloud)) = (map_channel, map) {
        file.put(channel, first_ns, &cloud)?;
    }
    file.put(
        loops,
        first_ns,
        &loop_markers(first_ns, run.loops, &estimate),
    )?;
    for (t, p) in &estimate[split..] {
        file.put(estimate_pose, *t, &pose_stamped(*t, p))?;
    }
    file.finish()
}

/// The `vinebench` metadata record: the alignment and its transform, values as Rust prints
/// them (shortest round-trip decimals), separated by spaces.
fn metadata(run: &RunResults<'_>) -> BTreeMap<String, String> {
    let s = run.map_from_estimate;
    let q = s.rotation.coords;
    let t = s.translation;
    BTreeMap::from([
        ("alignment".to_owned(), run.alignment.to_owned()),
        ("alignment_scale".to_owned(), format!("{}", s.scale)),
        (
            "alignment_rotation_xyzw".to_owned(),
            format!("{} {} {} {}", q.x, q.y, q.z, q.w),
        ),
        (
            "alignment_translation_m".to_owned(),
            format!("{} {} {}", t.x, t.y, t.z),
        ),
    ])
}

/// `geometry_msgs/PoseStamped` body (after any CDR header) of `map_from_base` at `stamp_ns`.
fn write_pose_stamped(w: &mut CdrWriter, stamp_ns: i64, map_from_base: &Isometry3<f64>) {
    header(w, stamp_ns, MAP_FRAME);
    pose(w, map_from_base);
}

fn pose_stamped(stamp_ns: i64, map_from_base: &Isometry3<f64>) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(80);
    write_pose_stamped(&mut w, stamp_ns, map_from_base);
    w.finish()
}

/// `nav_msgs/Path` stamped `stamp_ns` of every pose, each at its own stamp.
fn nav_path(stamp_ns: i64, poses: &[(i64, Isometry3<f64>)]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(80 * poses.len() + 32);
    header(&mut w, stamp_ns, MAP_FRAME);
    w.seq_len(poses.len());
    for (t, p) in poses {
        write_pose_stamped(&mut w, *t, p);
    }
    w.finish()
}

/// `sensor_msgs/PointCloud2` of `points_in_estimate` moved into `map`.
fn map_cloud(
    path: &Path,
    stamp_ns: i64,
    points_in_estimate: &[[f32; 3]],
    map_from_estimate: &Sim3,
) -> Result<Vec<u8>, DatasetError> {
    let n = points_in_estimate.len();
    let row_step = u32::try_from(n * MAP_POINT_STEP).map_err(|_| {
        DatasetError::invalid(
            path,
            format!("{n} map points: too many for one PointCloud2"),
        )
    })?;
    let r = map_from_estimate.rotation.to_rotation_matrix();
    let mut data = Vec::with_capacity(n * MAP_POINT_STEP);
    for p in points_in_estimate {
        let p_in_estimate = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        let p_in_map =
            r * (p_in_estimate * map_from_estimate.scale) + map_from_estimate.translation;
        for v in [p_in_map.x, p_in_map.y, p_in_map.z] {
            data.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    let mut w = CdrWriter::with_capacity(data.len() + 128);
    header(&mut w, stamp_ns, MAP_FRAME);
    w.u32(1); // height: an unordered cloud
    w.u32(n as u32);
    w.seq_len(3);
    for (name, offset) in [("x", 0), ("y", 4), ("z", 8)] {
        w.string(name);
        w.u32(offset);
        w.u8(FLOAT32);
        w.u32(1);
    }
    w.bool(false); // is_bigendian
    w.u32(MAP_POINT_STEP as u32);
    w.u32(row_step);
    w.bytes(&data);
    w.bool(true); // is_dense: map.ply holds points only
    Ok(w.finish())
}

/// The pose of `poses` (sorted by stamp, not empty) nearest in time to `t_ns`; the earlier
/// one at equal distance.
fn nearest(poses: &[(i64, Isometry3<f64>)], t_ns: i64) -> &Isometry3<f64> {
    let k = poses.partition_point(|(s, _)| *s < t_ns);
    let pick = match (k.checked_sub(1), poses.get(k)) {
        (Some(i), Some((after, _))) if t_ns - poses[i].0 > after - t_ns => k,
        (Some(i), _) => i,
        (None, _) => k,
    };
    &poses[pick].1
}

/// `visualization_msgs/MarkerArray` of a line per loop between the estimated poses nearest
/// its two stamps.
fn loop_markers(
    stamp_ns: i64,
    loops: &[JudgedLoop],
    estimate: &[(i64, Isometry3<f64>)],
) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(400 * loops.len() + 8);
    w.seq_len(loops.len());
    let (mut true_ids, mut false_ids) = (0, 0);
    for l in loops {
        let (ns, ids, color) = if l.true_loop {
            (TRUE_LOOPS_NS, &mut true_ids, GREEN)
        } else {
            (FALSE_LOOPS_NS, &mut false_ids, RED)
        };
        let ends = l.stamps_ns.map(|t| nearest(estimate, t).translation.vector);
        line_marker(&mut w, stamp_ns, ns, *ids, color, &ends);
        *ids += 1;
    }
    w.finish()
}

/// One `visualization_msgs/Marker` (ROS 2 Humble's fields, in order): a `LINE_LIST` of
/// `ends` in `map`, kept until deleted, no texture, text or mesh.
fn line_marker(
    w: &mut CdrWriter,
    stamp_ns: i64,
    ns: &str,
    id: i32,
    color: [f32; 4],
    ends: &[Vector3<f64>; 2],
) {
    header(w, stamp_ns, MAP_FRAME);
    w.string(ns);
    w.i32(id);
    w.i32(LINE_LIST);
    w.i32(ADD);
    pose(w, &Isometry3::identity());
    vector3(w, &Vector3::new(LOOP_LINE_WIDTH_M, 0.0, 0.0)); // scale: x is the line width
    for c in color {
        w.f32(c);
    }
    w.i32(0); // lifetime.sec: 0, forever
    w.u32(0); // lifetime.nanosec
    w.bool(false); // frame_locked
    w.seq_len(ends.len());
    for p in ends {
        vector3(w, p);
    }
    w.seq_len(0); // colors: the marker's own
    w.string(""); // texture_resource
    w.i32(0); // texture: an empty sensor_msgs/CompressedImage, header stamp 0, no frame
    w.u32(0);
    w.string("");
    w.string(""); // texture.format
    w.bytes(&[]); // texture.data
    w.seq_len(0); // uv_coordinates
    w.string(""); // text
    w.string(""); // mesh_resource
    w.string(""); // mesh_file.filename
    w.bytes(&[]); // mesh_file.data
    w.bool(false); // mesh_use_embedded_materials
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_loop_end_is_the_estimated_pose_nearest_in_time() {
        let poses: Vec<(i64, Isometry3<f64>)> = [10, 20, 30]
            .map(|t| (t, Isometry3::translation(t as f64, 0.0, 0.0)))
            .to_vec();
        let x = |t| nearest(&poses, t).translation.x;
        assert_eq!(
            [x(0), x(14), x(15), x(16), x(30), x(99)],
            [10.0, 10.0, 10.0, 20.0, 30.0, 30.0],
            "nearest, the earlier at a tie, the ends beyond the trajectory"
        );
    }
}
