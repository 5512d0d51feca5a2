//! The gyro model file (TOML): what the simulator runs and what the diagnosis
//! compares a recording with (and writes back, updated, after estimation).
//!
//! ```toml
//! [gyro]
//! sample_rate_hz = 1000.0
//! pulse_arcsec = 1.21             # angle per counter pulse, d
//! input_rate_dph = 12.3           # constant input (e.g. Earth rate on the axis); default 0
//! # output = "rate"               # "counts" (RLG pulse counter, the default) or "rate" (FOG/MEMS)
//! # rate_lsb_dps = 0.0005         # rate output: rate-word quantum, deg/s (absent or 0: unquantised);
//! #                               # then pulse_arcsec is left out
//!
//! [noise]                         # IEEE 952 coefficients; an absent key = the term is absent
//! quantization_arcsec = 0.35      # total white-angle Q seen by the Allan variance (>= d/sqrt(12))
//! arw_dpsh = 0.001                # angle random walk N
//! bias_instability_dph = 0.002    # flicker B (1/f from bias_instability_f_lo_hz upward)
//! bias_instability_f_lo_hz = 1e-7 # optional low edge of the flicker band (default 1e-7 Hz)
//! rrw_dphsh = 0.0                 # rate random walk K
//! rate_ramp_dphh = 0.0            # rate ramp R (sign allowed)
//!
//! [[noise.gauss_markov]]          # catalog terms, each repeatable
//! sigma_dph = 0.008
//! tau_c_s = 90.0
//! [[noise.sinusoid]]
//! amplitude_dph = 0.004
//! period_s = 600.0
//! [[noise.random_telegraph]]      # bias flips between +a and -a (mode hops)
//! amplitude_dph = 0.003
//! mean_dwell_s = 300.0
//!
//! [noise.warmup]                  # bias settling after switch-on: amplitude_dph exp(-t/tau_s)
//! amplitude_dph = 0.05            # offset at t = 0 from the settled bias (negative: rising bias)
//! tau_s = 900.0                   # time constant
//! [[noise.bias_step]]             # repeatable: the bias jumps by amplitude_dph at at_s and stays
//! at_s = 1800.0
//! amplitude_dph = 0.01
//! [noise.spikes]                  # single-sample readout glitches, Poisson in time
//! rate_per_h = 2.0                # mean number per hour
//! amplitude_dph = 5.0             # random sign, magnitude uniform in [0.1, 1] x amplitude_dph
//!
//! [thermal]                       # optional; present = the simulator emits a temp_c channel
//! temp_c0 = 25.0                  # temperature at t = 0
//! ramp_c_per_h = 0.5              # linear trend (default 0)
//! sine_amplitude_c = 0.2          # periodic part (default 0) ...
//! sine_period_s = 3600.0          # ... with this period (required when the amplitude > 0)
//! bias_sensitivity_dph_per_c = 0.001   # rate bias per degree away from temp_c0 (default 0)
//! lag_s = 120.0                   # the bias follows the temperature this much later (default 0)
//! ```
//!
//! ```toml
//! [readout_filter]                # optional: what the electronics do to the rate before output
//! kind = "moving_average"         # or "first_order"
//! length = 5                      # samples (moving_average)
//! # corner_hz = 30.0              # -3 dB frequency, Hz (first_order)
//! ```
//!
//! Rate output: the sensor outputs the (filtered) rate, rounded to a multiple of
//! `rate_lsb_dps`; that rounding is white *rate* noise of variance `lsb^2 / 12`
//! per sample (not the angle QN of a counter). A `quantization_arcsec` on a rate
//! gyro is a white angle error (as seen through the rate's first difference).
//!
//! Quantization: the counter alone gives a white angle error of `d/sqrt(12)`; a
//! `quantization_arcsec` above that is reached by adding a white Gaussian angle
//! error (the dither residual) of `sqrt(Q^2 - d^2/12)` before the counter. A value
//! below `d/sqrt(12)` is an error. Note that the counter's error is white only
//! when the angle's sub-pulse phase is randomised between samples (see
//! [`super::terms::counter_readout_avar`]).
//!
//! Thermal: `T(t) = temp_c0 + ramp_c_per_h t/3600 + sine_amplitude_c sin(2 pi t/sine_period_s)`
//! and the rate bias is `bias_sensitivity_dph_per_c (T(t - lag_s) - temp_c0)` (the
//! gyro's bias follows the chamber with a pure delay; `T` is analytic, so also
//! defined before the record starts); in Allan terms this is a rate ramp
//! `s * ramp` (deg/h/h) plus a sinusoid of amplitude `s * A`, whatever the lag.
//! The temperature recorded beside the output (the `temp_c` column) is `T(t)`.
//!
//! Transients and glitches (left out of [`GyroModel::terms`]: not stationary
//! noise): the warm-up adds `amplitude_dph exp(-t / tau_s)` to the rate, each
//! bias step `amplitude_dph` from `at_s` on (a step inside a sample period
//! counts for the fraction of the period after it). A spike disturbs one
//! sample's readout, not the true rate (so no readout filter acts on it): a
//! rate word is off by the spike `s` (deg/h); a pulse counter's reading is off
//! by the angle `s tau0` for that one sample, so its increments carry `+x`
//! then `-x`. Spikes arrive as a Poisson process of `rate_per_h` per hour
//! (each in the sample period where it falls), with a random sign and a
//! magnitude uniform in `[0.1, 1] amplitude_dph`.
//!
//! Unknown keys are errors naming the key and line (`deny_unknown_fields` on every
//! table); [`GyroModel::validate`] names the key and the value of any out-of-range
//! entry. [`GyroModel::to_toml`] writes the model back.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::ModelError;
use super::filter::{ReadoutFilter, ReadoutFilterParams};
use super::terms::{DEFAULT_FLICKER_F_LO_HZ, Term};
use crate::units;

