//! Writes a simulated stream as an MCAP file of ROS 2 messages.
//!
//! The file is written under a temporary name beside the target and renamed when complete,
//! so a failed recording never leaves a half-written file.

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use sim::SimConfig;
use sim::config::Side;
use sim::sensors::{LaserScan, Message, ScanSide};

use super::topics::{
    CAMERA_FRAME, IMU_FRAME, LASER_BACK_FRAME, LASER_FRONT_FRAME, LIDAR_FRAME, Topic,
};
use super::{DatasetError, EPOCH_NS, encode, schemas};

/// Target size of an MCAP chunk (before any compression; none is used). A camera frame
/// (about 2.1 MB at 640 x 480) fits whole.
const CHUNK_BYTES: u64 = 4 << 20;

/// rosbag2's QoS for `/tf_static` (reliable, transient local: latched), so `ros2 bag play`
/// offers it to late subscribers as `robot_state_publisher` does.
const LATCHED_QOS: &str = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 1\n  \
deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    \
nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    \
nsec: 4294967295\n  avoid_ros_namespace_conventions: false";

/// An MCAP recording being written; [`Recorder::finish`] puts it in place.
pub struct Recorder {
    writer: Option<mcap::Writer<BufWriter<File>>>,
    target: PathBuf,
    tmp: PathBuf,
    channels: BTreeMap<Topic, (u16, u32)>,
    /// Per 2D scanner: scan period (s) and how long after its stamp a scan is complete (ns).
    scan_timing: [(f32, i64); 2],
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("target", &self.target)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}

/// How long after its stamp a 2D scan is complete, as [`sim::sensors::Scan2dSensor`] times it:
/// the mirror turns once per period, samples `time_increment` apart.
fn scan_timing(cfg: &sim::config::Scan2dConfig) -> (f32, i64) {
    let angle_increment = (cfg.angle_max_rad - cfg.angle_min_rad) / (cfg.samples - 1) as f64;
    let time_increment_s = angle_increment / std::f64::consts::TAU / cfg.rate_hz;
    let sweep_ns = (time_increment_s * (cfg.samples - 1) as f64 * 1e9).round() as i64;
    ((1.0 / cfg.rate_hz) as f32, sweep_ns)
}

