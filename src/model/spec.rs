//! Acceptance testing: does this gyro meet its specification?
//!
//! A spec file (`config/spec_example.toml`) gives an upper limit on some of the
//! IEEE 952 coefficients and the confidence each verdict must have. Each limited
//! coefficient gets a verdict: `pass` (the coefficient is below its limit),
//! `fail` (above it) or `undecided`; the whole spec fails if any coefficient
//! fails, passes if all pass, and is undecided otherwise.
//!
//! # The statistics
//! The estimator ([`super::estimate`]) reports each coefficient with a 95 %
//! *fixed-sample* interval. Checking such an interval again and again on a
//! growing record and stopping at the first decisive look inflates the error
//! rate well beyond 5 % (the "optional stopping" or "peeking" problem). The rule
//! here keeps the probability of a wrong verdict at most `alpha = 1 - confidence`
//! whatever the stopping rule, by **alpha spending over a fixed schedule of
//! looks** (a Bonferroni union bound, valid under any dependence between looks):
//!
//! * Look `k = 0, 1, 2, ...` is at record length `T_k = first_look_s * 2^(k/2)`
//!   (geometric spacing: 60 s, 85 s, 120 s, 170 s, ... with the default). An
//!   update of the estimates counts as look `k` when it is the first one with a
//!   record of at least `T_k` (and `T_k` is the largest length passed); every
//!   other update leaves the verdicts as they are. Skipped looks only lower the
//!   error.
//! * Look `k` spends `alpha_k = alpha / ((k + 1)(k + 2))`; these sum to `alpha`
//!   over all looks (telescoping), so by the union bound the chance that *any*
//!   look gives a wrong verdict is at most `alpha`. Its one-sided quantile is
//!   `z_k = Phi^-1(1 - alpha_k)`: 1.96, 2.39, 2.64, 2.81, 2.94, ... for
//!   `alpha = 0.05`, growing like `sqrt(2 ln k)`, i.e. slowly.
//! * The anytime-valid bounds at look `k` come from the estimator's 95 %
//!   interval: on the log of the coefficient (the scale on which the variance
//!   estimators behind it are close to normal), the distances from the estimate
//!   to the interval's ends divided by `z95 = 1.96` are the standard errors of
//!   each side, `se_hi = (ln hi - ln v) / z95` and `se_lo = (ln v - ln lo) / z95`;
//!   the bounds are `upper = v exp(z_k se_hi)` and `lower = v exp(-z_k se_lo)`.
//!   A lower end at 0 gives a lower bound of 0 (that coefficient cannot fail).
//!   The estimator's intervals are statistical only; its systematic error (a
//!   fraction of a percent on Q in simulation: a few tenths of a standard error
//!   at long records, growing like `sqrt(T)` in those units) would eventually
//!   decide a gyro sitting at its limit, and on N and B the spread of the
//!   estimates about the truth is wider than their intervals say (measured:
//!   docs/acceptance.md). So a relative systematic error is added in quadrature
//!   to both standard errors: `systematic_rel`, by default Q 1 %, N 5 %, B and K
//!   30 % ([`default_systematic_rel`]). No verdict is given closer to the limit
//!   than about `z_k` times that.
//!   The rate ramp is signed: its interval is widened on the linear scale and the
//!   limit applies to its magnitude. A gyro inside the limit can then be failed
//!   from either side (`s > limit + y se` or `s < -limit - y se`), so the lower
//!   bound of the magnitude uses the quantile `y` that solves
//!   `Q(y) + Q(y + 2 limit / se) = alpha_k` ([`magnitude_fail_z`]): `z_k` when
//!   the standard error is small against the limit, the two-sided quantile
//!   when it is large (a short record, where the one-sided `z_k` erred up to
//!   `2 alpha_k` per look). The upper bound, which decides a `pass`, needs only
//!   one side and keeps `z_k`.
//! * A coefficient reported only as a 95 % upper bound `u` (the data do not
//!   resolve the term: value `null`) gets `upper = u (z_k / 1.645) exp(z_k systematic_rel)`, conservative
//!   because every such bound is of the form `a + z b` with `a, b >= 0` (or its
//!   square root); it can pass but never fail, and while it does not pass the
//!   verdict is `undecided` with a `reason` saying so. Nothing is guessed.
//! * Decision: `pass` when the upper bound is below the limit, `fail` when the
//!   lower bound is above it. A decision is final: later looks do not change it.
//!   If the truth is above the limit, a wrong `pass` needs `upper < truth` at
//!   some look, of probability at most `sum alpha_k = alpha`; the same for a
//!   wrong `fail`. The guarantee is per coefficient, as good as the estimator's
//!   intervals are (scripts/bench-acceptance measures it; docs/acceptance.md).
//!
//! `sagnac analyze` looks once at a fixed record ([`Spec::evaluate_fixed`]): a
//! single look needs no spending, `z = Phi^-1(confidence)`. (That is only right
//! for a record whose length was fixed in advance, not one cut when a verdict
//! appeared.)
//!
//! # Time to decision
//! [`SequentialSpec`] also predicts when an undecided coefficient will be
//! decided: the interval's half-width on the log scale is taken to shrink like
//! `c / sqrt(T)` (white-noise-like terms; a bound-only term like `T^(-1/4)`),
//! and the first future look whose widened bound crosses the limit is the
//! prediction. It is a rough guide for the operator, not part of the decision.
//!
//! Plain synchronous numerics, like the rest of [`crate::model`].

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, Normal};

