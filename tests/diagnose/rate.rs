//! Rate-output gyros and readout filters in the diagnosis.
//! A rate-output model without a filter against recordings simulated with a
//! first-order filter and with a moving average: the catalog entry
//! `readout_filter` is named with the truth's corner inside its 95 %
//! interval, and chi2/dof drops; the matched rate-output model raises no
//! alarm over several seeds; a counts recording against a rate model is an
//! error that says so; a filter with white angle noise after it is named
//! with both (the filter and Q fitted together).

use sagnac::diagnose::{self, DiagnoseError, Recording, Verdict};
use sagnac::model::{GyroModel, Simulator};

use crate::support;

mod shared;

use shared::{named_filter, opts};

/// A MEMS-like rate gyro at 200 Hz: ARW 0.5 deg/sqrt(h), bias instability
/// 5 deg/h, rate word LSB 0.01 deg/s (the white noise per sample is
/// N sqrt(fs) = 0.5/60 sqrt(200) = 0.118 deg/s, 12 LSB).
fn model(filter: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = 200.0\noutput = \"rate\"\nrate_lsb_dps = 0.01\ninput_rate_dph = 10.0\n\
         [noise]\narw_dpsh = 0.5\nbias_instability_dph = 5.0\n{filter}"
    );
    GyroModel::from_toml_str(&text, "rate test").unwrap()
}

const DUR_S: f64 = 1200.0;

