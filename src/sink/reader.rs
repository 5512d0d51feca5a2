//! Reading recordings back: for replay and `analyze --format mcap`, and to recover
//! what a crash left behind.
//!
//! Both paths read the file linearly with the `mcap` crate's sans-io reader, one
//! top-level record at a time, so every error can name its byte offset; a chunk
//! is decoded whole before any of its messages is handed out, so a damaged chunk
//! yields nothing. [`read_recording`] wants a complete file (footer and end magic;
//! message count equal to the Statistics record when there is one).
//! [`recover_recording`] accepts a file cut anywhere (a crash, `kill -9`, a full
//! disk): it keeps every message up to the last complete chunk and reports the
//! offset where the file breaks. Messages come back as typed [`SinkMessage`]s;
//! channels of other topics are skipped and counted.
//!
//! The recording's `sagnac` Metadata record ([`crate::sink::meta`]: sample rate,
//! pulse weight, model, config) is read here too, and only here: every scan
//! returns it, and [`read_metadata`] reads just the start of a file for it (the
//! writers put it before any chunk), for the commands that must know the rate
//! before they read the samples (`analyze`, `diagnose`, the daemon's replay).

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::{Path, PathBuf};

use ::mcap::McapError;
use ::mcap::records::Record;
use ::mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::sink::messages::{MESSAGE_ENCODING, MessageError, SinkMessage, Topic};
use crate::sink::meta::{METADATA_NAME, MetaError, RecordingMeta};

/// Errors of the reader; each names the file and a byte offset.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be opened or read.
    #[error("cannot read {} at byte {offset}: {source}", path.display())]
    Io {
        path: PathBuf,
        offset: u64,
        source: io::Error,
    },
    /// The file does not start with the MCAP magic.
    #[error("{} is not an MCAP file (bad magic in the first 8 bytes)", path.display())]
    NotMcap { path: PathBuf },
    /// The MCAP structure is broken at `offset` (start of the offending record).
    #[error("{}: MCAP record at byte {offset} is unreadable: {source}", path.display())]
    Mcap {
        path: PathBuf,
        offset: u64,
        source: McapError,
    },
    /// A message of one of our topics does not decode (offset of its chunk record).
    #[error("{}: message #{sequence} on {topic} in the record at byte {offset}: {source}", path.display())]
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
    #[error("{}: the sagnac metadata record at byte {offset}: {source}", path.display())]
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
    read_impl(&mut BufReader::new(file), len, path)
}

/// [`read_recording`] of a recording held in memory; `name` appears in errors.
pub fn read_recording_bytes(data: &[u8], name: &Path) -> Result<Recording, ReadError> {
    read_impl(&mut &data[..], data.len() as u64, name)
}

/// Read as much as possible of a recording that may be cut or damaged at its end.
/// Errors only when the file cannot be read or is not MCAP at all.
pub fn recover_recording(path: &Path) -> Result<Recovery, ReadError> {
    let (file, len) = open(path)?;
    recover_impl(&mut BufReader::new(file), len, path)
}

