//! The streaming diagnosis statistics against their batch references: the
//! Allan sums against `allan::deviation` (full overlap) and a direct strided
//! sum; the wavelet levels, the Welch bins, the made-up spans and the whole
//! statistic set against the whole-record functions, for several ways of
//! splitting the input; a Monte-Carlo run reduced as it is simulated against
//! the same run simulated whole and reduced in one piece.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::allan::{self, Phase, Stat};
use sagnac::diagnose::mc::{self, McJob};
use sagnac::diagnose::stats::{self, StatLayout, StatSet, Welch};
use sagnac::diagnose::stream::allan::{AllanStream, FULL_OVERLAP_CAP, STRIDED_TERMS};
use sagnac::diagnose::stream::dwt::DwtStream;
use sagnac::diagnose::stream::refill::Refill;
use sagnac::diagnose::stream::welch::WelchStream;
use sagnac::diagnose::stream::{Extras, StatStream};
use sagnac::diagnose::two_level::TwoLevelProbe;
use sagnac::model::Simulator;

/// Counts with a slow input, a random walk in the rate and white noise.
fn counts(n: usize, seed: u64) -> Vec<i64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut drift = 0.0f64;
    let mut acc = 0.0f64;
    (0..n)
        .map(|_| {
            drift += 0.002 * (rng.random::<f64>() - 0.5);
            acc += 3.3 + drift + 4.0 * (rng.random::<f64>() - 0.5);
            let c = acc.floor();
            acc -= c;
            c as i64
        })
        .collect()
}

/// Chunk sizes a stream is fed in: single samples, odd sizes, a block
/// boundary's neighbours, the whole record.
fn splits(n: usize) -> Vec<usize> {
    vec![1, 7, 4095, 65_537, n]
}

fn feed<T>(x: &[T], chunk: usize, mut f: impl FnMut(&[T])) {
    for c in x.chunks(chunk.max(1)) {
        f(c);
    }
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) || (a.is_nan() && b.is_nan())
}

#[test]
fn full_overlap_allan_sums_equal_the_batch_deviations() {
    let n = 300_000;
    let c = counts(n, 1);
    let ms: Vec<u64> = (0..=15).map(|j| 1u64 << j).collect();
    let phase = Phase::Counts(stats::counts_to_cumulative(&c));
    for chunk in [1, 7, 65_537, n] {
        let mut s = AllanStream::new(&ms, n);
        feed(&c, chunk, |x| s.push(x));
        let (oadev, mdev) = s.finish();
        for (i, &m) in ms.iter().enumerate() {
            for (stat, got) in [(Stat::Oadev, oadev[i]), (Stat::Mdev, mdev[i])] {
                let want = allan::deviation(&phase, stat, 1.0, m).map_or(f64::NAN, |d| d.0 * d.0);
                assert!(
                    close(got, want, 1e-12),
                    "{stat:?} m {m} chunk {chunk}: {got} vs {want}"
                );
            }
        }
    }
}

