//! The triad frame: three gyros (x, y, z) sampled together in one 24-byte frame.
//!
//! Little-endian, like the single frame:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 2 | sync `0xA5 0x5B` |
//! | 2 | 2 | `seq`: u16, +1 per sample period, wraps at 65536 |
//! | 4 | 4 | counter x: u32 cumulative up/down pulse counter (wraps at 2^32) |
//! | 8 | 4 | counter y |
//! | 12 | 4 | counter z |
//! | 16 | 2 | `temp`: i16, units of 0.01 deg C |
//! | 18 | 2 | `status`: u16 flags, as in the single frame |
//! | 20 | 2 | reserved, 0 |
//! | 22 | 2 | CRC-16/CCITT-FALSE over bytes 0..22, little-endian |
//!
//! The second sync byte differs from the single frame's (`0x5A`), so neither
//! decoder takes the other's frames. [`Triad`] plugs this layout into the
//! generic [`super::FrameDecoder`]: the same resync, CRC error / false sync split
//! (on the 24-byte grid), gap, duplicate and discontinuity policies and the same
//! exact accounting (`bytes_read == 24 * frames_decoded + bytes_skipped +
//! buffered`). A sample's increment is `[x, y, z]`, each the wrapping 32-bit
//! difference of its counter; a gap carries the whole difference of each.

use super::{
    FrameError, NotAFrame, RawFrame, STATUS_ALL_OK, Wire, crc_init_through, crc_position_tables,
    crc16, increment_between,
};

/// Length of one triad frame in bytes.
pub const TRIAD_FRAME_LEN: usize = 24;
/// The two sync bytes that start every triad frame.
pub const TRIAD_SYNC: [u8; 2] = [0xA5, 0x5B];
/// Names of the three axes, in frame order.
pub const AXES: [&str; 3] = ["x", "y", "z"];

const HEAD: usize = TRIAD_FRAME_LEN - 2;
const CRC_POS: [[u16; 256]; HEAD] = crc_position_tables();
const CRC_INIT: u16 = crc_init_through(HEAD);

/// CRC-16/CCITT-FALSE of a triad frame's first 22 bytes (equal to
/// `crc16(&head[..])`, by table lookups per position).
#[inline]
pub fn crc16_triad(head: &[u8; HEAD]) -> u16 {
    let mut c = CRC_INIT;
    for (i, &b) in head.iter().enumerate() {
        c ^= CRC_POS[i][b as usize];
    }
    c
}

/// The 24-byte triad frame as a wire format of [`super::FrameDecoder`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Triad;

impl Wire for Triad {
    const LEN: usize = TRIAD_FRAME_LEN;
    const SYNC: [u8; 2] = TRIAD_SYNC;
    type Counter = [u32; 3];
    type Increment = [i64; 3];

    fn check(buf: &[u8]) -> Result<(), NotAFrame> {
        match buf {
            [] => return Err(NotAFrame::Incomplete { have: 0 }),
            [b0, ..] if *b0 != TRIAD_SYNC[0] => return Err(NotAFrame::NoSync),
            [_] => return Err(NotAFrame::Incomplete { have: 1 }),
            [_, b1, ..] if *b1 != TRIAD_SYNC[1] => return Err(NotAFrame::NoSync),
            _ => {}
        }
        let Some(frame) = buf.get(..TRIAD_FRAME_LEN) else {
            return Err(NotAFrame::Incomplete { have: buf.len() });
        };
        let mut head = [0u8; HEAD];
        head.copy_from_slice(&frame[..HEAD]);
        let computed = crc16_triad(&head);
        let received = u16::from_le_bytes([frame[HEAD], frame[HEAD + 1]]);
        if computed != received {
            return Err(NotAFrame::BadCrc { computed, received });
        }
        Ok(())
    }

    fn parse(buf: &[u8]) -> Option<RawFrame<[u32; 3]>> {
        let b = buf.get(..TRIAD_FRAME_LEN)?;
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Some(RawFrame {
            seq: u16_at(2),
            counter: [u32_at(4), u32_at(8), u32_at(12)],
            temp_raw: i16::from_le_bytes([b[16], b[17]]),
            status: u16_at(18),
            reserved: u16_at(20),
            crc: u16_at(22),
        })
    }

    #[inline]
    fn increment(prev: [u32; 3], next: [u32; 3]) -> [i64; 3] {
        [
            increment_between(prev[0], next[0]),
            increment_between(prev[1], next[1]),
            increment_between(prev[2], next[2]),
        ]
    }
}

