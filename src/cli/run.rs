//! `sagnac run`: the acquisition daemon.
//!
//! ```text
//! sagnac run [--config FILE] [--serial [LABEL=]PATH ... --baud N [--queue-budget-mib M] | --replay [LABEL=]FILE ... [--speed X]
//!            | --simulate MODEL.toml | --simulate-triad X.toml,Y.toml,Z.toml] [--frame single|triad]
//!            [--sample-rate-hz F] [--pulse-arcsec D] [--metrics-addr ADDR] [--record-dir DIR]
//!            [--wavelet sym8] [--duration-s S] [--spec SPEC.toml [--stop-when-decided]]
//!            [--raw-statistics]
//! ```
//!
//! Thin: read the config file (or the built-in defaults), apply the flags,
//! validate (a bad value exits 2 naming the key and the flag), set up logging
//! (`log.format`, `log.level`; `RUST_LOG` overrides the level), start a tokio
//! runtime, install the SIGINT/SIGTERM handlers and run [`Daemon`]. The first
//! signal drains the pipeline and finishes the recording (exit 0); another one
//! at least a second later exits at once (exit 130).
//!
//! At a terminal (stderr a tty, `log.format = "human"`) one status line is
//! redrawn in place below the log lines: elapsed time, samples, lost samples, QN
//! and ARW with their 95 % intervals, the fit verdict, and a replay's progress
//! ([`super::progress::StatusLine`]); the intermediate estimate log lines are
//! then left to `debug`. Otherwise (a file, a pipe, a service) the log lines
//! are all there is, with no carriage return or escape code.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{ArgGroup, Args};

use super::progress::StatusLine;
use crate::daemon::config::{
    Config, ConfigError, FrameKind, KeysPresent, LabelledInput, LogFormat, SourceKind,
};
use crate::daemon::run::{Daemon, DaemonError, Explicit};
use crate::daemon::shutdown;

/// Arguments of `sagnac run`.
#[derive(Debug, Args)]
#[command(group(ArgGroup::new("source").args(["serial", "replay", "simulate", "simulate_triad"])))]
pub struct RunArgs {
    /// Configuration file (TOML, every key documented in config/default.toml); flags override it.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Read the gyro's frames from this serial device (e.g. /dev/ttyUSB0). Repeat it
    /// as LABEL=PATH for several devices in one daemon (each gyro's series and
    /// channels carry its label; a triad's gyros are LABEL_x, LABEL_y, LABEL_z).
    #[arg(long, value_name = "[LABEL=]PATH")]
    pub serial: Vec<String>,
    /// Baud rate of the serial device (default 921600).
    #[arg(long, value_name = "N", requires = "serial")]
    pub baud: Option<u32>,
    /// Replay a capture: raw frames (.bin) or an MCAP recording made by `sagnac run`.
    /// Repeat it as LABEL=FILE for several captures in one daemon.
    #[arg(long, value_name = "[LABEL=]FILE")]
    pub replay: Vec<String>,
    /// The frame of serial input and raw captures: single (16 bytes, one gyro) or
    /// triad (24 bytes, gyros x, y, z). Default single.
    #[arg(long, value_name = "single|triad")]
    pub frame: Option<String>,
    /// Pace of a replay or of the simulated bench, in multiples of real time (0 = as fast
    /// as possible; default: 1 for the simulated bench, 0 for a replay).
    #[arg(
        long,
        value_name = "X",
        conflicts_with = "serial",
        allow_negative_numbers = true
    )]
    pub speed: Option<f64>,
    /// Run the simulated bench on this gyro model (no source flag at all: the built-in
    /// model of the founding paper's gyro).
    #[arg(long, value_name = "MODEL.toml")]
    pub simulate: Option<PathBuf>,
    /// Run the simulated bench as a triad: three gyro models (x, y, z, one sample
    /// rate) sent through the real triad frame encoder and decoder.
    #[arg(long, value_name = "X.toml,Y.toml,Z.toml", value_delimiter = ',')]
    pub simulate_triad: Vec<PathBuf>,
    /// Memory budget of the serial source's pipeline queue, MiB (default 16).
    #[arg(long, value_name = "MIB", allow_negative_numbers = true)]
    pub queue_budget_mib: Option<f64>,
    /// Gyro sample (frame) rate, Hz (`--rate-hz` is an alias).
    #[arg(
        long,
        value_name = "F",
        alias = "rate-hz",
        allow_negative_numbers = true
    )]
    pub sample_rate_hz: Option<f64>,
    /// Angle of one counter pulse, arcsec.
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    pub pulse_arcsec: Option<f64>,
    /// Prometheus endpoint address (path /metrics; default 127.0.0.1:9898; "" disables it).
    #[arg(long, value_name = "ADDR")]
    pub metrics_addr: Option<String>,
    /// Directory for the MCAP recording, one file per run ("" disables recording).
    #[arg(long, value_name = "DIR")]
    pub record_dir: Option<String>,
    /// Wavelet of the QN-removal bank (sym8, haar, db4, sym4, db8).
    #[arg(long, value_name = "NAME")]
    pub wavelet: Option<String>,
    /// Stop after this many seconds of samples (0 = until SIGINT/SIGTERM or the end of a replay).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub duration_s: Option<f64>,
    /// Acceptance test against this spec file: verdicts at each estimator update
    /// (metrics, MCAP /gyro/verdict, a log line per change).
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Option<PathBuf>,
    /// End the run once every coefficient of the spec is decided (drain, final
    /// estimates, finished recording, exit 0).
    #[arg(long)]
    pub stop_when_decided: bool,
    /// Turn the data-quality stage off: no glitch exclusion, no warm-up, step or
    /// thermal assessment, no restart after a warm-up (the raw statistics, for
    /// comparison; `quality.raw_statistics`).
    #[arg(long)]
    pub raw_statistics: bool,
}

