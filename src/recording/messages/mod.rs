//! The messages the daemon records: one serde struct per MCAP channel, their JSON
//! Schemas, and the checks that keep them representable in JSON.
//!
//! Every channel is JSON-encoded (MCAP message encoding `json`) and carries a
//! hand-written JSON Schema (schema encoding `jsonschema`), so Foxglove and any
//! other MCAP tool can open a recording without our code. The recorder
//! ([`crate::recording::writer`]) writes [`SinkMessage`]s; the reader
//! ([`crate::recording::reader`]) gives them back, equal field for field except for the
//! fixed resolution of the rate values (see below).
//!
//! | topic | message | log time |
//! |---|---|---|
//! | `/gyro/raw` | [`RawBatch`]: per-sample pulse increments with gaps | `t0_ns` |
//! | `/gyro/clean` | [`RateBatch`]: wavelet-cleaned rate, deg/h | `t0_ns` |
//! | `/gyro/noise` | [`RateBatch`]: quantization-noise component, deg/h | `t0_ns` |
//! | `/gyro/estimates` | [`EstimateUpdate`]: noise coefficients with 95 % intervals and the data-quality findings, as `analyze --json` names them | `t_ns` |
//! | `/gyro/allan` | [`AllanUpdate`]: octave Allan curves with CIs | `t_ns` |
//! | `/gyro/events` | [`Event`]: gaps, resyncs, CRC errors, device changes, drops | `t_ns` |
//! | `/gyro/verdict` | [`VerdictUpdate`]: acceptance-test verdicts (`sagnac run --spec`) | `t_ns` |
//! | `/gyro/summary` | [`SummaryUpdate`]: 10 Hz scalars for plotting (mean raw and clean rate, temperature) | `timestamp` |
//!
//! Times are nanoseconds; the daemon uses nanoseconds since the Unix epoch (host
//! clock) so Foxglove shows wall time. `/gyro/summary` states its time as
//! Foxglove's `{sec, nsec}` (and its scalar fields are what Foxglove's Plot panel
//! can draw over time, which the 1000-value arrays of the sample channels are not).
//!
//! Rate values (`/gyro/clean`, `/gyro/noise`) are written with a fixed resolution
//! of [`RATE_RESOLUTION_DPH`] = 1e-3 deg/h (three decimals, `%.3f`), not as
//! shortest round-trip floats: the dropped digits were most of the bytes (and of
//! the compression work) of a recording, and they carry nothing physical. One
//! counter pulse at 1 kHz is about 1210 deg/h for the paper gyro, so the rounding
//! (at most 0.5e-3 deg/h) is 4e-7 of a pulse; the per-sample scatter of the clean
//! rate is tens of deg/h at 1 kHz (ARW 0.001 deg/rt(h) alone gives 1.9 deg/h), so
//! the rounding error is uniform and white, of standard deviation 2.9e-4 deg/h:
//! an extra angle random walk of 2.9e-4 * sqrt(tau0 / 1 s) / 60 deg/rt(h)
//! (1.5e-7 deg/rt(h) at 1 kHz, 1.5e-6 at 10 Hz), whose variance is below 1e-5 of
//! that of the best ring-laser gyros (ARW 1e-4 deg/rt(h)) at any sample rate
//! above 1 Hz. Replay and determinism rest on the integer counts of `/gyro/raw`,
//! which are exact. [`quantize_rate`] gives the value a recording reads back;
//! [`SinkMessage::recorded`] the whole message. Magnitudes of 2^51 * 1e-3 deg/h
//! (about 2.25e12 deg/h) and more are written exactly (shortest round-trip), as
//! are all other floats.
//!
//! JSON has no NaN or infinity: a message holding a non-finite number is refused
//! by [`SinkMessage::validate`] rather than silently recorded as `null`. Quantities that may be absent are `Option`s
//! (`null` in JSON).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::model::estimate::{Coefficient, NoiseEstimates};
use crate::model::spec::{CoefficientVerdict, SpecReport, Verdict};
use crate::quality::{DataQuality, Interval};
use crate::units;

mod json;
mod schema;

use json::{write_rate_batch, write_raw_batch, write_summary};
use schema::{
    allan_update_schema, estimate_update_schema, event_schema, rate_batch_schema, raw_batch_schema,
    summary_update_schema, verdict_update_schema,
};

/// Schema encoding written in the MCAP Schema records.
pub const SCHEMA_ENCODING: &str = "jsonschema";
/// Message encoding written in the MCAP Channel records.
pub const MESSAGE_ENCODING: &str = "json";

