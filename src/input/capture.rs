//! Synchronous reader of a raw `.bin` capture: the gyro's serial bytes exactly
//! as captured (frames plus whatever line noise came with them).
//!
//! This is the offline twin of the daemon's serial source: the same sans-IO
//! [`FrameDecoder`] runs over the file in read chunks, and samples plus decoder
//! events come out in blocks of bounded size (for `sagnac analyze --format
//! frames` and for replaying a capture through the pipeline). Corruption in the
//! capture is never an error (it is skipped and counted, see
//! [`crate::input::frame`]); errors are I/O failures, naming the file and the
//! byte offset, and a file that holds no valid frame at all.

use std::fs::File;
use std::io::{self, Read};
use std::path::{Path, PathBuf};

use bytes::BytesMut;

use super::frame::{
    Axes, DecodeEvent, Decoded, DecoderConfig, DecoderStats, FrameDecoder, Sample, Single,
};

/// Errors of the capture reader.
#[derive(Debug, thiserror::Error)]
pub enum CaptureError {
    /// The file could not be opened.
    #[error("cannot open frame capture {path}")]
    Open {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// Reading failed.
    #[error("read error in frame capture {path} at byte offset {offset}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Bytes read successfully before the failure.
        offset: u64,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// Not a single valid frame in the whole file.
    #[error(
        "no valid gyro frame in frame capture {path} ({bytes_read} bytes, {crc_errors} CRC errors, \
         {false_syncs} false syncs): is it a raw .bin capture of the 16-byte frames?"
    )]
    NoFrames {
        /// The file.
        path: PathBuf,
        /// Its length.
        bytes_read: u64,
        /// CRC errors seen.
        crc_errors: u64,
        /// False syncs seen.
        false_syncs: u64,
    },
}

/// A decoder event and its place among the samples of a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockEvent {
    /// Index (in the block's or summary's `samples`) of the first sample
    /// decoded after the event; equals `samples.len()` for trailing events.
    pub before_sample: usize,
    /// The event.
    pub event: DecodeEvent,
}

/// A block of decoded output.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CaptureBlock {
    /// Samples, in stream order.
    pub samples: Vec<Sample>,
    /// Events, in stream order, positioned among the samples.
    pub events: Vec<BlockEvent>,
}

impl CaptureBlock {
    /// No samples and no events.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty() && self.events.is_empty()
    }

    /// The samples' increments (gaps NOT filled: see
    /// [`crate::input::frame::fill_gap`]).
    pub fn increments(&self) -> impl Iterator<Item = i64> + '_ {
        self.samples.iter().map(|s| s.increment)
    }
}

/// A whole capture, decoded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CaptureSummary {
    /// All samples.
    pub samples: Vec<Sample>,
    /// All events, positioned among `samples`.
    pub events: Vec<BlockEvent>,
    /// Final decoder counts.
    pub stats: DecoderStats,
}

/// Reads a capture block by block: of single frames (`W` = [`Single`], the
/// default) or of one gyro of a multi-gyro frame (`W` = `Triad`, gyro
/// [`CaptureReader::axis`]).
#[derive(Debug)]
pub struct CaptureReader<R, W: Axes = Single> {
    path: PathBuf,
    reader: R,
    buf: BytesMut,
    chunk: Vec<u8>,
    decoder: FrameDecoder<W>,
    axis: usize,
    block_samples: usize,
    file_offset: u64,
    eof: bool,
    done: bool,
}

/// Default read chunk, bytes.
pub const DEFAULT_READ_CHUNK: usize = 64 * 1024;
/// Default block size, samples.
pub const DEFAULT_BLOCK_SAMPLES: usize = 16 * 1024;

impl CaptureReader<File> {
    /// Open a capture file with the default decoder configuration.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, CaptureError> {
        Self::open_with(path, DecoderConfig::default())
    }

    /// Open a capture file with `config`.
    pub fn open_with(path: impl AsRef<Path>, config: DecoderConfig) -> Result<Self, CaptureError> {
        let path = path.as_ref();
        let file = File::open(path).map_err(|source| CaptureError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(Self::new(file, path, config))
    }
}

