//! Equivalent degrees of freedom (EDF) and chi-square confidence intervals.
//!
//! Role in the whole: every Allan point (batch here, streaming in
//! `allan::streaming`, and the noise-coefficient fits in `model`) carries an
//! interval `[ci_lo, ci_hi]` computed from an EDF and a confidence level.
//!
//! * [`edf_greenhall`]: the general EDF algorithm of C. A. Greenhall and
//!   W. J. Riley, "Uncertainty of stability variances based on finite
//!   differences" (PTTI 2003; NIST SP 1065 section 5.3.3), for the Allan and
//!   Hadamard families, overlapped or not, modified or not. Stable32 uses it
//!   for the Min/Max Sigma columns.
//! * [`edf_totdev`]: the total-variance EDF of SP 1065 Table 7 (white, flicker
//!   and random-walk FM), with the SP 1065 Table 5 approximations for PM noise.
//! * [`chi2_interval`]: `dev * sqrt(edf / chi2(p))` bounds (SP 1065 eq. 45).

use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::Stat;

/// The "J_max" of Greenhall's algorithm: sums longer than this are replaced by
/// the asymptotic tables.
const J_MAX: f64 = 100.0;

/// Equivalent degrees of freedom of a finite-difference variance estimate
/// (Greenhall-Riley).
///
/// * `alpha`: noise exponent of S_y(f), 2 ..= -4, with `alpha + 2 d > 1`.
/// * `d`: difference order: 1 first difference, 2 Allan, 3 Hadamard.
/// * `m`: averaging factor; `n_phase`: number of phase points N.
/// * `overlapping`: stride 1 (OADEV, OHDEV, MDEV) instead of stride m.
/// * `modified`: the modified (phase-averaged) variant (MDEV).
///
/// Returns `f64::NAN` for arguments outside the model (alpha out of range,
/// `d` not 1..=3, or fewer points than one estimator term needs).
pub fn edf_greenhall(
    alpha: i32,
    d: u32,
    m: u64,
    n_phase: u64,
    overlapping: bool,
    modified: bool,
) -> f64 {
    if !(1..=3).contains(&d) || !(-4..=2).contains(&alpha) || alpha + 2 * d as i32 <= 1 || m == 0 {
        return f64::NAN;
    }
    let df = d as f64;
    let mf = m as f64;
    let n = n_phase as f64;
    // F: filter factor (1 modified, m unmodified); S: stride factor (m overlapped, 1 not).
    let f = if modified {
        Filter::Finite(1.0)
    } else {
        Filter::Finite(mf)
    };
    let s = if overlapping { mf } else { 1.0 };
    let l = if modified {
        mf + mf * df
    } else {
        1.0 + mf * df
    };
    if n < l {
        return f64::NAN;
    }
    let big_m = 1.0 + (s * (n - l) / mf).floor();
    let j = big_m.min((df + 1.0) * s);
    let r = big_m / s;

    let inv_edf = if modified {
        // case 1: modified variances, all alpha
        let f1 = Filter::Finite(1.0);
        if j <= J_MAX {
            basic_sum(j, big_m, s, f1, alpha, d) / (sz(0.0, f1, alpha, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table1(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, f1, alpha, d) / (sz(0.0, f1, alpha, d).powi(2) * J_MAX)
        }
    } else if alpha <= 0 {
        // case 2: unmodified, alpha <= 0
        if j <= J_MAX {
            let fp = if mf * (df + 1.0) <= J_MAX {
                f
            } else {
                Filter::Infinite
            };
            basic_sum(j, big_m, s, fp, alpha, d) / (sz(0.0, fp, alpha, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(alpha, d);
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            let fi = Filter::Infinite;
            basic_sum(J_MAX, J_MAX, mp, fi, alpha, d) / (sz(0.0, fi, alpha, d).powi(2) * J_MAX)
        }
    } else if alpha == 1 {
        // case 3: unmodified, flicker PM
        if j <= J_MAX {
            basic_sum(j, big_m, s, f, 1, d) / (sz(0.0, f, 1, d).powi(2) * big_m)
        } else if r > df + 1.0 {
            let (a0, a1) = table2(1, d);
            let (b0, b1) = table3(d);
            (a0 - a1 / r) / ((b0 + b1 * mf.ln()).powi(2) * r)
        } else {
            let mp = J_MAX / r;
            let (b0, b1) = table3(d);
            basic_sum(J_MAX, J_MAX, mp, Filter::Finite(mp), 1, d)
                / ((b0 + b1 * mf.ln()).powi(2) * J_MAX)
        }
    } else {
        // case 4: unmodified, white PM. Consecutive terms correlate only at
        // lags that are multiples of m, with rho_l = (-1)^l C(2d, d+l) / C(2d, d).
        let k = r.ceil();
        let c2d = binom(2 * d, d);
        if k <= df {
            let mut sum = 1.0;
            for l in 1..(k as u32) {
                let rho = binom(2 * d, d + l) / c2d;
                sum += 2.0 * (1.0 - l as f64 / r) * rho * rho;
            }
            sum / big_m
        } else {
            let a0 = binom(4 * d, 2 * d) / (c2d * c2d);
            let a1 = df / 2.0;
            (a0 - a1 / r) / big_m
        }
    };
    1.0 / inv_edf
}

/// Total-deviation EDF.
///
/// For white, flicker and random-walk FM (alpha 0, -1, -2) this is SP 1065
/// Table 7, `edf = b N / m - c`. SP 1065 gives no TOTVAR formula for PM noise;
/// like Stable32 (checked against its files to about 3e-4) we use the simple
/// AVAR approximations of SP 1065 Table 5 ([`edf_simple`]) for alpha 2 and 1,
/// and fall back to the overlapping-Allan Greenhall EDF where that
/// approximation is undefined (m close to N/2).
pub fn edf_totdev(alpha: i32, m: u64, n_phase: u64) -> f64 {
    let n = n_phase as f64;
    let mf = m as f64;
    match alpha {
        0 => 1.50 * n / mf,
        -1 => 1.17 * n / mf - 0.22,
        -2 => 0.93 * n / mf - 0.36,
        _ => {
            let e = edf_simple(alpha, m, n_phase);
            if e.is_finite() && e > 0.0 {
                e
            } else {
                edf_greenhall(alpha.clamp(-2, 2), 2, m, n_phase, true, false)
            }
        }
    }
}

/// Simple approximate Allan-variance EDF formulas (SP 1065 Table 5, after
/// Stein 1985), for alpha 2, 1, 0, -1, -2; `N - 1` for anything else.
pub fn edf_simple(alpha: i32, m: u64, n_phase: u64) -> f64 {
    let n = n_phase as f64;
    let m = m as f64;
    match alpha {
        2 => (n + 1.0) * (n - 2.0 * m) / (2.0 * (n - m)),
        1 => {
            let a = (n - 1.0) / (2.0 * m);
            let b = (2.0 * m + 1.0) * (n - 1.0) / 4.0;
            (a.ln() * b.ln()).sqrt().exp()
        }
        0 => {
            (3.0 * (n - 1.0) / (2.0 * m) - 2.0 * (n - 2.0) / n)
                * (4.0 * m * m / (4.0 * m * m + 5.0))
        }
        -1 => {
            if m == 1.0 {
                2.0 * (n - 2.0) / (2.3 * n - 4.9)
            } else {
                5.0 * n * n / (4.0 * m * (n + 3.0 * m))
            }
        }
        -2 => {
            (n - 2.0) / (m * (n - 3.0).powi(2))
                * ((n - 1.0).powi(2) - 3.0 * m * (n - 1.0) + 4.0 * m * m)
        }
        _ => n - 1.0,
    }
}

/// The EDF our estimators use for `stat` at noise exponent `alpha` (clamped to
/// the range the model accepts for that statistic).
pub fn edf_for_stat(stat: Stat, alpha: i32, m: u64, n_phase: u64) -> f64 {
    let a = alpha.clamp(stat.min_alpha(), 2);
    match stat {
        Stat::Adev => edf_greenhall(a, 2, m, n_phase, false, false),
        Stat::Oadev => edf_greenhall(a, 2, m, n_phase, true, false),
        Stat::Mdev => edf_greenhall(a, 2, m, n_phase, true, true),
        Stat::Hdev => edf_greenhall(a, 3, m, n_phase, false, false),
        Stat::Ohdev => edf_greenhall(a, 3, m, n_phase, true, false),
        Stat::Totdev => edf_totdev(a, m, n_phase),
    }
}

/// Two-sided chi-square confidence interval `(lo, hi)` for a deviation `dev`
/// estimated with `edf` degrees of freedom (non-integer allowed) at the given
/// confidence level (e.g. 0.683, Stable32's default, or 0.95):
/// `lo = dev sqrt(edf / chi2_{1-q})`, `hi = dev sqrt(edf / chi2_q)`, `q = (1 - confidence) / 2`.
/// Returns `(NAN, NAN)` when `edf` is not a positive finite number or the
/// confidence is outside (0, 1).
pub fn chi2_interval(dev: f64, edf: f64, confidence: f64) -> (f64, f64) {
    let edf_ok = edf.is_finite() && edf > 0.0;
    let conf_ok = confidence > 0.0 && confidence < 1.0; // false for NaN
    if !edf_ok || !conf_ok {
        return (f64::NAN, f64::NAN);
    }
    let Ok(chi2) = ChiSquared::new(edf) else {
        return (f64::NAN, f64::NAN);
    };
    let q = (1.0 - confidence) / 2.0;
    let chi_lo = chi2.inverse_cdf(q);
    let chi_hi = chi2.inverse_cdf(1.0 - q);
    (dev * (edf / chi_hi).sqrt(), dev * (edf / chi_lo).sqrt())
}

// ---------------------------------------------------------------------------
// Greenhall's building blocks (his eqs. 7-10).

#[derive(Debug, Clone, Copy)]
enum Filter {
    Finite(f64),
    Infinite,
}

/// sw(t): the generalized autocovariance kernel of the noise (eq. 7).
fn sw(t: f64, alpha: i32) -> f64 {
    let a = t.abs();
    match alpha {
        2 => -a,
        1 => xlnx(t, 2),
        0 => a * a * a,
        -1 => xlnx(t, 4),
        -2 => a.powi(5),
        -3 => xlnx(t, 6),
        -4 => a.powi(7),
        _ => f64::NAN,
    }
}

/// t^p ln|t| with the limit 0 at t = 0.
fn xlnx(t: f64, p: i32) -> f64 {
    if t == 0.0 {
        0.0
    } else {
        t.powi(p) * t.abs().ln()
    }
}

/// sx(t, F): sw passed through the F-point phase-averaging filter (eq. 8).
fn sx(t: f64, f: Filter, alpha: i32) -> f64 {
    match f {
        Filter::Infinite => sw(t, alpha + 2),
        Filter::Finite(ff) => {
            // For large F the direct second difference F^2 (2 sw(t) - sw(t-1/F) - sw(t+1/F))
            // cancels catastrophically; away from t = 0 its Taylor series is exact to ~1e-9.
            if alpha == 1 && ff > 64.0 && t.abs() * ff > 16.0 {
                let h2 = 1.0 / (ff * ff);
                let t2 = t * t;
                let g2 = 2.0 * t.abs().ln() + 3.0; // g''   for g = t^2 ln|t|
                let g4 = -2.0 / t2; //                g''''
                let g6 = -12.0 / (t2 * t2); //        g^(6)
                -(g2 + h2 * g4 / 12.0 + h2 * h2 * g6 / 360.0)
            } else {
                let h = 1.0 / ff;
                ff * ff * (2.0 * sw(t, alpha) - sw(t - h, alpha) - sw(t + h, alpha))
            }
        }
    }
}

/// sz(t): the d-th difference (binomial weights) of sx (eq. 9).
fn sz(t: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let di = d as i32;
    let c2d = 2 * d;
    let mut acc = 0.0;
    for k in -di..=di {
        let w = binom(c2d, (di + k) as u32);
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        acc += sign * w * sx(t + k as f64, f, alpha);
    }
    acc
}

/// BasicSum (eq. 10).
fn basic_sum(j: f64, big_m: f64, s: f64, f: Filter, alpha: i32, d: u32) -> f64 {
    let mut acc = sz(0.0, f, alpha, d).powi(2);
    acc += (1.0 - j / big_m) * sz(j / s, f, alpha, d).powi(2);
    let ji = j as u64;
    for jj in 1..ji {
        let jf = jj as f64;
        acc += 2.0 * (1.0 - jf / big_m) * sz(jf / s, f, alpha, d).powi(2);
    }
    acc
}

fn binom(n: u32, k: u32) -> f64 {
    if k > n {
        return 0.0;
    }
    let k = k.min(n - k);
    let mut r = 1.0_f64;
    for i in 0..k {
        r = r * (n - i) as f64 / (i + 1) as f64;
    }
    r.round()
}

/// Greenhall Table 1 (modified variances): (a0, a1), rows alpha 2..-4, columns d 1..3.
fn table1(alpha: i32, d: u32) -> (f64, f64) {
    const NA: (f64, f64) = (f64::NAN, f64::NAN);
    let rows: [[(f64, f64); 3]; 7] = [
        [
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
            (22.0 / 25.0, 2.0 / 3.0),
        ],
        [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
        [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
        [NA, (1.048, 0.534), (1.180, 0.816)],
        [NA, (1.302, 0.535), (1.175, 0.777)],
        [NA, NA, (1.194, 0.703)],
        [NA, NA, (1.489, 0.702)],
    ];
    rows[(2 - alpha) as usize][(d - 1) as usize]
}

/// Greenhall Table 2 (unmodified variances).
fn table2(alpha: i32, d: u32) -> (f64, f64) {
    const NA: (f64, f64) = (f64::NAN, f64::NAN);
    let rows: [[(f64, f64); 3]; 7] = [
        [
            (3.0 / 2.0, 1.0 / 2.0),
            (35.0 / 18.0, 1.0),
            (231.0 / 100.0, 3.0 / 2.0),
        ],
        [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
        [
            (2.0 / 3.0, 1.0 / 6.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (7.0 / 9.0, 1.0 / 2.0),
        ],
        [NA, (0.852, 0.375), (0.997, 0.617)],
        [NA, (1.079, 0.368), (1.033, 0.607)],
        [NA, NA, (1.053, 0.553)],
        [NA, NA, (1.302, 0.535)],
    ];
    rows[(2 - alpha) as usize][(d - 1) as usize]
}

/// Greenhall Table 3 (unmodified, flicker PM): (b0, b1) for d = 1..3.
fn table3(d: u32) -> (f64, f64) {
    [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)][(d - 1) as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_pm_closed_form_matches_brute_force_correlation_sum() {
        // Case 4 with K <= d (few terms, m > N/4): compare with the direct double sum
        // (1/M^2) sum_{n,n'} rho(n - n')^2 over the M overlapped terms.
        for (n_phase, m) in [(9_u64, 3_u64), (10, 3), (11, 4), (30, 10), (41, 15)] {
            let d = 2_u32;
            let l = 1 + 2 * m;
            if n_phase < l {
                continue;
            }
            let big_m = n_phase - l + 1;
            let rho = |lag: u64| -> f64 {
                if !lag.is_multiple_of(m) {
                    return 0.0;
                }
                match lag / m {
                    0 => 1.0,
                    1 => -4.0 / 6.0,
                    2 => 1.0 / 6.0,
                    _ => 0.0,
                }
            };
            let mut s = 0.0;
            for a in 0..big_m {
                for b in 0..big_m {
                    s += rho(a.abs_diff(b)).powi(2);
                }
            }
            let want = (big_m * big_m) as f64 / s;
            let got = edf_greenhall(2, d, m, n_phase, true, false);
            assert!(
                (got / want - 1.0).abs() < 1e-12,
                "N={n_phase} m={m}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn flicker_pm_taylor_branch_is_continuous() {
        // sx for alpha = 1 switches to a Taylor series for F > 64, |t| F > 16:
        // both forms agree where both are accurate.
        for &t in &[0.3, 1.0, 1.7, 2.5, 3.0] {
            let ff = 65.0;
            let h = 1.0 / ff;
            let direct = ff * ff * (2.0 * sw(t, 1) - sw(t - h, 1) - sw(t + h, 1));
            let taylor = sx(t, Filter::Finite(ff), 1);
            assert!(
                (direct - taylor).abs() < 1e-9,
                "t={t}: {direct} vs {taylor}"
            );
        }
    }

    #[test]
    fn chi2_interval_brackets_and_narrows() {
        let (lo, hi) = chi2_interval(1.0, 10.0, 0.683);
        assert!(lo < 1.0 && hi > 1.0);
        let (lo2, hi2) = chi2_interval(1.0, 1000.0, 0.683);
        assert!(lo2 > lo && hi2 < hi);
        // large edf: approximately dev (1 -+ 1/sqrt(2 edf))
        let (lo3, hi3) = chi2_interval(1.0, 20000.0, 0.6826894921370859);
        assert!((1.0 - lo3 - 0.005).abs() < 1e-4 && (hi3 - 1.0 - 0.005).abs() < 1e-4);
        assert!(chi2_interval(1.0, 0.0, 0.683).0.is_nan());
    }

    #[test]
    fn totdev_table7() {
        assert!((edf_totdev(0, 1, 1001) - 1501.5).abs() < 1e-12);
        assert!((edf_totdev(-2, 10, 1000) - (93.0 - 0.36)).abs() < 1e-12);
        assert!(edf_totdev(1, 500, 1001).is_finite()); // simple formula undefined here: fallback
    }
}
