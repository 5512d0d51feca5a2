//! Spectral lines at the whole record's resolution: find narrow
//! lines (sinusoids) the model does not have, from about ten cycles per record
//! up to the Nyquist frequency, and measure them with intervals from their
//! Fisher information.
//!
//! # Method
//! 1. **Spectrum** ([`LineSpectrum::new`]): the rate, mean and linear trend
//!    removed, Hann-windowed, one FFT of the whole record (`N` samples, bins
//!    `f_k = k / T`): the one-sided periodogram `P_k = 2 |X_k|^2 / (fs sum w^2)`
//!    (`E P_k = S(f_k)` for a smooth PSD `S`). It is whitened by the model's
//!    own PSD (its Gaussian terms, [`crate::model::spectrum::model_spectral_terms`]), so that a
//!    steep continuum (flicker, random walk) is flat around every bin.
//! 2. **Detection** ([`search`]): each usable bin `k` (not in a masked
//!    interval, e.g. the counter's own harmonic lines) is compared with its
//!    local level, the median of the whitened ordinates at the odd offsets
//!    `+-3, +-5, ..., +-(2W+1)` (symmetric, so a sloped residual continuum
//!    cancels to first order; two bins apart the Hann ordinates are almost
//!    uncorrelated, 1/36, and three bins from a line its leakage is 31 dB
//!    down). Under a locally smooth Gaussian continuum the ordinates are
//!    independent exponentials, so with `r_(m)` the `m`-th smallest of the `n`
//!    reference values (`m = ceil(n/2)`) the tail probability of
//!    `c = r_k / r_(m)` is exact:
//!    `P(c > x) = E exp(-x E_(m)) = prod_{j<m} (n - j) / (n - j + x)`.
//!    A bin is a line when that probability is below `alpha / (O M_o)`: a
//!    weighted Bonferroni correction, `alpha` family-wise, that shares the
//!    budget equally among the `O` octaves of frequency searched and within
//!    octave `o` among its `M_o` bins (a slow line is not charged for the
//!    bins up to Nyquist). Only local maxima are
//!    kept, and a weaker peak within the Hann sidelobe reach of a stronger one
//!    is dropped. A cheap block-median pre-screen picks the candidate bins.
//! 3. **Measurement** ([`fit_line`]): the frequency maximises the periodogram
//!    of the detrended rate near the peak, with a light (10 % Tukey) taper,
//!    i.e. a nearly least-squares sinusoid fit (a grid over +-1 bin, then
//!    golden section); the sampled amplitude is `2 |D_w(f)| / sum w`, divided
//!    by the sample average's response `sinc(pi f tau0)` to give the rate
//!    sinusoid's amplitude. The **Fisher information** of `A cos(2 pi f t + phi)` in
//!    white noise of variance `s2` per sample (`N` samples, `T = N tau0`)
//!    gives `var A = 2 s2 / N` and
//!    `var f = 24 s2 / ((2 pi)^2 A^2 N^3 tau0^2)` (Kay, eq. 3.41); the noise
//!    that matters is the local one, `s2 = S_loc fs / 2` with `S_loc` the
//!    local level around the line (the reference median de-biased by
//!    `E r_(m) = sum_{j<m} 1/(n-j)`, times the model PSD there). So
//!    `sd A = sqrt(S_loc / T) / sinc` and
//!    `sd f = sqrt(3 S_loc) / (pi A_s T^1.5)` (`A_s` the sampled amplitude)
//!    for a plain fit; the taper's exact linearised variances are used
//!    (`var A = 2 s2 sum w^2 / (sum w)^2`,
//!    `var omega = 2 s2 sum m^2 w^2 / (A_s^2 (sum m^2 w)^2)`).
//!    The coverage of the 95 % intervals `+-1.96 sd` is checked by simulation
//!    in `tests/diagnose/lines.rs`.

use std::f64::consts::PI;
use std::sync::Arc;

use rustfft::FftPlanner;
use rustfft::num_complex::Complex64;

/// Tuning of [`search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchParams {
    /// Family-wise false-alarm probability over the bins searched.
    pub alpha: f64,
    /// Lowest frequency searched, in cycles per record.
    pub min_cycles: f64,
    /// Reference half-width `W`: odd offsets 3 ..= 2W + 1 on each side.
    pub half_width: usize,
    /// Fewest reference ordinates for a bin to be tested.
    pub min_ref: usize,
}

impl Default for SearchParams {
    fn default() -> Self {
        SearchParams {
            alpha: 0.001,
            min_cycles: 10.0,
            half_width: 64,
            min_ref: 8,
        }
    }
}

