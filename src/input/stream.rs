//! The pull stream of an [`Input`](super::Input): blocks of samples, the
//! same whatever the format.
//!
//! Block sizes are the readers' own (64 Ki values of a text file, 16 Ki
//! frames of a capture, one `/gyro/raw` message of a recording), so a
//! consumer's results never depend on them.

use std::fs::File;
use std::io::{BufReader, Read};
use std::ops::Range;
use std::path::{Path, PathBuf};

use flate2::read::MultiGzDecoder;

use super::capture::{CaptureError, CaptureReader};
use super::frame::{Axes, DecoderConfig, DecoderStats, FilledSeries, Single, Triad};
use super::plain::SampleReader;
use super::recorded::RecordedStream;
use super::ros2::{Ros2Stream, StampReport};
use super::{Format, InputError, Meta};
use crate::recording::reader::Break;

/// Values per block of a text, CSV or f64le file.
const PLAIN_BLOCK: usize = 1 << 16;
/// The CSV column read along as the temperature.
pub const TEMPERATURE_COLUMN: &str = "temp_c";

/// One block of samples.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Block {
    /// Pulse increments, when the input is integral ([`Meta::integral`]).
    pub counts: Vec<i64>,
    /// Samples in the input's unit, otherwise.
    pub values: Vec<f64>,
    /// Samples made up to fill gaps (indices into this block, sorted, disjoint).
    pub filled: Vec<Range<usize>>,
    /// Temperature per sample, deg C; empty when this block has none.
    pub temp_c: Vec<f64>,
    /// Gaps (lost frames) in this block, and the samples lost in them.
    pub gaps: u64,
    pub lost_samples: u64,
}

impl Block {
    /// Samples in the block.
    pub fn len(&self) -> usize {
        self.counts.len().max(self.values.len())
    }
    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub(crate) fn clear(&mut self) {
        self.counts.clear();
        self.values.clear();
        self.filled.clear();
        self.temp_c.clear();
        self.gaps = 0;
        self.lost_samples = 0;
    }
}

/// What a pass met.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StreamReport {
    /// Samples handed out (filled ones included).
    pub samples: u64,
    /// Gaps, and samples lost in them (filled).
    pub gaps: u64,
    pub lost_samples: u64,
    /// The frame decoder's counts (frame captures).
    pub frames: Option<DecoderStats>,
    /// Where a cut or damaged recording stopped being readable.
    pub break_at: Option<Break>,
    /// A ROS 2 bag's stamps: out of order, duplicates.
    pub stamps: Option<StampReport>,
}

type AnyRead = Box<dyn Read + Send>;

enum Source {
    Plain(SampleReader, Vec<f64>),
    Single(Box<CaptureReader<AnyRead, Single>>),
    Triad(Box<CaptureReader<AnyRead, Triad>>),
    Recorded(Box<RecordedStream>),
    Bag(Box<Ros2Stream>),
    /// Samples in memory, and the next one to hand out.
    Memory(std::sync::Arc<Vec<f64>>, usize),
}

/// Anything that hands out one axis's blocks: a [`Stream`], or one axis of
/// a pass that reads several at once.
pub trait BlockSource {
    /// The next block into `block`; `false` at the end.
    fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError>;
    /// What the pass met so far (all of it once it ended).
    fn report(&self) -> StreamReport;
}

impl BlockSource for Stream {
    fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        Stream::next_block(self, block)
    }
    fn report(&self) -> StreamReport {
        Stream::report(self)
    }
}

/// A pass over an input's samples.
pub struct Stream {
    path: PathBuf,
    source: Source,
    integral: bool,
    report: StreamReport,
    done: bool,
}

impl Stream {
    pub(super) fn open(path: &Path, meta: &Meta) -> Result<Stream, InputError> {
        let source = match meta.format {
            Format::Csv | Format::Text | Format::F64le => {
                let side = (meta.format == Format::Csv).then_some(TEMPERATURE_COLUMN);
                // a fraction after the counts judged whole stops the pass
                let r =
                    SampleReader::open_with_side(path, meta.format, meta.column.as_deref(), side)?
                        .require_integers(meta.integral);
                Source::Plain(r, Vec::with_capacity(PLAIN_BLOCK))
            }
            Format::Frames => Source::Single(Box::new(capture::<Single>(path, meta, 0)?)),
            Format::TriadFrames => {
                let axis = super::frame::triad::AXES
                    .iter()
                    .position(|a| Some(*a) == meta.gyro.as_deref())
                    .expect("a triad capture is read for one of its gyros");
                Source::Triad(Box::new(capture::<Triad>(path, meta, axis)?))
            }
            Format::Mcap => {
                Source::Recorded(Box::new(RecordedStream::open(path, meta.gyro.as_deref())?))
            }
            Format::Ros2 => Source::Bag(Box::new(Ros2Stream::open(path, meta)?)),
            Format::Array => unreachable!("an array in memory is streamed by Stream::memory"),
        };
        Ok(Stream {
            path: path.to_path_buf(),
            source,
            integral: meta.integral,
            report: StreamReport::default(),
            done: false,
        })
    }

