//! Quantization-noise (QN) removal: splits a stream of rate samples (arcsec/s)
//! into `clean` and `noise` with `clean + noise == raw`.
//!
//! Role in the whole: the daemon and the offline commands feed every rate sample
//! through a [`QnSplitter`]; `allan` computes Allan statistics of both channels and
//! `model` reads QN from `noise` and ARW from `clean`, as the founding paper does.
//! [`QnSplitter::level_stats`] and [`QnSplitter::estimates`] expose the
//! per-level variances, gains and the QN / ARW estimates for the estimator.
//!
//! # Method
//! A [`StreamingBank`] (default `sym8`, depth J from the sample rate so that the
//! deepest detail band lies below about 0.5 Hz: J = 11 at 1 kHz, band 0.24-0.49 Hz)
//! analyses the stream. Every detail coefficient of level j is split as
//! `clean = g_j d`, `noise = (1 - g_j) d` (rule-dependent, below); the deepest
//! approximation (the band below 0.24 Hz at 1 kHz, which carries the mean rate
//! and bias instability) stays in `clean` untouched, so `noise` has no DC and its
//! integral (the angle error) stays bounded. The bank synthesises `clean`;
//! `noise = raw - clean` (delayed raw), so nothing is lost.
//!
//! ## The rule (chosen by measurement)
//! Per level j, a running mean square of the detail coefficients, `var_total_j`
//! (exponentially weighted, time constant `stats_window_s`, updated once per frame
//! of `2^J` samples), is compared with the QN share `var_qn_j`. Two ingredients:
//!
//! - **ARW floor** ([`QnEstimate::ArwFloor`], default): angle random walk is white
//!   in rate, so in an orthonormal bank it has the *same* per-coefficient variance
//!   `A = N^2 / tau0` at every level, while QN fades towards the deep levels. `A`
//!   is fitted (weighted least squares) to `var_total_j = A + c kappa_j` on the
//!   deepest levels (`kappa_j`: the exact energy factor of white angle noise in
//!   level j, [`qn_energy_factors`]); levels `J+1`, `J+2` are analysed for this fit
//!   only; 4, 3, then 2 consecutive levels ending at the deepest ready one are
//!   tried and the first fit with chi^2/dof <= [`FLOOR_MAX_CHI2_DOF`] and c >= 0
//!   is kept. Then `var_qn_j = max(0, var_total_j - A)`. This needs the f^2 shape
//!   of QN only on the deepest levels.
//! - **Power-preserving spectral subtraction** ([`QnRule::PowerSubtraction`],
//!   default): `g_j = sqrt(max(0, 1 - var_qn_j / var_total_j))`, so each level of
//!   `clean` carries, in expectation, the power of the non-QN part, and the Allan
//!   variance of `clean` follows ARW + BI down to about 1 s.
//!
//! Why not the white model ([`QnEstimate::WhiteModel`]: `var_qn_j = Q^2 kappa_j /
//! tau0^2` with Q from the finest level)? A pulse counter's error is white only if
//! the dither residual exceeds about d/2. The paper's Q = 0.35" = d/sqrt(12) means
//! almost no dither residual: the error is then a sawtooth of the angle, with
//! lines at the pulse frequency `rate/d` (10 Hz at 12.3 deg/h) and harmonics, and
//! 8x less power at the finest level than white QN of the same Q. Extrapolating
//! from the finest level then predicts far too little QN in the mid levels. Even
//! at Q = 0.5" (dither residual 0.3 d) the residual lines defeat it.
//!
//! Measured by `tests/numerics/dsp_qn_rules.rs` (1-hour runs of the paper's gyro, 1 kHz,
//! d = 1.21"; ratio of the clean ADEV to the ADEV of the run's own non-QN part;
//! worst case over four runs: Q 0.35" at 12.3 and at 3 deg/h, Q 0.5", Q 0.6"):
//!
//! | QN estimate / rule | worst, tau 1..32 s | worst, tau 2..32 s | note |
//! |---|---|---|---|
//! | ArwFloor / PowerSubtraction (default) | 8.1 % | 5.2 % | low by 3-8 % at 1 s |
//! | ArwFloor / Wiener | 28 % | 11 % | shrinks ARW: low at small tau |
//! | ArwFloor / SoftThreshold (3 sigma) | 97 % | 56 % | |
//! | ArwFloor / HardThreshold (3 sigma) | 294 % | 183 % | |
//! | WhiteModel / PowerSubtraction | 1244 % | 696 % | fails on sawtooth QN |
//! | WhiteModel / Wiener, Soft, Hard | > 1100 % | > 500 % | |
//!
//! Thresholds cannot separate two Gaussian-like noises of comparable size: there
//! is no sparsity to exploit. On 4-hour runs (`tests/numerics/dsp_qn.rs`) the default's
//! clean ADEV lies within 4 % of the true ARW + BI curve at 2, 8 and 32 s and
//! within 2 % of the run's own non-QN ADEV, while the raw ADEV is 4-12x above.
//! The running integral of `noise` has sd = Q (the angle error) and does not grow
//! with time; with the paper's weak dither its largest excursion over 1 h (and
//! 4 h) was 0.60 d, with a Gaussian dither residual (Q 0.6") 2.6 d = 5.3 sd.
//!
//! **Limits.** With weak dither and a slow input (pulse frequency `rate/d` below
//! about 1 Hz, i.e. below ~4 deg/h for d = 1.21"), the sawtooth lines fall into the
//! ARW band itself and no per-level rule separates them. Measured (1 h, N 0.001,
//! ratio clean ADEV / true at tau = 1, 2, 8, 32 s): 1 deg/h, Q 0.35": 0.86, 0.99,
//! 1.01, 1.00; 0.3 deg/h, Q 0.35": 4.3, 6.2, 1.5, 1.4 (fails), Q 0.5": 0.95, 1.41,
//! 0.99, 1.01 (fails at 2 s), Q 0.6": within 8 %; 0 deg/h, Q 0.35": 2.5x (the
//! counter error there is not QN-like at all), Q >= 0.5": within 5 %.
//!
//! ## Streaming, latency, edges
//! Output sample k (clean and noise) is emitted when raw sample
//! `k + latency()` has been pushed, `latency() = (L-1)(2^J-1)` (30705 samples,
//! 30.7 s, for sym8 at J = 11); [`QnSplitter::flush`] emits the rest at end of
//! stream. Results are identical for any split of the input into blocks: gains
//! change only at frame boundaries fixed by the sample count.
//!
//! The stream is extended at both ends by a constant: before the first sample by
//! the mean of the first frame (`2^J` samples, buffered), after the last by the
//! mean of the last frame, so a mean rate of several deg/h does not ring through
//! the bank as a step. Coefficients whose support reaches into an extension are
//! not used for statistics. Until a level has seen `min_coeffs` coefficients its
//! gain is 0 (its content goes to `noise`): at 1 kHz and J = 11 the deepest level
//! is ready after about 1.6 minutes, level 9 after 25 s.