use super::estimate::{Coefficient, NoiseEstimates};

/// Two-sided 95 % normal quantile: the estimator's intervals are 95 % two-sided.
pub const Z95: f64 = 1.959_963_984_540_054;
/// One-sided 95 % normal quantile: the estimator's upper bounds are one-sided 95 %.
pub const Z95_ONE_SIDED: f64 = 1.644_853_626_951_472_2;

/// Default length of the record at the first look, s.
pub const DEFAULT_FIRST_LOOK_S: f64 = 60.0;
/// Default relative systematic error of the estimator per coefficient (see
/// [`Spec::systematic_rel`]), measured by `scripts/bench-acceptance` as the
/// spread of the estimates about the truth beyond their intervals
/// (docs/acceptance.md): Q 1 %, N 5 %, B and K 30 % (B is included only when
/// the record happens to show it, so its first values run high), ramp 0 (a
/// signed slope on a linear scale).
pub fn default_systematic_rel(c: SpecCoefficient) -> f64 {
    match c {
        SpecCoefficient::Quantization => 0.01,
        SpecCoefficient::Arw => 0.05,
        SpecCoefficient::BiasInstability | SpecCoefficient::Rrw => 0.3,
        SpecCoefficient::RateRamp => 0.0,
    }
}

/// Errors reading or validating a spec file.
#[derive(Debug, thiserror::Error)]
pub enum SpecError {
    #[error("cannot read spec file {path}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("spec file {origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("spec file {origin}: `{key}` = {value}: {reason}")]
    Invalid {
        origin: String,
        key: &'static str,
        value: String,
        reason: &'static str,
    },
}

/// The file: one `[spec]` table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    spec: Spec,
}

/// A specification: upper limits on some coefficients, and the confidence of
/// each verdict.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// Quantization noise Q, arcsec.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantization_arcsec_max: Option<f64>,
    /// Angle random walk N, deg/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub arw_dpsh_max: Option<f64>,
    /// Bias instability B, deg/h.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bias_instability_dph_max: Option<f64>,
    /// Rate random walk K, deg/h/sqrt(h).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rrw_dphsh_max: Option<f64>,
    /// Rate ramp R (its magnitude), deg/h/h.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_ramp_dphh_max: Option<f64>,
    /// Guaranteed confidence of each verdict (0.5 to 0.9999).
    pub confidence: f64,
    /// Record length at the first look of a live run, s (looks follow at
    /// `first_look_s * 2^(k/2)`); default 60.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_look_s: Option<f64>,
    /// Relative systematic error of the estimator, added in quadrature to the
    /// standard error on the log scale (the intervals are statistical only), for
    /// every coefficient; absent = the measured per-coefficient defaults
    /// ([`default_systematic_rel`]), 0 = trust the intervals as they are.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub systematic_rel: Option<f64>,
}

