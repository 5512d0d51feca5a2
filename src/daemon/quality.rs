//! The data-quality stage of a live run ([`crate::quality`]), one per gyro.
//!
//! The pipeline excludes glitches as the samples arrive and keeps the block
//! means; here, at estimator boundaries, the numeric stage
//! ([`crate::daemon::process`]):
//!
//! * counts the glitches (`sagnac_outliers_total`, at every boundary: it is a
//!   read of the pipeline's spike report);
//! * assesses the slow effects ([`quality::assess`] on the spike report and
//!   the block means, against the pipeline's current ARW and QN) at the first
//!   estimator boundary [`LOWFREQ_EVERY_S`] seconds of samples after the
//!   previous assessment, or an eighth of the statistics' length once that is
//!   longer, and at the final update. One assessment costs about 0.3 s of
//!   CPU (the block means are at most 160 blocks, so it does not grow with
//!   the record): 0.1 % of a core at real-time pace in the first 40 minutes,
//!   less and less after, and a replay as fast as it can go makes about
//!   8 ln(T / 40 min) + 8 of them for
//!   a record of T (some 40 for 24 h). The schedule is by sample count, not
//!   wall time, so the findings (and the restart below) do not depend on the
//!   pace or on skipped estimator updates; nor do the assessments count
//!   against the estimator updates' budget;
//! * restarts the statistics once a warm-up has settled: when the latest
//!   assessment finds a warm-up and [`SETTLED_TAUS`] time constants (at the
//!   upper end of the time constant's 95 % interval, so that what is left of
//!   the settling is below a per cent of its amplitude whatever the estimate's
//!   error) have passed since the start of the statistics, the pipeline is
//!   replaced by a new one from the next sample on, once per run. Before that
//!   the warm-up is reported `modelled` (as `analyze` does); after it,
//!   `excluded` with the seconds left out.
//!
//! What the restarted statistics report is joined with what the first
//! pipeline found: outliers and bias steps of both (times from the start of
//! the run), the excluded warm-up, the current thermal response and
//! stationarity. The counters only increase.

use crate::daemon::status::{LiveStatus, StatusQuality};
use crate::model::estimate::NoiseEstimates;
use crate::pipeline::Pipeline;
use crate::quality::lowfreq::FineNoise;
use crate::quality::spikes::MAX_LISTED;
use crate::quality::{self, DataQuality, Outliers, StepFit, Warmup};
use crate::sink::metrics::GyroMetrics;

/// Least seconds of samples between assessments of the slow effects.
pub const LOWFREQ_EVERY_S: f64 = 300.0;
/// Past `LOWFREQ_EVERY_S * LOWFREQ_GROWTH` of statistics, assessments are
/// this fraction of the statistics' length apart.
pub const LOWFREQ_GROWTH: f64 = 8.0;
/// Time constants after which a warm-up has settled (`exp(-5)`: 0.7 % of
/// its amplitude is left).
pub const SETTLED_TAUS: f64 = 5.0;

/// What the pipeline before a restart found.
#[derive(Debug, Clone)]
struct Retired {
    outliers: Outliers,
    /// Outliers excluded as gaps.
    excluded: u64,
    steps: Vec<StepFit>,
}

/// The live data-quality state of one gyro.
#[derive(Debug)]
pub struct LiveQuality {
    tau0_s: f64,
    /// Samples of the current statistics at which the next assessment is due.
    next_at: u64,
    /// Uniform sample index where the current statistics start.
    base: u64,
    retired: Option<Retired>,
    /// The warm-up the restart left out.
    excluded: Option<Warmup>,
    /// The latest assessment, joined with what came before a restart.
    latest: Option<DataQuality>,
    /// The latest assessment found a warm-up that has not settled.
    settling: bool,
    /// The slow effects the latest assessment found in the current
    /// statistics, which the live estimates still hold (a warm-up before the
    /// restart, bias steps, a thermal response), in words.
    held: Option<String>,
    /// The latest assessment rejected the rate ramp
    /// ([`crate::quality::lowfreq::Correction::ramp_rejected`]).
    ramp_rejected: bool,
    /// Counter values published.
    outliers_published: u64,
    steps_published: u64,
}

