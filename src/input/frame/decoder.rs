//! The sans-IO frame decoder: bytes in a `BytesMut` -> [`Sample`]s and
//! [`DecodeEvent`]s, with exact accounting in [`DecoderStats`].
//!
//! The policies (resync, CRC error vs false sync, gaps, duplicates,
//! out-of-sequence frames, discontinuities) are documented on the parent module
//! [`crate::input::frame`]. No tokio here: the daemon wraps this in
//! [`super::codec::FrameCodec`], the offline reader in
//! [`crate::input::capture`].

use std::collections::VecDeque;

use bytes::{Buf, BytesMut};

use super::{NotAFrame, RawFrame, Single, Wire};

/// Pulses between two counter readings: `(next - prev) mod 2^32` read as a
/// two's-complement `i32`, so wraps at 2^32 in either direction are handled.
#[inline]
pub fn increment_between(prev: u32, next: u32) -> i64 {
    i64::from(next.wrapping_sub(prev) as i32)
}

/// Decoder settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecoderConfig {
    /// Largest number of lost samples accepted as a gap. A forward `seq` step
    /// `d` with `2 <= d <= max_gap + 1` is a gap of `d - 1`; a larger step is
    /// treated as out of sequence (see the module docs).
    pub max_gap: u16,
}

impl Default for DecoderConfig {
    fn default() -> Self {
        DecoderConfig { max_gap: 4096 }
    }
}

/// One decoded sample period: a frame accepted after the baseline. `C` is the
/// frame's counter (`u32`, or `[u32; 3]` for a triad frame), `I` its increment
/// (`i64`, or `[i64; 3]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<C = u32, I = i64> {
    /// Sequence number of the frame.
    pub seq: u16,
    /// Raw cumulative counter of the frame.
    pub counter: C,
    /// Pulses since the previous accepted frame. After a gap this is the WHOLE
    /// difference over the gap (`lost_before + 1` sample periods).
    pub increment: I,
    /// Samples lost immediately before this one (0 when contiguous).
    pub lost_before: u16,
    /// Temperature, deg C.
    pub temp_c: f64,
    /// Status flags.
    pub status: u16,
    /// Absolute stream offset of the frame's first byte.
    pub offset: u64,
}

/// The last frame of a run consumed by [`FrameDecoder::decode_run`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunEnd {
    /// Frames (= samples) in the run.
    pub samples: usize,
    /// `seq` of its last frame.
    pub seq: u16,
    /// Temperature of its last frame, deg C.
    pub temp_c: f64,
    /// Status flags (the same for the whole run).
    pub status: u16,
}

/// Something the decoder noticed. Offsets are absolute stream offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeEvent<C = u32> {
    /// The first accepted frame (or the first after
    /// [`FrameDecoder::reset_sequence`]): it sets the counter reference and
    /// produces no sample.
    Baseline {
        /// Sequence number of the frame.
        seq: u16,
        /// Its counter.
        counter: C,
        /// Its status flags.
        status: u16,
        /// Its offset.
        offset: u64,
    },
    /// A valid frame ended a run of skipped bytes.
    Resync {
        /// Length of the run.
        skipped_bytes: u64,
        /// Offset of the frame that ended it (the run started at
        /// `at_offset - skipped_bytes`).
        at_offset: u64,
    },
    /// Sync found on the frame grid (where a frame was expected), but the CRC
    /// failed.
    CrcError {
        /// Offset of the rejected candidate.
        offset: u64,
        /// CRC computed over its bytes 0..14.
        computed: u16,
        /// CRC it carried.
        received: u16,
    },
    /// A sync pattern off the frame grid (met while hunting), with a bad CRC.
    FalseSync {
        /// Offset of the rejected candidate.
        offset: u64,
    },
    /// `lost` samples are missing after `after_seq`; the next [`Sample`]
    /// carries the whole counter difference.
    Gap {
        /// Last accepted `seq` before the gap.
        after_seq: u16,
        /// Number of missing samples.
        lost: u16,
    },
    /// Status flags changed between two accepted frames.
    StatusChange {
        /// `seq` of the frame carrying the new flags.
        seq: u16,
        /// Previous flags.
        from: u16,
        /// New flags.
        to: u16,
    },
    /// A valid frame repeating the last accepted `seq`; dropped.
    Duplicate {
        /// Its `seq`.
        seq: u16,
        /// Its offset.
        offset: u64,
    },
    /// A valid frame whose `seq` is behind, or too far ahead; dropped.
    OutOfSequence {
        /// Its `seq`.
        seq: u16,
        /// The `seq` that would have continued the series.
        expected: u16,
        /// Its offset.
        offset: u64,
    },
    /// Two consecutive frames agreed on a new sequence: the decoder
    /// re-baselined. The counter difference across it is not emitted.
    Discontinuity {
        /// Last accepted `seq` of the old sequence.
        from_seq: u16,
        /// `seq` of the new baseline frame.
        to_seq: u16,
        /// Offset of the new baseline frame.
        offset: u64,
    },
    /// End of stream with a run of skipped bytes still open (garbage and/or a
    /// trailing partial frame, which is counted, not an error).
    EndOfStream {
        /// Length of the open run, including `trailing_bytes`.
        skipped_bytes: u64,
        /// Bytes still buffered at end of stream (a partial frame) and dropped.
        trailing_bytes: u64,
        /// Stream length.
        at_offset: u64,
    },
}

