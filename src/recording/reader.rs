//! Reading recordings back: the one reader of our MCAP recordings, shared by
//! the daemon's replay, `analyze`, `report` and `diagnose`, and used to recover
//! what a crash left behind.
//!
//! [`RecordingReader`] is a pull API: [`RecordingReader::next_message`] hands out
//! one typed [`RecordedMessage`] at a time, reading the file linearly with the
//! `mcap` crate's sans-io reader, one top-level record at a time, so every error
//! can name its byte offset; memory is bounded by one chunk (a chunk is decoded
//! whole before any of its messages is handed out, so a damaged chunk yields
//! nothing). A [`Selection`] limits which of our messages are decoded (the others
//! are counted and skipped); [`RawReader`] is the selection of one gyro's raw
//! counts (`/gyro/raw` or `/gyro/<label>/raw`) that replay, `analyze` and
//! `diagnose` read. A *strict* reader wants a complete file (footer and end
//! magic; message count equal to the Statistics record when there is one); the
//! other kind accepts a file cut anywhere (a crash, `kill -9`, a full disk): it
//! stops after the last complete chunk and reports the offset where the file
//! breaks. [`read_recording`] and [`recover_recording`] collect a whole file with
//! them; channels of other topics are skipped and counted.
//!
//! The recording's `sagnac` Metadata record ([`crate::recording::meta`]: sample rate,
//! pulse weight, model, config) is read here too, and only here: every reader
//! reports it, and [`read_metadata`] reads just the start of a file for it (the
//! writers put it before any chunk), for the commands that must know the rate
//! before they read the samples (`analyze`, `diagnose`, the daemon's replay).

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};

use ::mcap::McapError;
use ::mcap::records::Record;
use ::mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::recording::messages::{MESSAGE_ENCODING, MessageError, RawBatch, SinkMessage, Topic};
use crate::recording::meta::{METADATA_NAME, MetaError, RecordingMeta};

/// Errors of the reader; each names the file and a byte offset.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be opened or read.
    #[error("cannot read {} at byte {offset}", path.display())]
    Io {
        path: PathBuf,
        offset: u64,
        source: io::Error,
    },
    /// The file does not start with the MCAP magic.
    #[error("{} is not an MCAP file (bad magic in the first 8 bytes)", path.display())]
    NotMcap { path: PathBuf },
    /// The MCAP structure is broken at `offset` (start of the offending record).
    #[error("{}: MCAP record at byte {offset} is unreadable", path.display())]
    Mcap {
        path: PathBuf,
        offset: u64,
        source: McapError,
    },
    /// A message of one of our topics does not decode (offset of its chunk record).
    #[error("{}: message #{sequence} on {topic} in the record at byte {offset}", path.display())]
    Message {
        path: PathBuf,
        offset: u64,
        topic: &'static str,
        sequence: u32,
        source: Box<MessageError>,
    },
    /// One of our topics is declared with another message encoding.
    #[error("{}: channel {topic} at byte {offset} has message encoding `{encoding}`, expected `json`", path.display())]
    Encoding {
        path: PathBuf,
        offset: u64,
        topic: &'static str,
        encoding: String,
    },
    /// The `sagnac` Metadata record does not describe a recording.
    #[error("{}: the sagnac metadata record at byte {offset}", path.display())]
    Metadata {
        path: PathBuf,
        offset: u64,
        source: MetaError,
    },
    /// A message refers to a channel that was never declared.
    #[error("{}: message in the record at byte {offset} refers to undeclared channel {channel_id}", path.display())]
    UnknownChannel {
        path: PathBuf,
        offset: u64,
        channel_id: u16,
    },
    /// The file ends inside the record starting at `offset`, or before the footer and
    /// end magic: it was cut (a crash); recovery reads it up to `offset`.
    #[error("{}: truncated: the file ends in or before the record at byte {offset} (no footer / end magic)", path.display())]
    Incomplete { path: PathBuf, offset: u64 },
    /// The Statistics record disagrees with the messages read.
    #[error("{}: Statistics record at byte {offset} counts {expected} messages, {read} were read", path.display())]
    CountMismatch {
        path: PathBuf,
        offset: u64,
        expected: u64,
        read: u64,
    },
}

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    /// MCAP log time, ns (the sample time).
    pub log_time_ns: u64,
    /// MCAP publish time, ns.
    pub publish_time_ns: u64,
    /// Per-channel sequence number.
    pub sequence: u32,
    pub message: SinkMessage,
    /// The gyro whose channel it is on (`/gyro/<label>/...` of a recording of
    /// several gyros); `None` on today's channels and the shared `/gyro/events`.
    pub gyro: Option<String>,
}

