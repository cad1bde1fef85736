//! Recorded datasets: the simulator's stream as an MCAP file of ROS 2 messages, and back.
//!
//! [`Recorder`] writes what [`sim::Simulation::stream`] yields as an MCAP file (MCAP format
//! specification, <https://mcap.dev/spec>) with the ROS 2 profile: `ros2msg` schemas and
//! `cdr` message encoding (little-endian OMG CDR as the ROS 2 middleware serializes it, see
//! [`cdr`]), so `ros2 bag play FILE.mcap` and Foxglove open it. [`Replay`] reads such a file
//! back into the very same [`Message`] values, bit for bit and in the same order, so a plugin
//! can be fed from a file instead of the live simulator ([`replay_messages`]).
//!
//! | topic | type | frame | from |
//! |---|---|---|---|
//! | `/tf_static` | `tf2_msgs/msg/TFMessage` | `base_link` → `imu_link`, `velodyne`, `laser_front`, `laser_back`, `camera_color_optical_frame`, `gnss_link` (where the world has a receiver) | the mounts' `base_from_sensor` (the camera's with the rotation to its optical frame), once at t = 0 |
//! | `/gnss/fix` | `sensor_msgs/msg/NavSatFix` | `gnss_link` | [`sim::sensors::gnss::GnssFix`] in WGS-84 from the world's datum, logged after the receiver's latency: RTK float and fixed as `STATUS_GBAS_FIX`, single as `STATUS_FIX`, none as `STATUS_NO_FIX` with NaN coordinates; the covariance diagonal (east, north, up) |
//! | `/gnss/enu` | `vinebench_msgs/msg/GnssEnu` (its definition in the file's schema) | `gnss_link` | the same epoch as NavSatFix cannot say it: status (none, single, float, fixed), satellites, east-north-up position in the world frame, variances, HDOP, VDOP, latency |
//! | `/imu` | `sensor_msgs/msg/Imu` | `imu_link` | [`sim::sensors::ImuSample`]; no orientation (`orientation_covariance[0] = -1`) |
//! | `/points` | `sensor_msgs/msg/PointCloud2` | `velodyne` | [`sim::sensors::LidarScan`]: x, y, z, intensity (f32), ring (u16), time (f32, s after the stamp), as LIO-SAM reads them |
//! | `/scan_front`, `/scan_back` | `sensor_msgs/msg/LaserScan` | `laser_front`, `laser_back` | [`sim::sensors::LaserScan`] |
//! | `/odom` | `nav_msgs/msg/Odometry` | `odom` → `base_link` | [`sim::sensors::WheelOdometry`]: pose `odom_from_base`, twist linear.x and angular.z |
//! | `/ground_truth` | `geometry_msgs/msg/PoseStamped` | `map` | [`sim::sensors::GroundTruth`]: `world_from_base` |
//! | `/ground_truth/twist` | `geometry_msgs/msg/TwistStamped` | `map` | the same ground truth's `velocity_in_world` (linear, in `map`) and `omega_in_base` (angular, in `base_link`, as the simulator keeps it) |
//! | `/camera/color/image_raw` | `sensor_msgs/msg/Image` | `camera_color_optical_frame` | [`sim::sensors::RgbdFrame`]'s colour: `rgb8`, `step = 3 * width` |
//! | `/camera/depth/image_raw` | `sensor_msgs/msg/Image` | `camera_color_optical_frame` | its depth, registered to the colour image: `32FC1` in metres along the optical axis, `step = 4 * width`; invalid pixels as the camera gives them (0, as the Kinect v2 driver reports them) |
//! | `/camera/color/camera_info` | `sensor_msgs/msg/CameraInfo` | `camera_color_optical_frame` | its intrinsics: `k`, `p` from `[fx, fy, cx, cy]`, `plumb_bob` with zero `d`, `r` identity; one per frame, for both images |
//!
//! Frames follow REP 105 (`map` → `odom` → `base_link`) and REP 103 (x forward, y left, z up).
//!
//! Time: every header stamp is the measurement's stamp (a sweep's start) and every MCAP
//! `log_time` / `publish_time` the moment the message becomes available (a sweep's end,
//! everything else its stamp; a camera frame's three messages follow one another, colour,
//! depth, camera info), both offset by [`EPOCH_NS`] so that simulated time 0 is
//! 2023-11-14T22:13:20Z and no stamp is ROS's "zero time". The file holds no wall-clock time
//! and no compression, so the same configuration and seed give byte-identical files.
//!
//! [`write_results`] writes a scored run's `results.mcap` in the same encoding and on the same
//! timeline: ground truth and aligned estimate, map and loop closures, in frame `map` (see
//! `results.rs`).

mod cdr;
mod decode;
mod encode;
mod error;
mod mcap_file;
mod recorder;
mod replay;
mod results;
mod schemas;
mod topics;
mod wire;

pub use error::DatasetError;
pub use recorder::Recorder;
pub use replay::{Replay, replay_messages, replay_with_live};
pub use results::{JudgedLoop, RunResults, write_results};
pub use topics::Topic;
pub use wire::{Assembler, RosMessage, WireDetails, to_ros};

/// Simulated time 0 in the file's ROS time: 1.7e9 s after the Unix epoch, in nanoseconds.
pub const EPOCH_NS: i64 = 1_700_000_000_000_000_000;

#[cfg(doc)]
use sim::sensors::Message;