/// The whole record's Hann periodogram, whitened by the model's PSD.
#[derive(Debug, Clone)]
pub struct LineSpectrum {
    pub fs_hz: f64,
    /// Samples in the record.
    pub n: usize,
    /// One-sided PSD at `k / T`, `k = 0 ..= n/2`, (arcsec/s)^2/Hz (shared by
    /// the spectra whitened from it).
    pub psd: Arc<Vec<f64>>,
    /// The model's PSD at the same bins.
    pub model_psd: Vec<f64>,
    /// Bin usable (outside every masked interval, model PSD > 0).
    pub usable: Vec<bool>,
}

impl LineSpectrum {
    /// The spectrum of the detrended rate `x` (arcsec/s) sampled at `fs_hz`;
    /// `model_psd(f)` is the model's one-sided PSD at `f` Hz; `masked` lists
    /// `(f_hz, half_width_hz)` intervals left out (aliased into `[0, fs/2]`).
    pub fn new(
        x: &[f64],
        fs_hz: f64,
        model_psd: &dyn Fn(f64) -> f64,
        masked: &[(f64, f64)],
    ) -> LineSpectrum {
        Self::of(x.len(), |i| x[i], fs_hz, model_psd, masked)
    }

    /// [`LineSpectrum::new`] of the series `x(0..n)`, read through a function.
    pub fn of(
        n: usize,
        x: impl Fn(usize) -> f64,
        fs_hz: f64,
        model_psd: &dyn Fn(f64) -> f64,
        masked: &[(f64, f64)],
    ) -> LineSpectrum {
        let scale = 2.0 / (fs_hz * 0.375 * n as f64);
        let psd: Vec<f64> = hann_power(n, x).into_iter().map(|p| p * scale).collect();
        Self::whitened(Arc::new(psd), n, fs_hz, model_psd, masked)
    }

    /// A periodogram `psd` of `n` samples (kept from [`LineSpectrum::new`])
    /// divided by a model's PSD, with other bins masked: no new transform.
    pub fn whitened(
        psd: Arc<Vec<f64>>,
        n: usize,
        fs_hz: f64,
        model_psd: &dyn Fn(f64) -> f64,
        masked: &[(f64, f64)],
    ) -> LineSpectrum {
        let half = n / 2;
        let df = fs_hz / n as f64;
        let model_psd: Vec<f64> = (0..=half).map(|k| model_psd(k as f64 * df)).collect();
        let mut usable: Vec<bool> = model_psd.iter().map(|m| *m > 0.0).collect();
        usable[0] = false;
        for &(f, hw) in masked {
            mask_interval(&mut usable, fold(f, fs_hz), hw, df);
        }
        LineSpectrum {
            fs_hz,
            n,
            psd,
            model_psd,
            usable,
        }
    }

    /// The whitened ordinate `psd / model_psd` of bin `k` (NaN where the
    /// model's PSD is not positive): computed, not stored.
    #[inline]
    pub fn white(&self, k: usize) -> f64 {
        let m = self.model_psd[k];
        if m > 0.0 { self.psd[k] / m } else { f64::NAN }
    }

    /// Bins `0 ..= n/2`.
    pub fn bins(&self) -> usize {
        self.model_psd.len()
    }

    /// Bin width `1 / T`, Hz.
    pub fn df(&self) -> f64 {
        self.fs_hz / self.n as f64
    }

    /// Record length, s.
    pub fn duration_s(&self) -> f64 {
        self.n as f64 / self.fs_hz
    }

    /// The local reference of bin `k`: the median test of module step 2.
    pub fn reference(&self, k: usize, half_width: usize) -> Option<Reference> {
        let last = self.bins() - 1;
        let reach = (2 * half_width + 1).min(k.saturating_sub(1)).min(last - k);
        let mut v: Vec<f64> = (3..=reach)
            .step_by(2)
            .flat_map(|o| [k - o, k + o])
            .filter(|&j| self.usable[j] && self.white(j).is_finite())
            .map(|j| self.white(j))
            .collect();
        if v.is_empty() {
            return None;
        }
        let n = v.len();
        let m = n.div_ceil(2);
        let med = *v.select_nth_unstable_by(m - 1, |a, b| a.total_cmp(b)).1;
        Some(Reference { n, m, value: med })
    }

