//! The simulated test bench: the daemon's built-in gyro (no hardware needed),
//! and the bench emulator the serial tests write into a pseudo-terminal.
//!
//! * [`SimBench`] is the daemon source behind `sagnac run` without a source
//!   flag (or with `--simulate MODEL.toml`): the streaming [`Simulator`] makes
//!   pulse increments and temperatures, the real [`FrameEncoder`] turns them into
//!   16-byte frames, and the real [`FrameDecoder`] decodes them again, so the
//!   default run exercises the decode path and the frame counters exactly as a
//!   serial gyro would. The counter starts 1 000 000 pulses below 2^32 and
//!   `seq` at 65 000 so both wraps happen in a normal run. Without a thermal
//!   section in the model the frames carry a constant 25.00 deg C. Paced at
//!   `speed` times real time on the sample clock (0 = as fast as possible);
//!   lossless delivery (backpressure slows the simulation down).
//! * [`BenchEmulator`] simulates a whole run up front and keeps the truth (the
//!   increments, hence the total pulses): tests corrupt its frames with
//!   [`crate::source::frame::inject`] (which returns the exact ledger of what a
//!   decoder must report) and write them with [`write_paced`].

use std::io::{self, Write};
use std::time::{Duration, Instant};

use bytes::BytesMut;

use crate::daemon::batch::{Assembler, BatchSender, PipelineClosed, SourceReport, wall_ns};
use crate::daemon::shutdown::Shutdown;
use crate::daemon::telemetry::Telemetry;
use crate::model::{GyroModel, ModelError, Simulator};
use crate::source::frame::inject::{FaultPlan, Injected, inject};
use crate::source::frame::{FRAME_LEN, FrameDecoder, FrameEncoder, FrameError};

