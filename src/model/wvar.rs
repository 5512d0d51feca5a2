//! Expected wavelet variances: what each noise term contributes to the
//! variance of the detail coefficients of a decimated orthonormal DWT.
//!
//! The estimator (`model::estimate`) fits these to the detail-coefficient
//! variances the streaming wavelet bank measures (a GMWM-style fit, with the
//! paper's sym8 filters instead of Haar). Everything here is in rate units:
//! the transformed signal is the rate in arcsec/s (== deg/h), sampled every
//! `tau0_s`; frequencies `nu` are in cycles per input sample.
//!
//! Two exact routes, chosen per term:
//! * terms whose rate autocovariance has finite support (white angle noise =
//!   quantization, white rate = ARW) are propagated exactly through the filter
//!   bank in the lag domain: filtering by `h` and decimating by 2 maps an
//!   autocovariance `R` to `R'(t) = sum_m c_h(m) R(2t - m)` with `c_h` the
//!   filter's autocorrelation;
//! * low-frequency terms (flicker, rate random walk, Gauss-Markov) are
//!   integrated in the frequency domain, `var_j = int_0^{1/2} S(nu) |H_j(nu)|^2 dnu`,
//!   with `|H_j|^2` the level-j equivalent filter's power response and a
//!   Gauss-Legendre rule on dyadic segments around the band (their spectra fall
//!   with frequency, so what lies far above the band is negligible).
//!
//! The equivalent degrees of freedom of a level's mean square follow from the
//! same spectra: `EDF_j = N_j (int P)^2 / (2^{-j-1} int P^2)`, normalised so that
//! white noise gives exactly `N_j` (the coefficients of white noise through an
//! orthonormal DWT are independent).

// Rows, weights and coefficients are parallel arrays indexed together.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;
use std::f64::consts::PI;
use std::sync::{Arc, Mutex, OnceLock};

use super::filter::ReadoutFilter;
use super::resonance::Ar2;

/// A noise term whose spectrum is known up to a scale `theta` (its squared
/// IEEE 952 coefficient in arcsec/s units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpectralTerm {
    /// White angle noise of variance `theta` arcsec^2 (quantization, Q^2).
    WhiteAngle,
    /// White rate noise, `theta` = N^2 in arcsec^2/s (angle random walk).
    WhiteRate,
    /// Flicker rate noise, one-sided PSD `theta / (pi f)` for `f >= f_lo_hz`
    /// (bias instability; AVAR plateau `(2 ln 2 / pi) theta`), `theta` = B^2.
    Flicker { f_lo_hz: f64 },
    /// Rate random walk: increments of variance `theta * tau0` per sample,
    /// `theta` = K^2 in (arcsec/s)^2/s; AVAR `theta tau / 3`.
    RateRandomWalk,
    /// First-order Gauss-Markov rate with correlation time `tau_c_s`,
    /// stationary variance `theta` (arcsec/s)^2.
    GaussMarkov { tau_c_s: f64 },
    /// White rate noise through a readout filter (`theta` = N^2 of the
    /// unfiltered band, arcsec^2/s; the filter has unit DC gain).
    FilteredWhiteRate { filter: ReadoutFilter },
    /// The part of a white rate that a readout filter removes, `1 - |H|^2`
    /// (0 at DC): with [`SpectralTerm::FilteredWhiteRate`] it spans white noise
    /// added after the filter (a rate word's rounding) as `theta_f |H|^2 +
    /// theta_c (1 - |H|^2)`, so that `theta_f` stays the whole white level at
    /// low frequency (N^2) whatever share of it passed the filter.
    WhiteRateComplement { filter: ReadoutFilter },
    /// A resonance of unit variance (`theta` = sigma^2 in (arcsec/s)^2):
    /// the AR(2) rate of [`crate::model::resonance`] with centre and
    /// half-power width in cycles per sample, seen through the readout
    /// filter when there is one.
    Resonance {
        centre_nu: f64,
        width_nu: f64,
        filter: Option<ReadoutFilter>,
    },
}

/// Which signal the DWT analyses: the rate (arcsec/s) or the angle (arcsec,
/// the cumulative sum of rate x tau0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Domain {
    Rate,
    Angle,
}

impl SpectralTerm {
    /// One-sided PSD per unit theta, in the given domain: (arcsec/s)^2 or
    /// arcsec^2 per (cycle/sample). The angle is the running sum of rate x tau0,
    /// so its PSD is the rate PSD times `tau0^2 / (4 sin^2(pi nu))`.
    pub fn psd_domain(&self, nu: f64, tau0_s: f64, domain: Domain) -> f64 {
        self.psd_domain_trig(
            nu,
            (PI * nu).sin(),
            || (2.0 * PI * nu).cos(),
            tau0_s,
            domain,
        )
    }

    /// [`SpectralTerm::psd_domain`] from `s = sin(pi nu)` and (called only
    /// by the terms that need it) `c2 = cos(2 pi nu)`, for quadratures that
    /// hold them per node.
    pub fn psd_domain_trig(
        &self,
        nu: f64,
        s: f64,
        c2: impl FnOnce() -> f64,
        tau0_s: f64,
        domain: Domain,
    ) -> f64 {
        match (domain, self) {
            (Domain::Rate, _) => self.psd_cs_trig(nu, s, c2, tau0_s),
            (Domain::Angle, SpectralTerm::WhiteAngle) => 2.0,
            (Domain::Angle, _) => {
                self.psd_cs_trig(nu, s, c2, tau0_s) * tau0_s * tau0_s / (4.0 * s * s)
            }
        }
    }

    /// The readout filter a term passes through, if any.
    pub fn filter(&self) -> Option<ReadoutFilter> {
        match *self {
            SpectralTerm::FilteredWhiteRate { filter }
            | SpectralTerm::WhiteRateComplement { filter } => Some(filter),
            SpectralTerm::Resonance { filter, .. } => filter,
            _ => None,
        }
    }

    /// One-sided PSD per unit theta in (arcsec/s)^2 per (cycle/sample), at `nu`
    /// cycles/sample, for sample period `tau0_s` (discrete-time forms).
    pub fn psd_cs(&self, nu: f64, tau0_s: f64) -> f64 {
        self.psd_cs_trig(nu, (PI * nu).sin(), || (2.0 * PI * nu).cos(), tau0_s)
    }

