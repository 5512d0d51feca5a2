//! Diagnosis of a model-versus-recording mismatch (`sagnac diagnose`):
//! locate where a recording departs from its gyro model, name the physics the
//! model leaves out, fit it, and show the fit improve.
//!
//! # Reading order
//! [`diagnose`] is a short sequence of phases, one file each:
//! 1. [`reference`]: the model simulated like the recording (same length,
//!    rate, pulse weight and mean input), R Monte-Carlo runs; recording and
//!    runs reduced to the same statistics as they stream past ([`stream`],
//!    [`mc`]; the whole-record definitions are in [`stats`]): sym8 wavelet
//!    variances of the rate, modified and raw Allan variances, the Welch
//!    spectrum, the rate slope and the rate-on-temperature slope, the
//!    low-passed rate's kurtosis. These see through the quantization noise
//!    that dominates the raw Allan variance at short taus.
//! 2. [`locate`] (compare and locate): each point gets a log-scale z-score
//!    against the runs ([`compare`]), the spread floored by the estimator's
//!    chi-square EDF; points and Stouffer windows beyond a Bonferroni
//!    threshold (family-wise 1 %) form the mismatch regions.
//! 3. [`lines`]: narrow lines in the whole record's spectrum, from ten cycles
//!    per record to Nyquist ([`line_search`], 0.1 % family-wise against the
//!    model-whitened local continuum, the counter's own harmonics masked),
//!    become sinusoids or changes of the model's own, with intervals from the
//!    line's Fisher information.
//! 4. The broadband residual: [`candidates`] tests every catalog change
//!    against the model by its likelihood ratio on the wavelet variances
//!    ([`wvar_fit`]) and the low-frequency periodogram below the deepest
//!    level ([`lowfreq`]), calibrated on the model's own runs (a parametric
//!    bootstrap), so coherent evidence below the per-point gate is kept;
//!    [`telegraph`] checks that the model's Gauss-Markov and telegraph terms
//!    have the right distribution; [`broadband`] names the changes (AIC,
//!    parameter-only changes preferred unless beaten by more than 2, each
//!    kept only if its LR test passes at 1 %, up to three).
//! 5. [`slopes`]: a rate ramp, and a thermal sensitivity when the recording
//!    has a temperature, judged against the slope spread of the noise the
//!    recording actually has.
//! 6. [`refine`]: the updated model simulated again and compared on the same
//!    points (chi2/dof before and after); a new Gauss-Markov term tested
//!    against a random telegraph; the broadband parameters refitted about the
//!    updated model's own runs until they stop moving.
//! 7. [`report`]: the JSON document and the notes (the figure is drawn by
//!    [`crate::sink::report::diagnosis_fig`], outside the numerics).
//!
//! The vocabulary the phases share (an [`findings::Edit`] of the model and the
//! finding that reports it) is in [`findings`]. When nothing exceeds the
//! thresholds the verdict is "consistent" and nothing is added.
//!
//! Layering: the diagnosis runs the simulator and the estimators of
//! [`crate::model`] and the `analyze` pipeline ([`crate::pipeline`]); the
//! report ([`crate::sink::report`]) and the CLI use it.

// `!(x > 0.0)` is used on purpose throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub(crate) mod broadband;
pub mod candidates;
pub mod compare;
pub(crate) mod findings;
pub(crate) mod golden;
pub mod line_search;
pub(crate) mod lines;
pub(crate) mod locate;
pub(crate) mod lowfreq;
pub mod mc;
pub(crate) mod narrowband;
pub(crate) mod points;
pub(crate) mod quality;
pub(crate) mod read;
pub(crate) mod readout;
pub(crate) mod readout_angle;
pub mod reference;
pub(crate) mod refine;
pub mod report;
pub(crate) mod resonance;
pub(crate) mod slopes;
pub mod stats;
pub mod stream;
pub(crate) mod telegraph;
pub mod two_level;
pub(crate) mod types;
pub mod wvar_fit;

use self::compare::{LineHit, Point};
use self::findings::Finding;
use self::reference::Reference;
use self::wvar_fit::Basis;
use crate::model::GyroModel;
use crate::units;