/// A complete recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// Messages in file order.
    pub messages: Vec<RecordedMessage>,
    /// Messages on topics that are not ours, skipped.
    pub foreign_messages: u64,
    /// File size, bytes.
    pub file_len: u64,
    /// The recording's `sagnac` metadata record, if it has one.
    pub metadata: Option<RecordingMeta>,
}

/// What could be recovered from a possibly truncated recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Recovery {
    /// Messages of every complete chunk before the break, in file order.
    pub messages: Vec<RecordedMessage>,
    /// Messages on topics that are not ours, skipped.
    pub foreign_messages: u64,
    /// Bytes up to the end of the last record read whole (the break offset when broken).
    pub recovered_bytes: u64,
    /// File size, bytes.
    pub file_len: u64,
    /// Where and why reading stopped, `None` for a complete file.
    pub break_at: Option<Break>,
    /// The recording's `sagnac` metadata record, if one was read.
    pub metadata: Option<RecordingMeta>,
}

/// Where a truncated or damaged recording stops being readable.
#[derive(Debug, Clone, PartialEq)]
pub struct Break {
    /// Start of the first record that could not be read, bytes.
    pub offset: u64,
    /// Why (the error text).
    pub reason: String,
}

impl Recovery {
    /// Whether the file was complete (footer and end magic read).
    pub fn is_complete(&self) -> bool {
        self.break_at.is_none()
    }
}

/// Read a complete recording; any damage or truncation is an error.
pub fn read_recording(path: &Path) -> Result<Recording, ReadError> {
    let (file, len) = open(path)?;
    read_impl(BufReader::new(file), len, path)
}

/// [`read_recording`] of a recording held in memory; `name` appears in errors.
pub fn read_recording_bytes(data: &[u8], name: &Path) -> Result<Recording, ReadError> {
    read_impl(data, data.len() as u64, name)
}

/// Read as much as possible of a recording that may be cut or damaged at its end.
/// Errors only when the file cannot be read or is not MCAP at all.
pub fn recover_recording(path: &Path) -> Result<Recovery, ReadError> {
    let (file, len) = open(path)?;
    recover_impl(BufReader::new(file), len, path)
}

/// [`recover_recording`] of a recording held in memory; `name` appears in errors.
pub fn recover_recording_bytes(data: &[u8], name: &Path) -> Result<Recovery, ReadError> {
    recover_impl(data, data.len() as u64, name)
}

fn open(path: &Path) -> Result<(File, u64), ReadError> {
    let io_err = |source| ReadError::Io {
        path: path.to_path_buf(),
        offset: 0,
        source,
    };
    let file = File::open(path).map_err(io_err)?;
    let len = file.metadata().map_err(io_err)?.len();
    Ok((file, len))
}

fn read_impl<R: Read>(input: R, len: u64, path: &Path) -> Result<Recording, ReadError> {
    let mut reader = RecordingReader::from_reader(input, len, path, true)?;
    let mut messages = Vec::new();
    while let Some(m) = reader.next_message()? {
        messages.push(m);
    }
    let report = reader.into_report();
    Ok(Recording {
        messages,
        foreign_messages: report.foreign_messages,
        file_len: report.file_len,
        metadata: report.metadata,
    })
}