use serde::{Deserialize, Serialize};

use super::bank::{AnalysisOutput, CoeffHook, Fifo, StreamingAnalysis, StreamingBank};
use super::wavelet::Wavelet;
use super::{DspError, Result};

/// How each level's detail coefficients are split.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QnRule {
    /// `g = sqrt(max(0, 1 - var_qn / var_total))`: clean keeps the non-QN power.
    PowerSubtraction,
    /// `g = max(0, 1 - var_qn / var_total)` (Wiener gain).
    Wiener,
    /// Soft threshold at `threshold_k * sqrt(var_qn)`.
    SoftThreshold,
    /// Hard threshold at `threshold_k * sqrt(var_qn)`.
    HardThreshold,
}

/// How each level's QN variance is estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QnEstimate {
    /// `var_qn_j = max(0, var_total_j - A)`, A = the flat ARW floor fitted on the
    /// deepest levels (see module docs).
    ArwFloor,
    /// `var_qn_j = Q^2 kappa_j / tau0^2` with Q from the finest level, assuming the
    /// quantization error is white in angle at all frequencies.
    WhiteModel,
}

/// Configuration of a [`QnSplitter`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QnConfig {
    /// Wavelet name (`haar`, `db4`, `sym4`, `db8`, `sym8`).
    pub wavelet: String,
    /// Decomposition depth J; `None`: [`default_levels`] of the sample rate.
    pub levels: Option<u32>,
    /// Sample rate of the rate stream, Hz.
    pub sample_rate_hz: f64,
    /// Split rule.
    pub rule: QnRule,
    /// QN variance estimate.
    pub qn_estimate: QnEstimate,
    /// Threshold multiplier for the threshold rules.
    pub threshold_k: f64,
    /// Time constant of the running per-level statistics, s.
    pub stats_window_s: f64,
    /// Coefficients a level must have seen before its gain leaves 0.
    pub min_coeffs: u32,
}

impl Default for QnConfig {
    fn default() -> Self {
        QnConfig {
            wavelet: "sym8".to_string(),
            levels: None,
            sample_rate_hz: 1000.0,
            rule: QnRule::PowerSubtraction,
            qn_estimate: QnEstimate::ArwFloor,
            threshold_k: 3.0,
            stats_window_s: 600.0,
            min_coeffs: 32,
        }
    }
}

/// Default depth: the smallest J whose deepest detail band
/// `[fs/2^(J+1), fs/2^J]` lies below about 0.5 Hz (`fs/2^J <= 0.5 Hz`, with 3 %
/// slack), clamped to `2..=MAX_QN_LEVELS`. 1 kHz -> 11 (0.24-0.49 Hz).
pub fn default_levels(sample_rate_hz: f64) -> u32 {
    let j = ((sample_rate_hz / 0.5).log2() - 0.04).ceil();
    if j.is_finite() {
        (j.max(2.0) as u32).min(MAX_QN_LEVELS)
    } else {
        2
    }
}

