//! An MCAP file of ROS 2 messages being written (MCAP format specification,
//! <https://mcap.dev/spec>, `ros2` profile: `ros2msg` schemas, `cdr` messages), shared by the
//! sensor recording ([`super::Recorder`]) and a run's results ([`super::write_results`]).
//!
//! No compression and no wall-clock time, so the same messages give byte-identical files.
//! The file is written under a temporary name beside the target and renamed when complete,
//! so a failed write never leaves a half-written file.

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use super::{DatasetError, EPOCH_NS, schemas};

/// Target size of an MCAP chunk (before any compression; none is used). A camera frame
/// (about 2.1 MB at 640 x 480) fits whole.
const CHUNK_BYTES: u64 = 4 << 20;

/// rosbag2's QoS for a latched topic (reliable, transient local), as `/tf_static` is
/// published, so `ros2 bag play` offers its messages to late subscribers too.
const LATCHED_QOS: &str = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 1\n  \
deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    \
nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    \
nsec: 4294967295\n  avoid_ros_namespace_conventions: false";

/// An MCAP file being written; [`McapFile::finish`] puts it in place, dropping it unfinished
/// removes the temporary file.
pub(crate) struct McapFile {
    writer: Option<mcap::Writer<BufWriter<File>>>,
    target: PathBuf,
    tmp: PathBuf,
    /// Schema ids by ROS 2 type name, each schema written once.
    schemas: BTreeMap<&'static str, u16>,
    /// The next sequence number of each channel.
    sequences: BTreeMap<u16, u32>,
}

impl McapFile {
    /// Starts writing `path` (under a temporary name beside it).
    pub fn create(path: &Path) -> Result<Self, DatasetError> {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .ok_or_else(|| DatasetError::invalid(path, "not a file name"))?;
        let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        let file = File::create(&tmp).map_err(DatasetError::io(path))?;
        let mut out = Self {
            writer: None,
            target: path.to_owned(),
            tmp,
            schemas: BTreeMap::new(),
            sequences: BTreeMap::new(),
        };
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(format!("vinebench {}", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_BYTES))
            .create(BufWriter::new(file))
            .map_err(DatasetError::mcap(path))?;
        out.writer = Some(writer);
        Ok(out)
    }

    pub fn target(&self) -> &Path {
        &self.target
    }

    fn writer(&mut self) -> &mut mcap::Writer<BufWriter<File>> {
        self.writer.as_mut().expect("open until finished")
    }

    /// Adds a `cdr` channel of ROS 2 type `schema` (`pkg/msg/Name`), its schema written the
    /// first time the type is used; `latched` gives it rosbag2's transient-local QoS.
    pub fn channel(
        &mut self,
        topic: &str,
        schema: &'static str,
        latched: bool,
    ) -> Result<u16, DatasetError> {
        let schema_id = match self.schemas.get(schema) {
            Some(&id) => id,
            None => {
                let text = schemas::schema(schema);
                let id = self
                    .writer()
                    .add_schema(schema, "ros2msg", text.as_bytes())
                    .map_err(DatasetError::mcap(&self.target))?;
                self.schemas.insert(schema, id);
                id
            }
        };
        let mut channel_meta = BTreeMap::new();
        if latched {
            channel_meta.insert("offered_qos_profiles".to_owned(), LATCHED_QOS.to_owned());
        }
        let id = self
            .writer()
            .add_channel(schema_id, topic, "cdr", &channel_meta)
            .map_err(DatasetError::mcap(&self.target))?;
        self.sequences.insert(id, 0);
        Ok(id)
    }

    /// Writes a metadata record.
    pub fn metadata(
        &mut self,
        name: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<(), DatasetError> {
        let record = mcap::records::Metadata {
            name: name.to_owned(),
            metadata,
        };
        self.writer()
            .write_metadata(&record)
            .map_err(DatasetError::mcap(&self.target))
    }

    /// Appends a message to `channel`, logged and published at simulated time `ready_ns`
    /// (offset by [`EPOCH_NS`]).
    pub fn put(&mut self, channel: u16, ready_ns: i64, data: &[u8]) -> Result<(), DatasetError> {
        let sequence = self
            .sequences
            .get_mut(&channel)
            .expect("channels come from McapFile::channel");
        let time = u64::try_from(ready_ns + EPOCH_NS).expect("simulated time after 1970");
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: *sequence,
            log_time: time,
            publish_time: time,
        };
        *sequence += 1;
        self.writer()
            .write_to_known_channel(&header, data)
            .map_err(DatasetError::mcap(&self.target))
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

impl Drop for McapFile {
    fn drop(&mut self) {
        // Only an unfinished file still has its temporary file.
        drop(self.writer.take());
        if self.tmp.exists() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}
