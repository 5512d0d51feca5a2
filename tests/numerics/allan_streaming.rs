//! Streaming octave OADEV engine (`sagnac::allan::streaming`) against plain references
//! written here from their definitions: the NIST SP 1065 OADEV sum (and its strided
//! variant), exact integer sums for pulse counts, Greenhall's EDF algorithm, a batch
//! lag-1 autocorrelation noise identification, chi-square closed forms, and
//! Monte-Carlo simulations. Seeds are fixed; tolerances sit next to each assertion.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rustfft::{FftPlanner, num_complex::Complex};
use sagnac::allan::streaming::{
    InputKind, MIN_ID_POINTS, OctaveAllan, StreamConfig, StreamError, StreamPoint,
    chi2_dev_interval, edf_strided,
};

// ------------------------------------------------------------------------------
// References
// ------------------------------------------------------------------------------

/// Naive strided Allan variance on phase `x`: terms start at 0, s, 2s, ... (s = 1 is
/// the NIST SP 1065 OADEV). Returns (avar, number of terms).
fn naive_avar(x: &[f64], m: usize, s: usize, tau0: f64) -> (f64, u64) {
    let mut sum = 0.0;
    let mut n = 0u64;
    let mut i = 0;
    while i + 2 * m < x.len() {
        let z = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
        sum += z * z;
        n += 1;
        i += s;
    }
    let mf = m as f64;
    (sum / (2.0 * mf * mf * tau0 * tau0 * n as f64), n)
}

/// Exact integer version on an i128 phase (cumulative counts, no wrapping).
fn naive_avar_int(x: &[i128], m: usize, s: usize, tau0: f64) -> (f64, u64) {
    let mut sum: u128 = 0;
    let mut n = 0u64;
    let mut i = 0;
    while i + 2 * m < x.len() {
        let z = x[i + 2 * m] - 2 * x[i + m] + x[i];
        sum += (z * z) as u128;
        n += 1;
        i += s;
    }
    let mf = m as f64;
    (sum as f64 / (2.0 * mf * mf * tau0 * tau0 * n as f64), n)
}

/// AllanTools-style frequency to phase: remove the mean, integrate, prepend 0.
fn freq_to_phase(y: &[f64], tau0: f64) -> Vec<f64> {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let mut x = Vec::with_capacity(y.len() + 1);
    x.push(0.0);
    let mut acc = 0.0;
    for &v in y {
        acc += (v - mean) * tau0;
        x.push(acc);
    }
    x
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b { 0.0 } else { (a - b).abs() / b.abs() }
}

fn gaussian(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
    (0..n).map(|_| StandardNormal.sample(rng)).collect()
}

fn cumsum(v: &[f64]) -> Vec<f64> {
    let mut acc = 0.0;
    v.iter()
        .map(|&a| {
            acc += a;
            acc
        })
        .collect()
}

/// Power-law phase noise with S_x(f) ~ f^(alpha - 2) (Kasdin-Walter filter of white
/// noise, `(1 - B)^(-a/2)` with `a = 2 - alpha`, convolved by FFT).
fn power_law_phase(alpha: i32, n: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let a = f64::from(2 - alpha);
    let mut h = vec![0.0; n];
    h[0] = 1.0;
    for k in 1..n {
        h[k] = h[k - 1] * (a / 2.0 + k as f64 - 1.0) / k as f64;
    }
    let w = gaussian(rng, n);
    let len = (2 * n).next_power_of_two();
    let mut planner = FftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(len);
    let inv = planner.plan_fft_inverse(len);
    let mut hw: Vec<Complex<f64>> = (0..len)
        .map(|i| Complex::new(if i < n { h[i] } else { 0.0 }, 0.0))
        .collect();
    let mut ww: Vec<Complex<f64>> = (0..len)
        .map(|i| Complex::new(if i < n { w[i] } else { 0.0 }, 0.0))
        .collect();
    fwd.process(&mut hw);
    fwd.process(&mut ww);
    for (p, q) in hw.iter_mut().zip(&ww) {
        *p *= q;
    }
    inv.process(&mut hw);
    hw[..n].iter().map(|c| c.re / len as f64).collect()
}

fn feed_random_chunks(acc: &mut OctaveAllan<f64>, data: &[f64], rng: &mut ChaCha8Rng) {
    let mut i = 0;
    while i < data.len() {
        let len = match rng.random_range(0..3) {
            0 => 1,
            1 => rng.random_range(1..100),
            _ => rng.random_range(1..20_000),
        }
        .min(data.len() - i);
        if len == 1 {
            acc.push(data[i]).unwrap();
        } else {
            acc.push_block(&data[i..i + len]).unwrap();
        }
        i += len;
    }
}

fn small_cfg(tau0: f64, cap: u64, p: u64) -> StreamConfig {
    StreamConfig {
        tau0_s: tau0,
        full_overlap_cap: cap,
        strided_terms_per_tau: p,
        ..StreamConfig::default()
    }
}

// ------------------------------------------------------------------------------
// OADEV values against the naive batch definition
// ------------------------------------------------------------------------------

