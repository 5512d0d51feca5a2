//! The gyro's binary frame: wire format, sans-IO decoder, encoder, gap filling
//! and a corruption injector.
//!
//! This is the first stage of the acquisition chain: raw bytes from the serial
//! port (daemon), from a replayed `.bin` capture ([`crate::input::capture`]) or
//! from the emulator go in; uniformly numbered pulse increments
//! ([`Sample`]) and diagnostic [`DecodeEvent`]s come out and feed `dsp`/`allan`.
//!
//! # Frame format
//!
//! 16 bytes, multi-byte fields little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | sync `0xA5 0x5A` |
//! | 2 | 2 | `seq`: u16, +1 per sample period, wraps at 65536 |
//! | 4 | 4 | `counter`: u32 cumulative up/down pulse counter (two's complement, wraps at 2^32) |
//! | 8 | 2 | `temp`: i16, units of 0.01 deg C |
//! | 10 | 2 | `status`: u16 flags (bit 0 dither ok, bit 1 path-length control locked, bit 2 laser intensity ok) |
//! | 12 | 2 | reserved, 0 |
//! | 14 | 2 | CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor) over bytes 0..14, little-endian |
//!
//! CRC-16/CCITT-FALSE is the catalogue entry `CRC_16_IBM_3740` of the `crc`
//! crate (check value `0x29B1` for `"123456789"`).
//!
//! # Decoding (mini-redis style, sans-IO)
//!
//! [`FrameDecoder::decode`] works on the caller's `bytes::BytesMut`: [`check`]
//! asks "is a whole, valid frame at the front?", then [`parse`] reads it and the
//! buffer is advanced by 16 bytes. "Incomplete" is not an error: it means read
//! more bytes. Nothing in the stream can make the decoder fail or panic:
//!
//! * a byte that does not start the sync pattern is skipped (counted in
//!   `bytes_skipped`);
//! * a sync pattern followed by a bad CRC costs a ONE-byte slide, then the hunt
//!   for the next sync continues. It is counted as a **CRC error** when the
//!   candidate sits on the 16-byte grid of the last valid frame (a whole number
//!   of frame lengths after its end, or after stream offset 0 before any valid
//!   frame): a frame was expected there, so it is taken for a frame corrupted on
//!   the wire, and a burst of consecutive corrupted frames counts one CRC error
//!   each. Off the grid it is counted as a **false sync** (a sync pattern met
//!   while hunting: in garbage or inside a corrupted frame). The two counts
//!   together are all rejected sync candidates; the split is the decoder's best
//!   reading of an inherently ambiguous situation (garbage that happens to start
//!   with the sync pattern on the grid counts as a CRC error);
//! * when a valid frame ends a run of skipped bytes, one [`DecodeEvent::Resync`]
//!   reports the run length; a run still open at end of stream is reported by
//!   [`DecodeEvent::EndOfStream`] from [`FrameDecoder::decode_eof`], which also
//!   drops (and counts as skipped and as `trailing_bytes`) a trailing partial frame.
//!
//! Byte offsets in events are absolute stream offsets (bytes since the decoder
//! was created). Accounting identity, checked by the property tests:
//! `bytes_read == 16 * frames_decoded + bytes_skipped + bytes still buffered`.
//!
//! # Increments, counter wrap
//!
//! The counter is cumulative, so each accepted frame after the first yields
//! `increment = (counter[k] - counter[k-1]) mod 2^32` read as an `i32`
//! (`counter.wrapping_sub(prev) as i32 as i64`): `0xFFFF_FFFE -> 0x0000_0003`
//! is `+5`, `0x0000_0002 -> 0xFFFF_FFFD` is `-5`. An increment (over one sample
//! or over a whole gap) is unambiguous while its magnitude is below 2^31 pulses.
//! The first accepted frame only sets the baseline ([`DecodeEvent::Baseline`])
//! and produces no sample: N frames give N-1 increments.
//!
//! # Gap policy (sequence numbers)
//!
//! With `d = seq.wrapping_sub(prev_seq)` relative to the last accepted frame:
//!
//! * `d == 1`: a normal sample.
//! * `2 <= d <= max_gap + 1` ([`DecoderConfig::max_gap`], default 4096): `d - 1`
//!   samples were lost. Because the counter is cumulative **no angle is lost**:
//!   the WHOLE counter difference is emitted as the increment of the first
//!   sample after the gap, that sample carries `lost_before = d - 1`, and a
//!   [`DecodeEvent::Gap`]`{ after_seq, lost }` precedes it. `gaps` and
//!   `lost_samples` count them. The Allan and wavelet stages need a uniformly
//!   sampled series: [`fill_gap`] (or [`GapFiller`]) turns such a sample into
//!   `lost_before + 1` uniform samples by spreading the increment linearly as
//!   integers, `share_j = floor(I*(j+1)/n) - floor(I*j/n)` for `j = 0..n`, whose
//!   sum is exactly `I` and whose running sum never strays from the straight
//!   line by one pulse or more (the synthetic ones are flagged).
//! * `d == 0`: a duplicate. The frame is dropped (no sample), counted in
//!   `duplicates`, reported by [`DecodeEvent::Duplicate`].
//! * otherwise (a backward step, or a forward jump beyond `max_gap`): the frame is
//!   dropped, counted in `out_of_sequence`, reported by
//!   [`DecodeEvent::OutOfSequence`], and remembered. If the very next valid frame
//!   continues it (`seq == remembered + 1`) while still not fitting the old
//!   sequence, the gyro (or the link) restarted: the decoder re-baselines on the
//!   remembered frame ([`DecodeEvent::Discontinuity`], counted in
//!   `discontinuities`) and goes on from there. The counter difference across a
//!   discontinuity is NOT emitted (the elapsed number of samples is unknown);
//!   downstream should start a new segment. A single stale or replayed frame is
//!   thus ignored without ever double-counting angle.
//!
//! Status-flag changes between accepted frames are reported as
//! [`DecodeEvent::StatusChange`] and counted. A frame with a non-zero reserved
//! field but a valid CRC is accepted and counted in `reserved_nonzero`.
//!
//! # The triad frame
//!
//! A 24-byte frame carrying three counters (x, y, z) under one `seq`, sync
//! `0xA5 0x5B`: see [`triad`]. The decoder is generic over the wire format
//! ([`Wire`]: [`Single`], the default, or [`Triad`]); everything above holds for
//! both, with 24 in place of 16.
//!
//! # Submodules
//!
//! * `decoder`: [`FrameDecoder`] and its output types;
//! * `encoder`: [`FrameEncoder`], [`FrameWriter`] (used by the simulator and the
//!   bench emulator);
//! * `fill`: [`FilledSeries`], [`fill_gap`], [`GapFiller`], [`spread_increment`];
//! * [`inject`]: a seeded corruption injector with an exact ledger, for tests and
//!   the daemon's emulator;
//! * [`triad`]: the triad frame's layout, [`Triad`] and [`TriadEncoder`];
//! * [`codec`]: the `tokio_util::codec::Decoder` adapter (the only part that
//!   touches the tokio ecosystem).

