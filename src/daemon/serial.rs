//! The daemon's serial source: the gyro's frames read from a serial port with
//! `tokio-serial`, decoded by the sans-IO [`FrameDecoder`] and handed to the
//! pipeline as [`SourceBatch`]es (live delivery: the port is never paused).
//!
//! Reads are coalesced into batches of at most 50 ms or 4096 samples (a USB
//! adapter may deliver a few frames per read). The pipeline queue is bounded by
//! a memory budget (`source.queue_budget_mib`, 16 MiB: about 35 min at 1 kHz, see
//! [`crate::daemon::queue`]), so a burst or an estimator update that keeps the
//! pipeline thread busy loses nothing; past the budget, batches are dropped and
//! counted.
//!
//! # When the device goes away
//! A serial stream ends with EOF (or a read error) when the device vanishes
//! (USB adapter unplugged, pty closed). The source then
//! 1. drops the partial frame still buffered (counted in
//!    `sagnac_frame_errors_total{kind="truncated"}`),
//! 2. logs a warning and emits a `device_disconnected` event (recorded in the
//!    MCAP file, which stays valid: the recorder keeps running),
//! 3. reopens the port with exponential backoff (`reconnect_initial_s`,
//!    doubling up to `reconnect_max_s`), emitting `device_reconnected` when it
//!    succeeds.
//!
//! The decoder is kept across the outage, so its byte and frame counts, and its
//! cumulative-counter reference, continue. What happens to the samples depends
//! on how many sample periods the outage lasted (the gyro keeps counting):
//! * up to `max_gap` periods (4096 by default, 4.1 s at 1 kHz): the first frame
//!   after the outage shows a `seq` gap. The missing samples are counted as lost
//!   (`sagnac_lost_samples_total`, a `gap` event, a gap in `/gyro/raw`), and
//!   because the counter kept running the whole angle turned during the outage
//!   arrives with that frame: no pulse is lost, and the pipeline spreads it
//!   linearly over the missing periods.
//! * longer: the 16-bit `seq` cannot tell how many periods passed (it wraps
//!   every 65536), so the decoder drops the first frame as out of sequence and
//!   re-baselines on the next one (a discontinuity): the angle turned during the
//!   outage is not counted and the samples continue as a new time segment.
//!
//! The port must open at start-up (a wrong path fails the run at once);
//! reconnection is only attempted after a connection was made.

use std::path::PathBuf;
use std::time::Duration;

use bytes::BytesMut;
use tokio::io::AsyncReadExt;
use tokio_serial::SerialPortBuilderExt;

use crate::daemon::batch::{BatchSender, PipelineClosed, SourceReport, wall_ns};
use crate::daemon::lanes::Lanes;
use crate::daemon::shutdown::Shutdown;
use crate::daemon::telemetry::Telemetry;
use crate::input::frame::{Axes, DecoderConfig};
use crate::recording::messages::EventKind;

/// Errors of the serial source.
#[derive(Debug, thiserror::Error)]
pub enum SerialError {
    /// A setting is out of range.
    #[error("serial source: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The port could not be opened at start-up.
    #[error("cannot open serial port {path} at {baud} baud")]
    Open {
        path: PathBuf,
        baud: u32,
        source: tokio_serial::Error,
    },
    /// The pipeline stopped while the source was still reading.
    #[error("serial source {path}")]
    Pipeline {
        path: PathBuf,
        source: PipelineClosed,
    },
}

/// Settings of the serial source.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialConfig {
    /// Device path, e.g. `/dev/ttyUSB0`.
    pub path: PathBuf,
    /// Baud rate.
    pub baud: u32,
    /// First reconnect delay.
    pub reconnect_initial: Duration,
    /// Longest reconnect delay.
    pub reconnect_max: Duration,
    /// Sample rate of the gyro, Hz (for the sample clock).
    pub sample_rate_hz: f64,
    /// Stop after this many sample periods (`None`: until shut down).
    pub limit_periods: Option<u64>,
    /// Frame decoder settings.
    pub decoder: DecoderConfig,
}

/// A validated serial source, ready to run.
pub struct SerialSource {
    config: SerialConfig,
    port: Option<tokio_serial::SerialStream>,
}

impl std::fmt::Debug for SerialSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialSource")
            .field("config", &self.config)
            .field("open", &self.port.is_some())
            .finish()
    }
}

impl SerialConfig {
    /// Validate.
    pub fn build(self) -> Result<SerialSource, SerialError> {
        let bad = |key, value: String, reason| SerialError::Config { key, value, reason };
        if self.path.as_os_str().is_empty() {
            return Err(bad("path", "\"\"".into(), "a device path is required"));
        }
        if self.baud == 0 {
            return Err(bad("baud", "0".into(), "must be > 0"));
        }
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(bad(
                "sample_rate_hz",
                self.sample_rate_hz.to_string(),
                "must be > 0",
            ));
        }
        if self.reconnect_initial.is_zero() || self.reconnect_max < self.reconnect_initial {
            return Err(bad(
                "reconnect_max",
                format!("{:?}", self.reconnect_max),
                "must be >= reconnect_initial > 0",
            ));
        }
        Ok(SerialSource {
            config: self,
            port: None,
        })
    }
}

/// Read buffer growth per read, bytes (tokio-serial zero-fills the spare capacity).
const READ_RESERVE: usize = 4096;
/// Longest time decoded samples wait to be handed to the pipeline.
const COALESCE: Duration = Duration::from_millis(50);
/// Most samples per batch.
const MAX_BATCH: usize = 4096;

