//! The synchronous processing chain shared by `sagnac analyze` and the daemon:
//!
//! ```text
//! pulse increments (or rates) --> rate, arcsec/s
//!    |-> QnSplitter (streaming sym8)  --> clean, noise  (outputs, delayed by latency())
//!    |-> OctaveAllan x3 (raw exact counts, clean, noise)
//!    |-> wavelet level variances of the rate (deep) and of the angle (fine)
//!    |-> least-squares slope (rate ramp)
//! analysis() --> estimator (model::estimate) + Allan curves with CIs
//! ```
//!
//! Gaps: samples made up by the gap fill ([`Pipeline::push_counts_filled`])
//! flow through the outputs unchanged (the angle stays continuous), while the
//! level variances (rate and angle) leave out every coefficient whose support
//! touches one ([`crate::dsp::gaps`]) and the Allan sums every term with a
//! filled phase point; counts (`n_coef`, `n_terms`) are of what remains. Not
//! yet masked: the QN splitter's running per-level statistics (its gains) and
//! the rate-ramp slope, which see the filled samples as data.
//!
//! Everything is streaming with memory independent of the record length, and
//! results do not depend on how the input is split into blocks, so replaying a
//! capture through the daemon gives exactly what `analyze` gives on the file.

use std::ops::Range;

use serde::Serialize;

use crate::allan::streaming::{OctaveAllan, StreamConfig, StreamError, StreamPoint};
use crate::allan::{self, AllanPoint};
use crate::dsp::DspError;
use crate::dsp::bank::{AnalysisOutput, MAX_LEVELS, StreamingAnalysis};
use crate::dsp::gaps::{MaskCascade, good_segments};
use crate::dsp::qn::{QnConfig, QnSplitter};
use crate::dsp::wavelet::Wavelet;
use crate::model::baseline::{self, AdevPoint, BaselineEstimates};
use crate::model::estimate::{
    self, AllanObs, Counter, EstimatorInput, EstimatorOutput, FilterEstimate, NoiseEstimates,
    RampAccumulator,
};
use crate::model::fit::{FitOptions, LevelObs};
use crate::quality::blocks::BlockMeans;
use crate::quality::davar::Davar;
use crate::quality::lowfreq::Correction;
use crate::quality::spikes::{Emitted, Series, SpikeFilter};

pub mod axes;
pub mod feed;

/// Errors building or running the pipeline.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("pipeline configuration: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    #[error("wavelet stage")]
    Dsp(#[from] DspError),
    #[error("Allan stage")]
    Allan(#[from] StreamError),
    #[error(transparent)]
    Input(#[from] crate::input::InputError),
}

/// Configuration of the chain.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Pulse weight, arcsec, for count input; `None` for rate input.
    pub pulse_arcsec: Option<f64>,
    /// Wavelet of the QN-removal bank and of the level variances.
    pub wavelet: String,
    /// Depth of the QN-removal bank; `None` = automatic.
    pub levels: Option<u32>,
    /// Largest averaging factor with full overlap in the Allan accumulators.
    pub allan_cap: u64,
    /// Run the data-quality stage ([`crate::quality`]): glitches excluded as
    /// gaps before anything else sees the samples, block means and the
    /// dynamic Allan deviation kept for the slow effects. Off: the raw
    /// statistics (`--raw-statistics`).
    pub data_quality: bool,
}

impl PipelineConfig {
    /// Defaults for count input at `sample_rate_hz` with pulse weight `pulse_arcsec`.
    pub fn counts(sample_rate_hz: f64, pulse_arcsec: f64) -> Self {
        PipelineConfig {
            sample_rate_hz,
            pulse_arcsec: Some(pulse_arcsec),
            wavelet: "sym8".into(),
            levels: None,
            allan_cap: 1 << 16,
            data_quality: true,
        }
    }
    /// Defaults for rate input (deg/h) at `sample_rate_hz`.
    pub fn rates(sample_rate_hz: f64) -> Self {
        PipelineConfig {
            pulse_arcsec: None,
            ..Self::counts(sample_rate_hz, 1.0)
        }
    }
    fn validate(&self) -> Result<(), PipelineError> {
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(PipelineError::Config {
                key: "sample_rate_hz",
                value: self.sample_rate_hz.to_string(),
                reason: "must be > 0",
            });
        }
        if let Some(d) = self.pulse_arcsec
            && !(d.is_finite() && d > 0.0)
        {
            return Err(PipelineError::Config {
                key: "pulse_arcsec",
                value: d.to_string(),
                reason: "must be > 0",
            });
        }
        Ok(())
    }
}

/// Clean and noise rates produced by a push, deg/h, aligned with the input
/// delayed by [`Pipeline::latency`] samples.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PipelineOutput {
    pub clean_dph: Vec<f64>,
    pub noise_dph: Vec<f64>,
}

impl PipelineOutput {
    pub fn clear(&mut self) {
        self.clean_dph.clear();
        self.noise_dph.clear();
    }
}

