//! Null honesty: on recordings simulated from the model itself the
//! diagnosis must say "consistent" (nothing added, nothing changed) in all but
//! a few cases. Measured over 40 seeds spread over eight matched models that
//! differ in sample rate (100 Hz .. 1 kHz), duration (60 .. 300 s), quantization,
//! and catalog content (plain paper gyro, bias instability, Gauss-Markov,
//! sinusoid, random walk, telegraph): the false-alarm rate must stay below 5 %
//! (at most one alarm in 40). The design alpha is about 2 % (1 % broadband,
//! 0.1 % lines, 2 x 0.25 % slopes, the kurtosis test).

use std::time::Instant;

use sagnac::diagnose::{self, DiagnoseOptions, Verdict};
use sagnac::model::GyroModel;

use crate::support;

fn model(fs: f64, input_dph: f64, q: f64, n: f64, extra: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\npulse_arcsec = 1.21\ninput_rate_dph = {input_dph}\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\n{extra}"
    );
    GyroModel::from_toml_str(&text, "null").unwrap()
}

/// (model, duration s), one per family of seeds.
fn matched() -> Vec<(GyroModel, f64)> {
    vec![
        (model(1000.0, 12.3, 0.35, 0.001, ""), 60.0),
        (
            model(500.0, 12.3, 0.35, 0.001, "bias_instability_dph = 0.002\n"),
            120.0,
        ),
        (
            model(
                200.0,
                -4.0,
                0.5,
                0.0015,
                "[[noise.gauss_markov]]\nsigma_dph = 0.05\ntau_c_s = 5.0\n",
            ),
            300.0,
        ),
        (
            model(
                250.0,
                12.3,
                0.35,
                0.001,
                "[[noise.sinusoid]]\namplitude_dph = 0.03\nperiod_s = 2.0\n",
            ),
            200.0,
        ),
        (model(100.0, 30.0, 0.7, 0.002, "rrw_dphsh = 0.01\n"), 300.0),
        (
            model(
                200.0,
                12.3,
                0.7,
                0.001,
                "[[noise.random_telegraph]]\namplitude_dph = 0.05\nmean_dwell_s = 5.0\n",
            ),
            300.0,
        ),
        (model(2000.0, 15.0, 0.6, 0.00125, ""), 30.0),
        (
            model(
                400.0,
                12.3,
                0.35,
                0.001,
                "bias_instability_dph = 0.003\n[[noise.gauss_markov]]\nsigma_dph = 0.02\ntau_c_s = 0.3\n",
            ),
            150.0,
        ),
    ]
}

/// Diagnose `seeds` matched recordings, cycling over `models`: recording `s`
/// simulated with seed `rec_seed + s`, its reference runs from
/// `ref_seed + 31 s` (other seeds than the recording). Returns the seeds that
/// raised an alarm (a mismatch verdict, an added term or a parameter change)
/// and every run's max|z| / threshold.
fn null_runs(
    models: &[(GyroModel, f64)],
    seeds: u64,
    rec_seed: u64,
    ref_seed: u64,
) -> (Vec<u64>, Vec<f64>) {
    let (mut alarms, mut max_z) = (Vec::new(), Vec::new());
    for s in 0..seeds {
        let (m, dur) = &models[(s as usize) % models.len()];
        let rec = support::simulated_recording(m, rec_seed + s, *dur);
        let opts = DiagnoseOptions {
            seed: ref_seed + 31 * s,
            ..DiagnoseOptions::default()
        };
        let d = diagnose::diagnose(m, &rec, &opts).unwrap();
        let r = &d.report;
        max_z.push(d.max_abs_z / d.z_crit);
        // a narrowband excess needs twice the surrounding power at a
        // Bonferroni z: a matched simulation has none; so no resonance is
        // fitted either, and no note says one was tried
        for prefix in ["Narrowband excess", "A resonance fitted"] {
            let noted: Vec<&String> = d.notes.iter().filter(|n| n.starts_with(prefix)).collect();
            assert!(noted.is_empty(), "seed {s}: {noted:?}");
        }
        if r.verdict == Verdict::Mismatch
            || !r.added_terms.is_empty()
            || !r.parameter_changes.is_empty()
        {
            eprintln!(
                "seed {s} (model {}): alarm, max|z| {:.2} / crit {:.2}, lines {}, ramp z {:.2}, added {:?}, changes {:?}",
                s as usize % models.len(),
                d.max_abs_z,
                d.z_crit,
                d.lines.len(),
                d.ramp_z,
                r.added_terms.iter().map(|a| &a.term).collect::<Vec<_>>(),
                r.parameter_changes
                    .iter()
                    .map(|c| &c.term)
                    .collect::<Vec<_>>()
            );
            alarms.push(s);
        }
    }
    (alarms, max_z)
}

