//! QN splitter: bookkeeping (clean + noise == raw, latency, alignment, chunking
//! invariance), the paper's checks on simulated runs of its gyro (clean Allan
//! deviation on the ARW + BI curve, bounded noise integral), the estimates it
//! exposes, and its configuration.
//!
//! Simulated gyro (tests/support/dsp.rs): 28 cm RLG, 1 kHz, pulse weight 1.21", input
//! 12.3 deg/h (Earth rate), Q, N, B as stated per run; seeds fixed.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::dsp::qn::{EXTRA_LEVELS, default_levels, qn_energy_factors};
use sagnac::dsp::{DspError, QnConfig, QnEstimate, QnRule, QnSplitter, StreamingAnalysis, Wavelet};

use crate::support::dsp::{GyroSim, oadev};

const TAU0: f64 = 1e-3;

fn split(raw: &[f64], cfg: &QnConfig, blocks: &[usize]) -> (Vec<f64>, Vec<f64>, QnSplitter) {
    let mut sp = QnSplitter::new(cfg).unwrap();
    let (mut clean, mut noise) = (Vec::new(), Vec::new());
    let mut at = 0;
    for &b in blocks {
        sp.push(&raw[at..at + b], &mut clean, &mut noise);
        at += b;
    }
    assert_eq!(at, raw.len());
    sp.flush(&mut clean, &mut noise);
    (clean, noise, sp)
}

fn even_blocks(n: usize, b: usize) -> Vec<usize> {
    let mut v = vec![b; n / b];
    if !n.is_multiple_of(b) {
        v.push(n % b);
    }
    v
}

fn random_blocks(n: usize, seed: u64) -> Vec<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut v = Vec::new();
    let mut left = n;
    while left > 0 {
        let b = match rng.random_range(0..3) {
            0 => rng.random_range(1..4),
            1 => rng.random_range(1..700),
            _ => rng.random_range(1..20_000),
        }
        .min(left);
        v.push(b);
        left -= b;
    }
    v
}

fn paper(q: f64, n: f64, b: f64, seed: u64) -> GyroSim {
    let mut g = GyroSim::paper(q, n, b, seed);
    g.rate_dph = 12.3;
    g
}

#[test]
fn clean_plus_noise_is_raw_and_latency_is_fixed() {
    let g = paper(0.5, 0.001, 0.002, 21);
    let run = g.simulate(300_000);
    let cfg = QnConfig::new(1000.0);
    let mut sp = QnSplitter::new(&cfg).unwrap();
    let lat = sp.latency();
    assert_eq!(lat, 15 * ((1 << 11) - 1), "sym8, J = 11 at 1 kHz");
    let (mut clean, mut noise) = (Vec::new(), Vec::new());
    let mut pushed = 0;
    for b in random_blocks(run.raw.len(), 22) {
        sp.push(&run.raw[pushed..pushed + b], &mut clean, &mut noise);
        pushed += b;
        assert_eq!(clean.len(), pushed.saturating_sub(lat), "after {pushed}");
        assert_eq!(noise.len(), clean.len());
    }
    sp.flush(&mut clean, &mut noise);
    assert_eq!(clean.len(), run.raw.len());
    for (k, ((&c, &z), &r)) in clean.iter().zip(&noise).zip(&run.raw).enumerate() {
        // Float rounding only: noise = raw - clean, so the sum is raw to 1 ulp.
        let tol = 2.0 * f64::EPSILON * r.abs().max(c.abs());
        assert!((c + z - r).abs() <= tol, "sample {k}: {c} + {z} != {r}");
    }
}

