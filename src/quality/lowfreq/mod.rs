//! The slow effects of a bench run: a warm-up (an exponential settling of
//! the bias), bias steps, and the bias's response to temperature; each
//! found by a test calibrated on the record's own noise, then estimated with
//! intervals, and turned into a [`Correction`] of the rate.
//!
//! The method, on the record's block means ([`model::Coarse`], at most
//! [`MAX_BLOCKS`] blocks):
//! 1. the mean model is a constant and a rate ramp; the noise is the
//!    fine-scale white noise (known) plus flicker and rate random walk, fitted
//!    by REML ([`model::Noise::fit`]);
//! 2. three scans ([`scan`]) look for one more regressor: a warm-up over a
//!    grid of time constants, a step at every block boundary, and (with a
//!    temperature) the thermal response over a grid of lags; each scan's
//!    threshold is its own maximum's null level at [`ALPHA`];
//! 3. the scan that beats its threshold by the largest factor adds its
//!    regressor, the noise is refitted, and the scans run again (a warm-up
//!    and a thermal response once, steps up to [`MAX_STEPS`]);
//! 4. each shape parameter (time constant, step time, lag) is refined by
//!    golden-section search and given its profile-likelihood interval; each
//!    amplitude its profile interval over the shape parameter's interval.
//!
//! Rate random walk and a ramp stay in the null model, so a random walk or a
//! ramp of the gyro's own is not taken for a step or a warm-up; and a step or
//! a warm-up is found against them, so it is not read as a random walk.

use serde::{Deserialize, Serialize};

use super::blocks::BlockSeries;

pub use model::FineNoise;
use model::{Coarse, Fitted, Noise};
use scan::NoiseGrid;

pub mod model;
pub mod scan;

/// Most blocks of the analysis.
pub const MAX_BLOCKS: usize = 160;
/// Fewest blocks worth an analysis.
pub const MIN_BLOCKS: usize = 16;
/// False-alarm probability of each scan, per record.
pub const ALPHA: f64 = 0.002;
/// Most steps found.
pub const MAX_STEPS: usize = 5;
/// The profile likelihood's 95 % level (chi-square, 1 degree of freedom).
const CHI2_95: f64 = 3.841_458_820_694_124;
/// The standard normal's 97.5 % point.
const Z_975: f64 = 1.959_963_984_540_054;

/// A value with its 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub value: f64,
    pub ci95: [f64; 2],
}

/// A fitted warm-up: the bias is `amplitude * exp(-t/tau)` away from its
/// settled value at time `t` after the start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WarmupFit {
    pub amplitude_dph: Interval,
    pub tau_s: Interval,
}

/// A fitted bias step: the bias jumps by `amplitude` at `at`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepFit {
    pub at_s: Interval,
    pub amplitude_dph: Interval,
}

/// The bias's response to temperature, delayed by `lag`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThermalFit {
    pub bias_sensitivity_dph_per_c: Interval,
    pub lag_s: Interval,
    /// The response is significant, and the rate is compensated for it.
    pub compensated: bool,
}

/// What the analysis found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LowFreq {
    pub warmup: Option<WarmupFit>,
    pub steps: Vec<StepFit>,
    pub thermal: Option<ThermalFit>,
    /// The fitted flicker and random-walk coefficients of the noise left,
    /// deg/h and deg/h/sqrt(h).
    pub bias_instability_dph: f64,
    pub rrw_dphsh: f64,
    /// What to subtract from the rate.
    pub correction: Correction,
}

/// What to subtract from the rate: a function of time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Correction {
    warmup: Option<(f64, f64)>,
    steps: Vec<(f64, f64)>,
    thermal: Option<ThermalCorrection>,
}

#[derive(Debug, Clone, PartialEq)]
struct ThermalCorrection {
    sensitivity: f64,
    lag_s: f64,
    reference_c: f64,
    temp: Temperature,
}

impl Correction {
    /// Whether it corrects a thermal response.
    pub fn has_thermal(&self) -> bool {
        self.thermal.is_some()
    }

    /// Nothing to correct.
    pub fn is_empty(&self) -> bool {
        self.warmup.is_none() && self.steps.is_empty() && self.thermal.is_none()
    }

    /// The correction's mean over `[t0, t1)` (s from the record's start), deg/h.
    pub fn mean_dph(&self, t0: f64, t1: f64) -> f64 {
        let d = t1 - t0;
        let mut v = 0.0;
        if let Some((a, tau)) = self.warmup {
            v += a * tau / d * ((-t0 / tau).exp() - (-t1 / tau).exp());
        }
        for &(at, amp) in &self.steps {
            v += amp * ((t1 - at) / d).clamp(0.0, 1.0);
        }
        if let Some(t) = &self.thermal {
            v += t.sensitivity * (t.temp.at(0.5 * (t0 + t1) - t.lag_s) - t.reference_c);
        }
        v
    }
}

/// The temperature at any time, interpolated linearly between block means
/// (held at the ends).
#[derive(Debug, Clone, PartialEq)]
struct Temperature {
    block_s: f64,
    values: Vec<f64>,
}