/// The strided octaves against the sums written out directly: `x` and
/// `Q[k] = sum_{i<k} x[i]` at multiples of the stride.
#[test]
fn strided_allan_sums_equal_the_direct_strided_sums() {
    let m = 2 * FULL_OVERLAP_CAP;
    let n = (8 * m + 12_345) as usize;
    let c = counts(n, 2);
    let x = stats::counts_to_cumulative(&c);
    let mut q = vec![0i128; x.len() + 1];
    for (k, &v) in x.iter().enumerate() {
        q[k + 1] = q[k] + v as i128;
    }
    let s = m / STRIDED_TERMS;
    let np = x.len() as u64;
    let (mut so, mut no) = (0.0, 0u64);
    let mut j = 0;
    while j + 2 * m < np {
        let (a, b, e) = (x[j as usize], x[(j + m) as usize], x[(j + 2 * m) as usize]);
        so += ((e - 2 * b + a) as f64).powi(2);
        no += 1;
        j += s;
    }
    let (mut sm, mut nm) = (0.0, 0u64);
    let mut j = 0;
    while j + 3 * m <= np {
        let at = |k: u64| q[k as usize];
        let v = at(j + 3 * m) - 3 * at(j + 2 * m) + 3 * at(j + m) - at(j);
        sm += (v as f64).powi(2);
        nm += 1;
        j += s;
    }
    let mf = m as f64;
    let want_o = so / (2.0 * mf * mf * no as f64);
    let want_m = sm / (2.0 * mf.powi(4) * nm as f64);
    for chunk in [1000, 65_536, n] {
        let mut st = AllanStream::new(&[1, m], n);
        feed(&c, chunk, |v| st.push(v));
        let (o, md) = st.finish();
        assert!(
            close(o[1], want_o, 1e-12),
            "oadev chunk {chunk}: {} vs {want_o}",
            o[1]
        );
        assert!(
            close(md[1], want_m, 1e-12),
            "mdev chunk {chunk}: {} vs {want_m}",
            md[1]
        );
    }
    // and the strided estimate is the full-overlap one's to within its spread
    let full = allan::deviation(&Phase::Counts(x.clone()), Stat::Oadev, 1.0, m).unwrap();
    assert!(
        close(want_o, full.0 * full.0, 0.5),
        "{want_o} vs {}",
        full.0 * full.0
    );
}

#[test]
fn streamed_wavelet_levels_are_the_whole_records_to_the_bit() {
    let n = 200_003;
    let rate: Vec<f64> = counts(n, 3).iter().map(|&c| c as f64 * 1.7).collect();
    let (lo, hi) = stats::sym8();
    let batch = stats::dwt_level_mean_squares(&rate, &lo, &hi, 12, stats::MIN_LEVEL_COEFS);
    let approx5 = stats::dwt_approximation(&rate, &lo, 5);
    for chunk in splits(n) {
        let mut d = DwtStream::new(&lo, &hi, 12, &[5]);
        feed(&rate, chunk, |x| d.push(x));
        let got = d.level_mean_squares();
        for (b, g) in batch.iter().zip(&got) {
            assert_eq!(
                (b.1, b.2.to_bits()),
                (g.0, g.1.to_bits()),
                "level {} chunk {chunk}",
                b.0
            );
        }
        let a = d.approximation(5);
        assert_eq!(a.len(), approx5.len());
        assert!(a.iter().zip(&approx5).all(|(x, y)| close(*x, *y, 1e-12)));
    }
}

#[test]
fn streamed_welch_bins_equal_the_whole_records() {
    let n = 100_000;
    let rate: Vec<f64> = counts(n, 4).iter().map(|&c| 9.0 + c as f64).collect();
    for seg in [64, 1024] {
        let w = Welch::new(seg);
        let batch = w.psd(&rate, 250.0);
        for chunk in splits(n) {
            let mut s = WelchStream::new(&w, n, 250.0);
            feed(&rate, chunk, |x| s.push(x));
            let got = s.finish();
            assert_eq!(got.len(), batch.len());
            for k in 2..got.len() {
                assert!(
                    close(got[k], batch[k], 1e-9),
                    "seg {seg} bin {k} chunk {chunk}"
                );
            }
        }
    }
}

#[test]
fn streamed_made_up_spans_equal_the_whole_records() {
    let n = 50_000;
    let base = counts(n, 5);
    let spans = vec![
        0..3,
        10..11,
        11..14,
        999..1002,
        4094..4100,
        30_000..30_001,
        49_990..50_000,
    ];
    for rate_words in [false, true] {
        let mut want = base.clone();
        stats::refill(&mut want, &spans, rate_words);
        for chunk in [1, 2, 7, 4096, n] {
            let mut r = Refill::new(&spans, n, rate_words);
            let mut got = Vec::new();
            feed(&base, chunk, |x| r.push(x, &mut got));
            assert_eq!(got, want, "rate words {rate_words} chunk {chunk}");
        }
    }
}