fn check_against_naive(points: &[StreamPoint], x: &[f64], tau0: f64, cap: u64, p: u64, scale: f64) {
    assert!(!points.is_empty());
    for pt in points {
        let m = pt.m as usize;
        let expect_stride = if pt.m <= cap { 1 } else { pt.m / p };
        assert_eq!(pt.stride, expect_stride, "m {m}");
        let (avar, n) = naive_avar(x, m, pt.stride as usize, tau0);
        assert_eq!(pt.n, n, "term count at m {m}");
        if pt.stride == 1 {
            assert_eq!(pt.n, x.len() as u64 - 2 * pt.m, "n = N - 2m at m {m}");
        }
        // 1e-12 relative: same terms, different summation order.
        let got = pt.avar / (scale * scale);
        assert!(
            rel(got, avar) <= 1e-12,
            "m {m} stride {}: {got} vs {avar}",
            pt.stride
        );
        assert_eq!(pt.tau_s, pt.m as f64 * tau0);
        assert_eq!(pt.dev, pt.avar.sqrt());
    }
    // Every octave with at least one term is reported.
    let last = points.last().unwrap().m;
    assert!(x.len() as u64 > 2 * last && (x.len() as u64) <= 4 * last);
}

#[test]
fn full_overlap_phase_equals_naive_oadev() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    // White FM phase (random walk) plus white PM, 300 017 points: two complete blocks
    // of 2^17 and a partial one; octaves up to 2^17 (the first strided one).
    let w = gaussian(&mut rng, 300_017);
    let x: Vec<f64> = cumsum(&w)
        .iter()
        .zip(gaussian(&mut rng, 300_017))
        .map(|(a, b)| 1e-3 * a + 1e-4 * b)
        .collect();
    let tau0 = 0.01;
    let cfg = StreamConfig::with_tau0(tau0);
    let mut acc = OctaveAllan::phase(cfg.clone()).unwrap();
    acc.push_block(&x).unwrap();
    let pts = acc.points(0.683).unwrap();
    assert_eq!(pts.len(), 18);
    check_against_naive(
        &pts,
        &x,
        tau0,
        cfg.full_overlap_cap,
        cfg.strided_terms_per_tau,
        1.0,
    );
    assert_eq!(acc.samples(), x.len() as u64);
    assert_eq!(acc.phase_points(), x.len() as u64);
}

#[test]
fn strided_octaves_equal_naive_strided_sum() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    // cap = 16, P = 4: octaves 32 .. 2^15 use stride m / 4.
    let x = cumsum(&cumsum(&gaussian(&mut rng, 100_003)));
    let (cap, p) = (16, 4);
    let cfg = small_cfg(1.0, cap, p);
    let mut acc = OctaveAllan::phase(cfg).unwrap();
    acc.push_block(&x).unwrap();
    let pts = acc.points(0.9).unwrap();
    assert_eq!(pts.len(), 16);
    assert!(pts.iter().filter(|p| p.stride > 1).count() == 11);
    check_against_naive(&pts, &x, 1.0, cap, p, 1.0);
}

#[test]
fn freq_input_equals_naive_on_integrated_phase() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // A large constant offset (think Earth rate) on white + random-walk frequency.
    let rw = cumsum(&gaussian(&mut rng, 200_001));
    let y: Vec<f64> = gaussian(&mut rng, 200_001)
        .iter()
        .zip(&rw)
        .map(|(a, b)| 1234.5 + a + 0.01 * b)
        .collect();
    let tau0 = 0.1;
    let cfg = small_cfg(tau0, 1 << 10, 1 << 6);
    let mut acc = OctaveAllan::freq(cfg.clone()).unwrap();
    acc.push_block(&y).unwrap();
    assert_eq!(acc.samples(), y.len() as u64);
    assert_eq!(acc.phase_points(), y.len() as u64 + 1);
    let x = freq_to_phase(&y, tau0);
    check_against_naive(&acc.points(0.683).unwrap(), &x, tau0, 1 << 10, 1 << 6, 1.0);
}

#[test]
fn count_input_is_exact_even_when_the_cumulative_count_wraps() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    // A huge count rate (2^61 per sample, plus noise) makes the wrapping i64 cumulative
    // count overflow every few samples; the second differences stay small, so they are
    // exact (the reference accumulates in i128 and never wraps).
    let inc: Vec<i64> = (0..120_000)
        .map(|_| (1i64 << 61) + rng.random_range(-5..=5))
        .collect();
    let mut x = vec![0i128];
    for &d in &inc {
        let last = *x.last().unwrap();
        x.push(last + i128::from(d));
    }
    let tau0 = 1e-4;
    let scale = 1.2; // e.g. arcsec per pulse
    let cfg = StreamConfig {
        scale,
        ..small_cfg(tau0, 1 << 8, 1 << 4)
    };
    let mut acc = OctaveAllan::counts(cfg).unwrap();
    acc.push_block(&inc);
    assert_eq!(acc.input_kind(), InputKind::Counts);
    for pt in acc.points(0.683).unwrap() {
        let (avar, n) = naive_avar_int(&x, pt.m as usize, pt.stride as usize, tau0);
        assert_eq!(pt.n, n);
        // Exact integer sums on both sides: only the final scaling rounds (1e-15).
        assert!(
            rel(pt.avar, avar * scale * scale) <= 1e-15,
            "m {}: {} vs {}",
            pt.m,
            pt.avar,
            avar * scale * scale
        );
    }
}

#[test]
fn reports_mid_stream_equal_batch_on_the_prefix() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let x = cumsum(&gaussian(&mut rng, 50_000));
    let (cap, p) = (64, 8);
    let mut acc = OctaveAllan::phase(small_cfg(1.0, cap, p)).unwrap();
    let mut fed = 0;
    for stop in [3, 5, 1000, 4095, 4096, 4097, 12_345, 50_000] {
        acc.push_block(&x[fed..stop]).unwrap();
        fed = stop;
        let pts = acc.points(0.683).unwrap();
        if stop < 3 {
            assert!(pts.is_empty());
            continue;
        }
        check_against_naive(&pts, &x[..stop], 1.0, cap, p, 1.0);
    }
    let empty = OctaveAllan::phase(StreamConfig::default()).unwrap();
    assert!(empty.points(0.683).unwrap().is_empty());
}

