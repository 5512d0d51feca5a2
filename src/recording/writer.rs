//! MCAP recording: one zstd-chunked file per run, written by a dedicated std thread.
//!
//! The `mcap` crate's writer is synchronous (`Write + Seek`), so the [`Recorder`]
//! owns a std thread that holds the writer and is fed [`SinkMessage`]s through a
//! std channel bounded in messages (a group of messages is one hand-over); the
//! async daemon only ever calls the non-blocking [`RecordSender::try_send`] (and
//! counts what a full queue refuses). No tokio here.
//!
//! Flush policy: the thread closes the open chunk (`mcap::Writer::flush`, which also
//! flushes the file buffer to the OS) once the oldest unflushed message has waited
//! `flush_interval_s`, whether or not more messages arrive, and whenever the chunk
//! reaches `chunk_size` bytes. A crash (even `kill -9`) therefore loses at most the
//! last `flush_interval_s` of recorded messages plus what was still queued; the
//! truncated file is readable up to its last complete chunk with
//! [`crate::recording::reader::recover_recording`]. The data is not `fsync`ed: a power
//! loss may lose what the OS had not yet written.
//!
//! A recording started with [`Recorder::start_with_metadata`] holds, right after
//! the header, the `sagnac` Metadata record ([`crate::recording::meta`]: sample rate,
//! pulse weight, config or model, version). The schemas and channels go into a first chunk that is closed before
//! [`Recorder::start`] returns, so every recording is readable from its start.
//! (`start` does that small amount of file I/O on the calling thread; from async
//! code, call it in `spawn_blocking`.) Messages keep their sample time as MCAP log
//! time and publish time, so a replay reproduces the run exactly. A message with
//! a value JSON cannot carry (NaN, infinity) is refused by `send`/`try_send`.
//! The thread finishes the file on [`Recorder::finish`], or when every sender is
//! dropped; messages queued by other senders after `finish` are lost.
//!
//! Files are named by the UTC start time of the run, `sagnac-YYYYMMDDTHHMMSSZ.mcap`
//! (a `-1`, `-2`, ... suffix when that name is taken), in the record directory.
//! [`Recorder::finish`] writes the summary through `mcap::Writer::finish` and
//! reports its error; the writer's `Drop` would swallow it.

use std::collections::BTreeMap;
use std::fs::{File, OpenOptions};
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, SyncSender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use serde::{Deserialize, Serialize};

use crate::recording::messages::{
    MESSAGE_ENCODING, MessageError, SCHEMA_ENCODING, SinkMessage, Topic,
};
use crate::recording::meta::RecordingMeta;

mod queue;

use queue::{QueueReceiver, QueueSender, Refused, Weighed};

/// Errors of the recorder.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A configuration value is out of range.
    #[error("recorder config: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The system clock is before 1970, so the file cannot be named.
    #[error("system clock is before the Unix epoch: cannot name the recording")]
    ClockBeforeEpoch,
    /// The record directory cannot be created.
    #[error("cannot create record directory {}", path.display())]
    CreateDir { path: PathBuf, source: io::Error },
    /// The recording file cannot be created.
    #[error("cannot create recording {}", path.display())]
    CreateFile { path: PathBuf, source: io::Error },
    /// The recorder thread cannot be started.
    #[error("cannot start the recorder thread for {}", path.display())]
    Spawn { path: PathBuf, source: io::Error },
    /// The MCAP writer failed.
    #[error("MCAP writer failed on {} while {action} (file at {bytes} bytes)", path.display())]
    Mcap {
        path: PathBuf,
        action: &'static str,
        bytes: u64,
        source: ::mcap::McapError,
    },
    /// A message was refused before being queued.
    #[error("message refused for {}", path.display())]
    Invalid { path: PathBuf, source: MessageError },
    /// A message could not be serialized.
    #[error("cannot serialize a {topic} message for {}", path.display())]
    Serialize {
        path: PathBuf,
        topic: &'static str,
        source: serde_json::Error,
    },
    /// The queue is full (`try_send`); the message was dropped.
    #[error("recorder queue for {} is full ({capacity} messages): message dropped", path.display())]
    QueueFull { path: PathBuf, capacity: usize },
    /// The writer thread failed; `finish` returns the error itself.
    #[error("recorder for {} failed: {message}", path.display())]
    Failed { path: PathBuf, message: String },
    /// The recorder thread has stopped (after `finish` or an error that `finish` reports).
    #[error("recorder for {} has stopped", path.display())]
    Stopped { path: PathBuf },
    /// The recorder thread panicked.
    #[error("recorder thread for {} panicked", path.display())]
    Panicked { path: PathBuf },
}