/// A slow signal lies (almost) entirely in the untouched approximation band: away
/// from the two ends (constant extensions, levels not yet ready) clean must equal
/// raw sample for sample. A one-sample misalignment would show as ~3e-4 here.
#[test]
fn output_is_aligned_with_input() {
    let n = 400_000;
    let raw: Vec<f64> = (0..n)
        .map(|k| 12.3 + 10.0 * (2.0 * std::f64::consts::PI * 0.005 * k as f64 * TAU0).sin())
        .collect();
    let (clean, noise, _) = split(&raw, &QnConfig::new(1000.0), &even_blocks(n, 1000));
    let interior = 150_000..n - 40_000;
    let err = clean[interior.clone()]
        .iter()
        .zip(&raw[interior.clone()])
        .fold(0.0f64, |m, (c, r)| m.max((c - r).abs()));
    // Tolerance 1e-6 arcsec/s: the detail content of a 0.005 Hz sine is ~1e-9 of it.
    assert!(err < 1e-6, "max |clean - raw| = {err:e}");
    assert!(noise[interior].iter().all(|z| z.abs() < 1e-6));
}

#[test]
fn chunking_invariance_is_bit_exact() {
    let g = paper(0.35, 0.001, 0.002, 31);
    let run = g.simulate(600_000);
    let cfg = QnConfig::new(1000.0);
    let (c0, z0, s0) = split(&run.raw, &cfg, &[run.raw.len()]);
    for seed in [32, 33] {
        let (c, z, s) = split(&run.raw, &cfg, &random_blocks(run.raw.len(), seed));
        // Tolerance: none.
        assert!(c == c0 && z == z0, "seed {seed}: outputs differ");
        assert_eq!(s.level_stats(), s0.level_stats(), "seed {seed}");
        assert_eq!(s.estimates(), s0.estimates(), "seed {seed}");
    }
    // Block size 1 over a shorter stretch.
    let short = &run.raw[..80_000];
    let (c1, z1, _) = split(short, &cfg, &[short.len()]);
    let (c2, z2, _) = split(short, &cfg, &vec![1; short.len()]);
    assert!(c1 == c2 && z1 == z2, "block size 1 differs");
}

#[test]
fn short_and_empty_streams() {
    let cfg = QnConfig::new(1000.0);
    for n in [0usize, 1, 5, 2047, 2048, 2049, 40_000] {
        let raw: Vec<f64> = (0..n)
            .map(|k| 12.3 + ((k * 7919) % 13) as f64 - 6.0)
            .collect();
        let (c, z, sp) = split(&raw, &cfg, &even_blocks(n, 333));
        assert_eq!(c.len(), n, "n = {n}");
        assert_eq!(z.len(), n);
        for k in 0..n {
            assert!(
                (c[k] + z[k] - raw[k]).abs() <= 1e-12 * raw[k].abs().max(1.0),
                "n = {n}, k = {k}"
            );
        }
        assert_eq!(sp.samples_out(), n as u64);
    }
}

/// Non-finite samples do not poison the splitter: the bank sees the last finite
/// sample in their place, they appear in `noise` at their own index only.
#[test]
fn non_finite_samples_are_contained() {
    let g = paper(0.5, 0.001, 0.002, 91);
    let mut raw = g.simulate(200_000).raw;
    let bad = [60_000usize, 60_001, 123_456];
    let mut held = raw.clone();
    for (k, &i) in bad.iter().enumerate() {
        raw[i] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][k];
    }
    // Ascending order: a run of bad samples all take the last good value.
    for &i in &bad {
        held[i] = held[i - 1];
    }
    let cfg = QnConfig::new(1000.0);
    let (c_bad, z_bad, sp) = split(&raw, &cfg, &even_blocks(raw.len(), 4096));
    let (c_ref, _, sp_ref) = split(&held, &cfg, &even_blocks(held.len(), 4096));
    assert!(c_bad.iter().all(|c| c.is_finite()));
    assert!(
        c_bad == c_ref,
        "clean must equal the run with held samples, bit for bit"
    );
    for (k, z) in z_bad.iter().enumerate() {
        assert_eq!(z.is_finite(), !bad.contains(&k), "sample {k}");
    }
    assert_eq!(sp.level_stats(), sp_ref.level_stats());
}