fn recover_impl<R: Read>(input: R, len: u64, path: &Path) -> Result<Recovery, ReadError> {
    let mut reader = RecordingReader::from_reader(input, len, path, false)?;
    let mut messages = Vec::new();
    while let Some(m) = reader.next_message()? {
        messages.push(m);
    }
    let report = reader.into_report();
    Ok(Recovery {
        messages,
        foreign_messages: report.foreign_messages,
        recovered_bytes: report.recovered_bytes,
        file_len: report.file_len,
        break_at: report.break_at,
        metadata: report.metadata,
    })
}

/// What a reader has read so far (all of it once it returned `None`).
#[derive(Debug, Clone, PartialEq)]
pub struct ScanReport {
    /// Messages handed out.
    pub messages: u64,
    /// Messages on topics that are not ours, skipped.
    pub foreign_messages: u64,
    /// Messages of ours that the reader's [`Selection`] left undecoded.
    pub unselected_messages: u64,
    /// Bytes up to the end of the last record read whole.
    pub recovered_bytes: u64,
    /// File size, bytes.
    pub file_len: u64,
    /// Where reading stopped (only when `strict` is false; strict readers return the error).
    pub break_at: Option<Break>,
    /// The first `sagnac` metadata record read, if any.
    pub metadata: Option<RecordingMeta>,
}

/// Stream the messages of a recording to `each` without holding them all.
/// `strict`: like [`read_recording`] (errors on any damage); otherwise like
/// [`recover_recording`] (stops at the break).
pub fn scan_recording(
    path: &Path,
    strict: bool,
    each: &mut dyn FnMut(RecordedMessage),
) -> Result<ScanReport, ReadError> {
    let mut reader = RecordingReader::open(path, strict)?;
    while let Some(m) = reader.next_message()? {
        each(m);
    }
    Ok(reader.into_report())
}

/// Which of our messages a reader decodes; the others are counted
/// ([`ScanReport::unselected_messages`]) without being decoded.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Selection {
    /// Every message of our topics.
    #[default]
    All,
    /// Only the raw counts of one gyro: `/gyro/raw` for `None` (a recording of
    /// one gyro), `/gyro/<label>/raw` for `Some(label)`.
    Raw(Option<String>),
    /// The raw counts of every gyro.
    EveryRaw,
}

impl Selection {
    fn wants(&self, topic: Topic, gyro: Option<&str>) -> bool {
        match self {
            Selection::All => true,
            Selection::Raw(g) => topic == Topic::Raw && gyro == g.as_deref(),
            Selection::EveryRaw => topic == Topic::Raw,
        }
    }
}

/// The one reader of our recordings, with a pull API: [`RecordingReader::next_message`]
/// hands out the messages in file order, reading the file as it goes (memory is
/// bounded by one chunk). `strict` readers fail on any damage or truncation
/// ([`read_recording`]); the others stop at the break and report it in
/// [`ScanReport::break_at`] ([`recover_recording`]).
pub struct RecordingReader<R: Read = BufReader<File>> {
    input: R,
    reader: LinearReader,
    /// Offset of the next record to come out of `reader`.
    offset: u64,
    /// Bytes taken from `input`.
    bytes_read: u64,
    strict: bool,
    footer_seen: bool,
    /// (offset, message count) of the Statistics record.
    stats_count: Option<(u64, u64)>,
    done: bool,
    scanner: Scanner,
}

impl RecordingReader {
    /// Open the recording `path`.
    pub fn open(path: &Path, strict: bool) -> Result<RecordingReader, ReadError> {
        let (file, len) = open(path)?;
        RecordingReader::from_reader(BufReader::new(file), len, path, strict)
    }
}

