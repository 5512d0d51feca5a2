//! Recordings simulated from a model, for the diagnosis tests (and for
//! `examples/bench_diagnose`, which includes this file as its `support`).

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