/// One output item of the decoder, in stream order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decoded<C = u32, I = i64> {
    /// A sample.
    Sample(Sample<C, I>),
    /// An event (precedes the sample it concerns).
    Event(DecodeEvent<C>),
}

/// Exact counts since the decoder was created.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct DecoderStats {
    /// Bytes that appeared in the buffer (see [`FrameDecoder::decode`] for the
    /// buffer contract).
    pub bytes_read: u64,
    /// Frames with valid sync and CRC (each consumed 16 bytes), including
    /// duplicates and out-of-sequence frames.
    pub frames_decoded: u64,
    /// [`Sample`]s emitted.
    pub samples: u64,
    /// Bytes not part of a valid frame (skipped garbage, corrupted frames,
    /// trailing partial frame).
    pub bytes_skipped: u64,
    /// Runs of skipped bytes ended by a valid frame.
    pub resyncs: u64,
    /// Bad-CRC candidates on the frame grid (where a frame was expected).
    pub crc_errors: u64,
    /// Bad-CRC candidates off the frame grid (met while hunting).
    pub false_syncs: u64,
    /// Gap events.
    pub gaps: u64,
    /// Samples lost inside gaps.
    pub lost_samples: u64,
    /// Duplicate frames dropped.
    pub duplicates: u64,
    /// Out-of-sequence frames dropped.
    pub out_of_sequence: u64,
    /// Re-baselines on a new sequence.
    pub discontinuities: u64,
    /// Status-flag changes.
    pub status_changes: u64,
    /// Valid frames with a non-zero reserved field (accepted).
    pub reserved_nonzero: u64,
    /// Bytes of a trailing partial frame dropped at end of stream (also in
    /// `bytes_skipped`).
    pub trailing_bytes: u64,
}

#[derive(Debug, Clone, Copy)]
struct Anchor<C> {
    seq: u16,
    counter: C,
    offset: u64,
    status: u16,
}

impl<C: Copy> Anchor<C> {
    fn of(raw: &RawFrame<C>, offset: u64) -> Self {
        Anchor {
            seq: raw.seq,
            counter: raw.counter,
            offset,
            status: raw.status,
        }
    }
}

/// The sans-IO decoder. Feed it the same `BytesMut` over and over (append new
/// bytes at the end, never remove any yourself); it consumes frames and skipped
/// bytes from the front. `W` is the wire format: [`Single`] (the 16-byte
/// single-gyro frame, the default) or [`super::Triad`] (the 24-byte triad
/// frame); the policies and the accounting are the same.
#[derive(Debug, Clone)]
pub struct FrameDecoder<W: Wire = Single> {
    config: DecoderConfig,
    stats: DecoderStats,
    /// Absolute offset of the buffer's first byte.
    offset: u64,
    /// Buffer length when the last call returned (to count new bytes).
    buffered: usize,
    /// Bytes skipped since the last valid frame (a multiple of 16 = on its grid).
    skip_run: u64,
    /// Last accepted frame.
    last: Option<Anchor<W::Counter>>,
    /// Last out-of-sequence frame, a candidate new baseline.
    pending: Option<Anchor<W::Counter>>,
    /// Status flags of the last accepted frame.
    last_status: Option<u16>,
    queue: VecDeque<Decoded<W::Counter, W::Increment>>,
}

impl Default for FrameDecoder<Single> {
    fn default() -> Self {
        FrameDecoder::for_wire(DecoderConfig::default())
    }
}