/// Errors of message validation: what cannot be recorded faithfully.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MessageError {
    /// A float is NaN or infinite (JSON cannot carry it).
    #[error("{topic}: field `{field}` holds a non-finite number ({value})")]
    NonFinite {
        topic: &'static str,
        field: String,
        value: f64,
    },
    /// Gap indices must be strictly increasing and within `0..=counts.len()`.
    #[error(
        "{topic}: gap #{gap} has index {index} (previous {previous:?}, {len} samples): gap indices must increase strictly and not exceed the sample count"
    )]
    BadGapIndex {
        topic: &'static str,
        gap: usize,
        index: u64,
        previous: Option<u64>,
        len: usize,
    },
    /// A gap must lose at least one sample.
    #[error("{topic}: gap #{gap} at index {index} loses 0 samples")]
    EmptyGap {
        topic: &'static str,
        gap: usize,
        index: u64,
    },
    /// A batch with samples needs a positive sample period.
    #[error("{topic}: dt_ns is 0 for a batch of {len} samples")]
    ZeroPeriod { topic: &'static str, len: usize },
    /// The columns of an Allan curve must have equal lengths.
    #[error(
        "{topic}: Allan curve `{curve}` has columns of unequal length (tau_s {tau}, dev {dev}, ci_lo {ci_lo}, ci_hi {ci_hi}, n {n})"
    )]
    RaggedCurve {
        topic: &'static str,
        curve: String,
        tau: usize,
        dev: usize,
        ci_lo: usize,
        ci_hi: usize,
        n: usize,
    },
    /// The payload does not decode as the message type of its topic.
    #[error("{topic}: payload is not a valid message: {reason}")]
    Decode { topic: &'static str, reason: String },
}

/// A gap inside a [`RawBatch`]: `lost` samples are missing just before `counts[index]`
/// (`index == counts.len()` means at the end of the batch).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gap {
    pub index: u64,
    pub lost: u64,
}

/// `/gyro/raw`: a batch of per-sample pulse increments as decoded from the device.
///
/// Sample `i` has sequence number `seq0 + i + (lost samples of gaps with index <= i)`
/// and time `t0_ns + (seq - seq0) * dt_ns`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBatch {
    /// Time of the first sample, ns.
    pub t0_ns: u64,
    /// Sample period, ns.
    pub dt_ns: u64,
    /// Device sequence number of the first sample.
    pub seq0: u64,
    /// Pulse increments, one per sample (signed: up/down counter).
    pub counts: Vec<i64>,
    /// Missing samples inside the batch.
    pub gaps: Vec<Gap>,
    /// Device temperature, deg C, when the frames carry one.
    pub temp_c: Option<f64>,
    /// Device status word of the last frame in the batch.
    pub status: u32,
}

/// `/gyro/clean` and `/gyro/noise`: a batch of rate values, deg/h, uniformly spaced.
///
/// Serialized with the values on the [`RATE_RESOLUTION_DPH`] grid ([`quantize_rate`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RateBatch {
    /// Time of the first value, ns.
    pub t0_ns: u64,
    /// Spacing of the values, ns.
    pub dt_ns: u64,
    /// Rates, deg/h (recorded to 1e-3 deg/h, see [`quantize_rate`]).
    #[serde(serialize_with = "serialize_rates")]
    pub values: Vec<f64>,
}

/// Resolution of the recorded rate values (`/gyro/clean`, `/gyro/noise`), deg/h.
pub const RATE_RESOLUTION_DPH: f64 = 1e-3;

/// Recorded rates are multiples of [`RATE_RESOLUTION_DPH`] below this magnitude,
/// deg/h (2^51 milli-deg/h: the rounding below is exact there).
pub const RATE_GRID_LIMIT_DPH: f64 = 2_251_799_813_685.248;

/// `v` rounded to a multiple of 1e-3 deg/h (ties to even on `v * 1e3`), as an
/// integer number of milli-deg/h; `None` for non-finite values and magnitudes of
/// [`RATE_GRID_LIMIT_DPH`] and more (written exactly).
#[inline]
pub(super) fn rate_milli(v: f64) -> Option<i64> {
    if v.abs() < RATE_GRID_LIMIT_DPH {
        // |x| < 2^51: adding and removing 1.5 * 2^52 rounds to an integer (ties to even)
        const MAGIC: f64 = 6_755_399_441_055_744.0;
        let x = v * 1e3;
        Some(((x + MAGIC) - MAGIC) as i64)
    } else {
        None
    }
}

