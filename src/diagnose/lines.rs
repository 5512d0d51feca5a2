//! Phase 3, lines: narrow spectral lines at the whole record's resolution
//! ([`super::line_search`]) become sinusoid findings.
//!
//! The rate (mean and trend removed) is searched from ten cycles per record to
//! Nyquist against the model's own PSD, with the counter's harmonic line cores
//! masked ([`super::reference::counter_lines`]). Then:
//! * A line near one of the model's sinusoids (within three bins or five of
//!   its frequency standard deviations) is that sinusoid: it is a finding only
//!   when its amplitude or its frequency differs from the model's by more than
//!   the Bonferroni z over the model's sinusoids (family-wise
//!   [`super::ALPHA_LINES`]); then both are reported as parameter changes.
//! * Any other line is a new sinusoid with the line's amplitude and period.
//! * A model sinusoid without a line is measured at its own frequency (least
//!   squares, the local continuum from the spectrum): a significantly weaker
//!   or stronger amplitude is a parameter change.
//!
//! Every interval is the line fit's Fisher interval ([`super::line_search::LineFit`]).

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::sync::Arc;

use statrs::distribution::{ContinuousCDF, Normal};

use super::compare::{self, LineHit};
use super::findings::{Edit, Finding, fmt_g};
use super::line_search::{self as lines, Detection, LineFit};
use super::narrowband;
use super::reference::{Reference, counter_line_hz, counter_lines, rate_wander};
use super::stats::{self, StatLayout};
use super::types::{ALPHA_LINES, Recording};
use super::types::{AddedTerm, ParameterChange};
use crate::model::config::SinusoidParams;
use crate::model::spectrum::model_psd;
use crate::model::{GyroModel, Term};
use crate::units;

/// The whole-record line search of a recording ([`super::line_search`]).
#[derive(Debug, Clone)]
pub struct LineScan {
    /// The periodogram searched ([`lines::LineSpectrum::psd`]) of the
    /// `n`-sample record at `fs_hz`.
    pub psd: Arc<Vec<f64>>,
    pub n: usize,
    pub fs_hz: f64,
    /// Detected lines with their fits, strongest first.
    pub lines: Vec<(lines::Detection, lines::LineFit)>,
    /// The counter's line cores left out, `(f_true Hz, half-width Hz)`.
    pub masked: Vec<(f64, f64)>,
    /// Each model sinusoid measured at its own frequency: the local continuum
    /// PSD and the amplitude (arcsec/s); none outside the band searched or
    /// without a local reference.
    pub sine_checks: Vec<Option<(f64, f64)>>,
    /// The rate's mean (arcsec/s).
    pub mean_rate: f64,
}

/// The search parameters of the diagnosis (family-wise [`ALPHA_LINES`]).
pub fn search_params() -> lines::SearchParams {
    lines::SearchParams {
        alpha: ALPHA_LINES,
        ..lines::SearchParams::default()
    }
}

/// The line phase of the diagnosis: scan the recording against the reference
/// model and turn the lines into findings.
pub(crate) fn find(r: &Reference, rec: &Recording) -> LineFindings {
    let (fs, d) = (r.layout.fs_hz, r.layout.pulse_arcsec);
    let params = search_params();
    let scan = scan_lines(&r.model, &rec.counts, fs, d, r.wander(), &params);
    let found = line_findings(&scan, &r.model);
    LineFindings {
        periodogram: Some(Periodogram {
            detections: scan.lines.iter().map(|(det, _)| *det).collect(),
            mean_rate: scan.mean_rate,
            n: scan.n,
            // the periodogram alone: each use whitens it by its own model
            psd: scan.psd,
        }),
        ..found
    }
}

/// The line search's periodogram, kept for [`excess`].
#[derive(Debug)]
pub(crate) struct Periodogram {
    /// [`lines::LineSpectrum::psd`] of the `n`-sample record.
    psd: Arc<Vec<f64>>,
    n: usize,
    mean_rate: f64,
    /// The lines detected (their bins are left out).
    detections: Vec<Detection>,
}

