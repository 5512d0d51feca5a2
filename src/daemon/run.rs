//! Wiring the daemon together: [`Daemon::build`] validates the configuration
//! and builds every component; [`Daemon::run`] starts the tasks, waits for the
//! source to end (end of a replay, the run duration, or a shutdown request),
//! drains every stage in order and reports.
//!
//! ```text
//!  source task ──SourceBatch──▶ pipeline thread ──SinkMessage──▶ recorder thread (MCAP)
//!  (serial: async task;        (blocking: gap fill,      │
//!   replay, simulated bench:    QN removal, Allan,       └──▶ Metrics ◀── /metrics server task
//!   blocking threads)           estimator)
//! ```
//!
//! Every channel is bounded: the source -> pipeline queue holds
//! `run.channel_capacity` batches for a replay or the simulated bench (which
//! wait for room), and `source.queue_budget_mib` of sample data for a serial
//! source (which drops past it, see [`crate::daemon::queue`]); the recorder
//! queue holds 1024 messages.
//!
//! Shutdown (mini-redis style): SIGINT/SIGTERM (or a programmatic trigger)
//! flips a `watch` channel every task listens to. The source stops reading,
//! flushes the partial batch it holds and drops its sender; the pipeline thread
//! drains the queue, flushes the wavelet bank, publishes the final estimates
//! (log, MCAP, metrics) and returns; then the recorder writes its summary and
//! closes the file (its error is checked and returned); then the metrics server
//! stops. Each stage holds a drain guard; `run` returns once every guard is
//! dropped.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use crate::daemon::batch::{self, Delivery, SourceReport};
use crate::daemon::config::{Config, ConfigError, SourceKind};
use crate::daemon::http::{self, HttpError};
use crate::daemon::process::{Outputs, ProcessConfig, ProcessError, ProcessReport, Processor};
use crate::daemon::queue::QueueBound;
use crate::daemon::shutdown::{self, ShutdownTrigger};
use crate::daemon::status::LiveStatus;
use crate::daemon::telemetry::Telemetry;
use crate::model::{GyroModel, ModelError};
use crate::pipeline::PipelineConfig;
use crate::sink::mcap::{RecordError, Recorder, RecorderConfig, RecordingSummary};
use crate::sink::meta::{AGREE_REL, Contradiction, RecordingMeta, check_flag};
use crate::sink::metrics::{Metrics, MetricsError};
use crate::source::bench::{BenchError, SimBench, SimBenchConfig};
use crate::source::frame::DecoderConfig;
use crate::source::replay::{self, CaptureKind, ReplayConfig, ReplayError, ReplaySource};
use crate::source::serial::{SerialConfig, SerialError, SerialSource};

/// The built-in gyro model of the simulated bench (the founding paper's RLG).
pub const PAPER_GYRO_TOML: &str = include_str!("../../config/paper_gyro.toml");

/// zstd level of the recording: 1 compresses the JSON samples about twice as
/// fast as the default 3 for files about 10 % larger (scripts/bench-pipeline).
pub const ZSTD_LEVEL: u32 = 1;

/// Uncompressed chunk size of the recording, bytes: 256 KiB costs about 4 % fewer
/// instructions per sample than 1 MiB, 4 MiB or 16 MiB (callgrind, 200 s replay;
/// 64 KiB and 128 KiB cost the same as 256 KiB) for the same file size (within
/// 0.3 %), and keeps the compressor's working set small. At 1 kHz a chunk holds
/// about 9 s of samples, so the 2 s flush interval closes chunks in live runs.
pub const CHUNK_SIZE: u64 = 256 * 1024;

/// Share of wall time estimator updates may take with a replay or the simulated
/// bench (see [`crate::daemon::process`]). In a replay as fast as possible the
/// estimator always uses its whole budget (an update costs 0.03-0.3 s, an interval of
/// samples takes milliseconds), so this is a direct throughput cost; at 5 % a
/// dashboard still sees an update about every second of a fast replay, and the
/// final update (the one a replay is run for) is always made.
pub const UPDATE_BUDGET: f64 = 0.05;

