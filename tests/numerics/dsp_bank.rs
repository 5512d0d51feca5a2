//! Streaming filter bank: perfect reconstruction, fixed latency, chunking
//! invariance (bit for bit), agreement with the batch reference, bounded memory.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use sagnac::dsp::bank::{AnalysisOutput, MAX_LEVELS};
use sagnac::dsp::dwt::{self, Mode};
use sagnac::dsp::{CoeffHook, DspError, StreamingAnalysis, StreamingBank, Wavelet};

fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // A random walk plus white noise plus an offset: every band carries energy.
    let mut w = 0.0;
    (0..n)
        .map(|_| {
            w += rng.sample::<f64, _>(StandardNormal);
            5.0 + 0.1 * w + rng.sample::<f64, _>(StandardNormal)
        })
        .collect()
}

/// Random block sizes: mostly small (including 1), sometimes large.
fn random_splits(n: usize, seed: u64) -> Vec<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut left = n;
    while left > 0 {
        let b = match rng.random_range(0..4) {
            0 => 1,
            1 => rng.random_range(1..8),
            2 => rng.random_range(1..300),
            _ => rng.random_range(1..5000),
        }
        .min(left);
        out.push(b);
        left -= b;
    }
    out
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

fn max_abs(a: &[f64]) -> f64 {
    a.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

#[test]
fn perfect_reconstruction_all_wavelets() {
    let x = noise(40_000 + 37, 1);
    for name in Wavelet::NAMES {
        let w = Wavelet::by_name(name).unwrap();
        for levels in [1u32, 2, 5, 10] {
            let mut bank = StreamingBank::new(&w, levels).unwrap();
            assert_eq!(bank.latency(), (w.len() - 1) * ((1 << levels) - 1));
            let mut out = Vec::new();
            bank.push(&x, &mut out);
            bank.flush(&mut out);
            assert_eq!(out.len(), x.len(), "{name} J={levels}");
            let err = max_abs_diff(&out, &x);
            // Requirement: 1e-12 relative. Measured: about 1e-15.
            assert!(
                err <= 1e-12 * max_abs(&x),
                "{name} J={levels}: PR error {err:e}"
            );
        }
    }
}

/// After N pushed samples exactly max(0, N - latency) outputs have been released,
/// for any block sizes.
#[test]
fn fixed_latency_for_any_blocks() {
    let w = Wavelet::by_name("sym8").unwrap();
    for levels in [1u32, 3, 6] {
        let x = noise(30_000, 2);
        let mut bank = StreamingBank::new(&w, levels).unwrap();
        let lat = bank.latency();
        let mut out = Vec::new();
        let mut pushed = 0;
        for b in random_splits(x.len(), 3) {
            bank.push(&x[pushed..pushed + b], &mut out);
            pushed += b;
            assert_eq!(
                out.len(),
                pushed.saturating_sub(lat),
                "J={levels} after {pushed}"
            );
            assert_eq!(bank.samples_out() as usize, out.len());
        }
        // Output n is input n (delayed): check alignment, not only counts.
        let n = out.len();
        assert!(max_abs_diff(&out, &x[..n]) <= 1e-12 * max_abs(&x));
    }
}

/// Multiplies each level's details by a gain that changes every frame, as the QN
/// splitter does (a pure function of level and coefficient index).
struct FrameGains {
    levels: u32,
}
impl CoeffHook for FrameGains {
    fn details(&mut self, level: u32, first: u64, d: &mut [f64]) {
        for (i, c) in d.iter_mut().enumerate() {
            let idx = first + i as u64;
            let frame = idx >> (self.levels - level);
            *c *= 0.5 + 0.4 * ((frame as f64) * 0.7 + level as f64).sin();
        }
    }
}

#[test]
fn chunking_invariance_is_bit_exact() {
    let x = noise(50_000, 4);
    for name in ["haar", "db4", "sym8"] {
        let w = Wavelet::by_name(name).unwrap();
        let levels = 7;
        // Reference: one push.
        let mut bank = StreamingBank::new(&w, levels).unwrap();
        let mut hook = FrameGains { levels };
        let mut ref_out = Vec::new();
        bank.push_with(&x, &mut ref_out, &mut hook);
        bank.flush_with(&mut ref_out, &mut hook);
        let mut ana = StreamingAnalysis::new(&w, levels).unwrap();
        let mut ref_c = AnalysisOutput::default();
        ana.push(&x, &mut ref_c);
        for seed in 10..14 {
            let splits = random_splits(x.len(), seed);
            let mut bank = StreamingBank::new(&w, levels).unwrap();
            let mut hook = FrameGains { levels };
            let mut out = Vec::new();
            let mut ana = StreamingAnalysis::new(&w, levels).unwrap();
            let mut c = AnalysisOutput::default();
            let mut at = 0;
            for b in splits {
                bank.push_with(&x[at..at + b], &mut out, &mut hook);
                ana.push(&x[at..at + b], &mut c);
                at += b;
            }
            bank.flush_with(&mut out, &mut hook);
            // Tolerance: none (bit-identical).
            assert!(out == ref_out, "{name} seed {seed}: synthesis differs");
            assert!(c == ref_c, "{name} seed {seed}: coefficients differ");
        }
        // Every kernel variant this CPU runs gives the very same bits.
        for variant in ["baseline", "avx2", "avx512"] {
            let mut bank = StreamingBank::new(&w, levels).unwrap();
            if !bank.force_kernels(variant) {
                println!("kernel variant {variant} not available on this CPU");
                continue;
            }
            let mut hook = FrameGains { levels };
            let mut out = Vec::new();
            for chunk in x.chunks(999) {
                bank.push_with(chunk, &mut out, &mut hook);
            }
            bank.flush_with(&mut out, &mut hook);
            assert!(out == ref_out, "{name}: kernel variant {variant} differs");
        }
        assert!(
            !StreamingBank::new(&w, levels)
                .unwrap()
                .force_kernels("sse9")
        );
    }
}

/// Streaming analysis == batch reference (mode zero, offset 0); streaming
/// synthesis of modified coefficients == batch waverec of the same coefficients.
#[test]
fn streaming_equals_batch_reference() {
    let x = noise(6_001, 5);
    for name in Wavelet::NAMES {
        let w = Wavelet::by_name(name).unwrap();
        let levels = 6;
        let batch = dwt::wavedec(&x, &w, levels, Mode::Zero);
        let mut ana = StreamingAnalysis::new(&w, levels).unwrap();
        let mut c = AnalysisOutput::default();
        for chunk in x.chunks(333) {
            ana.push(chunk, &mut c);
        }
        ana.push(&vec![0.0; (w.len() + 1) << levels], &mut c);
        for j in 1..=levels as usize {
            let b = &batch[batch.len() - j];
            // 1e-12 relative: same sums, different association (polyphase, FMA).
            let err = max_abs_diff(&c.details[j - 1][..b.len()], b);
            assert!(err <= 1e-12 * max_abs(b), "{name} cD{j}: {err:e}");
        }
        let err = max_abs_diff(&c.approx[..batch[0].len()], &batch[0]);
        assert!(err <= 1e-12 * max_abs(&batch[0]), "{name} cA: {err:e}");

        // Synthesis with per-level gains (constant, so the batch side can apply them).
        struct G;
        impl CoeffHook for G {
            fn details(&mut self, level: u32, _f: u64, d: &mut [f64]) {
                d.iter_mut().for_each(|c| *c *= 1.0 / (1.0 + level as f64));
            }
        }
        let mut scaled = batch.clone();
        for j in 1..=levels as usize {
            let k = scaled.len() - j;
            scaled[k]
                .iter_mut()
                .for_each(|c| *c *= 1.0 / (1.0 + j as f64));
        }
        let rec = dwt::waverec(&scaled, &w, Mode::Zero).unwrap();
        let mut bank = StreamingBank::new(&w, levels).unwrap();
        let mut out = Vec::new();
        for chunk in x.chunks(777) {
            bank.push_with(chunk, &mut out, &mut G);
        }
        bank.flush_with(&mut out, &mut G);
        let err = max_abs_diff(&out, &rec[..x.len()]);
        assert!(err <= 1e-12 * max_abs(&rec), "{name} synthesis: {err:e}");
    }
}

/// Memory does not grow with the record: the bank's buffers after 4 M samples are
/// no larger than after 400 k, and within O(L 2^J).
#[test]
fn memory_independent_of_record_length() {
    let w = Wavelet::by_name("sym8").unwrap();
    let levels = 10;
    let mut bank = StreamingBank::new(&w, levels).unwrap();
    let block = noise(4096, 6);
    let mut out = Vec::new();
    let mut cap_at = |n_blocks: usize, bank: &mut StreamingBank| {
        for _ in 0..n_blocks {
            bank.push(&block, &mut out);
            out.clear();
        }
        bank.state_capacity()
    };
    let early = cap_at(100, &mut bank); // 410 k samples
    let late = cap_at(900, &mut bank); // 4.1 M samples
    assert!(late <= early, "state grew from {early} to {late} values");
    let bound = 4 * w.len() * (1 << levels) + 8 * 4096;
    assert!(late <= bound, "state {late} values > bound {bound}");
}

#[test]
fn invalid_depth_is_an_error() {
    let w = Wavelet::by_name("sym8").unwrap();
    for bad in [0, MAX_LEVELS + 1] {
        match StreamingBank::new(&w, bad) {
            Err(DspError::InvalidLevels { levels, .. }) => assert_eq!(levels, bad),
            other => panic!("levels {bad}: {other:?}"),
        }
    }
    let e = StreamingAnalysis::new(&w, 0).unwrap_err();
    assert!(e.to_string().contains("levels"), "{e}");
}
