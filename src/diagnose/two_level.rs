//! The two-level likelihood ratio: the statistic that tells a random
//! telegraph (mode hops between +a and -a, mean dwell T) from the
//! Gauss-Markov bias with the same spectrum (sigma = a, Tc = T/2).
//!
//! The rate is reduced by the sym8 low-pass cascade (which keeps most of the
//! quantization noise out) to blocks of about T/6, and the log
//! likelihood of the block series is computed twice with the term's own
//! parameters and a white background:
//! * as a two-state hidden Markov chain, levels +-a, switching with
//!   probability `(1 - phi) / 2` per block (forward algorithm);
//! * as an AR(1) with `phi = exp(-2 dt / T)` and variance a^2 (Kalman filter).
//!
//! Their difference is the Neyman-Pearson statistic of the two hypotheses.
//! With every parameter known it is the most powerful test there is
//! (`scripts/telegraph-oracle` measures that ceiling); here the background
//! level is read from the series' first differences and the statistic is
//! referenced to Monte-Carlo runs of both models, so its false-alarm rate
//! does not rest on those approximations.

use super::stats::dwt_approximation;

/// The term the statistic is evaluated for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoLevelProbe {
    /// Level (telegraph amplitude = Gauss-Markov sigma), arcsec/s.
    pub amp: f64,
    /// Mean dwell (= 2 Tc), s.
    pub mean_dwell_s: f64,
}

/// Blocks per mean dwell (to the nearest octave). Finer blocks add nothing the test can
/// use (the oracle's power is the same from T/40 to T/4,
/// `scripts/telegraph-oracle`), while the quantization noise that leaks
/// through the sym8 cascade grows quickly at finer levels: on a 200 Hz, 1"
/// counter (ARW 0.002 deg/sqrt(h)) with a 10 s dwell the background of
/// 0.32 s blocks is 7 times the ARW's variance, against 1.4 times for 1.28 s
/// blocks, and the separation of a 0.06 deg/h telegraph from its twin over
/// 12 records each grows from 1.1 to 4.9 sd.
const BLOCKS_PER_DWELL: f64 = 6.0;

/// Fewest blocks for a statistic.
const MIN_BLOCKS: usize = 32;

impl TwoLevelProbe {
    /// Sym8 level of the block series for samples of `tau0_s`: the one whose
    /// spacing is nearest (in ratio) to a sixth of the mean dwell, so that a
    /// dwell fitted a little short or long does not jump an octave.
    pub fn level(&self, tau0_s: f64) -> u32 {
        let target = self.mean_dwell_s / (BLOCKS_PER_DWELL * tau0_s);
        target.log2().round().max(0.0) as u32
    }

    /// Block spacing, s.
    pub fn block_s(&self, tau0_s: f64) -> f64 {
        tau0_s * 2f64.powi(self.level(tau0_s) as i32)
    }

    /// `log L(telegraph) - log L(Gauss-Markov)` of `rate` (arcsec/s, one
    /// value per `tau0_s`), with `lo` the sym8 low-pass filter. NaN when the
    /// record holds fewer than [`MIN_BLOCKS`] blocks or the probe is empty.
    pub fn llr(&self, rate: &[f64], tau0_s: f64, lo: &[f64]) -> f64 {
        if !(self.amp > 0.0 && self.mean_dwell_s > 0.0) {
            return f64::NAN;
        }
        let y = dwt_approximation(rate, lo, self.level(tau0_s));
        self.llr_of(y, tau0_s)
    }

    /// [`TwoLevelProbe::llr`] from the rate's approximation coefficients at
    /// [`TwoLevelProbe::level`].
    pub fn llr_of(&self, mut y: Vec<f64>, tau0_s: f64) -> f64 {
        if !(self.amp > 0.0 && self.mean_dwell_s > 0.0) {
            return f64::NAN;
        }
        let level = self.level(tau0_s);
        let dt = self.block_s(tau0_s);
        let scale = 2f64.powf(-(level as f64) / 2.0);
        if y.len() < MIN_BLOCKS {
            return f64::NAN;
        }
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        y.iter_mut().for_each(|v| *v = (*v - mean) * scale);
        let phi = (-2.0 * dt / self.mean_dwell_s).exp();
        let a2 = self.amp * self.amp;
        let var_e = background_variance(&y, a2, phi);
        hmm_loglik(&y, self.amp, phi, var_e) - ar1_loglik(&y, a2, phi, var_e)
    }
}

/// White background variance from first differences: `E (dy)^2 = 2 var_e +
/// 2 a^2 (1 - phi)` under either hypothesis; floored at a thousandth of a^2.
fn background_variance(y: &[f64], a2: f64, phi: f64) -> f64 {
    let d2 = y.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (y.len() - 1) as f64;
    (0.5 * d2 - a2 * (1.0 - phi)).max(1e-3 * a2)
}