/// The value a recording gives back for the rate `v` (deg/h): `v` rounded to
/// the [`RATE_RESOLUTION_DPH`] grid (error at most 0.5e-3 deg/h plus one rounding
/// of `v * 1e3`); non-finite values and magnitudes of about 2.25e12 deg/h and
/// more unchanged.
pub fn quantize_rate(v: f64) -> f64 {
    match rate_milli(v) {
        // |n| < 2^51: exact, and the division is correctly rounded, so this is the
        // f64 nearest to the decimal the recorder writes
        Some(n) => n as f64 / 1e3,
        None => v,
    }
}

fn serialize_rates<S: serde::Serializer>(values: &[f64], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(values.iter().map(|&v| quantize_rate(v)))
}

fn serialize_rate<S: serde::Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(quantize_rate(*v))
}

/// `/gyro/estimates`: one estimator update, with the fields of `sagnac analyze
/// --json` of the same name: `samples`, `duration_s` and `estimates` (the five
/// coefficients `quantization_arcsec`, `arw_dpsh`, `bias_instability_dph`,
/// `rrw_dphsh`, `rate_ramp_dphh`, each `{value, ci95: [lo, hi]}` or, when the data
/// do not resolve the term, `{value: null, upper95}`; units in the names,
/// [`units::COEFFICIENTS`]), and with the data-quality stage on, its findings
/// as `data_quality` (the fields of `analyze --json`'s `data_quality`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EstimateUpdate {
    /// Time of the update (time of the last sample used), ns.
    pub t_ns: u64,
    /// Samples used.
    pub samples: u64,
    /// Span of data used, s.
    pub duration_s: f64,
    /// The five coefficients.
    pub estimates: NoiseEstimates,
    /// What the data-quality stage found and did so far (absent with the raw
    /// statistics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_quality: Option<DataQuality>,
}

/// `dq` as recorded: JSON has no NaN or infinity, so a finding holding a
/// non-finite number is left out (an outlier time, a fit, the stationarity
/// test), and a non-finite excess kurtosis is `null`.
pub fn recordable_quality(dq: &DataQuality) -> DataQuality {
    let ok = |i: &Interval| i.value.is_finite() && i.ci95.iter().all(|v| v.is_finite());
    let mut out = dq.clone();
    out.outliers.at_s.retain(|t| t.is_finite());
    out.outliers.excess_kurtosis = dq.outliers.excess_kurtosis.filter(|k| k.is_finite());
    out.warmup = dq
        .warmup
        .clone()
        .filter(|w| ok(&w.amplitude_dph) && ok(&w.tau_s) && w.excluded_s.is_finite());
    out.steps.retain(|s| ok(&s.at_s) && ok(&s.amplitude_dph));
    out.thermal = dq
        .thermal
        .filter(|t| ok(&t.bias_sensitivity_dph_per_c) && ok(&t.lag_s));
    out.stationary = dq.stationary.clone().filter(|s| s.p_value.is_finite());
    out
}

impl EstimateUpdate {
    /// The coefficients by key, in the order of [`units::COEFFICIENTS`].
    pub fn coefficients(&self) -> [(&'static str, &Coefficient); 5] {
        let e = &self.estimates;
        [
            (units::COEFFICIENTS[0].0, &e.quantization_arcsec),
            (units::COEFFICIENTS[1].0, &e.arw_dpsh),
            (units::COEFFICIENTS[2].0, &e.bias_instability_dph),
            (units::COEFFICIENTS[3].0, &e.rrw_dphsh),
            (units::COEFFICIENTS[4].0, &e.rate_ramp_dphh),
        ]
    }
}

/// A time as Foxglove's messages state it: whole seconds and nanoseconds since
/// the Unix epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Timestamp {
    pub sec: u64,
    /// 0..=999_999_999.
    pub nsec: u32,
}

impl Timestamp {
    /// `t_ns` nanoseconds since the epoch.
    pub fn from_ns(t_ns: u64) -> Self {
        Timestamp {
            sec: t_ns / 1_000_000_000,
            nsec: (t_ns % 1_000_000_000) as u32,
        }
    }
    /// Nanoseconds since the epoch.
    pub fn ns(self) -> u64 {
        self.sec * 1_000_000_000 + u64::from(self.nsec)
    }
}

