//! The concealed-effect cases, shared by the tests of `concealed.rs` (each at
//! its own seed) and the table of `examples/bench_diagnose` (over more seeds),
//! which includes this file by its path: each case's model and truth, the
//! diagnosis run on it, and the judgement of what it found.

use std::time::Instant;

use sagnac::diagnose::compare::{Family, bonferroni_z};
use sagnac::diagnose::{self, DiagnoseOptions, Diagnosis, Verdict};
use sagnac::model::GyroModel;

use crate::support;

/// What the diagnosis must find.
#[derive(Debug, Clone, Copy)]
pub enum Expect {
    /// A new term with these (parameter, truth) pairs.
    Added(&'static str, &'static [(&'static str, f64)]),
    /// A parameter change of an existing term.
    Param(&'static str, f64),
    /// A model Gauss-Markov term replaced by a telegraph (truth amplitude, dwell).
    GmToTelegraph(f64, f64),
    /// Nothing: the model is right.
    Consistent,
}

pub struct Case {
    pub name: &'static str,
    /// Effect, in words (for the table).
    #[allow(dead_code)] // read by the table only
    pub what: &'static str,
    #[allow(dead_code)] // read by the table only
    pub fs: f64,
    pub dur_s: f64,
    pub seed: u64,
    pub model: String,
    pub truth: String,
    pub expect: Expect,
}

fn gyro(fs: f64, input_dph: f64, q: f64, n: f64, extra: &str) -> String {
    format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = {input_dph}\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\n{extra}"
    )
}

pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "gm_as_arw",
            what: "Gauss-Markov, Tc 0.5 s: extra ARW above a few s",
            fs: 1000.0,
            dur_s: 1800.0,
            seed: 101,
            model: gyro(1000.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                1000.0,
                12.3,
                0.35,
                0.001,
                "[[noise.gauss_markov]]\nsigma_dph = 0.035\ntau_c_s = 0.5\n",
            ),
            expect: Expect::Added("gauss_markov", &[("sigma_dph", 0.035), ("tau_c_s", 0.5)]),
        },
        Case {
            name: "sine_under_qn",
            what: "sinusoid 0.05 deg/h at 1.25 Hz, under QN",
            fs: 250.0,
            dur_s: 1200.0,
            seed: 202,
            model: gyro(250.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                250.0,
                12.3,
                0.35,
                0.001,
                "[[noise.sinusoid]]\namplitude_dph = 0.05\nperiod_s = 0.8\n",
            ),
            expect: Expect::Added("sinusoid", &[("amplitude_dph", 0.05), ("period_s", 0.8)]),
        },
        Case {
            name: "gm_as_arw_b",
            what: "Gauss-Markov, Tc 0.5 s, other rate/duration/Q",
            fs: 2000.0,
            dur_s: 900.0,
            seed: 111,
            model: gyro(2000.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                2000.0,
                12.3,
                0.35,
                0.001,
                "[[noise.gauss_markov]]\nsigma_dph = 0.04\ntau_c_s = 0.5\n",
            ),
            expect: Expect::Added("gauss_markov", &[("sigma_dph", 0.04), ("tau_c_s", 0.5)]),
        },
        Case {
            name: "sine_b",
            what: "sinusoid 0.06 deg/h at 0.25 Hz, under QN",
            fs: 500.0,
            dur_s: 900.0,
            seed: 212,
            model: gyro(500.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                500.0,
                12.3,
                0.35,
                0.001,
                "[[noise.sinusoid]]\namplitude_dph = 0.06\nperiod_s = 4.0\n",
            ),
            expect: Expect::Added("sinusoid", &[("amplitude_dph", 0.06), ("period_s", 4.0)]),
        },
        Case {
            name: "arw_changed",
            what: "ARW 0.0010 -> 0.00115 deg/sqrt(h), Q 0.6\"",
            fs: 2000.0,
            dur_s: 600.0,
            seed: 303,
            model: gyro(2000.0, 15.0, 0.6, 0.001, ""),
            truth: gyro(2000.0, 15.0, 0.6, 0.00115, ""),
            expect: Expect::Param("arw_dpsh", 0.00115),
        },
        Case {
            name: "telegraph",
            what: "mode hops +-0.06 deg/h, dwell 20 s (model: its GM twin), dithered counter",
            fs: 200.0,
            dur_s: 3600.0,
            seed: 404,
            model: gyro(
                200.0,
                12.3,
                0.7,
                0.001,
                "[[noise.gauss_markov]]\nsigma_dph = 0.06\ntau_c_s = 10.0\n",
            ),
            truth: gyro(
                200.0,
                12.3,
                0.7,
                0.001,
                "[[noise.random_telegraph]]\namplitude_dph = 0.06\nmean_dwell_s = 20.0\n",
            ),
            expect: Expect::GmToTelegraph(0.06, 20.0),
        },
        Case {
            name: "thermal",
            what: "bias 0.005 deg/h per deg C; temp_c 25 C + 0.5 C/h + 1 C sine (120 s); model has no thermal term",
            fs: 100.0,
            dur_s: 3600.0,
            seed: 707,
            model: gyro(100.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                100.0,
                12.3,
                0.35,
                0.001,
                "[thermal]\ntemp_c0 = 25.0\nramp_c_per_h = 0.5\nsine_amplitude_c = 1.0\nsine_period_s = 120.0\n\
                 bias_sensitivity_dph_per_c = 0.005\n",
            ),
            expect: Expect::Added("thermal", &[("bias_sensitivity_dph_per_c", 0.005)]),
        },
        Case {
            name: "thermal_ramp",
            what: "bias 0.01 deg/h per deg C; temp_c 25 C + 2 C/h (a chamber ramp: the response is a rate ramp of 0.02 deg/h/h); model has no thermal term",
            fs: 200.0,
            dur_s: 3600.0,
            seed: 909,
            model: gyro(200.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(
                200.0,
                12.3,
                0.35,
                0.001,
                "[thermal]\ntemp_c0 = 25.0\nramp_c_per_h = 2.0\nbias_sensitivity_dph_per_c = 0.01\n",
            ),
            expect: Expect::Added("thermal", &[("bias_sensitivity_dph_per_c", 0.01)]),
        },
        Case {
            name: "rate_ramp",
            what: "rate ramp 0.02 deg/h/h",
            fs: 200.0,
            dur_s: 3600.0,
            seed: 808,
            model: gyro(200.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(200.0, 12.3, 0.35, 0.001, "rate_ramp_dphh = 0.02\n"),
            expect: Expect::Added("rate_ramp_dphh", &[("rate_ramp_dphh", 0.02)]),
        },
        Case {
            name: "null_paper",
            what: "matched: paper gyro",
            fs: 1000.0,
            dur_s: 600.0,
            seed: 505,
            model: gyro(1000.0, 12.3, 0.35, 0.001, ""),
            truth: gyro(1000.0, 12.3, 0.35, 0.001, ""),
            expect: Expect::Consistent,
        },
        Case {
            name: "null_rich",
            what: "matched: BI + GM + sinusoid",
            fs: 200.0,
            dur_s: 1800.0,
            seed: 606,
            model: gyro(
                200.0,
                -4.0,
                0.5,
                0.0015,
                "bias_instability_dph = 0.003\n[[noise.gauss_markov]]\nsigma_dph = 0.05\ntau_c_s = 5.0\n\
                 [[noise.sinusoid]]\namplitude_dph = 0.02\nperiod_s = 40.0\n",
            ),
            truth: gyro(
                200.0,
                -4.0,
                0.5,
                0.0015,
                "bias_instability_dph = 0.003\n[[noise.gauss_markov]]\nsigma_dph = 0.05\ntau_c_s = 5.0\n\
                 [[noise.sinusoid]]\namplitude_dph = 0.02\nperiod_s = 40.0\n",
            ),
            expect: Expect::Consistent,
        },
    ]
}

pub struct Outcome {
    pub diag: Diagnosis,
    pub raw_threshold: f64,
    /// The diagnosis's wall time, s (for the table).
    #[allow(dead_code)] // read by the table only
    pub secs: f64,
}

pub fn run(case: &Case) -> Outcome {
    let model = GyroModel::from_toml_str(&case.model, case.name).unwrap();
    let truth = GyroModel::from_toml_str(&case.truth, case.name).unwrap();
    let rec = support::simulated_recording(&truth, case.seed, case.dur_s);
    let t = Instant::now();
    let diag = diagnose::diagnose(&model, &rec, &DiagnoseOptions::default()).unwrap();
    let secs = t.elapsed().as_secs_f64();
    // none of these effects is narrowband noise (a line is a line)
    assert!(
        !diag
            .notes
            .iter()
            .any(|n| n.starts_with("Narrowband excess")),
        "{}: {:?}",
        case.name,
        diag.notes
    );
    let n_raw = diag
        .before
        .iter()
        .filter(|p| p.family == Family::RawAllan)
        .count();
    Outcome {
        raw_threshold: bonferroni_z(0.05, n_raw),
        diag,
        secs,
    }
}

/// The truth lies inside the 95 % interval widened by half around its centre
/// (about +-3 sigma): one fixed-seed case may miss a 95 % interval one time
/// in twenty, a 3-sigma interval one time in 370.
fn covers(ci: [f64; 2], v: f64) -> bool {
    let c = 0.5 * (ci[0] + ci[1]);
    let h = 0.75 * (ci[1] - ci[0]);
    c - h <= v && v <= c + h
}

fn covers95(ci: [f64; 2], v: f64) -> &'static str {
    if ci[0] <= v && v <= ci[1] {
        "in 95% CI"
    } else {
        "outside 95% CI, inside 3 sigma"
    }
}

/// The case's verdict in words, and whether it matches the expectation.
pub fn judge(case: &Case, o: &Outcome) -> (String, String, bool) {
    let r = &o.diag.report;
    match case.expect {
        Expect::Consistent => {
            let ok = r.verdict == Verdict::Consistent
                && r.added_terms.is_empty()
                && r.parameter_changes.is_empty();
            ("consistent".into(), String::new(), ok)
        }
        Expect::Added(term, params) => {
            let found = r.added_terms.iter().find(|a| a.term == term);
            let named = r
                .added_terms
                .iter()
                .map(|a| a.term.as_str())
                .collect::<Vec<_>>()
                .join("+");
            let mut fits = Vec::new();
            let mut ok =
                r.verdict == Verdict::Mismatch && found.is_some() && r.parameter_changes.is_empty();
            if let Some(a) = found {
                for &(p, truth) in params {
                    let v = a.params.get(p).copied().unwrap_or(f64::NAN);
                    let ci = a.ci95.get(p).copied().unwrap_or([f64::NAN; 2]);
                    ok &= covers(ci, truth);
                    fits.push(format!(
                        "{p} {v:.4} [{:.4}, {:.4}] (truth {truth}, {})",
                        ci[0],
                        ci[1],
                        covers95(ci, truth)
                    ));
                }
            }
            (named, fits.join("; "), ok)
        }
        Expect::Param(key, truth) => {
            let found = r.parameter_changes.iter().find(|c| c.term == key);
            let named = r
                .parameter_changes
                .iter()
                .map(|c| c.term.as_str())
                .collect::<Vec<_>>()
                .join("+");
            let ok = r.verdict == Verdict::Mismatch
                && r.added_terms.is_empty()
                && found.is_some_and(|c| covers(c.ci95, truth));
            let fit = found.map_or(String::new(), |c| {
                format!(
                    "{key} {:.5} [{:.5}, {:.5}] (model {}, truth {truth}, {})",
                    c.fitted,
                    c.ci95[0],
                    c.ci95[1],
                    c.model,
                    covers95(c.ci95, truth)
                )
            });
            (format!("parameter: {named}"), fit, ok)
        }
        Expect::GmToTelegraph(a, dwell) => {
            let found = r.added_terms.iter().find(|t| t.term == "random_telegraph");
            let gm_off = r
                .parameter_changes
                .iter()
                .any(|c| c.term == "gauss_markov[0].sigma_dph" && c.fitted == 0.0);
            // the amplitude and dwell are fitted (not copied from the twin):
            // their intervals cover the truth
            let mut fits = Vec::new();
            let mut ok = r.verdict == Verdict::Mismatch && gm_off && found.is_some();
            if let Some(t) = found {
                for (p, truth) in [("amplitude_dph", a), ("mean_dwell_s", dwell)] {
                    let v = t.params.get(p).copied().unwrap_or(f64::NAN);
                    let ci = t.ci95.get(p).copied().unwrap_or([f64::NAN; 2]);
                    ok &= covers(ci, truth);
                    fits.push(format!(
                        "{p} {v:.4} [{:.4}, {:.4}] (truth {truth}, {})",
                        ci[0],
                        ci[1],
                        covers95(ci, truth)
                    ));
                }
            }
            let named = r
                .added_terms
                .iter()
                .map(|a| a.term.as_str())
                .collect::<Vec<_>>()
                .join("+");
            let k = o.diag.before.iter().find(|p| p.family == Family::Kurtosis);
            if let Some(p) = k {
                fits.push(format!(
                    "kurtosis {:.2} vs GM model {:.2} +- {:.2} (z {:.1})",
                    p.obs, p.model_mean, p.sd_log, p.z
                ));
            }
            let fit = fits.join("; ");
            (format!("{named} replaces gauss_markov[0]"), fit, ok)
        }
    }
}
