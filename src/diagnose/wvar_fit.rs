//! Fits on the wavelet variances: the level data, the closed-form basis of
//! each catalog shape, maximum-likelihood fits of an amplitude (and a time
//! constant or period) and their profile intervals. The candidate tests, the
//! broadband fit and the refinement all fit with these.
//!
//! Observations: the recording's sym8 detail variances `y_j`. Under a
//! candidate, their expectation is the model's Monte-Carlo mean `E0_j` plus the
//! closed-form change the candidate makes, `sum_k (theta_k - theta_k^model)
//! phi_jk` ([`crate::model::wvar`]: expected variance of level j per unit
//! squared coefficient of term k). Expectations add because the terms are
//! independent; the hard part (the counter's quantization of any shape) stays
//! in `E0` untouched. Each `y_j` is Gamma distributed with the EDF
//! `nu_j = 2 / var(ln y_j)` of the Monte-Carlo band, so
//! `l = -sum_j (nu_j/2) (ln mu_j + y_j/mu_j)` (the likelihood of
//! [`crate::model::fit`], with an offset).
//!
//! An amplitude is fitted by Fisher scoring ([`fit_amplitude`]); a time
//! constant or period on a log grid refined by golden section
//! ([`fit_shape`]). Which candidates are fitted, and how one is chosen, is
//! the business of [`super::candidates`] and [`super::broadband`].

use std::collections::HashMap;
use std::f64::consts::PI;
use std::sync::{Arc, Mutex};

use super::lowfreq::{LfLayout, LfWindows};
use super::stats::StatSet;
use crate::model::filter::ReadoutFilter;
use crate::model::wvar::{self, LevelBasis, SpectralTerm};

/// Wavelet-level data for the fits.
#[derive(Debug, Clone)]
pub struct LevelData {
    pub levels: Vec<u32>,
    pub y: Vec<f64>,
    /// Current expectation (model Monte-Carlo mean plus accepted changes).
    pub e0: Vec<f64>,
    /// Gamma shape x 2 (EDF) per level.
    pub nu: Vec<f64>,
}

impl LevelData {
    /// Log-likelihood of expectations `mu` (`-inf` if any is not positive).
    pub fn loglik(&self, mu: &[f64]) -> f64 {
        let mut l = 0.0;
        for ((&m, &y), &nu) in mu.iter().zip(&self.y).zip(&self.nu) {
            if !(m > 0.0) {
                return f64::NEG_INFINITY;
            }
            l -= 0.5 * nu * (m.ln() + y / m);
        }
        l
    }
}

/// Expected level variances per unit theta for the catalog's spectral shapes.
#[derive(Debug, Clone)]
pub struct Basis {
    pub tau0_s: f64,
    pub levels: Vec<u32>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    nodes: Vec<Vec<(f64, f64, f64)>>,
    white_angle: Vec<f64>,
    white_rate: Vec<f64>,
    rrw: Vec<f64>,
    /// The low-frequency periodogram rows after the levels, when present.
    lf: Option<Arc<LfWindows>>,
    /// [`Basis::filtered_white_rate`] by filter (the readout searches fit the
    /// same filters again and again; clones share it).
    filtered: Arc<Mutex<HashMap<FilterKey, Arc<Vec<f64>>>>>,
}

/// Filters memoised per basis at most (then the memo starts again).
const FILTER_MEMO: usize = 4096;

/// A readout filter as a memo key (its kind and parameter's bits).
type FilterKey = (u8, u64);

fn filter_key(f: Option<ReadoutFilter>) -> FilterKey {
    match f {
        None => (0, 0),
        Some(ReadoutFilter::MovingAverage { length }) => (1, u64::from(length)),
        Some(ReadoutFilter::FirstOrder { pole }) => (2, pole.to_bits()),
    }
}

impl Basis {
    /// Build for `levels` with analysis filters `lo`, `hi`.
    pub fn new(lo: &[f64], hi: &[f64], tau0_s: f64, levels: &[u32]) -> Basis {
        let lb = LevelBasis::new(
            lo,
            hi,
            tau0_s,
            levels,
            &[
                SpectralTerm::WhiteAngle,
                SpectralTerm::WhiteRate,
                SpectralTerm::RateRandomWalk,
            ],
        );
        let col = |k: usize| lb.phi.iter().map(|r| r[k]).collect::<Vec<f64>>();
        let nodes = levels
            .iter()
            .map(|&j| wvar::level_nodes(lo, hi, j, &[]))
            .collect();
        Basis {
            tau0_s,
            levels: levels.to_vec(),
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            nodes,
            white_angle: col(0),
            white_rate: col(1),
            rrw: col(2),
            lf: None,
            filtered: Arc::default(),
        }
    }

