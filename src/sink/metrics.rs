//! Prometheus metrics of the acquisition daemon: one [`Metrics`] value owning its
//! own `Registry`, updated from plain numbers by the daemon's tasks, rendered in
//! the text exposition format 0.0.4 by [`Metrics::encode`] for `GET /metrics`
//! (served by [`crate::daemon::http`]).
//!
//! Names follow the project convention (`sagnac_<name>_<unit>` gauges,
//! `sagnac_<name>_total` counters) and pass `promtool check metrics`.
//!
//! Every per-gyro series carries a `gyro` label. A daemon with one unlabelled
//! source names its gyro [`DEFAULT_GYRO`] (`gyro`); a daemon with several gyros
//! asks [`Metrics::gyro`] for one [`GyroMetrics`] handle per gyro, and that
//! handle is the only place where the label is attached. Daemon-wide series
//! (bytes read, the recording, the build) have no `gyro` label.
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `sagnac_samples_total` | counter | `gyro` |
//! | `sagnac_frames_decoded_total` | counter | `gyro` |
//! | `sagnac_frame_errors_total` | counter | `gyro`; `kind`: `crc`, `false_sync`, `truncated` |
//! | `sagnac_lost_samples_total` | counter | `gyro` |
//! | `sagnac_qn_arcseconds` | gauge | `gyro`; `bound`: `estimate`, `lower95`, `upper95` |
//! | `sagnac_arw_degrees_per_root_hour` | gauge | `gyro`; `bound` |
//! | `sagnac_bias_instability_degrees_per_hour` | gauge | `gyro`; `bound` |
//! | `sagnac_rrw_degrees_per_hour_per_root_hour` | gauge | `gyro`; `bound` |
//! | `sagnac_rate_ramp_degrees_per_hour_squared` | gauge | `gyro`; `bound` |
//! | `sagnac_allan_deviation_degrees_per_hour` | gauge | `gyro`; `channel`: `raw`, `clean`; `tau_seconds` |
//! | `sagnac_temperature_celsius` | gauge | `gyro` |
//! | `sagnac_processing_lag_seconds` | gauge | `gyro` |
//! | `sagnac_outliers_total` | counter | `gyro` (single-sample glitches the data-quality stage found; apart from lost samples) |
//! | `sagnac_bias_steps_total` | counter | `gyro` (bias steps the data-quality stage found so far) |
//! | `sagnac_warmup_active` | gauge | `gyro` (1 while a warm-up is found and not yet settled, else 0) |
//! | `sagnac_warmup_amplitude_dph` | gauge | `gyro` (the warm-up's amplitude, deg/h; 0 when none) |
//! | `sagnac_warmup_tau_seconds` | gauge | `gyro` (the warm-up's time constant, s; 0 when none) |
//! | `sagnac_gyro_info` | gauge | `gyro`, `serial_number`, `model` (always 1; from the config) |
//! | `sagnac_spec_verdict` | gauge | `gyro`; `coefficient` (as in the spec, and `overall`): 1 pass, 0 undecided, -1 fail |
//! | `sagnac_spec_limit` | gauge | `gyro`; `coefficient`: the spec's limit, in the coefficient's unit |
//! | `sagnac_spec_decision_eta_seconds` | gauge | `gyro`; `coefficient`: predicted record length until a decision (0 decided, NaN unknown) |
//! | `sagnac_bytes_read_total` | counter | (daemon-wide) |
//! | `sagnac_recording_bytes` | gauge | (daemon-wide) |
//! | `sagnac_build_info` | gauge | `version` (always 1) |
//!
//! The `sagnac_spec_*` series exist only in a run with a spec (`sagnac run --spec`).
//! The data-quality series (outliers, bias steps, warm-up) stay at 0 with the
//! raw statistics (`--raw-statistics`).
//!
//! A coefficient bound that is not known is absent (no series), not zero; the
//! temperature and lag read `NaN` until first set. The Allan series of a channel
//! are replaced as a whole at each update, so no stale tau lingers.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use prometheus::{Encoder, Gauge, GaugeVec, IntCounter, IntCounterVec, IntGauge, Opts, Registry};

