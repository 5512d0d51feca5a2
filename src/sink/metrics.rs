//! Prometheus metrics of the acquisition daemon: one [`Metrics`] value owning its
//! own `Registry`, updated from plain numbers by the daemon's tasks, rendered in
//! the text exposition format 0.0.4 by [`Metrics::encode`] for `GET /metrics`
//! (served by [`crate::daemon::http`]).
//!
//! Names follow the project convention (`sagnac_<name>_<unit>` gauges,
//! `sagnac_<name>_total` counters) and pass `promtool check metrics`:
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `sagnac_samples_total` | counter | |
//! | `sagnac_frames_decoded_total` | counter | |
//! | `sagnac_frame_errors_total` | counter | `kind`: `crc`, `false_sync`, `truncated` |
//! | `sagnac_lost_samples_total` | counter | |
//! | `sagnac_bytes_read_total` | counter | |
//! | `sagnac_qn_arcseconds` | gauge | `bound`: `estimate`, `lower95`, `upper95` |
//! | `sagnac_arw_degrees_per_root_hour` | gauge | `bound` |
//! | `sagnac_bias_instability_degrees_per_hour` | gauge | `bound` |
//! | `sagnac_rrw_degrees_per_hour_per_root_hour` | gauge | `bound` |
//! | `sagnac_rate_ramp_degrees_per_hour_squared` | gauge | `bound` |
//! | `sagnac_build_info` | gauge | `version` (always 1) |
//! | `sagnac_allan_deviation_degrees_per_hour` | gauge | `channel`: `raw`, `clean`; `tau_seconds` |
//! | `sagnac_temperature_celsius` | gauge | |
//! | `sagnac_processing_lag_seconds` | gauge | |
//! | `sagnac_recording_bytes` | gauge | |
//! | `sagnac_spec_verdict` | gauge | `coefficient` (as in the spec, and `overall`): 1 pass, 0 undecided, -1 fail |
//! | `sagnac_spec_limit` | gauge | `coefficient`: the spec's limit, in the coefficient's unit |
//! | `sagnac_spec_decision_eta_seconds` | gauge | `coefficient`: predicted record length until a decision (0 decided, NaN unknown) |
//!
//! The `sagnac_spec_*` series exist only in a run with a spec (`sagnac run --spec`).
//!
//! A coefficient bound that is not known is absent (no series), not zero; the
//! temperature and lag read `NaN` until first set. The Allan series of a channel
//! are replaced as a whole at each update, so no stale tau lingers.

use std::collections::BTreeMap;
use std::sync::Mutex;

use prometheus::{Encoder, Gauge, GaugeVec, IntCounter, IntCounterVec, IntGauge, Opts, Registry};

/// Errors of the metrics module.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// A metric could not be created or registered (a bug in this module).
    #[error("cannot register metric `{name}`: {source}")]
    Register {
        name: &'static str,
        source: prometheus::Error,
    },
    /// An Allan curve has columns of unequal length.
    #[error("Allan curve for channel `{channel}`: {taus} taus but {devs} deviations")]
    CurveLength {
        channel: &'static str,
        taus: usize,
        devs: usize,
    },
    /// An averaging time is not a positive finite number.
    #[error(
        "Allan curve for channel `{channel}`: tau #{index} = {tau_s} s is not positive and finite"
    )]
    BadTau {
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

/// The daemon's metrics and the registry that exposes them.
pub struct Metrics {
    registry: Registry,
    samples: IntCounter,
    frames_decoded: IntCounter,
    frame_errors: IntCounterVec,
    lost_samples: IntCounter,
    bytes_read: IntCounter,
    qn: GaugeVec,
    arw: GaugeVec,
    bias_instability: GaugeVec,
    rrw: GaugeVec,
    rate_ramp: GaugeVec,
    allan: GaugeVec,
    /// tau labels currently exported, per channel.
    allan_taus: Mutex<BTreeMap<AllanChannel, Vec<String>>>,
    temperature: Gauge,
    lag: Gauge,
    recording_bytes: IntGauge,
    spec_verdict: GaugeVec,
    spec_limit: GaugeVec,
    spec_eta: GaugeVec,
}

impl std::fmt::Debug for Metrics {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Metrics").finish_non_exhaustive()
    }
}