// ------------------------------------------------------------------------------
// Chunking invariance, snapshots, reset
// ------------------------------------------------------------------------------

fn bits(points: &[StreamPoint]) -> Vec<[u64; 11]> {
    points
        .iter()
        .map(|p| {
            [
                p.m,
                p.tau_s.to_bits(),
                p.stride,
                p.n,
                p.avar.to_bits(),
                p.dev.to_bits(),
                p.edf.to_bits(),
                p.alpha as u64,
                u64::from(p.alpha_measured),
                p.ci_lo.to_bits(),
                p.ci_hi.to_bits(),
            ]
        })
        .collect()
}

#[test]
fn chunking_invariance_is_bitwise_for_all_inputs() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let n = 150_000;
    let y: Vec<f64> = gaussian(&mut rng, n).iter().map(|v| 3.0 + v).collect();
    let inc: Vec<i64> = (0..n).map(|_| rng.random_range(-3..=4)).collect();
    for cfg in [StreamConfig::default(), small_cfg(0.5, 1 << 6, 1 << 3)] {
        for kind in [InputKind::Phase, InputKind::Freq] {
            let make = || match kind {
                InputKind::Phase => OctaveAllan::phase(cfg.clone()).unwrap(),
                _ => OctaveAllan::freq(cfg.clone()).unwrap(),
            };
            let mut whole = make();
            whole.push_block(&y).unwrap();
            let reference = bits(&whole.points(0.683).unwrap());
            let ids_ref = format!("{:?}", whole.noise_ids());
            for trial in 0..3 {
                let mut acc = make();
                let mut split = ChaCha8Rng::seed_from_u64(100 + trial);
                // Interleave reports: they must not perturb the state.
                let half = n / 2 + trial as usize * 777;
                feed_random_chunks(&mut acc, &y[..half], &mut split);
                let _ = acc.points(0.9).unwrap();
                feed_random_chunks(&mut acc, &y[half..], &mut split);
                assert_eq!(
                    bits(&acc.points(0.683).unwrap()),
                    reference,
                    "{kind:?} trial {trial}"
                );
                assert_eq!(format!("{:?}", acc.noise_ids()), ids_ref);
            }
        }
        let mut whole = OctaveAllan::counts(cfg.clone()).unwrap();
        whole.push_block(&inc);
        let reference = bits(&whole.points(0.683).unwrap());
        let mut acc = OctaveAllan::counts(cfg.clone()).unwrap();
        let mut i = 0;
        while i < n {
            let len = if rng.random_bool(0.5) {
                1
            } else {
                rng.random_range(1..9000)
            }
            .min(n - i);
            acc.push_block(&inc[i..i + len]);
            i += len;
        }
        assert_eq!(bits(&acc.points(0.683).unwrap()), reference, "counts");
    }
}

#[test]
fn clone_snapshots_and_reset() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let y = gaussian(&mut rng, 60_000);
    let cfg = small_cfg(1.0, 1 << 8, 1 << 4);
    let mut acc = OctaveAllan::freq(cfg.clone()).unwrap();
    acc.push_block(&y[..25_000]).unwrap();
    let snapshot = acc.clone();
    acc.push_block(&y[25_000..]).unwrap();
    let mut fresh = OctaveAllan::freq(cfg.clone()).unwrap();
    fresh.push_block(&y[..25_000]).unwrap();
    assert_eq!(
        bits(&snapshot.points(0.683).unwrap()),
        bits(&fresh.points(0.683).unwrap())
    );
    assert_eq!(snapshot.samples(), 25_000);

    acc.reset();
    assert_eq!(acc.samples(), 0);
    assert_eq!(acc.phase_points(), 0);
    assert!(acc.points(0.683).unwrap().is_empty());
    acc.push_block(&y).unwrap();
    let mut fresh = OctaveAllan::freq(cfg).unwrap();
    fresh.push_block(&y).unwrap();
    assert_eq!(
        bits(&acc.points(0.683).unwrap()),
        bits(&fresh.points(0.683).unwrap())
    );
}

// ------------------------------------------------------------------------------
// Memory
// ------------------------------------------------------------------------------

