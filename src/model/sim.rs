//! The gyro simulator: a physical model of a ring-laser gyro's readout, streamed
//! block by block (the daemon's built-in gyro, `sagnac simulate`, and the test
//! bench of the estimator and the diagnosis).
//!
//! # The model
//! Per sample period `tau0 = 1/fs` the simulator integrates the **true rate**
//! exactly over the period into a **true angle**:
//! * the constant input rate (e.g. the Earth-rate component on the axis);
//! * ARW: white rate noise (angle increment `N sqrt(tau0) g`);
//! * bias instability: 1/f rate noise from a [`FlickerBank`] (octave-spaced
//!   Gauss-Markov processes plus a white tail; see [`super::terms`]);
//! * RRW: a rate random walk; rate ramp; Gauss-Markov biases; sinusoidal biases
//!   (random phase); random-telegraph biases (exponential dwell times, switching
//!   instants resolved inside the sample); the thermal bias `s (T(t - lag) - T0)`
//!   (the gyro follows the chamber temperature `T` with a pure delay; the
//!   temperature channel reports `T(t)`);
//! * the warm-up `a exp(-t / tau)` (closed-form integral over each period) and
//!   bias steps (a step inside a period counts for the part of the period after it).
//!
//! Every Gaussian process is integrated **exactly** in distribution: for an
//! Ornstein-Uhlenbeck rate the pair (next rate, angle increment) is jointly
//! Gaussian, drawn as one normal for the rate innovation plus the conditional
//! residual of the increment; all those residuals (and ARW) are independent of
//! everything else, so they are merged into one normal per sample. The Allan
//! variance of the simulated angle samples is therefore exactly the sum of the
//! closed forms in [`super::terms`], at every `tau = m tau0`.
//!
//! The **readout** then adds a white Gaussian angle error `e` (the dither
//! residual, `sqrt(Q^2 - d^2/12)`) and quantises with a cumulative up/down pulse
//! counter: `C_k = floor((theta_k + e_k) / d)`; the output is the increment
//! `C_k - C_{k-1}` (an integer). The true angle is kept as whole pulses (i64) plus
//! a fraction in [0, 1), so precision does not degrade over indefinite runs.
//!
//! Physics note on quantization: the counter's error is white with variance
//! `d^2/12` only if the angle's sub-pulse phase is randomised between the samples
//! being compared. At a slow constant input and a dither residual well below
//! `d/2`, it is a sawtooth and its Allan variance oscillates around `3Q^2/tau^2`
//! ([`super::terms::counter_readout_avar`] gives the exact curve); this is what a
//! real counter does, and the simulator reproduces it.
//!
//! **Rate-output sensors** (`output = "rate"`, FOG/MEMS) have no counter: the
//! output is the rate over each period, `(theta_k - theta_{k-1} + e_k - e_{k-1}) / tau0`,
//! rounded to a multiple of `rate_lsb_dps` (white rate noise of variance
//! `lsb^2/12` when the noise spans several LSBs).
//!
//! A **readout filter** (`[readout_filter]`, [`super::filter`]) acts on the true
//! rate before the readout: the angle increments are filtered (moving average or
//! one pole, unit DC gain), then counted or output as a rate.
//!
//! **Spikes** (`[noise.spikes]`) are glitches of the readout, not of the true
//! rate, so they come after the filter: Poisson arrivals (each in the sample
//! period where it falls), random sign, magnitude uniform in `[0.1, 1]` of the
//! amplitude. A spike `s` puts the angle `x = s tau0` on the measured angle of
//! its sample only: a counter's reading of that frame is
//! `floor((theta_k + e_k + x) / d)` and the next frame reads right again (the
//! increments carry `+x`, then `-x`, in pulses); a rate word is off by `s` for
//! that one sample.
//!
//! # Streaming
//! [`Simulator::next_block`] appends the next `n` pulse increments; the stream is
//! identical whatever the block sizes (each term draws from its own ChaCha8 stream
//! in sample order), memory is bounded, and runs may be indefinite.
//! Determinism: `(model, seed)` fixes the output (rand_chacha ChaCha8Rng, value-stable;
//! normals and exponentials from rand_distr). Each term has its own RNG stream, so
//! adding a term does not change the realisation of the others.

use std::f64::consts::PI;
use std::io::Write;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Exp1, StandardNormal};

use super::ModelError;
use super::config::{GyroModel, OutputKind, ThermalParams, WarmupParams};
use super::filter::FilterState;
use super::terms::FlickerBank;
use crate::units;

/// Samples generated per internal chunk (bounds the scratch memory).
const CHUNK: usize = 4096;

// RNG stream numbers (each term has its own stream).
const STREAM_INIT: u64 = 0;
const STREAM_WHITE: u64 = 1;
const STREAM_DITHER: u64 = 2;
const STREAM_RRW: u64 = 3;
const STREAM_FLICKER: u64 = 1_000;
const STREAM_GM: u64 = 2_000;
const STREAM_RTN: u64 = 3_000;
const STREAM_SINE: u64 = 4_000;
const STREAM_RESONANCE: u64 = 5_000;
const STREAM_SPIKES: u64 = 6_000;

fn rng_for(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

#[inline]
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    rng.sample::<f64, _>(StandardNormal)
}

