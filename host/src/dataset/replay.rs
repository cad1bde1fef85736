//! Reads a recording back into the simulator's messages, in file order.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use mcap::records::{Record, op};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use sim::SensorSet;
use sim::sensors::Message;

use super::topics::Topic;
use super::wire::Assembler;
use super::{DatasetError, EPOCH_NS};

/// Largest MCAP record a recording may hold, bytes (chunks by their compressed and their
/// uncompressed length). A recording's chunks are about 4 MiB (`mcap_file.rs`) plus at
/// most one message, and its largest message is a camera frame's depth image (33 MB at
/// 3840 x 2160): anything larger is a damaged file, refused before its length is allocated.
const MAX_RECORD_BYTES: usize = 256 << 20;

/// The messages of a recording made by [`super::Recorder`], exactly as the simulator made
/// them and in the same order; topics of sensors outside the chosen set, `/tf_static` and
/// topics it does not know are skipped. Streams the file (memory: one chunk), or any other
/// source of its bytes ([`Replay::from_reader`]).
pub struct Replay<R = File> {
    path: PathBuf,
    source: R,
    reader: LinearReader,
    sensors: SensorSet,
    /// Channel id → its topic, or `None` for a topic that is skipped.
    channels: BTreeMap<u16, Option<Topic>>,
    /// Schema id → schema name.
    schemas: BTreeMap<u16, String>,
    /// The messages of a ground truth or camera frame read so far.
    assembler: Assembler,
    /// The records of the chunk being read, and where the next one starts.
    chunk: Vec<u8>,
    chunk_at: usize,
    done: bool,
}

impl<R> std::fmt::Debug for Replay<R> {
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
        Ok(Replay::from_reader(path, file, sensors))
    }
}