/// Allan curves of the three channels.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AllanCurves {
    pub raw: Vec<AllanPoint>,
    pub clean: Vec<AllanPoint>,
    pub noise: Vec<AllanPoint>,
}

/// The baseline estimators on the same data, for comparison.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Baselines {
    /// MATLAB's graphical recipe on the raw Allan deviation.
    pub graphical: BaselineEstimates,
    /// Weighted least squares of the IEEE 952 sum on the raw Allan variance.
    pub wls_raw: BaselineEstimates,
}

/// Goodness of fit of the estimator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitSummary {
    pub chi2_per_dof: f64,
    /// Degrees of freedom of the chi-square (observations less fitted parameters).
    pub dof: f64,
    /// False when the noise model does not describe the record (chi-square
    /// beyond its 99.9 % point; the intervals are then widened by the misfit).
    pub ok: bool,
    pub observations: usize,
}

/// What `analyze` prints and the daemon publishes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    pub estimates: NoiseEstimates,
    pub allan: AllanCurves,
    pub samples: u64,
    pub duration_s: f64,
    pub fit: FitSummary,
    /// The readout filter the data show, or `null`.
    pub readout_filter: Option<FilterEstimate>,
    pub baselines: Baselines,
    /// What the data-quality stage found and handled (absent with the raw
    /// statistics).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_quality: Option<crate::quality::DataQuality>,
}

/// Streaming per-level mean squares of a DWT, to any depth (two cascaded
/// analysis banks), counting only coefficients free of the start-up transient.
#[derive(Debug, Clone)]
struct LevelAccumulator {
    first: StreamingAnalysis,
    second: Option<StreamingAnalysis>,
    out1: AnalysisOutput,
    out2: AnalysisOutput,
    skip: u64,
    seen: Vec<u64>,
    /// Coefficients summed per level (transient-free and not touching a filled sample).
    count: Vec<u64>,
    sum_sq: Vec<f64>,
    blocks: Option<BlockSums>,
    /// Which coefficients touch a filled input sample.
    mask: MaskCascade,
    bad: Vec<Range<usize>>,
}

/// Per-block sums of the detail squares of every level, for a batch-means
/// variance of statistics built from them: the record is cut into blocks of
/// `2^span_log2` samples (by coefficient index, so chunking cannot change
/// them), at most `MAX_BLOCKS`, merged pairwise as the record grows.
#[derive(Debug, Clone)]
struct BlockSums {
    span_log2: u32,
    /// `sums[j][b]`: (sum of squares, coefficient count) of level j+1 in block b.
    sums: Vec<Vec<(f64, u64)>>,
}

const MAX_BLOCKS: usize = 64;

/// `sum v_i^2` in eight independent partial sums (vectorised; a fixed order
/// for a given slice).
fn sum_sq(v: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    let chunks = v.chunks_exact(8);
    let tail: f64 = chunks.remainder().iter().map(|x| x * x).sum();
    for c in chunks {
        for l in 0..8 {
            acc[l] += c[l] * c[l];
        }
    }
    ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7])) + tail
}

impl BlockSums {
    /// Add level `j+1`'s coefficients `d`, the first of index `first_index`;
    /// returns their sum of squares (the sum of the per-block parts).
    fn add(&mut self, j: usize, first_index: u64, d: &[f64]) -> f64 {
        // level j+1 has one coefficient per 2^(j+1) samples
        let shift = self.span_log2.saturating_sub(j as u32 + 1);
        let per_block = 1u64 << shift;
        let mut k = first_index;
        let mut rest = d;
        let mut total = 0.0;
        while !rest.is_empty() {
            let b = (k >> shift) as usize;
            let take = ((b as u64 + 1) * per_block - k).min(rest.len() as u64) as usize;
            let s = sum_sq(&rest[..take]);
            total += s;
            let level = &mut self.sums[j];
            if level.len() <= b {
                level.resize(b + 1, (0.0, 0));
            }
            level[b].0 += s;
            level[b].1 += take as u64;
            k += take as u64;
            rest = &rest[take..];
        }
        if self.sums[j].len() > MAX_BLOCKS {
            self.merge();
        }
        total
    }

    fn merge(&mut self) {
        self.span_log2 += 1;
        for level in &mut self.sums {
            let merged: Vec<(f64, u64)> = level
                .chunks(2)
                .map(|c| c.iter().fold((0.0, 0), |a, x| (a.0 + x.0, a.1 + x.1)))
                .collect();
            *level = merged;
        }
    }
}

impl LevelAccumulator {
    fn new(w: &Wavelet, levels: u32) -> Result<Self, PipelineError> {
        let l1 = levels.min(MAX_LEVELS);
        let second = if levels > l1 {
            Some(StreamingAnalysis::new(w, (levels - l1).min(MAX_LEVELS))?)
        } else {
            None
        };
        Ok(LevelAccumulator {
            first: StreamingAnalysis::new(w, l1)?,
            second,
            out1: AnalysisOutput::default(),
            out2: AnalysisOutput::default(),
            // a coefficient's support reaches back (L-1)(2^j - 1) samples: the
            // first L-1 coefficients of every level touch the zero pre-history
            skip: w.len() as u64 - 1,
            seen: vec![0; levels as usize],
            count: vec![0; levels as usize],
            sum_sq: vec![0.0; levels as usize],
            blocks: None,
            mask: MaskCascade::new(w.len(), levels as usize),
            bad: Vec::new(),
        })
    }

