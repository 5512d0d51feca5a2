//! Automatic estimation of the IEEE 952 coefficients: quantization (Q),
//! angle random walk (N), bias instability (B), rate random walk (K) and rate
//! ramp (R), each with a 95 % interval or, when the data do not support the
//! term, a 95 % upper bound.
//!
//! What goes in (all produced by the streaming pipeline, so the daemon and
//! `sagnac analyze` give the same answer):
//! * the variances of the sym8 detail coefficients of the raw rate, level by
//!   level, counting only coefficients free of start-up transients. sym8's
//!   sharp bands separate quantization noise (rate PSD rising as f^2) from ARW
//!   (flat) far better than the Allan filter, whose 1/f^2 sidelobes let QN
//!   leak into every tau: this is the paper's wavelet step, made quantitative;
//! * the overlapping Allan variance of the raw rate at octave taus beyond the
//!   deepest level that has enough sym8 coefficients (a 16-tap filter spans
//!   ~15 x 2^j samples, so the longest scales are only reachable by the Allan
//!   estimator);
//! * running sums for the least-squares rate slope (the ramp), which the
//!   wavelets cannot see (sym8 has 8 vanishing moments).
//!
//! The fit is `model::fit` (maximum likelihood on the chi-square sampling law
//! of each variance, model selection by likelihood ratio, profile intervals).
//! The ramp is a least-squares slope whose variance is computed from the
//! fitted noise spectrum (`int S(nu) |W(nu)|^2 dnu`), not from a white-noise
//! formula, so its interval stays honest under flicker and random walk; its
//! white-angle part is the quantization read from the angle, which on a short
//! record (below about 25 min at Q 0.5 arcsec, N 0.0005 deg/rt(h)) is most of
//! it, through the angle errors at the record's two ends. The
//! long-tau Allan points also see a ramp (R^2 tau^2 / 2): they get a ramp
//! column in the fit (0 on the wavelet levels), so that power does not go
//! into K, and a ramp is reported only when the slope's z test passes and
//! the fit keeps that column.

use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::filter::{FilterKind, ReadoutFilter};
use super::fit::{FitOptions, LevelFit, LevelObs, TermFit, fit_rows};
use super::wvar::{GL8, SpectralTerm};
use crate::units;

pub mod filter_search;
mod lf;
mod quantization;
mod sawtooth;

pub use sawtooth::Counter;

/// One overlapping Allan variance point of the raw rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanObs {
    /// Averaging factor (tau = m tau0).
    pub m: u64,
    /// Number of phase points the estimate was computed from.
    pub n_phase: u64,
    /// Allan variance, (arcsec/s)^2.
    pub avar: f64,
    /// Distance between the starts of successive terms (1 = full overlap).
    pub stride: u64,
    /// Number of second-difference terms.
    pub n_terms: u64,
}

impl AllanObs {
    /// EDF of this point for noise exponent `alpha`: Greenhall's algorithm for
    /// full overlap, the strided-estimator EDF otherwise.
    pub fn edf(&self, alpha: i32) -> f64 {
        let e = if self.stride <= 1 {
            crate::allan::edf_greenhall(alpha, 2, self.m, self.n_phase, true, false)
        } else {
            crate::allan::streaming::edf_strided(alpha, self.m, self.stride, self.n_terms)
                .unwrap_or_else(|_| crate::allan::edf_simple(alpha, self.m, self.n_phase))
        };
        if e.is_finite() { e.max(1.0) } else { 1.0 }
    }
}

/// Samples per block of [`RampAccumulator`] (blocks start at multiples of it).
const RAMP_BLOCK: u64 = 1024;

/// Streaming least-squares slope of the rate against time (equally spaced samples
/// `k = 0, 1, ...`). Samples are summed in blocks of [`RAMP_BLOCK`] at fixed sample
/// indices, relative to the block's first rate (two independent sums per sample, no
/// division); each full block is merged into the totals with Chan's pairwise update.
/// The index statistics are closed forms (mean `(n-1)/2`, sum of squared deviations
/// `n (n^2 - 1) / 12`). How the input is split into calls does not change a bit.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RampAccumulator {
    /// Samples in merged blocks (a multiple of [`RAMP_BLOCK`]).
    n: u64,
    /// Mean rate of the merged blocks.
    mean_r: f64,
    /// `sum (k - mean_k)(r - mean_r)` over the merged blocks.
    c_kr: f64,
    /// Samples of the open block, its first rate, `sum (r - ref)` and
    /// `sum j (r - ref)` (`j` the index within the block).
    open_n: u64,
    open_ref: f64,
    open_r: f64,
    open_jr: f64,
}

impl RampAccumulator {
    /// Add one rate sample (arcsec/s); samples are equally spaced.
    #[inline]
    pub fn push(&mut self, rate: f64) {
        if self.open_n == 0 {
            self.open_ref = rate;
        }
        let d = rate - self.open_ref;
        self.open_r += d;
        self.open_jr += self.open_n as f64 * d;
        self.open_n += 1;
        if self.open_n == RAMP_BLOCK {
            *self = self.merged();
        }
    }