impl Recorder {
    /// Starts `path` with a channel for each topic of `sensors`, `/tf_static` from the
    /// configuration's mounts, and `metadata` (a `vinebench` metadata record: what made it).
    pub fn create(
        path: &Path,
        config: &SimConfig,
        sensors: sim::SensorSet,
        metadata: BTreeMap<String, String>,
    ) -> Result<Self, DatasetError> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| DatasetError::invalid(path, "not a file name"))?;
        let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        let file = File::create(&tmp).map_err(DatasetError::io(path))?;
        let options = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(format!("vinebench {}", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_BYTES));
        let s = &config.sensors;
        let mut recorder = Self {
            writer: None,
            target: path.to_owned(),
            tmp,
            channels: BTreeMap::new(),
            scan_timing: [scan_timing(&s.scan2d_front), scan_timing(&s.scan2d_back)],
        };
        let mut writer = options
            .create(BufWriter::new(file))
            .map_err(DatasetError::mcap(path))?;
        let mut schema_ids = BTreeMap::new();
        for topic in Topic::ALL.into_iter().filter(|t| t.in_set(&sensors)) {
            let schema_id = match schema_ids.get(topic.schema()) {
                Some(&id) => id,
                None => {
                    let text = schemas::schema(topic.schema());
                    let id = writer
                        .add_schema(topic.schema(), "ros2msg", text.as_bytes())
                        .map_err(DatasetError::mcap(path))?;
                    schema_ids.insert(topic.schema(), id);
                    id
                }
            };
            let mut channel_meta = BTreeMap::new();
            if topic == Topic::TfStatic {
                channel_meta.insert("offered_qos_profiles".to_owned(), LATCHED_QOS.to_owned());
            }
            let id = writer
                .add_channel(schema_id, topic.name(), "cdr", &channel_meta)
                .map_err(DatasetError::mcap(path))?;
            recorder.channels.insert(topic, (id, 0));
        }
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "vinebench".to_owned(),
                metadata,
            })
            .map_err(DatasetError::mcap(path))?;
        recorder.writer = Some(writer);
        let mounts = [
            (IMU_FRAME, s.imu.mount.base_from_sensor()),
            (LIDAR_FRAME, s.lidar.mount.base_from_sensor()),
            (
                LASER_FRONT_FRAME,
                s.scan2d_front.mount_for(Side::Front).base_from_sensor(),
            ),
            (
                LASER_BACK_FRAME,
                s.scan2d_back.mount_for(Side::Back).base_from_sensor(),
            ),
            // The images' optical frame (z forward, x right, y down), as the rig gives it.
            (
                CAMERA_FRAME,
                s.camera.mount.base_from_sensor() * sim::camera::camera_from_optical(),
            ),
        ];
        recorder.put(Topic::TfStatic, 0, &encode::tf_message(0, &mounts))?;
        Ok(recorder)
    }

    fn put(&mut self, topic: Topic, ready_ns: i64, data: &[u8]) -> Result<(), DatasetError> {
        let (channel_id, sequence) = self.channels.get_mut(&topic).ok_or_else(|| {
            DatasetError::invalid(
                &self.target,
                format!("{} is not among the recorded sensors", topic.name()),
            )
        })?;
        let time = u64::try_from(ready_ns + EPOCH_NS).expect("simulated time after 1970");
        let header = mcap::records::MessageHeader {
            channel_id: *channel_id,
            sequence: *sequence,
            log_time: time,
            publish_time: time,
        };
        *sequence += 1;
        self.writer
            .as_mut()
            .expect("open until finished")
            .write_to_known_channel(&header, data)
            .map_err(DatasetError::mcap(&self.target))
    }

    fn scan(&mut self, m: &LaserScan) -> Result<(), DatasetError> {
        let (topic, frame, (scan_time_s, sweep_ns)) = match m.side {
            ScanSide::Front => (Topic::ScanFront, LASER_FRONT_FRAME, self.scan_timing[0]),
            ScanSide::Back => (Topic::ScanBack, LASER_BACK_FRAME, self.scan_timing[1]),
        };
        let data = encode::laser_scan(m, frame, scan_time_s);
        self.put(topic, m.stamp_ns + sweep_ns, &data)
    }

    /// Appends one message, logged at the time it became available.
    pub fn write(&mut self, message: &Message) -> Result<(), DatasetError> {
        match message {
            Message::GroundTruth(m) => {
                self.put(Topic::GroundTruth, m.stamp_ns, &encode::pose_stamped(m))?;
                self.put(
                    Topic::GroundTruthTwist,
                    m.stamp_ns,
                    &encode::twist_stamped(m),
                )
            }
            Message::Imu(m) => self.put(Topic::Imu, m.stamp_ns, &encode::imu(m)),
            Message::WheelOdometry(m) => self.put(Topic::Odom, m.stamp_ns, &encode::odometry(m)),
            Message::Lidar(m) => self.put(
                Topic::Points,
                m.stamp_ns + m.sweep_ns,
                &encode::point_cloud(m),
            ),
            Message::Scan2d(m) => self.scan(m),
            // A frame is available whole at its stamp (global shutter); the camera info comes
            // last and completes it on replay.
            Message::Rgbd(m) => {
                self.put(Topic::ColorImage, m.stamp_ns, &encode::color_image(m))?;
                self.put(Topic::DepthImage, m.stamp_ns, &encode::depth_image(m))?;
                self.put(Topic::CameraInfo, m.stamp_ns, &encode::camera_info(m))
            }
        }
    }

    /// Writes the summary, flushes and moves the file into place; returns its size in bytes.
    pub fn finish(mut self) -> Result<u64, DatasetError> {
        let mut writer = self.writer.take().expect("open until finished");
        writer.finish().map_err(DatasetError::mcap(&self.target))?;
        let file = writer
            .into_inner()
            .into_inner()
            .map_err(|e| DatasetError::io(&self.target)(e.into_error()))?;
        file.sync_all().map_err(DatasetError::io(&self.target))?;
        let size = file
            .metadata()
            .map_err(DatasetError::io(&self.target))?
            .len();
        drop(file);
        fs::rename(&self.tmp, &self.target).map_err(DatasetError::io(&self.target))?;
        Ok(size)
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        // Only an unfinished recording still has its temporary file.
        drop(self.writer.take());
        if self.tmp.exists() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}