    /// Also keep per-block sums (for a batch-means variance).
    fn with_blocks(mut self) -> Self {
        self.blocks = Some(BlockSums {
            span_log2: 16,
            sums: vec![Vec::new(); self.seen.len()],
        });
        self
    }

    #[cfg(test)]
    fn push(&mut self, x: &[f64]) {
        self.push_masked(x, &[]);
    }

    /// Push samples; `filled` (absolute sample indices, sorted) are the filled
    /// ones among them (and possibly later ones).
    fn push_masked(&mut self, x: &[f64], filled: &[Range<u64>]) {
        for r in filled {
            self.mask.add_input(r.clone());
        }
        let mut out1 = std::mem::take(&mut self.out1);
        out1.approx.clear();
        for d in &mut out1.details {
            d.clear();
        }
        self.first.push(x, &mut out1);
        let n1 = out1.details.len();
        for (j, d) in out1.details.iter().enumerate() {
            self.acc(j, d);
        }
        if let Some(second) = &mut self.second {
            let mut out2 = std::mem::take(&mut self.out2);
            out2.approx.clear();
            for d in &mut out2.details {
                d.clear();
            }
            second.push(&out1.approx, &mut out2);
            for (j, d) in out2.details.iter().enumerate() {
                self.acc(n1 + j, d);
            }
            self.out2 = out2;
        }
        self.out1 = out1;
    }

    /// Add level `j+1`'s new coefficients `d` (those after the start-up
    /// transient and not touching a filled sample).
    #[inline]
    fn acc(&mut self, j: usize, d: &[f64]) {
        let seen = self.seen[j];
        let start = self.skip.saturating_sub(seen).min(d.len() as u64) as usize;
        self.seen[j] += d.len() as u64;
        if self.mask.is_clear() {
            let d = &d[start..];
            self.count[j] += d.len() as u64;
            self.sum_sq[j] += match &mut self.blocks {
                Some(b) => b.add(j, seen + start as u64, d),
                None => sum_sq(d),
            };
            return;
        }
        self.bad.clear();
        self.mask
            .bad_spans(j, seen + start as u64, seen + d.len() as u64, &mut self.bad);
        let d = &d[start..];
        let first = seen + start as u64;
        let mut s = 0.0;
        for g in good_segments(d.len(), &self.bad) {
            self.count[j] += g.len() as u64;
            s += match &mut self.blocks {
                Some(b) => b.add(j, first + g.start as u64, &d[g]),
                None => sum_sq(&d[g]),
            };
        }
        self.sum_sq[j] += s;
    }

    /// The per-block observations (blocks of equal length; a last block
    /// shorter than half of them is left out).
    fn block_observations(&self) -> Vec<Vec<LevelObs>> {
        let Some(b) = &self.blocks else {
            return Vec::new();
        };
        let n_blocks = b.sums.first().map_or(0, |l| l.len());
        let full = 1u64 << b.span_log2.saturating_sub(1);
        (0..n_blocks)
            .filter(|&i| b.sums[0][i].1 * 2 >= full)
            .map(|i| {
                b.sums
                    .iter()
                    .enumerate()
                    .filter_map(|(j, l)| {
                        l.get(i).filter(|x| x.1 > 0).map(|x| LevelObs {
                            level: j as u32 + 1,
                            n_coef: x.1 as f64,
                            mean_sq: x.0 / x.1 as f64,
                        })
                    })
                    .collect()
            })
            .collect()
    }

    fn observations(&self) -> Vec<LevelObs> {
        (0..self.seen.len())
            .filter_map(|j| {
                let n = self.count[j];
                (n > 0).then(|| LevelObs {
                    level: j as u32 + 1,
                    n_coef: n as f64,
                    mean_sq: self.sum_sq[j] / n as f64,
                })
            })
            .collect()
    }
}

/// The chain.
#[derive(Debug)]
pub struct Pipeline {
    cfg: PipelineConfig,
    tau0_s: f64,
    wavelet: Wavelet,
    splitter: QnSplitter,
    raw_counts: Option<OctaveAllan<i64>>,
    raw_rate: Option<OctaveAllan>,
    clean_allan: OctaveAllan,
    noise_allan: OctaveAllan,
    rate_levels: LevelAccumulator,
    angle_levels: LevelAccumulator,
    ramp: RampAccumulator,
    angle: f64,
    samples: u64,
    /// Filled (not measured) samples pushed.
    filled: u64,
    rate_buf: Vec<f64>,
    angle_buf: Vec<f64>,
    /// This push's filled spans, absolute sample indices; the same one sample
    /// longer (a rate sample after a filled one is not measured either).
    fill_abs: Vec<Range<u64>>,
    fill_rate: Vec<Range<u64>>,
    /// The data-quality stage, when on.
    quality: Option<Quality>,
    /// [`EstimatorInput::ramp_se_factor`] (1 unless set) and
    /// [`EstimatorInput::ramp_joint_z`], [`EstimatorInput::ramp_rejected`].
    ramp_se_factor: f64,
    ramp_joint_z: Option<f64>,
    ramp_rejected: bool,
    /// What the data-quality stage subtracts from the rate ([`Self::set_correction`]).
    correction: Option<Correction>,
}

