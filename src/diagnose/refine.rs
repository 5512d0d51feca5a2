//! Phase 6, refine: the updated model (the reference model with every
//! finding applied) is simulated again and compared on the same points, so
//! the fit is seen to improve: chi2/dof before and after.
//!
//! A new Gauss-Markov term is first tested against a random telegraph with
//! the same spectrum ([`super::telegraph::test_new_gauss_markov`]). Then the
//! broadband parameters the findings changed (Q, ARW, bias instability, RRW)
//! are refitted about the updated model's own runs, up to three rounds, until
//! they move by less than a quarter of their 95 % half-width: the first fit is
//! linear about the original model's expectation, and a large change is not
//! linear (more ARW turns the counter's sawtooth quantization white) and
//! subtracts a large, noisy Monte-Carlo share. A round is kept unless it fits
//! worse and not acceptably. An updated model that fits worse than the
//! original, and not acceptably, is reported but not handed out.

use super::candidates::leave_one_out;
use super::compare::{self, Family, Point};
use super::findings::{
    Edit, Finding, UnitConv, fitted_parameters, fmt_g, sqrt_ci, tidy, with_findings,
};
use super::mc;
use super::points::{all_points, detect_points, floors, mean_stats};
use super::readout;
use super::reference::Reference;
use super::stats::StatSet;
use super::telegraph::{self, telegraph_alternative};
use super::types::{DiagnoseError, DiagnoseOptions, Recording, TelegraphTest};
use super::wvar_fit::{self, Basis, LevelData};
use crate::model::GyroModel;
use crate::units;

/// chi2/dof up to which an updated model counts as fitting the recording (a model
/// matched to the simulation that made the recording scores about 1).
pub const ACCEPTABLE_CHI2_PER_DOF: f64 = 1.5;

/// Refinement rounds of the broadband parameters about the updated model.
const REFINE_ROUNDS: usize = 3;

/// The updated model and how it fits.
pub(crate) struct Refined {
    /// The model to hand out (None when it fits worse and not acceptably).
    pub updated: Option<GyroModel>,
    /// The compared points against the updated model's runs.
    pub after: Vec<Point>,
    pub chi2_after: f64,
    pub telegraph_test: Option<TelegraphTest>,
    /// The reference model with the findings applied (at the recording's
    /// rate), whether or not it is handed out.
    pub fitted: GyroModel,
}

/// The updated model and its runs while it is being refined.
struct Current {
    model: GyroModel,
    runs: Vec<StatSet>,
    after: Vec<Point>,
    chi2: f64,
}

/// Simulate the model updated by `findings` (rewritten in place by the
/// telegraph test and the refinement) and compare it with the recording.
/// `telegraph_pending`: index of a new Gauss-Markov finding to test.
#[allow(clippy::too_many_arguments)] // the phase's inputs: reference, recording, user model, findings
pub(crate) fn refine(
    r: &Reference,
    rec: &Recording,
    user_model: &GyroModel,
    findings: &mut [Finding],
    regions: &str,
    telegraph_pending: Option<usize>,
    chi2_before: f64,
    opts: &DiagnoseOptions,
    notes: &mut Vec<String>,
) -> Result<Refined, DiagnoseError> {
    if findings.is_empty() {
        return Ok(Refined {
            updated: None,
            after: Vec::new(),
            chi2_after: chi2_before,
            telegraph_test: None,
            fitted: r.model.clone(),
        });
    }
    let temp = rec.temp_c.as_deref();
    let seeds_after: Vec<u64> = (0..opts.runs_after as u64)
        .map(|k| opts.seed.wrapping_add(1_000_003).wrapping_add(k))
        .collect();
    let cutoffs = &r.cutoffs_hz;
    let alt = telegraph_pending
        .and_then(|fi| telegraph_alternative(&r.model, findings, fi).map(|a| (fi, a)));
    let mut model = with_findings(&r.model, findings);
    let mut runs = mc::run(
        &r.job(&model, temp, cutoffs)
            .phase("simulating the updated model"),
        &seeds_after,
    )?;
    let mut telegraph_test = None;
    if let Some((fi, (alt_model, probe))) = &alt {
        let out = telegraph::test_new_gauss_markov(
            r,
            rec,
            findings,
            *fi,
            (alt_model, *probe),
            cutoffs,
            &seeds_after,
        )?;
        telegraph_test = Some(out.test);
        if let Some((m, rr)) = out.replaced {
            model = m;
            runs = rr;
        }
    }
    let after = all_points(&r.layout, &model, &r.obs, &runs, &r.kurt_taus);
    let chi2 = compare::chi2_per_dof(&detect_points(&after), fitted_parameters(findings));
    let mut cur = Current {
        model,
        runs,
        after,
        chi2,
    };
    let basis =
        Basis::new(&r.layout.lo, &r.layout.hi, r.tau0_s(), &r.layout.levels).with_lf(&r.layout.lf);
    for round in 0..REFINE_ROUNDS {
        if !refine_round(
            r,
            &basis,
            &mut cur,
            findings,
            round,
            &seeds_after,
            cutoffs,
            temp,
            notes,
        )? {
            break;
        }
    }
    recenter_filter(
        r,
        &basis,
        &mut cur,
        findings,
        regions,
        &seeds_after,
        cutoffs,
        temp,
        notes,
    )?;
    widen_about_updated(r, &basis, &cur, findings);
    widen_filter_about_updated(r, &basis, &cur, findings);
    let Current {
        model: mut m_new,
        after,
        chi2: chi2_after,
        ..
    } = cur;
    let fitted = m_new.clone();
    // restore the user's readout in the written model (at the rate it was fitted at)
    m_new.gyro = user_model.gyro.clone();
    m_new.gyro.sample_rate_hz = r.layout.fs_hz;
    tidy(&mut m_new);
    let updated = judge_update(m_new, findings, chi2_before, chi2_after, r.tau0_s(), notes);
    Ok(Refined {
        updated,
        after,
        chi2_after,
        telegraph_test,
        fitted,
    })
}