/// The coefficients a spec can limit, in the order of [`NoiseEstimates`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SpecCoefficient {
    Quantization,
    Arw,
    BiasInstability,
    Rrw,
    RateRamp,
}

impl SpecCoefficient {
    /// Bias instability, rate random walk and rate ramp: the terms a slow
    /// effect (warm-up, step, temperature) inflates.
    pub fn is_low_frequency(self) -> bool {
        matches!(
            self,
            SpecCoefficient::BiasInstability | SpecCoefficient::Rrw | SpecCoefficient::RateRamp
        )
    }

    pub const ALL: [SpecCoefficient; 5] = [
        SpecCoefficient::Quantization,
        SpecCoefficient::Arw,
        SpecCoefficient::BiasInstability,
        SpecCoefficient::Rrw,
        SpecCoefficient::RateRamp,
    ];

    /// The name (as in the estimates' JSON and the metrics' `coefficient` label).
    pub fn name(self) -> &'static str {
        match self {
            SpecCoefficient::Quantization => "quantization_arcsec",
            SpecCoefficient::Arw => "arw_dpsh",
            SpecCoefficient::BiasInstability => "bias_instability_dph",
            SpecCoefficient::Rrw => "rrw_dphsh",
            SpecCoefficient::RateRamp => "rate_ramp_dphh",
        }
    }

    /// The spec key of its limit.
    pub fn key(self) -> &'static str {
        match self {
            SpecCoefficient::Quantization => "spec.quantization_arcsec_max",
            SpecCoefficient::Arw => "spec.arw_dpsh_max",
            SpecCoefficient::BiasInstability => "spec.bias_instability_dph_max",
            SpecCoefficient::Rrw => "spec.rrw_dphsh_max",
            SpecCoefficient::RateRamp => "spec.rate_ramp_dphh_max",
        }
    }

    /// Its estimate.
    pub fn of(self, e: &NoiseEstimates) -> &Coefficient {
        match self {
            SpecCoefficient::Quantization => &e.quantization_arcsec,
            SpecCoefficient::Arw => &e.arw_dpsh,
            SpecCoefficient::BiasInstability => &e.bias_instability_dph,
            SpecCoefficient::Rrw => &e.rrw_dphsh,
            SpecCoefficient::RateRamp => &e.rate_ramp_dphh,
        }
    }

    /// A signed coefficient (the limit applies to its magnitude, on a linear scale).
    fn signed(self) -> bool {
        self == SpecCoefficient::RateRamp
    }
}

/// A verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Pass,
    Fail,
    Undecided,
}

impl Verdict {
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Undecided => "undecided",
        }
    }
    /// The metric value: 1 pass, 0 undecided, -1 fail.
    pub fn metric(self) -> f64 {
        match self {
            Verdict::Pass => 1.0,
            Verdict::Undecided => 0.0,
            Verdict::Fail => -1.0,
        }
    }
}

/// One coefficient's verdict (JSON: `spec.coefficients.<name>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoefficientVerdict {
    /// The spec's limit.
    pub limit: f64,
    pub verdict: Verdict,
    /// The estimate (`null`: only an upper bound, or nothing yet).
    pub estimate: Option<f64>,
    /// The bound that decides: the upper bound for `pass` and `undecided`, the
    /// lower bound for `fail` (at the verdict's confidence).
    pub bound: Option<f64>,
    /// Lower and upper bounds at the verdict's confidence (the lower one absent
    /// for a term reported only as an upper bound).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lower: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper: Option<f64>,
    /// Why an undecided coefficient is undecided.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Record length when it was decided, s (live runs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub decided_at_s: Option<f64>,
    /// Predicted further record length until a decision, s (live runs, undecided
    /// coefficients with a prediction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eta_s: Option<f64>,
}