pub use self::lines::{LineScan, line_scan};
pub use self::read::ReadError;
pub use self::report::{
    AddedTerm, DiagnosisReport, FitQuality, MismatchRegion, ParameterChange, Verdict,
};
use self::types::check_recording;
pub use self::types::{
    ALPHA_LINES, ALPHA_SLOPE, DiagnoseError, DiagnoseOptions, MAX_RESONANCES, MIN_SAMPLES,
    Recording, TelegraphTest,
};
pub use crate::model::spectrum::{model_psd, model_spectral_terms};

/// Everything the diagnosis found.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    pub report: DiagnosisReport,
    /// The model with the changes applied (None when consistent or unexplained).
    pub updated_model: Option<GyroModel>,
    /// Compared points against the model (wavelet, MDEV, spectrum, raw Allan).
    pub before: Vec<Point>,
    /// The same points against the updated model's Monte-Carlo runs.
    pub after: Vec<Point>,
    /// Detection threshold on |z| of the broadband points.
    pub z_crit: f64,
    /// Largest |z| of the raw overlapping Allan variance against the model.
    pub raw_allan_max_z: f64,
    /// Largest |z| of the detection points (wavelet, MDEV, spectral bands).
    pub max_abs_z: f64,
    pub lines: Vec<LineHit>,
    /// z of the rate slope and of the temperature slope.
    pub ramp_z: f64,
    pub thermal_z: Option<f64>,
    pub telegraph_test: Option<TelegraphTest>,
    /// Detection by model comparison: the largest likelihood ratio of a
    /// catalog change against its bootstrap threshold ([`candidates`]).
    pub model_comparison: Option<candidates::ModelComparison>,
    /// Input rate the Monte-Carlo runs used (the recording's mean), deg/h.
    pub mc_input_rate_dph: f64,
    /// Human-readable findings, one per line.
    pub notes: Vec<String>,
    /// What the data-quality stage found (phase 0); `None` with it off.
    pub data_quality: Option<crate::quality::DataQuality>,
}

/// Run the diagnosis of `rec` against `model`.
pub fn diagnose(
    model: &GyroModel,
    rec: &Recording,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    diagnose_with_progress(model, rec, opts, &mc::Progress::default())
}

/// [`diagnose`], telling `progress` of each Monte-Carlo run (the result does
/// not depend on it).
pub fn diagnose_with_progress(
    model: &GyroModel,
    rec: &Recording,
    opts: &DiagnoseOptions,
    progress: &mc::Progress,
) -> Result<Diagnosis, DiagnoseError> {
    check_recording(rec, opts)?;
    model.validate()?;
    check_output(model, rec)?;
    // 0: the data-quality stage, and the diagnosis of what remains
    let handled = if opts.data_quality {
        quality::handle(model, rec)?
    } else {
        quality::Handled::none(model, rec)
    };
    let mut d = diagnose_core(&handled.compared, &handled.recording, opts, progress)?;
    let updated = d.updated_model.take();
    d.updated_model = handled.updated(updated);
    for f in &handled.findings {
        d.report.parameter_changes.extend(f.changes.iter().cloned());
        d.report.added_terms.extend(f.added.iter().cloned());
        d.notes.insert(0, f.note.clone());
    }
    if !handled.findings.is_empty() {
        d.report.verdict = Verdict::Mismatch;
    }
    d.data_quality = handled.data_quality;
    Ok(d)
}

