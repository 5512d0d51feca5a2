//! The statistics the diagnosis compares, computed identically on the
//! recording and on every Monte-Carlo run of the model (so that whatever the
//! estimators do to quantization noise of any shape, the reference does too):
//! their whole-record definitions, and the layout and kernels
//! [`super::stream`] computes them with as a record streams past.
//!
//! Per record ([`StatSet`], laid out by a [`StatLayout`]):
//! * **wavelet variances**: mean squares of the sym8 detail coefficients of the
//!   rate (arcsec/s = deg/h), level by level, over the coefficients free of
//!   edge effects (valid convolution). sym8's sharp octave bands keep the
//!   quantization noise, whose rate PSD rises as f^2, out of the low levels;
//! * the **modified Allan variance** (phase-averaged: white angle noise falls
//!   as tau^-3) and the **overlapping Allan variance** (what users plot; the
//!   diagnosis only reports it), at octave averaging factors;
//! * the **Welch periodogram** of the rate (Hann window, 50 % overlap), kept
//!   bin by bin for the line search and averaged in quarter-octave bands;
//! * the least-squares **rate slope** (ramp), and the regression slope of the
//!   rate on the recording's temperature when there is one.
//!
//! Everything here is plain batch code on whole records; [`dwt_level_mean_squares`]
//! and [`Welch`] are checked against closed forms in `tests/diagnose/stats.rs`.

use std::f64::consts::PI;
use std::ops::Range;
use std::sync::Arc;

use rustfft::num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use super::lowfreq::LfLayout;
use crate::allan::{self, Phase, Stat};
use crate::model::estimate::RampAccumulator;

/// The sym8 analysis filters `(dec_lo, dec_hi)` (PyWavelets convention),
/// from the project's wavelet table.
pub fn sym8() -> (Vec<f64>, Vec<f64>) {
    let w = crate::dsp::wavelet::Wavelet::by_name("sym8").expect("sym8 is in the wavelet table");
    (w.dec_lo().to_vec(), w.dec_hi().to_vec())
}

/// Detail-coefficient mean squares of a decimated DWT of `x`, using only the
/// coefficients of the valid (edge-free) convolution at every level.
///
/// Returns `(level, n_coef, mean_sq)` for levels 1, 2, ... while a level has at
/// least `min_coef` coefficients (at most `max_levels` levels). The alignment
/// (correlation `sum_k f[k] a[2n + k]`) differs from PyWavelets' by a shift and
/// a reversal, which changes neither the power response `|H_j|^2` nor, for a
/// stationary input, the expected mean squares ([`crate::model::wvar`]).
pub fn dwt_level_mean_squares(
    x: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_levels: u32,
    min_coef: usize,
) -> Vec<(u32, usize, f64)> {
    dwt_level_mean_squares_of(x.to_vec(), lo, hi, max_levels, min_coef)
}

/// [`dwt_level_mean_squares`] of `a`, transformed in place (no copy of a
/// whole record).
pub fn dwt_level_mean_squares_of(
    mut a: Vec<f64>,
    lo: &[f64],
    hi: &[f64],
    max_levels: u32,
    min_coef: usize,
) -> Vec<(u32, usize, f64)> {
    let l = lo.len();
    let mut len = a.len();
    let mut out = Vec::new();
    for level in 1..=max_levels {
        if len < l {
            break;
        }
        let n_out = (len - l) / 2 + 1;
        if n_out < min_coef {
            break;
        }
        let ss = analysis_step_any(&mut a, n_out, lo, hi, 0.0);
        len = n_out;
        out.push((level, n_out, ss / n_out as f64));
    }
    out
}

/// One analysis step in place: `a[n] <- sum lo[k] a[2n+k]` for `n < n_out`;
/// returns `ss` plus the squared details, added in order (so a stream that
/// carries `ss` from call to call sums exactly as one whole call).
pub(crate) fn analysis_step_any(
    a: &mut [f64],
    n_out: usize,
    lo: &[f64],
    hi: &[f64],
    ss: f64,
) -> f64 {
    if lo.len() == 16 {
        let lo16: &[f64; 16] = lo.try_into().expect("16 taps");
        let hi16: &[f64; 16] = hi.try_into().expect("16 taps");
        analysis_step16(a, n_out, lo16, hi16, ss)
    } else {
        analysis_step(a, n_out, lo, hi, ss)
    }
}

