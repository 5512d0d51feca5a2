//! Offline inputs for the pipeline: CSV/text files (pulse counts or a rate
//! column in any unit), raw frame captures (`.bin`) and MCAP recordings made
//! by `sagnac run`. Each is streamed block by block into a
//! [`Pipeline`](crate::pipeline::Pipeline), so memory stays bounded and the
//! numbers are exactly those the daemon computes live.
//!
//! Gaps (lost frames) are filled the same way everywhere: the pulses of the
//! gap, which the cumulative counter kept, are spread over the missing
//! samples as integers ([`crate::source::frame::FilledSeries`]), so the
//! series stays uniformly sampled and no angle is lost; the made-up samples
//! are marked, and the pipeline's statistics leave them out.

use std::path::{Path, PathBuf};

use crate::pipeline::{Pipeline, PipelineConfig, PipelineError, PipelineOutput};
use crate::sink::messages::SinkMessage;
use crate::sink::meta::{AGREE_REL, Contradiction, GyroOutput, check_flag};
use crate::sink::reader::{ReadError, read_metadata, scan_recording};
use crate::source::capture::{CaptureError, CaptureReader};
use crate::source::frame::FilledSeries;
use crate::source::input::{InputError, InputFormat, SampleReader};
use crate::units;

/// Unit of a CSV rate column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RateUnit {
    /// Pulse increments per sample (integers or decimals).
    Counts,
    /// deg/h.
    Dph,
    /// deg/s.
    Dps,
    /// rad/s.
    #[value(name = "rad_s")]
    RadS,
}

/// Errors of the offline readers.
#[derive(Debug, thiserror::Error)]
pub enum OfflineError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Recording(#[from] ReadError),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error("{path}: no samples")]
    Empty { path: PathBuf },
    #[error("{path}: /gyro/raw batches disagree on the sample period ({first_ns} ns, then {other_ns} ns)")]
    MixedRate { path: PathBuf, first_ns: u64, other_ns: u64 },
    #[error(
        "{path}: the /gyro/raw batch at t0 = {t0_ns} ns has a gap of {lost} lost samples \
         (more than {MAX_GAP_SAMPLES}: not a recording of a gyro that kept running)"
    )]
    ImplausibleGap { path: PathBuf, t0_ns: u64, lost: u64 },
    #[error("{path}: no samples before the file becomes unreadable at byte {offset}: {reason}")]
    BrokenBeforeSamples { path: PathBuf, offset: u64, reason: String },
    /// A value the input does not carry and no flag gave.
    #[error("{flag} is required: {} carries no {what}", path.display())]
    FlagRequired { flag: &'static str, path: PathBuf, what: &'static str },
    /// A flag that contradicts the recording.
    #[error(transparent)]
    Contradiction(#[from] Contradiction),
    /// A recording of rate samples, which this reader does not convert.
    #[error("{}: its metadata says output = rate (rate samples, not pulse counts): not supported here yet", path.display())]
    RateOutput { path: PathBuf },
}

/// Longest gap (lost samples) a recording may hold: 4.7 h at 1 kHz. The frame
/// decoder never reports more than 4096; a gap this long would have to be filled
/// with that many made-up samples.
pub const MAX_GAP_SAMPLES: u64 = 1 << 24;

/// Called with (samples so far, total expected if known) as input is read.
pub type Progress<'a> = &'a mut dyn FnMut(u64, Option<u64>);

const BLOCK: usize = 1 << 16;

/// Feed a CSV/text file. `unit = Counts` with `pulse_arcsec` set uses the exact
/// integer path when every value is an integer, else the rate path.
pub fn run_file(
    path: &Path,
    format: InputFormat,
    column: Option<&str>,
    unit: RateUnit,
    cfg: &PipelineConfig,
    progress: Progress,
) -> Result<Pipeline, OfflineError> {
    let integral = unit == RateUnit::Counts && cfg.pulse_arcsec.is_some();
    match feed_file(path, format, column, unit, cfg, integral, progress) {
        Err(FeedError::NotInteger) => {
            let mut noop = |_: u64, _: Option<u64>| {};
            feed_file(path, format, column, unit, cfg, false, &mut noop).map_err(FeedError::into_offline)
        }
        other => other.map_err(FeedError::into_offline),
    }
}

