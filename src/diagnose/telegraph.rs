//! The two-level test: a random telegraph (mode hops between +a and -a, mean
//! dwell T) has the autocovariance `a^2 exp(-2|t|/T)` of a Gauss-Markov bias
//! with sigma = a, Tc = T/2, so no second-order statistic (spectrum, Allan or
//! wavelet variance) tells them apart. Their distributions differ: the rate
//! low-passed below the quantization noise has an excess kurtosis near -2 for
//! a two-level signal (plus the Gaussian background), 0 for a Gaussian one.
//!
//! Two uses, both referenced to Monte-Carlo runs:
//! * [`model_terms`] (phase 4, with the broadband fit): the kurtosis points of
//!   the model's own Gauss-Markov and telegraph terms ([`super::locate`]) say
//!   whether each has the right distribution; a wrong one is replaced by its
//!   twin, refitted on the wavelet variances.
//! * [`test_new_gauss_markov`] (phase 6, when the updated model is simulated):
//!   a Gauss-Markov term the broadband fit added is tested against a
//!   telegraph with the same spectrum by the two-level likelihood ratio
//!   ([`super::two_level`]), the most powerful statistic for that pair, and
//!   replaced only when it rejects the Gaussian term (one-sided, 1 %;
//!   [`ALPHA_TELEGRAPH`]).

use std::collections::BTreeMap;

use statrs::distribution::{ContinuousCDF, StudentsT};

use super::compare::{Family, Point};
use super::findings::{Edit, Finding, fmt_g, sqrt_ci, with_findings};
use super::locate::Located;
use super::mc;
use super::points::KTerm;
use super::reference::Reference;
use super::stats::StatSet;
use super::stream::{self, Extras};
use super::two_level::TwoLevelProbe;
use super::types::{AddedTerm, ParameterChange};
use super::types::{DiagnoseError, Recording, TelegraphTest};
use super::wvar_fit::{self, Basis, LevelData};
use crate::model::{GyroModel, Term};
use crate::units;

/// Findings from the kurtosis points of the model's Gauss-Markov and telegraph
/// terms that pass the detection threshold.
pub(crate) fn model_terms(
    r: &Reference,
    loc: &Located,
    basis: &Basis,
    data0: Option<&LevelData>,
) -> Vec<Finding> {
    let mut out = Vec::new();
    for p in loc
        .before
        .iter()
        .filter(|p| p.family == Family::Kurtosis && p.z.abs() > loc.z_crit)
    {
        match r.kterms[p.index] {
            KTerm::GaussMarkov(i) if p.z < 0.0 => {
                out.push(gauss_markov_to_telegraph(r, i, p, basis, data0))
            }
            KTerm::Telegraph(i) if p.z > 0.0 => out.push(telegraph_to_gauss_markov(&r.model, i, p)),
            _ => {}
        }
    }
    out
}