impl LiveQuality {
    /// For samples `tau0_s` apart.
    pub fn new(tau0_s: f64) -> LiveQuality {
        LiveQuality {
            tau0_s,
            next_at: (LOWFREQ_EVERY_S / tau0_s).round() as u64,
            base: 0,
            retired: None,
            excluded: None,
            latest: None,
            settling: false,
            held: None,
            ramp_rejected: false,
            outliers_published: 0,
            steps_published: 0,
        }
    }

    /// Whether the slow effects are assessed at an estimator boundary where
    /// the statistics hold `samples` (and when next, if so).
    pub fn due(&mut self, samples: u64) -> bool {
        if samples < self.next_at {
            return false;
        }
        let gap_s = LOWFREQ_EVERY_S.max(samples as f64 * self.tau0_s / LOWFREQ_GROWTH);
        self.next_at = samples + (gap_s / self.tau0_s).round() as u64;
        true
    }

    /// Assess the slow effects of `pipe`, whose estimates are `est`; true when
    /// the statistics should restart now (never at the `last` update).
    pub fn assess(&mut self, pipe: &Pipeline, est: &NoiseEstimates, last: bool) -> bool {
        let (Some(spikes), Some(series)) = (pipe.spike_report(), pipe.block_series()) else {
            return false;
        };
        let fine = FineNoise {
            arw_dpsh: est.arw_dpsh.value.unwrap_or(0.0),
            quantization_arcsec: est.quantization_arcsec.value.unwrap_or(0.0),
        };
        // the ramp is tested at every assessment: the estimates between two
        // assessments may find one the stage has already rejected
        let (mut dq, correction) = quality::assess(spikes, &series, fine, true);
        dq.stationary = pipe
            .davar()
            .and_then(|d| d.stationarity(fine.quantization_arcsec));
        let elapsed_s = pipe.samples_in() as f64 * self.tau0_s;
        let settled = dq
            .warmup
            .as_ref()
            .map(|w| elapsed_s >= SETTLED_TAUS * w.tau_s.ci95[1].max(w.tau_s.value));
        self.settling = self.excluded.is_none() && settled == Some(false);
        let restart = !last && self.excluded.is_none() && settled == Some(true);
        self.held = (!restart && !correction.is_empty()).then(|| held(&dq, &correction));
        self.ramp_rejected = !restart && correction.ramp_rejected();
        self.latest = Some(self.joined(dq));
        restart
    }

    /// The slow effects the live estimates still hold, in words (`None`:
    /// none found, or the statistics restarted after the warm-up): an
    /// acceptance test does not fail a coefficient they inflate meanwhile.
    pub fn held(&self) -> Option<&str> {
        self.held.as_deref()
    }

    /// `dq` of the current statistics with times from the start of the run,
    /// joined with what came before a restart.
    fn joined(&self, mut dq: DataQuality) -> DataQuality {
        let base_s = self.base as f64 * self.tau0_s;
        let shift = |i: &mut quality::Interval| {
            i.value += base_s;
            i.ci95[0] += base_s;
            i.ci95[1] += base_s;
        };
        for t in &mut dq.outliers.at_s {
            *t += base_s;
        }
        for s in &mut dq.steps {
            shift(&mut s.at_s);
        }
        if let Some(w) = &self.excluded {
            dq.warmup = Some(w.clone());
        }
        if let Some(r) = &self.retired {
            let o = &mut dq.outliers;
            o.count += r.outliers.count;
            o.excluded &= r.outliers.excluded;
            o.heavy_tailed_windows += r.outliers.heavy_tailed_windows;
            let mut at = r.outliers.at_s.clone();
            at.extend_from_slice(&o.at_s);
            at.truncate(MAX_LISTED);
            o.at_s = at;
            let mut steps = r.steps.clone();
            steps.append(&mut dq.steps);
            dq.steps = steps;
        }
        dq
    }

