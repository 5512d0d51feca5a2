//! The estimator's 95 % intervals are calibrated. Over 40 seeded
//! simulations of the paper's gyro (physical counter readout, pulse weight
//! 1.21", Q 0.35", ARW, flicker bias instability) the intervals must cover the
//! truth at least 85 % of the time, and the point estimates must be accurate.

use sagnac::model::config::GyroModel;
use sagnac::model::estimate::Coefficient;
use sagnac::model::sim::Simulator;
use sagnac::pipeline::{Analysis, Pipeline, PipelineConfig, PipelineOutput};

fn run(model: &str, seed: u64, duration_s: f64) -> Analysis {
    let m = GyroModel::from_toml_str(model, "test model").unwrap();
    let mut sim = Simulator::new(&m, seed, Some(duration_s)).unwrap();
    let mut p = Pipeline::new(&PipelineConfig::counts(
        m.gyro.sample_rate_hz,
        m.gyro.pulse_arcsec,
    ))
    .unwrap();
    let mut out = PipelineOutput::default();
    let mut c = Vec::new();
    loop {
        c.clear();
        if sim.next_block(1 << 16, &mut c) == 0 {
            break;
        }
        out.clear();
        p.push_counts(&c, &mut out);
    }
    out.clear();
    p.finish(&mut out);
    p.analysis()
}

fn covers(c: &Coefficient, truth: f64) -> bool {
    match (c.ci95, c.upper95) {
        (Some([lo, hi]), _) => lo <= truth && truth <= hi,
        (None, Some(u)) => truth <= u,
        _ => false,
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

#[test]
fn intervals_cover_the_truth_over_40_seeds() {
    let (q, n, b) = (0.35, 0.0015, 0.0025);
    let model = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\nbias_instability_dph = {b}\n"
    );
    let seeds = 40;
    let (mut cq, mut cn, mut cb) = (0, 0, 0);
    let (mut eq, mut en) = (Vec::new(), Vec::new());
    for seed in 0..seeds {
        let a = run(&model, 1000 + seed, 1200.0);
        let e = &a.estimates;
        cq += covers(&e.quantization_arcsec, q) as u32;
        cn += covers(&e.arw_dpsh, n) as u32;
        cb += covers(&e.bias_instability_dph, b) as u32;
        eq.push((e.quantization_arcsec.value.unwrap_or(0.0) / q - 1.0).abs());
        en.push((e.arw_dpsh.value.unwrap_or(0.0) / n - 1.0).abs());
    }
    let (mq, mn) = (median(eq), median(en));
    eprintln!(
        "coverage Q {cq}/{seeds}, N {cn}/{seeds}, B {cb}/{seeds}; median |err| Q {mq:.4}, N {mn:.4}"
    );
    for (name, c) in [("Q", cq), ("N", cn), ("B", cb)] {
        assert!(
            c as f64 >= 0.85 * seeds as f64,
            "{name}: coverage {c}/{seeds} below 85 %"
        );
    }
    // accuracy on 20-minute runs (the 1-hour figures are in scripts/bench-estimate)
    assert!(mq < 0.01, "median |error| of Q {mq}");
    assert!(mn < 0.05, "median |error| of N {mn}");
}

#[test]
fn white_qn_from_a_dithered_counter_is_estimated_too() {
    // a dither residual of about d/2 randomises the counter phase: QN is white
    let (q, n) = (0.5, 0.002);
    let model = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\n"
    );
    let a = run(&model, 7, 1800.0);
    let e = &a.estimates;
    let qe = e.quantization_arcsec.value.unwrap();
    let ne = e.arw_dpsh.value.unwrap();
    assert!((qe / q - 1.0).abs() < 0.01, "Q {qe}");
    assert!((ne / n - 1.0).abs() < 0.08, "N {ne}");
    assert!(
        covers(&e.quantization_arcsec, q) && covers(&e.arw_dpsh, n),
        "{e:?}"
    );
}

#[test]
fn absent_terms_are_not_reported() {
    // no flicker, no RRW, no ramp in the truth: each must come back as an upper bound
    let model = "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
                 [noise]\nquantization_arcsec = 0.4\narw_dpsh = 0.0015\n";
    let a = run(model, 11, 1200.0);
    let e = &a.estimates;
    assert!(
        e.rrw_dphsh.value.is_none() && e.rrw_dphsh.upper95.is_some(),
        "{:?}",
        e.rrw_dphsh
    );
    assert!(
        e.rate_ramp_dphh.value.is_none() && e.rate_ramp_dphh.upper95.is_some(),
        "{:?}",
        e.rate_ramp_dphh
    );
}