/// The model's gauss_markov[i] is two-level: a telegraph fitted on the
/// wavelet variances (as the Gauss-Markov term with the same second-order
/// statistics, in place of the model's) replaces it.
fn gauss_markov_to_telegraph(
    r: &Reference,
    i: usize,
    p: &Point,
    basis: &Basis,
    data0: Option<&LevelData>,
) -> Finding {
    let g = &r.model.noise.gauss_markov[i];
    let s2 = g.sigma_dph * g.sigma_dph;
    let phi0 = basis.gauss_markov(g.tau_c_s);
    let tc_grid = wvar_fit::log_grid(4.0 * r.tau0_s(), r.duration_s() / 3.0, 4);
    let fit = data0.and_then(|d| {
        wvar_fit::fit_shape(d, &tc_grid, &|t| basis.gauss_markov(t), Some((s2, &phi0)))
    });
    let (amp, dwell, ci) = match &fit {
        Some(f) if f.theta > 0.0 => {
            let tc = f.shape.unwrap_or(g.tau_c_s);
            let tci = f.shape_ci.unwrap_or((tc, tc));
            let mut ci = BTreeMap::new();
            ci.insert("amplitude_dph".to_string(), sqrt_ci(f.theta_ci, |x| x));
            ci.insert("mean_dwell_s".to_string(), [2.0 * tci.0, 2.0 * tci.1]);
            (f.theta.sqrt(), 2.0 * tc, ci)
        }
        _ => (g.sigma_dph, 2.0 * g.tau_c_s, BTreeMap::new()),
    };
    let t = Term::RandomTelegraph {
        amplitude_dph: amp,
        mean_dwell_s: dwell,
    };
    let fitted = if ci.is_empty() {
        "The wavelet variances could not be refitted: amplitude and dwell are the Gauss-Markov \
         term's (amplitude = sigma, mean dwell = 2 Tc)."
            .to_string()
    } else {
        let ca = ci["amplitude_dph"];
        let cd = ci["mean_dwell_s"];
        format!(
            "Fitted on the wavelet variances as the Gauss-Markov term with the same second-order \
             statistics (amplitude = sigma, mean dwell = 2 Tc): amplitude {} deg/h (95 % {}..{}), \
             mean dwell {} s (95 % {}..{}).",
            fmt_g(amp),
            fmt_g(ca[0]),
            fmt_g(ca[1]),
            fmt_g(dwell),
            fmt_g(cd[0]),
            fmt_g(cd[1])
        )
    };
    let expl = format!(
        "{} The model's gauss_markov[{i}] (sigma {} deg/h, Tc {} s) has the right spectrum and Allan \
         curve, but the low-passed rate (cut-off {} Hz) is two-level, not Gaussian: excess kurtosis \
         {:.2} against {:.2} +- {:.2} for the model (z = {:.1}). It is replaced by a random telegraph. \
         {fitted}",
        t.explanation(),
        fmt_g(g.sigma_dph),
        fmt_g(g.tau_c_s),
        fmt_g(1.0 / g.tau_c_s),
        p.obs,
        p.model_mean,
        p.sd_log,
        p.z
    );
    let params = BTreeMap::from([
        ("amplitude_dph".to_string(), amp),
        ("mean_dwell_s".to_string(), dwell),
    ]);
    let n_par = if ci.is_empty() { 0 } else { 2 };
    Finding {
        edit: Edit::GaussMarkovToTelegraph(i, amp, dwell),
        changes: vec![ParameterChange {
            term: format!("gauss_markov[{i}].sigma_dph"),
            model: g.sigma_dph,
            fitted: 0.0,
            ci95: [0.0, 0.0],
        }],
        added: Some(AddedTerm {
            term: "random_telegraph".into(),
            params,
            kind: None,
            explanation: expl.clone(),
            ci95: ci,
        }),
        n_par,
        note: expl,
    }
}

/// The model's random_telegraph[i] is not two-level: its Gauss-Markov twin replaces it.
fn telegraph_to_gauss_markov(model: &GyroModel, i: usize, p: &Point) -> Finding {
    let r = &model.noise.random_telegraph[i];
    let t = Term::GaussMarkov {
        sigma_dph: r.amplitude_dph,
        tau_c_s: 0.5 * r.mean_dwell_s,
    };
    let expl = format!(
        "{} The model's random_telegraph[{i}] (amplitude {} deg/h, dwell {} s) has the right spectrum, \
         but the low-passed rate is not two-level: excess kurtosis {:.2} against {:.2} +- {:.2} for \
         the model (z = {:.1}). It is replaced by a Gauss-Markov bias with the same second-order \
         statistics (sigma = amplitude, Tc = dwell / 2).",
        t.explanation(),
        fmt_g(r.amplitude_dph),
        fmt_g(r.mean_dwell_s),
        p.obs,
        p.model_mean,
        p.sd_log,
        p.z
    );
    let params = BTreeMap::from([
        ("sigma_dph".to_string(), r.amplitude_dph),
        ("tau_c_s".to_string(), 0.5 * r.mean_dwell_s),
    ]);
    Finding {
        edit: Edit::TelegraphToGaussMarkov(i),
        changes: vec![ParameterChange {
            term: format!("random_telegraph[{i}].amplitude_dph"),
            model: r.amplitude_dph,
            fitted: 0.0,
            ci95: [0.0, 0.0],
        }],
        added: Some(AddedTerm {
            term: "gauss_markov".into(),
            kind: None,
            params,
            explanation: expl.clone(),
            ci95: BTreeMap::new(),
        }),
        n_par: 0,
        note: expl,
    }
}

