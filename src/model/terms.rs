//! The noise-term library: every stochastic (and slow deterministic) error term of
//! a gyro with its IEEE 952 coefficient in user units, its one-sided rate PSD and
//! its closed-form Allan variance. The estimator fits these curves, the diagnosis
//! prints their physical explanations, and the simulator ([`super::sim`]) generates
//! exactly the processes described here, so simulated Allan variances match these
//! curves at every tau, including the shortest.
//!
//! # Conventions
//! * Internally rates are arcsec/s (= deg/h), angles arcsec, times s; the public
//!   constructors take the IEEE 952 coefficients in the units named by the field
//!   suffix (see [`crate::units`]).
//! * **PSDs are one-sided** rate PSDs in (arcsec/s)^2/Hz, i.e. twice the two-sided
//!   IEEE 952 expressions: ARW `2 N^2`, flicker `B^2/(pi f)`, RRW `K^2/(2 pi^2 f^2)`.
//!   With this convention the Allan variance is
//!   `AVAR(tau) = integral_0^inf S(f) * 2 sin^4(pi f tau)/(pi f tau)^2 df`.
//! * **Allan variance** is that of the angle samples `theta(k tau0)` at `tau = m tau0`
//!   (what a pulse counter measures). Because the gyro integrates the rate exactly
//!   and the Allan variance of angle samples at `tau = m tau0` only involves angle
//!   differences over multiples of tau, the continuous-time formulas hold exactly
//!   at every `tau = m tau0`, m >= 1: no discrete-time correction is needed for any
//!   term, and `avar` takes no `tau0`. Only the quantization-noise PSD depends on the
//!   sample period (white angle noise seen through the sampled first difference).
//! * **Bias instability** is 1/f ("flicker") rate noise with one-sided PSD
//!   `S(f) = B^2 / (pi f)` on a band `[f_lo, f_hi]` (`f_hi` may be infinite). Over an
//!   unbounded band its Allan variance is the IEEE 952 plateau `(2 ln 2 / pi) B^2`
//!   (Allan deviation `0.664 B`). [`flicker_avar`] gives the exact finite-band curve
//!   via cosine integrals. The simulator synthesises flicker with a [`FlickerBank`]
//!   (octave-spaced Gauss-Markov processes plus a white tail); the bank's exact Allan
//!   curve is [`FlickerBank::avar`], and it matches the ideal `[f_lo, inf)` curve to
//!   better than 7e-4 relative for `tau0 <= tau <= 1e-4 / f_lo` (tested).
//! * Every term's Allan variance is `coefficient^2 * unit_avar(tau)`, so an
//!   estimator can fit the squared coefficients by linear least squares once the
//!   shape parameters (correlation time, period, band) are fixed.

use std::f64::consts::{LN_2, PI};

use rustfft::num_complex::Complex64;

use super::resonance::Ar2;

use super::ModelError;
use crate::units;

/// Euler-Mascheroni constant.
pub const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// Default low band edge of the simulated flicker (1e-7 Hz: periods up to ~116 days).
pub const DEFAULT_FLICKER_F_LO_HZ: f64 = 1e-7;

/// The flicker bank's top corner, as a multiple of the sample rate (16 x Nyquist).
pub const FLICKER_TOP_PER_SAMPLE_RATE: f64 = 8.0;

/// Largest spacing of the flicker bank's corner frequencies, in octaves.
pub const FLICKER_OCTAVES_PER_NODE: f64 = 1.5;

// ---------------------------------------------------------------------------
// Special functions
// ---------------------------------------------------------------------------

/// Power series of `Cin(x) = integral_0^x (1 - cos t)/t dt` (accurate for |x| <= 4).
fn cin_series(x: f64) -> f64 {
    let x2 = x * x;
    // t_k = x^(2k) / (2k)!, sum (-1)^(k+1) t_k / (2k)
    let mut t = x2 / 2.0;
    let mut sum = 0.0;
    let mut k = 1u32;
    loop {
        let c = t / (2.0 * k as f64);
        if k % 2 == 1 {
            sum += c;
        } else {
            sum -= c;
        }
        if c <= 1e-17 * sum.abs() || k > 60 {
            return sum;
        }
        let kk = 2.0 * k as f64;
        t *= x2 / ((kk + 1.0) * (kk + 2.0));
        k += 1;
    }
}

/// `Ci(x)` for `x >= 2` from the continued fraction of `E1(i x)`
/// (`Ci(x) = -Re E1(ix)`), evaluated with the modified Lentz method.
fn ci_continued_fraction(x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = Complex64::new(1.0, x);
    let mut c = Complex64::new(1.0 / TINY, 0.0);
    let mut d = b.inv();
    let mut h = d;
    for k in 2..10_000u32 {
        let a = -(((k - 1) * (k - 1)) as f64);
        b.re += 2.0;
        d = (d * a + b).inv();
        c = b + c.inv() * a;
        let del = c * d;
        h *= del;
        if (del.re - 1.0).abs() + del.im.abs() < 1e-16 {
            break;
        }
    }
    let e1 = h * Complex64::new(x.cos(), -x.sin());
    -e1.re
}

/// The entire cosine integral `Cin(x) = integral_0^x (1 - cos t)/t dt`
/// (even in x; `Ci(x) = gamma + ln x - Cin(x)`).
pub fn cin(x: f64) -> f64 {
    let ax = x.abs();
    if ax <= 2.0 {
        cin_series(ax)
    } else {
        EULER_GAMMA + ax.ln() - ci_continued_fraction(ax)
    }
}

