//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// Repository root (the crate's manifest directory).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The third-party reference data in `../shared/data` (relative to the repository
/// root; `SAGNAC_SHARED_DATA` overrides). When it is absent, print a notice and
/// return `None` so the caller skips, except under `CI=true`, where absence fails.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("SAGNAC_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("..").join("shared").join("data"));
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!(
            "reference data not found at {} (CI=true: absence is a failure; set SAGNAC_SHARED_DATA)",
            dir.display()
        );
    }
    eprintln!(
        "NOTICE: reference data not found at {}; skipping this test (set SAGNAC_SHARED_DATA)",
        dir.display()
    );
    None
}

/// A recording of `m` simulated for `dur_s` seconds with `seed`: rate words
/// for a rate-output model, counts (with the temperature when the model has a
/// thermal section) otherwise.
pub fn simulated_recording(
    m: &sagnac::model::GyroModel,
    seed: u64,
    dur_s: f64,
) -> sagnac::diagnose::Recording {
    use sagnac::model::config::OutputKind;
    let mut sim = sagnac::model::Simulator::new(m, seed, Some(dur_s)).unwrap();
    let mut temp = Vec::new();
    if m.gyro.output == OutputKind::Rate {
        let mut rates = Vec::new();
        sim.next_block_rates(usize::MAX >> 1, &mut rates, &mut temp);
        return sagnac::diagnose::Recording::from_rates(
            &rates,
            None,
            m.gyro.sample_rate_hz,
            m.gyro.rate_lsb_dps,
        )
        .unwrap();
    }
    let mut counts = Vec::new();
    sim.next_block_with_temp(usize::MAX >> 1, &mut counts, &mut temp);
    sagnac::diagnose::Recording {
        counts,
        filled: Vec::new(),
        temp_c: (!temp.is_empty()).then_some(temp),
        sample_rate_hz: m.gyro.sample_rate_hz,
        pulse_arcsec: m.gyro.pulse_arcsec,
        output: Default::default(),
    }
}
