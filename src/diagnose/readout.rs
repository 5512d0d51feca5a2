//! The readout-filter candidate (catalog entry `readout_filter`): a new
//! filter when the model has none, or a change of the model's filter.
//!
//! A readout filter (an anti-alias low-pass before the ADC or the rate word,
//! or the averaging that strips a dither) attenuates the white rate noise
//! above its -3 dB corner: the finest wavelet levels fall below the white
//! plateau. Its signature on the wavelet variances is that of
//! [`crate::model::wvar::SpectralTerm::FilteredWhiteRate`] ([`Basis::filtered_white_rate`]).
//! White noise added after the filter (a rate word's LSB rounding, a white
//! angle error) is not filtered; it is in the model's Monte-Carlo mean and
//! stays there.
//!
//! Under the candidate, the expectation is the model's Monte-Carlo mean with
//! the white rate's contribution through the model's filter replaced by its
//! contribution through the candidate filter, `e0 - N0^2 phi_F0 + N^2 phi_F`,
//! with N^2 (the white level at low frequency) refitted. The likelihood is
//! profiled over moving averages of 2 ..= [`MAX_MA`] samples and over
//! first-order corners on a log grid (refined by golden section); the best
//! of either kind wins. The corner's 95 % interval is the span of the
//! candidates (of either kind) whose profile deviance from the best is below
//! the chi-square(1) 95 % point, its ends interpolated on the first-order
//! profile. Two parameters are fitted: the corner and N^2.

use std::collections::BTreeMap;

use super::findings::{Edit, Finding, fmt_g, sqrt_ci};
use super::golden::golden_max;
use super::telegraph::mean_sd;
use super::types::{AddedTerm, ParameterChange};
use super::wvar_fit::{Basis, CI_DEVIANCE, Fit, LevelData, fit_amplitude};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::model::filter::{ReadoutFilter, ReadoutFilterParams};
use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::units;

/// Longest moving average searched, samples.
pub const MAX_MA: u32 = 64;
/// First-order corners searched: log grid over [`FO_LO`, `FO_HI`] cycles per
/// sample, [`FO_PER_OCTAVE`] per octave.
const FO_LO: f64 = 0.002;
const FO_HI: f64 = 0.49;
const FO_PER_OCTAVE: usize = 8;

/// The best readout filter on the wavelet variances.
#[derive(Debug, Clone)]
pub struct FilterFit {
    pub filter: ReadoutFilter,
    /// The fit of N^2 through `filter`; `delta_mu` is relative to the
    /// model's expectation (`data.e0`), `n_par` = 2.
    pub fit: Fit,
    /// 95 % interval of the -3 dB corner, cycles per sample.
    pub corner_ci_cycles: (f64, f64),
    /// Moving-average lengths inside the interval (when a moving average won).
    pub length_ci: Option<(u32, u32)>,
    /// N^2's interval profiled over the corner against it at `filter` alone,
    /// (below, above) half-width ratios, at least 1.
    pub arw_profile_widen: (f64, f64),
}

/// One filter's profile: N^2 refitted through it.
fn profile(data: &LevelData, basis: &Basis, n2: f64, phi0: &[f64], f: ReadoutFilter) -> Fit {
    let phi = basis.filtered_white_rate(Some(f));
    let shifted = LevelData {
        e0: data
            .e0
            .iter()
            .zip(phi0)
            .zip(&phi)
            .map(|((e, p0), p)| e - n2 * p0 + n2 * p)
            .collect(),
        ..data.clone()
    };
    let mut fit = fit_amplitude(&shifted, &phi, n2, 0.0);
    for ((d, e1), e0) in fit.delta_mu.iter_mut().zip(&shifted.e0).zip(&data.e0) {
        *d += e1 - e0;
    }
    fit.n_par = 2;
    fit
}

fn first_order(cycles: f64) -> Option<ReadoutFilter> {
    ReadoutFilter::first_order(cycles, 1.0).ok()
}

