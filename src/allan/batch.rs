//! Batch (whole-series) Allan estimators and tau sets.
//!
//! Role in the whole: the reference implementation of every statistic the
//! project reports. `sagnac allan --engine batch` and `model` use it directly;
//! the streaming engine (`allan::streaming`) is checked against it.
//!
//! Each estimator is O(N) per averaging factor and allocation-free: ADEV and
//! OADEV sum squared second differences, MDEV keeps a running sum of second
//! differences updated by one third difference per step (SP 1065 eq. 14
//! without the O(N m) inner loop), HDEV/OHDEV use third differences, TOTDEV
//! reads the reflected extension (SP 1065 eq. 25) through index arithmetic
//! instead of building the 3N-4 array. The inner loops are generic over the
//! phase representation: pulse counts (`i64`) take their differences exactly.

use super::edf::{chi2_interval, edf_for_stat};
use super::noise_id::noise_id;
use super::sums::deviation;
use super::{ALL_TAU_DENSE, AllanError, AllanPoint, AllanResult, Phase, Stat, TauSet, check_tau0};

/// How confidence intervals are formed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanOptions {
    /// Two-sided confidence level (default 0.683, Stable32's).
    pub confidence: f64,
    /// `None`: identify the noise at each tau ([`noise_id`]); `Some(a)`: use alpha `a` everywhere.
    pub alpha: Option<i32>,
}

impl Default for AllanOptions {
    fn default() -> Self {
        AllanOptions {
            confidence: super::DEFAULT_CONFIDENCE,
            alpha: None,
        }
    }
}

/// Largest averaging factor evaluated for `stat` on `n_phase` points: the
/// largest m with `m * stop_ratio < N - 1` (Stable32's limits; 0 if none).
pub fn max_m(stat: Stat, n_phase: u64) -> u64 {
    if n_phase < 2 {
        return 0;
    }
    let lim = n_phase - 1; // m * ratio < lim
    let m = (lim - 1) / stat.stop_ratio();
    // never beyond what the estimator can form
    let mut m = m;
    while m > 0 && stat.n_terms(n_phase, m).is_none() {
        m -= 1;
    }
    m
}

/// The averaging factors of a tau set for `stat` on `n_phase` points.
///
/// * `Octave`: 1, 2, 4, ...; `Decade`: 1, 2, 5, 10, 20, 50, ... (the 1-2-5 sequence of the
///   sagnac CLI contract; Stable32 and AllanTools print 1, 2, 4 x 10^k: use `compute_at`
///   for those exact factors);
/// * `All`: every m up to [`ALL_TAU_DENSE`], then steps of `1 + m / ALL_TAU_DENSE`.
///
/// All stop at [`max_m`].
pub fn tau_ms(set: TauSet, stat: Stat, n_phase: u64) -> Vec<u64> {
    let top = max_m(stat, n_phase);
    let mut out = Vec::new();
    match set {
        TauSet::Octave => {
            let mut m = 1_u64;
            while m <= top {
                out.push(m);
                m *= 2;
            }
        }
        TauSet::Decade => {
            let mut dec = 1_u64;
            'outer: loop {
                for k in [1, 2, 5] {
                    let m = k * dec;
                    if m > top {
                        break 'outer;
                    }
                    out.push(m);
                }
                dec *= 10;
            }
        }
        TauSet::All => out = all_tau_progression(top, ALL_TAU_DENSE),
    }
    out
}

/// Stable32's "all tau" progression: 1, 2, ..., then `m += 1 + m / dense`,
/// up to `top`. (Stable32's files use `dense` 35 to 71.)
pub fn all_tau_progression(top: u64, dense: u64) -> Vec<u64> {
    let mut out = Vec::new();
    let mut m = 1_u64;
    while m <= top {
        out.push(m);
        m += 1 + m / dense.max(1);
    }
    out
}

/// Compute `stat` over a tau set, with confidence intervals.
pub fn compute(
    phase: &Phase,
    stat: Stat,
    tau0_s: f64,
    taus: TauSet,
    opts: &AllanOptions,
) -> Result<AllanResult, AllanError> {
    check_tau0(tau0_s)?;
    let ms = tau_ms(taus, stat, phase.len() as u64);
    if ms.is_empty() {
        return Err(AllanError::TooFewPoints {
            n_phase: phase.len() as u64,
            need: min_points(stat),
        });
    }
    compute_at(phase, stat, tau0_s, &ms, opts)
}