/// [`recover_recording`] of a recording held in memory; `name` appears in errors.
pub fn recover_recording_bytes(data: &[u8], name: &Path) -> Result<Recovery, ReadError> {
    recover_impl(&mut &data[..], data.len() as u64, name)
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

fn read_impl(input: &mut dyn Read, len: u64, path: &Path) -> Result<Recording, ReadError> {
    let mut messages = Vec::new();
    let report = scan(input, len, path, true, &mut |m| messages.push(m))?;
    if let Some(b) = report.break_at {
        // Unreachable in strict mode (scan returns the error), kept as a guard.
        return Err(ReadError::Incomplete {
            path: path.to_path_buf(),
            offset: b.offset,
        });
    }
    Ok(Recording {
        messages,
        foreign_messages: report.foreign_messages,
        file_len: report.file_len,
        metadata: report.metadata,
    })
}

fn recover_impl(input: &mut dyn Read, len: u64, path: &Path) -> Result<Recovery, ReadError> {
    let mut messages = Vec::new();
    let report = scan(input, len, path, false, &mut |m| messages.push(m))?;
    Ok(Recovery {
        messages,
        foreign_messages: report.foreign_messages,
        recovered_bytes: report.recovered_bytes,
        file_len: report.file_len,
        break_at: report.break_at,
        metadata: report.metadata,
    })
}

/// The outcome of [`scan_recording`].
#[derive(Debug, Clone, PartialEq)]
pub struct ScanReport {
    /// Messages handed to the callback.
    pub messages: u64,
    /// Messages on topics that are not ours, skipped.
    pub foreign_messages: u64,
    /// Bytes up to the end of the last record read whole.
    pub recovered_bytes: u64,
    /// File size, bytes.
    pub file_len: u64,
    /// Where reading stopped (only when `strict` is false; strict scans return the error).
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
    let (file, len) = open(path)?;
    scan(&mut BufReader::new(file), len, path, strict, each)
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
        crate::sink::meta::gyro_metadata_name,
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
    let (file, len) = open(path)?;
    let mut input = BufReader::new(file);
    let io_err = |offset, source| ReadError::Io {
        path: path.to_path_buf(),
        offset,
        source,
    };
    let mut magic = Vec::with_capacity(8);
    (&mut input)
        .take(8)
        .read_to_end(&mut magic)
        .map_err(|e| io_err(0, e))?;
    if magic[..] != ::mcap::MAGIC[..magic.len()] {
        return Err(ReadError::NotMcap {
            path: path.to_path_buf(),
        });
    }
    let scanner = Scanner {
        path,
        channels: HashMap::new(),
        report: ScanReport {
            messages: 0,
            foreign_messages: 0,
            recovered_bytes: 0,
            file_len: len,
            break_at: None,
            metadata: None,
        },
    };
    if magic.len() < 8 {
        return Err(scanner.mcap_error(0, McapError::UnexpectedEof));
    }
    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_emit_chunks(true)
        .with_record_length_limit(usize::try_from(len).unwrap_or(usize::MAX));
    let mut reader = LinearReader::new_with_options(options);
    let mut offset: u64 = 8;
    let mut found = Vec::new();
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| scanner.mcap_error(offset, e))? {
            LinearReadEvent::ReadRequest(need) => {
                let buf = reader.insert(need.clamp(1, 4096));
                let n = read_some(&mut input, buf).map_err(|e| io_err(offset, e))?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { data, opcode } => {
                let start = offset;
                offset = start + RECORD_PREFIX + data.len() as u64;
                match opcode {
                    ::mcap::records::op::CHUNK | ::mcap::records::op::MESSAGE => return Ok(found),
                    ::mcap::records::op::METADATA => {
                        let record = ::mcap::parse_record(opcode, data)
                            .map_err(|e| scanner.mcap_error(start, e))?;
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

struct Scanner<'a> {
    path: &'a Path,
    /// Declared channels: id -> our topic, or None for a foreign one.
    channels: HashMap<u16, Option<(Topic, Option<String>)>>,
    report: ScanReport,
}

/// Read `input` (`file_len` bytes, named `path` in errors) linearly.
fn scan(
    input: &mut dyn Read,
    file_len: u64,
    path: &Path,
    strict: bool,
    each: &mut dyn FnMut(RecordedMessage),
) -> Result<ScanReport, ReadError> {
    let io_err = |offset, source| ReadError::Io {
        path: path.to_path_buf(),
        offset,
        source,
    };

    // Check the magic ourselves so that a file cut inside it is "empty", not "foreign".
    let mut magic = Vec::with_capacity(8);
    input
        .take(8)
        .read_to_end(&mut magic)
        .map_err(|e| io_err(0, e))?;
    if magic[..] != ::mcap::MAGIC[..magic.len()] {
        return Err(ReadError::NotMcap {
            path: path.to_path_buf(),
        });
    }
    let mut scanner = Scanner {
        path,
        channels: HashMap::new(),
        report: ScanReport {
            messages: 0,
            foreign_messages: 0,
            recovered_bytes: magic.len() as u64,
            file_len,
            break_at: None,
            metadata: None,
        },
    };
    if magic.len() < 8 {
        scanner.report.recovered_bytes = 0;
        let e = scanner.mcap_error(0, McapError::UnexpectedEof);
        return scanner.stop(strict, 0, e);
    }

    let options = LinearReaderOptions::default()
        .with_skip_start_magic(true)
        .with_check_finishes_after_end_magic(strict)
        .with_emit_chunks(true)
        // No record can be longer than the file: fail at once on a corrupt length.
        .with_record_length_limit(usize::try_from(file_len).unwrap_or(usize::MAX));
    let mut reader = LinearReader::new_with_options(options);
    // Offset of the next record to come out of the reader.
    let mut offset: u64 = 8;
    let mut footer_seen = false;
    let mut stats_count: Option<(u64, u64)> = None;
    while let Some(event) = reader.next_event() {
        let event = match event {
            Ok(e) => e,
            Err(e) => {
                let e = scanner.mcap_error(offset, e);
                return scanner.stop(strict, offset, e);
            }
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let buf = reader.insert(need.clamp(1, READ_BLOCK));
                let n = read_some(input, buf).map_err(|e| io_err(offset, e))?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { data, opcode } => {
                let start = offset;
                let len = data.len() as u64;
                if opcode == ::mcap::records::op::CHUNK {
                    if let Err(e) = scanner.chunk(opcode, data, start, each) {
                        return scanner.stop(strict, start, e);
                    }
                    offset = start + RECORD_PREFIX + len;
                    scanner.report.recovered_bytes = offset;
                    continue;
                }
                let record = match ::mcap::parse_record(opcode, data) {
                    Ok(r) => r,
                    Err(e) => {
                        let e = scanner.mcap_error(start, e);
                        return scanner.stop(strict, start, e);
                    }
                };
                match record {
                    Record::Footer(_) => footer_seen = true,
                    Record::Statistics(ref s) => stats_count = Some((start, s.message_count)),
                    Record::Metadata(ref m)
                        if m.name == METADATA_NAME && scanner.report.metadata.is_none() =>
                    {
                        match parse_metadata(m, start, path) {
                            Ok(meta) => scanner.report.metadata = Some(meta),
                            Err(e) => return scanner.stop(strict, start, e),
                        }
                    }
                    _ => {}
                }
                if let Err(e) = scanner.record(record, start, each) {
                    return scanner.stop(strict, start, e);
                }
                offset = start + RECORD_PREFIX + len;
                scanner.report.recovered_bytes = offset;
            }
        }
    }
    // The reader only ends cleanly after the footer and the end magic.
    if !footer_seen {
        let e = scanner.mcap_error(offset, McapError::UnexpectedEof);
        return scanner.stop(strict, offset, e);
    }
    scanner.report.recovered_bytes = offset + ::mcap::MAGIC.len() as u64;
    if let Some((at, expected)) = stats_count {
        let read = scanner.report.messages + scanner.report.foreign_messages;
        if expected != read {
            let e = ReadError::CountMismatch {
                path: path.to_path_buf(),
                offset: at,
                expected,
                read,
            };
            return scanner.stop(strict, at, e);
        }
    }
    Ok(scanner.report)
}

/// Read up to `buf.len()` bytes, retrying on interruption; 0 means end of file.
fn read_some(input: &mut dyn Read, buf: &mut [u8]) -> io::Result<usize> {
    loop {
        match input.read(buf) {
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            other => return other,
        }
    }
}

impl Scanner<'_> {
    /// Stop at `offset` because of `error`: return it (strict) or report a break.
    fn stop(
        mut self,
        strict: bool,
        offset: u64,
        error: ReadError,
    ) -> Result<ScanReport, ReadError> {
        if strict {
            return Err(error);
        }
        self.report.break_at = Some(Break {
            offset,
            reason: error.to_string(),
        });
        Ok(self.report)
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
                path: self.path.to_path_buf(),
                offset,
            },
            McapError::RecordTooLarge { len, .. } if past_end(len) => ReadError::Incomplete {
                path: self.path.to_path_buf(),
                offset,
            },
            source => ReadError::Mcap {
                path: self.path.to_path_buf(),
                offset,
                source,
            },
        }
    }

    /// Decode a whole chunk record (body `body`, starting at `offset`) with its own
    /// sans-io reader: the chunk is decompressed and its CRC checked before any
    /// record is used, and `MAX_CHUNK_BYTES` bounds what a corrupt size field may
    /// make it allocate. Its messages are handed out only if the whole chunk decodes.
    fn chunk(
        &mut self,
        opcode: u8,
        body: &[u8],
        offset: u64,
        each: &mut dyn FnMut(RecordedMessage),
    ) -> Result<(), ReadError> {
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
        let mut foreign = 0;
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
                        Some(Some(m)) => decoded.push(m),
                        Some(None) => foreign += 1,
                        None => {}
                    }
                }
            }
        }
        // The chunk is whole: hand out its messages.
        self.report.messages += decoded.len() as u64;
        self.report.foreign_messages += foreign;
        decoded.into_iter().for_each(each);
        Ok(())
    }

    /// Handle one top-level record other than a chunk that starts at `offset`.
    fn record(
        &mut self,
        record: Record<'_>,
        offset: u64,
        each: &mut dyn FnMut(RecordedMessage),
    ) -> Result<(), ReadError> {
        match self.inner_record(record, offset)? {
            Some(Some(m)) => {
                self.report.messages += 1;
                each(m);
            }
            Some(None) => self.report.foreign_messages += 1,
            None => {}
        }
        Ok(())
    }

    /// Handle a record that may sit inside a chunk: `Some(Some(m))` for one of our
    /// messages, `Some(None)` for a foreign message, `None` for any other record.
    fn inner_record(
        &mut self,
        record: Record<'_>,
        offset: u64,
    ) -> Result<Option<Option<RecordedMessage>>, ReadError> {
        match record {
            Record::Channel(c) => {
                let topic = Topic::parse_channel(&c.topic);
                if let Some((t, _)) = &topic
                    && c.message_encoding != MESSAGE_ENCODING
                {
                    return Err(ReadError::Encoding {
                        path: self.path.to_path_buf(),
                        offset,
                        topic: t.name(),
                        encoding: c.message_encoding,
                    });
                }
                self.channels.insert(c.id, topic);
                Ok(None)
            }
            Record::Message { header, data } => {
                let topic = self
                    .channels
                    .get(&header.channel_id)
                    .cloned()
                    .ok_or_else(|| ReadError::UnknownChannel {
                        path: self.path.to_path_buf(),
                        offset,
                        channel_id: header.channel_id,
                    })?;
                let Some((topic, gyro)) = topic else {
                    return Ok(Some(None));
                };
                let message =
                    SinkMessage::from_json(topic, &data).map_err(|source| ReadError::Message {
                        path: self.path.to_path_buf(),
                        offset,
                        topic: topic.name(),
                        sequence: header.sequence,
                        source: Box::new(source),
                    })?;
                Ok(Some(Some(RecordedMessage {
                    log_time_ns: header.log_time,
                    publish_time_ns: header.publish_time,
                    sequence: header.sequence,
                    message,
                    gyro,
                })))
            }
            _ => Ok(None),
        }
    }
}