/// Fit a readout filter about the model's white level `n2` (arcsec^2/s)
/// and filter `current`. `None` when the model has no white rate to filter.
pub fn fit(
    data: &LevelData,
    basis: &Basis,
    n2: f64,
    current: Option<ReadoutFilter>,
) -> Option<FilterFit> {
    if !(n2 > 0.0) || data.loglik(&data.e0).is_infinite() {
        return None;
    }
    let phi0 = basis.filtered_white_rate(current);
    let eval = |f: ReadoutFilter| profile(data, basis, n2, &phi0, f);
    let (cands, fo_l) = candidates(data, basis, n2, &phi0, 30);
    let best = cands
        .iter()
        .max_by(|x, y| x.2.loglik.total_cmp(&y.2.loglik))?
        .clone();
    if !best.2.loglik.is_finite() {
        return None;
    }
    let l_max = best.2.loglik;
    let inside = |l: f64| 2.0 * (l_max - l) <= CI_DEVIANCE;
    let (mut lo, mut hi) = (best.0, best.0);
    for c in cands.iter().filter(|c| inside(c.2.loglik)) {
        lo = lo.min(c.0);
        hi = hi.max(c.0);
    }
    // ends on the continuous first-order profile, where it is inside
    let target = l_max - CI_DEVIANCE / 2.0;
    let cross = |inner: f64, outer: f64| {
        let (mut a, mut b) = (inner.ln(), outer.ln());
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if fo_l(m) >= target {
                a = m;
            } else {
                b = m;
            }
        }
        (0.5 * (a + b)).exp()
    };
    if fo_l(lo.ln()) >= target {
        lo = cross(lo, (lo / 1.5).max(1e-6));
    }
    if fo_l(hi.ln()) >= target {
        hi = cross(hi, (hi * 1.5).min(0.4999));
    }
    let length_ci = match best.1 {
        ReadoutFilter::MovingAverage { .. } => {
            let ls = cands.iter().filter_map(|c| match c.1 {
                ReadoutFilter::MovingAverage { length } if inside(c.2.loglik) => Some(length),
                _ => None,
            });
            let (mn, mx) = ls.fold((u32::MAX, 0), |(a, b), l| (a.min(l), b.max(l)));
            Some((mn, mx))
        }
        ReadoutFilter::FirstOrder { .. } => None,
    };
    // N^2's interval profiled over the filter too: each candidate inside the
    // corner's confidence set contributes its own N^2 interval, shrunk to the
    // deviance it has left (sqrt(1 - d / CI_DEVIANCE)); the union. At the best
    // filter alone the interval ignores that the corner and N^2 trade off.
    let mut fit = best.2.clone();
    let cond = best.2.theta_ci;
    for c in cands.iter().filter(|c| inside(c.2.loglik)) {
        let d = (2.0 * (l_max - c.2.loglik)).max(0.0);
        let k = (1.0 - d / CI_DEVIANCE).max(0.0).sqrt();
        let (a, b) = c.2.theta_ci;
        let (t, f) = (c.2.theta, &mut fit.theta_ci);
        f.0 = f.0.min(t - k * (t - a)).max(0.0);
        f.1 = f.1.max(t + k * (b - t));
    }
    // The first-order corner is continuous: N^2 at the ends of its interval
    // is how far the trade-off moves it, added in quadrature to the width at
    // the fitted corner (the projection of the joint ellipse); the grid
    // candidates above may all lie on one side of the best corner.
    let t = fit.theta;
    if let ReadoutFilter::FirstOrder { .. } = best.1 {
        let (mut dl, mut dh) = (0.0f64, 0.0f64);
        for f in [lo, hi].into_iter().filter_map(first_order) {
            let d = eval(f).theta - t;
            if d.is_finite() {
                dl = dl.max(-d);
                dh = dh.max(d);
            }
        }
        let (cl, ch) = (t - cond.0, cond.1 - t);
        fit.theta_ci.0 = fit.theta_ci.0.min(t - cl.hypot(dl)).max(0.0);
        fit.theta_ci.1 = fit.theta_ci.1.max(t + ch.hypot(dh));
    }
    let ratio = |p: f64, c: f64| if c > 0.0 { (p / c).max(1.0) } else { 1.0 };
    let arw_profile_widen = (
        ratio(t - fit.theta_ci.0, t - cond.0),
        ratio(fit.theta_ci.1 - t, cond.1 - t),
    );
    Some(FilterFit {
        filter: best.1,
        fit,
        corner_ci_cycles: (lo, hi),
        length_ci,
        arw_profile_widen,
    })
}

