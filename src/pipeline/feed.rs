//! An [`Input`] through the [`Pipeline`]: the one way `analyze`, `report`
//! and the Python package run the chain on a file, block by block, so memory
//! stays bounded and the numbers are those the daemon computes live.
//!
//! Pulse counts take the exact integer path; rate values (and counts that
//! are not whole numbers) are converted to deg/h and take the rate path. The
//! samples made up to fill gaps go in as filled spans, which the statistics
//! leave out ([`Pipeline::push_counts_filled`]).
//!
//! With the data-quality stage on ([`PipelineConfig::data_quality`]) the
//! first pass also excludes glitches and keeps the block means; when the
//! slow effects it finds (a warm-up, bias steps, a significant thermal
//! response) call for a correction, a second pass reads the input again and
//! runs the corrected rate through a new pipeline, whose estimates are the
//! result ([`crate::quality`]).

use super::{Analysis, Pipeline, PipelineConfig, PipelineError, PipelineOutput};
use crate::input::plain::PlainError;
use crate::input::{Block, BlockSource, Input, InputError, Prefetch, StreamReport, Unit};
use crate::quality::davar::DavarMap;
use crate::quality::lowfreq::{Correction, FineNoise};
use crate::quality::{self, DataQuality};

/// Called with (samples so far, total expected if known) as input is read.
pub type Progress<'a> = &'a mut dyn FnMut(u64, Option<u64>);

/// One push into the pipeline, as a [`Tap`] sees it: for a caller that wants
/// more than the final analysis, such as the time series of `sagnac report`.
#[derive(Debug, Clone, Copy)]
pub struct TapBlock<'a> {
    /// Index of the first sample of this push in the record.
    pub first_sample: u64,
    /// The pulse increments pushed (gaps filled), for count input on the exact path.
    pub counts: Option<&'a [i64]>,
    /// The raw rate of the samples pushed, deg/h (gaps filled); empty for the
    /// final flush.
    pub rate_dph: &'a [f64],
    /// Temperature per pushed sample, deg C, when the input carries one.
    pub temp_c: Option<&'a [f64]>,
    /// Gaps (lost frames) in this push, and the samples lost in them.
    pub gaps: u64,
    pub lost_samples: u64,
    /// The clean and noise rates this push produced (delayed by
    /// [`Pipeline::latency`] samples and by the glitch filter's window; the
    /// final flush gives the rest).
    pub out: &'a PipelineOutput,
}