/// The updated model judged: every finding's interval widened when it does not
/// fit, and no model handed out when it fits worse than the original and not
/// acceptably (with a note each time).
fn judge_update(
    m_new: GyroModel,
    findings: &mut [Finding],
    chi2_before: f64,
    chi2_after: f64,
    tau0_s: f64,
    notes: &mut Vec<String>,
) -> Option<GyroModel> {
    // A model that does not fit: the fit's intervals assume one that does.
    if chi2_after > ACCEPTABLE_CHI2_PER_DOF {
        let s = chi2_after.sqrt();
        for f in findings.iter_mut() {
            f.widen_for_misfit(s, 0.5 / tau0_s);
        }
        notes.push(format!(
            "The updated model does not describe the recording (chi2/dof {chi2_after:.2} > \
             {ACCEPTABLE_CHI2_PER_DOF}): every interval of the findings is widened by sqrt(chi2/dof) = {s:.2} \
             (the explanations quote the fit's own intervals)."
        ));
    }
    // An update that fits worse and not acceptably is reported, never handed out
    // as the better model. (A ramp or a thermal sensitivity is found by tests the
    // chi2 points barely see: its chi2/dof may rise a little while staying fine.)
    if chi2_after > chi2_before && chi2_after > ACCEPTABLE_CHI2_PER_DOF {
        notes.push(format!(
            "The updated model fits worse than the original (chi2/dof {chi2_before:.2} -> {chi2_after:.2}): \
             it is not offered as a replacement; the changes listed are candidates only."
        ));
        None
    } else {
        Some(m_new)
    }
}

/// One refinement round; false when the parameters stopped moving or the
/// round fitted worse (the round is then not kept).
#[allow(clippy::too_many_arguments)] // the round's state and its seeds, cut-offs and temperature
fn refine_round(
    r: &Reference,
    basis: &Basis,
    cur: &mut Current,
    findings: &mut [Finding],
    round: usize,
    seeds_after: &[u64],
    cutoffs: &[f64],
    temp: Option<&[f64]>,
    notes: &mut Vec<String>,
) -> Result<bool, DiagnoseError> {
    let knobs = refinable(findings);
    let Some(refit) = refine_broadband(r, basis, &cur.model, &cur.after, &cur.runs, &knobs) else {
        return Ok(false);
    };
    let moved = refit.iter().any(|k| {
        let half = 0.5 * (k.ci95[1] - k.ci95[0]);
        let now = k.current(&cur.model);
        !((k.value - now).abs() <= 0.25 * half)
    });
    if !moved {
        return Ok(false);
    }
    let mut m_try = cur.model.clone();
    for k in &refit {
        k.edit().apply(&mut m_try);
    }
    let tried = simulated(
        r,
        m_try,
        seeds_after,
        7_919 * (round as u64 + 1),
        "refining the updated model",
        cutoffs,
        temp,
        findings,
    )?;
    let chi2_try = tried.chi2;
    if !(chi2_try <= cur.chi2.max(ACCEPTABLE_CHI2_PER_DOF)) {
        return Ok(false);
    }
    notes.push(format!(
        "Refined about the updated model's own runs (round {}): {}; chi2/dof {:.2} -> {chi2_try:.2}.",
        round + 1,
        refit.iter().map(|k| format!("{} {}", k.key(), fmt_g(k.value))).collect::<Vec<_>>().join(", "),
        cur.chi2
    ));
    for k in &refit {
        k.store(findings);
    }
    *cur = tried;
    Ok(true)
}

