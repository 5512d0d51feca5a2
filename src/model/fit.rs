//! Maximum-likelihood fit of noise-term strengths to wavelet variances, with
//! model selection and profile-likelihood confidence intervals.
//!
//! Observations: for each DWT level `j`, the mean square `y_j` of `N_j` detail
//! coefficients. Model: `E[y_j] = mu_j(theta) = sum_k theta_k phi_jk`, linear in
//! the squared coefficients `theta_k >= 0` (see `model::wvar`). Sampling model:
//! `y_j ~ mu_j chi^2_{nu_j} / nu_j` independently across levels, with `nu_j` the
//! level's equivalent degrees of freedom under the fitted spectrum. The log
//! likelihood is then `l = -sum_j (nu_j/2) (ln mu_j + y_j/mu_j)`; its maximum
//! with `theta >= 0` is found by iteratively reweighted non-negative least
//! squares (Fisher scoring for a Gamma GLM with identity link: weights
//! `nu_j / (2 mu_j^2)`), each step solved exactly by enumerating the faces of
//! the positive orthant (at most a handful of terms).
//!
//! * Model selection: backward elimination by likelihood ratio. A term stays
//!   only if dropping it costs `2 dl >= 2.71`, the 5 % point of the
//!   `0.5 chi2_0 + 0.5 chi2_1` mixture that applies to a variance on its
//!   boundary (`3.84`, the 2.5 % point, for the terms in
//!   [`FitOptions::strict`]). At each step the term furthest below its own
//!   threshold goes. No term is forced in.
//! * Intervals: profile likelihood. A kept term gets the set where
//!   `2 (l_max - l_profile(theta_k)) <= 3.84` (95 %, two-sided); a dropped term
//!   gets the one-sided 95 % upper bound where that deviance reaches 2.71.

// Rows, weights and coefficients are parallel arrays indexed together.
#![allow(clippy::needless_range_loop)]
// `!(a >= b)` is meant: a NaN likelihood must fail the test.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::wvar::LevelBasis;

/// One level's observation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelObs {
    /// DWT level (1-based).
    pub level: u32,
    /// Number of detail coefficients averaged.
    pub n_coef: f64,
    /// Their mean square, (arcsec/s)^2.
    pub mean_sq: f64,
}

/// Result for one term.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermFit {
    /// Maximum-likelihood theta in the final model (0 when dropped).
    pub theta: f64,
    /// Kept by model selection.
    pub included: bool,
    /// 95 % profile-likelihood interval on theta (kept terms).
    pub ci95: Option<(f64, f64)>,
    /// One-sided 95 % upper bound on theta (dropped terms).
    pub upper95: Option<f64>,
    /// Likelihood-ratio statistic for the term, 2 (l_with - l_without).
    pub lr: f64,
}

/// Whole fit.
#[derive(Debug, Clone)]
pub struct LevelFit {
    pub terms: Vec<TermFit>,
    pub loglik: f64,
    /// Per-level EDF used in the likelihood.
    pub edf: Vec<f64>,
    /// Per-level fitted variance.
    pub fitted: Vec<f64>,
    /// Pearson chi-square per degree of freedom, `sum nu_j (y_j/mu_j - 1)^2 / 2 / dof`.
    pub chi2_per_dof: f64,
}

/// Thresholds for selection and intervals.
#[derive(Debug, Clone, Copy)]
pub struct FitOptions {
    /// Deviance a term must explain to be kept (default 2.71).
    pub keep_lr: f64,
    /// Terms held to [`FitOptions::keep_lr_strict`] instead (bit mask).
    pub strict: u64,
    /// Deviance a term in `strict` must explain to be kept (default 3.84, the
    /// 2.5 % point of the boundary mixture).
    pub keep_lr_strict: f64,
    /// Deviance defining the two-sided interval (default 3.84).
    pub ci_lr: f64,
    /// Deviance defining the one-sided upper bound (default 2.71).
    pub upper_lr: f64,
    /// Terms forced to stay (e.g. for a diagnosis that tests a fixed model).
    pub always_keep: u64,
    /// Nuisance terms left unconstrained in sign while the intervals of the
    /// others are profiled. A nuisance whose truth sits at its zero boundary
    /// would otherwise be held at 0 whenever the profile pushes against it, and
    /// the rows it would have absorbed would pin the term of interest: the
    /// interval would be that of a model that knows the nuisance is absent.
    pub signed_in_profile: u64,
    /// Terms that, dropped by model selection, are left free (>= 0) while
    /// the intervals and bounds of the others are profiled (bit mask): a term
    /// dropped below its threshold may still be there, and held at 0 it
    /// would leave the others' intervals those of a model that knows it is
    /// absent. Each interval is the union of the selected model's profile and
    /// the profile with these terms free, about that model's own maximum.
    pub free_in_profile: u64,
    /// Profile every readout-filter candidate of the estimator even when its
    /// coarse pass finds none within reach (default false: the coarse pass
    /// decides; true is the reference it is checked against).
    pub full_filter_search: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            keep_lr: 2.705_543_454_095_404,
            strict: 0,
            keep_lr_strict: 3.841_458_820_694_124,
            ci_lr: 3.841_458_820_694_124,
            upper_lr: 2.705_543_454_095_404,
            always_keep: 0,
            signed_in_profile: 0,
            free_in_profile: 0,
            full_filter_search: false,
        }
    }
}