    /// [`SpectralTerm::psd_cs`] from `s = sin(pi nu)` and `c2 = cos(2 pi nu)`.
    fn psd_cs_trig(&self, nu: f64, s: f64, c2: impl FnOnce() -> f64, tau0_s: f64) -> f64 {
        match *self {
            SpectralTerm::WhiteAngle => 8.0 * s * s / (tau0_s * tau0_s),
            SpectralTerm::WhiteRate => 2.0 / tau0_s,
            SpectralTerm::Flicker { f_lo_hz } => {
                if nu * (1.0 / tau0_s) < f_lo_hz {
                    0.0
                } else {
                    1.0 / (PI * nu)
                }
            }
            SpectralTerm::RateRandomWalk => tau0_s / (2.0 * s * s),
            SpectralTerm::GaussMarkov { tau_c_s } => {
                let phi = (-tau0_s / tau_c_s).exp();
                2.0 * (1.0 - phi * phi) / (1.0 + phi * phi - 2.0 * phi * c2())
            }
            SpectralTerm::FilteredWhiteRate { filter } => {
                2.0 / tau0_s * filter.power_trig(nu, s, c2)
            }
            SpectralTerm::WhiteRateComplement { filter } => {
                2.0 / tau0_s * (1.0 - filter.power_trig(nu, s, c2))
            }
            SpectralTerm::Resonance {
                centre_nu,
                width_nu,
                filter,
            } => {
                let c = c2();
                let p = Ar2::from_nu(centre_nu, width_nu).psd_cs_cos(c);
                match filter {
                    Some(f) => p * f.power_trig(nu, s, || c),
                    None => p,
                }
            }
        }
    }

    /// Rate autocovariance at lags 0, 1, ... per unit theta, for terms with
    /// finite support.
    fn finite_autocov(&self, tau0_s: f64, domain: Domain) -> Option<Vec<f64>> {
        if domain == Domain::Angle {
            return match *self {
                SpectralTerm::WhiteAngle => Some(vec![1.0]),
                _ => None,
            };
        }
        match *self {
            SpectralTerm::WhiteAngle => {
                Some(vec![2.0 / (tau0_s * tau0_s), -1.0 / (tau0_s * tau0_s)])
            }
            SpectralTerm::WhiteRate => Some(vec![1.0 / tau0_s]),
            SpectralTerm::FilteredWhiteRate { filter } => filter
                .finite_autocorr()
                .map(|r| r.iter().map(|v| v / tau0_s).collect()),
            SpectralTerm::WhiteRateComplement { filter } => filter.finite_autocorr().map(|r| {
                r.iter()
                    .enumerate()
                    .map(|(k, v)| (f64::from(u8::from(k == 0)) - v) / tau0_s)
                    .collect()
            }),
            _ => None,
        }
    }
}

impl SpectralTerm {
    /// Expected overlapping Allan variance, (arcsec/s)^2 per unit theta, at
    /// averaging factor `m` (tau = m tau0) for the discrete-time process:
    /// closed forms for white angle (3/tau^2) and white rate (1/tau), else
    /// `int_0^{1/2} S(nu) 2 sin^4(pi nu m) / (m^2 sin^2(pi nu)) dnu` by
    /// quadrature (resolved panels up to nu = 64/m, the sin^4 -> 3/8 envelope beyond).
    ///
    /// The quadratures are memoised process-wide (the estimator evaluates the
    /// same long-tau points for every candidate filter and at every update).
    pub fn allan_var(&self, m: u64, tau0_s: f64) -> f64 {
        let tau = m as f64 * tau0_s;
        match *self {
            SpectralTerm::WhiteAngle => 3.0 / (tau * tau),
            SpectralTerm::WhiteRate => 1.0 / tau,
            _ => {
                let mut key = term_key(self).to_vec();
                key.extend([m, tau0_s.to_bits()]);
                memoised(&ALLAN_CACHE, ALLAN_CACHE_ENTRIES, key, || {
                    self.allan_var_quadrature(m, tau0_s)
                })
            }
        }
    }

    /// [`SpectralTerm::allan_var`] by quadrature, for the terms without a closed form.
    fn allan_var_quadrature(&self, m: u64, tau0_s: f64) -> f64 {
        let mf = m as f64;
        let nu_lo = match *self {
            SpectralTerm::Flicker { f_lo_hz } => f_lo_hz * tau0_s,
            _ => 0.0,
        };
        // the PSD from the same sin(pi nu) (psd_cs would compute it again)
        let psd = |nu: f64, s0: f64| self.psd_cs_trig(nu, s0, || (2.0 * PI * nu).cos(), tau0_s);
        let g = |nu: f64| {
            let s1 = (PI * nu * mf).sin();
            let s0 = (PI * nu).sin();
            psd(nu, s0) * 2.0 * s1.powi(4) / (mf * mf * s0 * s0)
        };
        let envelope = |nu: f64| {
            let s0 = (PI * nu).sin();
            psd(nu, s0) * 0.75 / (mf * mf * s0 * s0)
        };
        let split = (64.0 / mf).min(0.5);
        let mut total = 0.0;
        // resolved part: panels of width 1/(4m) in nu
        let mut panels = ((split - nu_lo).max(0.0) * 4.0 * mf).ceil() as usize;
        if let SpectralTerm::FilteredWhiteRate { filter }
        | SpectralTerm::WhiteRateComplement { filter } = self
        {
            // resolve the filter's own structure (a moving average's lobes)
            let lobes = match filter {
                ReadoutFilter::MovingAverage { length } => *length as usize,
                ReadoutFilter::FirstOrder { .. } => 8,
            };
            panels = panels.max(16 * lobes);
        }
        if let SpectralTerm::Resonance { width_nu, .. } = *self {
            // a quarter of the half-power width per panel, over the resolved part
            let fine = (4.0 * (split - nu_lo).max(0.0) / width_nu).ceil();
            panels = panels.max(fine.min(200_000.0) as usize);
        }
        if panels > 0 {
            let h = (split - nu_lo) / panels as f64;
            for p in 0..panels {
                let c = nu_lo + (p as f64 + 0.5) * h;
                for &(x, w) in &GL8 {
                    total += 0.5 * h * w * g(c + 0.5 * h * x);
                }
            }
        }
        if split < 0.5 {
            // envelope part on a log grid
            let a = split.max(nu_lo).ln();
            let b = 0.5f64.ln();
            if b > a {
                let panels = 256;
                let h = (b - a) / panels as f64;
                for p in 0..panels {
                    let c = a + (p as f64 + 0.5) * h;
                    for &(x, w) in &GL8 {
                        let nu = (c + 0.5 * h * x).exp();
                        total += 0.5 * h * w * nu * envelope(nu);
                    }
                }
            }
        }
        total
    }