/// Ground truth of a block, for tests and for the diagnosis.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Truth {
    /// True angle increment over each sample period (everything except the
    /// readout error), arcsec.
    pub angle_increment_arcsec: Vec<f64>,
    /// White dither residual added before the counter at the end of each sample, arcsec.
    pub readout_error_arcsec: Vec<f64>,
    /// Spikes' glitch angle added to each sample's counter reading (and to
    /// that reading only), arcsec; empty when the model has no spikes.
    pub glitch_arcsec: Vec<f64>,
}

/// A resonance: the AR(2) rate `x` (arcsec/s) of [`crate::model::resonance`],
/// its last two values and the innovation's standard deviation.
#[derive(Debug, Clone)]
struct Resonance {
    x1: f64,
    x2: f64,
    a1: f64,
    a2: f64,
    innov_sd: f64,
    rng: ChaCha8Rng,
}

impl Resonance {
    /// Started in its stationary distribution (`x1`, `x2` of variance
    /// `sigma^2` and correlation `rho(1)`).
    fn new(sigma: f64, centre_hz: f64, width_hz: f64, tau0: f64, mut rng: ChaCha8Rng) -> Self {
        let ar = super::resonance::Ar2::new(centre_hz, width_hz, tau0);
        let rho = ar.autocorr(1);
        let x2 = sigma * normal(&mut rng);
        let x1 = rho * x2 + sigma * (1.0 - rho * rho).max(0.0).sqrt() * normal(&mut rng);
        Resonance {
            x1,
            x2,
            a1: ar.a1,
            a2: ar.a2,
            innov_sd: sigma * ar.innov_var.sqrt(),
            rng,
        }
    }
}

/// An exactly integrated Ornstein-Uhlenbeck rate.
#[derive(Debug, Clone)]
struct Ou {
    x: f64,
    a: f64,
    c_int: f64,
    k_cov: f64,
    s1: f64,
    rng: ChaCha8Rng,
}

/// `f(h) = h - 2(1 - e^-h) + (1 - e^-2h)/2` without cancellation.
fn ou_f(h: f64) -> f64 {
    if h < 0.1 {
        // sum_{n>=3} (-1)^(n+1) (2^(n-1) - 2) h^n / n!
        let mut sum = 0.0;
        let mut t = h * h * h / 6.0;
        let mut p = 4.0;
        for n in 3..20u32 {
            let sign = if n % 2 == 1 { 1.0 } else { -1.0 };
            sum += sign * (p - 2.0) * t;
            t *= h / (n + 1) as f64;
            p *= 2.0;
        }
        sum
    } else {
        h + 2.0 * (-h).exp_m1() - 0.5 * (-2.0 * h).exp_m1()
    }
}

/// Exact discretisation of an OU rate (stationary sigma, correlation time tc) over
/// one sample of length `dt`: returns `(a, c_int, k_cov, s1, residual_var)` with
/// `x' = a x + w1`, `w1 ~ N(0, s1^2)`, increment `= c_int x + k_cov w1 + r`,
/// `r ~ N(0, residual_var)` independent of `w1`.
fn ou_discretise(sigma: f64, tc: f64, dt: f64) -> (f64, f64, f64, f64, f64) {
    let h = dt / tc;
    let em = -(-h).exp_m1(); // 1 - a
    let e2 = -(-2.0 * h).exp_m1(); // 1 - a^2
    let a = 1.0 - em;
    let s1 = sigma * e2.sqrt();
    let c_int = tc * em;
    let k_cov = tc * em / (2.0 - em); // Cov(w1, w2) / Var(w1) = Tc (1-a)/(1+a)
    let resid = sigma * sigma * tc * tc * (2.0 * ou_f(h) - em * em * em / (2.0 - em));
    (a, c_int, k_cov, s1, resid.max(0.0))
}

#[derive(Debug, Clone)]
struct Rrw {
    w: f64,
    step: f64,
    rng: ChaCha8Rng,
}

#[derive(Debug, Clone)]
struct Sine {
    /// `2 A / omega * sin(omega tau0 / 2)`, arcsec.
    gain: f64,
    omega: f64,
    phase: f64,
}

#[derive(Debug, Clone)]
struct Rtn {
    amp: f64,
    dwell: f64,
    state: f64,
    remaining: f64,
    rng: ChaCha8Rng,
}

#[derive(Debug, Clone)]
struct Thermal {
    temp_c0: f64,
    ramp_c_per_s: f64,
    sine_amp_c: f64,
    omega: f64,
    /// rate bias per degree, arcsec/s/C
    sens: f64,
    /// delay of the bias behind the temperature, s
    lag: f64,
}

impl Thermal {
    /// The chamber temperature `T(t)`, deg C (analytic, so also for `t < 0`).
    fn temp_at(&self, t: f64) -> f64 {
        let mut v = self.temp_c0 + self.ramp_c_per_s * t;
        if self.omega > 0.0 {
            v += self.sine_amp_c * (self.omega * t).sin();
        }
        v
    }

    /// The bias's exact integral over each sample period into `dth`:
    /// `s (T(t - lag) - T0)` is a ramp plus a sinusoid of `t - lag`, whose
    /// integrals over a period are their values at the period's middle times
    /// `tau0` (times `2 sin(omega tau0 / 2) / omega` for the sinusoid).
    fn add(&self, dth: &mut [f64], k0: u64, tau0: f64) {
        let g_ramp = self.sens * self.ramp_c_per_s * tau0;
        let g_sine = if self.omega > 0.0 {
            self.sens * self.sine_amp_c * 2.0 / self.omega * (0.5 * self.omega * tau0).sin()
        } else {
            0.0
        };
        for (i, v) in dth.iter_mut().enumerate() {
            let t = ((k0 + i as u64) as f64 + 0.5) * tau0 - self.lag;
            *v += g_ramp * t;
            if g_sine != 0.0 {
                *v += g_sine * (self.omega * t).sin();
            }
        }
    }
}

