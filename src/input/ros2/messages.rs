//! The Imu messages of a bag, pulled one at a time: each file read linearly
//! with the `mcap` crate's sans-io reader (chunks decompressed, zstd or lz4),
//! its schemas and channels noted as they come, and the messages of the
//! wanted Imu topics decoded. Memory is one chunk at a time.

use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::PathBuf;
use std::sync::Arc;

use ::mcap::records::Record;
use ::mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::Ros2Error;
use super::bag::Bag;
use super::imu::{self, IMU_NAMES, ImuSample};
use crate::recording::reader::read_some;

/// Bytes asked of a file at a time.
const READ_BLOCK: usize = 1 << 16;

/// A topic of the bag and its type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// The schema name (`sensor_msgs/msg/Imu`, ...).
    pub type_name: String,
    /// Whether its messages are Imu messages in CDR that sagnac decodes.
    pub imu: bool,
}

/// A channel of the file being read: its topic, and whether it is wanted.
#[derive(Debug, Clone)]
struct ChannelUse {
    topic: Arc<str>,
    wanted: bool,
}

struct FileReader {
    path: PathBuf,
    input: Box<dyn Read + Send>,
    reader: LinearReader,
    bytes_read: u64,
    /// Schema id -> (name, an Imu in ros2msg).
    schemas: HashMap<u16, (String, bool)>,
    channels: HashMap<u16, ChannelUse>,
}

/// The Imu messages of some topics of a bag, in bag order.
pub struct ImuMessages {
    bag: Bag,
    /// `None`: every Imu topic.
    want: Option<String>,
    next_file: usize,
    file: Option<FileReader>,
    /// Every topic met so far, with its type.
    pub topics: BTreeMap<String, TopicInfo>,
}

impl ImuMessages {
    /// The messages of `want` (or of every Imu topic) in `bag`.
    pub fn new(bag: Bag, want: Option<String>) -> Self {
        ImuMessages {
            bag,
            want,
            next_file: 0,
            file: None,
            topics: BTreeMap::new(),
        }
    }

    /// The next message of a wanted topic, and its topic; `None` at the end.
    pub fn next_message(&mut self) -> Result<Option<(Arc<str>, ImuSample)>, Ros2Error> {
        loop {
            if self.file.is_none() {
                let Some(path) = self.bag.files.get(self.next_file).cloned() else {
                    return Ok(None);
                };
                self.next_file += 1;
                self.file = Some(FileReader::open(&self.bag, path)?);
            }
            let f = self.file.as_mut().expect("a file is open");
            match f.step(self.want.as_deref(), &mut self.topics)? {
                Step::Message(topic, s) => return Ok(Some((topic, s))),
                Step::More => {}
                Step::End => self.file = None,
            }
        }
    }
}

enum Step {
    Message(Arc<str>, ImuSample),
    More,
    End,
}

impl FileReader {
    fn open(bag: &Bag, path: PathBuf) -> Result<FileReader, Ros2Error> {
        let mut input = bag.reader(&path)?;
        let mut magic = [0u8; 8];
        input
            .read_exact(&mut magic)
            .map_err(|e| Ros2Error::io(&path, e))?;
        if magic != *::mcap::MAGIC {
            return Err(Ros2Error::NotMcap { path });
        }
        let options = LinearReaderOptions::default().with_skip_start_magic(true);
        Ok(FileReader {
            path,
            input,
            reader: LinearReader::new_with_options(options),
            bytes_read: 8,
            schemas: HashMap::new(),
            channels: HashMap::new(),
        })
    }

    fn broken(&self, reason: String) -> Ros2Error {
        Ros2Error::Broken {
            path: self.path.clone(),
            offset: self.bytes_read,
            reason,
        }
    }

    /// One event of the sans-io reader.
    fn step(
        &mut self,
        want: Option<&str>,
        topics: &mut BTreeMap<String, TopicInfo>,
    ) -> Result<Step, Ros2Error> {
        let event = match self.reader.next_event() {
            None => return Ok(Step::End),
            Some(Ok(e)) => e,
            Some(Err(e)) => return Err(self.broken(e.to_string())),
        };
        let (opcode, data) = match event {
            LinearReadEvent::ReadRequest(need) => {
                let buf = self.reader.insert(need.clamp(1, READ_BLOCK));
                let n =
                    read_some(&mut self.input, buf).map_err(|e| Ros2Error::io(&self.path, e))?;
                self.bytes_read += n as u64;
                self.reader.notify_read(n);
                return Ok(Step::More);
            }
            LinearReadEvent::Record { opcode, data } => (opcode, data),
        };
        let record = ::mcap::parse_record(opcode, data).map_err(|e| Ros2Error::Broken {
            path: self.path.clone(),
            offset: self.bytes_read,
            reason: e.to_string(),
        })?;
        match record {
            Record::Schema { header, data } => {
                let imu = IMU_NAMES.contains(&header.name.as_str()) && header.encoding == "ros2msg";
                if imu {
                    let text = String::from_utf8_lossy(&data);
                    imu::check_schema(&text).map_err(|reason| Ros2Error::Schema {
                        path: self.path.clone(),
                        name: header.name.clone(),
                        reason,
                    })?;
                }
                self.schemas.insert(header.id, (header.name, imu));
            }
            Record::Channel(c) => {
                let (type_name, imu) = self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                let imu = imu && c.message_encoding == "cdr";
                topics
                    .entry(c.topic.clone())
                    .or_insert(TopicInfo { type_name, imu });
                let wanted = imu && want.is_none_or(|w| w == c.topic);
                self.channels.insert(
                    c.id,
                    ChannelUse {
                        topic: c.topic.into(),
                        wanted,
                    },
                );
            }
            Record::Message { header, data } => {
                let Some(ch) = self.channels.get(&header.channel_id) else {
                    return Err(self.broken(format!(
                        "a message refers to channel {}, which was never declared",
                        header.channel_id
                    )));
                };
                if ch.wanted {
                    let s = imu::decode(&data).map_err(|reason| Ros2Error::Message {
                        path: self.path.clone(),
                        topic: ch.topic.to_string(),
                        sequence: header.sequence,
                        reason,
                    })?;
                    return Ok(Step::Message(ch.topic.clone(), s));
                }
            }
            _ => {}
        }
        Ok(Step::More)
    }
}