/// A complete gyro model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroModel {
    pub gyro: GyroParams,
    #[serde(default)]
    pub noise: NoiseParams,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<ThermalParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub readout_filter: Option<ReadoutFilterParams>,
}

/// What the sensor outputs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OutputKind {
    /// An RLG's cumulative up/down pulse counter: one integer increment per sample.
    #[default]
    Counts,
    /// A rate word (FOG, MEMS): one rate per sample, deg/s, quantised to `rate_lsb_dps`.
    Rate,
}

impl OutputKind {
    pub fn name(&self) -> &'static str {
        match self {
            OutputKind::Counts => "counts",
            OutputKind::Rate => "rate",
        }
    }
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_counts(v: &OutputKind) -> bool {
    *v == OutputKind::Counts
}

/// The readout: sample rate, pulse weight and the constant input rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroParams {
    pub sample_rate_hz: f64,
    /// What the sensor outputs (default: counts).
    #[serde(default, skip_serializing_if = "is_counts")]
    pub output: OutputKind,
    /// Angle per counter pulse, arcsec (counts output only; required there).
    #[serde(default, skip_serializing_if = "is_zero")]
    #[serde(alias = "pulse_weight_arcsec")]
    pub pulse_arcsec: f64,
    /// Rate-word quantum, deg/s (rate output only); 0 or absent = unquantised.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rate_lsb_dps: f64,
    #[serde(default)]
    pub input_rate_dph: f64,
}

/// IEEE 952 coefficients and the catalog terms. `None` / empty = absent.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseParams {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantization_arcsec: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arw_dpsh: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_instability_dph: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_instability_f_lo_hz: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rrw_dphsh: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_ramp_dphh: Option<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub gauss_markov: Vec<GaussMarkovParams>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sinusoid: Vec<SinusoidParams>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub random_telegraph: Vec<RandomTelegraphParams>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub resonance: Vec<ResonanceParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warmup: Option<WarmupParams>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bias_step: Vec<BiasStepParams>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spikes: Option<SpikesParams>,
}

