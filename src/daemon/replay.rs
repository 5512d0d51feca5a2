//! The daemon's replay source: a capture played back through the same pipeline
//! as a live gyro, as fast as possible or paced at `speed` times real time.
//!
//! Two kinds of capture, told apart by their first bytes:
//! * a raw frame capture (`.bin`: the serial bytes as captured): decoded by the
//!   same sans-IO [`FrameDecoder`] as the serial source, corruption included
//!   (so the frame counters and events come out as they did live);
//! * an MCAP recording made by `sagnac run`: the `/gyro/raw` messages (counts,
//!   gaps, sequence numbers and sample times as recorded), pulled from the shared
//!   recording reader ([`crate::recording::reader::RawReader`], the one `analyze` and
//!   `diagnose` read), are fed back; the other channels are skipped without being
//!   decoded. A recording cut by a crash is replayed up to its last complete
//!   chunk (with a warning). Gap events are re-emitted from the recorded gaps;
//!   the other recorded events are not. A recording of several gyros replays
//!   as several gyros, each with its recorded label and its own pipeline.
//!
//! Replays are lossless: the source runs on a blocking thread and waits for room
//! in the pipeline's bounded queue (backpressure), so its speed is that of the
//! slowest stage. Pacing follows the sample clock: the batch ending at sample
//! period `p` is sent no earlier than `start + p / (rate * speed)`.

use std::fs::File;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use bytes::BytesMut;

use crate::daemon::batch::{BatchSender, PipelineClosed, SourceBatch, SourceReport, wall_ns};
use crate::daemon::lanes::Lanes;
use crate::daemon::shutdown::Shutdown;
use crate::daemon::telemetry::Telemetry;
use crate::input::Format;
use crate::input::frame::{Axes, DecoderConfig};
use crate::recording::messages::{Event, EventKind, RawBatch};
use crate::recording::reader::RawReader;

/// Errors of the replay source; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A setting is out of range.
    #[error("replay source: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The capture cannot be opened or read.
    #[error("cannot read capture {} at byte {offset}", path.display())]
    Io {
        path: PathBuf,
        offset: u64,
        source: io::Error,
    },
    /// The recording is unreadable before its first sample.
    #[error("{}: no samples before the recording becomes unreadable at byte {offset}: {reason}", path.display())]
    BrokenBeforeSamples {
        path: PathBuf,
        offset: u64,
        reason: String,
    },
    /// The recording's sample period disagrees with the configured rate.
    #[error(
        "{}: /gyro/raw has a sample period of {dt_ns} ns but the gyro rate is {sample_rate_hz} Hz \
         (set --sample-rate-hz to {recorded_hz})", path.display()
    )]
    RateMismatch {
        path: PathBuf,
        dt_ns: u64,
        sample_rate_hz: f64,
        recorded_hz: f64,
    },
    /// A ROS 2 bag: rate samples with stamps, not a gyro's frames.
    #[error(
        "{}: a ROS 2 bag; the daemon replays raw frame captures and recordings made by `sagnac run`: \
         analyse a bag with `sagnac analyze --input BAG --gyro gyro_x`", path.display()
    )]
    Ros2Bag { path: PathBuf },
    /// The capture holds no sample at all (no valid frame, or no `/gyro/raw`).
    #[error(
        "{}: no samples in this capture ({bytes_read} bytes read): is it a raw frame \
         capture (.bin) or an MCAP recording made by `sagnac run`?", path.display()
    )]
    NoSamples { path: PathBuf, bytes_read: u64 },
    /// The recording cannot be read.
    #[error(transparent)]
    Recording(#[from] crate::recording::reader::ReadError),
    /// The recording's gyros cannot be read.
    #[error(transparent)]
    Input(#[from] crate::input::InputError),
    /// The pipeline stopped during the replay.
    #[error("replay of {}", path.display())]
    Pipeline {
        path: PathBuf,
        source: PipelineClosed,
    },
}

/// What kind of capture a file is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CaptureKind {
    /// Raw single frames.
    Frames,
    /// Raw triad frames.
    TriadFrames,
    /// Bytes in which no frame was found at the start: replayed as the
    /// configured frame (a capture may begin with a long stretch of noise).
    Unknown,
    /// An MCAP recording.
    Mcap,
}