    /// The local continuum PSD at `f_hz` ((arcsec/s)^2/Hz): the reference
    /// median de-biased, times the model PSD (None without a reference).
    pub fn local_psd(&self, f_hz: f64, half_width: usize) -> Option<f64> {
        let k = ((f_hz / self.df()).round() as usize).clamp(1, self.bins() - 1);
        let r = self.reference(k, half_width)?;
        Some(r.value / r.mean_order_stat() * self.model_psd[k])
    }
}

/// A bin's local reference: `value` is the `m`-th smallest of `n` whitened ordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    pub n: usize,
    pub m: usize,
    pub value: f64,
}

impl Reference {
    /// `E E_(m)` for unit exponentials: `sum_{j<m} 1 / (n - j)`.
    pub fn mean_order_stat(&self) -> f64 {
        (0..self.m).map(|j| 1.0 / (self.n - j) as f64).sum()
    }

    /// `ln P(r_k / r_(m) > c)` under the null: `sum_{j<m} ln((n-j) / (n-j+c))`.
    pub fn ln_tail(&self, c: f64) -> f64 {
        (0..self.m)
            .map(|j| {
                let a = (self.n - j) as f64;
                (a / (a + c)).ln()
            })
            .sum()
    }
}

/// A line detected by [`search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Peak bin (`f = bin / T`).
    pub bin: usize,
    pub f_hz: f64,
    /// Whitened ordinate over the de-biased local level (the line's power
    /// over the continuum's, in Hann-periodogram units).
    pub ratio: f64,
    /// Per-bin tail probability.
    pub p: f64,
    /// The Bonferroni count of its bin: the searched octaves times the bins
    /// in its octave ([`search`]'s budget; `p` is tested against `alpha /
    /// n_searched`).
    pub n_searched: usize,
}

/// Search `spec` for lines (module step 2), strongest first.
pub fn search(spec: &LineSpectrum, params: &SearchParams) -> Vec<Detection> {
    let last = spec.bins() - 1;
    let k_min = ((params.min_cycles).ceil() as usize).max(1);
    // the bins searched, as an iterator: a list would be as long as the record
    let searched = || (k_min..last).filter(|&k| spec.usable[k] && spec.white(k).is_finite());
    if searched().next().is_none() {
        return Vec::new();
    }
    let budget = OctaveBudget::new(searched(), k_min, params.alpha);
    let level = block_levels(spec, 64);
    let mut hits: Vec<Detection> = Vec::new();
    for k in searched() {
        let ln_crit = budget.ln_crit(k);
        // pre-screen: a quarter of the large-n threshold against the block level
        let (w, lv) = (spec.white(k), level[k / 64]);
        if !(w > 0.25 * -ln_crit * lv) || !is_local_max(spec, k) {
            continue;
        }
        let Some(r) = spec.reference(k, params.half_width) else {
            continue;
        };
        if r.n < params.min_ref || !(r.value > 0.0) {
            continue;
        }
        let lp = r.ln_tail(w / r.value);
        if lp < ln_crit {
            hits.push(Detection {
                bin: k,
                f_hz: k as f64 * spec.df(),
                ratio: w / (r.value / r.mean_order_stat()),
                p: lp.exp(),
                n_searched: budget.effective_bins(k),
            });
        }
    }
    drop_sidelobes(hits, |k| -budget.ln_crit(k))
}

/// The false-alarm budget of [`search`], shared equally by the octaves of
/// frequency searched (`[k_min 2^o, k_min 2^(o+1))` bins) and within an
/// octave equally by its bins: a weighted Bonferroni correction whose
/// family-wise level is still `alpha`. A bin of octave `o` is tested at
/// `alpha / (O M_o)` (`O` octaves, `M_o` bins in octave `o`), so a line a few
/// tens of cycles per record long, where the wavelet statistics are blind and
/// thermal or mechanical periods live, is not charged for the hundreds of
/// thousands of bins up to Nyquist; a line in the top octave pays at most
/// `ln O` more than under a flat correction.
struct OctaveBudget {
    k_min: usize,
    /// `O M_o` per octave `o`.
    effective: Vec<usize>,
    /// `ln(alpha / (O M_o))` per octave `o`.
    ln_crit: Vec<f64>,
}

impl OctaveBudget {
    fn new(searched: impl Iterator<Item = usize>, k_min: usize, alpha: f64) -> OctaveBudget {
        let mut counts: Vec<usize> = Vec::new();
        for k in searched {
            let o = octave(k, k_min);
            if counts.len() <= o {
                counts.resize(o + 1, 0);
            }
            counts[o] += 1;
        }
        let n_oct = counts.iter().filter(|&&c| c > 0).count();
        let effective: Vec<usize> = counts.iter().map(|&c| (c * n_oct).max(1)).collect();
        let ln_crit = effective.iter().map(|&e| (alpha / e as f64).ln()).collect();
        OctaveBudget {
            k_min,
            effective,
            ln_crit,
        }
    }