/// Items a decoder of wire format `W` yields.
pub type WireDecoded<W> = Decoded<<W as Wire>::Counter, <W as Wire>::Increment>;

impl FrameDecoder<Single> {
    /// A single-frame decoder with the default configuration.
    pub fn new() -> Self {
        Self::default()
    }

    /// A single-frame decoder with `config`.
    pub fn with_config(config: DecoderConfig) -> Self {
        FrameDecoder::for_wire(config)
    }

    /// One-shot: decode a whole single-frame stream held in memory.
    pub fn decode_all(bytes: &[u8], config: DecoderConfig) -> (Vec<Decoded>, DecoderStats) {
        FrameDecoder::<Single>::decode_all_wire(bytes, config)
    }
}

impl<W: Wire> FrameDecoder<W> {
    /// A decoder of wire format `W` with `config`.
    pub fn for_wire(config: DecoderConfig) -> Self {
        FrameDecoder {
            config,
            stats: DecoderStats::default(),
            offset: 0,
            buffered: 0,
            skip_run: 0,
            last: None,
            pending: None,
            last_status: None,
            queue: VecDeque::new(),
        }
    }

    /// One-shot: decode a whole stream of wire format `W` held in memory.
    pub fn decode_all_wire(
        bytes: &[u8],
        config: DecoderConfig,
    ) -> (Vec<WireDecoded<W>>, DecoderStats) {
        let mut dec = FrameDecoder::<W>::for_wire(config);
        let mut buf = BytesMut::from(bytes);
        let mut out = Vec::new();
        dec.finish(&mut buf, &mut out);
        (out, dec.stats)
    }

    /// The configuration.
    pub fn config(&self) -> &DecoderConfig {
        &self.config
    }

    /// Counts so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Absolute stream offset of the first byte still in the caller's buffer.
    pub fn stream_offset(&self) -> u64 {
        self.offset
    }

    /// `seq` of the last accepted frame, if any.
    pub fn last_seq(&self) -> Option<u16> {
        self.last.map(|a| a.seq)
    }

    /// Forget the sequence (e.g. after the serial device reconnected): the next
    /// valid frame becomes a new [`DecodeEvent::Baseline`]. Byte accounting and
    /// the status history are kept.
    pub fn reset_sequence(&mut self) {
        self.last = None;
        self.pending = None;
    }

    /// Next item from the front of `buf`, or `None` when more bytes are needed
    /// (the buffer then holds at most a partial frame candidate).
    ///
    /// Contract: the bytes of `buf` beyond what the previous call left are new
    /// input (they are added to `bytes_read`).
    pub fn decode(&mut self, buf: &mut BytesMut) -> Option<WireDecoded<W>> {
        if buf.len() > self.buffered {
            self.stats.bytes_read += (buf.len() - self.buffered) as u64;
        }
        let out = match self.next_in_sequence(buf) {
            Some(sample) => Some(Decoded::Sample(sample)),
            None => loop {
                if let Some(item) = self.queue.pop_front() {
                    break Some(item);
                }
                if !self.step(buf) {
                    break None;
                }
            },
        };
        self.buffered = buf.len();
        out
    }

    /// Fast path for the common case: nothing queued, no open skip run, and a
    /// valid frame at the front of `buf` that directly follows the last accepted
    /// one with the same status. Consumes it and returns its sample, with exactly
    /// the state and counts [`step`](Self::step) would leave; anything else is
    /// left to `step` (`None`, nothing consumed).
    #[inline]
    fn next_in_sequence(&mut self, buf: &mut BytesMut) -> Option<Sample<W::Counter, W::Increment>> {
        if !self.queue.is_empty() || self.skip_run != 0 {
            return None;
        }
        let last = self.last?;
        W::check(buf).ok()?;
        let raw = W::parse(buf)?;
        if raw.seq != last.seq.wrapping_add(1) || self.last_status != Some(raw.status) {
            return None;
        }
        let offset = self.offset;
        buf.advance(W::LEN);
        self.offset += W::LEN as u64;
        self.stats.frames_decoded += 1;
        if raw.reserved != 0 {
            self.stats.reserved_nonzero += 1;
        }
        self.pending = None;
        self.stats.samples += 1;
        self.last = Some(Anchor::of(&raw, offset));
        Some(Sample {
            seq: raw.seq,
            counter: raw.counter,
            increment: W::increment(last.counter, raw.counter),
            lost_before: 0,
            temp_c: raw.temp_c(),
            status: raw.status,
            offset,
        })
    }