    /// The statistics restart at uniform sample `at` after `old` (finished:
    /// its glitch filter has decided every sample) and its warm-up.
    pub fn restart(&mut self, old: &Pipeline, at: u64) {
        let report = old.spike_report().cloned().unwrap_or_default();
        let latest = self.latest.take();
        self.retired = Some(Retired {
            outliers: Outliers::from_report(&report, self.tau0_s),
            excluded: report.excluded,
            steps: latest.as_ref().map(|d| d.steps.clone()).unwrap_or_default(),
        });
        self.excluded = latest
            .as_ref()
            .and_then(|d| d.warmup.clone())
            .map(|w| Warmup {
                handled: "excluded".into(),
                excluded_s: at as f64 * self.tau0_s,
                ..w
            });
        self.latest = latest.map(|mut d| {
            d.warmup = self.excluded.clone();
            d
        });
        self.settling = false;
        self.ramp_rejected = false;
        self.base = at;
        self.next_at = (LOWFREQ_EVERY_S / self.tau0_s).round() as u64;
    }

    /// The latest assessment of the current statistics rejected the rate
    /// ramp: their estimates report it as a bound, as `analyze` does.
    pub fn ramp_rejected(&self) -> bool {
        self.ramp_rejected
    }

    /// Seconds of the run the restart left out, if it happened.
    pub fn excluded_s(&self) -> Option<f64> {
        self.excluded.as_ref().map(|w| w.excluded_s)
    }

    /// The latest findings, joined with what came before a restart.
    pub fn report(&self) -> Option<DataQuality> {
        self.latest.clone()
    }

    /// Publish the counts of `pipe` (the current statistics) and the latest
    /// findings: counters, warm-up gauges, the status line.
    pub fn publish(&mut self, pipe: &Pipeline, m: &GyroMetrics, status: Option<&LiveStatus>) {
        let report = pipe.spike_report();
        let retired = self.retired.as_ref();
        let outliers = report.map_or(0, |r| r.count) + retired.map_or(0, |r| r.outliers.count);
        let excluded = report.map_or(0, |r| r.excluded) + retired.map_or(0, |r| r.excluded);
        if outliers > self.outliers_published {
            m.add_outliers(outliers - self.outliers_published);
            self.outliers_published = outliers;
        }
        let steps = self.latest.as_ref().map_or(0, |d| d.steps.len() as u64);
        if steps > self.steps_published {
            m.add_bias_steps(steps - self.steps_published);
            self.steps_published = steps;
        }
        let warmup = self.latest.as_ref().and_then(|d| d.warmup.as_ref());
        m.set_warmup(
            self.settling,
            warmup.map(|w| (w.amplitude_dph.value, w.tau_s.value)),
        );
        if let Some(st) = status {
            st.set_quality(StatusQuality {
                warmup_settling_tau_s: warmup.filter(|_| self.settling).map(|w| w.tau_s.value),
                warmup_excluded_s: self.excluded_s(),
                outliers_excluded: excluded,
                steps,
            });
        }
    }
}