    /// The basis with the low-frequency periodogram rows of `layout` after the
    /// levels ([`super::lowfreq`]); unchanged when the layout has none.
    pub fn with_lf(mut self, layout: &LfLayout) -> Basis {
        if layout.bands.is_empty() {
            return self;
        }
        let win = LfWindows::new(layout, self.tau0_s);
        self.white_angle.extend(win.term(SpectralTerm::WhiteAngle));
        self.white_rate.extend(win.term(SpectralTerm::WhiteRate));
        self.rrw.extend(win.term(SpectralTerm::RateRandomWalk));
        self.lf = Some(Arc::new(win));
        self.filtered = Arc::default();
        self
    }

    /// Whether the rows include the low-frequency periodogram.
    pub fn has_lf(&self) -> bool {
        self.lf.is_some()
    }

    /// `levels` followed by the low-frequency rows of `term`.
    fn with_rows(&self, mut levels: Vec<f64>, term: SpectralTerm) -> Vec<f64> {
        if let Some(w) = &self.lf {
            levels.extend(w.term(term));
        }
        levels
    }

    /// White angle noise, per unit Q^2 (arcsec^2).
    pub fn white_angle(&self) -> Vec<f64> {
        self.white_angle.clone()
    }
    /// White rate noise, per unit N^2 (arcsec^2/s).
    pub fn white_rate(&self) -> Vec<f64> {
        self.white_rate.clone()
    }
    /// Rate random walk, per unit K^2 ((arcsec/s)^2/s).
    pub fn rrw(&self) -> Vec<f64> {
        self.rrw.clone()
    }

    /// White rate noise through a readout filter (`None`: the exact white
    /// column, [`Basis::white_rate`]), per unit N^2 of the unfiltered band.
    pub fn white_rate_through(&self, filter: Option<ReadoutFilter>) -> Vec<f64> {
        match filter {
            None => self.white_rate(),
            Some(f) => self.filtered_white_rate(Some(f)),
        }
    }

    /// White rate noise through `filter` (or unfiltered, `None`) by the
    /// level quadrature ([`wvar::level_nodes`]; the filter's signature is
    /// [`SpectralTerm::FilteredWhiteRate`]): both sides of a change of
    /// filter computed alike, so an unchanged filter changes nothing.
    pub fn filtered_white_rate(&self, filter: Option<ReadoutFilter>) -> Vec<f64> {
        let key = filter_key(filter);
        let memo = |m: &Mutex<HashMap<FilterKey, Arc<Vec<f64>>>>| {
            m.lock()
                .unwrap_or_else(|p| p.into_inner())
                .get(&key)
                .cloned()
        };
        if let Some(v) = memo(&self.filtered) {
            return v.to_vec();
        }
        let v = self.filtered_white_rate_uncached(filter);
        let mut m = self.filtered.lock().unwrap_or_else(|p| p.into_inner());
        if m.len() >= FILTER_MEMO {
            m.clear();
        }
        m.insert(key, Arc::new(v.clone()));
        v
    }

    fn filtered_white_rate_uncached(&self, filter: Option<ReadoutFilter>) -> Vec<f64> {
        let t = match filter {
            Some(filter) => SpectralTerm::FilteredWhiteRate { filter },
            None => SpectralTerm::WhiteRate,
        };
        let levels = self
            .nodes
            .iter()
            .map(|nodes| {
                nodes
                    .iter()
                    .map(|&(nu, w, h2)| w * h2 * t.psd_cs(nu, self.tau0_s))
                    .sum()
            })
            .collect();
        self.with_rows(levels, t)
    }

    /// Flicker from `f_lo_hz`, per unit B^2 ((arcsec/s)^2).
    pub fn flicker(&self, f_lo_hz: f64) -> Vec<f64> {
        let lb = LevelBasis::new(
            &self.lo,
            &self.hi,
            self.tau0_s,
            &self.levels,
            &[SpectralTerm::Flicker { f_lo_hz }],
        );
        self.with_rows(
            lb.phi.iter().map(|r| r[0]).collect(),
            SpectralTerm::Flicker { f_lo_hz },
        )
    }