/// Sleep until `t`, or forever when `None`.
async fn sleep_until_opt(t: Option<tokio::time::Instant>) {
    match t {
        Some(t) => tokio::time::sleep_until(t).await,
        None => std::future::pending().await,
    }
}

impl SerialSource {
    /// Open the port now (inside a tokio runtime), so that a wrong path fails
    /// before anything else starts. [`SerialSource::run`] opens it otherwise.
    pub fn open(&mut self) -> Result<(), SerialError> {
        if self.port.is_none() {
            let cfg = &self.config;
            let port = tokio_serial::new(cfg.path.display().to_string(), cfg.baud)
                .open_native_async()
                .map_err(|source| SerialError::Open {
                    path: cfg.path.clone(),
                    baud: cfg.baud,
                    source,
                })?;
            tracing::info!(device = %cfg.path.display(), baud = cfg.baud, "serial port open");
            self.port = Some(port);
        }
        Ok(())
    }

    /// Read until shut down, the period limit, or the pipeline closing. `W` is
    /// the frame format; `outs` holds each of its gyros' telemetry and sender.
    pub async fn run<W: Axes>(
        mut self,
        outs: Vec<(Telemetry, BatchSender)>,
        mut shutdown: Shutdown,
    ) -> Result<SourceReport, SerialError> {
        self.open()?;
        let mut port = self.port.take();
        let cfg = self.config;
        let device = cfg.path.display().to_string();
        let open = || tokio_serial::new(device.clone(), cfg.baud).open_native_async();
        let devices: Vec<_> = outs.iter().map(|(t, _)| t.device()).collect();
        let connected = |on: i64| devices.iter().for_each(|d| d.connected.set(on));
        connected(1);
        let pipeline_err = |source| SerialError::Pipeline {
            path: cfg.path.clone(),
            source,
        };

        let mut lanes = Lanes::<W>::new(cfg.decoder, cfg.sample_rate_hz, cfg.limit_periods, outs);
        let mut buf = BytesMut::with_capacity(READ_RESERVE);
        let mut disconnects = 0u64;
        let mut backoff = cfg.reconnect_initial;
        let mut flush_at: Option<tokio::time::Instant> = None;

        'run: loop {
            let Some(p) = port.as_mut() else {
                // Disconnected: wait, then try again.
                tokio::select! {
                    () = tokio::time::sleep(backoff) => {}
                    () = shutdown.requested() => break 'run,
                }
                match open() {
                    Ok(p) => {
                        tracing::info!(device, "serial device reconnected");
                        connected(1);
                        devices.iter().for_each(|d| d.reconnects.inc());
                        lanes.push_event(
                            wall_ns(),
                            EventKind::DeviceReconnected {
                                device: device.clone(),
                            },
                        );
                        port = Some(p);
                        backoff = cfg.reconnect_initial;
                    }
                    Err(e) => {
                        tracing::debug!(device, error = %crate::chain::chain(&e), retry_in = ?backoff, "serial device still away");
                        backoff = (backoff * 2).min(cfg.reconnect_max);
                    }
                }
                continue;
            };
            buf.reserve(READ_RESERVE);
            // read_buf is cancel safe: when another branch wins, nothing was read.
            let read = tokio::select! {
                r = p.read_buf(&mut buf) => Some(r),
                () = sleep_until_opt(flush_at) => None,
                () = shutdown.requested() => break 'run,
            };
            let Some(read) = read else {
                // The coalescing delay is over: hand the batch to the pipeline.
                flush_at = None;
                lanes.send().await.map_err(pipeline_err)?;
                continue;
            };
            let now = wall_ns();
            let gone = match read {
                Ok(0) => Some("end of stream".to_string()),
                Ok(_) => None,
                Err(e) => Some(e.to_string()),
            };
            if let Some(reason) = gone {
                went_away(&mut lanes, &mut buf, &device, reason, now);
                disconnects += 1;
                connected(0);
                port = None;
                backoff = cfg.reconnect_initial;
            } else {
                lanes.decode_available(&mut buf, now);
                lanes.sync_stats();
            }
            // Coalesce reads (a USB adapter may deliver a few frames per read) into
            // batches of at most COALESCE or MAX_BATCH samples: few batches, each
            // charged little more than its samples' bytes in the queue budget.
            let urgent = port.is_none() || lanes.done() || lanes.pending_samples() >= MAX_BATCH;
            if urgent {
                flush_at = None;
                lanes.send().await.map_err(pipeline_err)?;
            } else if flush_at.is_none() && lanes.has_pending() {
                flush_at = Some(tokio::time::Instant::now() + COALESCE);
            }
            if lanes.done() {
                tracing::info!(
                    periods = lanes.periods(),
                    "serial source: run duration reached"
                );
                break;
            }
        }
        // Shutdown: whatever is buffered is a partial frame of an interrupted stream.
        let now = wall_ns();
        if !lanes.done() {
            while lanes.decode_one(&mut buf, true, now) {}
        }
        lanes.sync_stats();
        lanes.send().await.map_err(pipeline_err)?;
        lanes.close(disconnects).await.map_err(pipeline_err)
    }
}

/// The device went away: drop the partial frame (counted), keep the
/// decoder's state, log it and record the event.
fn went_away<W: Axes>(
    lanes: &mut Lanes<W>,
    buf: &mut BytesMut,
    device: &str,
    reason: String,
    now: u64,
) {
    while lanes.decode_one(buf, true, now) {}
    lanes.sync_stats();
    tracing::warn!(
        device,
        reason,
        "serial device went away; reconnecting with backoff"
    );
    lanes.push_event(
        now,
        EventKind::DeviceDisconnected {
            device: device.to_string(),
            reason,
        },
    );
}
