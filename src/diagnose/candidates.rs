//! Phase 4a, the candidate tests (detection by model comparison): every
//! catalog change the broadband stage knows how to fit ([`super::wvar_fit`]) is fitted on the
//! recording's wavelet variances and tested against the model by its
//! likelihood ratio `LR = 2 (l_candidate - l_model)`; the largest LR over all
//! candidates is the test statistic.
//!
//! A per-point gate (max |z| against a Bonferroni threshold over ~80 points)
//! throws away coherent evidence: a Gauss-Markov bias that lifts four
//! adjacent wavelet levels by 2-3 sigma each never crosses ~4 sigma at one
//! point, but a candidate with that spectral shape gains an LR of tens.
//!
//! Null distribution of the maximum, by parametric bootstrap: each of the
//! model's own Monte-Carlo runs is treated as a recording and compared with
//! the other runs (leave-one-out: the reference never contains the run it
//! judges, and has one run fewer than the recording's, so the null is if
//! anything a little wide). The R maxima (R = 16 by default) are too few for
//! an empirical 99 % quantile; a scaled chi-square `c chi2_k` is fitted to
//! them by moments (k clamped to 1..12) and its `1 - alpha` quantile is the
//! threshold, never below the 2-parameter chi-square quantile (the broadband
//! stage's own acceptance test of a two-parameter term).
//!
//! Candidates: changes of Q, ARW, bias instability and RRW (new terms when
//! the model lacks them), of the model's Gauss-Markov amplitudes (and time
//! constants) and telegraph amplitudes; a new Gauss-Markov bias (Tc on a log
//! grid; a random telegraph has the same second-order statistics) and a
//! sinusoid too slow for the line search. A rate ramp is invisible to the
//! wavelets (sym8 has 8 vanishing moments): the slope test keeps it. The
//! modified Allan variance is not in the likelihood: it has no closed-form
//! basis here and its taus overlap the wavelet levels.

use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::compare::{Point, Region};
use super::locate::Located;
use super::points::floors;
use super::reference::Reference;
use super::stats::{StatLayout, StatSet};
use super::wvar_fit::{self, Basis, Fit, LevelData};
use crate::model::GyroModel;
use crate::units;

/// The candidate tests of the diagnosis: `data0` (the recording's level data,
/// [`super::broadband::level_data`]) against the reference's runs.
pub fn test(
    data0: &LevelData,
    basis: &Basis,
    r: &Reference,
    loc: &Located,
    alpha: f64,
) -> Option<ModelComparison> {
    let fw = floors(&r.layout, &r.model, &loc.mc_mean).0;
    compare(
        data0,
        basis,
        &r.model,
        &r.layout,
        &r.runs,
        &fw,
        &loc.wavelet_points(),
        alpha,
    )
}

/// The model comparison of one recording.
#[derive(Debug, Clone)]
pub struct ModelComparison {
    /// Largest LR over the candidates, and the candidate's name.
    pub max_lr: f64,
    pub best: String,
    /// Threshold: the fitted tail's `1 - alpha` quantile.
    pub lr_crit: f64,
    /// The bootstrap maxima (one per Monte-Carlo run, leave-one-out).
    pub null_max: Vec<f64>,
    /// Fitted tail: scale and degrees of freedom of `c chi2_k`.
    pub tail: (f64, f64),
    pub detected: bool,
    /// Every candidate on the recording: name, LR, fit (best LR first).
    pub ranking: Vec<(String, f64, Fit)>,
    /// Where the best candidate moves a wavelet level by more than one sigma
    /// (its predicted change, with the level's observed z).
    pub regions: Vec<Region>,
}

/// One fitted candidate: its name and fit.
pub struct Scored {
    pub name: String,
    pub fit: Fit,
}

