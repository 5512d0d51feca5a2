//! The record's low-frequency noise at block resolution: the block means'
//! covariance under white rate noise, quantization, bias instability
//! (flicker) and rate random walk, and its restricted maximum-likelihood fit.
//!
//! For block means `y_b` of length `T` (the mean rate over `[bT, (b+1)T)`):
//! * white rate noise (ARW `N`, known from the fine scales): variance
//!   `(60 N)^2 / (n_b tau0)` (deg/h)^2 for `n_b` measured samples; the
//!   quantization's white angle error `Q` adds `2 Q^2 / T^2`;
//! * flicker of coefficient `B` (one-sided PSD `B^2/(pi f)`): its angle
//!   structure function is `D(s) = -(B^2/pi) s^2 ln s + c s^2`, so
//!   `Cov(y_a, y_{a+k}) = const - B^2 h(k) / (2 pi)` with
//!   `h(k) = (k+1)^2 ln(k+1) + (k-1)^2 ln|k-1| - 2 k^2 ln k`; the constant is
//!   that of a band starting a decade below the record (the intercept of the
//!   mean model absorbs it), and the Allan variance of adjacent means is the
//!   plateau `(2 ln 2 / pi) B^2`;
//! * rate random walk `K` (deg/h/sqrt(h), `K/60` per sqrt(s)) from the start
//!   of the record: `Cov(y_a, y_b) = (K/60)^2 T (min(a, b) + 1/2)`, and
//!   `(K/60)^2 T (a + 1/3)` on the diagonal (the Allan variance `K^2 tau / 3`).
//!
//! [`Noise::fit`] finds `B^2` and `K^2` by restricted maximum likelihood
//! (REML) for a given mean model, by golden-section search on each in turn
//! on a log scale, each also tried at zero.

use super::super::gls::{Basis, Cholesky, dot};
use crate::par::par_map;

/// The block means the low-frequency analysis works on.
#[derive(Debug, Clone, PartialEq)]
pub struct Coarse {
    /// Block length, s.
    pub block_s: f64,
    /// Block means, deg/h.
    pub y: Vec<f64>,
    /// Measured samples per block.
    pub n: Vec<u64>,
    /// Sample period, s.
    pub tau0_s: f64,
}

impl Coarse {
    pub fn len(&self) -> usize {
        self.y.len()
    }
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }
    /// Start of block `b`, s.
    pub fn t0(&self, b: usize) -> f64 {
        b as f64 * self.block_s
    }
}

/// The known fine-scale noise: angle random walk and quantization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FineNoise {
    pub arw_dpsh: f64,
    pub quantization_arcsec: f64,
}

/// The covariance's building blocks for one [`Coarse`] series.
#[derive(Debug, Clone)]
pub struct Noise {
    n: usize,
    white: Vec<f64>,
    /// Flicker covariance per unit B^2, by lag.
    flicker: Vec<f64>,
    /// Random-walk covariance per unit (K/60)^2, dense.
    rrw: Vec<f64>,
}

/// The fitted noise: `B^2`, `K^2` (in deg/h and deg/h/sqrt(h)) and the
/// covariance's Cholesky factor.
#[derive(Debug, Clone)]
pub struct Fitted {
    pub b2: f64,
    pub k2: f64,
    pub chol: Cholesky,
}

fn h(k: f64) -> f64 {
    let xl = |x: f64| if x == 0.0 { 0.0 } else { x * x * x.abs().ln() };
    xl(k + 1.0) + xl(k - 1.0) - 2.0 * xl(k)
}