enum FeedError {
    NotInteger,
    Other(OfflineError),
}

impl FeedError {
    fn into_offline(self) -> OfflineError {
        match self {
            FeedError::Other(e) => e,
            FeedError::NotInteger => unreachable!("handled by the caller"),
        }
    }
}

impl<E: Into<OfflineError>> From<E> for FeedError {
    fn from(e: E) -> Self {
        FeedError::Other(e.into())
    }
}

fn feed_file(
    path: &Path,
    format: InputFormat,
    column: Option<&str>,
    unit: RateUnit,
    cfg: &PipelineConfig,
    integral: bool,
    progress: Progress,
) -> Result<Pipeline, FeedError> {
    let mut reader = SampleReader::open(path, format, column)?;
    let hint = reader.len_hint();
    let mut c = cfg.clone();
    if !integral {
        c.pulse_arcsec = None;
    }
    let mut pipe = Pipeline::new(&c)?;
    let mut out = PipelineOutput::default();
    let mut buf = Vec::with_capacity(BLOCK);
    let mut ints = Vec::with_capacity(BLOCK);
    let tau0 = 1.0 / cfg.rate_hz;
    let to_dph = |v: f64| -> f64 {
        match unit {
            RateUnit::Counts => units::counts_to_dph(v, cfg.pulse_arcsec.unwrap_or(1.0), tau0),
            RateUnit::Dph => v,
            RateUnit::Dps => units::dps_to_dph(v),
            RateUnit::RadS => units::rad_s_to_dph(v),
        }
    };
    loop {
        let n = reader.next_block(&mut buf, BLOCK)?;
        if n == 0 {
            break;
        }
        out.clear();
        if integral {
            ints.clear();
            for &v in &buf {
                if v.fract() != 0.0 || v.abs() > 9.0e15 {
                    return Err(FeedError::NotInteger);
                }
                ints.push(v as i64);
            }
            pipe.push_counts(&ints, &mut out);
        } else {
            for v in &mut buf {
                *v = to_dph(*v);
            }
            pipe.push_rates_dph(&buf, &mut out)?;
        }
        progress(pipe.samples(), hint);
    }
    if pipe.samples() == 0 {
        return Err(OfflineError::Empty { path: path.to_path_buf() }.into());
    }
    out.clear();
    pipe.finish(&mut out);
    Ok(pipe)
}

/// Feed a raw frame capture (`.bin`); gaps are filled. Returns the pipeline and
/// the decoder's counts.
pub fn run_capture(
    path: &Path,
    cfg: &PipelineConfig,
    progress: Progress,
) -> Result<(Pipeline, crate::source::frame::DecoderStats), OfflineError> {
    let mut reader = CaptureReader::open(path)?;
    let hint = std::fs::metadata(path).ok().map(|m| m.len() / 16);
    let mut pipe = Pipeline::new(cfg)?;
    let mut out = PipelineOutput::default();
    let mut series = FilledSeries::with_capacity(BLOCK);
    while let Some(block) = reader.next_block()? {
        series.clear();
        for s in &block.samples {
            series.push_sample(s);
        }
        out.clear();
        pipe.push_counts_filled(&series.counts, &series.filled, &mut out);
        progress(pipe.samples(), hint);
    }
    if pipe.samples() == 0 {
        return Err(OfflineError::Empty { path: path.to_path_buf() });
    }
    out.clear();
    pipe.finish(&mut out);
    Ok((pipe, *reader.stats()))
}

/// The sample rate and pulse weight an MCAP recording's counts are read with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordingGyro {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Angle of one pulse, arcsec.
    pub pulse_arcsec: f64,
}