fn check_named(truth_filter: &str, kind: &str, corner_hz: f64, seed: u64) {
    let truth = model(truth_filter);
    let rec = support::simulated_recording(&truth, seed, DUR_S);
    assert_eq!(rec.rate_quantum_dps(), 0.01, "the words are the LSB counts");
    let d = diagnose::diagnose(&model(""), &rec, &opts(seed + 100)).unwrap();
    let r = &d.report;
    eprintln!("{kind}: notes {:#?}\n added {:#?}", d.notes, r.added_terms);
    assert_eq!(r.verdict, Verdict::Mismatch);
    // a filter's roll-off is not a peak
    assert!(!d.notes.iter().any(|n| n.starts_with("Narrowband excess")));
    let (k, fc, ci, _) = named_filter(&d).expect("readout_filter named");
    assert_eq!(k, kind);
    assert!(
        ci[0] <= corner_hz * (1.0 + 1e-9) && corner_hz <= ci[1] * (1.0 + 1e-9),
        "truth {corner_hz} Hz outside {ci:?} (fitted {fc})"
    );
    assert!(
        r.fit_after.chi2_per_dof < r.fit_before.chi2_per_dof,
        "chi2/dof {} -> {}",
        r.fit_before.chi2_per_dof,
        r.fit_after.chi2_per_dof
    );
    let m = d.updated_model.expect("an updated model");
    // the written model holds the filter and the ARW the report gives (the
    // finding moved to its refit about the updated model, or kept)
    let written = m.readout_filter().expect("a written filter");
    let tau0 = 1.0 / m.gyro.sample_rate_hz;
    assert!(
        (written.corner_hz(tau0) - fc).abs() <= 1e-9 * fc,
        "written corner {} Hz, reported {fc} Hz",
        written.corner_hz(tau0)
    );
    let arw = r
        .parameter_changes
        .iter()
        .find(|c| c.term == "arw_dpsh")
        .expect("the ARW refitted through the filter");
    assert_eq!(m.noise.arw_dpsh, Some(arw.fitted));
    let text = m.to_toml().unwrap();
    assert!(text.contains("[readout_filter]"), "{text}");
    // the JSON holds the kind among the params
    let v = serde_json::to_value(r).unwrap();
    let entry = v["added_terms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["term"] == "readout_filter")
        .unwrap();
    assert_eq!(entry["params"]["kind"], kind);
    assert!(entry["params"]["corner_hz"].is_f64());
    let expl = entry["explanation"].as_str().unwrap();
    assert!(
        expl.contains("-3 dB") && expl.contains("group delay") && expl.contains("anti-alias"),
        "{expl}"
    );
}

#[test]
fn a_first_order_filter_the_model_lacks_is_named_with_its_corner() {
    check_named(
        "[readout_filter]\nkind = \"first_order\"\ncorner_hz = 15.0\n",
        "first_order",
        15.0,
        12,
    );
}

#[test]
fn a_moving_average_the_model_lacks_is_named_with_its_length() {
    // L = 5 at 200 Hz: -3 dB at 18.0 Hz
    let corner = sagnac::model::filter::ReadoutFilter::moving_average(5)
        .unwrap()
        .corner_hz(1.0 / 200.0);
    check_named(
        "[readout_filter]\nkind = \"moving_average\"\nlength = 5\n",
        "moving_average",
        corner,
        21,
    );
}

/// A moving average with white angle noise after it (a readout error added
/// after the filter), against a model with neither: no filter alone fits the
/// finest levels (the greedy search alone settles on a first-order corner),
/// so the filter and Q are fitted together. On each of three seeds the
/// average is named with its length, once, and the updated model fits; Q's
/// and the ARW's intervals hold the truth on at least two of the three.
#[test]
fn a_filter_with_white_angle_noise_after_it_is_named_with_both() {
    let truth = model(
        "quantization_arcsec = 1.0\n[readout_filter]\nkind = \"moving_average\"\nlength = 3\n",
    );
    let mut covered = [0usize; 2];
    for seed in [41u64, 42, 43] {
        let rec = support::simulated_recording(&truth, seed, DUR_S);
        let d = diagnose::diagnose(&model(""), &rec, &opts(seed + 100)).unwrap();
        let r = &d.report;
        eprintln!(
            "seed {seed}: added {:#?}\n changes {:#?}",
            r.added_terms, r.parameter_changes
        );
        assert_eq!(r.verdict, Verdict::Mismatch);
        let filters = r.added_terms.iter().filter(|a| a.term == "readout_filter");
        assert_eq!(filters.count(), 1, "seed {seed}: one filter named");
        let (k, _, _, len) = named_filter(&d).unwrap();
        assert_eq!(
            (k.as_str(), len),
            ("moving_average", Some(3.0)),
            "seed {seed}"
        );
        for (i, (term, t)) in [("quantization_arcsec", 1.0), ("arw_dpsh", 0.5)]
            .iter()
            .enumerate()
        {
            let c = r.parameter_changes.iter().find(|c| c.term == *term);
            let c = c.unwrap_or_else(|| panic!("seed {seed}: {term} refitted"));
            assert!(
                (c.fitted / t - 1.0).abs() < 0.02,
                "seed {seed}: {term} {}",
                c.fitted
            );
            covered[i] += usize::from(c.ci95[0] <= *t && *t <= c.ci95[1]);
        }
        assert!(
            r.fit_after.chi2_per_dof < 1.5,
            "seed {seed}: chi2/dof after {}",
            r.fit_after.chi2_per_dof
        );
        let m = d.updated_model.expect("an updated model");
        let q = m.noise.quantization_arcsec.expect("Q written");
        assert!((q - 1.0).abs() < 0.02, "seed {seed}: written Q {q}");
    }
    assert!(
        covered.iter().all(|&c| c >= 2),
        "Q, ARW covered in {covered:?} of 3"
    );
}

#[test]
fn a_matched_rate_output_model_raises_no_alarm() {
    let m = model("[readout_filter]\nkind = \"first_order\"\ncorner_hz = 15.0\n");
    let mut alarms = Vec::new();
    for seed in 0..5u64 {
        let rec = support::simulated_recording(&m, 500 + seed, DUR_S);
        let d = diagnose::diagnose(&m, &rec, &opts(900 + seed)).unwrap();
        if d.report.verdict != Verdict::Consistent {
            alarms.push((seed, d.notes.clone()));
        }
    }
    assert!(alarms.is_empty(), "false alarms: {alarms:#?}");
}

#[test]
fn a_counts_recording_against_a_rate_model_is_refused() {
    let counts_model = GyroModel::from_toml_str(
        "[gyro]\nsample_rate_hz = 200.0\npulse_arcsec = 1.21\n[noise]\narw_dpsh = 0.01\n",
        "counts",
    )
    .unwrap();
    let mut sim = Simulator::new(&counts_model, 1, Some(60.0)).unwrap();
    let mut counts = Vec::new();
    sim.next_block(usize::MAX >> 1, &mut counts);
    let rec = Recording {
        counts,
        filled: Vec::new(),
        temp_c: None,
        sample_rate_hz: 200.0,
        pulse_arcsec: 1.21,
        output: Default::default(),
    };
    let e = diagnose::diagnose(&model(""), &rec, &opts(1)).unwrap_err();
    assert!(matches!(e, DiagnoseError::OutputMismatch { .. }), "{e}");
    assert!(e.to_string().contains("rate recording"), "{e}");
    // and a rate recording against a counter
    let rate_rec = support::simulated_recording(&model(""), 2, 60.0);
    let e = diagnose::diagnose(&counts_model, &rate_rec, &opts(1)).unwrap_err();
    assert!(matches!(e, DiagnoseError::OutputMismatch { .. }), "{e}");
}

#[test]
fn the_filter_quadrature_matches_the_exact_lag_domain_columns() {
    use sagnac::diagnose::{stats, wvar_fit::Basis};
    use sagnac::model::filter::ReadoutFilter;
    use sagnac::model::wvar::{LevelBasis, SpectralTerm};
    let (lo, hi) = stats::sym8();
    let tau0 = 1.0 / 200.0;
    let levels: Vec<u32> = (1..=14).collect();
    let basis = Basis::new(&lo, &hi, tau0, &levels);
    let white = basis.white_rate();
    let quad = basis.filtered_white_rate(None);
    let ma = ReadoutFilter::moving_average(5).unwrap();
    let exact_ma = LevelBasis::new(
        &lo,
        &hi,
        tau0,
        &levels,
        &[SpectralTerm::FilteredWhiteRate { filter: ma }],
    );
    let quad_ma = basis.filtered_white_rate(Some(ma));
    for j in 0..levels.len() {
        let e1 = quad[j] / white[j] - 1.0;
        let e2 = quad_ma[j] / exact_ma.phi[j][0] - 1.0;
        eprintln!("level {}: white {e1:.2e}, MA5 {e2:.2e}", levels[j]);
        // tolerance: 1e-4 relative (the quadrature's accuracy)
        assert!(
            e1.abs() < 1e-4 && e2.abs() < 1e-4,
            "level {}: {e1:e} {e2:e}",
            levels[j]
        );
    }
}
