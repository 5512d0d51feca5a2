//! A random telegraph (mode hops) left out of the model is named as a
//! telegraph, and its Gauss-Markov twin (the same spectrum) as a
//! Gauss-Markov term, by the two-level likelihood ratio
//! (`src/diagnose/two_level.rs`). The gyro is the power table's telegraph
//! gyro (200 Hz, 1" pulse, ARW 0.002 deg/sqrt(h), 60 min) at +-0.08 deg/h,
//! dwell 10 s (15 sigma on the wavelet variances; named in 10 of 10 seeds of
//! `scripts/bench-diagnose --power --only "random telegraph" --size 0.08`,
//! where the most powerful test there is names it in 100 %,
//! `scripts/telegraph-oracle`). The seeds here are not the bench's.

use sagnac::diagnose::report::AddedTerm;
use sagnac::diagnose::{self, DiagnoseOptions, Verdict};
use sagnac::model::GyroModel;

use crate::support;

const BASE: &str = "[gyro]\nsample_rate_hz = 200.0\npulse_arcsec = 1.0\ninput_rate_dph = 10.0\n\
                    [noise]\nquantization_arcsec = 0.5773502691896257\narw_dpsh = 0.002\n";

fn model(extra: &str) -> GyroModel {
    GyroModel::from_toml_str(&format!("{BASE}{extra}"), "telegraph test").unwrap()
}

/// The one term the diagnosis adds to the plain model for a recording of `truth`.
fn added(truth: &GyroModel, seed: u64) -> AddedTerm {
    let rec = support::simulated_recording(truth, seed, 3600.0);
    let opts = DiagnoseOptions {
        seed: seed + 5000,
        ..DiagnoseOptions::default()
    };
    let d = diagnose::diagnose(&model(""), &rec, &opts).unwrap();
    let r = &d.report;
    eprintln!(
        "seed {seed}: added {:#?}\nchanges {:#?}",
        r.added_terms, r.parameter_changes
    );
    assert_eq!(r.verdict, Verdict::Mismatch);
    assert_eq!(r.added_terms.len(), 1, "one added term");
    r.added_terms[0].clone()
}

#[test]
fn mode_hops_are_named_a_random_telegraph() {
    let truth = model("[[noise.random_telegraph]]\namplitude_dph = 0.08\nmean_dwell_s = 10.0\n");
    for seed in [61, 62] {
        let a = added(&truth, seed);
        assert_eq!(a.term, "random_telegraph");
        let [lo, hi] = a.ci95["amplitude_dph"];
        assert!(
            lo <= 0.08 && 0.08 <= hi,
            "amplitude [{lo}, {hi}] holds 0.08"
        );
        let [lo, hi] = a.ci95["mean_dwell_s"];
        assert!(lo <= 10.0 && 10.0 <= hi, "dwell [{lo}, {hi}] s holds 10 s");
        assert!(a.explanation.contains("two-level log likelihood ratio"));
    }
}

#[test]
fn its_gauss_markov_twin_stays_gauss_markov() {
    let truth = model("[[noise.gauss_markov]]\nsigma_dph = 0.08\ntau_c_s = 5.0\n");
    for seed in [61, 62] {
        let a = added(&truth, seed);
        assert_eq!(a.term, "gauss_markov");
        let [lo, hi] = a.ci95["sigma_dph"];
        assert!(lo <= 0.08 && 0.08 <= hi, "sigma [{lo}, {hi}] holds 0.08");
        assert!(a.explanation.contains("is not shown two-level"));
    }
}