/// A first-order Gauss-Markov bias.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaussMarkovParams {
    pub sigma_dph: f64,
    pub tau_c_s: f64,
}

/// A sinusoidal bias (random phase in the simulator).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SinusoidParams {
    pub amplitude_dph: f64,
    pub period_s: f64,
}

/// A random telegraph bias flipping between +a and -a.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomTelegraphParams {
    pub amplitude_dph: f64,
    pub mean_dwell_s: f64,
}

/// A resonance: narrowband rate noise of standard deviation `sigma_dph`
/// centred at `centre_hz`, `width_hz` wide at half power (see
/// [`crate::model::resonance`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResonanceParams {
    pub sigma_dph: f64,
    pub centre_hz: f64,
    pub width_hz: f64,
}

/// The bias's settling after switch-on: a rate offset
/// `amplitude_dph * exp(-t / tau_s)` at time `t` since the start of the record
/// (a negative amplitude: the bias rises while it settles).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WarmupParams {
    pub amplitude_dph: f64,
    pub tau_s: f64,
}

/// A bias step: the bias jumps by `amplitude_dph` at time `at_s` and stays.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BiasStepParams {
    pub at_s: f64,
    pub amplitude_dph: f64,
}

/// Single-sample glitches of the readout arriving as a Poisson process at
/// `rate_per_h` per hour; each has a random sign and a magnitude drawn
/// uniformly in `[0.1, 1] * amplitude_dph`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpikesParams {
    pub rate_per_h: f64,
    pub amplitude_dph: f64,
}

/// A slow temperature profile and the bias it causes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalParams {
    pub temp_c0: f64,
    #[serde(default)]
    pub ramp_c_per_h: f64,
    #[serde(default)]
    pub sine_amplitude_c: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sine_period_s: Option<f64>,
    #[serde(default)]
    pub bias_sensitivity_dph_per_c: f64,
    /// Delay of the bias behind the chamber temperature, s (default 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lag_s: f64,
}

fn byte_to_line_col(text: &str, byte: usize) -> (usize, usize) {
    let byte = byte.min(text.len());
    let before = &text.as_bytes()[..byte];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let col = before.iter().rev().take_while(|&&b| b != b'\n').count() + 1;
    (line, col)
}

/// Highest sample rate a model may have, Hz.
pub const MAX_SAMPLE_RATE_HZ: f64 = 1e7;
/// Largest pulse weight, arcsec (one turn).
pub const MAX_PULSE_WEIGHT_ARCSEC: f64 = 1_296_000.0;
/// Largest input rate, deg/h (1e9 deg/h is about 77 000 turns per second).
pub const MAX_RATE_DPH: f64 = 1e9;
/// Shortest telegraph mean dwell, in sample periods.
pub const MIN_DWELL_PER_SAMPLE: f64 = 0.01;

/// A value for an error message: tiny and huge values in exponent form, not 300 digits.
fn show(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

fn finite(key: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ModelError::invalid(key, show(v), "must be finite"))
    }
}

fn nonneg(key: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::invalid(key, show(v), "must be finite and >= 0"))
    }
}

fn positive(key: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ModelError::invalid(key, show(v), "must be finite and > 0"))
    }
}

fn within(key: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), ModelError> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(ModelError::invalid(
            key,
            show(v),
            format!("must be in [{lo:e}, {hi:e}] {unit}"),
        ))
    }
}

impl GyroModel {
    /// Parse and validate a model from TOML text; `origin` names the source in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, ModelError> {
        let model: GyroModel = toml::from_str(text).map_err(|e| {
            let (line, column) = e
                .span()
                .map(|s| byte_to_line_col(text, s.start))
                .unwrap_or((0, 0));
            ModelError::Parse {
                origin: origin.to_string(),
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })?;
        model.validate().map_err(|e| e.with_origin(origin))?;
        Ok(model)
    }