impl<R: Read> Replay<R> {
    /// A recording's bytes read from `source`; `path` only names it in errors.
    pub fn from_reader(path: &Path, source: R, sensors: SensorSet) -> Self {
        // Chunks are read here, not by the crate (see `chunk_record`).
        let options = LinearReaderOptions::default()
            .with_emit_chunks(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(MAX_RECORD_BYTES);
        Self {
            path: path.to_owned(),
            source,
            reader: LinearReader::new_with_options(options),
            sensors,
            channels: BTreeMap::new(),
            schemas: BTreeMap::new(),
            assembler: Assembler::default(),
            chunk: Vec::new(),
            chunk_at: 0,
            done: false,
        }
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

    fn next_message(&mut self) -> Result<Option<(i64, Message)>, DatasetError> {
        while !self.done {
            // The records of the chunk being read, then the file's next record.
            if self.chunk_at < self.chunk.len() {
                let chunk = std::mem::take(&mut self.chunk);
                let found = self.chunk_record(&chunk);
                self.chunk = chunk;
                match found? {
                    Some(message) => return Ok(Some(message)),
                    None => continue,
                }
            }
            let Some(event) = self.reader.next_event() else {
                break;
            };
            let (opcode, data) = match event.map_err(DatasetError::mcap(&self.path))? {
                LinearReadEvent::ReadRequest(need) => {
                    let read = self
                        .source
                        .read(self.reader.insert(need))
                        .map_err(DatasetError::io(&self.path))?;
                    self.reader.notify_read(read);
                    continue;
                }
                LinearReadEvent::Record { opcode, data } => (opcode, data),
            };
            if opcode == op::CHUNK {
                let bad = |why: String| DatasetError::invalid(&self.path, format!("chunk: {why}"));
                if !strings_fit(opcode, data) {
                    return Err(bad("its compression's name runs past it".into()));
                }
                let Record::Chunk { header, data } =
                    mcap::parse_record(opcode, data).map_err(DatasetError::mcap(&self.path))?
                else {
                    return Err(bad("not a chunk".into()));
                };
                if !header.compression.is_empty() {
                    return Err(bad(format!(
                        "compressed ({}); vinebench records none",
                        header.compression
                    )));
                }
                if header.uncompressed_size != data.len() as u64 {
                    return Err(bad(format!(
                        "{} bytes of records, its header says {}",
                        data.len(),
                        header.uncompressed_size
                    )));
                }
                let crc = crc32fast::hash(&data);
                if header.uncompressed_crc != 0 && header.uncompressed_crc != crc {
                    return Err(bad(format!(
                        "CRC {crc:08x}, its header says {:08x}",
                        header.uncompressed_crc
                    )));
                }
                self.chunk.clear();
                self.chunk.extend_from_slice(&data);
                self.chunk_at = 0;
                continue;
            }
            let data = data.to_vec();
            if let Some(message) = self.record(opcode, &data)? {
                return Ok(Some(message));
            }
        }
        self.done = true;
        Ok(None)
    }

    /// The next record of the chunk being read: its records must tile it exactly (the mcap
    /// crate's own chunk reading underflows on a record that runs past its chunk).
    fn chunk_record(&mut self, chunk: &[u8]) -> Result<Option<(i64, Message)>, DatasetError> {
        let at = self.chunk_at;
        let bad = || DatasetError::invalid(&self.path, "chunk: a record runs past its end");
        let head = chunk.get(at..at + 9).ok_or_else(bad)?;
        let opcode = head[0];
        let len = u64::from_le_bytes(head[1..].try_into().expect("8 bytes"));
        let end = usize::try_from(len)
            .ok()
            .and_then(|len| (at + 9).checked_add(len))
            .filter(|&end| end <= chunk.len())
            .ok_or_else(bad)?;
        self.chunk_at = end;
        self.record(opcode, &chunk[at + 9..end])
    }

    /// Takes one record (in a chunk or not); returns the message it completes, with when it
    /// became available (its `log_time` on the simulator's clock).
    fn record(&mut self, opcode: u8, data: &[u8]) -> Result<Option<(i64, Message)>, DatasetError> {
        let record = match opcode {
            op::SCHEMA | op::CHANNEL | op::MESSAGE | op::DATA_END => {
                if !strings_fit(opcode, data) {
                    return Err(DatasetError::invalid(
                        &self.path,
                        format!("record {opcode:#04x}: a string runs past the record"),
                    ));
                }
                mcap::parse_record(opcode, data).map_err(DatasetError::mcap(&self.path))?
            }
            // The header, footer, metadata, attachments, indexes and statistics: nothing a
            // replay uses, so not parsed.
            _ => return Ok(None),
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
                let Some(topic) = topic else {
                    return Ok(None);
                };
                let ready_ns = i64::try_from(header.log_time)
                    .map(|t| t - EPOCH_NS)
                    .map_err(|_| {
                        DatasetError::invalid(
                            &self.path,
                            format!(
                                "{} message {}: log time {} ns is past any ROS time",
                                topic.name(),
                                header.sequence,
                                header.log_time
                            ),
                        )
                    })?;
                let message = self.assembler.push(topic, ready_ns, &data).map_err(|e| {
                    DatasetError::invalid(
                        &self.path,
                        format!("{} message {}: {e}", topic.name(), header.sequence),
                    )
                })?;
                return Ok(message.map(|m| (ready_ns, m)));
            }
            // The summary after the data section repeats schemas and channels only.
            Record::DataEnd(_) => self.done = true,
            _ => {}
        }
        Ok(None)
    }
}

impl<R: Read> Iterator for Replay<R> {
    type Item = Result<Message, DatasetError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_timed().map(|m| m.map(|(_, m)| m))
    }
}

impl<R: Read> Replay<R> {
    /// The next message with the time it became available on the simulator's clock (its
    /// `log_time` less [`EPOCH_NS`]: a sweep's end, anything else its stamp, a GNSS epoch
    /// after the receiver's latency), the time the live stream orders messages by.
    pub fn next_timed(&mut self) -> Option<Result<(i64, Message), DatasetError>> {
        if self.done {
            return None;
        }
        let next = self.next_message();
        self.done |= next.is_err();
        next.transpose()
    }
}

