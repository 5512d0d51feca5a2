//! Test-side helpers for the `dsp` tests: a minimal seeded RLG simulator and a plain
//! overlapping Allan deviation (NIST SP 1065 on phase).
//!
//! These stand in for the project's simulator and Allan engine (being written in
//! other modules) so the `dsp` tests stay self-contained; the lead may swap them.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// A static ring-laser-gyro run. Units: arcsec, seconds; rates in arcsec/s (= deg/h).
#[derive(Debug, Clone)]
pub struct GyroSim {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Pulse weight d (angle per counter step), arcsec.
    pub pulse_arcsec: f64,
    /// Constant input rate (earth rate component + bias), deg/h.
    pub rate_dph: f64,
    /// Angle random walk N, deg/sqrt(h).
    pub arw_dpsh: f64,
    /// Bias instability B, deg/h (flicker rate noise; AVAR plateau (2 ln2/pi) B^2).
    pub bi_dph: f64,
    /// Total quantization noise Q, arcsec: the white angle error ("dither residual")
    /// added before the counter is sized so that Q^2 = d^2/12 + sigma_dither^2.
    pub quantization_arcsec: f64,
    /// RNG seed.
    pub seed: u64,
}

/// What a simulation returns, all per sample (length n).
#[derive(Debug, Clone)]
pub struct SimRun {
    /// Counter increments (pulses per sample).
    pub counts: Vec<i64>,
    /// Raw rate from the counts, arcsec/s: `counts * d / tau0`.
    pub raw: Vec<f64>,
    /// The rate without quantization noise, arcsec/s: `(theta_k - theta_{k-1}) / tau0`
    /// of the true angle (constant rate + ARW + BI).
    pub truth: Vec<f64>,
}

/// Bias-instability flicker model: `BI_COMPONENTS` first-order Gauss-Markov
/// processes with time constants 0.3 s ... 3e4 s, two per decade, each of variance
/// `B^2 ln(r) / (2 pi)` (r = sqrt 10), whose PSDs sum to about `B^2 / (2 pi f)`,
/// IEEE 952's flicker with AVAR plateau `(2 ln2 / pi) B^2`. Updated every
/// `BI_STEP` samples and held in between.
const BI_T_MIN_S: f64 = 0.3;
const BI_COMPONENTS: usize = 11;
const BI_STEP: usize = 10;

fn bi_components(bi: f64) -> Vec<(f64, f64)> {
    let r = 10f64.sqrt();
    let var = bi * bi * r.ln() / (2.0 * std::f64::consts::PI);
    (0..BI_COMPONENTS)
        .map(|k| (BI_T_MIN_S * r.powi(k as i32), var))
        .collect()
}

/// Exact Allan variance of a continuous first-order Gauss-Markov process of
/// variance `var` and time constant `t`, at averaging time `tau`.
fn gm_avar(var: f64, t: f64, tau: f64) -> f64 {
    let x = tau / t;
    // AVAR = (var T^2 / tau^2) (2 tau/T - 3 + 4 e^{-tau/T} - e^{-2 tau/T})
    var / (x * x) * (2.0 * x - 3.0 + 4.0 * (-x).exp() - (-2.0 * x).exp())
}

impl GyroSim {
    /// The paper's gyro (28 cm RLG, 1 kHz, d = 1.21"), static, with the given Q, N, B.
    pub fn paper(quantization_arcsec: f64, arw_dpsh: f64, bi_dph: f64, seed: u64) -> GyroSim {
        GyroSim {
            sample_rate_hz: 1000.0,
            pulse_arcsec: 1.21,
            rate_dph: 10.6,
            arw_dpsh,
            bi_dph,
            quantization_arcsec,
            seed,
        }
    }

    /// White angle error added before quantization, arcsec.
    pub fn sigma_dither(&self) -> f64 {
        let d2 = self.pulse_arcsec * self.pulse_arcsec / 12.0;
        (self.quantization_arcsec * self.quantization_arcsec - d2)
            .max(0.0)
            .sqrt()
    }

