//! Phase 5, the slope tests: a rate ramp and a thermal bias sensitivity, the
//! two effects the wavelets cannot see (sym8 has 8 vanishing moments, so a
//! slow trend does not reach any level).
//!
//! The recording's least-squares rate slope, and with a `temp_c` channel the
//! regression slope of the rate on the temperature, are compared with the
//! model's runs, two-sided at [`super::ALPHA_SLOPE`] each. Their spread is
//! that of the runs, floored by the analytic spread under the model's
//! Gaussian terms, then widened to the larger analytic spread under the model
//! with the broadband changes found (a recording with far more ARW than the
//! model has far larger random slopes) or under the spectrum the recording's
//! own estimator fits (the `analyze` pipeline: low-frequency noise the
//! broadband fit missed or named wrongly). A thermal slope is explained
//! first; the ramp is then tested on what the temperature leaves.

use statrs::distribution::{ContinuousCDF, Normal};

use super::findings::{Edit, Finding, fmt_g, with_findings};
use super::reference::Reference;
use super::stats;
use super::telegraph::mean_sd;
use super::types::{ALPHA_SLOPE, Recording};
use crate::model::config::ThermalParams;
use crate::model::spectrum::model_spectral_terms;
use crate::model::{GyroModel, Term};
use crate::units;

/// The slope tests' outcome.
pub(crate) struct Slopes {
    /// Thermal and ramp findings, in that order.
    pub findings: Vec<Finding>,
    /// z of the rate slope and of the temperature slope (after widening).
    pub ramp_z: f64,
    pub thermal_z: Option<f64>,
    /// Two-sided threshold of each test.
    pub z_slope: f64,
}

impl Slopes {
    /// A slope test fired.
    pub fn significant(&self) -> bool {
        self.ramp_z.abs() > self.z_slope || self.thermal_z.is_some_and(|z| z.abs() > self.z_slope)
    }
}

/// The temperature slope against the model's.
#[derive(Debug, Clone, Copy)]
struct ThermalStat {
    z: f64,
    /// Observed and model slope, arcsec/s per deg C, and the spread of the observed one.
    obs_s: f64,
    sd: f64,
    s0: f64,
    /// The temperature's slope against time, deg C/s, and its correlation with time.
    t_vs_time: f64,
    corr: f64,
}

/// Run the slope tests. `found` are the findings so far (lines, two-level
/// test, broadband fit): the spread is widened to the noise they imply.
pub(crate) fn test(r: &Reference, rec: &Recording, found: &[Finding]) -> Slopes {
    let n = r.layout.n_samples as u64;
    let tau0 = r.tau0_s();
    let runs = r.runs.len() as f64;
    let z_slope = Normal::new(0.0, 1.0)
        .expect("standard normal")
        .inverse_cdf(1.0 - ALPHA_SLOPE / 2.0);
    let slope_sd_an = slope_sd_for(&r.model, n, tau0);
    let slopes: Vec<f64> = r.runs.iter().map(|s| s.slope).collect();
    let (slope_mean, slope_sd) = mean_sd(&slopes);
    let slope_sd0 = slope_sd.max(slope_sd_an) * (1.0 + 1.0 / runs).sqrt();
    // judged against the noise the recording has: the spread under the model
    // with the changes found so far, and at least the spread under the
    // spectrum the recording's own estimator fits
    let noise_model = with_findings(&r.model, found);
    let slope_sd_rec =
        recording_slope_sd(rec, r.layout.fs_hz, r.layout.pulse_arcsec).unwrap_or(0.0);
    let spread_scale = {
        let sd_now = slope_sd_for(&noise_model, n, tau0).max(slope_sd_rec);
        if slope_sd_an > 0.0 && sd_now > slope_sd_an {
            sd_now / slope_sd_an
        } else {
            1.0
        }
    };
    let ramp_z = (r.obs.slope - slope_mean) / slope_sd0 / spread_scale;
    let slope_sd = slope_sd0 * spread_scale;
    let thermal = rec.temp_c.as_deref().map(|t| {
        let mut s = thermal_stat(r, t);
        s.z /= spread_scale;
        s.sd *= spread_scale;
        s
    });
    let mut findings = Vec::new();
    let mut thermal_found = None;
    if let (Some(ts), Some(t)) = (thermal, rec.temp_c.as_deref())
        && ts.z.abs() > z_slope
    {
        findings.push(thermal_finding(&r.model, &ts, t, tau0));
        thermal_found = Some((ts.obs_s - ts.s0, ts.t_vs_time));
    }
    let extra = match thermal_found {
        Some((ds, tt)) => r.obs.slope - ds * tt - slope_mean,
        None => r.obs.slope - slope_mean,
    };
    let ramp_resid_z = match thermal_found {
        Some(_) => extra / slope_sd,
        None => ramp_z,
    };
    if ramp_resid_z.abs() > z_slope {
        findings.push(ramp_finding(&r.model, extra, slope_sd, ramp_resid_z));
    }
    Slopes {
        findings,
        ramp_z,
        thermal_z: thermal.map(|t| t.z),
        z_slope,
    }
}

