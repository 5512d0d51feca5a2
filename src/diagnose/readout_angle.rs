//! The readout-filter candidate fitted jointly with the white angle noise
//! after the filter (`readout_filter` with `quantization_arcsec`).
//!
//! A filter alone is a one-shape fit of the finest wavelet levels: below its
//! corner they follow the white plateau, above it they fall as the filter
//! makes them. A readout adds its own errors after the filter (a rate word's
//! or a counter's rounding, the sampling's timing jitter): white in angle,
//! they raise the finest levels again. When such an error is larger than the
//! model says, no filter alone reproduces the finest levels (a first-order
//! corner drifts to the top of the search, and the levels below the corner
//! still miss), while a filter with the white angle noise beside it does.
//! Greedy one-at-a-time selection cannot reach that pair: the white angle
//! change alone makes the misfit worse, and the filter alone settles on the
//! wrong shape first.
//!
//! Q^2 (white angle, arcsec^2) is profiled: at each Q^2 the filter is fitted
//! as [`readout::fit`] fits it (corner and N^2), on a log grid of Q^2 refined
//! by golden section; Q^2's 95 % interval is where the profile deviance stays
//! below the chi-square(1) point. Three parameters in all.

use super::golden::golden_max;
use super::readout::{self, FilterFit};
use super::wvar_fit::{self, Basis, CI_DEVIANCE, LevelData};
use crate::model::filter::ReadoutFilter;

/// Q^2 grid: powers of 2 of the reference white angle level, from
/// `2^GRID_LO` to `2^GRID_HI` times it (the profile over Q^2 is not
/// unimodal: the best filter changes kind along it, so the grid is fine).
const GRID_LO: i32 = -16;
const GRID_HI: i32 = 6;

/// Golden-section steps of the first-order corner in the profile over Q^2.
const LITE_GOLDEN: usize = 14;

/// The filter with the white angle noise refitted beside it.
#[derive(Debug, Clone)]
pub struct JointFit {
    /// The filter's fit at the best Q^2; `fit.delta_mu` is relative to the
    /// expectation given (the Q^2 change included), `fit.n_par` = 3.
    pub filter: FilterFit,
    /// White angle noise, arcsec^2, and its 95 % interval.
    pub q2: f64,
    pub q2_ci: (f64, f64),
    /// How much wider (below, above) Q's interval is, profiled over the
    /// filter and N^2, than at them fixed (at least 1).
    pub q_profile_widen: (f64, f64),
}

/// Fit a readout filter and Q^2 jointly about the current white rate `n2`
/// (arcsec^2/s), white angle `q2` (arcsec^2, at least `q2_floor`) and filter
/// `current`. `None` when the filter cannot be fitted, or when the best Q^2
/// is the current one (the filter alone is then the candidate).
pub fn fit(
    data: &LevelData,
    basis: &Basis,
    n2: f64,
    q2: f64,
    q2_floor: f64,
    current: Option<ReadoutFilter>,
) -> Option<JointFit> {
    let phi = basis.white_angle();
    let wr = basis.white_rate();
    if !(n2 > 0.0 && phi[0] > 0.0) {
        return None;
    }
    let shifted = |q: f64| LevelData {
        e0: data
            .e0
            .iter()
            .zip(&phi)
            .map(|(e, p)| e + (q - q2) * p)
            .collect(),
        ..data.clone()
    };
    let at = |q: f64| -> Option<FilterFit> {
        let mut ff = readout::fit(&shifted(q), basis, n2, current)?;
        for (d, p) in ff.fit.delta_mu.iter_mut().zip(&phi) {
            *d += (q - q2) * p;
        }
        // the log-likelihood is unchanged: the expectations e0 + delta_mu are the same
        ff.fit.n_par = 3;
        Some(ff)
    };
    // the profile over Q^2: the filter search without its intervals (the
    // log-likelihood is the same function of the expectations whatever e0)
    let ll = |q: f64| readout::best_loglik(&shifted(q), basis, n2, current, LITE_GOLDEN);
    // the reference level: white angle noise as large as the white rate at the finest level
    let q_ref = n2 * wr[0] / phi[0];
    let mut grid: Vec<f64> = (GRID_LO..=GRID_HI)
        .map(|k| q_ref * 2f64.powi(k))
        .filter(|&q| q > q2_floor)
        .collect();
    grid.insert(0, q2_floor.max(q_ref * 2f64.powi(GRID_LO - 1)));
    let vals: Vec<f64> = grid.iter().map(|&q| ll(q)).collect();
    let ib = (0..grid.len()).max_by(|&a, &b| vals[a].total_cmp(&vals[b]))?;
    if !vals[ib].is_finite() {
        return None;
    }
    let lq = |x: f64| ll(x.exp());
    let (a, b) = (
        grid[ib.saturating_sub(1)].ln(),
        grid[(ib + 1).min(grid.len() - 1)].ln(),
    );
    let golden = golden_max(&lq, a, b, 20).exp();
    let l_golden = ll(golden);
    let (best_q, l_best) = if l_golden < vals[ib] {
        (grid[ib], vals[ib])
    } else {
        (golden, l_golden)
    };
    let best = at(best_q)?;
    let l_max = l_best.max(best.fit.loglik);
    // no better than the current Q^2 (the plain filter candidate) by a nat: not a joint fit
    if !(l_max > ll(q2.max(q2_floor)) + 0.5) {
        return None;
    }
    let target = l_max - CI_DEVIANCE / 2.0;
    let bisect = |inner: f64, outer: f64| {
        let (mut a, mut b) = (inner.ln(), outer.ln());
        for _ in 0..20 {
            let m = 0.5 * (a + b);
            if lq(m) >= target {
                a = m;
            } else {
                b = m;
            }
        }
        (0.5 * (a + b)).exp()
    };
    let lo_end = grid[0];
    let lo = if ll(lo_end) >= target {
        q2_floor
    } else {
        bisect(best_q, lo_end)
    };
    let mut outer = best_q * 4.0;
    while ll(outer) >= target && outer < q_ref * 2f64.powi(GRID_HI + 12) {
        outer *= 4.0;
    }
    let hi = bisect(best_q, outer);
    let q2_ci = (lo.min(best_q), hi.max(best_q));
    // Q's interval with the filter and N^2 held: the width a refit about the
    // updated model's runs gives
    let held = {
        let mut fixed = data.clone();
        for (e, dm) in fixed.e0.iter_mut().zip(&best.fit.delta_mu) {
            *e += dm;
        }
        wvar_fit::fit_amplitude(&fixed, &phi, best_q, q2_floor).theta_ci
    };
    let mut best = best;
    widen_by_trade_off(&mut best, [lo.max(q2_floor), hi].map(at));
    Some(JointFit {
        filter: best,
        q2: best_q,
        q2_ci,
        q_profile_widen: profile_widen(best_q, q2_ci, held),
    })
}

