//! A resonance: narrowband rate noise, a damped oscillator driven by white
//! noise (a mechanical mode of the sense element, a bench vibration whose
//! frequency wanders). Defined in discrete time at the sample rate as the
//! stationary AR(2) process
//!
//! `x_k = a1 x_{k-1} + a2 x_{k-2} + e_k`, poles `r exp(+-i theta)`,
//! `theta = 2 pi f0 tau0`, `r = exp(-pi w tau0)`,
//!
//! whose impulse response rings at `f0` and decays as `exp(-pi w t)`: its
//! spectrum is a Lorentzian of full width at half power `w` about `f0` when
//! `w << f0` (quality factor `f0 / w`). The variance of `x` is `sigma^2`. The
//! simulator, the Allan variance and the spectra all use this one definition,
//! so the model's statistics are exact for what it simulates.

use std::f64::consts::PI;

use rustfft::num_complex::Complex64;

/// The AR(2) coefficients of a resonance, per unit stationary variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ar2 {
    pub a1: f64,
    pub a2: f64,
    /// Innovation variance that gives the process unit variance.
    pub innov_var: f64,
    /// Pole radius and angle (rad per sample).
    pub r: f64,
    pub theta: f64,
}

impl Ar2 {
    /// The process of centre `centre_hz` and width `width_hz` at sample period
    /// `tau0_s` (the caller checks `0 < centre < 1/(2 tau0)` and `width > 0`).
    pub fn new(centre_hz: f64, width_hz: f64, tau0_s: f64) -> Ar2 {
        Ar2::from_nu(centre_hz * tau0_s, width_hz * tau0_s)
    }

    /// The process from its centre and width in cycles per sample.
    pub fn from_nu(centre_nu: f64, width_nu: f64) -> Ar2 {
        let theta = 2.0 * PI * centre_nu;
        let r = (-PI * width_nu).exp();
        let (a1, a2) = (2.0 * r * theta.cos(), -r * r);
        let c = theta.cos();
        let r2 = r * r;
        // gamma0 / innovation variance of an AR(2)
        let g0 = (1.0 + r2) / ((1.0 - r2) * ((1.0 + r2).powi(2) - 4.0 * r2 * c * c));
        Ar2 {
            a1,
            a2,
            innov_var: 1.0 / g0,
            r,
            theta,
        }
    }

    /// One-sided PSD per unit variance, per (cycle/sample), from `c = cos(2 pi nu)`.
    pub fn psd_cs_cos(&self, c: f64) -> f64 {
        let (a1, a2) = (self.a1, self.a2);
        let d =
            1.0 + a1 * a1 + a2 * a2 - 2.0 * a1 * (1.0 - a2) * c - 2.0 * a2 * (2.0 * c * c - 1.0);
        2.0 * self.innov_var / d
    }

    /// Autocorrelation at lag `k` (`rho(0) = 1`).
    pub fn autocorr(&self, k: u64) -> f64 {
        let kf = k as f64;
        self.r.powf(kf) * ((kf * self.theta).cos() + self.c_sin() * (kf * self.theta).sin())
    }

    /// `C` of `rho(k) = r^k (cos k theta + C sin k theta)`.
    fn c_sin(&self) -> f64 {
        let r2 = self.r * self.r;
        (1.0 - r2) / ((1.0 + r2) * self.theta.tan())
    }

    /// Variance of the sum of `m` consecutive samples per unit variance,
    /// `sum_{|k|<m} (m - |k|) rho(k)` in closed form (`m` may be fractional).
    fn sum_var(&self, m: f64) -> f64 {
        let z = Complex64::from_polar(self.r, self.theta);
        let one = Complex64::new(1.0, 0.0);
        let zm1 = Complex64::from_polar(self.r.powf(m + 1.0), self.theta * (m + 1.0));
        let s = (m - (m + 1.0) * z + zm1) / ((one - z) * (one - z)) - m;
        let w = Complex64::new(1.0, -self.c_sin());
        m + 2.0 * (w * s).re
    }

    /// Overlapping Allan variance per unit variance at averaging factor `m`
    /// (tau = m tau0): `(4 V(m) - V(2m)) / (2 m^2)`, `V` the variance of an
    /// `m`-sample sum.
    pub fn unit_avar(&self, m: f64) -> f64 {
        (4.0 * self.sum_var(m) - self.sum_var(2.0 * m)) / (2.0 * m * m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ar() -> Ar2 {
        Ar2::new(19.0, 1.5, 0.01)
    }

    #[test]
    fn autocorrelation_follows_the_recursion() {
        let a = ar();
        for k in 2..40 {
            let rec = a.a1 * a.autocorr(k - 1) + a.a2 * a.autocorr(k - 2);
            assert!((rec - a.autocorr(k)).abs() < 1e-12, "lag {k}");
        }
        // Yule-Walker: rho(1) = a1 / (1 - a2)
        assert!((a.autocorr(1) - a.a1 / (1.0 - a.a2)).abs() < 1e-12);
    }

    #[test]
    fn psd_integrates_to_the_variance() {
        let a = ar();
        let n = 200_000;
        let h = 0.5 / n as f64;
        let total: f64 = (0..n)
            .map(|i| a.psd_cs_cos((2.0 * PI * (i as f64 + 0.5) * h).cos()) * h)
            .sum();
        assert!((total - 1.0).abs() < 1e-6, "{total}");
    }

    #[test]
    fn closed_form_avar_matches_the_direct_sums() {
        let a = ar();
        for m in [1u64, 2, 3, 7, 20, 133] {
            let v = |n: u64| -> f64 {
                (1..n)
                    .map(|k| 2.0 * (n - k) as f64 * a.autocorr(k))
                    .sum::<f64>()
                    + n as f64
            };
            let direct = (4.0 * v(m) - v(2 * m)) / (2.0 * (m * m) as f64);
            let closed = a.unit_avar(m as f64);
            assert!(
                (closed / direct - 1.0).abs() < 1e-9,
                "m {m}: {closed} vs {direct}"
            );
        }
        // one sample: half the mean square of a first difference, 1 - rho(1)
        assert!((a.unit_avar(1.0) - (1.0 - a.autocorr(1))).abs() < 1e-12);
    }

    #[test]
    fn half_power_width_is_the_width() {
        // a narrow resonance: the PSD falls to half its peak at f0 +- w/2
        let a = Ar2::new(20.0, 0.5, 0.01);
        let p = |f: f64| a.psd_cs_cos((2.0 * PI * f * 0.01).cos());
        let peak = p(20.0);
        let half = 0.5 * (p(19.75) + p(20.25)) / peak;
        assert!((half - 0.5).abs() < 0.01, "{half}");
    }
}