/// The config key a flag overrides (for error messages).
fn flag_of(args: &RunArgs, key: &str) -> Option<(&'static str, bool)> {
    Some(match key {
        "source.serial_path" => ("--serial", !args.serial.is_empty()),
        "source.baud" => ("--baud", args.baud.is_some()),
        "source.replay_path" => ("--replay", !args.replay.is_empty()),
        "source.inputs" => (
            if args.serial.is_empty() {
                "--replay"
            } else {
                "--serial"
            },
            !args.serial.is_empty() || !args.replay.is_empty(),
        ),
        "source.frame" => ("--frame", args.frame.is_some()),
        "source.triad_models" => ("--simulate-triad", !args.simulate_triad.is_empty()),
        "source.speed" => ("--speed", args.speed.is_some()),
        "source.model" => ("--simulate", args.simulate.is_some()),
        "source.queue_budget_mib" => ("--queue-budget-mib", args.queue_budget_mib.is_some()),
        "gyro.sample_rate_hz" => ("--sample-rate-hz", args.sample_rate_hz.is_some()),
        "gyro.pulse_arcsec" => ("--pulse-arcsec", args.pulse_arcsec.is_some()),
        "metrics.addr" => ("--metrics-addr", args.metrics_addr.is_some()),
        "record.dir" => ("--record-dir", args.record_dir.is_some()),
        "dsp.wavelet" => ("--wavelet", args.wavelet.is_some()),
        "run.duration_s" => ("--duration-s", args.duration_s.is_some()),
        "spec.path" => ("--spec", args.spec.is_some()),
        "spec.stop_when_decided" => ("--stop-when-decided", args.stop_when_decided),
        "quality.raw_statistics" => ("--raw-statistics", args.raw_statistics),
        _ => return None,
    })
}

/// `--serial` / `--replay` values: one unlabelled PATH is today's single input
/// (`source.serial_path` / `source.replay_path`); otherwise every value must be
/// LABEL=PATH (`source.inputs`).
fn set_inputs(cfg: &mut Config, values: &[String], serial: bool) -> Result<(), ConfigError> {
    let single = if serial {
        &mut cfg.source.serial_path
    } else {
        &mut cfg.source.replay_path
    };
    if let [one] = values
        && LabelledInput::parse(one).is_err()
    {
        *single = one.clone();
        cfg.source.inputs.clear();
        return Ok(());
    }
    for v in values {
        if let Err(message) = LabelledInput::parse(v) {
            return Err(ConfigError::Invalid {
                key: "source.inputs",
                value: v.clone(),
                message,
            });
        }
    }
    single.clear();
    cfg.source.inputs = values.to_vec();
    Ok(())
}

