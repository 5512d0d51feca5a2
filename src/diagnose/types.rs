//! The vocabulary every phase of the diagnosis shares: the recording
//! diagnosed ([`Recording`]), the options and thresholds, the errors, the
//! telegraph test's result, and the changes a finding makes to the model
//! ([`ParameterChange`], [`AddedTerm`], as the JSON reports them). [`super::diagnose`] orchestrates the phases
//! over these; the phases import them from here.

use crate::model::ModelError;
use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::model::config::OutputKind;

/// A recording to diagnose: integer increments (and optionally a temperature
/// per sample) with the readout's sample rate and the angle of one increment.
///
/// A pulse counter's recording (`output` = counts) holds its pulse
/// increments and pulse weight. A rate-output gyro's recording (`output` =
/// rate, [`Recording::from_rates`]) holds its rate words as integers: sample
/// `k`'s rate is `counts[k]` quanta, and one quantum held for one sample
/// period is the angle `pulse_arcsec` (= quantum in arcsec/s x tau0). Every
/// statistic of the diagnosis is computed on the rate `counts[k] x
/// pulse_arcsec / tau0`, so both kinds go through the same code; what
/// differs is the physics the reference simulates (a counter, or a rate
/// word with its LSB rounding and readout filter).
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    pub counts: Vec<i64>,
    /// Samples made up to fill gaps (indices into `counts`, sorted, disjoint).
    pub filled: Vec<std::ops::Range<usize>>,
    pub temp_c: Option<Vec<f64>>,
    pub sample_rate_hz: f64,
    pub pulse_arcsec: f64,
    /// What the sensor output: pulse counts or rate words.
    pub output: OutputKind,
}

/// Largest rate word a rate recording may hold, in its quantum (2^52: exact in f64).
const MAX_RATE_WORD: f64 = 4.5e15;

impl Recording {
    /// A rate-output recording from rates in deg/s sampled at `sample_rate_hz`.
    ///
    /// When every rate is a multiple of `rate_lsb_dps` (> 0; within 1e-3 of
    /// an LSB, which absorbs decimal printing) the words are exactly the LSB
    /// counts. Otherwise (no LSB, or rates off its grid) they are counted in
    /// a quantum 1e-4 of the rate's sample-to-sample spread (or of the LSB),
    /// whose rounding adds a white noise 1e-8 of the recording's own.
    pub fn from_rates(
        rates_dps: &[f64],
        temp_c: Option<Vec<f64>>,
        sample_rate_hz: f64,
        rate_lsb_dps: f64,
    ) -> Result<Recording, DiagnoseError> {
        if let Some(i) = rates_dps.iter().position(|v| !v.is_finite()) {
            return Err(DiagnoseError::RateNonFinite {
                index: i,
                value: rates_dps[i],
            });
        }
        let on_grid = |q: f64| {
            rates_dps
                .iter()
                .all(|v| ((v / q) - (v / q).round()).abs() < 1e-3)
        };
        let quantum_dps = if rate_lsb_dps > 0.0 && on_grid(rate_lsb_dps) {
            rate_lsb_dps
        } else {
            let n = rates_dps.len().max(2);
            let diff2 = rates_dps
                .windows(2)
                .map(|w| (w[1] - w[0]).powi(2))
                .sum::<f64>()
                / (n - 1) as f64;
            let spread = diff2.sqrt().max(rate_lsb_dps);
            if !(spread > 0.0) {
                return Err(DiagnoseError::RateConstant { n: rates_dps.len() });
            }
            1e-4 * spread
        };
        let peak = rates_dps.iter().fold(0.0f64, |a, v| a.max(v.abs())) / quantum_dps;
        if peak > MAX_RATE_WORD {
            return Err(DiagnoseError::RateRange {
                peak_dps: peak * quantum_dps,
                quantum_dps,
            });
        }
        Ok(Recording {
            counts: rates_dps
                .iter()
                .map(|v| (v / quantum_dps).round() as i64)
                .collect(),
            filled: Vec::new(),
            temp_c,
            sample_rate_hz,
            pulse_arcsec: quantum_dps * crate::units::ARCSEC_PER_DEG / sample_rate_hz,
            output: OutputKind::Rate,
        })
    }