    /// Read, parse and validate a model file.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// The model as TOML text (parses back to an equal model).
    pub fn to_toml(&self) -> Result<String, ModelError> {
        toml::to_string(self).map_err(|e| ModelError::Serialize(e.to_string()))
    }

    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        1.0 / self.gyro.sample_rate_hz
    }

    /// The white-angle error of the counter alone, `d / sqrt(12)`, arcsec.
    pub fn counter_q_arcsec(&self) -> f64 {
        self.gyro.pulse_arcsec / 12f64.sqrt()
    }

    /// Total quantization coefficient Q (arcsec): the configured value, or
    /// `d/sqrt(12)` when absent.
    pub fn quantization_q_arcsec(&self) -> f64 {
        self.noise
            .quantization_arcsec
            .unwrap_or_else(|| self.counter_q_arcsec())
    }

    /// Standard deviation of the white dither residual added before the counter,
    /// `sqrt(Q^2 - d^2/12)` (0 when Q is absent or equal to `d/sqrt(12)`), arcsec.
    pub fn dither_sigma_arcsec(&self) -> f64 {
        let q = self.quantization_q_arcsec();
        let c = self.counter_q_arcsec();
        (q * q - c * c).max(0.0).sqrt()
    }

    /// The readout filter, when the model has one (validated by [`GyroModel::validate`]).
    pub fn readout_filter(&self) -> Option<ReadoutFilter> {
        self.readout_filter
            .as_ref()
            .and_then(|f| f.filter(self.tau0_s()).ok())
    }

    /// Low edge of the flicker band, Hz.
    pub fn flicker_f_lo_hz(&self) -> f64 {
        self.noise
            .bias_instability_f_lo_hz
            .unwrap_or(DEFAULT_FLICKER_F_LO_HZ)
    }

    /// Check every value; errors name the key (with its table path) and the value.
    pub fn validate(&self) -> Result<(), ModelError> {
        self.validate_gyro()?;
        self.validate_noise()?;
        self.validate_catalog()?;
        self.validate_transients()?;
        self.validate_thermal()
    }

    /// `[gyro]` and the `[readout_filter]` (whose corner is checked against
    /// the sample rate).
    fn validate_gyro(&self) -> Result<(), ModelError> {
        let g = &self.gyro;
        within(
            "gyro.sample_rate_hz",
            g.sample_rate_hz,
            1e-6,
            MAX_SAMPLE_RATE_HZ,
            "Hz",
        )?;
        match g.output {
            OutputKind::Counts => {
                within(
                    "gyro.pulse_arcsec",
                    g.pulse_arcsec,
                    1e-9,
                    MAX_PULSE_WEIGHT_ARCSEC,
                    "arcsec (at most one turn)",
                )?;
                if g.rate_lsb_dps != 0.0 {
                    return Err(ModelError::invalid(
                        "gyro.rate_lsb_dps",
                        show(g.rate_lsb_dps),
                        "only for output = \"rate\" (a counter's quantum is gyro.pulse_arcsec)",
                    ));
                }
            }
            OutputKind::Rate => {
                if g.pulse_arcsec != 0.0 {
                    return Err(ModelError::invalid(
                        "gyro.pulse_arcsec",
                        show(g.pulse_arcsec),
                        "only for output = \"counts\" (a rate word's quantum is gyro.rate_lsb_dps)",
                    ));
                }
                within(
                    "gyro.rate_lsb_dps",
                    g.rate_lsb_dps,
                    0.0,
                    MAX_RATE_DPH / 3600.0,
                    "deg/s",
                )?;
            }
        }
        if let Some(f) = &self.readout_filter {
            f.filter(self.tau0_s())?;
        }
        within(
            "gyro.input_rate_dph",
            g.input_rate_dph,
            -MAX_RATE_DPH,
            MAX_RATE_DPH,
            "deg/h",
        )
    }

    /// The IEEE 952 coefficients of `[noise]`.
    fn validate_noise(&self) -> Result<(), ModelError> {
        let n = &self.noise;
        if let Some(q) = n.quantization_arcsec {
            nonneg("noise.quantization_arcsec", q)?;
            let c = self.counter_q_arcsec();
            if q < c * (1.0 - 1e-9) {
                return Err(ModelError::invalid(
                    "noise.quantization_arcsec",
                    q,
                    format!(
                        "below pulse_arcsec/sqrt(12) = {c:.6}: the pulse counter alone already gives \
                         d/sqrt(12); Q must be >= that (omit the key to get exactly d/sqrt(12))"
                    ),
                ));
            }
        }
        if let Some(v) = n.arw_dpsh {
            nonneg("noise.arw_dpsh", v)?;
        }
        if let Some(v) = n.bias_instability_dph {
            nonneg("noise.bias_instability_dph", v)?;
        }
        if let Some(v) = n.bias_instability_f_lo_hz {
            positive("noise.bias_instability_f_lo_hz", v)?;
            let top = super::terms::FLICKER_TOP_PER_SAMPLE_RATE * self.gyro.sample_rate_hz;
            if v * 2.0 > top {
                return Err(ModelError::invalid(
                    "noise.bias_instability_f_lo_hz",
                    v,
                    format!(
                        "must be below half the flicker top corner ({top} Hz = 8 x sample rate)"
                    ),
                ));
            }
        }
        if let Some(v) = n.rrw_dphsh {
            nonneg("noise.rrw_dphsh", v)?;
        }
        if let Some(v) = n.rate_ramp_dphh {
            finite("noise.rate_ramp_dphh", v)?;
        }
        Ok(())
    }

    /// The catalog terms, `[[noise.gauss_markov]]`, `[[noise.sinusoid]]`,
    /// `[[noise.random_telegraph]]` and `[[noise.resonance]]`; keys are named
    /// with the entry's index, `noise.sinusoid[0].period_s`.
    fn validate_catalog(&self) -> Result<(), ModelError> {
        let (n, fs) = (&self.noise, self.gyro.sample_rate_hz);
        for (i, t) in n.gauss_markov.iter().enumerate() {
            nonneg(&format!("noise.gauss_markov[{i}].sigma_dph"), t.sigma_dph)?;
            positive(&format!("noise.gauss_markov[{i}].tau_c_s"), t.tau_c_s)?;
        }
        for (i, t) in n.sinusoid.iter().enumerate() {
            nonneg(
                &format!("noise.sinusoid[{i}].amplitude_dph"),
                t.amplitude_dph,
            )?;
            positive(&format!("noise.sinusoid[{i}].period_s"), t.period_s)?;
        }
        for (i, t) in n.random_telegraph.iter().enumerate() {
            nonneg(
                &format!("noise.random_telegraph[{i}].amplitude_dph"),
                t.amplitude_dph,
            )?;
            // the simulator draws each switch: a dwell far below the sample
            // period would cost unbounded work per sample (and is white noise)
            let min_dwell = MIN_DWELL_PER_SAMPLE / fs;
            if !(t.mean_dwell_s.is_finite() && t.mean_dwell_s >= min_dwell) {
                return Err(ModelError::invalid(
                    format!("noise.random_telegraph[{i}].mean_dwell_s"),
                    show(t.mean_dwell_s),
                    format!("must be finite and >= {min_dwell:e} s (1/100 of the sample period)"),
                ));
            }
        }
        for (i, t) in n.resonance.iter().enumerate() {
            let key = |k: &str| format!("noise.resonance[{i}].{k}");
            nonneg(&key("sigma_dph"), t.sigma_dph)?;
            let nyquist = 0.5 * fs;
            if !(t.centre_hz > 0.0 && t.centre_hz < nyquist) {
                return Err(ModelError::invalid(
                    key("centre_hz"),
                    show(t.centre_hz),
                    format!(
                        "must be in (0, {nyquist}) Hz: above 0 and below the Nyquist frequency"
                    ),
                ));
            }
            // the pole radius exp(-pi w tau0) must stay below 1 and above 0
            if !(t.width_hz > 0.0 && t.width_hz <= fs) {
                return Err(ModelError::invalid(
                    key("width_hz"),
                    show(t.width_hz),
                    format!("must be in (0, {fs}] Hz (the sample rate)"),
                ));
            }
        }
        Ok(())
    }

    /// The bias's transients and the readout's glitches: `[noise.warmup]`,
    /// `[[noise.bias_step]]` (keys named with the entry's index) and
    /// `[noise.spikes]`.
    fn validate_transients(&self) -> Result<(), ModelError> {
        let n = &self.noise;
        let rate = |key: &str, v: f64| within(key, v, -MAX_RATE_DPH, MAX_RATE_DPH, "deg/h");
        if let Some(w) = &n.warmup {
            rate("noise.warmup.amplitude_dph", w.amplitude_dph)?;
            positive("noise.warmup.tau_s", w.tau_s)?;
        }
        for (i, b) in n.bias_step.iter().enumerate() {
            nonneg(&format!("noise.bias_step[{i}].at_s"), b.at_s)?;
            rate(
                &format!("noise.bias_step[{i}].amplitude_dph"),
                b.amplitude_dph,
            )?;
        }
        if let Some(sp) = &n.spikes {
            // the simulator draws each spike: a mean gap far below the sample
            // period would cost unbounded work per sample
            let max = units::S_PER_H * self.gyro.sample_rate_hz / MIN_DWELL_PER_SAMPLE;
            within(
                "noise.spikes.rate_per_h",
                sp.rate_per_h,
                0.0,
                max,
                "per hour (at most 100 per sample period)",
            )?;
            within(
                "noise.spikes.amplitude_dph",
                sp.amplitude_dph,
                0.0,
                MAX_RATE_DPH,
                "deg/h",
            )?;
        }
        Ok(())
    }

    /// `[thermal]`.
    fn validate_thermal(&self) -> Result<(), ModelError> {
        let Some(th) = &self.thermal else {
            return Ok(());
        };
        finite("thermal.temp_c0", th.temp_c0)?;
        finite("thermal.ramp_c_per_h", th.ramp_c_per_h)?;
        nonneg("thermal.sine_amplitude_c", th.sine_amplitude_c)?;
        match th.sine_period_s {
            Some(p) => positive("thermal.sine_period_s", p)?,
            None if th.sine_amplitude_c > 0.0 => {
                return Err(ModelError::invalid(
                    "thermal.sine_period_s",
                    "(missing)",
                    "required when thermal.sine_amplitude_c > 0",
                ));
            }
            None => {}
        }
        finite(
            "thermal.bias_sensitivity_dph_per_c",
            th.bias_sensitivity_dph_per_c,
        )?;
        nonneg("thermal.lag_s", th.lag_s)
    }

    /// Mean rate over a record of `duration_s` of the transient terms and of
    /// the thermal lag, deg/h: the warm-up's `a tau (1 - exp(-D/tau)) / D`, each
    /// bias step's `a (D - at) / D`, and the lag's shift `-s ramp lag` of the
    /// thermal ramp's bias (0 when the model has none of them).
    pub fn transient_mean_rate_dph(&self, duration_s: f64) -> f64 {
        let d = duration_s;
        if !d.is_finite() || d <= 0.0 {
            return 0.0;
        }
        let mut sum = 0.0;
        if let Some(w) = &self.noise.warmup {
            sum += -w.amplitude_dph * w.tau_s * (-d / w.tau_s).exp_m1() / d;
        }
        for b in &self.noise.bias_step {
            sum += b.amplitude_dph * (d - b.at_s).max(0.0) / d;
        }
        if let Some(th) = self.thermal.as_ref().filter(|t| t.lag_s > 0.0) {
            sum -= th.bias_sensitivity_dph_per_c * th.ramp_c_per_h * th.lag_s / units::S_PER_H;
        }
        sum
    }

    /// The model's noise terms for the Allan analysis, in a fixed order:
    /// quantization (total Q), ARW, bias instability (ideal 1/f on
    /// `[flicker_f_lo_hz, inf)`), RRW, rate ramp (model ramp plus thermal ramp
    /// `s * ramp`, added linearly since both are deterministic), the catalog terms,
    /// and the thermal sinusoid. Absent or zero terms are left out.
    ///
    /// The warm-up, the bias steps and the spikes are not in the list: the
    /// first two are deterministic transients and the spikes are sparse
    /// glitches, none a stationary noise with an Allan or spectral closed form.
    /// A thermal lag changes neither term of the thermal profile: delayed, the
    /// ramp's bias is the same ramp (offset by a constant) and the sinusoid's
    /// only changes phase.
    pub fn terms(&self) -> Vec<Term> {
        let n = &self.noise;
        let mut out = vec![Term::Quantization {
            quantization_arcsec: self.quantization_q_arcsec(),
        }];
        if let Some(v) = n.arw_dpsh.filter(|v| *v > 0.0) {
            out.push(Term::AngleRandomWalk { arw_dpsh: v });
        }
        if self.gyro.output == OutputKind::Rate && self.gyro.rate_lsb_dps > 0.0 {
            out.push(Term::RateQuantization {
                rate_lsb_dps: self.gyro.rate_lsb_dps,
                tau0_s: self.tau0_s(),
            });
        }
        if let Some(v) = n.bias_instability_dph.filter(|v| *v > 0.0) {
            out.push(Term::BiasInstability {
                bias_instability_dph: v,
                f_lo_hz: self.flicker_f_lo_hz(),
                f_hi_hz: f64::INFINITY,
            });
        }
        if let Some(v) = n.rrw_dphsh.filter(|v| *v > 0.0) {
            out.push(Term::RateRandomWalk { rrw_dphsh: v });
        }
        let thermal_ramp = self
            .thermal
            .as_ref()
            .map(|t| t.bias_sensitivity_dph_per_c * t.ramp_c_per_h)
            .unwrap_or(0.0);
        let ramp = n.rate_ramp_dphh.unwrap_or(0.0) + thermal_ramp;
        if ramp != 0.0 {
            out.push(Term::RateRamp {
                rate_ramp_dphh: ramp,
            });
        }
        for t in &n.gauss_markov {
            out.push(Term::GaussMarkov {
                sigma_dph: t.sigma_dph,
                tau_c_s: t.tau_c_s,
            });
        }
        for t in &n.sinusoid {
            out.push(Term::Sinusoid {
                amplitude_dph: t.amplitude_dph,
                period_s: t.period_s,
            });
        }
        for t in &n.random_telegraph {
            out.push(Term::RandomTelegraph {
                amplitude_dph: t.amplitude_dph,
                mean_dwell_s: t.mean_dwell_s,
            });
        }
        for t in &n.resonance {
            out.push(Term::Resonance {
                sigma_dph: t.sigma_dph,
                centre_hz: t.centre_hz,
                width_hz: t.width_hz,
                tau0_s: self.tau0_s(),
            });
        }
        if let Some(th) = &self.thermal {
            let a = (th.bias_sensitivity_dph_per_c * th.sine_amplitude_c).abs();
            if let (true, Some(p)) = (a > 0.0, th.sine_period_s) {
                out.push(Term::Sinusoid {
                    amplitude_dph: a,
                    period_s: p,
                });
            }
        }
        out
    }
}