/// The verdict of a whole spec (JSON: `spec`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecReport {
    pub verdict: Verdict,
    /// The guaranteed confidence of each verdict.
    pub confidence: f64,
    /// The look the bounds were computed at (live runs; `null`: a single fixed look).
    pub look: Option<u32>,
    /// The normal quantile the bounds were widened to.
    pub z: f64,
    /// Record length of that look, s.
    pub duration_s: f64,
    pub coefficients: BTreeMap<String, CoefficientVerdict>,
}

impl SpecReport {
    /// Whether every coefficient is decided.
    pub fn all_decided(&self) -> bool {
        self.coefficients
            .values()
            .all(|c| c.verdict != Verdict::Undecided)
    }
}

fn invalid(
    origin: &str,
    key: &'static str,
    value: impl ToString,
    reason: &'static str,
) -> SpecError {
    SpecError::Invalid {
        origin: origin.to_string(),
        key,
        value: value.to_string(),
        reason,
    }
}

impl Spec {
    /// Parse and validate spec TOML; `origin` names it in messages.
    pub fn from_toml(text: &str, origin: &str) -> Result<Spec, SpecError> {
        let file: SpecFile = toml::from_str(text).map_err(|e| SpecError::Parse {
            origin: origin.to_string(),
            message: e.to_string(),
        })?;
        file.spec.validate(origin)?;
        Ok(file.spec)
    }

    /// Read, parse and validate a spec file.
    pub fn load(path: &Path) -> Result<Spec, SpecError> {
        let text = std::fs::read_to_string(path).map_err(|source| SpecError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Spec::from_toml(&text, &path.display().to_string())
    }

    /// Check every value; the first problem names its key.
    pub fn validate(&self, origin: &str) -> Result<(), SpecError> {
        for c in SpecCoefficient::ALL {
            if let Some(v) = self.limit(c)
                && !(v.is_finite() && v > 0.0)
            {
                return Err(invalid(origin, c.key(), v, "must be a finite number > 0"));
            }
        }
        if self.limits().next().is_none() {
            return Err(invalid(
                origin,
                "spec",
                "no limit",
                "give at least one of quantization_arcsec_max, arw_dpsh_max, bias_instability_dph_max, \
                 rrw_dphsh_max, rate_ramp_dphh_max",
            ));
        }
        let c = self.confidence;
        if !(c.is_finite() && (0.5..=0.9999).contains(&c)) {
            return Err(invalid(
                origin,
                "spec.confidence",
                c,
                "must be from 0.5 to 0.9999",
            ));
        }
        if let Some(f) = self.first_look_s
            && !(f.is_finite() && f > 0.0)
        {
            return Err(invalid(
                origin,
                "spec.first_look_s",
                f,
                "must be a finite number of seconds > 0",
            ));
        }
        if let Some(r) = self.systematic_rel
            && !(r.is_finite() && (0.0..=0.5).contains(&r))
        {
            return Err(invalid(
                origin,
                "spec.systematic_rel",
                r,
                "must be from 0 to 0.5",
            ));
        }
        Ok(())
    }

    /// The estimator's relative systematic error assumed for `c`.
    pub fn systematic_rel(&self, c: SpecCoefficient) -> f64 {
        self.systematic_rel
            .unwrap_or_else(|| default_systematic_rel(c))
    }

    /// The limit on `c`, if any.
    pub fn limit(&self, c: SpecCoefficient) -> Option<f64> {
        match c {
            SpecCoefficient::Quantization => self.quantization_arcsec_max,
            SpecCoefficient::Arw => self.arw_dpsh_max,
            SpecCoefficient::BiasInstability => self.bias_instability_dph_max,
            SpecCoefficient::Rrw => self.rrw_dphsh_max,
            SpecCoefficient::RateRamp => self.rate_ramp_dphh_max,
        }
    }

    /// The limited coefficients and their limits.
    pub fn limits(&self) -> impl Iterator<Item = (SpecCoefficient, f64)> + '_ {
        SpecCoefficient::ALL
            .into_iter()
            .filter_map(|c| self.limit(c).map(|l| (c, l)))
    }

    /// `1 - confidence`.
    pub fn alpha(&self) -> f64 {
        1.0 - self.confidence
    }

    /// Record length at the first look, s.
    pub fn first_look_s(&self) -> f64 {
        self.first_look_s.unwrap_or(DEFAULT_FIRST_LOOK_S)
    }