/// `model` simulated on `seeds` (each offset by `offset`) and compared with
/// the recording: a candidate state of the refinement.
#[allow(clippy::too_many_arguments)] // the model, its seeds, cut-offs and temperature
fn simulated(
    r: &Reference,
    model: GyroModel,
    seeds: &[u64],
    offset: u64,
    phase: &'static str,
    cutoffs: &[f64],
    temp: Option<&[f64]>,
    findings: &[Finding],
) -> Result<Current, DiagnoseError> {
    let seeds: Vec<u64> = seeds.iter().map(|s| s.wrapping_add(offset)).collect();
    let runs = mc::run(&r.job(&model, temp, cutoffs).phase(phase), &seeds)?;
    let after = all_points(&r.layout, &model, &r.obs, &runs, &r.kurt_taus);
    let chi2 = compare::chi2_per_dof(&detect_points(&after), fitted_parameters(findings));
    Ok(Current {
        model,
        runs,
        after,
        chi2,
    })
}

/// A broadband parameter the refinement may move.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Knob {
    Quantization,
    Arw,
    BiasInstability,
    Rrw,
}

impl Knob {
    /// The parameter's name in the model file and the JSON.
    fn key(self) -> &'static str {
        match self {
            Knob::Quantization => "quantization_arcsec",
            Knob::Arw => "arw_dpsh",
            Knob::BiasInstability => "bias_instability_dph",
            Knob::Rrw => "rrw_dphsh",
        }
    }
}

/// A refitted broadband parameter, in the model file's units.
#[derive(Debug, Clone, Copy)]
struct Refit {
    knob: Knob,
    value: f64,
    ci95: [f64; 2],
}

impl Refit {
    fn edit(&self) -> Edit {
        match self.knob {
            Knob::Quantization => Edit::Quantization(self.value),
            Knob::Arw => Edit::Arw(self.value),
            Knob::BiasInstability => Edit::BiasInstability(self.value),
            Knob::Rrw => Edit::Rrw(self.value),
        }
    }

    /// The parameter's value in `m`, in the model file's units.
    fn current(&self, m: &GyroModel) -> f64 {
        let n = &m.noise;
        match self.knob {
            Knob::Quantization => m.quantization_q_arcsec(),
            Knob::Arw => n.arw_dpsh.unwrap_or(0.0),
            Knob::BiasInstability => n.bias_instability_dph.unwrap_or(0.0),
            Knob::Rrw => n.rrw_dphsh.unwrap_or(0.0),
        }
    }