impl Metrics {
    /// Create every metric and register it in a fresh registry.
    pub fn new() -> Result<Metrics, MetricsError> {
        let registry = Registry::new();
        fn reg<C: prometheus::core::Collector + Clone + 'static>(
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
        let counter =
            |name: &'static str, help: &str| reg(&registry, name, IntCounter::new(name, help));
        let bounds = |name: &'static str, help: &str| {
            reg(
                &registry,
                name,
                GaugeVec::new(Opts::new(name, help), &["bound"]),
            )
        };
        let m = Metrics {
            samples: counter("sagnac_samples_total", "Gyro samples decoded.")?,
            frames_decoded: counter(
                "sagnac_frames_decoded_total",
                "Frames decoded with a valid CRC.",
            )?,
            frame_errors: reg(
                &registry,
                "sagnac_frame_errors_total",
                IntCounterVec::new(
                    Opts::new(
                        "sagnac_frame_errors_total",
                        "Frame decoding errors by kind: crc (CRC mismatch), false_sync (sync pattern not starting a valid frame), truncated (partial frame at end of input or disconnect).",
                    ),
                    &["kind"],
                ),
            )?,
            lost_samples: counter(
                "sagnac_lost_samples_total",
                "Samples missing according to the device sequence numbers.",
            )?,
            bytes_read: counter(
                "sagnac_bytes_read_total",
                "Bytes read from the device or input file.",
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
            allan: reg(
                &registry,
                "sagnac_allan_deviation_degrees_per_hour",
                GaugeVec::new(
                    Opts::new(
                        "sagnac_allan_deviation_degrees_per_hour",
                        "Octave Allan deviation, degrees per hour, per channel (raw, clean) and averaging time tau in seconds.",
                    ),
                    &["channel", "tau_seconds"],
                ),
            )?,
            allan_taus: Mutex::new(BTreeMap::new()),
            temperature: reg(
                &registry,
                "sagnac_temperature_celsius",
                Gauge::new(
                    "sagnac_temperature_celsius",
                    "Gyro temperature reported by the device, degrees Celsius (NaN when unknown).",
                ),
            )?,
            lag: reg(
                &registry,
                "sagnac_processing_lag_seconds",
                Gauge::new(
                    "sagnac_processing_lag_seconds",
                    "Wall time minus the sample time of the newest processed sample, seconds (NaN before the first).",
                ),
            )?,
            recording_bytes: reg(
                &registry,
                "sagnac_recording_bytes",
                IntGauge::new(
                    "sagnac_recording_bytes",
                    "Size of the current MCAP recording written so far, bytes.",
                ),
            )?,
            spec_verdict: reg(
                &registry,
                "sagnac_spec_verdict",
                GaugeVec::new(
                    Opts::new(
                        "sagnac_spec_verdict",
                        "Acceptance-test verdict per coefficient (and overall): 1 pass, 0 undecided, -1 fail.",
                    ),
                    &["coefficient"],
                ),
            )?,
            spec_limit: reg(
                &registry,
                "sagnac_spec_limit",
                GaugeVec::new(
                    Opts::new("sagnac_spec_limit", "The spec's upper limit per coefficient, in the coefficient's unit."),
                    &["coefficient"],
                ),
            )?,
            spec_eta: reg(
                &registry,
                "sagnac_spec_decision_eta_seconds",
                GaugeVec::new(
                    Opts::new(
                        "sagnac_spec_decision_eta_seconds",
                        "Predicted further record length until the coefficient is decided, seconds (0: decided; NaN: no prediction).",
                    ),
                    &["coefficient"],
                ),
            )?,
            registry,
        };
        for kind in FrameErrorKind::ALL {
            m.frame_errors.with_label_values(&[kind.as_str()]);
        }
        m.temperature.set(f64::NAN);
        m.lag.set(f64::NAN);
        let build = reg(
            &m.registry,
            "sagnac_build_info",
            GaugeVec::new(Opts::new("sagnac_build_info", "Always 1; the version label says which sagnac runs."), &["version"]),
        )?;
        build.with_label_values(&[env!("CARGO_PKG_VERSION")]).set(1.0);
        Ok(m)
    }