/// Phases 1-7 on a recording the data-quality stage has handled.
fn diagnose_core(
    model: &GyroModel,
    rec: &Recording,
    opts: &DiagnoseOptions,
    progress: &mc::Progress,
) -> Result<Diagnosis, DiagnoseError> {
    // 1-2: the reference, and where the recording leaves its band
    let reference = Reference::simulate(model, rec, opts, progress)?;
    let r = &reference;
    let located = locate::locate(r, opts.alpha);
    let mut notes: Vec<String> = report::rate_note(r.layout.fs_hz, model.gyro.sample_rate_hz)
        .into_iter()
        .collect();
    // 3: lines
    let mut lines = lines::find(r, rec);
    let findings: Vec<Finding> = std::mem::take(&mut lines.findings);
    // 4: the broadband residual: candidate tests, distribution, broadband fit
    let basis =
        Basis::new(&r.layout.lo, &r.layout.hi, r.tau0_s(), &r.layout.levels).with_lf(&r.layout.lf);
    let data0 = broadband::level_data(r, &located, &basis, &lines.sines);
    let comparison = data0
        .as_ref()
        .and_then(|d0| candidates::test(d0, &basis, r, &located, opts.alpha));
    let lr_detected = comparison.as_ref().is_some_and(|c| c.detected);
    let regions = match &comparison {
        Some(c) if located.regions.is_empty() && c.detected => c.regions.clone(),
        _ => located.regions.clone(),
    };
    if let Some(c) = comparison.as_ref().filter(|c| c.detected) {
        notes.push(report::comparison_note(
            c,
            opts.alpha,
            located.max_abs_z,
            located.z_crit,
        ));
    }
    let ctx = Explain {
        r,
        rec,
        model,
        located: &located,
        basis: &basis,
        regions: &regions,
        lr_detected,
        opts,
    };
    let mut pass = ctx.run(findings.clone(), data0.clone())?;
    let periodogram = lines.periodogram.take();
    // 6b: narrowband noise the updated model does not explain: a resonance,
    // fitted, and phases 4-6 run again with it (kept when it fits better)
    // (up to MAX_RESONANCES, each where an excess remains with the last)
    if let Some(p) = &periodogram {
        let (mut base, mut data) = (findings.clone(), data0.clone());
        for _ in 0..MAX_RESONANCES {
            let (next, added) = ctx.with_resonance_if_better(pass, &base, data.as_ref(), p)?;
            pass = next;
            let Some((finding, fit)) = added else { break };
            data = ctx.resonance_data(data.as_ref(), &fit);
            base.push(finding);
        }
    }
    let excess = periodogram
        .as_ref()
        .map(|p| lines::excess(r, p, &pass.refined.fitted));
    drop(periodogram);
    let Pass {
        findings,
        slopes,
        refined,
        notes: pass_notes,
    } = pass;
    notes.extend(pass_notes);
    notes.extend(
        excess
            .and_then(|e| e.0)
            .filter(|e| e.ratio >= narrowband::NOTE_RATIO)
            .as_ref()
            .map(narrowband::note),
    );
    let mismatch = !regions.is_empty()
        || lr_detected
        || !lines.hits.is_empty()
        || slopes.significant()
        || !findings.is_empty();
    // 7: report
    notes.extend(report::closing_notes(
        &findings,
        comparison.as_ref(),
        mismatch,
        located.max_abs_z,
        located.z_crit,
    ));
    Ok(Diagnosis {
        report: report::document(
            mismatch,
            &regions,
            &findings,
            located.chi2_before,
            refined.chi2_after,
        ),
        updated_model: refined.updated,
        before: located.before,
        after: refined.after,
        z_crit: located.z_crit,
        raw_allan_max_z: located.raw_allan_max_z,
        max_abs_z: located.max_abs_z,
        lines: lines.hits,
        ramp_z: slopes.ramp_z,
        thermal_z: slopes.thermal_z,
        telegraph_test: refined.telegraph_test,
        model_comparison: comparison,
        mc_input_rate_dph: r.model.gyro.input_rate_dph,
        notes,
        data_quality: None,
    })
}

/// What phases 4-6 share between their runs (without and with a resonance).
struct Explain<'a> {
    r: &'a Reference,
    rec: &'a Recording,
    model: &'a GyroModel,
    located: &'a locate::Located,
    basis: &'a Basis,
    regions: &'a [compare::Region],
    lr_detected: bool,
    opts: &'a DiagnoseOptions,
}

/// One run of phases 4-6: the findings, the slope tests, the refined model
/// and the notes it wrote.
struct Pass {
    findings: Vec<Finding>,
    slopes: slopes::Slopes,
    refined: refine::Refined,
    notes: Vec<String>,
}