pub mod axes;
pub mod codec;
mod decoder;
mod encoder;
mod fill;
pub mod inject;
pub mod triad;

pub use crate::dsp::gaps::spread_increment;
pub use axes::Axes;
pub use decoder::{
    DecodeEvent, Decoded, DecoderConfig, DecoderStats, FrameDecoder, RunEnd, Sample, WireDecoded,
    increment_between,
};
pub use encoder::{FrameEncoder, FrameWriter, encode_increments};
pub use fill::{FilledSeries, GapFiller, UniformSample, fill_gap};
pub use triad::{TRIAD_FRAME_LEN, TRIAD_SYNC, Triad, TriadEncoder, encode_triad_frame};

use crc::{CRC_16_IBM_3740, Crc};

/// Length of one frame in bytes.
pub const FRAME_LEN: usize = 16;
/// The two sync bytes that start every frame.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Degrees Celsius per unit of the raw `temp` field.
pub const TEMP_C_PER_LSB: f64 = 0.01;

/// Status flag bit 0: dither OK.
pub const STATUS_DITHER_OK: u16 = 1 << 0;
/// Status flag bit 1: path-length control loop locked.
pub const STATUS_PLC_LOCKED: u16 = 1 << 1;
/// Status flag bit 2: laser intensity OK.
pub const STATUS_LASER_OK: u16 = 1 << 2;
/// All three "healthy" flags.
pub const STATUS_ALL_OK: u16 = STATUS_DITHER_OK | STATUS_PLC_LOCKED | STATUS_LASER_OK;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor).
pub const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// CRC-16/CCITT-FALSE of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

