//! The vocabulary the phases share: an [`Edit`] (one change to the model) and
//! a [`Finding`] (the edit with what the JSON reports about it: parameter
//! changes, an added term, the parameters it fitted, a note in words).
//!
//! Every phase that explains something (lines, the two-level test, the
//! broadband fit, the slope tests) returns findings; the refinement and the
//! report only read them.

use std::collections::BTreeMap;

use super::types::{AddedTerm, ParameterChange};
use crate::model::GyroModel;
use crate::model::config::{
    BiasStepParams, GaussMarkovParams, RandomTelegraphParams, ResonanceParams, SinusoidParams,
    SpikesParams, ThermalParams, WarmupParams,
};
use crate::model::filter::ReadoutFilterParams;

/// A unit conversion (internal units to the model file's).
pub(crate) type UnitConv = fn(f64) -> f64;

/// One change to the model, with what the JSON reports about it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Edit {
    Quantization(f64),
    /// Q fitted jointly with a readout filter (white angle noise after it):
    /// `profile_widen` as for the filter's ARW, how much wider (below,
    /// above) Q's interval is profiled over the filter and the white level
    /// than at them fixed.
    QuantizationBesideFilter {
        quantization_arcsec: f64,
        profile_widen: (f64, f64),
    },
    Arw(f64),
    BiasInstability(f64),
    Rrw(f64),
    RateRamp(f64),
    GaussMarkov {
        index: Option<usize>,
        sigma_dph: f64,
        tau_c_s: f64,
    },
    Telegraph {
        index: Option<usize>,
        amplitude_dph: f64,
        mean_dwell_s: f64,
    },
    Sinusoid {
        index: Option<usize>,
        amplitude_dph: f64,
        period_s: f64,
    },
    Thermal(ThermalParams),
    /// A readout filter (new or replacing the model's) with the white level
    /// refitted through it.
    ReadoutFilter {
        params: ReadoutFilterParams,
        arw_dpsh: f64,
        /// How much wider (below, above) the ARW's interval is when profiled
        /// over the corner's confidence set than at the fitted corner alone:
        /// the corner and the white level trade off, and a refit through the
        /// fitted filter carries only the conditional width.
        arw_profile_widen: (f64, f64),
    },
    /// Replace gauss_markov[i] by a telegraph (amplitude, mean dwell), fitted
    /// on the recording's wavelet variances.
    GaussMarkovToTelegraph(usize, f64, f64),
    /// Replace random_telegraph[i] by a Gauss-Markov term with the same spectrum.
    TelegraphToGaussMarkov(usize),
    /// A warm-up, bias steps or glitches the data-quality stage found (set
    /// as found; the diagnosis compared the recording without them).
    Warmup(WarmupParams),
    BiasStep(BiasStepParams),
    Spikes(SpikesParams),
    /// A new resonance.
    Resonance {
        sigma_dph: f64,
        centre_hz: f64,
        width_hz: f64,
    },
}

