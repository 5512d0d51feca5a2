//! Phase 0, the data-quality stage on the recording (the same code as
//! `analyze`'s, [`crate::quality`]): glitches, a warm-up, bias steps and the
//! thermal response are found and measured first. Glitches are replaced in
//! the recording and marked filled (a counter's pair by its total spread
//! over the two samples, so the angle stays exact). The slow effects are
//! deterministic, so they go into the model the recording is compared with
//! (its Monte-Carlo runs then carry them, with the counter's own
//! quantization of them, which no correction of integer increments could
//! reproduce); a warm-up or a step is then not read as a rate random walk,
//! and a measured temperature response is preferred over a sinusoid or a
//! ramp that only mimics it.
//!
//! The effects found become findings of their own (`warmup`, `bias_step`,
//! `spikes`, `thermal`), reported beside the others and written into the
//! updated model; an effect the model already has with parameters inside
//! the found intervals is consistent.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::ops::Range;

use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::findings::{Edit, Finding, fmt_g};
use super::types::{AddedTerm, ParameterChange};
use super::types::{DiagnoseError, Recording};
use crate::model::GyroModel;
use crate::model::config::{BiasStepParams, OutputKind, SpikesParams, WarmupParams};
use crate::pipeline::{Pipeline, PipelineConfig, PipelineOutput};
use crate::quality::lowfreq::{FineNoise, Interval};
use crate::quality::spikes::{Emitted, Series, SpikeFilter};
use crate::quality::{self, DataQuality};

/// The recording as handled, the model it is compared with, and what was found.
pub(crate) struct Handled<'a> {
    /// The recording itself unless glitches were taken out of it.
    pub recording: Cow<'a, Recording>,
    /// The model with the slow effects found (glitches left out: the
    /// recording is cleared of them).
    pub compared: GyroModel,
    pub findings: Vec<Finding>,
    pub data_quality: Option<DataQuality>,
}

impl<'a> Handled<'a> {
    /// Nothing handled (`--raw-statistics`).
    pub fn none(model: &GyroModel, rec: &'a Recording) -> Handled<'a> {
        Handled {
            recording: Cow::Borrowed(rec),
            compared: model.clone(),
            findings: Vec::new(),
            data_quality: None,
        }
    }

    /// The updated model: the diagnosis's (or the compared model, when only
    /// this stage found something), with the glitches found.
    pub fn updated(&self, diagnosed: Option<GyroModel>) -> Option<GyroModel> {
        if self.findings.is_empty() {
            return diagnosed;
        }
        let mut m = diagnosed.unwrap_or_else(|| self.compared.clone());
        for f in &self.findings {
            if let Edit::Spikes(_) = f.edit {
                f.edit.apply(&mut m);
            }
        }
        Some(m)
    }
}

/// Run the stage on `rec`, handle it, and turn what it found into findings.
pub(crate) fn handle<'a>(
    model: &GyroModel,
    rec: &'a Recording,
) -> Result<Handled<'a>, DiagnoseError> {
    let k = rec.pulse_arcsec * rec.sample_rate_hz;
    let counts = rec.output == OutputKind::Counts;
    let pipe = first_pass(rec, counts, k)?;
    let est = pipe.estimator_output().estimates;
    let fine = FineNoise {
        arw_dpsh: est.arw_dpsh.value.unwrap_or(0.0),
        quantization_arcsec: est.quantization_arcsec.value.unwrap_or(0.0),
    };
    let spikes = pipe.spike_report().cloned().unwrap_or_default();
    let series = pipe
        .block_series()
        .expect("the data-quality stage keeps block means");
    // a ramp the stage's test supports is looked at again as a warm-up or a
    // step ([`quality::lowfreq`]): the diagnosis names the physics
    let (dq, _) = quality::assess(&spikes, &series, fine, true);
    let mut recording = Cow::Borrowed(rec);
    if spikes.excluded > 0 {
        exclude_glitches(recording.to_mut(), counts, k);
    }
    let spike_amp_dph = if counts {
        spikes.max_abs * k
    } else {
        spikes.max_abs
    };
    let findings = findings(model, &dq, rec, spike_amp_dph);
    let mut compared = model.clone();
    compared.noise.spikes = None;
    if findings.iter().any(|f| matches!(f.edit, Edit::BiasStep(_))) {
        compared.noise.bias_step.clear();
    }
    for f in findings
        .iter()
        .filter(|f| !matches!(f.edit, Edit::Spikes(_)))
    {
        f.edit.apply(&mut compared);
    }
    Ok(Handled {
        recording,
        compared,
        findings,
        data_quality: Some(dq),
    })
}