    /// Bulk form of the fast path: consume the longest run (at most `max`
    /// frames) of valid frames at the front of `buf` that each directly follow
    /// the previous accepted one with the same status, append their pulse
    /// increments to `increments`, and return what the last of them carried.
    /// Exactly the state, counts and samples that calling [`decode`](Self::decode)
    /// once per frame would give (those calls would return only
    /// [`Decoded::Sample`]s with `lost_before == 0`); `None`, with nothing
    /// consumed, when the front of `buf` is anything else, which `decode` then
    /// handles.
    pub fn decode_run(
        &mut self,
        buf: &mut BytesMut,
        max: usize,
        increments: &mut Vec<W::Increment>,
    ) -> Option<RunEnd> {
        if !self.queue.is_empty() || self.skip_run != 0 || max == 0 {
            return None;
        }
        let last = self.last?;
        let status = self.last_status?;
        let mut prev = last;
        let mut reserved_nonzero = 0u64;
        let mut n = 0usize;
        let mut last_raw = None;
        for frame in buf.chunks_exact(W::LEN).take(max) {
            let Some(raw) = W::check(frame).ok().and_then(|()| W::parse(frame)) else {
                break;
            };
            if raw.seq != prev.seq.wrapping_add(1) || raw.status != status {
                break;
            }
            increments.push(W::increment(prev.counter, raw.counter));
            reserved_nonzero += u64::from(raw.reserved != 0);
            prev = Anchor::of(&raw, self.offset + (n * W::LEN) as u64);
            last_raw = Some(raw);
            n += 1;
        }
        let last_raw = last_raw?;
        if buf.len() > self.buffered {
            self.stats.bytes_read += (buf.len() - self.buffered) as u64;
        }
        buf.advance(n * W::LEN);
        self.buffered = buf.len();
        self.offset += (n * W::LEN) as u64;
        self.stats.frames_decoded += n as u64;
        self.stats.samples += n as u64;
        self.stats.reserved_nonzero += reserved_nonzero;
        self.pending = None;
        self.last = Some(prev);
        Some(RunEnd {
            samples: n,
            seq: last_raw.seq,
            temp_c: last_raw.temp_c(),
            status,
        })
    }

    /// Like [`decode`](Self::decode), at end of stream: once no further item can
    /// be decoded, the remaining bytes (a partial frame) are dropped and counted
    /// (`trailing_bytes`, `bytes_skipped`), and an open run of skipped bytes is
    /// reported by [`DecodeEvent::EndOfStream`]. Returns `None` when done; the
    /// buffer is then empty.
    pub fn decode_eof(&mut self, buf: &mut BytesMut) -> Option<WireDecoded<W>> {
        if let Some(item) = self.decode(buf) {
            return Some(item);
        }
        let trailing = buf.len();
        if trailing > 0 {
            self.skip(buf, trailing);
            self.stats.trailing_bytes += trailing as u64;
            self.buffered = 0;
        }
        if self.skip_run > 0 {
            self.queue
                .push_back(Decoded::Event(DecodeEvent::EndOfStream {
                    skipped_bytes: self.skip_run,
                    trailing_bytes: trailing as u64,
                    at_offset: self.offset,
                }));
            self.skip_run = 0;
        }
        self.queue.pop_front()
    }

    /// Decode everything currently decodable in `buf` into `out`.
    pub fn decode_available(&mut self, buf: &mut BytesMut, out: &mut Vec<WireDecoded<W>>) {
        while let Some(item) = self.decode(buf) {
            out.push(item);
        }
    }

    /// Decode everything in `buf` as the end of the stream into `out`.
    pub fn finish(&mut self, buf: &mut BytesMut, out: &mut Vec<WireDecoded<W>>) {
        while let Some(item) = self.decode_eof(buf) {
            out.push(item);
        }
    }

    fn skip(&mut self, buf: &mut BytesMut, n: usize) {
        buf.advance(n);
        self.offset += n as u64;
        self.stats.bytes_skipped += n as u64;
        self.skip_run += n as u64;
    }