    fn key(&self) -> &'static str {
        self.knob.key()
    }

    /// Put the refitted value into the last finding that set this parameter
    /// (its edit, its reported change or added term, and its note).
    fn store(&self, findings: &mut [Finding]) {
        let Some(f) = findings
            .iter_mut()
            .rev()
            .find(|f| knob_of(&f.edit) == Some(self.knob))
        else {
            return;
        };
        let before = edit_value(&f.edit);
        let mut ci95 = self.ci95;
        f.edit = match &f.edit {
            // A readout filter keeps its shape; its white level is refitted
            // through it, and the interval widened by the corner's trade-off.
            Edit::ReadoutFilter {
                params,
                arw_profile_widen: (wl, wh),
                ..
            } => {
                ci95 = widened(self.value, ci95, (*wl, *wh));
                Edit::ReadoutFilter {
                    params: params.clone(),
                    arw_dpsh: self.value,
                    arw_profile_widen: (*wl, *wh),
                }
            }
            // Q fitted with a filter: likewise widened by their trade-off
            Edit::QuantizationBesideFilter {
                profile_widen: (wl, wh),
                ..
            } => {
                ci95 = widened(self.value, ci95, (*wl, *wh));
                ci95[0] = ci95[0].max(0.0);
                Edit::QuantizationBesideFilter {
                    quantization_arcsec: self.value,
                    profile_widen: (*wl, *wh),
                }
            }
            _ => self.edit(),
        };
        let key = self.key();
        for c in f.changes.iter_mut().filter(|c| c.term == key) {
            c.fitted = self.value;
            c.ci95 = ci95;
        }
        if let Some(a) = f.added.as_mut() {
            if let Some(v) = a.params.get_mut(key) {
                *v = self.value;
            }
            if let Some(ci) = a.ci95.get_mut(key) {
                *ci = ci95;
            }
        }
        f.note.push_str(&format!(
            " Refined about the updated model's runs: {key} {} -> {}.",
            fmt_g(before),
            fmt_g(self.value)
        ));
    }
}

/// `ci95` about `v` with each side stretched by its profile-widening factor
/// (a refitted value whose interval carries a trade-off with another parameter).
fn widened(v: f64, ci95: [f64; 2], (wl, wh): (f64, f64)) -> [f64; 2] {
    [v - wl * (v - ci95[0]), v + wh * (ci95[1] - v)]
}

fn knob_of(e: &Edit) -> Option<Knob> {
    match e {
        Edit::Quantization(_) | Edit::QuantizationBesideFilter { .. } => Some(Knob::Quantization),
        // The white level refitted with a readout filter: found about the
        // original model's Monte-Carlo mean less its white share, whose noise
        // the filter's attenuation of the fine levels amplifies (the ARW of a
        // 5-sample average scattered 3x its claimed width until refined).
        Edit::Arw(_) | Edit::ReadoutFilter { .. } => Some(Knob::Arw),
        Edit::BiasInstability(_) => Some(Knob::BiasInstability),
        Edit::Rrw(_) => Some(Knob::Rrw),
        _ => None,
    }
}

fn edit_value(e: &Edit) -> f64 {
    match e {
        Edit::Quantization(v) | Edit::Arw(v) | Edit::BiasInstability(v) | Edit::Rrw(v) => *v,
        Edit::ReadoutFilter { arw_dpsh, .. } => *arw_dpsh,
        Edit::QuantizationBesideFilter {
            quantization_arcsec,
            ..
        } => *quantization_arcsec,
        _ => f64::NAN,
    }
}

/// The broadband parameters the findings changed or added, once each.
fn refinable(findings: &[Finding]) -> Vec<Knob> {
    let mut knobs = Vec::new();
    for k in findings.iter().filter_map(|f| knob_of(&f.edit)) {
        if !knobs.contains(&k) {
            knobs.push(k);
        }
    }
    knobs
}

/// Refit `knobs` on the recording's wavelet variances about the expectation of
/// `model`'s own runs (`after`, `runs`): coordinate sweeps of one-parameter
/// likelihood fits. None when there is nothing to refit or the levels are
/// incomplete.
fn refine_broadband(
    r: &Reference,
    basis: &Basis,
    model: &GyroModel,
    after: &[Point],
    runs: &[StatSet],
    knobs: &[Knob],
) -> Option<Vec<Refit>> {
    if knobs.is_empty() {
        return None;
    }
    let mut data = after_data(r, basis, after, runs)?;
    // (knob, basis shape, current theta, floor, theta -> model units)
    let mut state: Vec<(Knob, Vec<f64>, f64, f64, UnitConv)> = knobs
        .iter()
        .map(|&kn| knob_state(kn, basis, model))
        .collect();
    let mut cis = vec![(0.0, 0.0); state.len()];
    for _sweep in 0..3 {
        for (i, (_, phi, theta, floor, _)) in state.iter_mut().enumerate() {
            let fit = wvar_fit::fit_amplitude(&data, phi, *theta, *floor);
            if !fit.theta.is_finite() {
                return None;
            }
            for (e, d) in data.e0.iter_mut().zip(&fit.delta_mu) {
                *e += d;
            }
            *theta = fit.theta;
            cis[i] = fit.theta_ci;
        }
    }

    Some(
        state
            .iter()
            .zip(&cis)
            .map(|((kn, _, theta, _, conv), ci)| Refit {
                knob: *kn,
                value: conv(theta.sqrt()),
                ci95: sqrt_ci(*ci, conv),
            })
            .collect(),
    )
}