/// The cosine integral `Ci(x) = -integral_x^inf cos t / t dt`, for `x > 0`
/// (NaN for `x <= 0`).
pub fn ci(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        f64::NAN
    } else if x.is_infinite() {
        0.0
    } else if x <= 2.0 {
        EULER_GAMMA + x.ln() - cin_series(x)
    } else {
        ci_continued_fraction(x)
    }
}

/// `G(x) = integral_0^x sin^4(t)/t^3 dt`, the flicker Allan integral
/// (`G(inf) = ln 2`). Closed form:
/// `G(x) = -sin^4 x/(2x^2) + (sin 4x - 2 sin 2x)/(4x) + Cin(4x) - Cin(2x)`.
pub fn flicker_integral(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 0.0;
    }
    if x.is_infinite() {
        return LN_2;
    }
    if x < 1e-2 {
        // sin^4 t / t^3 = t - 2t^3/3 + t^5/5 - ...
        let x2 = x * x;
        return x2 * (0.5 - x2 * (1.0 / 6.0 - x2 / 30.0));
    }
    let s = x.sin();
    let s2 = s * s;
    let base = -s2 * s2 / (2.0 * x * x) + ((4.0 * x).sin() - 2.0 * (2.0 * x).sin()) / (4.0 * x);
    if x <= 0.5 {
        base + cin_series(4.0 * x) - cin_series(2.0 * x)
    } else {
        // Cin(4x) - Cin(2x) = ln 2 + Ci(2x) - Ci(4x)
        base + LN_2 + ci(2.0 * x) - ci(4.0 * x)
    }
}

/// `g(u) = 2u - 3 + 4 e^-u - e^-2u`, the Gauss-Markov Allan shape, with its
/// power series below u = 0.05 (the direct form cancels to `2u^3/3`).
fn gm_shape(u: f64) -> f64 {
    if u < 0.05 {
        // sum_{n>=3} (-1)^n (4 - 2^n) u^n / n!
        let mut sum = 0.0;
        let mut un_over_fact = u * u * u / 6.0;
        let mut two_n = 8.0;
        for n in 3..16u32 {
            let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * (4.0 - two_n) * un_over_fact;
            un_over_fact *= u / (n + 1) as f64;
            two_n *= 2.0;
        }
        sum
    } else {
        2.0 * u - 3.0 + 4.0 * (-u).exp() - (-2.0 * u).exp()
    }
}

// ---------------------------------------------------------------------------
// Closed-form Allan variances in internal units (arcsec, arcsec/s, s)
// ---------------------------------------------------------------------------

/// White angle noise (quantization) with coefficient `quantization_arcsec`: `3 Q^2 / tau^2`.
#[inline]
pub fn quantization_avar(quantization_arcsec: f64, tau_s: f64) -> f64 {
    3.0 * quantization_arcsec * quantization_arcsec / (tau_s * tau_s)
}

/// White rate noise (ARW) with `n` in arcsec/sqrt(s): `N^2 / tau`.
#[inline]
pub fn arw_avar(n_arcsec_sqrt_s: f64, tau_s: f64) -> f64 {
    n_arcsec_sqrt_s * n_arcsec_sqrt_s / tau_s
}

/// Flicker rate noise with one-sided PSD `b^2/(pi f)` on the band `[f_lo, f_hi]`
/// (`b` in arcsec/s; `f_hi` may be `f64::INFINITY`, `f_lo` may be 0):
/// `AVAR = (2 b^2 / pi) [G(pi f_hi tau) - G(pi f_lo tau)]` with [`flicker_integral`].
/// For `f_lo -> 0`, `f_hi -> inf` this is the plateau `(2 ln 2/pi) b^2`.
pub fn flicker_avar(b_arcsec_s: f64, tau_s: f64, f_lo_hz: f64, f_hi_hz: f64) -> f64 {
    let hi = flicker_integral(PI * f_hi_hz * tau_s);
    let lo = flicker_integral(PI * f_lo_hz * tau_s);
    2.0 * b_arcsec_s * b_arcsec_s / PI * (hi - lo)
}

/// Rate random walk with `k` in arcsec/s/sqrt(s): `K^2 tau / 3`.
#[inline]
pub fn rrw_avar(k_arcsec_s_sqrt_s: f64, tau_s: f64) -> f64 {
    k_arcsec_s_sqrt_s * k_arcsec_s_sqrt_s * tau_s / 3.0
}

/// Rate ramp with `r` in arcsec/s^2: `R^2 tau^2 / 2`.
#[inline]
pub fn rate_ramp_avar(r_arcsec_s2: f64, tau_s: f64) -> f64 {
    r_arcsec_s2 * r_arcsec_s2 * tau_s * tau_s / 2.0
}

