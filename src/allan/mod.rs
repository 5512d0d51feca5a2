//! Allan statistics: batch estimators (OADEV, ADEV, MDEV, HDEV, OHDEV, TOTDEV)
//! with equivalent degrees of freedom and chi-square confidence intervals, and
//! the streaming octave-spaced accumulators used by the daemon.
//!
//! Role in the whole: `input::plain` (or the daemon) delivers samples; this
//! module turns them into a [`Phase`] series (integrated angle, or time error
//! for clocks) and computes deviations at averaging factors `m` (tau = m *
//! tau0). The results ([`AllanResult`]) feed `model` (noise-term estimation)
//! and the `sagnac allan` command's JSON output.
//!
//! * [`batch`]: whole-series estimators, tau sets, the [`compute`] entry point.
//! * [`edf`]: Greenhall-Riley EDF, total-deviation EDF, chi-square intervals.
//! * [`noise_id`]: power-law noise identification (lag-1 ACF, B1 / R(n)).
//! * [`streaming`]: `OctaveAllan`, octave-spaced accumulators with bounded
//!   memory, equal to the batch OADEV up to a full-overlap cap, strided beyond.
//!
//! The definitions follow NIST SP 1065 and IEEE Std 952 and are checked
//! against Stable32 result files and AllanTools (see `tests/numerics/allan_*.rs`).
//!
//! Conventions: `alpha` is the exponent of the fractional-frequency (rate) PSD,
//! `S_y(f) ~ f^alpha`: 2 white PM (quantization noise), 1 flicker PM, 0 white
//! FM (angle random walk), -1 flicker FM (bias instability), -2 random-walk FM
//! (rate random walk). `n_phase` is the number of phase points `N`.

pub mod batch;
pub mod edf;
pub mod noise_id;
pub mod streaming;
pub mod sums;

pub use batch::{AllanOptions, all_tau_progression, compute, compute_at, max_m, tau_ms};
pub use edf::{chi2_interval, edf_for_stat, edf_greenhall, edf_simple, edf_totdev};
pub use noise_id::{
    Lag1, NoiseId, NoiseIdMethod, noise_id, noise_id_b1_rn, noise_id_lag1, noise_id_lag1_series,
};
pub use sums::deviation;

use serde::{Deserialize, Serialize};

/// Stable32's default confidence factor for the Min/Max Sigma columns.
pub const DEFAULT_CONFIDENCE: f64 = 0.683;

/// The statistic to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stat {
    /// Non-overlapping Allan deviation (SP 1065 eq. 7).
    Adev,
    /// Overlapping Allan deviation (IEEE 952; SP 1065 eq. 11).
    Oadev,
    /// Modified Allan deviation (SP 1065 eq. 14).
    Mdev,
    /// Non-overlapping Hadamard deviation (SP 1065 eq. 18).
    Hdev,
    /// Overlapping Hadamard deviation (SP 1065 eq. 20).
    Ohdev,
    /// Total deviation with reflected extension (SP 1065 eq. 25), no bias correction.
    Totdev,
}

impl Stat {
    /// Lower-case name, as in the JSON contract and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Stat::Adev => "adev",
            Stat::Oadev => "oadev",
            Stat::Mdev => "mdev",
            Stat::Hdev => "hdev",
            Stat::Ohdev => "ohdev",
            Stat::Totdev => "totdev",
        }
    }

    /// Order of the phase difference the estimator is built on (2 Allan, 3 Hadamard).
    pub fn difference_order(self) -> u32 {
        match self {
            Stat::Hdev | Stat::Ohdev => 3,
            _ => 2,
        }
    }

    /// Stable32's "stop ratio": the largest averaging factor used is the
    /// largest `m` with `m * ratio < N - 1` (N phase points). Checked against
    /// the AF columns of the Stable32 files.
    pub fn stop_ratio(self) -> u64 {
        match self {
            Stat::Adev | Stat::Hdev => 5,
            Stat::Oadev | Stat::Mdev | Stat::Ohdev => 4,
            Stat::Totdev => 2,
        }
    }

    /// Most negative noise exponent alpha the EDF model accepts (alpha + 2d > 1).
    pub fn min_alpha(self) -> i32 {
        match self {
            Stat::Hdev | Stat::Ohdev => -4,
            _ => -2,
        }
    }

    /// Number of terms `n` of the estimator for `n_phase` points at factor `m`
    /// (the Stable32 `#` column), or `None` when `m` is too large for one term.
    pub fn n_terms(self, n_phase: u64, m: u64) -> Option<u64> {
        if m == 0 || n_phase == 0 {
            return None;
        }
        let n = n_phase;
        let terms = match self {
            // len(x[2m::m]) and len(x[3m::m])
            Stat::Adev => ((n - 1) / m).checked_sub(1)?,
            Stat::Hdev => ((n - 1) / m).checked_sub(2)?,
            Stat::Oadev => n.checked_sub(2 * m)?,
            Stat::Mdev => (n + 1).checked_sub(3 * m)?,
            Stat::Ohdev => n.checked_sub(3 * m)?,
            Stat::Totdev => {
                if m >= n || n < 3 {
                    return None;
                }
                n - 2
            }
        };
        (terms >= 1).then_some(terms)
    }
}

