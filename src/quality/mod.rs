//! The data-quality stage: what makes a real bench run differ from the
//! stationary noise every estimator assumes, found, measured and handled
//! before the final estimates.
//!
//! - [`spikes`]: single-sample glitches, excluded as gaps as the samples
//!   arrive (the pipeline's first stage);
//! - [`blocks`]: block means of the rate and the temperature, the record at
//!   the resolution the slow effects live at;
//! - [`lowfreq`]: the warm-up, bias steps and the thermal response, tested
//!   against the record's own fitted noise and estimated with intervals;
//! - [`davar`]: the dynamic Allan deviation (Allan deviation over windows
//!   of the record) and the test of its stationarity.
//!
//! [`DataQuality`] is what `analyze --json` prints as `data_quality`, the
//! daemon records in `/gyro/estimates` and the report draws. Everything here
//! is plain synchronous numerics; the pipeline runs it.

use serde::{Deserialize, Serialize};

pub mod blocks;
pub mod davar;
pub mod gls;
pub mod lowfreq;
pub mod spikes;

pub use lowfreq::{Interval, StepFit, ThermalFit};

/// The outliers (glitches) of a record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outliers {
    /// Outliers found.
    pub count: u64,
    /// Their times, s from the start (the first [`spikes::MAX_LISTED`]).
    pub at_s: Vec<f64>,
    /// The test's threshold, in standard deviations of its statistic.
    pub threshold_sigma: f64,
    /// Every one was excluded as a gap (false: in windows whose noise is
    /// heavy-tailed they were kept).
    pub excluded: bool,
    /// How many were excluded.
    pub excluded_count: u64,
    /// Excess kurtosis of the test statistic over the samples kept (0 for Gaussian noise).
    pub excess_kurtosis: Option<f64>,
    /// Windows of the record whose noise is heavy-tailed.
    pub heavy_tailed_windows: u64,
}

impl Outliers {
    pub fn from_report(r: &spikes::SpikeReport, tau0_s: f64) -> Outliers {
        Outliers {
            count: r.count,
            at_s: r.at.iter().map(|&k| k as f64 * tau0_s).collect(),
            threshold_sigma: spikes::THRESHOLD_SIGMA,
            excluded: r.heavy_windows == 0,
            excluded_count: r.excluded,
            excess_kurtosis: r.excess_kurtosis(),
            heavy_tailed_windows: r.heavy_windows,
        }
    }
}

/// A fitted warm-up, and how it was handled.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Warmup {
    pub amplitude_dph: Interval,
    pub tau_s: Interval,
    /// `modelled` (the fitted settling subtracted) or `excluded` (the
    /// statistics restarted after it).
    pub handled: String,
    /// Seconds of the record left out.
    pub excluded_s: f64,
}

/// What the data-quality stage found and did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DataQuality {
    pub outliers: Outliers,
    pub warmup: Option<Warmup>,
    pub steps: Vec<StepFit>,
    pub thermal: Option<ThermalFit>,
    pub stationary: Option<davar::Stationarity>,
}

impl DataQuality {
    /// Whether anything was handled (excluded, modelled or compensated).
    pub fn handled_anything(&self) -> bool {
        self.outliers.excluded_count > 0
            || self.warmup.is_some()
            || !self.steps.is_empty()
            || self.thermal.as_ref().is_some_and(|t| t.compensated)
    }

    /// One line per finding, for a terminal.
    pub fn lines(&self) -> Vec<String> {
        let mut v = Vec::new();
        let o = &self.outliers;
        if o.count > 0 {
            v.push(format!(
                "outliers: {} beyond {} sigma, {}",
                o.count,
                o.threshold_sigma,
                if o.excluded {
                    "excluded as gaps".to_string()
                } else {
                    format!(
                        "{} excluded, the rest kept: the noise of {} windows is heavy-tailed (excess kurtosis {:.2})",
                        o.excluded_count,
                        o.heavy_tailed_windows,
                        o.excess_kurtosis.unwrap_or(f64::NAN)
                    )
                }
            ));
        }
        if let Some(w) = &self.warmup {
            v.push(format!(
                "warm-up: {:+.4} deg/h [{:+.4}, {:+.4}] settling with tau {:.0} s [{:.0}, {:.0}], {}",
                w.amplitude_dph.value,
                w.amplitude_dph.ci95[0],
                w.amplitude_dph.ci95[1],
                w.tau_s.value,
                w.tau_s.ci95[0],
                w.tau_s.ci95[1],
                w.handled
            ));
        }
        for s in &self.steps {
            v.push(format!(
                "bias step: {:+.4} deg/h [{:+.4}, {:+.4}] at {:.1} s [{:.1}, {:.1}], modelled",
                s.amplitude_dph.value,
                s.amplitude_dph.ci95[0],
                s.amplitude_dph.ci95[1],
                s.at_s.value,
                s.at_s.ci95[0],
                s.at_s.ci95[1]
            ));
        }
        if let Some(t) = &self.thermal {
            v.push(format!(
                "thermal: {:+.5} deg/h per deg C [{:+.5}, {:+.5}], lag {:.0} s [{:.0}, {:.0}], {}",
                t.bias_sensitivity_dph_per_c.value,
                t.bias_sensitivity_dph_per_c.ci95[0],
                t.bias_sensitivity_dph_per_c.ci95[1],
                t.lag_s.value,
                t.lag_s.ci95[0],
                t.lag_s.ci95[1],
                match (t.compensated, t.confounded_with_ramp) {
                    (true, false) => "compensated",
                    (true, true) =>
                        "compensated; the temperature changed linearly, so a rate ramp of the gyro's own \
                         cannot be told from this response and is attributed to it (lag not identified)",
                    (false, false) => "not significant, not compensated",
                    (false, true) =>
                        "not significant, not compensated; the temperature changed linearly, so this was \
                         also the test of a rate ramp, which is reported as a bound",
                }
            ));
        }
        if let Some(s) = &self.stationary
            && !s.ok
        {
            v.push(format!(
                "not stationary: what remains changes over the record (p = {:.2e}; see the dynamic Allan deviation)",
                s.p_value
            ));
        }
        v
    }
}

/// The data-quality findings of a first pass (glitches, and the slow effects
/// in the block means, against the fine-scale noise `fine`), and the
/// correction a second pass subtracts from the rate. The stationarity of what
/// remains is the second pass's ([`davar::Davar::stationarity`]).
/// `ramp_found`: the first pass's estimates found a rate ramp (the stage's
/// own test of it, [`lowfreq::Correction::ramp_rejected`], is made only then
/// or when effects are found: otherwise it could change nothing).
pub fn assess(
    spikes: &spikes::SpikeReport,
    series: &blocks::BlockSeries,
    fine: lowfreq::FineNoise,
    ramp_found: bool,
) -> (DataQuality, lowfreq::Correction) {
    let low = lowfreq::analyse_for(series, fine, ramp_found).unwrap_or_default();
    let dq = DataQuality {
        outliers: Outliers::from_report(spikes, series.tau0_s),
        warmup: low.warmup.map(|w| Warmup {
            amplitude_dph: w.amplitude_dph,
            tau_s: w.tau_s,
            handled: "modelled".into(),
            excluded_s: 0.0,
        }),
        steps: low.steps,
        thermal: low.thermal,
        stationary: None,
    };
    (dq, low.correction)
}