/// First-order Gauss-Markov rate (autocovariance `sigma^2 e^{-|s|/Tc}`):
/// `AVAR = (sigma^2 Tc^2 / tau^2) (2u - 3 + 4 e^-u - e^-2u)`, `u = tau/Tc`.
///
/// Derivation: with the angle structure function `D(t) = E[(theta(t) - theta(0))^2]
/// = 2 sigma^2 Tc^2 (t/Tc - 1 + e^{-t/Tc})`, the Allan variance of angle samples is
/// `(4 D(tau) - D(2 tau)) / (2 tau^2)`. Limits: `sigma^2 (2/3) tau/Tc` (RRW-like,
/// `K^2 = 2 sigma^2/Tc`) for tau << Tc, `2 sigma^2 Tc / tau` (ARW-like) for tau >> Tc.
pub fn gauss_markov_avar(sigma_arcsec_s: f64, tau_c_s: f64, tau_s: f64) -> f64 {
    let r = tau_c_s / tau_s;
    sigma_arcsec_s * sigma_arcsec_s * r * r * gm_shape(tau_s / tau_c_s)
}

/// Sinusoidal rate `A sin(2 pi t/T + phi)` (any phase): `A^2 sin^4(x)/x^2`, `x = pi tau/T`.
pub fn sinusoid_avar(amplitude_arcsec_s: f64, period_s: f64, tau_s: f64) -> f64 {
    let x = PI * tau_s / period_s;
    let s = x.sin();
    amplitude_arcsec_s * amplitude_arcsec_s * s * s * s * s / (x * x)
}

/// Random telegraph rate (`+a`/`-a`, exponential dwell times with mean `dwell`).
/// Its autocovariance is `a^2 e^{-2|s|/dwell}`, so its Allan variance is exactly
/// [`gauss_markov_avar`] with `sigma = a` and `Tc = dwell / 2`.
pub fn random_telegraph_avar(amplitude_arcsec_s: f64, mean_dwell_s: f64, tau_s: f64) -> f64 {
    gauss_markov_avar(amplitude_arcsec_s, 0.5 * mean_dwell_s, tau_s)
}

/// One-sided PSD of a first-order Gauss-Markov rate: `4 sigma^2 Tc / (1 + (2 pi f Tc)^2)`.
#[inline]
pub fn gauss_markov_psd(sigma_arcsec_s: f64, tau_c_s: f64, f_hz: f64) -> f64 {
    let w = 2.0 * PI * f_hz * tau_c_s;
    4.0 * sigma_arcsec_s * sigma_arcsec_s * tau_c_s / (1.0 + w * w)
}

/// Allan variance of a pulse counter read at a **constant** input rate, with a white
/// Gaussian dither residual of standard deviation `dither_sigma_arcsec` added to the
/// angle before the counter (no other noise).
///
/// The readout error is a deterministic sawtooth of the angle, blurred by the dither.
/// Averaged over the uniformly visited sub-pulse phase, its autocovariance at a lag
/// whose angle advance is `delta` pulses (fractional part) is
/// `R(delta) = d^2 sum_n cos(2 pi n delta) exp(-4 pi^2 n^2 s^2) / (2 pi^2 n^2)`,
/// `s = sigma/d` (`R = d^2 (1/12 - delta(1-delta)/2)` without dither), and its
/// variance is `V = d^2/12 + sigma^2`. Hence
/// `AVAR(tau) = (6V - 8 R(delta_1) + 2 R(delta_2)) / (2 tau^2)` with
/// `delta_j = frac(j rate tau / d)`. Only when `s >~ 0.5` do the sums vanish and
/// the IEEE 952 white-angle form `3 Q^2/tau^2`, `Q^2 = V`, hold; for a small
/// dither residual the quantization Allan curve oscillates with tau (period
/// `d / rate`). Valid for `tau >= tau0` and a rate whose per-sample advance is
/// not a ratio of small integers of the pulse weight (equidistributed phase),
/// for records many periods `d/rate` long. Dither residuals below `1e-6 d` are
/// treated as zero (error below `2e-6 d^2` in R).
pub fn counter_readout_avar(
    pulse_arcsec: f64,
    dither_sigma_arcsec: f64,
    rate_dph: f64,
    tau_s: f64,
) -> f64 {
    let d = pulse_arcsec;
    let s = dither_sigma_arcsec / d;
    let rate = units::dph_to_arcsec_per_s(rate_dph);
    let cov = |delta: f64| -> f64 {
        let delta = delta - delta.floor();
        if s < 1e-6 {
            1.0 / 12.0 - delta * (1.0 - delta) / 2.0
        } else {
            let n_max = ((1.0 / s).ceil() as usize + 2).min(2_000_000);
            let mut sum = 0.0;
            for n in 1..=n_max {
                let nf = n as f64;
                let damp = (-4.0 * PI * PI * nf * nf * s * s).exp();
                if damp < 1e-18 {
                    break;
                }
                sum += (2.0 * PI * nf * delta).cos() * damp / (2.0 * PI * PI * nf * nf);
            }
            sum
        }
    };
    let adv = rate * tau_s / d;
    let v = 1.0 / 12.0 + s * s;
    d * d * (6.0 * v - 8.0 * cov(adv) + 2.0 * cov(2.0 * adv)) / (2.0 * tau_s * tau_s)
}

// ---------------------------------------------------------------------------
// The flicker synthesiser design
// ---------------------------------------------------------------------------

/// One first-order Gauss-Markov (Ornstein-Uhlenbeck) rate component.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GmComponent {
    /// Stationary standard deviation, arcsec/s.
    pub sigma_arcsec_s: f64,
    /// Correlation time, s.
    pub tau_c_s: f64,
}