/// [`analysis_step_any`] for any filter length. In place is safe: `a[n]` is
/// never read again (later windows start at `2n' > n`).
fn analysis_step(a: &mut [f64], n_out: usize, lo: &[f64], hi: &[f64], mut ss: f64) -> f64 {
    let l = lo.len();
    for n in 0..n_out {
        let w = &a[2 * n..2 * n + l];
        let mut s_lo = 0.0;
        let mut s_hi = 0.0;
        for k in 0..l {
            s_lo += lo[k] * w[k];
            s_hi += hi[k] * w[k];
        }
        ss += s_hi * s_hi;
        a[n] = s_lo;
    }
    ss
}

/// [`analysis_step`] for 16-tap filters (fixed size: the compiler unrolls it).
fn analysis_step16(
    a: &mut [f64],
    n_out: usize,
    lo: &[f64; 16],
    hi: &[f64; 16],
    mut ss: f64,
) -> f64 {
    for n in 0..n_out {
        let w: &[f64; 16] = a[2 * n..2 * n + 16].try_into().expect("16 samples");
        let mut s_lo = [0.0f64; 4];
        let mut s_hi = [0.0f64; 4];
        for k in 0..4 {
            for q in 0..4 {
                s_lo[q] += lo[4 * k + q] * w[4 * k + q];
                s_hi[q] += hi[4 * k + q] * w[4 * k + q];
            }
        }
        let h = (s_hi[0] + s_hi[1]) + (s_hi[2] + s_hi[3]);
        ss += h * h;
        a[n] = (s_lo[0] + s_lo[1]) + (s_lo[2] + s_lo[3]);
    }
    ss
}

/// The approximation (low-pass) coefficients of `x` at `level`, valid part only.
pub fn dwt_approximation(x: &[f64], lo: &[f64], level: u32) -> Vec<f64> {
    let l = lo.len();
    let mut a = x.to_vec();
    for _ in 0..level {
        if a.len() < l {
            a.clear();
            break;
        }
        let n_out = (a.len() - l) / 2 + 1;
        for n in 0..n_out {
            let w = &a[2 * n..2 * n + l];
            a[n] = lo.iter().zip(w).map(|(c, v)| c * v).sum();
        }
        a.truncate(n_out);
    }
    a
}

/// A Welch periodogram plan: Hann window of `seg` samples (a power of two),
/// 50 % overlap, one-sided PSD.
#[derive(Clone)]
pub struct Welch {
    seg: usize,
    fft: Arc<dyn Fft<f64>>,
    window: Vec<f64>,
    /// `sum w^2`.
    wss: f64,
}

impl std::fmt::Debug for Welch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Welch").field("seg", &self.seg).finish()
    }
}

impl Welch {
    /// A plan for segments of `seg` samples.
    pub fn new(seg: usize) -> Welch {
        let mut planner = FftPlanner::new();
        let fft = planner.plan_fft_forward(seg);
        let window: Vec<f64> = (0..seg)
            .map(|n| 0.5 - 0.5 * (2.0 * PI * n as f64 / seg as f64).cos())
            .collect();
        let wss = window.iter().map(|w| w * w).sum();
        Welch {
            seg,
            fft,
            window,
            wss,
        }
    }

    /// Segment length.
    pub fn seg(&self) -> usize {
        self.seg
    }

    /// Number of segments for `n` samples.
    pub fn segments(&self, n: usize) -> usize {
        if n < self.seg {
            0
        } else {
            (n - self.seg) / (self.seg / 2) + 1
        }
    }

