//! Phase 1, the reference: the model simulated like the recording.
//!
//! The recording is reduced to its statistics ([`super::stats`]); the model is
//! simulated `runs` times at the recording's length, sample rate, pulse weight
//! and mean input (so that the counter's sawtooth lines land in the same
//! Welch bins), and every run is reduced the same way ([`super::mc`]). The
//! counter's own harmonic lines, whose exact place depends on the record's
//! mean rate and wander, are masked out of the spectral bands first.
//!
//! [`points_against`] gives the compared points of a recording against any
//! model without the rest of the diagnosis: used to judge an effect against
//! the band of the simulator that made the recording (an effect is
//! "concealed" only when the raw Allan deviation misses it against that band)
//! and to measure how far an effect moves each statistic (the power bench).

use std::f64::consts::PI;

use super::compare::Point;
use super::mc;
use super::mc::Progress;
use super::points::{KTerm, all_points, kurtosis_scales};
use super::stats::{self, StatLayout, StatSet};
use super::stream::{self, Extras};
use super::types::{DiagnoseError, DiagnoseOptions, Recording, check_recording};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::units;

/// The recording and the model's Monte-Carlo runs, reduced to the same statistics.
#[derive(Debug, Clone)]
pub struct Reference {
    /// What is computed and where (the counter's line cores masked).
    pub layout: StatLayout,
    /// The recording's statistics.
    pub obs: StatSet,
    /// The model as simulated: the recording's rate, pulse weight and mean input.
    pub model: GyroModel,
    /// The Monte-Carlo runs' statistics.
    pub runs: Vec<StatSet>,
    /// Low-pass cut-offs of the kurtosis statistics (one per model
    /// Gauss-Markov or telegraph term), their tau spans and terms.
    pub cutoffs_hz: Vec<f64>,
    pub kurt_taus: Vec<(f64, f64)>,
    pub kterms: Vec<KTerm>,
    /// Worker threads of the Monte-Carlo runs.
    pub threads: usize,
    /// Told of each Monte-Carlo run.
    pub progress: Progress,
    /// The recording's rate averaged over blocks ([`BlockRate`]).
    pub blocks: BlockRate,
}

/// A recording's rate averaged over consecutive blocks (at most
/// [`BlockRate::MAX_BLOCKS`] of them): what the record holds at periods far
/// longer than a block, in the time domain.
#[derive(Debug, Clone, Default)]
pub struct BlockRate {
    /// Block means, arcsec/s (= deg/h).
    pub mean: Vec<f64>,
    /// Block length, s.
    pub dt_s: f64,
}

impl BlockRate {
    pub const MAX_BLOCKS: usize = 4096;

    pub fn of(counts: &[i64], pulse_arcsec: f64, fs_hz: f64) -> BlockRate {
        let len = counts.len().div_ceil(Self::MAX_BLOCKS).max(1);
        let g = pulse_arcsec * fs_hz;
        let mean = counts
            .chunks_exact(len)
            .map(|b| g * b.iter().sum::<i64>() as f64 / len as f64)
            .collect();
        BlockRate {
            mean,
            dt_s: len as f64 / fs_hz,
        }
    }

    /// The least-squares amplitude (with a mean and a line) of a sinusoid of
    /// period `period_s`, corrected for the block average's attenuation.
    pub fn sine_amplitude(&self, period_s: f64) -> f64 {
        let f = 1.0 / period_s;
        let x = PI * f * self.dt_s;
        let sinc = if x.abs() < 1e-12 { 1.0 } else { x.sin() / x };
        super::line_search::sine_amplitude_ls(&self.mean, self.dt_s, f) / sinc.max(1e-3)
    }
}