/// The design of the simulator's flicker (bias-instability) generator: a sum of
/// Gauss-Markov processes with corner frequencies `f_j` spaced at most 1.5 octaves
/// apart from `f_lo` to `f_top`, plus white rate noise standing in for the
/// components above `f_top`.
///
/// Why it is 1/f: a GM component with corner `f_c` has PSD
/// `(2 sigma^2/(pi f_c)) / (1 + (f/f_c)^2)`. Integrating such Lorentzians over
/// `ln f_c` with weight `2 B^2 / (pi^2 f_c)` gives exactly `B^2/(pi f)` between
/// the edges; the bank is a quadrature of that integral in `ln f_c` with step
/// `h <= 1.5 ln 2` (equal weights `h`, Gregory end corrections `3/8, 7/6, 23/24`;
/// `sigma_j^2 = W_j B^2 / pi`). Poisson summation bounds the interior ripple of the
/// equal-weight rule by `4 exp(-pi^2/h)` = 3e-4. The components above `f_top` would
/// each add a flat `2 W B^2/(pi^2 f_c)` below their corner; their sum
/// `2 B^2 / (pi^2 f_top)` is added as white rate noise, so the PSD stays 1/f up to a
/// fraction of `f_top` instead of rolling off like an arctangent.
///
/// With `f_top = 8 fs` (16 x Nyquist; 26 components from 1e-7 Hz at 1 kHz) the
/// bank's Allan variance is within 7e-4 of the ideal `[f_lo, inf)` flicker for
/// `tau0 <= tau <= 1e-4/f_lo`, within 0.4 % up to `1e-3/f_lo` and within 3.5 % up to
/// `1e-2/f_lo` (the soft low corner); its PSD is within 0.3 % of `B^2/(pi f)` on
/// `[1000 f_lo, fs/2]` (all tested). Memory and cost per sample are constant (one
/// Gaussian draw per component), so the generator runs indefinitely.
#[derive(Debug, Clone, PartialEq)]
pub struct FlickerBank {
    b_arcsec_s: f64,
    f_lo_hz: f64,
    f_top_hz: f64,
    components: Vec<GmComponent>,
    white_psd: f64,
}

impl FlickerBank {
    /// A bank for bias instability `bias_instability_dph` (deg/h) from `f_lo_hz` to `f_top_hz`.
    pub fn new(bias_instability_dph: f64, f_lo_hz: f64, f_top_hz: f64) -> Result<Self, ModelError> {
        if !(bias_instability_dph.is_finite() && bias_instability_dph >= 0.0) {
            return Err(ModelError::invalid(
                "bias_instability_dph",
                bias_instability_dph,
                "must be finite and >= 0",
            ));
        }
        if !(f_lo_hz.is_finite() && f_lo_hz > 0.0) {
            return Err(ModelError::invalid(
                "bias_instability_f_lo_hz",
                f_lo_hz,
                "must be finite and > 0",
            ));
        }
        if !(f_top_hz.is_finite() && f_top_hz >= 2.0 * f_lo_hz) {
            return Err(ModelError::invalid(
                "flicker top corner (Hz)",
                f_top_hz,
                format!("must be finite and at least twice f_lo = {f_lo_hz}"),
            ));
        }
        let b = units::dph_to_arcsec_per_s(bias_instability_dph);
        let span = (f_top_hz / f_lo_hz).ln();
        let intervals = (span / (FLICKER_OCTAVES_PER_NODE * LN_2) - 1e-9)
            .ceil()
            .max(1.0) as usize;
        let h = span / intervals as f64;
        let nodes = intervals + 1;
        let components = (0..nodes)
            .map(|j| {
                let f_c = f_lo_hz * (h * j as f64).exp();
                // Gregory end corrections (3/8, 7/6, 23/24) when there are enough nodes,
                // else the plain trapezoid rule
                let from_end = j.min(nodes - 1 - j);
                let w = if nodes >= 6 {
                    h * match from_end {
                        0 => 3.0 / 8.0,
                        1 => 7.0 / 6.0,
                        2 => 23.0 / 24.0,
                        _ => 1.0,
                    }
                } else if from_end == 0 {
                    0.5 * h
                } else {
                    h
                };
                GmComponent {
                    sigma_arcsec_s: (w / PI).sqrt() * b,
                    tau_c_s: 1.0 / (2.0 * PI * f_c),
                }
            })
            .collect();
        Ok(FlickerBank {
            b_arcsec_s: b,
            f_lo_hz,
            f_top_hz,
            components,
            white_psd: 2.0 * b * b / (PI * PI * f_top_hz),
        })
    }

    /// The bank the simulator uses at `sample_rate_hz`: `f_top = 8 fs`.
    pub fn for_sample_rate(
        bias_instability_dph: f64,
        f_lo_hz: f64,
        sample_rate_hz: f64,
    ) -> Result<Self, ModelError> {
        Self::new(
            bias_instability_dph,
            f_lo_hz,
            FLICKER_TOP_PER_SAMPLE_RATE * sample_rate_hz,
        )
    }

    /// Bias instability B in deg/h.
    pub fn bias_instability_dph(&self) -> f64 {
        units::arcsec_per_s_to_dph(self.b_arcsec_s)
    }
    /// Low edge (lowest corner), Hz.
    pub fn f_lo_hz(&self) -> f64 {
        self.f_lo_hz
    }
    /// Top corner, Hz.
    pub fn f_top_hz(&self) -> f64 {
        self.f_top_hz
    }
    /// The Gauss-Markov components, slowest first.
    pub fn components(&self) -> &[GmComponent] {
        &self.components
    }
    /// One-sided PSD of the white tail, (arcsec/s)^2/Hz.
    pub fn white_psd(&self) -> f64 {
        self.white_psd
    }

