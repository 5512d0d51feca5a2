//! Power-law noise identification: which noise exponent alpha dominates at an
//! averaging factor m. The EDF (and so the confidence interval) depends on it.
//!
//! Role in the whole: the batch and streaming engines call [`noise_id`] per
//! tau; `model` can use it to label the slope regions of a gyro's Allan curve
//! (alpha 2 = quantization noise, 0 = angle random walk, -1 = bias instability,
//! -2 = rate random walk).
//!
//! * Lag-1 autocorrelation (W. J. Riley and C. A. Greenhall, "Power law noise
//!   identification using the lag 1 autocorrelation", EFTF 2004): used when at
//!   least [`LAG1_MIN_POINTS`] decimated phase points remain. The engine does not
//!   detrend the decimated phase first: measured on the Stable32 files, that
//!   reproduces their Alpha column on 3273 of 3309 rows (AllanTools' quadratic
//!   detrend: 3007); the remaining rows sit on the rho = 0.25 or 2 rho = -0.5
//!   decision boundaries. [`noise_id_lag1_series`] offers the detrended variant.
//! * B1 ratio (Barnes; Howe 2000) and R(n) = MVAR/AVAR, as SP 1065 section 5.6
//!   describes, for fewer points. Stable32's own choices there are not fully
//!   documented; the agreement we reach is measured and reported by the tests.

use super::sums::deviation;
use super::{Phase, Stat};

/// Fewest decimated points for the lag-1 ACF method (Riley & Greenhall).
pub const LAG1_MIN_POINTS: usize = 30;

/// How a noise exponent was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseIdMethod {
    /// Lag-1 autocorrelation of the decimated, detrended phase.
    Lag1Acf,
    /// B1 ratio, refined by R(n) for phase noise.
    B1Rn,
    /// Too few points for either method: white FM (alpha 0) assumed.
    Assumed,
}

/// Result of a noise identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseId {
    /// Integer noise exponent, clamped to the range the statistic's EDF accepts.
    pub alpha: i32,
    /// Method used.
    pub method: NoiseIdMethod,
}

/// Result of the lag-1 ACF method on one series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lag1 {
    /// Integer alpha: `-round(2 rho) - 2 d` (+2 for phase data).
    pub alpha: i32,
    /// Non-integer estimate `-2 (rho + d)` (+2 for phase data).
    pub alpha_f: f64,
    /// Number of differencing steps taken.
    pub d: u32,
    /// `r1 / (1 + r1)` at the final step.
    pub rho: f64,
}

/// Identify the dominant noise at factor `m` for `stat` on a phase series:
/// lag-1 ACF when the series decimated by `m` has at least 30 points, else
/// B1 / R(n), else alpha 0 (white FM) assumed. The result is clamped to
/// `stat.min_alpha() ..= 2`.
pub fn noise_id(phase: &Phase, stat: Stat, m: u64) -> NoiseId {
    let dmax = if stat.difference_order() == 3 { 3 } else { 2 };
    let clamp = |a: i32| a.clamp(stat.min_alpha(), 2);
    let n = phase.len();
    let mu = m.max(1) as usize;
    if n.div_ceil(mu) >= LAG1_MIN_POINTS {
        let l = match phase {
            Phase::F64(x) => lag1_strided(x, mu, dmax, |v| v),
            // cumulative counts below 2^53 convert exactly, so their differences stay exact
            Phase::Counts(c) => lag1_strided(c, mu, dmax, |v| v as f64),
        };
        if let Some(l) = l {
            return NoiseId {
                alpha: clamp(l.alpha),
                method: NoiseIdMethod::Lag1Acf,
            };
        }
    }
    if let Some(a) = noise_id_b1_rn(phase, m) {
        return NoiseId {
            alpha: clamp(a),
            method: NoiseIdMethod::B1Rn,
        };
    }
    NoiseId {
        alpha: 0,
        method: NoiseIdMethod::Assumed,
    }
}