/// A narrowband excess of the recording's spectrum over `model`'s (the
/// updated model: what its terms, a readout filter's side lobes included,
/// explain is not an excess), the detected lines' bins left out.
/// Returned with the periodogram whitened by `model` (the resonance fit's input).
pub(crate) fn excess(
    r: &Reference,
    p: &Periodogram,
    model: &GyroModel,
) -> (Option<narrowband::Excess>, lines::LineSpectrum) {
    let (fs, d) = (r.layout.fs_hz, r.layout.pulse_arcsec);
    let df = fs / p.n as f64;
    let masked = counter_lines(model, p.mean_rate, r.wander(), fs, d, df);
    let spectrum =
        lines::LineSpectrum::whitened(p.psd.clone(), p.n, fs, &model_psd(model), &masked);
    let counter_hz = counter_line_hz(model, p.mean_rate, fs, d, narrowband::BAND, 0.01);
    (
        narrowband::find(&spectrum, &p.detections, &counter_hz, ALPHA_LINES),
        spectrum,
    )
}

/// Scan the rate of `counts` (pulse `d`, rate `fs`) for lines against
/// `model` (simulated at the recording's rate and pulse weight); `wander` is
/// [`rate_wander`]. The rate, its mean and linear trend removed, is read
/// from the counts by the transform and by each line fit, never held.
fn scan_lines(
    model: &GyroModel,
    counts: &[i64],
    fs: f64,
    d: f64,
    wander: f64,
    params: &lines::SearchParams,
) -> LineScan {
    let n = counts.len();
    let g = d * fs;
    let rate = |i: usize| counts[i] as f64 * g;
    let trend = lines::TrendLine::of(n, rate);
    let x = |i: usize| trend.residual(i, rate(i));
    let masked = counter_lines(model, trend.mean, wander, fs, d, fs / n as f64);
    let mut spectrum = lines::LineSpectrum::of(n, x, fs, &model_psd(model), &masked);
    let hw = params.half_width;
    let detections: Vec<(lines::Detection, f64)> = lines::search(&spectrum, params)
        .into_iter()
        .filter_map(|det| Some((det, spectrum.local_psd(det.f_hz, hw)?)))
        .collect();
    let t = spectrum.duration_s();
    let sines = &model.noise.sinusoid;
    let sine_refs: Vec<Option<f64>> = sines
        .iter()
        .map(|s| {
            let f = 1.0 / s.period_s;
            (f >= 2.0 / t && f < fs / 2.0)
                .then(|| spectrum.local_psd(f, hw))
                .flatten()
        })
        .collect();
    let psd = std::mem::take(&mut spectrum.psd);
    drop(spectrum);
    let lines = detections
        .into_iter()
        .map(|(det, s)| (det, lines::fit_line(n, x, fs, det.f_hz, s)))
        .collect();
    let sine_checks = sine_refs
        .iter()
        .zip(sines)
        .map(|(r, s)| {
            let f = 1.0 / s.period_s;
            let xarg = PI * f / fs;
            let sinc = xarg.sin() / xarg;
            r.map(|s_loc| {
                (
                    s_loc,
                    2.0 * lines::dft(n, x, 1.0 / fs, f).norm() / n as f64 / sinc,
                )
            })
        })
        .collect();
    LineScan {
        psd,
        n,
        fs_hz: fs,
        lines,
        masked,
        sine_checks,
        mean_rate: trend.mean,
    }
}

/// The line search of [`super::diagnose`] on its own: `rec` against `model`
/// (whose sample rate and pulse weight are taken from the recording).
pub fn line_scan(model: &GyroModel, rec: &Recording, params: &lines::SearchParams) -> LineScan {
    let fs = rec.sample_rate_hz;
    let d = rec.pulse_arcsec;
    let mut m = model.clone();
    m.gyro.sample_rate_hz = fs;
    if m.gyro.output == crate::model::config::OutputKind::Counts {
        m.gyro.pulse_arcsec = d;
    }
    let rate = stats::counts_to_rate(&rec.counts, d, fs);
    let layout = StatLayout::new(rate.len(), fs, d);
    let lv = stats::dwt_level_mean_squares(
        &rate,
        &layout.lo,
        &layout.hi,
        layout.levels.len() as u32,
        stats::MIN_LEVEL_COEFS,
    );
    let wvar: Vec<f64> = lv.iter().map(|t| t.2).collect();
    let mean_rate = rate.iter().sum::<f64>() / rate.len() as f64;
    let wander = rate_wander(&layout.levels, &wvar, fs, mean_rate.abs() / d);
    drop(rate);
    scan_lines(&m, &rec.counts, fs, d, wander, params)
}