    /// The true Allan variance of the non-QN part (ARW + BI), (arcsec/s)^2.
    pub fn true_avar_arw_bi(&self, tau_s: f64) -> f64 {
        let n = self.arw_dpsh * 60.0;
        let bi: f64 = bi_components(self.bi_dph)
            .iter()
            .map(|&(t, v)| gm_avar(v, t, tau_s))
            .sum();
        n * n / tau_s + bi
    }

    /// The IEEE 952 QN Allan variance, 3 Q^2 / tau^2.
    pub fn qn_avar(&self, tau_s: f64) -> f64 {
        3.0 * self.quantization_arcsec * self.quantization_arcsec / (tau_s * tau_s)
    }

    /// Simulate `n` samples.
    pub fn simulate(&self, n: usize) -> SimRun {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let tau0 = 1.0 / self.sample_rate_hz;
        let d = self.pulse_arcsec;
        let arw_step = self.arw_dpsh * 60.0 * tau0.sqrt(); // angle increment std, arcsec
        let sig_d = self.sigma_dither();
        let comps = bi_components(self.bi_dph);
        let step_s = BI_STEP as f64 * tau0;
        let phis: Vec<f64> = comps.iter().map(|&(t, _)| (-step_s / t).exp()).collect();
        let mut bi_state: Vec<f64> = comps
            .iter()
            .map(|&(_, v)| v.sqrt() * rng.sample::<f64, _>(StandardNormal))
            .collect();
        let mut bi_rate: f64 = bi_state.iter().sum();
        let mut theta = rng.random::<f64>() * d; // random initial fringe phase
        let angle_meas = |theta: f64, rng: &mut ChaCha8Rng| {
            let dn: f64 = if sig_d > 0.0 {
                sig_d * rng.sample::<f64, _>(StandardNormal)
            } else {
                0.0
            };
            ((theta + dn) / d).floor() as i64
        };
        let mut c_prev = angle_meas(theta, &mut rng);
        let mut run = SimRun {
            counts: Vec::with_capacity(n),
            raw: Vec::with_capacity(n),
            truth: Vec::with_capacity(n),
        };
        for k in 0..n {
            if k % BI_STEP == 0 && !comps.is_empty() {
                bi_rate = 0.0;
                for (i, &(_, v)) in comps.iter().enumerate() {
                    let w: f64 = rng.sample(StandardNormal);
                    bi_state[i] =
                        phis[i] * bi_state[i] + (v * (1.0 - phis[i] * phis[i])).sqrt() * w;
                    bi_rate += bi_state[i];
                }
            }
            let w: f64 = rng.sample(StandardNormal);
            let dtheta = (self.rate_dph + bi_rate) * tau0 + arw_step * w;
            theta += dtheta;
            let c = angle_meas(theta, &mut rng);
            let dc = c - c_prev;
            c_prev = c;
            run.counts.push(dc);
            run.raw.push(dc as f64 * d / tau0);
            run.truth.push(dtheta / tau0);
        }
        run
    }
}

/// Overlapping Allan deviation (NIST SP 1065 eq. 11) of rate samples `y` (sample
/// period `tau0`) at averaging factor `m`, computed on phase
/// `x[0] = 0, x[k+1] = x[k] + (y[k] - mean) tau0`.
pub fn oadev(y: &[f64], tau0: f64, m: usize) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let mut x = Vec::with_capacity(y.len() + 1);
    x.push(0.0);
    let mut acc = 0.0;
    for &v in y {
        acc += (v - mean) * tau0;
        x.push(acc);
    }
    let n = x.len();
    assert!(n > 2 * m, "record too short for m = {m}");
    let mut s = 0.0;
    for i in 0..n - 2 * m {
        let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
        s += d * d;
    }
    let tau = m as f64 * tau0;
    (s / (2.0 * (n - 2 * m) as f64 * tau * tau)).sqrt()
}