/// The model with the new Gauss-Markov term `findings[fi]` simulated as a
/// telegraph with the same spectrum instead (`None` when that finding is not
/// a new Gauss-Markov term).
pub(crate) fn telegraph_alternative(
    base: &GyroModel,
    findings: &[Finding],
    fi: usize,
) -> Option<(GyroModel, TwoLevelProbe)> {
    let Edit::GaussMarkov {
        index: None,
        sigma_dph,
        tau_c_s,
    } = findings[fi].edit
    else {
        return None;
    };
    let mut alt = base.clone();
    for (k, f) in findings.iter().enumerate() {
        if k == fi {
            Edit::Telegraph {
                index: None,
                amplitude_dph: sigma_dph,
                mean_dwell_s: 2.0 * tau_c_s,
            }
            .apply(&mut alt);
        } else {
            f.edit.apply(&mut alt);
        }
    }
    Some((
        alt,
        TwoLevelProbe {
            amp: units::dph_to_arcsec_per_s(sigma_dph),
            mean_dwell_s: 2.0 * tau_c_s,
        },
    ))
}

/// The updated model's runs after the two-level test of a new Gauss-Markov term.
pub(crate) struct TelegraphOutcome {
    pub test: TelegraphTest,
    /// The updated model and its runs, when the telegraph was chosen.
    pub replaced: Option<(GyroModel, Vec<StatSet>)>,
}

/// Runs of each model (the updated model with the Gauss-Markov term, and the
/// telegraph alternative) that reference the two-level statistic: only that
/// statistic is computed on them, so they are cheap, and with 24 the
/// Student-t threshold at [`ALPHA_TELEGRAPH`] is 2.5 sd of the Gauss-Markov
/// runs (3.2 sd with the 8 full runs of the updated model).
const TWO_LEVEL_RUNS: u64 = 24;