impl Temperature {
    fn at(&self, t: f64) -> f64 {
        let x = t / self.block_s - 0.5;
        if x <= 0.0 {
            return self.values[0];
        }
        let i = x.floor() as usize;
        if i + 1 >= self.values.len() {
            return *self.values.last().expect("a temperature series has values");
        }
        let f = x - i as f64;
        self.values[i] * (1.0 - f) + self.values[i + 1] * f
    }
}

/// One effect in the mean model, by its shape parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Effect {
    Warmup { tau_s: f64 },
    Step { at_s: f64 },
    Thermal { lag_s: f64 },
}

/// The analysis's working state.
struct Analysis<'a> {
    c: Coarse,
    noise: Noise,
    temp: Option<Temperature>,
    series: &'a BlockSeries,
    span_s: f64,
}

/// Find, test and fit the slow effects of `series` (block means), given the
/// fine-scale noise; `None` when the record is too short for it.
pub fn analyse(series: &BlockSeries, fine: FineNoise) -> Option<LowFreq> {
    let c = coarsen(series)?;
    let temp = series
        .temp_c
        .as_ref()
        .filter(|t| t.iter().any(|v| (v - t[0]).abs() > 1e-9))
        .map(|t| Temperature {
            block_s: series.block_s,
            values: t.clone(),
        });
    let a = Analysis {
        noise: Noise::new(&c, fine),
        span_s: c.len() as f64 * c.block_s,
        c,
        temp,
        series,
    };
    let effects = a.select()?;
    a.report(effects)
}

/// The block means at no more than [`MAX_BLOCKS`] blocks (whole merges of the
/// accumulator's blocks; a last block shorter than half the others dropped).
fn coarsen(s: &BlockSeries) -> Option<Coarse> {
    let fine = s.rate_dph.len();
    let g = fine.div_ceil(MAX_BLOCKS).max(1);
    let mut y = Vec::new();
    let mut n = Vec::new();
    for chunk in s.rate_dph.chunks(g).zip(s.n.chunks(g)) {
        let (r, m) = chunk;
        let tot: u64 = m.iter().sum();
        if r.len() * 2 < g || tot == 0 {
            break;
        }
        let sum: f64 = r
            .iter()
            .zip(m)
            .filter(|(_, k)| **k > 0)
            .map(|(v, k)| v * *k as f64)
            .sum();
        y.push(sum / tot as f64);
        n.push(tot);
    }
    // a last chunk shorter than the blocks is not a full block
    let full = s.samples as f64 * s.tau0_s / (g as f64 * s.block_s);
    if (y.len() as f64) > full.floor() && full.fract() < 0.5 {
        y.pop();
        n.pop();
    }
    (y.len() >= MIN_BLOCKS).then(|| Coarse {
        block_s: g as f64 * s.block_s,
        y,
        n,
        tau0_s: s.tau0_s,
    })
}