/// Lag-1 ACF noise identification on a real phase series decimated by `m`
/// (every m-th point, not detrended, as the engine and Stable32 do), with at
/// most `dmax` differencing steps (2 for the Allan family, 3 for Hadamard).
/// `None` when fewer than 30 points remain or the series is degenerate.
pub fn noise_id_lag1(phase: &[f64], m: usize, dmax: u32) -> Option<Lag1> {
    let m = m.max(1);
    if phase.len().div_ceil(m) < LAG1_MIN_POINTS {
        return None;
    }
    lag1_strided(phase, m, dmax, |v| v)
}

/// The undetrended lag-1 method on `x[::m]` without copying anything: the
/// d-th differences of the strided series are formed on the fly (in the same
/// order of operations as repeated differencing of a copy).
fn lag1_strided<T: Copy>(
    x: &[T],
    m: usize,
    dmax: u32,
    to: impl Fn(T) -> f64 + Copy,
) -> Option<Lag1> {
    let len = x.len().div_ceil(m);
    if len < LAG1_MIN_POINTS {
        return None;
    }
    for d in 0..=dmax.min(3) {
        let n = len - d as usize;
        let r1 = lag1_acf_iter(
            || StridedDiff {
                x,
                m,
                d: d as usize,
                pos: 0,
                n,
                to,
            },
            n,
        )?;
        let rho = r1 / (1.0 + r1);
        if rho < 0.25 || d >= dmax.min(3) {
            let alpha = -((2.0 * rho).round_ties_even() as i32) - 2 * d as i32 + 2;
            return Some(Lag1 {
                alpha,
                alpha_f: -2.0 * (rho + d as f64) + 2.0,
                d,
                rho,
            });
        }
    }
    None
}

/// Iterator over the d-th differences (d <= 3) of `x[::m]`.
struct StridedDiff<'a, T, F> {
    x: &'a [T],
    m: usize,
    d: usize,
    pos: usize,
    n: usize,
    to: F,
}

impl<T: Copy, F: Fn(T) -> f64> Iterator for StridedDiff<'_, T, F> {
    type Item = f64;
    #[inline]
    fn next(&mut self) -> Option<f64> {
        if self.pos >= self.n {
            return None;
        }
        let mut w = [0.0_f64; 4];
        for (k, slot) in w.iter_mut().enumerate().take(self.d + 1) {
            *slot = (self.to)(self.x[(self.pos + k) * self.m]);
        }
        for level in 0..self.d {
            for k in 0..self.d - level {
                w[k] = w[k + 1] - w[k];
            }
        }
        self.pos += 1;
        Some(w[0])
    }
}

/// The lag-1 ACF algorithm on an already decimated (phase) or averaged
/// (frequency, `is_phase = false`) series `z`, consumed as scratch space.
/// Optionally removes a least-squares polynomial of `detrend_degree` (1 or 2;
/// AllanTools uses 2 for phase, 1 for frequency), then differences until
/// `rho = r1 / (1 + r1) < 0.25` (at least `dmin`, at most `dmax` times).
pub fn noise_id_lag1_series(
    mut z: Vec<f64>,
    is_phase: bool,
    dmin: u32,
    dmax: u32,
    detrend_degree: Option<u32>,
) -> Option<Lag1> {
    if z.len() < LAG1_MIN_POINTS {
        return None;
    }
    if let Some(deg) = detrend_degree {
        detrend(&mut z, deg.clamp(1, 2));
    }
    let mut d = 0_u32;
    loop {
        let r1 = lag1_acf(&z)?;
        let rho = r1 / (1.0 + r1);
        if d >= dmin && (rho < 0.25 || d >= dmax) {
            let add = if is_phase { 2 } else { 0 };
            let alpha_f = -2.0 * (rho + d as f64) + add as f64;
            let alpha = -((2.0 * rho).round_ties_even() as i32) - 2 * d as i32 + add;
            return Some(Lag1 {
                alpha,
                alpha_f,
                d,
                rho,
            });
        }
        // first difference in place
        for i in 0..z.len() - 1 {
            z[i] = z[i + 1] - z[i];
        }
        z.pop();
        if z.len() < 2 {
            return None;
        }
        d += 1;
    }
}

