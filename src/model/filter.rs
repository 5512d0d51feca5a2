//! Readout filters: what a sensor's electronics do to the rate before it is
//! output (anti-alias filter, dither stripping, averaging of a rate word).
//!
//! Two kinds, both discrete-time, applied to the sampled rate `x[k]`:
//! * **moving average** of `L >= 2` samples, `y[k] = (x[k] + ... + x[k-L+1]) / L`,
//!   power response `|H(nu)|^2 = (sin(pi nu L) / (L sin(pi nu)))^2`;
//! * **first order** (one pole), `y[k] = a y[k-1] + (1 - a) x[k]`, power response
//!   `(1 - a)^2 / (1 + a^2 - 2 a cos(2 pi nu))`, with the pole `a` chosen so that
//!   the response is exactly -3 dB at the corner: `a = (2 - c) - sqrt((2 - c)^2 - 1)`,
//!   `c = cos(2 pi f_c tau0)`.
//!
//! Both have unit DC gain, so a filtered white rate of PSD `N^2` keeps its
//! angle random walk `N` at low frequency: the ARW the estimator reports is the
//! white coefficient of the unfiltered band. Every kind is described by its
//! -3 dB frequency `corner_hz` (for a moving average, found by bisection).
//!
//! The filter acts on the white-rate term, whose power lies at high
//! frequency. The low-frequency terms (flicker, rate random walk,
//! Gauss-Markov) pass a corner far above their band unchanged, so the model
//! leaves them unfiltered.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::ModelError;

/// Longest moving average accepted (samples).
pub const MAX_MA_LENGTH: u32 = 4096;

/// A readout filter, with its parameters in samples (length) or as a pole.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReadoutFilter {
    /// Moving average of `length` samples (>= 2).
    MovingAverage { length: u32 },
    /// One-pole low-pass `y[k] = a y[k-1] + (1 - a) x[k]`, `0 < a < 1`.
    FirstOrder { pole: f64 },
}

/// The filter kind, as written in model files and JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterKind {
    MovingAverage,
    FirstOrder,
}

impl FilterKind {
    pub fn name(&self) -> &'static str {
        match self {
            FilterKind::MovingAverage => "moving_average",
            FilterKind::FirstOrder => "first_order",
        }
    }
}

impl ReadoutFilter {
    /// A one-pole filter whose -3 dB frequency is `corner_hz` at sample period
    /// `tau0_s` (`0 < corner_hz < 1 / (2 tau0_s)`).
    pub fn first_order(corner_hz: f64, tau0_s: f64) -> Result<Self, ModelError> {
        let nyq = 0.5 / tau0_s;
        if !(corner_hz.is_finite() && corner_hz > 0.0 && corner_hz < nyq) {
            return Err(ModelError::invalid(
                "readout_filter.corner_hz",
                corner_hz,
                format!("must be in (0, {nyq}) Hz (below the Nyquist frequency)"),
            ));
        }
        let c = (2.0 * PI * corner_hz * tau0_s).cos();
        let b = 2.0 - c;
        Ok(ReadoutFilter::FirstOrder {
            pole: b - (b * b - 1.0).sqrt(),
        })
    }

    /// A moving average of `length` samples (2 ..= [`MAX_MA_LENGTH`]).
    pub fn moving_average(length: u32) -> Result<Self, ModelError> {
        if !(2..=MAX_MA_LENGTH).contains(&length) {
            return Err(ModelError::invalid(
                "readout_filter.length",
                length,
                format!("must be an integer in [2, {MAX_MA_LENGTH}] samples"),
            ));
        }
        Ok(ReadoutFilter::MovingAverage { length })
    }

    pub fn kind(&self) -> FilterKind {
        match self {
            ReadoutFilter::MovingAverage { .. } => FilterKind::MovingAverage,
            ReadoutFilter::FirstOrder { .. } => FilterKind::FirstOrder,
        }
    }

    /// Power response `|H(nu)|^2` at `nu` cycles per sample (1 at DC).
    pub fn power(&self, nu: f64) -> f64 {
        self.power_trig(nu, (PI * nu).sin(), || (2.0 * PI * nu).cos())
    }

    /// [`ReadoutFilter::power`] from `s0 = sin(pi nu)` and (for a first-order
    /// filter) `c2 = cos(2 pi nu)`, for quadratures that hold them per node.
    pub fn power_trig(&self, nu: f64, s0: f64, c2: impl FnOnce() -> f64) -> f64 {
        match *self {
            ReadoutFilter::MovingAverage { length } => {
                if s0.abs() < 1e-300 {
                    return 1.0;
                }
                let l = f64::from(length);
                let r = (PI * nu * l).sin() / (l * s0);
                r * r
            }
            ReadoutFilter::FirstOrder { pole: a } => {
                (1.0 - a) * (1.0 - a) / (1.0 + a * a - 2.0 * a * c2())
            }
        }
    }