    /// `O M_o` of the octave holding bin `k` (a searched bin).
    fn effective_bins(&self, k: usize) -> usize {
        self.effective[octave(k, self.k_min)]
    }

    /// `ln(alpha / (O M_o))`: the log tail probability below which bin `k` is a line.
    fn ln_crit(&self, k: usize) -> f64 {
        self.ln_crit[octave(k, self.k_min)]
    }
}

/// The octave `floor(log2(k / k_min))` of bin `k >= k_min`.
fn octave(k: usize, k_min: usize) -> usize {
    (usize::BITS - 1 - (k / k_min).leading_zeros()) as usize
}

/// Mean-free level per block of `b` bins: the block median of the usable
/// whitened ordinates over `ln 2` (the global median where a block has none).
fn block_levels(spec: &LineSpectrum, b: usize) -> Vec<f64> {
    let blocks = spec.bins().div_ceil(b);
    let mut out = Vec::with_capacity(blocks);
    let mut v = Vec::with_capacity(b);
    for i in 0..blocks {
        v.clear();
        let hi = ((i + 1) * b).min(spec.bins());
        v.extend(
            (i * b..hi)
                .filter(|&j| spec.usable[j] && spec.white(j).is_finite())
                .map(|j| spec.white(j)),
        );
        out.push(if v.len() >= 8 {
            let m = v.len() / 2;
            *v.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1 / std::f64::consts::LN_2
        } else {
            f64::NAN
        });
    }
    let mut good: Vec<f64> = out.iter().copied().filter(|v| v.is_finite()).collect();
    let fill = if good.is_empty() {
        1.0
    } else {
        let m = good.len() / 2;
        *good.select_nth_unstable_by(m, |a, b| a.total_cmp(b)).1
    };
    out.iter()
        .map(|v| if v.is_finite() { *v } else { fill })
        .collect()
}

fn is_local_max(spec: &LineSpectrum, k: usize) -> bool {
    let w = spec.white(k);
    let left = k == 0 || !(spec.white(k - 1) > w);
    let right = k + 1 >= spec.bins() || !(spec.white(k + 1) > w);
    left && right
}

/// Keep the strongest of the peaks within each other's Hann sidelobe reach:
/// a line `R` times the continuum leaks `R / (pi o (o^2 - 1))^2` at `o` bins;
/// a weaker peak closer than where that falls to a tenth of its own bin's
/// threshold `thr(bin)` (`3 + (10 R / (thr pi^2))^(1/6)` bins) is its
/// leakage, not a line.
fn drop_sidelobes(mut hits: Vec<Detection>, thr: impl Fn(usize) -> f64) -> Vec<Detection> {
    hits.sort_by(|a, b| b.ratio.total_cmp(&a.ratio));
    let mut kept: Vec<Detection> = Vec::new();
    for h in hits {
        let leak = kept.iter().any(|s| {
            let reach = 3.0 + (10.0 * s.ratio / (thr(h.bin) * PI * PI)).powf(1.0 / 6.0);
            (h.bin as f64 - s.bin as f64).abs() <= reach
        });
        if !leak {
            kept.push(h);
        }
    }
    kept
}

/// A line measured by [`fit_line`]: the rate sinusoid `amp sin(2 pi f t + phi)`
/// (arcsec/s) with its Fisher standard deviations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFit {
    pub f_hz: f64,
    pub f_sd: f64,
    pub amp: f64,
    pub amp_sd: f64,
    /// Local continuum PSD used for the standard deviations, (arcsec/s)^2/Hz.
    pub s_local: f64,
}

impl LineFit {
    /// 95 % interval of the period, s.
    pub fn period_ci95(&self) -> [f64; 2] {
        let h = 1.96 * self.f_sd;
        [1.0 / (self.f_hz + h), 1.0 / (self.f_hz - h).max(1e-300)]
    }

    /// 95 % interval of the amplitude, arcsec/s.
    pub fn amp_ci95(&self) -> [f64; 2] {
        let h = 1.96 * self.amp_sd;
        [(self.amp - h).max(0.0), self.amp + h]
    }
}