    /// Power-law exponent alpha of the phase/frequency noise this term looks
    /// like at averaging time `tau_s` (for EDF formulas): 2 white PM,
    /// 0 white FM, -1 flicker FM, -2 random-walk FM.
    pub fn alpha_at(&self, tau_s: f64) -> i32 {
        match *self {
            SpectralTerm::WhiteAngle => 2,
            SpectralTerm::WhiteRate
            | SpectralTerm::FilteredWhiteRate { .. }
            | SpectralTerm::WhiteRateComplement { .. }
            | SpectralTerm::Resonance { .. } => 0,
            SpectralTerm::Flicker { .. } => -1,
            SpectralTerm::RateRandomWalk => -2,
            SpectralTerm::GaussMarkov { tau_c_s } => {
                if tau_s < tau_c_s {
                    -2
                } else {
                    0
                }
            }
        }
    }
}

/// Power response `|H(nu)|^2` of an FIR filter at `nu` cycles/sample.
pub fn power_response(h: &[f64], nu: f64) -> f64 {
    let (sw, cw) = (-2.0 * PI * nu).sin_cos();
    power_at(h, sw, cw)
}

/// `|H|^2` at the angle `w` per sample, from `(sin w, cos w)`: a unit phasor
/// rotated tap by tap instead of a sine and cosine per tap.
#[inline]
fn power_at(h: &[f64], sw: f64, cw: f64) -> f64 {
    let (mut pr, mut pi) = (1.0f64, 0.0f64);
    let (mut re, mut im) = (0.0, 0.0);
    for &c in h {
        re += c * pr;
        im += c * pi;
        let npr = pr * cw - pi * sw;
        pi = pr * sw + pi * cw;
        pr = npr;
    }
    re * re + im * im
}

/// Power response of the level-`j` (1-based) detail filter of a decimated DWT:
/// `|G(2^{j-1} nu)|^2 prod_{i<j-1} |H(2^i nu)|^2`.
///
/// One sine and cosine per call: the angle is doubled from stage to stage by
/// the double-angle formulas (the phase error grows as `2^i eps`, as it does
/// when `2 pi 2^i nu` is rounded and reduced directly).
pub fn level_power_response(lo: &[f64], hi: &[f64], level: u32, nu: f64) -> f64 {
    let (mut s, mut c) = (-2.0 * PI * nu).sin_cos();
    let mut p = 1.0;
    for _ in 0..level - 1 {
        p *= power_at(lo, s, c);
        (s, c) = (2.0 * s * c, (c - s) * (c + s));
    }
    p * power_at(hi, s, c)
}

fn autocorr(h: &[f64]) -> Vec<f64> {
    // c(m) for m = 0..L-1 (symmetric)
    (0..h.len())
        .map(|m| h.iter().zip(&h[m..]).map(|(a, b)| a * b).sum())
        .collect()
}

fn sym_get(r: &[f64], lag: i64) -> f64 {
    let l = lag.unsigned_abs() as usize;
    if l < r.len() { r[l] } else { 0.0 }
}

/// Exact detail variances for levels 1..=levels of a rate process with a finite
/// symmetric autocovariance `r0` (lags 0..r0.len()).
pub fn finite_level_vars(lo: &[f64], hi: &[f64], r0: &[f64], levels: u32) -> Vec<f64> {
    let clo = autocorr(lo);
    let chi = autocorr(hi);
    let lmax = lo.len() as i64 - 1;
    let mut r = r0.to_vec();
    let mut out = Vec::with_capacity(levels as usize);
    for _ in 0..levels {
        let mut v = 0.0;
        for m in -lmax..=lmax {
            v += sym_get(&chi, m) * sym_get(&r, m);
        }
        out.push(v);
        // lowpass + decimate
        let w = r.len() as i64 - 1;
        let w_new = (w + lmax + 1) / 2;
        let mut rn = vec![0.0; w_new as usize + 1];
        for (t, slot) in rn.iter_mut().enumerate() {
            let mut s = 0.0;
            for m in -lmax..=lmax {
                s += sym_get(&clo, m) * sym_get(&r, 2 * t as i64 - m);
            }
            *slot = s;
        }
        r = rn;
    }
    out
}

/// Gauss-Legendre nodes and weights on [-1, 1] (8 points).
pub(crate) const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

/// Quadrature nodes `(nu, weight, |H_j(nu)|^2)` covering the frequencies that
/// matter for level `j`: dyadic segments from 2^{-j-14} up to min(1/2, 2^{-j+4}),
/// each split into 32 panels of an 8-point Gauss-Legendre rule.
pub fn level_nodes(
    lo: &[f64],
    hi: &[f64],
    level: u32,
    extra_breaks: &[f64],
) -> Vec<(f64, f64, f64)> {
    let top = (2f64.powi(-(level as i32) + 4)).min(0.5);
    let bottom = 2f64.powi(-(level as i32) - 14);
    let mut breaks = vec![bottom];
    let mut b = bottom;
    while b * 2.0 < top {
        b *= 2.0;
        breaks.push(b);
    }
    breaks.push(top);
    for &e in extra_breaks {
        if e > bottom && e < top {
            breaks.push(e);
        }
    }
    breaks.sort_by(|a, b| a.total_cmp(b));
    breaks.dedup();
    let mut nodes = Vec::with_capacity(breaks.len() * 32 * 8);
    for seg in breaks.windows(2) {
        let (a, b) = (seg[0], seg[1]);
        let panels = 32;
        let h = (b - a) / panels as f64;
        for p in 0..panels {
            let c = a + (p as f64 + 0.5) * h;
            for &(x, w) in &GL8 {
                let nu = c + 0.5 * h * x;
                nodes.push((nu, 0.5 * h * w, level_power_response(lo, hi, level, nu)));
            }
        }
    }
    nodes
}

/// Most level quadratures [`LevelBasis::new_in`] keeps memoised (a few
/// hundred bytes each); the cache is emptied when full. One estimate with the
/// readout-filter search needs about 100 candidate filters x 10-20 levels.
pub const BASIS_CACHE_ENTRIES: usize = 4096;
/// Most levels' quadrature nodes kept memoised (about 200 kB each).
const NODE_CACHE_ENTRIES: usize = 128;

/// Quadrature nodes of one level, shared: `(nu, weight, |H_j(nu)|^2)` and
/// each node's `(sin(pi nu), cos(2 pi nu))`, which every term's PSD is made of
/// (computed once here, not per term and per candidate filter).
struct LevelNodes {
    pts: Vec<(f64, f64, f64)>,
    trig: Vec<(f64, f64)>,
    /// The weights alone, contiguous.
    w: Vec<f64>,
    /// `sum w h2` and `sum w h2^2` (the EDF's white normalisation).
    w_int: f64,
    w_int2: f64,
}