/// The data-quality stage's parts that run inside the pipeline.
#[derive(Debug)]
struct Quality {
    spikes: SpikeFilter,
    emitted: Emitted,
    blocks: BlockMeans,
    davar: Davar,
    /// Samples taken in (emitted or pending in the spike filter).
    taken: u64,
}

/// The Allan accumulators' configuration for `cfg`, values scaled by `scale`.
fn allan_config(cfg: &PipelineConfig, scale: f64) -> StreamConfig {
    StreamConfig {
        tau0_s: 1.0 / cfg.sample_rate_hz,
        full_overlap_cap: cfg.allan_cap,
        scale,
        ..StreamConfig::default()
    }
}

/// Depth of the deep (rate) level accumulator.
const DEEP_LEVELS: u32 = 32;

impl Pipeline {
    pub fn new(cfg: &PipelineConfig) -> Result<Pipeline, PipelineError> {
        cfg.validate()?;
        let tau0_s = 1.0 / cfg.sample_rate_hz;
        let wavelet = Wavelet::by_name(&cfg.wavelet)?;
        let mut qn = QnConfig::new(cfg.sample_rate_hz);
        qn.wavelet = cfg.wavelet.clone();
        qn.levels = cfg.levels;
        qn.validate()?;
        let splitter = QnSplitter::new(&qn)?;
        let j = splitter.levels();
        let scfg = |scale: f64| allan_config(cfg, scale);
        let (raw_counts, raw_rate) = match cfg.pulse_arcsec {
            Some(d) => (Some(OctaveAllan::counts(scfg(d))?), None),
            None => (None, Some(OctaveAllan::freq(scfg(1.0))?)),
        };
        Ok(Pipeline {
            cfg: cfg.clone(),
            tau0_s,
            splitter,
            raw_counts,
            raw_rate,
            clean_allan: OctaveAllan::freq(scfg(1.0))?,
            noise_allan: OctaveAllan::freq(scfg(1.0))?,
            rate_levels: LevelAccumulator::new(&wavelet, DEEP_LEVELS)?,
            angle_levels: LevelAccumulator::new(&wavelet, (j + 2).min(MAX_LEVELS))?.with_blocks(),
            wavelet,
            ramp: RampAccumulator::default(),
            angle: 0.0,
            samples: 0,
            filled: 0,
            rate_buf: Vec::new(),
            angle_buf: Vec::new(),
            fill_abs: Vec::new(),
            fill_rate: Vec::new(),
            quality: cfg.data_quality.then(|| Quality {
                spikes: SpikeFilter::new(if cfg.pulse_arcsec.is_some() {
                    Series::Counts
                } else {
                    Series::Rates
                }),
                emitted: Emitted::default(),
                blocks: BlockMeans::new(tau0_s),
                davar: Davar::new(tau0_s),
                taken: 0,
            }),
            ramp_se_factor: 1.0,
            ramp_joint_z: None,
            ramp_rejected: false,
            correction: None,
        })
    }

    /// The statistics are of a rate from which effects fitted beside a ramp
    /// were subtracted: the ramp's standard error is widened by `se_factor`
    /// (at least 1), and a ramp is reported only when its z in the joint
    /// fit, `joint_z`, passes too
    /// ([`crate::quality::lowfreq::Correction::ramp_se_factor`], [`crate::quality::lowfreq::Correction::ramp_joint_z`]).
    fn set_fitted_effects(&mut self, se_factor: f64, joint_z: Option<f64>) {
        self.ramp_se_factor = se_factor.max(1.0);
        self.ramp_joint_z = joint_z;
    }

    /// Whether the data-quality stage tested the rate ramp and rejected it
    /// ([`crate::quality::lowfreq::Correction::ramp_rejected`]): the
    /// estimates then report it as a bound. Returns whether that changed.
    pub fn set_ramp_rejected(&mut self, rejected: bool) -> bool {
        std::mem::replace(&mut self.ramp_rejected, rejected) != rejected
    }

    /// The pulse counter whose readout error the statistics carry, at the
    /// mean input it saw (with a correction, the corrected rate's mean plus
    /// the correction's): its sawtooth corrects the quantization estimate
    /// ([`crate::model::estimate::Counter`]).
    fn counter(&self) -> Option<Counter> {
        let seen_dph = match &self.correction {
            Some(c) if self.samples > 0 => c.mean_dph(0.0, self.samples as f64 * self.tau0_s),
            _ => 0.0,
        };
        self.cfg.pulse_arcsec.map(|d| Counter {
            pulse_arcsec: d,
            pulses_per_sample: (self.ramp.mean() + seen_dph) * self.tau0_s / d,
        })
    }