/// (below, above) ratios of Q's profile interval to its interval with the
/// filter and N^2 held (in Q, arcsec; at least 1).
fn profile_widen(q2: f64, profiled: (f64, f64), held: (f64, f64)) -> (f64, f64) {
    let q = q2.sqrt();
    let r = |w: f64, c: f64| if c > 0.0 { (w / c).max(1.0) } else { 1.0 };
    (
        r(q - profiled.0.max(0.0).sqrt(), q - held.0.max(0.0).sqrt()),
        r(profiled.1.sqrt() - q, held.1.sqrt() - q),
    )
}

/// N^2's interval with the trade-off against Q^2: N^2 at the ends of Q^2's
/// interval (`ends`, the filter refitted there) is how far Q^2 moves it,
/// added in quadrature to the width at the best Q^2 (the projection of the
/// joint ellipse); the profile widening ratios grow alike.
fn widen_by_trade_off(best: &mut FilterFit, ends: [Option<FilterFit>; 2]) {
    let t = best.fit.theta;
    let (mut dl, mut dh) = (0.0f64, 0.0f64);
    for e in ends.iter().flatten() {
        let d = e.fit.theta - t;
        if d.is_finite() {
            dl = dl.max(-d);
            dh = dh.max(d);
        }
    }
    let (cl, ch) = (t - best.fit.theta_ci.0, best.fit.theta_ci.1 - t);
    let (wl, wh) = (cl.hypot(dl), ch.hypot(dh));
    best.fit.theta_ci = ((t - wl).max(0.0), t + wh);
    let ratio = |w: f64, c: f64| if c > 0.0 { (w / c).max(1.0) } else { 1.0 };
    let (rl, rh) = best.arw_profile_widen;
    best.arw_profile_widen = (rl * ratio(wl, cl), rh * ratio(wh, ch));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::wvar_fit::Fit;

    fn ff(theta: f64, ci: (f64, f64)) -> FilterFit {
        FilterFit {
            filter: ReadoutFilter::MovingAverage { length: 2 },
            fit: Fit {
                theta,
                theta_ci: ci,
                shape: None,
                shape_ci: None,
                loglik: 0.0,
                n_par: 3,
                delta_mu: Vec::new(),
            },
            corner_ci_cycles: (0.25, 0.25),
            length_ci: Some((2, 2)),
            arw_profile_widen: (1.0, 1.0),
        }
    }

    #[test]
    fn the_profile_widening_is_the_ratio_of_half_widths_in_q() {
        // Q = 2: profiled [1.5, 3], held [1.9, 2.2] (in Q)
        let (lo, hi) = profile_widen(4.0, (2.25, 9.0), (3.61, 4.84));
        assert!((lo - 5.0).abs() < 1e-9, "{lo}");
        assert!((hi - 5.0).abs() < 1e-9, "{hi}");
        // never below 1
        assert_eq!(profile_widen(4.0, (3.9, 4.1), (1.0, 9.0)), (1.0, 1.0));
    }

    #[test]
    fn the_trade_off_adds_in_quadrature() {
        // at the Q^2 ends N^2 moves by -4 and +0.5; its own half-widths are 3 and 3
        let mut best = ff(10.0, (7.0, 13.0));
        widen_by_trade_off(
            &mut best,
            [Some(ff(6.0, (5.0, 7.0))), Some(ff(10.5, (9.0, 12.0)))],
        );
        let (lo, hi) = best.fit.theta_ci;
        assert!((lo - 5.0).abs() < 1e-12, "{lo}"); // 10 - hypot(3, 4)
        assert!((hi - (10.0 + 3.0f64.hypot(0.5))).abs() < 1e-12, "{hi}");
        assert!((best.arw_profile_widen.0 - 5.0 / 3.0).abs() < 1e-12);
        // no ends: unchanged
        let mut same = ff(10.0, (7.0, 13.0));
        widen_by_trade_off(&mut same, [None, None]);
        assert_eq!(same.fit.theta_ci, (7.0, 13.0));
        assert_eq!(same.arw_profile_widen, (1.0, 1.0));
    }
}