/// The `gyro` label of the single unlabelled source of a daemon.
pub const DEFAULT_GYRO: &str = "gyro";

/// Errors of the metrics module.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// A metric could not be created or registered (a bug in this module).
    #[error("cannot register metric `{name}`")]
    Register {
        name: &'static str,
        source: prometheus::Error,
    },
    /// An Allan curve has columns of unequal length.
    #[error("Allan curve of gyro `{gyro}`, channel `{channel}`: {taus} taus but {devs} deviations")]
    CurveLength {
        gyro: String,
        channel: &'static str,
        taus: usize,
        devs: usize,
    },
    /// An averaging time is not a positive finite number.
    #[error(
        "Allan curve of gyro `{gyro}`, channel `{channel}`: tau #{index} = {tau_s} s is not positive and finite"
    )]
    BadTau {
        gyro: String,
        channel: &'static str,
        index: usize,
        tau_s: f64,
    },
}

/// The kinds of `sagnac_frame_errors_total`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameErrorKind {
    /// A complete frame whose CRC does not match.
    Crc,
    /// A sync pattern that did not start a valid frame (bad header or length field);
    /// the decoder resumed the search one byte later.
    FalseSync,
    /// A partial frame cut by the end of the input or a device disconnect.
    Truncated,
}

impl FrameErrorKind {
    pub const ALL: [FrameErrorKind; 3] = [
        FrameErrorKind::Crc,
        FrameErrorKind::FalseSync,
        FrameErrorKind::Truncated,
    ];

    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            FrameErrorKind::Crc => "crc",
            FrameErrorKind::FalseSync => "false_sync",
            FrameErrorKind::Truncated => "truncated",
        }
    }
}

/// The `channel` label of `sagnac_allan_deviation_degrees_per_hour`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum AllanChannel {
    Raw,
    Clean,
}

impl AllanChannel {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            AllanChannel::Raw => "raw",
            AllanChannel::Clean => "clean",
        }
    }
}

/// A coefficient with its 95 % interval; `None` removes that series.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Bounds95 {
    pub estimate: Option<f64>,
    pub lower95: Option<f64>,
    pub upper95: Option<f64>,
}

/// Who a gyro is: its `gyro` label and the other labels of its `sagnac_gyro_info`
/// (empty strings when not configured; Prometheus treats them as absent labels).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct GyroInfo {
    /// The `gyro` label of every series of this gyro.
    pub label: String,
    /// The unit's serial number (config `gyro.serial_number`).
    pub serial_number: String,
    /// The unit's model name (config `gyro.model_name`).
    pub model: String,
}

impl GyroInfo {
    /// A gyro known only by its label.
    pub fn labelled(label: &str) -> GyroInfo {
        GyroInfo {
            label: label.to_string(),
            ..GyroInfo::default()
        }
    }
}

/// The metric families of the per-gyro series, each with a leading `gyro` label.
#[derive(Clone)]
struct GyroFamilies {
    samples: IntCounterVec,
    frames_decoded: IntCounterVec,
    frame_errors: IntCounterVec,
    lost_samples: IntCounterVec,
    qn: GaugeVec,
    arw: GaugeVec,
    bias_instability: GaugeVec,
    rrw: GaugeVec,
    rate_ramp: GaugeVec,
    allan: GaugeVec,
    temperature: GaugeVec,
    lag: GaugeVec,
    outliers: IntCounterVec,
    bias_steps: IntCounterVec,
    warmup_active: GaugeVec,
    warmup_amplitude: GaugeVec,
    warmup_tau: GaugeVec,
    info: GaugeVec,
    spec_verdict: GaugeVec,
    spec_limit: GaugeVec,
    spec_eta: GaugeVec,
}

/// Create a collector and register it (the daemon's own series use it too).
pub fn register<C: prometheus::core::Collector + Clone + 'static>(
    registry: &Registry,
    name: &'static str,
    made: prometheus::Result<C>,
) -> Result<C, MetricsError> {
    let c = made.map_err(|source| MetricsError::Register { name, source })?;
    registry
        .register(Box::new(c.clone()))
        .map_err(|source| MetricsError::Register { name, source })?;
    Ok(c)
}

