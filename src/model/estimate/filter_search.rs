//! Readout-filter detection and fit.
//!
//! A readout filter (anti-alias, dither stripping, averaging) attenuates the
//! white rate noise at the fine wavelet levels. Read with an unfiltered model,
//! those falling levels look like flicker or rate random walk and the
//! flat part is misread: ARW too low, B or K invented. Here the
//! white-rate column of the low-frequency model is replaced by a *filtered*
//! white rate (exact level variances and Allan signature of
//! [`SpectralTerm::FilteredWhiteRate`]), and a column for what the filter
//! removes from a white rate ([`SpectralTerm::WhiteRateComplement`]) takes
//! white noise the electronics add after the filter (a rate word's LSB
//! rounding), so that N stays the whole white level at low frequency.
//!
//! The filter's shape is a nonlinear parameter: the likelihood is profiled
//! over moving averages of 2 ..= [`MAX_MA`] samples and over first-order
//! corners on a log grid (refined by golden section), every candidate on the
//! same rows with the EDFs held at those of the unfiltered fit, so that the
//! log-likelihoods compare. A filter is reported when it beats no filter by
//! [`FILTER_LR`] in deviance. Its corner's 95 % interval is the set of
//! candidates (of either kind) within `ci_lr` of the best, and the ARW
//! interval is widened to cover the ARW of every such candidate.

use super::lf::{Lf, Rows, saturate};
use super::standard_terms;
use crate::model::filter::ReadoutFilter;
use crate::model::fit::{FitOptions, ml_edf, ml_loglik_fixed_edf};
use crate::model::wvar::SpectralTerm;
use crate::par::par_map;

/// Longest moving average searched, samples.
pub const MAX_MA: u32 = 32;
/// First-order corners searched: this many, log-spaced over [`FO_LO`, `FO_HI`] cycles/sample.
const FO_GRID: usize = 28;
const FO_LO: f64 = 0.004;
const FO_HI: f64 = 0.49;
/// Deviance a filter must explain over no filter to be reported (chi-square
/// with 2 degrees of freedom at 1e-3: the shape adds a kind and a corner, and
/// the search runs over many candidates).
pub const FILTER_LR: f64 = 13.8;

/// Column of [`SpectralTerm::WhiteRateComplement`] in [`filtered_terms`].
pub const COMPLEMENT_COL: usize = 4;

/// The terms of the low-frequency fit with white rate through `filter`:
/// Q^2 (nuisance), N^2 (the white level at low frequency, filtered), B^2,
/// K^2, and the part of a white rate the filter removes (white noise added
/// after the filter appears there: its theta is that noise's level).
pub fn filtered_terms(n_samples: u64, tau0_s: f64, filter: ReadoutFilter) -> Vec<SpectralTerm> {
    let mut t = standard_terms(n_samples, tau0_s).to_vec();
    t[1] = SpectralTerm::FilteredWhiteRate { filter };
    t.push(SpectralTerm::WhiteRateComplement { filter });
    debug_assert_eq!(t.len(), COMPLEMENT_COL + 1);
    t
}

/// One candidate's profile value.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    filter: ReadoutFilter,
    loglik: f64,
    /// ML N^2 (unfiltered band), arcsec^2/s.
    n2: f64,
}

/// The chosen filter, its corner interval and what it does to ARW.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterChoice {
    pub filter: ReadoutFilter,
    /// 95 % interval of the -3 dB frequency, cycles per sample.
    pub corner_ci_cycles: (f64, f64),
    /// `(ML N^2, deviance against the best)` of the candidates within the
    /// corner interval (the best included, and the interval's ends).
    pub n2_inside: Vec<(f64, f64)>,
    /// Deviance of the filter against none.
    pub lr: f64,
}