    /// Subtract `correction` (the slow effects the data-quality stage fitted)
    /// from the rate before the statistics: the second pass over a record,
    /// set before its first sample. The effects it was fitted beside and its
    /// verdict on the ramp go to the estimates. A counter keeps its glitch
    /// test on the increments and its readout's sawtooth in the quantization
    /// estimate; its raw Allan variance is then of the corrected rate.
    pub fn set_correction(&mut self, correction: Correction) -> Result<(), PipelineError> {
        assert_eq!(
            self.samples_in(),
            0,
            "a correction is set before the first sample"
        );
        self.set_fitted_effects(correction.ramp_se_factor(), correction.ramp_joint_z());
        self.set_ramp_rejected(correction.ramp_rejected());
        if self.raw_counts.take().is_some() {
            self.raw_rate = Some(OctaveAllan::freq(allan_config(&self.cfg, 1.0))?);
        }
        self.correction = Some(correction);
        Ok(())
    }

    /// Samples through the statistics (those a glitch filter still holds are not).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples pushed in (the statistics' and those the glitch filter holds).
    pub fn samples_in(&self) -> u64 {
        self.quality.as_ref().map_or(self.samples, |q| q.taken)
    }

    /// Temperatures (deg C) of samples `first..` (absolute indices), for the
    /// data-quality stage's thermal analysis.
    pub fn push_temperature(&mut self, first: u64, temp_c: &[f64]) {
        if let Some(q) = &mut self.quality {
            q.blocks.push_temps(first, temp_c);
        }
    }

    /// What the glitch filter found so far.
    pub fn spike_report(&self) -> Option<&crate::quality::spikes::SpikeReport> {
        self.quality.as_ref().map(|q| q.spikes.report())
    }

    /// Block means of the rate and temperature so far.
    pub fn block_series(&self) -> Option<crate::quality::blocks::BlockSeries> {
        self.quality.as_ref().map(|q| q.blocks.series())
    }

    /// The dynamic Allan deviation so far.
    pub fn davar(&self) -> Option<&Davar> {
        self.quality.as_ref().map(|q| &q.davar)
    }
    /// Delay of the clean/noise outputs, samples.
    pub fn latency(&self) -> usize {
        self.splitter.latency()
    }
    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// Filled (not measured) samples pushed.
    pub fn filled_samples(&self) -> u64 {
        self.filled
    }

    /// Detail-level mean squares of the rate, (arcsec/s)^2, as the estimator
    /// gets them (transient-free coefficients not touching a filled sample).
    pub fn rate_level_observations(&self) -> Vec<LevelObs> {
        self.rate_levels.observations()
    }

    /// The same for the angle (arcsec^2), the QN band.
    pub fn angle_level_observations(&self) -> Vec<LevelObs> {
        self.angle_levels.observations()
    }

    /// Push pulse increments (count input), all measured.
    pub fn push_counts(&mut self, counts: &[i64], out: &mut PipelineOutput) {
        self.push_counts_filled(counts, &[], out);
    }

    /// Push pulse increments with `filled[i]` true for a sample made up by the
    /// gap fill (see [`Self::push_counts_filled`]).
    pub fn push_counts_masked(
        &mut self,
        counts: &[i64],
        filled: &[bool],
        out: &mut PipelineOutput,
    ) {
        assert_eq!(
            counts.len(),
            filled.len(),
            "push_counts_masked: one flag per sample"
        );
        self.push_counts_filled(counts, &crate::dsp::gaps::spans_of(filled), out);
    }

    /// Push pulse increments of which the spans `filled` (indices into
    /// `counts`, sorted, disjoint) were made up by the gap fill
    /// ([`crate::input::frame::fill`]). They go into the outputs and keep the
    /// angle continuous, but the statistics leave out every wavelet
    /// coefficient whose support touches one of them and every Allan second
    /// difference with one of its three phase points inside a gap (a filled
    /// sample `k` makes the angle after it unknown; the angle after the
    /// measured sample that ends the gap is known again), and count
    /// coefficients and terms from what remains. A wavelet level much coarser
    /// than a gap keeps its coefficients ([`crate::dsp::gaps::GAP_SCALE`]); so
    /// that this does not depend on how the pushes split a gap, a span that
    /// runs on past the end of `counts` is given whole (its end beyond
    /// `counts.len()`), as [`crate::input::frame::FilledSeries::filled_in`] does.
    pub fn push_counts_filled(
        &mut self,
        counts: &[i64],
        filled: &[Range<usize>],
        out: &mut PipelineOutput,
    ) {
        let Some(q) = &mut self.quality else {
            return self.process_counts(counts, filled, out);
        };
        q.taken += counts.len() as u64;
        let mut e = std::mem::take(&mut q.emitted);
        e.clear();
        q.spikes.push_counts(counts, filled, &mut e);
        if !e.counts.is_empty() {
            self.process_counts(&e.counts, &e.filled, out);
        }
        if let Some(q) = &mut self.quality {
            q.emitted = e;
        }
    }