#[test]
fn memory_prediction_is_exact_and_72h_at_10khz_fits_in_8_mb() {
    // The prediction must equal the actual accounting at every stage of a run ...
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for cfg in [small_cfg(1.0, 1 << 6, 1 << 3), StreamConfig::default()] {
        let mut acc = OctaveAllan::freq(cfg.clone()).unwrap();
        assert_eq!(
            acc.memory_bytes(),
            cfg.memory_bytes_after(InputKind::Freq, 0).unwrap()
        );
        let y = gaussian(&mut rng, 1 << 16);
        for _ in 0..12 {
            acc.push_block(&y[..rng.random_range(1..y.len())]).unwrap();
            let predicted = cfg
                .memory_bytes_after(InputKind::Freq, acc.phase_points())
                .unwrap();
            assert_eq!(
                acc.memory_bytes(),
                predicted,
                "after {} points",
                acc.phase_points()
            );
        }
        let mut counts = OctaveAllan::counts(cfg.clone()).unwrap();
        counts.push_block(&vec![3i64; 300_000]);
        assert_eq!(
            counts.memory_bytes(),
            cfg.memory_bytes_after(InputKind::Counts, counts.phase_points())
                .unwrap()
        );
    }
    // ... and stop growing once every strided ring is full (bounded by octave count).
    let cfg = small_cfg(1.0, 1 << 4, 1 << 2);
    // (Octave 62, stride 2^60, holds its 2P + 1 = 9 values from 8 * 2^60 + 1 points on.)
    let grown = cfg
        .memory_bytes_after(InputKind::Freq, (1 << 63) + (1 << 62))
        .unwrap();
    assert!(grown > cfg.memory_bytes_after(InputKind::Freq, 1 << 62).unwrap());
    assert_eq!(
        grown,
        cfg.memory_bytes_after(InputKind::Freq, u64::MAX - 1)
            .unwrap()
    );

    // 72 h at 10 kHz with the defaults: 2.592e9 samples, octaves up to 2^30.
    let cfg = StreamConfig::with_tau0(1e-4);
    let samples = 72 * 3600 * 10_000u64;
    for kind in [InputKind::Freq, InputKind::Counts] {
        let bytes = cfg.memory_bytes_after(kind, samples + 1).unwrap();
        eprintln!("{kind:?}: state after 72 h at 10 kHz = {bytes} bytes");
        assert!(bytes < 8 << 20, "{bytes} bytes");
        // Even an endless stream (every ring of the 62 octaves full) stays below 8 MB.
        let endless = cfg.memory_bytes_after(kind, u64::MAX - 1).unwrap();
        eprintln!("{kind:?}: state for an endless stream = {endless} bytes");
        assert!(endless < 8 << 20, "{endless} bytes");
    }
}

// ------------------------------------------------------------------------------
// EDF: Greenhall limits and Monte Carlo
// ------------------------------------------------------------------------------

// Greenhall & Riley, "Uncertainty of stability variances based on finite
// differences" (PTTI 2003): equations (7)-(10) and tables 2, 3, for d = 2 (Allan)
// and unmodified variances (F = m), written here independently of the engine.

fn gh_sw(t: f64, alpha: i32) -> f64 {
    let u = t.abs();
    match alpha {
        2 => -u,
        1 => {
            if u == 0.0 {
                0.0
            } else {
                t * t * u.ln()
            }
        }
        0 => u * u * u,
        -1 => {
            if u == 0.0 {
                0.0
            } else {
                t.powi(4) * u.ln()
            }
        }
        -2 => u.powi(5),
        _ => panic!("alpha {alpha}"),
    }
}

/// Eq. (8); `f = None` means F = infinity, where sx = sw(t, alpha + 2).
fn gh_sx(t: f64, f: Option<f64>, alpha: i32) -> f64 {
    match f {
        None => gh_sw(t, alpha + 2),
        Some(f) => {
            f * f * (2.0 * gh_sw(t, alpha) - gh_sw(t - 1.0 / f, alpha) - gh_sw(t + 1.0 / f, alpha))
        }
    }
}

/// Eq. (9), d = 2.
fn gh_sz(t: f64, f: Option<f64>, alpha: i32) -> f64 {
    6.0 * gh_sx(t, f, alpha) - 4.0 * gh_sx(t - 1.0, f, alpha) - 4.0 * gh_sx(t + 1.0, f, alpha)
        + gh_sx(t - 2.0, f, alpha)
        + gh_sx(t + 2.0, f, alpha)
}