/// A candidate filter: its corner (cycles per sample), the filter and its fit.
type Cand = (f64, ReadoutFilter, Fit);

/// Every moving average and first-order corner of the search profiled, the
/// best first-order corner refined by `golden` golden-section steps; and the
/// first-order profile log-likelihood as a function of the log corner.
fn candidates<'a>(
    data: &'a LevelData,
    basis: &'a Basis,
    n2: f64,
    phi0: &'a [f64],
    golden: usize,
) -> (Vec<Cand>, impl Fn(f64) -> f64 + 'a) {
    let eval = move |f: ReadoutFilter| profile(data, basis, n2, phi0, f);
    let mut cands: Vec<Cand> = Vec::new();
    for l in 2..=MAX_MA {
        let f = ReadoutFilter::MovingAverage { length: l };
        cands.push((f.corner_cycles(), f, eval(f)));
    }
    let n_fo = ((FO_HI / FO_LO).log2() * FO_PER_OCTAVE as f64).ceil() as usize;
    let fo_grid: Vec<f64> = (0..=n_fo)
        .map(|i| FO_LO * (FO_HI / FO_LO).powf(i as f64 / n_fo as f64))
        .collect();
    let n_ma = cands.len();
    for &c in &fo_grid {
        if let Some(f) = first_order(c) {
            cands.push((c, f, eval(f)));
        }
    }
    let fo_l = move |lc: f64| first_order(lc.exp()).map_or(f64::NEG_INFINITY, |f| eval(f).loglik);
    // refine the best first-order corner between its grid neighbours
    let ib = cands[n_ma..]
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.2.loglik.total_cmp(&b.1.2.loglik))
        .map_or(0, |(i, _)| i);
    let (a, b) = (
        fo_grid[ib.saturating_sub(1)].ln(),
        fo_grid[(ib + 1).min(fo_grid.len() - 1)].ln(),
    );
    let lc = golden_max(&fo_l, a, b, golden);
    if let Some(f) = first_order(lc.exp()) {
        cands.push((lc.exp(), f, eval(f)));
    }
    (cands, fo_l)
}