#[test]
fn false_alarm_rate_on_matched_simulations_is_below_5_percent_over_40_seeds() {
    let seeds = 40u64;
    let t = Instant::now();
    let (alarms, mut max_z) = null_runs(&matched(), seeds, 9000, 77_000);
    let rate = alarms.len() as f64 / seeds as f64;
    max_z.sort_by(f64::total_cmp);
    eprintln!(
        "false alarms: {}/{seeds} = {:.1} % (seeds {alarms:?}); median max|z|/crit {:.2}; {:.1} s",
        alarms.len(),
        100.0 * rate,
        max_z[max_z.len() / 2],
        t.elapsed().as_secs_f64()
    );
    assert!(
        rate < 0.05,
        "false-alarm rate {rate} on matched recordings (alarms at seeds {alarms:?})"
    );
    // the broadband statistic is not degenerate: under the null its maximum
    // sits well inside the threshold but is not zero
    let med = max_z[max_z.len() / 2];
    assert!((0.2..1.0).contains(&med), "median max|z| / threshold {med}");
}

/// A dithered pulse counter's own line, at the mean pulse rate (12.3 deg/h
/// over 1.21" is 10.2 Hz), wanders with the rate: its core is masked, its
/// skirts stand a few per cent above the model's spectrum in their band of
/// 1/8 octave over an hour. That is not narrowband noise: a clean hour of
/// the counter (1 kHz, Q 0.61", ARW 0.002 deg/sqrt(h), BI 0.003 deg/h)
/// diagnosed against its own model gets no resonance tried and no note.
#[test]
fn a_counters_own_line_is_not_taken_for_a_resonance() {
    let m = model(1000.0, 12.3, 0.61, 0.002, "bias_instability_dph = 0.003\n");
    for s in [2u64, 3] {
        let rec = support::simulated_recording(&m, 5100 + s, 3600.0);
        let opts = DiagnoseOptions {
            seed: 6100 + s,
            ..DiagnoseOptions::default()
        };
        let d = diagnose::diagnose(&m, &rec, &opts).unwrap();
        let tried: Vec<&String> = d
            .notes
            .iter()
            .filter(|n| n.starts_with("A resonance") || n.starts_with("Narrowband excess"))
            .collect();
        assert!(tried.is_empty(), "seed {s}: {tried:?}");
        assert_eq!(
            d.report.verdict,
            Verdict::Consistent,
            "seed {s}: {:?}",
            d.notes
        );
    }
}

/// A recording whose ARW is far above the model's (here 50x) is a parameter
/// change of `arw_dpsh`, not also a rate ramp: the slope test must judge the
/// recorded slope against the noise the recording really has (the model's
/// runs alone would make any random slope look significant). Over six seeds no
/// rate ramp may be added, and the ARW must come out within 3 % of the truth
/// with a 95 % interval that covers it (at most one miss). The first, linear
/// fit alone gave 0.071..0.087 with a 1 % interval: the large change also
/// turns the counter's sawtooth quantization white, which only refitting
/// about the updated model's own runs sees. (Measured over 30 seeds: mean
/// 0.9999 x truth, scatter 0.70 %, claimed 0.68 %, 2 misses.)
#[test]
fn a_large_arw_excess_is_not_also_called_a_rate_ramp() {
    let m = model(200.0, 12.3, 0.35, 0.001, "");
    let truth = model(200.0, 12.3, 0.35, 0.05, "");
    let mut ramps = Vec::new();
    let mut missed = Vec::new();
    for s in 0..6u64 {
        let rec = support::simulated_recording(&truth, 4400 + s, 600.0);
        let d = diagnose::diagnose(&m, &rec, &DiagnoseOptions::default()).unwrap();
        let r = &d.report;
        eprintln!(
            "seed {s}: chi2 {:.2} -> {:.2}, ramp z {:.2}, added {:?}, changes {:?}",
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof,
            d.ramp_z,
            r.added_terms.iter().map(|a| &a.term).collect::<Vec<_>>(),
            r.parameter_changes
                .iter()
                .map(|c| (&c.term, c.fitted, c.ci95))
                .collect::<Vec<_>>()
        );
        assert_eq!(r.verdict, Verdict::Mismatch, "seed {s}");
        let arw = r
            .parameter_changes
            .iter()
            .find(|c| c.term == "arw_dpsh")
            .unwrap_or_else(|| panic!("seed {s}: no arw_dpsh change"));
        if !(arw.ci95[0] <= 0.05 && 0.05 <= arw.ci95[1]) {
            missed.push((s, arw.fitted, arw.ci95));
        }
        // one change per parameter, from the model's value to the final fit
        assert_eq!(arw.model, 0.001, "seed {s}");
        assert_eq!(
            r.parameter_changes
                .iter()
                .filter(|c| c.term == "arw_dpsh")
                .count(),
            1,
            "seed {s}"
        );
        assert!(
            (arw.fitted / 0.05 - 1.0).abs() < 0.03,
            "seed {s}: arw {} ci {:?}",
            arw.fitted,
            arw.ci95
        );
        if r.added_terms.iter().any(|a| a.term == "rate_ramp_dphh")
            || r.parameter_changes
                .iter()
                .any(|c| c.term == "rate_ramp_dphh")
        {
            ramps.push(s);
        }
    }
    assert!(ramps.is_empty(), "spurious rate ramp at seeds {ramps:?}");
    // 95 % intervals: at most one miss in six
    assert!(missed.len() <= 1, "ARW intervals missing 0.05: {missed:?}");
}