/// The recording through a pipeline with the data-quality stage on.
fn first_pass(rec: &Recording, counts: bool, k: f64) -> Result<Pipeline, DiagnoseError> {
    let fs = rec.sample_rate_hz;
    let cfg = if counts {
        PipelineConfig::counts(fs, rec.pulse_arcsec)
    } else {
        PipelineConfig::rates(fs)
    };
    let mut pipe = Pipeline::new(&cfg).map_err(|e| DiagnoseError::Options(e.to_string()))?;
    let mut out = PipelineOutput::default();
    let mut spans = Vec::new();
    let mut rates = Vec::new();
    for start in (0..rec.counts.len()).step_by(1 << 16) {
        let end = (start + (1 << 16)).min(rec.counts.len());
        spans_in(&rec.filled, start..end, &mut spans);
        if let Some(t) = &rec.temp_c {
            pipe.push_temperature(start as u64, &t[start..end]);
        }
        let chunk = &rec.counts[start..end];
        if counts {
            pipe.push_counts_filled(chunk, &spans, &mut out);
        } else {
            rates.clear();
            rates.extend(chunk.iter().map(|&c| c as f64 * k));
            pipe.push_rates_dph_filled(&rates, &spans, &mut out)
                .map_err(|e| DiagnoseError::Options(e.to_string()))?;
        }
        out.clear();
    }
    pipe.finish(&mut out);
    Ok(pipe)
}

/// The spans of `filled` inside `range`, relative to its start (ends kept whole).
fn spans_in(filled: &[Range<usize>], range: Range<usize>, out: &mut Vec<Range<usize>>) {
    out.clear();
    for r in filled {
        if r.end > range.start && r.start < range.end {
            out.push(r.start.max(range.start) - range.start..r.end - range.start);
        }
    }
}

/// Replace the glitches the stage excluded (the same windows and decisions
/// as its first pass) and mark them filled.
fn exclude_glitches(rec: &mut Recording, counts: bool, k: f64) {
    let mut out = Emitted::default();
    if counts {
        let mut f = SpikeFilter::new(Series::Counts);
        f.push_counts(&rec.counts, &rec.filled, &mut out);
        f.finish(&mut out);
        rec.counts = out.counts;
    } else {
        let rates: Vec<f64> = rec.counts.iter().map(|&c| c as f64 * k).collect();
        let mut f = SpikeFilter::new(Series::Rates);
        f.push_rates(&rates, &rec.filled, &mut out);
        f.finish(&mut out);
        rec.counts = out.rates.iter().map(|r| (r / k).round() as i64).collect();
    }
    let mut spans = out.filled;
    spans.sort_by_key(|r| r.start);
    spans.dedup();
    rec.filled = spans;
}

fn inside(v: f64, i: &Interval) -> bool {
    i.ci95[0] <= v && v <= i.ci95[1]
}

/// An added term of several parameters.
fn added(term: &str, params: &[(&str, Interval)], explanation: String) -> AddedTerm {
    AddedTerm {
        term: term.into(),
        kind: None,
        params: params
            .iter()
            .map(|(k, i)| (k.to_string(), i.value))
            .collect(),
        ci95: params
            .iter()
            .map(|(k, i)| (k.to_string(), i.ci95))
            .collect(),
        explanation,
    }
}