/// What `path` is, by its content ([`crate::input::detect`]).
pub fn probe(path: &Path) -> Result<CaptureKind, ReplayError> {
    if path.is_dir() {
        return Err(ReplayError::Ros2Bag {
            path: path.to_path_buf(),
        });
    }
    let d = crate::input::detect::detect(path).map_err(|source| ReplayError::Io {
        path: path.to_path_buf(),
        offset: 0,
        source,
    })?;
    Ok(match d.format {
        Some(Format::Mcap) => CaptureKind::Mcap,
        Some(Format::Ros2) => {
            return Err(ReplayError::Ros2Bag {
                path: path.to_path_buf(),
            });
        }
        Some(Format::Frames) if !d.gzip => CaptureKind::Frames,
        Some(Format::TriadFrames) if !d.gzip => CaptureKind::TriadFrames,
        _ => CaptureKind::Unknown,
    })
}

/// Settings of the replay source.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayConfig {
    /// The capture.
    pub path: PathBuf,
    /// Pace in multiples of real time; 0 = as fast as possible.
    pub speed: f64,
    /// Gyro sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Stop after this many sample periods.
    pub limit_periods: Option<u64>,
    /// Frame decoder settings (raw captures).
    pub decoder: DecoderConfig,
}

/// A validated replay, ready to run.
#[derive(Debug)]
pub struct ReplaySource {
    config: ReplayConfig,
    kind: CaptureKind,
    /// The gyros of an MCAP recording of several, in order (empty: one gyro).
    gyros: Vec<String>,
}

impl ReplayConfig {
    /// Validate and look at the file.
    pub fn build(self) -> Result<ReplaySource, ReplayError> {
        let bad = |key, value: String, reason| ReplayError::Config { key, value, reason };
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return Err(bad("speed", self.speed.to_string(), "must be >= 0"));
        }
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(bad(
                "sample_rate_hz",
                self.sample_rate_hz.to_string(),
                "must be > 0",
            ));
        }
        let kind = probe(&self.path)?;
        let gyros = match kind {
            CaptureKind::Mcap => crate::recording::reader::recording_gyro_labels(&self.path)?,
            _ => Vec::new(),
        };
        Ok(ReplaySource {
            config: self,
            kind,
            gyros,
        })
    }
}

/// Stream time covered by one paced batch.
const PACED_BATCH: Duration = Duration::from_millis(20);
/// Samples per batch when not paced.
const FAST_BATCH_SAMPLES: usize = 8192;
/// File read size, bytes.
const READ_CHUNK: usize = 64 * 1024;
/// Longest single sleep, so that shutdown is noticed quickly.
const SLEEP_SLICE: Duration = Duration::from_millis(50);

/// Sends batches no earlier than their due time on the sample clock.
struct Pacer {
    start: Instant,
    /// Seconds of wall time per sample period; 0 = not paced.
    s_per_period: f64,
}

impl Pacer {
    fn new(sample_rate_hz: f64, speed: f64) -> Self {
        Pacer {
            start: Instant::now(),
            s_per_period: if speed > 0.0 {
                1.0 / (sample_rate_hz * speed)
            } else {
                0.0
            },
        }
    }

    fn batch_samples(&self) -> usize {
        if self.s_per_period > 0.0 {
            ((PACED_BATCH.as_secs_f64() / self.s_per_period) as usize).max(1)
        } else {
            FAST_BATCH_SAMPLES
        }
    }