/// Position tables of the frame CRC: `CRC_POS[i][b]` is the CRC register (init 0)
/// after a 14-byte message holding `b` at position `i` and zeros elsewhere.
const CRC_POS: [[u16; 256]; 14] = crc_position_tables();
/// The register after 14 zero bytes with the init value 0xFFFF.
const CRC_INIT_14: u16 = crc_init_through(14);

pub(crate) const fn crc_step_zero(crc: u16) -> u16 {
    // one zero byte through the MSB-first register (poly 0x1021)
    let mut c = crc;
    let mut k = 0;
    while k < 8 {
        c = if c & 0x8000 != 0 {
            (c << 1) ^ 0x1021
        } else {
            c << 1
        };
        k += 1;
    }
    c
}

pub(crate) const fn crc_init_through(n: usize) -> u16 {
    let mut c = 0xFFFF;
    let mut i = 0;
    while i < n {
        c = crc_step_zero(c);
        i += 1;
    }
    c
}

pub(crate) const fn crc_position_tables<const N: usize>() -> [[u16; 256]; N] {
    let mut t = [[0u16; 256]; N];
    let mut b = 0;
    while b < 256 {
        // byte b last (position N - 1): one step from register b << 8
        let mut c = crc_step_zero((b as u16) << 8);
        let mut i = N;
        while i > 0 {
            i -= 1;
            t[i][b] = c;
            c = crc_step_zero(c); // one more zero byte after it
        }
        b += 1;
    }
    t
}

/// CRC-16/CCITT-FALSE of a frame's first 14 bytes, equal to
/// `crc16(&head[..])`: the CRC is linear, so it is the init term XOR one table
/// lookup per byte, independent of each other (the decoder's hot path).
#[inline]
pub fn crc16_frame(head: &[u8; 14]) -> u16 {
    let mut c = CRC_INIT_14;
    let mut i = 0;
    while i < 14 {
        c ^= CRC_POS[i][head[i] as usize];
        i += 1;
    }
    c
}

/// Errors of the frame layer. Decoding itself never fails (bad bytes are
/// skipped and counted); these come from encoding and from the I/O adapter.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// An increment that a 32-bit wrapping counter cannot carry unambiguously.
    #[error(
        "increment {increment} pulses for frame seq {seq} is outside the representable range \
         [-2^31, 2^31-1] of a wrapping 32-bit counter difference"
    )]
    IncrementOutOfRange {
        /// Sequence number of the frame that would carry it.
        seq: u16,
        /// The offending increment.
        increment: i64,
    },
    /// An I/O error of the stream being decoded (the tokio codec adapter).
    #[error("I/O error while reading frames")]
    Io(#[from] std::io::Error),
    /// An I/O error while writing frames ([`FrameWriter`]).
    #[error("I/O error writing frames after {offset} bytes")]
    Write {
        /// Bytes successfully written before the error.
        offset: u64,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// The fields of one frame, as on the wire (`C`: `u32` for the single frame,
/// `[u32; 3]` for the triad frame).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RawFrame<C = u32> {
    /// Sequence number, +1 per sample period, wraps.
    pub seq: u16,
    /// Cumulative up/down pulse counter(s), wrap at 2^32.
    pub counter: C,
    /// Temperature in units of 0.01 deg C.
    pub temp_raw: i16,
    /// Status flags (`STATUS_*`).
    pub status: u16,
    /// Reserved field (0 on a conforming gyro).
    pub reserved: u16,
    /// The CRC as received.
    pub crc: u16,
}

impl<C> RawFrame<C> {
    /// Temperature in deg C.
    pub fn temp_c(&self) -> f64 {
        f64::from(self.temp_raw) * TEMP_C_PER_LSB
    }
}

/// Why the bytes at the front of a buffer are not (yet) a valid frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotAFrame {
    /// Not enough bytes to decide: read more. Not an error.
    Incomplete {
        /// Bytes present.
        have: usize,
    },
    /// The front does not start with the sync pattern.
    NoSync,
    /// Sync present, CRC mismatch.
    BadCrc {
        /// CRC computed over bytes 0..14.
        computed: u16,
        /// CRC carried in bytes 14..16.
        received: u16,
    },
}

