//! Low-frequency rows of the broadband likelihood: the whole record's
//! periodogram below the deepest wavelet level.
//!
//! The sym8 levels stop where fewer than [`super::stats::MIN_LEVEL_COEFS`]
//! coefficients clear the filter's boundary, about `T / 30`; what a record
//! says about its spectrum below that, down to `1 / T`, is left out of the
//! wavelet likelihood. There the broadband shapes part ways most: over one
//! decade a flicker (bias instability) rises 10x, a rate random walk 100x,
//! while a Gauss-Markov term with `Tc` well below `T / 30` is flat, like
//! white rate noise. So a Gauss-Markov bias and a raised bias instability that
//! fit the levels equally well are told apart here.
//!
//! The statistic: the rate averaged over [`LF_BLOCKS`] blocks, its
//! least-squares line removed (a ramp is the slope test's business and would
//! swamp these bins), a Hann taper, and the periodogram
//! `P_k = 2 tau_b |a_k|^2 / sum w^2` at the bins `k = 1..` below the deepest
//! level's band, averaged over octave bands of bins. Its expectation under a
//! spectrum `S` (one-sided, per Hz) is exact for the detrended, tapered
//! estimator: `E P_k = (2 / sum w^2) int_0^1/2 S(nu / tau_b) G_k(nu) dnu`
//! with `G_k` the power response of the bin's weights `c_k = (I - P)(w e_k)`
//! (`P` the projection on the line), evaluated on a frequency grid fine
//! near zero ([`LfWindows`]). Block averaging does not matter at these
//! frequencies except for white angle noise, whose blue spectrum aliases: its
//! block-level form is used.
//!
//! The rows join the wavelet levels in [`super::wvar_fit::LevelData`] with the
//! same Gamma likelihood; their expectation is the model's Monte-Carlo mean
//! and their EDF the runs' log spread, floored by the bands' analytic EDF.

use std::f64::consts::PI;

use super::line_search::detrend;
use crate::model::wvar::SpectralTerm;

/// Blocks the rate is averaged into before the low-frequency periodogram.
pub const LF_BLOCKS: usize = 1024;
/// Highest bin used.
const MAX_BIN: usize = 63;

/// Where the low-frequency rows are: the block length and the bands of bins.
#[derive(Debug, Clone, PartialEq)]
pub struct LfLayout {
    /// Samples per block (0: no rows).
    pub block_len: usize,
    /// Block duration, s.
    pub tau_b_s: f64,
    /// Bands of bins, inclusive `(k_lo, k_hi)`.
    pub bands: Vec<(usize, usize)>,
}

impl LfLayout {
    /// Rows for a record of `n` samples at `fs_hz` whose deepest wavelet level
    /// is `deepest` (its band starts at `fs / 2^(deepest + 1)`): the bins
    /// strictly below that band, in octaves `1, 2-3, 4-7, ...`.
    pub fn new(n: usize, fs_hz: f64, deepest: u32) -> LfLayout {
        let block_len = n / LF_BLOCKS;
        let none = LfLayout {
            block_len: 0,
            tau_b_s: 0.0,
            bands: Vec::new(),
        };
        if block_len < 2 || deepest == 0 {
            return none;
        }
        let t_used = (block_len * LF_BLOCKS) as f64 / fs_hz;
        let f_edge = fs_hz / 2f64.powi(deepest as i32 + 1);
        let k_max = (((f_edge * t_used).ceil() as usize).saturating_sub(1)).min(MAX_BIN);
        let mut bands = Vec::new();
        let mut k = 1usize;
        while k <= k_max {
            bands.push((k, (2 * k - 1).min(k_max)));
            k *= 2;
        }
        LfLayout {
            block_len,
            tau_b_s: block_len as f64 / fs_hz,
            bands,
        }
    }

    /// Highest bin of the rows (0 when there are none).
    pub fn k_max(&self) -> usize {
        self.bands.last().map_or(0, |b| b.1)
    }

    /// Band values `mean_k P_k` of a rate record (arcsec/s).
    pub fn psd(&self, rate: &[f64]) -> Vec<f64> {
        if self.bands.is_empty() {
            return Vec::new();
        }
        let b = self.block_len;
        let means: Vec<f64> = (0..LF_BLOCKS)
            .map(|i| rate[i * b..(i + 1) * b].iter().sum::<f64>() / b as f64)
            .collect();
        self.psd_of_means(&means)
    }