    /// The registry (to add process metrics or gather in tests).
    pub fn registry(&self) -> &Registry {
        &self.registry
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
        self.frame_errors
            .with_label_values(&[kind.as_str()])
            .inc_by(n);
    }

    /// Count lost samples.
    pub fn add_lost_samples(&self, n: u64) {
        self.lost_samples.inc_by(n);
    }

    /// Count bytes read.
    pub fn add_bytes_read(&self, n: u64) {
        self.bytes_read.inc_by(n);
    }

    /// Set the quantization-noise coefficient, arcsec.
    pub fn set_qn_arcsec(&self, b: Bounds95) {
        set_bounds(&self.qn, b);
    }

    /// Set the angle-random-walk coefficient, deg/sqrt(h).
    pub fn set_arw_dpsh(&self, b: Bounds95) {
        set_bounds(&self.arw, b);
    }

    /// Set the bias-instability coefficient, deg/h.
    pub fn set_bias_instability_dph(&self, b: Bounds95) {
        set_bounds(&self.bias_instability, b);
    }

    /// Set the rate-random-walk coefficient, deg/h/sqrt(h).
    pub fn set_rrw_dphsh(&self, b: Bounds95) {
        set_bounds(&self.rrw, b);
    }

    /// Set the rate ramp, deg/h/h.
    pub fn set_rate_ramp_dphh(&self, b: Bounds95) {
        set_bounds(&self.rate_ramp, b);
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
        if tau_s.len() != adev_dph.len() {
            return Err(MetricsError::CurveLength {
                channel: name,
                taus: tau_s.len(),
                devs: adev_dph.len(),
            });
        }
        if let Some(index) = tau_s.iter().position(|t| !(t.is_finite() && *t > 0.0)) {
            return Err(MetricsError::BadTau {
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
        for old in taus.remove(&channel).unwrap_or_default() {
            // Absent series are fine: removing is idempotent for us.
            let _ = self.allan.remove_label_values(&[name, &old]);
        }
        for (label, &dev) in labels.iter().zip(adev_dph) {
            self.allan.with_label_values(&[name, label]).set(dev);
        }
        taus.insert(channel, labels);
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

    /// Set the size of the current recording, bytes.
    pub fn set_recording_bytes(&self, bytes: u64) {
        self.recording_bytes
            .set(i64::try_from(bytes).unwrap_or(i64::MAX));
    }

    /// Set one coefficient's acceptance-test series: verdict (1 pass, 0 undecided,
    /// -1 fail), its limit (`None` for `overall`) and the predicted time to a
    /// decision, s (`None`: exported as NaN).
    pub fn set_spec(&self, coefficient: &str, verdict: f64, limit: Option<f64>, eta_s: Option<f64>) {
        self.spec_verdict.with_label_values(&[coefficient]).set(verdict);
        if let Some(l) = limit {
            self.spec_limit.with_label_values(&[coefficient]).set(l);
        }
        if coefficient != "overall" {
            self.spec_eta.with_label_values(&[coefficient]).set(eta_s.unwrap_or(f64::NAN));
        }
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

/// The content type of [`Metrics::encode`].
pub const TEXT_CONTENT_TYPE: &str = "text/plain; version=0.0.4; charset=utf-8";

fn set_bounds(gauge: &GaugeVec, b: Bounds95) {
    for (label, value) in [
        ("estimate", b.estimate),
        ("lower95", b.lower95),
        ("upper95", b.upper95),
    ] {
        match value {
            Some(v) => gauge.with_label_values(&[label]).set(v),
            None => {
                let _ = gauge.remove_label_values(&[label]);
            }
        }
    }
}

/// The `tau_seconds` label: tau rounded to 9 significant digits, in shortest form
/// (0.001 * 2^7 gives "0.128", whatever the last bits of the product).
pub fn tau_label(tau_s: f64) -> String {
    // `{:.8e}` rounds correctly to 9 significant digits; parsing gives the double
    // nearest that decimal, which `{}` prints back as the shortest such decimal.
    let rounded: f64 = format!("{tau_s:.8e}").parse().unwrap_or(tau_s);
    format!("{rounded}")
}