impl FitOptions {
    /// The deviance term `i` must explain to be kept.
    pub fn keep_threshold(&self, i: usize) -> f64 {
        if i < 64 && self.strict & (1 << i) != 0 {
            self.keep_lr_strict
        } else {
            self.keep_lr
        }
    }
}

struct Problem<'a> {
    phi: &'a [Vec<f64>],
    y: Vec<f64>,
    half_edf: Vec<f64>,
    k: usize,
    /// Columns not held to theta >= 0 (bit mask).
    signed: u64,
}

impl Problem<'_> {
    fn mu(&self, j: usize, theta: &[f64]) -> f64 {
        self.phi[j].iter().zip(theta).map(|(p, t)| p * t).sum()
    }

    fn loglik(&self, theta: &[f64]) -> f64 {
        let mut l = 0.0;
        for j in 0..self.y.len() {
            let m = self.mu(j, theta);
            if m <= 0.0 {
                return f64::NEG_INFINITY;
            }
            l -= self.half_edf[j] * (m.ln() + self.y[j] / m);
        }
        l
    }

    /// Maximise the likelihood over the `free` terms (theta >= 0), holding the
    /// others at `base` values.
    fn maximise(&self, free: &[bool], base: &[f64], start: Option<&[f64]>) -> Vec<f64> {
        let n = self.y.len();
        let mut theta = base.to_vec();
        // initial weights from the observations themselves
        let mut w: Vec<f64> = (0..n)
            .map(|j| self.half_edf[j] / (self.y[j] * self.y[j]).max(1e-300))
            .collect();
        if let Some(s) = start {
            theta.copy_from_slice(s);
            for (i, f) in free.iter().enumerate() {
                if !f {
                    theta[i] = base[i];
                }
            }
        } else {
            theta = self.wnnls(free, base, &w);
        }
        let mut l_old = self.loglik(&theta);
        for _ in 0..200 {
            for j in 0..n {
                let m = self.mu(j, &theta).max(1e-300);
                w[j] = self.half_edf[j] / (m * m);
            }
            let cand = self.wnnls(free, base, &w);
            // step halving keeps the likelihood monotone
            let mut step = 1.0;
            let mut next = cand.clone();
            let mut l_new = self.loglik(&next);
            while !(l_new >= l_old - 1e-12 * l_old.abs()) && step > 1e-6 {
                step *= 0.5;
                for i in 0..self.k {
                    next[i] = theta[i] + step * (cand[i] - theta[i]);
                }
                l_new = self.loglik(&next);
            }
            if !(l_new >= l_old - 1e-12 * l_old.abs()) {
                break;
            }
            let change = theta
                .iter()
                .zip(&next)
                .map(|(a, b)| (a - b).abs() / a.abs().max(b.abs()).max(1e-300))
                .fold(0.0f64, f64::max);
            theta = next;
            let dl = l_new - l_old;
            l_old = l_new;
            if change < 1e-11 || dl.abs() < 1e-13 * l_old.abs().max(1.0) && change < 1e-7 {
                break;
            }
        }
        theta
    }

    /// Weighted non-negative least squares of `y - (fixed part)` on the free
    /// columns, by enumerating the faces of the orthant.
    fn wnnls(&self, free: &[bool], base: &[f64], w: &[f64]) -> Vec<f64> {
        let n = self.y.len();
        let free_idx: Vec<usize> = (0..self.k).filter(|&i| free[i]).collect();
        let resid: Vec<f64> = (0..n)
            .map(|j| {
                let fixed: f64 = (0..self.k)
                    .filter(|&i| !free[i])
                    .map(|i| self.phi[j][i] * base[i])
                    .sum();
                self.y[j] - fixed
            })
            .collect();
        // column scales for conditioning
        let scale: Vec<f64> = free_idx
            .iter()
            .map(|&i| {
                let s: f64 = (0..n).map(|j| w[j] * self.phi[j][i] * self.phi[j][i]).sum();
                if s > 0.0 { s.sqrt() } else { 1.0 }
            })
            .collect();
        let m = free_idx.len();
        let mut best: Option<(f64, Vec<f64>)> = None;
        let signed = |b: usize| self.signed & (1 << free_idx[b]) != 0;
        for mask in 0u32..(1u32 << m) {
            // a signed column is never dropped to its face
            if (0..m).any(|b| signed(b) && mask & (1 << b) == 0) {
                continue;
            }
            let sub: Vec<usize> = (0..m).filter(|b| mask & (1 << b) != 0).collect();
            let p = sub.len();
            let mut a = vec![vec![0.0; p]; p];
            let mut rhs = vec![0.0; p];
            for j in 0..n {
                for (r, &br) in sub.iter().enumerate() {
                    let xr = self.phi[j][free_idx[br]] / scale[br];
                    rhs[r] += w[j] * xr * resid[j];
                    for (c, &bc) in sub.iter().enumerate() {
                        a[r][c] += w[j] * xr * self.phi[j][free_idx[bc]] / scale[bc];
                    }
                }
            }
            let Some(sol) = solve(a, rhs) else { continue };
            if sub
                .iter()
                .zip(&sol)
                .any(|(&b, &v)| !v.is_finite() || (v < 0.0 && !signed(b)))
            {
                continue;
            }
            let mut th = base.to_vec();
            for &i in &free_idx {
                th[i] = 0.0;
            }
            for (r, &br) in sub.iter().enumerate() {
                th[free_idx[br]] = sol[r] / scale[br];
            }
            let obj: f64 = (0..n)
                .map(|j| {
                    let e = self.y[j] - self.mu(j, &th);
                    w[j] * e * e
                })
                .sum();
            if best.as_ref().is_none_or(|(b, _)| obj < *b) {
                best = Some((obj, th));
            }
        }
        best.map(|b| b.1).unwrap_or_else(|| base.to_vec())
    }
}