/// Errors of the daemon.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("gyro model {origin}: {source}")]
    Model { origin: String, source: ModelError },
    #[error(transparent)]
    Serial(#[from] SerialError),
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error(transparent)]
    Bench(#[from] BenchError),
    #[error(transparent)]
    Process(#[from] ProcessError),
    #[error("MCAP recording: {0}")]
    Record(#[from] RecordError),
    #[error(transparent)]
    Http(#[from] HttpError),
    #[error(transparent)]
    Spec(#[from] crate::model::spec::SpecError),
    #[error("metrics: {0}")]
    Metrics(#[from] MetricsError),
    /// An explicit gyro setting contradicts what the replayed recording says.
    #[error(transparent)]
    Contradiction(#[from] Contradiction),
    /// A source that does not carry the gyro's rate or pulse weight (serial
    /// input, a raw frame capture) and no flag or config key giving them.
    #[error(
        "{input} does not carry the gyro's {missing}: give {how} (raw frames have no metadata; \
         an MCAP recording made by `sagnac run` and the simulated bench carry them)"
    )]
    GyroUnspecified {
        input: String,
        missing: &'static str,
        how: &'static str,
    },
    #[error("the {task} task failed: {message}")]
    Task { task: &'static str, message: String },
}

/// Which gyro settings the user gave explicitly (a flag, or the key present in
/// the config file, whatever its value): those must agree with what a simulated
/// model or an MCAP recording says; otherwise the source's own values are used.
/// Serial input and raw frame captures carry neither, so both must be given.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Explicit {
    pub rate_hz: bool,
    pub pulse_arcsec: bool,
}

enum Source {
    Serial(Box<SerialSource>),
    Replay(Box<ReplaySource>),
    Bench(Box<SimBench>),
}

/// A daemon ready to run.
pub struct Daemon {
    config: Config,
    source: Source,
    processor: Processor,
    metrics_addr: Option<SocketAddr>,
    /// The metadata record of the recording.
    recording_meta: RecordingMeta,
    /// The live status a terminal shows, if any.
    status: Option<Arc<LiveStatus>>,
}

/// What a run did.
#[derive(Debug)]
pub struct RunReport {
    /// The source's counts.
    pub source: SourceReport,
    /// The pipeline's counts and final analysis.
    pub process: ProcessReport,
    /// The recording, if any.
    pub recording: Option<RecordingSummary>,
    /// Where `/metrics` was served, if anywhere.
    pub metrics_addr: Option<SocketAddr>,
}

/// Serial input and raw frame captures do not carry the rate or pulse weight:
/// both must be given explicitly.
fn require_explicit(explicit: Explicit, input: String) -> Result<(), DaemonError> {
    let (missing, how) = match (explicit.rate_hz, explicit.pulse_arcsec) {
        (true, true) => return Ok(()),
        (false, false) => (
            "sample rate and pulse weight",
            "--rate-hz and --pulse-arcsec (config keys `gyro.rate_hz`, `gyro.pulse_arcsec`)",
        ),
        (false, true) => ("sample rate", "--rate-hz (config key `gyro.rate_hz`)"),
        (true, false) => (
            "pulse weight",
            "--pulse-arcsec (config key `gyro.pulse_arcsec`)",
        ),
    };
    Err(DaemonError::GyroUnspecified {
        input,
        missing,
        how,
    })
}

fn mismatch(key: &'static str, value: f64, message: &'static str) -> DaemonError {
    DaemonError::Config(ConfigError::Invalid {
        key,
        value: value.to_string(),
        message,
    })
}

impl Daemon {
    /// Validate `config` (already overridden by flags) and build every component.
    /// The gyro rate and pulse weight of a simulated bench come from its model,
    /// the rate and pulse weight of an MCAP replay from the recording (its
    /// metadata record, else its sample period), unless given explicitly (then
    /// they must agree). The recording made carries them in its metadata record.
    pub fn build(mut config: Config, explicit: Explicit) -> Result<Daemon, DaemonError> {
        config.validate()?;
        let speed = config.source.effective_speed();
        let limit = |rate_hz: f64| {
            (config.run.duration_s > 0.0)
                .then(|| (config.run.duration_s * rate_hz).round().max(1.0) as u64)
        };
        let mut model_toml = None;
        let source = match config.source.kind {
            SourceKind::Simulate => {
                let (model, origin) = if config.source.model.is_empty() {
                    (
                        GyroModel::from_toml_str(PAPER_GYRO_TOML, "built-in paper_gyro.toml"),
                        "built-in paper_gyro.toml".to_string(),
                    )
                } else {
                    let p = PathBuf::from(&config.source.model);
                    (GyroModel::load(&p), p.display().to_string())
                };
                let model = model.map_err(|source| DaemonError::Model {
                    origin: origin.clone(),
                    source,
                })?;
                if model.gyro.output != crate::model::config::OutputKind::Counts {
                    return Err(DaemonError::Config(ConfigError::Invalid {
                        key: "source.model",
                        value: origin.clone(),
                        message: "gyro.output = \"rate\": the simulated bench sends pulse-counter frames; simulate a \
                         rate gyro with `sagnac simulate` (CSV) instead",
                    }));
                }
                model_toml = model.to_toml().ok();
                let (rate, pulse) = (model.gyro.sample_rate_hz, model.gyro.pulse_weight_arcsec);
                if explicit.rate_hz && config.gyro.rate_hz != rate {
                    return Err(mismatch(
                        "gyro.rate_hz",
                        config.gyro.rate_hz,
                        "differs from the simulated model's gyro.sample_rate_hz (leave it out to use the model's)",
                    ));
                }
                if explicit.pulse_arcsec && config.gyro.pulse_arcsec != pulse {
                    return Err(mismatch(
                        "gyro.pulse_arcsec",
                        config.gyro.pulse_arcsec,
                        "differs from the simulated model's gyro.pulse_weight_arcsec (leave it out to use the model's)",
                    ));
                }
                config.gyro.rate_hz = rate;
                config.gyro.pulse_arcsec = pulse;
                tracing::info!(
                    model = origin,
                    seed = config.source.seed,
                    speed,
                    "source: simulated bench"
                );
                Source::Bench(Box::new(
                    SimBenchConfig {
                        model,
                        seed: config.source.seed,
                        speed,
                        duration_s: (config.run.duration_s > 0.0).then_some(config.run.duration_s),
                    }
                    .build()?,
                ))
            }
            SourceKind::Replay => {
                let path = PathBuf::from(&config.source.replay_path);
                if replay::probe(&path)? == CaptureKind::Mcap {
                    // The recording's own rate and pulse weight (its metadata record,
                    // else the sample period of /gyro/raw); an explicit value must agree.
                    let recorded = replay::probe_mcap_gyro(&path)?;
                    let given = |on: bool, v: f64| on.then_some(v);
                    if let Some(r) = check_flag(
                        "gyro.rate_hz",
                        given(explicit.rate_hz, config.gyro.rate_hz),
                        recorded.rate_hz,
                        &path,
                        recorded.origin,
                        recorded.rate_rel_tol,
                    )? {
                        config.gyro.rate_hz = r;
                    }
                    if let Some(p) = check_flag(
                        "gyro.pulse_arcsec",
                        given(explicit.pulse_arcsec, config.gyro.pulse_arcsec),
                        recorded.pulse_arcsec,
                        &path,
                        recorded.origin,
                        AGREE_REL,
                    )? {
                        config.gyro.pulse_arcsec = p;
                    }
                } else {
                    require_explicit(explicit, format!("raw frame capture {}", path.display()))?;
                }
                tracing::info!(path = %path.display(), speed, "source: replay");
                Source::Replay(Box::new(
                    ReplayConfig {
                        path,
                        speed,
                        rate_hz: config.gyro.rate_hz,
                        limit_periods: limit(config.gyro.rate_hz),
                        decoder: DecoderConfig::default(),
                    }
                    .build()?,
                ))
            }
            SourceKind::Serial => {
                require_explicit(
                    explicit,
                    format!("serial input {}", config.source.serial_path),
                )?;
                tracing::info!(
                    device = config.source.serial_path,
                    baud = config.source.baud,
                    "source: serial"
                );
                Source::Serial(Box::new(
                    SerialConfig {
                        path: PathBuf::from(&config.source.serial_path),
                        baud: config.source.baud,
                        reconnect_initial: Duration::from_secs_f64(
                            config.source.reconnect_initial_s,
                        ),
                        reconnect_max: Duration::from_secs_f64(config.source.reconnect_max_s),
                        rate_hz: config.gyro.rate_hz,
                        limit_periods: limit(config.gyro.rate_hz),
                        decoder: DecoderConfig::default(),
                    }
                    .build()?,
                ))
            }
        };
        let live = config.source.kind == SourceKind::Serial;
        let mut processor = ProcessConfig {
            pipeline: PipelineConfig {
                rate_hz: config.gyro.rate_hz,
                pulse_arcsec: Some(config.gyro.pulse_arcsec),
                wavelet: config.dsp.wavelet.clone(),
                levels: (config.dsp.levels > 0).then_some(config.dsp.levels),
                allan_cap: config.allan.full_overlap_max_m,
            },
            interval_s: config.estimator.interval_s,
            batch_samples: config.record.batch_samples,
            delivery: if live {
                Delivery::Live
            } else {
                Delivery::Lossless
            },
            update_budget: (!live).then_some(UPDATE_BUDGET),
        }
        .build()?;
        if !config.spec.path.is_empty() {
            let spec = crate::model::spec::Spec::load(std::path::Path::new(&config.spec.path))?;
            tracing::info!(
                path = config.spec.path,
                confidence = spec.confidence,
                "acceptance test"
            );
            // the stop trigger is attached in run()
            processor.set_spec(spec, None);
        }
        let metrics_addr = if config.metrics.addr.is_empty() {
            None
        } else {
            // validate() checked that it parses
            config.metrics.addr.parse().ok()
        };
        // What the recording says about itself (see crate::sink::meta).
        let mut recording_meta =
            RecordingMeta::counts(config.gyro.rate_hz, config.gyro.pulse_arcsec);
        recording_meta.config = toml::to_string(&config).ok();
        recording_meta.model = model_toml;
        Ok(Daemon {
            config,
            source,
            processor,
            metrics_addr,
            recording_meta,
            status: None,
        })
    }

    /// Keep `status` up to date during the run (samples, estimates, and a
    /// replay's progress through its file), for a terminal's status line.
    pub fn with_status(mut self, status: Arc<LiveStatus>) -> Self {
        self.status = Some(status);
        self
    }

    /// The configuration in effect (after the source's own settings were applied).
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// Run until the source ends or `trigger` fires, then drain everything.
    pub async fn run(self, trigger: ShutdownTrigger) -> Result<RunReport, DaemonError> {
        let Daemon {
            config,
            mut source,
            mut processor,
            metrics_addr,
            recording_meta,
            status,
        } = self;
        if config.spec.stop_when_decided {
            // --stop-when-decided: the ordinary shutdown once every coefficient is decided
            processor.attach_spec_stop(trigger.clone());
        }
        // A serial port that cannot be opened fails the run before anything starts.
        if let Source::Serial(s) = &mut source {
            s.open()?;
        }
        let gyro = config.gyro.info(crate::sink::metrics::DEFAULT_GYRO);
        let telemetry = Telemetry::new(Arc::new(Metrics::new()?), &gyro)?;
        if let (Some(st), Source::Replay(_)) = (&status, &source)
            && let Ok(m) = std::fs::metadata(&config.source.replay_path)
        {
            st.set_replay(m.len(), Arc::clone(&telemetry.metrics));
        }
        let (drain_guard, drained) = shutdown::drain_channel();

        // The metrics server stops last, after the final estimates are in.
        let (http_trigger, http_shutdown) = shutdown::channel();
        let mut served = None;
        let http_task = match metrics_addr {
            Some(addr) => {
                let (bound, server) =
                    http::bind(addr, Arc::clone(&telemetry.metrics), http_shutdown.watch()).await?;
                tracing::info!("metrics on http://{bound}/metrics");
                served = Some(bound);
                let guard = drain_guard.clone();
                Some(tokio::spawn(async move {
                    server.await;
                    drop(guard);
                }))
            }
            None => None,
        };

        let recorder = if config.record.dir.is_empty() {
            None
        } else {
            let rc = RecorderConfig {
                record_dir: PathBuf::from(&config.record.dir),
                flush_interval_s: config.record.flush_interval_s,
                zstd_level: ZSTD_LEVEL,
                chunk_size: CHUNK_SIZE,
                ..RecorderConfig::default()
            };
            let r = tokio::task::spawn_blocking(move || {
                Recorder::start_with_metadata(
                    &rc,
                    std::time::SystemTime::now(),
                    Some(&recording_meta),
                )
            })
            .await
            .map_err(|e| join_err("recorder start", e))??;
            tracing::info!(path = %r.path().display(), "recording");
            Some(r)
        };

        tracing::info!(
            rate_hz = config.gyro.rate_hz,
            pulse_arcsec = config.gyro.pulse_arcsec,
            wavelet = config.dsp.wavelet,
            latency_samples = processor.pipeline().latency(),
            estimator_interval_s = config.estimator.interval_s,
            "pipeline ready"
        );

        let bound = match source {
            Source::Serial(_) => QueueBound::Bytes(config.source.queue_budget_bytes()),
            _ => QueueBound::Batches(config.run.channel_capacity),
        };
        let (sender, rx) = batch::channel(bound, &telemetry);
        let outputs = Outputs {
            recorder: recorder.as_ref().map(Recorder::sender),
            telemetry: telemetry.clone(),
            stop: Some(trigger.subscribe()),
            status,
        };
        let guard = drain_guard.clone();
        let process_task = tokio::task::spawn_blocking(move || {
            let report = processor.run(rx, outputs);
            drop(guard);
            report
        });
        let sd = trigger.subscribe();
        let tel = telemetry.clone();
        let source_result: Result<SourceReport, DaemonError> = match source {
            Source::Serial(s) => tokio::spawn(async move { s.run(sender, tel, sd).await })
                .await
                .map_err(|e| join_err("serial source", e))?
                .map_err(DaemonError::from),
            Source::Replay(r) => {
                tokio::task::spawn_blocking(move || r.run_blocking(sender, tel, sd))
                    .await
                    .map_err(|e| join_err("replay source", e))?
                    .map_err(DaemonError::from)
            }
            Source::Bench(b) => {
                tokio::task::spawn_blocking(move || b.run_blocking(sender, tel, sd))
                    .await
                    .map_err(|e| join_err("simulated bench", e))?
                    .map_err(DaemonError::from)
            }
        };
        if let Err(e) = &source_result {
            tracing::error!(error = %e, "source failed; draining the pipeline");
        }
        if trigger.is_triggered() {
            tracing::info!("shutdown requested: draining the pipeline");
        }
        // The source dropped its sender: the pipeline drains and returns.
        let process = process_task.await.map_err(|e| join_err("pipeline", e))?;
        let recording = match recorder {
            Some(r) => {
                let summary = tokio::task::spawn_blocking(move || r.finish())
                    .await
                    .map_err(|e| join_err("recorder", e))?;
                match summary {
                    Ok(s) => {
                        telemetry.metrics.set_recording_bytes(s.bytes);
                        tracing::info!(
                            path = %s.path.display(),
                            bytes = s.bytes,
                            messages = s.messages(),
                            "recording finished"
                        );
                        Some(s)
                    }
                    Err(e) => {
                        tracing::error!(error = %e, "recording failed");
                        http_trigger.trigger();
                        return Err(e.into());
                    }
                }
            }
            None => None,
        };
        http_trigger.trigger();
        if let Some(t) = http_task {
            let _ = t.await;
        }
        drop(drain_guard);
        drained.wait().await;
        let source = source_result?;
        tracing::info!(
            samples = process.samples,
            periods = process.periods,
            lost = process.lost,
            updates = process.updates,
            max_estimate_latency_s = process.max_estimate_latency_s,
            recorder_dropped = process.recorder_dropped,
            "run finished"
        );
        Ok(RunReport {
            source,
            process,
            recording,
            metrics_addr: served,
        })
    }
}

fn join_err(task: &'static str, e: tokio::task::JoinError) -> DaemonError {
    DaemonError::Task {
        task,
        message: e.to_string(),
    }
}