    fn process_counts(
        &mut self,
        counts: &[i64],
        filled: &[Range<usize>],
        out: &mut PipelineOutput,
    ) {
        self.set_filled(filled, counts.len());
        let d = self.cfg.pulse_arcsec.unwrap_or(1.0);
        if let Some(a) = &mut self.raw_counts {
            for r in &self.fill_abs {
                a.mark_filled(r.start + 1..r.end + 1);
            }
            a.push_block(counts);
        }
        let k = d / self.tau0_s;
        self.rate_buf.clear();
        self.rate_buf.extend(counts.iter().map(|&c| c as f64 * k));
        if self.correction.is_some() {
            self.correct_rate_buf();
            self.push_raw_rate()
                .expect("a counter's corrected rates are finite");
        }
        self.process_rates(out);
    }

    /// Subtract the correction, if any, from `rate_buf` (this push's rates).
    fn correct_rate_buf(&mut self) {
        if let Some(c) = &self.correction {
            let t0 = self.samples as f64 * self.tau0_s;
            for (i, r) in self.rate_buf.iter_mut().enumerate() {
                let t = t0 + i as f64 * self.tau0_s;
                *r -= c.mean_dph(t, t + self.tau0_s);
            }
        }
    }

    /// `rate_buf` into the raw rate's Allan accumulator, its filled spans marked.
    fn push_raw_rate(&mut self) -> Result<(), PipelineError> {
        if let Some(a) = &mut self.raw_rate {
            for r in &self.fill_abs {
                a.mark_filled(r.start + 1..r.end + 1);
            }
            a.push_block(&self.rate_buf)?;
        }
        Ok(())
    }

    /// Push rates in deg/h (== arcsec/s) (rate input).
    pub fn push_rates_dph(
        &mut self,
        rates: &[f64],
        out: &mut PipelineOutput,
    ) -> Result<(), PipelineError> {
        self.push_rates_dph_filled(rates, &[], out)
    }

    /// Push rates in deg/h with the spans `filled` made up (see
    /// [`Self::push_counts_filled`]).
    pub fn push_rates_dph_filled(
        &mut self,
        rates: &[f64],
        filled: &[Range<usize>],
        out: &mut PipelineOutput,
    ) -> Result<(), PipelineError> {
        let Some(q) = &mut self.quality else {
            return self.process_rates_dph(rates, filled, out);
        };
        q.taken += rates.len() as u64;
        let mut e = std::mem::take(&mut q.emitted);
        e.clear();
        q.spikes.push_rates(rates, filled, &mut e);
        let r = if e.rates.is_empty() {
            Ok(())
        } else {
            self.process_rates_dph(&e.rates, &e.filled, out)
        };
        if let Some(q) = &mut self.quality {
            q.emitted = e;
        }
        r
    }

    fn process_rates_dph(
        &mut self,
        rates: &[f64],
        filled: &[Range<usize>],
        out: &mut PipelineOutput,
    ) -> Result<(), PipelineError> {
        self.set_filled(filled, rates.len());
        self.rate_buf.clear();
        self.rate_buf.extend_from_slice(rates);
        self.correct_rate_buf();
        self.push_raw_rate()?;
        self.process_rates(out);
        Ok(())
    }

    fn set_filled(&mut self, filled: &[Range<usize>], n: usize) {
        self.fill_abs.clear();
        self.fill_rate.clear();
        let s0 = self.samples;
        for r in filled {
            let (a, b) = (r.start.min(n), r.end.min(n));
            if a >= b {
                continue;
            }
            self.filled += (b - a) as u64;
            // a span may run past this push: the mask takes its whole length
            // (how many levels it masks depends on it), so that the statistics
            // do not depend on where the pushes split a gap
            let span = s0 + a as u64..s0 + r.end.max(b) as u64;
            self.fill_rate.push(span.start..span.end + 1);
            self.fill_abs.push(span);
        }
        // the clean and noise channels: output sample k is input sample k
        for r in &self.fill_abs {
            self.clean_allan.mark_filled(r.start + 1..r.end + 1);
            self.noise_allan.mark_filled(r.start + 1..r.end + 1);
        }
    }

    fn process_rates(&mut self, out: &mut PipelineOutput) {
        if let Some(q) = &mut self.quality {
            let base = self.samples;
            // this push's filled spans, relative (from the absolute ones)
            let rel: Vec<Range<usize>> = self
                .fill_abs
                .iter()
                .map(|r| (r.start - base) as usize..(r.end - base) as usize)
                .collect();
            q.blocks.push_rates(base, &self.rate_buf, &rel);
            q.davar.push(&self.rate_buf, &rel);
        }
        let n0 = out.clean_dph.len();
        self.splitter
            .push(&self.rate_buf, &mut out.clean_dph, &mut out.noise_dph);
        self.rate_levels
            .push_masked(&self.rate_buf, &self.fill_rate);
        self.ramp.push_slice(&self.rate_buf);
        self.angle_buf.clear();
        for &r in &self.rate_buf {
            self.angle += r * self.tau0_s;
            self.angle_buf.push(self.angle);
        }
        self.angle_levels
            .push_masked(&self.angle_buf, &self.fill_abs);
        self.samples += self.rate_buf.len() as u64;
        self.feed_channels(n0, out);
    }