/// Profile the likelihood over readout filters; `None` when no filter beats
/// the unfiltered model by [`FILTER_LR`].
pub(super) fn search(
    lf: &Lf,
    n_samples: u64,
    from: usize,
    opts: &FitOptions,
) -> Option<FilterChoice> {
    let ci_lr = opts.ci_lr;
    let none_terms = standard_terms(n_samples, lf.tau0).to_vec();
    let none_basis = lf.basis(&none_terms);
    let r0 = lf.rows(&none_terms, &none_basis.phi, from);
    // the filter adds a column and a shape: leave at least two spare rows
    if r0.y.len() < none_terms.len() + 4 {
        return None;
    }
    let edf = ml_edf(
        &r0.phi,
        &r0.y,
        &r0.edf0,
        &lf.edf(&none_terms, &none_basis, from, &r0.phi),
    );
    let l_none = ml_loglik_fixed_edf(&r0.phi, &r0.y, &edf).1;
    let eval = |f: ReadoutFilter| -> Candidate {
        let terms = filtered_terms(n_samples, lf.tau0, f);
        // the EDFs are held fixed: the rows alone, no Gram matrices
        let Rows { phi, y, .. } = lf.rows(&terms, &lf.bands(&terms), from);
        let (theta, loglik) = ml_loglik_fixed_edf(&phi, &y, &edf);
        Candidate {
            filter: f,
            loglik,
            n2: theta[1],
        }
    };
    if !opts.full_filter_search && !coarse_pass(&eval, l_none) {
        return None;
    }
    let ma: Vec<ReadoutFilter> = (2..=MAX_MA)
        .filter_map(|l| ReadoutFilter::moving_average(l).ok())
        .collect();
    let mut cands = par_map(&ma, |&f| eval(f));
    let poles = fo_grid();
    let fo = par_map(&poles, |&p| eval(ReadoutFilter::FirstOrder { pole: p }));
    cands.extend(refine_first_order(&fo, &eval));
    cands.extend(fo);
    let best = *cands.iter().max_by(|a, b| a.loglik.total_cmp(&b.loglik))?;
    let lr = 2.0 * (best.loglik - l_none);
    if !(lr >= FILTER_LR) {
        return None;
    }
    let mut inside: Vec<Candidate> = cands
        .iter()
        .copied()
        .filter(|c| 2.0 * (best.loglik - c.loglik) <= ci_lr)
        .collect();
    if let ReadoutFilter::FirstOrder { .. } = best.filter {
        inside.extend(first_order_ci(&best, &eval, ci_lr));
    }
    let lo = inside.iter().map(corner_of).fold(f64::INFINITY, f64::min);
    let hi = inside.iter().map(corner_of).fold(0.0, f64::max);
    let n2_inside = inside
        .iter()
        .map(|c| (c.n2, (2.0 * (best.loglik - c.loglik)).max(0.0)))
        .collect();
    Some(FilterChoice {
        filter: best.filter,
        corner_ci_cycles: (lo, hi),
        n2_inside,
        lr,
    })
}

/// The interval of N^2 over the filter's confidence set: each candidate's own
/// profile interval, approximated as the best filter's interval `(lo, hi)`
/// about `n2_best`, shrunk by `sqrt(1 - deviance / ci_lr)` and centred on the
/// candidate's N^2; the union over candidates.
pub fn n2_interval(c: &FilterChoice, n2_best: f64, (lo, hi): (f64, f64), ci_lr: f64) -> (f64, f64) {
    let (dl, dh) = (n2_best - lo, hi - n2_best);
    c.n2_inside.iter().fold((lo, hi), |(a, b), &(n2, dev)| {
        let s = (1.0 - dev / ci_lr).max(0.0).sqrt();
        (a.min(n2 - s * dl).max(0.0), b.max(n2 + s * dh))
    })
}

/// Deviance over no filter that the best candidate of the coarse pass must
/// reach for the full search to run (a third of [`FILTER_LR`]).
pub const COARSE_LR: f64 = FILTER_LR / 3.0;
/// Moving-average lengths of the coarse pass (steps of at most 1.5x).
const COARSE_MA: [u32; 9] = [2, 3, 4, 6, 8, 12, 16, 24, 32];
/// Every this many points of the first-order grid are in the coarse pass.
const COARSE_FO_STEP: usize = 3;