impl<R: Read> RecordingReader<R> {
    /// A reader of `input`, `file_len` bytes long, called `name` in errors.
    pub fn from_reader(
        mut input: R,
        file_len: u64,
        name: &Path,
        strict: bool,
    ) -> Result<RecordingReader<R>, ReadError> {
        // Check the magic ourselves so that a file cut inside it is "empty", not "foreign".
        let mut magic = Vec::with_capacity(8);
        (&mut input)
            .take(8)
            .read_to_end(&mut magic)
            .map_err(|source| ReadError::Io {
                path: name.to_path_buf(),
                offset: 0,
                source,
            })?;
        if magic[..] != ::mcap::MAGIC[..magic.len()] {
            return Err(ReadError::NotMcap {
                path: name.to_path_buf(),
            });
        }
        let options = LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_check_finishes_after_end_magic(strict)
            .with_emit_chunks(true)
            // No record can be longer than the file: fail at once on a corrupt length.
            .with_record_length_limit(usize::try_from(file_len).unwrap_or(usize::MAX));
        let mut r = RecordingReader {
            input,
            reader: LinearReader::new_with_options(options),
            offset: 8,
            bytes_read: magic.len() as u64,
            strict,
            footer_seen: false,
            stats_count: None,
            done: false,
            scanner: Scanner::new(name, file_len, magic.len() as u64),
        };
        if magic.len() < 8 {
            r.scanner.report.recovered_bytes = 0;
            let e = r.scanner.mcap_error(0, McapError::UnexpectedEof);
            r.stop(0, e)?;
        }
        Ok(r)
    }

    /// Decode only the messages `selection` names.
    pub fn select(mut self, selection: Selection) -> Self {
        self.scanner.selection = selection;
        self
    }

    /// The next message, `None` at the end of the file (or at the break of a
    /// non-strict reader). A chunk's messages come out only once the whole
    /// chunk has decoded.
    pub fn next_message(&mut self) -> Result<Option<RecordedMessage>, ReadError> {
        loop {
            if let Some(m) = self.scanner.pending.pop_front() {
                return Ok(Some(m));
            }
            if self.done {
                return Ok(None);
            }
            self.step()?;
        }
    }

    /// Bytes of the file read so far.
    pub fn bytes_read(&self) -> u64 {
        self.bytes_read
    }

    /// What was read so far.
    pub fn report(&self) -> &ScanReport {
        &self.scanner.report
    }

    /// What was read.
    pub fn into_report(self) -> ScanReport {
        self.scanner.report
    }

    /// Stop at `offset` because of `error`: return it (strict) or report a break.
    fn stop(&mut self, offset: u64, error: ReadError) -> Result<(), ReadError> {
        self.done = true;
        if self.strict {
            return Err(error);
        }
        self.scanner.report.break_at = Some(Break {
            offset,
            reason: error.to_string(),
        });
        Ok(())
    }

