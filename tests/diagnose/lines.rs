//! Spectral lines at the whole record's resolution
//! (`diagnose::line_search`): located to the Fisher bound, intervals that
//! cover, and no lines on matched recordings.

use sagnac::diagnose;
use sagnac::diagnose::line_search::SearchParams;

use crate::support;

mod shared;

use shared::{coverage, gyro, null_alarms, paper_gyro};

fn sine(amp_dph: f64, period_s: f64) -> String {
    format!("[[noise.sinusoid]]\namplitude_dph = {amp_dph}\nperiod_s = {period_s}\n")
}

/// The case: a 1 h, 1 kHz record of the gyro with a 0.03 deg/h
/// line of period 40 s (90 cycles), diagnosed against the model without it:
/// a new sinusoid of period 40 s, its 95 % interval well under 1 % wide and
/// covering the truth, the amplitude's too, and the written model carries it.
#[test]
fn forty_second_line_is_located_to_well_under_one_percent() {
    let model = gyro(1000.0, "");
    let truth = gyro(1000.0, &sine(0.03, 40.0));
    let rec = support::simulated_recording(&truth, 1, 3600.0);
    let d = diagnose::diagnose(&model, &rec, &diagnose::DiagnoseOptions::default()).unwrap();
    let r = &d.report;
    eprintln!("{}", serde_json::to_string_pretty(r).unwrap());
    assert_eq!(r.verdict, diagnose::Verdict::Mismatch);
    assert!(r.parameter_changes.is_empty(), "{:?}", r.parameter_changes);
    let sines: Vec<_> = r
        .added_terms
        .iter()
        .filter(|a| a.term == "sinusoid")
        .collect();
    assert_eq!(sines.len(), 1, "{:?}", r.added_terms);
    let (p, pci) = (sines[0].params["period_s"], sines[0].ci95["period_s"]);
    let (a, aci) = (
        sines[0].params["amplitude_dph"],
        sines[0].ci95["amplitude_dph"],
    );
    // located: within 0.2 % of 40 s, the 95 % interval under 0.5 % wide and covering 40 s
    assert!((p - 40.0).abs() < 0.08, "period {p}");
    assert!((pci[1] - pci[0]) / p < 0.005, "period interval {pci:?}");
    assert!(pci[0] <= 40.0 && 40.0 <= pci[1], "period interval {pci:?}");
    // amplitude: within 25 %, its interval covering the truth
    assert!((a - 0.03).abs() < 0.0075, "amplitude {a}");
    assert!(
        aci[0] <= 0.03 && 0.03 <= aci[1],
        "amplitude interval {aci:?}"
    );
    // the refined model carries that line and fits
    let m = d.updated_model.as_ref().expect("an updated model");
    assert_eq!(m.noise.sinusoid.len(), 1);
    assert_eq!(m.noise.sinusoid[0].period_s, p);
    assert_eq!(m.noise.sinusoid[0].amplitude_dph, a);
    assert!(
        r.fit_after.chi2_per_dof < 1.5,
        "chi2/dof after {}",
        r.fit_after.chi2_per_dof
    );
}

/// The truth lies inside the 95 % interval widened by half around its centre
/// (about +-3 sigma; as in `concealed/shared.rs`): one fixed-seed case
/// may miss a 95 % interval one time in twenty, a 3-sigma interval one time in
/// 370. The coverage of the 95 % intervals themselves is measured over seeds.
fn covers(ci: [f64; 2], v: f64) -> bool {
    let c = 0.5 * (ci[0] + ci[1]);
    let h = 0.75 * (ci[1] - ci[0]);
    c - h <= v && v <= c + h
}

/// A short-period line (0.5 s, 0.12 deg/h) under the quantization noise of
/// the issue's gyro (Q 0.61": at 2 Hz the QN density is four times the ARW's)
/// is found by the search alone, its intervals covering the truth.
#[test]
fn short_period_line_under_quantization_is_found() {
    let model = gyro(1000.0, "");
    let truth = gyro(1000.0, &sine(0.12, 0.5));
    let rec = support::simulated_recording(&truth, 3, 1200.0);
    let scan = diagnose::line_scan(&model, &rec, &SearchParams::default());
    assert_eq!(scan.lines.len(), 1, "{:?}", scan.lines);
    let f = scan.lines[0].1;
    let (p, a) = (f.period_ci95(), f.amp_ci95());
    eprintln!("{f:?}: period {p:?}, amplitude {a:?}");
    assert!(covers(p, 0.5), "period interval {p:?}");
    assert!(covers(a, 0.12), "amplitude interval {a:?}");
}

/// Matched recordings (the gyro, dithered; the paper's, whose
/// counter sawtooth has harmonic lines) show no line at the diagnosis's
/// alpha, over a few seeds.
#[test]
fn no_line_on_matched_recordings() {
    for (m, dur) in [
        (gyro(1000.0, ""), 600.0),
        (paper_gyro(1000.0, ""), 600.0),
        (paper_gyro(250.0, ""), 1200.0),
    ] {
        assert_eq!(null_alarms(&m, dur, 3, 8100, 0.001), 0);
    }
}

/// Over a handful of seeds the 95 % intervals cover about 95 % of the time
/// (`bench_diagnose lines` measures more); at least 8 of 10 here
/// (a 95 % coverage gives 8 or more with probability 0.99).
#[test]
fn intervals_cover_over_seeds() {
    let (cp, ca, det) = coverage(&gyro(1000.0, ""), 0.1, 10.0, 600.0, 10, 6100);
    eprintln!("detected {det}/10, period covered {cp}, amplitude covered {ca}");
    assert_eq!(det, 10);
    assert!(cp >= 8 && ca >= 8, "period {cp}/10, amplitude {ca}/10");
}
