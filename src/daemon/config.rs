//! The daemon's configuration: `config/default.toml` documents every key.
//!
//! One serde struct per stage, `deny_unknown_fields` on every one of them, and
//! `validate()` with messages that name the key and the offending value.
//! Command-line flags of `sagnac run` override the file.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Errors reading or validating a configuration.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config file {path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("config key `{key}`: {message} (got {value})")]
    Invalid {
        key: &'static str,
        value: String,
        message: &'static str,
    },
}

/// Where samples come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SourceKind {
    Serial,
    Replay,
    #[default]
    Simulate,
}

/// The frame a serial port or a raw capture carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FrameKind {
    /// The 16-byte single-gyro frame.
    #[default]
    Single,
    /// The 24-byte triad frame: gyros x, y, z.
    Triad,
}

impl FrameKind {
    /// Gyros per frame.
    pub fn gyros(self) -> usize {
        match self {
            FrameKind::Single => 1,
            FrameKind::Triad => 3,
        }
    }

    /// The gyro labels of a stream of these frames whose input is labelled
    /// `input` (`None`: unlabelled). A single frame is its input's label, or
    /// `gyro`; a triad's gyros are `x`, `y`, `z`, or `LABEL_x`, `LABEL_y`,
    /// `LABEL_z`.
    pub fn labels(self, input: Option<&str>) -> Vec<String> {
        match (self, input) {
            (FrameKind::Single, Some(l)) => vec![l.to_string()],
            (FrameKind::Single, None) => vec![crate::sink::metrics::DEFAULT_GYRO.to_string()],
            (FrameKind::Triad, Some(l)) => AXES.iter().map(|a| format!("{l}_{a}")).collect(),
            (FrameKind::Triad, None) => AXES.iter().map(|a| a.to_string()).collect(),
        }
    }
}

use crate::input::frame::triad::AXES;

/// One of several labelled inputs: `LABEL=PATH` (a serial device or a capture).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LabelledInput {
    /// The input's label (its gyro's, or the prefix of its triad's).
    pub label: String,
    /// Device or file path.
    pub path: String,
}

impl LabelledInput {
    /// Parse `LABEL=PATH`; the error says what is wrong.
    pub fn parse(text: &str) -> Result<LabelledInput, &'static str> {
        let (label, path) = text.split_once('=').ok_or("must be LABEL=PATH")?;
        if !crate::recording::messages::valid_gyro_label(label) {
            return Err("LABEL must be 1-32 ASCII letters, digits, _ or -");
        }
        if path.is_empty() {
            return Err("PATH is empty");
        }
        Ok(LabelledInput {
            label: label.to_string(),
            path: path.to_string(),
        })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SourceConfig {
    /// `serial`, `replay` or `simulate` (the built-in simulated bench).
    pub kind: SourceKind,
    /// The frame of serial input and raw captures: `single` or `triad`.
    pub frame: FrameKind,
    /// Several labelled inputs of `kind` (serial devices or captures), each
    /// `LABEL=PATH`, instead of `serial_path` / `replay_path`.
    pub inputs: Vec<String>,
    /// Three gyro model TOMLs (x, y, z) of a simulated triad (kind = simulate),
    /// instead of `model`.
    pub triad_models: Vec<String>,
    /// Serial device path (kind = serial).
    pub serial_path: String,
    /// Serial baud rate.
    pub baud: u32,
    /// First reconnect delay after the device disappears, seconds.
    pub reconnect_initial_s: f64,
    /// Longest reconnect delay (exponential backoff), seconds.
    pub reconnect_max_s: f64,
    /// Capture to replay: a raw frame capture (`.bin`) or an MCAP recording (kind = replay).
    pub replay_path: String,
    /// Pace in multiples of real time; 0 = as fast as possible. Absent = the
    /// source's default ([`SourceConfig::effective_speed`]): real time (1) for the
    /// simulated bench, as fast as possible (0) for a replay.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub speed: Option<f64>,
    /// Gyro model TOML for the simulated bench; empty = the built-in paper gyro.
    pub model: String,
    /// Seed of the simulated bench.
    pub seed: u64,
    /// Memory budget of the queue between a live (serial) source and the
    /// pipeline, MiB of queued sample data: a burst within it loses nothing.
    pub queue_budget_mib: f64,
}

impl Default for SourceConfig {
    fn default() -> Self {
        SourceConfig {
            kind: SourceKind::Simulate,
            frame: FrameKind::Single,
            inputs: Vec::new(),
            triad_models: Vec::new(),
            serial_path: String::new(),
            baud: 921_600,
            reconnect_initial_s: 0.5,
            reconnect_max_s: 10.0,
            replay_path: String::new(),
            speed: None,
            model: String::new(),
            seed: 1,
            queue_budget_mib: 16.0,
        }
    }
}

/// Smallest and largest `source.queue_budget_mib`: 64 KiB, 4 GiB.
pub const QUEUE_BUDGET_MIB: [f64; 2] = [1.0 / 16.0, 4096.0];

impl SourceConfig {
    /// `queue_budget_mib` in bytes (validated: 64 KiB to 4 GiB).
    pub fn queue_budget_bytes(&self) -> u64 {
        (self.queue_budget_mib * crate::daemon::queue::MIB).round() as u64
    }