impl GyroFamilies {
    fn new(registry: &Registry) -> Result<GyroFamilies, MetricsError> {
        let counter = |name: &'static str, help: &str| {
            register(
                registry,
                name,
                IntCounterVec::new(Opts::new(name, help), &["gyro"]),
            )
        };
        let gauge = |name: &'static str, help: &str, labels: &[&str]| {
            let mut all = vec!["gyro"];
            all.extend_from_slice(labels);
            register(registry, name, GaugeVec::new(Opts::new(name, help), &all))
        };
        let bounds = |name: &'static str, help: &str| gauge(name, help, &["bound"]);
        Ok(GyroFamilies {
            samples: counter("sagnac_samples_total", "Gyro samples decoded.")?,
            frames_decoded: counter(
                "sagnac_frames_decoded_total",
                "Frames decoded with a valid CRC.",
            )?,
            frame_errors: register(
                registry,
                "sagnac_frame_errors_total",
                IntCounterVec::new(
                    Opts::new(
                        "sagnac_frame_errors_total",
                        "Frame decoding errors by kind: crc (CRC mismatch), false_sync (sync pattern not starting a valid frame), truncated (partial frame at end of input or disconnect).",
                    ),
                    &["gyro", "kind"],
                ),
            )?,
            lost_samples: counter(
                "sagnac_lost_samples_total",
                "Samples missing according to the device sequence numbers.",
            )?,
            qn: bounds(
                "sagnac_qn_arcseconds",
                "Quantization noise coefficient Q, arcseconds, with its 95% interval.",
            )?,
            arw: bounds(
                "sagnac_arw_degrees_per_root_hour",
                "Angle random walk coefficient N, degrees per square root of hour, with its 95% interval.",
            )?,
            bias_instability: bounds(
                "sagnac_bias_instability_degrees_per_hour",
                "Bias instability coefficient B, degrees per hour, with its 95% interval.",
            )?,
            rrw: bounds(
                "sagnac_rrw_degrees_per_hour_per_root_hour",
                "Rate random walk coefficient K, degrees per hour per square root of hour, with its 95% interval \
                 (only upper95 while the term is not found).",
            )?,
            rate_ramp: bounds(
                "sagnac_rate_ramp_degrees_per_hour_squared",
                "Rate ramp R, degrees per hour per hour (signed), with its 95% interval (only upper95, on its \
                 magnitude, while the ramp is not found).",
            )?,
            allan: gauge(
                "sagnac_allan_deviation_degrees_per_hour",
                "Octave Allan deviation, degrees per hour, per channel (raw, clean) and averaging time tau in seconds.",
                &["channel", "tau_seconds"],
            )?,
            temperature: gauge(
                "sagnac_temperature_celsius",
                "Gyro temperature reported by the device, degrees Celsius (NaN when unknown).",
                &[],
            )?,
            lag: gauge(
                "sagnac_processing_lag_seconds",
                "Wall time minus the sample time of the newest processed sample, seconds (NaN before the first).",
                &[],
            )?,
            outliers: counter(
                "sagnac_outliers_total",
                "Single-sample glitches (outliers) found by the data-quality stage, excluded from the statistics \
                 as gaps unless the noise is heavy-tailed (lost samples are counted apart).",
            )?,
            bias_steps: counter(
                "sagnac_bias_steps_total",
                "Bias steps found by the data-quality stage's analysis of the slow effects so far.",
            )?,
            warmup_active: gauge(
                "sagnac_warmup_active",
                "1 while a warm-up (exponential settling of the bias) is found and has not settled yet \
                 (5 time constants since the start of the statistics), else 0.",
                &[],
            )?,
            warmup_amplitude: gauge(
                "sagnac_warmup_amplitude_dph",
                "Amplitude of the warm-up found (the bias's offset at the start from its settled value), \
                 degrees per hour (0 when none).",
                &[],
            )?,
            warmup_tau: gauge(
                "sagnac_warmup_tau_seconds",
                "Time constant of the warm-up found, seconds (0 when none).",
                &[],
            )?,
            info: gauge(
                "sagnac_gyro_info",
                "Always 1; the labels say which unit each gyro label is (serial number and model from the config).",
                &["serial_number", "model"],
            )?,
            spec_verdict: gauge(
                "sagnac_spec_verdict",
                "Acceptance-test verdict per coefficient (and overall): 1 pass, 0 undecided, -1 fail.",
                &["coefficient"],
            )?,
            spec_limit: gauge(
                "sagnac_spec_limit",
                "The spec's upper limit per coefficient, in the coefficient's unit.",
                &["coefficient"],
            )?,
            spec_eta: gauge(
                "sagnac_spec_decision_eta_seconds",
                "Predicted further record length until the coefficient is decided, seconds (0: decided; NaN: no prediction).",
                &["coefficient"],
            )?,
        })
    }
}