    /// One look at a record of fixed length (`sagnac analyze`): `z = Phi^-1(confidence)`.
    pub fn evaluate_fixed(&self, e: &NoiseEstimates, duration_s: f64) -> SpecReport {
        let z = normal_quantile(self.confidence);
        let coefficients = self
            .limits()
            .map(|(c, limit)| {
                (
                    c.name().to_string(),
                    judge(c, c.of(e), limit, z, self.systematic_rel(c)),
                )
            })
            .collect();
        report(self.confidence, None, z, duration_s, coefficients)
    }
}

fn report(
    confidence: f64,
    look: Option<u32>,
    z: f64,
    duration_s: f64,
    coefficients: BTreeMap<String, CoefficientVerdict>,
) -> SpecReport {
    let vs: Vec<Verdict> = coefficients
        .values()
        .map(|c: &CoefficientVerdict| c.verdict)
        .collect();
    let verdict = if vs.contains(&Verdict::Fail) {
        Verdict::Fail
    } else if vs.iter().all(|v| *v == Verdict::Pass) {
        Verdict::Pass
    } else {
        Verdict::Undecided
    };
    SpecReport {
        verdict,
        confidence,
        look,
        z,
        duration_s,
        coefficients,
    }
}

/// `Phi^-1(p)`.
pub fn normal_quantile(p: f64) -> f64 {
    // Normal::new(0, 1) cannot fail
    Normal::new(0.0, 1.0)
        .map(|n| n.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

/// The alpha-spending schedule of a live run (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LookSchedule {
    pub first_look_s: f64,
    pub alpha: f64,
}

impl LookSchedule {
    /// Record length of look `k`, s: `first_look_s * 2^(k/2)`.
    pub fn length_s(&self, k: u32) -> f64 {
        self.first_look_s * 2f64.powf(k as f64 / 2.0)
    }
    /// The largest look whose length a record of `duration_s` has reached.
    pub fn look_at(&self, duration_s: f64) -> Option<u32> {
        if !(duration_s.is_finite() && duration_s >= self.first_look_s) {
            return None;
        }
        let mut k = (2.0 * (duration_s / self.first_look_s).log2())
            .floor()
            .max(0.0) as u32;
        // guard the floating-point edges
        while self.length_s(k) > duration_s && k > 0 {
            k -= 1;
        }
        while self.length_s(k + 1) <= duration_s {
            k += 1;
        }
        Some(k)
    }
    /// The error spent at look `k`: `alpha / ((k + 1)(k + 2))`.
    pub fn alpha_k(&self, k: u32) -> f64 {
        let k = k as f64;
        self.alpha / ((k + 1.0) * (k + 2.0))
    }
    /// The one-sided quantile of look `k`.
    pub fn z(&self, k: u32) -> f64 {
        normal_quantile(1.0 - self.alpha_k(k))
    }
}

/// The side standard errors of a coefficient on its decision scale (log, or
/// linear for a signed one), and its centre there.
#[derive(Debug, Clone, Copy)]
struct Scaled {
    centre: f64,
    se_lo: f64,
    se_hi: f64,
}

fn scaled(c: SpecCoefficient, v: f64, lo: f64, hi: f64, sys: f64) -> Option<Scaled> {
    if c.signed() {
        return (v.is_finite() && lo.is_finite() && hi.is_finite()).then(|| Scaled {
            centre: v,
            se_lo: ((v - lo) / Z95).max(0.0),
            se_hi: ((hi - v) / Z95).max(0.0),
        });
    }
    if !(v.is_finite() && v > 0.0 && hi.is_finite()) {
        return None;
    }
    let centre = v.ln();
    let se_hi = ((hi.max(v)).ln() - centre) / Z95;
    let se_lo = if lo > 0.0 {
        (centre - lo.min(v).ln()) / Z95
    } else {
        f64::INFINITY
    };
    let (se_hi, se_lo) = (se_hi.hypot(sys), se_lo.hypot(sys));
    Some(Scaled {
        centre,
        se_lo,
        se_hi,
    })
}

/// (lower, upper) bounds of the coefficient's magnitude at quantile `z` with the
/// standard errors scaled by `shrink`. For a signed coefficient the lower bound
/// of the magnitude, which decides a `fail`, uses [`magnitude_fail_z`]: both
/// signs can fail a gyro whose truth is inside `[-limit, limit]`.
fn bounds_at(c: SpecCoefficient, s: Scaled, z: f64, shrink: f64, limit: f64) -> (f64, f64) {
    let lo = s.centre - z * s.se_lo * shrink;
    let hi = s.centre + z * s.se_hi * shrink;
    if c.signed() {
        let upper = lo.abs().max(hi.abs());
        let (se_lo, se_hi) = (s.se_lo * shrink, s.se_hi * shrink);
        let lower = if lo > 0.0 {
            (s.centre - magnitude_fail_z(z, se_hi, limit) * se_lo).max(0.0)
        } else if hi < 0.0 {
            (-(s.centre + magnitude_fail_z(z, se_lo, limit) * se_hi)).max(0.0)
        } else {
            0.0
        };
        (lower, upper)
    } else {
        let lower = if lo.is_finite() { lo.exp() } else { 0.0 };
        (lower, hi.exp())
    }
}

/// The quantile that keeps a wrong `fail` of a signed coefficient at the
/// one-sided level `alpha = 1 - Phi(z)` of quantile `z`.
///
/// The verdict is on the magnitude: `fail` when `|s| - y se > limit`. For an
/// estimate `s ~ N(R, se^2)` with `|R| <= limit` that happens on either side,
/// `s > limit + y se` or `s < -limit - y se`, with probability at most (at
/// `|R| = limit`) `Q(y) + Q(y + 2 limit / se)`, `Q` the normal tail. The
/// one-sided `y = z` therefore errs up to `2 alpha` when `se` is large against
/// the limit (a short record: the truth, whatever its sign, is within a
/// fraction of a standard error of both `+limit` and `-limit`). `y` solves
/// `Q(y) + Q(y + 2 limit / se) = alpha`: `z` when `se << limit`, the
/// two-sided `Phi^-1(1 - alpha/2)` when `se >> limit`.
/// `se` is the standard error on the other side (the tail towards `-limit`).
pub fn magnitude_fail_z(z: f64, se: f64, limit: f64) -> f64 {
    let n = Normal::new(0.0, 1.0).expect("standard normal");
    let usable = z.is_finite() && limit > 0.0 && se > 0.0;
    if !usable {
        return z;
    }
    if !se.is_finite() {
        return normal_quantile(1.0 - 0.5 * n.sf(z));
    }
    let alpha = n.sf(z);
    let d = 2.0 * limit / se;
    let excess = |y: f64| n.sf(y) + n.sf(y + d) - alpha;
    // excess(z) >= 0 and excess is decreasing; the root is below the two-sided quantile
    let (mut a, mut b) = (z, normal_quantile(1.0 - 0.5 * alpha).max(z));
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if excess(m) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    b
}

/// The verdict on one coefficient at one look with one-sided quantile `z`.
fn judge(
    c: SpecCoefficient,
    coef: &Coefficient,
    limit: f64,
    z: f64,
    sys: f64,
) -> CoefficientVerdict {
    let undecided = |estimate, lower, upper, reason: String| CoefficientVerdict {
        limit,
        verdict: Verdict::Undecided,
        estimate,
        bound: upper,
        lower,
        upper,
        reason: Some(reason),
        decided_at_s: None,
        eta_s: None,
    };
    match (coef.value, coef.ci95, coef.upper95) {
        (Some(v), Some([lo, hi]), _) => {
            let Some(s) = scaled(c, v, lo, hi, sys) else {
                return undecided(
                    Some(v),
                    None,
                    None,
                    "the estimate's interval is not usable (not finite)".into(),
                );
            };
            let (lower, upper) = bounds_at(c, s, z, 1.0, limit);
            let (verdict, bound) = if upper < limit {
                (Verdict::Pass, upper)
            } else if lower > limit {
                (Verdict::Fail, lower)
            } else {
                return undecided(
                    Some(v),
                    Some(lower),
                    Some(upper),
                    format!(
                        "the interval [{lower:.4e}, {upper:.4e}] at this confidence contains the limit {limit:.4e}: \
                         more data needed"
                    ),
                );
            };
            CoefficientVerdict {
                limit,
                verdict,
                estimate: Some(v),
                bound: Some(bound),
                lower: Some(lower),
                upper: Some(upper),
                reason: None,
                decided_at_s: None,
                eta_s: None,
            }
        }
        (Some(v), None, _) => undecided(Some(v), None, None, "the estimate has no interval".into()),
        (None, _, Some(u)) if u.is_finite() && u >= 0.0 => {
            let upper = u * (z / Z95_ONE_SIDED).max(1.0) * (z * sys).exp();
            if upper < limit {
                CoefficientVerdict {
                    limit,
                    verdict: Verdict::Pass,
                    estimate: None,
                    bound: Some(upper),
                    lower: None,
                    upper: Some(upper),
                    reason: None,
                    decided_at_s: None,
                    eta_s: None,
                }
            } else {
                undecided(
                    None,
                    None,
                    Some(upper),
                    format!(
                        "the record does not resolve this term (no estimate, only an upper bound of {upper:.4e} \
                         at this confidence, above the limit {limit:.4e}): a longer record is needed"
                    ),
                )
            }
        }
        _ => undecided(
            None,
            None,
            None,
            "no estimate yet (too short a record)".into(),
        ),
    }
}

/// The verdicts of a live run, look by look (see the module docs).
#[derive(Debug, Clone)]
pub struct SequentialSpec {
    spec: Spec,
    schedule: LookSchedule,
    /// The last look evaluated.
    last_look: Option<u32>,
    /// The current report (`None` before the first look).
    report: Option<SpecReport>,
}

/// What one update did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Observed {
    /// The update was a look (the verdicts were re-evaluated).
    pub looked: bool,
    /// Some verdict changed.
    pub changed: bool,
}

