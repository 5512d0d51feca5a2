//! Phase 4, the broadband fit: the residual the wavelet variances show is
//! explained by catalog changes, greedily, up to three.
//!
//! At each step every candidate is fitted on the recording's sym8 level
//! variances about the current expectation ([`super::wvar_fit`]):
//! parameter-only changes of the model's own terms (Q, ARW, bias instability,
//! RRW, a Gauss-Markov amplitude or amplitude and time constant, a telegraph
//! amplitude) and new terms (bias instability or RRW when the model lacks
//! them, a Gauss-Markov bias, a sinusoid too slow for the line search). The
//! best parameter-only change and the best new term are compared by AIC, the
//! parameter change winning unless beaten by more than 2; the winner is kept
//! only when its likelihood-ratio test passes at 1 %, and its change is added
//! to the expectation before the next step.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::compare::Region;
use super::findings::{Edit, Finding, UnitConv, fmt_g, sqrt_ci};
use super::line_search::SearchParams;
use super::locate::Located;
use super::readout;
use super::readout_angle;
use super::reference::{BlockRate, Reference};
use super::stats::StatSet;
use super::types::{AddedTerm, ParameterChange};
use super::wvar_fit::{self, Basis, Fit, LevelData};
use crate::model::filter::{ReadoutFilter, ReadoutFilterParams};
use crate::model::{GyroModel, Term};
use crate::units;

/// Changes accepted at most.
const MAX_STEPS: usize = 3;

/// The wavelet-level data of the fits: the recording's level variances, the
/// model's Monte-Carlo mean plus the lines found (`sines`: frequency Hz,
/// amplitude arcsec/s), and each level's EDF. `None` when a level has no
/// valid point.
pub(crate) fn level_data(
    r: &Reference,
    loc: &Located,
    basis: &Basis,
    sines: &[(f64, f64)],
) -> Option<LevelData> {
    let wpts = loc.wavelet_points();
    if wpts.len() != r.layout.levels.len() {
        return None;
    }
    let runs = r.runs.len() as f64;
    let mut data = LevelData {
        levels: r.layout.levels.clone(),
        y: r.obs.wvar.clone(),
        e0: loc.mc_mean.wvar.clone(),
        nu: wpts
            .iter()
            .map(|p| 2.0 / (p.sd_log * p.sd_log * (1.0 + 1.0 / runs)))
            .collect(),
    };
    if basis.has_lf() {
        let all: Vec<&StatSet> = r.runs.iter().collect();
        wvar_fit::append_rows(&mut data, &r.layout.lf, &r.obs.lf_psd, &all);
    }
    for &(f, amp) in sines {
        let phi = basis.sinusoid(f);
        for j in 0..data.e0.len() {
            data.e0[j] += amp * amp * phi[j];
        }
    }
    Some(data)
}

/// A candidate of the broadband stage.
struct Candidate {
    fit: Fit,
    /// Parameter-only change of an existing term.
    param_only: bool,
    finding: Finding,
}

/// Current squared amplitudes of the model's broadband terms (updated as
/// changes are accepted).
#[derive(Debug, Clone)]
struct Current {
    q2: f64,
    n2: f64,
    b2: f64,
    k2: f64,
    gm: Vec<(f64, f64)>,
    rtn: Vec<(f64, f64)>,
    /// The readout filter the white rate goes through.
    filter: Option<ReadoutFilter>,
    tau0_s: f64,
}

impl Current {
    fn of(model: &GyroModel) -> Current {
        let nz = &model.noise;
        let q = model.quantization_q_arcsec();
        let arw = units::dpsh_to_arcsec_per_sqrt_s(nz.arw_dpsh.unwrap_or(0.0));
        Current {
            q2: q * q,
            n2: arw * arw,
            b2: nz.bias_instability_dph.unwrap_or(0.0).powi(2),
            k2: units::dphsh_to_arcsec_per_s_sqrt_s(nz.rrw_dphsh.unwrap_or(0.0)).powi(2),
            gm: nz
                .gauss_markov
                .iter()
                .map(|g| (g.sigma_dph * g.sigma_dph, g.tau_c_s))
                .collect(),
            rtn: nz
                .random_telegraph
                .iter()
                .map(|r| (r.amplitude_dph * r.amplitude_dph, r.mean_dwell_s))
                .collect(),
            filter: model.readout_filter(),
            tau0_s: model.tau0_s(),
        }
    }