    /// Take one event from the sans-io reader.
    fn step(&mut self) -> Result<(), ReadError> {
        let event = match self.reader.next_event() {
            None => return self.finish(),
            Some(Ok(e)) => e,
            Some(Err(e)) => {
                let e = self.scanner.mcap_error(self.offset, e);
                return self.stop(self.offset, e);
            }
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let buf = self.reader.insert(need.clamp(1, READ_BLOCK));
                let n = read_some(&mut self.input, buf).map_err(|source| {
                    self.done = true;
                    ReadError::Io {
                        path: self.scanner.path.clone(),
                        offset: self.offset,
                        source,
                    }
                })?;
                self.bytes_read += n as u64;
                self.reader.notify_read(n);
                Ok(())
            }
            LinearReadEvent::Record { data, opcode } => {
                let start = self.offset;
                let end = start + RECORD_PREFIX + data.len() as u64;
                let handled = if opcode == ::mcap::records::op::CHUNK {
                    self.scanner.chunk(opcode, data, start)
                } else {
                    self.scanner
                        .top_level(opcode, data, start)
                        .map(|seen| match seen {
                            TopLevel::Footer => self.footer_seen = true,
                            TopLevel::Statistics(count) => self.stats_count = Some((start, count)),
                            TopLevel::Other => {}
                        })
                };
                match handled {
                    Ok(()) => {
                        self.offset = end;
                        self.scanner.report.recovered_bytes = end;
                        Ok(())
                    }
                    Err(e) => self.stop(start, e),
                }
            }
        }
    }

    /// The sans-io reader is done: check that the file was whole.
    fn finish(&mut self) -> Result<(), ReadError> {
        self.done = true;
        // The reader only ends cleanly after the footer and the end magic.
        if !self.footer_seen {
            let e = self
                .scanner
                .mcap_error(self.offset, McapError::UnexpectedEof);
            return self.stop(self.offset, e);
        }
        let report = &mut self.scanner.report;
        report.recovered_bytes = self.offset + ::mcap::MAGIC.len() as u64;
        if let Some((at, expected)) = self.stats_count {
            let read = report.messages + report.foreign_messages + report.unselected_messages;
            if expected != read {
                let e = ReadError::CountMismatch {
                    path: self.scanner.path.clone(),
                    offset: at,
                    expected,
                    read,
                };
                return self.stop(at, e);
            }
        }
        Ok(())
    }
}

/// One gyro's raw counts in a recording (or every gyro's), pulled batch by
/// batch ([`RawReader::next_batch`]): what replay, `analyze` and `diagnose`
/// read. The recording's other channels are skipped without being decoded.
pub struct RawReader<R: Read = BufReader<File>> {
    inner: RecordingReader<R>,
}

impl RawReader {
    /// The `/gyro/raw` batches of `path` (of gyro `gyro`'s `/gyro/<label>/raw`
    /// when `Some`); `strict` as in [`RecordingReader`].
    pub fn open(path: &Path, gyro: Option<&str>, strict: bool) -> Result<RawReader, ReadError> {
        let (file, len) = open(path)?;
        RawReader::from_reader(BufReader::new(file), len, path, gyro, strict)
    }

    /// The raw batches of every gyro of `path`, in file order (see
    /// [`RawReader::next_labelled`]).
    pub fn open_every(path: &Path, strict: bool) -> Result<RawReader, ReadError> {
        Ok(RawReader {
            inner: RecordingReader::open(path, strict)?.select(Selection::EveryRaw),
        })
    }
}

impl<R: Read> RawReader<R> {
    /// [`RawReader::open`] of `input` (`file_len` bytes, called `name` in errors).
    pub fn from_reader(
        input: R,
        file_len: u64,
        name: &Path,
        gyro: Option<&str>,
        strict: bool,
    ) -> Result<RawReader<R>, ReadError> {
        let selection = Selection::Raw(gyro.map(str::to_string));
        Ok(RawReader {
            inner: RecordingReader::from_reader(input, file_len, name, strict)?.select(selection),
        })
    }

    /// The next batch of raw counts (with its gaps, sequence numbers, times,
    /// temperature and status as recorded), `None` at the end or at the break.
    pub fn next_batch(&mut self) -> Result<Option<RawBatch>, ReadError> {
        Ok(self.next_labelled()?.map(|(_, b)| b))
    }

    /// [`RawReader::next_batch`] with the gyro whose batch it is (`None`: the
    /// `/gyro/raw` of a recording of one gyro).
    pub fn next_labelled(&mut self) -> Result<Option<(Option<String>, RawBatch)>, ReadError> {
        while let Some(m) = self.inner.next_message()? {
            if let SinkMessage::Raw(b) = m.message {
                return Ok(Some((m.gyro, b)));
            }
        }
        Ok(None)
    }

    /// Bytes of the file read so far.
    pub fn bytes_read(&self) -> u64 {
        self.inner.bytes_read()
    }

