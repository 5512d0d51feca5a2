//! Frame encoding: turn a stream of pulse increments into gyro frames, as the
//! real gyro does. Used by the simulator, the bench emulator and the tests.
//!
//! The model: the gyro holds `(seq, counter)`. Its first frame reports the
//! starting state (the decoder's baseline); each sample period adds the
//! period's pulses to the wrapping 32-bit counter, increments `seq` (wrapping)
//! and sends a frame. So N increments become N + 1 frames.

use std::io::Write;

use super::{FRAME_LEN, FrameError, STATUS_ALL_OK, encode_frame};

/// Stateful encoder: current `seq`, `counter`, temperature and status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameEncoder {
    seq: u16,
    counter: u32,
    temp_raw: i16,
    status: u16,
}

impl FrameEncoder {
    /// Start at `(start_seq, start_counter)` (choose them near 65535 / 2^32 to
    /// exercise the wraps), 25.00 deg C, all status flags OK.
    pub fn new(start_seq: u16, start_counter: u32) -> Self {
        FrameEncoder {
            seq: start_seq,
            counter: start_counter,
            temp_raw: 2500,
            status: STATUS_ALL_OK,
        }
    }

    /// Current sequence number (of the last frame produced).
    pub fn seq(&self) -> u16 {
        self.seq
    }

    /// Current counter.
    pub fn counter(&self) -> u32 {
        self.counter
    }

    /// Temperature field for the following frames, raw units of 0.01 deg C.
    pub fn set_temp_raw(&mut self, temp_raw: i16) {
        self.temp_raw = temp_raw;
    }

    /// Temperature for the following frames in deg C, rounded to 0.01 deg C and
    /// saturated to the i16 range (NaN becomes 0).
    pub fn set_temp_c(&mut self, temp_c: f64) {
        // `as` saturates and maps NaN to 0.
        self.temp_raw = (temp_c / super::TEMP_C_PER_LSB).round() as i16;
    }

    /// Status flags for the following frames.
    pub fn set_status(&mut self, status: u16) {
        self.status = status;
    }

    /// The frame for the current state (the first frame of a stream).
    pub fn current_frame(&self) -> [u8; FRAME_LEN] {
        encode_frame(self.seq, self.counter, self.temp_raw, self.status)
    }

    /// Advance one sample period carrying `increment` pulses and return its
    /// frame. Errors (state unchanged) when `increment` is outside
    /// `[-2^31, 2^31 - 1]`, the range a decoder can recover from a wrapping
    /// 32-bit difference.
    pub fn step(&mut self, increment: i64) -> Result<[u8; FRAME_LEN], FrameError> {
        let seq = self.seq.wrapping_add(1);
        let inc = i32::try_from(increment)
            .map_err(|_| FrameError::IncrementOutOfRange { seq, increment })?;
        self.seq = seq;
        self.counter = self.counter.wrapping_add(inc as u32);
        Ok(self.current_frame())
    }
}

/// The N + 1 frames (baseline first) that carry `increments`.
pub fn encode_increments(
    encoder: &mut FrameEncoder,
    increments: &[i64],
) -> Result<Vec<[u8; FRAME_LEN]>, FrameError> {
    let mut frames = Vec::with_capacity(increments.len() + 1);
    frames.push(encoder.current_frame());
    for &inc in increments {
        frames.push(encoder.step(inc)?);
    }
    Ok(frames)
}

/// Writes frames for a stream of increments to any `Write` (a file, a pty, a
/// socket); the baseline frame goes out before the first increment.
#[derive(Debug)]
pub struct FrameWriter<W: Write> {
    inner: W,
    encoder: FrameEncoder,
    started: bool,
    bytes_written: u64,
}

impl<W: Write> FrameWriter<W> {
    /// Wrap `inner`; nothing is written yet.
    pub fn new(inner: W, encoder: FrameEncoder) -> Self {
        FrameWriter {
            inner,
            encoder,
            started: false,
            bytes_written: 0,
        }
    }

    /// The encoder (to change temperature or status between frames).
    pub fn encoder_mut(&mut self) -> &mut FrameEncoder {
        &mut self.encoder
    }

    /// Bytes written so far.
    pub fn bytes_written(&self) -> u64 {
        self.bytes_written
    }

    fn write_frame(&mut self, frame: &[u8; FRAME_LEN]) -> Result<(), FrameError> {
        self.inner
            .write_all(frame)
            .map_err(|source| FrameError::Write {
                offset: self.bytes_written,
                source,
            })?;
        self.bytes_written += FRAME_LEN as u64;
        Ok(())
    }

    /// Write the baseline frame now (otherwise it goes out with the first
    /// increment). Does nothing if already written.
    pub fn start(&mut self) -> Result<(), FrameError> {
        if !self.started {
            let f = self.encoder.current_frame();
            self.write_frame(&f)?;
            self.started = true;
        }
        Ok(())
    }

    /// Write the frame of one sample period.
    pub fn write_increment(&mut self, increment: i64) -> Result<(), FrameError> {
        self.start()?;
        let f = self.encoder.step(increment)?;
        self.write_frame(&f)
    }

    /// Write the frames of many sample periods.
    pub fn write_increments(&mut self, increments: &[i64]) -> Result<(), FrameError> {
        increments
            .iter()
            .try_for_each(|&inc| self.write_increment(inc))
    }

    /// Flush the inner writer.
    pub fn flush(&mut self) -> Result<(), FrameError> {
        self.inner.flush().map_err(|source| FrameError::Write {
            offset: self.bytes_written,
            source,
        })
    }

    /// Flush and return the inner writer.
    pub fn into_inner(mut self) -> Result<W, FrameError> {
        self.flush()?;
        Ok(self.inner)
    }
}