impl Reference {
    /// Reduce `rec` and `opts.runs` runs of `model` (checked by the caller).
    pub fn simulate(
        model: &GyroModel,
        rec: &Recording,
        opts: &DiagnoseOptions,
        progress: &Progress,
    ) -> Result<Self, DiagnoseError> {
        let threads = if opts.threads == 0 {
            std::thread::available_parallelism().map_or(1, |n| n.get())
        } else {
            opts.threads
        };
        let n = rec.counts.len();
        let temp = rec.temp_c.as_deref();
        let mut layout = StatLayout::new(n, rec.sample_rate_hz, rec.pulse_arcsec);
        layout.filled = rec.filled.clone();
        layout.rate_words = rec.output == OutputKind::Rate;
        let ks = kurtosis_scales(model);
        let cutoffs_hz: Vec<f64> = ks.iter().map(|k| k.0).collect();
        let kurt_taus: Vec<(f64, f64)> = ks.iter().map(|k| k.1).collect();
        let kterms: Vec<KTerm> = ks.iter().map(|k| k.2).collect();
        let extras = Extras {
            temp_c: temp,
            lp_cutoffs_hz: &cutoffs_hz,
            two_level: None,
            full: true,
        };
        let mut obs = stream::reduce_counts(&layout, &rec.counts, extras);
        let ref_model = reference_model(model, rec, obs.mean_rate);
        mask_counter_lines(&mut layout, &ref_model, &obs);
        obs.band_psd = stats::band_means(&layout, &obs.psd);
        let seeds: Vec<u64> = (0..opts.runs as u64)
            .map(|r| opts.seed.wrapping_add(r))
            .collect();
        let job = mc::McJob {
            model: &ref_model,
            layout: &layout,
            temp_c: temp,
            lp_cutoffs_hz: &cutoffs_hz,
            threads,
            full: true,
            two_level: None,
            phase: "simulating the model",
            progress,
        };
        let runs = mc::run(&job, &seeds)?;
        Ok(Reference {
            layout,
            obs,
            model: ref_model,
            runs,
            cutoffs_hz,
            kurt_taus,
            kterms,
            threads,
            progress: progress.clone(),
            blocks: BlockRate::of(&rec.counts, rec.pulse_arcsec, rec.sample_rate_hz),
        })
    }

    /// A Monte-Carlo job over the reference's layout, for `model`.
    pub fn job<'a>(
        &'a self,
        model: &'a GyroModel,
        temp_c: Option<&'a [f64]>,
        cutoffs_hz: &'a [f64],
    ) -> mc::McJob<'a> {
        mc::McJob {
            model,
            layout: &self.layout,
            temp_c,
            lp_cutoffs_hz: cutoffs_hz,
            threads: self.threads,
            full: true,
            two_level: None,
            phase: "simulating a candidate",
            progress: &self.progress,
        }
    }

    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        self.layout.tau0_s()
    }

    /// Record length, s.
    pub fn duration_s(&self) -> f64 {
        self.layout.n_samples as f64 * self.layout.tau0_s()
    }

    /// Slow rate wander of the recording ([`rate_wander`]).
    pub fn wander(&self) -> f64 {
        let d = self.layout.pulse_arcsec;
        rate_wander(
            &self.layout.levels,
            &self.obs.wvar,
            self.layout.fs_hz,
            self.obs.mean_rate.abs() / d,
        )
    }
}

/// The points (wavelet, MDEV, spectral bands, raw Allan, kurtosis) of `rec`
/// against `opts.runs` Monte-Carlo runs of `model` at the recording's rate,
/// pulse weight and mean input.
pub fn points_against(
    model: &GyroModel,
    rec: &Recording,
    opts: &DiagnoseOptions,
) -> Result<Vec<Point>, DiagnoseError> {
    check_recording(rec, opts)?;
    model.validate()?;
    let r = Reference::simulate(model, rec, opts, &Progress::default())?;
    Ok(all_points(
        &r.layout,
        &r.model,
        &r.obs,
        &r.runs,
        &r.kurt_taus,
    ))
}

/// The model as simulated for the comparison: the recording's sample rate and
/// pulse weight, and a constant input that reproduces the recording's mean rate.
pub(crate) fn reference_model(model: &GyroModel, rec: &Recording, mean_rate: f64) -> GyroModel {
    let mut m = model.clone();
    m.gyro.sample_rate_hz = rec.sample_rate_hz;
    // a rate word's LSB is the model's own (the recording's quantum only counts it)
    if m.gyro.output == OutputKind::Counts {
        m.gyro.pulse_arcsec = rec.pulse_arcsec;
    }
    let dur = rec.counts.len() as f64 / rec.sample_rate_hz;
    // deterministic parts of the model with a non-zero mean over the record
    let ramp = units::dphh_to_arcsec_per_s2(m.noise.rate_ramp_dphh.unwrap_or(0.0)) * dur / 2.0;
    let thermal = m.thermal.as_ref().map_or(0.0, |t| {
        units::dph_to_arcsec_per_s(t.bias_sensitivity_dph_per_c) * t.ramp_c_per_h / units::S_PER_H
            * dur
            / 2.0
    });
    m.gyro.input_rate_dph =
        units::arcsec_per_s_to_dph(mean_rate - ramp - thermal) - m.transient_mean_rate_dph(dur);
    m
}