/// Called once per push into the pipeline, after it.
pub type Tap<'a> = &'a mut dyn FnMut(&TapBlock<'_>);

/// The pipeline configuration `input` is read with: its sample rate, and
/// for pulse counts its pulse weight (each an error naming the flag when
/// neither the file nor the command line gives it).
pub fn config_for(input: &Input) -> Result<PipelineConfig, InputError> {
    let rate = input.sample_rate_hz()?;
    Ok(match input.meta().unit {
        Unit::Counts => PipelineConfig::counts(rate, input.pulse_arcsec()?),
        _ => PipelineConfig::rates(rate),
    })
}

/// A pipeline that has taken a whole input.
#[derive(Debug)]
pub struct Fed {
    /// The pipeline, finished (every sample has its clean and noise values):
    /// the second pass's when the data-quality stage corrected the rate.
    pub pipeline: Pipeline,
    /// What the pass over the input met (gaps, frame counts, a break).
    pub report: StreamReport,
    /// What the data-quality stage found and did (`None`: the raw statistics).
    pub data_quality: Option<DataQuality>,
    /// The first pass's dynamic Allan deviation (glitches excluded, nothing
    /// else handled), for the report's figure.
    pub davar: Option<DavarMap>,
    /// The final analysis (the pipeline's, with the data-quality findings),
    /// computed once.
    analysis: Analysis,
}

impl Fed {
    /// The final analysis, with the data-quality findings.
    pub fn analysis(&self) -> Analysis {
        self.analysis.clone()
    }
}

/// Run every sample of `input` through a pipeline configured by `cfg`,
/// showing each push of the first pass to `tap`. Counts judged whole on
/// their first samples ([`crate::input::Meta::integral_tentative`]) that turn
/// out to hold a fraction are read again as rates, the result of an input
/// opened as not whole; with a `tap`, which must see one pass only, such an
/// input is checked whole first.
pub fn run(
    input: &Input,
    cfg: &PipelineConfig,
    progress: Progress,
    tap: Option<Tap>,
) -> Result<Fed, PipelineError> {
    let tentative = input.meta().integral_tentative;
    if tentative && tap.is_some() {
        let checked = input.checked_whole()?;
        return run(&checked, cfg, progress, tap);
    }
    let mut stream = Prefetch::new(input.stream()?)?;
    match run_from(input, &mut stream, cfg, progress, tap) {
        Err(PipelineError::Input(InputError::Plain(PlainError::NotInteger { .. })))
            if tentative =>
        {
            let rates = input.as_fractional();
            let mut stream = Prefetch::new(rates.stream()?)?;
            run_from(&rates, &mut stream, cfg, progress, None)
        }
        done => done,
    }
}

/// [`run`], the first pass taking its blocks from `first` (one axis of a
/// pass that reads several at once); a second pass, when the data-quality
/// stage corrects the rate, reads `input` again.
pub fn run_from(
    input: &Input,
    first: &mut dyn BlockSource,
    cfg: &PipelineConfig,
    progress: Progress,
    tap: Option<Tap>,
) -> Result<Fed, PipelineError> {
    let (pipe, report) = pass(input, first, cfg, progress, tap, None)?;
    let first = pipe.analysis();
    if !cfg.data_quality {
        return Ok(Fed {
            pipeline: pipe,
            report,
            data_quality: None,
            davar: None,
            analysis: first,
        });
    }
    let fine = FineNoise {
        arw_dpsh: first.estimates.arw_dpsh.value.unwrap_or(0.0),
        quantization_arcsec: first.estimates.quantization_arcsec.value.unwrap_or(0.0),
    };
    let spikes = pipe.spike_report().cloned().unwrap_or_default();
    let series = pipe
        .block_series()
        .expect("the data-quality stage keeps block means");
    let davar = pipe.davar().map(|d| d.map());
    // the stage's rejection of the ramp changes only a ramp found
    let ramp_found = first.estimates.rate_ramp_dphh.value.is_some();
    let (mut dq, correction) = quality::assess(&spikes, &series, fine, ramp_found);
    let (final_pipe, mut analysis) = if !correction.is_empty() {
        let mut again = Prefetch::new(input.stream()?)?;
        let p = pass(
            input,
            &mut again,
            cfg,
            &mut |_, _| {},
            None,
            Some(&correction),
        )?
        .0;
        let a = p.analysis();
        (p, a)
    } else if correction.ramp_rejected() && ramp_found {
        let mut p = pipe;
        p.set_ramp_rejected(true);
        let a = p.analysis();
        (p, a)
    } else {
        (pipe, first)
    };
    let q = analysis.estimates.quantization_arcsec.value.unwrap_or(0.0);
    dq.stationary = final_pipe.davar().and_then(|d| d.stationarity(q));
    analysis.data_quality = Some(dq.clone());
    Ok(Fed {
        pipeline: final_pipe,
        report,
        data_quality: Some(dq),
        davar,
        analysis,
    })
}

/// One pass over the input; with a `correction`, the statistics are of the
/// corrected rate ([`Pipeline::set_correction`]).
fn pass(
    input: &Input,
    stream: &mut dyn BlockSource,
    cfg: &PipelineConfig,
    progress: Progress,
    mut tap: Option<Tap>,
    correction: Option<&Correction>,
) -> Result<(Pipeline, StreamReport), PipelineError> {
    let meta = input.meta();
    let exact = meta.integral;
    let mut c = cfg.clone();
    if !exact {
        c.pulse_arcsec = None;
    }
    let mut pipe = Pipeline::new(&c)?;
    if let Some(corr) = correction {
        pipe.set_correction(corr.clone())?;
    }
    let mut block = Block::default();
    let mut out = PipelineOutput::default();
    let mut rates = Vec::new();
    let pulse = cfg.pulse_arcsec.unwrap_or(1.0);
    let tau0 = 1.0 / cfg.sample_rate_hz;
    while stream.next_block(&mut block)? {
        out.clear();
        let first_sample = pipe.samples_in();
        if !block.temp_c.is_empty() {
            pipe.push_temperature(first_sample, &block.temp_c);
        }
        rates.clear();
        if exact {
            pipe.push_counts_filled(&block.counts, &block.filled, &mut out);
            if tap.is_some() {
                let k = pulse * cfg.sample_rate_hz;
                rates.extend(block.counts.iter().map(|&c| c as f64 * k));
            }
        } else {
            raw_rates(meta.unit, &block, pulse, tau0, &mut rates);
            pipe.push_rates_dph_filled(&rates, &block.filled, &mut out)?;
        }
        if let Some(tap) = tap.as_deref_mut() {
            tap(&TapBlock {
                first_sample,
                counts: exact.then_some(&block.counts[..]),
                rate_dph: &rates,
                temp_c: (!block.temp_c.is_empty()).then_some(&block.temp_c[..]),
                gaps: block.gaps,
                lost_samples: block.lost_samples,
                out: &out,
            });
        }
        progress(pipe.samples_in(), meta.len_hint);
    }
    out.clear();
    pipe.finish(&mut out);
    if let Some(tap) = tap {
        tap(&TapBlock {
            first_sample: pipe.samples(),
            counts: None,
            rate_dph: &[],
            temp_c: None,
            gaps: 0,
            lost_samples: 0,
            out: &out,
        });
    }
    Ok((pipe, stream.report()))
}

/// The block's rate samples as deg/h.
fn raw_rates(unit: Unit, block: &Block, pulse: f64, tau0: f64, out: &mut Vec<f64>) {
    out.extend(block.values.iter().map(|&v| unit.to_dph(v, pulse, tau0)));
}