impl QnConfig {
    /// Default config at `sample_rate_hz`.
    pub fn new(sample_rate_hz: f64) -> QnConfig {
        QnConfig {
            sample_rate_hz,
            ..QnConfig::default()
        }
    }

    /// The depth actually used.
    pub fn resolved_levels(&self) -> u32 {
        self.levels
            .unwrap_or_else(|| default_levels(self.sample_rate_hz))
    }

    /// Check every field; errors name the key and value.
    pub fn validate(&self) -> Result<()> {
        Wavelet::by_name(&self.wavelet)?;
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(DspError::InvalidConfig {
                key: "sample_rate_hz",
                value: self.sample_rate_hz.to_string(),
                why: "must be a positive finite number of Hz",
            });
        }
        let j = self.resolved_levels();
        if !(2..=MAX_QN_LEVELS).contains(&j) {
            return Err(DspError::InvalidLevels {
                levels: j,
                max: MAX_QN_LEVELS,
                why: "QN splitting needs at least 2 levels; beyond 16 the latency and the energy-factor setup grow as 2^levels",
            });
        }
        if !(self.stats_window_s.is_finite() && self.stats_window_s > 0.0) {
            return Err(DspError::InvalidConfig {
                key: "stats_window_s",
                value: self.stats_window_s.to_string(),
                why: "must be a positive finite number of seconds",
            });
        }
        if !(self.threshold_k.is_finite() && self.threshold_k >= 0.0) {
            return Err(DspError::InvalidConfig {
                key: "threshold_k",
                value: self.threshold_k.to_string(),
                why: "must be a finite number >= 0",
            });
        }
        if self.min_coeffs == 0 {
            return Err(DspError::InvalidConfig {
                key: "min_coeffs",
                value: "0".to_string(),
                why: "must be at least 1",
            });
        }
        Ok(())
    }
}

/// Energy factors of white angle noise: with rate `r[k] = (e[k] - e[k-1]) / tau0`
/// and `e` white with variance `Q^2`, a level-j detail coefficient has variance
/// `Q^2 kappa_j / tau0^2` (steady state). Index `j-1` for level j, index J for the
/// deepest approximation. Computed exactly from the cascaded (equivalent) filters:
/// `kappa = sum_n (f[n] - f[n-1])^2`.
pub fn qn_energy_factors(w: &Wavelet, levels: u32) -> Vec<f64> {
    fn conv_up(a: &[f64], h: &[f64], step: usize) -> Vec<f64> {
        let mut out = vec![0.0; a.len() + (h.len() - 1) * step];
        for (k, &hk) in h.iter().enumerate() {
            for (i, &ai) in a.iter().enumerate() {
                out[i + k * step] += hk * ai;
            }
        }
        out
    }
    fn diff_energy(f: &[f64]) -> f64 {
        let mut prev = 0.0;
        let mut s = 0.0;
        for &x in f.iter().chain(std::iter::once(&0.0)) {
            s += (x - prev) * (x - prev);
            prev = x;
        }
        s
    }
    let mut chain = vec![1.0];
    let mut out = Vec::with_capacity(levels as usize + 1);
    for j in 0..levels {
        let step = 1usize << j;
        out.push(diff_energy(&conv_up(&chain, w.dec_hi(), step)));
        chain = conv_up(&chain, w.dec_lo(), step);
    }
    out.push(diff_energy(&chain));
    out
}

/// Statistics of one band, for the estimator and for monitoring.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LevelStats {
    /// Level j (1 = finest); 0 denotes the bank's deepest approximation.
    pub level: u32,
    /// Nominal band edges, Hz.
    pub band_lo_hz: f64,
    /// Nominal band edges, Hz.
    pub band_hi_hz: f64,
    /// Effective number of coefficients behind the running statistics.
    pub weight: f64,
    /// Running mean square of the coefficients, (arcsec/s)^2 (for the approximation:
    /// variance about its running mean).
    pub var_total: f64,
    /// Estimated QN share of `var_total`.
    pub var_qn: f64,
    /// White-angle-noise energy factor kappa of this band.
    pub kappa: f64,
    /// Gain applied to this band's coefficients (for threshold rules: the measured
    /// rms ratio clean/raw over the last frames). The approximation has gain 1.
    pub gain: f64,
}

/// Global estimates derived from the running statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct QnEstimates {
    /// Q (arcsec) from the finest level under the white-angle-noise model:
    /// `sqrt((var_total_1 - A) tau0^2 / kappa_1)`. Exact for white QN; low when the
    /// quantization error is a sawtooth (weak dither).
    pub q_white_arcsec: Option<f64>,
    /// Q (arcsec) as the standard deviation of the running integral of `noise`
    /// (the angle error itself, any spectrum); running over `stats_window_s`.
    pub q_integral_arcsec: Option<f64>,
    /// ARW from the fitted floor A: `N = sqrt(A tau0) / 60`, deg/sqrt(h).
    pub arw_floor_dpsh: Option<f64>,
}