    fn feed_channels(&mut self, from: usize, out: &PipelineOutput) {
        // the channel accumulators see exactly the samples emitted (finite values)
        let _ = self.clean_allan.push_block(&out.clean_dph[from..]);
        let _ = self.noise_allan.push_block(&out.noise_dph[from..]);
    }

    /// End of stream: flush the wavelet bank so every sample has its clean and
    /// noise values.
    pub fn finish(&mut self, out: &mut PipelineOutput) {
        if let Some(q) = &mut self.quality {
            let mut e = std::mem::take(&mut q.emitted);
            e.clear();
            q.spikes.finish(&mut e);
            if !e.counts.is_empty() {
                self.process_counts(&e.counts, &e.filled, out);
            } else if !e.rates.is_empty() {
                // finite rates were checked as they came in
                let _ = self.process_rates_dph(&e.rates, &e.filled, out);
            }
        }
        let n0 = out.clean_dph.len();
        self.splitter.flush(&mut out.clean_dph, &mut out.noise_dph);
        self.feed_channels(n0, out);
    }

    fn raw_points(&self) -> Vec<StreamPoint> {
        let conf = allan::DEFAULT_CONFIDENCE;
        match (&self.raw_counts, &self.raw_rate) {
            (Some(a), _) => a.points(conf).unwrap_or_default(),
            (_, Some(a)) => a.points(conf).unwrap_or_default(),
            _ => Vec::new(),
        }
    }

    /// The estimator's full output (coefficients, the fit behind them, the
    /// rate slope and its spread under the fitted spectrum) from everything
    /// pushed so far.
    pub fn estimator_output(&self) -> EstimatorOutput {
        self.estimator_output_with(&FitOptions::default())
    }

    /// [`Pipeline::estimator_output`] with other fit options.
    pub fn estimator_output_with(&self, opts: &FitOptions) -> EstimatorOutput {
        self.estimate_from(&self.raw_points(), opts)
    }

    fn estimate_from(&self, raw_points: &[StreamPoint], opts: &FitOptions) -> EstimatorOutput {
        let levels = self.rate_levels.observations();
        let angle_levels = self.angle_levels.observations();
        let angle_blocks = self.angle_levels.block_observations();
        let allan_obs: Vec<AllanObs> = raw_points
            .iter()
            .map(|p| AllanObs {
                m: p.m,
                n_phase: self.n_phase(p),
                avar: p.avar,
                stride: p.stride,
                n_terms: p.n,
            })
            .collect();
        let input = EstimatorInput {
            tau0_s: self.tau0_s,
            n_samples: self.samples,
            dec_lo: self.wavelet.dec_lo(),
            dec_hi: self.wavelet.dec_hi(),
            levels: &levels,
            angle_levels: &angle_levels,
            angle_blocks: &angle_blocks,
            allan: &allan_obs,
            ramp: Some(self.ramp),
            counter: self.counter(),
            ramp_se_factor: self.ramp_se_factor,
            ramp_joint_z: self.ramp_joint_z,
            ramp_rejected: self.ramp_rejected,
        };
        estimate::estimate(&input, opts)
    }

    /// Phase points of a gap-free record giving the same number of terms as
    /// `p` has (the record's own count when nothing was filled).
    fn n_phase(&self, p: &StreamPoint) -> u64 {
        if self.filled == 0 {
            self.samples + 1
        } else {
            p.n.saturating_sub(1) * p.stride + 2 * p.m + 1
        }
    }

    /// Estimates and curves from everything pushed so far.
    pub fn analysis(&self) -> Analysis {
        let conf = allan::DEFAULT_CONFIDENCE;
        let raw_points = self.raw_points();
        let est = self.estimate_from(&raw_points, &FitOptions::default());
        let adev: Vec<AdevPoint> = raw_points
            .iter()
            .filter(|p| p.n > 0)
            .map(|p| AdevPoint {
                tau_s: p.tau_s,
                adev: p.dev,
                edf: p.edf,
            })
            .collect();
        Analysis {
            estimates: est.estimates,
            allan: AllanCurves {
                raw: to_points(&raw_points),
                clean: to_points(&self.clean_allan.points(conf).unwrap_or_default()),
                noise: to_points(&self.noise_allan.points(conf).unwrap_or_default()),
            },
            samples: self.samples,
            duration_s: self.samples as f64 * self.tau0_s,
            fit: FitSummary {
                chi2_per_dof: est.quality.chi2_per_dof,
                dof: est.quality.dof,
                ok: est.quality.ok,
                observations: est.fit.edf.len(),
            },
            readout_filter: est.readout_filter,
            baselines: Baselines {
                graphical: baseline::graphical(&adev),
                wls_raw: baseline::wls_raw(&adev),
            },
            data_quality: None,
        }
    }
}