/// The counter's own lines, `(f_true Hz, half-width Hz)` of each core to mask
/// in a spectrum with bins `df` Hz wide.
///
/// At a constant input `r` the counter's error is a sawtooth of the angle:
/// harmonics `k r / d` with angle amplitude `d/(pi k)`, damped by the dither
/// residual (`exp(-2 pi^2 k^2 s^2)`, `s` = dither/d) and seen in the rate
/// through the first difference (`2 |sin(pi f tau0)| / tau0`, aliased into
/// `[0, fs/2]`). Angle random walk diffuses each harmonic's phase into a
/// Lorentzian of half-width `(2 pi k N/d)^2 / (4 pi)` Hz; slow rate wander
/// (`wander`, arcsec/s: the recording's low-frequency wavelet energy) moves it
/// by `k wander / d`. A harmonic whose peak density exceeds a fifth of the
/// continuum (ARW plus white dither) has its core masked (three widths, plus
/// three bins, plus the wander shift): there the spectrum depends on the exact
/// mean rate and wander of the record, which the Monte-Carlo runs reproduce
/// only in distribution. The tails are left in: they follow from the model's ARW.
pub(crate) fn counter_lines(
    model: &GyroModel,
    mean_rate: f64,
    wander: f64,
    fs: f64,
    d: f64,
    df: f64,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let Some(c) = Counter::new(model, mean_rate, fs, d) else {
        return out;
    };
    for k in 1..=100_000usize {
        let kf = k as f64;
        let Some(Harmonic { f_true, p, bg, .. }) = c.harmonic(kf) else {
            break;
        };
        let gamma = (2.0 * PI * kf * c.arw / d).powi(2) / (4.0 * PI);
        let width = gamma.max(kf * wander / d).max(df);
        let peak = p / (PI * width);
        if peak < 0.2 * bg {
            if 1.0 / kf < 1e-3 && p < 1e-6 * bg * df {
                // later harmonics are weaker still (amplitude ~ 1/k)
                break;
            }
            continue;
        }
        // the core only: the Lorentzian tails follow from the model's ARW and
        // are reproduced by the runs; the core depends on the record's exact
        // mean rate and wander
        let reach = (p * width / (PI * 0.2 * bg) - width * width)
            .max(0.0)
            .sqrt()
            .min(3.0 * width);
        out.push((f_true, reach + 3.0 * df + 4.0 * kf * wander / d));
    }
    out
}

/// A pulse counter's sawtooth, for its harmonics ([`counter_lines`]).
struct Counter {
    /// The fundamental, Hz; the dither residual in pulses and arcsec; the
    /// white rate noise, arcsec/sqrt(s); the pulse weight, arcsec; tau0, s.
    f1: f64,
    s: f64,
    sd_dither: f64,
    arw: f64,
    d: f64,
    tau0: f64,
    fs: f64,
}

/// One harmonic: its frequency (Hz), aliased into `[0, fs/2]`, its power
/// in the rate ((arcsec/s)^2) and the continuum's density under it.
struct Harmonic {
    f_true: f64,
    f_alias: f64,
    p: f64,
    bg: f64,
}

impl Counter {
    /// `None` for a rate word (its rounding is white at a noisy input) or
    /// no mean rate.
    fn new(model: &GyroModel, mean_rate: f64, fs: f64, d: f64) -> Option<Counter> {
        let f1 = mean_rate.abs() / d;
        (f1 > 0.0 && model.gyro.output != OutputKind::Rate).then(|| Counter {
            f1,
            s: model.dither_sigma_arcsec() / d,
            sd_dither: model.dither_sigma_arcsec(),
            arw: units::dpsh_to_arcsec_per_sqrt_s(model.noise.arw_dpsh.unwrap_or(0.0)),
            d,
            tau0: 1.0 / fs,
            fs,
        })
    }