/// Per-level running statistics and gains: the bank hook.
#[derive(Debug, Clone)]
struct QnHook {
    /// Bank depth J.
    levels: usize,
    /// Statistics slots: `0..J` bank details, `J..J+EXTRA_LEVELS` the extra
    /// (estimation-only) detail levels, `J+EXTRA_LEVELS` the bank's approximation.
    /// `nd = J + EXTRA_LEVELS` detail slots in all.
    nd: usize,
    /// Analysis of the approximation stream two levels further, for statistics only.
    extra: StreamingAnalysis,
    extra_out: AnalysisOutput,
    rule: QnRule,
    estimate: QnEstimate,
    threshold_k: f64,
    min_coeffs: f64,
    /// Per-frame decay of the running statistics.
    lambda: f64,
    tau0: f64,
    /// kappa per slot (details of levels 1..=J+EXTRA_LEVELS, then level J's approximation).
    kappa: Vec<f64>,
    /// Statistics are accumulated only while true (not during warm-up or flush).
    collecting: bool,
    /// Per slot: first coefficient index whose support lies in real data.
    first_real: Vec<u64>,
    // per-frame accumulators, per slot
    /// This frame's coefficients per slot (unmodified, statistics-eligible only):
    /// sums are formed at the frame's end in a fixed order, so they do not depend
    /// on how the caller cut the stream into blocks.
    frame_buf: Vec<Vec<f64>>,
    // running (exponentially weighted) sums
    ew_sq: Vec<f64>,
    ew_sum: Vec<f64>,
    ew_n: Vec<f64>,
    /// Per level: coefficients used for statistics so far (not decayed).
    seen: Vec<u64>,
    var_total: Vec<f64>,
    var_qn: Vec<f64>,
    arw_floor: Option<f64>,
    // per-level split parameters
    gain: Vec<f64>,
    thresh: Vec<f64>,
    // threshold rules: measured clean/raw power per level
    ew_clean_sq: Vec<f64>,
}

impl QnHook {
    fn ready(&self, j: usize) -> bool {
        self.seen[j] as f64 >= self.min_coeffs
    }

    fn update(&mut self) {
        let jj = self.levels;
        let nd = self.nd;
        for j in 0..=nd {
            let buf = &self.frame_buf[j];
            let (sq, sum, n) = (sum_sq(buf), sum_plain(buf), buf.len() as f64);
            let clean_sq = if j < jj {
                let t = self.thresh[j];
                match self.rule {
                    QnRule::SoftThreshold => sum_sq_map(buf, |c| (c.abs() - t).max(0.0)),
                    QnRule::HardThreshold => {
                        sum_sq_map(buf, |c| if c.abs() <= t { 0.0 } else { c })
                    }
                    _ => 0.0,
                }
            } else {
                0.0
            };
            self.frame_buf[j].clear();
            self.ew_sq[j] = self.lambda * self.ew_sq[j] + sq;
            self.ew_sum[j] = self.lambda * self.ew_sum[j] + sum;
            self.ew_n[j] = self.lambda * self.ew_n[j] + n;
            self.ew_clean_sq[j] = self.lambda * self.ew_clean_sq[j] + clean_sq;
            self.seen[j] += n as u64;
            if self.ew_n[j] > 0.0 {
                let m = self.ew_sq[j] / self.ew_n[j];
                self.var_total[j] = if j < nd {
                    m
                } else {
                    let mean = self.ew_sum[j] / self.ew_n[j];
                    (m - mean * mean).max(0.0)
                };
            }
        }
        self.arw_floor = self.fit_floor();
        for j in 0..jj {
            if !self.ready(j) {
                self.var_qn[j] = 0.0;
                self.gain[j] = 0.0;
                self.thresh[j] = f64::INFINITY;
                continue;
            }
            let tot = self.var_total[j];
            let qn = match self.estimate {
                QnEstimate::ArwFloor => self.arw_floor.map_or(tot, |a| (tot - a).max(0.0)),
                QnEstimate::WhiteModel => {
                    let q2 = self.q2_white().unwrap_or(0.0);
                    q2 * self.kappa[j] / (self.tau0 * self.tau0)
                }
            };
            self.var_qn[j] = qn.min(tot);
            let frac = if tot > 0.0 {
                (1.0 - qn / tot).clamp(0.0, 1.0)
            } else {
                0.0
            };
            self.gain[j] = match self.rule {
                QnRule::PowerSubtraction => frac.sqrt(),
                QnRule::Wiener => frac,
                QnRule::SoftThreshold | QnRule::HardThreshold => {
                    if self.ew_sq[j] > 0.0 {
                        (self.ew_clean_sq[j] / self.ew_sq[j]).sqrt()
                    } else {
                        0.0
                    }
                }
            };
            self.thresh[j] = self.threshold_k * qn.sqrt();
        }
    }

