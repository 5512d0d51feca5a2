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
//!   [`crate::input::frame::inject`] (which returns the exact ledger of what a
//!   decoder must report) and write them with [`write_paced`].

use std::io::{self, Write};
use std::time::{Duration, Instant};

use bytes::BytesMut;

use crate::daemon::batch::{BatchSender, PipelineClosed, SourceReport, wall_ns};
use crate::daemon::lanes::Lanes;
use crate::daemon::shutdown::Shutdown;
use crate::daemon::telemetry::Telemetry;
use crate::input::frame::inject::{FaultPlan, Injected, inject};
use crate::input::frame::{
    Axes, DecoderConfig, FRAME_LEN, FrameEncoder, FrameError, Single, Triad, TriadEncoder,
};
use crate::model::{GyroModel, ModelError, Simulator};

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
    #[error("simulated bench")]
    Model(#[from] ModelError),
    /// An increment does not fit a frame.
    #[error("simulated bench")]
    Frame(#[from] FrameError),
    /// The pipeline stopped.
    #[error("simulated bench")]
    Pipeline(#[from] PipelineClosed),
}

/// Initial frame `seq` of the simulated gyro (wraps after 536 samples).
pub const SIM_START_SEQ: u16 = 65_000;
/// Initial counter of the simulated gyro (wraps after 10^6 pulses up).
pub const SIM_START_COUNTER: u32 = u32::MAX - 999_999;

/// Settings of the simulated bench.
#[derive(Debug, Clone, PartialEq)]
pub struct SimBenchConfig {
    /// The gyro model: one gyro on single frames.
    pub model: GyroModel,
    /// With two more models (y, z): a triad, `model` as x, on triad frames.
    pub triad: Option<Box<[GyroModel; 2]>>,
    /// Noise seed (the triad's y and z use `seed + 1`, `seed + 2`).
    pub seed: u64,
    /// Pace in multiples of real time (0 = as fast as possible).
    pub speed: f64,
    /// Run length, s (`None`: until shut down).
    pub duration_s: Option<f64>,
}

/// A simulated bench, ready to run.
#[derive(Debug)]
pub struct SimBench {
    sims: Vec<Simulator>,
    speed: f64,
    sample_rate_hz: f64,
}

impl SimBenchConfig {
    /// Validate the models and set up the simulators.
    pub fn build(self) -> Result<SimBench, BenchError> {
        if !(self.speed.is_finite() && self.speed >= 0.0) {
            return Err(BenchError::Config {
                key: "speed",
                value: self.speed.to_string(),
                reason: "must be >= 0",
            });
        }
        let mut models = vec![self.model];
        if let Some(more) = self.triad {
            models.extend(*more);
        }
        let sims = models
            .iter()
            .zip(self.seed..)
            .map(|(m, seed)| Simulator::new(m, seed, self.duration_s))
            .collect::<Result<Vec<_>, _>>()?;
        let sample_rate_hz = sims[0].sample_rate_hz();
        if sims.iter().any(|s| s.sample_rate_hz() != sample_rate_hz) {
            return Err(BenchError::Config {
                key: "gyro.sample_rate_hz",
                value: sims
                    .iter()
                    .map(|s| s.sample_rate_hz().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                reason: "the three gyros of a triad share its frame: give them one sample rate",
            });
        }
        Ok(SimBench {
            sample_rate_hz,
            sims,
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

/// The encoder of the bench's frames: single or triad.
enum BenchEncoder {
    Single(FrameEncoder),
    Triad(TriadEncoder),
}

impl BenchEncoder {
    fn current_frame(&self, out: &mut BytesMut) {
        match self {
            BenchEncoder::Single(e) => out.extend_from_slice(&e.current_frame()),
            BenchEncoder::Triad(e) => out.extend_from_slice(&e.current_frame()),
        }
    }

    fn set_temp_c(&mut self, t: f64) {
        match self {
            BenchEncoder::Single(e) => e.set_temp_c(t),
            BenchEncoder::Triad(e) => e.set_temp_c(t),
        }
    }

    /// The frame of sample `i` of the block `counts` (one slice per gyro).
    fn step(
        &mut self,
        counts: &[Vec<i64>],
        i: usize,
        out: &mut BytesMut,
    ) -> Result<(), FrameError> {
        match self {
            BenchEncoder::Single(e) => out.extend_from_slice(&e.step(counts[0][i])?),
            BenchEncoder::Triad(e) => {
                out.extend_from_slice(&e.step([counts[0][i], counts[1][i], counts[2][i]])?)
            }
        }
        Ok(())
    }
}

impl SimBench {
    /// Sample rate of the simulated gyros, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    /// Gyros simulated: 1, or 3 for a triad.
    pub fn gyros(&self) -> usize {
        self.sims.len()
    }

    /// Run on the calling (blocking) thread until the run length, a shutdown, or
    /// the pipeline closing; `outs` holds each gyro's telemetry and sender (one,
    /// or three for a triad). The samples go through the real frame encoder and
    /// decoder (the triad frame for three gyros).
    pub fn run_blocking(
        self,
        outs: Vec<(Telemetry, BatchSender)>,
        shutdown: Shutdown,
    ) -> Result<SourceReport, BenchError> {
        if self.sims.len() == 3 {
            self.run_frames::<Triad>(outs, shutdown)
        } else {
            self.run_frames::<Single>(outs, shutdown)
        }
    }

    fn run_frames<W: Axes>(
        mut self,
        outs: Vec<(Telemetry, BatchSender)>,
        shutdown: Shutdown,
    ) -> Result<SourceReport, BenchError> {
        let s_per_sample = if self.speed > 0.0 {
            1.0 / (self.sample_rate_hz * self.speed)
        } else {
            0.0
        };
        let block = if s_per_sample > 0.0 {
            ((PACED_BATCH.as_secs_f64() / s_per_sample) as usize).max(1)
        } else {
            FAST_BATCH
        };
        let thermal = self.sims[0].has_temperature();
        let mut enc = if W::GYROS == 3 {
            BenchEncoder::Triad(TriadEncoder::new(SIM_START_SEQ, [SIM_START_COUNTER; 3]))
        } else {
            BenchEncoder::Single(FrameEncoder::new(SIM_START_SEQ, SIM_START_COUNTER))
        };
        if let Some(t) = self.sims[0].temperature_at(0.0) {
            enc.set_temp_c(t);
        }
        let mut lanes = Lanes::<W>::new(DecoderConfig::default(), self.sample_rate_hz, None, outs);
        let mut bytes = BytesMut::with_capacity((block + 1) * W::LEN);
        enc.current_frame(&mut bytes);
        let mut counts = vec![Vec::with_capacity(block); self.sims.len()];
        let (mut temps, mut scratch) = (Vec::with_capacity(block), Vec::new());
        let start = Instant::now();
        let mut emitted = 0u64;
        while !shutdown.is_requested() {
            let mut n = usize::MAX;
            for (k, sim) in self.sims.iter_mut().enumerate() {
                counts[k].clear();
                let t = if k == 0 { &mut temps } else { &mut scratch };
                t.clear();
                n = n.min(sim.next_block_with_temp(block, &mut counts[k], t));
            }
            if n == 0 {
                break;
            }
            for i in 0..n {
                if thermal {
                    enc.set_temp_c(temps[i]);
                }
                enc.step(&counts, i, &mut bytes)?;
            }
            emitted += n as u64;
            // Pace: the block's last sample is due at start + emitted periods.
            if s_per_sample > 0.0 {
                let due = start + Duration::from_secs_f64(emitted as f64 * s_per_sample);
                pace_until(due, &shutdown);
            }
            let now = wall_ns();
            lanes.decode_available(&mut bytes, now);
            lanes.sync_stats();
            lanes.blocking_send()?;
        }
        let report = lanes.report(0);
        tracing::info!(
            samples = report.samples,
            gyros = W::GYROS,
            "simulated bench stopped"
        );
        Ok(report)
    }
}

/// Sleep until `due` in short slices, or until a shutdown.
fn pace_until(due: Instant, shutdown: &Shutdown) {
    while !shutdown.is_requested() {
        let now = Instant::now();
        if now >= due {
            break;
        }
        std::thread::sleep((due - now).min(SLEEP_SLICE));
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
    use crate::input::frame::inject::FrameAction;

    const PAPER: &str = include_str!("../../config/paper_gyro.toml");

    #[test]
    fn the_simulated_bench_delivers_exactly_the_simulator_stream() {
        let model = GyroModel::from_toml_str(PAPER, "paper_gyro.toml").unwrap();
        let bench = SimBenchConfig {
            model: model.clone(),
            triad: None,
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
        let h = std::thread::spawn(move || bench.run_blocking(vec![(t2, sender)], sd).unwrap());
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
    fn a_simulated_triad_delivers_each_gyros_simulator_stream_through_triad_frames() {
        let x = GyroModel::from_toml_str(PAPER, "paper_gyro.toml").unwrap();
        let mut y = x.clone();
        y.gyro.input_rate_dph = -40.0;
        let mut z = x.clone();
        z.noise.arw_dpsh = Some(0.005);
        let bench = SimBenchConfig {
            model: x.clone(),
            triad: Some(Box::new([y.clone(), z.clone()])),
            seed: 11,
            speed: 0.0,
            duration_s: Some(10.0),
        }
        .build()
        .unwrap();
        assert_eq!(bench.gyros(), 3);
        let base = Telemetry::standalone().unwrap();
        let metrics = base.metrics.clone();
        let mut outs = Vec::new();
        let mut rxs = Vec::new();
        for label in ["x", "y", "z"] {
            let t = base.for_gyro(&crate::sink::metrics::GyroInfo::labelled(label));
            let (sender, rx) = batch::channel(QueueBound::Batches(64), &t);
            outs.push((t, sender));
            rxs.push(rx);
        }
        let (_trigger, sd) = shutdown::channel();
        let h = std::thread::spawn(move || bench.run_blocking(outs, sd).unwrap());
        let mut got = vec![Vec::new(); 3];
        // three queues: drain them in turn until all are closed
        let mut open = [true; 3];
        while open.iter().any(|o| *o) {
            for k in 0..3 {
                if open[k] {
                    match rxs[k].blocking_recv() {
                        Some(b) => got[k].extend(b.counts),
                        None => open[k] = false,
                    }
                }
            }
        }
        let report = h.join().unwrap();
        assert_eq!(report.samples, 10_000);
        for (k, (m, seed)) in [(&x, 11), (&y, 12), (&z, 13)].into_iter().enumerate() {
            let mut want = Vec::new();
            Simulator::new(m, seed, Some(10.0))
                .unwrap()
                .next_block(10_000, &mut want);
            assert_eq!(
                got[k], want,
                "gyro {k}: triad encode + decode must be lossless"
            );
        }
        let text = metrics.encode();
        for g in ["x", "y", "z"] {
            assert!(
                text.contains(&format!(
                    "sagnac_frames_decoded_total{{gyro=\"{g}\"}} 10001\n"
                )),
                "{text}"
            );
        }
        // 10 001 frames of 24 bytes, counted once for the stream
        assert!(text.contains("sagnac_bytes_read_total 240024\n"), "{text}");
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
