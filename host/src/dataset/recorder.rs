//! Writes a simulated stream as an MCAP file of ROS 2 messages.
//!
//! The file is written under a temporary name beside the target and renamed when complete,
//! so a failed recording never leaves a half-written file ([`McapFile`]).

use std::collections::BTreeMap;
use std::path::Path;

use sim::SimConfig;
use sim::config::Side;
use sim::sensors::{LaserScan, Message, ScanSide};

use super::mcap_file::McapFile;
use super::topics::{
    CAMERA_FRAME, IMU_FRAME, LASER_BACK_FRAME, LASER_FRONT_FRAME, LIDAR_FRAME, Topic,
};
use super::{DatasetError, encode};

/// An MCAP recording being written; [`Recorder::finish`] puts it in place.
pub struct Recorder {
    file: McapFile,
    channels: BTreeMap<Topic, u16>,
    /// Per 2D scanner: scan period (s) and how long after its stamp a scan is complete (ns).
    scan_timing: [(f32, i64); 2],
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("target", &self.file.target())
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
        let mut file = McapFile::create(path)?;
        let mut channels = BTreeMap::new();
        for topic in Topic::ALL.into_iter().filter(|t| t.in_set(&sensors)) {
            let id = file.channel(topic.name(), topic.schema(), topic == Topic::TfStatic)?;
            channels.insert(topic, id);
        }
        file.metadata("vinebench", metadata)?;
        let s = &config.sensors;
        let mut recorder = Self {
            file,
            channels,
            scan_timing: [scan_timing(&s.scan2d_front), scan_timing(&s.scan2d_back)],
        };
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
        let channel = *self.channels.get(&topic).ok_or_else(|| {
            DatasetError::invalid(
                self.file.target(),
                format!("{} is not among the recorded sensors", topic.name()),
            )
        })?;
        self.file.put(channel, ready_ns, data)
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
    pub fn finish(self) -> Result<u64, DatasetError> {
        self.file.finish()
    }
}