impl Edit {
    pub(crate) fn apply(&self, m: &mut GyroModel) {
        let n = &mut m.noise;
        match self {
            Edit::Quantization(v)
            | Edit::QuantizationBesideFilter {
                quantization_arcsec: v,
                ..
            } => n.quantization_arcsec = Some(*v),
            Edit::Arw(v) => n.arw_dpsh = Some(*v),
            Edit::BiasInstability(v) => n.bias_instability_dph = Some(*v),
            Edit::Rrw(v) => n.rrw_dphsh = Some(*v),
            Edit::RateRamp(v) => n.rate_ramp_dphh = Some(*v),
            Edit::GaussMarkov {
                index,
                sigma_dph,
                tau_c_s,
            } => {
                let p = GaussMarkovParams {
                    sigma_dph: *sigma_dph,
                    tau_c_s: *tau_c_s,
                };
                match index {
                    Some(i) => n.gauss_markov[*i] = p,
                    None => n.gauss_markov.push(p),
                }
            }
            Edit::Telegraph {
                index,
                amplitude_dph,
                mean_dwell_s,
            } => {
                let p = RandomTelegraphParams {
                    amplitude_dph: *amplitude_dph,
                    mean_dwell_s: *mean_dwell_s,
                };
                match index {
                    Some(i) => n.random_telegraph[*i] = p,
                    None => n.random_telegraph.push(p),
                }
            }
            Edit::Sinusoid {
                index,
                amplitude_dph,
                period_s,
            } => {
                let p = SinusoidParams {
                    amplitude_dph: *amplitude_dph,
                    period_s: *period_s,
                };
                match index {
                    Some(i) => n.sinusoid[*i] = p,
                    None => n.sinusoid.push(p),
                }
            }
            Edit::Thermal(t) => m.thermal = Some(t.clone()),
            Edit::Warmup(w) => n.warmup = Some(w.clone()),
            Edit::BiasStep(b) => n.bias_step.push(b.clone()),
            Edit::Spikes(s) => n.spikes = Some(s.clone()),
            Edit::ReadoutFilter {
                params, arw_dpsh, ..
            } => {
                m.readout_filter = Some(params.clone());
                m.noise.arw_dpsh = Some(*arw_dpsh);
            }
            Edit::GaussMarkovToTelegraph(i, amplitude_dph, mean_dwell_s) => {
                // zero amplitude keeps the indices of the other edits valid;
                // zero terms are dropped by `tidy`
                n.gauss_markov[*i].sigma_dph = 0.0;
                n.random_telegraph.push(RandomTelegraphParams {
                    amplitude_dph: *amplitude_dph,
                    mean_dwell_s: *mean_dwell_s,
                });
            }
            Edit::Resonance {
                sigma_dph,
                centre_hz,
                width_hz,
            } => n.resonance.push(ResonanceParams {
                sigma_dph: *sigma_dph,
                centre_hz: *centre_hz,
                width_hz: *width_hz,
            }),
            Edit::TelegraphToGaussMarkov(i) => {
                let r = n.random_telegraph[*i].clone();
                n.random_telegraph[*i].amplitude_dph = 0.0;
                n.gauss_markov.push(GaussMarkovParams {
                    sigma_dph: r.amplitude_dph,
                    tau_c_s: 0.5 * r.mean_dwell_s,
                });
            }
        }
    }
}

/// Drop catalog terms whose amplitude an edit set to zero.
pub(crate) fn tidy(m: &mut GyroModel) {
    let n = &mut m.noise;
    n.gauss_markov.retain(|g| g.sigma_dph > 0.0);
    n.random_telegraph.retain(|r| r.amplitude_dph > 0.0);
    n.sinusoid.retain(|s| s.amplitude_dph > 0.0);
    n.resonance.retain(|r| r.sigma_dph > 0.0);
}

/// `base` with every finding's edit applied, in order.
pub(crate) fn with_findings(base: &GyroModel, findings: &[Finding]) -> GyroModel {
    let mut m = base.clone();
    for f in findings {
        f.edit.apply(&mut m);
    }
    m
}

/// A finding: the edit, its JSON entries, the parameters it fitted.
#[derive(Debug, Clone)]
pub(crate) struct Finding {
    pub edit: Edit,
    pub changes: Vec<ParameterChange>,
    pub added: Option<AddedTerm>,
    pub n_par: usize,
    pub note: String,
}

impl Finding {
    /// Multiply every interval's half-widths by `s` about its value (a lower
    /// end at or above zero stays so): the Birge ratio `sqrt(chi2/dof)` of an
    /// updated model that does not fit the recording, whose misfit the fit's
    /// own intervals do not carry.
    /// A filter corner stays below the Nyquist frequency `nyquist_hz`.
    pub fn widen_for_misfit(&mut self, s: f64, nyquist_hz: f64) {
        let scale = |ci: &mut [f64; 2], v: f64, key: &str| {
            let lo = v - s * (v - ci[0]);
            ci[0] = if ci[0] >= 0.0 { lo.max(0.0) } else { lo };
            ci[1] = v + s * (ci[1] - v);
            if key.ends_with("corner_hz") {
                ci[1] = ci[1].min(nyquist_hz);
            }
        };
        for c in &mut self.changes {
            scale(&mut c.ci95, c.fitted, &c.term);
        }
        if let Some(a) = self.added.as_mut() {
            for (k, ci) in a.ci95.iter_mut() {
                if let Some(&v) = a.params.get(k) {
                    scale(ci, v, k);
                }
            }
        }
    }