    /// Add consecutive rate samples (the same result as pushing them one by one).
    pub fn push_slice(&mut self, rates: &[f64]) {
        let mut rest = rates;
        while let Some((&first, _)) = rest.split_first() {
            if self.open_n == 0 {
                self.open_ref = first;
            }
            let take = ((RAMP_BLOCK - self.open_n) as usize).min(rest.len());
            let (block, tail) = rest.split_at(take);
            let (r0, mut s_r, mut s_jr, mut j) =
                (self.open_ref, self.open_r, self.open_jr, self.open_n as f64);
            for &r in block {
                let d = r - r0;
                s_r += d;
                s_jr += j * d;
                j += 1.0;
            }
            (self.open_r, self.open_jr) = (s_r, s_jr);
            self.open_n += take as u64;
            if self.open_n == RAMP_BLOCK {
                *self = self.merged();
            }
            rest = tail;
        }
    }

    /// The totals with the open block merged in (and no open block).
    fn merged(&self) -> Self {
        if self.open_n == 0 {
            return *self;
        }
        let (na, nb) = (self.n as f64, self.open_n as f64);
        let n = na + nb;
        let mean_b = self.open_ref + self.open_r / nb;
        // sum (j - mean_j)(d - mean_d) = sum j d - mean_j sum d
        let c_b = self.open_jr - 0.5 * (nb - 1.0) * self.open_r;
        let (mean_r, c_kr) = if self.n == 0 {
            (mean_b, c_b)
        } else {
            // block mean index minus merged mean index: (na + (nb-1)/2) - (na-1)/2
            let dk = 0.5 * n;
            let dr = mean_b - self.mean_r;
            (
                self.mean_r + dr * (nb / n),
                self.c_kr + c_b + dk * dr * (na * nb / n),
            )
        };
        Self {
            n: self.n + self.open_n,
            mean_r,
            c_kr,
            ..Self::default()
        }
    }

    /// Samples seen.
    pub fn count(&self) -> u64 {
        self.n + self.open_n
    }
    /// Least-squares slope in rate units per sample.
    pub fn slope_per_sample(&self) -> f64 {
        let m = self.merged();
        let n = m.n as f64;
        let m2_k = n * (n * n - 1.0) / 12.0;
        if m2_k > 0.0 { m.c_kr / m2_k } else { 0.0 }
    }
    /// Mean rate.
    pub fn mean(&self) -> f64 {
        self.merged().mean_r
    }
}

/// One coefficient as reported: a value with its 95 % interval, or `null`
/// with a 95 % upper bound when the data do not support the term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coefficient {
    pub value: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ci95: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub upper95: Option<f64>,
}

impl Coefficient {
    /// The coefficient in another unit: value, interval and bound times `f`
    /// (an accelerometer's name for a gyro-named coefficient,
    /// [`crate::units::ACCEL_COEFFICIENTS`]).
    pub fn scaled(&self, f: f64) -> Coefficient {
        Coefficient {
            value: self.value.map(|v| v * f),
            ci95: self.ci95.map(|[lo, hi]| [lo * f, hi * f]),
            upper95: self.upper95.map(|u| u * f),
        }
    }
}

/// The five IEEE 952 coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseEstimates {
    pub quantization_arcsec: Coefficient,
    pub arw_dpsh: Coefficient,
    pub bias_instability_dph: Coefficient,
    pub rrw_dphsh: Coefficient,
    pub rate_ramp_dphh: Coefficient,
}

/// Everything the estimator needs.
#[derive(Debug, Clone)]
pub struct EstimatorInput<'a> {
    pub tau0_s: f64,
    /// Samples in the record.
    pub n_samples: u64,
    /// Wavelet analysis filters (orthonormal, PyWavelets convention).
    pub dec_lo: &'a [f64],
    pub dec_hi: &'a [f64],
    /// Detail-coefficient variances of the raw rate, (arcsec/s)^2.
    pub levels: &'a [LevelObs],
    /// Detail-coefficient variances of the raw angle (cumulative counts x
    /// pulse weight), arcsec^2, for the fine levels (the QN band).
    pub angle_levels: &'a [LevelObs],
    /// The same, per block of equal length (for a batch-means variance of Q;
    /// may be empty).
    pub angle_blocks: &'a [Vec<LevelObs>],
    /// Raw-rate overlapping Allan variances; only those beyond the deepest
    /// level are used.
    pub allan: &'a [AllanObs],
    pub ramp: Option<RampAccumulator>,
    /// The pulse counter the angle comes from (`None` for rate words): its
    /// sawtooth readout error is told apart from white quantization noise.
    pub counter: Option<Counter>,
    /// Factor (at least 1) on the ramp's standard error: effects fitted
    /// beside a ramp and subtracted from the rate before these statistics
    /// trade off against it (the data-quality stage's
    /// `Correction::ramp_se_factor`); 1 for a record taken as it is.
    pub ramp_se_factor: f64,
    /// The ramp's z in the data-quality stage's joint fit with those effects
    /// (`Correction::ramp_joint_z`): a ramp is reported only when it passes
    /// there too. `None` for a record taken as it is.
    pub ramp_joint_z: Option<f64>,
    /// The data-quality stage tested the ramp against the block means' noise
    /// refitted without it (or, under a linear temperature, the response in
    /// its place) and it did not pass (`Correction::ramp_rejected`): the ramp
    /// is reported as a bound, whatever the test here says. `false` for a
    /// record taken as it is.
    pub ramp_rejected: bool,
}