/// The recording's wavelet-level data about the expectation of a model's own
/// runs (`after`, `runs`); None when the levels are incomplete.
fn after_data(
    r: &Reference,
    basis: &Basis,
    after: &[Point],
    runs: &[StatSet],
) -> Option<LevelData> {
    let layout = &r.layout;
    let wpts: Vec<&Point> = after
        .iter()
        .filter(|p| p.family == Family::Wavelet)
        .collect();
    if runs.is_empty() || wpts.len() != layout.levels.len() {
        return None;
    }
    let nr = runs.len() as f64;
    let mut data = LevelData {
        levels: layout.levels.clone(),
        y: r.obs.wvar.clone(),
        e0: mean_stats(runs).wvar,
        nu: wpts
            .iter()
            .map(|p| 2.0 / (p.sd_log * p.sd_log * (1.0 + 1.0 / nr)))
            .collect(),
    };
    if basis.has_lf() {
        let all: Vec<&StatSet> = runs.iter().collect();
        wvar_fit::append_rows(&mut data, &layout.lf, &r.obs.lf_psd, &all);
    }
    Some(data)
}

/// Give every broadband parameter change (Q, ARW, bias instability, RRW;
/// refitted or not) an interval at least as wide as its one-parameter fit
/// about the updated model's own runs, with those runs' EDFs and widened by
/// the levels' correlation ([`wvar_fit::level_correlation_factor`]). A change
/// found about the original model carries that model's EDFs, which overstate
/// the information of levels a readout filter attenuates (the ARW refitted
/// with a 5-sample average scattered 4x its claimed width).
fn widen_about_updated(r: &Reference, basis: &Basis, cur: &Current, findings: &mut [Finding]) {
    let Some(data) = after_data(r, basis, &cur.after, &cur.runs) else {
        return;
    };
    let run_wvar: Vec<&[f64]> = cur.runs.iter().map(|s| s.wvar.as_slice()).collect();
    let knobs = [
        Knob::Quantization,
        Knob::Arw,
        Knob::BiasInstability,
        Knob::Rrw,
    ];
    for kn in knobs {
        let key = kn.key();
        if !findings
            .iter()
            .flat_map(|f| &f.changes)
            .any(|c| c.term == key)
        {
            continue;
        }
        let (_, phi, theta, floor, conv) = knob_state(kn, basis, &cur.model);
        let fit = wvar_fit::fit_amplitude(&data, &phi, theta, floor);
        if !(fit.theta.is_finite() && fit.theta > 0.0) {
            continue;
        }
        let factor = wvar_fit::level_correlation_factor(&data, &phi, &run_wvar);
        let ci = sqrt_ci(
            wvar_fit::widen_ci(fit.theta, fit.theta_ci, factor, floor),
            conv,
        );
        let v = conv(fit.theta.sqrt());
        let (below, above) = (v - ci[0], ci[1] - v);
        for c in findings
            .iter_mut()
            .flat_map(|f| f.changes.iter_mut())
            .filter(|c| c.term == key)
        {
            c.ci95 = [
                c.ci95[0].min(c.fitted - below).max(0.0),
                c.ci95[1].max(c.fitted + above),
            ];
        }
    }
}