    /// The bank's exact one-sided rate PSD, (arcsec/s)^2/Hz.
    pub fn psd(&self, f_hz: f64) -> f64 {
        self.white_psd
            + self
                .components
                .iter()
                .map(|c| gauss_markov_psd(c.sigma_arcsec_s, c.tau_c_s, f_hz))
                .sum::<f64>()
    }

    /// The exact Allan variance of what the simulator generates, (arcsec/s)^2.
    pub fn avar(&self, tau_s: f64) -> f64 {
        // white one-sided PSD S0 -> AVAR S0 / (2 tau)
        self.white_psd / (2.0 * tau_s)
            + self
                .components
                .iter()
                .map(|c| gauss_markov_avar(c.sigma_arcsec_s, c.tau_c_s, tau_s))
                .sum::<f64>()
    }
}

// ---------------------------------------------------------------------------
// The term catalog
// ---------------------------------------------------------------------------

/// One noise term with its parameters in user units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Term {
    /// Quantization noise (white angle), Q in arcsec.
    Quantization { quantization_arcsec: f64 },
    /// Angle random walk (white rate), N in deg/sqrt(h).
    AngleRandomWalk { arw_dpsh: f64 },
    /// Bias instability: 1/f rate noise `B^2/(pi f)` on `[f_lo_hz, f_hi_hz]`
    /// (`f_hi_hz` may be infinite). B in deg/h.
    BiasInstability {
        bias_instability_dph: f64,
        f_lo_hz: f64,
        f_hi_hz: f64,
    },
    /// Rate random walk, K in deg/h/sqrt(h).
    RateRandomWalk { rrw_dphsh: f64 },
    /// Rate ramp, R in deg/h/h.
    RateRamp { rate_ramp_dphh: f64 },
    /// First-order Gauss-Markov bias, sigma in deg/h, correlation time in s.
    GaussMarkov { sigma_dph: f64, tau_c_s: f64 },
    /// Sinusoidal bias, amplitude in deg/h, period in s.
    Sinusoid { amplitude_dph: f64, period_s: f64 },
    /// Random telegraph bias (+a / -a), amplitude in deg/h, mean dwell time in s.
    RandomTelegraph {
        amplitude_dph: f64,
        mean_dwell_s: f64,
    },
    /// Rate-word quantization of a rate-output gyro: rounding to a multiple of
    /// `rate_lsb_dps` (deg/s) at each sample of period `tau0_s`, white in *rate*
    /// with variance `lsb^2 / 12` per sample (an ARW-like term
    /// `N^2 = lsb^2 tau0 / 12`), not the white-angle QN of a pulse counter.
    RateQuantization { rate_lsb_dps: f64, tau0_s: f64 },
    /// A resonance: narrowband rate noise of standard deviation `sigma_dph`
    /// (deg/h) centred at `centre_hz` with half-power width `width_hz`, the
    /// sample-rate AR(2) process of [`crate::model::resonance`] (sample period
    /// `tau0_s`).
    Resonance {
        sigma_dph: f64,
        centre_hz: f64,
        width_hz: f64,
        tau0_s: f64,
    },
}