impl std::fmt::Display for Stat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Which averaging factors to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TauSet {
    /// m = 1, 2, 4, 8, ...
    Octave,
    /// m = 1, 2, 4, 10, 20, 40, 100, ... (the Stable32 / AllanTools "decade" set).
    Decade,
    /// Every m up to [`ALL_TAU_DENSE`], then Stable32's "all tau" progression
    /// `m += 1 + m / ALL_TAU_DENSE` (about 1 % steps), so large files stay tractable.
    All,
}

/// Below this averaging factor `TauSet::All` lists every m; above it the step
/// grows as `1 + m / ALL_TAU_DENSE` (Stable32 uses the same rule with 35..71).
pub const ALL_TAU_DENSE: u64 = 100;

/// How the input samples relate to phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DataKind {
    /// Phase / angle / time-error samples x(t).
    Phase,
    /// Frequency / rate samples y(t), integrated to phase the AllanTools way.
    Freq,
    /// Integer pulse-count increments per sample, accumulated exactly in i64.
    Counts,
}

/// A phase series. Integer pulse counts stay exact: their differences are
/// computed in `i64` and only the (small) differences are converted to `f64`.
#[derive(Debug, Clone, PartialEq)]
pub enum Phase {
    /// Real-valued phase.
    F64(Vec<f64>),
    /// Cumulative integer counts (phase in pulses).
    Counts(Vec<i64>),
}

impl Phase {
    /// Number of phase points N.
    pub fn len(&self) -> usize {
        match self {
            Phase::F64(v) => v.len(),
            Phase::Counts(v) => v.len(),
        }
    }

    /// True when there are no phase points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Phase point `i` as `f64`.
    pub fn get_f64(&self, i: usize) -> f64 {
        match self {
            Phase::F64(v) => v[i],
            Phase::Counts(v) => v[i] as f64,
        }
    }

    /// Build a phase series from raw samples of the given kind.
    ///
    /// * `Phase`: taken as is (must be finite).
    /// * `Freq`: [`freq_to_phase`] (N samples give N+1 phase points).
    /// * `Counts`: [`counts_to_phase`] (N increments give N+1 points, exact).
    pub fn from_samples(samples: &[f64], kind: DataKind, tau0_s: f64) -> Result<Phase, AllanError> {
        Phase::from_vec(samples.to_vec(), kind, tau0_s)
    }

    /// As [`Phase::from_samples`], taking ownership: phase samples are moved
    /// and frequency samples integrated in place (no second copy of a large file).
    pub fn from_vec(
        mut samples: Vec<f64>,
        kind: DataKind,
        tau0_s: f64,
    ) -> Result<Phase, AllanError> {
        if samples.is_empty() {
            return Err(AllanError::TooFewPoints {
                n_phase: 0,
                need: 3,
            });
        }
        if let Some(i) = samples.iter().position(|v| !v.is_finite()) {
            return Err(AllanError::NonFinite {
                index: i as u64,
                value: samples[i],
            });
        }
        check_tau0(tau0_s)?;
        Ok(match kind {
            DataKind::Phase => Phase::F64(samples),
            DataKind::Freq => {
                let mean = mean_f64(&samples);
                let mut acc = 0.0_f64;
                for v in samples.iter_mut() {
                    acc += *v - mean;
                    *v = acc * tau0_s;
                }
                samples.insert(0, 0.0);
                Phase::F64(samples)
            }
            DataKind::Counts => Phase::Counts(counts_to_phase(&samples)?),
        })
    }
}