impl Analysis<'_> {
    /// Columns of the mean model with `effects`.
    fn columns(&self, effects: &[Effect]) -> Vec<Vec<f64>> {
        let n = self.c.len();
        let mut cols = vec![
            vec![1.0; n],
            (0..n)
                .map(|b| (b as f64 + 0.5) * self.c.block_s / 3600.0)
                .collect(),
        ];
        cols.extend(effects.iter().map(|e| self.regressor(*e)));
        cols
    }

    /// The block means of one effect of unit amplitude.
    fn regressor(&self, e: Effect) -> Vec<f64> {
        let t = self.c.block_s;
        (0..self.c.len())
            .map(|b| {
                let (t0, t1) = (self.c.t0(b), self.c.t0(b) + t);
                match e {
                    Effect::Warmup { tau_s } => {
                        tau_s / t * ((-t0 / tau_s).exp() - (-t1 / tau_s).exp())
                    }
                    Effect::Step { at_s } => ((t1 - at_s) / t).clamp(0.0, 1.0),
                    Effect::Thermal { lag_s } => {
                        let temp = self
                            .temp
                            .as_ref()
                            .expect("a thermal effect has a temperature");
                        // the block mean of T(t - lag), from the fine blocks inside
                        let k = 8;
                        (0..k)
                            .map(|i| temp.at(t0 + (i as f64 + 0.5) * t / k as f64 - lag_s))
                            .sum::<f64>()
                            / k as f64
                    }
                }
            })
            .collect()
    }

    fn fit(&self, effects: &[Effect]) -> Option<Fitted> {
        self.noise
            .fit(&self.c.y, &self.columns(effects), self.span_s)
    }

    /// The candidates given the effects already in the model: (kind, shape
    /// parameters, regressors); kind 0 a warm-up, 1 a step, 2 thermal.
    fn candidates(&self, effects: &[Effect]) -> Vec<(u8, Vec<f64>, Vec<Vec<f64>>)> {
        let n = self.c.len();
        let t = self.c.block_s;
        let mut out = Vec::new();
        let mut add = |kind: u8, params: Vec<f64>, make: &dyn Fn(f64) -> Effect| {
            let cols = params.iter().map(|&p| self.regressor(make(p))).collect();
            out.push((kind, params, cols));
        };
        if !effects.iter().any(|e| matches!(e, Effect::Warmup { .. })) {
            add(0, log_grid(0.5 * t, self.span_s / 3.0, 24), &|tau_s| {
                Effect::Warmup { tau_s }
            });
        }
        let steps = effects
            .iter()
            .filter(|e| matches!(e, Effect::Step { .. }))
            .count();
        if steps < MAX_STEPS {
            let ats = (2..n - 2).map(|b| b as f64 * t).collect();
            add(1, ats, &|at_s| Effect::Step { at_s });
        }
        if self.temp.is_some() && !effects.iter().any(|e| matches!(e, Effect::Thermal { .. })) {
            add(2, lag_grid(t, self.span_s), &|lag_s| Effect::Thermal {
                lag_s,
            });
        }
        out
    }

    /// Steps 1-3 of the method: the effects the record holds.
    fn select(&self) -> Option<Vec<Effect>> {
        let mut effects: Vec<Effect> = Vec::new();
        let (scale_b, scale_k) = Noise::scales(&self.c.y, self.span_s);
        for round in 0..(MAX_STEPS + 2) {
            let x = self.columns(&effects);
            let fitted = self.fit(&effects)?;
            let grid = NoiseGrid::new(&self.noise, &x, fitted.b2, fitted.k2, scale_b, scale_k);
            let mut best: Option<(f64, Effect)> = None;
            for (kind, params, cols) in self.candidates(&effects) {
                let scan = grid.scan(params, cols);
                let Some((i, lr)) = grid.best(&scan, &self.c.y) else {
                    continue;
                };
                // the threshold is at least one chi-square(1) test's: below
                // it the scan's maximum cannot pass, whatever the replicas say
                if lr <= scan::floor(ALPHA) {
                    continue;
                }
                let seed = 0x5D_A7A ^ ((round as u64) << 8) ^ u64::from(kind);
                let limit = grid.threshold(&scan, &fitted.chol, ALPHA, seed);
                let ratio = lr / limit;
                let p = scan.params[i];
                let effect = match kind {
                    0 => Effect::Warmup { tau_s: p },
                    1 => Effect::Step { at_s: p },
                    _ => Effect::Thermal { lag_s: p },
                };
                if ratio > 1.0 && best.is_none_or(|b| ratio > b.0) {
                    best = Some((ratio, effect));
                }
            }
            match best {
                Some((_, e)) => effects.push(e),
                None => break,
            }
        }
        Some(effects)
    }
}

/// `n` points evenly spaced on a log scale from `lo` to `hi`.
fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(hi > lo) {
        return vec![lo];
    }
    (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// Lags from 0 to a quarter of the record (at most an hour), half a block apart.
fn lag_grid(block_s: f64, span_s: f64) -> Vec<f64> {
    let top = (0.25 * span_s).min(3600.0);
    let step = (0.5 * block_s).max(top / 64.0);
    (0..)
        .map(|i| i as f64 * step)
        .take_while(|l| *l <= top)
        .collect()
}

mod report;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// Block means of white noise of sd `sd` per block, plus `f(t)`.
    fn series(n: usize, block_s: f64, sd: f64, seed: u64, f: impl Fn(f64) -> f64) -> BlockSeries {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let tau0 = 0.005;
        let per = (block_s / tau0) as u64;
        BlockSeries {
            block_s,
            t0_s: (0..n).map(|b| b as f64 * block_s).collect(),
            rate_dph: (0..n)
                .map(|b| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    sd * z + f((b as f64 + 0.5) * block_s)
                })
                .collect(),
            n: vec![per; n],
            temp_c: None,
            samples: per * n as u64,
            tau0_s: tau0,
        }
    }

    /// The white noise whose block means have standard deviation `sd`:
    /// (60 N)^2 / block_s = sd^2.
    fn white_for(sd: f64, block_s: f64) -> FineNoise {
        FineNoise {
            arw_dpsh: sd * block_s.sqrt() / 60.0,
            quantization_arcsec: 0.0,
        }
    }

    #[test]
    fn a_warm_up_in_white_block_noise_is_found_and_clean_noise_gives_nothing() {
        let sd = 0.8;
        let s = series(160, 15.0, sd, 1, |t| 5.0 * (-t / 300.0).exp());
        let f = white_for(sd, 15.0);
        let low = analyse(&s, f).unwrap();
        let w = low.warmup.expect("the warm-up");
        assert!(
            w.amplitude_dph.ci95[0] <= 5.0 && 5.0 <= w.amplitude_dph.ci95[1],
            "{w:?}"
        );
        assert!(
            w.tau_s.ci95[0] <= 300.0 && 300.0 <= w.tau_s.ci95[1],
            "{w:?}"
        );
        assert!(low.steps.is_empty());
        let clean = analyse(&series(160, 15.0, sd, 2, |_| 0.0), f).unwrap();
        assert!(
            clean.warmup.is_none() && clean.steps.is_empty(),
            "{clean:?}"
        );
    }
}