    /// One-sided PSD at bins `0..=seg/2` (units of x^2 per Hz), averaged over
    /// the segments of `x` (mean removed first). Two real segments share one
    /// complex FFT.
    pub fn psd(&self, x: &[f64], fs: f64) -> Vec<f64> {
        let half = self.seg / 2;
        let k_seg = self.segments(x.len());
        let mut acc = vec![0.0; half + 1];
        if k_seg == 0 {
            return acc;
        }
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let mut work = self.work();
        let mut s = 0;
        while s < k_seg {
            let a = &x[s * half..s * half + self.seg];
            let b = (s + 1 < k_seg).then(|| &x[(s + 1) * half..(s + 1) * half + self.seg]);
            self.accumulate(a, b, mean, &mut work, &mut acc);
            s += 2;
        }
        self.scale(&mut acc, k_seg, fs);
        acc
    }

    /// Scratch for [`Welch::accumulate`].
    pub(crate) fn work(&self) -> WelchWork {
        WelchWork {
            buf: vec![Complex64::new(0.0, 0.0); self.seg],
            scratch: vec![Complex64::new(0.0, 0.0); self.fft.get_inplace_scratch_len()],
        }
    }

    /// Add the periodograms of segment `a` and (when given) `b`, `offset`
    /// removed, to `acc` (bins `0..=seg/2`, unscaled). The Hann window's
    /// transform vanishes beyond bin 1, so an offset other than the mean
    /// changes bins 0 and 1 only.
    pub(crate) fn accumulate(
        &self,
        a: &[f64],
        b: Option<&[f64]>,
        offset: f64,
        work: &mut WelchWork,
        acc: &mut [f64],
    ) {
        let seg = self.seg;
        let half = seg / 2;
        let buf = &mut work.buf;
        for n in 0..seg {
            let re = (a[n] - offset) * self.window[n];
            let im = b.map_or(0.0, |b| (b[n] - offset) * self.window[n]);
            buf[n] = Complex64::new(re, im);
        }
        self.fft.process_with_scratch(buf, &mut work.scratch);
        for k in 0..=half {
            let xk = buf[k];
            let xm = buf[(seg - k) % seg].conj();
            let fa = (xk + xm) * 0.5;
            acc[k] += fa.norm_sqr();
            if b.is_some() {
                let fb = (xk - xm) * Complex64::new(0.0, -0.5);
                acc[k] += fb.norm_sqr();
            }
        }
    }

    /// Scale accumulated periodograms of `k_seg` segments to a one-sided PSD.
    pub(crate) fn scale(&self, acc: &mut [f64], k_seg: usize, fs: f64) {
        let half = self.seg / 2;
        let scale = 1.0 / (fs * self.wss * k_seg as f64);
        for (k, v) in acc.iter_mut().enumerate() {
            let one_sided = if k == 0 || k == half { 1.0 } else { 2.0 };
            *v *= scale * one_sided;
        }
    }
}

/// Scratch buffers of one Welch FFT.
pub(crate) struct WelchWork {
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

/// A quarter-octave band of Welch bins.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    pub f_lo_hz: f64,
    pub f_hi_hz: f64,
    /// Bins averaged (those not masked as quantization lines).
    pub bins: Vec<usize>,
}

/// Which statistics a [`StatSet`] holds, and where.
#[derive(Debug, Clone)]
pub struct StatLayout {
    pub fs_hz: f64,
    pub pulse_arcsec: f64,
    pub n_samples: usize,
    /// Wavelet levels (1-based) and their valid coefficient counts.
    pub levels: Vec<u32>,
    pub n_coef: Vec<usize>,
    /// Averaging factors of the (modified) Allan variances.
    pub ms: Vec<u64>,
    pub welch: Welch,
    /// Segments averaged by the Welch estimate.
    pub welch_segments: usize,
    /// Fine bins compared, `k_lo..k_hi`.
    pub k_lo: usize,
    pub k_hi: usize,
    /// `mask[k - k_lo]`: bin usable (false near the counter's own lines).
    pub mask: Vec<bool>,
    pub bands: Vec<Band>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    /// The low-frequency periodogram rows below the deepest level ([`super::lowfreq`]).
    pub lf: LfLayout,
    /// The recording's made-up samples (gap fill, replaced glitches): every
    /// Monte-Carlo run makes up the same ones the same way ([`refill`]).
    pub filled: Vec<Range<usize>>,
    /// The record is of rate words (made-up samples interpolated), not pulse
    /// increments (made-up samples share their span's total).
    pub rate_words: bool,
}

