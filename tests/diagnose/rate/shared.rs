//! What the tests of `rate.rs` and the corner-coverage table of
//! `examples/bench_diagnose` (which includes this file by its path) both use:
//! the diagnosis options of a seed and the `readout_filter` entry a diagnosis
//! names.

use sagnac::diagnose::{self, DiagnoseOptions};

/// The diagnosis options with `seed`.
pub fn opts(seed: u64) -> DiagnoseOptions {
    DiagnoseOptions {
        seed,
        ..DiagnoseOptions::default()
    }
}

/// The `readout_filter` entry of a diagnosis: (kind, corner, its ci95).
pub fn named_filter(d: &diagnose::Diagnosis) -> Option<(String, f64, [f64; 2], Option<f64>)> {
    let a = d
        .report
        .added_terms
        .iter()
        .find(|a| a.term == "readout_filter")?;
    Some((
        a.kind.clone()?,
        a.params["corner_hz"],
        a.ci95["corner_hz"],
        a.params.get("length").copied(),
    ))
}