/// One term's values over a level's nodes: `(P(nu) |H_j|^2, w P(nu) |H_j|^2)`.
type Column = Arc<(Vec<f64>, Vec<f64>)>;

static COLUMN_CACHE: Memo<Column> = OnceLock::new();
/// Most term columns kept memoised (about 75 kB each).
const COLUMN_CACHE_ENTRIES: usize = 256;

static ALLAN_CACHE: Memo<f64> = OnceLock::new();
/// Most Allan-variance quadratures kept memoised.
const ALLAN_CACHE_ENTRIES: usize = 8192;

fn term_column(
    t: &SpectralTerm,
    nodes: &LevelNodes,
    tau0_s: f64,
    domain: Domain,
) -> (Vec<f64>, Vec<f64>) {
    let col: Vec<f64> = nodes
        .pts
        .iter()
        .zip(&nodes.trig)
        .map(|(&(nu, _, h2), &(sn, c2))| t.psd_domain_trig(nu, sn, || c2, tau0_s, domain) * h2)
        .collect();
    let wcol = col.iter().zip(&nodes.w).map(|(p, w)| w * p).collect();
    (col, wcol)
}

/// The column of `a - b` (both columns of the same nodes).
fn difference(a: &Column, b: &Column) -> (Vec<f64>, Vec<f64>) {
    let sub = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p - q).collect();
    (sub(&a.0, &b.0), sub(&a.1, &b.1))
}

/// `sum a_i b_i` over four interleaved partial sums (vectorisable).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

type Nodes = Arc<LevelNodes>;

/// A process-wide memo keyed by exact bit patterns.
type Memo<V> = OnceLock<Mutex<HashMap<Vec<u64>, V>>>;

static NODE_CACHE: Memo<Nodes> = OnceLock::new();

/// The memoised value of `key`, computed (outside the lock) and kept if absent;
/// the memo is emptied when it holds `cap` values.
fn memoised<V: Clone>(memo: &Memo<V>, cap: usize, key: Vec<u64>, compute: impl FnOnce() -> V) -> V {
    let map = memo.get_or_init(Default::default);
    if let Some(v) = map.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return v.clone();
    }
    let v = compute();
    let mut m = map.lock().unwrap_or_else(|e| e.into_inner());
    if m.len() >= cap {
        m.clear();
    }
    m.insert(key, v.clone());
    v
}

/// [`level_nodes`], memoised (the filter responses at the nodes are most of a
/// level's quadrature cost, and they do not depend on the terms unless a break
/// falls between the octave breaks).
fn memo_level_nodes(lo: &[f64], hi: &[f64], level: u32, extra_breaks: &[f64]) -> Nodes {
    let mut key = filter_level_key(lo, hi, level, extra_breaks.len());
    // breaks on the octave grid or outside the band add no node: leave them out
    let top = (2f64.powi(-(level as i32) + 4)).min(0.5);
    let bottom = 2f64.powi(-(level as i32) - 14);
    key.extend(
        extra_breaks
            .iter()
            .filter(|&&e| e > bottom && e < top && e.log2().fract() != 0.0)
            .map(|e| e.to_bits()),
    );
    memoised(&NODE_CACHE, NODE_CACHE_ENTRIES, key, || {
        let pts = level_nodes(lo, hi, level, extra_breaks);
        let trig = pts
            .iter()
            .map(|&(nu, _, _)| ((PI * nu).sin(), (2.0 * PI * nu).cos()))
            .collect();
        let w: Vec<f64> = pts.iter().map(|p| p.1).collect();
        let (mut w_int, mut w_int2) = (0.0, 0.0);
        for &(_, w, h2) in &pts {
            w_int += w * h2;
            w_int2 += w * h2 * h2;
        }
        Arc::new(LevelNodes {
            pts,
            trig,
            w,
            w_int,
            w_int2,
        })
    })
}

static LEVEL_CACHE: Memo<LevelQuadrature> = OnceLock::new();

/// The filters and the level as exact bit patterns: the start of every memo key,
/// with room for `more` further words.
fn filter_level_key(lo: &[f64], hi: &[f64], level: u32, more: usize) -> Vec<u64> {
    let mut k = Vec::with_capacity(lo.len() + hi.len() + 3 + more);
    k.push(lo.len() as u64);
    k.extend(lo.iter().map(|x| x.to_bits()));
    k.push(hi.len() as u64);
    k.extend(hi.iter().map(|x| x.to_bits()));
    k.push(u64::from(level));
    k
}

/// Everything one level's quadrature depends on, as exact bit patterns.
fn level_key(
    lo: &[f64],
    hi: &[f64],
    tau0_s: f64,
    level: u32,
    terms: &[SpectralTerm],
    domain: Domain,
) -> Vec<u64> {
    let mut k = filter_level_key(lo, hi, level, 2 + 2 * terms.len());
    k.push(tau0_s.to_bits());
    k.push(domain as u64);
    for t in terms {
        k.extend(term_key(t));
    }
    k
}

/// A term as exact bit patterns: its kind and its parameter.
fn term_key(t: &SpectralTerm) -> [u64; 4] {
    let one = |tag: u64, p: f64| [tag, p.to_bits(), 0, 0];
    match *t {
        SpectralTerm::WhiteAngle => one(0, 0.0),
        SpectralTerm::WhiteRate => one(1, 0.0),
        SpectralTerm::Flicker { f_lo_hz } => one(2, f_lo_hz),
        SpectralTerm::RateRandomWalk => one(3, 0.0),
        SpectralTerm::GaussMarkov { tau_c_s } => one(4, tau_c_s),
        SpectralTerm::FilteredWhiteRate { filter } => {
            let (kind, bits) = filter.key();
            [4 + kind, bits, 0, 0]
        }
        SpectralTerm::WhiteRateComplement { filter } => {
            let (kind, bits) = filter.key();
            [8 + kind, bits, 0, 0]
        }
        SpectralTerm::Resonance {
            centre_nu,
            width_nu,
            filter,
        } => {
            let (kind, bits) = filter.map_or((0, 0), |f| f.key());
            [16 + kind, centre_nu.to_bits(), width_nu.to_bits(), bits]
        }
    }
}