/// The daemon's metrics and the registry that exposes them.
pub struct Metrics {
    registry: Registry,
    bytes_read: IntCounter,
    recording_bytes: IntGauge,
    gyros: GyroFamilies,
    /// tau labels currently exported, per (gyro, channel).
    allan_taus: Arc<Mutex<BTreeMap<(String, AllanChannel), Vec<String>>>>,
    /// The gyro labels handed out so far.
    known: Mutex<std::collections::BTreeSet<String>>,
}

impl std::fmt::Debug for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Metrics").finish_non_exhaustive()
    }
}

impl Metrics {
    /// Create every metric family and register it in a fresh registry. Per-gyro
    /// series appear once a gyro is added with [`Metrics::gyro`].
    pub fn new() -> Result<Metrics, MetricsError> {
        let registry = Registry::new();
        let bytes_read = register(
            &registry,
            "sagnac_bytes_read_total",
            IntCounter::new(
                "sagnac_bytes_read_total",
                "Bytes read from the devices or input files.",
            ),
        )?;
        let recording_bytes = register(
            &registry,
            "sagnac_recording_bytes",
            IntGauge::new(
                "sagnac_recording_bytes",
                "Size of the current MCAP recording written so far, bytes.",
            ),
        )?;
        let build = register(
            &registry,
            "sagnac_build_info",
            GaugeVec::new(
                Opts::new(
                    "sagnac_build_info",
                    "Always 1; the version label says which sagnac runs.",
                ),
                &["version"],
            ),
        )?;
        build
            .with_label_values(&[env!("CARGO_PKG_VERSION")])
            .set(1.0);
        Ok(Metrics {
            gyros: GyroFamilies::new(&registry)?,
            registry,
            bytes_read,
            recording_bytes,
            allan_taus: Arc::new(Mutex::new(BTreeMap::new())),
            known: Mutex::new(std::collections::BTreeSet::new()),
        })
    }

    /// The series of one gyro: exports its `sagnac_gyro_info` and its counters
    /// at 0 (temperature and lag at NaN until set). Asking again for a label
    /// already handed out returns a handle on the same series, unchanged (its info
    /// stays the first one given).
    pub fn gyro(&self, info: &GyroInfo) -> GyroMetrics {
        let f = &self.gyros;
        let g = info.label.as_str();
        let gm = GyroMetrics {
            label: Arc::from(g),
            samples: f.samples.with_label_values(&[g]),
            frames_decoded: f.frames_decoded.with_label_values(&[g]),
            frame_errors: FrameErrorKind::ALL
                .map(|k| f.frame_errors.with_label_values(&[g, k.as_str()])),
            lost_samples: f.lost_samples.with_label_values(&[g]),
            temperature: f.temperature.with_label_values(&[g]),
            lag: f.lag.with_label_values(&[g]),
            outliers: f.outliers.with_label_values(&[g]),
            bias_steps: f.bias_steps.with_label_values(&[g]),
            warmup: [
                f.warmup_active.with_label_values(&[g]),
                f.warmup_amplitude.with_label_values(&[g]),
                f.warmup_tau.with_label_values(&[g]),
            ],
            families: f.clone(),
            allan_taus: Arc::clone(&self.allan_taus),
        };
        let mut known = self
            .known
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if known.insert(g.to_string()) {
            f.info
                .with_label_values(&[g, &info.serial_number, &info.model])
                .set(1.0);
            gm.temperature.set(f64::NAN);
            gm.lag.set(f64::NAN);
        }
        gm
    }