    /// A pass over samples in memory (`integral`: whole pulse counts).
    pub(super) fn memory(path: &Path, values: std::sync::Arc<Vec<f64>>, integral: bool) -> Stream {
        Stream {
            path: path.to_path_buf(),
            source: Source::Memory(values, 0),
            integral,
            report: StreamReport::default(),
            done: false,
        }
    }

    /// The next block into `block`; `false` at the end (and ever after). A
    /// pass that ends without a single sample is an error.
    pub fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        block.clear();
        if self.done {
            return Ok(false);
        }
        let more = match &mut self.source {
            Source::Plain(r, buf) => plain_block(r, buf, self.integral, block)?,
            Source::Single(r) => capture_block(r, block)?,
            Source::Triad(r) => capture_block(r, block)?,
            Source::Recorded(r) => r.next_block(block)?,
            Source::Bag(r) => r.next_block(block)?,
            Source::Memory(values, pos) => {
                let end = (*pos + PLAIN_BLOCK).min(values.len());
                let chunk = &values[*pos..end];
                *pos = end;
                if self.integral {
                    block.counts.extend(chunk.iter().map(|&v| v as i64));
                } else {
                    block.values.extend_from_slice(chunk);
                }
                !chunk.is_empty()
            }
        };
        self.report.samples += block.len() as u64;
        self.report.gaps += block.gaps;
        self.report.lost_samples += block.lost_samples;
        if !more {
            self.done = true;
            self.finish()?;
        }
        Ok(more)
    }

    /// What the pass met so far (all of it once it ended).
    pub fn report(&self) -> StreamReport {
        self.report.clone()
    }

    /// The file read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn finish(&mut self) -> Result<(), InputError> {
        let path = self.path.clone();
        match &self.source {
            Source::Single(r) => self.report.frames = Some(no_frames(r, &path)?),
            Source::Triad(r) => self.report.frames = Some(no_frames(r, &path)?),
            Source::Recorded(r) => self.report.break_at = r.break_at(),
            Source::Bag(r) => self.report.stamps = Some(r.report().clone()),
            Source::Plain(..) | Source::Memory(..) => {}
        }
        if self.report.samples > 0 {
            return Ok(());
        }
        Err(match &self.report.break_at {
            Some(b) => InputError::BrokenBeforeSamples {
                path,
                offset: b.offset,
                reason: b.reason.clone(),
            },
            None => InputError::Empty { path },
        })
    }
}

/// A capture of wire `W`, gyro `axis`, gzip-compressed or not.
fn capture<W: Axes>(
    path: &Path,
    meta: &Meta,
    axis: usize,
) -> Result<CaptureReader<AnyRead, W>, InputError> {
    let file = File::open(path).map_err(|source| CaptureError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    let read: AnyRead = if meta.gzip {
        Box::new(MultiGzDecoder::new(BufReader::new(file)))
    } else {
        Box::new(file)
    };
    Ok(CaptureReader::for_axis(
        read,
        path,
        DecoderConfig::default(),
        axis,
    ))
}

/// The decoder's counts; an error when the whole capture held no valid frame.
fn no_frames<W: Axes>(
    r: &CaptureReader<AnyRead, W>,
    path: &Path,
) -> Result<DecoderStats, InputError> {
    let stats = *r.stats();
    if stats.frames_decoded == 0 {
        return Err(CaptureError::NoFrames {
            path: path.to_path_buf(),
            bytes_read: stats.bytes_read,
            crc_errors: stats.crc_errors,
            false_syncs: stats.false_syncs,
        }
        .into());
    }
    Ok(stats)
}

fn plain_block(
    r: &mut SampleReader,
    buf: &mut Vec<f64>,
    integral: bool,
    block: &mut Block,
) -> Result<bool, InputError> {
    if r.next_block(buf, PLAIN_BLOCK)? == 0 {
        return Ok(false);
    }
    if integral {
        // whole: checked when the input was opened, or by the reader
        block.counts.extend(buf.iter().map(|&v| v as i64));
    } else {
        std::mem::swap(&mut block.values, buf);
    }
    if r.side().len() == block.len() {
        block.temp_c.extend_from_slice(r.side());
    }
    Ok(true)
}

fn capture_block<W: Axes>(
    r: &mut CaptureReader<AnyRead, W>,
    block: &mut Block,
) -> Result<bool, InputError> {
    loop {
        let Some(b) = r.next_block()? else {
            return Ok(false);
        };
        if b.samples.is_empty() {
            continue;
        }
        let mut series = FilledSeries {
            counts: std::mem::take(&mut block.counts),
            filled: std::mem::take(&mut block.filled),
        };
        for s in &b.samples {
            let n = series.push_sample(s);
            block.temp_c.extend(std::iter::repeat_n(s.temp_c, n));
            block.gaps += u64::from(s.lost_before > 0);
            block.lost_samples += u64::from(s.lost_before);
        }
        block.counts = series.counts;
        block.filled = series.filled;
        return Ok(true);
    }
}