fn thermal_stat(r: &Reference, t: &[f64]) -> ThermalStat {
    let runs = r.runs.len() as f64;
    let tau0 = r.tau0_s();
    let ts: Vec<f64> = r.runs.iter().filter_map(|s| s.temp_slope).collect();
    let (_, s) = mean_sd(&ts);
    let s0 = units::dph_to_arcsec_per_s(
        r.model
            .thermal
            .as_ref()
            .map_or(0.0, |t| t.bias_sensitivity_dph_per_c),
    );
    let sd = s * (1.0 + 1.0 / runs).sqrt();
    let obs_s = r.obs.temp_slope.unwrap_or(0.0);
    // slope of the temperature against time (collinearity with a ramp)
    let time: Vec<f64> = (0..t.len()).map(|k| k as f64 * tau0).collect();
    let t_vs_time = stats::regression_slope(&time, t);
    let corr = {
        let (_, st) = mean_sd(t);
        let (_, sx) = mean_sd(&time);
        if st > 0.0 { t_vs_time * sx / st } else { 0.0 }
    };
    ThermalStat {
        z: (obs_s - s0) / sd.max(1e-300),
        obs_s,
        sd,
        s0,
        t_vs_time,
        corr,
    }
}

fn thermal_finding(model: &GyroModel, ts: &ThermalStat, t: &[f64], tau0: f64) -> Finding {
    let s_dph = units::arcsec_per_s_to_dph(ts.obs_s);
    let sd_dph = units::arcsec_per_s_to_dph(ts.sd);
    let mut th = fit_temperature_profile(t, tau0, s_dph);
    // the recorded temperature gives the profile; the gyro's lag behind it stays the model's
    th.lag_s = model.thermal.as_ref().map_or(0.0, |t| t.lag_s);
    let sine = match th.sine_period_s {
        Some(p) if th.sine_amplitude_c > 0.0 => {
            format!(
                " + {} C sin(2 pi t / {} s)",
                fmt_g(th.sine_amplitude_c),
                fmt_g(p)
            )
        }
        _ => String::new(),
    };
    let collinear = if ts.corr.abs() > 0.9 {
        " The temperature is nearly linear in time here, so a rate ramp would explain the data as well; \
         the temperature is the physical cause offered."
    } else {
        ""
    };
    let expl = format!(
        "Thermal bias sensitivity: the rate follows the recorded temperature with {} deg/h per deg C \
         (model {}; z = {:.1}). The temperature profile was fitted as {} C + {} C/h{}.{}",
        fmt_g(s_dph),
        fmt_g(units::arcsec_per_s_to_dph(ts.s0)),
        ts.z,
        fmt_g(th.temp_c0),
        fmt_g(th.ramp_c_per_h),
        sine,
        collinear
    );
    let ci = [s_dph - 1.96 * sd_dph, s_dph + 1.96 * sd_dph];
    Finding::scalar(
        Edit::Thermal(th),
        model.thermal.is_some(),
        (
            "thermal.bias_sensitivity_dph_per_c",
            "thermal",
            "bias_sensitivity_dph_per_c",
        ),
        units::arcsec_per_s_to_dph(ts.s0),
        s_dph,
        ci,
        expl,
    )
}