/// Shortest sample period accepted, s (1 ps: far below any gyro's, and
/// `1 / tau0^2` stays finite).
pub const TAU0_MIN_S: f64 = 1e-12;
/// Longest sample period accepted, s (about 32 years).
pub const TAU0_MAX_S: f64 = 1e9;

/// Reject tau0 outside [`TAU0_MIN_S`, `TAU0_MAX_S`] (NaN included).
pub fn check_tau0(tau0_s: f64) -> Result<(), AllanError> {
    if (TAU0_MIN_S..=TAU0_MAX_S).contains(&tau0_s) {
        Ok(())
    } else {
        Err(AllanError::BadTau0 { tau0_s })
    }
}

/// Integrate frequency (rate) samples to phase the AllanTools way: subtract
/// the mean, cumulative sum times `tau0_s`, and a leading 0, so N samples give
/// N + 1 phase points. (The mean removal keeps digits when the rate sits on a
/// large offset; Allan statistics do not see a constant rate.)
pub fn freq_to_phase(y: &[f64], tau0_s: f64) -> Vec<f64> {
    let mean = mean_f64(y);
    let mut out = Vec::with_capacity(y.len() + 1);
    out.push(0.0);
    let mut acc = 0.0_f64;
    for &v in y {
        acc += v - mean;
        out.push(acc * tau0_s);
    }
    out
}

/// Accumulate integer pulse-count increments into an exact `i64` phase series
/// with a leading 0 (N increments give N + 1 points). Fails when a value is
/// not an integer or does not fit.
pub fn counts_to_phase(increments: &[f64]) -> Result<Vec<i64>, AllanError> {
    const LIMIT: f64 = 9_007_199_254_740_992.0; // 2^53: exactly representable integers
    let mut out = Vec::with_capacity(increments.len() + 1);
    out.push(0_i64);
    let mut acc: i64 = 0;
    for (i, &v) in increments.iter().enumerate() {
        if !(v.is_finite() && v.fract() == 0.0 && v.abs() <= LIMIT) {
            return Err(AllanError::NotInteger {
                index: i as u64,
                value: v,
            });
        }
        acc = acc
            .checked_add(v as i64)
            .ok_or(AllanError::CountOverflow { index: i as u64 })?;
        out.push(acc);
    }
    Ok(out)
}

/// Mean with Neumaier-compensated summation (exact enough for 1e7+ samples).
pub(crate) fn mean_f64(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut sum = 0.0_f64;
    let mut comp = 0.0_f64;
    for &x in v {
        let t = sum + x;
        if sum.abs() >= x.abs() {
            comp += (sum - t) + x;
        } else {
            comp += (x - t) + sum;
        }
        sum = t;
    }
    (sum + comp) / v.len() as f64
}

/// One row of a result: the Stable32 columns plus the EDF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AllanPoint {
    /// Averaging time m * tau0, seconds.
    pub tau_s: f64,
    /// Averaging factor.
    pub m: u64,
    /// Number of terms in the estimator (Stable32 `#`).
    pub n: u64,
    /// The deviation (units of phase / s; e.g. pulses/s, or fractional frequency).
    pub dev: f64,
    /// Lower confidence bound on `dev`.
    pub ci_lo: f64,
    /// Upper confidence bound on `dev`.
    pub ci_hi: f64,
    /// Equivalent degrees of freedom used for the interval.
    pub edf: f64,
    /// Noise exponent alpha used for the EDF.
    pub alpha: i32,
}

/// A deviation curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AllanResult {
    /// The statistic.
    pub stat: Stat,
    /// Sample interval, seconds.
    pub tau0_s: f64,
    /// One point per averaging factor, increasing m.
    pub points: Vec<AllanPoint>,
}