/// Make up a simulated run's samples in `filled` as the recording's were: a
/// counter's increments over a span share its total (the angle at its end
/// kept, as the gap fill and the glitch replacement do), rate words are
/// interpolated between the span's neighbours (a single glitch: their mean).
/// The recording and its Monte-Carlo runs then hold made-up samples at the
/// same places, made the same way, and every statistic compares like with like.
pub fn refill(counts: &mut [i64], filled: &[Range<usize>], rate_words: bool) {
    let n = counts.len();
    for r in filled {
        let (a, b) = (r.start.min(n), r.end.min(n));
        if a >= b {
            continue;
        }
        let left = (a > 0).then(|| counts[a - 1]);
        let right = (b < n).then(|| counts[b]);
        fill_span(&mut counts[a..b], left, right, rate_words);
    }
}

/// Make up one span's samples ([`refill`]) from its neighbours `left` (none
/// at the record's start) and `right` (none at its end).
pub(crate) fn fill_span(span: &mut [i64], left: Option<i64>, right: Option<i64>, rate_words: bool) {
    if rate_words {
        let last = *span.last().expect("a span is not empty");
        let left = left.or(right).unwrap_or(last);
        let right = right.unwrap_or(left);
        let len = (span.len() + 1) as f64;
        for (j, c) in span.iter_mut().enumerate() {
            let w = (j + 1) as f64 / len;
            *c = ((1.0 - w) * left as f64 + w * right as f64).round() as i64;
        }
    } else {
        let total: i64 = span.iter().sum();
        let shares = crate::dsp::gaps::spread_increment(total, span.len() as u32);
        for (c, s) in span.iter_mut().zip(shares) {
            *c = s;
        }
    }
}

/// Smallest count of valid coefficients for a wavelet level to be compared.
pub const MIN_LEVEL_COEFS: usize = 8;

impl StatLayout {
    /// The layout for a record of `n` samples at `fs_hz` (no line mask yet).
    pub fn new(n: usize, fs_hz: f64, pulse_arcsec: f64) -> StatLayout {
        let (lo, hi) = sym8();
        let probe = dwt_counts(n, lo.len(), MIN_LEVEL_COEFS);
        let levels: Vec<u32> = (1..=probe.len() as u32).collect();
        let n_phase = n as u64 + 1;
        let top_o = allan::max_m(Stat::Oadev, n_phase);
        let top_m = allan::max_m(Stat::Mdev, n_phase);
        // long-tau points with fewer than ~8 independent terms carry little and
        // have badly skewed sampling laws: stop at N/8
        let top = top_o.min(top_m).min((n / 8) as u64);
        let mut ms = Vec::new();
        let mut m = 1u64;
        while m <= top {
            ms.push(m);
            m *= 2;
        }
        // Welch: at least 15 segments (50 % overlap), at most 2^16 samples
        let mut seg = 64usize;
        while seg * 2 <= 65_536 && (n / (seg * 2)) * 2 >= 16 {
            seg *= 2;
        }
        let welch = Welch::new(seg);
        let welch_segments = welch.segments(n);
        let k_lo = 2;
        let k_hi = seg / 2; // exclusive: Nyquist bin left out
        let mask = vec![true; k_hi - k_lo];
        let lf = LfLayout::new(n, fs_hz, probe.len() as u32);
        let mut lay = StatLayout {
            fs_hz,
            pulse_arcsec,
            n_samples: n,
            levels,
            n_coef: probe,
            ms,
            welch,
            welch_segments,
            k_lo,
            k_hi,
            mask,
            bands: Vec::new(),
            lo,
            hi,
            lf,
            filled: Vec::new(),
            rate_words: false,
        };
        lay.rebuild_bands();
        lay
    }