/// Fit every catalog candidate on `data` about `model` (its current squared
/// amplitudes are those the expectation `data.e0` was simulated with).
pub fn candidates(data: &LevelData, basis: &Basis, model: &GyroModel, dur_s: f64) -> Vec<Scored> {
    let nz = &model.noise;
    let tau0 = basis.tau0_s;
    let q = model.quantization_q_arcsec();
    let arw = units::dpsh_to_arcsec_per_sqrt_s(nz.arw_dpsh.unwrap_or(0.0));
    let b2 = nz.bias_instability_dph.unwrap_or(0.0).powi(2);
    let k2 = units::dphsh_to_arcsec_per_s_sqrt_s(nz.rrw_dphsh.unwrap_or(0.0)).powi(2);
    let d2_12 = model.gyro.pulse_arcsec.powi(2) / 12.0;
    let mut out = Vec::new();
    let mut push = |name: String, fit: Option<Fit>| {
        if let Some(fit) = fit.filter(|f| f.loglik.is_finite()) {
            out.push(Scored { name, fit });
        }
    };
    let amp =
        |phi: &[f64], t0: f64, floor: f64| Some(wvar_fit::fit_amplitude(data, phi, t0, floor));
    push(
        "quantization_arcsec".into(),
        amp(&basis.white_angle(), q * q, d2_12),
    );
    push(
        "arw_dpsh".into(),
        amp(
            &basis.white_rate_through(model.readout_filter()),
            arw * arw,
            0.0,
        ),
    );
    if super::readout::offered(model) {
        push(
            "readout_filter".into(),
            super::readout::fit(data, basis, arw * arw, model.readout_filter()).map(|f| f.fit),
        );
    }
    let flicker = basis.flicker(model.flicker_f_lo_hz());
    push("bias_instability_dph".into(), amp(&flicker, b2, 0.0));
    push("rrw_dphsh".into(), amp(&basis.rrw(), k2, 0.0));
    let tc_grid = wvar_fit::log_grid(4.0 * tau0, dur_s / 3.0, 4);
    let gm = |t: f64| basis.gauss_markov(t);
    for (i, g) in nz.gauss_markov.iter().enumerate() {
        let s2 = g.sigma_dph * g.sigma_dph;
        let phi0 = basis.gauss_markov(g.tau_c_s);
        push(format!("gauss_markov[{i}].sigma_dph"), amp(&phi0, s2, 0.0));
        push(
            format!("gauss_markov[{i}]"),
            wvar_fit::fit_shape(data, &tc_grid, &gm, Some((s2, &phi0))),
        );
    }
    for (i, r) in nz.random_telegraph.iter().enumerate() {
        let phi0 = basis.gauss_markov(0.5 * r.mean_dwell_s);
        let a2 = r.amplitude_dph * r.amplitude_dph;
        push(
            format!("random_telegraph[{i}].amplitude_dph"),
            amp(&phi0, a2, 0.0),
        );
    }
    push(
        "gauss_markov".into(),
        wvar_fit::fit_shape(data, &tc_grid, &gm, None),
    );
    let p_grid = wvar_fit::log_grid(
        dur_s / super::line_search::SearchParams::default().min_cycles,
        dur_s / 2.0,
        4,
    );
    if p_grid.len() > 1 {
        let sine = |p: f64| basis.sinusoid(1.0 / p);
        push(
            "sinusoid".into(),
            wvar_fit::fit_shape(data, &p_grid, &sine, None),
        );
    }
    out
}

/// Every candidate's LR on `data`, largest first.
pub fn ranked(
    data: &LevelData,
    basis: &Basis,
    model: &GyroModel,
    dur_s: f64,
) -> Vec<(f64, Scored)> {
    let l0 = data.loglik(&data.e0);
    if !l0.is_finite() {
        return Vec::new();
    }
    let mut v: Vec<(f64, Scored)> = candidates(data, basis, model, dur_s)
        .into_iter()
        .map(|c| (2.0 * (c.fit.loglik - l0).max(0.0), c))
        .collect();
    v.sort_by(|a, b| b.0.total_cmp(&a.0));
    v
}

/// The largest LR over the candidates on `data`, with the best candidate.
pub fn max_lr(
    data: &LevelData,
    basis: &Basis,
    model: &GyroModel,
    dur_s: f64,
) -> Option<(f64, Scored)> {
    ranked(data, basis, model, dur_s).into_iter().next()
}

impl ModelComparison {
    /// The candidates within `delta` of the best by AIC (`-LR + 2 n_par`),
    /// best first: changes the wavelet variances cannot tell apart.
    pub fn near_best(&self, delta: f64) -> Vec<&(String, f64, Fit)> {
        let aic = |e: &(String, f64, Fit)| -e.1 + 2.0 * e.2.n_par as f64;
        let best = self.ranking.iter().map(aic).fold(f64::INFINITY, f64::min);
        let mut v: Vec<_> = self
            .ranking
            .iter()
            .filter(|e| aic(e) <= best + delta)
            .collect();
        v.sort_by(|a, b| aic(a).total_cmp(&aic(b)));
        v
    }
}

