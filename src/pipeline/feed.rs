//! An [`Input`] through the [`Pipeline`]: the one way `analyze`, `report`
//! and the Python package run the chain on a file, block by block, so memory
//! stays bounded and the numbers are those the daemon computes live.
//!
//! Pulse counts take the exact integer path; rate values (and counts that
//! are not whole numbers) are converted to deg/h and take the rate path. The
//! samples made up to fill gaps go in as filled spans, which the statistics
//! leave out ([`Pipeline::push_counts_filled`]).

use super::{Pipeline, PipelineConfig, PipelineError, PipelineOutput};
use crate::input::{Block, Input, InputError, StreamReport, Unit};

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
    /// [`Pipeline::latency`] samples; the final flush gives the rest).
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
    /// The pipeline, finished (every sample has its clean and noise values).
    pub pipeline: Pipeline,
    /// What the pass over the input met (gaps, frame counts, a break).
    pub report: StreamReport,
}

/// Run every sample of `input` through a pipeline configured by `cfg`,
/// showing each push to `tap`.
pub fn run(
    input: &Input,
    cfg: &PipelineConfig,
    progress: Progress,
    mut tap: Option<Tap>,
) -> Result<Fed, PipelineError> {
    let meta = input.meta();
    let mut c = cfg.clone();
    if !meta.integral {
        c.pulse_arcsec = None;
    }
    let mut pipe = Pipeline::new(&c)?;
    let mut stream = input.stream()?;
    let mut block = Block::default();
    let mut out = PipelineOutput::default();
    let mut rates = Vec::new();
    let pulse = cfg.pulse_arcsec.unwrap_or(1.0);
    let tau0 = 1.0 / cfg.sample_rate_hz;
    while stream.next_block(&mut block)? {
        out.clear();
        let first_sample = pipe.samples();
        rates.clear();
        if meta.integral {
            pipe.push_counts_filled(&block.counts, &block.filled, &mut out);
            if tap.is_some() {
                let k = pulse * cfg.sample_rate_hz;
                rates.extend(block.counts.iter().map(|&c| c as f64 * k));
            }
        } else {
            let unit = meta.unit;
            rates.extend(block.values.iter().map(|&v| unit.to_dph(v, pulse, tau0)));
            pipe.push_rates_dph_filled(&rates, &block.filled, &mut out)?;
        }
        if let Some(tap) = tap.as_deref_mut() {
            tap(&TapBlock {
                first_sample,
                counts: meta.integral.then_some(&block.counts[..]),
                rate_dph: &rates,
                temp_c: (!block.temp_c.is_empty()).then_some(&block.temp_c[..]),
                gaps: block.gaps,
                lost_samples: block.lost_samples,
                out: &out,
            });
        }
        progress(pipe.samples(), meta.len_hint);
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
    Ok(Fed {
        pipeline: pipe,
        report: stream.report(),
    })
}