/// Eq. (10).
fn gh_basic_sum(j: f64, m_terms: f64, s: f64, f: Option<f64>, alpha: i32) -> f64 {
    let mut sum =
        gh_sz(0.0, f, alpha).powi(2) + (1.0 - j / m_terms) * gh_sz(j / s, f, alpha).powi(2);
    let mut k = 1.0;
    while k < j {
        sum += 2.0 * (1.0 - k / m_terms) * gh_sz(k / s, f, alpha).powi(2);
        k += 1.0;
    }
    sum
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum GhCase {
    /// Direct basic sum (J <= J_max) with the tau0-averaged phase model (F = m).
    DirectAveraged,
    /// Direct basic sum with the same phase model as the engine.
    Direct,
    /// Table 2/3 asymptotic or the J_max interpolation.
    Approximation,
}

/// Greenhall's EDF for the Allan variance at averaging factor m on N phase points.
fn greenhall_edf(alpha: i32, m: u64, n_phase: u64, overlapping: bool) -> (f64, GhCase) {
    let d = 2.0;
    let mf = m as f64;
    let s = if overlapping { mf } else { 1.0 };
    let l = 1.0 + mf * d;
    let m_terms = 1.0 + (s * (n_phase as f64 - l) / mf).floor();
    let j = m_terms.min((d + 1.0) * s);
    let j_max = 100.0;
    let r = m_terms / s;
    let table2 = |alpha: i32| match alpha {
        2 => (35.0 / 18.0, 1.0),
        1 => (790.0, 410.0),
        0 => (2.0 / 3.0, 1.0 / 3.0),
        -1 => (0.852, 0.375),
        -2 => (1.079, 0.368),
        _ => unreachable!(),
    };
    let (inv, case) = if alpha <= 0 {
        if j <= j_max {
            let (f, case) = if mf * (d + 1.0) <= j_max {
                (Some(mf), GhCase::DirectAveraged)
            } else {
                (None, GhCase::Direct)
            };
            let v =
                gh_basic_sum(j, m_terms, s, f, alpha) / (gh_sz(0.0, f, alpha).powi(2) * m_terms);
            (v, case)
        } else if r > d + 1.0 {
            let (a0, a1) = table2(alpha);
            ((a0 - a1 / r) / r, GhCase::Approximation)
        } else {
            let mp = j_max / r;
            let v = gh_basic_sum(j_max, j_max, mp, None, alpha)
                / (gh_sz(0.0, None, alpha).powi(2) * j_max);
            (v, GhCase::Approximation)
        }
    } else if alpha == 1 {
        let (b0, b1) = (15.23, 12.0);
        if j <= j_max {
            let v = gh_basic_sum(j, m_terms, s, Some(mf), 1)
                / (gh_sz(0.0, Some(mf), 1).powi(2) * m_terms);
            (v, GhCase::Direct)
        } else if r > d + 1.0 {
            let (a0, a1) = table2(1);
            (
                (a0 - a1 / r) / ((b0 + b1 * mf.ln()).powi(2) * r),
                GhCase::Approximation,
            )
        } else {
            let mp = j_max / r;
            let v =
                gh_basic_sum(j_max, j_max, mp, Some(mp), 1) / ((b0 + b1 * mf.ln()).powi(2) * j_max);
            (v, GhCase::Approximation)
        }
    } else {
        assert!(
            r.ceil() > d,
            "Greenhall case 4 with K <= d is not implemented here"
        );
        let (a0, a1) = table2(2);
        ((a0 - a1 / r) / m_terms, GhCase::Direct)
    };
    (1.0 / inv, case)
}

/// Tolerance for engine vs Greenhall where both use the same phase model.
fn gh_tolerance(alpha: i32, case: GhCase) -> f64 {
    match (alpha, case) {
        // Identical closed form / identical finite sums.
        (2, _) | (0 | -2, GhCase::Direct) => 1e-12,
        // Tables 2 are 3-4 digit fits of the same sums.
        (0 | -2, _) => 2e-3,
        // Greenhall truncates the FFM lag sum at 3 tau (the engine adds the t^-2 tail:
        // 0.37-0.46 % lower EDF), plus the table fit where applicable.
        (-1, _) => 1e-2,
        // FPM: tail beyond 3 tau is O(1e-4) of the sum; tables 2/3 are ~1 % fits and
        // the J_max interpolation (r <= 3) about 2 %.
        (1, GhCase::Direct) => 1e-3,
        (1, _) => 3e-2,
        _ => unreachable!(),
    }
}

const GH_GRID: [(u64, u64); 12] = [
    (1, 50),
    (2, 90),
    (4, 1000),
    (16, 1000),
    (40, 120),
    (64, 150),
    (64, 100_000),
    (128, 5_000),
    (256, 1000),
    (1024, 5000),
    (1024, 1_000_000),
    (4096, 100_000),
];

#[test]
fn edf_at_stride_one_is_greenhalls_oadev_edf() {
    let mut compared = 0;
    for alpha in [2, 1, 0, -1, -2] {
        for (m, n_phase) in GH_GRID {
            if alpha == 2 && ((n_phase - 2 * m) as f64 / m as f64).ceil() <= 2.0 {
                continue; // Greenhall's case 4 needs r > 2
            }
            let (gh, case) = greenhall_edf(alpha, m, n_phase, true);
            let ours = edf_strided(alpha, m, 1, n_phase - 2 * m).unwrap();
            if case == GhCase::DirectAveraged {
                continue; // different phase model, see the Monte-Carlo test below
            }
            let tol = gh_tolerance(alpha, case);
            assert!(
                rel(ours, gh) <= tol,
                "alpha {alpha} m {m} N {n_phase} ({case:?}): {ours} vs Greenhall {gh}"
            );
            compared += 1;
        }
    }
    assert!(compared >= 45, "{compared}");
}

#[test]
fn edf_at_stride_m_is_greenhalls_adev_edf() {
    let mut compared = 0;
    for alpha in [2, 1, 0, -1, -2] {
        for (m, n_phase) in GH_GRID {
            let terms = (n_phase - 1 - 2 * m) / m + 1;
            if alpha == 2 && (terms as f64).ceil() <= 2.0 {
                continue;
            }
            let (gh, case) = greenhall_edf(alpha, m, n_phase, false);
            if case == GhCase::DirectAveraged {
                continue;
            }
            let ours = edf_strided(alpha, m, m, terms).unwrap();
            let tol = gh_tolerance(alpha, case);
            assert!(
                rel(ours, gh) <= tol,
                "alpha {alpha} m {m} N {n_phase} ({case:?}): {ours} vs Greenhall {gh}"
            );
            compared += 1;
        }
    }
    assert!(compared >= 45, "{compared}");
}

/// Monte-Carlo EDF of the strided estimator: returns (empirical EDF, its standard error).
/// `phase` makes one realisation of N phase points; E[V] is estimated from the runs too.
fn monte_carlo_edf(
    runs: usize,
    m: usize,
    s: usize,
    mut phase: impl FnMut() -> Vec<f64>,
) -> (f64, f64, u64) {
    let mut vs = Vec::with_capacity(runs);
    let mut n_terms = 0;
    for _ in 0..runs {
        let x = phase();
        let (v, n) = naive_avar(&x, m, s, 1.0);
        vs.push(v);
        n_terms = n;
    }
    let r = runs as f64;
    let mean = vs.iter().sum::<f64>() / r;
    let var = vs.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (r - 1.0);
    let m4 = vs.iter().map(|v| (v - mean).powi(4)).sum::<f64>() / r;
    let edf = 2.0 * mean * mean / var;
    // Delta method: se(var)/var = sqrt((m4/var^2 - (r-3)/(r-1)) / r),
    // se(mean^2)/mean^2 = 2 sqrt(var / r) / mean; they are correlated, so add linearly.
    let rel_var = ((m4 / (var * var) - (r - 3.0) / (r - 1.0)) / r).sqrt();
    let rel_mean2 = 2.0 * (var / r).sqrt() / mean;
    (edf, edf * (rel_var + rel_mean2), n_terms)
}

#[test]
fn edf_of_strided_estimator_matches_monte_carlo() {
    // (alpha, m, stride, N, runs, power check). White FM = integrated white frequency
    // (exactly the engine's point-sampled model), white PM = white phase, RW FM =
    // doubly integrated white noise. For RW FM the overlap hardly changes the EDF, so
    // there the alternative estimator's EDF cannot be told apart (no power check).
    let cases: [(i32, usize, usize, usize, usize, bool); 6] = [
        (0, 16, 4, 1024, 20_000, true),
        (0, 64, 16, 2048, 20_000, true),
        (0, 2, 1, 50, 40_000, true),
        (2, 16, 4, 1024, 20_000, true),
        (-2, 16, 4, 1024, 20_000, false),
        (-2, 8, 8, 400, 20_000, false),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for (alpha, m, s, n_phase, runs, power) in cases {
        let (mc, se, n_terms) = monte_carlo_edf(runs, m, s, || match alpha {
            2 => gaussian(&mut rng, n_phase),
            0 => {
                let mut x = vec![0.0];
                x.extend(cumsum(&gaussian(&mut rng, n_phase - 1)));
                x
            }
            _ => {
                let mut x = vec![0.0];
                x.extend(cumsum(&cumsum(&gaussian(&mut rng, n_phase - 1))));
                x
            }
        });
        let ours = edf_strided(alpha, m as u64, s as u64, n_terms).unwrap();
        eprintln!(
            "alpha {alpha} m {m} s {s} N {n_phase}: EDF {ours:.3}, Monte Carlo {mc:.3} +- {se:.3}"
        );
        // 4.5 standard errors of the simulation.
        assert!(
            (ours - mc).abs() <= 4.5 * se,
            "alpha {alpha} m {m} s {s}: {ours} vs MC {mc} +- {se}"
        );
        // The test has power: the full-overlap EDF on the same length would fail for
        // stride > 1 (and the non-overlapping one for stride 1).
        let other = if s > 1 {
            edf_strided(alpha, m as u64, 1, (n_phase - 2 * m) as u64).unwrap()
        } else {
            edf_strided(
                alpha,
                m as u64,
                m as u64,
                ((n_phase - 1 - 2 * m) / m + 1) as u64,
            )
            .unwrap()
        };
        if power {
            assert!(
                (other - mc).abs() > 4.5 * se,
                "alpha {alpha} m {m}: alternative {other} not rejected"
            );
        }
        if (alpha, m, s) == (0, 2, 1) {
            // Greenhall's tau0-averaged phase model (his choice for 3m <= 100) gives a
            // visibly different EDF for integrated white FM; the point-sampled one fits.
            let (gh, case) = greenhall_edf(0, 2, n_phase as u64, true);
            assert_eq!(case, GhCase::DirectAveraged);
            assert!(
                (gh - mc).abs() > 4.5 * se,
                "Greenhall averaged model {gh} vs MC {mc}"
            );
        }
    }
}

// ------------------------------------------------------------------------------
// Noise identification
// ------------------------------------------------------------------------------

/// Mean-removed lag-1 autocorrelation (two-pass textbook formula).
fn lag1(v: &[f64]) -> f64 {
    let mu = v.iter().sum::<f64>() / v.len() as f64;
    let num: f64 = v.windows(2).map(|w| (w[0] - mu) * (w[1] - mu)).sum();
    let den: f64 = v.iter().map(|a| (a - mu) * (a - mu)).sum();
    num / den
}

fn diff(v: &[f64]) -> Vec<f64> {
    v.windows(2).map(|w| w[1] - w[0]).collect()
}

/// Batch Riley-Greenhall identification on the m-decimated phase, dmin = 1, dmax = 2.
fn batch_noise_id(x: &[f64], m: usize) -> (f64, f64, Option<i32>) {
    let dec: Vec<f64> = x.iter().step_by(m).copied().collect();
    let d1 = diff(&dec);
    let d2 = diff(&d1);
    let (r1, r2) = (lag1(&d1), lag1(&d2));
    if (d1.len() as u64) < MIN_ID_POINTS {
        return (r1, r2, None);
    }
    let delta = |r: f64| r / (1.0 + r);
    let (d, dl) = if delta(r1) < 0.25 {
        (1.0, delta(r1))
    } else {
        (2.0, delta(r2))
    };
    let alpha = (2.0 - 2.0 * d - (2.0 * dl).round()) as i32;
    (r1, r2, Some(alpha.clamp(-2, 2)))
}

#[test]
fn noise_id_equals_batch_lag1_method() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    // White PM at short tau, white FM in the middle, RW FM at long tau.
    let n = 1 << 18;
    let wpm = gaussian(&mut rng, n);
    let wfm = cumsum(&gaussian(&mut rng, n));
    let rw = cumsum(&cumsum(&gaussian(&mut rng, n)));
    let x: Vec<f64> = (0..n)
        .map(|i| 30.0 * wpm[i] + wfm[i] + 1e-3 * rw[i])
        .collect();
    let mut acc = OctaveAllan::phase(small_cfg(1.0, 1 << 8, 1 << 4)).unwrap();
    acc.push_block(&x).unwrap();
    let ids = acc.noise_ids();
    let mut seen = std::collections::BTreeSet::new();
    for (m, id) in &ids {
        if id.points < 4 {
            continue;
        }
        let (r1, r2, alpha) = batch_noise_id(&x, *m as usize);
        // Streaming shifted sums vs two-pass formula: 1e-9 absolute on r1.
        assert!((id.r1_d1 - r1).abs() <= 1e-9, "m {m}: {} vs {r1}", id.r1_d1);
        assert!((id.r1_d2 - r2).abs() <= 1e-9, "m {m}: {} vs {r2}", id.r1_d2);
        assert_eq!(id.alpha, alpha, "m {m}");
        if let Some(a) = alpha {
            seen.insert(a);
        }
    }
    // The mixture exercises several noise types.
    assert!(seen.len() >= 3, "{seen:?}");
    // Reported alphas: own where identified, else the nearest shorter identified octave.
    let pts = acc.points(0.683).unwrap();
    let mut last = None;
    for pt in &pts {
        let own = ids.iter().find(|(m, _)| *m == pt.m).unwrap().1.alpha;
        assert_eq!(pt.alpha_measured, own.is_some());
        if own.is_some() {
            last = own;
        }
        assert_eq!(pt.alpha, own.or(last).unwrap_or(0), "m {}", pt.m);
    }
    assert!(pts.iter().any(|p| !p.alpha_measured));
}

#[test]
fn noise_id_recovers_pure_power_laws() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = 1 << 16;
    for alpha in [2, 1, 0, -1, -2] {
        let x = power_law_phase(alpha, n, &mut rng);
        let mut acc = OctaveAllan::phase(StreamConfig::default()).unwrap();
        acc.push_block(&x).unwrap();
        let mut checked = 0;
        for (m, id) in acc.noise_ids() {
            // With >= 1000 non-overlapping averages the lag-1 delta has a standard error
            // of about 0.07 against a rounding margin of 0.25: every octave must be right
            // - except flicker PM, whose m-decimation folds log2(m) octaves of flicker
            // into the band, so delta drifts from -1/2 towards -1 (white PM) as m grows.
            // AllanTools' autocorr_noise_id on the same kind of data does the same
            // (delta -0.5, -0.6, -0.65, -0.72, -0.76, -0.8 at m = 1 .. 32): inherent to
            // the method; checked for m <= 4 only, and the drift direction is asserted.
            if id.points < 1000 {
                continue;
            }
            if alpha == 1 && m > 4 {
                assert!(id.delta < -0.55 && id.delta > -1.0, "m {m}: {id:?}");
                continue;
            }
            assert_eq!(id.alpha, Some(alpha), "alpha {alpha} m {m}: {id:?}");
            checked += 1;
        }
        assert_eq!(checked, if alpha == 1 { 3 } else { 7 });
    }
}