/// The rate and pulse weight of the recording `path`, given the flags
/// `--rate-hz` and `--pulse-arcsec` (`None` when absent): the recording's
/// `sagnac` metadata record supplies what a flag leaves out, and a flag that
/// contradicts it is an error naming the flag, the file and both values. An
/// older recording without the record gives its rate as the sample period of
/// `/gyro/raw` (a flag must agree within 1 ns of period) and no pulse weight.
/// What neither gives is an error naming the flag.
pub fn recording_gyro(
    path: &Path,
    rate_flag: Option<f64>,
    pulse_flag: Option<f64>,
) -> Result<RecordingGyro, OfflineError> {
    let (rate, pulse) = match read_metadata(path)? {
        Some(meta) => {
            if meta.output == GyroOutput::Rate {
                return Err(OfflineError::RateOutput { path: path.to_path_buf() });
            }
            let origin = "in its sagnac metadata record";
            (
                check_flag("--rate-hz", rate_flag, Some(meta.sample_rate_hz), path, origin, AGREE_REL)?,
                check_flag("--pulse-arcsec", pulse_flag, meta.pulse_arcsec, path, origin, AGREE_REL)?,
            )
        }
        None => {
            let dt = recording_period_ns(path)?.filter(|dt| *dt > 0);
            let recorded = dt.map(|dt| 1e9 / dt as f64);
            let tol = dt.map_or(0.0, |dt| 1.0 / dt as f64);
            (
                check_flag("--rate-hz", rate_flag, recorded, path, "as the sample period of /gyro/raw", tol)?,
                pulse_flag,
            )
        }
    };
    let required = |flag, what| OfflineError::FlagRequired { flag, path: path.to_path_buf(), what };
    Ok(RecordingGyro {
        rate_hz: rate.ok_or_else(|| required("--rate-hz", "sample rate (no metadata record, no /gyro/raw sample)"))?,
        pulse_arcsec: pulse.ok_or_else(|| required("--pulse-arcsec", "pulse weight (no sagnac metadata record)"))?,
    })
}

/// Sample period (ns) of the first `/gyro/raw` batch of a recording, if any.
pub fn recording_period_ns(path: &Path) -> Result<Option<u64>, OfflineError> {
    let mut dt = None;
    scan_recording(path, false, &mut |m| {
        if dt.is_none()
            && let SinkMessage::Raw(b) = &m.message {
                dt = Some(b.dt_ns);
            }
    })?;
    Ok(dt)
}

/// Feed the `/gyro/raw` channel of an MCAP recording (truncated files are read
/// up to their last complete chunk); gaps are filled. Returns the pipeline and,
/// for a cut or damaged file, where reading stopped.
pub fn run_recording(
    path: &Path,
    cfg: &PipelineConfig,
    progress: Progress,
) -> Result<(Pipeline, Option<crate::sink::reader::Break>), OfflineError> {
    let mut pipe = Pipeline::new(cfg)?;
    let mut out = PipelineOutput::default();
    let mut series = FilledSeries::default();
    let mut first_dt: Option<u64> = None;
    let mut mixed: Option<u64> = None;
    let mut implausible: Option<(u64, u64)> = None;
    let report = scan_recording(path, false, &mut |m| {
        if implausible.is_some() {
            return;
        }
        if let SinkMessage::Raw(b) = m.message {
            if let Some(g) = b.gaps.iter().find(|g| g.lost > MAX_GAP_SAMPLES) {
                implausible = Some((b.t0_ns, g.lost));
                return;
            }
            match first_dt {
                None => first_dt = Some(b.dt_ns),
                Some(d) if d != b.dt_ns && !b.counts.is_empty() => mixed = Some(b.dt_ns),
                _ => {}
            }
            series.clear();
            let mut gaps = b.gaps.iter().peekable();
            for (i, &c) in b.counts.iter().enumerate() {
                let mut lost = 0u64;
                while let Some(g) = gaps.next_if(|g| g.index as usize == i) {
                    lost += g.lost;
                }
                series.push(c, lost);
            }
            out.clear();
            pipe.push_counts_filled(&series.counts, &series.filled, &mut out);
            progress(pipe.samples(), None);
        }
    })?;
    if let Some((t0_ns, lost)) = implausible {
        return Err(OfflineError::ImplausibleGap { path: path.to_path_buf(), t0_ns, lost });
    }
    if let (Some(a), Some(b)) = (first_dt, mixed) {
        return Err(OfflineError::MixedRate { path: path.to_path_buf(), first_ns: a, other_ns: b });
    }
    if pipe.samples() == 0 {
        return Err(match report.break_at {
            Some(b) => OfflineError::BrokenBeforeSamples { path: path.to_path_buf(), offset: b.offset, reason: b.reason },
            None => OfflineError::Empty { path: path.to_path_buf() },
        });
    }
    out.clear();
    pipe.finish(&mut out);
    Ok((pipe, report.break_at))
}