/// The configuration: the file (or the defaults) with the flags applied, and
/// which gyro settings were given explicitly.
pub fn resolve(args: &RunArgs) -> Result<(Config, Explicit), ConfigError> {
    let (mut cfg, keys) = match &args.config {
        Some(p) => {
            let loaded = Config::load_with_keys(p)?;
            if let Ok(text) = std::fs::read_to_string(p) {
                for (old, new) in crate::keys::renamed_in(&text, crate::keys::DAEMON_RENAMES) {
                    eprintln!(
                        "warning: {}",
                        crate::keys::rename_warning(&p.display().to_string(), old, new)
                    );
                }
            }
            loaded
        }
        None => (Config::default(), KeysPresent::default()),
    };
    // Given = the flag, or the key present in the file (whatever its value).
    let explicit = Explicit {
        sample_rate_hz: args.sample_rate_hz.is_some() || keys.contains("gyro.sample_rate_hz"),
        pulse_arcsec: args.pulse_arcsec.is_some() || keys.contains("gyro.pulse_arcsec"),
        frame: args.frame.is_some() || keys.contains("source.frame"),
    };
    if !args.serial.is_empty() {
        cfg.source.kind = SourceKind::Serial;
        set_inputs(&mut cfg, &args.serial, true)?;
    }
    if let Some(b) = args.baud {
        cfg.source.baud = b;
    }
    if !args.replay.is_empty() {
        cfg.source.kind = SourceKind::Replay;
        set_inputs(&mut cfg, &args.replay, false)?;
    }
    if let Some(p) = &args.simulate {
        cfg.source.kind = SourceKind::Simulate;
        cfg.source.model = p.display().to_string();
    }
    if !args.simulate_triad.is_empty() {
        cfg.source.kind = SourceKind::Simulate;
        cfg.source.model.clear();
        cfg.source.triad_models = args
            .simulate_triad
            .iter()
            .map(|p| p.display().to_string())
            .collect();
    }
    if let Some(f) = &args.frame {
        cfg.source.frame = match f.as_str() {
            "single" => FrameKind::Single,
            "triad" => FrameKind::Triad,
            _ => {
                return Err(ConfigError::Invalid {
                    key: "source.frame",
                    value: f.clone(),
                    message: "must be single or triad",
                });
            }
        };
    }
    if let Some(s) = args.speed {
        cfg.source.speed = Some(s);
    }
    if let Some(v) = args.queue_budget_mib {
        cfg.source.queue_budget_mib = v;
    }
    if let Some(v) = args.sample_rate_hz {
        cfg.gyro.sample_rate_hz = v;
    }
    if let Some(v) = args.pulse_arcsec {
        cfg.gyro.pulse_arcsec = v;
    }
    if let Some(a) = &args.metrics_addr {
        cfg.metrics.addr = a.clone();
    }
    if let Some(d) = &args.record_dir {
        cfg.record.dir = d.clone();
    }
    if let Some(w) = &args.wavelet {
        cfg.dsp.wavelet = w.clone();
    }
    if let Some(d) = args.duration_s {
        cfg.run.duration_s = d;
    }
    if let Some(p) = &args.spec {
        cfg.spec.path = p.display().to_string();
    }
    if args.stop_when_decided {
        cfg.spec.stop_when_decided = true;
    }
    if args.raw_statistics {
        cfg.quality.raw_statistics = true;
    }
    cfg.validate()?;
    Ok((cfg, explicit))
}