struct RunResult {
    name: String,
    clean_vs_model: Vec<f64>,
    clean_vs_truth: Vec<f64>,
    raw_vs_model: Vec<f64>,
}

const TAUS: [f64; 5] = [0.5, 1.0, 2.0, 8.0, 32.0];

fn run_case(name: &str, g: &GyroSim, hours: f64) -> RunResult {
    let n = (hours * 3.6e6) as usize;
    let run = g.simulate(n);
    let (clean, _, _) = split(&run.raw, &QnConfig::new(1000.0), &even_blocks(n, 4096));
    let mut r = RunResult {
        name: name.to_string(),
        clean_vs_model: vec![],
        clean_vs_truth: vec![],
        raw_vs_model: vec![],
    };
    for &tau in &TAUS {
        let m = (tau / TAU0).round() as usize;
        let model = g.true_avar_arw_bi(tau).sqrt();
        let c = oadev(&clean, TAU0, m);
        r.clean_vs_model.push(c / model);
        r.clean_vs_truth.push(c / oadev(&run.truth, TAU0, m));
        r.raw_vs_model.push(oadev(&run.raw, TAU0, m) / model);
    }
    r
}

/// The acceptance test. Three 4-hour static runs of the paper's gyro (4 h
/// keeps the Allan deviation's own scatter at tau = 32 s near 3 %, so the 10 %
/// band tests the splitter, not the luck of the seed):
/// clean ADEV within 10 % of the true ARW + BI curve at tau = 2, 8, 32 s, raw ADEV
/// more than 3x above it at 2 and 8 s. Also: clean within 5 % of the ADEV of the
/// very realisation's non-QN part at 2..32 s, and within 10 % at 1 s.
#[test]
fn clean_allan_deviation_follows_arw_bi() {
    let cases = [
        (
            "Q 0.35 (weak dither) N 0.001 B 0.002",
            paper(0.35, 0.001, 0.002, 41),
        ),
        ("Q 0.50 N 0.0012 B 0.003", paper(0.5, 0.0012, 0.003, 42)),
        ("Q 0.60 N 0.0010 B 0.002", paper(0.6, 0.001, 0.002, 43)),
    ];
    let results: Vec<RunResult> = cases.iter().map(|(n, g)| run_case(n, g, 4.0)).collect();
    println!("ADEV ratios at tau = {TAUS:?} s");
    for r in &results {
        let f = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:6.3}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        println!("{:<40} clean/model {}", r.name, f(&r.clean_vs_model));
        println!("{:<40} clean/truth {}", "", f(&r.clean_vs_truth));
        println!("{:<40} raw/model   {}", "", f(&r.raw_vs_model));
    }
    for r in &results {
        for (i, &tau) in TAUS.iter().enumerate() {
            if tau >= 2.0 {
                // Requirement: within 10 % of the true ARW+BI curve.
                let e = (r.clean_vs_model[i] - 1.0).abs();
                assert!(
                    e <= 0.10,
                    "{}: clean/model at {tau} s = {:.3}",
                    r.name,
                    r.clean_vs_model[i]
                );
                // Ours: within 5 % of this realisation's non-QN ADEV.
                let e = (r.clean_vs_truth[i] - 1.0).abs();
                assert!(
                    e <= 0.05,
                    "{}: clean/truth at {tau} s = {:.3}",
                    r.name,
                    r.clean_vs_truth[i]
                );
            }
            if tau == 1.0 {
                let e = (r.clean_vs_truth[i] - 1.0).abs();
                assert!(
                    e <= 0.10,
                    "{}: clean/truth at 1 s = {:.3}",
                    r.name,
                    r.clean_vs_truth[i]
                );
            }
            if tau == 2.0 || tau == 8.0 {
                // Requirement: raw buried under QN, > 3x the ARW+BI curve.
                assert!(
                    r.raw_vs_model[i] > 3.0,
                    "{}: raw/model at {tau} s = {:.3}",
                    r.name,
                    r.raw_vs_model[i]
                );
            }
        }
    }
}