/// The log-likelihood of the best filter about `n2` and `current` (the
/// search of [`fit`] without its intervals, `golden` refinement steps).
pub(crate) fn best_loglik(
    data: &LevelData,
    basis: &Basis,
    n2: f64,
    current: Option<ReadoutFilter>,
    golden: usize,
) -> f64 {
    if !(n2 > 0.0) {
        return f64::NEG_INFINITY;
    }
    let phi0 = basis.filtered_white_rate(current);
    let (cands, _) = candidates(data, basis, n2, &phi0, golden);
    cands
        .iter()
        .map(|c| c.2.loglik)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Whether the candidate is tried: on a rate-output gyro, and on any model
/// that already has a filter (a change of it). A pulse counter without a
/// filter is not offered one.
pub(crate) fn offered(model: &GyroModel) -> bool {
    model.gyro.output == OutputKind::Rate || model.readout_filter.is_some()
}

/// The finding of a fitted filter: the model-file `[readout_filter]` table
/// and the refitted ARW, reported as the catalog entry `readout_filter`
/// (`params`: `kind`, `corner_hz`, `length` for a moving average) and, when
/// the model had a filter, as a change of its corner.
pub(crate) fn finding(ff: &FilterFit, model: &GyroModel, n2_model: f64, regions: &str) -> Finding {
    let tau0 = model.tau0_s();
    let f = ff.filter;
    let fc = f.corner_hz(tau0);
    let ci = [ff.corner_ci_cycles.0 / tau0, ff.corner_ci_cycles.1 / tau0];
    let delay_s = f.delay_samples() * tau0;
    let arw = units::arcsec_per_sqrt_s_to_dpsh(ff.fit.theta.sqrt());
    let arw_model = units::arcsec_per_sqrt_s_to_dpsh(n2_model.sqrt());
    let mut params = BTreeMap::from([("corner_hz".to_string(), fc)]);
    let mut ci95 = BTreeMap::from([("corner_hz".to_string(), ci)]);
    let what = match (f, ff.length_ci) {
        (ReadoutFilter::MovingAverage { length }, lci) => {
            params.insert("length".into(), f64::from(length));
            if let Some((a, b)) = lci {
                ci95.insert("length".into(), [f64::from(a), f64::from(b)]);
            }
            format!(
                "a moving average of {length} samples ({} ms: a boxcar, as a decimating or dither-stripping \
                 averager applies)",
                fmt_g(f64::from(length) * tau0 * 1e3)
            )
        }
        (ReadoutFilter::FirstOrder { .. }, _) => {
            "a first-order (one-pole) low-pass, as an anti-alias RC stage".into()
        }
    };
    let had = model.readout_filter();
    let at_edge =
        matches!(f, ReadoutFilter::FirstOrder { .. }) && ff.corner_ci_cycles.1 >= 0.98 * FO_HI;
    let edge = if at_edge {
        format!(
            " The corner is at the top of the search ({} cycles per sample): the finest level falls less \
             than any one-pole filter below Nyquist makes it, as an average over a fraction of an output \
             sample (decimation from a faster internal rate) does.",
            FO_HI
        )
    } else {
        String::new()
    };
    let explanation = format!(
        "A readout filter the model {}: {what}, -3 dB at {} Hz (95 % {}..{} Hz), group delay {} ms ({} samples). \
         The electronics low-pass the rate before it is output (an anti-alias filter ahead of the sampling, or \
         the averaging that strips a dither), so the white rate noise falls off above the corner: the finest \
         wavelet levels (tau below about {} s) lie below the white plateau an unfiltered readout gives \
         (mismatch at {regions}). Below the corner the white level is unchanged: ARW {} deg/sqrt(h) \
         (the model: {}). A rate word's LSB rounding comes after the filter and stays white.{edge}",
        if had.is_some() {
            "describes wrongly"
        } else {
            "lacks"
        },
        fmt_g(fc),
        fmt_g(ci[0]),
        fmt_g(ci[1]),
        fmt_g(delay_s * 1e3),
        fmt_g(f.delay_samples()),
        fmt_g(1.0 / (2.0 * fc)),
        fmt_g(arw),
        fmt_g(arw_model),
    );
    let mut changes = vec![ParameterChange {
        term: "arw_dpsh".into(),
        model: arw_model,
        fitted: arw,
        ci95: sqrt_ci(ff.fit.theta_ci, units::arcsec_per_sqrt_s_to_dpsh),
    }];
    if let Some(old) = had {
        changes.push(ParameterChange {
            term: "readout_filter.corner_hz".into(),
            model: old.corner_hz(tau0),
            fitted: fc,
            ci95: ci,
        });
    }
    Finding {
        edit: Edit::ReadoutFilter {
            params: ReadoutFilterParams::from_filter(&f, tau0),
            arw_dpsh: arw,
            arw_profile_widen: ff.arw_profile_widen,
        },
        changes,
        added: Some(AddedTerm {
            term: "readout_filter".into(),
            params,
            kind: Some(f.kind().name().into()),
            explanation,
            ci95,
        }),
        n_par: 2,
        note: format!(
            "readout_filter: {} -3 dB {} Hz [{}, {}], delay {} ms; arw_dpsh {} -> {}",
            f.kind().name(),
            fmt_g(fc),
            fmt_g(ci[0]),
            fmt_g(ci[1]),
            fmt_g(delay_s * 1e3),
            fmt_g(arw_model),
            fmt_g(arw)
        ),
    }
}

/// The `readout_filter` finding `f` moved to `about`, the filter and white
/// level refitted about the updated model's own runs (their EDFs), when it is
/// of the same kind: its corner, ARW and intervals become the refit's.
/// `model` is the model under test and `regions` the mismatch regions in
/// words. The first fit, about the original model, weighs the levels the
/// filter attenuates with that model's EDFs; its corner scattered 1.5x the
/// refit's over seeds (a first-order 15 Hz filter at 200 Hz).
pub(crate) fn recentered(
    f: &Finding,
    about: &FilterFit,
    model: &GyroModel,
    regions: &str,
) -> Option<Finding> {
    let tau0_s = model.tau0_s();
    let ours = finding_filter(f, tau0_s).filter(|o| o.kind() == about.filter.kind())?;
    let n2_model = units::dpsh_to_arcsec_per_sqrt_s(model.noise.arw_dpsh.unwrap_or(0.0)).powi(2);
    let mut moved = finding(about, model, n2_model, regions);
    let arw_of = |e: &Edit| match e {
        Edit::ReadoutFilter { arw_dpsh, .. } => *arw_dpsh,
        _ => f64::NAN,
    };
    moved.note = format!(
        "{} Refitted about the updated model's runs: corner {} -> {} Hz, arw_dpsh {} -> {}.",
        f.note,
        fmt_g(ours.corner_hz(tau0_s)),
        fmt_g(about.filter.corner_hz(tau0_s)),
        fmt_g(arw_of(&f.edit)),
        fmt_g(arw_of(&moved.edit)),
    );
    Some(moved)
}

/// Widen a `readout_filter` finding's corner and ARW intervals to at least
/// those of `about`, the filter refitted about the updated model's own runs
/// (their EDFs: the original model's overstate the information of the levels
/// the filter attenuates, and the corner found with them scattered 1.7x its
/// claimed width). Half-widths are carried about the finding's own values;
/// intervals only grow. Nothing changes when `about` is of another kind.
pub(crate) fn widen_about_updated(f: &mut Finding, about: &FilterFit, tau0_s: f64) {
    let Some(ours) = finding_filter(f, tau0_s).filter(|o| o.kind() == about.filter.kind()) else {
        return;
    };
    let fc = ours.corner_hz(tau0_s);
    let (c, (a, b)) = (about.filter.corner_cycles(), about.corner_ci_cycles);
    let corner = [
        fc - (c - a) / tau0_s,
        (fc + (b - c) / tau0_s).min(0.5 / tau0_s),
    ];
    let t = about.fit.theta;
    let arw_of = |x: f64| units::arcsec_per_sqrt_s_to_dpsh(x.max(0.0).sqrt());
    let (arw_lo, arw_hi) = (
        arw_of(t) - arw_of(about.fit.theta_ci.0),
        arw_of(about.fit.theta_ci.1) - arw_of(t),
    );
    widen_finding(f, corner, (arw_lo, arw_hi));
}

/// Widen a `readout_filter` finding's corner and ARW intervals to at least
/// `t sd` about its values, `sd` the scatter of the corner and of the ARW over
/// `boot` (the filter refitted on each of the updated model's runs against the
/// others; `t` Student's 97.5 % point for that many runs, inflated by
/// `sqrt(1 + 1/n)` for the mean the recording is judged against). The
/// likelihood intervals assume independent levels; a filter's transition
/// band spans several, and the corner so found scattered 1.6x its claimed
/// width. Nothing with fewer than 4 refits of the finding's kind.
pub(crate) fn widen_by_scatter(f: &mut Finding, boot: &[FilterFit], tau0_s: f64) {
    let Some(ours) = finding_filter(f, tau0_s) else {
        return;
    };
    let same: Vec<&FilterFit> = boot
        .iter()
        .filter(|b| b.filter.kind() == ours.kind())
        .collect();
    let n = same.len();
    if n < 4 {
        return;
    }
    let sd = |v: Vec<f64>| mean_sd(&v).1;
    let t = StudentsT::new(0.0, 1.0, (n - 1) as f64).map_or(1.96, |d| d.inverse_cdf(0.975))
        * (1.0 + 1.0 / n as f64).sqrt();
    let corner_sd = sd(same.iter().map(|b| b.filter.corner_hz(tau0_s)).collect());
    let arw_sd = sd(same
        .iter()
        .map(|b| units::arcsec_per_sqrt_s_to_dpsh(b.fit.theta.max(0.0).sqrt()))
        .collect());
    let fc = ours.corner_hz(tau0_s);
    let corner = [fc - t * corner_sd, (fc + t * corner_sd).min(0.5 / tau0_s)];
    widen_finding(f, corner, (t * arw_sd, t * arw_sd));
}

/// The filter of a `readout_filter` finding.
fn finding_filter(f: &Finding, tau0_s: f64) -> Option<ReadoutFilter> {
    match &f.edit {
        Edit::ReadoutFilter { params, .. } => params.filter(tau0_s).ok(),
        _ => None,
    }
}

/// Widen the finding's corner interval (Hz) to include `corner`, and its ARW
/// interval to at least `arw` (below, above) about the refitted ARW.
fn widen_finding(f: &mut Finding, corner: [f64; 2], arw: (f64, f64)) {
    for ch in f.changes.iter_mut() {
        match ch.term.as_str() {
            "arw_dpsh" => widen(&mut ch.ci95, ch.fitted - arw.0, ch.fitted + arw.1),
            "readout_filter.corner_hz" => {
                ch.ci95 = widened_text(ch.ci95, corner, &mut f.note, &mut None);
            }
            _ => {}
        }
    }
    if let Some(added) = f.added.as_mut()
        && let Some(ci) = added.ci95.get_mut("corner_hz")
    {
        *ci = widened_text(*ci, corner, &mut f.note, &mut Some(&mut added.explanation));
    }
}

fn widen(ci: &mut [f64; 2], lo: f64, hi: f64) {
    ci[0] = ci[0].min(lo).max(0.0);
    ci[1] = ci[1].max(hi);
}

/// `old` widened to include `new`, with the interval's text in the note
/// (`[lo, hi]`) and the explanation (`95 % lo..hi Hz`) rewritten.
fn widened_text(
    old: [f64; 2],
    new: [f64; 2],
    note: &mut String,
    explanation: &mut Option<&mut String>,
) -> [f64; 2] {
    let mut ci = old;
    widen(&mut ci, new[0], new[1]);
    let text = |c: [f64; 2], sep: &str| format!("{}{sep}{}", fmt_g(c[0]), fmt_g(c[1]));
    *note = note.replace(&text(old, ", "), &text(ci, ", "));
    if let Some(e) = explanation.as_mut() {
        **e = e.replace(&text(old, ".."), &text(ci, ".."));
    }
    ci
}

#[cfg(test)]
mod tests {
    use super::*;

    const TAU0: f64 = 1.0 / 200.0;

    fn filter_fit(corner_hz: f64, arw_dpsh: f64, half: f64) -> FilterFit {
        let theta = units::dpsh_to_arcsec_per_sqrt_s(arw_dpsh).powi(2);
        let c = corner_hz * TAU0;
        FilterFit {
            filter: ReadoutFilter::first_order(corner_hz, TAU0).unwrap(),
            fit: Fit {
                theta,
                theta_ci: (theta * (1.0 - half), theta * (1.0 + half)),
                shape: None,
                shape_ci: None,
                loglik: 0.0,
                n_par: 2,
                delta_mu: Vec::new(),
            },
            corner_ci_cycles: (c * (1.0 - half), c * (1.0 + half)),
            length_ci: None,
            arw_profile_widen: (1.0, 1.0),
        }
    }

    fn a_model() -> GyroModel {
        GyroModel::from_toml_str(
            "[gyro]\nsample_rate_hz = 200.0\noutput = \"rate\"\nrate_lsb_dps = 0.01\n\
             [noise]\narw_dpsh = 0.5\n",
            "test",
        )
        .unwrap()
    }

    fn a_finding() -> Finding {
        let n2 = units::dpsh_to_arcsec_per_sqrt_s(0.5).powi(2);
        finding(
            &filter_fit(15.0, 0.5, 0.01),
            &a_model(),
            n2,
            "0.005..0.04 s",
        )
    }

    fn corner_ci(f: &Finding) -> [f64; 2] {
        f.added.as_ref().unwrap().ci95["corner_hz"]
    }

    #[test]
    fn scatter_of_the_refits_sets_the_interval_floor() {
        let mut f = a_finding();
        let fc = 15.0;
        let before = corner_ci(&f);
        assert!((before[0] - fc * 0.99).abs() < 1e-9 && (before[1] - fc * 1.01).abs() < 1e-9);
        // eight refits at 15 +- 0.3 Hz: sample sd of [-3, 3] x 0.1 (in pairs)
        let offs = [-0.3, 0.3, -0.1, 0.1, -0.2, 0.2, 0.0, 0.0];
        let boot: Vec<FilterFit> = offs
            .iter()
            .map(|d| filter_fit(fc + d, 0.5 - d / 50.0, 0.01))
            .collect();
        let sd = (offs.iter().map(|d| d * d).sum::<f64>() / 7.0).sqrt();
        let t = 2.364_624_251_6 * (1.0 + 1.0 / 8.0f64).sqrt();
        widen_by_scatter(&mut f, &boot, TAU0);
        let ci = corner_ci(&f);
        assert!((ci[0] - (fc - t * sd)).abs() < 1e-6, "{ci:?}");
        assert!((ci[1] - (fc + t * sd)).abs() < 1e-6, "{ci:?}");
        let text = format!("95 % {}..{} Hz", fmt_g(ci[0]), fmt_g(ci[1]));
        assert!(f.added.as_ref().unwrap().explanation.contains(&text));
        assert!(
            f.note
                .contains(&format!("[{}, {}]", fmt_g(ci[0]), fmt_g(ci[1])))
        );
        let arw = f.changes.iter().find(|c| c.term == "arw_dpsh").unwrap();
        let arw_sd = sd / 50.0;
        assert!(
            (arw.ci95[1] - (arw.fitted + t * arw_sd)).abs() < 1e-6,
            "{:?}",
            arw.ci95
        );
        // a tighter scatter never narrows what is there
        let tight: Vec<FilterFit> = offs
            .iter()
            .map(|d| filter_fit(fc + d / 100.0, 0.5, 0.01))
            .collect();
        widen_by_scatter(&mut f, &tight, TAU0);
        assert_eq!(corner_ci(&f), ci);
    }

    #[test]
    fn few_refits_or_another_kind_leave_the_finding_alone() {
        let mut f = a_finding();
        let before = corner_ci(&f);
        let three: Vec<FilterFit> = [14.0, 15.0, 16.0]
            .iter()
            .map(|&c| filter_fit(c, 0.5, 0.01))
            .collect();
        widen_by_scatter(&mut f, &three, TAU0);
        assert_eq!(corner_ci(&f), before);
        let mut ma = filter_fit(15.0, 0.5, 0.01);
        ma.filter = ReadoutFilter::MovingAverage { length: 5 };
        widen_about_updated(&mut f, &ma, TAU0);
        assert_eq!(corner_ci(&f), before);
    }

    #[test]
    fn the_updated_fit_carries_its_half_widths_about_the_finding() {
        let mut f = a_finding();
        // refitted about the updated model at 15.2 Hz, +- 3 %
        widen_about_updated(&mut f, &filter_fit(15.2, 0.5, 0.03), TAU0);
        let ci = corner_ci(&f);
        assert!((ci[0] - (15.0 - 15.2 * 0.03)).abs() < 1e-6, "{ci:?}");
        assert!((ci[1] - (15.0 + 15.2 * 0.03)).abs() < 1e-6, "{ci:?}");
    }

    #[test]
    fn a_refit_of_the_same_kind_moves_the_finding() {
        let f = a_finding();
        // refitted about the updated model at 15.2 Hz, ARW 0.49, +- 2 %
        let about = filter_fit(15.2, 0.49, 0.02);
        let moved = recentered(&f, &about, &a_model(), "0.005..0.04 s").unwrap();
        let ci = corner_ci(&moved);
        assert!(
            (ci[0] - 15.2 * 0.98).abs() < 1e-9 && (ci[1] - 15.2 * 1.02).abs() < 1e-9,
            "{ci:?}"
        );
        let added = moved.added.as_ref().unwrap();
        assert!((added.params["corner_hz"] - 15.2).abs() < 1e-9);
        let arw = moved.changes.iter().find(|c| c.term == "arw_dpsh").unwrap();
        assert!(
            (arw.fitted - 0.49).abs() < 1e-12 && arw.model == 0.5,
            "{arw:?}"
        );
        match moved.edit {
            Edit::ReadoutFilter {
                params, arw_dpsh, ..
            } => {
                let fc = params.filter(TAU0).unwrap().corner_hz(TAU0);
                assert!((fc - 15.2).abs() < 1e-9 && (arw_dpsh - 0.49).abs() < 1e-12);
            }
            e => panic!("{e:?}"),
        }
        assert!(
            added.explanation.contains("-3 dB at 15.2 Hz")
                && added.explanation.contains("0.005..0.04 s")
        );
        assert!(moved.note.starts_with(&f.note));
        assert!(
            moved
                .note
                .contains("corner 15 -> 15.2 Hz, arw_dpsh 0.5 -> 0.49"),
            "{}",
            moved.note
        );
        // a refit of another kind leaves it where it is
        let mut ma = about;
        ma.filter = ReadoutFilter::MovingAverage { length: 5 };
        assert!(recentered(&f, &ma, &a_model(), "").is_none());
    }
}