/// Recorder settings (the `[record]` table of the daemon config).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecorderConfig {
    /// Directory receiving one file per run.
    pub record_dir: PathBuf,
    /// Longest time a recorded message waits before its chunk is closed, s.
    pub flush_interval_s: f64,
    /// Capacity of the queue between the daemon and the writer thread, messages
    /// (a group queued by `RecordSender::send_all`, one hand-over to the writer
    /// thread, takes one place per message).
    pub queue_capacity: usize,
    /// Uncompressed chunk size at which a chunk is closed early, bytes.
    pub chunk_size: u64,
    /// zstd level (0: the library default, 3).
    pub zstd_level: u32,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        RecorderConfig {
            record_dir: PathBuf::from("recordings"),
            flush_interval_s: 2.0,
            queue_capacity: 1024,
            chunk_size: 1024 * 1024,
            zstd_level: 0,
        }
    }
}

impl RecorderConfig {
    /// Check ranges: `0 < flush_interval_s <= 3600`, `queue_capacity >= 1`,
    /// `4096 <= chunk_size <= 256 MiB`, `zstd_level <= 19`.
    pub fn validate(&self) -> Result<(), RecordError> {
        let bad = |key, value: String, reason| Err(RecordError::Config { key, value, reason });
        if !(self.flush_interval_s > 0.0 && self.flush_interval_s <= 3600.0) {
            return bad(
                "flush_interval_s",
                self.flush_interval_s.to_string(),
                "must be in (0, 3600] seconds",
            );
        }
        if self.queue_capacity == 0 {
            return bad("queue_capacity", "0".into(), "must be at least 1");
        }
        if !(4096..=256 * 1024 * 1024).contains(&self.chunk_size) {
            return bad(
                "chunk_size",
                self.chunk_size.to_string(),
                "must be in [4096, 268435456] bytes",
            );
        }
        if self.zstd_level > 19 {
            return bad(
                "zstd_level",
                self.zstd_level.to_string(),
                "must be at most 19",
            );
        }
        Ok(())
    }

    fn flush_interval(&self) -> Duration {
        Duration::from_secs_f64(self.flush_interval_s)
    }
}

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingSummary {
    /// The file.
    pub path: PathBuf,
    /// Messages written, per topic name.
    pub messages_per_topic: BTreeMap<String, u64>,
    /// File size, bytes.
    pub bytes: u64,
    /// Chunks closed by the flush policy, by `Recorder::flush` or by `finish`
    /// (chunks closed because they reached `chunk_size` are not counted).
    pub flushes: u64,
}

impl RecordingSummary {
    /// Total messages written.
    pub fn messages(&self) -> u64 {
        self.messages_per_topic.values().sum()
    }
}