// ------------------------------------------------------------------------------
// Confidence intervals
// ------------------------------------------------------------------------------

#[test]
fn chi2_interval_matches_closed_form_for_two_dof() {
    // chi2 with 2 dof: quantile(p) = -2 ln(1 - p).
    let (conf, dev) = (0.9, 3.0);
    let (lo, hi) = chi2_dev_interval(dev, 2.0, conf).unwrap();
    let p = 0.05f64;
    let q_lo = -2.0 * (1.0 - p).ln();
    let q_hi = -2.0 * p.ln();
    assert!(rel(lo, dev * (2.0 / q_hi).sqrt()) <= 1e-9, "{lo}");
    assert!(rel(hi, dev * (2.0 / q_lo).sqrt()) <= 1e-9, "{hi}");
    // Large EDF (a long run at m = 1): the interval shrinks like 1/sqrt(2 edf).
    let (lo, hi) = chi2_dev_interval(1.0, 2.6e9, 0.683).unwrap();
    let half = 1.0 / (2.0 * 2.6e9f64).sqrt();
    assert!(
        rel(1.0 - lo, half) < 1e-3 && rel(hi - 1.0, half) < 1e-3,
        "{lo} {hi}"
    );
    assert!(matches!(
        chi2_dev_interval(1.0, 3.0, 1.0),
        Err(StreamError::Confidence { .. })
    ));
}