/// What the lines contribute to the diagnosis.
#[derive(Debug, Default)]
pub(crate) struct LineFindings {
    pub findings: Vec<Finding>,
    /// The lines the model does not explain.
    pub hits: Vec<LineHit>,
    /// `(f Hz, amplitude arcsec/s)` of the line power the model lacks (for the
    /// wavelet-level expectation of the broadband fit).
    pub sines: Vec<(f64, f64)>,
    /// The periodogram searched (for [`excess`]).
    pub periodogram: Option<Periodogram>,
}

/// Turn the scan's lines (and the model's sinusoids) into findings.
fn line_findings(scan: &LineScan, model: &GyroModel) -> LineFindings {
    let sines = &model.noise.sinusoid;
    let z_check = compare::bonferroni_z(ALPHA_LINES, sines.len().max(1));
    let df = scan.fs_hz / scan.n as f64;
    let mut handled = vec![false; sines.len()];
    let mut out = LineFindings::default();
    for (det, fit) in &scan.lines {
        let near = sines
            .iter()
            .position(|s| (1.0 / s.period_s - fit.f_hz).abs() <= (3.0 * df).max(5.0 * fit.f_sd));
        let finding = match near {
            Some(i) => {
                handled[i] = true;
                let Some(f) = changed_sine(i, &sines[i], fit, z_check) else {
                    continue;
                };
                let m = units::dph_to_arcsec_per_s(sines[i].amplitude_dph);
                out.sines
                    .push((fit.f_hz, (fit.amp * fit.amp - m * m).max(0.0).sqrt()));
                f
            }
            None => {
                out.sines.push((fit.f_hz, fit.amp));
                new_sine(det, fit, z_of(det))
            }
        };
        out.hits.push(LineHit {
            bin: det.bin,
            f_hz: fit.f_hz,
            ratio: det.ratio,
            z: z_of(det),
        });
        out.findings.push(finding);
    }
    for (i, s) in sines.iter().enumerate().filter(|(i, _)| !handled[*i]) {
        if let Some((f, extra)) = sine_amplitude_check(scan, i, s, z_check) {
            out.sines.push((1.0 / s.period_s, extra));
            out.findings.push(f);
        }
    }
    out
}

/// Equivalent one-sided z of a detection's per-bin tail probability.
fn z_of(det: &Detection) -> f64 {
    -Normal::new(0.0, 1.0)
        .expect("standard normal")
        .inverse_cdf(det.p.max(1e-300))
}

/// The model's sinusoid `i` seen as a line: a finding when amplitude or
/// frequency differ beyond `z_check`.
fn changed_sine(i: usize, old: &SinusoidParams, fit: &LineFit, z_check: f64) -> Option<Finding> {
    let z_a = (fit.amp - units::dph_to_arcsec_per_s(old.amplitude_dph)) / fit.amp_sd.max(1e-300);
    let z_f = (fit.f_hz - 1.0 / old.period_s) / fit.f_sd.max(1e-300);
    if z_a.abs() <= z_check && z_f.abs() <= z_check {
        return None;
    }
    let amp = units::arcsec_per_s_to_dph(fit.amp);
    let per = 1.0 / fit.f_hz;
    let amp_ci = fit.amp_ci95().map(units::arcsec_per_s_to_dph);
    Some(Finding {
        edit: Edit::Sinusoid {
            index: Some(i),
            amplitude_dph: amp,
            period_s: per,
        },
        changes: vec![
            ParameterChange {
                term: format!("sinusoid[{i}].amplitude_dph"),
                model: old.amplitude_dph,
                fitted: amp,
                ci95: amp_ci,
            },
            ParameterChange {
                term: format!("sinusoid[{i}].period_s"),
                model: old.period_s,
                fitted: per,
                ci95: fit.period_ci95(),
            },
        ],
        added: None,
        n_par: 2,
        note: format!(
            "sinusoid[{i}]: the line at {} Hz differs from the model's: amplitude {} deg/h (model {}, z = {z_a:.1}), \
             period {} s (model {}, z = {z_f:.1})",
            fmt_g(fit.f_hz),
            fmt_g(amp),
            fmt_g(old.amplitude_dph),
            fmt_g(per),
            fmt_g(old.period_s)
        ),
    })
}