/// The effects of `dq` that `correction` would remove, in words.
fn held(dq: &DataQuality, correction: &quality::lowfreq::Correction) -> String {
    let mut what = Vec::new();
    if dq.warmup.is_some() {
        what.push("a warm-up");
    }
    if !dq.steps.is_empty() {
        what.push("bias steps");
    }
    if correction.has_thermal() {
        what.push("a thermal response");
    }
    format!("{} in the live statistics", what.join(" and "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{PipelineConfig, PipelineOutput};
    use crate::quality::Interval;
    use crate::sink::metrics::{GyroInfo, Metrics};

    fn interval(value: f64) -> Interval {
        Interval {
            value,
            ci95: [value - 1.0, value + 1.0],
        }
    }

    #[test]
    fn assessments_come_every_five_minutes_then_every_eighth_of_the_record() {
        // 200 Hz, estimator boundaries every 5 s
        let mut q = LiveQuality::new(0.005);
        let at: Vec<u64> = (1..=800)
            .map(|k| k * 1000)
            .filter(|&n| q.due(n))
            .map(|n| n / 200)
            .collect();
        let mut want: Vec<u64> = (1..=8).map(|k| 300 * k).collect();
        want.extend([2700, 3040, 3420, 3850]);
        assert_eq!(at, want);
        // a day at 1 kHz, boundaries every second: some 40 assessments
        let mut q = LiveQuality::new(0.001);
        let n = (1..=86_400u64).filter(|&s| q.due(s * 1000)).count();
        assert!((30..45).contains(&n), "{n}");
    }

    #[test]
    fn a_restart_keeps_what_came_before_with_times_from_the_start_of_the_run() {
        // the old statistics: a counter with two glitches (a +x, -x pair each)
        let mut old = Pipeline::new(&PipelineConfig::counts(200.0, 1.21)).unwrap();
        let mut counts = vec![10i64; 12_000];
        for k in [3_000, 7_000] {
            counts[k] += 400;
            counts[k + 1] -= 400;
        }
        let mut out = PipelineOutput::default();
        old.push_counts(&counts, &mut out);
        old.finish(&mut out);
        assert_eq!(old.spike_report().unwrap().count, 2);
        let mut q = LiveQuality::new(0.005);
        let step = StepFit {
            at_s: interval(20.0),
            amplitude_dph: interval(0.5),
        };
        let mut dq = quality::assess(
            &Default::default(),
            &crate::quality::blocks::BlockMeans::new(0.005).series(),
            FineNoise {
                arw_dpsh: 0.0,
                quantization_arcsec: 0.0,
            },
            false,
        )
        .0;
        dq.warmup = Some(Warmup {
            amplitude_dph: interval(3.0),
            tau_s: interval(60.0),
            handled: "modelled".into(),
            excluded_s: 0.0,
        });
        dq.steps = vec![step];
        q.latest = Some(dq.clone());
        q.settling = true;
        q.restart(&old, 12_000);
        assert_eq!(q.excluded_s(), Some(60.0));
        let w = q.report().unwrap().warmup.unwrap();
        assert_eq!((w.handled.as_str(), w.excluded_s), ("excluded", 60.0));
        // the new statistics find an outlier at 1 s and a step at 10 s of their own
        dq.warmup = None;
        dq.outliers.count = 1;
        dq.outliers.at_s = vec![1.0];
        dq.steps = vec![StepFit {
            at_s: interval(10.0),
            amplitude_dph: interval(-0.5),
        }];
        let j = q.joined(dq);
        assert_eq!(j.outliers.count, 3);
        assert_eq!(j.outliers.at_s, vec![15.0, 35.0, 61.0]);
        assert_eq!(j.steps.len(), 2);
        assert_eq!(j.steps[0].at_s.value, 20.0);
        assert_eq!(j.steps[1].at_s, interval(70.0));
        assert_eq!(j.warmup, Some(w));
        // counters: what came before plus the new statistics', never down
        q.latest = Some(j);
        let metrics = Metrics::new().unwrap();
        let m = metrics.gyro(&GyroInfo::labelled("x"));
        let fresh = Pipeline::new(&PipelineConfig::counts(200.0, 1.21)).unwrap();
        q.publish(&fresh, &m, None);
        q.publish(&fresh, &m, None);
        let text = metrics.encode();
        for line in [
            "sagnac_outliers_total{gyro=\"x\"} 2\n",
            "sagnac_bias_steps_total{gyro=\"x\"} 2\n",
            "sagnac_warmup_active{gyro=\"x\"} 0\n",
            "sagnac_warmup_tau_seconds{gyro=\"x\"} 60\n",
        ] {
            assert!(text.contains(line), "{line} in\n{text}");
        }
    }
}