/// The findings of the stage, against what the model already has.
fn findings(
    model: &GyroModel,
    dq: &DataQuality,
    rec: &Recording,
    spike_amp_dph: f64,
) -> Vec<Finding> {
    let mut out = Vec::new();
    if let Some(w) = &dq.warmup {
        let consistent = model.noise.warmup.as_ref().is_some_and(|m| {
            inside(m.amplitude_dph, &w.amplitude_dph) && inside(m.tau_s, &w.tau_s)
        });
        if !consistent {
            out.push(warmup_finding(model, w.amplitude_dph, w.tau_s));
        }
    }
    for s in &dq.steps {
        let known = model
            .noise
            .bias_step
            .iter()
            .any(|m| inside(m.at_s, &s.at_s) && inside(m.amplitude_dph, &s.amplitude_dph));
        if !known {
            let note = format!(
                "Bias step: the bias jumps by {} deg/h [{}, {}] at {} s [{}, {}] (a change-point scan of the block \
                 means against the recording's own fitted noise, rate random walk included); added to the model the \
                 recording is compared with, so it is not read as a rate random walk.",
                fmt_g(s.amplitude_dph.value),
                fmt_g(s.amplitude_dph.ci95[0]),
                fmt_g(s.amplitude_dph.ci95[1]),
                fmt_g(s.at_s.value),
                fmt_g(s.at_s.ci95[0]),
                fmt_g(s.at_s.ci95[1])
            );
            out.push(Finding {
                edit: Edit::BiasStep(BiasStepParams {
                    at_s: s.at_s.value,
                    amplitude_dph: s.amplitude_dph.value,
                }),
                changes: Vec::new(),
                added: Some(added(
                    "bias_step",
                    &[("at_s", s.at_s), ("amplitude_dph", s.amplitude_dph)],
                    note.clone(),
                )),
                n_par: 2,
                note,
            });
        }
    }
    let duration_h = rec.counts.len() as f64 / rec.sample_rate_hz / 3600.0;
    if dq.outliers.count > 0 && dq.outliers.excluded && model.noise.spikes.is_none() {
        out.push(spikes_finding(dq.outliers.count, duration_h, spike_amp_dph));
    }
    if let Some(t) = dq.thermal.as_ref().filter(|t| t.compensated)
        && let Some(f) = thermal_finding(model, t, rec)
    {
        out.push(f);
    }
    out
}

fn warmup_finding(model: &GyroModel, a: Interval, tau: Interval) -> Finding {
    let note = format!(
        "Warm-up: the bias settles by {} deg/h [{}, {}] with a time constant of {} s [{}, {}] (an exponential \
         scan of the block means against the recording's own fitted noise, rate random walk included); added \
         to the model the recording is compared with, so it is not read as a rate random walk or a ramp.",
        fmt_g(-a.value),
        fmt_g(-a.ci95[1]),
        fmt_g(-a.ci95[0]),
        fmt_g(tau.value),
        fmt_g(tau.ci95[0]),
        fmt_g(tau.ci95[1])
    );
    let edit = Edit::Warmup(WarmupParams {
        amplitude_dph: a.value,
        tau_s: tau.value,
    });
    match &model.noise.warmup {
        Some(m) => Finding {
            edit,
            changes: vec![
                ParameterChange {
                    term: "warmup.amplitude_dph".into(),
                    model: m.amplitude_dph,
                    fitted: a.value,
                    ci95: a.ci95,
                },
                ParameterChange {
                    term: "warmup.tau_s".into(),
                    model: m.tau_s,
                    fitted: tau.value,
                    ci95: tau.ci95,
                },
            ],
            added: None,
            n_par: 2,
            note,
        },
        None => Finding {
            edit,
            changes: Vec::new(),
            added: Some(added(
                "warmup",
                &[("amplitude_dph", a), ("tau_s", tau)],
                note.clone(),
            )),
            n_par: 2,
            note,
        },
    }
}