impl Term {
    /// Short machine name (matches the model-file keys).
    pub fn name(&self) -> &'static str {
        match self {
            Term::Quantization { .. } => "quantization",
            Term::AngleRandomWalk { .. } => "arw",
            Term::BiasInstability { .. } => "bias_instability",
            Term::RateRandomWalk { .. } => "rrw",
            Term::RateRamp { .. } => "rate_ramp",
            Term::GaussMarkov { .. } => "gauss_markov",
            Term::Sinusoid { .. } => "sinusoid",
            Term::RandomTelegraph { .. } => "random_telegraph",
            Term::RateQuantization { .. } => "rate_quantization",
            Term::Resonance { .. } => "resonance",
        }
    }

    /// A short physical explanation a test engineer recognises.
    pub fn explanation(&self) -> &'static str {
        match self {
            Term::Quantization { .. } => {
                "Quantization noise: the counter only registers whole fringes (pulses), so the angle is \
                 known to within one pulse weight; residual dither adds to it. White in angle: Allan \
                 slope -1, dominant at short averaging times. Its integral stays bounded."
            }
            Term::AngleRandomWalk { .. } => {
                "Angle random walk: white noise on the rate (spontaneous emission, random phase kicks at \
                 each dither lock-in crossing). The angle error grows as sqrt(t): Allan slope -1/2."
            }
            Term::BiasInstability { .. } => {
                "Bias instability: 1/f (flicker) wander of the bias, e.g. slow changes of the discharge, \
                 backscatter and electronics. Flat floor of the Allan deviation at about 0.664 B."
            }
            Term::RateRandomWalk { .. } => {
                "Rate random walk: the bias itself random-walks with no restoring force (slow thermal or \
                 ageing drift). Allan slope +1/2 at long averaging times."
            }
            Term::RateRamp { .. } => {
                "Rate ramp: a steady bias drift over the run (warm-up, a temperature trend, a slowly \
                 changing input). Allan slope +1."
            }
            Term::GaussMarkov { .. } => {
                "Gauss-Markov bias: a bias that wanders but is pulled back with correlation time Tc \
                 (e.g. thermal coupling through a time constant). Looks like rate random walk below Tc \
                 and like white rate noise well above it; the Allan deviation has a hump near 1.9 Tc."
            }
            Term::Sinusoid { .. } => {
                "Periodic bias: a sinusoidal rate error with period T (air-conditioning cycle, pump or \
                 fan, day/night heating, a mechanical resonance). The Allan deviation peaks near \
                 tau = 0.37 T and returns to zero at every multiple of T."
            }
            Term::RandomTelegraph { .. } => {
                "Random telegraph bias (mode hops): the bias jumps between two levels +a and -a at random \
                 times, as when the laser hops between longitudinal modes. Same Allan signature as a \
                 Gauss-Markov term with sigma = a and Tc = mean dwell / 2."
            }
            Term::RateQuantization { .. } => {
                "Rate-word quantization: a FOG or MEMS gyro outputs its rate as an integer number of LSBs, \
                 so each sample is rounded; the rounding error is white in rate (variance LSB^2/12), an \
                 angle random walk of its own, not the angle quantization of a pulse counter."
            }
            Term::Resonance { .. } => {
                "Resonance: narrowband rate noise around a centre frequency, a damped mode rung by noise \
                 (a mechanical mode of the proof mass or fibre coil, a structural mode of the mount, a \
                 pump or fan whose frequency wanders). A hump in the spectrum a few per cent of its \
                 frequency wide; in the Allan deviation a bump near tau = 0.37/f0 that the quantization \
                 noise of a pulse counter can hide."
            }
        }
    }

    /// The amplitude coefficient in user units (Q, N, B, K, R, sigma, A, a).
    pub fn coefficient(&self) -> f64 {
        match *self {
            Term::Quantization {
                quantization_arcsec,
            } => quantization_arcsec,
            Term::AngleRandomWalk { arw_dpsh } => arw_dpsh,
            Term::BiasInstability {
                bias_instability_dph,
                ..
            } => bias_instability_dph,
            Term::RateRandomWalk { rrw_dphsh } => rrw_dphsh,
            Term::RateRamp { rate_ramp_dphh } => rate_ramp_dphh,
            Term::GaussMarkov { sigma_dph, .. } => sigma_dph,
            Term::Sinusoid { amplitude_dph, .. } => amplitude_dph,
            Term::RandomTelegraph { amplitude_dph, .. } => amplitude_dph,
            Term::RateQuantization { rate_lsb_dps, .. } => rate_lsb_dps,
            Term::Resonance { sigma_dph, .. } => sigma_dph,
        }
    }

    /// Unit of [`Term::coefficient`].
    pub fn coefficient_unit(&self) -> &'static str {
        match self {
            Term::Quantization { .. } => "arcsec",
            Term::AngleRandomWalk { .. } => "deg/sqrt(h)",
            Term::RateRandomWalk { .. } => "deg/h/sqrt(h)",
            Term::RateRamp { .. } => "deg/h/h",
            Term::RateQuantization { .. } => "deg/s",
            _ => "deg/h",
        }
    }

    /// The same term with another amplitude coefficient (shape parameters kept).
    pub fn with_coefficient(&self, c: f64) -> Term {
        let mut t = *self;
        match &mut t {
            Term::Quantization {
                quantization_arcsec,
            } => *quantization_arcsec = c,
            Term::AngleRandomWalk { arw_dpsh } => *arw_dpsh = c,
            Term::BiasInstability {
                bias_instability_dph,
                ..
            } => *bias_instability_dph = c,
            Term::RateRandomWalk { rrw_dphsh } => *rrw_dphsh = c,
            Term::RateRamp { rate_ramp_dphh } => *rate_ramp_dphh = c,
            Term::GaussMarkov { sigma_dph, .. } => *sigma_dph = c,
            Term::Sinusoid { amplitude_dph, .. } => *amplitude_dph = c,
            Term::RandomTelegraph { amplitude_dph, .. } => *amplitude_dph = c,
            Term::RateQuantization { rate_lsb_dps, .. } => *rate_lsb_dps = c,
            Term::Resonance { sigma_dph, .. } => *sigma_dph = c,
        }
        t
    }

    /// Check the parameters (finite, non-negative amplitudes, positive times).
    pub fn validate(&self) -> Result<(), ModelError> {
        let nonneg = |key: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(ModelError::invalid(key, v, "must be finite and >= 0"))
            }
        };
        let positive = |key: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ModelError::invalid(key, v, "must be finite and > 0"))
            }
        };
        match *self {
            Term::Quantization {
                quantization_arcsec,
            } => nonneg("quantization_arcsec", quantization_arcsec),
            Term::AngleRandomWalk { arw_dpsh } => nonneg("arw_dpsh", arw_dpsh),
            Term::BiasInstability {
                bias_instability_dph,
                f_lo_hz,
                f_hi_hz,
            } => {
                nonneg("bias_instability_dph", bias_instability_dph)?;
                if !(f_lo_hz.is_finite() && f_lo_hz >= 0.0) {
                    return Err(ModelError::invalid(
                        "bias_instability_f_lo_hz",
                        f_lo_hz,
                        "must be finite and >= 0",
                    ));
                }
                if f_hi_hz.is_nan() || f_hi_hz <= f_lo_hz {
                    return Err(ModelError::invalid(
                        "bias_instability_f_hi_hz",
                        f_hi_hz,
                        format!("must exceed f_lo = {f_lo_hz} (infinity allowed)"),
                    ));
                }
                Ok(())
            }
            Term::RateRandomWalk { rrw_dphsh } => nonneg("rrw_dphsh", rrw_dphsh),
            Term::RateRamp { rate_ramp_dphh } => {
                if rate_ramp_dphh.is_finite() {
                    Ok(())
                } else {
                    Err(ModelError::invalid(
                        "rate_ramp_dphh",
                        rate_ramp_dphh,
                        "must be finite",
                    ))
                }
            }
            Term::GaussMarkov { sigma_dph, tau_c_s } => {
                nonneg("sigma_dph", sigma_dph)?;
                positive("tau_c_s", tau_c_s)
            }
            Term::Sinusoid {
                amplitude_dph,
                period_s,
            } => {
                nonneg("amplitude_dph", amplitude_dph)?;
                positive("period_s", period_s)
            }
            Term::RandomTelegraph {
                amplitude_dph,
                mean_dwell_s,
            } => {
                nonneg("amplitude_dph", amplitude_dph)?;
                positive("mean_dwell_s", mean_dwell_s)
            }
            Term::RateQuantization {
                rate_lsb_dps,
                tau0_s,
            } => {
                nonneg("rate_lsb_dps", rate_lsb_dps)?;
                positive("tau0_s", tau0_s)
            }
            Term::Resonance {
                sigma_dph,
                centre_hz,
                width_hz,
                tau0_s,
            } => {
                nonneg("sigma_dph", sigma_dph)?;
                positive("tau0_s", tau0_s)?;
                positive("width_hz", width_hz)?;
                let nyquist = 0.5 / tau0_s;
                if !(centre_hz.is_finite() && centre_hz > 0.0 && centre_hz < nyquist) {
                    return Err(ModelError::invalid(
                        "centre_hz",
                        centre_hz,
                        format!("must be in (0, {nyquist}) Hz (below the Nyquist frequency)"),
                    ));
                }
                Ok(())
            }
        }
    }

    /// One-sided rate PSD at `f_hz`, (arcsec/s)^2/Hz, for sample period `tau0_s`.
    ///
    /// Quantization: white angle noise of variance Q^2 seen as a sampled rate,
    /// `8 Q^2 sin^2(pi f tau0) / tau0` for `f <= 1/(2 tau0)` (IEEE 952's
    /// `(2 pi f)^2 Q^2 tau0`, two-sided, at low f). Rate ramp: the formal IEEE 952
    /// `2 R^2 / (2 pi f)^3` (a ramp is not stationary). Sinusoid: no continuous part;
    /// see [`Term::spectral_line`].
    pub fn psd(&self, f_hz: f64, tau0_s: f64) -> f64 {
        let f = f_hz;
        match *self {
            Term::Quantization {
                quantization_arcsec,
            } => {
                if f < 0.0 || f > 0.5 / tau0_s {
                    0.0
                } else {
                    let s = (PI * f * tau0_s).sin();
                    8.0 * quantization_arcsec * quantization_arcsec * s * s / tau0_s
                }
            }
            Term::AngleRandomWalk { arw_dpsh } => {
                let n = units::dpsh_to_arcsec_per_sqrt_s(arw_dpsh);
                2.0 * n * n
            }
            Term::BiasInstability {
                bias_instability_dph,
                f_lo_hz,
                f_hi_hz,
            } => {
                if f < f_lo_hz || f > f_hi_hz || f <= 0.0 {
                    0.0
                } else {
                    let b = units::dph_to_arcsec_per_s(bias_instability_dph);
                    b * b / (PI * f)
                }
            }
            Term::RateRandomWalk { rrw_dphsh } => {
                let k = units::dphsh_to_arcsec_per_s_sqrt_s(rrw_dphsh);
                k * k / (2.0 * PI * PI * f * f)
            }
            Term::RateRamp { rate_ramp_dphh } => {
                let r = units::dphh_to_arcsec_per_s2(rate_ramp_dphh);
                let w = 2.0 * PI * f;
                2.0 * r * r / (w * w * w)
            }
            Term::GaussMarkov { sigma_dph, tau_c_s } => {
                gauss_markov_psd(units::dph_to_arcsec_per_s(sigma_dph), tau_c_s, f)
            }
            Term::Sinusoid { .. } => 0.0,
            Term::RandomTelegraph {
                amplitude_dph,
                mean_dwell_s,
            } => gauss_markov_psd(
                units::dph_to_arcsec_per_s(amplitude_dph),
                0.5 * mean_dwell_s,
                f,
            ),
            Term::RateQuantization {
                rate_lsb_dps,
                tau0_s,
            } => {
                // white over the band: one-sided 2 var tau0
                let l = rate_lsb_dps * units::ARCSEC_PER_DEG;
                if f < 0.0 || f > 0.5 / tau0_s {
                    0.0
                } else {
                    l * l / 6.0 * tau0_s
                }
            }
            Term::Resonance {
                sigma_dph,
                centre_hz,
                width_hz,
                tau0_s,
            } => {
                if f < 0.0 || f > 0.5 / tau0_s {
                    0.0
                } else {
                    let s = units::dph_to_arcsec_per_s(sigma_dph);
                    let ar = Ar2::new(centre_hz, width_hz, tau0_s);
                    s * s * ar.psd_cs_cos((2.0 * PI * f * tau0_s).cos()) * tau0_s
                }
            }
        }
    }

    /// A spectral line `(frequency Hz, power (arcsec/s)^2)` for the sinusoid
    /// (`A^2/2` at `1/T`); `None` for the other terms.
    pub fn spectral_line(&self) -> Option<(f64, f64)> {
        match *self {
            Term::Sinusoid {
                amplitude_dph,
                period_s,
            } => {
                let a = units::dph_to_arcsec_per_s(amplitude_dph);
                Some((1.0 / period_s, 0.5 * a * a))
            }
            _ => None,
        }
    }

    /// Allan variance at `tau_s` for a unit coefficient (1 in user units), (arcsec/s)^2.
    /// `avar = coefficient^2 * unit_avar`.
    pub fn unit_avar(&self, tau_s: f64) -> f64 {
        match *self {
            Term::Quantization { .. } => quantization_avar(1.0, tau_s),
            Term::AngleRandomWalk { .. } => arw_avar(units::dpsh_to_arcsec_per_sqrt_s(1.0), tau_s),
            Term::BiasInstability {
                f_lo_hz, f_hi_hz, ..
            } => flicker_avar(units::dph_to_arcsec_per_s(1.0), tau_s, f_lo_hz, f_hi_hz),
            Term::RateRandomWalk { .. } => {
                rrw_avar(units::dphsh_to_arcsec_per_s_sqrt_s(1.0), tau_s)
            }
            Term::RateRamp { .. } => rate_ramp_avar(units::dphh_to_arcsec_per_s2(1.0), tau_s),
            Term::GaussMarkov { tau_c_s, .. } => {
                gauss_markov_avar(units::dph_to_arcsec_per_s(1.0), tau_c_s, tau_s)
            }
            Term::Sinusoid { period_s, .. } => {
                sinusoid_avar(units::dph_to_arcsec_per_s(1.0), period_s, tau_s)
            }
            Term::RandomTelegraph { mean_dwell_s, .. } => {
                random_telegraph_avar(units::dph_to_arcsec_per_s(1.0), mean_dwell_s, tau_s)
            }
            Term::RateQuantization { tau0_s, .. } => {
                // unit LSB (1 deg/s): N^2 = 3600^2 tau0 / 12, AVAR N^2 / tau
                units::ARCSEC_PER_DEG * units::ARCSEC_PER_DEG * tau0_s / 12.0 / tau_s
            }
            Term::Resonance {
                centre_hz,
                width_hz,
                tau0_s,
                ..
            } => Ar2::new(centre_hz, width_hz, tau0_s).unit_avar(tau_s / tau0_s),
        }
    }

    /// Allan variance at `tau_s` (tau = m tau0, m >= 1), (arcsec/s)^2 = (deg/h)^2.
    pub fn avar(&self, tau_s: f64) -> f64 {
        let c = self.coefficient();
        c * c * self.unit_avar(tau_s)
    }

    /// Allan variance over a tau grid: `out[i] = avar(taus[i])`.
    pub fn avar_into(&self, taus: &[f64], out: &mut [f64]) {
        assert_eq!(
            taus.len(),
            out.len(),
            "avar_into: taus and out differ in length"
        );
        let c2 = self.coefficient() * self.coefficient();
        for (o, &t) in out.iter_mut().zip(taus) {
            *o = c2 * self.unit_avar(t);
        }
    }

    /// Add this term's Allan variance over a tau grid to `out`.
    pub fn add_avar_into(&self, taus: &[f64], out: &mut [f64]) {
        assert_eq!(
            taus.len(),
            out.len(),
            "add_avar_into: taus and out differ in length"
        );
        let c2 = self.coefficient() * self.coefficient();
        for (o, &t) in out.iter_mut().zip(taus) {
            *o += c2 * self.unit_avar(t);
        }
    }
}

