//! What the test of `compare.rs` and the candidate dump of
//! `examples/bench_diagnose` (which includes this file by its path) both use:
//! the paper's gyro, its simulated recording, and the one-line summary of a
//! diagnosis.

use sagnac::diagnose::{Diagnosis, Recording};
use sagnac::model::{GyroModel, Simulator};

/// The paper's gyro: pulse 1.21", dither residual 0.5", Earth rate ~10 deg/h.
pub fn paper(extra: &str) -> GyroModel {
    let q = (1.21f64.powi(2) / 12.0 + 0.25).sqrt();
    let text = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 10.0\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.002\nbias_instability_dph = 0.003\n{extra}"
    );
    GyroModel::from_toml_str(&text, "paper").unwrap()
}

pub fn simulate(m: &GyroModel, seed: u64, dur_s: f64) -> Recording {
    let mut sim = Simulator::new(m, seed, Some(dur_s)).unwrap();
    let mut counts = Vec::new();
    sim.next_block(usize::MAX >> 1, &mut counts);
    Recording {
        counts,
        filled: Vec::new(),
        temp_c: None,
        sample_rate_hz: m.gyro.sample_rate_hz,
        pulse_arcsec: m.gyro.pulse_arcsec,
        output: Default::default(),
    }
}

pub fn summary(d: &Diagnosis) -> String {
    let c = d.model_comparison.as_ref();
    format!(
        "max|z| {:.2}/{:.2}, LR {:.1} ({}) / crit {:.1}, null max {:?}, added {:?}, changes {:?}",
        d.max_abs_z,
        d.z_crit,
        c.map_or(f64::NAN, |c| c.max_lr),
        c.map_or("-", |c| c.best.as_str()),
        c.map_or(f64::NAN, |c| c.lr_crit),
        c.map(|c| c
            .null_max
            .iter()
            .map(|v| (v * 10.0).round() / 10.0)
            .collect::<Vec<_>>()),
        d.report
            .added_terms
            .iter()
            .map(|a| (&a.term, &a.params, &a.ci95))
            .collect::<Vec<_>>(),
        d.report
            .parameter_changes
            .iter()
            .map(|c| (&c.term, c.fitted, c.ci95))
            .collect::<Vec<_>>()
    )
}