    /// [`LfLayout::psd`] from the rate's [`LF_BLOCKS`] block means.
    pub fn psd_of_means(&self, means: &[f64]) -> Vec<f64> {
        if self.bands.is_empty() {
            return Vec::new();
        }
        let x = detrend(means);
        let w = hann();
        let sw2: f64 = w.iter().map(|v| v * v).sum();
        let bin = |k: usize| {
            let (mut re, mut im) = (0.0, 0.0);
            for (n, (&xn, &wn)) in x.iter().zip(&w).enumerate() {
                let ph = -2.0 * PI * (k * n % LF_BLOCKS) as f64 / LF_BLOCKS as f64;
                re += wn * xn * ph.cos();
                im += wn * xn * ph.sin();
            }
            2.0 * self.tau_b_s * (re * re + im * im) / sw2
        };
        self.bands
            .iter()
            .map(|&(lo, hi)| (lo..=hi).map(bin).sum::<f64>() / (hi - lo + 1) as f64)
            .collect()
    }

    /// Analytic EDF of each band (`nb` Hann bins, adjacent ones correlated).
    pub fn edf(&self) -> Vec<f64> {
        self.bands
            .iter()
            .map(|&(lo, hi)| {
                let nb = (hi - lo + 1) as f64;
                // |rho|^2 of Hann bins one and two apart: 4/9, 1/36
                let var =
                    nb + 2.0 * (nb - 1.0).max(0.0) * 4.0 / 9.0 + 2.0 * (nb - 2.0).max(0.0) / 36.0;
                2.0 * nb * nb / var
            })
            .collect()
    }

    /// Floors of the log standard deviation of each band: `sqrt(psi'(EDF/2))`.
    pub fn floor_sd(&self) -> Vec<f64> {
        self.edf()
            .iter()
            .map(|&e| trigamma(0.5 * e).sqrt())
            .collect()
    }
}

/// The periodic Hann taper over the blocks.
fn hann() -> Vec<f64> {
    (0..LF_BLOCKS)
        .map(|n| 0.5 * (1.0 - (2.0 * PI * n as f64 / LF_BLOCKS as f64).cos()))
        .collect()
}

/// `psi'(x)`, x > 0: recurrence up to 10, then the asymptotic series.
fn trigamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc += 1.0 / (x * x);
        x += 1.0;
    }
    let x2 = x * x;
    acc + 1.0 / x + 1.0 / (2.0 * x2) + 1.0 / (6.0 * x2 * x) - 1.0 / (30.0 * x2 * x2 * x)
        + 1.0 / (42.0 * x2 * x2 * x2 * x)
}

/// The bins' weights and power responses on a frequency grid: the exact
/// expectation of the rows under any spectrum.
#[derive(Debug, Clone)]
pub struct LfWindows {
    layout: LfLayout,
    tau0_s: f64,
    /// Weights `c_k` (re, im) per bin `1..=k_max`.
    weights: Vec<Vec<(f64, f64)>>,
    /// Grid in cycles per block and trapezoid weights.
    grid: Vec<(f64, f64)>,
    /// `G_k` on the grid, per bin.
    g: Vec<Vec<f64>>,
    sw2: f64,
}

impl LfWindows {
    /// Windows of `layout` for a record with sample period `tau0_s`.
    pub fn new(layout: &LfLayout, tau0_s: f64) -> LfWindows {
        let w = hann();
        let sw2: f64 = w.iter().map(|v| v * v).sum();
        let k_max = layout.k_max();
        let weights: Vec<Vec<(f64, f64)>> = (1..=k_max).map(|k| bin_weights(&w, k)).collect();
        let grid = frequency_grid(k_max);
        let g = weights
            .iter()
            .map(|c| grid.iter().map(|&(nu, _)| power_response(c, nu)).collect())
            .collect();
        LfWindows {
            layout: layout.clone(),
            tau0_s,
            weights,
            grid,
            g,
            sw2,
        }
    }

    /// Rows (one per band) of the expected periodogram per unit theta of `term`.
    pub fn term(&self, term: SpectralTerm) -> Vec<f64> {
        let tb = self.layout.tau_b_s;
        let b = self.layout.block_len as f64;
        let s1 = |nu: f64| -> f64 {
            match term {
                // blue: aliased by the block average, use its block-level form
                SpectralTerm::WhiteAngle => SpectralTerm::WhiteAngle.psd_cs(nu, tb) * tb,
                _ => term.psd_cs(nu / b, self.tau0_s) * self.tau0_s,
            }
        };
        // G_k vanishes like nu^4 at 0 (the line is removed): the red spectra's pole adds nothing
        let spectrum: Vec<f64> = self
            .grid
            .iter()
            .map(|&(nu, _)| if nu > 0.0 { s1(nu) } else { 0.0 })
            .collect();
        self.bands(|k| {
            let gk = &self.g[k - 1];
            let int: f64 = self
                .grid
                .iter()
                .zip(gk)
                .zip(&spectrum)
                .map(|((&(_, dw), &g), &s)| dw * g * s)
                .sum();
            2.0 * int / self.sw2
        })
    }