    /// Take an accepted edit into the current amplitudes.
    fn accept(&mut self, edit: &Edit) {
        match edit {
            Edit::Quantization(v)
            | Edit::QuantizationBesideFilter {
                quantization_arcsec: v,
                ..
            } => self.q2 = v * v,
            Edit::Arw(v) => self.n2 = units::dpsh_to_arcsec_per_sqrt_s(*v).powi(2),
            Edit::BiasInstability(v) => self.b2 = v * v,
            Edit::Rrw(v) => self.k2 = units::dphsh_to_arcsec_per_s_sqrt_s(*v).powi(2),
            Edit::GaussMarkov {
                index: Some(i),
                sigma_dph,
                tau_c_s,
            } => self.gm[*i] = (sigma_dph * sigma_dph, *tau_c_s),
            Edit::GaussMarkov {
                index: None,
                sigma_dph,
                tau_c_s,
            } => self.gm.push((sigma_dph * sigma_dph, *tau_c_s)),
            Edit::Telegraph {
                index: Some(i),
                amplitude_dph,
                mean_dwell_s,
            } => self.rtn[*i] = (amplitude_dph * amplitude_dph, *mean_dwell_s),
            Edit::ReadoutFilter {
                params, arw_dpsh, ..
            } => {
                self.filter = params.filter(self.tau0_s).ok();
                self.n2 = units::dpsh_to_arcsec_per_sqrt_s(*arw_dpsh).powi(2);
            }
            _ => {}
        }
    }
}

/// What the candidates of one step share.
struct Ctx<'a> {
    data: &'a LevelData,
    basis: &'a Basis,
    cur: &'a Current,
    /// The mismatch regions, in words (for the explanations).
    regions: &'a str,
    f_lo_flicker: f64,
    /// Lowest Q: the counter alone gives d/sqrt(12).
    d2_12: f64,
    tc_grid: &'a [f64],
    p_grid: &'a [f64],
    /// The recording in the time domain, to bound a slow sinusoid.
    blocks: &'a BlockRate,
}

fn chi2_quantile(p: f64, dof: f64) -> f64 {
    ChiSquared::new(dof)
        .map(|c| c.inverse_cdf(p))
        .unwrap_or(f64::INFINITY)
}