/// Is a whole, valid frame at the front of `buf`? (mini-redis' `check` step.)
///
/// Decides as early as possible: a first byte other than `0xA5`, or a second
/// byte other than `0x5A`, is [`NotAFrame::NoSync`] even when fewer than 16 bytes
/// are present.
pub fn check(buf: &[u8]) -> Result<(), NotAFrame> {
    match buf {
        [] => return Err(NotAFrame::Incomplete { have: 0 }),
        [b0, ..] if *b0 != SYNC[0] => return Err(NotAFrame::NoSync),
        [_] => return Err(NotAFrame::Incomplete { have: 1 }),
        [_, b1, ..] if *b1 != SYNC[1] => return Err(NotAFrame::NoSync),
        _ => {}
    }
    if buf.len() < FRAME_LEN {
        return Err(NotAFrame::Incomplete { have: buf.len() });
    }
    let head: &[u8; 14] = buf[..14].try_into().expect("16 bytes checked above");
    let computed = crc16_frame(head);
    let received = u16::from_le_bytes([buf[14], buf[15]]);
    if computed != received {
        return Err(NotAFrame::BadCrc { computed, received });
    }
    Ok(())
}

/// Read the fields of the frame at the front of `buf` (mini-redis' `parse`
/// step). Does not validate sync or CRC (call [`check`] first); returns `None`
/// when fewer than 16 bytes are present.
pub fn parse(buf: &[u8]) -> Option<RawFrame> {
    let b: &[u8; FRAME_LEN] = buf.get(..FRAME_LEN)?.try_into().ok()?;
    let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
    Some(RawFrame {
        seq: u16_at(2),
        counter: u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
        temp_raw: i16::from_le_bytes([b[8], b[9]]),
        status: u16_at(10),
        reserved: u16_at(12),
        crc: u16_at(14),
    })
}

/// Encode one frame (reserved field 0, CRC appended).
pub fn encode_frame(seq: u16, counter: u32, temp_raw: i16, status: u16) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[0..2].copy_from_slice(&SYNC);
    f[2..4].copy_from_slice(&seq.to_le_bytes());
    f[4..8].copy_from_slice(&counter.to_le_bytes());
    f[8..10].copy_from_slice(&temp_raw.to_le_bytes());
    f[10..12].copy_from_slice(&status.to_le_bytes());
    // bytes 12..14: reserved, 0
    let crc = crc16(&f[..14]);
    f[14..16].copy_from_slice(&crc.to_le_bytes());
    f
}

/// A wire format the generic [`FrameDecoder`] reads: its length, sync pattern,
/// `check`/`parse` steps and how two counter readings make an increment. The
/// decoding policies (resync, CRC error vs false sync on the `LEN`-byte grid,
/// gaps, duplicates, discontinuities) do not depend on it.
pub trait Wire: Copy + std::fmt::Debug + 'static {
    /// Frame length, bytes.
    const LEN: usize;
    /// The two sync bytes.
    const SYNC: [u8; 2];
    /// The cumulative counter(s) of a frame.
    type Counter: Copy + std::fmt::Debug + PartialEq + Eq;
    /// Pulses between two frames.
    type Increment: Copy + std::fmt::Debug + PartialEq;
    /// Is a whole, valid frame at the front of `buf`?
    fn check(buf: &[u8]) -> Result<(), NotAFrame>;
    /// The fields of the frame at the front of `buf` (not validated).
    fn parse(buf: &[u8]) -> Option<RawFrame<Self::Counter>>;
    /// Pulses from `prev` to `next` (wrapping 32-bit differences).
    fn increment(prev: Self::Counter, next: Self::Counter) -> Self::Increment;
}

/// The 16-byte single-gyro frame (sync `0xA5 0x5A`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Single;

impl Wire for Single {
    const LEN: usize = FRAME_LEN;
    const SYNC: [u8; 2] = SYNC;
    type Counter = u32;
    type Increment = i64;
    #[inline]
    fn check(buf: &[u8]) -> Result<(), NotAFrame> {
        check(buf)
    }
    #[inline]
    fn parse(buf: &[u8]) -> Option<RawFrame> {
        parse(buf)
    }
    #[inline]
    fn increment(prev: u32, next: u32) -> i64 {
        increment_between(prev, next)
    }
}