/// Whether every string of a schema or channel record (a `u32` length, then that many
/// bytes) lies within the record. The mcap crate reserves a string's declared length before
/// it reads the string, so a damaged length would allocate up to 4 GiB.
fn strings_fit(opcode: u8, data: &[u8]) -> bool {
    // The end of the string at `at`, if it fits.
    let string = |at: usize| -> Option<usize> {
        let len = u32::from_le_bytes(data.get(at..at.checked_add(4)?)?.try_into().ok()?);
        at.checked_add(4 + len as usize)
            .filter(|&end| end <= data.len())
    };
    let fits = || -> Option<()> {
        match opcode {
            // Times, size and CRC, then the compression's name.
            op::CHUNK => {
                string(28)?;
            }
            // id, name, encoding (the schema's data the crate checks itself).
            op::SCHEMA => {
                string(2).and_then(string)?;
            }
            // id, schema id, topic, message encoding, then the metadata: its length in
            // bytes, and key and value strings until that many are read.
            op::CHANNEL => {
                let map = string(4).and_then(string)?;
                let map_end = string(map)?;
                let mut at = map + 4;
                while at < map_end {
                    at = string(at).and_then(string)?;
                }
            }
            _ => {}
        }
        Some(())
    };
    fits().is_some()
}

/// The messages of the recording at `path` for `sensors`, for feeding a plugin as the live
/// [`sim::Simulation::stream`] would. The whole file is read and decoded once first, so a
/// damaged or foreign file is an error here, before anything is fed; the iterator then
/// streams the file again. It panics only if the file changes on disk in between.
pub fn replay_messages(
    path: &Path,
    sensors: SensorSet,
) -> anyhow::Result<impl Iterator<Item = Message>> {
    Ok(checked_replay(path, sensors)?.map(|(_, m)| m))
}

/// The recording at `path` read and decoded whole once (an error here for a damaged or
/// foreign file), then streamed again, each message with when it became available
/// ([`Replay::next_timed`]); panics only if the file changes on disk in between.
fn checked_replay(
    path: &Path,
    sensors: SensorSet,
) -> anyhow::Result<impl Iterator<Item = (i64, Message)> + Send + use<>> {
    for message in Replay::open(path, sensors)? {
        message?;
    }
    let mut replay = Replay::open(path, sensors)?;
    Ok(std::iter::from_fn(move || {
        replay
            .next_timed()
            .map(|m| m.unwrap_or_else(|e| panic!("{e} (the file changed during the replay)")))
    }))
}

/// [`replay_messages`] with `live`'s messages merged in where a live stream of both would
/// put them: by the time each becomes available, a recorded message first at a tie (the
/// simulator lists the GNSS receiver after every other sensor). `live` is the run's own
/// GNSS receiver (`runner::record`: a recording made once for every receiver of a sweep
/// leaves GNSS out), whose epochs become available after its latency; any other message
/// it yields counts as available at its stamp.
pub fn replay_with_live<'a>(
    path: &Path,
    sensors: SensorSet,
    live: impl Iterator<Item = Message> + Send + 'a,
) -> anyhow::Result<impl Iterator<Item = Message> + Send + 'a> {
    Ok(Merge {
        recorded: checked_replay(path, sensors)?.peekable(),
        live: live.peekable(),
    })
}

/// When a live message becomes available on the simulator's clock.
fn live_ready_ns(message: &Message) -> i64 {
    match message {
        Message::Gnss(fix) => fix.stamp_ns + fix.latency_ns,
        m => m.stamp_ns(),
    }
}

/// Two streams in order of availability, the recorded one first at a tie.
struct Merge<A: Iterator, B: Iterator> {
    recorded: std::iter::Peekable<A>,
    live: std::iter::Peekable<B>,
}

impl<A, B> Iterator for Merge<A, B>
where
    A: Iterator<Item = (i64, Message)>,
    B: Iterator<Item = Message>,
{
    type Item = Message;

    fn next(&mut self) -> Option<Message> {
        let live = self.live.peek().map(live_ready_ns);
        match (self.recorded.peek(), live) {
            (Some(&(recorded, _)), Some(live)) if live < recorded => self.live.next(),
            (Some(_), _) => self.recorded.next().map(|(_, m)| m),
            (None, _) => self.live.next(),
        }
    }
}