    /// The -3 dB frequency, cycles per sample.
    pub fn corner_cycles(&self) -> f64 {
        match *self {
            ReadoutFilter::FirstOrder { pole: a } => {
                // invert 2 (1-a)^2 = 1 + a^2 - 2 a c
                let c = (1.0 + a * a - 2.0 * (1.0 - a) * (1.0 - a)) / (2.0 * a);
                c.clamp(-1.0, 1.0).acos() / (2.0 * PI)
            }
            ReadoutFilter::MovingAverage { length } => {
                // |H| falls monotonically from 1 to 0 on (0, 1/L)
                let (mut lo, mut hi) = (0.0, 1.0 / f64::from(length));
                for _ in 0..100 {
                    let mid = 0.5 * (lo + hi);
                    if self.power(mid) > 0.5 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            }
        }
    }

    /// The -3 dB frequency in Hz at sample period `tau0_s`.
    pub fn corner_hz(&self, tau0_s: f64) -> f64 {
        self.corner_cycles() / tau0_s
    }

    /// Group delay at DC, samples: `(L - 1) / 2` or `a / (1 - a)`.
    pub fn delay_samples(&self) -> f64 {
        match *self {
            ReadoutFilter::MovingAverage { length } => 0.5 * (f64::from(length) - 1.0),
            ReadoutFilter::FirstOrder { pole: a } => a / (1.0 - a),
        }
    }

    /// Autocorrelation of the impulse response at lags 0, 1, ... (white input
    /// of unit variance), when it has finite support (moving average).
    pub fn finite_autocorr(&self) -> Option<Vec<f64>> {
        match *self {
            ReadoutFilter::MovingAverage { length } => {
                let l = f64::from(length);
                Some((0..length).map(|k| (l - f64::from(k)) / (l * l)).collect())
            }
            ReadoutFilter::FirstOrder { .. } => None,
        }
    }

    /// Exact bit pattern identifying the filter (memo keys).
    pub fn key(&self) -> (u64, u64) {
        match *self {
            ReadoutFilter::MovingAverage { length } => (1, u64::from(length)),
            ReadoutFilter::FirstOrder { pole } => (2, pole.to_bits()),
        }
    }

    /// A streaming filter state for the simulator, started at the steady
    /// state of a constant input `x0`.
    pub fn state(&self, x0: f64) -> FilterState {
        match *self {
            ReadoutFilter::MovingAverage { length } => FilterState::MovingAverage {
                ring: vec![x0; length as usize],
                pos: 0,
                sum: x0 * f64::from(length),
                since_resum: 0,
            },
            ReadoutFilter::FirstOrder { pole } => FilterState::FirstOrder { pole, y: x0 },
        }
    }
}

/// Running state of a [`ReadoutFilter`] over a sample stream.
#[derive(Debug, Clone)]
pub enum FilterState {
    MovingAverage {
        ring: Vec<f64>,
        pos: usize,
        sum: f64,
        since_resum: usize,
    },
    FirstOrder {
        pole: f64,
        y: f64,
    },
}

impl FilterState {
    /// Filter `x` in place.
    pub fn apply(&mut self, x: &mut [f64]) {
        match self {
            FilterState::MovingAverage {
                ring,
                pos,
                sum,
                since_resum,
            } => {
                let l = ring.len();
                let inv = 1.0 / l as f64;
                for v in x.iter_mut() {
                    *sum += *v - ring[*pos];
                    ring[*pos] = *v;
                    *pos = (*pos + 1) % l;
                    *since_resum += 1;
                    if *since_resum >= 1 << 16 {
                        // keep the running sum free of accumulated round-off
                        *sum = ring.iter().sum();
                        *since_resum = 0;
                    }
                    *v = *sum * inv;
                }
            }
            FilterState::FirstOrder { pole, y } => {
                let (a, b) = (*pole, 1.0 - *pole);
                for v in x.iter_mut() {
                    *y = a * *y + b * *v;
                    *v = *y;
                }
            }
        }
    }
}

/// The `[readout_filter]` table of a model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadoutFilterParams {
    pub kind: FilterKind,
    /// Samples (moving average).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<u32>,
    /// -3 dB frequency, Hz (first order).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corner_hz: Option<f64>,
}