    /// Sleep until period `p` is due; `false` if a shutdown came first.
    fn wait_until(&self, periods: u64, shutdown: &Shutdown) -> bool {
        if self.s_per_period <= 0.0 {
            return !shutdown.is_requested();
        }
        let due = self.start + Duration::from_secs_f64(periods as f64 * self.s_per_period);
        loop {
            if shutdown.is_requested() {
                return false;
            }
            let now = Instant::now();
            if now >= due {
                return true;
            }
            std::thread::sleep((due - now).min(SLEEP_SLICE));
        }
    }
}

impl ReplaySource {
    /// What kind of capture this is.
    pub fn kind(&self) -> CaptureKind {
        self.kind
    }

    /// The gyros of an MCAP recording of several, in order (empty for one gyro
    /// and for a frame capture, whose gyros its frame format says).
    pub fn recorded_gyros(&self) -> &[String] {
        &self.gyros
    }

    /// Replay on the calling (blocking) thread until the end of the capture, the
    /// period limit, or a shutdown. `W` is the frame format of a frame capture;
    /// `outs` holds each of its gyros' telemetry and sender (for an MCAP
    /// recording, one per recorded gyro, in [`ReplaySource::recorded_gyros`] order).
    pub fn run_blocking<W: Axes>(
        self,
        outs: Vec<(Telemetry, BatchSender)>,
        shutdown: Shutdown,
    ) -> Result<SourceReport, ReplayError> {
        let path = self.config.path.clone();
        let report = match self.kind {
            CaptureKind::Mcap => self.replay_mcap(outs, &shutdown),
            _ => self.replay_frames::<W>(outs, &shutdown),
        }?;
        if report.samples == 0 && !shutdown.is_requested() {
            return Err(ReplayError::NoSamples {
                path,
                bytes_read: report.bytes_read,
            });
        }
        tracing::info!(
            path = %path.display(),
            samples = report.samples,
            periods = report.periods,
            "replay finished"
        );
        Ok(report)
    }