/// The bias's settling after switch-on, `a exp(-t / tau)`.
#[derive(Debug, Clone)]
struct Warmup {
    /// The angle over the first period, `a tau (1 - exp(-tau0 / tau))`, arcsec.
    gain: f64,
    /// `tau0 / tau`.
    decay_per_sample: f64,
}

impl Warmup {
    fn new(w: &WarmupParams, tau0: f64) -> Self {
        let a = units::dph_to_arcsec_per_s(w.amplitude_dph);
        let h = tau0 / w.tau_s;
        Warmup {
            gain: -a * w.tau_s * (-h).exp_m1(),
            decay_per_sample: h,
        }
    }

    /// The exact integral over period `k`, `gain exp(-k tau0 / tau)`, into `dth`.
    fn add(&self, dth: &mut [f64], k0: u64) {
        for (i, v) in dth.iter_mut().enumerate() {
            let x = (k0 + i as u64) as f64 * self.decay_per_sample;
            if x > 746.0 {
                // exp(-x) is 0 in f64 from here on
                break;
            }
            *v += self.gain * (-x).exp();
        }
    }
}

/// A bias step of `amp` (arcsec/s) at time `at` (s).
#[derive(Debug, Clone)]
struct BiasStep {
    at: f64,
    amp: f64,
}

impl BiasStep {
    /// The step's angle over each period into `dth`: `amp tau0` after the
    /// step, `amp (t_end - at)` in the period it falls in, 0 before.
    fn add(&self, dth: &mut [f64], k0: u64, tau0: f64) {
        let chunk_end = (k0 + dth.len() as u64) as f64 * tau0;
        if self.at >= chunk_end {
            return;
        }
        for (i, v) in dth.iter_mut().enumerate() {
            let k = k0 + i as u64;
            let (t0, t1) = (k as f64 * tau0, (k + 1) as f64 * tau0);
            if self.at <= t0 {
                *v += self.amp * tau0;
            } else if self.at < t1 {
                *v += self.amp * (t1 - self.at);
            }
        }
    }
}

/// The deterministic rate terms (rate ramp, sinusoids, thermal bias, warm-up,
/// bias steps), each integrated exactly over the sample periods.
#[derive(Debug, Clone)]
struct Deterministic {
    /// Rate ramp, arcsec/s^2.
    ramp: f64,
    sines: Vec<Sine>,
    thermal: Option<Thermal>,
    warmup: Option<Warmup>,
    steps: Vec<BiasStep>,
}

impl Deterministic {
    fn new(model: &GyroModel, seed: u64) -> Self {
        let tau0 = model.tau0_s();
        let noise = &model.noise;
        Deterministic {
            ramp: units::dphh_to_arcsec_per_s2(noise.rate_ramp_dphh.unwrap_or(0.0)),
            sines: sines(model, seed),
            thermal: model.thermal.as_ref().map(Thermal::new),
            warmup: noise
                .warmup
                .as_ref()
                .filter(|w| w.amplitude_dph != 0.0)
                .map(|w| Warmup::new(w, tau0)),
            steps: noise
                .bias_step
                .iter()
                .filter(|b| b.amplitude_dph != 0.0)
                .map(|b| BiasStep {
                    at: b.at_s,
                    amp: units::dph_to_arcsec_per_s(b.amplitude_dph),
                })
                .collect(),
        }
    }

    /// The terms' angles over samples `k0..k0 + dth.len()`, added to `dth`.
    fn add(&self, dth: &mut [f64], k0: u64, tau0: f64) {
        let t_mid = |i: usize| ((k0 + i as u64) as f64 + 0.5) * tau0;
        if self.ramp != 0.0 {
            let g = self.ramp * tau0;
            for (i, v) in dth.iter_mut().enumerate() {
                *v += g * t_mid(i);
            }
        }
        for s in &self.sines {
            for (i, v) in dth.iter_mut().enumerate() {
                *v += s.gain * (s.omega * t_mid(i) + s.phase).sin();
            }
        }
        if let Some(th) = &self.thermal {
            th.add(dth, k0, tau0);
        }
        if let Some(w) = &self.warmup {
            w.add(dth, k0);
        }
        for b in &self.steps {
            b.add(dth, k0, tau0);
        }
    }
}

/// Single-sample readout glitches: Poisson arrivals, each in the sample
/// period where it falls, with a random sign and a magnitude uniform in
/// `[0.1, 1] amp`; kept apart from the true angle.
#[derive(Debug, Clone)]
struct Spikes {
    /// Mean gap between arrivals, sample periods.
    mean_gap: f64,
    /// Largest spike, arcsec/s.
    amp: f64,
    /// Arrival time of the next spike, sample periods since the start.
    next: f64,
    rng: ChaCha8Rng,
    /// The glitch angle (spike times `tau0`) of each sample of the chunk, arcsec.
    buf: Vec<f64>,
}