impl ReadoutFilterParams {
    /// The filter at sample period `tau0_s`; errors name the key.
    pub fn filter(&self, tau0_s: f64) -> Result<ReadoutFilter, ModelError> {
        match self.kind {
            FilterKind::MovingAverage => {
                if self.corner_hz.is_some() {
                    return Err(ModelError::invalid(
                        "readout_filter.corner_hz",
                        self.corner_hz.unwrap_or_default(),
                        "a moving average is set by its length (samples), not by corner_hz",
                    ));
                }
                let l = self.length.ok_or_else(|| {
                    ModelError::invalid(
                        "readout_filter.length",
                        "(missing)",
                        "required for kind = \"moving_average\"",
                    )
                })?;
                ReadoutFilter::moving_average(l)
            }
            FilterKind::FirstOrder => {
                if self.length.is_some() {
                    return Err(ModelError::invalid(
                        "readout_filter.length",
                        self.length.unwrap_or_default(),
                        "a first-order filter is set by corner_hz, not by a length",
                    ));
                }
                let c = self.corner_hz.ok_or_else(|| {
                    ModelError::invalid(
                        "readout_filter.corner_hz",
                        "(missing)",
                        "required for kind = \"first_order\"",
                    )
                })?;
                ReadoutFilter::first_order(c, tau0_s)
            }
        }
    }

    /// The model-file table of a filter (corner written for a first-order one).
    pub fn from_filter(f: &ReadoutFilter, tau0_s: f64) -> Self {
        match *f {
            ReadoutFilter::MovingAverage { length } => ReadoutFilterParams {
                kind: FilterKind::MovingAverage,
                length: Some(length),
                corner_hz: None,
            },
            ReadoutFilter::FirstOrder { .. } => ReadoutFilterParams {
                kind: FilterKind::FirstOrder,
                length: None,
                corner_hz: Some(f.corner_hz(tau0_s)),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_corner_is_minus_3_db() {
        for fc in [0.5, 10.0, 30.0, 80.0, 99.0] {
            let f = ReadoutFilter::first_order(fc, 1.0 / 200.0).unwrap();
            let p = f.power(fc / 200.0);
            assert!((p - 0.5).abs() < 1e-12, "fc {fc}: |H|^2 = {p}");
            assert!((f.corner_hz(1.0 / 200.0) / fc - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn moving_average_corner_and_response() {
        // L = 2: |H|^2 = cos^2(pi nu), -3 dB at nu = 1/4
        let f = ReadoutFilter::moving_average(2).unwrap();
        assert!((f.corner_cycles() - 0.25).abs() < 1e-12);
        // large L: corner -> 0.4429 / L
        let f = ReadoutFilter::moving_average(1000).unwrap();
        assert!((f.corner_cycles() * 1000.0 - 0.442_946).abs() < 1e-4);
        // the response is the squared DFT of the box
        let f = ReadoutFilter::moving_average(5).unwrap();
        let nu: f64 = 0.13;
        let (mut re, mut im) = (0.0, 0.0);
        for k in 0..5 {
            re += (2.0 * PI * nu * k as f64).cos() / 5.0;
            im += (2.0 * PI * nu * k as f64).sin() / 5.0;
        }
        assert!((f.power(nu) - (re * re + im * im)).abs() < 1e-14);
    }

    #[test]
    fn streaming_state_matches_direct_filter_on_any_split() {
        let x: Vec<f64> = (0..500).map(|k| ((k * 7919) % 101) as f64 - 50.0).collect();
        for filt in [
            ReadoutFilter::moving_average(7).unwrap(),
            ReadoutFilter::first_order(3.0, 0.01).unwrap(),
        ] {
            let mut whole = x.clone();
            filt.state(0.0).apply(&mut whole);
            // direct reference
            let direct: Vec<f64> = match filt {
                ReadoutFilter::MovingAverage { length } => (0..x.len())
                    .map(|k| {
                        (0..length as usize)
                            .map(|i| if k >= i { x[k - i] } else { 0.0 })
                            .sum::<f64>()
                            / length as f64
                    })
                    .collect(),
                ReadoutFilter::FirstOrder { pole } => {
                    let mut y = 0.0;
                    x.iter()
                        .map(|v| {
                            y = pole * y + (1.0 - pole) * v;
                            y
                        })
                        .collect()
                }
            };
            for (a, b) in whole.iter().zip(&direct) {
                assert!((a - b).abs() < 1e-9, "{a} vs {b}");
            }
            let mut split = x.clone();
            let mut st = filt.state(0.0);
            let (a, b) = split.split_at_mut(123);
            st.apply(a);
            st.apply(b);
            assert_eq!(split, whole);
        }
    }

    #[test]
    fn params_errors_name_the_key() {
        let p = ReadoutFilterParams {
            kind: FilterKind::FirstOrder,
            length: None,
            corner_hz: Some(150.0),
        };
        let e = p.filter(1.0 / 200.0).unwrap_err().to_string();
        assert!(e.contains("readout_filter.corner_hz"), "{e}");
        let p = ReadoutFilterParams {
            kind: FilterKind::MovingAverage,
            length: None,
            corner_hz: None,
        };
        let e = p.filter(1.0 / 200.0).unwrap_err().to_string();
        assert!(e.contains("readout_filter.length"), "{e}");
        let p = ReadoutFilterParams {
            kind: FilterKind::MovingAverage,
            length: Some(1),
            corner_hz: None,
        };
        assert!(p.filter(1.0 / 200.0).is_err());
    }
}