/// Test the new Gauss-Markov term `findings[fi]` against the telegraph
/// alternative `alt` by the two-level likelihood ratio of `probe` (the term's
/// own level and dwell), referenced to [`TWO_LEVEL_RUNS`] runs of each model.
/// Rewrites `findings[fi]`: a telegraph when chosen (its updated model then
/// simulated on `seeds`), else the explanation says why the Gauss-Markov
/// shape stays.
pub(crate) fn test_new_gauss_markov(
    r: &Reference,
    rec: &Recording,
    findings: &mut [Finding],
    fi: usize,
    (alt, probe): (&GyroModel, TwoLevelProbe),
    cutoffs: &[f64],
    seeds: &[u64],
) -> Result<TelegraphOutcome, DiagnoseError> {
    let temp = rec.temp_c.as_deref();
    let test_seeds: Vec<u64> = (0..TWO_LEVEL_RUNS)
        .map(|k| seeds[0].wrapping_add(7_000_003).wrapping_add(k))
        .collect();
    let gm_model = with_findings(&r.model, findings);
    let statistic_runs = |model: &GyroModel, phase: &'static str| {
        let job = mc::McJob {
            full: false,
            two_level: Some(probe),
            ..r.job(model, temp, &[]).phase(phase)
        };
        mc::run(&job, &test_seeds)
    };
    let runs_gm = statistic_runs(&gm_model, "simulating the Gauss-Markov term")?;
    let runs_alt = statistic_runs(alt, "simulating a random telegraph")?;
    // the recording's statistic, reduced as its runs are (no whole-length rate)
    let extras = Extras {
        temp_c: None,
        lp_cutoffs_hz: &[],
        two_level: Some(probe),
        full: false,
    };
    let obs = stream::reduce_counts(&r.layout, &rec.counts, extras).two_level_llr;
    let gl: Vec<f64> = runs_gm.iter().map(|s| s.two_level_llr).collect();
    let rl: Vec<f64> = runs_alt.iter().map(|s| s.two_level_llr).collect();
    let (choose, g, rt) = telegraph_decision(obs, &gl, &rl);
    let test = TelegraphTest {
        block_s: probe.block_s(r.tau0_s()),
        observed: obs,
        gauss_markov: g,
        telegraph: rt,
        telegraph_chosen: choose,
    };
    if choose {
        if let Some(f) = as_telegraph(&findings[fi], &test) {
            findings[fi] = f;
            let rebuilt = with_findings(&r.model, findings);
            let runs = mc::run(
                &r.job(&rebuilt, temp, cutoffs)
                    .phase("simulating the updated model"),
                seeds,
            )?;
            return Ok(TelegraphOutcome {
                test,
                replaced: Some((rebuilt, runs)),
            });
        }
    } else if let Some(a) = findings[fi].added.as_mut() {
        a.explanation.push_str(&format!(
            " The rate averaged over {} s blocks is not shown two-level: its two-level log likelihood ratio is \
             {:.1}, against {:.1} +- {:.1} for this Gauss-Markov term and {:.1} +- {:.1} for a random telegraph \
             with the same spectrum{}.",
            fmt_g(test.block_s),
            obs,
            g.0,
            g.1,
            rt.0,
            rt.1,
            if (rt.0 - g.0).abs() / ((g.1 * g.1 + rt.1 * rt.1) / 2.0).sqrt().max(1e-300) < 1.5 {
                " (the two are not separable at this record length: a random telegraph is not excluded)"
            } else {
                ""
            }
        ));
    }
    Ok(TelegraphOutcome {
        test,
        replaced: None,
    })
}

/// The new Gauss-Markov finding `old` restated as a random telegraph.
fn as_telegraph(old: &Finding, t: &TelegraphTest) -> Option<Finding> {
    let Edit::GaussMarkov {
        sigma_dph, tau_c_s, ..
    } = old.edit
    else {
        return None;
    };
    let a = old.added.as_ref().expect("a new term");
    let sci = a
        .ci95
        .get("sigma_dph")
        .copied()
        .unwrap_or([sigma_dph, sigma_dph]);
    let tci = a.ci95.get("tau_c_s").copied().unwrap_or([tau_c_s, tau_c_s]);
    let term = Term::RandomTelegraph {
        amplitude_dph: sigma_dph,
        mean_dwell_s: 2.0 * tau_c_s,
    };
    let (g, rt) = (t.gauss_markov, t.telegraph);
    let expl = format!(
        "{} The second-order statistics located it like a Gauss-Markov bias (sigma {} deg/h, \
         Tc {} s); the rate averaged over {} s blocks is two-level, not Gaussian: its two-level \
         log likelihood ratio is {:.1}, against {:.1} +- {:.1} for the Gauss-Markov model and \
         {:.1} +- {:.1} for a random telegraph.",
        term.explanation(),
        fmt_g(sigma_dph),
        fmt_g(tau_c_s),
        fmt_g(t.block_s),
        t.observed,
        g.0,
        g.1,
        rt.0,
        rt.1
    );
    let params = BTreeMap::from([
        ("amplitude_dph".to_string(), sigma_dph),
        ("mean_dwell_s".to_string(), 2.0 * tau_c_s),
    ]);
    let ci = BTreeMap::from([
        ("amplitude_dph".to_string(), sci),
        ("mean_dwell_s".to_string(), [2.0 * tci[0], 2.0 * tci[1]]),
    ]);
    Some(Finding {
        edit: Edit::Telegraph {
            index: None,
            amplitude_dph: sigma_dph,
            mean_dwell_s: 2.0 * tau_c_s,
        },
        changes: vec![],
        added: Some(AddedTerm {
            term: "random_telegraph".into(),
            params,
            kind: None,
            explanation: expl.clone(),
            ci95: ci,
        }),
        n_par: 2,
        note: expl,
    })
}