/// Encode one triad frame (reserved field 0, CRC appended).
pub fn encode_triad_frame(
    seq: u16,
    counters: [u32; 3],
    temp_raw: i16,
    status: u16,
) -> [u8; TRIAD_FRAME_LEN] {
    let mut f = [0u8; TRIAD_FRAME_LEN];
    f[0..2].copy_from_slice(&TRIAD_SYNC);
    f[2..4].copy_from_slice(&seq.to_le_bytes());
    for (k, c) in counters.iter().enumerate() {
        f[4 + 4 * k..8 + 4 * k].copy_from_slice(&c.to_le_bytes());
    }
    f[16..18].copy_from_slice(&temp_raw.to_le_bytes());
    f[18..20].copy_from_slice(&status.to_le_bytes());
    // bytes 20..22: reserved, 0
    let crc = crc16(&f[..HEAD]);
    f[22..24].copy_from_slice(&crc.to_le_bytes());
    f
}

/// Stateful triad encoder: `seq`, three counters, temperature and status, as
/// [`super::FrameEncoder`] for one gyro (N increments become N + 1 frames).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriadEncoder {
    seq: u16,
    counters: [u32; 3],
    temp_raw: i16,
    status: u16,
}

impl TriadEncoder {
    /// Start at `(start_seq, start_counters)`, 25.00 deg C, all status flags OK.
    pub fn new(start_seq: u16, start_counters: [u32; 3]) -> Self {
        TriadEncoder {
            seq: start_seq,
            counters: start_counters,
            temp_raw: 2500,
            status: STATUS_ALL_OK,
        }
    }

    /// Sequence number of the last frame produced.
    pub fn seq(&self) -> u16 {
        self.seq
    }

    /// Current counters.
    pub fn counters(&self) -> [u32; 3] {
        self.counters
    }

    /// Temperature for the following frames, deg C (rounded to 0.01, saturated).
    pub fn set_temp_c(&mut self, temp_c: f64) {
        self.temp_raw = (temp_c / super::TEMP_C_PER_LSB).round() as i16;
    }

    /// Status flags for the following frames.
    pub fn set_status(&mut self, status: u16) {
        self.status = status;
    }

    /// The frame for the current state (the first frame of a stream).
    pub fn current_frame(&self) -> [u8; TRIAD_FRAME_LEN] {
        encode_triad_frame(self.seq, self.counters, self.temp_raw, self.status)
    }

    /// Advance one sample period carrying `increments` pulses (x, y, z) and
    /// return its frame; errors (state unchanged) when one is outside
    /// `[-2^31, 2^31 - 1]`.
    pub fn step(&mut self, increments: [i64; 3]) -> Result<[u8; TRIAD_FRAME_LEN], FrameError> {
        let seq = self.seq.wrapping_add(1);
        let mut next = self.counters;
        for (c, &increment) in next.iter_mut().zip(&increments) {
            let inc = i32::try_from(increment)
                .map_err(|_| FrameError::IncrementOutOfRange { seq, increment })?;
            *c = c.wrapping_add(inc as u32);
        }
        self.seq = seq;
        self.counters = next;
        Ok(self.current_frame())
    }
}

/// The N + 1 triad frames (baseline first) that carry `increments`.
pub fn encode_triad_increments(
    encoder: &mut TriadEncoder,
    increments: &[[i64; 3]],
) -> Result<Vec<[u8; TRIAD_FRAME_LEN]>, FrameError> {
    let mut frames = Vec::with_capacity(increments.len() + 1);
    frames.push(encoder.current_frame());
    for &inc in increments {
        frames.push(encoder.step(inc)?);
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_crc_equals_the_catalogue_crc() {
        let mut head = [0u8; HEAD];
        for (i, b) in head.iter_mut().enumerate() {
            *b = (i as u8).wrapping_mul(37).wrapping_add(11);
        }
        assert_eq!(crc16_triad(&head), crc16(&head));
        assert_eq!(crc16_triad(&[0u8; HEAD]), crc16(&[0u8; HEAD]));
    }

    #[test]
    fn known_answer_frame() {
        let f = encode_triad_frame(0x1234, [1, 0xFFFF_FFFF, 0x0102_0304], -150, 7);
        assert_eq!(&f[..4], &[0xA5, 0x5B, 0x34, 0x12]);
        assert_eq!(&f[4..16], &[1, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 4, 3, 2, 1]);
        assert_eq!(&f[16..22], &[0x6A, 0xFF, 7, 0, 0, 0]);
        assert_eq!(u16::from_le_bytes([f[22], f[23]]), crc16(&f[..22]));
        assert_eq!(Triad::check(&f), Ok(()));
        let raw = Triad::parse(&f).unwrap();
        assert_eq!(raw.counter, [1, 0xFFFF_FFFF, 0x0102_0304]);
        assert_eq!(
            (raw.seq, raw.temp_raw, raw.status, raw.reserved),
            (0x1234, -150, 7, 0)
        );
        // a single frame is not a triad frame, and vice versa
        let single = super::super::encode_frame(1, 2, 3, 4);
        assert_eq!(Triad::check(&single), Err(NotAFrame::NoSync));
        assert_eq!(super::super::check(&f), Err(NotAFrame::NoSync));
    }
}