/// `/gyro/summary`: one window of [`SUMMARY_PERIOD_S`] (0.1 s) of samples as
/// scalars, for plots over time.
///
/// The window holds [`summary_window_samples`] consecutive sample periods
/// (gap-filled ones included), cut short at the start of a new time segment and
/// at the end of the run. The rates are means over the window's periods: the raw
/// rate of the gap-filled pulse increments (`pulses x pulse_arcsec x sample_rate_hz`,
/// what the pipeline sees) and the wavelet-cleaned rate of the same periods
/// (of the values before the rounding of `/gyro/clean`); both are recorded on
/// the same 1e-3 deg/h grid ([`quantize_rate`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SummaryUpdate {
    /// Time of the window's first sample.
    pub timestamp: Timestamp,
    /// Sample periods in the window (gap-filled ones included).
    pub samples: u64,
    /// Of those, periods whose sample was lost (gap-filled).
    pub lost_samples: u64,
    /// Mean raw rate, deg/h (recorded to 1e-3 deg/h).
    #[serde(serialize_with = "serialize_rate")]
    pub raw_rate_dph: f64,
    /// Mean wavelet-cleaned rate, deg/h (recorded to 1e-3 deg/h).
    #[serde(serialize_with = "serialize_rate")]
    pub clean_rate_dph: f64,
    /// Device temperature, deg C (the last one received in the window), when the frames carry one.
    pub temp_c: Option<f64>,
}

/// Nominal length of a `/gyro/summary` window, s (10 Hz).
pub const SUMMARY_PERIOD_S: f64 = 0.1;

/// Sample periods per `/gyro/summary` window at `sample_rate_hz`: `sample_rate_hz x 0.1`
/// rounded, at least 1 (exactly 10 Hz when `sample_rate_hz` is a multiple of 10).
pub fn summary_window_samples(sample_rate_hz: f64) -> u64 {
    (sample_rate_hz * SUMMARY_PERIOD_S).round().max(1.0) as u64
}

/// An octave Allan-deviation curve in columns of equal length.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AllanCurve {
    /// Averaging times, s.
    pub tau_s: Vec<f64>,
    /// Allan deviation, deg/h.
    pub dev: Vec<f64>,
    /// Lower end of the confidence interval of `dev`, deg/h.
    pub ci_lo: Vec<f64>,
    /// Upper end of the confidence interval of `dev`, deg/h.
    pub ci_hi: Vec<f64>,
    /// Number of terms averaged at each tau.
    pub n: Vec<u64>,
}

/// `/gyro/allan`: the Allan curves at one update.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AllanUpdate {
    /// Time of the update, ns.
    pub t_ns: u64,
    /// Channel (`raw`, `clean`) -> curve.
    pub curves: BTreeMap<String, AllanCurve>,
    /// The unit of each column of the curves, as `analyze --json` has it in
    /// its `units` map ([`AllanUpdate::column_units`]; absent in recordings
    /// made before it was written).
    #[serde(default)]
    pub units: BTreeMap<String, String>,
}

impl AllanUpdate {
    /// The curves at `t_ns`, with their columns' units.
    pub fn new(t_ns: u64, curves: BTreeMap<String, AllanCurve>) -> Self {
        AllanUpdate {
            t_ns,
            curves,
            units: Self::column_units(),
        }
    }

    /// `tau_s`: s; `dev`, `ci_lo`, `ci_hi`: deg/h; `n`: 1.
    pub fn column_units() -> BTreeMap<String, String> {
        [
            ("tau_s", "s"),
            ("dev", "deg/h"),
            ("ci_lo", "deg/h"),
            ("ci_hi", "deg/h"),
            ("n", "1"),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
    }
}

/// `/gyro/events`: something noteworthy happened at `t_ns`.
///
/// JSON: `{"t_ns": .., "kind": "<snake_case kind>", <fields of the kind>}`, and
/// `"gyro": "<label>"` in a recording of several gyros (whose events share
/// `/gyro/events`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Event {
    /// Time of the event, ns.
    pub t_ns: u64,
    #[serde(flatten)]
    pub kind: EventKind,
    /// The gyro it concerns, in a recording of several gyros.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro: Option<String>,
}

impl Event {
    /// An event of no particular gyro (or of the only one).
    pub fn new(t_ns: u64, kind: EventKind) -> Self {
        Event {
            t_ns,
            kind,
            gyro: None,
        }
    }
}

/// The kinds of [`Event`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum EventKind {
    /// `lost` samples are missing, starting at sequence number `seq`.
    Gap { seq: u64, lost: u64 },
    /// The frame decoder lost sync and found it again `skipped_bytes` later.
    Resync {
        byte_offset: u64,
        skipped_bytes: u64,
    },
    /// A frame at `byte_offset` failed its CRC.
    CrcError { byte_offset: u64 },
    /// The device status word changed.
    StatusChange { from: u32, to: u32 },
    /// The device went away.
    DeviceDisconnected { device: String, reason: String },
    /// The device is back.
    DeviceReconnected { device: String },
    /// `dropped` messages for `sink` were dropped because its queue was full.
    BackpressureDrop { sink: String, dropped: u64 },
}