impl Spikes {
    fn new(model: &GyroModel, seed: u64) -> Option<Self> {
        let sp = model
            .noise
            .spikes
            .as_ref()
            .filter(|sp| sp.rate_per_h > 0.0 && sp.amplitude_dph > 0.0)?;
        let mean_gap = units::S_PER_H * model.gyro.sample_rate_hz / sp.rate_per_h;
        let mut rng = rng_for(seed, STREAM_SPIKES);
        let next = mean_gap * rng.sample::<f64, _>(Exp1);
        Some(Spikes {
            mean_gap,
            amp: units::dph_to_arcsec_per_s(sp.amplitude_dph),
            next,
            rng,
            buf: vec![0.0; CHUNK],
        })
    }

    /// The glitch angles of samples `k0..k0 + m` into `buf[..m]`.
    fn fill(&mut self, k0: u64, m: usize, tau0: f64) {
        let buf = &mut self.buf[..m];
        buf.fill(0.0);
        let end = (k0 + m as u64) as f64;
        while self.next < end {
            // earlier chunks consumed every arrival before k0
            let i = (self.next.floor() as u64 - k0) as usize;
            let magnitude = self.amp * (0.1 + 0.9 * self.rng.random::<f64>());
            let sign = if self.rng.random::<bool>() { 1.0 } else { -1.0 };
            buf[i] += sign * magnitude * tau0;
            self.next += self.mean_gap * self.rng.sample::<f64, _>(Exp1);
        }
    }
}

/// The streaming gyro simulator.
#[derive(Debug, Clone)]
pub struct Simulator {
    fs: f64,
    tau0: f64,
    d: f64,
    inv_d: f64,
    input_inc: f64,
    total: Option<u64>,
    k: u64,
    whole: i64,
    frac: f64,
    counter: i64,
    dither_sigma: f64,
    dither_rng: ChaCha8Rng,
    white_sigma: f64,
    white_rng: ChaCha8Rng,
    ous: Vec<Ou>,
    resonances: Vec<Resonance>,
    rrw: Option<Rrw>,
    det: Deterministic,
    rtns: Vec<Rtn>,
    spikes: Option<Spikes>,
    flicker: Option<FlickerBank>,
    buf_dtheta: Vec<f64>,
    buf_e: Vec<f64>,
    output: OutputKind,
    rate_lsb_dps: f64,
    filter: Option<FilterState>,
    /// Rate output: the previous sample's white angle error (arcsec).
    e_prev: f64,
}

/// Samples of a run of `duration_s` at `fs` (`None`: unbounded).
fn run_length(duration_s: Option<f64>, fs: f64) -> Result<Option<u64>, ModelError> {
    let Some(dur) = duration_s else {
        return Ok(None);
    };
    if !(dur.is_finite() && dur > 0.0) {
        return Err(ModelError::invalid(
            "duration_s",
            dur,
            "must be finite and > 0",
        ));
    }
    let n = (dur * fs).round();
    if n < 1.0 {
        return Err(ModelError::invalid(
            "duration_s",
            dur,
            "shorter than one sample period",
        ));
    }
    Ok(Some(n as u64))
}

/// The Gaussian terms: the OU processes (flicker bank components, then the
/// Gauss-Markov biases), the rate random walk, and the variance of the one
/// merged white normal per sample (ARW, the flicker's white tail, and the
/// conditional residuals of the OU and RRW increments).
struct GaussianTerms {
    white_var: f64,
    ous: Vec<Ou>,
    flicker: Option<FlickerBank>,
    rrw: Option<Rrw>,
}

impl GaussianTerms {
    fn new(model: &GyroModel, seed: u64) -> Result<Self, ModelError> {
        let noise = &model.noise;
        let fs = model.gyro.sample_rate_hz;
        let tau0 = 1.0 / fs;
        let mut white_var = 0.0;
        if let Some(n) = noise.arw_dpsh {
            let n = units::dpsh_to_arcsec_per_sqrt_s(n);
            white_var += n * n * tau0;
        }
        let mut ous = Vec::new();
        let mut add_ou = |sigma: f64, tc: f64, stream: u64, white_var: &mut f64| {
            let (a, c_int, k_cov, s1, resid) = ou_discretise(sigma, tc, tau0);
            let mut rng = rng_for(seed, stream);
            let x = sigma * normal(&mut rng); // stationary start
            *white_var += resid;
            ous.push(Ou {
                x,
                a,
                c_int,
                k_cov,
                s1,
                rng,
            });
        };
        let mut flicker = None;
        if let Some(b) = noise.bias_instability_dph.filter(|b| *b > 0.0) {
            let bank = FlickerBank::for_sample_rate(b, model.flicker_f_lo_hz(), fs)?;
            for (j, c) in bank.components().iter().enumerate() {
                add_ou(
                    c.sigma_arcsec_s,
                    c.tau_c_s,
                    STREAM_FLICKER + j as u64,
                    &mut white_var,
                );
            }
            // white tail: one-sided PSD S0 -> angle increment variance S0 tau0 / 2
            white_var += bank.white_psd() * tau0 / 2.0;
            flicker = Some(bank);
        }
        for (i, g) in noise.gauss_markov.iter().enumerate() {
            if g.sigma_dph > 0.0 {
                add_ou(
                    units::dph_to_arcsec_per_s(g.sigma_dph),
                    g.tau_c_s,
                    STREAM_GM + i as u64,
                    &mut white_var,
                );
            }
        }
        let rrw = noise.rrw_dphsh.filter(|k| *k > 0.0).map(|k| {
            let k = units::dphsh_to_arcsec_per_s_sqrt_s(k);
            white_var += k * k * tau0 * tau0 * tau0 / 12.0;
            Rrw {
                w: 0.0,
                step: k * tau0.sqrt(),
                rng: rng_for(seed, STREAM_RRW),
            }
        });
        Ok(GaussianTerms {
            white_var,
            ous,
            flicker,
            rrw,
        })
    }
}