/// The level data of run `k` judged against the other runs (leave-one-out):
/// expectation their mean, EDF from their log spread (floored by `floor_sd`).
pub fn leave_one_out(
    layout: &StatLayout,
    runs: &[StatSet],
    k: usize,
    floor_sd: &[f64],
    lf: bool,
) -> LevelData {
    let others: Vec<&StatSet> = runs
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, s)| s)
        .collect();
    let r = others.len() as f64;
    let nl = layout.levels.len();
    let mut e0 = vec![0.0; nl];
    let mut nu = vec![0.0; nl];
    for j in 0..nl {
        let vals: Vec<f64> = others.iter().map(|s| s.wvar[j]).collect();
        e0[j] = vals.iter().sum::<f64>() / r;
        let logs: Vec<f64> = vals.iter().map(|v| v.max(1e-300).ln()).collect();
        let m = logs.iter().sum::<f64>() / r;
        let var = logs.iter().map(|l| (l - m).powi(2)).sum::<f64>() / (r - 1.0).max(1.0);
        let sd = var.sqrt().max(floor_sd[j]);
        nu[j] = 2.0 / (sd * sd * (1.0 + 1.0 / r));
    }
    let mut data = LevelData {
        levels: layout.levels.clone(),
        y: runs[k].wvar.clone(),
        e0,
        nu,
    };
    if lf {
        wvar_fit::append_rows(&mut data, &layout.lf, &runs[k].lf_psd, &others);
    }
    data
}

/// A scaled chi-square `c chi2_k` fitted to `x` by moments (k clamped to
/// 1..12, c then set by the mean): `(c, k)`.
pub fn fit_tail(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let v = x.iter().map(|a| (a - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    if !(m > 0.0 && v > 0.0) {
        return (m.max(1e-300), 1.0);
    }
    let k = (2.0 * m * m / v).clamp(1.0, 12.0);
    (m / k, k)
}

/// The `p` quantile of `c chi2_k`.
pub fn tail_quantile((c, k): (f64, f64), p: f64) -> f64 {
    ChiSquared::new(k)
        .map(|d| c * d.inverse_cdf(p))
        .unwrap_or(f64::INFINITY)
}

/// Smallest threshold: the two-parameter chi-square quantile at `1 - alpha`.
fn lr_floor(alpha: f64) -> f64 {
    ChiSquared::new(2.0)
        .map(|d| d.inverse_cdf(1.0 - alpha))
        .unwrap_or(f64::INFINITY)
}

/// Compare `data` (the recording) with the model, calibrating the maximum LR
/// on the model's own runs. `wpts` are the recording's wavelet points (for
/// the z reported in the regions), `floor_sd` the analytic floors of the log
/// sd per level.
#[allow(clippy::too_many_arguments)]
pub fn compare(
    data: &LevelData,
    basis: &Basis,
    model: &GyroModel,
    layout: &StatLayout,
    runs: &[StatSet],
    floor_sd: &[f64],
    wpts: &[&Point],
    alpha: f64,
) -> Option<ModelComparison> {
    let dur = layout.n_samples as f64 * layout.tau0_s();
    let all = ranked(data, basis, model, dur);
    let (lr, best) = all.first().map(|(l, c)| (*l, c))?;
    let null_max: Vec<f64> = (0..runs.len())
        .filter_map(|k| {
            let d = leave_one_out(layout, runs, k, floor_sd, basis.has_lf());
            max_lr(&d, basis, model, dur).map(|x| x.0)
        })
        .collect();
    if null_max.len() < 4 {
        return None;
    }
    let tail = fit_tail(&null_max);
    let lr_crit = tail_quantile(tail, 1.0 - alpha).max(lr_floor(alpha));
    let detected = lr > lr_crit;
    let regions = if detected {
        moved_regions(data, &best.fit, wpts)
    } else {
        Vec::new()
    };
    Some(ModelComparison {
        max_lr: lr,
        best: best.name.clone(),
        lr_crit,
        null_max,
        tail,
        detected,
        regions,
        ranking: all.into_iter().map(|(l, c)| (c.name, l, c.fit)).collect(),
    })
}

/// The tau spans of the levels where `fit` moves the expectation by more than
/// one sigma of the level (log scale), with the observed z of the level.
fn moved_regions(data: &LevelData, fit: &Fit, wpts: &[&Point]) -> Vec<Region> {
    let mut hits = Vec::new();
    for (j, p) in wpts.iter().enumerate().take(data.e0.len()) {
        let e = data.e0[j];
        let moved = ((e + fit.delta_mu[j]).max(1e-300) / e).ln().abs();
        if e > 0.0 && moved > (2.0 / data.nu[j]).sqrt() {
            hits.push((p.tau_lo_s, p.tau_hi_s, p.z));
        }
    }
    super::compare::merge(hits)
}
