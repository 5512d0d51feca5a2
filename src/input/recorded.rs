//! An MCAP recording made by `sagnac run` as an input: which gyro, its sample
//! rate and pulse weight (its `sagnac` metadata record, checked against the
//! flags), and its `/gyro/raw` batches as blocks with the gaps filled.
//!
//! A recording cut by a crash is read up to its last complete chunk; the
//! stream's report says where it broke.

use std::path::{Path, PathBuf};

use super::{Block, Format, InputError, Meta, Request, Unit, not_applicable, pick_gyro};
use crate::input::frame::FilledSeries;
use crate::recording::meta::{AGREE_REL, GyroOutput, RecordingMeta, check_flag};
use crate::recording::reader::{self, Break, RawReader};

/// What a recording says about one of its gyros.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedGyro {
    /// Its label (`None`: the only gyro, on `/gyro/raw`).
    pub label: Option<String>,
    /// Sample rate, Hz, if known.
    pub sample_rate_hz: Option<f64>,
    /// Angle of one pulse, arcsec, if known (only a metadata record says it).
    pub pulse_arcsec: Option<f64>,
    /// Weight of one rate LSB, deg/s (rate output, when known).
    pub rate_lsb_dps: Option<f64>,
    /// What the counts are.
    pub output: GyroOutput,
    /// Where the values come from (for messages).
    pub origin: &'static str,
    /// Relative tolerance of a flag against `sample_rate_hz`
    /// (see [`crate::recording::meta::check_flag`]).
    pub rate_rel_tol: f64,
}

impl RecordedGyro {
    fn from_meta(label: Option<String>, meta: RecordingMeta) -> Self {
        RecordedGyro {
            label,
            sample_rate_hz: Some(meta.sample_rate_hz),
            pulse_arcsec: meta.pulse_arcsec,
            rate_lsb_dps: meta.rate_lsb_dps,
            output: meta.output,
            origin: "in its sagnac metadata record",
            rate_rel_tol: AGREE_REL,
        }
    }
}

/// The gyros of a recording, in order: for a recording of one gyro, its
/// `sagnac` metadata record, or for an older recording without one the
/// sample period of its first `/gyro/raw` message (and no pulse weight); for
/// a recording of several, each gyro's `sagnac/<label>` record.
pub fn recorded_gyros(path: &Path) -> Result<Vec<RecordedGyro>, InputError> {
    let labels = reader::recording_gyro_labels(path)?;
    if !labels.is_empty() {
        let mut gyros = Vec::new();
        for label in labels {
            if let Some(meta) = reader::read_metadata_of(path, Some(&label))? {
                gyros.push(RecordedGyro::from_meta(Some(label), meta));
            }
        }
        return Ok(gyros);
    }
    if let Some(meta) = reader::read_metadata(path)? {
        return Ok(vec![RecordedGyro::from_meta(None, meta)]);
    }
    let dt = reader::first_raw_period_ns(path, None)?;
    Ok(vec![RecordedGyro {
        label: None,
        sample_rate_hz: dt.map(|dt| 1e9 / dt as f64),
        pulse_arcsec: None,
        rate_lsb_dps: None,
        output: GyroOutput::Counts,
        origin: "as the sample period of /gyro/raw",
        // 1 ns in the period
        rate_rel_tol: dt.map_or(0.0, |dt| 1.0 / dt as f64),
    }])
}

/// Settle the gyro and its settings (see [`super::Input::open`]).
pub(super) fn open(path: &Path, req: &Request, meta: &mut Meta) -> Result<(), InputError> {
    let why = ", which holds pulse counts";
    if req.column.is_some() {
        return Err(not_applicable("--column", path, Format::Mcap, why));
    }
    if req.unit.is_some_and(|u| u != Unit::Counts) {
        return Err(not_applicable("--unit", path, Format::Mcap, why));
    }
    let gyros = recorded_gyros(path)?;
    meta.gyros = gyros.iter().filter_map(|g| g.label.clone()).collect();
    meta.gyro = pick_gyro(path, &meta.gyros, req)?;
    if meta.gyro.is_none() && !meta.gyros.is_empty() {
        // every gyro, each opened on its own (`Input::for_axis`): its settings are its own
        return Ok(());
    }
    let gyro = gyros
        .into_iter()
        .find(|g| g.label == meta.gyro)
        .expect("the gyro picked is one of the recording's");
    if gyro.output == GyroOutput::Rate {
        return Err(InputError::RateOutput {
            path: path.to_path_buf(),
        });
    }
    meta.sample_rate_hz = check_flag(
        "--sample-rate-hz",
        req.sample_rate_hz,
        gyro.sample_rate_hz,
        path,
        gyro.origin,
        gyro.rate_rel_tol,
    )?;
    meta.pulse_arcsec = check_flag(
        "--pulse-arcsec",
        req.pulse_arcsec,
        gyro.pulse_arcsec,
        path,
        gyro.origin,
        AGREE_REL,
    )?;
    meta.rate_lsb_dps = gyro.rate_lsb_dps;
    meta.origin = match (req.sample_rate_hz, req.pulse_arcsec) {
        (None, None) => "from the recording",
        (Some(_), Some(_)) => "given on the command line (checked against the recording)",
        _ => "from the recording and the command line",
    }
    .into();
    meta.unit = Unit::Counts;
    meta.integral = true;
    Ok(())
}

/// The `/gyro/raw` batches of one gyro as blocks.
pub(super) struct RecordedStream {
    path: PathBuf,
    reader: RawReader,
    series: FilledSeries,
    dt_ns: Option<u64>,
}

impl RecordedStream {
    pub(super) fn open(path: &Path, gyro: Option<&str>) -> Result<Self, InputError> {
        Ok(RecordedStream {
            path: path.to_path_buf(),
            reader: RawReader::open(path, gyro, false)?,
            series: FilledSeries::default(),
            dt_ns: None,
        })
    }

    /// Where a cut or damaged file stopped being readable.
    pub(super) fn break_at(&self) -> Option<Break> {
        self.reader.report().break_at.clone()
    }

    /// The next batch with samples into `block`; `false` at the end.
    pub(super) fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        loop {
            let Some(b) = self.reader.next_batch()? else {
                return Ok(false);
            };
            if let Some(g) = b.gaps.iter().find(|g| g.lost > super::MAX_GAP_SAMPLES) {
                return Err(InputError::ImplausibleGap {
                    path: self.path.clone(),
                    t0_ns: b.t0_ns,
                    lost: g.lost,
                });
            }
            if b.counts.is_empty() {
                continue;
            }
            match self.dt_ns {
                None => self.dt_ns = Some(b.dt_ns),
                Some(d) if d != b.dt_ns => {
                    return Err(InputError::MixedRate {
                        path: self.path.clone(),
                        first_ns: d,
                        other_ns: b.dt_ns,
                        t0_ns: b.t0_ns,
                    });
                }
                _ => {}
            }
            self.series.clear();
            let mut gaps = b.gaps.iter().peekable();
            for (i, &c) in b.counts.iter().enumerate() {
                let mut lost = 0u64;
                while let Some(g) = gaps.next_if(|g| g.index as usize == i) {
                    lost += g.lost;
                }
                self.series.push(c, lost);
            }
            std::mem::swap(&mut block.counts, &mut self.series.counts);
            std::mem::swap(&mut block.filled, &mut self.series.filled);
            if let Some(t) = b.temp_c {
                block.temp_c.resize(block.counts.len(), t);
            }
            block.gaps = b.gaps.len() as u64;
            block.lost_samples = b.gaps.iter().map(|g| g.lost).sum();
            return Ok(true);
        }
    }
}