/// Compute `stat` at explicit averaging factors (any m that leaves at least one term).
pub fn compute_at(
    phase: &Phase,
    stat: Stat,
    tau0_s: f64,
    ms: &[u64],
    opts: &AllanOptions,
) -> Result<AllanResult, AllanError> {
    check_tau0(tau0_s)?;
    if !(opts.confidence > 0.0 && opts.confidence < 1.0) {
        return Err(AllanError::BadConfidence {
            confidence: opts.confidence,
        });
    }
    let n_phase = phase.len() as u64;
    if let Some(&m) = ms.iter().find(|&&m| stat.n_terms(n_phase, m).is_none()) {
        return Err(AllanError::TauTooLarge { stat, m, n_phase });
    }
    let point = |m: u64| -> AllanPoint {
        let (dev, n) = deviation(phase, stat, tau0_s, m).expect("m validated above");
        let alpha = match opts.alpha {
            Some(a) => a.clamp(stat.min_alpha(), 2),
            None => noise_id(phase, stat, m).alpha,
        };
        let edf = edf_for_stat(stat, alpha, m, n_phase);
        let (ci_lo, ci_hi) = chi2_interval(dev, edf, opts.confidence);
        AllanPoint {
            tau_s: m as f64 * tau0_s,
            m,
            n,
            dev,
            ci_lo,
            ci_hi,
            edf,
            alpha,
        }
    };
    // Each tau is independent: spread them over the cores for large inputs
    // (results do not depend on the split).
    let threads = if n_phase < 1 << 16 {
        1
    } else {
        std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(ms.len())
            .min(8)
    };
    let points: Vec<AllanPoint> = if threads <= 1 {
        ms.iter().map(|&m| point(m)).collect()
    } else {
        let mut slots: Vec<Option<AllanPoint>> = vec![None; ms.len()];
        std::thread::scope(|sc| {
            let handles: Vec<_> = (0..threads)
                .map(|t| {
                    let point = &point;
                    // interleave so that small and large m mix in every thread
                    sc.spawn(move || {
                        (t..ms.len())
                            .step_by(threads)
                            .map(|i| (i, point(ms[i])))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            for h in handles {
                for (i, p) in h.join().expect("Allan worker thread panicked") {
                    slots[i] = Some(p);
                }
            }
        });
        slots
            .into_iter()
            .map(|p| p.expect("every tau computed"))
            .collect()
    };
    Ok(AllanResult {
        stat,
        tau0_s,
        points,
    })
}

/// Fewest phase points for which `stat` has at least one averaging factor.
pub fn min_points(stat: Stat) -> u64 {
    // smallest N for which max_m(stat, N) >= 1
    (2..64).find(|&n| max_m(stat, n) >= 1).unwrap_or(64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::sums::sum_squares;

    /// Direct O(N m) definitions, for checking the fast loops.
    fn naive(x: &[f64], stat: Stat, m: usize) -> f64 {
        let n = x.len();
        let d2 = |i: usize| x[i + 2 * m] - 2.0 * x[i + m] + x[i];
        let d3 = |i: usize| x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
        match stat {
            Stat::Adev => (0..)
                .map(|k| k * m)
                .take_while(|&i| i + 2 * m < n)
                .map(|i| d2(i).powi(2))
                .sum(),
            Stat::Oadev => (0..n - 2 * m).map(|i| d2(i).powi(2)).sum(),
            Stat::Hdev => (0..)
                .map(|k| k * m)
                .take_while(|&i| i + 3 * m < n)
                .map(|i| d3(i).powi(2))
                .sum(),
            Stat::Ohdev => (0..n - 3 * m).map(|i| d3(i).powi(2)).sum(),
            Stat::Mdev => (0..n + 1 - 3 * m)
                .map(|j| (j..j + m).map(d2).sum::<f64>().powi(2))
                .sum(),
            Stat::Totdev => {
                let mut ext = Vec::new();
                for j in (1..n - 1).rev() {
                    ext.push(2.0 * x[0] - x[j]);
                }
                ext.extend_from_slice(x);
                for j in 1..n - 1 {
                    ext.push(2.0 * x[n - 1] - x[n - 1 - j]);
                }
                let off = n - 2;
                (1..n - 1)
                    .map(|i| (ext[off + i - m] - 2.0 * ext[off + i] + ext[off + i + m]).powi(2))
                    .sum()
            }
        }
    }

    fn series(n: usize) -> Vec<f64> {
        // deterministic, irregular
        let mut s = 12345_u64;
        let mut acc = 0.0;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                acc += ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5;
                acc
            })
            .collect()
    }

    #[test]
    fn fast_loops_equal_naive_definitions() {
        let x = series(203);
        for stat in [
            Stat::Adev,
            Stat::Oadev,
            Stat::Mdev,
            Stat::Hdev,
            Stat::Ohdev,
            Stat::Totdev,
        ] {
            for m in 1..=100 {
                let Some(n) = stat.n_terms(x.len() as u64, m as u64) else {
                    continue;
                };
                let fast = sum_squares(&x, stat, m, n as usize);
                let slow = naive(&x, stat, m);
                assert!(
                    (fast / slow - 1.0).abs() < 1e-11,
                    "{stat} m={m}: {fast} vs {slow}"
                );
            }
        }
    }

    #[test]
    fn counts_path_equals_f64_path() {
        let c: Vec<i64> = series(300)
            .iter()
            .map(|v| (v * 1000.0).round() as i64)
            .collect();
        let f: Vec<f64> = c.iter().map(|&v| v as f64).collect();
        for stat in [
            Stat::Adev,
            Stat::Oadev,
            Stat::Mdev,
            Stat::Hdev,
            Stat::Ohdev,
            Stat::Totdev,
        ] {
            for m in [1_u64, 3, 16, 70] {
                let a = deviation(&Phase::Counts(c.clone()), stat, 0.5, m);
                let b = deviation(&Phase::F64(f.clone()), stat, 0.5, m);
                match (a, b) {
                    (Some((da, na)), Some((db, nb))) => {
                        assert_eq!(na, nb);
                        assert!((da / db - 1.0).abs() < 1e-12, "{stat} m={m}");
                    }
                    (None, None) => {}
                    _ => panic!("{stat} m={m}: validity differs"),
                }
            }
        }
    }

    #[test]
    fn counts_keep_precision_on_a_huge_offset() {
        // cumulative counts near 2^60: f64 phase would lose the unit steps entirely
        let base: i64 = 1 << 60;
        let c: Vec<i64> = (0..1000).map(|i| base + 3 * i + (i % 2)).collect();
        let (dev, _) = deviation(&Phase::Counts(c), Stat::Oadev, 1.0, 1).unwrap();
        // second differences alternate +-2: AVAR = 4/2 = 2
        assert!((dev - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn tau_sets() {
        assert_eq!(
            tau_ms(TauSet::Octave, Stat::Oadev, 1001),
            vec![1, 2, 4, 8, 16, 32, 64, 128]
        );
        assert_eq!(
            tau_ms(TauSet::Octave, Stat::Totdev, 1001),
            vec![1, 2, 4, 8, 16, 32, 64, 128, 256]
        );
        assert_eq!(
            tau_ms(TauSet::Octave, Stat::Adev, 19983).last(),
            Some(&2048)
        ); // ocxo adev_octave
        assert_eq!(
            tau_ms(TauSet::Octave, Stat::Oadev, 19983).last(),
            Some(&4096)
        );
        assert_eq!(
            tau_ms(TauSet::Octave, Stat::Totdev, 19983).last(),
            Some(&8192)
        );
        assert_eq!(
            tau_ms(TauSet::Decade, Stat::Oadev, 556990),
            vec![
                1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000, 100000
            ]
        );
        assert_eq!(
            tau_ms(TauSet::Decade, Stat::Totdev, 556990).last(),
            Some(&200000)
        );
        assert_eq!(
            tau_ms(TauSet::Decade, Stat::Adev, 241218).last(),
            Some(&20000)
        ); // 1-2-5 cut at Stable32's adev stop ratio (its ADEV_decade file ends at 40000 = 4 x 10^4)
        let all = tau_ms(TauSet::All, Stat::Oadev, 1001);
        assert_eq!(&all[..5], &[1, 2, 3, 4, 5]);
        assert_eq!(all.iter().filter(|&&m| m <= 100).count(), 100);
        assert_eq!(all.last(), Some(&248)); // 248 * 4 < 1000
        assert!(all.windows(2).all(|w| w[1] > w[0]));
        // large N stays tractable: about 1 % steps (about 230 per decade) beyond m = 100
        let big = tau_ms(TauSet::All, Stat::Oadev, 10_000_001);
        assert!(big.len() < 1100, "{}", big.len());
        assert!(
            big.windows(2)
                .all(|w| (w[1] - w[0]) as f64 <= 1.0 + w[0] as f64 / 100.0)
        );
        assert!(tau_ms(TauSet::Octave, Stat::Oadev, 5).is_empty());
    }

    #[test]
    fn stable32_all_tau_rule() {
        // ocxo oadev all-tau rows (dense 53), first steps and the end: 4929 is the last AF < 19982/4
        let p = all_tau_progression(max_m(Stat::Oadev, 19983), 53);
        assert_eq!(&p[50..56], &[51, 52, 53, 55, 57, 59]);
        assert_eq!(p.last(), Some(&4929));
        assert_eq!(p.len(), 273);
        // Cs5071A oadev_all: dense 35, 314 rows ending at 138921
        let p = all_tau_progression(max_m(Stat::Oadev, 556990), 35);
        assert_eq!(p.len(), 314);
        assert_eq!(p.last(), Some(&138921));
        let p = all_tau_progression(max_m(Stat::Totdev, 556990), 35);
        assert_eq!((p.len(), p.last()), (338, Some(&273162)));
        let p = all_tau_progression(max_m(Stat::Adev, 556990), 35);
        assert_eq!((p.len(), p.last()), (306, Some(&110887)));
    }

    #[test]
    fn threaded_compute_equals_the_plain_loop() {
        // >= 65536 points takes the multi-threaded path
        let p = Phase::F64(series(70_000));
        let opts = AllanOptions::default();
        for stat in [Stat::Oadev, Stat::Mdev, Stat::Totdev] {
            let r = compute(&p, stat, 0.1, TauSet::Octave, &opts).unwrap();
            let ms = tau_ms(TauSet::Octave, stat, 70_000);
            assert_eq!(r.points.iter().map(|q| q.m).collect::<Vec<_>>(), ms);
            for q in &r.points {
                let (dev, n) = deviation(&p, stat, 0.1, q.m).unwrap();
                let alpha = noise_id(&p, stat, q.m).alpha;
                assert_eq!((q.dev, q.n, q.alpha), (dev, n, alpha), "{stat} m={}", q.m);
                assert_eq!(q.edf, edf_for_stat(stat, alpha, q.m, 70_000));
            }
        }
    }

    #[test]
    fn compute_rejects_bad_arguments() {
        let p = Phase::F64(series(100));
        assert!(matches!(
            compute_at(&p, Stat::Oadev, 1.0, &[60], &AllanOptions::default()),
            Err(AllanError::TauTooLarge { m: 60, .. })
        ));
        assert!(matches!(
            compute(
                &p,
                Stat::Oadev,
                -1.0,
                TauSet::Octave,
                &AllanOptions::default()
            ),
            Err(AllanError::BadTau0 { .. })
        ));
        let bad = AllanOptions {
            confidence: 1.5,
            alpha: None,
        };
        assert!(matches!(
            compute(&p, Stat::Oadev, 1.0, TauSet::Octave, &bad),
            Err(AllanError::BadConfidence { .. })
        ));
        assert!(matches!(
            compute(
                &Phase::F64(vec![1.0, 2.0, 3.0]),
                Stat::Oadev,
                1.0,
                TauSet::Octave,
                &AllanOptions::default()
            ),
            Err(AllanError::TooFewPoints { .. })
        ));
    }
}
