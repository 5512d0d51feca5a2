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
use super::stats::golden_max;
use super::wvar_fit::{Basis, CI_DEVIANCE, Fit, LevelData, fit_amplitude};
use super::{AddedTerm, ParameterChange};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::model::filter::{ReadoutFilter, ReadoutFilterParams};
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
    // every candidate: (corner cycles, filter, loglik)
    let mut cands: Vec<(f64, ReadoutFilter, Fit)> = Vec::new();
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
    let fo_l = |lc: f64| first_order(lc.exp()).map_or(f64::NEG_INFINITY, |f| eval(f).loglik);
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
    let lc = golden_max(&fo_l, a, b, 30);
    if let Some(f) = first_order(lc.exp()) {
        cands.push((lc.exp(), f, eval(f)));
    }
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
    for c in cands.iter().filter(|c| inside(c.2.loglik)) {
        let d = (2.0 * (l_max - c.2.loglik)).max(0.0);
        let k = (1.0 - d / CI_DEVIANCE).max(0.0).sqrt();
        let (a, b) = c.2.theta_ci;
        let (t, f) = (c.2.theta, &mut fit.theta_ci);
        f.0 = f.0.min(t - k * (t - a)).max(0.0);
        f.1 = f.1.max(t + k * (b - t));
    }
    Some(FilterFit {
        filter: best.1,
        fit,
        corner_ci_cycles: (lo, hi),
        length_ci,
    })
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