    /// The registry (to add process metrics or gather in tests).
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Count bytes read.
    pub fn add_bytes_read(&self, n: u64) {
        self.bytes_read.inc_by(n);
    }

    /// Set the size of the current recording, bytes.
    pub fn set_recording_bytes(&self, bytes: u64) {
        self.recording_bytes
            .set(i64::try_from(bytes).unwrap_or(i64::MAX));
    }

    /// The text exposition (format 0.0.4) of every metric.
    pub fn encode(&self) -> String {
        let families = self.registry.gather();
        let mut buf = Vec::new();
        match prometheus::TextEncoder::new().encode(&families, &mut buf) {
            Ok(()) => String::from_utf8_lossy(&buf).into_owned(),
            Err(e) => {
                // Cannot happen with the metrics built above; keep the endpoint alive.
                tracing::error!("metrics encoding failed: {e}");
                format!("# sagnac: metrics encoding failed: {e}\n")
            }
        }
    }
}

/// The series of one gyro, every one carrying its `gyro` label: the one handle
/// through which the daemon's tasks update them (cheap to clone).
#[derive(Clone)]
pub struct GyroMetrics {
    label: Arc<str>,
    samples: IntCounter,
    frames_decoded: IntCounter,
    frame_errors: [IntCounter; 3],
    lost_samples: IntCounter,
    temperature: Gauge,
    lag: Gauge,
    outliers: IntCounter,
    bias_steps: IntCounter,
    /// `sagnac_warmup_active`, `_amplitude_dph`, `_tau_seconds`.
    warmup: [Gauge; 3],
    families: GyroFamilies,
    allan_taus: Arc<Mutex<BTreeMap<(String, AllanChannel), Vec<String>>>>,
}

impl std::fmt::Debug for GyroMetrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GyroMetrics")
            .field("gyro", &self.label)
            .finish_non_exhaustive()
    }
}

impl GyroMetrics {
    /// The `gyro` label.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// Count decoded samples.
    pub fn add_samples(&self, n: u64) {
        self.samples.inc_by(n);
    }

    /// Count decoded frames.
    pub fn add_frames_decoded(&self, n: u64) {
        self.frames_decoded.inc_by(n);
    }

    /// Count frame errors of one kind.
    pub fn add_frame_errors(&self, kind: FrameErrorKind, n: u64) {
        let i = FrameErrorKind::ALL
            .iter()
            .position(|&k| k == kind)
            .unwrap_or(0);
        self.frame_errors[i].inc_by(n);
    }

    /// Count lost samples.
    pub fn add_lost_samples(&self, n: u64) {
        self.lost_samples.inc_by(n);
    }

    /// Set the quantization-noise coefficient, arcsec.
    pub fn set_qn_arcsec(&self, b: Bounds95) {
        self.set_bounds(&self.families.qn, b);
    }

    /// Set the angle-random-walk coefficient, deg/sqrt(h).
    pub fn set_arw_dpsh(&self, b: Bounds95) {
        self.set_bounds(&self.families.arw, b);
    }

    /// Set the bias-instability coefficient, deg/h.
    pub fn set_bias_instability_dph(&self, b: Bounds95) {
        self.set_bounds(&self.families.bias_instability, b);
    }

    /// Set the rate-random-walk coefficient, deg/h/sqrt(h).
    pub fn set_rrw_dphsh(&self, b: Bounds95) {
        self.set_bounds(&self.families.rrw, b);
    }

    /// Set the rate ramp, deg/h/h.
    pub fn set_rate_ramp_dphh(&self, b: Bounds95) {
        self.set_bounds(&self.families.rate_ramp, b);
    }

    fn set_bounds(&self, gauge: &GaugeVec, b: Bounds95) {
        for (bound, value) in [
            ("estimate", b.estimate),
            ("lower95", b.lower95),
            ("upper95", b.upper95),
        ] {
            match value {
                Some(v) => gauge.with_label_values(&[&self.label, bound]).set(v),
                None => {
                    // absent already is fine: removing is idempotent for us
                    let _ = gauge.remove_label_values(&[&self.label, bound]);
                }
            }
        }
    }