    /// Q^2 (arcsec^2) from the finest level under the white model.
    fn q2_white(&self) -> Option<f64> {
        if !self.ready(0) {
            return None;
        }
        let a = self.arw_floor.unwrap_or(0.0);
        Some(((self.var_total[0] - a) * self.tau0 * self.tau0 / self.kappa[0]).max(0.0))
    }

    /// The ARW floor A: a weighted least-squares fit of `var_total_j = A + c kappa_j`
    /// over consecutive detail levels ending at the deepest level whose statistics
    /// are ready (levels `J+1, J+2` are analysed for this purpose only), trying 4,
    /// then 3, then 2 levels and keeping the first fit that is consistent (chi^2
    /// per degree of freedom at most [`FLOOR_MAX_CHI2_DOF`], c >= 0). Weights:
    /// inverse variance of a mean square, `n_j / (2 var_j^2)`. A shallower level
    /// that carries more QN than the f^2 shape allows (sawtooth lines of a weakly
    /// dithered counter) fails the test and is dropped instead of dragging A down.
    fn fit_floor(&self) -> Option<f64> {
        let deepest = (0..self.nd)
            .rev()
            .find(|&j| self.ready(j) && self.var_total[j] > 0.0)?;
        for k in (2..=4usize.min(deepest + 1)).rev() {
            let lo = deepest + 1 - k;
            if !(lo..=deepest).all(|j| self.ready(j) && self.var_total[j] > 0.0) {
                continue;
            }
            let pts: Vec<(f64, f64, f64)> = (lo..=deepest)
                .map(|j| {
                    let y = self.var_total[j];
                    (self.kappa[j], y, self.ew_n[j] / (2.0 * y * y))
                })
                .collect();
            let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &(x, y, w) in &pts {
                sw += w;
                sx += w * x;
                sy += w * y;
                sxx += w * x * x;
                sxy += w * x * y;
            }
            let det = sw * sxx - sx * sx;
            if det.abs() <= 1e-12 * sw * sxx {
                continue;
            }
            let a = (sxx * sy - sx * sxy) / det;
            let c = (sw * sxy - sx * sy) / det;
            let chi2: f64 = pts
                .iter()
                .map(|&(x, y, w)| w * (y - a - c * x).powi(2))
                .sum();
            let dof = (k - 2) as f64;
            if c >= 0.0 && (k == 2 || chi2 / dof <= FLOOR_MAX_CHI2_DOF) {
                return Some(a.max(0.0));
            }
        }
        None
    }
}

/// Largest chi^2 per degree of freedom accepted for the ARW-floor fit (generous:
/// the weights assume Gaussian coefficients and independent frames).
pub const FLOOR_MAX_CHI2_DOF: f64 = 6.0;

/// Deepest bank the splitter accepts (at 1 kHz: deepest band 7.6 mHz, latency 16 min).
pub const MAX_QN_LEVELS: u32 = 16;

/// Levels analysed below the bank's depth J, for the ARW-floor fit only.
pub const EXTRA_LEVELS: u32 = 2;

impl CoeffHook for QnHook {
    fn details(&mut self, level: u32, first: u64, d: &mut [f64]) {
        let j = level as usize - 1;
        let skip = self.first_real[j].saturating_sub(first).min(d.len() as u64) as usize;
        if self.collecting {
            self.frame_buf[j].extend_from_slice(&d[skip..]);
        }
        match self.rule {
            QnRule::PowerSubtraction | QnRule::Wiener => {
                let g = self.gain[j];
                d.iter_mut().for_each(|c| *c *= g);
            }
            QnRule::SoftThreshold => {
                let t = self.thresh[j];
                d.iter_mut()
                    .for_each(|c| *c = (c.abs() - t).max(0.0).copysign(*c));
            }
            QnRule::HardThreshold => {
                let t = self.thresh[j];
                d.iter_mut().for_each(|c| {
                    if c.abs() <= t {
                        *c = 0.0
                    }
                });
            }
        }
    }

    fn approx(&mut self, first: u64, a: &mut [f64]) {
        let (jj, nd) = (self.levels, self.nd);
        // The extra levels run on every approximation coefficient (warm-up and flush
        // included) so their filters see one continuous stream.
        let mut out = std::mem::take(&mut self.extra_out);
        out.approx.clear();
        out.details.iter_mut().for_each(Vec::clear);
        let mut before = [0u64; EXTRA_LEVELS as usize];
        for (x, b) in before.iter_mut().enumerate() {
            *b = self.extra.produced(x);
        }
        self.extra.push(a, &mut out);
        if self.collecting {
            for (x, d) in out.details.iter().enumerate() {
                let slot = jj + x;
                let skip = self.first_real[slot]
                    .saturating_sub(before[x])
                    .min(d.len() as u64) as usize;
                self.frame_buf[slot].extend_from_slice(&d[skip..]);
            }
            let skip = self.first_real[nd]
                .saturating_sub(first)
                .min(a.len() as u64) as usize;
            self.frame_buf[nd].extend_from_slice(&a[skip..]);
        }
        self.extra_out = out;
    }