/// Measure the line near `f0_hz` in the detrended rate `x(0..n)` (module
/// step 3), read through a function (the record is not held as a series);
/// `s_local` is the continuum PSD at the line ([`LineSpectrum::local_psd`]).
pub fn fit_line(
    n: usize,
    x: impl Fn(usize) -> f64,
    fs_hz: f64,
    f0_hz: f64,
    s_local: f64,
) -> LineFit {
    let tau0 = 1.0 / fs_hz;
    let t = n as f64 * tau0;
    let df = 1.0 / t;
    let w = Taper::new(n);
    let power = |f: f64| dft_by(n, tau0, f, |k| x(k) * w.at(k)).norm_sqr();
    // grid over +-1 bin in eighths (the main lobe is +-1 bin wide), then
    // golden section over +-1/8 bin about the best grid point
    let best = (-8..=8)
        .map(|i| f0_hz + i as f64 * df / 8.0)
        .max_by(|a, b| power(*a).total_cmp(&power(*b)))
        .unwrap_or(f0_hz);
    let f = super::golden::golden_max(&power, best - df / 8.0, best + df / 8.0, 40);
    let m = window_moments(&w);
    let a_s = 2.0 * power(f).sqrt() / m.sum_w;
    let xarg = PI * f * tau0;
    let sinc = if xarg > 0.0 { xarg.sin() / xarg } else { 1.0 };
    let s2 = 0.5 * s_local.max(0.0) * fs_hz;
    // windowed estimators, linearised: var A = 2 s2 sum w^2 / (sum w)^2,
    // var omega = 2 s2 sum(m^2 w^2) / (A^2 (sum m^2 w)^2) rad^2/sample^2
    // (both the Cramer-Rao bound when w = 1)
    let var_w = 2.0 * s2 * m.sum_m2w2 / (a_s.max(1e-300).powi(2) * m.sum_m2w.powi(2));
    LineFit {
        f_hz: f,
        f_sd: var_w.sqrt() * fs_hz / (2.0 * PI),
        amp: a_s / sinc,
        amp_sd: (2.0 * s2 * m.sum_w2).sqrt() / m.sum_w / sinc,
        s_local: s_local.max(0.0),
    }
}

/// Sums of a window `w` over the centred sample index `m = k - (N-1)/2`.
struct WindowMoments {
    sum_w: f64,
    sum_w2: f64,
    sum_m2w: f64,
    sum_m2w2: f64,
}

fn window_moments(w: &Taper) -> WindowMoments {
    let c = 0.5 * (w.n as f64 - 1.0);
    let mut m = WindowMoments {
        sum_w: 0.0,
        sum_w2: 0.0,
        sum_m2w: 0.0,
        sum_m2w2: 0.0,
    };
    for (k, v) in (0..w.n).map(|k| (k, w.at(k))) {
        let m2 = (k as f64 - c).powi(2);
        m.sum_w += v;
        m.sum_w2 += v * v;
        m.sum_m2w += m2 * v;
        m.sum_m2w2 += m2 * v * v;
    }
    m
}

/// The fit's taper: a Tukey window with cosine ends over `TAPER` of the
/// record each. A plain (rectangular) fit is the least-squares one, but its
/// frequency estimate weights the noise by time, whose kernel falls only as
/// `1/k`: the quantization noise far up the band (thousands of times the
/// continuum at the line) then adds as much variance again as the noise at
/// the line. The smooth taper confines the kernel to the line's neighbourhood
/// at a small loss of efficiency (frequency variance x1.25, amplitude x1.08).
fn taper(k: usize, n: usize) -> f64 {
    const TAPER: f64 = 0.1;
    let u = (k as f64 + 0.5) / n as f64;
    let e = u.min(1.0 - u);
    if e >= TAPER {
        1.0
    } else {
        0.5 - 0.5 * (PI * e / TAPER).cos()
    }
}

/// [`taper`] over `n` samples, its cosine ends tabulated (the flat middle,
/// 80 % of the record, is not stored).
struct Taper {
    n: usize,
    left: Vec<f64>,
    /// `right[j]` is sample `right_start + j`.
    right: Vec<f64>,
    right_start: usize,
}

impl Taper {
    fn new(n: usize) -> Taper {
        let left: Vec<f64> = (0..n)
            .map(|k| taper(k, n))
            .take_while(|&v| v != 1.0)
            .collect();
        let mut right_start = n;
        while right_start > left.len() && taper(right_start - 1, n) != 1.0 {
            right_start -= 1;
        }
        let right = (right_start..n).map(|k| taper(k, n)).collect();
        Taper {
            n,
            left,
            right,
            right_start,
        }
    }

