//! Offline inputs for the pipeline: CSV/text files (pulse counts or a rate
//! column in any unit), raw frame captures (`.bin`) and MCAP recordings made
//! by `sagnac run`. Each is streamed block by block into a
//! [`Pipeline`](crate::pipeline::Pipeline), so memory stays bounded and the
//! numbers are exactly those the daemon computes live.
//!
//! Gaps (lost frames) are filled the same way everywhere: the pulses of the
//! gap, which the cumulative counter kept, are spread over the missing
//! samples as integers ([`crate::input::frame::FilledSeries`]), so the
//! series stays uniformly sampled and no angle is lost; the made-up samples
//! are marked, and the pipeline's statistics leave them out.

use std::path::{Path, PathBuf};

use crate::pipeline::{Pipeline, PipelineConfig, PipelineError, PipelineOutput};
use crate::recording::meta::{AGREE_REL, Contradiction, GyroOutput, check_flag};
use crate::recording::reader::{RawReader, ReadError, first_raw_period_ns};
use crate::input::capture::{CaptureError, CaptureReader};
use crate::input::frame::FilledSeries;
use crate::input::plain::{InputError, InputFormat, SampleReader};
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

impl RateUnit {
    /// A sample in this unit as deg/h (`pulse_arcsec`, `tau0_s`: the
    /// counter's pulse weight and sample period, for `Counts`).
    pub fn to_dph(self, v: f64, pulse_arcsec: f64, tau0_s: f64) -> f64 {
        match self {
            RateUnit::Counts => units::counts_to_dph(v, pulse_arcsec, tau0_s),
            RateUnit::Dph => v,
            RateUnit::Dps => units::dps_to_dph(v),
            RateUnit::RadS => units::rad_s_to_dph(v),
        }
    }
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
    #[error(
        "{path}: /gyro/raw batches disagree on the sample period ({first_ns} ns, then {other_ns} ns)"
    )]
    MixedRate {
        path: PathBuf,
        first_ns: u64,
        other_ns: u64,
    },
    #[error(
        "{path}: the /gyro/raw batch at t0 = {t0_ns} ns has a gap of {lost} lost samples \
         (more than {MAX_GAP_SAMPLES}: not a recording of a gyro that kept running)"
    )]
    ImplausibleGap {
        path: PathBuf,
        t0_ns: u64,
        lost: u64,
    },
    #[error("{path}: no samples before the file becomes unreadable at byte {offset}: {reason}")]
    BrokenBeforeSamples {
        path: PathBuf,
        offset: u64,
        reason: String,
    },
    /// A value the input does not carry and no flag gave.
    #[error("{flag} is required: {} carries no {what}", path.display())]
    FlagRequired {
        flag: &'static str,
        path: PathBuf,
        what: &'static str,
    },
    /// A flag that contradicts the recording.
    #[error(transparent)]
    Contradiction(#[from] Contradiction),
    /// A recording of several gyros read without saying which.
    #[error("{}: a recording of several gyros ({}): choose one with --gyro LABEL", path.display(), labels.join(", "))]
    ChooseGyro { path: PathBuf, labels: Vec<String> },
    /// `--gyro` names a gyro the recording does not have.
    #[error("--gyro {gyro}: {} has no such gyro ({})", path.display(), if labels.is_empty() { "it is a recording of one gyro, on /gyro/raw: leave --gyro out".to_string() } else { format!("its gyros: {}", labels.join(", ")) })]
    NoSuchGyro {
        path: PathBuf,
        gyro: String,
        labels: Vec<String>,
    },
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

/// One push into the pipeline, as a [`Tap`] sees it: for a caller that wants
/// more than the final [`Analysis`](crate::pipeline::Analysis), such as the
/// time series of `sagnac report`.
#[derive(Debug, Clone, Copy)]
pub struct TapBlock<'a> {
    /// Index of the first sample of this push in the record. A push at 0 after
    /// others means the reading started over (a CSV column of counts that turns
    /// out not to be integers is re-read on the rate path): drop what was seen.
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

/// A shorter-lived copy of an optional tap (to hand it to a callee twice).
fn reborrow<'s>(tap: &'s mut Option<Tap<'_>>) -> Option<Tap<'s>> {
    tap.as_mut().map(|t| &mut **t as Tap<'s>)
}

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
    run_file_tapped(path, format, column, unit, cfg, progress, None)
}

/// [`run_file`], showing every push to `tap`; a CSV file's `temp_c` column,
/// when it has one, comes along as [`TapBlock::temp_c`].
pub fn run_file_tapped(
    path: &Path,
    format: InputFormat,
    column: Option<&str>,
    unit: RateUnit,
    cfg: &PipelineConfig,
    progress: Progress,
    mut tap: Option<Tap>,
) -> Result<Pipeline, OfflineError> {
    let integral = unit == RateUnit::Counts && cfg.pulse_arcsec.is_some();
    match feed_file(
        path,
        format,
        column,
        unit,
        cfg,
        integral,
        progress,
        reborrow(&mut tap),
    ) {
        Err(FeedError::NotInteger) => {
            let mut noop = |_: u64, _: Option<u64>| {};
            feed_file(path, format, column, unit, cfg, false, &mut noop, tap)
                .map_err(FeedError::into_offline)
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
    mut tap: Option<Tap>,
) -> Result<Pipeline, FeedError> {
    let mut reader = SampleReader::open(path, format, column)?;
    // the temperature column rides along only for a tap that shows it
    let mut temps = match (&tap, format) {
        (Some(_), InputFormat::Csv) => match SampleReader::open(path, format, Some("temp_c")) {
            Ok(r) => Some(r),
            Err(InputError::MissingColumn { .. }) => None,
            Err(e) => return Err(e.into()),
        },
        _ => None,
    };
    let mut temp_buf = Vec::new();
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
    let to_dph = |v: f64| unit.to_dph(v, cfg.pulse_arcsec.unwrap_or(1.0), tau0);
    loop {
        let n = reader.next_block(&mut buf, BLOCK)?;
        if n == 0 {
            break;
        }
        out.clear();
        let first_sample = pipe.samples();
        if integral {
            ints.clear();
            for &v in &buf {
                if v.fract() != 0.0 || v.abs() > 9.0e15 {
                    return Err(FeedError::NotInteger);
                }
                ints.push(v as i64);
            }
            pipe.push_counts(&ints, &mut out);
        }
        for v in &mut buf {
            *v = to_dph(*v);
        }
        if !integral {
            pipe.push_rates_dph(&buf, &mut out)?;
        }
        if let Some(tap) = tap.as_deref_mut() {
            let mut temp_c = None;
            if let Some(t) = &mut temps {
                // a temp_c column shorter than the data ends the temperature there
                temp_buf.clear();
                let got = t.next_block(&mut temp_buf, n)?;
                if got == n {
                    temp_c = Some(&temp_buf[..]);
                } else {
                    temps = None;
                }
            }
            let counts = integral.then_some(&ints[..]);
            tap(&TapBlock {
                first_sample,
                counts,
                rate_dph: &buf,
                temp_c,
                gaps: 0,
                lost_samples: 0,
                out: &out,
            });
        }
        progress(pipe.samples(), hint);
    }
    if pipe.samples() == 0 {
        return Err(OfflineError::Empty {
            path: path.to_path_buf(),
        }
        .into());
    }
    out.clear();
    pipe.finish(&mut out);
    tap_flush(tap, &pipe, &out);
    Ok(pipe)
}

/// Show the final flush (the last clean and noise values) to `tap`.
fn tap_flush(tap: Option<Tap>, pipe: &Pipeline, out: &PipelineOutput) {
    if let Some(tap) = tap {
        tap(&TapBlock {
            first_sample: pipe.samples(),
            counts: None,
            rate_dph: &[],
            temp_c: None,
            gaps: 0,
            lost_samples: 0,
            out,
        });
    }
}

/// Feed a raw frame capture (`.bin`); gaps are filled. Returns the pipeline and
/// the decoder's counts.
pub fn run_capture(
    path: &Path,
    cfg: &PipelineConfig,
    progress: Progress,
) -> Result<(Pipeline, crate::input::frame::DecoderStats), OfflineError> {
    run_capture_tapped(path, cfg, progress, None)
}

/// [`run_capture`], showing every push to `tap` (with the frames'
/// temperature, repeated over a gap).
pub fn run_capture_tapped(
    path: &Path,
    cfg: &PipelineConfig,
    progress: Progress,
    mut tap: Option<Tap>,
) -> Result<(Pipeline, crate::input::frame::DecoderStats), OfflineError> {
    let mut reader = CaptureReader::open(path)?;
    let hint = std::fs::metadata(path).ok().map(|m| m.len() / 16);
    let mut pipe = Pipeline::new(cfg)?;
    let mut out = PipelineOutput::default();
    let mut series = FilledSeries::with_capacity(BLOCK);
    let (mut rates, mut temps) = (Vec::new(), Vec::new());
    while let Some(block) = reader.next_block()? {
        series.clear();
        for s in &block.samples {
            series.push_sample(s);
        }
        let first_sample = push_filled(&mut pipe, &series, &mut out);
        if let Some(tap) = tap.as_deref_mut() {
            tap_rates(cfg, &series.counts, &mut rates);
            temps.clear();
            let (mut gaps, mut lost) = (0, 0);
            for s in &block.samples {
                temps.extend(std::iter::repeat_n(
                    s.temp_c,
                    usize::from(s.lost_before) + 1,
                ));
                gaps += u64::from(s.lost_before > 0);
                lost += u64::from(s.lost_before);
            }
            tap(&TapBlock {
                first_sample,
                counts: Some(&series.counts),
                rate_dph: &rates,
                temp_c: Some(&temps),
                gaps,
                lost_samples: lost,
                out: &out,
            });
        }
        progress(pipe.samples(), hint);
    }
    if pipe.samples() == 0 {
        return Err(OfflineError::Empty {
            path: path.to_path_buf(),
        });
    }
    out.clear();
    pipe.finish(&mut out);
    tap_flush(tap, &pipe, &out);
    Ok((pipe, *reader.stats()))
}

/// Push a gap-filled block of counts into `pipe` (its output replaces `out`);
/// the index of the block's first sample.
fn push_filled(pipe: &mut Pipeline, series: &FilledSeries, out: &mut PipelineOutput) -> u64 {
    out.clear();
    let first_sample = pipe.samples();
    pipe.push_counts_filled(&series.counts, &series.filled, out);
    first_sample
}

/// The rates (deg/h) of `counts` at `cfg`'s rate and pulse weight, for a tap.
fn tap_rates(cfg: &PipelineConfig, counts: &[i64], rates: &mut Vec<f64>) {
    let k = cfg.pulse_arcsec.unwrap_or(1.0) * cfg.rate_hz;
    rates.clear();
    rates.extend(counts.iter().map(|&c| c as f64 * k));
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
    gyro: Option<&str>,
    rate_flag: Option<f64>,
    pulse_flag: Option<f64>,
) -> Result<RecordingGyro, OfflineError> {
    let gyro = select_gyro(path, gyro)?;
    let (rate, pulse) = match crate::recording::reader::read_metadata_of(path, gyro.as_deref())? {
        Some(meta) => {
            if meta.output == GyroOutput::Rate {
                return Err(OfflineError::RateOutput {
                    path: path.to_path_buf(),
                });
            }
            let origin = "in its sagnac metadata record";
            (
                check_flag(
                    "--rate-hz",
                    rate_flag,
                    Some(meta.sample_rate_hz),
                    path,
                    origin,
                    AGREE_REL,
                )?,
                check_flag(
                    "--pulse-arcsec",
                    pulse_flag,
                    meta.pulse_arcsec,
                    path,
                    origin,
                    AGREE_REL,
                )?,
            )
        }
        None => {
            let dt = first_raw_period_ns(path, gyro.as_deref())?;
            let recorded = dt.map(|dt| 1e9 / dt as f64);
            let tol = dt.map_or(0.0, |dt| 1.0 / dt as f64);
            (
                check_flag(
                    "--rate-hz",
                    rate_flag,
                    recorded,
                    path,
                    "as the sample period of /gyro/raw",
                    tol,
                )?,
                pulse_flag,
            )
        }
    };
    let required = |flag, what| OfflineError::FlagRequired {
        flag,
        path: path.to_path_buf(),
        what,
    };
    Ok(RecordingGyro {
        rate_hz: rate.ok_or_else(|| {
            required(
                "--rate-hz",
                "sample rate (no metadata record, no /gyro/raw sample)",
            )
        })?,
        pulse_arcsec: pulse.ok_or_else(|| {
            required("--pulse-arcsec", "pulse weight (no sagnac metadata record)")
        })?,
    })
}

/// Which gyro of the recording `path` to read, given `--gyro`: `None` for a
/// recording of one gyro (and no `--gyro`), the label for one of several; an
/// error naming the labels when a recording of several gyros is read without
/// `--gyro`, or `--gyro` names a gyro it does not have.
pub fn select_gyro(path: &Path, gyro: Option<&str>) -> Result<Option<String>, OfflineError> {
    let labels = crate::recording::reader::recording_gyro_labels(path)?;
    match gyro {
        None if labels.is_empty() => Ok(None),
        None => Err(OfflineError::ChooseGyro {
            path: path.to_path_buf(),
            labels,
        }),
        Some(g) if labels.iter().any(|l| l == g) => Ok(Some(g.to_string())),
        Some(g) => Err(OfflineError::NoSuchGyro {
            path: path.to_path_buf(),
            gyro: g.to_string(),
            labels,
        }),
    }
}

/// Feed the `/gyro/raw` channel of an MCAP recording (of a recording of
/// several gyros: gyro `gyro`'s `/gyro/<label>/raw`, see [`select_gyro`];
/// truncated files are read up to their last complete chunk); gaps are
/// filled. Returns the pipeline and, for a cut or damaged file, where reading
/// stopped.
pub fn run_recording(
    path: &Path,
    gyro: Option<&str>,
    cfg: &PipelineConfig,
    progress: Progress,
) -> Result<(Pipeline, Option<crate::recording::reader::Break>), OfflineError> {
    run_recording_tapped(path, gyro, cfg, progress, None)
}

/// [`run_recording`], showing every push to `tap` (with the batches'
/// temperature, when they carry one).
pub fn run_recording_tapped(
    path: &Path,
    gyro: Option<&str>,
    cfg: &PipelineConfig,
    progress: Progress,
    mut tap: Option<Tap>,
) -> Result<(Pipeline, Option<crate::recording::reader::Break>), OfflineError> {
    let gyro = select_gyro(path, gyro)?;
    let mut pipe = Pipeline::new(cfg)?;
    let (mut rates, mut temps) = (Vec::new(), Vec::new());
    let mut out = PipelineOutput::default();
    let mut series = FilledSeries::default();
    let mut first_dt: Option<u64> = None;
    let mut mixed: Option<u64> = None;
    let mut implausible: Option<(u64, u64)> = None;
    let mut reader = RawReader::open(path, gyro.as_deref(), false)?;
    while let Some(b) = reader.next_batch()? {
        if let Some(g) = b.gaps.iter().find(|g| g.lost > MAX_GAP_SAMPLES) {
            implausible = Some((b.t0_ns, g.lost));
            break;
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
        let first_sample = push_filled(&mut pipe, &series, &mut out);
        if let Some(tap) = tap.as_deref_mut() {
            tap_rates(cfg, &series.counts, &mut rates);
            let temp_c = b.temp_c.map(|t| {
                temps.clear();
                temps.resize(series.counts.len(), t);
                &temps[..]
            });
            tap(&TapBlock {
                first_sample,
                counts: Some(&series.counts),
                rate_dph: &rates,
                temp_c,
                gaps: b.gaps.len() as u64,
                lost_samples: b.gaps.iter().map(|g| g.lost).sum(),
                out: &out,
            });
        }
        progress(pipe.samples(), None);
    }
    let report = reader.report().clone();
    if let Some((t0_ns, lost)) = implausible {
        return Err(OfflineError::ImplausibleGap {
            path: path.to_path_buf(),
            t0_ns,
            lost,
        });
    }
    if let (Some(a), Some(b)) = (first_dt, mixed) {
        return Err(OfflineError::MixedRate {
            path: path.to_path_buf(),
            first_ns: a,
            other_ns: b,
        });
    }
    if pipe.samples() == 0 {
        return Err(match report.break_at {
            Some(b) => OfflineError::BrokenBeforeSamples {
                path: path.to_path_buf(),
                offset: b.offset,
                reason: b.reason,
            },
            None => OfflineError::Empty {
                path: path.to_path_buf(),
            },
        });
    }
    out.clear();
    pipe.finish(&mut out);
    tap_flush(tap, &pipe, &out);
    Ok((pipe, report.break_at))
}