impl SequentialSpec {
    pub fn new(spec: Spec) -> Self {
        let schedule = LookSchedule {
            first_look_s: spec.first_look_s(),
            alpha: spec.alpha(),
        };
        SequentialSpec {
            spec,
            schedule,
            last_look: None,
            report: None,
        }
    }

    pub fn spec(&self) -> &Spec {
        &self.spec
    }

    pub fn schedule(&self) -> LookSchedule {
        self.schedule
    }

    /// The current verdicts: before the first look every coefficient is
    /// undecided (reason: the first look is at `first_look_s`).
    pub fn report(&self) -> SpecReport {
        match &self.report {
            Some(r) => r.clone(),
            None => {
                let first = self.schedule.first_look_s;
                let coefficients = self
                    .spec
                    .limits()
                    .map(|(c, limit)| {
                        (
                            c.name().to_string(),
                            CoefficientVerdict {
                                limit,
                                verdict: Verdict::Undecided,
                                estimate: None,
                                bound: None,
                                lower: None,
                                upper: None,
                                reason: Some(format!("the first look is at {first} s of record")),
                                decided_at_s: None,
                                eta_s: None,
                            },
                        )
                    })
                    .collect();
                report(
                    self.spec.confidence,
                    None,
                    self.schedule.z(0),
                    0.0,
                    coefficients,
                )
            }
        }
    }