/// The mismatch regions in words, as the findings' explanations quote them.
pub(crate) fn region_text(regions: &[Region]) -> String {
    regions
        .iter()
        .map(|g| {
            format!(
                "{}..{} s (z {:.1})",
                fmt_g(g.tau_min_s),
                fmt_g(g.tau_max_s),
                g.max_z
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The broadband stage: greedy selection of up to three catalog changes
/// (`joint_readout`: the readout filter with the white angle noise after it
/// among the candidates).
/// Returns the findings, each flagged when it is a new Gauss-Markov term
/// (to be tested against a random telegraph; only the first one is).
pub(crate) fn fit(
    data0: &LevelData,
    basis: &Basis,
    r: &Reference,
    regions: &[Region],
    joint_readout: bool,
) -> Vec<(Finding, bool)> {
    let model = &r.model;
    let dur = r.duration_s();
    let mut cur = Current::of(model);
    let mut data = data0.clone();
    let mut out: Vec<(Finding, bool)> = Vec::new();
    let region_text = region_text(regions);
    let tc_grid = wvar_fit::log_grid(4.0 * r.tau0_s(), dur / 3.0, 4);
    // periods beyond the line search's reach (fewer than min_cycles per record)
    let p_grid = wvar_fit::log_grid(dur / SearchParams::default().min_cycles, dur / 2.0, 4);
    for _step in 0..MAX_STEPS {
        let l0 = data.loglik(&data.e0);
        let ctx = Ctx {
            data: &data,
            basis,
            cur: &cur,
            regions: &region_text,
            f_lo_flicker: model.flicker_f_lo_hz(),
            d2_12: model.gyro.pulse_arcsec.powi(2) / 12.0,
            tc_grid: &tc_grid,
            p_grid: &p_grid,
            blocks: &r.blocks,
        };
        let mut cands = parameter_candidates(&ctx);
        if readout::offered(model)
            && let Some(ff) = readout::fit(&data, basis, cur.n2, cur.filter)
        {
            let mut m = model.clone();
            m.readout_filter = cur
                .filter
                .map(|f| ReadoutFilterParams::from_filter(&f, model.tau0_s()));
            let finding = readout::finding(&ff, &m, cur.n2, &region_text);
            cands.push(Candidate {
                fit: ff.fit,
                param_only: cur.filter.is_some(),
                finding,
            });
        }
        let joint = (joint_readout && readout::offered(model))
            .then(|| filter_with_white_angle(&ctx, model))
            .flatten()
            .map(|(cand, q)| {
                cands.push(cand);
                (cands.len() - 1, q)
            });
        let new_gm_index = cands.len();
        let has_new_gm = new_gauss_markov(&ctx).map(|c| cands.push(c)).is_some();
        cands.extend(new_sinusoid(&ctx));
        let Some(pick) = choose(&cands) else {
            break;
        };
        let with_q = joint.and_then(|(i, q)| (i == pick).then_some(q));
        let c = cands.swap_remove(pick);
        let dev = 2.0 * (c.fit.loglik - l0);
        if !(dev > chi2_quantile(0.99, c.fit.n_par as f64)) {
            break;
        }
        // accept: update the expectation and the current amplitudes
        for j in 0..data.e0.len() {
            data.e0[j] += c.fit.delta_mu[j];
        }
        cur.accept(&c.finding.edit);
        let is_new_gm = (has_new_gm && pick == new_gm_index)
            || matches!(c.finding.edit, Edit::GaussMarkov { index: None, .. });
        out.push((c.finding, is_new_gm));
        if let Some(q) = with_q {
            cur.accept(&q.edit);
            out.push((q, false));
        }
    }
    // only the first new Gauss-Markov term is tested against a random telegraph
    let mut seen = false;
    for (_, flag) in out.iter_mut() {
        if *flag {
            if seen {
                *flag = false;
            }
            seen = true;
        }
    }
    out
}

/// The readout filter with the white angle noise after it refitted beside it
/// ([`readout_angle`]): the filter's candidate (three parameters) and the
/// Q finding accepted with it.
fn filter_with_white_angle(c: &Ctx, model: &GyroModel) -> Option<(Candidate, Finding)> {
    let j = readout_angle::fit(c.data, c.basis, c.cur.n2, c.cur.q2, c.d2_12, c.cur.filter)?;
    let mut m = model.clone();
    m.readout_filter = c
        .cur
        .filter
        .map(|f| ReadoutFilterParams::from_filter(&f, model.tau0_s()));
    let mut finding = readout::finding(&j.filter, &m, c.cur.n2, c.regions);
    finding.n_par = 3;
    let (q0, q) = (c.cur.q2.sqrt(), j.q2.sqrt());
    let q_finding = Finding {
        edit: Edit::QuantizationBesideFilter {
            quantization_arcsec: q,
            profile_widen: j.q_profile_widen,
        },
        changes: vec![ParameterChange {
            term: "quantization_arcsec".into(),
            model: q0,
            fitted: q,
            ci95: sqrt_ci(j.q2_ci, |x| x),
        }],
        added: None,
        n_par: 1,
        note: format!(
            "quantization_arcsec: {} -> {} arcsec: white angle noise after the readout filter, fitted \
             with it (the readout's own error, added after the filter, fills the finest levels back in; \
             mismatch at {})",
            fmt_g(q0),
            fmt_g(q),
            c.regions
        ),
    };
    let cand = Candidate {
        fit: j.filter.fit,
        param_only: c.cur.filter.is_some(),
        finding,
    };
    Some((cand, q_finding))
}

/// The best parameter-only change and the best new term, by AIC: the
/// parameter change wins unless the new term is better by more than 2.
fn choose(cands: &[Candidate]) -> Option<usize> {
    let aic = |c: &Candidate| -2.0 * c.fit.loglik + 2.0 * c.fit.n_par as f64;
    let best = |param: bool| {
        cands
            .iter()
            .enumerate()
            .filter(|(_, c)| c.param_only == param && c.fit.loglik.is_finite())
            .min_by(|a, b| aic(a.1).total_cmp(&aic(b.1)))
    };
    match (best(true), best(false)) {
        (Some(p), Some(nw)) => Some(if aic(p.1) <= aic(nw.1) + 2.0 {
            p.0
        } else {
            nw.0
        }),
        (Some(p), None) => Some(p.0),
        (None, Some(nw)) => Some(nw.0),
        (None, None) => None,
    }
}

/// Changes of the model's own parameters (bias instability and RRW become
/// new terms when the model lacks them).
fn parameter_candidates(c: &Ctx) -> Vec<Candidate> {
    let mut cands = vec![quantization_candidate(c), arw_candidate(c)];
    cands.push(flicker_or_rrw(c, true));
    cands.push(flicker_or_rrw(c, false));
    for (i, &(s2, tc)) in c.cur.gm.iter().enumerate() {
        cands.extend(gauss_markov_changes(c, i, s2, tc));
    }
    for (i, &(a2, dwell)) in c.cur.rtn.iter().enumerate() {
        let phi0 = c.basis.gauss_markov(dwell / 2.0);
        let fit = wvar_fit::fit_amplitude(c.data, &phi0, a2, 0.0);
        let v = fit.theta.sqrt();
        cands.push(Candidate {
            finding: Finding {
                edit: Edit::Telegraph {
                    index: Some(i),
                    amplitude_dph: v,
                    mean_dwell_s: dwell,
                },
                changes: vec![ParameterChange {
                    term: format!("random_telegraph[{i}].amplitude_dph"),
                    model: a2.sqrt(),
                    fitted: v,
                    ci95: sqrt_ci(fit.theta_ci, |x| x),
                }],
                added: None,
                n_par: 1,
                note: format!(
                    "random_telegraph[{i}].amplitude_dph: {} -> {} deg/h",
                    fmt_g(a2.sqrt()),
                    fmt_g(v)
                ),
            },
            fit,
            param_only: true,
        });
    }
    cands
}

fn quantization_candidate(c: &Ctx) -> Candidate {
    let q2 = c.cur.q2;
    let fit = wvar_fit::fit_amplitude(c.data, &c.basis.white_angle(), q2, c.d2_12);
    let v = fit.theta.sqrt();
    Candidate {
        finding: Finding {
            edit: Edit::Quantization(v),
            changes: vec![ParameterChange {
                term: "quantization_arcsec".into(),
                model: q2.sqrt(),
                fitted: v,
                ci95: sqrt_ci(fit.theta_ci, |x| x),
            }],
            added: None,
            n_par: 1,
            note: format!(
                "quantization_arcsec: {} -> {} arcsec (parameter change; mismatch at {})",
                fmt_g(q2.sqrt()),
                fmt_g(v),
                c.regions
            ),
        },
        fit,
        param_only: true,
    }
}

fn arw_candidate(c: &Ctx) -> Candidate {
    let n2 = c.cur.n2;
    let fit = wvar_fit::fit_amplitude(c.data, &c.basis.white_rate_through(c.cur.filter), n2, 0.0);
    let v = units::arcsec_per_sqrt_s_to_dpsh(fit.theta.sqrt());
    let old = units::arcsec_per_sqrt_s_to_dpsh(n2.sqrt());
    Candidate {
        finding: Finding {
            edit: Edit::Arw(v),
            changes: vec![ParameterChange {
                term: "arw_dpsh".into(),
                model: old,
                fitted: v,
                ci95: sqrt_ci(fit.theta_ci, units::arcsec_per_sqrt_s_to_dpsh),
            }],
            added: None,
            n_par: 1,
            note: format!(
                "arw_dpsh: {} -> {} deg/sqrt(h): the angle random walk is {} than modelled, at every \
                 scale where it dominates (a parameter change, no new physics; mismatch at {})",
                fmt_g(old),
                fmt_g(v),
                if v > old { "stronger" } else { "weaker" },
                c.regions
            ),
        },
        fit,
        param_only: n2 > 0.0,
    }
}

/// Bias instability (`flicker`) or RRW: a parameter change when the model has
/// the term, else a new term.
fn flicker_or_rrw(c: &Ctx, flicker: bool) -> Candidate {
    let (theta0, phi) = if flicker {
        (c.cur.b2, c.basis.flicker(c.f_lo_flicker))
    } else {
        (c.cur.k2, c.basis.rrw())
    };
    let is_param = theta0 > 0.0;
    let fit = wvar_fit::fit_amplitude(c.data, &phi, theta0, 0.0);
    let (key, unit, conv): (&str, &str, UnitConv) = if flicker {
        ("bias_instability_dph", "deg/h", units::arcsec_per_s_to_dph)
    } else {
        (
            "rrw_dphsh",
            "deg/h/sqrt(h)",
            units::arcsec_per_s_sqrt_s_to_dphsh,
        )
    };
    // B is stored in deg/h = arcsec/s already; K needs its conversion
    let old = if flicker {
        theta0.sqrt()
    } else {
        conv(theta0.sqrt())
    };
    let v = conv(fit.theta.sqrt());
    let (edit, term) = if flicker {
        (
            Edit::BiasInstability(v),
            Term::BiasInstability {
                bias_instability_dph: v,
                f_lo_hz: c.f_lo_flicker,
                f_hi_hz: f64::INFINITY,
            },
        )
    } else {
        (Edit::Rrw(v), Term::RateRandomWalk { rrw_dphsh: v })
    };
    let ci = sqrt_ci(fit.theta_ci, conv);
    let (changes, added) = if is_param {
        (
            vec![ParameterChange {
                term: key.into(),
                model: old,
                fitted: v,
                ci95: ci,
            }],
            None,
        )
    } else {
        let explanation = format!(
            "{} Fitted {} {unit} on the wavelet variances (mismatch at {}).",
            term.explanation(),
            fmt_g(v),
            c.regions
        );
        let added = AddedTerm {
            term: key.into(),
            kind: None,
            params: BTreeMap::from([(key.to_string(), v)]),
            explanation,
            ci95: BTreeMap::from([(key.to_string(), ci)]),
        };
        (vec![], Some(added))
    };
    Candidate {
        finding: Finding {
            edit,
            changes,
            added,
            n_par: 1,
            note: format!("{key}: {} -> {} {unit}", fmt_g(old), fmt_g(v)),
        },
        fit,
        param_only: is_param,
    }
}

/// The model's gauss_markov[i]: its amplitude alone, and amplitude and time constant.
fn gauss_markov_changes(c: &Ctx, i: usize, s2: f64, tc: f64) -> Vec<Candidate> {
    let phi0 = c.basis.gauss_markov(tc);
    let fit = wvar_fit::fit_amplitude(c.data, &phi0, s2, 0.0);
    let v = fit.theta.sqrt();
    let sigma_change = |v: f64, fit: &Fit| ParameterChange {
        term: format!("gauss_markov[{i}].sigma_dph"),
        model: s2.sqrt(),
        fitted: v,
        ci95: sqrt_ci(fit.theta_ci, |x| x),
    };
    let mut out = vec![Candidate {
        finding: Finding {
            edit: Edit::GaussMarkov {
                index: Some(i),
                sigma_dph: v,
                tau_c_s: tc,
            },
            changes: vec![sigma_change(v, &fit)],
            added: None,
            n_par: 1,
            note: format!(
                "gauss_markov[{i}].sigma_dph: {} -> {} deg/h",
                fmt_g(s2.sqrt()),
                fmt_g(v)
            ),
        },
        fit,
        param_only: true,
    }];
    let gm = |t: f64| c.basis.gauss_markov(t);
    if let Some(fit) = wvar_fit::fit_shape(c.data, c.tc_grid, &gm, Some((s2, &phi0))) {
        let v = fit.theta.sqrt();
        let t = fit.shape.unwrap_or(tc);
        let tci = fit.shape_ci.unwrap_or((t, t));
        let tc_change = ParameterChange {
            term: format!("gauss_markov[{i}].tau_c_s"),
            model: tc,
            fitted: t,
            ci95: [tci.0, tci.1],
        };
        out.push(Candidate {
            finding: Finding {
                edit: Edit::GaussMarkov {
                    index: Some(i),
                    sigma_dph: v,
                    tau_c_s: t,
                },
                changes: vec![sigma_change(v, &fit), tc_change],
                added: None,
                n_par: 2,
                note: format!(
                    "gauss_markov[{i}]: sigma {} -> {} deg/h, tau_c {} -> {} s",
                    fmt_g(s2.sqrt()),
                    fmt_g(v),
                    fmt_g(tc),
                    fmt_g(t)
                ),
            },
            fit,
            param_only: true,
        });
    }
    out
}

/// A new Gauss-Markov bias (time constant on a log grid).
fn new_gauss_markov(c: &Ctx) -> Option<Candidate> {
    let fit = wvar_fit::fit_shape(c.data, c.tc_grid, &|t| c.basis.gauss_markov(t), None)?;
    let v = fit.theta.sqrt();
    let t = fit.shape.unwrap_or(1.0);
    let tci = fit.shape_ci.unwrap_or((t, t));
    let term = Term::GaussMarkov {
        sigma_dph: v,
        tau_c_s: t,
    };
    let arw_equiv = units::arcsec_per_sqrt_s_to_dpsh((2.0 * v * v * t).sqrt());
    let expl = format!(
        "{} Fitted sigma = {} deg/h, Tc = {} s on the wavelet variances (mismatch at {}). \
         Above tau ~ {} s it adds 2 sigma^2 Tc to the Allan variance, like an extra ARW of {} deg/sqrt(h), \
         but its spectrum rolls off above {} Hz, which the wavelet levels resolve and the raw Allan \
         curve (dominated there by quantization noise) does not.",
        term.explanation(),
        fmt_g(v),
        fmt_g(t),
        c.regions,
        fmt_g(3.0 * t),
        fmt_g(arw_equiv),
        fmt_g(1.0 / (2.0 * PI * t))
    );
    let params = BTreeMap::from([("sigma_dph".to_string(), v), ("tau_c_s".to_string(), t)]);
    let ci = BTreeMap::from([
        ("sigma_dph".to_string(), sqrt_ci(fit.theta_ci, |x| x)),
        ("tau_c_s".to_string(), [tci.0, tci.1]),
    ]);
    Some(Candidate {
        finding: Finding {
            edit: Edit::GaussMarkov {
                index: None,
                sigma_dph: v,
                tau_c_s: t,
            },
            changes: vec![],
            added: Some(AddedTerm {
                term: "gauss_markov".into(),
                params,
                kind: None,
                explanation: expl,
                ci95: ci,
            }),
            n_par: 2,
            note: format!(
                "new gauss_markov: sigma {} deg/h, tau_c {} s",
                fmt_g(v),
                fmt_g(t)
            ),
        },
        fit,
        param_only: false,
    })
}

/// How far a slow sinusoid's amplitude fitted on the wavelet variances may
/// exceed the record's least-squares amplitude at its period before it is
/// refused as a description of the record.
const SLOW_SINE_MAX_RATIO: f64 = 3.0;

/// A new sinusoid too slow for the line search (periods above T / min_cycles),
/// refused when its amplitude is over [`SLOW_SINE_MAX_RATIO`] times what the
/// record holds at that period.
fn new_sinusoid(c: &Ctx) -> Option<Candidate> {
    if c.p_grid.len() <= 1 {
        return None;
    }
    let fit = wvar_fit::fit_shape(c.data, c.p_grid, &|p| c.basis.sinusoid(1.0 / p), None)?;
    let amp = fit.theta.sqrt();
    let p = fit.shape.unwrap_or(1.0);
    // A sinusoid of a few cycles per record is plain in the time domain: the
    // wavelet variances' excess is not one when the record holds far less at
    // that period (slow wander of another kind, fitted by a line's leakage).
    if amp > SLOW_SINE_MAX_RATIO * c.blocks.sine_amplitude(p) {
        return None;
    }
    let pci = fit.shape_ci.unwrap_or((p, p));
    let term = Term::Sinusoid {
        amplitude_dph: amp,
        period_s: p,
    };
    let params = BTreeMap::from([
        ("amplitude_dph".to_string(), amp),
        ("period_s".to_string(), p),
    ]);
    let ci = BTreeMap::from([
        ("amplitude_dph".to_string(), sqrt_ci(fit.theta_ci, |x| x)),
        ("period_s".to_string(), [pci.0, pci.1]),
    ]);
    let explanation = format!(
        "{} A long-period bias oscillation (too slow for the line search), fitted on the \
         wavelet variances: amplitude {} deg/h, period {} s (mismatch at {}).",
        term.explanation(),
        fmt_g(amp),
        fmt_g(p),
        c.regions
    );
    Some(Candidate {
        finding: Finding {
            edit: Edit::Sinusoid {
                index: None,
                amplitude_dph: amp,
                period_s: p,
            },
            changes: vec![],
            added: Some(AddedTerm {
                term: "sinusoid".into(),
                params,
                kind: None,
                explanation,
                ci95: ci,
            }),
            n_par: 2,
            note: format!(
                "new long-period sinusoid: amplitude {} deg/h, period {} s",
                fmt_g(amp),
                fmt_g(p)
            ),
        },
        fit,
        param_only: false,
    })
}