fn assert_sets_close(got: &StatSet, want: &StatSet, what: &str) {
    let vecs: [(&str, &Vec<f64>, &Vec<f64>, f64); 7] = [
        ("wvar", &got.wvar, &want.wvar, 0.0),
        ("mvar", &got.mvar, &want.mvar, 1e-12),
        ("avar", &got.avar, &want.avar, 1e-12),
        ("psd", &got.psd, &want.psd, 1e-9),
        ("band_psd", &got.band_psd, &want.band_psd, 1e-9),
        ("kurtosis", &got.kurtosis, &want.kurtosis, 1e-9),
        ("lf_psd", &got.lf_psd, &want.lf_psd, 1e-12),
    ];
    for (name, g, w, rel) in vecs {
        assert_eq!(g.len(), w.len(), "{what}: {name} length");
        for (a, b) in g.iter().zip(w.iter()) {
            assert!(close(*a, *b, rel), "{what}: {name} {a} vs {b}");
        }
    }
    assert!(
        close(got.mean_rate, want.mean_rate, 1e-12),
        "{what}: mean rate"
    );
    assert!(close(got.slope, want.slope, 1e-9), "{what}: slope");
    match (got.temp_slope, want.temp_slope) {
        (Some(a), Some(b)) => assert!(close(a, b, 1e-9), "{what}: temp slope {a} vs {b}"),
        (a, b) => assert_eq!(a.is_some(), b.is_some(), "{what}: temp slope"),
    }
    let (a, b) = (got.two_level_llr, want.two_level_llr);
    // a difference of two log likelihoods: compared in their own units
    assert!(
        (a - b).abs() < 1e-8 || (a.is_nan() && b.is_nan()),
        "{what}: two-level {a} vs {b}"
    );
}

#[test]
fn streamed_statistic_set_equals_the_batch_one() {
    let n = 400_000;
    let c = counts(n, 6);
    let layout = StatLayout::new(n, 400.0, 1.21);
    assert!(layout.ms.iter().all(|&m| m <= FULL_OVERLAP_CAP));
    let temp: Vec<f64> = (0..n).map(|k| 20.0 + (k as f64 * 1e-4).sin()).collect();
    let cutoffs = [0.5, 3.0];
    let probe = TwoLevelProbe {
        amp: 0.3,
        mean_dwell_s: 5.0,
    };
    let mut want = stats::compute(&layout, &c, Some(&temp), &cutoffs);
    let rate = stats::counts_to_rate(&c, 1.21, 400.0);
    want.two_level_llr = probe.llr(&rate, 1.0 / 400.0, &layout.lo);
    let extras = Extras {
        temp_c: Some(&temp),
        lp_cutoffs_hz: &cutoffs,
        two_level: Some(probe),
        full: true,
    };
    for chunk in [1000, 65_536, n] {
        let mut s = StatStream::new(&layout, extras);
        feed(&c, chunk, |x| s.push(x));
        assert_sets_close(&s.finish(), &want, &format!("chunk {chunk}"));
    }
}

/// A Monte-Carlo run reduced as it is simulated (in pieces, its made-up
/// spans made up on the way) against the same seed simulated whole, made up
/// and reduced by the batch functions.
#[test]
fn a_monte_carlo_run_is_the_whole_simulated_records() {
    let model = super::stats::gauss_markov_gyro(500.0);
    let n = 300_000;
    let mut layout = StatLayout::new(n, 500.0, 1.21);
    layout.filled = vec![5..9, 70_000..70_003, 131_071..131_075];
    let seed = 77;
    let mut sim = Simulator::new(&model, seed, Some(n as f64 / 500.0)).unwrap();
    let mut whole = Vec::new();
    sim.next_block(n, &mut whole);
    whole.resize(n, *whole.last().unwrap());
    stats::refill(&mut whole, &layout.filled, false);
    let want = stats::compute(&layout, &whole, None, &[0.4]);
    let progress = mc::Progress::default();
    let job = McJob {
        model: &model,
        layout: &layout,
        temp_c: None,
        lp_cutoffs_hz: &[0.4],
        threads: 1,
        full: true,
        two_level: None,
        phase: "test",
        progress: &progress,
    };
    let got = mc::run(&job, &[seed]).unwrap();
    assert_sets_close(&got[0], &want, "monte-carlo run");
}