/// Full result: the coefficients plus the fit behind them.
#[derive(Debug, Clone)]
pub struct EstimatorOutput {
    pub estimates: NoiseEstimates,
    pub fit: LevelFit,
    /// Squared coefficients in arcsec/s units, in the order Q, N, B, K.
    pub theta: [f64; 4],
    /// Rate slope (arcsec/s^2) and its standard deviation.
    pub ramp_arcsec_s2: Option<(f64, f64)>,
    /// The readout filter the data show (`None`: none).
    pub readout_filter: Option<FilterEstimate>,
    /// Whether the fitted noise model describes the record.
    pub quality: FitQuality,
}

/// A fitted readout filter, as reported (JSON `readout_filter`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FilterEstimate {
    pub kind: FilterKind,
    /// -3 dB frequency, Hz.
    pub corner_hz: f64,
    /// 95 % interval of `corner_hz`.
    pub ci95: [f64; 2],
    /// Moving-average length, samples.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub length: Option<u32>,
    /// Group delay at DC, s.
    pub delay_s: f64,
}

impl FilterEstimate {
    fn new(c: &filter_search::FilterChoice, tau0_s: f64) -> Self {
        let length = match c.filter {
            ReadoutFilter::MovingAverage { length } => Some(length),
            ReadoutFilter::FirstOrder { .. } => None,
        };
        FilterEstimate {
            kind: c.filter.kind(),
            corner_hz: c.filter.corner_hz(tau0_s),
            ci95: [c.corner_ci_cycles.0 / tau0_s, c.corner_ci_cycles.1 / tau0_s],
            length,
            delay_s: c.filter.delay_samples() * tau0_s,
        }
    }
}

/// Goodness of the final fit: Pearson chi-square against its degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    pub chi2_per_dof: f64,
    pub dof: f64,
    /// False when the chi-square is beyond its 99.9 % point: the noise model
    /// does not describe the record, and every interval is widened.
    pub ok: bool,
}

/// Chi-square tail probability below which a fit is reported as not describing the record.
pub const MISFIT_P: f64 = 1e-3;

impl FitQuality {
    /// Quality of `fit` on `n_obs` observations, with `extra_params` fitted
    /// outside the linear terms (a readout filter's shape).
    pub fn of(fit: &LevelFit, n_obs: usize, extra_params: usize) -> Self {
        let n_par = fit.terms.iter().filter(|t| t.included).count() + extra_params;
        let dof = (n_obs as f64 - n_par as f64).max(1.0);
        // LevelFit's chi2_per_dof counts only the linear terms
        let chi2 = fit.chi2_per_dof * (n_obs as f64 - (n_par - extra_params) as f64).max(1.0);
        // A chi-square that is not finite is a collapsed fit (every term at 0,
        // a predicted variance of 0 against observed noise): not a description.
        let ok = chi2.is_finite()
            && ChiSquared::new(dof)
                .map(|d| 1.0 - d.cdf(chi2) >= MISFIT_P)
                .unwrap_or(true);
        FitQuality {
            chi2_per_dof: chi2 / dof,
            dof,
            ok,
        }
    }

    /// The fit collapsed (its chi-square is not finite): its profile bounds
    /// say nothing, and the per-level bounds are reported instead.
    pub fn collapsed(&self) -> bool {
        self.dof > 0.0 && !self.chi2_per_dof.is_finite()
    }

    /// A fit with no observations (too short a record, or no noise).
    pub fn none() -> Self {
        FitQuality {
            chi2_per_dof: f64::NAN,
            dof: 0.0,
            ok: true,
        }
    }

    /// The factor intervals are widened by: `sqrt(chi2/dof)` for a misfit, else
    /// 1 (also for a collapsed fit, whose terms get the per-level bounds).
    pub fn widening(&self) -> f64 {
        if self.ok || self.collapsed() {
            1.0
        } else {
            self.chi2_per_dof.sqrt().max(1.0)
        }
    }
}

impl EstimatorOutput {
    /// A record without noise: nothing found, every upper bound 0.
    pub fn no_noise() -> Self {
        let zero = Coefficient {
            value: None,
            ci95: None,
            upper95: Some(0.0),
        };
        let mut out = Self::insufficient();
        out.estimates = NoiseEstimates {
            quantization_arcsec: zero,
            arw_dpsh: zero,
            bias_instability_dph: zero,
            rrw_dphsh: zero,
            rate_ramp_dphh: zero,
        };
        out.ramp_arcsec_s2 = Some((0.0, 0.0));
        out
    }