    /// What was read so far; its `break_at` says where a cut file stopped.
    pub fn report(&self) -> &ScanReport {
        self.inner.report()
    }
}

/// The sample period (ns) of the first `/gyro/raw` batch (of gyro `gyro`) with
/// one, `None` when the recording has none; reads only up to that batch.
pub fn first_raw_period_ns(path: &Path, gyro: Option<&str>) -> Result<Option<u64>, ReadError> {
    let mut reader = RawReader::open(path, gyro, false)?;
    while let Some(b) = reader.next_batch()? {
        if b.dt_ns > 0 {
            return Ok(Some(b.dt_ns));
        }
    }
    Ok(None)
}

/// The `sagnac` metadata record of a recording, read from the start of the file
/// up to the first chunk or message (sagnac writes it right after the header;
/// a file without one before its data, such as a recording made before the
/// record existed, gives `None`). Cheap: it reads a few hundred bytes.
pub fn read_metadata(path: &Path) -> Result<Option<RecordingMeta>, ReadError> {
    read_metadata_of(path, None)
}

/// [`read_metadata`] of gyro `gyro` of a recording of several gyros (its
/// `sagnac/<label>` record); `None` reads the common `sagnac` record.
pub fn read_metadata_of(
    path: &Path,
    gyro: Option<&str>,
) -> Result<Option<RecordingMeta>, ReadError> {
    let wanted = gyro.map_or_else(
        || METADATA_NAME.to_string(),
        crate::recording::meta::gyro_metadata_name,
    );
    for (offset, m) in metadata_records(path)? {
        if m.name == wanted {
            return parse_metadata(&m, offset, path).map(Some);
        }
    }
    Ok(None)
}

/// The gyro labels of a recording of several gyros (from their `sagnac/<label>`
/// metadata records, in order); empty for a recording of one gyro.
pub fn recording_gyro_labels(path: &Path) -> Result<Vec<String>, ReadError> {
    let prefix = format!("{METADATA_NAME}/");
    Ok(metadata_records(path)?
        .into_iter()
        .filter_map(|(_, m)| m.name.strip_prefix(&prefix).map(str::to_string))
        .collect())
}