impl Explain<'_> {
    /// Phases 4-6 from the given findings (the lines', and a resonance's) on
    /// `data0` (the wavelet data with what those findings explain in it).
    /// When the broadband stage took a readout filter with the white angle
    /// noise after it (a choice made on the wavelet variances alone, about
    /// the model's long-tau terms), the phases run again without that
    /// candidate, and the explanation whose updated model fits the recording
    /// better (chi2/dof over every statistic) is kept.
    fn run(
        &self,
        findings: Vec<Finding>,
        data0: Option<wvar_fit::LevelData>,
    ) -> Result<Pass, DiagnoseError> {
        let with = self.run_with(findings.clone(), data0.clone(), true)?;
        let joint = |p: &Pass| {
            p.findings
                .iter()
                .any(|f| matches!(f.edit, findings::Edit::QuantizationBesideFilter { .. }))
        };
        if !joint(&with) {
            return Ok(with);
        }
        let mut without = self.run_with(findings, data0, false)?;
        if with.refined.chi2_after <= without.refined.chi2_after {
            return Ok(with);
        }
        without.notes.push(format!(
            "The readout filter fitted with the white angle noise after it fitted the recording worse \
             (chi2/dof {} against {} with the filter alone): not kept.",
            findings::fmt_g(with.refined.chi2_after),
            findings::fmt_g(without.refined.chi2_after)
        ));
        Ok(without)
    }

    /// [`Explain::run`] with or without the filter-with-Q candidate.
    fn run_with(
        &self,
        mut findings: Vec<Finding>,
        data0: Option<wvar_fit::LevelData>,
        joint_readout: bool,
    ) -> Result<Pass, DiagnoseError> {
        let (r, located) = (self.r, self.located);
        let mut notes = Vec::new();
        findings.extend(telegraph::model_terms(
            r,
            located,
            self.basis,
            data0.as_ref(),
        ));
        let mut telegraph_pending = None;
        if (!self.regions.is_empty() || self.lr_detected)
            && let Some(d0) = &data0
        {
            for (f, is_new_gm) in broadband::fit(d0, self.basis, r, self.regions, joint_readout) {
                if is_new_gm {
                    telegraph_pending = Some(findings.len());
                }
                findings.push(f);
            }
        }
        // 5: slopes
        let slopes = slopes::test(r, self.rec, &findings);
        findings.extend(slopes.findings.iter().cloned());
        // 6: the updated model, simulated again and refined
        let refined = refine::refine(
            r,
            self.rec,
            self.model,
            &mut findings,
            &broadband::region_text(self.regions),
            telegraph_pending,
            located.chi2_before,
            self.opts,
            &mut notes,
        )?;
        Ok(Pass {
            findings,
            slopes,
            refined,
            notes,
        })
    }

    /// Phase 6b: where the narrowband check finds an excess against the
    /// first explanation `pass`, a resonance fitted to it (fitted against the
    /// model under test: the first run's broadband terms may be bent to
    /// imitate it) and phases 4-6 run again with it; the second explanation
    /// is kept when the resonance's sigma is significant in its own fit and
    /// the chi2 is lower. When the ARW refitted beside the
    /// resonance is not significant once the tail's error is carried, the
    /// resonance whose tail takes the rest of the white level is tried too,
    /// and kept (the model's ARW with it) when the periodogram does not
    /// reject it and the wavelet variances fit as well. `line_findings` are
    /// the lines' (and the resonances kept before), `data0` the wavelet data
    /// with them; returns the explanation kept, and the resonance it added.
    fn with_resonance_if_better(
        &self,
        pass: Pass,
        line_findings: &[Finding],
        data0: Option<&wvar_fit::LevelData>,
        p: &lines::Periodogram,
    ) -> Result<(Pass, Option<(Finding, resonance::ResonanceFit)>), DiagnoseError> {
        let r = self.r;
        let Some(ex) = lines::excess(r, p, &pass.refined.fitted).0 else {
            return Ok((pass, None));
        };
        // against the model under test with the resonances kept before
        let spec = lines::excess(r, p, &findings::with_findings(&r.model, line_findings)).1;
        let adopted = |pass: Pass, fit: resonance::ResonanceFit| {
            let f = pass.findings.iter().find(|f| {
                matches!(f.edit, findings::Edit::Resonance { centre_hz, .. } if centre_hz == fit.centre_hz)
            });
            let added = f.cloned().map(|f| (f, fit));
            Ok((pass, added))
        };
        let filter = r.model.readout_filter();
        let budget = resonance::white_budget(&pass.refined.fitted);
        let Some(fit) = resonance::fit(&spec, &ex, filter, resonance::Tail::AtMost(budget)) else {
            return Ok((pass, None));
        };
        // its power must be significant in its own fit
        if !(fit.sigma_ci95[0] > 0.0) {
            let mut pass = pass;
            pass.notes.push(format!(
                "A resonance fitted at {} Hz is not significant on the periodogram (sigma {} deg/h, \
                 its 95 % interval reaching zero): not added.",
                findings::fmt_g(fit.centre_hz),
                findings::fmt_g(fit.sigma_dph)
            ));
            return Ok((pass, None));
        }
        let mut with = self.with_resonance(line_findings, data0, &fit)?;
        if !(with.refined.chi2_after < pass.refined.chi2_after) {
            let mut pass = pass;
            pass.notes.push(format!(
                "A resonance fitted at {} Hz did not improve the fit (chi2/dof {} with it against {} \
                 without): not added.",
                findings::fmt_g(fit.centre_hz),
                findings::fmt_g(with.refined.chi2_after),
                findings::fmt_g(pass.refined.chi2_after)
            ));
            return Ok((pass, None));
        }
        if !resonance::widen_white(&mut with.findings, &fit) {
            return adopted(with, fit);
        }
        let n2 = 2.0
            * units::dpsh_to_arcsec_per_sqrt_s(self.model.noise.arw_dpsh.unwrap_or(0.0)).powi(2);
        let Some(alt) = (budget > n2)
            .then(|| resonance::fit(&spec, &ex, filter, resonance::Tail::Exactly(budget - n2)))
            .flatten()
            .filter(|alt| 2.0 * (alt.nll - fit.nll) < resonance::LR_1DOF_95)
        else {
            return adopted(with, fit);
        };
        let mut kept = self.with_resonance(line_findings, data0, &alt)?;
        let names_arw = kept
            .findings
            .iter()
            .any(|f| f.changes.iter().any(|c| c.term == "arw_dpsh"));
        if names_arw
            || kept.refined.chi2_after
                > with.refined.chi2_after.max(refine::ACCEPTABLE_CHI2_PER_DOF)
        {
            return adopted(with, fit);
        }
        kept.notes.push(format!(
            "The model's angle random walk is kept: the resonance whose white tail takes the rest \
             of the white level the first explanation measured ({} (deg/h)^2/Hz) fits the \
             periodogram as well as the free one (likelihood ratio {} < {}), and the wavelet \
             variances as well (chi2/dof {} against {} with the ARW refitted).",
            findings::fmt_g(budget - n2),
            findings::fmt_g(2.0 * (alt.nll - fit.nll)),
            resonance::LR_1DOF_95,
            findings::fmt_g(kept.refined.chi2_after),
            findings::fmt_g(with.refined.chi2_after)
        ));
        adopted(kept, alt)
    }

    /// `data` with the wavelet variances of the resonance `fit` added to the
    /// expectation, as a line's are.
    fn resonance_data(
        &self,
        data: Option<&wvar_fit::LevelData>,
        fit: &resonance::ResonanceFit,
    ) -> Option<wvar_fit::LevelData> {
        data.map(|d| {
            let mut d = d.clone();
            let phi =
                self.basis
                    .resonance(fit.centre_hz, fit.width_hz, self.r.model.readout_filter());
            let s2 = fit.sigma_dph * fit.sigma_dph;
            d.e0.iter_mut().zip(&phi).for_each(|(e, p)| *e += s2 * p);
            d
        })
    }

    /// [`Explain::run`] with the resonance `fit` added after `line_findings`
    /// and its wavelet variances added to the expectation, as a line's are.
    /// The fit saw the resonance through the model's readout filter; when the
    /// run names another, it is run again with the ratio of the two filters'
    /// gains at the centre divided out of sigma (the simulator passes the
    /// resonance through the model's filter).
    fn with_resonance(
        &self,
        line_findings: &[Finding],
        data0: Option<&wvar_fit::LevelData>,
        fit: &resonance::ResonanceFit,
    ) -> Result<Pass, DiagnoseError> {
        let data = self.resonance_data(data0, fit);
        let tau0 = self.r.tau0_s();
        let gain2 = |m: &GyroModel| {
            m.readout_filter()
                .map_or(1.0, |f| f.power(fit.centre_hz * tau0))
        };
        let with_gain = |g: f64| {
            let mut findings = line_findings.to_vec();
            findings.push(resonance::finding(fit, g, tau0));
            self.run(findings, data.clone())
        };
        // the fit saw the resonance through the model's own filter
        let own = gain2(&self.r.model);
        let pass = with_gain(1.0)?;
        let named = gain2(&pass.refined.fitted) / own;
        if (named - 1.0).abs() < 0.01 {
            return Ok(pass);
        }
        with_gain(named)
    }
}