    /// Rows per unit squared amplitude of a sinusoid at `f_hz`.
    pub fn sinusoid(&self, f_hz: f64) -> Vec<f64> {
        let tb = self.layout.tau_b_s;
        let nu0 = f_hz * tb;
        let x = PI * nu0;
        let g2 = if x.abs() < 1e-12 {
            1.0
        } else {
            (x.sin() / x).powi(2)
        };
        self.bands(|k| tb * g2 * power_response(&self.weights[k - 1], nu0) / self.sw2)
    }

    fn bands(&self, per_bin: impl Fn(usize) -> f64) -> Vec<f64> {
        self.layout
            .bands
            .iter()
            .map(|&(lo, hi)| (lo..=hi).map(&per_bin).sum::<f64>() / (hi - lo + 1) as f64)
            .collect()
    }
}

/// `c_k = (I - P)(w e^{-2 pi i k n / N})`, `P` the projection on `{1, n}`.
fn bin_weights(w: &[f64], k: usize) -> Vec<(f64, f64)> {
    let n = w.len();
    let mut v: Vec<(f64, f64)> = w
        .iter()
        .enumerate()
        .map(|(i, &wi)| {
            let ph = -2.0 * PI * (k * i % n) as f64 / n as f64;
            (wi * ph.cos(), wi * ph.sin())
        })
        .collect();
    let nf = n as f64;
    let tbar = 0.5 * (nf - 1.0);
    let stt: f64 = (0..n).map(|i| (i as f64 - tbar).powi(2)).sum();
    let (mut m_re, mut m_im, mut s_re, mut s_im) = (0.0, 0.0, 0.0, 0.0);
    for (i, &(re, im)) in v.iter().enumerate() {
        let t = i as f64 - tbar;
        m_re += re;
        m_im += im;
        s_re += t * re;
        s_im += t * im;
    }
    for (i, c) in v.iter_mut().enumerate() {
        let t = i as f64 - tbar;
        c.0 -= m_re / nf + t * s_re / stt;
        c.1 -= m_im / nf + t * s_im / stt;
    }
    v
}

/// `(|C(nu)|^2 + |C(-nu)|^2) / 2`, `C(nu) = sum_n c_n e^{2 pi i nu n}`.
fn power_response(c: &[(f64, f64)], nu: f64) -> f64 {
    let (st, ct) = (2.0 * PI * nu).sin_cos();
    // e^{+i theta n} by recurrence (renormalised now and then)
    let (mut pr, mut pi) = (1.0f64, 0.0f64);
    let (mut a_re, mut a_im, mut b_re, mut b_im) = (0.0, 0.0, 0.0, 0.0);
    for (n, &(re, im)) in c.iter().enumerate() {
        // C(nu): c * e^{+i}; C(-nu): c * e^{-i}
        a_re += re * pr - im * pi;
        a_im += re * pi + im * pr;
        b_re += re * pr + im * pi;
        b_im += im * pr - re * pi;
        let npr = pr * ct - pi * st;
        pi = pr * st + pi * ct;
        pr = npr;
        if n % 256 == 255 {
            let r = (pr * pr + pi * pi).sqrt();
            pr /= r;
            pi /= r;
        }
    }
    0.5 * (a_re * a_re + a_im * a_im + b_re * b_re + b_im * b_im)
}