/// Lag-1 autocorrelation `sum (z_i - zbar)(z_{i+1} - zbar) / sum (z_i - zbar)^2`.
fn lag1_acf(z: &[f64]) -> Option<f64> {
    lag1_acf_iter(|| z.iter().copied(), z.len())
}

/// [`lag1_acf`] over a re-iterable sequence of `n` values (two passes).
fn lag1_acf_iter<I: Iterator<Item = f64>>(seq: impl Fn() -> I, n: usize) -> Option<f64> {
    if n < 2 {
        return None;
    }
    let mean = sum4(seq()) / n as f64;
    let num = sum4(
        seq()
            .zip(seq().skip(1))
            .map(|(a, b)| (a - mean) * (b - mean)),
    );
    let den = sum4(seq().map(|v| (v - mean) * (v - mean)));
    (den > 0.0 && num.is_finite()).then_some(num / den)
}

/// Sum with four interleaved accumulators (faster, and no less accurate than
/// a single running sum).
fn sum4(it: impl Iterator<Item = f64>) -> f64 {
    let mut s = [0.0_f64; 4];
    for (i, v) in it.enumerate() {
        s[i & 3] += v;
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// Remove the least-squares polynomial of degree 1 or 2 in the sample index,
/// using the discrete orthogonal (Gram) polynomials on 0..n, which keeps the
/// fit well conditioned for millions of points.
fn detrend(z: &mut [f64], degree: u32) {
    let n = z.len() as f64;
    let c = (n - 1.0) / 2.0;
    let p2_off = (n * n - 1.0) / 12.0;
    let p1 = |i: usize| i as f64 - c;
    let p2 = |i: usize| {
        let t = i as f64 - c;
        t * t - p2_off
    };
    let (mut s0, mut s1, mut s2, mut q1, mut q2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (i, &v) in z.iter().enumerate() {
        s0 += v;
        s1 += v * p1(i);
        q1 += p1(i) * p1(i);
        if degree >= 2 {
            s2 += v * p2(i);
            q2 += p2(i) * p2(i);
        }
    }
    let b0 = s0 / n;
    let b1 = if q1 > 0.0 { s1 / q1 } else { 0.0 };
    let b2 = if degree >= 2 && q2 > 0.0 {
        s2 / q2
    } else {
        0.0
    };
    for (i, v) in z.iter_mut().enumerate() {
        *v -= b0 + b1 * p1(i) + b2 * p2(i);
    }
}

/// B1 / R(n) identification (SP 1065 section 5.6) at factor `m`:
/// B1 = (sample variance of the m-averaged rates) / (non-overlapped AVAR),
/// compared with Barnes' expectations for mu = -2, -1, 0, 1 (alpha 2|1, 0, -1,
/// -2), boundaries at geometric means; for mu = -2, R(n) = MVAR / AVAR
/// separates white PM (R = 1/m) from flicker PM. `None` when fewer than two
/// averages exist.
pub fn noise_id_b1_rn(phase: &Phase, m: u64) -> Option<i32> {
    let n = phase.len() as u64;
    if m == 0 || n < 2 {
        return None;
    }
    let nf = (n - 1) / m; // number of m-averaged rate values
    if nf < 2 {
        return None;
    }
    let mu = m as usize;
    let ybar: Vec<f64> = (0..nf as usize)
        .map(|k| phase.get_f64((k + 1) * mu) - phase.get_f64(k * mu))
        .collect();
    let mean = super::mean_f64(&ybar);
    let var = ybar.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (nf - 1) as f64;
    let avar =
        ybar.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (2.0 * (nf - 1) as f64);
    if avar.is_nan() || avar <= 0.0 {
        return None;
    }
    let b1 = var / avar;
    let nn = nf as f64;
    // (alpha, mu) from high to low alpha; alpha 2 stands for "PM" (mu = -2)
    let cands = [(2, -2), (0, -1), (-1, 0), (-2, 1)];
    let mut alpha = -2;
    for w in cands.windows(2) {
        let bound = (b1_theory(nn, w[0].1) * b1_theory(nn, w[1].1)).sqrt();
        if b1 < bound {
            alpha = w[0].0;
            break;
        }
    }
    if alpha == 2 {
        // R(n) needs MDEV and ADEV at m (tau0 cancels in the ratio)
        if let (Some((md, _)), Some((ad, _))) = (
            deviation(phase, Stat::Mdev, 1.0, m),
            deviation(phase, Stat::Adev, 1.0, m),
        ) && ad > 0.0
        {
            let rn = (md / ad).powi(2);
            let bound = (rn_theory(m as f64, 2) * rn_theory(m as f64, 1)).sqrt();
            alpha = if rn < bound { 2 } else { 1 };
        }
    }
    Some(alpha)
}

/// Expected B1 for `n` averages and AVAR tau exponent `mu` (Barnes; Howe 2000, Table 3).
fn b1_theory(n: f64, mu: i32) -> f64 {
    match mu {
        0 => n * n.ln() / (2.0 * (n - 1.0) * std::f64::consts::LN_2),
        _ => {
            let m = mu as f64;
            n * (1.0 - n.powf(m)) / (2.0 * (n - 1.0) * (1.0 - 2f64.powf(m)))
        }
    }
}

/// Expected R(n) = MVAR/AVAR for white PM (alpha 2: 1/m) and flicker PM
/// (alpha 1: IEEE 1139 expressions with f_h = 1/(2 tau0)); 1 otherwise.
fn rn_theory(m: f64, alpha: i32) -> f64 {
    use std::f64::consts::PI;
    match alpha {
        2 => 1.0 / m,
        1 => {
            let avar = (1.038 + 3.0 * (PI * m).ln()) / (4.0 * PI * PI);
            let mvar = 3.0 * (256.0_f64 / 27.0).ln() / (8.0 * PI * PI);
            mvar / avar
        }
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detrend_removes_exact_quadratic() {
        let mut z: Vec<f64> = (0..50)
            .map(|i| 3.0 + 0.5 * i as f64 - 0.01 * (i * i) as f64)
            .collect();
        detrend(&mut z, 2);
        assert!(
            z.iter().all(|v| v.abs() < 1e-10),
            "residual {:?}",
            z.iter().fold(0.0_f64, |a, v| a.max(v.abs()))
        );
    }

    #[test]
    fn strided_lag1_equals_copying_version() {
        // random walk + white noise: needs differencing, exercises d = 0..2
        let mut s = 7_u64;
        let mut acc = 0.0;
        let x: Vec<f64> = (0..5000)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                acc += u;
                acc * (1.0 + (i % 7) as f64 * 1e-3) + 0.3 * u * u
            })
            .collect();
        for m in [1, 2, 3, 10, 50, 166] {
            for dmax in [1, 2, 3] {
                let a = noise_id_lag1(&x, m, dmax).unwrap();
                let z: Vec<f64> = x.iter().step_by(m).copied().collect();
                let b = noise_id_lag1_series(z, true, 0, dmax, None).unwrap();
                assert_eq!(a, b, "m={m} dmax={dmax}");
            }
        }
    }

    #[test]
    fn b1_theory_special_cases() {
        // mu = 1 (random-walk FM) gives N/2; mu = -1 (white FM) gives 1
        assert!((b1_theory(10.0, 1) - 5.0).abs() < 1e-12);
        assert!((b1_theory(10.0, -1) - 1.0).abs() < 1e-12);
        assert!((b1_theory(10.0, -2) - 11.0 / 15.0).abs() < 1e-12);
    }
}
