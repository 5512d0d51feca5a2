//! A resonance the model leaves out is located (the narrowband
//! check), named as the catalog's `resonance` with its centre, width and
//! sigma inside their 95 % intervals, and the updated model fits (chi2/dof
//! about 1). The gyro is the ADIS16405's datasheet model with a 19 Hz mode;
//! a second case passes the mode through the readout filter the model
//! already has, so the filter's gain must be divided out of the fitted sigma.
//! A third is a pulse counter like the paper's (1 kHz, 1.21"), whose 50 Hz
//! mode stands only 10-30 % above the quantization noise in the spectrum and
//! leaves a white tail that looks like angle random walk: the mode is named,
//! and the ARW is not changed (or, if changed, its interval holds the truth).

use sagnac::diagnose::{self, DiagnoseOptions, Verdict};
use sagnac::model::GyroModel;

use crate::support;

const RESONANCE: (f64, f64, f64) = (1200.0, 19.0, 1.5);

fn model(extra: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\nrate_lsb_dps = 0.05\n\
         [noise]\narw_dpsh = 3.0\nbias_instability_dph = 25.0\n{extra}"
    );
    GyroModel::from_toml_str(&text, "resonance test").unwrap()
}

fn with_resonance(filter: &str) -> GyroModel {
    let (s, f0, w) = RESONANCE;
    model(&format!(
        "[[noise.resonance]]\nsigma_dph = {s}\ncentre_hz = {f0}\nwidth_hz = {w}\n{filter}"
    ))
}

fn check(truth: &GyroModel, under_test: &GyroModel, seed: u64) {
    let rec = support::simulated_recording(truth, seed, 3600.0);
    let opts = DiagnoseOptions {
        seed: seed + 1000,
        ..DiagnoseOptions::default()
    };
    let d = diagnose::diagnose(under_test, &rec, &opts).unwrap();
    let r = &d.report;
    eprintln!("notes {:#?}\nadded {:#?}", d.notes, r.added_terms);
    assert_eq!(r.verdict, Verdict::Mismatch);
    let a = r
        .added_terms
        .iter()
        .find(|a| a.term == "resonance")
        .expect("a resonance named");
    let (s, f0, w) = RESONANCE;
    for (key, truth) in [("sigma_dph", s), ("centre_hz", f0), ("width_hz", w)] {
        let ci = a.ci95[key];
        assert!(
            ci[0] <= truth && truth <= ci[1],
            "{key}: truth {truth} outside {ci:?} (fitted {})",
            a.params[key]
        );
        // an interval that says something: within 10 % of the value
        assert!(ci[1] - ci[0] < 0.2 * truth, "{key}: {ci:?}");
    }
    assert!(
        r.fit_before.chi2_per_dof > 10.0 && r.fit_after.chi2_per_dof < 1.5,
        "chi2/dof {} -> {}",
        r.fit_before.chi2_per_dof,
        r.fit_after.chi2_per_dof
    );
    // explained: no excess is left, and nothing else was bent to imitate it
    assert!(!d.notes.iter().any(|n| n.starts_with("Narrowband excess")));
    assert!(
        !r.added_terms.iter().any(|a| a.term == "readout_filter"),
        "{:?}",
        r.added_terms
    );
    // the written model holds the resonance and reads back
    let m = d.updated_model.expect("an updated model");
    let text = toml::to_string(&m).unwrap();
    let back = GyroModel::from_toml_str(&text, "written").unwrap();
    let res = &back.noise.resonance;
    assert_eq!(res.len(), 1, "{text}");
    assert_eq!(res[0].sigma_dph, a.params["sigma_dph"]);
    assert_eq!(res[0].centre_hz, a.params["centre_hz"]);
}

#[test]
fn a_resonance_left_out_is_named_and_fitted() {
    check(&with_resonance(""), &model(""), 7);
}

#[test]
fn a_resonance_behind_the_readout_filter_keeps_its_own_sigma() {
    // a first-order 25 Hz filter passes |H|^2 = 0.63 at 19 Hz
    let filter = "[readout_filter]\nkind = \"first_order\"\ncorner_hz = 25.0\n";
    check(&with_resonance(filter), &model(filter), 21);
}

/// The paper's pulse counter (1 kHz, 1.21", Q = sqrt(1.21^2/12 + 0.5^2)) with
/// `extra` in its noise table.
fn counter(extra: &str) -> GyroModel {
    let q = (1.21f64 * 1.21 / 12.0 + 0.25).sqrt();
    let text = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 10.0\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.002\n{extra}"
    );
    GyroModel::from_toml_str(&text, "counter").unwrap()
}

#[test]
fn a_resonance_under_the_quantization_noise_is_named_and_the_arw_kept() {
    let (s, f0, w) = (20.0, 50.0, 3.0);
    let truth = counter(&format!(
        "[[noise.resonance]]\nsigma_dph = {s}\ncentre_hz = {f0}\nwidth_hz = {w}\n"
    ));
    for seed in [3, 11] {
        let rec = support::simulated_recording(&truth, seed, 1200.0);
        let opts = DiagnoseOptions {
            seed: seed + 1000,
            ..DiagnoseOptions::default()
        };
        let d = diagnose::diagnose(&counter(""), &rec, &opts).unwrap();
        let r = &d.report;
        eprintln!(
            "notes {:#?}\nadded {:#?}\nchanges {:#?}",
            d.notes, r.added_terms, r.parameter_changes
        );
        let a = r
            .added_terms
            .iter()
            .find(|a| a.term == "resonance")
            .expect("a resonance named");
        for (key, truth) in [("sigma_dph", s), ("centre_hz", f0), ("width_hz", w)] {
            let ci = a.ci95[key];
            assert!(
                ci[0] <= truth && truth <= ci[1],
                "{key}: {truth} outside {ci:?}"
            );
        }
        for c in r.parameter_changes.iter().filter(|c| c.term == "arw_dpsh") {
            assert!(c.ci95[0] <= 0.002 && 0.002 <= c.ci95[1], "{c:?}");
        }
        assert!(
            r.fit_after.chi2_per_dof < 1.5,
            "{}",
            r.fit_after.chi2_per_dof
        );
        assert!(!d.notes.iter().any(|n| n.starts_with("Narrowband excess")));
    }
}