    fn pipeline_err(&self) -> impl Fn(PipelineClosed) -> ReplayError + '_ {
        |source| ReplayError::Pipeline {
            path: self.config.path.clone(),
            source,
        }
    }

    fn replay_frames<W: Axes>(
        &self,
        outs: Vec<(Telemetry, BatchSender)>,
        shutdown: &Shutdown,
    ) -> Result<SourceReport, ReplayError> {
        let cfg = &self.config;
        let io_err = |offset, source| ReplayError::Io {
            path: cfg.path.clone(),
            offset,
            source,
        };
        let mut file = File::open(&cfg.path).map_err(|e| io_err(0, e))?;
        let pacer = Pacer::new(cfg.sample_rate_hz, cfg.speed);
        let per_batch = pacer.batch_samples();
        let mut lanes = Lanes::<W>::new(cfg.decoder, cfg.sample_rate_hz, cfg.limit_periods, outs);
        let mut buf = BytesMut::with_capacity(2 * READ_CHUNK);
        let mut in_batch = 0usize;
        let mut eof = false;
        let mut stopped = false;
        while !eof && !stopped {
            // Read straight into the decoder's buffer (no intermediate copy).
            let have = buf.len();
            buf.resize(have + READ_CHUNK, 0);
            let n = loop {
                match file.read(&mut buf[have..]) {
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    r => break r.map_err(|e| io_err(lanes.stats().bytes_read, e)),
                }
            };
            buf.truncate(have + *n.as_ref().unwrap_or(&0));
            let n = n?;
            let now = wall_ns();
            eof = n == 0;
            loop {
                // Runs of contiguous frames in bulk (nearly every frame of a clean
                // capture), then one item at a time; the same samples either way.
                let room = per_batch.saturating_sub(in_batch).max(1).min(lanes.room());
                let run = lanes.decode_run(&mut buf, room, now);
                if run > 0 {
                    in_batch += run;
                } else {
                    let was = lanes.periods();
                    if !lanes.decode_one(&mut buf, eof, now) {
                        break;
                    }
                    in_batch += usize::from(lanes.periods() != was);
                }
                if in_batch >= per_batch || lanes.done() {
                    lanes.sync_stats();
                    if !pacer.wait_until(lanes.periods(), shutdown) {
                        stopped = true;
                    }
                    lanes.blocking_send().map_err(self.pipeline_err())?;
                    in_batch = 0;
                    if stopped || lanes.done() {
                        stopped = true;
                        break;
                    }
                }
            }
        }
        lanes.sync_stats();
        if !stopped {
            pacer.wait_until(lanes.periods(), shutdown);
        }
        lanes.blocking_send().map_err(self.pipeline_err())?;
        // Nothing is held by a lossless sender.
        Ok(lanes.report(0))
    }

    fn replay_mcap(
        &self,
        outs: Vec<(Telemetry, BatchSender)>,
        shutdown: &Shutdown,
    ) -> Result<SourceReport, ReplayError> {
        let cfg = &self.config;
        let pacer = Pacer::new(cfg.sample_rate_hz, cfg.speed);
        // Up to the last complete chunk of a cut recording (the shared reader's
        // recovery), the other channels skipped undecoded.
        let mut reader = if self.gyros.is_empty() {
            RawReader::open(&cfg.path, None, false)?
        } else {
            RawReader::open_every(&cfg.path, false)?
        };
        let mut lanes: Vec<McapLane> = outs.into_iter().map(McapLane::new).collect();
        let mut read_bytes = 0u64;
        while !shutdown.is_requested() {
            let Some((gyro, raw)) = reader.next_labelled()? else {
                break;
            };
            let i = match &gyro {
                None => 0,
                Some(g) => match self.gyros.iter().position(|l| l == g) {
                    Some(i) => i,
                    None => continue,
                },
            };
            let Some(mut b) = lanes[i].batch(raw, cfg)? else {
                if lanes.iter().all(|l| l.done) {
                    break;
                }
                continue;
            };
            let now_read = reader.bytes_read();
            lanes[0]
                .telemetry
                .metrics
                .add_bytes_read(now_read - read_bytes);
            read_bytes = now_read;
            if !pacer.wait_until(lanes[i].report.periods, shutdown) {
                break;
            }
            b.arrived = Instant::now();
            lanes[i].out.blocking_send(b).map_err(self.pipeline_err())?;
        }
        // per gyro: every gyro's samples and periods are those of the first
        let mut report = lanes.swap_remove(0).report;
        report.bytes_read = reader.bytes_read();
        if let Some(cut) = &reader.report().break_at {
            if report.samples == 0 {
                return Err(ReplayError::BrokenBeforeSamples {
                    path: cfg.path.clone(),
                    offset: cut.offset,
                    reason: cut.reason.clone(),
                });
            }
            tracing::warn!(
                path = %cfg.path.display(),
                offset = cut.offset,
                reason = cut.reason,
                "recording is cut: unreadable from byte {}; replayed up to its last complete chunk",
                cut.offset
            );
        }
        Ok(report)
    }
}

/// One recorded gyro of an MCAP replay: where its batches go, and its counts.
struct McapLane {
    telemetry: Telemetry,
    out: BatchSender,
    report: SourceReport,
    next_seq: Option<u64>,
    /// The period limit is reached.
    done: bool,
}

impl McapLane {
    fn new((telemetry, out): (Telemetry, BatchSender)) -> McapLane {
        McapLane {
            telemetry,
            out,
            report: SourceReport::default(),
            next_seq: None,
            done: false,
        }
    }