fn to_points(p: &[StreamPoint]) -> Vec<AllanPoint> {
    p.iter()
        .filter(|p| p.n > 0 && p.avar.is_finite())
        .map(AllanPoint::from)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_sums_add_up_to_the_levels_and_ignore_chunking() {
        let w = Wavelet::by_name("sym8").unwrap();
        let mut s = 0x9E37_79B9_7F4A_7C15_u64;
        let x: Vec<f64> = (0..600_000)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let mut one = LevelAccumulator::new(&w, 10).unwrap().with_blocks();
        one.push(&x);
        let mut many = LevelAccumulator::new(&w, 10).unwrap().with_blocks();
        for c in x.chunks(7_919) {
            many.push(c);
        }
        let (a, b) = (one.blocks.as_ref().unwrap(), many.blocks.as_ref().unwrap());
        assert_eq!(a.span_log2, b.span_log2);
        for j in 0..10 {
            // every transient-free coefficient is in exactly one block
            let n: u64 = a.sums[j].iter().map(|x| x.1).sum();
            assert_eq!(n, one.seen[j] - one.skip, "level {}", j + 1);
            let tot: f64 = a.sums[j].iter().map(|x| x.0).sum();
            assert!((tot / one.sum_sq[j] - 1.0).abs() < 1e-12);
            for (p, q) in a.sums[j].iter().zip(&b.sums[j]) {
                assert_eq!(p.1, q.1);
                assert!((p.0 - q.0).abs() <= 1e-12 * p.0.abs());
            }
        }
        // 600 000 samples in blocks of 2^16: 9 full blocks and a short tail
        assert_eq!(a.span_log2, 16);
        assert_eq!(one.block_observations().len(), 9);
        // more than MAX_BLOCKS blocks merge pairwise
        let mut long = LevelAccumulator::new(&w, 2).unwrap().with_blocks();
        for _ in 0..8 {
            long.push(&x);
        }
        let l = long.blocks.as_ref().unwrap();
        assert_eq!(l.span_log2, 17);
        assert!(l.sums[0].len() <= MAX_BLOCKS);
    }
    /// A counter's record with a warm-up, corrected (the data-quality
    /// stage's second pass), keeps the counter's glitch test and readout: its
    /// quantization is the raw record's (a smooth correction leaves the
    /// fine scales alone) and nothing is taken for a glitch. The same rates
    /// read as a rate gyro's lose the readout: the sawtooth lines of this
    /// weakly dithered counter (d 0.76", Q 0.353", one pulse per 300
    /// samples) then count as white noise.
    #[test]
    fn a_corrected_counter_keeps_its_glitch_test_and_readout() {
        let model = crate::model::GyroModel::from_toml_str(
            "[gyro]\nsample_rate_hz = 2000\ninput_rate_dph = -3.589\npulse_arcsec = 0.7583\n\
             [noise]\nquantization_arcsec = 0.35298\narw_dpsh = 0.009762\nbias_instability_dph = 0.01206\n\
             [noise.warmup]\namplitude_dph = -2.0\ntau_s = 300.0\n",
            "test",
        )
        .unwrap();
        let mut sim = crate::model::sim::Simulator::new(&model, 5, Some(600.0)).unwrap();
        let mut counts = Vec::new();
        sim.next_block(1_200_000, &mut counts);
        let q = |p: &Pipeline| p.analysis().estimates.quantization_arcsec.value.unwrap();
        let glitches = |p: &Pipeline| p.spike_report().unwrap().count;
        let mut out = PipelineOutput::default();
        let cfg = PipelineConfig::counts(2000.0, 0.7583);
        let mut raw = Pipeline::new(&cfg).unwrap();
        raw.push_counts(&counts, &mut out);
        let mut corrected = Pipeline::new(&cfg).unwrap();
        corrected
            .set_correction(Correction::warmup(-2.0, 300.0))
            .unwrap();
        for c in counts.chunks(4099) {
            corrected.push_counts(c, &mut out);
        }
        let (a, b) = (q(&raw), q(&corrected));
        assert!((b / a - 1.0).abs() < 1e-4, "{a} {b}");
        assert_eq!((glitches(&raw), glitches(&corrected)), (0, 0));
        // the corrected rates read as a rate gyro's
        let w = Correction::warmup(-2.0, 300.0);
        let rates: Vec<f64> = (0..counts.len())
            .map(|i| {
                let t = i as f64 / 2000.0;
                counts[i] as f64 * 0.7583 * 2000.0 - w.mean_dph(t, t + 1.0 / 2000.0)
            })
            .collect();
        let mut as_rates = Pipeline::new(&PipelineConfig::rates(2000.0)).unwrap();
        as_rates.push_rates_dph(&rates, &mut out).unwrap();
        let c = q(&as_rates);
        assert!((c / a - 1.0).abs() > 3e-4, "{a} {c}");
    }
}