    /// Every coefficient unknown: too little data.
    pub fn insufficient() -> Self {
        let none = Coefficient {
            value: None,
            ci95: None,
            upper95: None,
        };
        EstimatorOutput {
            estimates: NoiseEstimates {
                quantization_arcsec: none,
                arw_dpsh: none,
                bias_instability_dph: none,
                rrw_dphsh: none,
                rate_ramp_dphh: none,
            },
            fit: LevelFit {
                terms: Vec::new(),
                loglik: 0.0,
                edf: Vec::new(),
                fitted: Vec::new(),
                chi2_per_dof: f64::NAN,
            },
            theta: [0.0; 4],
            ramp_arcsec_s2: None,
            readout_filter: None,
            quality: FitQuality::none(),
        }
    }
}

/// Blocks needed before their spread is trusted as a variance of Q^2.
pub const MIN_BATCHES: usize = 8;

/// Levels whose count of transient-free coefficients is at least this are used.
pub const MIN_LEVEL_COEFS: f64 = 8.0;

/// A level starts the QN band when it rises above its deeper neighbour by this
/// many standard deviations, and above the level beyond that one as well.
pub const CUT_RISE_Z: f64 = 3.0;
/// The finest kept level is dropped while it exceeds the fit of the deeper ones
/// by this many standard deviations (low-frequency terms only: a non-white QN tail).
pub const TRIM_EXCESS_Z: f64 = 4.0;

/// The low-frequency corner of the fitted flicker term, cycles per sample: the
/// power of two at or just below `1e-3 / n_samples`.
pub fn flicker_corner_cycles(n_samples: u64) -> f64 {
    (1e-3 / n_samples.max(1) as f64).log2().floor().exp2()
}

/// The terms fitted, in order: Q^2, N^2, B^2, K^2.
pub fn standard_terms(n_samples: u64, tau0_s: f64) -> [SpectralTerm; 4] {
    [
        SpectralTerm::WhiteAngle,
        SpectralTerm::WhiteRate,
        // flicker with no visible low-frequency corner: put it about three
        // decades below the record's lowest frequency, at a power of two in
        // cycles per sample (between 2^-11 and 2^-10 of 1/N): the corner then
        // falls on an octave break of the wavelet-level quadrature and stays put
        // while the record grows within an octave, so the daemon's periodic
        // updates reuse the memoised quadrature (the level variances move by
        // far less than their uncertainty between such corners)
        SpectralTerm::Flicker {
            f_lo_hz: flicker_corner_cycles(n_samples) / tau0_s,
        },
        SpectralTerm::RateRandomWalk,
    ]
}

/// Run the estimator.
///
/// 1. Quantization, read from the noise component as the paper does, made
///    exact ([`quantization`]): QN is white-or-periodic noise in *angle*, so
///    its variance is the high-frequency energy of the angle signal.
/// 2. The low-frequency terms (N, B, K) from the rate-domain levels below the
///    QN band ([`lf`]) plus long-tau Allan points, with a free white-angle
///    nuisance term so that QN leakage is absorbed when it is white and costs
///    nothing when it is not; the white rate passes through a readout filter
///    when the data show one ([`filter_search`]).
/// 3. The fit's honesty: a chi-square far above its degrees of freedom marks
///    the fit as not describing the record, and every interval is widened by
///    the misfit.
/// 4. The ramp, a least-squares slope with its spread under the fitted spectrum.
pub fn estimate(input: &EstimatorInput, opts: &FitOptions) -> EstimatorOutput {
    // No noise at all (a stuck counter, a dead gyro): the raw Allan variance of
    // integer counts is then exactly 0 at every tau. Nothing is found (a fit
    // would "find" terms at round-off size); every bound is 0.
    if !input.allan.is_empty() && input.allan.iter().all(|a| a.avar == 0.0) {
        return EstimatorOutput::no_noise();
    }
    let tau0 = input.tau0_s;
    let std_terms = standard_terms(input.n_samples, tau0).to_vec();
    let q2_first = quantization::q_from_angle(input, &std_terms, &[0.0; 4], false).q2;
    let Some(lf) = lf_setup(input, q2_first) else {
        return EstimatorOutput::insufficient();
    };
    let std_basis = lf.basis(&std_terms);
    let cut = lf.qn_cut();
    // Fewer than two levels below the QN band: the record is too short to
    // separate the low-frequency terms from QN; bounds only.
    let too_short = lf.levels.len() - cut < 2;
    let level_bounds = lf.level_bounds(&std_basis, 4);
    let mut from = if too_short {
        lf.levels.len().saturating_sub(2)
    } else {
        cut
    };
    from = lf.trim(&std_terms, &std_basis, from);
    // With no more observations than the nuisance, ARW, flicker and RRW
    // columns, the fit is saturated and its likelihood-ratio tests say
    // nothing: fit ARW (and the nuisance) only, and bound the others.
    let saturated = lf.rows(&std_terms, &std_basis.phi, from).y.len() <= std_terms.len();
    let choice = if too_short || saturated {
        None
    } else {
        filter_search::search(&lf, input.n_samples, from, opts)
    };
    let terms = match &choice {
        Some(c) => filter_search::filtered_terms(input.n_samples, tau0, c.filter),
        None => std_terms,
    };
    let basis = lf.basis(&terms);
    let mut rows = lf.rows(&terms, &basis.phi, from);
    filter_search::saturate_rows(&mut rows, saturated);
    let o = fit_options(opts, choice.is_some());
    let corr = |theta: &[f64]| lf.correlation(&terms, from, theta);
    let fit = fit_rows(
        &rows.phi,
        &rows.y,
        &rows.edf0,
        &lf.edf(&terms, &basis, from, &rows.phi),
        &o,
        Some(&corr),
    );
    let quality = FitQuality::of(&fit, rows.y.len(), usize::from(choice.is_some()));
    let theta_lf = fitted_thetas(&fit, terms.len(), too_short, saturated);
    let q_read = quantization::q_from_angle(input, &terms, &theta_lf, true);
    let q2 = q_read.q2;
    let widen = quality.widening();
    let theta = [q2.max(0.0), theta_lf[1], theta_lf[2], theta_lf[3]];
    // a collapsed fit bounds nothing: each term gets its per-level bound, as
    // on a record too short for the fit
    let collapsed = quality.collapsed();
    let coef = |i: usize| -> Coefficient {
        if too_short || collapsed || (saturated && i >= 2) {
            return Coefficient {
                value: None,
                ci95: None,
                upper95: level_bounds[i]
                    .is_finite()
                    .then(|| CONV[i](level_bounds[i])),
            };
        }
        let mut t = fit.terms[i];
        if i == 1 {
            if let (Some(c), Some(ci)) = (&choice, t.ci95.as_mut()) {
                *ci = filter_search::n2_interval(c, t.theta, *ci, opts.ci_lr);
            }
        }
        let t = widen_term(t, widen);
        let t = if i == RRW_COL { rrw_supported(t) } else { t };
        term_coefficient(&t, CONV[i])
    };
    let ramp_term = fit.terms.get(terms.len()).filter(|_| lf.ramp_col);
    let (ramp, ramp_wide) = ramp_slopes(
        input,
        &terms,
        &fit,
        &theta_lf,
        q2,
        &level_bounds,
        collapsed,
        widen * input.ramp_se_factor.max(1.0),
    );
    EstimatorOutput {
        estimates: NoiseEstimates {
            quantization_arcsec: quantization::coefficient(&q_read, widen),
            arw_dpsh: coef(1),
            bias_instability_dph: coef(2),
            rrw_dphsh: coef(3),
            rate_ramp_dphh: ramp_coefficient(
                ramp,
                ramp_wide,
                lf.ramp_col,
                ramp_term.is_some_and(|t| t.included),
                !input.ramp_rejected && input.ramp_joint_z.is_none_or(|z| z * z >= opts.ci_lr),
                opts.ci_lr,
            ),
        },
        fit,
        theta,
        ramp_arcsec_s2: ramp,
        readout_filter: choice.map(|c| FilterEstimate::new(&c, tau0)),
        quality,
    }
}