    /// Whether every coefficient is decided.
    pub fn all_decided(&self) -> bool {
        self.report.as_ref().is_some_and(SpecReport::all_decided)
    }

    /// An estimator update on a record of `duration_s`: a look if it is the first
    /// update past a new scheduled length, else nothing changes.
    pub fn observe(&mut self, e: &NoiseEstimates, duration_s: f64) -> Observed {
        self.observe_held(e, duration_s, None)
    }

    /// [`SequentialSpec::observe`] while the estimates still hold a slow
    /// effect (`held`, in words: a warm-up not yet left out, a bias step, a
    /// thermal response): a low-frequency coefficient (bias instability,
    /// rate random walk, rate ramp) it inflates is not failed meanwhile, it
    /// stays undecided with `held` as the reason; a pass (its upper bound
    /// below the limit even with the effect) and the other coefficients are
    /// decided as usual.
    pub fn observe_held(
        &mut self,
        e: &NoiseEstimates,
        duration_s: f64,
        held: Option<&str>,
    ) -> Observed {
        let Some(k) = self.schedule.look_at(duration_s) else {
            return Observed {
                looked: false,
                changed: false,
            };
        };
        if self.last_look.is_some_and(|l| l >= k) {
            return Observed {
                looked: false,
                changed: false,
            };
        }
        self.last_look = Some(k);
        let z = self.schedule.z(k);
        let old = self.report.take();
        let mut coefficients = BTreeMap::new();
        for (c, limit) in self.spec.limits() {
            let name = c.name().to_string();
            let previous = old.as_ref().and_then(|r| r.coefficients.get(&name));
            let v = match previous {
                // a decision is final
                Some(p) if p.verdict != Verdict::Undecided => p.clone(),
                _ => {
                    let mut v = judge(c, c.of(e), limit, z, self.spec.systematic_rel(c));
                    if let Some(why) =
                        held.filter(|_| v.verdict == Verdict::Fail && c.is_low_frequency())
                    {
                        v.verdict = Verdict::Undecided;
                        v.reason = Some(format!("not failed while {why}"));
                    }
                    if v.verdict == Verdict::Undecided {
                        v.eta_s = self.eta(c, c.of(e), limit, k, duration_s);
                    } else {
                        v.decided_at_s = Some(duration_s);
                    }
                    v
                }
            };
            coefficients.insert(name, v);
        }
        let new = report(self.spec.confidence, Some(k), z, duration_s, coefficients);
        let changed = match &old {
            None => true,
            Some(o) => {
                o.verdict != new.verdict
                    || o.coefficients
                        .iter()
                        .any(|(n, c)| new.coefficients.get(n).map(|d| d.verdict) != Some(c.verdict))
            }
        };
        self.report = Some(new);
        Observed {
            looked: true,
            changed,
        }
    }