/// Format a time as compact ISO 8601 UTC, `YYYYMMDDTHHMMSSZ` (whole seconds, truncated).
pub fn format_utc_compact(time: SystemTime) -> Result<String, RecordError> {
    let secs = time
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_err(|_| RecordError::ClockBeforeEpoch)?
        .as_secs();
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (year, month, day) = civil_from_days(days);
    Ok(format!(
        "{year:04}{month:02}{day:02}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    ))
}

/// The file name of a run started at `start`: `sagnac-YYYYMMDDTHHMMSSZ.mcap`.
pub fn recording_file_name(start: SystemTime) -> Result<String, RecordError> {
    Ok(format!("sagnac-{}.mcap", format_utc_compact(start)?))
}

/// Gregorian (year, month 1-12, day 1-31) of a day count since 1970-01-01.
/// Proleptic calendar in 400-year eras (146 097 days), years starting in March.
fn civil_from_days(days: u64) -> (u64, u64, u64) {
    // Shift the origin to 0000-03-01, an era boundary.
    let z = days + 719_468;
    let era = z / 146_097;
    let doe = z % 146_097; // day of era, 0..146096
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // year of era, 0..399
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of the March-based year, 0..365
    let mp = (5 * doy + 2) / 153; // month from March, 0..11
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + u64::from(month <= 2);
    (year, month, day)
}

/// The recording file, buffered: a `File` that publishes its size (the highest
/// position written to the OS) to a shared counter.
///
/// Unlike `BufWriter`, asking for the position (`stream_position`, which the
/// `mcap` writer does around every record it indexes) neither flushes the
/// buffer nor makes a system call: the position is tracked here. Any other
/// seek (the writer goes back to each chunk's header to fill it in) and
/// `flush` write the buffer out first. A closed chunk thus costs two writes and
/// two seeks instead of one small write per record.
struct RecordFile {
    file: File,
    /// Bytes written but not yet handed to the OS; they start at `pos - buf.len()`.
    buf: Vec<u8>,
    /// Position of the next byte written (the buffer's end).
    pos: u64,
    /// Highest position handed to the OS.
    len: u64,
    shared: Arc<AtomicU64>,
}

impl RecordFile {
    /// Buffer size: larger than a typical compressed chunk, so a chunk reaches
    /// the OS in one write.
    const BUFFER: usize = 256 * 1024;

    fn new(file: File, shared: Arc<AtomicU64>) -> RecordFile {
        RecordFile {
            file,
            buf: Vec::with_capacity(Self::BUFFER),
            pos: 0,
            len: 0,
            shared,
        }
    }

    /// Hand `data`, which ends at position `end`, to the OS.
    fn write_out(&mut self, data: &[u8], end: u64) -> io::Result<()> {
        self.file.write_all(data)?;
        if end > self.len {
            self.len = end;
            self.shared.store(end, Ordering::Relaxed);
        }
        Ok(())
    }

    fn flush_buf(&mut self) -> io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        let mut buf = std::mem::take(&mut self.buf);
        let result = self.write_out(&buf, self.pos);
        // After an error the recorder stops: what was buffered is dropped either way.
        buf.clear();
        self.buf = buf;
        result
    }
}

impl Write for RecordFile {
    fn write(&mut self, data: &[u8]) -> io::Result<usize> {
        if self.buf.len() + data.len() > Self::BUFFER {
            self.flush_buf()?;
        }
        if data.len() >= Self::BUFFER {
            self.write_out(data, self.pos + data.len() as u64)?;
        } else {
            self.buf.extend_from_slice(data);
        }
        self.pos += data.len() as u64;
        Ok(data.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.flush_buf()?;
        self.file.flush()
    }
}

impl Seek for RecordFile {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        if to == SeekFrom::Current(0) {
            return Ok(self.pos);
        }
        self.flush_buf()?;
        self.pos = self.file.seek(to)?;
        Ok(self.pos)
    }

    fn stream_position(&mut self) -> io::Result<u64> {
        Ok(self.pos)
    }
}

enum Command {
    /// A message of gyro `.0` (its index in the recording's gyro list; `None`
    /// with one gyro, or for a daemon-wide event).
    Message(Option<u16>, SinkMessage),
    /// Messages of gyro `.0` queued together (one wake of the writer thread).
    Messages(Option<u16>, Vec<SinkMessage>),
    Flush(SyncSender<Result<u64, RecordError>>),
    Finish,
}

impl Weighed for Command {
    fn messages(&self) -> usize {
        match self {
            Command::Message(..) => 1,
            Command::Messages(_, msgs) => msgs.len(),
            Command::Flush(_) | Command::Finish => 0,
        }
    }
}

/// Messages per queue entry of [`RecordSender::send_all`] at most (and at
/// most the queue's capacity).
pub const GROUP_MAX: usize = 128;

/// A message that [`RecordSender::checked`] found recordable.
#[derive(Debug)]
pub struct Checked(SinkMessage);

impl Checked {
    /// The message.
    pub fn message(&self) -> &SinkMessage {
        &self.0
    }
}

/// A cloneable handle that queues messages for a [`Recorder`].
#[derive(Clone)]
pub struct RecordSender {
    tx: QueueSender<Command>,
    /// The gyro whose messages this handle queues (a recording of several gyros).
    gyro: Option<u16>,
    /// The recording's gyro labels (empty or one: today's topics).
    gyros: Arc<Vec<String>>,
    path: Arc<PathBuf>,
    capacity: usize,
    bytes: Arc<AtomicU64>,
    dropped: Arc<AtomicU64>,
}

impl RecordSender {
    /// Queue a message, blocking while the queue is full (offline tools, tests).
    pub fn send(&self, msg: SinkMessage) -> Result<(), RecordError> {
        self.check(&msg)?;
        self.tx.send(self.command(msg)).map_err(|_| self.stopped())
    }

    /// A handle that queues the messages of gyro `label` of a recording of
    /// several gyros (its `/gyro/<label>/...` channels; its events name it).
    /// With one gyro (or a label the recording does not have) the handle
    /// writes today's channels.
    pub fn for_gyro(&self, label: &str) -> RecordSender {
        let mut s = self.clone();
        s.gyro = if self.gyros.len() > 1 {
            self.gyros
                .iter()
                .position(|g| g == label)
                .and_then(|i| u16::try_from(i).ok())
        } else {
            None
        };
        s
    }

    fn command(&self, msg: SinkMessage) -> Command {
        Command::Message(self.gyro, self.tag(msg))
    }

    /// `msg` with its event (if it is one) naming this handle's gyro.
    fn tag(&self, mut msg: SinkMessage) -> SinkMessage {
        if let (Some(i), SinkMessage::Event(e)) = (self.gyro, &mut msg) {
            e.gyro = Some(self.gyros[usize::from(i)].clone());
        }
        msg
    }

    /// Queue `msgs` in entries of up to [`GROUP_MAX`] messages, blocking while
    /// they do not fit: one hand-over to the writer thread per entry (the
    /// daemon queues what one input batch produced this way).
    pub fn send_all(&self, msgs: Vec<Checked>) -> Result<(), RecordError> {
        for cmd in self.groups(msgs) {
            self.tx.send(cmd.1).map_err(|_| self.stopped())?;
        }
        Ok(())
    }

    /// [`RecordSender::send_all`] without blocking: a group the full queue
    /// refuses is dropped, each of its messages counted in
    /// [`RecordSender::dropped`]; the result is the first refusal.
    pub fn try_send_all(&self, msgs: Vec<Checked>) -> Result<(), RecordError> {
        let mut first = Ok(());
        for (n, cmd) in self.groups(msgs) {
            if let Err(e) = self.offer(cmd, n) {
                if matches!(e, RecordError::Stopped { .. }) {
                    return Err(e);
                }
                if first.is_ok() {
                    first = Err(e);
                }
            }
        }
        first
    }

    /// `msg` if it can be recorded ([`RecordError::Invalid`] if not), for
    /// [`RecordSender::send_all`].
    pub fn checked(&self, msg: SinkMessage) -> Result<Checked, RecordError> {
        self.check(&msg)?;
        Ok(Checked(msg))
    }

    /// The queue entries of `msgs`, each with its number of messages.
    fn groups(&self, msgs: Vec<Checked>) -> Vec<(u64, Command)> {
        let size = GROUP_MAX.min(self.capacity).max(1);
        let mut out = Vec::with_capacity(msgs.len().div_ceil(size));
        let mut it = msgs.into_iter().peekable();
        while it.peek().is_some() {
            let group: Vec<SinkMessage> = it.by_ref().take(size).map(|m| self.tag(m.0)).collect();
            let n = group.len() as u64;
            let cmd = if n == 1 {
                Command::Message(self.gyro, group.into_iter().next().expect("one message"))
            } else {
                Command::Messages(self.gyro, group)
            };
            out.push((n, cmd));
        }
        out
    }

    /// Queue `cmd` (holding `n` messages) without blocking.
    fn offer(&self, cmd: Command, n: u64) -> Result<(), RecordError> {
        match self.tx.try_send(cmd) {
            Ok(()) => Ok(()),
            Err(Refused::Full) => {
                self.dropped.fetch_add(n, Ordering::Relaxed);
                Err(RecordError::QueueFull {
                    path: self.path.to_path_buf(),
                    capacity: self.capacity,
                })
            }
            Err(Refused::Stopped) => Err(self.stopped()),
        }
    }

    /// Queue a message without blocking (the daemon). A full queue drops the message,
    /// counts it in [`RecordSender::dropped`] and returns [`RecordError::QueueFull`].
    pub fn try_send(&self, msg: SinkMessage) -> Result<(), RecordError> {
        self.check(&msg)?;
        self.offer(self.command(msg), 1)
    }

    /// Bytes of the recording written to the OS so far (the `sagnac_recording_bytes` gauge).
    pub fn bytes_written(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Messages dropped by [`RecordSender::try_send`] because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    fn check(&self, msg: &SinkMessage) -> Result<(), RecordError> {
        msg.validate().map_err(|source| RecordError::Invalid {
            path: self.path.to_path_buf(),
            source,
        })
    }

    fn stopped(&self) -> RecordError {
        RecordError::Stopped {
            path: self.path.to_path_buf(),
        }
    }
}

/// An MCAP recording in progress.
pub struct Recorder {
    sender: RecordSender,
    thread: JoinHandle<Result<RecordingSummary, RecordError>>,
}

impl Recorder {
    /// Start a recording named by the current time in `config.record_dir`.
    pub fn start(config: &RecorderConfig) -> Result<Recorder, RecordError> {
        Recorder::start_at(config, SystemTime::now())
    }

    /// Start a recording named by `start` (tests, replays of old runs), without
    /// a metadata record.
    pub fn start_at(config: &RecorderConfig, start: SystemTime) -> Result<Recorder, RecordError> {
        Recorder::start_with_metadata(config, start, None)
    }

    /// Start a recording named by `start` whose first record after the header is
    /// `metadata` (the `sagnac` Metadata record of [`crate::recording::meta`]).
    pub fn start_with_metadata(
        config: &RecorderConfig,
        start: SystemTime,
        metadata: Option<&RecordingMeta>,
    ) -> Result<Recorder, RecordError> {
        Recorder::start_gyros(config, start, metadata, &[])
    }

    /// Start a recording of several gyros: `gyros` are their labels and
    /// metadata records (`sagnac/<label>`, after the common `metadata`), and
    /// each gets its own channels `/gyro/<label>/raw`, `/clean`, `/noise`,
    /// `/estimates`, `/allan`, `/verdict`, `/summary`; events share
    /// `/gyro/events` and name their gyro. With fewer than two gyros this is
    /// [`Recorder::start_with_metadata`]: today's channels.
    pub fn start_gyros(
        config: &RecorderConfig,
        start: SystemTime,
        metadata: Option<&RecordingMeta>,
        gyros: &[(String, RecordingMeta)],
    ) -> Result<Recorder, RecordError> {
        config.validate()?;
        let dir = &config.record_dir;
        std::fs::create_dir_all(dir).map_err(|source| RecordError::CreateDir {
            path: dir.clone(),
            source,
        })?;
        let (path, file) = create_unique(dir, &recording_file_name(start)?)?;
        let bytes = Arc::new(AtomicU64::new(0));
        let file = RecordFile::new(file, Arc::clone(&bytes));
        let options = ::mcap::WriteOptions::new()
            .compression(Some(::mcap::Compression::Zstd))
            .compression_level(config.zstd_level)
            .compression_threads(0)
            .chunk_size(Some(config.chunk_size))
            .profile("");
        let mcap_err = |action, source| RecordError::Mcap {
            path: path.clone(),
            action,
            bytes: bytes.load(Ordering::Relaxed),
            source,
        };
        let mut writer = options
            .create(file)
            .map_err(|e| mcap_err("writing the header", e))?;
        // The recording's description first, where a reader finds it at once.
        if let Some(meta) = metadata {
            writer
                .write_metadata(&meta.to_record())
                .map_err(|e| mcap_err("writing the metadata record", e))?;
        }
        let multi = gyros.len() > 1;
        if multi {
            for (label, meta) in gyros {
                writer
                    .write_metadata(&meta.to_record_for(label))
                    .map_err(|e| mcap_err("writing a gyro's metadata record", e))?;
            }
        }
        let channels = add_channels(&mut writer, gyros, &path, &mcap_err)?;
        // Close the first chunk (schemas and channels) at once: from now on the
        // file is readable, and recovery always finds the channel records.
        writer
            .flush()
            .map_err(|e| mcap_err("closing the first chunk", e))?;
        let (tx, rx) = queue::queue(config.queue_capacity);
        let path = Arc::new(path);
        let mut worker = Worker {
            writer,
            channels,
            path: Arc::clone(&path),
            bytes: Arc::clone(&bytes),
            flush_interval: config.flush_interval(),
            flushes: 1,
            payload: Vec::new(),
        };
        let thread = std::thread::Builder::new()
            .name("sagnac-mcap".into())
            .spawn(move || {
                let result = worker.run(&rx);
                match result {
                    Ok(()) => worker.finish(),
                    Err(e) => Err(e),
                }
            })
            .map_err(|source| RecordError::Spawn {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(Recorder {
            sender: RecordSender {
                tx,
                gyro: None,
                gyros: Arc::new(if multi {
                    gyros.iter().map(|(l, _)| l.clone()).collect()
                } else {
                    Vec::new()
                }),
                path,
                capacity: config.queue_capacity,
                bytes,
                dropped: Arc::new(AtomicU64::new(0)),
            },
            thread,
        })
    }

    /// The recording file.
    pub fn path(&self) -> &Path {
        &self.sender.path
    }

    /// A handle for other tasks to queue messages.
    pub fn sender(&self) -> RecordSender {
        self.sender.clone()
    }

    /// See [`RecordSender::send`].
    pub fn send(&self, msg: SinkMessage) -> Result<(), RecordError> {
        self.sender.send(msg)
    }

    /// See [`RecordSender::try_send`].
    pub fn try_send(&self, msg: SinkMessage) -> Result<(), RecordError> {
        self.sender.try_send(msg)
    }

    /// See [`RecordSender::bytes_written`].
    pub fn bytes_written(&self) -> u64 {
        self.sender.bytes_written()
    }

    /// See [`RecordSender::dropped`].
    pub fn dropped(&self) -> u64 {
        self.sender.dropped()
    }

    /// Close the open chunk now, after every message queued before this call, and
    /// return the file size, which is then a chunk boundary. Blocks until done.
    pub fn flush(&self) -> Result<u64, RecordError> {
        let (ack_tx, ack_rx) = mpsc::sync_channel(1);
        self.sender
            .tx
            .send(Command::Flush(ack_tx))
            .map_err(|_| self.sender.stopped())?;
        ack_rx.recv().map_err(|_| self.sender.stopped())?
    }

    /// Write every queued message, the summary and the end magic, and close the file.
    /// Returns the first error the writer thread met, if any. Senders still held
    /// elsewhere get [`RecordError::Stopped`] afterwards.
    pub fn finish(self) -> Result<RecordingSummary, RecordError> {
        // If the thread already stopped on an error, the send fails and join reports it.
        let _ = self.sender.tx.send(Command::Finish);
        let path = self.sender.path.to_path_buf();
        drop(self.sender);
        self.thread
            .join()
            .map_err(|_| RecordError::Panicked { path })?
    }
}

/// Create `dir/name`, or `dir/<stem>-1.mcap`, `-2`, ... when taken (never overwrite).
fn create_unique(dir: &Path, name: &str) -> Result<(PathBuf, File), RecordError> {
    let stem = name.strip_suffix(".mcap").unwrap_or(name);
    for i in 0..1000u32 {
        let candidate = if i == 0 {
            dir.join(name)
        } else {
            dir.join(format!("{stem}-{i}.mcap"))
        };
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&candidate)
        {
            Ok(file) => return Ok((candidate, file)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(source) => {
                return Err(RecordError::CreateFile {
                    path: candidate,
                    source,
                });
            }
        }
    }
    Err(RecordError::CreateFile {
        path: dir.join(name),
        source: io::Error::new(io::ErrorKind::AlreadyExists, "1000 runs named alike"),
    })
}

/// Every topic's schema and channels (one per gyro in a recording of several,
/// but one `/gyro/events`).
fn add_channels(
    writer: &mut ::mcap::Writer<RecordFile>,
    gyros: &[(String, RecordingMeta)],
    path: &Path,
    mcap_err: &dyn Fn(&'static str, ::mcap::McapError) -> RecordError,
) -> Result<BTreeMap<(Option<u16>, Topic), ChannelState>, RecordError> {
    let multi = gyros.len() > 1;
    let mut channels = BTreeMap::new();
    for topic in Topic::ALL {
        let schema = serde_json::to_vec_pretty(&topic.json_schema()).map_err(|source| {
            RecordError::Serialize {
                path: path.to_path_buf(),
                topic: topic.name(),
                source,
            }
        })?;
        let schema_id = writer
            .add_schema(topic.schema_name(), SCHEMA_ENCODING, &schema)
            .map_err(|e| mcap_err("adding a schema", e))?;
        let owners: Vec<Option<u16>> = if multi && topic != Topic::Events {
            (0..gyros.len()).map(|i| u16::try_from(i).ok()).collect()
        } else {
            vec![None]
        };
        for g in owners {
            let name = topic.name_for(g.map(|i| gyros[usize::from(i)].0.as_str()));
            let id = writer
                .add_channel(schema_id, &name, MESSAGE_ENCODING, &BTreeMap::new())
                .map_err(|e| mcap_err("adding a channel", e))?;
            channels.insert(
                (g, topic),
                ChannelState {
                    id,
                    name,
                    sequence: 0,
                    count: 0,
                },
            );
        }
    }
    Ok(channels)
}

/// One channel of the recording: its id, name, next sequence number and the
/// messages written (one lookup per message).
struct ChannelState {
    id: u16,
    name: String,
    sequence: u32,
    count: u64,
}

struct Worker {
    writer: ::mcap::Writer<RecordFile>,
    /// (gyro index, topic) -> its channel.
    channels: BTreeMap<(Option<u16>, Topic), ChannelState>,
    path: Arc<PathBuf>,
    bytes: Arc<AtomicU64>,
    flush_interval: Duration,
    flushes: u64,
    /// Reused JSON buffer of the message being written.
    payload: Vec<u8>,
}

impl Worker {
    /// Write until told to finish (or every sender is gone). An error stops the thread.
    fn run(&mut self, rx: &QueueReceiver<Command>) -> Result<(), RecordError> {
        // When the oldest message not yet in a closed chunk arrived.
        let mut pending_since: Option<Instant> = None;
        loop {
            let command = match pending_since {
                None => rx.recv(),
                Some(since) => {
                    match rx.recv_timeout(self.flush_interval.saturating_sub(since.elapsed())) {
                        Ok(c) => Some(c),
                        Err(RecvTimeoutError::Timeout) => {
                            self.flush()?;
                            pending_since = None;
                            continue;
                        }
                        Err(RecvTimeoutError::Disconnected) => None,
                    }
                }
            };
            match command {
                Some(Command::Message(gyro, msg)) => {
                    self.write(gyro, &msg)?;
                    let since = *pending_since.get_or_insert_with(Instant::now);
                    if since.elapsed() >= self.flush_interval {
                        self.flush()?;
                        pending_since = None;
                    }
                }
                Some(Command::Messages(gyro, msgs)) => {
                    for msg in &msgs {
                        self.write(gyro, msg)?;
                    }
                    let since = *pending_since.get_or_insert_with(Instant::now);
                    if since.elapsed() >= self.flush_interval {
                        self.flush()?;
                        pending_since = None;
                    }
                }
                Some(Command::Flush(ack)) => {
                    pending_since = None;
                    match self.flush() {
                        Ok(()) => {
                            let _ = ack.send(Ok(self.bytes.load(Ordering::Relaxed)));
                        }
                        Err(e) => {
                            // The flush caller gets the message; finish() gets the error.
                            let _ = ack.send(Err(RecordError::Failed {
                                path: self.path.to_path_buf(),
                                message: e.to_string(),
                            }));
                            return Err(e);
                        }
                    }
                }
                // Finish on request, and also when every sender is gone.
                Some(Command::Finish) | None => return Ok(()),
            }
        }
    }

    fn mcap_err(&self, action: &'static str, source: ::mcap::McapError) -> RecordError {
        RecordError::Mcap {
            path: self.path.to_path_buf(),
            action,
            bytes: self.bytes.load(Ordering::Relaxed),
            source,
        }
    }

    fn write(&mut self, gyro: Option<u16>, msg: &SinkMessage) -> Result<(), RecordError> {
        let topic = msg.topic();
        let key = if topic == Topic::Events {
            (None, topic)
        } else {
            (gyro, topic)
        };
        let mut data = std::mem::take(&mut self.payload);
        msg.write_json(&mut data)
            .map_err(|source| RecordError::Serialize {
                path: self.path.to_path_buf(),
                topic: topic.name(),
                source,
            })?;
        let ch = self
            .channels
            .get_mut(&key)
            .expect("every (gyro, topic) has a channel");
        let header = ::mcap::records::MessageHeader {
            channel_id: ch.id,
            sequence: ch.sequence,
            log_time: msg.time_ns(),
            publish_time: msg.time_ns(),
        };
        ch.sequence = ch.sequence.wrapping_add(1);
        ch.count += 1;
        let written = self.writer.write_to_known_channel(&header, &data);
        self.payload = data; // the buffer is reused by the next message
        written.map_err(|e| self.mcap_err("writing a message", e))?;
        Ok(())
    }

    fn flush(&mut self) -> Result<(), RecordError> {
        self.writer
            .flush()
            .map_err(|e| self.mcap_err("closing a chunk", e))?;
        self.flushes += 1;
        Ok(())
    }

    fn finish(mut self) -> Result<RecordingSummary, RecordError> {
        self.writer
            .finish()
            .map_err(|e| self.mcap_err("writing the summary (finish)", e))?;
        self.flushes += 1;
        // finish() may leave the summary and end magic in the file's buffer: push them to
        // the OS and to the disk, and surface any error here (Drop would swallow it).
        let io_err = |e: io::Error, action| RecordError::Mcap {
            path: self.path.to_path_buf(),
            action,
            bytes: self.bytes.load(Ordering::Relaxed),
            source: e.into(),
        };
        let mut file = self.writer.into_inner();
        file.flush()
            .map_err(|e| io_err(e, "flushing the file after finish"))?;
        file.file
            .sync_all()
            .map_err(|e| io_err(e, "syncing the file after finish"))?;
        Ok(RecordingSummary {
            path: self.path.to_path_buf(),
            messages_per_topic: self
                .channels
                .into_values()
                .map(|c| (c.name, c.count))
                .collect(),
            bytes: file.len,
            flushes: self.flushes,
        })
    }
}