/// Mean and sample sd.
pub(crate) fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    (m, s)
}

/// One-sided false-telegraph probability of [`telegraph_decision`].
pub const ALPHA_TELEGRAPH: f64 = 0.01;

/// Test of a new Gauss-Markov term against a random telegraph with the same
/// spectrum by a statistic (the two-level likelihood ratio) observed on the
/// recording and on runs of both. The Gauss-Markov term (Gaussian, the
/// default: no second-order statistic tells the two apart) stays unless the
/// observed statistic rejects it: beyond the Gauss-Markov runs' mean towards the
/// telegraph's by the one-sided Student-t quantile at [`ALPHA_TELEGRAPH`]
/// (the runs' sd, as a prediction for one new draw), and closer to the
/// telegraph's runs by likelihood. A Gaussian bias is then called a telegraph
/// in at most about 1 % of records, whatever the record length; a telegraph
/// is named where the statistic separates them.
fn telegraph_decision(obs: f64, gm: &[f64], rtn: &[f64]) -> (bool, (f64, f64), (f64, f64)) {
    let g: Vec<f64> = gm.iter().copied().filter(|v| v.is_finite()).collect();
    let r: Vec<f64> = rtn.iter().copied().filter(|v| v.is_finite()).collect();
    if g.len() < 2 || r.len() < 2 || !obs.is_finite() {
        return (false, (f64::NAN, f64::NAN), (f64::NAN, f64::NAN));
    }
    let (mg, sg) = mean_sd(&g);
    let (mr, sr) = mean_sd(&r);
    let sg = sg.max(1e-3);
    let sr = sr.max(1e-3);
    let ll = |x: f64, m: f64, s: f64| -0.5 * ((x - m) / s).powi(2) - s.ln();
    let n = g.len() as f64;
    let t = StudentsT::new(0.0, 1.0, n - 1.0)
        .map(|d| d.inverse_cdf(1.0 - ALPHA_TELEGRAPH))
        .unwrap_or(f64::INFINITY);
    let toward = (obs - mg) * (mr - mg).signum() / (sg * (1.0 + 1.0 / n).sqrt());
    let choose = toward > t && ll(obs, mr, sr) > ll(obs, mg, sg);
    (choose, (mg, sg), (mr, sr))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// Over many records: a Gaussian bias is called a telegraph in about
    /// ALPHA_TELEGRAPH of them, whatever the separation; a separable telegraph
    /// is named.
    #[test]
    fn the_telegraph_is_chosen_only_when_the_statistic_rejects_the_gaussian_term() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut draw = |m: f64, s: f64, k: usize| -> Vec<f64> {
            let d = Normal::new(m, s).unwrap();
            (0..k).map(|_| d.sample(&mut rng)).collect()
        };
        let trials = 4000;
        for sep in [1.5, 3.0, 6.0] {
            let (mg, mr, sd) = (0.0, -0.1 * sep, 0.1);
            let (mut false_rtn, mut true_rtn) = (0, 0);
            for _ in 0..trials {
                let (g, r) = (draw(mg, sd, 8), draw(mr, sd, 8));
                let obs_gm = draw(mg, sd, 1)[0];
                let obs_rtn = draw(mr, sd, 1)[0];
                false_rtn += telegraph_decision(obs_gm, &g, &r).0 as usize;
                true_rtn += telegraph_decision(obs_rtn, &g, &r).0 as usize;
            }
            let fa = false_rtn as f64 / trials as f64;
            let power = true_rtn as f64 / trials as f64;
            assert!(fa <= 0.015, "separation {sep}: false telegraph {fa}");
            if sep >= 6.0 {
                assert!(power >= 0.95, "separation {sep}: telegraph named {power}");
            }
        }
    }
}