    /// Gauss-Markov with correlation time `tc_s`, per unit sigma^2.
    pub fn gauss_markov(&self, tc_s: f64) -> Vec<f64> {
        let t = SpectralTerm::GaussMarkov { tau_c_s: tc_s };
        let levels = self
            .nodes
            .iter()
            .map(|nodes| {
                nodes
                    .iter()
                    .map(|&(nu, w, h2)| w * h2 * t.psd_cs(nu, self.tau0_s))
                    .sum()
            })
            .collect();
        self.with_rows(levels, t)
    }

    /// A resonance (centre and width in Hz) through `filter`, per unit
    /// sigma^2 ((arcsec/s)^2): the level quadrature with breaks about the
    /// centre ([`wvar::LevelBasis`]).
    pub fn resonance(
        &self,
        centre_hz: f64,
        width_hz: f64,
        filter: Option<ReadoutFilter>,
    ) -> Vec<f64> {
        let t = SpectralTerm::Resonance {
            centre_nu: centre_hz * self.tau0_s,
            width_nu: width_hz * self.tau0_s,
            filter,
        };
        let lb = LevelBasis::new(&self.lo, &self.hi, self.tau0_s, &self.levels, &[t]);
        self.with_rows(lb.phi.iter().map(|r| r[0]).collect(), t)
    }

    /// A sinusoid of frequency `f_hz`, per unit A^2 ((arcsec/s)^2): power
    /// `A^2/2` through the level's response, with the sample-average gain.
    pub fn sinusoid(&self, f_hz: f64) -> Vec<f64> {
        let nu = f_hz * self.tau0_s;
        let x = PI * nu;
        let sinc2 = if x.abs() < 1e-12 {
            1.0
        } else {
            (x.sin() / x).powi(2)
        };
        let mut rows: Vec<f64> = self
            .levels
            .iter()
            .map(|&j| 0.5 * sinc2 * wvar::level_power_response(&self.lo, &self.hi, j, nu))
            .collect();
        if let Some(w) = &self.lf {
            rows.extend(w.sinusoid(f_hz));
        }
        rows
    }
}

/// The result of fitting one candidate.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Squared amplitude (theta) at the maximum.
    pub theta: f64,
    /// 95 % profile interval on theta.
    pub theta_ci: (f64, f64),
    /// Shape (time constant or period, s) at the maximum, for two-parameter candidates.
    pub shape: Option<f64>,
    pub shape_ci: Option<(f64, f64)>,
    /// Maximised log-likelihood.
    pub loglik: f64,
    /// Parameters fitted.
    pub n_par: usize,
    /// Change of the expectations relative to the current `e0`.
    pub delta_mu: Vec<f64>,
}

/// Deviance defining the 95 % profile interval (chi2_1).
pub const CI_DEVIANCE: f64 = 3.841_458_820_694_124;

/// Maximise the likelihood of `mu = base + theta phi` over `theta >= theta_min`.
/// Returns `(theta, loglik)`.
fn fit_linear(
    data: &LevelData,
    base: &[f64],
    phi: &[f64],
    theta_min: f64,
    start: f64,
) -> (f64, f64) {
    let n = data.y.len();
    // lowest theta keeping every expectation positive
    let mut lo = theta_min;
    for j in 0..n {
        if phi[j] > 0.0 && base[j] + lo * phi[j] <= 0.0 {
            lo = lo.max(-base[j] / phi[j] * (1.0 - 1e-9) + 1e-300);
        }
    }
    let mu_at = |t: f64, mu: &mut Vec<f64>| {
        mu.clear();
        mu.extend((0..n).map(|j| base[j] + t * phi[j]));
    };
    let mut mu = Vec::with_capacity(n);
    let mut theta = start.max(lo);
    mu_at(theta, &mut mu);
    let mut l = data.loglik(&mu);
    if !l.is_finite() {
        // walk up until every expectation is positive
        let scale = phi.iter().cloned().fold(0.0, f64::max).max(1e-300);
        let bump = data.y.iter().cloned().fold(0.0, f64::max) / scale;
        theta = lo + bump.max(1e-300);
        mu_at(theta, &mut mu);
        l = data.loglik(&mu);
    }
    for _ in 0..200 {
        let (mut score, mut info) = (0.0, 0.0);
        for j in 0..n {
            let m = mu[j];
            score += 0.5 * data.nu[j] * phi[j] * (data.y[j] - m) / (m * m);
            info += 0.5 * data.nu[j] * phi[j] * phi[j] / (m * m);
        }
        if !(info > 0.0) {
            break;
        }
        let mut step = score / info;
        let mut improved = false;
        for _ in 0..60 {
            let cand = (theta + step).max(lo);
            mu_at(cand, &mut mu);
            let lc = data.loglik(&mu);
            if lc >= l - 1e-12 * l.abs() {
                let moved = (cand - theta).abs();
                theta = cand;
                improved = moved > 1e-12 * theta.abs().max(1e-300);
                l = lc;
                break;
            }
            step *= 0.5;
        }
        if !improved {
            break;
        }
    }
    mu_at(theta, &mut mu);
    (theta, data.loglik(&mu))
}