/// Move a `readout_filter` finding to its refit about the updated model's own
/// runs (corner and white level, with those runs' EDFs), simulate the moved
/// model and keep it unless it fits worse and not acceptably (as a refinement
/// round). The interval floor of [`widen_filter_about_updated`] measures the
/// scatter of exactly this refit, so the reported corner is the one it
/// describes.
#[allow(clippy::too_many_arguments)] // the stage's state and its seeds, cut-offs and temperature
fn recenter_filter(
    r: &Reference,
    basis: &Basis,
    cur: &mut Current,
    findings: &mut [Finding],
    regions: &str,
    seeds_after: &[u64],
    cutoffs: &[f64],
    temp: Option<&[f64]>,
    notes: &mut Vec<String>,
) -> Result<(), DiagnoseError> {
    let Some(i) = findings
        .iter()
        .rposition(|f| matches!(f.edit, Edit::ReadoutFilter { .. }))
    else {
        return Ok(());
    };
    let Some(data) = after_data(r, basis, &cur.after, &cur.runs) else {
        return Ok(());
    };
    let n2 = units::dpsh_to_arcsec_per_sqrt_s(cur.model.noise.arw_dpsh.unwrap_or(0.0)).powi(2);
    let Some(moved) = readout::fit(&data, basis, n2, cur.model.readout_filter())
        .and_then(|about| readout::recentered(&findings[i], &about, &r.model, regions))
    else {
        return Ok(());
    };
    let mut m_try = cur.model.clone();
    moved.edit.apply(&mut m_try);
    let tried = simulated(
        r,
        m_try,
        seeds_after,
        104_729,
        "simulating the refitted filter",
        cutoffs,
        temp,
        findings,
    )?;
    let chi2 = tried.chi2;
    if !(chi2 <= cur.chi2.max(ACCEPTABLE_CHI2_PER_DOF)) {
        notes.push(format!(
            "The readout filter refitted about the updated model's runs fitted worse (chi2/dof {:.2} -> \
             {chi2:.2}): the first fit is kept.",
            cur.chi2
        ));
        return Ok(());
    }
    notes.push(format!(
        "Readout filter refitted about the updated model's own runs: chi2/dof {:.2} -> {chi2:.2}.",
        cur.chi2
    ));
    findings[i] = moved;
    *cur = tried;
    Ok(())
}

/// Refit a `readout_filter` finding's filter about the updated model's own
/// runs (their EDFs) and widen its corner and ARW intervals to that fit's.
fn widen_filter_about_updated(
    r: &Reference,
    basis: &Basis,
    cur: &Current,
    findings: &mut [Finding],
) {
    let Some(f) = findings
        .iter_mut()
        .rev()
        .find(|f| matches!(f.edit, Edit::ReadoutFilter { .. }))
    else {
        return;
    };
    let Some(data) = after_data(r, basis, &cur.after, &cur.runs) else {
        return;
    };
    let n2 = units::dpsh_to_arcsec_per_sqrt_s(cur.model.noise.arw_dpsh.unwrap_or(0.0)).powi(2);
    let current = cur.model.readout_filter();
    if let Some(about) = readout::fit(&data, basis, n2, current) {
        readout::widen_about_updated(f, &about, r.tau0_s());
    }
    // the fit's sampling scatter, measured: each run judged against the others
    let fw = floors(&r.layout, &cur.model, &mean_stats(&cur.runs)).0;
    let boot: Vec<readout::FilterFit> = (0..cur.runs.len())
        .filter_map(|k| {
            let d = leave_one_out(&r.layout, &cur.runs, k, &fw, basis.has_lf());
            readout::fit(&d, basis, n2, current)
        })
        .collect();
    readout::widen_by_scatter(f, &boot, r.tau0_s());
}

/// A knob's basis shape, current squared amplitude (internal units), lower
/// bound and conversion to the model file's units.
fn knob_state(kn: Knob, basis: &Basis, model: &GyroModel) -> (Knob, Vec<f64>, f64, f64, UnitConv) {
    let nz = &model.noise;
    match kn {
        Knob::Quantization => {
            let q = model.quantization_q_arcsec();
            (
                kn,
                basis.white_angle(),
                q * q,
                model.gyro.pulse_arcsec.powi(2) / 12.0,
                (|x| x) as UnitConv,
            )
        }
        Knob::Arw => {
            let arw = units::dpsh_to_arcsec_per_sqrt_s(nz.arw_dpsh.unwrap_or(0.0));
            let phi = basis.white_rate_through(model.readout_filter());
            (
                kn,
                phi,
                arw * arw,
                0.0,
                units::arcsec_per_sqrt_s_to_dpsh as UnitConv,
            )
        }
        Knob::BiasInstability => (
            kn,
            basis.flicker(model.flicker_f_lo_hz()),
            nz.bias_instability_dph.unwrap_or(0.0).powi(2),
            0.0,
            units::arcsec_per_s_to_dph as UnitConv,
        ),
        Knob::Rrw => {
            let k = units::dphsh_to_arcsec_per_s_sqrt_s(nz.rrw_dphsh.unwrap_or(0.0));
            (
                kn,
                basis.rrw(),
                k * k,
                0.0,
                units::arcsec_per_s_sqrt_s_to_dphsh as UnitConv,
            )
        }
    }
}