/// The Metadata records before the first chunk or message, with their offsets.
fn metadata_records(path: &Path) -> Result<Vec<(u64, ::mcap::records::Metadata)>, ReadError> {
    // strict: a file cut inside its magic is an error here
    let mut r = RecordingReader::open(path, true)?;
    let mut found = Vec::new();
    while let Some(event) = r.reader.next_event() {
        let start = r.offset;
        match event.map_err(|e| r.scanner.mcap_error(start, e))? {
            LinearReadEvent::ReadRequest(need) => {
                let buf = r.reader.insert(need.clamp(1, 4096));
                let n = read_some(&mut r.input, buf).map_err(|source| ReadError::Io {
                    path: path.to_path_buf(),
                    offset: start,
                    source,
                })?;
                r.reader.notify_read(n);
            }
            LinearReadEvent::Record { data, opcode } => {
                r.offset = start + RECORD_PREFIX + data.len() as u64;
                match opcode {
                    ::mcap::records::op::CHUNK | ::mcap::records::op::MESSAGE => return Ok(found),
                    ::mcap::records::op::METADATA => {
                        let record = ::mcap::parse_record(opcode, data)
                            .map_err(|e| r.scanner.mcap_error(start, e))?;
                        if let Record::Metadata(m) = record {
                            found.push((start, m));
                        }
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(found)
}

fn parse_metadata(
    m: &::mcap::records::Metadata,
    offset: u64,
    path: &Path,
) -> Result<RecordingMeta, ReadError> {
    RecordingMeta::from_map(&m.metadata).map_err(|source| ReadError::Metadata {
        path: path.to_path_buf(),
        offset,
        source,
    })
}

/// Bytes handed to the sans-io reader per read.
const READ_BLOCK: usize = 64 * 1024;
/// Largest chunk (compressed or not) the reader accepts, bytes: far above what the
/// recorder writes (`chunk_size` <= 256 MiB plus one message), far below what a
/// corrupt size field could ask for.
const MAX_CHUNK_BYTES: usize = 1 << 30;
/// Opcode (1) and length (8) before every record body.
const RECORD_PREFIX: u64 = 9;

/// The record-level half of a [`RecordingReader`]: channels, counts, and the
/// messages decoded and not yet handed out.
struct Scanner {
    path: PathBuf,
    selection: Selection,
    /// Declared channels: id -> our topic (and gyro), or None for a foreign one.
    channels: HashMap<u16, Option<(Topic, Option<String>)>>,
    report: ScanReport,
    pending: VecDeque<RecordedMessage>,
}

/// A top-level record other than a chunk, as far as the reader cares.
enum TopLevel {
    Footer,
    /// The Statistics record's message count.
    Statistics(u64),
    Other,
}

/// A record that may sit inside a chunk.
// Returned by value and consumed at once: boxing the message would allocate per message.
#[allow(clippy::large_enum_variant)]
enum Inner {
    /// One of our messages, decoded.
    Ours(RecordedMessage),
    /// One of our messages, not selected.
    Unselected,
    /// A message on a foreign topic.
    Foreign,
    /// Any other record.
    Other,
}

/// Read up to `buf.len()` bytes, retrying on interruption; 0 means end of file.
pub(crate) fn read_some(input: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    loop {
        match input.read(buf) {
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            other => return other,
        }
    }
}

impl Scanner {
    fn new(path: &Path, file_len: u64, recovered_bytes: u64) -> Scanner {
        Scanner {
            path: path.to_path_buf(),
            selection: Selection::All,
            channels: HashMap::new(),
            report: ScanReport {
                messages: 0,
                foreign_messages: 0,
                unselected_messages: 0,
                recovered_bytes,
                file_len,
                break_at: None,
                metadata: None,
            },
            pending: VecDeque::new(),
        }
    }

    /// The error for an MCAP failure in the record starting at `offset`; the end of
    /// the file inside a record (or where the end magic should be) is a truncation.
    fn mcap_error(&self, offset: u64, source: McapError) -> ReadError {
        // The record length limit is the file size, so "too large" means the record
        // (as declared) runs past the end of the file.
        let past_end = |len: u64| {
            offset.saturating_add(RECORD_PREFIX).saturating_add(len) > self.report.file_len
        };
        match source {
            McapError::UnexpectedEof => ReadError::Incomplete {
                path: self.path.clone(),
                offset,
            },
            McapError::RecordTooLarge { len, .. } if past_end(len) => ReadError::Incomplete {
                path: self.path.clone(),
                offset,
            },
            source => ReadError::Mcap {
                path: self.path.clone(),
                offset,
                source,
            },
        }
    }

    /// Decode a whole chunk record (body `body`, starting at `offset`) with its own
    /// sans-io reader: the chunk is decompressed and its CRC checked before any
    /// record is used, and `MAX_CHUNK_BYTES` bounds what a corrupt size field may
    /// make it allocate. Its messages are queued only if the whole chunk decodes.
    fn chunk(&mut self, opcode: u8, body: &[u8], offset: u64) -> Result<(), ReadError> {
        let mut prefix = [0u8; RECORD_PREFIX as usize];
        prefix[0] = opcode;
        prefix[1..].copy_from_slice(&(body.len() as u64).to_le_bytes());
        let mut input = prefix.as_slice().chain(body);
        let mut reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_skip_start_magic(true)
                .with_skip_end_magic(true)
                .with_prevalidate_chunk_crcs(true)
                .with_record_length_limit(MAX_CHUNK_BYTES),
        );
        let mut decoded = Vec::new();
        let (mut foreign, mut unselected) = (0, 0);
        while let Some(event) = reader.next_event() {
            match event.map_err(|e| self.mcap_error(offset, e))? {
                LinearReadEvent::ReadRequest(need) => {
                    let buf = reader.insert(need.clamp(1, READ_BLOCK));
                    let n = read_some(&mut input, buf)
                        .map_err(|e| self.mcap_error(offset, e.into()))?;
                    reader.notify_read(n);
                }
                LinearReadEvent::Record { data, opcode } => {
                    let record = ::mcap::parse_record(opcode, data)
                        .map_err(|e| self.mcap_error(offset, e))?;
                    match self.inner_record(record, offset)? {
                        Inner::Ours(m) => decoded.push(m),
                        Inner::Unselected => unselected += 1,
                        Inner::Foreign => foreign += 1,
                        Inner::Other => {}
                    }
                }
            }
        }
        // The chunk is whole: hand out its messages.
        self.report.messages += decoded.len() as u64;
        self.report.foreign_messages += foreign;
        self.report.unselected_messages += unselected;
        self.pending.extend(decoded);
        Ok(())
    }

    /// Handle one top-level record other than a chunk (`data`, starting at `offset`).
    fn top_level(&mut self, opcode: u8, data: &[u8], offset: u64) -> Result<TopLevel, ReadError> {
        let record = ::mcap::parse_record(opcode, data).map_err(|e| self.mcap_error(offset, e))?;
        let seen = match record {
            Record::Footer(_) => TopLevel::Footer,
            Record::Statistics(ref s) => TopLevel::Statistics(s.message_count),
            Record::Metadata(ref m)
                if m.name == METADATA_NAME && self.report.metadata.is_none() =>
            {
                self.report.metadata = Some(parse_metadata(m, offset, &self.path)?);
                TopLevel::Other
            }
            _ => TopLevel::Other,
        };
        match self.inner_record(record, offset)? {
            Inner::Ours(m) => {
                self.report.messages += 1;
                self.pending.push_back(m);
            }
            Inner::Unselected => self.report.unselected_messages += 1,
            Inner::Foreign => self.report.foreign_messages += 1,
            Inner::Other => {}
        }
        Ok(seen)
    }

    /// Handle a record that may sit inside a chunk (`offset`: where the record
    /// holding it starts).
    fn inner_record(&mut self, record: Record<'_>, offset: u64) -> Result<Inner, ReadError> {
        match record {
            Record::Channel(c) => {
                let topic = Topic::parse_channel(&c.topic);
                if let Some((t, _)) = &topic
                    && c.message_encoding != MESSAGE_ENCODING
                {
                    return Err(ReadError::Encoding {
                        path: self.path.clone(),
                        offset,
                        topic: t.name(),
                        encoding: c.message_encoding,
                    });
                }
                self.channels.insert(c.id, topic);
                Ok(Inner::Other)
            }
            Record::Message { header, data } => {
                let Some(channel) = self.channels.get(&header.channel_id) else {
                    return Err(ReadError::UnknownChannel {
                        path: self.path.clone(),
                        offset,
                        channel_id: header.channel_id,
                    });
                };
                let Some((topic, gyro)) = channel else {
                    return Ok(Inner::Foreign);
                };
                if !self.selection.wants(*topic, gyro.as_deref()) {
                    return Ok(Inner::Unselected);
                }
                let (topic, gyro) = (*topic, gyro.clone());
                let message =
                    SinkMessage::from_json(topic, &data).map_err(|source| ReadError::Message {
                        path: self.path.clone(),
                        offset,
                        topic: topic.name(),
                        sequence: header.sequence,
                        source: Box::new(source),
                    })?;
                Ok(Inner::Ours(RecordedMessage {
                    log_time_ns: header.log_time,
                    publish_time_ns: header.publish_time,
                    sequence: header.sequence,
                    message,
                    gyro,
                }))
            }
            _ => Ok(Inner::Other),
        }
    }
}