#[test]
fn confidence_intervals_cover_the_true_white_fm_deviation() {
    // 1000 white-FM runs (sigma_y = 1, tau0 = 1: true AVAR = 1/m). 68.3 % intervals must
    // cover the truth in 0.683 +- 0.06 of the runs (4 binomial standard errors), at a
    // full-overlap octave and at two strided ones (cap = 16, P = 4).
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let runs = 1000;
    let octaves = [4u64, 64, 512];
    let mut covered = [0usize; 3];
    let cfg = small_cfg(1.0, 16, 4);
    for _ in 0..runs {
        let y = gaussian(&mut rng, 4096);
        let mut acc = OctaveAllan::freq(cfg.clone()).unwrap();
        acc.push_block(&y).unwrap();
        let pts = acc.points(0.683).unwrap();
        for (k, &m) in octaves.iter().enumerate() {
            let pt = pts.iter().find(|p| p.m == m).unwrap();
            let truth = 1.0 / (m as f64).sqrt();
            if pt.ci_lo <= truth && truth <= pt.ci_hi {
                covered[k] += 1;
            }
            assert!(pt.ci_lo < pt.dev && pt.dev < pt.ci_hi);
        }
    }
    for (k, &m) in octaves.iter().enumerate() {
        let frac = covered[k] as f64 / runs as f64;
        eprintln!("m {m}: coverage {frac}");
        assert!((frac - 0.683).abs() <= 0.06, "m {m}: coverage {frac}");
    }
}