/// Column of the rate random walk in [`standard_terms`] (and in the filtered terms).
const RRW_COL: usize = 3;

/// The fit's options: the white-angle nuisance, and with a readout filter the
/// filter's complement column, stay out of model selection; RRW must pass
/// the stricter threshold.
fn fit_options(opts: &FitOptions, filtered: bool) -> FitOptions {
    let mut o = *opts;
    // RRW rests on the few longest-tau points, which overlap one another: the
    // likelihood, which counts them as independent, overstates its deviance.
    // At the 5 % threshold a clean record "found" RRW in 14 of 119 clean runs
    // without one (scripts/bench-quality 100 8001 clean, and 8101); at the
    // 2.5 % threshold in 3 of 119, while K's coverage on the RRW cases of
    // scripts/bench-bias-coverage is unchanged (26/30, 25/30).
    o.strict |= 1 << RRW_COL;
    // RRW dropped below that threshold may still be there: held at 0, the
    // flicker takes its power and bias instability's interval is that of a
    // gyro known to have none (4 h records with RRW the fit dropped: BI
    // 1.6-2.2x the truth, the interval off it)
    o.free_in_profile |= 1 << RRW_COL;
    // The white-angle nuisance stays out of model selection, and so does the
    // filter's complement column: dropped at its zero boundary, it would be
    // held at 0 in N's profile, the fine (filtered) levels would then pin N as
    // if no white noise could enter after the filter, and N's interval would be
    // too narrow by about 1.6 (2 h, 500 Hz, moving average of 6: 15/20 covered).
    o.always_keep |= 1;
    if filtered {
        o.always_keep |= 1 << filter_search::COMPLEMENT_COL;
        o.signed_in_profile |= 1 << filter_search::COMPLEMENT_COL;
    }
    o
}