    /// Predicted further record length until `coef` is decided (see the module docs).
    fn eta(
        &self,
        c: SpecCoefficient,
        coef: &Coefficient,
        limit: f64,
        k: u32,
        duration_s: f64,
    ) -> Option<f64> {
        const HORIZON: u32 = 80;
        match (coef.value, coef.ci95, coef.upper95) {
            (Some(v), Some([lo, hi]), _) => {
                let s = scaled(c, v, lo, hi, self.spec.systematic_rel(c))?;
                (k + 1..k + HORIZON).find_map(|j| {
                    let t = self.schedule.length_s(j);
                    let (lower, upper) =
                        bounds_at(c, s, self.schedule.z(j), (duration_s / t).sqrt(), limit);
                    (upper < limit || lower > limit).then_some(t - duration_s)
                })
            }
            (None, _, Some(u)) if u.is_finite() && u > 0.0 => (k + 1..k + HORIZON).find_map(|j| {
                let t = self.schedule.length_s(j);
                let zj = self.schedule.z(j);
                let upper = u
                    * (zj / Z95_ONE_SIDED).max(1.0)
                    * (zj * self.spec.systematic_rel(c)).exp()
                    * (duration_s / t).powf(0.25);
                (upper < limit).then_some(t - duration_s)
            }),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spending_sums_to_alpha_and_the_first_look_is_the_two_sided_95() {
        let s = LookSchedule {
            first_look_s: 60.0,
            alpha: 0.05,
        };
        let total: f64 = (0..100_000).map(|k| s.alpha_k(k)).sum();
        assert!((total - 0.05).abs() < 1e-6, "{total}");
        assert!((s.z(0) - Z95).abs() < 1e-9);
        assert_eq!(s.look_at(59.9), None);
        assert_eq!(s.look_at(60.0), Some(0));
        assert_eq!(s.look_at(84.0), Some(0));
        assert_eq!(s.look_at(85.0), Some(1));
        assert_eq!(s.look_at(120.0), Some(2));
        assert_eq!(s.look_at(3600.0), Some(11));
    }
}