    fn frame_end(&mut self, _frame: u64) {
        if self.collecting {
            self.update();
        }
    }
}

/// Sum of squares in a fixed order (four interleaved partial sums).
fn sum_sq(x: &[f64]) -> f64 {
    sum_sq_map(x, |c| c)
}

fn sum_sq_map(x: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0; 4];
    let chunks = x.chunks_exact(4);
    let rem = chunks.remainder();
    for c in chunks {
        for i in 0..4 {
            let v = f(c[i]);
            acc[i] += v * v;
        }
    }
    for (i, &c) in rem.iter().enumerate() {
        let v = f(c);
        acc[i] += v * v;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

fn sum_plain(x: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let chunks = x.chunks_exact(4);
    let rem = chunks.remainder();
    for c in chunks {
        for i in 0..4 {
            acc[i] += c[i];
        }
    }
    for (i, &c) in rem.iter().enumerate() {
        acc[i] += c;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// The noise integral is sampled every this many output samples.
const INTEGRAL_STEP: usize = 16;

/// Sum of one integral step in a fixed pairwise order (vectorisable, and the same
/// wherever the step falls in a block).
#[inline]
fn step_sum(c: &[f64; INTEGRAL_STEP]) -> f64 {
    let mut v = [0.0; 8];
    for i in 0..8 {
        v[i] = c[i] + c[i + 8];
    }
    for i in 0..4 {
        v[i] += v[i + 4];
    }
    (v[0] + v[2]) + (v[1] + v[3])
}

enum Phase {
    /// Buffering the first frame to learn the start extension.
    Start(Vec<f64>),
    Running,
}

/// Streaming QN splitter. See the module docs for the method and the latency.
pub struct QnSplitter {
    cfg: QnConfig,
    bank: StreamingBank,
    hook: QnHook,
    phase: Phase,
    frame: usize,
    /// Warm-up samples fed before the first real sample.
    warmup: usize,
    /// Bank outputs still to drop (the warm-up's).
    drop_out: usize,
    /// Raw samples pushed to the bank and not yet emitted (at least the last
    /// `min(pushed, latency)`, which also gives the end extension).
    raw: Fifo,
    /// Last finite raw sample (stands in for non-finite ones inside the bank).
    last_finite: f64,
    n_in: u64,
    n_out: u64,
    // running integral of noise (angle, arcsec) and its EW moments
    integral: f64,
    int_carry: [f64; INTEGRAL_STEP],
    int_carry_len: usize,
    int_w: f64,
    int_s1: f64,
    int_s2: f64,
    int_lambda: f64,
    scratch: Vec<f64>,
    flushed: bool,
}

impl std::fmt::Debug for QnSplitter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QnSplitter")
            .field("cfg", &self.cfg)
            .field("n_in", &self.n_in)
            .field("n_out", &self.n_out)
            .finish_non_exhaustive()
    }
}

impl QnSplitter {
    /// Build from a validated config.
    pub fn new(cfg: &QnConfig) -> Result<QnSplitter> {
        cfg.validate()?;
        let w = Wavelet::by_name(&cfg.wavelet)?;
        let levels = cfg.resolved_levels();
        let bank = StreamingBank::new(&w, levels)?;
        let jj = levels as usize;
        let frame = 1usize << jj;
        let l = w.len();
        let warmup = 2 * l * frame;
        let tau0 = 1.0 / cfg.sample_rate_hz;
        // Coefficient i of level j depends on inputs 2^j(i+1)-1-(L-1)(2^j-1) ..= 2^j(i+1)-1.
        // Slots: details of levels 1..=J+EXTRA_LEVELS, then level J's approximation
        // (which shares level J's support). Coefficient i of level j depends on the
        // inputs 2^j(i+1)-1-(L-1)(2^j-1) ..= 2^j(i+1)-1.
        let nd = jj + EXTRA_LEVELS as usize;
        let first_real = (1..=nd)
            .chain(std::iter::once(jj))
            .map(|j| {
                let s = 1u64 << j;
                let need = warmup as u64 + (l as u64 - 1) * (s - 1) + 1;
                need.div_ceil(s) - 1
            })
            .collect();
        let mut kappa = qn_energy_factors(&w, levels + EXTRA_LEVELS);
        kappa.truncate(nd);
        kappa.push(qn_energy_factors(&w, levels)[jj]);
        let frame_s = frame as f64 * tau0;
        let hook = QnHook {
            levels: jj,
            nd,
            extra: StreamingAnalysis::new(&w, EXTRA_LEVELS)?,
            extra_out: AnalysisOutput::default(),
            rule: cfg.rule,
            estimate: cfg.qn_estimate,
            threshold_k: cfg.threshold_k,
            min_coeffs: cfg.min_coeffs as f64,
            lambda: (-frame_s / cfg.stats_window_s).exp(),
            tau0,
            kappa,
            collecting: false,
            first_real,
            frame_buf: vec![Vec::new(); nd + 1],
            ew_sq: vec![0.0; nd + 1],
            ew_sum: vec![0.0; nd + 1],
            ew_n: vec![0.0; nd + 1],
            seen: vec![0; nd + 1],
            var_total: vec![0.0; nd + 1],
            var_qn: vec![0.0; nd + 1],
            arw_floor: None,
            gain: vec![0.0; jj],
            thresh: vec![f64::INFINITY; jj],
            ew_clean_sq: vec![0.0; nd + 1],
        };
        Ok(QnSplitter {
            cfg: cfg.clone(),
            bank,
            hook,
            phase: Phase::Start(Vec::with_capacity(frame)),
            frame,
            warmup,
            drop_out: warmup,
            raw: Fifo::default(),
            last_finite: 0.0,
            n_in: 0,
            n_out: 0,
            integral: 0.0,
            int_carry: [0.0; INTEGRAL_STEP],
            int_carry_len: 0,
            int_w: 0.0,
            int_s1: 0.0,
            int_s2: 0.0,
            int_lambda: (-(INTEGRAL_STEP as f64) * tau0 / cfg.stats_window_s).exp(),
            scratch: Vec::new(),
            flushed: false,
        })
    }

    /// The config this splitter runs.
    pub fn config(&self) -> &QnConfig {
        &self.cfg
    }
    /// Decomposition depth J.
    pub fn levels(&self) -> u32 {
        self.bank.levels()
    }
    /// Fixed latency in samples, `(L-1)(2^J-1)`: output k appears once raw sample
    /// `k + latency` has been pushed.
    pub fn latency(&self) -> usize {
        self.bank.latency()
    }
    /// Raw samples pushed.
    pub fn samples_in(&self) -> u64 {
        self.n_in
    }
    /// Output samples emitted (per channel).
    pub fn samples_out(&self) -> u64 {
        self.n_out
    }

    /// Push raw rate samples (arcsec/s); append every completed output sample to
    /// `clean` and `noise` (same count to each, aligned with the raw input delayed
    /// by [`QnSplitter::latency`]). A non-finite input sample is replaced inside the
    /// bank by the last finite one (so it cannot poison the statistics); it comes
    /// out unchanged in `noise` (`raw - clean`) at that sample only.
    pub fn push(&mut self, raw: &[f64], clean: &mut Vec<f64>, noise: &mut Vec<f64>) {
        assert!(!self.flushed, "QnSplitter::push after flush");
        self.n_in += raw.len() as u64;
        let mut rest = raw;
        if let Phase::Start(buf) = &mut self.phase {
            let take = (self.frame - buf.len()).min(rest.len());
            buf.extend_from_slice(&rest[..take]);
            rest = &rest[take..];
            if buf.len() < self.frame {
                return;
            }
            let first = std::mem::take(buf);
            self.phase = Phase::Running;
            self.start(&first, clean, noise);
        }
        if !rest.is_empty() {
            self.feed(rest, clean, noise);
        }
    }

    fn start(&mut self, first: &[f64], clean: &mut Vec<f64>, noise: &mut Vec<f64>) {
        let (sum, k) = first
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0, 0usize), |(s, k), v| (s + v, k + 1));
        let c = if k > 0 { sum / k as f64 } else { 0.0 };
        self.last_finite = c;
        let pad = vec![c; self.frame];
        self.hook.collecting = false;
        self.scratch.clear();
        for _ in 0..self.warmup / self.frame {
            self.bank.push_with(&pad, &mut self.scratch, &mut self.hook);
        }
        self.hook.collecting = true;
        self.feed(first, clean, noise);
    }

    fn feed(&mut self, x: &[f64], clean: &mut Vec<f64>, noise: &mut Vec<f64>) {
        self.raw.push(x);
        if x.iter().all(|v| v.is_finite()) {
            if let Some(&v) = x.last() {
                self.last_finite = v;
            }
            self.bank.push_with(x, &mut self.scratch, &mut self.hook);
        } else {
            // A non-finite sample would poison the running statistics for good: the
            // bank sees the last finite sample instead; `noise = raw - clean` then
            // carries the non-finite value at that sample only.
            let mut held = Vec::with_capacity(x.len());
            for &v in x {
                if v.is_finite() {
                    self.last_finite = v;
                }
                held.push(self.last_finite);
            }
            self.bank
                .push_with(&held, &mut self.scratch, &mut self.hook);
        }
        self.emit(clean, noise);
    }

    fn emit(&mut self, clean: &mut Vec<f64>, noise: &mut Vec<f64>) {
        let drop = self.drop_out.min(self.scratch.len());
        self.drop_out -= drop;
        let out = &self.scratch[drop..];
        let n = out.len().min(self.raw.len());
        let (out, raw) = (&out[..n], &self.raw.as_slice()[..n]);
        clean.extend_from_slice(out);
        let start = noise.len();
        noise.extend(raw.iter().zip(out).map(|(r, c)| r - c));
        self.raw.advance(n);
        self.n_out += n as u64;
        self.scratch.clear();
        if self.hook.collecting {
            self.integrate(&noise[start..]);
        }
    }

    /// Running integral of `noise` (angle), sampled every [`INTEGRAL_STEP`] output
    /// samples (steps aligned to the output index, so block splits do not matter),
    /// with exponentially weighted first and second moments.
    fn integrate(&mut self, z: &[f64]) {
        let mut z = z;
        if self.int_carry_len > 0 {
            let take = (INTEGRAL_STEP - self.int_carry_len).min(z.len());
            self.int_carry[self.int_carry_len..self.int_carry_len + take]
                .copy_from_slice(&z[..take]);
            self.int_carry_len += take;
            z = &z[take..];
            if self.int_carry_len < INTEGRAL_STEP {
                return;
            }
            let s = step_sum(&self.int_carry);
            self.int_step(s);
            self.int_carry_len = 0;
        }
        let chunks = z.chunks_exact(INTEGRAL_STEP);
        let rem = chunks.remainder();
        for c in chunks {
            let s = step_sum(c.try_into().expect("chunk of INTEGRAL_STEP"));
            self.int_step(s);
        }
        self.int_carry[..rem.len()].copy_from_slice(rem);
        self.int_carry_len = rem.len();
    }

    #[inline]
    fn int_step(&mut self, sum: f64) {
        self.integral += sum * self.hook.tau0;
        let lam = self.int_lambda;
        self.int_w = lam * self.int_w + 1.0;
        self.int_s1 = lam * self.int_s1 + self.integral;
        self.int_s2 = lam * self.int_s2 + self.integral * self.integral;
    }

    /// End of stream: extend by the mean of the last frame and emit every remaining
    /// output sample. Statistics and gains are frozen during the flush. Further
    /// pushes are a bug (they panic).
    pub fn flush(&mut self, clean: &mut Vec<f64>, noise: &mut Vec<f64>) {
        if self.flushed {
            return;
        }
        if let Phase::Start(buf) = &mut self.phase {
            // Shorter than one frame: start with what there is.
            let first = std::mem::take(buf);
            self.phase = Phase::Running;
            if first.is_empty() {
                self.flushed = true;
                return;
            }
            self.start(&first, clean, noise);
        }
        self.hook.collecting = false;
        // Mean of the last frame (or of every sample still buffered, if fewer).
        let k = self.raw.len().min(self.frame);
        let live = self.raw.as_slice();
        let (sum, m) = live[live.len() - k..]
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0, 0usize), |(s, m), v| (s + v, m + 1));
        let c = if m == 0 {
            self.last_finite
        } else {
            sum / m as f64
        };
        let pad = vec![c; self.frame];
        while self.n_out < self.n_in {
            self.bank.push_with(&pad, &mut self.scratch, &mut self.hook);
            self.emit(clean, noise);
        }
        self.flushed = true;
    }

    /// Per-band statistics: the bank's detail levels `1..=J` (finest first), then the
    /// estimation-only levels `J+1..=J+EXTRA_LEVELS` (gain reported as 1: they are
    /// part of the untouched approximation), then the approximation (`level = J+1`
    /// would be ambiguous, so it is reported with `level = 0`).
    pub fn level_stats(&self) -> Vec<LevelStats> {
        let h = &self.hook;
        let fs = self.cfg.sample_rate_hz;
        (0..=h.nd)
            .map(|j| {
                let approx = j == h.nd;
                let hi = if approx {
                    fs / (1u64 << (h.levels + 1)) as f64
                } else {
                    fs / (1u64 << (j + 1)) as f64
                };
                let lo = if approx { 0.0 } else { hi / 2.0 };
                LevelStats {
                    level: if approx { 0 } else { j as u32 + 1 },
                    band_lo_hz: lo,
                    band_hi_hz: hi,
                    weight: h.ew_n[j],
                    var_total: h.var_total[j],
                    var_qn: if j < h.levels { h.var_qn[j] } else { 0.0 },
                    kappa: h.kappa[j],
                    gain: if j < h.levels { h.gain[j] } else { 1.0 },
                }
            })
            .collect()
    }

    /// Q and ARW estimates from the running statistics (`None` until ready).
    pub fn estimates(&self) -> QnEstimates {
        let h = &self.hook;
        let q_integral = (self.int_w > 0.0).then(|| {
            let m = self.int_s1 / self.int_w;
            (self.int_s2 / self.int_w - m * m).max(0.0).sqrt()
        });
        QnEstimates {
            q_white_arcsec: h.q2_white().map(f64::sqrt),
            q_integral_arcsec: q_integral,
            arw_floor_dpsh: h.arw_floor.map(|a| (a * h.tau0).sqrt() / 60.0),
        }
    }
}