/// The sinusoidal biases (a random phase each).
fn sines(model: &GyroModel, seed: u64) -> Vec<Sine> {
    let tau0 = model.tau0_s();
    model
        .noise
        .sinusoid
        .iter()
        .enumerate()
        .filter(|(_, s)| s.amplitude_dph > 0.0)
        .map(|(i, s)| {
            let a = units::dph_to_arcsec_per_s(s.amplitude_dph);
            let omega = 2.0 * PI / s.period_s;
            let mut rng = rng_for(seed, STREAM_SINE + i as u64);
            let phase = 2.0 * PI * rng.random::<f64>();
            Sine {
                gain: 2.0 * a / omega * (0.5 * omega * tau0).sin(),
                omega,
                phase,
            }
        })
        .collect()
}

/// The resonances, each started in its stationary distribution.
fn resonances(model: &GyroModel, seed: u64) -> Vec<Resonance> {
    let tau0 = model.tau0_s();
    model
        .noise
        .resonance
        .iter()
        .enumerate()
        .filter(|(_, r)| r.sigma_dph > 0.0)
        .map(|(i, r)| {
            Resonance::new(
                units::dph_to_arcsec_per_s(r.sigma_dph),
                r.centre_hz,
                r.width_hz,
                tau0,
                rng_for(seed, STREAM_RESONANCE + i as u64),
            )
        })
        .collect()
}

/// The random-telegraph biases: a random start state and a first dwell each.
fn telegraphs(model: &GyroModel, seed: u64) -> Vec<Rtn> {
    model
        .noise
        .random_telegraph
        .iter()
        .enumerate()
        .filter(|(_, r)| r.amplitude_dph > 0.0)
        .map(|(i, r)| {
            let mut rng = rng_for(seed, STREAM_RTN + i as u64);
            let state = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let remaining = r.mean_dwell_s * rng.sample::<f64, _>(Exp1);
            Rtn {
                amp: units::dph_to_arcsec_per_s(r.amplitude_dph),
                dwell: r.mean_dwell_s,
                state,
                remaining,
                rng,
            }
        })
        .collect()
}

impl Thermal {
    fn new(t: &ThermalParams) -> Self {
        Thermal {
            temp_c0: t.temp_c0,
            ramp_c_per_s: t.ramp_c_per_h / units::S_PER_H,
            sine_amp_c: t.sine_amplitude_c,
            omega: match t.sine_period_s {
                Some(p) if t.sine_amplitude_c > 0.0 => 2.0 * PI / p,
                _ => 0.0,
            },
            sens: units::dph_to_arcsec_per_s(t.bias_sensitivity_dph_per_c),
            lag: t.lag_s,
        }
    }
}

/// The readout's start: the true angle's sub-pulse fraction, the first white
/// angle error and the counter reading (0 for a rate output).
struct ReadoutStart {
    frac: f64,
    e0: f64,
    counter: i64,
    dither_rng: ChaCha8Rng,
}

impl ReadoutStart {
    fn new(model: &GyroModel, seed: u64) -> Self {
        let dither_sigma = model.dither_sigma_arcsec();
        let mut dither_rng = rng_for(seed, STREAM_DITHER);
        let mut init = rng_for(seed, STREAM_INIT);
        let frac: f64 = init.random::<f64>();
        let e0 = if dither_sigma > 0.0 {
            dither_sigma * normal(&mut dither_rng)
        } else {
            0.0
        };
        let counter = match model.gyro.output {
            OutputKind::Counts => (frac + e0 / model.gyro.pulse_arcsec).floor() as i64,
            OutputKind::Rate => 0,
        };
        ReadoutStart {
            frac,
            e0,
            counter,
            dither_rng,
        }
    }
}

impl Simulator {
    /// A simulator for `model` (validated here), seeded with `seed`. With
    /// `duration_s = Some(D)` the stream ends after `round(D fs)` samples;
    /// with `None` it is unbounded.
    pub fn new(model: &GyroModel, seed: u64, duration_s: Option<f64>) -> Result<Self, ModelError> {
        model.validate()?;
        let fs = model.gyro.sample_rate_hz;
        let tau0 = 1.0 / fs;
        let d = model.gyro.pulse_arcsec;
        let total = run_length(duration_s, fs)?;
        let gauss = GaussianTerms::new(model, seed)?;
        let start = ReadoutStart::new(model, seed);
        let input_inc = units::dph_to_arcsec_per_s(model.gyro.input_rate_dph) * tau0;
        Ok(Simulator {
            fs,
            tau0,
            d,
            inv_d: if d > 0.0 { 1.0 / d } else { 0.0 },
            input_inc,
            total,
            k: 0,
            whole: 0,
            frac: start.frac,
            counter: start.counter,
            dither_sigma: model.dither_sigma_arcsec(),
            dither_rng: start.dither_rng,
            white_sigma: gauss.white_var.sqrt(),
            white_rng: rng_for(seed, STREAM_WHITE),
            ous: gauss.ous,
            resonances: resonances(model, seed),
            rrw: gauss.rrw,
            det: Deterministic::new(model, seed),
            rtns: telegraphs(model, seed),
            spikes: Spikes::new(model, seed),
            flicker: gauss.flicker,
            buf_dtheta: vec![0.0; CHUNK],
            buf_e: vec![0.0; CHUNK],
            output: model.gyro.output,
            rate_lsb_dps: model.gyro.rate_lsb_dps,
            filter: model.readout_filter().map(|f| f.state(input_inc)),
            e_prev: start.e0,
        })
    }