/// Errors of the simulated bench.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A setting is out of range.
    #[error("simulated bench: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The model cannot be simulated.
    #[error("simulated bench: {0}")]
    Model(#[from] ModelError),
    /// An increment does not fit a frame.
    #[error("simulated bench: {0}")]
    Frame(#[from] FrameError),
    /// The pipeline stopped.
    #[error("simulated bench: {0}")]
    Pipeline(#[from] PipelineClosed),
}

/// Initial frame `seq` of the simulated gyro (wraps after 536 samples).
pub const SIM_START_SEQ: u16 = 65_000;
/// Initial counter of the simulated gyro (wraps after 10^6 pulses up).
pub const SIM_START_COUNTER: u32 = u32::MAX - 999_999;

/// Settings of the simulated bench.
#[derive(Debug, Clone, PartialEq)]
pub struct SimBenchConfig {
    /// The gyro model.
    pub model: GyroModel,
    /// Noise seed.
    pub seed: u64,
    /// Pace in multiples of real time (0 = as fast as possible).
    pub speed: f64,
    /// Run length, s (`None`: until shut down).
    pub duration_s: Option<f64>,
}

/// A simulated bench, ready to run.
#[derive(Debug)]
pub struct SimBench {
    sim: Simulator,
    speed: f64,
    rate_hz: f64,
}

impl SimBenchConfig {
    /// Validate the model and set up the simulator.
    pub fn build(self) -> Result<SimBench, BenchError> {
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return Err(BenchError::Config {
                key: "speed",
                value: self.speed.to_string(),
                reason: "must be >= 0",
            });
        }
        let sim = Simulator::new(&self.model, self.seed, self.duration_s)?;
        Ok(SimBench {
            rate_hz: sim.sample_rate_hz(),
            sim,
            speed: self.speed,
        })
    }
}

/// Stream time per batch when paced.
const PACED_BATCH: Duration = Duration::from_millis(20);
/// Samples per batch when not paced.
const FAST_BATCH: usize = 8192;
/// Longest single sleep.
const SLEEP_SLICE: Duration = Duration::from_millis(50);

impl SimBench {
    /// Sample rate of the simulated gyro, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// Run on the calling (blocking) thread until the run length, a shutdown, or
    /// the pipeline closing.
    pub fn run_blocking(
        mut self,
        mut out: BatchSender,
        telemetry: Telemetry,
        shutdown: Shutdown,
    ) -> Result<SourceReport, BenchError> {
        let s_per_sample = if self.speed > 0.0 {
            1.0 / (self.rate_hz * self.speed)
        } else {
            0.0
        };
        let block = if s_per_sample > 0.0 {
            ((PACED_BATCH.as_secs_f64() / s_per_sample) as usize).max(1)
        } else {
            FAST_BATCH
        };
        let thermal = self.sim.has_temperature();
        let mut enc = FrameEncoder::new(SIM_START_SEQ, SIM_START_COUNTER);
        if let Some(t) = self.sim.temperature_at(0.0) {
            enc.set_temp_c(t);
        }
        let mut dec = FrameDecoder::new();
        let mut asm = Assembler::new(self.rate_hz, None, telemetry);
        let mut bytes = BytesMut::with_capacity((block + 1) * FRAME_LEN);
        bytes.extend_from_slice(&enc.current_frame());
        let (mut counts, mut temps) = (Vec::with_capacity(block), Vec::with_capacity(block));
        let start = Instant::now();
        let mut emitted = 0u64;
        loop {
            if shutdown.is_requested() {
                break;
            }
            counts.clear();
            temps.clear();
            let n = self
                .sim
                .next_block_with_temp(block, &mut counts, &mut temps);
            if n == 0 {
                break;
            }
            for (i, &c) in counts.iter().enumerate() {
                if thermal {
                    enc.set_temp_c(temps[i]);
                }
                bytes.extend_from_slice(&enc.step(c)?);
            }
            emitted += n as u64;
            // Pace: the block's last sample is due at start + emitted periods.
            if s_per_sample > 0.0 {
                let due = start + Duration::from_secs_f64(emitted as f64 * s_per_sample);
                loop {
                    if shutdown.is_requested() {
                        break;
                    }
                    let now = Instant::now();
                    if now >= due {
                        break;
                    }
                    std::thread::sleep((due - now).min(SLEEP_SLICE));
                }
            }
            let now = wall_ns();
            while let Some(item) = dec.decode(&mut bytes) {
                asm.push(item, now);
            }
            asm.sync_stats(dec.stats());
            if let Some(b) = asm.take(Instant::now()) {
                out.blocking_send(b)?;
            }
        }
        let s = dec.stats();
        tracing::info!(samples = s.samples, "simulated bench stopped");
        Ok(SourceReport {
            bytes_read: s.bytes_read,
            samples: s.samples,
            periods: asm.periods(),
            disconnects: 0,
        })
    }
}

/// A whole simulated run, encoded as clean frames, with its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchEmulator {
    /// The simulated pulse increments (the truth).
    pub increments: Vec<i64>,
    /// The `increments.len() + 1` clean frames (baseline first).
    pub frames: Vec<[u8; FRAME_LEN]>,
}

impl BenchEmulator {
    /// Simulate `duration_s` of `model` with `seed` and encode it from
    /// `(start_seq, start_counter)`.
    pub fn simulate(
        model: &GyroModel,
        seed: u64,
        duration_s: f64,
        start_seq: u16,
        start_counter: u32,
    ) -> Result<BenchEmulator, BenchError> {
        let mut sim = Simulator::new(model, seed, Some(duration_s))?;
        let total = sim.samples_total().unwrap_or(0) as usize;
        let (mut increments, mut temps) = (Vec::with_capacity(total), Vec::with_capacity(total));
        sim.next_block_with_temp(total, &mut increments, &mut temps);
        let mut enc = FrameEncoder::new(start_seq, start_counter);
        let mut frames = Vec::with_capacity(total + 1);
        frames.push(enc.current_frame());
        for (i, &c) in increments.iter().enumerate() {
            if let Some(&t) = temps.get(i) {
                enc.set_temp_c(t);
            }
            frames.push(enc.step(c)?);
        }
        Ok(BenchEmulator { increments, frames })
    }

    /// The true number of pulses between the first and the last frame.
    pub fn true_total_pulses(&self) -> i64 {
        self.increments.iter().sum()
    }