/// Running integral (angle) of a rate series, arcsec.
fn integral(x: &[f64], mean: f64) -> Vec<f64> {
    let mut acc = 0.0;
    x.iter()
        .map(|v| {
            acc += (v - mean) * TAU0;
            acc
        })
        .collect()
}

/// Standard deviation of I(t + lag) - I(t) over t.
fn increment_sd(i: &[f64], lag: usize) -> f64 {
    let d: Vec<f64> = i
        .windows(lag + 1)
        .step_by(97)
        .map(|w| w[lag] - w[0])
        .collect();
    let m = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / d.len() as f64).sqrt()
}

/// The paper's check: over an hour, the integral of `noise` stays bounded (about one
/// pulse weight for the paper's weakly dithered counter; for a Gaussian dither
/// residual, the angle error itself, sd = Q), while the integral of the raw rate
/// wanders as ARW does. Each case simulates 4 h: the noise bounds are asserted on
/// the first hour and on all 4 h; the raw integral's growth needs the 4 h to be
/// measured with some precision (its increments at a 1800 s lag).
#[test]
fn noise_integral_is_bounded() {
    let d = 1.21;
    let hour = 3_600_000;
    println!("noise integral, in pulse weights d = {d}\"");
    for (q, seed) in [(0.35, 51u64), (0.6, 52)] {
        let g = paper(q, 0.001, 0.002, seed);
        let n = 4 * hour;
        let run = g.simulate(n);
        let (_, noise, sp) = split(&run.raw, &QnConfig::new(1000.0), &even_blocks(n, 4096));
        let i_noise = integral(&noise, 0.0);
        let stats = |i: &[f64]| {
            let max = i.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let mean = i.iter().sum::<f64>() / i.len() as f64;
            let sd = (i.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / i.len() as f64).sqrt();
            (max, sd)
        };
        let (max1, sd1) = stats(&i_noise[..hour]);
        let (max4, sd4) = stats(&i_noise);
        let raw_mean = run.raw.iter().sum::<f64>() / n as f64;
        let i_raw = integral(&run.raw, raw_mean);
        let (raw_max1, _) = stats(&i_raw[..hour]);
        let (lag_s, lag_l) = (60_000, 1_800_000);
        let grow_noise = increment_sd(&i_noise, lag_l) / increment_sd(&i_noise, lag_s);
        let grow_raw = increment_sd(&i_raw, lag_l) / increment_sd(&i_raw, lag_s);
        // Model growth of the raw integral's increment sd: sqrt((N^2 T + 2 Q^2)) ratio.
        let n2 = (0.001f64 * 60.0).powi(2);
        let model_raw = ((n2 * 1800.0 + 2.0 * q * q) / (n2 * 60.0 + 2.0 * q * q)).sqrt();
        println!(
            "Q = {q}: noise integral 1 h: max {:.3} d, sd {:.3} d; 4 h: max {:.3} d, sd {:.3} d (Q/d = {:.3}); \
             raw integral 1 h max {:.2} d; increment sd 60 s -> 1800 s: noise x{grow_noise:.2}, \
             raw x{grow_raw:.2} (model x{model_raw:.2}); q_integral {:.3}",
            max1 / d,
            sd1 / d,
            max4 / d,
            sd4 / d,
            q / d,
            raw_max1 / d,
            sp.estimates().q_integral_arcsec.unwrap()
        );
        for (what, max, sd) in [("1 h", max1, sd1), ("4 h", max4, sd4)] {
            // sd of the integral is the angle error Q (10 %).
            assert!((sd / q - 1.0).abs() <= 0.10, "Q = {q}, {what}: sd {sd}");
            if q < 0.4 {
                // Weak dither: the error is the counter's sawtooth, |e| < d; measured
                // max 0.6-1.0 d.
                assert!(max <= 1.2 * d, "Q = {q}, {what}: max {max}");
            } else {
                // Gaussian dither residual: its tail, about 5.5-6 sd over 3.6-14 M samples.
                assert!(max <= 7.0 * q, "Q = {q}, {what}: max {max}");
            }
        }
        // Bounded: no growth with lag (white angle error: sqrt(2) Q at every lag).
        assert!(
            (grow_noise - 1.0).abs() <= 0.15,
            "Q = {q}: noise integral grows x{grow_noise}"
        );
        // Wanders: ARW makes the raw integral's increments grow (model x2.8-x3.8).
        assert!(
            grow_raw > 2.0,
            "Q = {q}: raw integral grows only x{grow_raw}"
        );
    }
}