/// The ramp's slope and standard error under the fitted spectrum, and again
/// with every term the record cannot rule out at its upper bound (the
/// interval's spread).
#[allow(clippy::too_many_arguments)]
fn ramp_slopes(
    input: &EstimatorInput,
    terms: &[SpectralTerm],
    fit: &LevelFit,
    theta_lf: &[f64],
    q2: f64,
    level_bounds: &[f64],
    collapsed: bool,
    widen: f64,
) -> (Option<(f64, f64)>, Option<(f64, f64)>) {
    // The slope's white-angle part is the quantization read from the angle
    // (`q2`, thousands of degrees of freedom), not the low-frequency fit's
    // white-angle nuisance (a few levels below the QN band, often 0 or far
    // off). On a short record it is the largest part of the slope's variance:
    // the slope's end weights `+-(n/2) / S_kk` fall on the rate differences at
    // the two ends, so the first and last angle errors enter as
    // `72 Q^2 / T^4` (against `12 N^2 / T^3` for ARW; at Q 0.48 arcsec and N
    // 0.0005 deg/rt(h) the QN part is larger below about 25 min). With the
    // nuisance in its place the standard error scattered from record to
    // record and the slope's z-scores had heavy tails (examples/ramp_calibration.rs).
    let mut theta_ramp = theta_lf.to_vec();
    if q2.is_finite() {
        theta_ramp[0] = theta_ramp[0].max(q2);
    }
    let ramp = ramp_slope(input, terms, &theta_ramp).map(|(s, sd)| (s, sd * widen));
    // The ramp's interval allows every term the record cannot rule out at its
    // upper bound (an unresolved bias instability or RRW wanders the rate as
    // much as a ramp over the record); whether a ramp is reported at all stays
    // the z test under the fitted spectrum with the Allan ramp column kept.
    let theta_slope: Vec<f64> = fit.terms[..terms.len()]
        .iter()
        .zip(&theta_ramp)
        .enumerate()
        .map(|(k, (t, &th))| {
            if collapsed {
                th.max(
                    level_bounds
                        .get(k)
                        .copied()
                        .filter(|b| b.is_finite())
                        .unwrap_or(0.0),
                )
            } else if t.included {
                th
            } else {
                th.max(t.upper95.unwrap_or(0.0))
            }
        })
        .collect();
    let ramp_wide = ramp_slope(input, terms, &theta_slope).map(|(s, sd)| (s, sd * widen));
    (ramp, ramp_wide)
}

/// Conversions from theta (arcsec/s units, squared) to the reported units of Q, N, B, K.
const CONV: [fn(f64) -> f64; 4] = [
    |t: f64| t.sqrt(),
    |t: f64| units::arcsec_per_sqrt_s_to_dpsh(t.sqrt()),
    |t: f64| units::arcsec_per_s_to_dph(t.sqrt()),
    |t: f64| units::arcsec_per_s_sqrt_s_to_dphsh(t.sqrt()),
];

/// The low-frequency fit's inputs: usable levels, and the long-tau Allan
/// points beyond the deepest level where quantization carries less than half
/// the variance (QN-dominated points say nothing about the low-frequency
/// terms, and QN-subtracted they could leave a meaningless near-zero
/// observation). `None` when fewer than two levels are usable.
fn lf_setup<'a>(input: &EstimatorInput<'a>, q2_first: f64) -> Option<lf::Lf<'a>> {
    let tau0 = input.tau0_s;
    let levels: Vec<LevelObs> = input.levels.iter().copied().filter(usable).collect();
    if levels.len() < 2 {
        return None;
    }
    let deepest = levels.iter().map(|l| l.level).max().unwrap_or(0);
    let m_min = 1u64 << (deepest + 1).min(62);
    let qn = SpectralTerm::WhiteAngle;
    let allan: Vec<AllanObs> = input
        .allan
        .iter()
        .copied()
        .filter(|a| a.m >= m_min && a.avar > 0.0 && a.avar.is_finite() && a.n_terms > 0)
        .filter(|a| q2_first.max(0.0) * qn.allan_var(a.m, tau0) < 0.5 * a.avar)
        .collect();
    // A rate ramp R is invisible on the wavelet levels (vanishing moments) but
    // adds R^2 tau^2 / 2 to the long-tau Allan points; without a column for it
    // the fit would put that power into RRW. With Allan points, a ramp column
    // (theta = R^2, (arcsec/s^2)^2; 0 on the levels) takes it.
    let ramp_col = !allan.is_empty();
    Some(lf::Lf {
        tau0,
        dec_lo: input.dec_lo,
        dec_hi: input.dec_hi,
        levels,
        allan,
        q2_first,
        ramp_col,
    })
}

/// A level with enough transient-free coefficients and a finite positive variance.
pub(super) fn usable(l: &LevelObs) -> bool {
    l.n_coef >= MIN_LEVEL_COEFS && l.mean_sq > 0.0 && l.mean_sq.is_finite()
}

/// Widen a term's interval (or bound) about its estimate by `s >= 1`.
fn widen_term(mut t: TermFit, s: f64) -> TermFit {
    if s > 1.0 {
        if let Some((lo, hi)) = t.ci95.as_mut() {
            *lo = (t.theta - s * (t.theta - *lo)).max(0.0);
            *hi = t.theta + s * (*hi - t.theta);
        }
        if let Some(u) = t.upper95.as_mut() {
            *u *= s;
        }
    }
    t
}

/// The low-frequency fit's thetas of the first `n` terms; 0 where the record
/// is too short for the fit, and beyond ARW where the fit is saturated.
fn fitted_thetas(fit: &LevelFit, n: usize, too_short: bool, saturated: bool) -> Vec<f64> {
    (0..n)
        .map(|k| {
            if too_short || (saturated && k >= 2) {
                0.0
            } else {
                fit.terms[k].theta
            }
        })
        .collect()
}