/// Glitches: their count, their rate per hour with its exact Poisson
/// interval, and the largest seen.
fn spikes_finding(count: u64, duration_h: f64, amp_dph: f64) -> Finding {
    let n = count as f64;
    let lo = ChiSquared::new(2.0 * n).map_or(0.0, |c| c.inverse_cdf(0.025) / 2.0);
    let hi = ChiSquared::new(2.0 * n + 2.0).map_or(f64::INFINITY, |c| c.inverse_cdf(0.975) / 2.0);
    let rate = n / duration_h;
    let note = format!(
        "Spikes: {count} single-sample glitches ({} per hour, up to {} deg/h), excluded as gaps before the rest of \
         the diagnosis (a robust test on the sample's departure from its neighbours, 6 sigma of the recording's own \
         noise).",
        fmt_g(rate),
        fmt_g(amp_dph)
    );
    let mut params = BTreeMap::new();
    params.insert("count".to_string(), n);
    params.insert("rate_per_h".to_string(), rate);
    params.insert("amplitude_dph".to_string(), amp_dph);
    let mut ci95 = BTreeMap::new();
    ci95.insert("rate_per_h".to_string(), [lo / duration_h, hi / duration_h]);
    Finding {
        edit: Edit::Spikes(SpikesParams {
            rate_per_h: rate,
            amplitude_dph: amp_dph,
        }),
        changes: Vec::new(),
        added: Some(AddedTerm {
            term: "spikes".into(),
            kind: None,
            params,
            ci95,
            explanation: note.clone(),
        }),
        n_par: 1,
        note,
    }
}

/// The measured temperature's effect: a change of the model's sensitivity
/// (and lag) or, for a model without `[thermal]`, the term with the recorded
/// temperature's profile.
fn thermal_finding(model: &GyroModel, t: &quality::ThermalFit, rec: &Recording) -> Option<Finding> {
    let s = t.bias_sensitivity_dph_per_c;
    let lag = t.lag_s;
    if let Some(m) = &model.thermal
        && inside(m.bias_sensitivity_dph_per_c, &s)
        && inside(m.lag_s, &lag)
    {
        return None;
    }
    let temps = rec.temp_c.as_deref()?;
    let tau0 = 1.0 / rec.sample_rate_hz;
    let mut th = super::slopes::fit_temperature_profile(temps, tau0, s.value);
    th.lag_s = lag.value;
    let behind = if t.confounded_with_ramp {
        "the lag not identified (the temperature changed linearly over the record, so a lag only shifts the \
         bias's constant, and a rate ramp of the gyro's own cannot be told from this response)"
            .to_string()
    } else {
        format!(
            "{} s [{}, {}] behind it",
            fmt_g(lag.value),
            fmt_g(lag.ci95[0]),
            fmt_g(lag.ci95[1])
        )
    };
    let note = format!(
        "Thermal bias sensitivity: the bias follows the recorded temperature with {} deg/h per deg C [{}, {}], \
         {behind} (a regression of the block means on the delayed temperature against the \
         recording's own fitted noise); the measured cause is preferred over a sinusoid or a ramp that only mimics \
         it, and it is added to the model the recording is compared with (the recorded temperature's profile).",
        fmt_g(s.value),
        fmt_g(s.ci95[0]),
        fmt_g(s.ci95[1]),
    );
    Some(match &model.thermal {
        Some(m) => {
            let mut changes = vec![ParameterChange {
                term: "thermal.bias_sensitivity_dph_per_c".into(),
                model: m.bias_sensitivity_dph_per_c,
                fitted: s.value,
                ci95: s.ci95,
            }];
            // the model's lag stands where its interval holds it, or where
            // the lag is not identified
            if t.confounded_with_ramp || inside(m.lag_s, &lag) {
                th.lag_s = m.lag_s;
            } else {
                changes.push(ParameterChange {
                    term: "thermal.lag_s".into(),
                    model: m.lag_s,
                    fitted: lag.value,
                    ci95: lag.ci95,
                });
            }
            Finding {
                edit: Edit::Thermal(th),
                changes,
                added: None,
                n_par: 2,
                note,
            }
        }
        None => Finding {
            edit: Edit::Thermal(th),
            changes: Vec::new(),
            added: Some(added(
                "thermal",
                &[("bias_sensitivity_dph_per_c", s), ("lag_s", lag)],
                note.clone(),
            )),
            n_par: 2,
            note,
        },
    })
}