    /// A one-parameter finding: a change of the model's parameter when the
    /// model `had` the term, else a new term. `keys` = (the change's term, the
    /// added term's name, its parameter's key).
    pub fn scalar(
        edit: Edit,
        had: bool,
        keys: (&str, &str, &str),
        model: f64,
        fitted: f64,
        ci95: [f64; 2],
        note: String,
    ) -> Finding {
        let (change, term, key) = keys;
        Finding {
            edit,
            changes: if had {
                vec![ParameterChange {
                    term: change.into(),
                    model,
                    fitted,
                    ci95,
                }]
            } else {
                vec![]
            },
            added: (!had).then(|| AddedTerm {
                term: term.into(),
                kind: None,
                params: BTreeMap::from([(key.to_string(), fitted)]),
                explanation: note.clone(),
                ci95: BTreeMap::from([(key.to_string(), ci95)]),
            }),
            n_par: 1,
            note,
        }
    }
}

/// Parameters fitted by all findings together (the chi2/dof's correction).
pub(crate) fn fitted_parameters(findings: &[Finding]) -> usize {
    findings.iter().map(|f| f.n_par).sum()
}

/// The findings' parameter changes, one per parameter: a parameter changed
/// twice (the broadband fit may move ARW, then Q, then ARW again) is reported
/// from the model's value to the last fitted one.
pub(crate) fn merged_changes(findings: &[Finding]) -> Vec<ParameterChange> {
    let mut out: Vec<ParameterChange> = Vec::new();
    for c in findings.iter().flat_map(|f| &f.changes) {
        match out.iter_mut().find(|o| o.term == c.term) {
            Some(o) => {
                o.fitted = c.fitted;
                o.ci95 = c.ci95;
            }
            None => out.push(c.clone()),
        }
    }
    out
}

/// A number for a sentence: 4 decimals trimmed, or 4 significant digits in
/// exponent form when very small or large.
pub(crate) fn fmt_g(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-3 && v.abs() < 1e5 {
        format!("{:.4}", v)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.3e}")
    }
}

/// The interval of an amplitude from that of its square, converted by `f`.
pub(crate) fn sqrt_ci(ci: (f64, f64), f: impl Fn(f64) -> f64) -> [f64; 2] {
    [f(ci.0.max(0.0).sqrt()), f(ci.1.max(0.0).sqrt())]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn misfit_widens_every_interval_about_its_value() {
        let mut f = Finding {
            edit: Edit::Arw(2.5),
            changes: vec![ParameterChange {
                term: "arw_dpsh".into(),
                model: 3.0,
                fitted: 2.5,
                ci95: [2.4, 2.7],
            }],
            added: Some(AddedTerm {
                term: "gauss_markov".into(),
                params: BTreeMap::from([("sigma_dph".to_string(), 10.0)]),
                kind: None,
                explanation: String::new(),
                ci95: BTreeMap::from([("sigma_dph".to_string(), [2.0, 12.0])]),
            }),
            n_par: 2,
            note: String::new(),
        };
        f.widen_for_misfit(3.0, 50.0);
        let c = f.changes[0].ci95;
        assert!(
            (c[0] - 2.2).abs() < 1e-12 && (c[1] - 3.1).abs() < 1e-12,
            "{c:?}"
        );
        // a non-negative lower end stays non-negative
        let a = f.added.as_ref().unwrap().ci95["sigma_dph"];
        assert_eq!(a, [0.0, 16.0]);
        // a corner interval ends below the Nyquist frequency
        let mut g = f.clone();
        g.changes[0].term = "readout_filter.corner_hz".into();
        g.changes[0].fitted = 49.0;
        g.changes[0].ci95 = [48.0, 49.9];
        g.widen_for_misfit(3.0, 50.0);
        assert_eq!(g.changes[0].ci95, [46.0, 50.0]);
    }
}