    /// The rate word's quantum, deg/s (rate recordings).
    pub fn rate_quantum_dps(&self) -> f64 {
        self.pulse_arcsec * self.sample_rate_hz / crate::units::ARCSEC_PER_DEG
    }
}

/// Tuning of the diagnosis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagnoseOptions {
    /// Monte-Carlo runs of the model (the bands).
    pub runs: usize,
    /// Monte-Carlo runs of the updated model (the "after" fit and the
    /// random-telegraph test).
    pub runs_after: usize,
    /// Base seed of the Monte-Carlo runs.
    pub seed: u64,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Family-wise false-alarm probability of the broadband test.
    pub alpha: f64,
    /// Run the data-quality stage first (phase 0); off: `--raw-statistics`.
    pub data_quality: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            runs: 16,
            runs_after: 8,
            seed: 0x5A6_AC00,
            threads: 0,
            alpha: 0.01,
            data_quality: true,
        }
    }
}

/// Family-wise false-alarm probability of the spectral line search.
pub const ALPHA_LINES: f64 = 0.001;
/// Two-sided false-alarm probability of each slope test (ramp, temperature).
pub const ALPHA_SLOPE: f64 = 0.0025;
/// Smallest recording, samples.
pub const MIN_SAMPLES: usize = 4096;
/// Most resonances fitted, one after another where an excess remains.
pub const MAX_RESONANCES: usize = 3;

/// Errors of the diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error("the recording has {n} samples; the diagnosis needs at least {need}")]
    TooShort { n: usize, need: usize },
    #[error("recording sample rate {0} Hz: must be finite and > 0")]
    BadRate(f64),
    #[error("recording pulse weight {0} arcsec: must be finite and > 0")]
    BadPulse(f64),
    #[error("the temperature channel has {got} values for {n} samples")]
    TempLength { got: usize, n: usize },
    #[error("temperature at sample {index} is not finite ({value})")]
    TempNonFinite { index: usize, value: f64 },
    #[error("rate sample {index} is not finite ({value})")]
    RateNonFinite { index: usize, value: f64 },
    #[error(
        "all {n} rate samples are equal: no noise to compare with the model (a dead gyro or a stuck output?)"
    )]
    RateConstant { n: usize },
    #[error("rates up to {peak_dps} deg/s are too large to count in quanta of {quantum_dps} deg/s")]
    RateRange { peak_dps: f64, quantum_dps: f64 },
    #[error(
        "the model's [gyro] output = \"{model}\" but the recording holds {}: a rate-output model needs a \
         rate recording (CSV --column NAME --unit dps|dph|rad_s) and a counts model a recording of pulse counts",
        if *recording == OutputKind::Rate { "rate samples" } else { "pulse counts" }
    )]
    OutputMismatch {
        model: &'static str,
        recording: OutputKind,
    },
    #[error("options: {0}")]
    Options(String),
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// The random-telegraph versus Gauss-Markov distribution test.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TelegraphTest {
    /// Block length of the two-level likelihood ratio, s.
    pub block_s: f64,
    /// The recording's two-level log likelihood ratio.
    pub observed: f64,
    /// Mean and sd over the Gauss-Markov model's runs.
    pub gauss_markov: (f64, f64),
    /// Mean and sd over the random-telegraph model's runs.
    pub telegraph: (f64, f64),
    /// Chose the random telegraph.
    pub telegraph_chosen: bool,
}