/// `/gyro/verdict`: the acceptance test's verdicts after an estimator update
/// ([`crate::model::spec`]; the same fields as `spec` in `sagnac analyze --spec`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VerdictUpdate {
    /// Time of the update, ns.
    pub t_ns: u64,
    /// Overall verdict: fail if any coefficient fails, pass if all pass.
    pub verdict: Verdict,
    /// Guaranteed confidence of each verdict.
    pub confidence: f64,
    /// The look of the schedule the verdicts were last evaluated at (`null`: none yet).
    pub look: Option<u32>,
    /// Normal quantile of that look.
    pub z: f64,
    /// Record length at that look, s.
    pub duration_s: f64,
    /// Coefficient name -> verdict.
    pub coefficients: BTreeMap<String, CoefficientVerdict>,
}

impl VerdictUpdate {
    /// The message of `report` at `t_ns` (non-finite numbers dropped to `null`).
    pub fn new(t_ns: u64, report: &SpecReport) -> Self {
        let fin = |v: Option<f64>| v.filter(|x| x.is_finite());
        let coefficients = report
            .coefficients
            .iter()
            .map(|(k, c)| {
                let mut c = c.clone();
                (c.estimate, c.bound, c.lower, c.upper) =
                    (fin(c.estimate), fin(c.bound), fin(c.lower), fin(c.upper));
                (c.decided_at_s, c.eta_s) = (fin(c.decided_at_s), fin(c.eta_s));
                (k.clone(), c)
            })
            .collect();
        VerdictUpdate {
            t_ns,
            verdict: report.verdict,
            confidence: report.confidence,
            look: report.look,
            z: report.z,
            duration_s: report.duration_s,
            coefficients,
        }
    }
}

/// The channels of a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Topic {
    Raw,
    Clean,
    Noise,
    Estimates,
    Allan,
    Events,
    Verdict,
    Summary,
}

impl Topic {
    /// All topics, in channel-id order of a recording.
    pub const ALL: [Topic; 8] = [
        Topic::Raw,
        Topic::Clean,
        Topic::Noise,
        Topic::Estimates,
        Topic::Allan,
        Topic::Events,
        Topic::Verdict,
        Topic::Summary,
    ];

    /// The MCAP topic name.
    pub fn name(self) -> &'static str {
        match self {
            Topic::Raw => "/gyro/raw",
            Topic::Clean => "/gyro/clean",
            Topic::Noise => "/gyro/noise",
            Topic::Estimates => "/gyro/estimates",
            Topic::Allan => "/gyro/allan",
            Topic::Events => "/gyro/events",
            Topic::Verdict => "/gyro/verdict",
            Topic::Summary => "/gyro/summary",
        }
    }

    /// The topic with this MCAP name.
    pub fn from_name(name: &str) -> Option<Topic> {
        Topic::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The channel name of this topic for gyro `gyro` of a recording of
    /// several gyros (`/gyro/<label>/raw`, ...; events stay on the shared
    /// `/gyro/events` and name their gyro), or today's name with one gyro (`None`).
    pub fn name_for(self, gyro: Option<&str>) -> String {
        match gyro {
            Some(label) if self != Topic::Events => {
                format!("/gyro/{label}/{}", &self.name()["/gyro/".len()..])
            }
            _ => self.name().to_string(),
        }
    }

    /// The topic and gyro label of a channel name: `/gyro/raw` is `(Raw,
    /// None)`, `/gyro/x/raw` is `(Raw, Some("x"))`; `None` for a foreign channel.
    pub fn parse_channel(name: &str) -> Option<(Topic, Option<String>)> {
        if let Some(t) = Topic::from_name(name) {
            return Some((t, None));
        }
        let rest = name.strip_prefix("/gyro/")?;
        let (label, tail) = rest.split_once('/')?;
        let topic = Topic::from_name(&format!("/gyro/{tail}"))?;
        (topic != Topic::Events && valid_gyro_label(label))
            .then(|| (topic, Some(label.to_string())))
    }

    /// The MCAP schema name.
    pub fn schema_name(self) -> &'static str {
        match self {
            Topic::Raw => "sagnac.RawBatch",
            Topic::Clean | Topic::Noise => "sagnac.RateBatch",
            Topic::Estimates => "sagnac.EstimateUpdate",
            Topic::Allan => "sagnac.AllanUpdate",
            Topic::Events => "sagnac.Event",
            Topic::Verdict => "sagnac.VerdictUpdate",
            Topic::Summary => "sagnac.SummaryUpdate",
        }
    }

    /// The JSON Schema of the topic's messages.
    pub fn json_schema(self) -> Value {
        match self {
            Topic::Raw => raw_batch_schema(),
            Topic::Clean => rate_batch_schema("wavelet-cleaned rate"),
            Topic::Noise => rate_batch_schema("quantization-noise component of the rate"),
            Topic::Estimates => estimate_update_schema(),
            Topic::Allan => allan_update_schema(),
            Topic::Events => event_schema(),
            Topic::Verdict => verdict_update_schema(),
            Topic::Summary => summary_update_schema(),
        }
    }
}

