//! The diagnosis proved on recordings where the left-out effect is
//! concealed, i.e. invisible in the raw Allan deviation within its band, yet
//! real. Each case simulates a "real" gyro (the model plus the effect) with
//! `model::sim`, diagnoses it against the model, and asserts that
//! * the raw Allan deviation alone does not see it (max |z| below its own
//!   Bonferroni 5 % threshold over its taus),
//! * the diagnosis says "mismatch", names the right physics (a parameter change
//!   when that is what happened, a new term otherwise) and its 95 % intervals
//!   cover the truth,
//! * the updated model, simulated again, fits: chi2/dof drops.
//!
//! Matched recordings (model = truth) must come out "consistent" with nothing
//! added. `bench_table` (ignored; `scripts/bench-diagnose` runs it) prints the
//! table of all cases.

use std::time::Instant;

use sagnac::diagnose::compare::{Family, bonferroni_z};
use sagnac::diagnose::{self, DiagnoseOptions, Diagnosis, Verdict};
use sagnac::model::GyroModel;

use crate::support;

/// What the diagnosis must find.
#[derive(Debug, Clone, Copy)]
enum Expect {
    /// A new term with these (parameter, truth) pairs.
    Added(&'static str, &'static [(&'static str, f64)]),
    /// A parameter change of an existing term.
    Param(&'static str, f64),
    /// A model Gauss-Markov term replaced by a telegraph (truth amplitude, dwell).
    GmToTelegraph(f64, f64),
    /// Nothing: the model is right.
    Consistent,
}

struct Case {
    name: &'static str,
    /// Effect, in words (for the table).
    what: &'static str,
    fs: f64,
    dur_s: f64,
    seed: u64,
    model: String,
    truth: String,
    expect: Expect,
}

fn gyro(fs: f64, input_dph: f64, q: f64, n: f64, extra: &str) -> String {
    format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = {input_dph}\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\n{extra}"
    )
}

fn cases() -> Vec<Case> {
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

struct Outcome {
    diag: Diagnosis,
    raw_threshold: f64,
    secs: f64,
}

fn run(case: &Case) -> Outcome {
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
fn judge(case: &Case, o: &Outcome) -> (String, String, bool) {
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

fn check(name: &str) {
    let case = cases().into_iter().find(|c| c.name == name).unwrap();
    let o = run(&case);
    let r = &o.diag.report;
    let (named, fit, ok) = judge(&case, &o);
    eprintln!(
        "{name}: raw-AV max|z| {:.2} (threshold {:.2}); detection max|z| {:.2} (threshold {:.2}), ramp z {:.2}; {named}; {fit}; chi2/dof {:.2} -> {:.2}",
        o.diag.raw_allan_max_z,
        o.raw_threshold,
        o.diag.max_abs_z,
        o.diag.z_crit,
        o.diag.ramp_z,
        r.fit_before.chi2_per_dof,
        r.fit_after.chi2_per_dof
    );
    eprintln!("{}", serde_json::to_string_pretty(r).unwrap());
    assert!(
        ok,
        "{name}: expected {:?}, got {named} / {fit}",
        case.expect
    );
    // concealed: the raw Allan deviation alone would not raise an alarm
    assert!(
        o.diag.raw_allan_max_z < o.raw_threshold,
        "{name}: raw Allan max |z| {} reaches its threshold {}",
        o.diag.raw_allan_max_z,
        o.raw_threshold
    );
    if !matches!(case.expect, Expect::Consistent) {
        // a thermal sensitivity (the rate regressed on the recorded temperature)
        // and a rate ramp (the rate's slope) are found by tests without a tau
        // range, and the chi2 points (wavelets, MDEV, spectrum) barely see them
        let slope_found = matches!(case.expect, Expect::Added("thermal" | "rate_ramp_dphh", _));
        // the fit improves (broadband effects), and the updated model fits
        // about as well as a matched one (all)
        assert!(
            slope_found || r.fit_after.chi2_per_dof < r.fit_before.chi2_per_dof,
            "{name}: chi2/dof {} -> {}",
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof
        );
        assert!(
            r.fit_after.chi2_per_dof < 1.5,
            "{name}: chi2/dof after {}",
            r.fit_after.chi2_per_dof
        );
        // every broadband or line effect is located in tau
        if !slope_found {
            assert!(!r.mismatch_regions.is_empty(), "{name}: no region located");
        }
        let m = o.diag.updated_model.as_ref().expect("an updated model");
        // the written model is valid and parses back
        let back = GyroModel::from_toml_str(&m.to_toml().unwrap(), "updated").unwrap();
        assert_eq!(&back, m);
    }
}

#[test]
fn gauss_markov_masquerading_as_arw_is_found() {
    check("gm_as_arw");
}

#[test]
fn sinusoid_buried_under_quantization_is_found() {
    check("sine_under_qn");
}

#[test]
fn gauss_markov_at_another_rate_duration_and_magnitude_is_found() {
    check("gm_as_arw_b");
}

#[test]
fn slow_sinusoid_under_quantization_is_found() {
    check("sine_b");
}

#[test]
fn arw_change_is_a_parameter_change_not_a_new_term() {
    check("arw_changed");
}

#[test]
fn random_telegraph_is_told_from_its_gauss_markov_twin() {
    check("telegraph");
}

#[test]
fn thermal_sensitivity_is_found_from_the_temperature_channel() {
    check("thermal");
}

#[test]
fn rate_ramp_is_found_by_the_slope_test() {
    check("rate_ramp");
}

#[test]
fn matched_paper_gyro_is_consistent() {
    check("null_paper");
}

#[test]
fn matched_rich_model_is_consistent() {
    check("null_rich");
}

/// The table of `scripts/bench-diagnose`. Each case is run with its own seed
/// (the detail columns) and `SAGNAC_BENCH_SEEDS - 1` further seeds (default
/// 3 in all); the last two columns count, over those seeds, the runs whose
/// named physics was right (with the truth in the widened intervals, as the
/// tests judge it) and the runs the raw Allan deviation alone missed.
#[test]
#[ignore]
fn bench_table() {
    let seeds: u64 = std::env::var("SAGNAC_BENCH_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3)
        .max(1);
    println!(
        "| case | effect | fs Hz | T s | raw-AV max|z| (5% thr) | verdict | named physics | fitted vs truth | chi2/dof before -> after | diagnose s | ok | correct / seeds | raw-AV concealed / seeds |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut misses = Vec::new();
    for mut case in cases() {
        let o = run(&case);
        let (named, fit, ok) = judge(&case, &o);
        let mut n_ok = ok as usize;
        let mut n_hid = (o.diag.raw_allan_max_z < o.raw_threshold) as usize;
        let base = case.seed;
        for k in 1..seeds {
            case.seed = base.wrapping_add(1000 * k);
            let ok_k = run(&case);
            let (named_k, fit_k, good) = judge(&case, &ok_k);
            n_ok += good as usize;
            n_hid += (ok_k.diag.raw_allan_max_z < ok_k.raw_threshold) as usize;
            if !good {
                misses.push(format!(
                    "{} seed {}: {:?}, {named_k} {fit_k} (detection max|z| {:.2}, threshold {:.2}; raw-AV max|z| {:.2})",
                    case.name,
                    case.seed,
                    ok_k.diag.report.verdict,
                    ok_k.diag.max_abs_z,
                    ok_k.diag.z_crit,
                    ok_k.diag.raw_allan_max_z
                ));
            }
        }
        case.seed = base;
        let r = &o.diag.report;
        println!(
            "| {} | {} | {} | {} | {:.2} ({:.2}) | {:?} | {} | {} | {:.2} -> {:.2} | {:.1} | {} | {n_ok}/{seeds} | {n_hid}/{seeds} |",
            case.name,
            case.what,
            case.fs,
            case.dur_s,
            o.diag.raw_allan_max_z,
            o.raw_threshold,
            r.verdict,
            named,
            fit,
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof,
            o.secs,
            if ok { "yes" } else { "NO" }
        );
    }
    for m in misses {
        println!("miss: {m}");
    }
}