/// Frequencies (cycles per block) and trapezoid weights: 1/16-bin steps up to
/// 24 bins past the last, then geometric to Nyquist.
fn frequency_grid(k_max: usize) -> Vec<(f64, f64)> {
    let n = LF_BLOCKS as f64;
    let fine_top = ((k_max + 24) as f64 / n).min(0.5);
    let mut nus: Vec<f64> = (0..=((fine_top * n * 16.0) as usize))
        .map(|i| i as f64 / (16.0 * n))
        .collect();
    let last = *nus.last().unwrap_or(&0.0);
    if last < 0.5 {
        let steps = 200;
        let r = (0.5 / last).powf(1.0 / steps as f64);
        for i in 1..=steps {
            nus.push((last * r.powi(i)).min(0.5));
        }
    }
    let m = nus.len();
    (0..m)
        .map(|i| {
            let left = if i > 0 { nus[i] - nus[i - 1] } else { 0.0 };
            let right = if i + 1 < m { nus[i + 1] - nus[i] } else { 0.0 };
            (nus[i], 0.5 * (left + right))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            // Box-Muller over a 64-bit LCG
            let mut u = || {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (2.0 * PI * b).cos()
        }
    }

    #[test]
    fn the_bands_lie_below_the_deepest_level() {
        // 1 h at 1 kHz, deepest level 17: its band starts at 1000 / 2^18 Hz = 3.81 mHz
        let l = LfLayout::new(3_600_000, 1000.0, 17);
        let t = (l.block_len * LF_BLOCKS) as f64 / 1000.0;
        assert_eq!(l.bands.first(), Some(&(1, 1)));
        assert!(l.k_max() as f64 / t < 1000.0 / 2f64.powi(18));
        assert!((l.k_max() + 1) as f64 / t >= 1000.0 / 2f64.powi(18));
        assert!(l.bands.windows(2).all(|w| w[1].0 == w[0].1 + 1));
        assert!(LfLayout::new(1000, 1000.0, 3).bands.is_empty());
    }

    #[test]
    fn white_and_red_expectations_match_a_monte_carlo() {
        // white rate (N^2 = 0.04 arcsec^2/s) plus a rate random walk
        // (K^2 = 1e-6 (arcsec/s)^2/s) at 100 Hz, 1024 x 64 samples
        let (fs, n) = (100.0, LF_BLOCKS * 64);
        let l = LfLayout::new(n, fs, 6);
        assert!(l.bands.len() >= 3, "{l:?}");
        let win = LfWindows::new(&l, 1.0 / fs);
        let (n2, k2) = (0.04, 1e-6);
        let ew = win.term(SpectralTerm::WhiteRate);
        let ek = win.term(SpectralTerm::RateRandomWalk);
        // white: exactly flat at the one-sided level 2 N^2 times the taper's loss to the line fit
        for (e, &(lo, _)) in ew.iter().zip(&l.bands) {
            let rel = e / 2.0 - 1.0;
            assert!(rel.abs() < if lo == 1 { 0.5 } else { 0.02 }, "white {e}");
        }
        let runs = 400;
        let mut acc = vec![0.0; l.bands.len()];
        let mut g = lcg(7);
        for _ in 0..runs {
            let mut walk = 0.0;
            let rate: Vec<f64> = (0..n)
                .map(|_| {
                    walk += (k2 / fs).sqrt() * g();
                    (n2 * fs).sqrt() * g() + walk
                })
                .collect();
            for (a, p) in acc.iter_mut().zip(l.psd(&rate)) {
                *a += p / runs as f64;
            }
        }
        for (i, a) in acc.iter().enumerate() {
            let e = n2 * ew[i] + k2 * ek[i];
            let nb = (l.bands[i].1 - l.bands[i].0 + 1) as f64;
            // the Monte-Carlo mean's own standard error: about 1/sqrt(runs nb)
            let tol = 4.0 / (runs as f64 * nb).sqrt();
            assert!(
                (a / e - 1.0).abs() < tol,
                "band {i}: mc {a} vs {e} (tol {tol})"
            );
        }
    }

    #[test]
    fn a_sinusoid_lands_in_its_bin() {
        let l = LfLayout::new(LF_BLOCKS * 8, 10.0, 3);
        let win = LfWindows::new(&l, 0.1);
        let t = (LF_BLOCKS * 8) as f64 / 10.0;
        let rows = win.sinusoid(2.0 / t);
        // bin 2 is in band 1 (2-3): the periodogram of A cos is A^2 T / 2 there, spread over 2 bins
        let (i, best) = rows
            .iter()
            .enumerate()
            .fold((0, 0.0), |a, (i, &v)| if v > a.1 { (i, v) } else { a });
        assert_eq!(i, 1);
        assert!(best > 0.1 * t / 2.0, "{rows:?}");
    }

    #[test]
    fn trigamma_is_right() {
        assert!((trigamma(1.0) - PI * PI / 6.0).abs() < 1e-9);
        assert!((trigamma(0.5) - PI * PI / 2.0).abs() < 1e-9);
    }
}