/// A line the model has nothing for: a new sinusoid.
fn new_sine(det: &Detection, fit: &LineFit, z: f64) -> Finding {
    let amp = units::arcsec_per_s_to_dph(fit.amp);
    let per = 1.0 / fit.f_hz;
    let amp_ci = fit.amp_ci95().map(units::arcsec_per_s_to_dph);
    let per_ci = fit.period_ci95();
    let t = Term::Sinusoid {
        amplitude_dph: amp,
        period_s: per,
    };
    let expl = format!(
        "{} Found as a narrow line in the whole record's spectrum at {} Hz ({} cycles; z = {z:.1}, tested at \
         the family-wise level over {} bins: the searched octaves times the bins of its octave), {:.1} times the local continuum; least-squares fit: amplitude {} \
         deg/h (95 % {}..{}), period {} s (95 % {}..{}), intervals from the line's Fisher information at the \
         local noise level. Its Allan signature (peak near tau = {} s) lies under the quantization noise.",
        t.explanation(),
        fmt_g(fit.f_hz),
        det.bin,
        det.n_searched,
        det.ratio,
        fmt_g(amp),
        fmt_g(amp_ci[0]),
        fmt_g(amp_ci[1]),
        fmt_g(per),
        fmt_g(per_ci[0]),
        fmt_g(per_ci[1]),
        fmt_g(0.371 * per)
    );
    Finding {
        edit: Edit::Sinusoid {
            index: None,
            amplitude_dph: amp,
            period_s: per,
        },
        changes: vec![],
        added: Some(AddedTerm {
            term: "sinusoid".into(),
            kind: None,
            params: BTreeMap::from([
                ("amplitude_dph".to_string(), amp),
                ("period_s".to_string(), per),
            ]),
            explanation: expl,
            ci95: BTreeMap::from([
                ("amplitude_dph".to_string(), amp_ci),
                ("period_s".to_string(), per_ci),
            ]),
        }),
        n_par: 2,
        note: format!(
            "new sinusoid at {} Hz: amplitude {} deg/h, period {} s (95 % {}..{})",
            fmt_g(fit.f_hz),
            fmt_g(amp),
            fmt_g(per),
            fmt_g(per_ci[0]),
            fmt_g(per_ci[1])
        ),
    }
}

/// A model sinusoid the search did not see: its amplitude measured at its own
/// frequency. Returns the finding and the amplitude the model lacks (arcsec/s).
fn sine_amplitude_check(
    scan: &LineScan,
    i: usize,
    s: &SinusoidParams,
    z_check: f64,
) -> Option<(Finding, f64)> {
    let (s_loc, amp) = scan.sine_checks[i]?;
    let (f, fs) = (1.0 / s.period_s, scan.fs_hz);
    let t = scan.n as f64 / fs;
    let xarg = PI * f / fs;
    let sinc = xarg.sin() / xarg;
    let sd = (s_loc / t).sqrt() / sinc;
    let model_amp = units::dph_to_arcsec_per_s(s.amplitude_dph);
    let z = (amp - model_amp) / sd;
    if !(z.abs() > z_check) {
        return None;
    }
    let fitted = units::arcsec_per_s_to_dph(amp);
    let sd_dph = units::arcsec_per_s_to_dph(sd);
    let finding = Finding {
        edit: Edit::Sinusoid {
            index: Some(i),
            amplitude_dph: fitted,
            period_s: s.period_s,
        },
        changes: vec![ParameterChange {
            term: format!("sinusoid[{i}].amplitude_dph"),
            model: s.amplitude_dph,
            fitted,
            ci95: [(fitted - 1.96 * sd_dph).max(0.0), fitted + 1.96 * sd_dph],
        }],
        added: None,
        n_par: 1,
        note: format!(
            "sinusoid[{i}] (period {} s): amplitude {} deg/h in the recording, model {} (z = {z:.1})",
            fmt_g(s.period_s),
            fmt_g(fitted),
            fmt_g(s.amplitude_dph)
        ),
    };
    Some((finding, (amp - model_amp).max(0.0)))
}
