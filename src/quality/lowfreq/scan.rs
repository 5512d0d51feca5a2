//! Likelihood-ratio scans for the slow effects, with the noise refitted
//! under each alternative, calibrated on the fitted noise.
//!
//! Each effect is a regressor of the block means with a shape parameter: a
//! warm-up `exp(-t/tau)` (over a grid of `tau`), a bias step at `t0` (each
//! block boundary), a thermal response `T(t - lag)` (over a grid of lags).
//! A rate random walk absorbs much of any slow effect when its coefficient is
//! fitted without the effect, so the test compares the two models each at its
//! own best noise: on a grid of flicker and random-walk coefficients
//! ([`NoiseGrid`]) around the null model's REML estimates, the (full, not
//! restricted: REML likelihoods of different mean models do not compare)
//! likelihood of the data with and without the regressor is computed at
//! every grid point (one Cholesky factor per point serves every candidate),
//! and the likelihood ratio is the difference of the two maxima over the
//! grid. A scan takes the largest over its candidates.
//!
//! The scan's null distribution is simulated from the null model (fixed
//! seed, so a record always gets the same answer); its 90th percentile is
//! read as the maximum of `M` independent chi-square(1) variables, and the
//! threshold set where that maximum exceeds with probability `alpha` (per
//! scan and record).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::super::gls::{Basis, Cholesky, dot};
use super::model::Noise;
use crate::par::par_map;

/// Null replicas per threshold.
const REPLICAS: usize = 160;

/// One grid point: the factor, the whitened mean model, and the constant
/// part of its likelihood (`ln det Sigma`).
struct Point {
    chol: Cholesky,
    basis: Basis,
    constant: f64,
}

/// The noise grid for one mean model.
pub struct NoiseGrid {
    points: Vec<Point>,
    n: usize,
}

/// A scan's candidates at every grid point: `ln |x_perp|^2` and the unit
/// vector of the whitened, projected regressor.
pub struct Scan {
    /// The shape parameter of each candidate.
    pub params: Vec<f64>,
    /// `[candidate][grid point]`: (ln norm^2, unit vector; empty when in the span).
    units: Vec<Vec<(f64, Vec<f64>)>>,
}

impl NoiseGrid {
    /// The grid about the null estimates `b2`, `k2` (each also at zero).
    pub fn new(
        noise: &Noise,
        x: &[Vec<f64>],
        b2: f64,
        k2: f64,
        scale_b: f64,
        scale_k: f64,
    ) -> NoiseGrid {
        let axis = |v: f64, scale: f64, down: f64| {
            let top = if v > 0.0 { 3.0 * v } else { 3.0 * scale };
            let mut a = vec![0.0];
            a.extend((0..7).map(|i| top * down.powf(i as f64 / 6.0)));
            a
        };
        let bs = axis(b2, scale_b, 1e-3);
        let ks = axis(k2, scale_k, 1e-4);
        let pairs: Vec<(f64, f64)> = bs
            .iter()
            .flat_map(|&b| ks.iter().map(move |&k| (b, k)))
            .collect();
        let points = par_map(&pairs, |&(b, k)| point(noise, x, b, k))
            .into_iter()
            .flatten()
            .collect();
        NoiseGrid {
            points,
            n: x.first().map_or(0, Vec::len),
        }
    }

    /// Whiten and project every candidate regressor at every grid point.
    pub fn scan(&self, params: Vec<f64>, columns: Vec<Vec<f64>>) -> Scan {
        let units = par_map(&columns, |col| {
            self.points
                .iter()
                .map(|p| {
                    let mut v = col.clone();
                    p.chol.whiten(&mut v);
                    p.basis.residual(&mut v);
                    let n2 = dot(&v, &v);
                    if n2 > 1e-18 {
                        let s = n2.sqrt();
                        v.iter_mut().for_each(|a| *a /= s);
                        (n2.ln(), v)
                    } else {
                        (0.0, Vec::new())
                    }
                })
                .collect()
        });
        Scan { params, units }
    }

    /// Per grid point: the whitened, projected data and its null criterion.
    fn residuals(&self, y: &[f64]) -> Vec<(Vec<f64>, f64)> {
        self.points
            .iter()
            .map(|p| {
                let mut w = y.to_vec();
                p.chol.whiten(&mut w);
                p.basis.residual(&mut w);
                let r0 = p.constant + dot(&w, &w);
                (w, r0)
            })
            .collect()
    }

    /// The largest likelihood ratio of the scan's candidates for `y`, and
    /// the index of its candidate.
    pub fn best(&self, scan: &Scan, y: &[f64]) -> Option<(usize, f64)> {
        best_of(scan, &self.residuals(y))
    }