    /// Consume one frame or one bad-CRC byte (queueing what it produced), or
    /// return `false` when more bytes are needed.
    fn step(&mut self, buf: &mut BytesMut) -> bool {
        loop {
            match W::check(buf) {
                Ok(()) => {
                    let Some(raw) = W::parse(buf) else {
                        return false; // unreachable: check saw 16 bytes
                    };
                    let offset = self.offset;
                    buf.advance(W::LEN);
                    self.offset += W::LEN as u64;
                    self.stats.frames_decoded += 1;
                    if self.skip_run > 0 {
                        self.stats.resyncs += 1;
                        self.push(DecodeEvent::Resync {
                            skipped_bytes: self.skip_run,
                            at_offset: offset,
                        });
                        self.skip_run = 0;
                    }
                    self.accept(&raw, offset);
                    return true;
                }
                Err(NotAFrame::Incomplete { .. }) => return false,
                Err(NotAFrame::NoSync) => {
                    // Slide to the next possible sync start (every byte in
                    // between is a one-byte slide that cannot start a frame).
                    let n = buf[1..]
                        .iter()
                        .position(|&b| b == W::SYNC[0])
                        .map_or(buf.len(), |p| p + 1);
                    self.skip(buf, n);
                }
                Err(NotAFrame::BadCrc { computed, received }) => {
                    let offset = self.offset;
                    if self.skip_run.is_multiple_of(W::LEN as u64) {
                        self.stats.crc_errors += 1;
                        self.push(DecodeEvent::CrcError {
                            offset,
                            computed,
                            received,
                        });
                    } else {
                        self.stats.false_syncs += 1;
                        self.push(DecodeEvent::FalseSync { offset });
                    }
                    self.skip(buf, 1);
                    return true;
                }
            }
        }
    }

    fn push(&mut self, ev: DecodeEvent<W::Counter>) {
        self.queue.push_back(Decoded::Event(ev));
    }

    fn track_status(&mut self, seq: u16, status: u16) {
        if let Some(from) = self.last_status
            && from != status
        {
            self.stats.status_changes += 1;
            self.push(DecodeEvent::StatusChange {
                seq,
                from,
                to: status,
            });
        }
        self.last_status = Some(status);
    }

    fn baseline(&mut self, anchor: Anchor<W::Counter>) {
        self.track_status(anchor.seq, anchor.status);
        self.push(DecodeEvent::Baseline {
            seq: anchor.seq,
            counter: anchor.counter,
            status: anchor.status,
            offset: anchor.offset,
        });
        self.last = Some(anchor);
    }

    /// A frame with a valid CRC: place it in the sequence.
    fn accept(&mut self, raw: &RawFrame<W::Counter>, offset: u64) {
        if raw.reserved != 0 {
            self.stats.reserved_nonzero += 1;
        }
        let here = Anchor::of(raw, offset);
        let Some(last) = self.last else {
            self.pending = None;
            self.baseline(here);
            return;
        };
        let d = raw.seq.wrapping_sub(last.seq);
        if d == 0 {
            self.stats.duplicates += 1;
            self.push(DecodeEvent::Duplicate {
                seq: raw.seq,
                offset,
            });
            return;
        }
        if u32::from(d) <= u32::from(self.config.max_gap) + 1 {
            self.pending = None;
            self.emit_sample(last, raw, offset, d - 1);
            return;
        }
        if let Some(p) = self.pending
            && raw.seq == p.seq.wrapping_add(1)
        {
            // Two consecutive frames agree on a new sequence: re-baseline on
            // the remembered one and continue from it.
            self.stats.discontinuities += 1;
            self.push(DecodeEvent::Discontinuity {
                from_seq: last.seq,
                to_seq: p.seq,
                offset: p.offset,
            });
            self.pending = None;
            self.track_status(p.seq, p.status);
            self.emit_sample(p, raw, offset, 0);
            return;
        }
        self.stats.out_of_sequence += 1;
        self.push(DecodeEvent::OutOfSequence {
            seq: raw.seq,
            expected: last.seq.wrapping_add(1),
            offset,
        });
        self.pending = Some(here);
    }

    fn emit_sample(
        &mut self,
        prev: Anchor<W::Counter>,
        raw: &RawFrame<W::Counter>,
        offset: u64,
        lost: u16,
    ) {
        if lost > 0 {
            self.stats.gaps += 1;
            self.stats.lost_samples += u64::from(lost);
            self.push(DecodeEvent::Gap {
                after_seq: prev.seq,
                lost,
            });
        }
        self.track_status(raw.seq, raw.status);
        self.stats.samples += 1;
        self.queue.push_back(Decoded::Sample(Sample {
            seq: raw.seq,
            counter: raw.counter,
            increment: W::increment(prev.counter, raw.counter),
            lost_before: lost,
            temp_c: raw.temp_c(),
            status: raw.status,
            offset,
        }));
        self.last = Some(Anchor::of(raw, offset));
    }
}
