//! Issue 14: spectral lines at the whole record's resolution
//! (`model::diagnose::lines`): located to the Fisher bound, intervals that
//! cover, and no lines on matched recordings.

use sagnac::model::diagnose::lines::SearchParams;
use sagnac::model::diagnose::{self, Recording};
use sagnac::model::{GyroModel, Simulator};

/// The gyro: pulse 1.21", dither residual 0.5" (Q = sqrt(d^2/12 + 0.5^2)),
/// Earth-rate input, ARW 0.002 deg/sqrt(h), BI 0.003 deg/h, plus `extra`.
fn gyro(fs: f64, extra: &str) -> GyroModel {
    let q = (1.21f64 * 1.21 / 12.0 + 0.25).sqrt();
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_weight_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.002\nbias_instability_dph = 0.003\n{extra}"
    );
    GyroModel::from_toml_str(&text, "lines").unwrap()
}

fn sine(amp_dph: f64, period_s: f64) -> String {
    format!("[[noise.sinusoid]]\namplitude_dph = {amp_dph}\nperiod_s = {period_s}\n")
}

fn simulate(m: &GyroModel, seed: u64, dur_s: f64) -> Recording {
    let mut sim = Simulator::new(m, seed, Some(dur_s)).unwrap();
    let mut counts = Vec::new();
    sim.next_block(usize::MAX >> 1, &mut counts);
    Recording {
        counts,
        temp_c: None,
        sample_rate_hz: m.gyro.sample_rate_hz,
        pulse_arcsec: m.gyro.pulse_weight_arcsec,
    }
}

#[test]
#[ignore]
fn explore() {
    let model = gyro(1000.0, "");
    let truth = gyro(1000.0, &sine(0.03, 40.0));
    let t = std::time::Instant::now();
    let rec = simulate(&truth, 1, 3600.0);
    eprintln!("sim {:.2}s", t.elapsed().as_secs_f64());
    let t = std::time::Instant::now();
    let scan = diagnose::line_scan(&model, &rec, &SearchParams::default());
    eprintln!("scan {:.2}s, masked {}", t.elapsed().as_secs_f64(), scan.masked.len());
    for (d, f) in &scan.lines {
        eprintln!("{d:?}\n  {f:?} period {} {:?} amp {:?}", 1.0 / f.f_hz, f.period_ci95(), f.amp_ci95());
    }
}