    /// `taper(k, n)`.
    #[inline]
    fn at(&self, k: usize) -> f64 {
        if k < self.left.len() {
            self.left[k]
        } else if k >= self.right_start {
            self.right[k - self.right_start]
        } else {
            1.0
        }
    }
}

/// `sum_k x_k e^{-2 pi i f k tau0}` (rectangular window) of `x(0..n)`, read
/// through a function; the phasor re-anchored every 4096 samples.
pub fn dft(n: usize, x: impl Fn(usize) -> f64, tau0: f64, f_hz: f64) -> Complex64 {
    dft_by(n, tau0, f_hz, x)
}

fn dft_by(n: usize, tau0: f64, f_hz: f64, val: impl Fn(usize) -> f64) -> Complex64 {
    let w = -2.0 * PI * f_hz * tau0;
    let step = Complex64::from_polar(1.0, w);
    let mut acc = Complex64::new(0.0, 0.0);
    for start in (0..n).step_by(4096) {
        let mut ph = Complex64::from_polar(1.0, w * start as f64);
        let mut part = Complex64::new(0.0, 0.0);
        for k in start..(start + 4096).min(n) {
            part += ph * val(k);
            ph *= step;
        }
        acc += part;
    }
    acc
}

/// Amplitude of the least-squares sinusoid at `f_hz` in `x` (sampled every
/// `dt_s`), fitted together with a mean and a line: the time-domain amplitude
/// a record holds at that frequency, whatever its noise.
pub fn sine_amplitude_ls(x: &[f64], dt_s: f64, f_hz: f64) -> f64 {
    let w = 2.0 * PI * f_hz * dt_s;
    let basis =
        |g: fn(f64) -> f64| detrend(&(0..x.len()).map(|i| g(w * i as f64)).collect::<Vec<_>>());
    let (s, c) = (basis(f64::sin), basis(f64::cos));
    let y = detrend(x);
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let (ss, cc, sc) = (dot(&s, &s), dot(&c, &c), dot(&s, &c));
    let (sy, cy) = (dot(&s, &y), dot(&c, &y));
    let det = ss * cc - sc * sc;
    if !(det > 0.0) {
        return 0.0;
    }
    let a = (cc * sy - sc * cy) / det;
    let b = (ss * cy - sc * sy) / det;
    a.hypot(b)
}

/// `x` with its least-squares line removed.
pub fn detrend(x: &[f64]) -> Vec<f64> {
    let mut v = x.to_vec();
    detrend_in_place(&mut v);
    v
}

/// [`detrend`] in place.
pub fn detrend_in_place(x: &mut [f64]) {
    let t = TrendLine::of(x.len(), |i| x[i]);
    for (i, v) in x.iter_mut().enumerate() {
        *v = t.residual(i, *v);
    }
}

/// The least-squares line of a series `x(0), ..., x(n-1)`: what [`detrend`]
/// removes, for a series read through a function (never held whole).
#[derive(Debug, Clone, Copy)]
pub struct TrendLine {
    /// The series' mean.
    pub mean: f64,
    slope: f64,
    centre: f64,
}

impl TrendLine {
    /// The line of `x(0..n)`.
    pub fn of(n: usize, x: impl Fn(usize) -> f64) -> TrendLine {
        let nf = n as f64;
        let c = 0.5 * (nf - 1.0);
        let mean = (0..n).map(&x).sum::<f64>() / nf;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for i in 0..n {
            let d = i as f64 - c;
            sxy += d * (x(i) - mean);
            sxx += d * d;
        }
        let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        TrendLine {
            mean,
            slope: b,
            centre: c,
        }
    }

    /// Sample `i`, of value `v`, less the line.
    #[inline]
    pub fn residual(&self, i: usize, v: f64) -> f64 {
        v - self.mean - self.slope * (i as f64 - self.centre)
    }
}