    /// Replace the Allan curve of a channel: deviations in deg/h at averaging times in s.
    /// On error nothing changes.
    pub fn set_allan_curve(
        &self,
        channel: AllanChannel,
        tau_s: &[f64],
        adev_dph: &[f64],
    ) -> Result<(), MetricsError> {
        let name = channel.as_str();
        let gyro = self.label.to_string();
        if tau_s.len() != adev_dph.len() {
            return Err(MetricsError::CurveLength {
                gyro,
                channel: name,
                taus: tau_s.len(),
                devs: adev_dph.len(),
            });
        }
        if let Some(index) = tau_s.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
            return Err(MetricsError::BadTau {
                gyro,
                channel: name,
                index,
                tau_s: tau_s[index],
            });
        }
        let labels: Vec<String> = tau_s.iter().map(|&t| tau_label(t)).collect();
        let mut taus = self
            .allan_taus
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let allan = &self.families.allan;
        for old in taus.remove(&(gyro.clone(), channel)).unwrap_or_default() {
            let _ = allan.remove_label_values(&[&gyro, name, &old]);
        }
        for (label, &dev) in labels.iter().zip(adev_dph) {
            allan.with_label_values(&[&gyro, name, label]).set(dev);
        }
        taus.insert((gyro, channel), labels);
        Ok(())
    }

    /// Set the device temperature, deg C (`None`: unknown, exported as NaN).
    pub fn set_temperature_c(&self, temp_c: Option<f64>) {
        self.temperature.set(temp_c.unwrap_or(f64::NAN));
    }

    /// Set the processing lag, s.
    pub fn set_processing_lag_s(&self, lag_s: f64) {
        self.lag.set(lag_s);
    }

    /// Count outliers (glitches) found.
    pub fn add_outliers(&self, n: u64) {
        self.outliers.inc_by(n);
    }

    /// Count bias steps found.
    pub fn add_bias_steps(&self, n: u64) {
        self.bias_steps.inc_by(n);
    }

    /// Set the warm-up series: whether one is settling, its amplitude (deg/h)
    /// and time constant (s); `None` (no warm-up) and non-finite numbers read 0.
    pub fn set_warmup(&self, active: bool, amplitude_tau: Option<(f64, f64)>) {
        let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
        let (a, tau) = amplitude_tau.unwrap_or((0.0, 0.0));
        self.warmup[0].set(if active { 1.0 } else { 0.0 });
        self.warmup[1].set(finite(a));
        self.warmup[2].set(finite(tau));
    }

    /// Set one coefficient's acceptance-test series: verdict (1 pass, 0 undecided,
    /// -1 fail), its limit (`None` for `overall`) and the predicted time to a
    /// decision, s (`None`: exported as NaN).
    pub fn set_spec(
        &self,
        coefficient: &str,
        verdict: f64,
        limit: Option<f64>,
        eta_s: Option<f64>,
    ) {
        let f = &self.families;
        let labels = [&*self.label, coefficient];
        f.spec_verdict.with_label_values(&labels).set(verdict);
        if let Some(l) = limit {
            f.spec_limit.with_label_values(&labels).set(l);
        }
        if coefficient != "overall" {
            f.spec_eta
                .with_label_values(&labels)
                .set(eta_s.unwrap_or(f64::NAN));
        }
    }
}

/// The content type of [`Metrics::encode`].
pub const TEXT_CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

/// The `tau_seconds` label: tau rounded to 9 significant digits, in shortest form
/// (0.001 * 2^7 gives "0.128", whatever the last bits of the product).
pub fn tau_label(tau_s: f64) -> String {
    // `{:.8e}` rounds correctly to 9 significant digits; parsing gives the double
    // nearest that decimal, which `{}` prints back as the shortest such decimal.
    let rounded: f64 = format!("{tau_s:.8e}").parse().unwrap_or(tau_s);
    format!("{rounded}")
}