/// Sum of the Allan variances of independent terms over a tau grid.
pub fn total_avar_into(terms: &[Term], taus: &[f64], out: &mut [f64]) {
    assert_eq!(
        taus.len(),
        out.len(),
        "total_avar_into: taus and out differ in length"
    );
    out.iter_mut().for_each(|o| *o = 0.0);
    for t in terms {
        t.add_avar_into(taus, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gm_shape_series_joins_direct_form() {
        // both branches at the switch point agree to 1e-10 relative
        let u: f64 = 0.05;
        let direct: f64 = 2.0 * u - 3.0 + 4.0 * (-u).exp() - (-2.0 * u).exp();
        let series = {
            let mut s = 0.0;
            let mut t = u * u * u / 6.0;
            let mut p = 8.0;
            for n in 3..16u32 {
                s += if n % 2 == 0 { 1.0 } else { -1.0 } * (4.0 - p) * t;
                t *= u / (n + 1) as f64;
                p *= 2.0;
            }
            s
        };
        assert!(
            (direct / series - 1.0).abs() < 1e-10,
            "{direct} vs {series}"
        );
        assert!((gm_shape(1e-4) / (2.0 / 3.0 * 1e-12) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn cin_branches_join_at_two() {
        let a = cin_series(2.0);
        let b = EULER_GAMMA + 2f64.ln() - ci_continued_fraction(2.0);
        assert!((a - b).abs() < 1e-14, "{a} vs {b}");
    }
}