#[test]
fn a_rate_ramp_is_found_with_its_sign() {
    let model = "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
                 [noise]\nquantization_arcsec = 0.4\narw_dpsh = 0.0015\nrate_ramp_dphh = -0.5\n";
    let a = run(model, 3, 1800.0);
    let r = a.estimates.rate_ramp_dphh;
    let [lo, hi] = r.ci95.expect("ramp detected");
    assert!(lo <= -0.5 && -0.5 <= hi, "{r:?}");
}

/// A moderate ramp (0.02 deg/h/h over 1 h at 200 Hz: invisible on the wavelet
/// levels, but R^2 tau^2 / 2 dominates the longest Allan points) must be called
/// a ramp, not rate random walk. Without a ramp column in the Allan fit the
/// estimator put that power into K and then judged the slope against the
/// inflated K: over seeds 100..109 it found the ramp 2 times and a false K 8
/// times; with the column, 7 and 2.
#[test]
fn a_moderate_ramp_is_a_ramp_not_rate_random_walk() {
    let model = "[gyro]\nsample_rate_hz = 200.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
                 [noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\nrate_ramp_dphh = 0.02\n";
    let (mut ramps, mut covered, mut false_k) = (0, 0, 0);
    let seeds = 100..108u64;
    for seed in seeds.clone() {
        let e = run(model, seed, 3600.0).estimates;
        if let Some([lo, hi]) = e.rate_ramp_dphh.ci95 {
            ramps += 1;
            covered += usize::from(lo <= 0.02 && 0.02 <= hi);
        }
        false_k += usize::from(e.rrw_dphsh.value.is_some());
        eprintln!(
            "seed {seed}: ramp {:?} K {:?}",
            e.rate_ramp_dphh, e.rrw_dphsh
        );
    }
    let n = seeds.count();
    assert!(ramps >= 5, "ramp found in {ramps}/{n}");
    assert!(
        covered + 1 >= ramps,
        "ramp interval covered 0.02 in {covered}/{ramps}"
    );
    assert!(false_k <= 2, "false K in {false_k}/{n}");
}

#[test]
fn qn_interval_covers_a_slow_dithered_counter() {
    // No input rate, a fine pulse and a dither residual: the readout error's
    // variance depends on where the slowly wandering angle sits within a pulse,
    // so the QN energy is not stationary and a chi-square interval alone is
    // too narrow (it covered 7 of 10 such 30-minute runs); the batch-means
    // variance must make up for it.
    let q = 0.3;
    let model = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 0.5\ninput_rate_dph = 0.0\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = 0.0005\nrrw_dphsh = 0.002\n"
    );
    let seeds = 30;
    let mut cq = 0;
    let (mut err, mut z2) = (Vec::new(), 0.0);
    for seed in 0..seeds {
        let a = run(&model, 500 + seed, 1800.0);
        let c = &a.estimates.quantization_arcsec;
        cq += covers(c, q) as u32;
        let v = c.value.unwrap_or(0.0);
        err.push((v / q - 1.0).abs());
        // the error in units of the interval's standard deviation
        let [lo, hi] = c.ci95.expect("QN is found");
        z2 += ((v - q) / ((hi - lo) / (2.0 * 1.96))).powi(2);
    }
    let rms_z = (z2 / seeds as f64).sqrt();
    println!(
        "slow dithered counter: QN coverage {cq}/{seeds}, rms z {rms_z:.2}, median |err| {:.5}",
        median(err.clone())
    );
    assert!(cq as f64 >= 0.85 * seeds as f64, "QN coverage {cq}/{seeds}");
    // calibrated intervals give rms z near 1 (the chi-square interval alone
    // gave 1.36 here)
    assert!(rms_z < 1.3, "QN interval too narrow: rms z {rms_z:.2}");
    assert!(median(err) < 0.005);
}

