//! Reads a recording back into the simulator's messages, in file order.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read as _;
use std::path::{Path, PathBuf};

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use nalgebra::Isometry3;
use sim::SensorSet;
use sim::sensors::{Message, ScanSide};

use super::decode::Plane;
use super::topics::Topic;
use super::{DatasetError, EPOCH_NS, decode};

/// The messages of a recording made by [`super::Recorder`], exactly as the simulator made
/// them and in the same order; topics of sensors outside the chosen set, `/tf_static` and
/// topics it does not know are skipped. Streams the file (memory: one chunk).
pub struct Replay {
    path: PathBuf,
    file: File,
    reader: LinearReader,
    sensors: SensorSet,
    /// Channel id → its topic, or `None` for a topic that is skipped.
    channels: BTreeMap<u16, Option<Topic>>,
    /// Schema id → schema name.
    schemas: BTreeMap<u16, String>,
    /// A `/ground_truth` pose waiting for its `/ground_truth/twist`.
    pose: Option<(i64, Isometry3<f64>)>,
    /// A camera frame's colour and depth images waiting for its camera info.
    color: Option<Plane<u8>>,
    depth: Option<Plane<f32>>,
    done: bool,
}

impl std::fmt::Debug for Replay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replay")
            .field("path", &self.path)
            .field("sensors", &self.sensors)
            .finish_non_exhaustive()
    }
}

impl Replay {
    pub fn open(path: &Path, sensors: SensorSet) -> Result<Self, DatasetError> {
        let file = File::open(path).map_err(DatasetError::io(path))?;
        let options = LinearReaderOptions::default()
            .with_validate_chunk_crcs(true)
            .with_validate_data_section_crc(true);
        Ok(Self {
            path: path.to_owned(),
            file,
            reader: LinearReader::new_with_options(options),
            sensors,
            channels: BTreeMap::new(),
            schemas: BTreeMap::new(),
            pose: None,
            color: None,
            depth: None,
            done: false,
        })
    }

    fn add_channel(&mut self, channel: mcap::records::Channel) -> Result<(), DatasetError> {
        let topic = Topic::from_name(&channel.topic).filter(|t| t.in_set(&self.sensors));
        if let Some(topic) = topic.filter(|&t| t != Topic::TfStatic) {
            let schema = self.schemas.get(&channel.schema_id).map(String::as_str);
            if schema != Some(topic.schema()) || channel.message_encoding != "cdr" {
                return Err(DatasetError::invalid(
                    &self.path,
                    format!(
                        "{} is {} in {}, expected {} in cdr",
                        channel.topic,
                        schema.unwrap_or("without a schema"),
                        channel.message_encoding,
                        topic.schema()
                    ),
                ));
            }
        }
        self.channels
            .insert(channel.id, topic.filter(|&t| t != Topic::TfStatic));
        Ok(())
    }

    /// Decodes one message of a topic that is replayed; `None` for the first half of a
    /// ground truth (its pose) and the images of a camera frame before its camera info.
    fn decode(
        &mut self,
        topic: Topic,
        log_time: u64,
        data: &[u8],
    ) -> Result<Option<Message>, DatasetError> {
        let ready_ns = log_time as i64 - EPOCH_NS;
        Ok(Some(match topic {
            Topic::Imu => Message::Imu(decode::imu(data)?),
            Topic::Odom => Message::WheelOdometry(decode::odometry(data)?),
            Topic::Points => Message::Lidar(decode::point_cloud(data, ready_ns)?),
            Topic::ScanFront => Message::Scan2d(decode::laser_scan(data, ScanSide::Front)?),
            Topic::ScanBack => Message::Scan2d(decode::laser_scan(data, ScanSide::Back)?),
            Topic::GroundTruth => {
                self.pose = Some(decode::pose_stamped(data)?);
                return Ok(None);
            }
            Topic::GroundTruthTwist => {
                let pose = self
                    .pose
                    .take()
                    .ok_or_else(|| DatasetError::decode("a twist without the pose before it"))?;
                Message::GroundTruth(decode::twist_stamped(data, pose)?)
            }
            Topic::ColorImage => {
                if self.color.is_some() {
                    return Err(DatasetError::decode(
                        "a colour image follows one without its camera info",
                    ));
                }
                self.color = Some(decode::color_image(data)?);
                return Ok(None);
            }
            Topic::DepthImage => {
                if self.color.is_none() || self.depth.is_some() {
                    return Err(DatasetError::decode(
                        "a depth image without a colour image just before it",
                    ));
                }
                self.depth = Some(decode::depth_image(data)?);
                return Ok(None);
            }
            Topic::CameraInfo => {
                let (Some(color), Some(depth)) = (self.color.take(), self.depth.take()) else {
                    return Err(DatasetError::decode(
                        "a camera info without the colour and depth images before it",
                    ));
                };
                Message::Rgbd(decode::camera_info(data, color, depth)?)
            }
            Topic::TfStatic => return Ok(None),
        }))
    }

    fn next_message(&mut self) -> Result<Option<Message>, DatasetError> {
        while !self.done {
            let Some(event) = self.reader.next_event() else {
                break;
            };
            let record = match event.map_err(DatasetError::mcap(&self.path))? {
                LinearReadEvent::ReadRequest(need) => {
                    let read = self
                        .file
                        .read(self.reader.insert(need))
                        .map_err(DatasetError::io(&self.path))?;
                    self.reader.notify_read(read);
                    continue;
                }
                LinearReadEvent::Record { opcode, data } => {
                    mcap::parse_record(opcode, data).map_err(DatasetError::mcap(&self.path))?
                }
            };
            match record {
                Record::Schema { header, .. } => {
                    self.schemas.insert(header.id, header.name);
                }
                Record::Channel(channel) => self.add_channel(channel)?,
                Record::Message { header, data } => {
                    let topic = *self.channels.get(&header.channel_id).ok_or_else(|| {
                        DatasetError::invalid(
                            &self.path,
                            format!("a message on unknown channel {}", header.channel_id),
                        )
                    })?;
                    let Some(topic) = topic else { continue };
                    // `data` borrows the reader; decoding needs `self` for the pending pose.
                    let data = data.into_owned();
                    let decoded = self.decode(topic, header.log_time, &data).map_err(|e| {
                        DatasetError::invalid(
                            &self.path,
                            format!("{} message {}: {e}", topic.name(), header.sequence),
                        )
                    })?;
                    if decoded.is_some() {
                        return Ok(decoded);
                    }
                }
                // The summary after the data section repeats schemas and channels only.
                Record::DataEnd(_) => self.done = true,
                _ => {}
            }
        }
        self.done = true;
        Ok(None)
    }
}

impl Iterator for Replay {
    type Item = Result<Message, DatasetError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let next = self.next_message();
        self.done |= next.is_err();
        next.transpose()
    }
}

/// The messages of the recording at `path` for `sensors`, for feeding a plugin as the live
/// [`sim::Simulation::stream`] would. The whole file is read and decoded once first, so a
/// damaged or foreign file is an error here, before anything is fed; the iterator then
/// streams the file again. It panics only if the file changes on disk in between.
pub fn replay_messages(
    path: &Path,
    sensors: SensorSet,
) -> anyhow::Result<impl Iterator<Item = Message>> {
    for message in Replay::open(path, sensors)? {
        message?;
    }
    let replay = Replay::open(path, sensors)?;
    Ok(replay.map(|m| m.unwrap_or_else(|e| panic!("{e} (the file changed during the replay)"))))
}