/// The model and the recording must be of the same kind of sensor.
pub(crate) fn check_output(model: &GyroModel, rec: &Recording) -> Result<(), DiagnoseError> {
    if model.gyro.output != rec.output {
        return Err(DiagnoseError::OutputMismatch {
            model: model.gyro.output.name(),
            recording: rec.output,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::stats::refill;
    use super::{DiagnoseOptions, Recording, Verdict, diagnose};
    use crate::model::config::OutputKind;
    use crate::model::{GyroModel, Simulator};

    #[test]
    fn made_up_samples_share_their_total_or_follow_their_neighbours() {
        let mut c = vec![3, 9, 0, 0, 5, 7, 1];
        refill(&mut c, &[1..4], false);
        assert_eq!(c[1..4].iter().sum::<i64>(), 9);
        assert_eq!(c[1..4], [3, 3, 3]);
        let mut w = vec![10, 99, 30, 50, -70, 90];
        refill(&mut w, &[1..2, 3..5], true);
        assert_eq!(w, vec![10, 20, 30, 50, 70, 90]);
    }

    /// A recording that lost a fifth of its samples in bursts (filled as the
    /// input layer fills them: each burst's pulses spread over it and the
    /// frame after it) matches its own model: the Monte-Carlo runs make up
    /// the same samples. Without the filled spans the same recording is a
    /// mismatch: the flat fills look like missing noise.
    #[test]
    fn a_recording_with_filled_gaps_matches_its_own_model() {
        let m = GyroModel::from_toml_str(
            "[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
             [noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\n",
            "gaps",
        )
        .unwrap();
        let mut sim = Simulator::new(&m, 11, Some(120.0)).unwrap();
        let mut counts = Vec::new();
        while sim.next_block(1 << 16, &mut counts) > 0 {}
        let n = counts.len();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut filled = Vec::new();
        let mut at = 500;
        while at + 2_500 < n {
            let len = rng.random_range(50..1_500);
            // the burst and the frame after it carry the burst's pulses
            let total: i64 = counts[at..=at + len].iter().sum();
            let shares = crate::dsp::gaps::spread_increment(total, len as u32 + 1);
            for (c, s) in counts[at..=at + len].iter_mut().zip(shares) {
                *c = s;
            }
            filled.push(at..at + len);
            at += len + 1 + rng.random_range(1_000..3_000);
        }
        let lost: usize = filled.iter().map(|r| r.len()).sum();
        assert!(lost * 6 > n, "lost {lost} of {n}");
        let rec = |filled: Vec<std::ops::Range<usize>>| Recording {
            counts: counts.clone(),
            filled,
            temp_c: None,
            sample_rate_hz: 500.0,
            pulse_arcsec: 1.21,
            output: OutputKind::Counts,
        };
        let opts = DiagnoseOptions {
            seed: 77,
            ..DiagnoseOptions::default()
        };
        let d = diagnose(&m, &rec(filled), &opts).unwrap();
        let r = &d.report;
        assert!(
            r.verdict != Verdict::Mismatch
                && r.added_terms.is_empty()
                && r.parameter_changes.is_empty(),
            "{:?} {:?} {:?}",
            r.verdict,
            r.added_terms,
            r.parameter_changes
        );
        let blind = diagnose(&m, &rec(Vec::new()), &opts).unwrap();
        assert_eq!(blind.report.verdict, Verdict::Mismatch);
    }
}