/// Frequencies (cycles/sample) where a term's spectrum has structure the
/// octave grid does not resolve: a flicker's low corner, a resonance's centre
/// and its flanks out to eight widths.
fn term_breaks(t: &SpectralTerm, tau0_s: f64) -> Vec<f64> {
    match *t {
        SpectralTerm::Flicker { f_lo_hz } => vec![f_lo_hz * tau0_s],
        SpectralTerm::Resonance {
            centre_nu,
            width_nu,
            ..
        } => [-8.0, -4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0]
            .iter()
            .map(|k| centre_nu + k * width_nu)
            .filter(|&nu| nu > 0.0 && nu < 0.5)
            .collect(),
        _ => Vec::new(),
    }
}

/// For each term with a finite-support autocovariance, its exact variance at
/// levels `1..=max(levels)` (those terms need no quadrature); `None` for the others.
fn finite_terms_level_vars(
    lo: &[f64],
    hi: &[f64],
    tau0_s: f64,
    levels: &[u32],
    terms: &[SpectralTerm],
    domain: Domain,
) -> Vec<Option<Vec<f64>>> {
    let max_level = levels.iter().copied().max().unwrap_or(1);
    terms
        .iter()
        .map(|t| {
            t.finite_autocov(tau0_s, domain)
                .map(|r0| finite_level_vars(lo, hi, &r0, max_level))
        })
        .collect()
}

static BAND_CACHE: Memo<f64> = OnceLock::new();
/// Most band integrals [`LevelBasis::bands_in`] keeps memoised (a few hundred
/// bytes of key each).
const BAND_CACHE_ENTRIES: usize = 8192;

/// The band integral of term `t` at level `j` among `terms` (whose breaks
/// place the nodes), as [`LevelQuadrature::compute`] sums it: a complement
/// whose filtered white rate is among the terms is the white rate's column
/// less the filtered one (both bands are computed, and kept, together).
#[allow(clippy::too_many_arguments)]
fn level_band(
    lo: &[f64],
    hi: &[f64],
    tau0_s: f64,
    j: u32,
    t: &SpectralTerm,
    terms: &[SpectralTerm],
    breaks: &[f64],
    domain: Domain,
) -> f64 {
    let filter = match *t {
        SpectralTerm::FilteredWhiteRate { filter }
        | SpectralTerm::WhiteRateComplement { filter } => Some(filter),
        _ => None,
    };
    let at = |u: &SpectralTerm| terms.iter().position(|v| v == u);
    // a filtered white rate and, after it, its complement: a pair
    let pair = filter.filter(|&filter| {
        let f = at(&SpectralTerm::FilteredWhiteRate { filter });
        let c = at(&SpectralTerm::WhiteRateComplement { filter });
        matches!((f, c), (Some(f), Some(c)) if f < c)
    });
    let key = |u: &SpectralTerm, paired: bool| {
        let mut k = column_key(lo, hi, tau0_s, j, u, breaks, domain);
        k.push(u64::from(paired));
        k
    };
    let paired = pair.is_some();
    memoised(&BAND_CACHE, BAND_CACHE_ENTRIES, key(t, paired), || {
        let nodes = memo_level_nodes(lo, hi, j, breaks);
        let Some(filter) = pair else {
            return term_column(t, &nodes, tau0_s, domain).1.iter().sum();
        };
        // the white rate's column is the memoised one of the full quadrature
        let white = memoised(
            &COLUMN_CACHE,
            COLUMN_CACHE_ENTRIES,
            column_key(lo, hi, tau0_s, j, &SpectralTerm::WhiteRate, breaks, domain),
            || {
                Arc::new(term_column(
                    &SpectralTerm::WhiteRate,
                    &nodes,
                    tau0_s,
                    domain,
                ))
            },
        );
        let f = SpectralTerm::FilteredWhiteRate { filter };
        let fcol = term_column(&f, &nodes, tau0_s, domain);
        let f_band: f64 = fcol.1.iter().sum();
        let c_band: f64 = white.1.iter().zip(&fcol.1).map(|(p, q)| p - q).sum();
        let c = SpectralTerm::WhiteRateComplement { filter };
        let (mine, other, other_band) = if *t == f {
            (f_band, c, c_band)
        } else {
            (c_band, f, f_band)
        };
        memoised(&BAND_CACHE, BAND_CACHE_ENTRIES, key(&other, true), || {
            other_band
        });
        mine
    })
}

/// The memo key of a term's column at level `j` with the nodes placed by `breaks`.
fn column_key(
    lo: &[f64],
    hi: &[f64],
    tau0_s: f64,
    j: u32,
    t: &SpectralTerm,
    breaks: &[f64],
    domain: Domain,
) -> Vec<u64> {
    let mut key = level_key(lo, hi, tau0_s, j, std::slice::from_ref(t), domain);
    key.extend(breaks.iter().map(|b| b.to_bits()));
    key
}

/// The spectral quadrature of one level: band integrals of the terms, their
/// Gram matrix and the white-noise normalisation of the EDF.
#[derive(Debug, Clone)]
struct LevelQuadrature {
    band: Vec<f64>,
    gram: Vec<Vec<f64>>,
    white_ratio: f64,
}

impl LevelQuadrature {
    fn compute(
        lo: &[f64],
        hi: &[f64],
        tau0_s: f64,
        j: u32,
        terms: &[SpectralTerm],
        domain: Domain,
    ) -> Self {
        let breaks: Vec<f64> = terms.iter().flat_map(|t| term_breaks(t, tau0_s)).collect();
        let nodes = memo_level_nodes(lo, hi, j, &breaks);
        // one column per term over the nodes (PSD x |H_j|^2, and x weight),
        // then the band integrals and the Gram matrix as dot products of
        // contiguous columns; a term without a filter has the same column in
        // every candidate of the readout-filter search: memoised
        let column = |t: &SpectralTerm| -> Column {
            let key = column_key(lo, hi, tau0_s, j, t, &breaks, domain);
            memoised(&COLUMN_CACHE, COLUMN_CACHE_ENTRIES, key, || {
                Arc::new(term_column(t, &nodes, tau0_s, domain))
            })
        };
        let mut cols: Vec<Column> = Vec::with_capacity(terms.len());
        for t in terms {
            let c = match *t {
                // not memoised: a new column per candidate filter
                SpectralTerm::FilteredWhiteRate { .. } => {
                    Arc::new(term_column(t, &nodes, tau0_s, domain))
                }
                // what the filter removes from a white rate: the white rate's
                // column less the filtered one, when that is already here
                SpectralTerm::WhiteRateComplement { filter } => {
                    let f = SpectralTerm::FilteredWhiteRate { filter };
                    match terms
                        .iter()
                        .position(|u| *u == f)
                        .filter(|&i| i < cols.len())
                    {
                        Some(i) => {
                            Arc::new(difference(&column(&SpectralTerm::WhiteRate), &cols[i]))
                        }
                        None => Arc::new(term_column(t, &nodes, tau0_s, domain)),
                    }
                }
                _ => column(t),
            };
            cols.push(c);
        }
        let k = terms.len();
        let row: Vec<f64> = cols.iter().map(|c| c.1.iter().sum()).collect();
        let mut g = vec![vec![0.0; k]; k];
        for a in 0..k {
            for b in a..k {
                g[a][b] = dot(&cols[a].1, &cols[b].0);
                g[b][a] = g[a][b];
            }
        }
        let (w_int, w_int2) = (nodes.w_int, nodes.w_int2);
        let scale = 2f64.powi(-(j as i32) - 1);
        LevelQuadrature {
            band: row,
            gram: g,
            white_ratio: w_int * w_int / (scale * w_int2),
        }
    }
}