/// RRW as found only where its interval (profiled with the other terms
/// free, widened for a poor fit) excludes zero, else bounded by the
/// interval's upper end: its inclusion test rests on the few longest-tau
/// points, where flicker scatter, an unfound step or a trend the model lacks
/// raise the Allan variance as a random walk does, and an interval reaching
/// zero says the data do not exclude a gyro without one.
fn rrw_supported(mut t: TermFit) -> TermFit {
    if t.included
        && let Some((lo, hi)) = t.ci95
        && lo <= 0.0
    {
        t.included = false;
        t.ci95 = None;
        t.upper95 = Some(hi);
    }
    t
}

/// A fitted term as a reported coefficient (value and interval, or a bound).
fn term_coefficient(t: &TermFit, conv: fn(f64) -> f64) -> Coefficient {
    if t.included {
        let (lo, hi) = t.ci95.unwrap_or((t.theta, t.theta));
        Coefficient {
            value: Some(conv(t.theta)),
            ci95: Some([conv(lo), conv(hi)]),
            upper95: None,
        }
    } else {
        Coefficient {
            value: None,
            ci95: None,
            upper95: Some(conv(t.upper95.unwrap_or(0.0))),
        }
    }
}

/// The least-squares rate slope (arcsec/s^2) and its spread under the fitted spectrum.
fn ramp_slope(input: &EstimatorInput, terms: &[SpectralTerm], theta: &[f64]) -> Option<(f64, f64)> {
    let tau0 = input.tau0_s;
    input.ramp.filter(|r| r.count() > 2).map(|r| {
        let n = r.count();
        let slope = r.slope_per_sample() / tau0;
        let var: f64 = terms
            .iter()
            .zip(theta)
            .map(|(t, th)| th * slope_var_per_theta(t, n, tau0))
            .sum();
        (slope, var.max(0.0).sqrt())
    })
}

/// The reported ramp: a signed parameter, included when its likelihood-ratio
/// (z^2) test passes under the fitted spectrum (`ramp`) and, where the
/// long-tau Allan points had a ramp column, the fit kept it (the tau^2 growth
/// is there: a slope alone can come from low-frequency noise the fit left
/// out). Its interval and bound use the spread `wide`, with the unresolved
/// terms at their upper bounds: the slope of one record cannot tell a ramp
/// from the low-frequency noise the record does not exclude, so the interval
/// may reach zero although the test found a ramp. `joint_ok`: the ramp also
/// passes beside the effects subtracted from the rate
/// ([`EstimatorInput::ramp_joint_z`]; true without) and was not rejected by
/// the stage ([`EstimatorInput::ramp_rejected`]).
fn ramp_coefficient(
    ramp: Option<(f64, f64)>,
    wide: Option<(f64, f64)>,
    ramp_col: bool,
    col_kept: bool,
    joint_ok: bool,
    ci_lr: f64,
) -> Coefficient {
    let z = 1.959_964;
    let to = units::arcsec_per_s2_to_dphh;
    let sd_wide = |sd: f64| wide.map_or(sd, |(_, w)| w.max(sd));
    match ramp {
        Some((s, sd))
            if sd > 0.0 && (s / sd).powi(2) >= ci_lr && (!ramp_col || col_kept) && joint_ok =>
        {
            let w = sd_wide(sd);
            Coefficient {
                value: Some(to(s)),
                ci95: Some([to(s - z * w), to(s + z * w)]),
                upper95: None,
            }
        }
        Some((s, sd)) => Coefficient {
            value: None,
            ci95: None,
            upper95: Some(to(s.abs() + z * sd_wide(sd))),
        },
        None => Coefficient {
            value: None,
            ci95: None,
            upper95: None,
        },
    }
}