/// `|X_k|^2`, `k = 0 ..= n/2`, of the Hann-windowed real series `x(0..n)`.
/// An even length is transformed as `n/2` complex points (even samples real,
/// odd imaginary) and the halves separated, in half the memory of a complex
/// transform of the whole record; the transform itself is done in place
/// ([`Dft`]), and the series is read through `x`, never held.
fn hann_power(n: usize, x: impl Fn(usize) -> f64) -> Vec<f64> {
    if n % 2 == 1 || n < 4 {
        let mut buf: Vec<Complex64> = (0..n)
            .map(|k| Complex64::new(x(k) * hann(k, n), 0.0))
            .collect();
        let at = Dft::run(&mut buf);
        return (0..=n / 2).map(|k| buf[at.index(k)].norm_sqr()).collect();
    }
    let m = n / 2;
    let mut z: Vec<Complex64> = (0..m)
        .map(|j| Complex64::new(x(2 * j) * hann(2 * j, n), x(2 * j + 1) * hann(2 * j + 1, n)))
        .collect();
    let at = Dft::run(&mut z);
    // X_k = E_k + w^k O_k, E_k = (Z_k + conj Z_{m-k}) / 2,
    // O_k = (Z_k - conj Z_{m-k}) / 2i, w = exp(-2 pi i / n)
    (0..=m)
        .map(|k| {
            let (a, b) = (z[at.index(k % m)], z[at.index((m - k) % m)].conj());
            let e = (a + b) * 0.5;
            let o = (a - b) * Complex64::new(0.0, -0.5);
            let w = Complex64::from_polar(1.0, -2.0 * PI * k as f64 / n as f64);
            (e + w * o).norm_sqr()
        })
        .collect()
}

/// Where an in-place DFT left bin `k`: a long transform whose length splits
/// into two factors near its square root is done by the four-step method
/// (short transforms of columns, twiddles, short transforms of rows: no
/// whole-length scratch or twiddle table beside the data), which leaves
/// `X[k1 + m1 k2]` at `m2 k1 + k2`; any other in natural order.
#[derive(Debug, Clone, Copy)]
struct Dft {
    /// `(m1, m2)`, or none for natural order.
    split: Option<(usize, usize)>,
}

impl Dft {
    /// Transform `z` in place.
    fn run(z: &mut [Complex64]) -> Dft {
        let split = four_step_split(z.len());
        match split {
            Some((m1, m2)) => four_step(z, m1, m2),
            None => FftPlanner::new().plan_fft_forward(z.len()).process(z),
        }
        Dft { split }
    }

    fn index(&self, k: usize) -> usize {
        match self.split {
            Some((m1, m2)) => m2 * (k % m1) + k / m1,
            None => k,
        }
    }
}

/// Factors `m = m1 m2`, `m1 <= m2` the largest factor not above `sqrt(m)`,
/// for lengths from 2^20 whose `m1` is at least `sqrt(m) / 16`.
fn four_step_split(m: usize) -> Option<(usize, usize)> {
    if m < 1 << 20 {
        return None;
    }
    let r = (m as f64).sqrt() as usize;
    (r / 16..=r)
        .rev()
        .find(|&m1| m1 >= 2 && m.is_multiple_of(m1))
        .map(|m1| (m1, m / m1))
}

/// Bailey's four-step DFT of `z` (length `m1 m2`, read as `m1` rows of
/// `m2`): each column's length-`m1` transform, times `exp(-2 pi i j2 k1 / m)`,
/// then each row's length-`m2` transform. Columns go eight at a time through
/// a small buffer.
fn four_step(z: &mut [Complex64], m1: usize, m2: usize) {
    const COLS: usize = 8;
    let m = m1 * m2;
    let mut planner = FftPlanner::new();
    let (f1, f2) = (planner.plan_fft_forward(m1), planner.plan_fft_forward(m2));
    let scratch_len = f1
        .get_inplace_scratch_len()
        .max(f2.get_inplace_scratch_len());
    let mut scratch = vec![Complex64::new(0.0, 0.0); scratch_len];
    let mut cols = vec![Complex64::new(0.0, 0.0); COLS * m1];
    let mut j2 = 0;
    while j2 < m2 {
        let w = COLS.min(m2 - j2);
        for j1 in 0..m1 {
            for c in 0..w {
                cols[c * m1 + j1] = z[m2 * j1 + j2 + c];
            }
        }
        f1.process_with_scratch(&mut cols[..w * m1], &mut scratch);
        for c in 0..w {
            let col = &mut cols[c * m1..(c + 1) * m1];
            for (k1, v) in col.iter_mut().enumerate() {
                let ph = -2.0 * PI * (((j2 + c) * k1) % m) as f64 / m as f64;
                *v *= Complex64::from_polar(1.0, ph);
            }
        }
        for k1 in 0..m1 {
            for c in 0..w {
                z[m2 * k1 + j2 + c] = cols[c * m1 + k1];
            }
        }
        j2 += w;
    }
    f2.process_with_scratch(z, &mut scratch);
}

fn hann(k: usize, n: usize) -> f64 {
    0.5 - 0.5 * (2.0 * PI * k as f64 / n as f64).cos()
}