/// The linear model of the detail variances: for each level and term, the
/// variance per unit theta, plus what the EDF computation needs.
#[derive(Debug, Clone)]
pub struct LevelBasis {
    pub terms: Vec<SpectralTerm>,
    pub levels: Vec<u32>,
    /// `phi[j][k]`: variance of level `levels[j]` per unit theta of `terms[k]`.
    pub phi: Vec<Vec<f64>>,
    /// `gram[j][k][l] = int P_k P_l dnu` over the band region (for the EDF).
    pub gram: Vec<Vec<Vec<f64>>>,
    /// `band[j][k] = int P_k dnu` over the same band region as `gram`.
    band: Vec<Vec<f64>>,
    /// White-noise normalisation of the EDF formula per level.
    white_ratio: Vec<f64>,
}

impl LevelBasis {
    /// Build the basis for `levels` (1-based DWT levels) of a record sampled at
    /// `tau0_s`, with filters `lo`/`hi` (orthonormal analysis pair).
    pub fn new(
        lo: &[f64],
        hi: &[f64],
        tau0_s: f64,
        levels: &[u32],
        terms: &[SpectralTerm],
    ) -> Self {
        Self::new_in(lo, hi, tau0_s, levels, terms, Domain::Rate)
    }

    /// As [`LevelBasis::new`], for a DWT of the rate or of the angle.
    ///
    /// A level's quadrature depends only on the filters, the sample period, the
    /// level and the terms, never on data, and costs tens of milliseconds: the
    /// quadrature results are memoised per level, process-wide (at most
    /// [`BASIS_CACHE_ENTRIES`] levels), so the daemon's periodic estimator updates
    /// and the estimator's repeated fits reuse them. A memoised level is the one
    /// computed here, bit for bit.
    pub fn new_in(
        lo: &[f64],
        hi: &[f64],
        tau0_s: f64,
        levels: &[u32],
        terms: &[SpectralTerm],
        domain: Domain,
    ) -> Self {
        let finite = finite_terms_level_vars(lo, hi, tau0_s, levels, terms, domain);
        let mut phi = Vec::with_capacity(levels.len());
        let mut gram = Vec::with_capacity(levels.len());
        let mut white_ratio = Vec::with_capacity(levels.len());
        let mut band = Vec::with_capacity(levels.len());
        for &j in levels {
            let q = memoised(
                &LEVEL_CACHE,
                BASIS_CACHE_ENTRIES,
                level_key(lo, hi, tau0_s, j, terms, domain),
                || LevelQuadrature::compute(lo, hi, tau0_s, j, terms, domain),
            );
            let mut row = q.band.clone();
            for (i, f) in finite.iter().enumerate() {
                if let Some(v) = f {
                    row[i] = v[j as usize - 1];
                }
            }
            band.push(q.band);
            white_ratio.push(q.white_ratio);
            phi.push(row);
            gram.push(q.gram);
        }
        LevelBasis {
            terms: terms.to_vec(),
            levels: levels.to_vec(),
            phi,
            gram,
            band,
            white_ratio,
        }
    }

    /// The rows `phi` of [`LevelBasis::new_in`] alone, bit for bit, without the
    /// Gram matrices (the readout-filter search compares candidates with the
    /// EDFs held fixed, so it needs only these). Finite-support terms (a
    /// moving average's filtered white rate and its complement) take their
    /// exact variances and no quadrature; every other band integral is a
    /// scalar memoised per level and term, so a candidate's bands outlive a
    /// change of the other terms (the flicker's corner as the record grows).
    pub fn bands_in(
        lo: &[f64],
        hi: &[f64],
        tau0_s: f64,
        levels: &[u32],
        terms: &[SpectralTerm],
        domain: Domain,
    ) -> Vec<Vec<f64>> {
        let finite = finite_terms_level_vars(lo, hi, tau0_s, levels, terms, domain);
        let breaks: Vec<f64> = terms.iter().flat_map(|t| term_breaks(t, tau0_s)).collect();
        levels
            .iter()
            .map(|&j| {
                let band =
                    |t: &SpectralTerm| level_band(lo, hi, tau0_s, j, t, terms, &breaks, domain);
                terms
                    .iter()
                    .zip(&finite)
                    .map(|(t, f)| f.as_ref().map_or_else(|| band(t), |v| v[j as usize - 1]))
                    .collect()
            })
            .collect()
    }

    /// Expected variance of level index `j` for parameters `theta`.
    pub fn mean(&self, j: usize, theta: &[f64]) -> f64 {
        self.phi[j].iter().zip(theta).map(|(p, t)| p * t).sum()
    }