/// A rate ramp of the model's plus `extra` (arcsec/s^2), with spread `sd`.
fn ramp_finding(model: &GyroModel, extra: f64, sd: f64, z: f64) -> Finding {
    let ramp_model = units::dphh_to_arcsec_per_s2(model.noise.rate_ramp_dphh.unwrap_or(0.0));
    let fitted = units::arcsec_per_s2_to_dphh(ramp_model + extra);
    let sd = units::arcsec_per_s2_to_dphh(sd);
    let ci = [fitted - 1.96 * sd, fitted + 1.96 * sd];
    let had = model.noise.rate_ramp_dphh.is_some_and(|v| v != 0.0);
    let t = Term::RateRamp {
        rate_ramp_dphh: fitted,
    };
    let expl = format!(
        "{} The least-squares rate slope is {} deg/h/h (z = {:.1} against the model's runs); \
         the wavelets cannot see a ramp (sym8 has 8 vanishing moments), the long-tau Allan variance does.",
        t.explanation(),
        fmt_g(fitted),
        z
    );
    Finding::scalar(
        Edit::RateRamp(fitted),
        had,
        ("rate_ramp_dphh", "rate_ramp_dphh", "rate_ramp_dphh"),
        model.noise.rate_ramp_dphh.unwrap_or(0.0),
        fitted,
        ci,
        expl,
    )
}

/// Standard deviation of the recording's least-squares rate slope
/// (arcsec/s^2) under the noise spectrum its own estimator fits: the
/// streaming pipeline `sagnac analyze` runs.
fn recording_slope_sd(rec: &Recording, fs: f64, d: f64) -> Option<f64> {
    use crate::pipeline::{Pipeline, PipelineConfig, PipelineOutput};
    let mut pipe = Pipeline::new(&PipelineConfig::counts(fs, d)).ok()?;
    let mut out = PipelineOutput::default();
    for block in rec.counts.chunks(1 << 16) {
        pipe.push_counts(block, &mut out);
        out.clear();
    }
    pipe.finish(&mut out);
    let (_, sd) = pipe.estimator_output().ramp_arcsec_s2?;
    sd.is_finite().then_some(sd)
}

/// Standard deviation of the least-squares rate slope (arcsec/s^2) over `n`
/// samples under the model's Gaussian terms (analytic, from their spectra).
pub(crate) fn slope_sd_for(model: &GyroModel, n: u64, tau0: f64) -> f64 {
    let (terms, theta) = model_spectral_terms(model);
    terms
        .iter()
        .zip(&theta)
        .map(|(t, th)| th * crate::model::estimate::slope_var_per_theta(t, n, tau0))
        .sum::<f64>()
        .sqrt()
}

/// Fit `T(t) = T0 + ramp t + A sin(2 pi t / P)` to the recorded temperature
/// (the sine only when it explains at least half of the residual variance).
pub(crate) fn fit_temperature_profile(t: &[f64], tau0: f64, sens_dph_per_c: f64) -> ThermalParams {
    let n = t.len();
    let time: Vec<f64> = (0..n).map(|k| k as f64 * tau0).collect();
    let slope = stats::regression_slope(&time, t);
    let mt = t.iter().sum::<f64>() / n as f64;
    let mtime = time.iter().sum::<f64>() / n as f64;
    let t0 = mt - slope * mtime;
    let resid: Vec<f64> = (0..n).map(|k| t[k] - t0 - slope * time[k]).collect();
    let var_r = resid.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let mut sine = (0.0, None);
    if var_r > 0.0 {
        // coarse periodogram of the residual over periods from 4 samples... the record
        let dur = n as f64 * tau0;
        let mut best = (0.0, 0.0);
        let mut f = 1.0 / dur;
        while f < 0.25 / tau0 && f < 200.0 / dur {
            let p = stats::dft_plain(&resid, tau0, f).norm();
            if p > best.1 {
                best = (f, p);
            }
            f += 0.5 / dur;
        }
        if best.0 > 0.0 {
            let amp = 2.0 * best.1 / n as f64;
            if amp * amp / 2.0 >= 0.5 * var_r {
                sine = (amp, Some(1.0 / best.0));
            }
        }
    }
    ThermalParams {
        temp_c0: t0,
        ramp_c_per_h: slope * units::S_PER_H,
        sine_amplitude_c: sine.0,
        sine_period_s: sine.1,
        bias_sensitivity_dph_per_c: sens_dph_per_c,
        lag_s: 0.0,
    }
}