/// Bisection for the `theta` where `dev(theta)` crosses `level`, between `a`
/// (inside) and `b` (outside).
fn cross(dev: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, level: f64) -> f64 {
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if dev(m) <= level {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// Profile interval of a one-dimensional maximum `theta_hat` of `prof`
/// (a profile log-likelihood), restricted to `theta >= theta_min`.
fn profile_ci(
    prof: &dyn Fn(f64) -> f64,
    theta_hat: f64,
    l_max: f64,
    theta_min: f64,
    scale: f64,
) -> (f64, f64) {
    let dev = |t: f64| 2.0 * (l_max - prof(t));
    let mut step = scale.max(theta_hat.abs() * 1e-3).max(1e-300);
    // upper
    let mut b = theta_hat + step;
    let mut guard = 0;
    while dev(b) <= CI_DEVIANCE && guard < 200 {
        step *= 2.0;
        b = theta_hat + step;
        guard += 1;
    }
    let hi = cross(&dev, theta_hat, b, CI_DEVIANCE);
    // lower
    let lo = if dev(theta_min) <= CI_DEVIANCE {
        theta_min
    } else {
        cross(&dev, theta_hat, theta_min, CI_DEVIANCE)
    };
    (lo, hi)
}

/// Fisher standard error of theta at `theta` (a bracketing scale).
fn fisher_scale(data: &LevelData, base: &[f64], phi: &[f64], theta: f64) -> f64 {
    let mut info = 0.0;
    for j in 0..data.y.len() {
        let m = (base[j] + theta * phi[j]).max(1e-300);
        info += 0.5 * data.nu[j] * phi[j] * phi[j] / (m * m);
    }
    if info > 0.0 {
        1.0 / info.sqrt()
    } else {
        theta.abs().max(1e-300)
    }
}

/// Fit `mu = e0 - theta0 phi + theta phi`, `theta >= theta_floor`: the term
/// with expected-variance shape `phi` changes its squared amplitude from
/// `theta0` (`theta_floor` is its physical lower bound, usually 0).
pub fn fit_amplitude(data: &LevelData, phi: &[f64], theta0: f64, theta_floor: f64) -> Fit {
    let base: Vec<f64> = (0..data.y.len())
        .map(|j| data.e0[j] - theta0 * phi[j])
        .collect();
    let (theta, l) = fit_linear(data, &base, phi, theta_floor, theta0.max(theta_floor));
    let se = fisher_scale(data, &base, phi, theta);
    let prof = |t: f64| {
        let mu: Vec<f64> = (0..data.y.len()).map(|j| base[j] + t * phi[j]).collect();
        data.loglik(&mu)
    };
    let theta_min = {
        let mut lo = theta_floor;
        for j in 0..data.y.len() {
            if phi[j] > 0.0 && base[j] <= 0.0 {
                lo = lo.max(-base[j] / phi[j] * (1.0 + 1e-9));
            }
        }
        lo
    };
    let ci = profile_ci(&prof, theta, l, theta_min, se);
    Fit {
        theta,
        theta_ci: ci,
        shape: None,
        shape_ci: None,
        loglik: l,
        n_par: 1,
        delta_mu: phi.iter().map(|p| (theta - theta0) * p).collect(),
    }
}

/// A log grid from `lo` to `hi` with `per_octave` points per octave.
pub fn log_grid(lo: f64, hi: f64, per_octave: usize) -> Vec<f64> {
    if !(hi > lo && lo > 0.0) {
        return vec![lo];
    }
    let n = ((hi / lo).log2() * per_octave as f64).ceil() as usize;
    (0..=n)
        .map(|i| lo * (hi / lo).powf(i as f64 / n.max(1) as f64))
        .collect()
}

/// Fit a two-parameter term: amplitude theta (>= 0) and a shape `s` (time
/// constant or period) on `grid`, with `phi_of(s)` the expected-variance shape.
/// `replace`: `Some((theta0, phi0))` when the candidate replaces an existing
/// term (its old contribution `theta0 phi0` is removed from `e0`).
pub fn fit_shape(
    data: &LevelData,
    grid: &[f64],
    phi_of: &dyn Fn(f64) -> Vec<f64>,
    replace: Option<(f64, &[f64])>,
) -> Option<Fit> {
    let n = data.y.len();
    let base: Vec<f64> = match replace {
        Some((t0, p0)) => (0..n).map(|j| data.e0[j] - t0 * p0[j]).collect(),
        None => data.e0.clone(),
    };
    if base.iter().any(|b| !(*b > 0.0)) && replace.is_none() {
        return None;
    }
    let phis: Vec<Vec<f64>> = grid.iter().map(|&s| phi_of(s)).collect();
    let fits: Vec<(f64, f64)> = phis
        .iter()
        .map(|phi| fit_linear(data, &base, phi, 0.0, 0.0))
        .collect();
    let (ibest, _) = fits
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.1.total_cmp(&b.1.1))?;
    // golden-section refinement of log s between the neighbours
    let (a, b) = (
        grid[ibest.saturating_sub(1)].ln(),
        grid[(ibest + 1).min(grid.len() - 1)].ln(),
    );
    let eval = |ls: f64| -> (f64, f64) {
        let phi = phi_of(ls.exp());
        fit_linear(data, &base, &phi, 0.0, 0.0)
    };
    let mut s_best = super::golden::golden_max(&|ls| eval(ls).1, a, b, 30).exp();
    let (mut theta, mut l) = eval(s_best.ln());
    if fits[ibest].1 > l {
        s_best = grid[ibest];
        theta = fits[ibest].0;
        l = fits[ibest].1;
    }
    let phi_best = phi_of(s_best);
    // profile over theta: maximise over the grid shapes (and the best one)
    let mut shapes: Vec<(f64, Vec<f64>)> = grid.iter().cloned().zip(phis.iter().cloned()).collect();
    shapes.push((s_best, phi_best.clone()));
    let prof_theta = |t: f64| -> f64 {
        shapes
            .iter()
            .map(|(_, phi)| {
                let mu: Vec<f64> = (0..n).map(|j| base[j] + t * phi[j]).collect();
                data.loglik(&mu)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let se = fisher_scale(data, &base, &phi_best, theta);
    let theta_ci = profile_ci(&prof_theta, theta, l, 0.0, se);
    // profile over the shape: the grid's maximised likelihoods, interpolated in log s
    let mut pts: Vec<(f64, f64)> = grid
        .iter()
        .map(|s| s.ln())
        .zip(fits.iter().map(|f| f.1))
        .collect();
    pts.push((s_best.ln(), l));
    pts.sort_by(|x, y| x.0.total_cmp(&y.0));
    let inside = |v: f64| 2.0 * (l - v) <= CI_DEVIANCE;
    let ib = pts.iter().position(|p| p.0 == s_best.ln()).unwrap_or(0);
    let mut lo_s = pts[0].0;
    for i in (0..ib).rev() {
        if !inside(pts[i].1) {
            // interpolate between i (outside) and i+1 (inside)
            let (x0, y0) = pts[i];
            let (x1, y1) = pts[i + 1];
            let target = l - CI_DEVIANCE / 2.0;
            let t = if (y1 - y0).abs() > 0.0 {
                (target - y0) / (y1 - y0)
            } else {
                0.5
            };
            lo_s = x0 + t.clamp(0.0, 1.0) * (x1 - x0);
            break;
        }
    }
    let mut hi_s = pts[pts.len() - 1].0;
    for i in ib + 1..pts.len() {
        if !inside(pts[i].1) {
            let (x0, y0) = pts[i - 1];
            let (x1, y1) = pts[i];
            let target = l - CI_DEVIANCE / 2.0;
            let t = if (y1 - y0).abs() > 0.0 {
                (target - y0) / (y1 - y0)
            } else {
                0.5
            };
            hi_s = x0 + t.clamp(0.0, 1.0) * (x1 - x0);
            break;
        }
    }
    let delta_mu: Vec<f64> = (0..n)
        .map(|j| base[j] + theta * phi_best[j] - data.e0[j])
        .collect();
    Some(Fit {
        theta,
        theta_ci,
        shape: Some(s_best),
        shape_ci: Some((lo_s.exp(), hi_s.exp())),
        loglik: l,
        n_par: 2,
        delta_mu,
    })
}

/// How much wider a one-parameter fit's interval must be than the likelihood
/// says, because the levels are not independent: a steep spectrum (a readout
/// filter's roll-off) leaks into the finer levels through the wavelet's
/// sidelobes, so their variances move together, while the likelihood counts
/// each level's EDF as independent information (on a 200 Hz gyro behind a
/// 5-sample average, the refitted ARW scattered 4x its claimed width).
///
/// The fit's estimate is linear in the level variances near the optimum,
/// `delta theta = sum_j g_j (y_j - mu_j)`, with `g_j` proportional to
/// `nu_j phi_j / mu_j^2` (the score). Its variance is computed twice on the
/// wavelet levels: from the runs' actual deviations from their mean
/// (`runs_wvar`, what the simulator says), and as the likelihood assumes
/// (`2 mu_j^2 / nu_j`, independent). Returns `sqrt(actual / assumed)`, at
/// least 1 (1 with fewer than four runs).
pub fn level_correlation_factor(data: &LevelData, phi: &[f64], runs_wvar: &[&[f64]]) -> f64 {
    let nl = data.levels.len().min(phi.len());
    if runs_wvar.len() < 4 || runs_wvar.iter().any(|r| r.len() < nl) {
        return 1.0;
    }
    let g: Vec<f64> = (0..nl)
        .map(|j| {
            let mu = data.e0[j];
            if mu > 0.0 {
                data.nu[j] * phi[j] / (mu * mu)
            } else {
                0.0
            }
        })
        .collect();
    let assumed: f64 = (0..nl)
        .map(|j| g[j] * g[j] * 2.0 * data.e0[j] * data.e0[j] / data.nu[j])
        .sum();
    let n = runs_wvar.len() as f64;
    let mean: Vec<f64> = (0..nl)
        .map(|j| runs_wvar.iter().map(|r| r[j]).sum::<f64>() / n)
        .collect();
    let dev: Vec<f64> = runs_wvar
        .iter()
        .map(|r| (0..nl).map(|j| g[j] * (r[j] - mean[j])).sum())
        .collect();
    let actual = dev.iter().map(|d| d * d).sum::<f64>() / (n - 1.0);
    if !(assumed > 0.0 && actual.is_finite()) {
        return 1.0;
    }
    (actual / assumed).sqrt().max(1.0)
}

/// `ci` about `theta` with both half-widths multiplied by `factor` (the
/// lower end kept at or above `floor`).
pub fn widen_ci(theta: f64, ci: (f64, f64), factor: f64, floor: f64) -> (f64, f64) {
    (
        (theta - factor * (theta - ci.0)).max(floor),
        theta + factor * (ci.1 - theta),
    )
}
/// Append the low-frequency rows to `data`: observed `y`, expectation the
/// mean of `runs`, EDF from their log spread floored by `layout`'s analytic
/// EDF. Nothing when the runs carry no such rows.
pub fn append_rows(data: &mut LevelData, layout: &LfLayout, y: &[f64], runs: &[&StatSet]) {
    let nb = layout.bands.len();
    if nb == 0 || y.len() != nb || runs.is_empty() || runs.iter().any(|s| s.lf_psd.len() != nb) {
        return;
    }
    let r = runs.len() as f64;
    let floor = layout.floor_sd();
    for i in 0..nb {
        let vals: Vec<f64> = runs.iter().map(|s| s.lf_psd[i]).collect();
        let e0 = vals.iter().sum::<f64>() / r;
        let logs: Vec<f64> = vals.iter().map(|v| v.max(1e-300).ln()).collect();
        let m = logs.iter().sum::<f64>() / r;
        let var = logs.iter().map(|l| (l - m).powi(2)).sum::<f64>() / (r - 1.0).max(1.0);
        let sd = var.sqrt().max(floor[i]);
        data.y.push(y[i]);
        data.e0.push(e0);
        data.nu.push(2.0 / (sd * sd * (1.0 + 1.0 / r)));
    }
}