/// The estimates exposed for the estimator module.
#[test]
fn estimates_and_level_stats() {
    for (q, n_arw, seed) in [(0.35, 0.001, 61u64), (0.6, 0.0015, 62)] {
        let g = paper(q, n_arw, 0.002, seed);
        let run = g.simulate(1_800_000);
        let (_, _, sp) = split(
            &run.raw,
            &QnConfig::new(1000.0),
            &even_blocks(run.raw.len(), 5000),
        );
        let e = sp.estimates();
        let (qi, arw) = (e.q_integral_arcsec.unwrap(), e.arw_floor_dpsh.unwrap());
        println!(
            "Q {q} N {n_arw}: q_integral {qi:.4}, q_white {:.4}, arw_floor {arw:.5}",
            e.q_white_arcsec.unwrap()
        );
        // Q from the noise integral: 5 %.
        assert!((qi / q - 1.0).abs() <= 0.05, "q_integral {qi} vs {q}");
        // ARW from the fitted floor: 10 % (statistical scatter over 30 min ~ 4 %).
        assert!(
            (arw / n_arw - 1.0).abs() <= 0.10,
            "arw_floor {arw} vs {n_arw}"
        );
        if q > 0.5 {
            // White-model Q from the finest level holds when the dither whitens QN.
            let qw = e.q_white_arcsec.unwrap();
            assert!((qw / q - 1.0).abs() <= 0.05, "q_white {qw} vs {q}");
        }
        let stats = sp.level_stats();
        let j = sp.levels() as usize;
        assert_eq!(stats.len(), j + EXTRA_LEVELS as usize + 1);
        for (i, s) in stats.iter().enumerate() {
            assert!(s.var_qn >= 0.0 && s.var_qn <= s.var_total, "{s:?}");
            assert!((0.0..=1.0).contains(&s.gain), "{s:?}");
            if i < j {
                assert_eq!(s.level as usize, i + 1);
                // Power subtraction: g^2 = 1 - var_qn / var_total.
                let g2 = 1.0 - s.var_qn / s.var_total;
                assert!((s.gain * s.gain - g2).abs() < 1e-12, "{s:?}");
            }
        }
        assert_eq!(
            stats[j + EXTRA_LEVELS as usize].level,
            0,
            "approximation last"
        );
        // The finest level is all QN, the deepest detail mostly ARW.
        assert!(
            stats[0].gain < 0.01 && stats[j - 1].gain > 0.7,
            "{:?}",
            (stats[0], stats[j - 1])
        );
    }
}