/// Variance of the least-squares slope (rate units per second) of `n` equally
/// spaced samples, per unit theta of `term`: `int_0^{1/2} S(nu) |W(nu)|^2 dnu`
/// with `W` the transfer function of the slope weights.
pub fn slope_var_per_theta(term: &SpectralTerm, n: u64, tau0_s: f64) -> f64 {
    let nf = n as f64;
    let skk = nf * (nf * nf - 1.0) / 12.0; // sum (k - kbar)^2
    let norm = 1.0 / (skk * tau0_s).powi(2);
    let nu_lo = match *term {
        SpectralTerm::Flicker { f_lo_hz } => f_lo_hz * tau0_s,
        _ => 0.0,
    };
    // |sum (k - kbar) e^{-i 2 pi nu k}|^2 = (D'(nu) / 2 pi)^2, D = sin(pi nu n)/sin(pi nu)
    let w2 = |nu: f64| {
        let (s1, c1) = (PI * nu * nf).sin_cos();
        let (s0, c0) = (PI * nu).sin_cos();
        let dp = PI * (nf * c1 * s0 - s1 * c0) / (s0 * s0);
        (dp / (2.0 * PI)).powi(2) * norm
    };
    let split = (64.0 / nf).min(0.5);
    let mut total = 0.0;
    let panels = ((split - nu_lo).max(0.0) * 4.0 * nf).ceil() as usize;
    if panels > 0 {
        let h = (split - nu_lo) / panels as f64;
        for p in 0..panels {
            let c = nu_lo + (p as f64 + 0.5) * h;
            for &(x, w) in &GL8 {
                let nu = c + 0.5 * h * x;
                total += 0.5 * h * w * term.psd_cs(nu, tau0_s) * w2(nu);
            }
        }
    }
    if split < 0.5 {
        let a = split.max(nu_lo).ln();
        let b = 0.5f64.ln();
        let panels = 256;
        let h = (b - a) / panels as f64;
        for p in 0..panels {
            let c = a + (p as f64 + 0.5) * h;
            for &(x, w) in &GL8 {
                let nu = (c + 0.5 * h * x).exp();
                let s0 = (PI * nu).sin();
                // cos^2(pi nu n) averages to 1/2 beyond the resolved region
                let env = nf * nf / (8.0 * s0 * s0) * norm;
                total += 0.5 * h * w * nu * term.psd_cs(nu, tau0_s) * env;
            }
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_variance_matches_closed_forms() {
        let tau0 = 0.01;
        let n = 20_000u64;
        let nf = n as f64;
        let skk = nf * (nf * nf - 1.0) / 12.0;
        // white rate, variance 1/tau0 per sample: var = (1/tau0) / (skk tau0^2)
        let v = slope_var_per_theta(&SpectralTerm::WhiteRate, n, tau0);
        let want = (1.0 / tau0) / (skk * tau0 * tau0);
        assert!((v - want).abs() / want < 2e-3, "white: {v} vs {want}");
        // rate random walk: var = K^2 tau0 sum_m (sum_{k>=m} w_k)^2 with w the slope weights
        let kbar = (nf - 1.0) / 2.0;
        let mut suffix = 0.0;
        let mut acc = 0.0;
        for k in (1..n).rev() {
            suffix += (k as f64 - kbar) / (skk * tau0);
            acc += suffix * suffix;
        }
        let want = tau0 * acc;
        let v = SpectralTerm::RateRandomWalk;
        let got = slope_var_per_theta(&v, n, tau0);
        assert!((got - want).abs() / want < 1e-2, "rrw: {got} vs {want}");
    }

    #[test]
    fn ramp_accumulator_is_the_least_squares_fit_whatever_the_split() {
        // noisy rate with an offset and a ramp; two-pass least squares as reference
        let mut s = 0x853c_49e6_748f_ea9bu64;
        let rates: Vec<f64> = (0..100_003)
            .map(|k| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                15.0 + 3e-6 * k as f64 + 40.0 * u
            })
            .collect();
        let n = rates.len() as f64;
        let (mk, mr) = ((n - 1.0) / 2.0, rates.iter().sum::<f64>() / n);
        let (mut skk, mut skr) = (0.0, 0.0);
        for (k, &r) in rates.iter().enumerate() {
            skk += (k as f64 - mk).powi(2);
            skr += (k as f64 - mk) * (r - mr);
        }
        let want = skr / skk;
        let mut one = RampAccumulator::default();
        for &r in &rates {
            one.push(r);
        }
        assert_eq!(one.count(), rates.len() as u64);
        assert!(
            (one.slope_per_sample() - want).abs() <= 1e-9 * want.abs(),
            "{} vs {want}",
            one.slope_per_sample()
        );
        assert!((one.mean() - mr).abs() <= 1e-12 * mr.abs());
        // slices of awkward sizes (across block boundaries) and mixed calls: same bits
        for cut in [1usize, 7, 1023, 1024, 1025, 5000, 100_003] {
            let mut acc = RampAccumulator::default();
            for (i, part) in rates.chunks(cut).enumerate() {
                if i % 3 == 2 {
                    part.iter().for_each(|&r| acc.push(r));
                } else {
                    acc.push_slice(part);
                }
                // a snapshot in the middle changes nothing
                let _ = acc.slope_per_sample();
            }
            assert_eq!(acc, one, "cut {cut}");
        }
    }

    #[test]
    fn ramp_accumulator_recovers_a_slope_exactly() {
        let mut r = RampAccumulator::default();
        for k in 0..100_000 {
            r.push(3.0 + 2.5e-4 * k as f64);
        }
        assert!((r.slope_per_sample() - 2.5e-4).abs() < 1e-15 * 1e4);
        assert!((r.mean() - (3.0 + 2.5e-4 * 99_999.0 / 2.0)).abs() < 1e-9);
    }

    #[test]
    fn coefficient_json_shape() {
        let c = Coefficient {
            value: None,
            ci95: None,
            upper95: Some(0.1),
        };
        assert_eq!(
            serde_json::to_string(&c).unwrap(),
            r#"{"value":null,"upper95":0.1}"#
        );
        let c = Coefficient {
            value: Some(1.0),
            ci95: Some([0.5, 2.0]),
            upper95: None,
        };
        assert_eq!(
            serde_json::to_string(&c).unwrap(),
            r#"{"value":1.0,"ci95":[0.5,2.0]}"#
        );
    }
}