    /// Equivalent degrees of freedom of the mean square of `n_coef` detail
    /// coefficients at level index `j`, under parameters `theta`.
    pub fn edf(&self, j: usize, theta: &[f64], n_coef: f64) -> f64 {
        let level = self.levels[j];
        let scale = 2f64.powi(-(level as i32) - 1);
        let g = &self.gram[j];
        let mut den = 0.0;
        for a in 0..theta.len() {
            for b in 0..theta.len() {
                den += theta[a] * theta[b] * g[a][b];
            }
        }
        let num: f64 = self.band[j].iter().zip(theta).map(|(p, t)| p * t).sum();
        if den <= 0.0 || num <= 0.0 {
            return n_coef;
        }
        let ratio = num * num / (scale * den) / self.white_ratio[j];
        (n_coef * ratio).clamp(1.0_f64.min(n_coef), n_coef)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_doubled_angle_level_response_is_the_stage_by_stage_product() {
        // each stage's phasor from its own sine and cosine, as the definition reads
        let direct = |j: u32, nu: f64| {
            let mut p = power_response(&SYM8_HI, nu * (1u64 << (j - 1)) as f64);
            for i in 0..j - 1 {
                p *= power_response(&SYM8_LO, nu * (1u64 << i) as f64);
            }
            p
        };
        for j in [1u32, 2, 5, 12, 20] {
            let mut worst = 0.0f64;
            // from the deep stopband to the passband and up to Nyquist
            for k in 0..4000 {
                let nu = 0.5 * (k as f64 + 0.5) / 4000.0 * 2f64.powi(-(k % 7));
                let (a, b) = (
                    level_power_response(&SYM8_LO, &SYM8_HI, j, nu),
                    direct(j, nu),
                );
                assert!(a >= 0.0);
                // relative to the value, or to 1e-12 of the level's peak gain
                // (2^j) in the deep stopband, where both sums cancel
                let scale = b.max(1e-12 * 2f64.powi(j as i32));
                worst = worst.max((a - b).abs() / scale);
            }
            assert!(worst < 1e-6, "level {j}: relative difference {worst:e}");
        }
    }

    #[test]
    fn the_bands_alone_are_the_basis_rows_bit_for_bit() {
        let fl = SpectralTerm::Flicker {
            f_lo_hz: 2f64.powi(-30) * 1000.0,
        };
        let ma = ReadoutFilter::moving_average(5).unwrap();
        let fo = ReadoutFilter::FirstOrder { pole: 0.7 };
        let sets: Vec<Vec<SpectralTerm>> = vec![
            vec![
                SpectralTerm::WhiteAngle,
                SpectralTerm::WhiteRate,
                fl,
                SpectralTerm::RateRandomWalk,
            ],
            [ma, fo]
                .iter()
                .flat_map(|&filter| {
                    [
                        SpectralTerm::WhiteAngle,
                        SpectralTerm::FilteredWhiteRate { filter },
                        fl,
                        SpectralTerm::RateRandomWalk,
                        SpectralTerm::WhiteRateComplement { filter },
                    ]
                })
                .collect(),
            // a complement with no filtered white rate before it
            vec![
                SpectralTerm::WhiteRateComplement { filter: fo },
                SpectralTerm::GaussMarkov { tau_c_s: 3.0 },
            ],
        ];
        let levels: Vec<u32> = (1..=14).collect();
        for terms in &sets {
            for domain in [Domain::Rate, Domain::Angle] {
                let b = LevelBasis::new_in(&SYM8_LO, &SYM8_HI, 1e-3, &levels, terms, domain);
                // twice: computed, then from the memo
                for _ in 0..2 {
                    let phi =
                        LevelBasis::bands_in(&SYM8_LO, &SYM8_HI, 1e-3, &levels, terms, domain);
                    for (r, q) in phi.iter().zip(&b.phi) {
                        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                        assert_eq!(bits(r), bits(q), "{terms:?} {domain:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn memoised_basis_is_the_computed_one_and_keys_tell_terms_apart() {
        let terms = [
            SpectralTerm::WhiteRate,
            SpectralTerm::Flicker { f_lo_hz: 1e-2 },
            SpectralTerm::RateRandomWalk,
        ];
        let levels = [3, 7, 12];
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for _ in 0..2 {
            let b = LevelBasis::new_in(&SYM8_LO, &SYM8_HI, 1e-3, &levels, &terms, Domain::Angle);
            for (i, &j) in levels.iter().enumerate() {
                // memoised nodes and quadrature are the ones computed afresh, bit for bit
                let nodes = memo_level_nodes(&SYM8_LO, &SYM8_HI, j, &[1e-5]);
                let fresh_nodes = level_nodes(&SYM8_LO, &SYM8_HI, j, &[1e-5]);
                assert_eq!(nodes.pts.len(), fresh_nodes.len());
                assert_eq!(nodes.trig.len(), fresh_nodes.len());
                for (a, f) in nodes.pts.iter().zip(&fresh_nodes) {
                    assert_eq!(bits(&[a.0, a.1, a.2]), bits(&[f.0, f.1, f.2]));
                }
                let q =
                    LevelQuadrature::compute(&SYM8_LO, &SYM8_HI, 1e-3, j, &terms, Domain::Angle);
                assert_eq!(bits(&b.phi[i]), bits(&q.band), "level {j}");
                assert_eq!(bits(&b.band[i]), bits(&q.band), "level {j}");
                for (g, h) in b.gram[i].iter().zip(&q.gram) {
                    assert_eq!(bits(g), bits(h), "level {j}");
                }
                assert_eq!(b.white_ratio[i].to_bits(), q.white_ratio.to_bits());
            }
        }
        let fresh = LevelBasis::new_in(&SYM8_LO, &SYM8_HI, 1e-3, &levels, &terms, Domain::Angle);
        // a different flicker corner, domain or period is a different basis
        let other = [
            SpectralTerm::WhiteRate,
            SpectralTerm::Flicker { f_lo_hz: 2e-2 },
            SpectralTerm::RateRandomWalk,
        ];
        let k = |t: &[SpectralTerm], d, tau0| level_key(&SYM8_LO, &SYM8_HI, tau0, 7, t, d);
        assert_ne!(
            k(&terms, Domain::Angle, 1e-3),
            k(&other, Domain::Angle, 1e-3)
        );
        assert_ne!(
            k(&terms, Domain::Angle, 1e-3),
            k(&terms, Domain::Rate, 1e-3)
        );
        assert_ne!(
            k(&terms, Domain::Angle, 1e-3),
            k(&terms, Domain::Angle, 2e-3)
        );
        let b = LevelBasis::new_in(&SYM8_LO, &SYM8_HI, 1e-3, &levels, &other, Domain::Angle);
        assert_ne!(b.phi[2][1], fresh.phi[2][1]);
    }

    // PyWavelets sym8 dec_lo / dec_hi (pywt 1.9, printed with repr()).
    pub(crate) const SYM8_LO: [f64; 16] = [
        -0.0033824159510061256,
        -0.0005421323317911481,
        0.03169508781149298,
        0.007607487324917605,
        -0.1432942383508097,
        -0.061273359067658524,
        0.4813596512583722,
        0.7771857517005235,
        0.3644418948353314,
        -0.05194583810770904,
        -0.027219029917056003,
        0.049137179673607506,
        0.003808752013890615,
        -0.01495225833704823,
        -0.0003029205147213668,
        0.0018899503327594609,
    ];
    pub(crate) const SYM8_HI: [f64; 16] = [
        -0.0018899503327594609,
        -0.0003029205147213668,
        0.01495225833704823,
        0.003808752013890615,
        -0.049137179673607506,
        -0.027219029917056003,
        0.05194583810770904,
        0.3644418948353314,
        -0.7771857517005235,
        0.4813596512583722,
        0.061273359067658524,
        -0.1432942383508097,
        -0.007607487324917605,
        0.03169508781149298,
        0.0005421323317911481,
        -0.0033824159510061256,
    ];

    #[test]
    fn white_rate_has_unit_variance_at_every_level() {
        // orthonormal DWT: white noise of variance s^2 gives detail variance s^2
        let v = finite_level_vars(&SYM8_LO, &SYM8_HI, &[1.0], 20);
        for (j, x) in v.iter().enumerate() {
            assert!((x - 1.0).abs() < 1e-12, "level {}: {x}", j + 1);
        }
    }

    #[test]
    fn white_angle_level_variance_matches_frequency_integral() {
        // exact lag-domain propagation vs quadrature of 8 sin^2(pi nu) |H_j|^2
        let tau0 = 1e-3;
        let v = finite_level_vars(
            &SYM8_LO,
            &SYM8_HI,
            &[2.0 / (tau0 * tau0), -1.0 / (tau0 * tau0)],
            8,
        );
        for j in 1..=8u32 {
            // full-band quadrature on a fine uniform grid (QN rises with f, so all of [0, 1/2] matters)
            let n = 200_000;
            let mut s = 0.0;
            for i in 0..n {
                let nu = (i as f64 + 0.5) / n as f64 * 0.5;
                s += SpectralTerm::WhiteAngle.psd_cs(nu, tau0)
                    * level_power_response(&SYM8_LO, &SYM8_HI, j, nu);
            }
            s *= 0.5 / n as f64;
            let rel = (s - v[j as usize - 1]).abs() / v[j as usize - 1];
            assert!(
                rel < 1e-6,
                "level {j}: quad {s} exact {} rel {rel}",
                v[j as usize - 1]
            );
        }
    }

    #[test]
    fn flicker_level_variance_matches_ideal_octave_band() {
        // For 1/f noise with one-sided PSD 1/(pi nu), an ideal octave band
        // [2^{-j-1}, 2^{-j}] with orthonormal gain 2^j gives 2^j ln(2)/pi.
        let tau0 = 1e-3;
        let levels: Vec<u32> = (3..=14).collect();
        let b = LevelBasis::new(
            &SYM8_LO,
            &SYM8_HI,
            tau0,
            &levels,
            &[SpectralTerm::Flicker { f_lo_hz: 1e-9 }],
        );
        for (j, row) in b.phi.iter().enumerate() {
            let ideal = 2f64.powi(levels[j] as i32) * 2f64.ln() / PI;
            let rel = (row[0] - ideal).abs() / ideal;
            assert!(
                rel < 0.02,
                "level {}: {} vs {ideal} (rel {rel})",
                levels[j],
                row[0]
            );
        }
    }

    #[test]
    fn allan_quadrature_reproduces_ieee_952_signatures() {
        let tau0 = 1e-3;
        // flicker plateau (2 ln 2 / pi) theta once tau is far from both band edges
        let fl = SpectralTerm::Flicker { f_lo_hz: 1e-9 };
        for m in [100u64, 10_000, 1_000_000] {
            let v = fl.allan_var(m, tau0);
            let plateau = 2.0 * 2f64.ln() / PI;
            assert!(
                (v - plateau).abs() / plateau < 0.01,
                "flicker m={m}: {v} vs {plateau}"
            );
        }
        // rate random walk K^2 tau / 3 (discrete correction O(1/m))
        for m in [1000u64, 100_000] {
            let v = SpectralTerm::RateRandomWalk.allan_var(m, tau0);
            let want = m as f64 * tau0 / 3.0;
            assert!((v - want).abs() / want < 2e-3, "rrw m={m}: {v} vs {want}");
        }
        // white rate through the generic quadrature path equals 1/tau
        let white_via_gm = SpectralTerm::GaussMarkov { tau_c_s: 1e-12 };
        for m in [1u64, 7, 1000] {
            let v = white_via_gm.allan_var(m, tau0);
            // GM with a vanishing correlation time is white with variance 1 per sample: AVAR = 1/m
            assert!(
                ((v - 1.0 / m as f64).abs() * (m as f64)) < 2e-3,
                "white m={m}: {v}"
            );
        }
        // Gauss-Markov closed form: sigma^2 (Tc/tau)^2 (2 tau/Tc - 3 + 4 e^{-tau/Tc} - e^{-2 tau/Tc}) ... for tau >> tau0
        let tc = 5.0;
        for m in [500u64, 5000, 50_000] {
            let tau = m as f64 * tau0;
            let x = tau / tc;
            let want = (1.0 / (x * x)) * (2.0 * x - 3.0 + 4.0 * (-x).exp() - (-2.0 * x).exp());
            let v = SpectralTerm::GaussMarkov { tau_c_s: tc }.allan_var(m, tau0);
            assert!((v - want).abs() / want < 5e-3, "gm m={m}: {v} vs {want}");
        }
    }

    #[test]
    fn angle_domain_white_angle_is_flat_and_arw_grows_like_a_random_walk() {
        let tau0 = 1e-3;
        let levels: Vec<u32> = (1..=10).collect();
        let b = LevelBasis::new_in(
            &SYM8_LO,
            &SYM8_HI,
            tau0,
            &levels,
            &[SpectralTerm::WhiteAngle, SpectralTerm::WhiteRate],
            Domain::Angle,
        );
        for j in 0..levels.len() {
            assert!(
                (b.phi[j][0] - 1.0).abs() < 1e-12,
                "white angle level {}: {}",
                levels[j],
                b.phi[j][0]
            );
            if j >= 3 {
                // a random walk (PSD ~ 1/nu^2) through an orthonormal octave band of gain 2^j:
                // variance ~ 4^j, once the band is far from Nyquist
                let r = b.phi[j][1] / b.phi[j - 1][1];
                assert!(
                    (r - 4.0).abs() < 0.1,
                    "ARW angle ratio at level {}: {r}",
                    levels[j]
                );
            }
        }
    }

    #[test]
    fn white_edf_equals_coefficient_count() {
        let levels: Vec<u32> = (1..=12).collect();
        let b = LevelBasis::new(
            &SYM8_LO,
            &SYM8_HI,
            1e-3,
            &levels,
            &[SpectralTerm::WhiteRate],
        );
        for j in 0..levels.len() {
            let e = b.edf(j, &[1.0], 1000.0);
            assert!((e - 1000.0).abs() < 1e-6, "level {}: {e}", levels[j]);
        }
    }
}