    /// The corrupted stream and its ledger.
    pub fn inject(&self, plan: &FaultPlan) -> Injected {
        inject(&self.frames, plan)
    }

    /// Byte offset in `self.inject(plan).bytes` where clean frame `index`'s
    /// faults (its garbage, then the frame) begin: the stream can be cut there.
    pub fn stream_offset_of(&self, plan: &FaultPlan, index: usize) -> usize {
        let mut head = plan.clone();
        head.faults.retain(|&i, _| i < index);
        head.tail.clear();
        inject(&self.frames[..index.min(self.frames.len())], &head)
            .bytes
            .len()
    }
}

/// Write `bytes` to `w` at about `bytes_per_s` (in 1/50 s slices; 0 = at once),
/// flushing after each slice.
pub fn write_paced<W: Write>(w: &mut W, bytes: &[u8], bytes_per_s: f64) -> io::Result<()> {
    if bytes_per_s <= 0.0 {
        w.write_all(bytes)?;
        return w.flush();
    }
    let slice = ((bytes_per_s / 50.0) as usize).max(1);
    let start = Instant::now();
    let mut sent = 0usize;
    for part in bytes.chunks(slice) {
        w.write_all(part)?;
        w.flush()?;
        sent += part.len();
        let due = start + Duration::from_secs_f64(sent as f64 / bytes_per_s);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::daemon::batch;
    use crate::daemon::queue::QueueBound;
    use crate::daemon::shutdown;
    use crate::source::frame::inject::FrameAction;

    const PAPER: &str = include_str!("../../config/paper_gyro.toml");

    #[test]
    fn the_simulated_bench_delivers_exactly_the_simulator_stream() {
        let model = GyroModel::from_toml_str(PAPER, "paper_gyro.toml").unwrap();
        let bench = SimBenchConfig {
            model: model.clone(),
            seed: 7,
            speed: 0.0,
            duration_s: Some(20.0),
        }
        .build()
        .unwrap();
        let telemetry = Telemetry::standalone().unwrap();
        let (sender, mut rx) = batch::channel(QueueBound::Batches(4), &telemetry);
        let (_trigger, sd) = shutdown::channel();
        let t2 = telemetry.clone();
        let h = std::thread::spawn(move || bench.run_blocking(sender, t2, sd).unwrap());
        let mut got = Vec::new();
        while let Some(b) = rx.blocking_recv() {
            assert!(b.gaps.is_empty());
            got.extend(b.counts);
        }
        let report = h.join().unwrap();
        let mut want = Vec::new();
        Simulator::new(&model, 7, Some(20.0))
            .unwrap()
            .next_block(20_000, &mut want);
        assert_eq!(got, want, "encode + decode must be lossless");
        assert_eq!(report.samples, 20_000);
        // 20 001 frames of 16 bytes went through the decoder
        let text = telemetry.metrics.encode();
        assert!(
            text.contains("sagnac_frames_decoded_total{gyro=\"gyro\"} 20001\n"),
            "{text}"
        );
        assert!(text.contains("sagnac_bytes_read_total 320016\n"), "{text}");
        assert!(
            !text.contains("sagnac_device_connected"),
            "the simulated bench has no device:\n{text}"
        );
    }

    #[test]
    fn stream_offsets_cut_the_injected_stream_at_frame_boundaries() {
        let model = GyroModel::from_toml_str(PAPER, "paper_gyro.toml").unwrap();
        let emu = BenchEmulator::simulate(&model, 3, 1.0, 65_530, u32::MAX - 20).unwrap();
        let mut plan = FaultPlan::none();
        plan.add_garbage_before(10, &[1, 2, 3]);
        plan.set_action(11, FrameAction::Drop);
        let full = emu.inject(&plan);
        // frames 0..10 clean, then 3 garbage bytes before frame 10
        assert_eq!(emu.stream_offset_of(&plan, 10), 10 * FRAME_LEN);
        assert_eq!(emu.stream_offset_of(&plan, 12), 11 * FRAME_LEN + 3);
        assert_eq!(
            &full.bytes[11 * FRAME_LEN + 3..12 * FRAME_LEN + 3],
            &emu.frames[12][..]
        );
    }
}