    /// Frequency of Welch bin `k`, Hz.
    pub fn bin_hz(&self, k: usize) -> f64 {
        k as f64 * self.fs_hz / self.welch.seg() as f64
    }

    /// Bin width, Hz.
    pub fn bin_width_hz(&self) -> f64 {
        self.fs_hz / self.welch.seg() as f64
    }

    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        1.0 / self.fs_hz
    }

    /// Record length, s.
    pub fn duration_s(&self) -> f64 {
        self.n_samples as f64 / self.fs_hz
    }

    /// Mask the bins within `half_width_hz` of `f_hz` (aliased into `[0, fs/2]`).
    pub fn mask_line(&mut self, f_hz: f64, half_width_hz: f64) {
        let fs = self.fs_hz;
        let mut f = f_hz.rem_euclid(fs);
        if f > fs / 2.0 {
            f = fs - f;
        }
        let df = self.bin_width_hz();
        let k0 = ((f - half_width_hz) / df).floor().max(0.0) as usize;
        let k1 = ((f + half_width_hz) / df).ceil() as usize;
        for k in k0..=k1 {
            if k >= self.k_lo && k < self.k_hi {
                self.mask[k - self.k_lo] = false;
            }
        }
    }

    /// Recompute the quarter-octave bands from the mask.
    pub fn rebuild_bands(&mut self) {
        self.bands.clear();
        let f0 = self.bin_hz(self.k_lo);
        let f_top = self.bin_hz(self.k_hi);
        let mut i = 0;
        let mut last_bin: Option<usize> = None;
        loop {
            let a = f0 * 2f64.powf(i as f64 / 4.0);
            let b = f0 * 2f64.powf((i + 1) as f64 / 4.0);
            if a >= f_top {
                break;
            }
            // one guard bin after the previous band: Hann bins one apart are
            // correlated (4/9), two apart hardly (1/36), so bands stay independent
            let first_ok = last_bin.map_or(0, |l| l + 2);
            let bins: Vec<usize> = (self.k_lo..self.k_hi)
                .filter(|&k| {
                    let f = self.bin_hz(k);
                    k >= first_ok && f >= a && f < b && self.mask[k - self.k_lo]
                })
                .collect();
            if let Some(&l) = bins.last() {
                last_bin = Some(l);
            }
            if !bins.is_empty() {
                self.bands.push(Band {
                    f_lo_hz: a,
                    f_hi_hz: b.min(f_top),
                    bins,
                });
            }
            i += 1;
        }
    }
}

/// Valid coefficient counts per level for `n` samples and filter length `l`.
fn dwt_counts(n: usize, l: usize, min_coef: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut len = n;
    while len >= l {
        let n_out = (len - l) / 2 + 1;
        if n_out < min_coef {
            break;
        }
        out.push(n_out);
        len = n_out;
    }
    out
}

/// The statistics of one record (recording or simulation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StatSet {
    /// Wavelet detail mean squares per level, (arcsec/s)^2.
    pub wvar: Vec<f64>,
    /// Modified Allan variance per averaging factor, (arcsec/s)^2.
    pub mvar: Vec<f64>,
    /// Overlapping Allan variance per averaging factor, (arcsec/s)^2.
    pub avar: Vec<f64>,
    /// Welch PSD at bins `k_lo..k_hi`, (arcsec/s)^2/Hz.
    pub psd: Vec<f64>,
    /// Band means of `psd`.
    pub band_psd: Vec<f64>,
    /// Mean rate, arcsec/s.
    pub mean_rate: f64,
    /// Least-squares rate slope, arcsec/s^2.
    pub slope: f64,
    /// Regression slope of the rate on the temperature, arcsec/s per deg C.
    pub temp_slope: Option<f64>,
    /// Excess kurtosis of the low-passed rate, one per requested cut-off.
    pub kurtosis: Vec<f64>,
    /// Band means of the low-frequency periodogram, (arcsec/s)^2/Hz.
    pub lf_psd: Vec<f64>,
    /// Two-level likelihood ratio for the job's probe
    /// ([`super::two_level::TwoLevelProbe::llr`]); NaN without one.
    pub two_level_llr: f64,
}