    /// What the simulated sensor outputs.
    pub fn output(&self) -> OutputKind {
        self.output
    }
    /// Rate-word quantum, deg/s (0: unquantised or counts output).
    pub fn rate_lsb_dps(&self) -> f64 {
        self.rate_lsb_dps
    }
    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.fs
    }
    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        self.tau0
    }
    /// Pulse weight d, arcsec.
    pub fn pulse_arcsec(&self) -> f64 {
        self.d
    }
    /// Standard deviation of the white dither residual added before the counter, arcsec.
    pub fn dither_sigma_arcsec(&self) -> f64 {
        self.dither_sigma
    }
    /// Whether the model has a thermal section (a `temp_c` channel).
    pub fn has_temperature(&self) -> bool {
        self.det.thermal.is_some()
    }
    /// The flicker generator, when the model has bias instability.
    pub fn flicker_bank(&self) -> Option<&FlickerBank> {
        self.flicker.as_ref()
    }
    /// Samples emitted so far.
    pub fn samples_emitted(&self) -> u64 {
        self.k
    }
    /// Total samples of a finite run (`None` = unbounded).
    pub fn samples_total(&self) -> Option<u64> {
        self.total
    }
    /// Samples left in a finite run (`None` = unbounded).
    pub fn remaining(&self) -> Option<u64> {
        self.total.map(|t| t - self.k)
    }
    /// The cumulative counter reading (pulses) after the last emitted sample.
    pub fn counter(&self) -> i64 {
        self.counter
    }
    /// The true angle as (whole pulses, fraction in [0, 1)) after the last emitted sample.
    pub fn true_angle_pulses(&self) -> (i64, f64) {
        (self.whole, self.frac)
    }
    /// Temperature of the thermal profile at time `t_s`, deg C (`None` without thermal model).
    pub fn temperature_at(&self, t_s: f64) -> Option<f64> {
        self.det.thermal.as_ref().map(|t| t.temp_at(t_s))
    }

    /// Append the next `n` pulse increments (fewer at the end of a finite run) to
    /// `counts`; returns how many were appended.
    pub fn next_block(&mut self, n: usize, counts: &mut Vec<i64>) -> usize {
        self.generate(n, counts, None, None)
    }

    /// Like [`Simulator::next_block`], and also append the temperature (deg C) at
    /// the end of each sample period to `temp_c` when the model has a thermal
    /// section (otherwise `temp_c` is left untouched).
    pub fn next_block_with_temp(
        &mut self,
        n: usize,
        counts: &mut Vec<i64>,
        temp_c: &mut Vec<f64>,
    ) -> usize {
        self.generate(n, counts, Some(temp_c), None)
    }

    /// Like [`Simulator::next_block_with_temp`], and also append the ground truth.
    pub fn next_block_truth(
        &mut self,
        n: usize,
        counts: &mut Vec<i64>,
        temp_c: &mut Vec<f64>,
        truth: &mut Truth,
    ) -> usize {
        self.generate(n, counts, Some(temp_c), Some(truth))
    }

    /// Samples the next block may hold: `n`, or fewer at the end of a finite run.
    fn block_len(&self, n: usize) -> usize {
        match self.remaining() {
            Some(r) => n.min(usize::try_from(r).unwrap_or(usize::MAX)),
            None => n,
        }
    }

    /// Append the next `n` output rates (deg/s; fewer at the end of a finite run)
    /// of a rate-output model to `rates_dps`, and the temperatures to `temp_c`
    /// when the model has a thermal section. Returns how many were appended;
    /// 0 for a counts-output model (use [`Simulator::next_block`]).
    pub fn next_block_rates(
        &mut self,
        n: usize,
        rates_dps: &mut Vec<f64>,
        temp_c: &mut Vec<f64>,
    ) -> usize {
        if self.output != OutputKind::Rate {
            return 0;
        }
        let n = self.block_len(n);
        let mut done = 0;
        while done < n {
            let m = (n - done).min(CHUNK);
            self.fill_chunk(m);
            let (to_dps, lsb) = (1.0 / (self.tau0 * units::ARCSEC_PER_DEG), self.rate_lsb_dps);
            let glitch = self.spikes.as_ref().map(|sp| &sp.buf[..m]);
            for i in 0..m {
                let e = self.buf_e[i];
                let mut r = (self.buf_dtheta[i] + e - self.e_prev) * to_dps;
                self.e_prev = e;
                if let Some(g) = glitch {
                    // one rate word off by the spike, g / tau0
                    r += g[i] * to_dps;
                }
                rates_dps.push(if lsb > 0.0 {
                    (r / lsb).round() * lsb
                } else {
                    r
                });
            }
            if let Some(th) = self.det.thermal.as_ref() {
                temp_c
                    .extend((0..m).map(|i| th.temp_at((self.k + i as u64 + 1) as f64 * self.tau0)));
            }
            self.k += m as u64;
            done += m;
        }
        n
    }

    fn generate(
        &mut self,
        n: usize,
        counts: &mut Vec<i64>,
        mut temp_c: Option<&mut Vec<f64>>,
        mut truth: Option<&mut Truth>,
    ) -> usize {
        if self.output != OutputKind::Counts {
            return 0;
        }
        let n = self.block_len(n);
        counts.reserve(n.min(1 << 20));
        let mut done = 0;
        while done < n {
            let m = (n - done).min(CHUNK);
            self.fill_chunk(m);
            let inv_d = self.inv_d;
            let glitch = self.spikes.as_ref().map(|sp| &sp.buf[..m]);
            for i in 0..m {
                self.frac += self.buf_dtheta[i] * inv_d;
                let f = self.frac.floor();
                self.whole += f as i64;
                self.frac -= f;
                let mut e = self.buf_e[i];
                if let Some(g) = glitch {
                    // this one reading is off; the true angle is not
                    e += g[i];
                }
                let c = self.whole + (self.frac + e * inv_d).floor() as i64;
                counts.push(c - self.counter);
                self.counter = c;
            }
            if let (Some(out), Some(th)) = (temp_c.as_deref_mut(), self.det.thermal.as_ref()) {
                out.extend((0..m).map(|i| th.temp_at((self.k + i as u64 + 1) as f64 * self.tau0)));
            }
            if let Some(t) = truth.as_deref_mut() {
                t.angle_increment_arcsec
                    .extend_from_slice(&self.buf_dtheta[..m]);
                t.readout_error_arcsec.extend_from_slice(&self.buf_e[..m]);
                if let Some(g) = glitch {
                    t.glitch_arcsec.extend_from_slice(g);
                }
            }
            self.k += m as u64;
            done += m;
        }
        n
    }

    /// True angle increments (arcsec) of the next `m` samples into `buf_dtheta`,
    /// dither residuals into `buf_e`, spikes' glitch angles into their buffer.
    fn fill_chunk(&mut self, m: usize) {
        let tau0 = self.tau0;
        let k0 = self.k;
        let Simulator {
            buf_dtheta,
            buf_e,
            ous,
            resonances,
            rrw,
            det,
            rtns,
            white_rng,
            dither_rng,
            ..
        } = self;
        let dth = &mut buf_dtheta[..m];
        let e = &mut buf_e[..m];
        dth.fill(self.input_inc);
        det.add(dth, k0, tau0);
        for ou in ous.iter_mut() {
            let (mut x, a, c_int, k_cov, s1) = (ou.x, ou.a, ou.c_int, ou.k_cov, ou.s1);
            for v in dth.iter_mut() {
                let w1 = s1 * normal(&mut ou.rng);
                *v += c_int * x + k_cov * w1;
                x = a * x + w1;
            }
            ou.x = x;
        }
        for r in resonances.iter_mut() {
            let (mut x1, mut x2, a1, a2, sd) = (r.x1, r.x2, r.a1, r.a2, r.innov_sd);
            for v in dth.iter_mut() {
                let x = a1 * x1 + a2 * x2 + sd * normal(&mut r.rng);
                *v += x * tau0;
                x2 = x1;
                x1 = x;
            }
            (r.x1, r.x2) = (x1, x2);
        }
        if let Some(r) = rrw.as_mut() {
            for v in dth.iter_mut() {
                let dw = r.step * normal(&mut r.rng);
                *v += (r.w + 0.5 * dw) * tau0;
                r.w += dw;
            }
        }
        for r in rtns.iter_mut() {
            for v in dth.iter_mut() {
                let mut left = tau0;
                let mut acc = 0.0;
                while r.remaining < left {
                    acc += r.state * r.remaining;
                    left -= r.remaining;
                    r.state = -r.state;
                    r.remaining = r.dwell * r.rng.sample::<f64, _>(Exp1);
                }
                acc += r.state * left;
                r.remaining -= left;
                *v += r.amp * acc;
            }
        }
        if self.white_sigma > 0.0 {
            let s = self.white_sigma;
            for v in dth.iter_mut() {
                *v += s * normal(white_rng);
            }
        }
        if let Some(f) = self.filter.as_mut() {
            f.apply(dth);
        }
        // a glitch is the readout's, not the true rate's: after the filter, apart
        if let Some(sp) = self.spikes.as_mut() {
            sp.fill(k0, m, tau0);
        }
        if self.dither_sigma > 0.0 {
            let s = self.dither_sigma;
            for v in e.iter_mut() {
                *v = s * normal(dither_rng);
            }
        } else {
            e.fill(0.0);
        }
    }
}