/// kappa: Parseval (exact identity) and a Monte Carlo check against the bank.
#[test]
fn qn_energy_factors_are_right() {
    for name in Wavelet::NAMES {
        let w = Wavelet::by_name(name).unwrap();
        let levels = 8u32;
        let k = qn_energy_factors(&w, levels);
        // Energy of a differenced unit white sequence is 2 per sample; the bank is
        // orthonormal: sum_j kappa_j / 2^j + kappa_A / 2^J = 2.
        let total: f64 = (0..levels as usize)
            .map(|j| k[j] / (1u64 << (j + 1)) as f64)
            .sum::<f64>()
            + k[levels as usize] / (1u64 << levels) as f64;
        assert!((total - 2.0).abs() < 1e-12, "{name}: {total}");
    }
    // Monte Carlo: white angle noise through the streaming analysis.
    let w = Wavelet::by_name("sym8").unwrap();
    let levels = 6u32;
    let k = qn_energy_factors(&w, levels);
    let mut rng = ChaCha8Rng::seed_from_u64(71);
    let e: Vec<f64> = (0..2_000_001).map(|_| rng.random::<f64>() - 0.5).collect(); // var 1/12
    let r: Vec<f64> = e.windows(2).map(|p| p[1] - p[0]).collect();
    let mut ana = StreamingAnalysis::new(&w, levels).unwrap();
    let mut out = sagnac::dsp::bank::AnalysisOutput::default();
    ana.push(&r, &mut out);
    for (j, (det, kappa)) in out.details.iter().zip(&k).enumerate() {
        let d = &det[20..];
        let v = d.iter().map(|c| c * c).sum::<f64>() / d.len() as f64;
        let want = kappa / 12.0;
        // 2 % (level 6 has 31 k coefficients: sampling sd ~0.8 %).
        assert!(
            (v / want - 1.0).abs() < 0.02,
            "level {}: {v} vs {want}",
            j + 1
        );
    }
}

#[test]
fn config_defaults_validation_and_serde() {
    assert_eq!(default_levels(1000.0), 11);
    assert_eq!(default_levels(1024.0), 11);
    assert_eq!(default_levels(400.0), 10);
    assert_eq!(default_levels(100.0), 8);
    let c = QnConfig::new(1000.0);
    assert_eq!(c.resolved_levels(), 11);
    assert_eq!(
        (c.rule, c.qn_estimate, c.wavelet.as_str()),
        (QnRule::PowerSubtraction, QnEstimate::ArwFloor, "sym8")
    );
    c.validate().unwrap();

    let bad = |f: &dyn Fn(&mut QnConfig)| {
        let mut c = QnConfig::new(1000.0);
        f(&mut c);
        c.validate().unwrap_err()
    };
    assert!(matches!(
        bad(&|c| c.wavelet = "sym5".into()),
        DspError::UnknownWavelet { .. }
    ));
    let e = bad(&|c| c.sample_rate_hz = 0.0);
    assert!(e.to_string().contains("sample_rate_hz"), "{e}");
    assert!(matches!(
        bad(&|c| c.levels = Some(1)),
        DspError::InvalidLevels { levels: 1, .. }
    ));
    assert!(matches!(
        bad(&|c| c.levels = Some(40)),
        DspError::InvalidLevels { levels: 40, .. }
    ));
    assert!(
        bad(&|c| c.stats_window_s = -1.0)
            .to_string()
            .contains("stats_window_s")
    );
    assert!(
        bad(&|c| c.threshold_k = f64::NAN)
            .to_string()
            .contains("threshold_k")
    );
    assert!(
        bad(&|c| c.min_coeffs = 0)
            .to_string()
            .contains("min_coeffs")
    );
    assert!(
        QnSplitter::new(&QnConfig {
            wavelet: "nope".into(),
            ..QnConfig::new(1000.0)
        })
        .is_err()
    );

    let t: QnConfig = toml::from_str(
        "wavelet = \"db8\"\nlevels = 9\nsample_rate_hz = 400.0\nrule = \"wiener\"\n",
    )
    .unwrap();
    assert_eq!(
        (t.wavelet.as_str(), t.levels, t.rule),
        ("db8", Some(9), QnRule::Wiener)
    );
    assert_eq!(t.stats_window_s, QnConfig::default().stats_window_s);
    let e = toml::from_str::<QnConfig>("wavelets = \"sym8\"\n").unwrap_err();
    assert!(e.to_string().contains("wavelets"), "{e}");
}