/// Check the recording and the options.
pub(super) fn check_recording(
    rec: &Recording,
    opts: &DiagnoseOptions,
) -> Result<(), DiagnoseError> {
    let n = rec.counts.len();
    if n < MIN_SAMPLES {
        return Err(DiagnoseError::TooShort {
            n,
            need: MIN_SAMPLES,
        });
    }
    if !(rec.sample_rate_hz.is_finite() && rec.sample_rate_hz > 0.0) {
        return Err(DiagnoseError::BadRate(rec.sample_rate_hz));
    }
    if !(rec.pulse_arcsec.is_finite() && rec.pulse_arcsec > 0.0) {
        return Err(DiagnoseError::BadPulse(rec.pulse_arcsec));
    }
    if let Some(t) = &rec.temp_c {
        if t.len() != n {
            return Err(DiagnoseError::TempLength { got: t.len(), n });
        }
        if let Some(i) = t.iter().position(|v| !v.is_finite()) {
            return Err(DiagnoseError::TempNonFinite {
                index: i,
                value: t[i],
            });
        }
    }
    if opts.runs < 4 || opts.runs_after < 2 {
        return Err(DiagnoseError::Options(format!(
            "runs = {} and runs_after = {}: need at least 4 and 2 Monte-Carlo runs",
            opts.runs, opts.runs_after
        )));
    }
    if !(opts.alpha > 0.0 && opts.alpha < 0.5) {
        return Err(DiagnoseError::Options(format!(
            "alpha = {}: must be in (0, 0.5)",
            opts.alpha
        )));
    }
    Ok(())
}

/// A changed parameter of a term the model already has (JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterChange {
    /// Model-file key (`arw_dpsh`, `gauss_markov[0].tau_c_s`, ...).
    pub term: String,
    pub model: f64,
    pub fitted: f64,
    pub ci95: [f64; 2],
}

/// A term the model lacks (JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "AddedTermJson", try_from = "AddedTermJson")]
pub struct AddedTerm {
    /// Model-file key (`gauss_markov`, `sinusoid`, `random_telegraph`, `rrw_dphsh`, ...).
    pub term: String,
    /// Model-file parameter names and fitted values.
    pub params: BTreeMap<String, f64>,
    /// The term's kind when it has several (`readout_filter`: `moving_average`
    /// or `first_order`); in the JSON it is `params.kind`.
    pub kind: Option<String>,
    pub explanation: String,
    /// 95 % intervals of the parameters (same names as `params`).
    pub ci95: BTreeMap<String, [f64; 2]>,
}

/// [`AddedTerm`] as written: the kind among the parameters.
#[derive(Serialize, Deserialize)]
struct AddedTermJson {
    term: String,
    params: BTreeMap<String, serde_json::Value>,
    explanation: String,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    ci95: BTreeMap<String, [f64; 2]>,
}

impl From<AddedTerm> for AddedTermJson {
    fn from(a: AddedTerm) -> Self {
        let mut params: BTreeMap<String, serde_json::Value> = a
            .params
            .into_iter()
            .map(|(k, v)| (k, serde_json::Value::from(v)))
            .collect();
        if let Some(kind) = a.kind {
            params.insert("kind".into(), serde_json::Value::String(kind));
        }
        AddedTermJson {
            term: a.term,
            params,
            explanation: a.explanation,
            ci95: a.ci95,
        }
    }
}

impl TryFrom<AddedTermJson> for AddedTerm {
    type Error = String;
    fn try_from(j: AddedTermJson) -> Result<Self, String> {
        let mut params = BTreeMap::new();
        let mut kind = None;
        for (k, v) in j.params {
            match (k.as_str(), v) {
                ("kind", serde_json::Value::String(s)) => kind = Some(s),
                (_, v) => {
                    let x = v.as_f64().ok_or_else(|| {
                        format!("added term {}: params.{k} is not a number", j.term)
                    })?;
                    params.insert(k, x);
                }
            }
        }
        Ok(AddedTerm {
            term: j.term,
            params,
            kind,
            explanation: j.explanation,
            ci95: j.ci95,
        })
    }
}