fn push_i64(buf: &mut Vec<u8>, v: i64) {
    let mut tmp = [0u8; 20];
    let mut i = tmp.len();
    let mut u = v.unsigned_abs();
    loop {
        i -= 1;
        tmp[i] = b'0' + (u % 10) as u8;
        u /= 10;
        if u == 0 {
            break;
        }
    }
    if v < 0 {
        buf.push(b'-');
    }
    buf.extend_from_slice(&tmp[i..]);
}

/// Fixed-point with 4 decimals (0.1 mK for temperatures).
fn push_fixed4(buf: &mut Vec<u8>, v: f64) {
    if !v.is_finite() {
        buf.extend_from_slice(b"nan");
        return;
    }
    let s = (v * 1e4).round() as i64;
    if s < 0 {
        buf.push(b'-');
    }
    let u = s.unsigned_abs();
    push_i64(buf, (u / 10_000) as i64);
    buf.push(b'.');
    let f = u % 10_000;
    buf.extend_from_slice(&[
        b'0' + (f / 1000) as u8,
        b'0' + (f / 100 % 10) as u8,
        b'0' + (f / 10 % 10) as u8,
        b'0' + (f % 10) as u8,
    ]);
}

/// Run the simulator to its end and write CSV: header `counts` (or `counts,temp_c`
/// with a thermal model; temperatures with 4 decimals), one row per sample; for a
/// rate-output model, `rate_dps` (deg/s) instead of `counts`.
/// Returns the number of rows. The simulator must have a finite duration.
pub fn write_csv<W: Write>(sim: &mut Simulator, out: W) -> Result<u64, ModelError> {
    if sim.samples_total().is_none() {
        return Err(ModelError::invalid(
            "duration_s",
            "(none)",
            "CSV output needs a finite duration",
        ));
    }
    let mut out = std::io::BufWriter::with_capacity(1 << 20, out);
    if sim.output() == OutputKind::Rate {
        // rates in deg/s as the shortest decimal that reads back exactly
        write_rows(
            sim,
            &mut out,
            "rate_dps",
            |sim, n, v, t| sim.next_block_rates(n, v, t),
            |buf, v: f64| {
                // writing into a Vec cannot fail
                let _ = write!(buf, "{v}");
            },
        )
    } else {
        write_rows(
            sim,
            &mut out,
            "counts",
            |sim, n, v, t| sim.next_block_with_temp(n, v, t),
            |buf, v: i64| push_i64(buf, v),
        )
    }
}