/// Whether a coarse subset of the candidates (19 of about 75) comes within
/// reach of [`FILTER_LR`]: on a record with no filter, the estimate then skips
/// the full profile. The likelihood is smooth in the corner, and a filter
/// strong enough to be reported beats no filter by far more than
/// [`COARSE_LR`] at the coarse candidate nearest to it
/// (`tests/numerics/estimate_filter.rs`, `coarse_pass_never_hides_a_reported_filter`;
/// [`FitOptions::full_filter_search`] turns the pass off).
fn coarse_pass(eval: &(dyn Fn(ReadoutFilter) -> Candidate + Sync), l_none: f64) -> bool {
    let ma = COARSE_MA
        .iter()
        .filter_map(|&l| ReadoutFilter::moving_average(l).ok());
    let fo = fo_grid()
        .into_iter()
        .step_by(COARSE_FO_STEP)
        .map(|p| ReadoutFilter::FirstOrder { pole: p });
    let filters: Vec<ReadoutFilter> = ma.chain(fo).collect();
    par_map(&filters, |&f| eval(f).loglik)
        .into_iter()
        .any(|l| 2.0 * (l - l_none) >= COARSE_LR)
}

/// Poles of the first-order grid (log-spaced corners).
fn fo_grid() -> Vec<f64> {
    (0..FO_GRID)
        .map(|i| {
            let c = FO_LO * (FO_HI / FO_LO).powf(i as f64 / (FO_GRID - 1) as f64);
            pole_of(c)
        })
        .collect()
}

/// The pole of a one-pole filter with -3 dB at `c` cycles per sample.
fn pole_of(c: f64) -> f64 {
    let b = 2.0 - (2.0 * std::f64::consts::PI * c).cos();
    b - (b * b - 1.0).sqrt()
}

fn corner_of(c: &Candidate) -> f64 {
    c.filter.corner_cycles()
}

/// Golden-section refinement of the best first-order grid point over the
/// log corner between its neighbours; returns the points evaluated.
fn refine_first_order(
    grid: &[Candidate],
    eval: &dyn Fn(ReadoutFilter) -> Candidate,
) -> Vec<Candidate> {
    let Some(ib) = (0..grid.len()).max_by(|&a, &b| grid[a].loglik.total_cmp(&grid[b].loglik))
    else {
        return Vec::new();
    };
    let (mut a, mut b) = (
        corner_of(&grid[ib.saturating_sub(1)]).ln(),
        corner_of(&grid[(ib + 1).min(grid.len() - 1)]).ln(),
    );
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let at = |x: f64| {
        eval(ReadoutFilter::FirstOrder {
            pole: pole_of(x.exp()),
        })
    };
    let mut out = Vec::new();
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (at(x1), at(x2));
    for _ in 0..14 {
        if f1.loglik >= f2.loglik {
            out.push(f2);
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = at(x1);
        } else {
            out.push(f1);
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = at(x2);
        }
    }
    out.extend([f1, f2]);
    out
}

/// The ends of the profile-likelihood interval of a first-order corner: from
/// the best corner, step out in log corner until the deviance passes `ci_lr`,
/// then bisect; the candidates at both ends.
fn first_order_ci(
    best: &Candidate,
    eval: &dyn Fn(ReadoutFilter) -> Candidate,
    ci_lr: f64,
) -> [Candidate; 2] {
    let x0 = corner_of(best).ln();
    let at = |x: f64| {
        eval(ReadoutFilter::FirstOrder {
            pole: pole_of(x.exp()),
        })
    };
    let dev = |c: &Candidate| 2.0 * (best.loglik - c.loglik);
    let bound = |dir: f64| -> Candidate {
        let limit = if dir > 0.0 {
            FO_HI.ln()
        } else {
            (FO_LO / 4.0).ln()
        };
        let (mut inside, mut step) = (*best, 0.02);
        let mut x_in = x0;
        loop {
            let x = (x_in + dir * step).clamp(limit.min(x0), limit.max(x0));
            let c = at(x);
            if dev(&c) > ci_lr {
                let (mut a, mut b) = (x_in, x);
                for _ in 0..20 {
                    let m = 0.5 * (a + b);
                    let cm = at(m);
                    if dev(&cm) > ci_lr {
                        b = m;
                    } else {
                        (a, inside) = (m, cm);
                    }
                }
                return inside;
            }
            if x == limit {
                return c;
            }
            (x_in, inside) = (x, c);
            step *= 2.0;
        }
    };
    [bound(-1.0), bound(1.0)]
}

/// Saturation is decided on the unfiltered rows; the filtered rows follow it.
pub(super) fn saturate_rows(r: &mut Rows, saturated: bool) {
    if saturated {
        saturate(&mut r.phi);
    }
}