/// One-shot weighted non-negative least squares: minimise
/// `sum_j w_j (y_j - sum_k theta_k phi_jk)^2` over `theta >= 0`.
pub fn weighted_nnls(phi: &[Vec<f64>], y: &[f64], w: &[f64]) -> Vec<f64> {
    let k = phi.first().map_or(0, |r| r.len());
    let prob = Problem {
        phi,
        y: y.to_vec(),
        half_edf: vec![1.0; y.len()],
        k,
        signed: 0,
    };
    prob.wnnls(&vec![true; k], &vec![0.0; k], w)
}

/// Solve a small dense system by Gaussian elimination with partial pivoting.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for c in 0..n {
        let piv = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if !(a[piv][c].abs() >= 1e-300) {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for cc in c..n {
                a[r][cc] -= f * a[c][cc];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// Fit `basis` to `obs` (same level order as `basis.levels`).
pub fn fit_levels(basis: &LevelBasis, obs: &[LevelObs], opts: &FitOptions) -> LevelFit {
    assert_eq!(
        obs.len(),
        basis.levels.len(),
        "observations must match the basis levels"
    );
    let y: Vec<f64> = obs.iter().map(|o| o.mean_sq).collect();
    let n0: Vec<f64> = obs.iter().map(|o| o.n_coef).collect();
    fit_rows(
        &basis.phi,
        &y,
        &n0,
        &|j, theta| basis.edf(j, theta, obs[j].n_coef),
        opts,
        None, // the levels of an orthonormal DWT
    )
}

/// Maximum-likelihood strengths only (no selection, no intervals): the quick
/// fit used while choosing which observations to trust.
pub fn ml_theta(
    phi: &[Vec<f64>],
    y: &[f64],
    edf0: &[f64],
    edf: &dyn Fn(usize, &[f64]) -> f64,
) -> Vec<f64> {
    ml_with_edf(phi, y, edf0, edf, 2).1
}

/// Maximum-likelihood strengths and the log-likelihood they reach with the
/// EDFs held at `edf` (so that models differing in a nonlinear parameter,
/// such as a readout filter's corner, are compared on one likelihood).
pub fn ml_loglik_fixed_edf(phi: &[Vec<f64>], y: &[f64], edf: &[f64]) -> (Vec<f64>, f64) {
    let k = phi.first().map_or(0, |r| r.len());
    let prob = Problem {
        phi,
        y: y.to_vec(),
        half_edf: edf.iter().map(|e| e / 2.0).collect(),
        k,
        signed: 0,
    };
    let theta = prob.maximise(&vec![true; k], &vec![0.0; k], None);
    let l = prob.loglik(&theta);
    (theta, l)
}

/// The EDFs the ML fit converges to (see [`ml_theta`]).
pub fn ml_edf(
    phi: &[Vec<f64>],
    y: &[f64],
    edf0: &[f64],
    edf: &dyn Fn(usize, &[f64]) -> f64,
) -> Vec<f64> {
    let (prob, _) = ml_with_edf(phi, y, edf0, edf, 2);
    prob.half_edf.iter().map(|h| 2.0 * h).collect()
}

/// Maximise the likelihood, re-deriving the EDFs from the fitted spectrum
/// `rounds` times; returns the problem (with its final EDFs) and theta.
fn ml_with_edf<'a>(
    phi: &'a [Vec<f64>],
    y: &[f64],
    edf0: &[f64],
    edf: &dyn Fn(usize, &[f64]) -> f64,
    rounds: usize,
) -> (Problem<'a>, Vec<f64>) {
    let k = phi.first().map_or(0, |r| r.len());
    let n = y.len();
    let mut prob = Problem {
        phi,
        y: y.to_vec(),
        half_edf: edf0.iter().map(|e| e / 2.0).collect(),
        k,
        signed: 0,
    };
    let all = vec![true; k];
    let zero = vec![0.0; k];
    let mut theta = prob.maximise(&all, &zero, None);
    for _ in 0..rounds {
        prob.half_edf = (0..n).map(|j| edf(j, &theta) / 2.0).collect();
        theta = prob.maximise(&all, &zero, Some(&theta));
    }
    (prob, theta)
}

/// The correlation matrix of the observations under a spectrum `theta`, for
/// [`fit_rows`]; `None`: the observations are independent.
pub type Correlation<'a> = Option<&'a dyn Fn(&[f64]) -> Vec<Vec<f64>>>;

/// Generic fit: rows `phi[j][k]` (expected value of observation `j` per unit
/// theta_k), observations `y[j]`, starting EDFs `edf0[j]`, and `edf(j, theta)`
/// giving the EDF of observation `j` under a spectrum. The likelihood takes
/// the observations as independent; where `corr` says they are not, each
/// term's profile threshold is widened by its Godambe factor
/// ([`godambe_factors`]).
pub fn fit_rows(
    phi: &[Vec<f64>],
    y: &[f64],
    edf0: &[f64],
    edf: &dyn Fn(usize, &[f64]) -> f64,
    opts: &FitOptions,
    corr: Correlation,
) -> LevelFit {
    let k = phi.first().map_or(0, |r| r.len());
    let n = y.len();
    let zero = vec![0.0; k];
    // EDF depends on the spectrum: iterate fit -> EDF a few times
    let (prob, mut theta) = ml_with_edf(phi, y, edf0, edf, 4);

    // backward elimination
    let mut active = vec![true; k];
    let mut lr = vec![0.0; k];
    loop {
        let l_act = prob.loglik(&theta);
        let mut worst: Option<(usize, f64, Vec<f64>)> = None;
        for i in 0..k {
            if !active[i] {
                continue;
            }
            let mut act = active.clone();
            act[i] = false;
            let th = prob.maximise(&act, &zero, None);
            let d = (2.0 * (l_act - prob.loglik(&th))).max(0.0);
            lr[i] = d;
            if opts.always_keep & (1 << i) != 0 {
                continue;
            }
            let margin = d - opts.keep_threshold(i);
            if worst.as_ref().is_none_or(|w| margin < w.1) {
                worst = Some((i, margin, th));
            }
        }
        match worst {
            Some((i, margin, th)) if margin < 0.0 => {
                active[i] = false;
                theta = th;
            }
            _ => break,
        }
    }
    let l_max = prob.loglik(&theta);
    let widen = match corr {
        Some(c) => godambe_factors(&prob, &theta, &active, &c(&theta)),
        None => vec![1.0; k],
    };
    let terms = profile_terms(&prob, &theta, &active, &lr, opts, &widen);
    let fitted: Vec<f64> = (0..n).map(|j| prob.mu(j, &theta)).collect();
    let chi2: f64 = (0..n)
        .map(|j| prob.half_edf[j] * (prob.y[j] / fitted[j] - 1.0).powi(2))
        .sum();
    let n_par = active.iter().filter(|a| **a).count();
    let dof = (n as f64 - n_par as f64).max(1.0);
    LevelFit {
        terms,
        loglik: l_max,
        edf: prob.half_edf.iter().map(|h| 2.0 * h).collect(),
        fitted,
        chi2_per_dof: chi2 / dof,
    }
}

/// Profile-likelihood intervals (active terms) and upper bounds (dropped
/// terms) of every term about the fit `theta`. With nuisances in
/// `opts.signed_in_profile`, each interval is the union of the constrained
/// profile's and the profile with those nuisances free in sign, the latter only
/// when the data are consistent with the constraint (the signed optimum within
/// `ci_lr` of the constrained one): a model that needs a negative nuisance does
/// not fit, and its signed profile says nothing about the constrained fit.
fn profile_terms(
    prob: &Problem,
    theta: &[f64],
    active: &[bool],
    lr: &[f64],
    opts: &FitOptions,
    widen: &[f64],
) -> Vec<TermFit> {
    let l_max = prob.loglik(theta);
    let mut terms = profile_with(prob, theta, active, lr, opts, widen, l_max);
    free_dropped_terms(prob, theta, active, lr, opts, widen, &mut terms);
    if opts.signed_in_profile == 0 {
        return terms;
    }
    let signed = Problem {
        signed: opts.signed_in_profile,
        y: prob.y.clone(),
        half_edf: prob.half_edf.clone(),
        ..*prob
    };
    let l_ref = signed
        .loglik(&signed.maximise(active, &vec![0.0; prob.k], Some(theta)))
        .max(l_max);
    if 2.0 * (l_ref - l_max) > opts.ci_lr {
        return terms;
    }
    let wide = profile_with(&signed, theta, active, lr, opts, widen, l_ref);
    union_with(&mut terms, wide, |_| true);
    terms
}

/// Widen each interval and bound of `terms` to its union with `wide`'s, for
/// the terms `i` where `take(i)`.
fn union_with(terms: &mut [TermFit], wide: Vec<TermFit>, take: impl Fn(usize) -> bool) {
    for (i, (t, w)) in terms.iter_mut().zip(wide).enumerate() {
        if !take(i) {
            continue;
        }
        if let (Some((lo, hi)), Some((wl, wh))) = (t.ci95.as_mut(), w.ci95) {
            *lo = lo.min(wl);
            *hi = hi.max(wh);
        }
        if let (Some(u), Some(wu)) = (t.upper95.as_mut(), w.upper95) {
            *u = u.max(wu);
        }
    }
}

/// Widen `terms` (the selected model's profile about `theta`) to the union
/// with the profile where the dropped terms of [`FitOptions::free_in_profile`]
/// are free (>= 0), about that model's maximum. The freed terms' own bounds
/// stay the selected model's.
fn free_dropped_terms(
    prob: &Problem,
    theta: &[f64],
    active: &[bool],
    lr: &[f64],
    opts: &FitOptions,
    widen: &[f64],
    terms: &mut [TermFit],
) {
    let freed: Vec<bool> = (0..prob.k)
        .map(|j| !active[j] && opts.free_in_profile >> j & 1 == 1)
        .collect();
    if !freed.contains(&true) {
        return;
    }
    let act: Vec<bool> = active.iter().zip(&freed).map(|(a, f)| *a || *f).collect();
    let full = prob.maximise(&act, &vec![0.0; prob.k], Some(theta));
    let l_full = prob.loglik(&full).max(prob.loglik(theta));
    let wide = profile_with(prob, &full, &act, lr, opts, widen, l_full);
    union_with(terms, wide, |i| !freed[i]);
}

/// The profile intervals and bounds of [`profile_terms`] for one problem,
/// deviances measured from `l_ref`, term `i`'s thresholds times `widen[i]`.
fn profile_with(
    prob: &Problem,
    theta: &[f64],
    active: &[bool],
    lr: &[f64],
    opts: &FitOptions,
    widen: &[f64],
    l_ref: f64,
) -> Vec<TermFit> {
    let k = prob.k;
    let zero = vec![0.0; k];
    let mut terms = Vec::with_capacity(k);
    for i in 0..k {
        let profile = |t: f64| -> f64 {
            let mut act = active.to_vec();
            act[i] = false;
            let mut base = zero.clone();
            base[i] = t;
            let th = prob.maximise(&act, &base, None);
            2.0 * (l_ref - prob.loglik(&th))
        };
        // a scale for bracketing: Fisher standard error of theta_i
        let se = fisher_se(prob, theta, i);
        let (ci_lr, upper_lr) = (opts.ci_lr * widen[i], opts.upper_lr * widen[i]);
        if active[i] {
            let hi = find_crossing(&profile, theta[i], se, ci_lr);
            let lo = if profile(0.0) <= ci_lr {
                0.0
            } else {
                bisect(&profile, 0.0, theta[i], ci_lr, true)
            };
            terms.push(TermFit {
                theta: theta[i],
                included: true,
                ci95: Some((lo, hi)),
                upper95: None,
                lr: lr[i],
            });
        } else {
            let up = find_crossing(&profile, 0.0, se, upper_lr);
            terms.push(TermFit {
                theta: 0.0,
                included: false,
                ci95: None,
                upper95: Some(up),
                lr: lr[i],
            });
        }
    }
    terms
}

/// Godambe (sandwich) factors of the profile deviance, one per term. The
/// likelihood counts each observation as independent; when they are
/// correlated (`corr`, under `theta`) the deviance of term `i` is
/// asymptotically `c_i chi2_1` with `c_i = (H^-1 J H^-1)_ii / (H^-1)_ii`, `H`
/// the information of the independent likelihood over the active terms (and
/// `i`) and `J` the variance of its score under the correlation. At least 1:
/// intervals are only ever widened.
fn godambe_factors(prob: &Problem, theta: &[f64], active: &[bool], corr: &[Vec<f64>]) -> Vec<f64> {
    let n = prob.y.len();
    let mu: Vec<f64> = (0..n).map(|j| prob.mu(j, theta).max(1e-300)).collect();
    // score weight of observation j for term c, and the observation's sd
    let w = |j: usize, c: usize| prob.half_edf[j] * prob.phi[j][c] / (mu[j] * mu[j]);
    let sd: Vec<f64> = (0..n)
        .map(|j| mu[j] / prob.half_edf[j].max(1e-300).sqrt())
        .collect();
    (0..prob.k)
        .map(|i| {
            let set: Vec<usize> = (0..prob.k).filter(|&c| active[c] || c == i).collect();
            let h: Vec<Vec<f64>> = set
                .iter()
                .map(|&a| {
                    set.iter()
                        .map(|&b| (0..n).map(|j| w(j, a) * prob.phi[j][b]).sum())
                        .collect()
                })
                .collect();
            let pos = set.iter().position(|&c| c == i).expect("i is in the set");
            let mut e = vec![0.0; set.len()];
            e[pos] = 1.0;
            let Some(x) = solve(h, e) else { return 1.0 };
            // x = H^-1 e_i: the score combination of term i
            let g: Vec<f64> = (0..n)
                .map(|j| set.iter().zip(&x).map(|(&c, xc)| w(j, c) * xc).sum::<f64>() * sd[j])
                .collect();
            let num: f64 = (0..n)
                .map(|j| g[j] * (0..n).map(|l| corr[j][l] * g[l]).sum::<f64>())
                .sum();
            let c = num / x[pos];
            if c.is_finite() && x[pos] > 0.0 {
                c.max(1.0)
            } else {
                1.0
            }
        })
        .collect()
}

fn fisher_se(prob: &Problem, theta: &[f64], i: usize) -> f64 {
    let mut info = 0.0;
    for j in 0..prob.y.len() {
        let m = prob.mu(j, theta).max(1e-300);
        info += prob.half_edf[j] * prob.phi[j][i] * prob.phi[j][i] / (m * m);
    }
    if info > 0.0 {
        1.0 / info.sqrt()
    } else {
        theta[i].abs().max(1e-300)
    }
}

/// Smallest t > start where f(t) reaches `level` (f increasing there).
fn find_crossing(f: &dyn Fn(f64) -> f64, start: f64, se: f64, level: f64) -> f64 {
    let mut step = se.max(start * 1e-3).max(1e-300);
    let mut lo = start;
    let mut hi = start + step;
    let mut guard = 0;
    while f(hi) < level && guard < 200 {
        lo = hi;
        step *= 2.0;
        hi = start + step;
        guard += 1;
    }
    bisect(f, lo, hi, level, false)
}

/// Bisection for f(t) = level on [a, b]; `decreasing` tells the direction.
fn bisect(f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, level: f64, decreasing: bool) -> f64 {
    for _ in 0..80 {
        let m = 0.5 * (a + b);
        let above = f(m) > level;
        if above != decreasing {
            b = m;
        } else {
            a = m;
        }
        if (b - a) <= 1e-10 * b.abs() {
            break;
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::super::wvar::{LevelBasis, SpectralTerm};
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{ChiSquared, Distribution};

    const SYM8_LO: [f64; 16] = [
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
    const SYM8_HI: [f64; 16] = [
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

    fn paper_basis(n_samples: f64) -> (LevelBasis, Vec<f64>) {
        let tau0 = 1e-3;
        // levels with at least 8 coefficients free of start-up transients
        let levels: Vec<u32> = (1..=30u32)
            .filter(|&j| n_samples / 2f64.powi(j as i32) - 15.0 >= 8.0)
            .collect();
        let terms = [
            SpectralTerm::WhiteAngle,
            SpectralTerm::WhiteRate,
            SpectralTerm::Flicker {
                f_lo_hz: 1.0 / (n_samples * tau0),
            },
            SpectralTerm::RateRandomWalk,
        ];
        let b = LevelBasis::new(&SYM8_LO, &SYM8_HI, tau0, &levels, &terms);
        let counts: Vec<f64> = levels
            .iter()
            .map(|&j| (n_samples / 2f64.powi(j as i32)).floor() - 15.0)
            .collect();
        (b, counts)
    }

    /// Draw level observations from the fitted sampling model itself and check
    /// that the machinery recovers the truth with calibrated intervals.
    #[test]
    fn profile_intervals_cover_truth_under_the_sampling_model() {
        let n_samples = 3.6e6;
        let (basis, counts) = paper_basis(n_samples);
        // paper's gyro in arcsec/s units: Q = 0.35", N = 0.0015 deg/sqrt(h), B = 0.0025 deg/h, no RRW
        let truth = [
            0.35f64.powi(2),
            (0.0015f64 * 60.0).powi(2),
            0.0025f64.powi(2),
            0.0,
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut cover = [0usize; 3];
        let mut rrw_false = 0;
        let mut bi_found = 0;
        let runs = 200;
        for _ in 0..runs {
            let obs: Vec<LevelObs> = (0..basis.levels.len())
                .map(|j| {
                    let mu = basis.mean(j, &truth);
                    let nu = basis.edf(j, &truth, counts[j]);
                    let x: f64 = ChiSquared::new(nu).unwrap().sample(&mut rng);
                    LevelObs {
                        level: basis.levels[j],
                        n_coef: counts[j],
                        mean_sq: mu * x / nu,
                    }
                })
                .collect();
            let fit = fit_levels(&basis, &obs, &FitOptions::default());
            for t in 0..3 {
                let ok = match (fit.terms[t].ci95, fit.terms[t].upper95) {
                    (Some((lo, hi)), _) => lo <= truth[t] && truth[t] <= hi,
                    (None, Some(up)) => truth[t] <= up,
                    _ => false,
                };
                if ok {
                    cover[t] += 1;
                }
                if t == 2 && fit.terms[t].included {
                    bi_found += 1;
                }
            }
            if fit.terms[3].included {
                rrw_false += 1;
            }
        }
        eprintln!("coverage {cover:?} / {runs}, BI detected {bi_found}, RRW false {rrw_false}");
        for t in 0..3 {
            let c = cover[t] as f64 / runs as f64;
            // 95 % nominal; 200 runs give a binomial sd of 1.5 %
            assert!(c > 0.90 && c <= 0.99, "term {t}: coverage {c}");
        }
        // an absent term is reported at most ~5 % of the time (binomial slack)
        assert!(
            (rrw_false as f64 / runs as f64) < 0.10,
            "RRW false detections {rrw_false}/{runs}"
        );
    }

    /// A nuisance that only the first rows see, its truth at its zero boundary:
    /// with it free in sign, the interval of the flat term no longer leans on
    /// those rows as if the nuisance were known absent; where the rows need it
    /// far below zero (a misfit), the constrained interval stands.
    #[test]
    fn a_signed_nuisance_widens_the_profile_only_when_the_data_allow_it() {
        let shape = [8.0, 4.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let phi: Vec<Vec<f64>> = shape.iter().map(|&s| vec![1.0, s]).collect();
        let edf = vec![2.0e4; shape.len()];
        let fit = |dip: f64, signed: u64| {
            let y: Vec<f64> = shape
                .iter()
                .map(|&s| if s > 0.0 { 1.0 - dip * s / 8.0 } else { 1.0 })
                .collect();
            let opts = FitOptions {
                always_keep: 0b11,
                signed_in_profile: signed,
                ..FitOptions::default()
            };
            let f = fit_rows(&phi, &y, &edf, &|j, _| edf[j], &opts, None);
            let (lo, hi) = f.terms[0].ci95.unwrap();
            (f.terms[1].theta, lo, hi)
        };
        // a dip of half a standard error: the nuisance sits at 0
        let (nuis, lo0, hi0) = fit(0.005, 0);
        let (_, lo1, hi1) = fit(0.005, 0b10);
        assert_eq!(nuis, 0.0);
        assert!(
            lo1 <= lo0 && hi1 >= hi0,
            "[{lo1}, {hi1}] must contain [{lo0}, {hi0}]"
        );
        assert!(
            hi1 - lo1 > 1.1 * (hi0 - lo0),
            "signed [{lo1}, {hi1}] vs constrained [{lo0}, {hi0}]"
        );
        // six rows alone (the nuisance-free ones) give the flat term's width
        // sqrt(2/(6 x 2e4)) x 1.96 x 2 in relative terms: the signed interval is no wider
        let six = 2.0 * 1.959964 * (2.0 / (6.0 * 2.0e4f64)).sqrt();
        assert!(
            hi1 - lo1 <= six * 1.05,
            "signed width {} vs six rows {six}",
            hi1 - lo1
        );
        // a dip of 50 %: the rows want a strongly negative nuisance; unchanged
        let (_, lo2, hi2) = fit(0.5, 0);
        let (_, lo3, hi3) = fit(0.5, 0b10);
        assert_eq!((lo2, hi2), (lo3, hi3));
    }

    /// The exact observations of a flat term of 1 and a second term of
    /// `theta1` with level shape `shape`, each row of EDF `edf`, fitted.
    fn flat_and_shape(shape: &[f64], theta1: f64, edf: f64, opts: &FitOptions) -> LevelFit {
        let phi: Vec<Vec<f64>> = shape.iter().map(|&s| vec![1.0, s]).collect();
        let y: Vec<f64> = shape.iter().map(|&s| 1.0 + theta1 * s).collect();
        let edf = vec![edf; shape.len()];
        fit_rows(&phi, &y, &edf, &|j, _| edf[j], opts, None)
    }

    /// A term whose deviance lies between the two thresholds stays at the
    /// default one and goes when it is held to the strict one; the other
    /// term's selection does not change.
    #[test]
    fn a_strict_term_needs_the_stricter_deviance() {
        let shape = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 4.0, 8.0];
        let fit = |rise: f64, strict: u64| {
            let opts = FitOptions {
                strict,
                ..FitOptions::default()
            };
            flat_and_shape(&shape, rise, 1.0e3, &opts)
        };
        // the rise whose deviance is about 3.3 (bisection on the default fit)
        let (mut a, mut b) = (0.0, 0.05);
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if fit(m, 0).terms[1].lr < 3.3 {
                a = m;
            } else {
                b = m;
            }
        }
        let loose = fit(a, 0);
        let strict = fit(a, 0b10);
        let lr = loose.terms[1].lr;
        assert!((3.2..3.4).contains(&lr), "deviance {lr}");
        assert!(loose.terms[1].included && loose.terms[0].included);
        assert!(!strict.terms[1].included && strict.terms[0].included);
        assert_eq!(strict.terms[1].theta, 0.0);
        assert!(strict.terms[1].upper95.is_some());
    }

    /// Two observations of one level, each with EDF nu, correlated rho: the
    /// independent likelihood counts 2 nu, the truth is worth 2 nu / (1 +
    /// rho), so the deviance is (1 + rho) chi2_1. With rho = 0 nothing widens.
    #[test]
    fn the_godambe_factor_of_correlated_duplicates_is_one_plus_rho() {
        let phi = vec![vec![1.0], vec![1.0]];
        let prob = Problem {
            phi: &phi,
            y: vec![2.0, 2.0],
            half_edf: vec![10.0, 10.0],
            k: 1,
            signed: 0,
        };
        for rho in [0.0, 0.3, 0.8] {
            let corr = vec![vec![1.0, rho], vec![rho, 1.0]];
            let c = godambe_factors(&prob, &[2.0], &[true], &corr);
            assert!((c[0] - (1.0 + rho)).abs() < 1e-12, "rho {rho}: {}", c[0]);
        }
        // negatively correlated observations never narrow an interval
        let corr = vec![vec![1.0, -0.5], vec![-0.5, 1.0]];
        assert_eq!(godambe_factors(&prob, &[2.0], &[true], &corr), vec![1.0]);
    }

    /// A term dropped below its threshold although present (a rate random
    /// walk the strict test leaves out): held at 0, the term it trades with
    /// takes its rows and that term's interval leaves the truth; left free
    /// in the profile, the interval holds the truth. Where the dropped term
    /// is truly absent, freeing it changes no interval by more than it may.
    #[test]
    fn a_dropped_term_left_free_keeps_the_others_intervals_honest() {
        // term 0 flat, term 1 rising over the rows
        let shape1 = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
        let fit = |t1: f64, free: u64| {
            let opts = FitOptions {
                always_keep: 0b01,
                strict: 0b10,
                free_in_profile: free,
                ..FitOptions::default()
            };
            flat_and_shape(&shape1, t1, 400.0, &opts)
        };
        // present, below the strict threshold
        let held = fit(0.12, 0);
        assert!(!held.terms[1].included, "{:?}", held.terms);
        let (lo, hi) = held.terms[0].ci95.unwrap();
        assert!(
            lo > 1.0 || hi < 1.0,
            "the held interval holds the truth: [{lo}, {hi}]"
        );
        let freed = fit(0.12, 0b10);
        let (lo, hi) = freed.terms[0].ci95.unwrap();
        assert!(lo <= 1.0 && 1.0 <= hi, "[{lo}, {hi}]");
        assert_eq!(freed.terms[0].theta, held.terms[0].theta);
        assert_eq!(freed.terms[1].upper95, held.terms[1].upper95);
        // absent: the interval may only widen, by the share term 1 could take
        let (a, b) = (fit(0.0, 0), fit(0.0, 0b10));
        let ((l0, h0), (l1, h1)) = (a.terms[0].ci95.unwrap(), b.terms[0].ci95.unwrap());
        assert!(
            l1 <= l0 && h1 >= h0 && h1 - l1 < 2.0 * (h0 - l0),
            "[{l0}, {h0}] -> [{l1}, {h1}]"
        );
    }
}
