//! The gyros of the line tests and the counts over seeds that the tests of
//! `lines.rs` assert on a few seeds and `examples/bench_diagnose` (which
//! includes this file by its path) reports over many: the coverage of the
//! intervals and the records with a false line.

use sagnac::diagnose;
use sagnac::diagnose::line_search::SearchParams;
use sagnac::model::GyroModel;

use crate::support;

/// The gyro: pulse 1.21", dither residual 0.5" (Q = sqrt(d^2/12 + 0.5^2)),
/// Earth-rate input, ARW 0.002 deg/sqrt(h), BI 0.003 deg/h, plus `extra`.
pub fn gyro(fs: f64, extra: &str) -> GyroModel {
    let q = (1.21f64 * 1.21 / 12.0 + 0.25).sqrt();
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.002\nbias_instability_dph = 0.003\n{extra}"
    );
    GyroModel::from_toml_str(&text, "lines").unwrap()
}

/// The paper's gyro as in `config/paper_gyro.toml` (Q 0.35: the counter's
/// sawtooth is not white), ARW 0.001, BI 0.002.
pub fn paper_gyro(fs: f64, extra: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\nbias_instability_dph = 0.002\n{extra}"
    );
    GyroModel::from_toml_str(&text, "lines").unwrap()
}

/// Coverage of the 95 % period and amplitude intervals over `seeds` records:
/// (period covered, amplitude covered, detected).
pub fn coverage(
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
pub fn null_alarms(model: &GyroModel, dur: f64, seeds: u64, base: u64, alpha: f64) -> usize {
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