/// Errors of the Allan module.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AllanError {
    #[error("tau0 must be a number of seconds in [1e-12, 1e9] (got {tau0_s})")]
    BadTau0 { tau0_s: f64 },
    #[error("{n_phase} phase points are too few (need at least {need})")]
    TooFewPoints { n_phase: u64, need: u64 },
    #[error("averaging factor m = {m} is too large for {stat} on {n_phase} phase points")]
    TauTooLarge { stat: Stat, m: u64, n_phase: u64 },
    #[error("sample {index} is not finite ({value})")]
    NonFinite { index: u64, value: f64 },
    #[error("sample {index} ({value}) is not an integer pulse count within +-2^53")]
    NotInteger { index: u64, value: f64 },
    #[error("cumulative pulse count overflows i64 at sample {index}")]
    CountOverflow { index: u64 },
    #[error("confidence level must be in (0, 1) (got {confidence})")]
    BadConfidence { confidence: f64 },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn freq_to_phase_matches_hand_integration() {
        // mean 2.5; deviations -1.5, -0.5, 0.5, 1.5; tau0 = 2 s
        let y = [1.0, 2.0, 3.0, 4.0];
        let x = freq_to_phase(&y, 2.0);
        assert_eq!(
            Phase::from_samples(&y, DataKind::Freq, 2.0).unwrap(),
            Phase::F64(x.clone())
        ); // same arithmetic
        let want = [0.0, -3.0, -4.0, -3.0, 0.0];
        assert_eq!(x.len(), 5);
        for (a, b) in x.iter().zip(want) {
            assert!((a - b).abs() <= 1e-12, "{a} vs {b}"); // exact arithmetic here
        }
    }

    #[test]
    fn freq_to_phase_removes_large_offset() {
        // a 1e7 offset must not eat the 1e-3 fluctuation's digits
        let y: Vec<f64> = (0..1000)
            .map(|i| 1e7 + if i % 2 == 0 { 1e-3 } else { -1e-3 })
            .collect();
        let x = freq_to_phase(&y, 1.0);
        // inputs are only representable to ulp(1e7) = 1.9e-9, i.e. 2e-6 of the fluctuation
        assert!(
            x.iter().all(|v| v.abs() <= 1.00001e-3),
            "phase stays within one step"
        );
        assert!((x[1] - 1e-3).abs() < 1e-8); // 1e-5 relative
    }

    #[test]
    fn counts_accumulate_exactly_and_reject_fractions() {
        let c = counts_to_phase(&[3.0, -1.0, 4.0, 0.0]).unwrap();
        assert_eq!(c, vec![0, 3, 2, 6, 6]);
        let big = counts_to_phase(&[4.0e15, 4.0e15, 1.0]).unwrap();
        assert_eq!(big[3], 8_000_000_000_000_001); // beyond f64's integer precision
        assert!(matches!(
            counts_to_phase(&[1.0, 0.5]),
            Err(AllanError::NotInteger { index: 1, .. })
        ));
    }

    #[test]
    fn n_terms_follow_sp1065_counts() {
        let n = 1001;
        assert_eq!(Stat::Adev.n_terms(n, 1), Some(999));
        assert_eq!(Stat::Adev.n_terms(n, 128), Some(6)); // phase_dat_adev_octave
        assert_eq!(Stat::Oadev.n_terms(n, 128), Some(745));
        assert_eq!(Stat::Mdev.n_terms(n, 128), Some(618));
        assert_eq!(Stat::Hdev.n_terms(n, 128), Some(5));
        assert_eq!(Stat::Ohdev.n_terms(n, 128), Some(617));
        assert_eq!(Stat::Totdev.n_terms(n, 256), Some(999));
        assert_eq!(Stat::Oadev.n_terms(n, 501), None);
        assert_eq!(Stat::Totdev.n_terms(n, 1001), None);
    }

    #[test]
    fn phase_from_samples_validates() {
        for bad in [0.0, -1.0, 1e-320, 1e-13, 2e9, f64::NAN, f64::INFINITY] {
            assert!(
                matches!(
                    Phase::from_samples(&[1.0, 2.0], DataKind::Phase, bad),
                    Err(AllanError::BadTau0 { .. })
                ),
                "tau0 {bad}"
            );
        }
        assert!(check_tau0(1e-12).is_ok() && check_tau0(1e9).is_ok());
        assert!(matches!(
            Phase::from_samples(&[1.0, f64::NAN], DataKind::Phase, 1.0),
            Err(AllanError::NonFinite { index: 1, .. })
        ));
        let p = Phase::from_samples(&[1.0, 2.0, 3.0], DataKind::Counts, 1.0).unwrap();
        assert_eq!(p, Phase::Counts(vec![0, 1, 3, 6]));
    }
}