impl<R: Read> CaptureReader<R> {
    /// Read from any reader; `name` is used in error messages.
    pub fn new(reader: R, name: impl Into<PathBuf>, config: DecoderConfig) -> Self {
        CaptureReader::<R, Single>::for_axis(reader, name, config, 0)
    }
}

impl<R: Read, W: Axes> CaptureReader<R, W> {
    /// Read gyro `axis` (0-based, below `W::GYROS`) of frames of wire `W`
    /// from any reader; `name` is used in error messages.
    pub fn for_axis(
        reader: R,
        name: impl Into<PathBuf>,
        config: DecoderConfig,
        axis: usize,
    ) -> Self {
        assert!(
            axis < W::GYROS,
            "axis {axis} of a frame of {} gyros",
            W::GYROS
        );
        CaptureReader {
            path: name.into(),
            reader,
            buf: BytesMut::new(),
            chunk: vec![0; DEFAULT_READ_CHUNK],
            decoder: FrameDecoder::<W>::for_wire(config),
            axis,
            block_samples: DEFAULT_BLOCK_SAMPLES,
            file_offset: 0,
            eof: false,
            done: false,
        }
    }

    /// At most `n` (at least 1) samples per block.
    pub fn with_block_samples(mut self, n: usize) -> Self {
        self.block_samples = n.max(1);
        self
    }

    /// Read the file in chunks of `bytes` (at least 1).
    pub fn with_read_chunk(mut self, bytes: usize) -> Self {
        self.chunk = vec![0; bytes.max(1)];
        self
    }

    /// The file name used in errors.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Decoder counts so far.
    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// The next block (at most `block_samples` samples, plus the events among
    /// them), or `None` at end of file.
    pub fn next_block(&mut self) -> Result<Option<CaptureBlock>, CaptureError> {
        if self.done {
            return Ok(None);
        }
        let mut block = CaptureBlock::default();
        loop {
            loop {
                let item = if self.eof {
                    self.decoder.decode_eof(&mut self.buf)
                } else {
                    self.decoder.decode(&mut self.buf)
                };
                match item.map(|i| W::axis(&i, self.axis)) {
                    Some(Decoded::Sample(s)) => block.samples.push(s),
                    Some(Decoded::Event(event)) => block.events.push(BlockEvent {
                        before_sample: block.samples.len(),
                        event,
                    }),
                    None => break,
                }
                if block.samples.len() >= self.block_samples {
                    return Ok(Some(block));
                }
            }
            if self.eof {
                self.done = true;
                return Ok((!block.is_empty()).then_some(block));
            }
            let n = loop {
                match self.reader.read(&mut self.chunk) {
                    Ok(n) => break n,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(source) => {
                        return Err(CaptureError::Read {
                            path: self.path.clone(),
                            offset: self.file_offset,
                            source,
                        });
                    }
                }
            };
            if n == 0 {
                self.eof = true;
            } else {
                self.buf.extend_from_slice(&self.chunk[..n]);
                self.file_offset += n as u64;
            }
        }
    }

    /// Decode the rest of the capture at once. Errors with
    /// [`CaptureError::NoFrames`] when the whole capture held no valid frame.
    pub fn read_all(mut self) -> Result<CaptureSummary, CaptureError> {
        let mut sum = CaptureSummary::default();
        while let Some(block) = self.next_block()? {
            let base = sum.samples.len();
            sum.events
                .extend(block.events.into_iter().map(|e| BlockEvent {
                    before_sample: e.before_sample + base,
                    event: e.event,
                }));
            sum.samples.extend(block.samples);
        }
        sum.stats = *self.decoder.stats();
        if sum.stats.frames_decoded == 0 {
            return Err(CaptureError::NoFrames {
                path: self.path,
                bytes_read: sum.stats.bytes_read,
                crc_errors: sum.stats.crc_errors,
                false_syncs: sum.stats.false_syncs,
            });
        }
        Ok(sum)
    }
}