#[test]
fn a_record_shorter_than_the_qn_band_gives_honest_bounds() {
    // 10 s of the paper's gyro: every wavelet level is quantization noise, so
    // nothing separates ARW, flicker or RRW from it. The answer is upper
    // bounds that hold (they used to collapse to ~1e-122), and QN itself.
    let (q, n, b) = (0.35, 0.001, 0.002);
    let model = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\nbias_instability_dph = {b}\n"
    );
    for seed in 0..5 {
        let e = run(&model, 70 + seed, 10.0).estimates;
        assert!(
            covers(&e.quantization_arcsec, q),
            "{:?}",
            e.quantization_arcsec
        );
        for (name, c, truth) in [("N", &e.arw_dpsh, n), ("B", &e.bias_instability_dph, b)] {
            assert!(c.value.is_none(), "{name} claimed from 10 s: {c:?}");
            let u = c.upper95.expect("an upper bound");
            // a real bound: above the truth, but within a few decades of it
            assert!(u >= truth && u < 1e3 * truth, "{name} upper bound {u}");
        }
    }
}

#[test]
fn two_minute_records_keep_their_intervals_calibrated() {
    // The daemon's first minutes: QN dominates the Allan points there, which
    // once read as a spurious bias instability (covered 2 of 20).
    let (q, n, b) = (0.35, 0.001, 0.002);
    let model = format!(
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\nbias_instability_dph = {b}\n"
    );
    let seeds = 20;
    let (mut cq, mut cn, mut cb) = (0, 0, 0);
    for seed in 0..seeds {
        let e = run(&model, 300 + seed, 120.0).estimates;
        cq += covers(&e.quantization_arcsec, q) as u32;
        cn += covers(&e.arw_dpsh, n) as u32;
        cb += covers(&e.bias_instability_dph, b) as u32;
    }
    println!("120 s records: coverage Q {cq}/{seeds}, N {cn}/{seeds}, B {cb}/{seeds}");
    for (name, c) in [("Q", cq), ("N", cn), ("B", cb)] {
        assert!(
            c as f64 >= 0.85 * seeds as f64,
            "{name} coverage {c}/{seeds}"
        );
    }
}

/// A counter whose bias wanders as a Gauss-Markov process (27 s) beside a
/// random walk: the deep angle-domain levels hold more of it than the
/// fitted low-frequency terms say, and were read as quantization (seed 1:
/// Q 0.26 % high, its +-0.08 % interval off the truth). The sum of the
/// levels ends where a level past the counter's lines holds far more than
/// white quantization noise continued.
#[test]
fn a_wandering_bias_the_fit_misses_is_not_read_as_quantization() {
    let model = "[gyro]\nsample_rate_hz = 2000\ninput_rate_dph = 10.404\npulse_arcsec = 0.6272\n\
                 [noise]\nquantization_arcsec = 0.22691\narw_dpsh = 0.000501\n\
                 bias_instability_dph = 0.01571\nrrw_dphsh = 0.03055\n\
                 [[noise.gauss_markov]]\nsigma_dph = 0.01669\ntau_c_s = 27.4\n";
    for seed in 1..=4 {
        let q = run(model, seed, 1800.0).estimates.quantization_arcsec;
        assert!(covers(&q, 0.22691), "seed {seed}: {q:?}");
        assert!(
            (q.value.unwrap() / 0.22691 - 1.0).abs() < 1e-3,
            "seed {seed}: {q:?}"
        );
    }
}

/// A counter read with little dither (sigma_e 0.12 d) at a slow input (0.004
/// pulses per sample) and a little angle random walk: the random walk spreads
/// the sawtooth's fundamental into a narrow line whose tails reach below the
/// deepest level summed. Counted as a pure line, Q came out 0.15 % low on
/// every seed (-4 of its standard deviations over 4 h).
#[test]
fn a_narrow_sawtooth_lines_tails_are_counted() {
    let model = "[gyro]\nsample_rate_hz = 2000\ninput_rate_dph = 9.532\npulse_arcsec = 1.1852\n\
                 [noise]\nquantization_arcsec = 0.37169\narw_dpsh = 0.005159\n";
    let errs: Vec<f64> = (1..=3)
        .map(|seed| {
            let q = run(model, seed, 3600.0).estimates.quantization_arcsec;
            assert!(covers(&q, 0.37169), "seed {seed}: {q:?}");
            q.value.unwrap() / 0.37169 - 1.0
        })
        .collect();
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    assert!(mean.abs() < 5e-4, "mean relative error {mean} ({errs:?})");
}