/// Log likelihood of `y` as `a s_k + e_k`, `s_k = +-1` a symmetric Markov
/// chain that switches with probability `(1 - phi) / 2`, `e` white of
/// variance `var_e` (forward algorithm, scaled).
pub fn hmm_loglik(y: &[f64], a: f64, phi: f64, var_e: f64) -> f64 {
    let p = 0.5 * (1.0 - phi);
    let c = -0.5 * (2.0 * std::f64::consts::PI * var_e).ln();
    let (mut fu, mut fd) = (0.5, 0.5);
    let mut ll = 0.0;
    for (k, &v) in y.iter().enumerate() {
        if k > 0 {
            (fu, fd) = ((1.0 - p) * fu + p * fd, p * fu + (1.0 - p) * fd);
        }
        // emission densities relative to the nearer level (no underflow)
        let (eu, ed) = ((v - a).powi(2), (v + a).powi(2));
        let m = eu.min(ed);
        fu *= (-0.5 * (eu - m) / var_e).exp();
        fd *= (-0.5 * (ed - m) / var_e).exp();
        let tot = fu + fd;
        ll += tot.ln() + c - 0.5 * m / var_e;
        fu /= tot;
        fd /= tot;
    }
    ll
}

/// Log likelihood of `y` as a stationary AR(1) of variance `a2` and
/// coefficient `phi` plus white noise of variance `var_e` (Kalman filter).
pub fn ar1_loglik(y: &[f64], a2: f64, phi: f64, var_e: f64) -> f64 {
    let q = a2 * (1.0 - phi * phi);
    let (mut m, mut p) = (0.0, a2);
    let mut ll = 0.0;
    for (k, &v) in y.iter().enumerate() {
        if k > 0 {
            m *= phi;
            p = phi * phi * p + q;
        }
        let s = p + var_e;
        let r = v - m;
        ll -= 0.5 * ((2.0 * std::f64::consts::PI * s).ln() + r * r / s);
        let g = p / s;
        m += g * r;
        p *= 1.0 - g;
    }
    ll
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// Block series of both hypotheses with known parameters.
    fn series(telegraph: bool, a: f64, phi: f64, sd_e: f64, n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let e = Normal::new(0.0, sd_e).unwrap();
        let w = Normal::new(0.0, a * (1.0 - phi * phi).sqrt()).unwrap();
        let mut s = if telegraph {
            a
        } else {
            Normal::new(0.0, a).unwrap().sample(&mut rng)
        };
        (0..n)
            .map(|_| {
                s = if telegraph {
                    if rng.random::<f64>() < 0.5 * (1.0 - phi) {
                        -s
                    } else {
                        s
                    }
                } else {
                    phi * s + w.sample(&mut rng)
                };
                s + e.sample(&mut rng)
            })
            .collect()
    }

    /// With no background the chain's likelihood is exact: one switch in a
    /// two-sample series costs ln(p) against ln(1 - p).
    #[test]
    fn the_forward_algorithm_matches_a_hand_computed_chain() {
        let (a, phi, var_e) = (1.0, 0.6, 0.04);
        let p: f64 = 0.2;
        let y = [1.0, -1.0];
        let g = |x: f64, m: f64| (-(x - m).powi(2) / (2.0 * var_e)).exp();
        let c = (2.0 * std::f64::consts::PI * var_e).sqrt();
        let lik = 0.5 * g(1.0, 1.0) * (p * g(-1.0, -1.0) + (1.0 - p) * g(-1.0, 1.0))
            + 0.5 * g(1.0, -1.0) * (p * g(-1.0, 1.0) + (1.0 - p) * g(-1.0, -1.0));
        let want = (lik / (c * c)).ln();
        assert!((hmm_loglik(&y, a, phi, var_e) - want).abs() < 1e-12);
    }

    /// The Kalman likelihood equals the Gaussian density of the series with
    /// covariance a^2 phi^|i-j| + var_e delta_ij (two samples, closed form).
    #[test]
    fn the_kalman_filter_matches_the_joint_gaussian_density() {
        let (a2, phi, var_e) = (2.0, 0.7, 0.5);
        let y = [0.3, -1.1];
        let (s11, s12): (f64, f64) = (a2 + var_e, a2 * phi);
        let det = s11 * s11 - s12 * s12;
        let quad = (s11 * y[0] * y[0] - 2.0 * s12 * y[0] * y[1] + s11 * y[1] * y[1]) / det;
        let want = -(2.0 * std::f64::consts::PI).ln() - 0.5 * det.ln() - 0.5 * quad;
        assert!((ar1_loglik(&y, a2, phi, var_e) - want).abs() < 1e-12);
    }

    /// With the background averaged over one dwell at half the level, the
    /// ratio separates the hypotheses: over 40 series each, at least 36
    /// telegraphs lie above the 95th percentile of their Gauss-Markov twins.
    #[test]
    fn the_ratio_is_larger_for_a_telegraph_than_for_its_gauss_markov_twin() {
        let (a, dwell_blocks, n) = (1.0, 16.0_f64, 4000);
        let phi = (-2.0 / dwell_blocks).exp();
        let sd_e = 2.0 * a; // 0.5 a over a dwell of 16 blocks
        let stat = |y: &[f64]| {
            let a2 = a * a;
            let v = background_variance(y, a2, phi);
            hmm_loglik(y, a, phi, v) - ar1_loglik(y, a2, phi, v)
        };
        let mut gm: Vec<f64> = (0..40)
            .map(|s| stat(&series(false, a, phi, sd_e, n, s)))
            .collect();
        gm.sort_by(f64::total_cmp);
        let thr = gm[37];
        let above = (0..40)
            .filter(|&s| stat(&series(true, a, phi, sd_e, n, 100 + s)) > thr)
            .count();
        assert!(
            above >= 36,
            "{above}/40 telegraphs above the twin's 95th percentile"
        );
    }
}
