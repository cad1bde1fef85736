//! Writes a simulated stream as an MCAP file of ROS 2 messages.
//!
//! The file is written under a temporary name beside the target and renamed when complete,
//! so a failed recording never leaves a half-written file ([`McapFile`]).

use std::collections::BTreeMap;
use std::path::Path;

use sim::SimConfig;
use sim::config::Side;
use sim::sensors::Message;

use super::mcap_file::McapFile;
use super::topics::{
    CAMERA_FRAME, GNSS_FRAME, IMU_FRAME, LASER_BACK_FRAME, LASER_FRONT_FRAME, LIDAR_FRAME, Topic,
};
use super::wire::{WireDetails, to_ros};
use super::{DatasetError, encode};

/// An MCAP recording being written; [`Recorder::finish`] puts it in place.
pub struct Recorder {
    file: McapFile,
    channels: BTreeMap<Topic, u16>,
    wire_details: WireDetails,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("target", &self.file.target())
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
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
        // GNSS channels only where the world has a receiver.
        let has = |t: &Topic| {
            !matches!(t, Topic::GnssFix | Topic::GnssEnu) || !config.sensors.gnss.is_absent()
        };
        for topic in Topic::ALL
            .into_iter()
            .filter(|t| t.in_set(&sensors) && has(t))
        {
            let id = file.channel(topic.name(), topic.schema(), topic == Topic::TfStatic)?;
            channels.insert(topic, id);
        }
        file.metadata("vinebench", metadata)?;
        let s = &config.sensors;
        let mut recorder = Self {
            file,
            channels,
            wire_details: WireDetails::new(config),
        };
        let [x, y, z] = s.gnss.mount_xyz_m;
        let gnss =
            (!s.gnss.is_absent()).then(|| (GNSS_FRAME, nalgebra::Isometry3::translation(x, y, z)));
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
        let mounts: Vec<_> = mounts.into_iter().chain(gnss).collect();
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

    /// Appends one message, logged at the time it became available.
    pub fn write(&mut self, message: &Message) -> Result<(), DatasetError> {
        for (topic, ready_ns, data) in to_ros(message, &self.wire_details) {
            self.put(topic, ready_ns, &data)?;
        }
        Ok(())
    }

    /// Writes the summary, flushes and moves the file into place; returns its size in bytes.
    pub fn finish(self) -> Result<u64, DatasetError> {
        self.file.finish()
    }
}