/// A bias instability near the detection limit may be named as another
/// low-frequency shape (here, at seed 3, a short Gauss-Markov term); the slope
/// test must still judge the record's slope against the low-frequency noise the
/// record has (the spread under its own estimator's fit), not against the
/// small spread of the term it was named as. Before, this record also got a
/// spurious rate ramp, -0.29 deg/h/h at z -8.
#[test]
fn a_misnamed_bias_instability_does_not_bring_a_spurious_ramp() {
    let m = model(200.0, 12.3, 0.35, 0.001, "");
    let truth = model(200.0, 12.3, 0.35, 0.001, "bias_instability_dph = 0.02\n");
    let rec = support::simulated_recording(&truth, 3, 1200.0);
    let d = diagnose::diagnose(&m, &rec, &DiagnoseOptions::default()).unwrap();
    let r = &d.report;
    eprintln!(
        "ramp z {:.2}, added {:?}",
        d.ramp_z,
        r.added_terms.iter().map(|a| &a.term).collect::<Vec<_>>()
    );
    assert_eq!(r.verdict, Verdict::Mismatch);
    assert!(
        !r.added_terms.iter().any(|a| a.term == "rate_ramp_dphh"),
        "spurious ramp (z {:.2})",
        d.ramp_z
    );
    assert!(d.ramp_z.abs() < 3.0, "ramp z {:.2}", d.ramp_z);
}

/// A rate-output model (FOG or MEMS rate word): `[gyro] output = "rate"`.
fn rate_model(fs: f64, rate_lsb_dps: f64, n: f64, extra: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\noutput = \"rate\"\nrate_lsb_dps = {rate_lsb_dps}\ninput_rate_dph = 10.0\n\
         [noise]\narw_dpsh = {n}\n{extra}"
    );
    GyroModel::from_toml_str(&text, "rate null").unwrap()
}

/// (model, duration s): rate-output gyros from a MEMS datasheet to a FOG,
/// 100 Hz .. 1 kHz, with and without readout filters of both kinds.
fn matched_rate() -> Vec<(GyroModel, f64)> {
    vec![
        // the ADIS16405 datasheet model (docs/diagnose.md's real-data table)
        (
            rate_model(100.0, 0.05, 3.0, "bias_instability_dph = 25.0\n"),
            300.0,
        ),
        // a MEMS gyro behind an anti-alias RC stage
        (
            rate_model(
                200.0,
                0.01,
                0.5,
                "bias_instability_dph = 5.0\n[readout_filter]\nkind = \"first_order\"\ncorner_hz = 30.0\n",
            ),
            300.0,
        ),
        // a FOG rate word behind an averaging filter, with a Gauss-Markov bias
        (
            rate_model(
                1000.0,
                0.0005,
                0.02,
                "[[noise.gauss_markov]]\nsigma_dph = 0.5\ntau_c_s = 2.0\n[readout_filter]\nkind = \"moving_average\"\nlength = 4\n",
            ),
            60.0,
        ),
        // a FOG with a coarse word, no filter
        (
            rate_model(500.0, 0.002, 0.05, "bias_instability_dph = 0.3\n"),
            120.0,
        ),
        // a MEMS gyro with a rate random walk behind a first-order filter near Nyquist
        (
            rate_model(
                400.0,
                0.02,
                1.0,
                "rrw_dphsh = 20.0\n[readout_filter]\nkind = \"first_order\"\ncorner_hz = 150.0\n",
            ),
            200.0,
        ),
    ]
}

/// Null honesty on rate-output gyros: 40 matched recordings over five rate
/// models (false alarms at most 5 % over at least 40 matched seeds):
/// at most two. Measured: 2/40, at that bound (seed 34, a quantization change
/// on the 400 Hz gyro behind its 150 Hz filter; seed 38, one broadband point
/// at 4.25 against the threshold 4.16), so the rate-output false-alarm rate is
/// not shown to be below the design alpha of about 2 %.
#[test]
fn false_alarm_rate_on_matched_rate_output_simulations_is_below_5_percent_over_40_seeds() {
    let seeds = 40u64;
    let t = Instant::now();
    let (alarms, _) = null_runs(&matched_rate(), seeds, 19_000, 87_000);
    eprintln!(
        "rate-output false alarms: {}/{seeds} (seeds {alarms:?}); {:.1} s",
        alarms.len(),
        t.elapsed().as_secs_f64()
    );
    assert!(
        alarms.len() <= 2,
        "false alarms on matched rate-output recordings at seeds {alarms:?}"
    );
}