/// Rate in arcsec/s from pulse increments.
pub fn counts_to_rate(counts: &[i64], pulse_arcsec: f64, fs_hz: f64) -> Vec<f64> {
    let g = pulse_arcsec * fs_hz;
    counts.iter().map(|&c| c as f64 * g).collect()
}

/// Cumulative pulse count (phase in pulses), leading 0.
pub fn counts_to_cumulative(counts: &[i64]) -> Vec<i64> {
    let mut out = Vec::with_capacity(counts.len() + 1);
    let mut acc = 0i64;
    out.push(0);
    for &c in counts {
        acc += c;
        out.push(acc);
    }
    out
}

/// Compute every statistic of `layout` for one record. `temp_c`, when given,
/// is the temperature regressor (one value per sample); `lp_cutoffs_hz` lists
/// the low-pass cut-offs of the kurtosis statistics.
pub fn compute(
    layout: &StatLayout,
    counts: &[i64],
    temp_c: Option<&[f64]>,
    lp_cutoffs_hz: &[f64],
) -> StatSet {
    let fs = layout.fs_hz;
    let tau0 = 1.0 / fs;
    let d = layout.pulse_arcsec;
    // one whole-record array beside the counts at a time: the phase, then
    // the rate, which the wavelet transform takes over last
    let phase = Phase::Counts(counts_to_cumulative(counts));
    let dev = |stat: Stat, m: u64| -> f64 {
        allan::deviation(&phase, stat, tau0, m)
            .map(|(dv, _)| (dv * d) * (dv * d))
            .unwrap_or(f64::NAN)
    };
    let mvar: Vec<f64> = layout.ms.iter().map(|&m| dev(Stat::Mdev, m)).collect();
    let avar: Vec<f64> = layout.ms.iter().map(|&m| dev(Stat::Oadev, m)).collect();
    drop(phase);
    let rate = counts_to_rate(counts, d, fs);
    let full = layout.welch.psd(&rate, fs);
    let psd: Vec<f64> = full[layout.k_lo..layout.k_hi].to_vec();
    let band_psd = band_means(layout, &psd);
    let mut ramp = RampAccumulator::default();
    ramp.push_slice(&rate);
    let temp_slope = temp_c.map(|t| regression_slope(t, &rate));
    let kurtosis = lp_cutoffs_hz
        .iter()
        .map(|&fc| lowpass_kurtosis(&rate, tau0, fc, &layout.lo))
        .collect();
    let lf_psd = layout.lf.psd(&rate);
    let lv = dwt_level_mean_squares_of(
        rate,
        &layout.lo,
        &layout.hi,
        layout.levels.len() as u32,
        MIN_LEVEL_COEFS,
    );
    StatSet {
        wvar: lv.iter().map(|t| t.2).collect(),
        mvar,
        avar,
        psd,
        band_psd,
        mean_rate: ramp.mean(),
        slope: ramp.slope_per_sample() / tau0,
        temp_slope,
        kurtosis,
        lf_psd,
        two_level_llr: f64::NAN,
    }
}

/// Band means of fine-bin PSD values (`psd[k - k_lo]`).
pub fn band_means(layout: &StatLayout, psd: &[f64]) -> Vec<f64> {
    layout
        .bands
        .iter()
        .map(|b| b.bins.iter().map(|&k| psd[k - layout.k_lo]).sum::<f64>() / b.bins.len() as f64)
        .collect()
}

/// Least-squares slope of `y` on `x`.
pub fn regression_slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 2 {
        return 0.0;
    }
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for i in 0..n {
        let dx = x[i] - mx;
        sxy += dx * (y[i] - my);
        sxx += dx * dx;
    }
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