    /// Harmonic `k`; `None` once the dither has damped it below 1e-6.
    fn harmonic(&self, k: f64) -> Option<Harmonic> {
        let damp = (-2.0 * PI * PI * k * k * self.s * self.s).exp();
        if damp < 1e-6 {
            return None;
        }
        let (tau0, fs) = (self.tau0, self.fs);
        let f_true = k * self.f1;
        let a = self.d / (PI * k) * 2.0 * (PI * f_true * tau0).sin().abs() / tau0 * damp;
        let mut fa = f_true.rem_euclid(fs);
        if fa > fs / 2.0 {
            fa = fs - fa;
        }
        let bg = (2.0 * self.arw * self.arw
            + 8.0 * self.sd_dither * self.sd_dither * (PI * fa * tau0).sin().powi(2) / tau0)
            .max(1e-300);
        Some(Harmonic {
            f_true,
            f_alias: fa,
            p: 0.5 * a * a,
            bg,
        })
    }
}

/// The aliased frequencies (Hz) of the counter's harmonics whose power is at
/// least `share` of the continuum's over `band` (relative width) about them,
/// masked core or not: spread by the rate's wander they raise their band.
pub(crate) fn counter_line_hz(
    model: &GyroModel,
    mean_rate: f64,
    fs: f64,
    d: f64,
    band: f64,
    share: f64,
) -> Vec<f64> {
    let Some(c) = Counter::new(model, mean_rate, fs, d) else {
        return Vec::new();
    };
    (1..=100_000usize)
        .map_while(|k| c.harmonic(k as f64))
        .filter(|h| h.p >= share * h.bg * band * h.f_alias)
        .map(|h| h.f_alias)
        .collect()
}

/// Slow rate wander (arcsec/s): the wavelet energy of the levels below
/// `f1 / 2` (`f1` the counter's fundamental, Hz).
pub(crate) fn rate_wander(levels: &[u32], wvar: &[f64], fs: f64, f1: f64) -> f64 {
    levels
        .iter()
        .zip(wvar)
        .filter(|(j, _)| fs / 2f64.powi(**j as i32) <= (f1 / 2.0).max(1e-9))
        .map(|(j, w)| w * 2f64.powi(-(*j as i32)))
        .sum::<f64>()
        .sqrt()
}

/// Mask the counter's own lines ([`counter_lines`]) in the layout's Welch bins.
fn mask_counter_lines(layout: &mut StatLayout, model: &GyroModel, obs: &StatSet) {
    let d = layout.pulse_arcsec;
    let fs = layout.fs_hz;
    let wander = rate_wander(&layout.levels, &obs.wvar, fs, obs.mean_rate.abs() / d);
    let df = layout.bin_width_hz();
    for (f, hw) in counter_lines(model, obs.mean_rate, wander, fs, d, df) {
        layout.mask_line(f, hw);
    }
    layout.rebuild_bands();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slow sinusoid on a mean and a line, in pulse counts: the block
    /// means give back its amplitude (the block average's attenuation undone).
    #[test]
    fn block_rate_gives_a_slow_sinusoids_amplitude() {
        let (fs, pulse, n) = (100.0, 0.5, 1_000_000usize);
        let (amp_dph, period_s) = (40.0, 2_500.0);
        let mut phase = 0.0f64;
        let mut last = 0i64;
        let counts: Vec<i64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                let rate =
                    900.0 + 5.0 * t / 3600.0 + amp_dph * (2.0 * PI * t / period_s + 0.7).sin();
                phase += rate / fs / pulse;
                let c = phase.floor() as i64;
                let d = c - last;
                last = c;
                d
            })
            .collect();
        let b = BlockRate::of(&counts, pulse, fs);
        assert_eq!(
            b.mean.len(),
            n / n.div_ceil(4096),
            "blocks of ceil(n / 4096) samples"
        );
        let a = b.sine_amplitude(period_s);
        assert!((a / amp_dph - 1.0).abs() < 0.01, "{a} against {amp_dph}");
        // far from its period the record holds almost nothing
        assert!(b.sine_amplitude(period_s / 1.7) < 0.1 * amp_dph);
    }
}