    /// The null model's criterion for `y`: its smallest `-2 ln L` (up to a
    /// constant) over the grid's noise points.
    pub fn null_criterion(&self, y: &[f64]) -> f64 {
        self.residuals(y)
            .iter()
            .map(|r| r.1)
            .fold(f64::INFINITY, f64::min)
    }

    /// The level the scan's maximum exceeds with probability `alpha` when the
    /// data follow the null covariance `null` (see the module docs).
    pub fn threshold(&self, scan: &Scan, null: &Cholesky, alpha: f64, seed: u64) -> f64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = self.n;
        let draws: Vec<Vec<f64>> = (0..REPLICAS)
            .map(|_| (0..n).map(|_| StandardNormal.sample(&mut rng)).collect())
            .collect();
        let mut maxima = par_map(&draws, |z| {
            let y = null.color(z);
            best_of(scan, &self.residuals(&y)).map_or(0.0, |b| b.1)
        });
        maxima.sort_by(f64::total_cmp);
        let q90 = maxima[(REPLICAS * 9) / 10].max(1e-6);
        let chi = ChiSquared::new(1.0).expect("one degree of freedom");
        let f90 = chi.cdf(q90).clamp(1e-12, 1.0 - 1e-15);
        let m_eff = (0.9f64.ln() / f90.ln()).max(1.0);
        chi.inverse_cdf((1.0 - alpha).powf(1.0 / m_eff))
    }
}

/// The lowest threshold [`NoiseGrid::threshold`] can return: one chi-square(1)
/// test at level `alpha` (its effective number of tests is at least 1).
pub fn floor(alpha: f64) -> f64 {
    ChiSquared::new(1.0)
        .expect("one degree of freedom")
        .inverse_cdf(1.0 - alpha)
}

fn point(noise: &Noise, x: &[Vec<f64>], b2: f64, k2: f64) -> Option<Point> {
    let chol = Cholesky::new(&noise.covariance(b2, k2), noise.len())?;
    let mut basis = Basis::default();
    for col in x {
        let mut v = col.clone();
        chol.whiten(&mut v);
        basis.push(v);
    }
    Some(Point {
        constant: chol.log_det(),
        chol,
        basis,
    })
}

/// The best candidate given each grid point's residual and null criterion.
fn best_of(scan: &Scan, res: &[(Vec<f64>, f64)]) -> Option<(usize, f64)> {
    let null = res.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    scan.units
        .iter()
        .enumerate()
        .filter_map(|(i, per_point)| {
            let alt = per_point
                .iter()
                .zip(res)
                .filter(|(u, _)| !u.1.is_empty())
                .map(|((_, u), (w, r0))| r0 - dot(u, w).powi(2))
                .fold(f64::INFINITY, f64::min);
            alt.is_finite().then_some((i, (null - alt).max(0.0)))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::super::model::{Coarse, FineNoise};
    use super::*;

    #[test]
    fn a_step_is_found_and_pure_noise_stays_below_the_threshold() {
        let n = 80;
        let c = Coarse {
            block_s: 10.0,
            y: vec![0.0; n],
            n: vec![1000; n],
            tau0_s: 0.01,
        };
        let noise = Noise::new(
            &c,
            FineNoise {
                arw_dpsh: 0.1,
                quantization_arcsec: 0.0,
            },
        );
        let ones = vec![1.0; n];
        let x = vec![ones];
        let grid = NoiseGrid::new(&noise, &x, 0.0, 0.0, 1.0, 1.0);
        let steps: Vec<f64> = (2..n - 2).map(|b| b as f64).collect();
        let cols: Vec<Vec<f64>> = steps
            .iter()
            .map(|&j| {
                (0..n)
                    .map(|b| if b as f64 >= j { 1.0 } else { 0.0 })
                    .collect()
            })
            .collect();
        let scan = grid.scan(steps, cols);
        let null = Cholesky::new(&noise.covariance(0.0, 0.0), n).unwrap();
        let limit = grid.threshold(&scan, &null, 0.01, 7);
        // white block noise of sd (60 * 0.1)^2 / (1000 * 0.01) -> sd 1.9 deg/h
        let sd = ((6.0f64).powi(2) / 10.0).sqrt();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut y: Vec<f64> = (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sd * z
            })
            .collect();
        let (_, lr0) = grid.best(&scan, &y).unwrap();
        assert!(lr0 < limit, "{lr0} vs {limit}");
        for v in &mut y[50..] {
            *v += 3.0 * sd;
        }
        let (i, lr) = grid.best(&scan, &y).unwrap();
        assert!(
            lr > limit && scan.params[i] == 50.0,
            "{lr} {}",
            scan.params[i]
        );
    }
}