/// Excess kurtosis of the rate low-passed at `fc_hz` and sampled every
/// `1/(2 fc)`: the two-level (random telegraph) test statistic. The rate is
/// first reduced with the sym8 low-pass cascade (which keeps the quantization
/// noise out: a plain block average would alias it down), then filtered with a
/// Gaussian low-pass (-3 dB at `fc`) by FFT; the ends (two filter widths) are
/// dropped. Returns NaN when fewer than 16 samples remain.
pub fn lowpass_kurtosis(rate: &[f64], tau0_s: f64, fc_hz: f64, lo: &[f64]) -> f64 {
    let level = kurtosis_level(tau0_s, fc_hz);
    let a = dwt_approximation(rate, lo, level);
    lowpass_kurtosis_of(&a, tau0_s * 2f64.powi(level as i32), fc_hz)
}

/// The approximation level [`lowpass_kurtosis`] reads for `fc_hz`: the
/// deepest whose sample spacing still resolves `4 fc`.
pub fn kurtosis_level(tau0_s: f64, fc_hz: f64) -> u32 {
    let mut level = 0u32;
    while tau0_s * 2f64.powi(level as i32 + 1) <= 1.0 / (8.0 * fc_hz) {
        level += 1;
    }
    level
}

/// [`lowpass_kurtosis`] from the approximation coefficients `a`, spaced `dt` s.
pub fn lowpass_kurtosis_of(a: &[f64], dt: f64, fc_hz: f64) -> f64 {
    let n = a.len();
    if n < 32 {
        return f64::NAN;
    }
    let mean = a.iter().sum::<f64>() / n as f64;
    let size = (2 * n).next_power_of_two();
    let mut buf: Vec<Complex64> = a.iter().map(|&v| Complex64::new(v - mean, 0.0)).collect();
    buf.resize(size, Complex64::new(0.0, 0.0));
    let mut planner = FftPlanner::new();
    planner.plan_fft_forward(size).process(&mut buf);
    // Gaussian |H| = exp(-ln2/2 (f/fc)^2): power -3 dB at fc
    let c = std::f64::consts::LN_2 / 2.0;
    for (k, v) in buf.iter_mut().enumerate() {
        let kk = if k <= size / 2 { k } else { size - k };
        let f = kk as f64 / (size as f64 * dt);
        *v *= (-c * (f / fc_hz).powi(2)).exp() / size as f64;
    }
    planner.plan_fft_inverse(size).process(&mut buf);
    let edge = ((2.0 / fc_hz) / dt).ceil() as usize;
    let step = ((1.0 / (2.0 * fc_hz)) / dt).floor().max(1.0) as usize;
    if 2 * edge >= n {
        return f64::NAN;
    }
    let xs: Vec<f64> = (edge..n - edge).step_by(step).map(|i| buf[i].re).collect();
    excess_kurtosis(&xs)
}

/// Sample excess kurtosis `m4 / m2^2 - 3` (NaN below 16 values).
pub fn excess_kurtosis(x: &[f64]) -> f64 {
    if x.len() < 16 {
        return f64::NAN;
    }
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let (mut m2, mut m4) = (0.0, 0.0);
    for &v in x {
        let d2 = (v - m) * (v - m);
        m2 += d2;
        m4 += d2 * d2;
    }
    m2 /= n;
    m4 /= n;
    if m2 > 0.0 {
        m4 / (m2 * m2) - 3.0
    } else {
        f64::NAN
    }
}

/// Plain DFT `sum x_k e^{-2 pi i f k tau0}` (the phasor re-anchored every
/// 4096 samples against round-off).
pub fn dft_plain(x: &[f64], tau0: f64, f: f64) -> Complex64 {
    let step = Complex64::from_polar(1.0, -2.0 * PI * f * tau0);
    let mut ph = Complex64::new(1.0, 0.0);
    let mut acc = Complex64::new(0.0, 0.0);
    for (k, &v) in x.iter().enumerate() {
        acc += ph * v;
        ph *= step;
        if k % 4096 == 4095 {
            ph = Complex64::from_polar(1.0, -2.0 * PI * f * tau0 * (k + 1) as f64);
        }
    }
    acc
}
