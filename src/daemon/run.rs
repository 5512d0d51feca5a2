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

use crate::daemon::batch::{self, BatchSender, Delivery, SourceReport};
use crate::daemon::bench::{BenchError, SimBench, SimBenchConfig};
use crate::daemon::config::{Config, ConfigError, FrameKind, LabelledInput, SourceKind};
use crate::daemon::http::{self, HttpError};
use crate::daemon::process::{Outputs, ProcessConfig, ProcessError, ProcessReport, Processor};
use crate::daemon::queue::QueueBound;
use crate::daemon::replay::{self, CaptureKind, ReplayConfig, ReplayError, ReplaySource};
use crate::daemon::serial::{SerialConfig, SerialError, SerialSource};
use crate::daemon::shutdown::{self, ShutdownTrigger};
use crate::daemon::status::LiveStatus;
use crate::daemon::telemetry::Telemetry;
use crate::input::frame::{DecoderConfig, Single, Triad};
use crate::model::{GyroModel, ModelError};
use crate::pipeline::PipelineConfig;
use crate::recording::meta::{AGREE_REL, Contradiction, RecordingMeta, check_flag};
use crate::recording::writer::{RecordError, Recorder, RecorderConfig, RecordingSummary};
use crate::sink::metrics::{Metrics, MetricsError};

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
    #[error("gyro model {origin}")]
    Model { origin: String, source: ModelError },
    #[error(transparent)]
    Serial(#[from] SerialError),
    #[error(transparent)]
    Replay(#[from] ReplayError),
    #[error(transparent)]
    Bench(#[from] BenchError),
    #[error(transparent)]
    Process(#[from] ProcessError),
    #[error("MCAP recording")]
    Record(#[from] RecordError),
    #[error(transparent)]
    Http(#[from] HttpError),
    #[error(transparent)]
    Spec(#[from] crate::model::spec::SpecError),
    #[error("metrics")]
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
    pub sample_rate_hz: bool,
    pub pulse_arcsec: bool,
    /// `source.frame` (`--frame`) was given: a raw capture's frames must be of it.
    pub frame: bool,
}

enum Source {
    Serial(Box<SerialSource>),
    Replay(Box<ReplaySource>),
    Bench(Box<SimBench>),
}

/// One gyro of the daemon: its label, its numeric stage and what its
/// recording's metadata says of it.
struct Gyro {
    label: String,
    processor: Processor,
    meta: RecordingMeta,
}

/// One source (a serial port, a capture, the simulated bench) and the gyros
/// its frames carry (one, or three for a triad).
struct Input {
    source: Source,
    frame: FrameKind,
    gyros: Vec<Gyro>,
}

/// A daemon ready to run.
pub struct Daemon {
    config: Config,
    inputs: Vec<Input>,
    metrics_addr: Option<SocketAddr>,
    /// The metadata record of the recording.
    recording_meta: RecordingMeta,
    /// The live status a terminal shows, if any (of the first gyro).
    status: Option<Arc<LiveStatus>>,
}

/// What a run did.
#[derive(Debug)]
pub struct RunReport {
    /// The sources' counts, summed over the sources (per gyro of a triad,
    /// samples and periods are those of one gyro).
    pub source: SourceReport,
    /// The first gyro's pipeline counts and final analysis.
    pub process: ProcessReport,
    /// Every gyro's label and pipeline report, in order.
    pub gyros: Vec<(String, ProcessReport)>,
    /// The recording, if any.
    pub recording: Option<RecordingSummary>,
    /// Where `/metrics` was served, if anywhere.
    pub metrics_addr: Option<SocketAddr>,
}

/// The gyros of an MCAP recording: (label, rate in Hz, pulse weight in arcsec).
type RecordedGyros = Vec<(Option<String>, f64, f64)>;

/// A source as built, before its gyros' pipelines: its frame, and each gyro's
/// label and (rate, pulse weight, model TOML).
struct BuiltSource {
    source: Source,
    frame: FrameKind,
    labels: Vec<String>,
    gyros: Vec<(f64, f64, Option<String>)>,
}

/// Two gyros with one label would share metrics and topics.
fn check_labels_unique(inputs: &[Input]) -> Result<(), DaemonError> {
    let labels: Vec<&str> = inputs
        .iter()
        .flat_map(|i| i.gyros.iter().map(|g| g.label.as_str()))
        .collect();
    match labels
        .iter()
        .enumerate()
        .find(|(k, l)| labels[..*k].contains(l))
    {
        Some((_, dup)) => Err(DaemonError::Config(ConfigError::Invalid {
            key: "source.inputs",
            value: dup.to_string(),
            message: "two gyros have this label: give the inputs distinct labels",
        })),
        None => Ok(()),
    }
}

/// Serial input and raw frame captures do not carry the rate or pulse weight:
/// both must be given explicitly.
fn require_explicit(explicit: Explicit, input: String) -> Result<(), DaemonError> {
    let (missing, how) = match (explicit.sample_rate_hz, explicit.pulse_arcsec) {
        (true, true) => return Ok(()),
        (false, false) => (
            "sample rate and pulse weight",
            "--sample-rate-hz and --pulse-arcsec (config keys `gyro.sample_rate_hz`, `gyro.pulse_arcsec`)",
        ),
        (false, true) => (
            "sample rate",
            "--sample-rate-hz (config key `gyro.sample_rate_hz`)",
        ),
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

/// A gyro model of the simulated bench: `path`, or the built-in paper gyro when empty.
fn load_model(path: &str) -> Result<(GyroModel, String), DaemonError> {
    let (model, origin) = if path.is_empty() {
        let origin = "built-in paper_gyro.toml".to_string();
        (GyroModel::from_toml_str(PAPER_GYRO_TOML, &origin), origin)
    } else {
        let p = PathBuf::from(path);
        if let Ok(text) = std::fs::read_to_string(&p) {
            for (old, new) in crate::keys::renamed_in(&text, crate::keys::MODEL_RENAMES) {
                tracing::warn!("{}", crate::keys::rename_warning(path, old, new));
            }
        }
        (GyroModel::load(&p), p.display().to_string())
    };
    let model = model.map_err(|source| DaemonError::Model {
        origin: origin.clone(),
        source,
    })?;
    if model.gyro.output != crate::model::config::OutputKind::Counts {
        return Err(DaemonError::Config(ConfigError::Invalid {
            key: "source.model",
            value: origin,
            message: "gyro.output = \"rate\": the simulated bench sends pulse-counter frames; simulate a \
             rate gyro with `sagnac simulate` (CSV) instead",
        }));
    }
    Ok((model, origin))
}

/// The (label, path) of each serial device or capture of `kind`.
fn labelled_inputs(config: &Config, single: &str) -> Vec<(Option<String>, String)> {
    if config.source.inputs.is_empty() {
        return vec![(None, single.to_string())];
    }
    config
        .source
        .inputs
        .iter()
        .filter_map(|t| LabelledInput::parse(t).ok()) // validate() checked them
        .map(|i| (Some(i.label), i.path))
        .collect()
}

impl Daemon {
    /// Validate `config` (already overridden by flags) and build every component.
    /// The gyro rate and pulse weight of a simulated bench come from its model,
    /// the rate and pulse weight of an MCAP replay from the recording (its
    /// metadata record, else its sample period), unless given explicitly (then
    /// they must agree). The recording made carries them in its metadata record.
    pub fn build(mut config: Config, explicit: Explicit) -> Result<Daemon, DaemonError> {
        config.validate()?;
        let (built, model_toml) = Daemon::sources(&mut config, explicit)?;
        let spec = Daemon::spec(&config)?;
        let live = config.source.kind == SourceKind::Serial;
        let mut inputs = Vec::new();
        for b in built {
            let mut gyros = Vec::new();
            for (label, (sample_rate_hz, pulse_arcsec, model)) in b.labels.into_iter().zip(b.gyros)
            {
                let mut processor = Daemon::processor(&config, sample_rate_hz, pulse_arcsec, live)?;
                if let Some(spec) = &spec {
                    // the stop trigger is attached in run()
                    processor.set_spec(spec.clone(), None);
                }
                let mut meta = RecordingMeta::counts(sample_rate_hz, pulse_arcsec);
                meta.model = model;
                gyros.push(Gyro {
                    label,
                    processor,
                    meta,
                });
            }
            inputs.push(Input {
                source: b.source,
                frame: b.frame,
                gyros,
            });
        }
        check_labels_unique(&inputs)?;
        // validate() checked that it parses
        let metrics_addr = config.metrics.addr.parse().ok();
        // What the recording says about itself (see crate::recording::meta).
        let mut recording_meta =
            RecordingMeta::counts(config.gyro.sample_rate_hz, config.gyro.pulse_arcsec);
        recording_meta.config = toml::to_string(&config).ok();
        recording_meta.model = model_toml;
        Ok(Daemon {
            config,
            inputs,
            metrics_addr,
            recording_meta,
            status: None,
        })
    }

    /// Every source of the configuration, with its gyros' labels and
    /// settings; and the simulated bench's model TOML.
    fn sources(
        config: &mut Config,
        explicit: Explicit,
    ) -> Result<(Vec<BuiltSource>, Option<String>), DaemonError> {
        let mut built = Vec::new();
        let mut model_toml = None;
        match config.source.kind {
            SourceKind::Simulate => {
                let (bench, gyros) = Daemon::simulated(config, explicit)?;
                model_toml = gyros[0].2.clone();
                let frame = if gyros.len() == 3 {
                    FrameKind::Triad
                } else {
                    FrameKind::Single
                };
                built.push(BuiltSource {
                    source: Source::Bench(Box::new(bench)),
                    frame,
                    labels: frame.labels(None),
                    gyros,
                });
            }
            SourceKind::Replay => {
                for (label, path) in labelled_inputs(config, &config.source.replay_path.clone()) {
                    let (source, frame, several) =
                        Daemon::replay(config, explicit, PathBuf::from(path))?;
                    let (labels, gyros) = match several {
                        // a recording of several gyros: its labels (after the input's)
                        Some(recorded) => recorded
                            .into_iter()
                            .map(|(l, rate, pulse)| {
                                let l = l.unwrap_or_default();
                                let l = label.as_ref().map_or(l.clone(), |i| format!("{i}_{l}"));
                                (l, (rate, pulse, None))
                            })
                            .unzip(),
                        None => {
                            let g = (config.gyro.sample_rate_hz, config.gyro.pulse_arcsec, None);
                            (frame.labels(label.as_deref()), vec![g; frame.gyros()])
                        }
                    };
                    built.push(BuiltSource {
                        source,
                        frame,
                        labels,
                        gyros,
                    });
                }
            }
            SourceKind::Serial => {
                for (label, path) in labelled_inputs(config, &config.source.serial_path.clone()) {
                    let source = Daemon::serial(config, explicit, PathBuf::from(path))?;
                    let frame = config.source.frame;
                    let g = (config.gyro.sample_rate_hz, config.gyro.pulse_arcsec, None);
                    built.push(BuiltSource {
                        source,
                        frame,
                        labels: frame.labels(label.as_deref()),
                        gyros: vec![g; frame.gyros()],
                    });
                }
            }
        }
        Ok((built, model_toml))
    }

    /// The acceptance test's spec, when configured.
    fn spec(config: &Config) -> Result<Option<crate::model::spec::Spec>, DaemonError> {
        if config.spec.path.is_empty() {
            return Ok(None);
        }
        let spec = crate::model::spec::Spec::load(std::path::Path::new(&config.spec.path))?;
        tracing::info!(
            path = config.spec.path,
            confidence = spec.confidence,
            "acceptance test"
        );
        Ok(Some(spec))
    }

    /// The simulated bench (one gyro, or a triad), and each gyro's rate, pulse
    /// weight and model TOML; sets `config.gyro` from the (first) model.
    fn simulated(
        config: &mut Config,
        explicit: Explicit,
    ) -> Result<(SimBench, Vec<(f64, f64, Option<String>)>), DaemonError> {
        let paths = if config.source.triad_models.is_empty() {
            vec![config.source.model.clone()]
        } else {
            config.source.triad_models.clone()
        };
        let mut models = Vec::new();
        let mut gyros = Vec::new();
        for path in &paths {
            let (model, origin) = load_model(path)?;
            let (rate, pulse) = (model.gyro.sample_rate_hz, model.gyro.pulse_arcsec);
            if explicit.sample_rate_hz && config.gyro.sample_rate_hz != rate {
                return Err(mismatch(
                    "gyro.sample_rate_hz",
                    config.gyro.sample_rate_hz,
                    "differs from the simulated model's gyro.sample_rate_hz (leave it out to use the model's)",
                ));
            }
            if explicit.pulse_arcsec && config.gyro.pulse_arcsec != pulse {
                return Err(mismatch(
                    "gyro.pulse_arcsec",
                    config.gyro.pulse_arcsec,
                    "differs from the simulated model's gyro.pulse_arcsec (leave it out to use the model's)",
                ));
            }
            tracing::info!(
                model = origin,
                seed = config.source.seed,
                "source: simulated bench"
            );
            gyros.push((rate, pulse, model.to_toml().ok()));
            models.push(model);
        }
        config.gyro.sample_rate_hz = gyros[0].0;
        config.gyro.pulse_arcsec = gyros[0].1;
        let model = models.remove(0);
        let triad = match <[GyroModel; 2]>::try_from(models) {
            Ok(yz) => Some(Box::new(yz)),
            Err(_) => None,
        };
        let bench = SimBenchConfig {
            model,
            triad,
            seed: config.source.seed,
            speed: config.source.effective_speed(),
            duration_s: (config.run.duration_s > 0.0).then_some(config.run.duration_s),
        }
        .build()?;
        Ok((bench, gyros))
    }

    /// Sample periods of `config.run.duration_s` at `sample_rate_hz`, if limited.
    fn limit(config: &Config, sample_rate_hz: f64) -> Option<u64> {
        (config.run.duration_s > 0.0)
            .then(|| (config.run.duration_s * sample_rate_hz).round().max(1.0) as u64)
    }

    /// A replay of `path`, its frame, and for an MCAP recording of several
    /// gyros each one's (recorded label, rate, pulse weight). An MCAP
    /// recording's rate and pulse weight (its first gyro's) go into
    /// `config.gyro`; an explicit value must agree with every gyro's.
    fn replay(
        config: &mut Config,
        explicit: Explicit,
        path: PathBuf,
    ) -> Result<(Source, FrameKind, Option<RecordedGyros>), DaemonError> {
        let mut frame = config.source.frame;
        let mut several = None;
        let kind = replay::probe(&path)?;
        if kind == CaptureKind::Mcap {
            if frame == FrameKind::Triad {
                return Err(DaemonError::Config(ConfigError::Invalid {
                    key: "source.frame",
                    value: "\"triad\"".into(),
                    message: "applies to raw frame captures; an MCAP recording is replayed as recorded",
                }));
            }
            let recorded = Daemon::recorded_gyros(config, explicit, &path)?;
            (config.gyro.sample_rate_hz, config.gyro.pulse_arcsec) = (recorded[0].1, recorded[0].2);
            if recorded.iter().any(|g| g.1 != recorded[0].1) {
                return Err(DaemonError::Config(ConfigError::Invalid {
                    key: "source.replay_path",
                    value: path.display().to_string(),
                    message: "its gyros have different sample rates: replay them one by one \
                     from their raw captures, or analyze each with --gyro",
                }));
            }
            if recorded[0].0.is_some() {
                several = Some(recorded);
            }
            frame = FrameKind::Single;
        } else {
            require_explicit(explicit, format!("raw frame capture {}", path.display()))?;
            frame = Daemon::capture_frame(frame, explicit.frame, kind, &path)?;
        }
        let speed = config.source.effective_speed();
        tracing::info!(path = %path.display(), speed, frame = ?frame, "source: replay");
        let source = Source::Replay(Box::new(
            ReplayConfig {
                path,
                speed,
                sample_rate_hz: config.gyro.sample_rate_hz,
                limit_periods: Daemon::limit(config, config.gyro.sample_rate_hz),
                decoder: DecoderConfig::default(),
            }
            .build()?,
        ));
        Ok((source, frame, several))
    }

    /// The frame of a raw capture: the one its content shows, which an
    /// explicit `source.frame` must name; the configured one when the content
    /// does not tell.
    fn capture_frame(
        configured: FrameKind,
        explicit: bool,
        kind: CaptureKind,
        path: &std::path::Path,
    ) -> Result<FrameKind, DaemonError> {
        let found = match kind {
            CaptureKind::Frames => FrameKind::Single,
            CaptureKind::TriadFrames => FrameKind::Triad,
            CaptureKind::Unknown | CaptureKind::Mcap => return Ok(configured),
        };
        if explicit && found != configured {
            return Err(DaemonError::Config(ConfigError::Invalid {
                key: "source.frame",
                value: format!("{configured:?}").to_lowercase(),
                message: if found == FrameKind::Triad {
                    "the capture holds triad frames (24 bytes, sync A5 5B): leave --frame out"
                } else {
                    "the capture holds single frames (16 bytes, sync A5 5A): leave --frame out"
                },
            }));
        }
        if found != configured {
            tracing::info!(path = %path.display(), frame = ?found, "the capture's frames, found by content");
        }
        Ok(found)
    }

    /// Each gyro of the MCAP recording `path`: (label, rate, pulse weight), from
    /// its metadata record (else the sample period of `/gyro/raw`); an explicit
    /// `gyro.sample_rate_hz` / `gyro.pulse_arcsec` must agree, and supplies what the
    /// recording does not say.
    fn recorded_gyros(
        config: &Config,
        explicit: Explicit,
        path: &std::path::Path,
    ) -> Result<RecordedGyros, DaemonError> {
        let given = |on: bool, v: f64| on.then_some(v);
        let mut out = Vec::new();
        for recorded in crate::input::recorded_gyros(path).map_err(ReplayError::from)? {
            let label = recorded.label.clone();
            let rate = check_flag(
                "gyro.sample_rate_hz",
                given(explicit.sample_rate_hz, config.gyro.sample_rate_hz),
                recorded.sample_rate_hz,
                path,
                recorded.origin,
                recorded.rate_rel_tol,
            )?
            .unwrap_or(config.gyro.sample_rate_hz);
            let pulse = check_flag(
                "gyro.pulse_arcsec",
                given(explicit.pulse_arcsec, config.gyro.pulse_arcsec),
                recorded.pulse_arcsec,
                path,
                recorded.origin,
                AGREE_REL,
            )?
            .unwrap_or(config.gyro.pulse_arcsec);
            out.push((label, rate, pulse));
        }
        Ok(out)
    }

    /// A serial source on `path`.
    fn serial(config: &Config, explicit: Explicit, path: PathBuf) -> Result<Source, DaemonError> {
        require_explicit(explicit, format!("serial input {}", path.display()))?;
        tracing::info!(device = %path.display(), baud = config.source.baud, frame = ?config.source.frame, "source: serial");
        Ok(Source::Serial(Box::new(
            SerialConfig {
                path,
                baud: config.source.baud,
                reconnect_initial: Duration::from_secs_f64(config.source.reconnect_initial_s),
                reconnect_max: Duration::from_secs_f64(config.source.reconnect_max_s),
                sample_rate_hz: config.gyro.sample_rate_hz,
                limit_periods: Daemon::limit(config, config.gyro.sample_rate_hz),
                decoder: DecoderConfig::default(),
            }
            .build()?,
        )))
    }

    /// One gyro's numeric stage.
    fn processor(
        config: &Config,
        sample_rate_hz: f64,
        pulse_arcsec: f64,
        live: bool,
    ) -> Result<Processor, DaemonError> {
        Ok(ProcessConfig {
            pipeline: PipelineConfig {
                sample_rate_hz,
                pulse_arcsec: Some(pulse_arcsec),
                wavelet: config.dsp.wavelet.clone(),
                levels: (config.dsp.levels > 0).then_some(config.dsp.levels),
                allan_cap: config.allan.full_overlap_max_m,
                data_quality: !config.quality.raw_statistics,
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
        .build()?)
    }

    /// Keep `status` up to date during the run (samples, estimates, and a
    /// replay's progress through its file), for a terminal's status line. With
    /// several gyros it follows the first.
    pub fn with_status(mut self, status: Arc<LiveStatus>) -> Self {
        self.status = Some(status);
        self
    }

    /// The configuration in effect (after the source's own settings were applied).
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The gyro labels, in order.
    pub fn gyro_labels(&self) -> Vec<String> {
        self.inputs
            .iter()
            .flat_map(|i| i.gyros.iter().map(|g| g.label.clone()))
            .collect()
    }

    /// Run until the source ends or `trigger` fires, then drain everything:
    /// start the metrics server and the recorder, spawn each gyro's pipeline
    /// and each source, join the sources, then drain the pipelines, the
    /// recorder and the server, in that order.
    pub async fn run(self, trigger: ShutdownTrigger) -> Result<RunReport, DaemonError> {
        let Daemon {
            config,
            mut inputs,
            metrics_addr,
            recording_meta,
            status,
        } = self;
        prepare_inputs(&config, &mut inputs, &trigger)?;
        let base = base_telemetry(&config, &inputs, status.as_ref())?;
        let (drain_guard, drained) = shutdown::drain_channel();
        let server = MetricsServer::start(metrics_addr, &base, &drain_guard).await?;
        let recorder = if config.record.dir.is_empty() {
            None
        } else {
            Some(start_recorder(&config, recording_meta, &inputs).await?)
        };
        log_ready(&config, &inputs);
        let tasks = spawn_gyros(
            &config,
            inputs,
            &base,
            recorder.as_ref(),
            &trigger,
            &drain_guard,
            status,
        );
        let source = join_sources(tasks.sources, &trigger).await;
        if trigger.is_triggered() {
            tracing::info!("shutdown requested: draining the pipeline");
        }
        // The sources dropped their senders: the pipelines drain and return.
        let gyros = join_pipelines(tasks.pipelines).await?;
        let recording = match recorder {
            Some(r) => finish_recorder(r, &base).await.map(Some),
            None => Ok(None),
        };
        let served = server.stop().await;
        drop(drain_guard);
        drained.wait().await;
        let (recording, source) = (recording?, source?);
        log_finished(&gyros);
        Ok(RunReport {
            source,
            process: gyros[0].1.clone(),
            gyros,
            recording,
            metrics_addr: served,
        })
    }
}

/// Before anything starts: the stop triggers of `--stop-when-decided` (the
/// ordinary shutdown once every gyro's coefficients are decided), and the
/// serial ports, which fail the run now when they cannot be opened.
fn prepare_inputs(
    config: &Config,
    inputs: &mut [Input],
    trigger: &ShutdownTrigger,
) -> Result<(), DaemonError> {
    if config.spec.stop_when_decided {
        let n_gyros = inputs.iter().map(|i| i.gyros.len()).sum();
        let stops = all_decided(trigger, n_gyros);
        for (g, stop) in inputs
            .iter_mut()
            .flat_map(|i| i.gyros.iter_mut())
            .zip(stops)
        {
            g.processor.attach_spec_stop(stop);
        }
    }
    for input in inputs {
        if let Source::Serial(s) = &mut input.source {
            s.open()?;
        }
    }
    Ok(())
}

/// The metrics every gyro shares, and a replay's progress for the status line.
fn base_telemetry(
    config: &Config,
    inputs: &[Input],
    status: Option<&Arc<LiveStatus>>,
) -> Result<Telemetry, DaemonError> {
    let first_label = &inputs[0].gyros[0].label;
    let base = Telemetry::new(Arc::new(Metrics::new()?), &config.gyro.info(first_label))?;
    if let (Some(st), Source::Replay(_)) = (status, &inputs[0].source)
        && let Ok(m) = std::fs::metadata(
            labelled_inputs(config, &config.source.replay_path)[0]
                .1
                .as_str(),
        )
    {
        st.set_replay(m.len(), Arc::clone(&base.metrics));
    }
    Ok(base)
}

/// The `/metrics` server task; it stops last, after the final estimates are in.
struct MetricsServer {
    trigger: ShutdownTrigger,
    task: Option<tokio::task::JoinHandle<()>>,
    bound: Option<SocketAddr>,
}

impl MetricsServer {
    async fn start(
        addr: Option<SocketAddr>,
        base: &Telemetry,
        drain_guard: &shutdown::DrainGuard,
    ) -> Result<MetricsServer, DaemonError> {
        let (trigger, shutdown) = shutdown::channel();
        let Some(addr) = addr else {
            return Ok(MetricsServer {
                trigger,
                task: None,
                bound: None,
            });
        };
        let (bound, server) = http::bind(addr, Arc::clone(&base.metrics), shutdown.watch()).await?;
        tracing::info!("metrics on http://{bound}/metrics");
        let guard = drain_guard.clone();
        let task = tokio::spawn(async move {
            server.await;
            drop(guard);
        });
        Ok(MetricsServer {
            trigger,
            task: Some(task),
            bound: Some(bound),
        })
    }

    /// Stop serving; where it served.
    async fn stop(self) -> Option<SocketAddr> {
        self.trigger.trigger();
        if let Some(t) = self.task {
            let _ = t.await;
        }
        self.bound
    }
}

fn log_ready(config: &Config, inputs: &[Input]) {
    tracing::info!(
        sample_rate_hz = config.gyro.sample_rate_hz,
        pulse_arcsec = config.gyro.pulse_arcsec,
        wavelet = config.dsp.wavelet,
        gyros = inputs.iter().map(|i| i.gyros.len()).sum::<usize>(),
        latency_samples = inputs[0].gyros[0].processor.pipeline().latency(),
        estimator_interval_s = config.estimator.interval_s,
        "pipeline ready"
    );
}

type PipelineTask = tokio::task::JoinHandle<(String, ProcessReport)>;

/// The running tasks: one pipeline thread per gyro, one task per source.
struct Tasks {
    pipelines: Vec<PipelineTask>,
    sources: Vec<SourceTask>,
}

/// Spawn every gyro's pipeline thread, then each source feeding its gyros.
fn spawn_gyros(
    config: &Config,
    inputs: Vec<Input>,
    base: &Telemetry,
    recorder: Option<&Recorder>,
    trigger: &ShutdownTrigger,
    drain_guard: &shutdown::DrainGuard,
    mut status: Option<Arc<LiveStatus>>,
) -> Tasks {
    let n_gyros: usize = inputs.iter().map(|i| i.gyros.len()).sum();
    let bound = if config.source.kind == SourceKind::Serial {
        // the budget is shared by the gyros' queues
        QueueBound::Bytes(config.source.queue_budget_bytes() / n_gyros as u64)
    } else {
        QueueBound::Batches(config.run.channel_capacity)
    };
    let mut tasks = Tasks {
        pipelines: Vec::new(),
        sources: Vec::new(),
    };
    for input in inputs {
        let mut outs = Vec::new();
        for g in input.gyros {
            let telemetry = base.for_gyro(&config.gyro.info(&g.label));
            let (sender, rx) = batch::channel(bound, &telemetry);
            let outputs = Outputs {
                recorder: recorder.map(|r| r.sender().for_gyro(&g.label)),
                telemetry: telemetry.clone(),
                stop: Some(trigger.subscribe()),
                status: status.take(),
            };
            let guard = drain_guard.clone();
            let (processor, label) = (g.processor, g.label);
            tasks.pipelines.push(tokio::task::spawn_blocking(move || {
                let report = processor.run(rx, outputs);
                drop(guard);
                (label, report)
            }));
            outs.push((telemetry, sender));
        }
        tasks.sources.push(spawn_source(
            input.source,
            input.frame,
            outs,
            trigger.subscribe(),
        ));
    }
    tasks
}

/// Wait for every source; the first failure stops the others (the pipelines
/// still drain) and is the result.
async fn join_sources(
    sources: Vec<SourceTask>,
    trigger: &ShutdownTrigger,
) -> Result<SourceReport, DaemonError> {
    let mut result: Result<SourceReport, DaemonError> = Ok(SourceReport::default());
    for task in sources {
        let r = task
            .await
            .map_err(|e| join_err("source", e))
            .and_then(|r| r);
        match (r, &mut result) {
            (Ok(r), Ok(total)) => {
                total.bytes_read += r.bytes_read;
                total.samples += r.samples;
                total.periods += r.periods;
                total.disconnects += r.disconnects;
            }
            (Err(e), Ok(_)) => {
                tracing::error!(error = %crate::chain::chain(&e), "source failed; draining the pipeline");
                trigger.trigger();
                result = Err(e);
            }
            (Err(e), Err(_)) => tracing::error!(error = %crate::chain::chain(&e), "source failed"),
            (Ok(_), Err(_)) => {}
        }
    }
    result
}

async fn join_pipelines(
    pipelines: Vec<PipelineTask>,
) -> Result<Vec<(String, ProcessReport)>, DaemonError> {
    let mut gyros = Vec::new();
    for t in pipelines {
        gyros.push(t.await.map_err(|e| join_err("pipeline", e))?);
    }
    Ok(gyros)
}

fn log_finished(gyros: &[(String, ProcessReport)]) {
    for (label, p) in gyros {
        tracing::info!(
            gyro = label,
            samples = p.samples,
            periods = p.periods,
            lost = p.lost,
            updates = p.updates,
            max_estimate_latency_s = p.max_estimate_latency_s,
            recorder_dropped = p.recorder_dropped,
            "run finished"
        );
    }
}

/// One stop trigger per gyro; `main` fires once all of them have.
fn all_decided(main: &ShutdownTrigger, n: usize) -> Vec<ShutdownTrigger> {
    let subs: Vec<(ShutdownTrigger, shutdown::Shutdown)> =
        (0..n).map(|_| shutdown::channel()).collect();
    let main = main.clone();
    let (triggers, mut waits): (Vec<_>, Vec<_>) = subs.into_iter().unzip();
    tokio::spawn(async move {
        for w in &mut waits {
            w.requested().await;
        }
        main.trigger();
    });
    triggers
}

/// The recording: one gyro on today's channels, several on `/gyro/<label>/...`.
async fn start_recorder(
    config: &Config,
    meta: RecordingMeta,
    inputs: &[Input],
) -> Result<Recorder, DaemonError> {
    let rc = RecorderConfig {
        record_dir: PathBuf::from(&config.record.dir),
        flush_interval_s: config.record.flush_interval_s,
        zstd_level: ZSTD_LEVEL,
        chunk_size: CHUNK_SIZE,
        ..RecorderConfig::default()
    };
    let gyros: Vec<(String, RecordingMeta)> = inputs
        .iter()
        .flat_map(|i| i.gyros.iter())
        .map(|g| {
            let mut m = g.meta.clone();
            m.config = meta.config.clone();
            (g.label.clone(), m)
        })
        .collect();
    // every gyro's pipeline sends into the one queue: each gets a single
    // gyro's room, so a live source's burst drops no more often with three
    let rc = RecorderConfig {
        queue_capacity: rc.queue_capacity * gyros.len().max(1),
        ..rc
    };
    let r = tokio::task::spawn_blocking(move || {
        Recorder::start_gyros(&rc, std::time::SystemTime::now(), Some(&meta), &gyros)
    })
    .await
    .map_err(|e| join_err("recorder start", e))??;
    tracing::info!(path = %r.path().display(), "recording");
    Ok(r)
}

/// Finish the recording (its error is the run's).
async fn finish_recorder(
    r: Recorder,
    telemetry: &Telemetry,
) -> Result<RecordingSummary, DaemonError> {
    let summary = tokio::task::spawn_blocking(move || r.finish())
        .await
        .map_err(|e| join_err("recorder", e))?;
    match summary {
        Ok(s) => {
            telemetry.metrics.set_recording_bytes(s.bytes);
            tracing::info!(path = %s.path.display(), bytes = s.bytes, messages = s.messages(), "recording finished");
            Ok(s)
        }
        Err(e) => {
            tracing::error!(error = %crate::chain::chain(&e), "recording failed");
            Err(e.into())
        }
    }
}

type SourceTask = tokio::task::JoinHandle<Result<SourceReport, DaemonError>>;

/// Start a source's task: serial on the runtime, replay and bench on blocking threads.
fn spawn_source(
    source: Source,
    frame: FrameKind,
    outs: Vec<(Telemetry, BatchSender)>,
    sd: shutdown::Shutdown,
) -> SourceTask {
    match (source, frame) {
        (Source::Serial(s), FrameKind::Single) => {
            tokio::spawn(async move { s.run::<Single>(outs, sd).await.map_err(DaemonError::from) })
        }
        (Source::Serial(s), FrameKind::Triad) => {
            tokio::spawn(async move { s.run::<Triad>(outs, sd).await.map_err(DaemonError::from) })
        }
        (Source::Replay(r), FrameKind::Single) => tokio::task::spawn_blocking(move || {
            r.run_blocking::<Single>(outs, sd)
                .map_err(DaemonError::from)
        }),
        (Source::Replay(r), FrameKind::Triad) => tokio::task::spawn_blocking(move || {
            r.run_blocking::<Triad>(outs, sd).map_err(DaemonError::from)
        }),
        (Source::Bench(b), _) => {
            tokio::task::spawn_blocking(move || b.run_blocking(outs, sd).map_err(DaemonError::from))
        }
    }
}

fn join_err(task: &'static str, e: tokio::task::JoinError) -> DaemonError {
    DaemonError::Task {
        task,
        message: e.to_string(),
    }
}