/// The CSV rows of a whole run: `column` (and `temp_c` with a thermal model),
/// blocks from `next`, values written by `fmt`.
fn write_rows<W: Write, T: Copy>(
    sim: &mut Simulator,
    out: &mut W,
    column: &str,
    next: impl Fn(&mut Simulator, usize, &mut Vec<T>, &mut Vec<f64>) -> usize,
    fmt: impl Fn(&mut Vec<u8>, T),
) -> Result<u64, ModelError> {
    const BLOCK: usize = 65_536;
    let thermal = sim.has_temperature();
    let header = if thermal {
        format!("{column},temp_c\n")
    } else {
        format!("{column}\n")
    };
    out.write_all(header.as_bytes())
        .map_err(ModelError::Write)?;
    let (mut vals, mut temps) = (Vec::with_capacity(BLOCK), Vec::with_capacity(BLOCK));
    let mut buf = Vec::with_capacity(BLOCK * 20);
    let mut rows = 0u64;
    loop {
        vals.clear();
        temps.clear();
        buf.clear();
        let n = next(sim, BLOCK, &mut vals, &mut temps);
        if n == 0 {
            break;
        }
        for i in 0..n {
            fmt(&mut buf, vals[i]);
            if thermal {
                buf.push(b',');
                push_fixed4(&mut buf, temps[i]);
            }
            buf.push(b'\n');
        }
        out.write_all(&buf).map_err(ModelError::Write)?;
        rows += n as u64;
    }
    out.flush().map_err(ModelError::Write)?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ou_discretisation_matches_angle_structure_function() {
        // Total increment variance c^2 s^2 + k^2 s1^2 + resid must equal
        // D(dt) = 2 sigma^2 Tc^2 (h - 1 + e^-h), over 12 decades of h.
        for &h in &[
            1e-9, 1e-6, 1e-3, 0.05, 0.099, 0.1, 0.5, 1.0, 3.0, 30.0, 700.0,
        ] {
            let (sigma, dt) = (0.7, 1e-3);
            let tc = dt / h;
            let (_a, c, k, s1, r) = ou_discretise(sigma, tc, dt);
            let total = c * c * sigma * sigma + k * k * s1 * s1 + r;
            let d = if h < 1e-3 {
                // series of h - 1 + e^-h = h^2/2 - h^3/6 + h^4/24
                2.0 * sigma * sigma * tc * tc * (h * h / 2.0 - h * h * h / 6.0 + h.powi(4) / 24.0)
            } else {
                2.0 * sigma * sigma * tc * tc * (h - 1.0 + (-h).exp())
            };
            assert!((total / d - 1.0).abs() < 1e-9, "h={h}: {total} vs {d}");
            // and the residual alone is the Brownian-bridge value sigma^2 dt^3/(6 Tc) for small h
            if h < 1e-3 {
                let bb = sigma * sigma * dt * dt * dt / (6.0 * tc);
                assert!((r / bb - 1.0).abs() < 1e-3, "h={h}: resid {r} vs {bb}");
            }
        }
    }

    #[test]
    fn fixed_point_formatting() {
        let mut b = Vec::new();
        for v in [0.0, 25.0, -3.14149, 1234.56789, -0.00004, 0.00005] {
            push_fixed4(&mut b, v);
            b.push(b' ');
        }
        push_i64(&mut b, i64::MIN);
        b.push(b' ');
        push_i64(&mut b, -7);
        assert_eq!(
            String::from_utf8(b).unwrap(),
            "0.0000 25.0000 -3.1415 1234.5679 0.0000 0.0001 -9223372036854775808 -7"
        );
    }
}