impl Noise {
    pub fn new(c: &Coarse, fine: FineNoise) -> Noise {
        let n = c.len();
        let t = c.block_s;
        let nw = 60.0 * fine.arw_dpsh;
        let q = fine.quantization_arcsec;
        let white =
            c.n.iter()
                .map(|&m| {
                    let w = nw * nw / (m.max(1) as f64 * c.tau0_s);
                    w + 2.0 * q * q / (t * t)
                })
                .collect();
        let top = 2.0 * (10.0 * n.max(2) as f64).ln() + 3.0;
        let flicker = (0..n)
            .map(|k| (top - h(k as f64)) / (2.0 * std::f64::consts::PI))
            .collect();
        let mut rrw = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..n {
                rrw[a * n + b] = t * if a == b {
                    a as f64 + 1.0 / 3.0
                } else {
                    a.min(b) as f64 + 0.5
                };
            }
        }
        Noise {
            n,
            white,
            flicker,
            rrw,
        }
    }

    /// Blocks.
    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The scales of `B^2` and `K^2` for `y` over `span_s`: the data's
    /// variance, and the random walk that reaches it over the record.
    pub fn scales(y: &[f64], span_s: f64) -> (f64, f64) {
        let var = variance(y).max(1e-30);
        (var, var * 3600.0 / span_s.max(1e-9))
    }

    /// The covariance for `b2` (deg/h)^2 and `k2` (deg/h/sqrt(h))^2, row-major.
    pub fn covariance(&self, b2: f64, k2: f64) -> Vec<f64> {
        let n = self.n;
        let ks = k2 / 3600.0;
        let mut s = vec![0.0; n * n];
        for a in 0..n {
            for b in 0..n {
                let lag = a.abs_diff(b);
                s[a * n + b] = b2 * self.flicker[lag] + ks * self.rrw[a * n + b];
            }
            // a little of the diagonal's own scale keeps a noise-free model definite
            s[a * n + a] += self.white[a] * (1.0 + 1e-9) + 1e-12;
        }
        s
    }

    /// Minus twice the restricted log-likelihood (up to a constant) of `y`
    /// under the mean model `x`, and the factor; `None` when not definite.
    pub fn reml(&self, y: &[f64], x: &[Vec<f64>], b2: f64, k2: f64) -> Option<(f64, Cholesky)> {
        let chol = Cholesky::new(&self.covariance(b2, k2), self.n)?;
        let mut basis = Basis::default();
        let mut log_det_x = 0.0;
        for col in x {
            let mut v = col.clone();
            chol.whiten(&mut v);
            let before = dot(&v, &v);
            let mut r = v.clone();
            basis.residual(&mut r);
            let after = dot(&r, &r);
            if basis.push(v) {
                log_det_x += after.max(1e-300).ln();
            } else {
                let _ = before;
            }
        }
        let mut w = y.to_vec();
        chol.whiten(&mut w);
        basis.residual(&mut w);
        Some((chol.log_det() + log_det_x + dot(&w, &w), chol))
    }

    /// REML estimates of `B^2` and `K^2` for `y` under the mean model `x`.
    pub fn fit(&self, y: &[f64], x: &[Vec<f64>], span_s: f64) -> Option<Fitted> {
        let (var, k_scale) = Noise::scales(y, span_s);
        let f = |b2: f64, k2: f64| self.reml(y, x, b2, k2).map_or(f64::INFINITY, |r| r.0);
        let (mut b2, mut k2) = (0.0, 0.0);
        for _ in 0..2 {
            b2 = best_scale(|v| f(v, k2), var);
            k2 = best_scale(|v| f(b2, v), k_scale);
        }
        let (_, chol) = self.reml(y, x, b2, k2)?;
        Some(Fitted { b2, k2, chol })
    }
}

/// The value in `{0} U [1e-6, 1e4] * scale` minimising `f` (golden section on
/// the log scale after a coarse grid).
fn best_scale(f: impl Fn(f64) -> f64 + Sync, scale: f64) -> f64 {
    let (lo, hi) = ((1e-6f64).ln(), (1e4f64).ln());
    let grid: Vec<f64> = (0..=20).map(|i| lo + (hi - lo) * i as f64 / 20.0).collect();
    let vals: Vec<f64> = par_map(&grid, |&u| f(scale * u.exp()));
    let i = (0..vals.len())
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(0);
    let (a, b) = (grid[i.saturating_sub(1)], grid[(i + 1).min(grid.len() - 1)]);
    // 14 steps leave a bracket 1e-3 of a grid step wide (0.1 % in the variance)
    let (u, fu) = golden_min(|u| f(scale * u.exp()), a, b, 14);
    if f(0.0) <= fu { 0.0 } else { scale * u.exp() }
}

/// Golden-section search for the minimum of a unimodal `f` on `[a, b]`:
/// after `iters` steps, the better of the last two interior points and its value.
pub fn golden_min(
    mut f: impl FnMut(f64) -> f64,
    mut a: f64,
    mut b: f64,
    iters: usize,
) -> (f64, f64) {
    let g = 0.618_033_988_749_894_9;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { (c, fc) } else { (d, fd) }
}

/// Sample variance (n - 1).
pub fn variance(y: &[f64]) -> f64 {
    let n = y.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let m = y.iter().sum::<f64>() / n;
    y.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_differences_have_the_terms_allan_variances() {
        let c = Coarse {
            block_s: 10.0,
            y: vec![0.0; 50],
            n: vec![10_000; 50],
            tau0_s: 0.001,
        };
        let fine = FineNoise {
            arw_dpsh: 0.01,
            quantization_arcsec: 0.0,
        };
        let noise = Noise::new(&c, fine);
        let n = c.len();
        let avar = |s: &[f64], a: usize| {
            0.5 * (s[a * n + a] + s[(a + 1) * n + a + 1] - 2.0 * s[a * n + a + 1])
        };
        // flicker: the plateau (2 ln 2 / pi) B^2
        let s = noise.covariance(1.0, 0.0);
        let want = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;
        let white = (60.0f64 * 0.01).powi(2) / 10.0;
        for a in [0, 10, 40] {
            assert!(
                (avar(&s, a) - white - want).abs() < 1e-9 * want,
                "{}",
                avar(&s, a)
            );
        }
        // rate random walk: K^2 tau / 3 with K per sqrt(s) = K / 60
        let s = noise.covariance(0.0, 1.0);
        let want = 10.0 / 3.0 / 3600.0;
        for a in [0, 10, 40] {
            assert!((avar(&s, a) - white - want).abs() < 1e-9, "{}", avar(&s, a));
        }
    }
}