    /// The pace actually used, in multiples of real time (0 = as fast as possible):
    /// `speed` when set, otherwise 1 for the simulated bench (so a dashboard shows
    /// it converging) and 0 for a replay. Serial input is never paced.
    pub fn effective_speed(&self) -> f64 {
        match (self.speed, self.kind) {
            (Some(s), _) => s,
            (None, SourceKind::Simulate) => 1.0,
            (None, _) => 0.0,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroConfig {
    /// Sample (frame) rate, Hz.
    #[serde(alias = "rate_hz")]
    pub sample_rate_hz: f64,
    /// Angle per counter pulse, arcsec.
    pub pulse_arcsec: f64,
    /// Serial number of the unit on this bench (the `serial_number` label of
    /// `sagnac_gyro_info`); empty = not given.
    pub serial_number: String,
    /// Model name of the unit (the `model` label of `sagnac_gyro_info`); empty = not given.
    pub model_name: String,
}

impl Default for GyroConfig {
    fn default() -> Self {
        GyroConfig {
            sample_rate_hz: 1000.0,
            pulse_arcsec: 1.21,
            serial_number: String::new(),
            model_name: String::new(),
        }
    }
}

/// Longest `gyro.serial_number` and `gyro.model_name`, characters.
pub const GYRO_NAME_MAX_CHARS: usize = 128;

impl GyroConfig {
    /// The metrics' description of this gyro under the label `label`.
    pub fn info(&self, label: &str) -> crate::sink::metrics::GyroInfo {
        crate::sink::metrics::GyroInfo {
            label: label.to_string(),
            serial_number: self.serial_number.clone(),
            model: self.model_name.clone(),
        }
    }
}

/// A label value given in the config: printable, at most [`GYRO_NAME_MAX_CHARS`].
fn label_value(key: &'static str, v: &str) -> Result<(), ConfigError> {
    if v.chars().count() > GYRO_NAME_MAX_CHARS {
        return Err(invalid(
            key,
            format!("{} characters", v.chars().count()),
            "must be at most 128 characters",
        ));
    }
    if v.chars().any(char::is_control) {
        return Err(invalid(
            key,
            format!("{v:?}"),
            "must not contain control characters (newline, tab, ...)",
        ));
    }
    Ok(())
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DspConfig {
    /// Wavelet of the QN-removal bank (sym8, haar, db4, sym4, db8).
    pub wavelet: String,
    /// Decomposition depth; 0 = automatic (deepest detail band below ~0.5 Hz).
    pub levels: u32,
}

impl Default for DspConfig {
    fn default() -> Self {
        DspConfig {
            wavelet: "sym8".into(),
            levels: 0,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AllanConfig {
    /// Largest averaging factor computed with full overlap (a power of two).
    pub full_overlap_max_m: u64,
}

impl Default for AllanConfig {
    fn default() -> Self {
        AllanConfig {
            full_overlap_max_m: 1 << 16,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorConfig {
    /// Seconds of data between estimator updates.
    pub interval_s: f64,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        EstimatorConfig { interval_s: 5.0 }
    }
}

/// The data-quality stage ([`crate::quality`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QualityConfig {
    /// Turn the stage off: no glitch exclusion, no warm-up, step or thermal
    /// handling (the raw statistics, for comparison).
    pub raw_statistics: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsConfig {
    /// Address of the Prometheus endpoint (`/metrics`); loopback by default.
    /// Empty disables it.
    pub addr: String,
}

impl Default for MetricsConfig {
    fn default() -> Self {
        MetricsConfig {
            addr: "127.0.0.1:9898".into(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RecordConfig {
    /// Directory for MCAP recordings (one file per run); empty = do not record.
    pub dir: String,
    /// Longest time between chunk flushes, seconds: what a crash can lose.
    pub flush_interval_s: f64,
    /// Samples per `/gyro/raw` message.
    pub batch_samples: usize,
}

impl Default for RecordConfig {
    fn default() -> Self {
        RecordConfig {
            dir: "recordings".into(),
            flush_interval_s: 2.0,
            batch_samples: 1000,
        }
    }
}

/// Log output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    #[default]
    Human,
    Json,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LogConfig {
    pub format: LogFormat,
    /// tracing filter directive, e.g. `info` or `sagnac=debug`.
    pub level: String,
}

impl Default for LogConfig {
    fn default() -> Self {
        LogConfig {
            format: LogFormat::Human,
            level: "info".into(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Stop after this many seconds of samples; 0 = run until SIGINT/SIGTERM
    /// (or the end of a replay).
    pub duration_s: f64,
    /// Capacity, in batches, of the queue between a replay or the simulated
    /// bench and the pipeline (a live source's queue is sized by
    /// `source.queue_budget_mib`).
    pub channel_capacity: usize,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig {
            duration_s: 0.0,
            channel_capacity: 64,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct SpecRunConfig {
    /// Spec file of the acceptance test ([`crate::model::spec`]); empty = none.
    pub path: String,
    /// End the run once every coefficient of the spec is decided.
    pub stop_when_decided: bool,
}

/// The whole configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub source: SourceConfig,
    pub gyro: GyroConfig,
    pub dsp: DspConfig,
    pub allan: AllanConfig,
    pub estimator: EstimatorConfig,
    pub quality: QualityConfig,
    pub metrics: MetricsConfig,
    pub record: RecordConfig,
    pub log: LogConfig,
    pub run: RunConfig,
    pub spec: SpecRunConfig,
}

/// Which keys a config file sets, by presence (a key set to its default value
/// counts as set).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct KeysPresent {
    keys: std::collections::BTreeSet<String>,
}

impl KeysPresent {
    /// The dotted keys (`gyro.sample_rate_hz`) of TOML text that parsed as a [`Config`].
    /// Renamed keys count under their new names ([`crate::keys::DAEMON_RENAMES`]).
    pub fn of_toml(text: &str) -> KeysPresent {
        KeysPresent {
            keys: crate::keys::dotted_keys(text, crate::keys::DAEMON_RENAMES),
        }
    }

    /// Whether the file sets `key` (dotted: `gyro.sample_rate_hz`).
    pub fn contains(&self, key: &str) -> bool {
        self.keys.contains(key)
    }
}

fn invalid(key: &'static str, value: impl ToString, message: &'static str) -> ConfigError {
    ConfigError::Invalid {
        key,
        value: value.to_string(),
        message,
    }
}

fn positive(key: &'static str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(key, v, "must be a finite number > 0"))
    }
}

impl Config {
    /// Parse TOML text; `path` names the file in messages.
    pub fn from_toml(text: &str, path: &Path) -> Result<Config, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Ok(cfg)
    }

    /// Read and parse a file (not yet validated: flags may still override).
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        Config::load_with_keys(path).map(|(cfg, _)| cfg)
    }

    /// Read and parse a file, and say which keys it sets ([`KeysPresent`]),
    /// whatever their values.
    pub fn load_with_keys(path: &Path) -> Result<(Config, KeysPresent), ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let cfg = Config::from_toml(&text, path)?;
        Ok((cfg, KeysPresent::of_toml(&text)))
    }

    /// The labelled inputs and the triad models: well formed, labels unique,
    /// no mix with the single-input keys.
    fn validate_inputs(&self) -> Result<(), ConfigError> {
        let s = &self.source;
        let mut labels = std::collections::BTreeSet::new();
        for text in &s.inputs {
            let input = LabelledInput::parse(text)
                .map_err(|m| invalid("source.inputs", format!("{text:?}"), m))?;
            if !labels.insert(input.label) {
                return Err(invalid(
                    "source.inputs",
                    format!("{text:?}"),
                    "labels must be unique",
                ));
            }
        }
        if !s.inputs.is_empty() {
            if s.kind == SourceKind::Simulate {
                return Err(invalid(
                    "source.inputs",
                    format!("{:?}", s.inputs),
                    "labelled inputs are serial devices or captures: source.kind must be serial or replay",
                ));
            }
            let single = if s.kind == SourceKind::Serial {
                &s.serial_path
            } else {
                &s.replay_path
            };
            if !single.is_empty() {
                return Err(invalid(
                    "source.inputs",
                    format!("{:?}", s.inputs),
                    "give either labelled inputs or source.serial_path / source.replay_path, not both",
                ));
            }
        }
        if !s.triad_models.is_empty() {
            if s.triad_models.len() != 3 {
                return Err(invalid(
                    "source.triad_models",
                    format!("{:?}", s.triad_models),
                    "a simulated triad needs exactly three models (x, y, z)",
                ));
            }
            if s.kind != SourceKind::Simulate || !s.model.is_empty() {
                return Err(invalid(
                    "source.triad_models",
                    format!("{:?}", s.triad_models),
                    "a simulated triad needs source.kind = \"simulate\" and no source.model",
                ));
            }
        }
        Ok(())
    }

    /// Check every value; the first problem is reported with its key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        positive("gyro.sample_rate_hz", self.gyro.sample_rate_hz)?;
        positive("gyro.pulse_arcsec", self.gyro.pulse_arcsec)?;
        label_value("gyro.serial_number", &self.gyro.serial_number)?;
        label_value("gyro.model_name", &self.gyro.model_name)?;
        self.validate_inputs()?;
        let labelled = !self.source.inputs.is_empty();
        match self.source.kind {
            SourceKind::Serial => {
                if self.source.serial_path.is_empty() && !labelled {
                    return Err(invalid(
                        "source.serial_path",
                        "\"\"",
                        "required when source.kind = \"serial\"",
                    ));
                }
                if self.source.baud == 0 {
                    return Err(invalid("source.baud", 0, "must be > 0"));
                }
            }
            SourceKind::Replay => {
                if self.source.replay_path.is_empty() && !labelled {
                    return Err(invalid(
                        "source.replay_path",
                        "\"\"",
                        "required when source.kind = \"replay\"",
                    ));
                }
            }
            SourceKind::Simulate => {}
        }
        positive(
            "source.reconnect_initial_s",
            self.source.reconnect_initial_s,
        )?;
        positive("source.reconnect_max_s", self.source.reconnect_max_s)?;
        if self.source.reconnect_max_s < self.source.reconnect_initial_s {
            return Err(invalid(
                "source.reconnect_max_s",
                self.source.reconnect_max_s,
                "must be >= source.reconnect_initial_s",
            ));
        }
        let b = self.source.queue_budget_mib;
        if !(b.is_finite() && (QUEUE_BUDGET_MIB[0]..=QUEUE_BUDGET_MIB[1]).contains(&b)) {
            return Err(invalid(
                "source.queue_budget_mib",
                b,
                "must be from 0.0625 (64 KiB) to 4096 (4 GiB)",
            ));
        }
        if let Some(speed) = self.source.speed
            && !(speed.is_finite() && speed >= 0.0)
        {
            return Err(invalid(
                "source.speed",
                speed,
                "must be >= 0 (0 = as fast as possible)",
            ));
        }
        if !["sym8", "haar", "db4", "sym4", "db8"].contains(&self.dsp.wavelet.as_str()) {
            return Err(invalid(
                "dsp.wavelet",
                &self.dsp.wavelet,
                "must be one of sym8, haar, db4, sym4, db8",
            ));
        }
        if self.dsp.levels > 30 {
            return Err(invalid(
                "dsp.levels",
                self.dsp.levels,
                "must be 0 (auto) to 30",
            ));
        }
        let m = self.allan.full_overlap_max_m;
        if m < 2 || !m.is_power_of_two() || m > (1 << 24) {
            return Err(invalid(
                "allan.full_overlap_max_m",
                m,
                "must be a power of two from 2 to 2^24",
            ));
        }
        positive("estimator.interval_s", self.estimator.interval_s)?;
        if !self.metrics.addr.is_empty() && self.metrics.addr.parse::<SocketAddr>().is_err() {
            return Err(invalid(
                "metrics.addr",
                &self.metrics.addr,
                "must be IP:PORT, e.g. 127.0.0.1:9898",
            ));
        }
        positive("record.flush_interval_s", self.record.flush_interval_s)?;
        if self.record.batch_samples == 0 {
            return Err(invalid("record.batch_samples", 0, "must be > 0"));
        }
        if !(self.run.duration_s.is_finite() && self.run.duration_s >= 0.0) {
            return Err(invalid(
                "run.duration_s",
                self.run.duration_s,
                "must be >= 0 (0 = until stopped)",
            ));
        }
        if self.run.channel_capacity == 0 {
            return Err(invalid("run.channel_capacity", 0, "must be > 0"));
        }
        if self.spec.stop_when_decided && self.spec.path.is_empty() {
            return Err(invalid(
                "spec.stop_when_decided",
                true,
                "needs a spec file (spec.path, --spec)",
            ));
        }
        if self.log.level.trim().is_empty() {
            return Err(invalid(
                "log.level",
                "\"\"",
                "must be a tracing filter such as info",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn default_toml() -> String {
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/default.toml"))
            .unwrap()
    }

    #[test]
    fn default_toml_parses_validates_and_equals_the_built_in_defaults() {
        let cfg = Config::from_toml(&default_toml(), Path::new("config/default.toml")).unwrap();
        cfg.validate().unwrap();
        assert_eq!(
            cfg,
            Config::default(),
            "config/default.toml must document the built-in defaults"
        );
    }

    #[test]
    fn keys_present_are_found_by_presence_not_value() {
        let k = KeysPresent::of_toml("[gyro]\nrate_hz = 1000.0\n[source]\nkind = \"serial\"\n");
        assert!(
            k.contains("gyro.sample_rate_hz") && k.contains("source.kind") && k.contains("gyro")
        );
        assert!(!k.contains("gyro.pulse_arcsec"));
        assert_eq!(KeysPresent::of_toml(""), KeysPresent::default());
    }

    #[test]
    fn unknown_keys_are_rejected_at_every_level() {
        for (text, key) in [
            ("bogus = 1", "bogus"),
            ("[gyro]\nrate = 5", "rate"),
            ("[gyro]\nserial = \"A1\"", "serial"),
            ("[record]\nflush_s = 1", "flush_s"),
        ] {
            let err = Config::from_toml(text, Path::new("x.toml"))
                .unwrap_err()
                .to_string();
            assert!(err.contains(key) && err.contains("x.toml"), "{err}");
        }
    }

    #[test]
    fn bad_values_name_their_key() {
        let cases = [
            ("[gyro]\nrate_hz = -1.0", "gyro.sample_rate_hz"),
            ("[gyro]\npulse_arcsec = 0.0", "gyro.pulse_arcsec"),
            ("[source]\nkind = \"serial\"", "source.serial_path"),
            ("[source]\nkind = \"replay\"", "source.replay_path"),
            ("[dsp]\nwavelet = \"morlet\"", "dsp.wavelet"),
            (
                "[allan]\nfull_overlap_max_m = 1000",
                "allan.full_overlap_max_m",
            ),
            ("[metrics]\naddr = \"localhost\"", "metrics.addr"),
            ("[source]\nspeed = -2.0", "source.speed"),
            ("[source]\nqueue_budget_mib = 0", "source.queue_budget_mib"),
            (
                "[source]\nqueue_budget_mib = -1.0",
                "source.queue_budget_mib",
            ),
            (
                "[source]\nqueue_budget_mib = 0.01",
                "source.queue_budget_mib",
            ),
            (
                "[source]\nqueue_budget_mib = 1e9",
                "source.queue_budget_mib",
            ),
            (
                "[source]\nqueue_budget_mib = nan",
                "source.queue_budget_mib",
            ),
            ("[run]\nchannel_capacity = 0", "run.channel_capacity"),
            ("[gyro]\nserial_number = \"SN\\n1\"", "gyro.serial_number"),
            ("[gyro]\nmodel_name = \"tab\\there\"", "gyro.model_name"),
        ];
        let long = format!(
            "[gyro]\nmodel_name = \"{}\"",
            "m".repeat(GYRO_NAME_MAX_CHARS + 1)
        );
        let err = Config::from_toml(&long, Path::new("x.toml"))
            .unwrap()
            .validate()
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("gyro.model_name") && err.contains("129 characters"),
            "{err}"
        );
        for (text, key) in cases {
            let cfg = Config::from_toml(text, Path::new("x.toml")).unwrap();
            let err = cfg.validate().unwrap_err().to_string();
            assert!(err.contains(key), "{text}: {err}");
        }
    }
}