    /// The source batch of the recorded batch `raw` (cut at the period limit),
    /// counted; `None` once the limit is reached. The recorded sample period
    /// must be the configured rate's.
    fn batch(
        &mut self,
        mut raw: RawBatch,
        cfg: &ReplayConfig,
    ) -> Result<Option<SourceBatch>, ReplayError> {
        let period_ns = 1e9 / cfg.sample_rate_hz;
        if !raw.counts.is_empty() && (raw.dt_ns as f64 - period_ns).abs() > 1.0 {
            return Err(ReplayError::RateMismatch {
                path: cfg.path.clone(),
                dt_ns: raw.dt_ns,
                sample_rate_hz: cfg.sample_rate_hz,
                recorded_hz: 1e9 / raw.dt_ns as f64,
            });
        }
        // Apply the period limit at a sample boundary.
        if let Some(limit) = cfg.limit_periods {
            let left = limit.saturating_sub(self.report.periods);
            if left == 0 {
                self.done = true;
                return Ok(None);
            }
            truncate_periods(&mut raw, left);
        }
        let b = recorded_batch(raw, self.next_seq);
        let lost: u64 = b.gaps.iter().map(|g| g.lost).sum();
        self.telemetry.gyro.add_samples(b.counts.len() as u64);
        self.telemetry.gyro.add_lost_samples(lost);
        self.report.samples += b.counts.len() as u64;
        self.report.periods += b.periods();
        self.next_seq = Some(b.seq0 + b.periods());
        Ok(Some(b))
    }
}

/// The source batch of a recorded `/gyro/raw` batch, its gaps re-emitted as
/// gap events; a new segment when it does not follow `next_seq`.
fn recorded_batch(raw: RawBatch, next_seq: Option<u64>) -> SourceBatch {
    let mut b = SourceBatch::new(Instant::now());
    b.new_segment = next_seq.is_some_and(|s| s != raw.seq0);
    b.seq0 = raw.seq0;
    b.t0_ns = raw.t0_ns;
    b.temp_c = raw.temp_c;
    b.status = Some(raw.status);
    let mut seq = raw.seq0;
    let mut gi = 0;
    for i in 0..raw.counts.len() {
        while gi < raw.gaps.len() && raw.gaps[gi].index == i as u64 {
            let g = raw.gaps[gi];
            let t_ns = raw.t0_ns + ((seq - raw.seq0) as f64 * raw.dt_ns as f64).round() as u64;
            b.events.push(Event {
                t_ns,
                kind: EventKind::Gap { seq, lost: g.lost },
                gyro: None,
            });
            seq += g.lost;
            gi += 1;
        }
        seq += 1;
    }
    b.counts = raw.counts;
    b.gaps = raw.gaps;
    b
}

/// Keep at most `periods` sample periods of `raw` (cut at a sample).
fn truncate_periods(raw: &mut RawBatch, periods: u64) {
    let mut used = 0u64;
    let mut gi = 0;
    for i in 0..raw.counts.len() {
        let mut lost = 0;
        while gi < raw.gaps.len() && raw.gaps[gi].index == i as u64 {
            lost += raw.gaps[gi].lost;
            gi += 1;
        }
        used += lost + 1;
        if used >= periods {
            raw.counts.truncate(i + 1);
            raw.gaps.retain(|g| g.index <= i as u64);
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::messages::Gap;

    #[test]
    fn truncation_keeps_whole_samples() {
        let mut raw = RawBatch {
            t0_ns: 0,
            dt_ns: 1,
            seq0: 0,
            counts: vec![1, 2, 3, 4],
            gaps: vec![Gap { index: 2, lost: 5 }],
            temp_c: None,
            status: 0,
        };
        let mut r = raw.clone();
        truncate_periods(&mut r, 2);
        assert_eq!(r.counts, vec![1, 2]);
        assert!(r.gaps.is_empty());
        // the third sample covers periods 3..8 (5 lost + itself): a limit of 4 keeps it whole
        truncate_periods(&mut raw, 4);
        assert_eq!(raw.counts, vec![1, 2, 3]);
        assert_eq!(raw.gaps, vec![Gap { index: 2, lost: 5 }]);
    }
}