// ------------------------------------------------------------------------------
// Bad input
// ------------------------------------------------------------------------------

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut acc = OctaveAllan::freq(StreamConfig::default()).unwrap();
    let err = acc.push_block(&[1.0, 2.0, f64::NAN, 4.0]).unwrap_err();
    assert!(
        matches!(err, StreamError::NonFinite { index: 2, .. }),
        "{err}"
    );
    assert_eq!(acc.samples(), 2);
    let err = acc.push(f64::INFINITY).unwrap_err();
    assert!(
        matches!(err, StreamError::NonFinite { index: 2, .. }),
        "{err}"
    );
    // a block cut short by a bad sample leaves the accumulator as if fed
    // the samples before it: what follows gives the same bits
    let y: Vec<f64> = (0..9000)
        .map(|k| ((k * 7919) % 1013) as f64 * 1e-3)
        .collect();
    let mut cut = OctaveAllan::freq(StreamConfig::default()).unwrap();
    let mut bad = y[..5000].to_vec();
    bad[3001] = f64::INFINITY;
    let err = cut.push_block(&bad).unwrap_err();
    assert!(
        matches!(err, StreamError::NonFinite { index: 3001, .. }),
        "{err}"
    );
    cut.push_block(&y[3001..]).unwrap();
    let mut whole = OctaveAllan::freq(StreamConfig::default()).unwrap();
    whole.push_block(&y).unwrap();
    let (a, b) = (cut.points(0.683).unwrap(), whole.points(0.683).unwrap());
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(p.avar.to_bits(), q.avar.to_bits(), "m {}", p.m);
    }
    let mut ph = OctaveAllan::phase(StreamConfig::default()).unwrap();
    assert!(ph.push_block(&[f64::NEG_INFINITY]).is_err());
    assert_eq!(ph.samples(), 0);

    for cfg in [
        StreamConfig {
            tau0_s: 0.0,
            ..StreamConfig::default()
        },
        StreamConfig {
            tau0_s: f64::NAN,
            ..StreamConfig::default()
        },
        StreamConfig {
            full_overlap_cap: 3,
            ..StreamConfig::default()
        },
        StreamConfig {
            full_overlap_cap: 1 << 25,
            ..StreamConfig::default()
        },
        StreamConfig {
            strided_terms_per_tau: 1 << 17,
            ..StreamConfig::default()
        },
        StreamConfig {
            max_octave: 63,
            ..StreamConfig::default()
        },
        StreamConfig {
            scale: 0.0,
            ..StreamConfig::default()
        },
    ] {
        let err = OctaveAllan::phase(cfg.clone()).unwrap_err();
        assert!(matches!(err, StreamError::Config { .. }), "{cfg:?}: {err}");
    }
    assert!(matches!(
        acc.points(0.0),
        Err(StreamError::Confidence { .. })
    ));
    assert!(matches!(
        acc.points(f64::NAN),
        Err(StreamError::Confidence { .. })
    ));

    // The configuration deserialises with defaults and rejects unknown keys.
    let cfg: StreamConfig = toml::from_str("tau0_s = 0.0001").unwrap();
    assert_eq!(cfg, StreamConfig::with_tau0(1e-4));
    assert!(toml::from_str::<StreamConfig>("tau0 = 1.0").is_err());
}

#[test]
fn constant_input_gives_zero_deviation_and_no_nan() {
    // Constant counts rate: every second difference is 0, r1 is undefined (0/0).
    let mut acc = OctaveAllan::counts(small_cfg(1.0, 16, 4)).unwrap();
    acc.push_block(&vec![7i64; 10_000]);
    let pts = acc.points(0.95).unwrap();
    assert_eq!(pts.len(), 13); // 10 001 phase points: m = 1 .. 4096
    for pt in &pts {
        assert_eq!(pt.avar, 0.0);
        assert_eq!((pt.ci_lo, pt.ci_hi), (0.0, 0.0));
        assert!(pt.edf.is_finite() && pt.edf >= 1.0, "{pt:?}");
        assert!(!pt.alpha_measured);
        assert_eq!(pt.alpha, 0);
    }
    let json = serde_json::to_string(&pts).unwrap();
    assert!(!json.contains("null") && !json.contains("NaN"), "{json}");
}

#[test]
fn max_octave_limits_the_report() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let x = cumsum(&gaussian(&mut rng, 20_000));
    let cfg = StreamConfig {
        max_octave: 5,
        ..StreamConfig::default()
    };
    let mut acc = OctaveAllan::phase(cfg).unwrap();
    acc.push_block(&x).unwrap();
    let pts = acc.points(0.683).unwrap();
    assert_eq!(
        pts.iter().map(|p| p.m).collect::<Vec<_>>(),
        vec![1, 2, 4, 8, 16, 32]
    );
    for pt in &pts {
        let (avar, n) = naive_avar(&x, pt.m as usize, 1, 1.0);
        assert_eq!((pt.stride, pt.n), (1, n));
        assert!(rel(pt.avar, avar) <= 1e-12, "m {}", pt.m);
    }
}