fn init_logging(cfg: &Config, line: Option<&StatusLine>) -> Result<()> {
    let filter = match std::env::var("RUST_LOG") {
        Ok(v) if !v.trim().is_empty() => tracing_subscriber::EnvFilter::try_new(&v)
            .with_context(|| format!("RUST_LOG = {v:?} is not a valid tracing filter"))?,
        _ => tracing_subscriber::EnvFilter::try_new(&cfg.log.level).map_err(|e| {
            anyhow::Error::new(ConfigError::Invalid {
                key: "log.level",
                value: cfg.log.level.clone(),
                message: "must be a tracing filter such as info or sagnac=debug",
            })
            .context(format!("invalid log filter: {e}"))
        })?,
    };
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(super::progress::stderr_is_terminal());
    // A subscriber may already be set (tests calling run twice): keep it.
    let _ = match (cfg.log.format, line) {
        (LogFormat::Human, Some(l)) => builder.with_writer(l.log_writer()).try_init(),
        (LogFormat::Human, None) => builder.with_writer(std::io::stderr).try_init(),
        (LogFormat::Json, _) => builder.with_writer(std::io::stderr).json().try_init(),
    };
    Ok(())
}

/// Say where a bad configuration value came from: the flag that set it, or
/// else the config file (the error itself names the key).
fn with_flag(args: &RunArgs, e: DaemonError) -> anyhow::Error {
    let key = match &e {
        DaemonError::Config(ConfigError::Invalid { key, .. }) => Some(*key),
        DaemonError::Contradiction(c) => Some(c.flag),
        _ => None,
    };
    let origin = key.and_then(|key| match (flag_of(args, key), &args.config) {
        (Some((flag, true)), _) => Some(format!("bad value for {flag}")),
        (_, Some(file)) => Some(format!("bad value in {}", file.display())),
        _ => None,
    });
    match origin {
        Some(o) => anyhow::Error::new(e).context(o),
        None => anyhow::Error::new(e),
    }
}

/// Run `sagnac run`.
pub fn run(args: RunArgs) -> Result<()> {
    // The signal handlers come first: a SIGTERM while the daemon is being built
    // (tens of milliseconds) is a shutdown request like any other, not a kill.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("sagnac-rt")
        .build()
        .context("starting the tokio runtime")?;
    let (trigger, _) = shutdown::channel();
    runtime.block_on(async { install_signal_handlers(trigger.clone()) })?;
    let (cfg, explicit) = resolve(&args).map_err(|e| with_flag(&args, DaemonError::Config(e)))?;
    let mut line = match cfg.log.format {
        LogFormat::Human => StatusLine::on_terminal(),
        LogFormat::Json => None,
    };
    init_logging(&cfg, line.as_ref())?;
    let mut daemon = Daemon::build(cfg, explicit).map_err(|e| with_flag(&args, e))?;
    if let Some(l) = &mut line {
        daemon = daemon.with_status(l.status());
        l.start();
    }
    let result =
        runtime.block_on(async move { daemon.run(trigger).await.map_err(anyhow::Error::new) });
    if let Some(l) = line {
        l.finish();
    }
    let report = result?;
    // Do not wait for blocking threads still parked in the pool.
    runtime.shutdown_timeout(std::time::Duration::from_millis(100));
    if let Some(rec) = &report.recording {
        tracing::info!(path = %rec.path.display(), "done");
    }
    Ok(())
}

/// Signals within this time of the first count as the same request.
const REPEAT_WINDOW: std::time::Duration = std::time::Duration::from_secs(1);

/// First SIGINT/SIGTERM: graceful shutdown; another one at least a second
/// later: exit 130 at once.
fn install_signal_handlers(trigger: shutdown::ShutdownTrigger) -> Result<()> {
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate()).context("installing the SIGTERM handler")?;
    let mut int = signal(SignalKind::interrupt()).context("installing the SIGINT handler")?;
    tokio::spawn(async move {
        let mut first: Option<std::time::Instant> = None;
        loop {
            let name = tokio::select! {
                _ = term.recv() => "SIGTERM",
                _ = int.recv() => "SIGINT",
            };
            match first {
                None => {
                    tracing::info!(
                        signal = name,
                        "stopping: draining the pipeline and finishing the recording (send again to exit at once)"
                    );
                    trigger.trigger();
                    first = Some(std::time::Instant::now());
                }
                // A copy of the same signal (e.g. sent to the process and to its
                // group by a supervisor) is not a second request.
                Some(t) if t.elapsed() < REPEAT_WINDOW => {}
                Some(_) => {
                    eprintln!("sagnac run: second {name}: exiting without draining");
                    std::process::exit(130);
                }
            }
        }
    });
    Ok(())
}
