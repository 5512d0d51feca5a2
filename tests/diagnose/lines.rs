//! Spectral lines at the whole record's resolution
//! (`diagnose::line_search`): located to the Fisher bound, intervals that
//! cover, and no lines on matched recordings.

use sagnac::diagnose;
use sagnac::diagnose::line_search::SearchParams;
use sagnac::model::GyroModel;

use crate::support;

/// The gyro: pulse 1.21", dither residual 0.5" (Q = sqrt(d^2/12 + 0.5^2)),
/// Earth-rate input, ARW 0.002 deg/sqrt(h), BI 0.003 deg/h, plus `extra`.
fn gyro(fs: f64, extra: &str) -> GyroModel {
    let q = (1.21f64 * 1.21 / 12.0 + 0.25).sqrt();
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.002\nbias_instability_dph = 0.003\n{extra}"
    );
    GyroModel::from_toml_str(&text, "lines").unwrap()
}

fn sine(amp_dph: f64, period_s: f64) -> String {
    format!("[[noise.sinusoid]]\namplitude_dph = {amp_dph}\nperiod_s = {period_s}\n")
}

/// The paper's gyro as in `config/paper_gyro.toml` (Q 0.35: the counter's
/// sawtooth is not white), ARW 0.001, BI 0.002.
fn paper_gyro(fs: f64, extra: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\nbias_instability_dph = 0.002\n{extra}"
    );
    GyroModel::from_toml_str(&text, "lines").unwrap()
}

/// Coverage of the 95 % period and amplitude intervals over `seeds` records:
/// (period covered, amplitude covered, detected).
fn coverage(
    model: &GyroModel,
    amp: f64,
    period: f64,
    dur: f64,
    seeds: u64,
    base: u64,
) -> (usize, usize, usize) {
    let mut truth = model.clone();
    truth
        .noise
        .sinusoid
        .push(sagnac::model::config::SinusoidParams {
            amplitude_dph: amp,
            period_s: period,
        });
    let (mut cp, mut ca, mut det) = (0, 0, 0);
    for s in 0..seeds {
        let rec = support::simulated_recording(&truth, base + s, dur);
        let scan = diagnose::line_scan(model, &rec, &SearchParams::default());
        let Some((_, f)) = scan
            .lines
            .iter()
            .find(|(_, f)| (1.0 / f.f_hz - period).abs() < 0.05 * period)
        else {
            continue;
        };
        det += 1;
        let p = f.period_ci95();
        let a = f.amp_ci95();
        cp += (p[0] <= period && period <= p[1]) as usize;
        ca += (a[0] <= amp && amp <= a[1]) as usize;
    }
    (cp, ca, det)
}

/// Records with any line, over `seeds` matched simulations, at family-wise `alpha`.
fn null_alarms(model: &GyroModel, dur: f64, seeds: u64, base: u64, alpha: f64) -> usize {
    let params = SearchParams {
        alpha,
        ..SearchParams::default()
    };
    (0..seeds)
        .filter(|s| {
            let rec = support::simulated_recording(model, base + s, dur);
            let scan = diagnose::line_scan(model, &rec, &params);
            if let Some((d, _)) = scan.lines.first() {
                eprintln!(
                    "seed {}: line at {} Hz, ratio {:.1}, p {:.2e}",
                    base + s,
                    d.f_hz,
                    d.ratio,
                    d.p
                );
            }
            !scan.lines.is_empty()
        })
        .count()
}

/// The numbers of the report: coverage and false alarms over many seeds.
#[test]
#[ignore]
fn bench_coverage_and_false_alarms() {
    let seeds: u64 = std::env::var("SAGNAC_BENCH_SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(40);
    for (name, m, amp, per, dur) in [
        ("issue gyro, 10 s line", gyro(1000.0, ""), 0.08, 10.0, 600.0),
        (
            "issue gyro, 40 s line",
            gyro(1000.0, ""),
            0.06,
            40.0,
            1200.0,
        ),
        (
            "issue gyro, 0.5 s line under QN",
            gyro(1000.0, ""),
            0.12,
            0.5,
            1200.0,
        ),
        (
            "paper gyro, 0.8 s line",
            paper_gyro(250.0, ""),
            0.05,
            0.8,
            1200.0,
        ),
    ] {
        let (cp, ca, det) = coverage(&m, amp, per, dur, seeds, 5000);
        println!(
            "coverage {name} (A {amp}, T {dur} s): detected {det}/{seeds}, period {cp}/{det}, amplitude {ca}/{det}"
        );
    }
    for (name, m, dur) in [
        ("issue gyro 1 kHz", gyro(1000.0, ""), 600.0),
        ("paper gyro 1 kHz", paper_gyro(1000.0, ""), 600.0),
        ("paper gyro 250 Hz", paper_gyro(250.0, ""), 1200.0),
    ] {
        let a = null_alarms(&m, dur, seeds, 7000, 0.05);
        println!("null {name}, {dur} s: records with a line at alpha 5 %: {a}/{seeds}");
    }
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
/// (about +-3 sigma; as in `tests/diagnose/concealed.rs`): one fixed-seed case
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
/// (`bench_coverage_and_false_alarms` measures more); at least 8 of 10 here
/// (a 95 % coverage gives 8 or more with probability 0.99).
#[test]
fn intervals_cover_over_seeds() {
    let (cp, ca, det) = coverage(&gyro(1000.0, ""), 0.1, 10.0, 600.0, 10, 6100);
    eprintln!("detected {det}/10, period covered {cp}, amplitude covered {ca}");
    assert_eq!(det, 10);
    assert!(cp >= 8 && ca >= 8, "period {cp}/10, amplitude {ca}/10");
}