/// Whether `label` can name a gyro: 1-32 ASCII letters, digits, `_` or `-`
/// (it becomes an MCAP topic segment and a Prometheus label value).
pub fn valid_gyro_label(label: &str) -> bool {
    (1..=32).contains(&label.len())
        && label
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// A message on one of the channels.
#[derive(Debug, Clone, PartialEq)]
pub enum SinkMessage {
    Raw(RawBatch),
    Clean(RateBatch),
    Noise(RateBatch),
    Estimates(EstimateUpdate),
    Allan(AllanUpdate),
    Event(Event),
    Verdict(VerdictUpdate),
    Summary(SummaryUpdate),
}

impl SinkMessage {
    /// A statistic of the data (estimates, an Allan curve), recomputable from the
    /// data channels: what a live source's full recorder queue may drop.
    pub fn is_statistic(&self) -> bool {
        matches!(self, SinkMessage::Estimates(_) | SinkMessage::Allan(_))
    }

    /// The channel the message goes to.
    pub fn topic(&self) -> Topic {
        match self {
            SinkMessage::Raw(_) => Topic::Raw,
            SinkMessage::Clean(_) => Topic::Clean,
            SinkMessage::Noise(_) => Topic::Noise,
            SinkMessage::Estimates(_) => Topic::Estimates,
            SinkMessage::Allan(_) => Topic::Allan,
            SinkMessage::Event(_) => Topic::Events,
            SinkMessage::Verdict(_) => Topic::Verdict,
            SinkMessage::Summary(_) => Topic::Summary,
        }
    }

    /// Sample time of the message, ns: its MCAP log time and publish time.
    pub fn time_ns(&self) -> u64 {
        match self {
            SinkMessage::Raw(m) => m.t0_ns,
            SinkMessage::Clean(m) | SinkMessage::Noise(m) => m.t0_ns,
            SinkMessage::Estimates(m) => m.t_ns,
            SinkMessage::Allan(m) => m.t_ns,
            SinkMessage::Event(m) => m.t_ns,
            SinkMessage::Verdict(m) => m.t_ns,
            SinkMessage::Summary(m) => m.timestamp.ns(),
        }
    }

    /// The message as a recording gives it back: rate values (`/gyro/clean`,
    /// `/gyro/noise`, the rates of `/gyro/summary`) on the 1e-3 deg/h grid
    /// ([`quantize_rate`]), all else unchanged.
    pub fn recorded(&self) -> SinkMessage {
        let q = |m: &RateBatch| RateBatch {
            t0_ns: m.t0_ns,
            dt_ns: m.dt_ns,
            values: m.values.iter().map(|&v| quantize_rate(v)).collect(),
        };
        match self {
            SinkMessage::Clean(m) => SinkMessage::Clean(q(m)),
            SinkMessage::Noise(m) => SinkMessage::Noise(q(m)),
            SinkMessage::Summary(m) => SinkMessage::Summary(SummaryUpdate {
                raw_rate_dph: quantize_rate(m.raw_rate_dph),
                clean_rate_dph: quantize_rate(m.clean_rate_dph),
                ..m.clone()
            }),
            other => other.clone(),
        }
    }

    /// JSON payload (after [`SinkMessage::validate`], this decodes to
    /// [`SinkMessage::recorded`]: exact except for the 1e-3 deg/h rate grid).
    pub fn to_json(&self) -> Result<Vec<u8>, serde_json::Error> {
        match self {
            SinkMessage::Raw(m) => serde_json::to_vec(m),
            SinkMessage::Clean(m) | SinkMessage::Noise(m) => serde_json::to_vec(m),
            SinkMessage::Estimates(m) => serde_json::to_vec(m),
            SinkMessage::Allan(m) => serde_json::to_vec(m),
            SinkMessage::Event(m) => serde_json::to_vec(m),
            SinkMessage::Verdict(m) => serde_json::to_vec(m),
            SinkMessage::Summary(m) => serde_json::to_vec(m),
        }
    }

    /// JSON payload written into `out` (cleared first): the same JSON value as
    /// [`SinkMessage::to_json`] (byte for byte except that rate values are written
    /// with three fixed decimals, `1.500` where serde_json writes `1.5`). The
    /// sample batches (`/gyro/raw`, `/gyro/clean`, `/gyro/noise`: nearly all the
    /// bytes of a recording) are formatted directly into the recorder's reused
    /// buffer: counts with serde_json's integer formatter, rates in fixed point.
    pub fn write_json(&self, out: &mut Vec<u8>) -> Result<(), serde_json::Error> {
        out.clear();
        match self {
            SinkMessage::Raw(m) => write_raw_batch(m, out),
            SinkMessage::Clean(m) | SinkMessage::Noise(m) => write_rate_batch(m, out),
            SinkMessage::Estimates(m) => serde_json::to_writer(&mut *out, m)?,
            SinkMessage::Allan(m) => serde_json::to_writer(&mut *out, m)?,
            SinkMessage::Event(m) => serde_json::to_writer(&mut *out, m)?,
            SinkMessage::Verdict(m) => serde_json::to_writer(&mut *out, m)?,
            SinkMessage::Summary(m) => write_summary(m, out),
        }
        Ok(())
    }

    /// Decode a JSON payload of `topic`, and validate it.
    pub fn from_json(topic: Topic, payload: &[u8]) -> Result<SinkMessage, MessageError> {
        let decode_err = |e: serde_json::Error| MessageError::Decode {
            topic: topic.name(),
            reason: e.to_string(),
        };
        let msg = match topic {
            Topic::Raw => SinkMessage::Raw(serde_json::from_slice(payload).map_err(decode_err)?),
            Topic::Clean => {
                SinkMessage::Clean(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Noise => {
                SinkMessage::Noise(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Estimates => {
                SinkMessage::Estimates(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Allan => {
                SinkMessage::Allan(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Events => {
                SinkMessage::Event(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Verdict => {
                SinkMessage::Verdict(serde_json::from_slice(payload).map_err(decode_err)?)
            }
            Topic::Summary => {
                SinkMessage::Summary(serde_json::from_slice(payload).map_err(decode_err)?)
            }
        };
        msg.validate()?;
        Ok(msg)
    }

    /// Check that the message can be recorded faithfully: finite floats, ordered
    /// gaps, equal-length Allan columns, a sample period for non-empty batches.
    pub fn validate(&self) -> Result<(), MessageError> {
        let topic = self.topic().name();
        match self {
            SinkMessage::Raw(m) => {
                if m.dt_ns == 0 && !m.counts.is_empty() {
                    return Err(MessageError::ZeroPeriod {
                        topic,
                        len: m.counts.len(),
                    });
                }
                finite_opt(topic, "temp_c", m.temp_c)?;
                let mut previous: Option<u64> = None;
                for (gap, g) in m.gaps.iter().enumerate() {
                    let in_order = previous.is_none_or(|p| g.index > p);
                    if !in_order || g.index > m.counts.len() as u64 {
                        return Err(MessageError::BadGapIndex {
                            topic,
                            gap,
                            index: g.index,
                            previous,
                            len: m.counts.len(),
                        });
                    }
                    if g.lost == 0 {
                        return Err(MessageError::EmptyGap {
                            topic,
                            gap,
                            index: g.index,
                        });
                    }
                    previous = Some(g.index);
                }
                Ok(())
            }
            SinkMessage::Clean(m) | SinkMessage::Noise(m) => {
                if m.dt_ns == 0 && !m.values.is_empty() {
                    return Err(MessageError::ZeroPeriod {
                        topic,
                        len: m.values.len(),
                    });
                }
                finite_slice(topic, "values", &m.values)
            }
            SinkMessage::Estimates(m) => {
                finite(topic, "duration_s", m.duration_s)?;
                for (name, c) in m.coefficients() {
                    finite_opt(topic, &format!("estimates.{name}.value"), c.value)?;
                    if let Some(ci) = c.ci95 {
                        finite_slice(topic, &format!("estimates.{name}.ci95"), &ci)?;
                    }
                    finite_opt(topic, &format!("estimates.{name}.upper95"), c.upper95)?;
                }
                match &m.data_quality {
                    Some(dq) => finite_quality(topic, dq),
                    None => Ok(()),
                }
            }
            SinkMessage::Summary(m) => {
                if m.timestamp.nsec >= 1_000_000_000 {
                    return Err(MessageError::Decode {
                        topic,
                        reason: format!("timestamp.nsec = {} is not below 1e9", m.timestamp.nsec),
                    });
                }
                finite(topic, "raw_rate_dph", m.raw_rate_dph)?;
                finite(topic, "clean_rate_dph", m.clean_rate_dph)?;
                finite_opt(topic, "temp_c", m.temp_c)
            }
            SinkMessage::Allan(m) => {
                for (name, c) in &m.curves {
                    let len = c.tau_s.len();
                    if [c.dev.len(), c.ci_lo.len(), c.ci_hi.len(), c.n.len()]
                        .iter()
                        .any(|&l| l != len)
                    {
                        return Err(MessageError::RaggedCurve {
                            topic,
                            curve: name.clone(),
                            tau: len,
                            dev: c.dev.len(),
                            ci_lo: c.ci_lo.len(),
                            ci_hi: c.ci_hi.len(),
                            n: c.n.len(),
                        });
                    }
                    finite_slice(topic, &format!("curves.{name}.tau_s"), &c.tau_s)?;
                    finite_slice(topic, &format!("curves.{name}.dev"), &c.dev)?;
                    finite_slice(topic, &format!("curves.{name}.ci_lo"), &c.ci_lo)?;
                    finite_slice(topic, &format!("curves.{name}.ci_hi"), &c.ci_hi)?;
                }
                Ok(())
            }
            SinkMessage::Event(_) => Ok(()),
            SinkMessage::Verdict(m) => {
                finite(topic, "confidence", m.confidence)?;
                finite(topic, "z", m.z)?;
                finite(topic, "duration_s", m.duration_s)?;
                for (name, c) in &m.coefficients {
                    finite(topic, &format!("coefficients.{name}.limit"), c.limit)?;
                    for (field, v) in [
                        ("estimate", c.estimate),
                        ("bound", c.bound),
                        ("lower", c.lower),
                        ("upper", c.upper),
                        ("decided_at_s", c.decided_at_s),
                        ("eta_s", c.eta_s),
                    ] {
                        finite_opt(topic, &format!("coefficients.{name}.{field}"), v)?;
                    }
                }
                Ok(())
            }
        }
    }
}

fn finite(topic: &'static str, field: &str, value: f64) -> Result<(), MessageError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(MessageError::NonFinite {
            topic,
            field: field.to_string(),
            value,
        })
    }
}

fn finite_opt(topic: &'static str, field: &str, value: Option<f64>) -> Result<(), MessageError> {
    value.map_or(Ok(()), |v| finite(topic, field, v))
}

/// Every number of a `data_quality` finite.
fn finite_quality(topic: &'static str, dq: &DataQuality) -> Result<(), MessageError> {
    let interval = |field: &str, i: &Interval| {
        finite(topic, &format!("data_quality.{field}.value"), i.value)?;
        finite_slice(topic, &format!("data_quality.{field}.ci95"), &i.ci95)
    };
    let o = &dq.outliers;
    finite_slice(topic, "data_quality.outliers.at_s", &o.at_s)?;
    finite(
        topic,
        "data_quality.outliers.threshold_sigma",
        o.threshold_sigma,
    )?;
    finite_opt(
        topic,
        "data_quality.outliers.excess_kurtosis",
        o.excess_kurtosis,
    )?;
    if let Some(w) = &dq.warmup {
        interval("warmup.amplitude_dph", &w.amplitude_dph)?;
        interval("warmup.tau_s", &w.tau_s)?;
        finite(topic, "data_quality.warmup.excluded_s", w.excluded_s)?;
    }
    for (k, s) in dq.steps.iter().enumerate() {
        interval(&format!("steps[{k}].at_s"), &s.at_s)?;
        interval(&format!("steps[{k}].amplitude_dph"), &s.amplitude_dph)?;
    }
    if let Some(t) = &dq.thermal {
        interval(
            "thermal.bias_sensitivity_dph_per_c",
            &t.bias_sensitivity_dph_per_c,
        )?;
        interval("thermal.lag_s", &t.lag_s)?;
    }
    if let Some(s) = &dq.stationary {
        finite(topic, "data_quality.stationary.p_value", s.p_value)?;
    }
    Ok(())
}

fn finite_slice(topic: &'static str, field: &str, values: &[f64]) -> Result<(), MessageError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => finite(topic, &format!("{field}[{i}]"), values[i]),
    }
}