/// `f` aliased into `[0, fs/2]`.
fn fold(f: f64, fs: f64) -> f64 {
    let a = f.rem_euclid(fs);
    if a > fs / 2.0 { fs - a } else { a }
}

fn mask_interval(usable: &mut [bool], f: f64, hw: f64, df: f64) {
    let k0 = ((f - hw) / df).floor().max(0.0) as usize;
    let k1 = (((f + hw) / df).ceil() as usize).min(usable.len() - 1);
    for u in usable.iter_mut().take(k1 + 1).skip(k0) {
        *u = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-length transform gives the whole record's Hann periodogram
    /// (against the direct DFT, even and odd lengths).
    #[test]
    fn the_half_length_transform_is_the_periodogram() {
        for n in [8usize, 9, 64, 1000, 1001] {
            let x: Vec<f64> = (0..n)
                .map(|k| ((k * 7919) % 97) as f64 - 48.0 + (0.3 * k as f64).sin())
                .collect();
            let got = hann_power(n, |i| x[i]);
            assert_eq!(got.len(), n / 2 + 1);
            let peak = got.iter().cloned().fold(0.0, f64::max);
            for (k, g) in got.iter().enumerate() {
                let mut acc = Complex64::new(0.0, 0.0);
                for (j, &v) in x.iter().enumerate() {
                    let ph = -2.0 * PI * ((k * j) % n) as f64 / n as f64;
                    acc += Complex64::from_polar(v * hann(j, n), ph);
                }
                assert!((g - acc.norm_sqr()).abs() <= 1e-9 * peak, "n {n} k {k}");
            }
        }
    }

    /// The four-step transform is rustfft's whole-length one, on lengths that
    /// split evenly, unevenly, and not at all (a prime: natural order).
    #[test]
    fn the_four_step_transform_is_the_whole_length_one() {
        for m in [1usize << 20, 1_048_576 + 3 * 4096, 1_200_000, 1_048_583] {
            let z0: Vec<Complex64> = (0..m)
                .map(|k| {
                    Complex64::new(((k * 7919) % 97) as f64 - 48.0, ((k * 104_729) % 89) as f64)
                })
                .collect();
            let mut want = z0.clone();
            FftPlanner::new().plan_fft_forward(m).process(&mut want);
            let mut got = z0;
            let at = Dft::run(&mut got);
            assert_eq!(at.split.is_some(), m != 1_048_583, "m {m}");
            let peak = want.iter().map(|c| c.norm()).fold(0.0, f64::max);
            for (k, w) in want.iter().enumerate() {
                let g = got[at.index(k)];
                assert!((g - w).norm() <= 1e-12 * peak, "m {m} k {k}: {g} vs {w}");
            }
        }
    }

    /// The tabulated taper is the taper at every sample.
    #[test]
    fn the_tabulated_taper_is_the_taper() {
        for n in [1usize, 2, 9, 10, 11, 1000, 1001, 65_537] {
            let t = Taper::new(n);
            for k in 0..n {
                assert_eq!(t.at(k).to_bits(), taper(k, n).to_bits(), "n {n} k {k}");
            }
            assert!(
                t.left.len() + t.right.len() <= n.div_ceil(4).max(2),
                "n {n}"
            );
        }
    }

    #[test]
    fn octaves_double_from_the_lowest_bin() {
        assert_eq!(octave(10, 10), 0);
        assert_eq!(octave(19, 10), 0);
        assert_eq!(octave(20, 10), 1);
        assert_eq!(octave(39, 10), 1);
        assert_eq!(octave(40, 10), 2);
        assert_eq!(octave(600_000, 10), 15);
    }

    /// The weights `1 / (O M_o)` of the searched bins sum to one, so the
    /// family-wise level is `alpha`, with gaps (masked bins) in the list.
    #[test]
    fn the_octave_budget_spends_alpha_exactly() {
        let searched: Vec<usize> = (10..200_000).filter(|k| k % 7 != 3).collect();
        let b = OctaveBudget::new(searched.iter().copied(), 10, 0.001);
        let total: f64 = searched
            .iter()
            .map(|&k| 1.0 / b.effective_bins(k) as f64)
            .sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
        // 15 octaves: a bin at 30 cycles is charged 15 * 17 (bins 20..40 less
        // the masked ones), one near the top 15 * (its octave's ~ 2^14 * 10 * 6/7)
        assert_eq!(b.effective_bins(30), 15 * 17);
        assert!(b.effective_bins(190_000) > 15 * 30_000);
        assert_eq!(b.ln_crit(30), (0.001_f64 / 255.0).ln());
    }
}
