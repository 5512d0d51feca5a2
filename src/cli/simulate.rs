//! `sagnac simulate`: run the gyro simulator on a model file and write the pulse
//! stream as CSV, as a raw frame capture (`--format frames`: the 16-byte gyro
//! frames of [`crate::input::frame`], what a serial capture holds), or as an
//! MCAP recording holding `/gyro/raw` (`--format mcap`, the channel `sagnac run`
//! records and replays, with the `sagnac` metadata record: rate, pulse weight and
//! the model's text, so that `analyze` and `diagnose` need no flags for it).
//!
//! Frames start at `seq` 65000 and a counter 10^6 pulses below 2^32 (both wrap
//! in a normal run), with all status flags OK and the model's temperature (25.00
//! deg C without a thermal section); N samples give N + 1 frames (the first is
//! the decoder's baseline). MCAP batches hold 1000 samples; simulated time
//! starts at the Unix epoch (t = 0), so the same model and seed give the same
//! messages.
//!
//! `--format triad-frames` writes a triad capture (the 24-byte frames of
//! [`crate::input::frame::triad`]) from three models given as
//! `--model X.toml,Y.toml,Z.toml`: axis x runs with `--seed S`, y with S + 1, z
//! with S + 2; the three must have the same sample rate and count pulses; the
//! temperature field is axis x's. It starts at the same `seq` and the same counter
//! on every axis as the single-frame capture.
//!
//! At a terminal a progress bar (samples written of the run's total) shows once
//! the run takes more than a moment ([`super::progress::DelayedBar`]).

use std::fs::File;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};

use super::progress::{DelayedBar, LineCounter};
use crate::daemon::bench::{SIM_START_COUNTER, SIM_START_SEQ};
use crate::input::frame::{FrameEncoder, FrameWriter, STATUS_ALL_OK, TriadEncoder};
use crate::model::config::OutputKind;
use crate::model::{Simulator, sim};
use crate::recording::messages::{RawBatch, SinkMessage};
use crate::recording::meta::RecordingMeta;
use crate::recording::writer::{Recorder, RecorderConfig};

/// Output format of `sagnac simulate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SimFormat {
    /// CSV: header `counts` (plus `temp_c` with a thermal model), one row per sample.
    Csv,
    /// Raw gyro frames, 16 bytes each (a `.bin` capture).
    Frames,
    /// Raw triad frames, 24 bytes each, from three models (--model X.toml,Y.toml,Z.toml).
    TriadFrames,
    /// MCAP recording with the `/gyro/raw` channel (not to stdout).
    Mcap,
}

/// Simulate a gyro from a model file.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Gyro model (TOML), e.g. config/paper_gyro.toml; for --format triad-frames
    /// three, comma-separated: X.toml,Y.toml,Z.toml.
    #[arg(long, value_delimiter = ',', required = true)]
    pub model: Vec<PathBuf>,
    /// Run length, seconds.
    #[arg(long)]
    pub duration_s: f64,
    /// RNG seed (same model + seed = identical output).
    #[arg(long)]
    pub seed: u64,
    /// Output file ("-" = stdout).
    #[arg(long)]
    pub out: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = SimFormat::Csv)]
    pub format: SimFormat,
}

/// Run `sagnac simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    let to_stdout = args.out.as_os_str() == "-";
    if args.format == SimFormat::Mcap && to_stdout {
        bail!("--format mcap cannot go to stdout (MCAP needs a seekable file): give --out FILE");
    }
    if args.format == SimFormat::TriadFrames {
        return run_triad(&args, to_stdout);
    }
    let [model_path] = args.model.as_slice() else {
        bail!(
            "--model takes one model file with --format {} (three, comma-separated, only with --format triad-frames); got {}",
            format_name(args.format),
            args.model.len()
        );
    };
    let model = super::load_model(model_path)?;
    let mut simulator = Simulator::new(&model, args.seed, Some(args.duration_s))
        .with_context(|| format!("setting up the simulator for {}", model_path.display()))?;
    if simulator.output() == OutputKind::Rate && args.format != SimFormat::Csv {
        bail!(
            "{}: gyro.output = \"rate\" is written as CSV (column rate_dps, deg/s); --format {} carries \
             pulse counts",
            model_path.display(),
            format_name(args.format)
        );
    }
    let mut bar = DelayedBar::new("simulating", "samples");
    match args.format {
        SimFormat::Csv | SimFormat::TriadFrames => {}
        SimFormat::Frames => {
            let frames = if to_stdout {
                write_frames(&mut simulator, std::io::stdout().lock(), &mut bar)
            } else {
                let file = File::create(&args.out)
                    .with_context(|| format!("creating {}", args.out.display()))?;
                write_frames(&mut simulator, file, &mut bar)
            }
            .with_context(|| format!("writing frames to {}", args.out.display()))?;
            bar.finish();
            tracing::debug!(frames, "simulate: done");
            return Ok(());
        }
        SimFormat::Mcap => {
            // the recording carries its rate, pulse weight and model (the file's text)
            let text = std::fs::read_to_string(model_path)
                .with_context(|| format!("reading {}", model_path.display()))?;
            let mut meta =
                RecordingMeta::counts(simulator.sample_rate_hz(), simulator.pulse_arcsec());
            meta.model = Some(text);
            let messages = write_mcap(&mut simulator, &meta, &args.out, &mut bar)
                .with_context(|| format!("writing MCAP recording {}", args.out.display()))?;
            bar.finish();
            tracing::debug!(messages, "simulate: done");
            return Ok(());
        }
    }
    // the bar counts the CSV rows as they are written (after the header)
    let total = simulator.samples_total();
    let rows = if args.out.as_os_str() == "-" {
        sim::write_csv(
            &mut simulator,
            LineCounter::new(std::io::stdout().lock(), &mut bar, total, 1),
        )
    } else {
        let file =
            File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
        sim::write_csv(&mut simulator, LineCounter::new(file, &mut bar, total, 1))
    }
    .with_context(|| format!("writing {}", args.out.display()))?;
    bar.finish();
    tracing::debug!(rows, "simulate: done");
    Ok(())
}

/// Samples generated per simulator call.
const BLOCK: usize = 65_536;

fn format_name(f: SimFormat) -> &'static str {
    match f {
        SimFormat::Csv => "csv",
        SimFormat::Frames => "frames",
        SimFormat::TriadFrames => "triad-frames",
        SimFormat::Mcap => "mcap",
    }
}

/// `--format triad-frames`: three models, one triad capture.
fn run_triad(args: &SimulateArgs, to_stdout: bool) -> anyhow::Result<()> {
    let [_, _, _] = args.model.as_slice() else {
        bail!(
            "--format triad-frames takes three models, --model X.toml,Y.toml,Z.toml (axes x, y, z); got {}",
            args.model.len()
        );
    };
    let mut sims = Vec::with_capacity(3);
    for (k, path) in args.model.iter().enumerate() {
        let model = super::load_model(path)?;
        let sim = Simulator::new(
            &model,
            args.seed.wrapping_add(k as u64),
            Some(args.duration_s),
        )
        .with_context(|| format!("setting up the simulator for {}", path.display()))?;
        if sim.output() == OutputKind::Rate {
            bail!(
                "{}: gyro.output = \"rate\": a triad frame carries pulse counters",
                path.display()
            );
        }
        sims.push(sim);
    }
    let rate = sims[0].sample_rate_hz();
    for (sim, path) in sims.iter().zip(&args.model).skip(1) {
        if sim.sample_rate_hz() != rate {
            bail!(
                "{}: gyro.sample_rate_hz = {} differs from axis x's {} ({}): the three gyros of a triad frame share one sample clock",
                path.display(),
                sim.sample_rate_hz(),
                rate,
                args.model[0].display()
            );
        }
    }
    let mut bar = DelayedBar::new("simulating", "samples");
    let frames = if to_stdout {
        write_triad_frames(&mut sims, std::io::stdout().lock(), &mut bar)
    } else {
        let file =
            File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
        write_triad_frames(&mut sims, file, &mut bar)
    }
    .with_context(|| format!("writing triad frames to {}", args.out.display()))?;
    bar.finish();
    tracing::debug!(frames, "simulate: done");
    Ok(())
}

/// Write the triad frames of the whole run; returns the number of frames.
fn write_triad_frames<W: std::io::Write>(
    sims: &mut [Simulator],
    out: W,
    bar: &mut DelayedBar,
) -> anyhow::Result<u64> {
    use std::io::Write as _;
    let start = SIM_START_COUNTER;
    let mut enc = TriadEncoder::new(SIM_START_SEQ, [start; 3]);
    if let Some(t) = sims[0].temperature_at(0.0) {
        enc.set_temp_c(t);
    }
    let thermal = sims[0].has_temperature();
    let mut w = std::io::BufWriter::with_capacity(1 << 20, out);
    w.write_all(&enc.current_frame())?;
    let mut counts: [Vec<i64>; 3] = std::array::from_fn(|_| Vec::with_capacity(BLOCK));
    let mut temps: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(BLOCK));
    let mut frames = 1u64;
    loop {
        let mut n = [0usize; 3];
        for k in 0..3 {
            counts[k].clear();
            temps[k].clear();
            n[k] = sims[k].next_block_with_temp(BLOCK, &mut counts[k], &mut temps[k]);
        }
        if n[0] != n[1] || n[0] != n[2] {
            bail!(
                "the three simulators produced {n:?} samples in one block (same rate and duration expected)"
            );
        }
        if n[0] == 0 {
            break;
        }
        for i in 0..n[0] {
            if thermal {
                enc.set_temp_c(temps[0][i]);
            }
            w.write_all(&enc.step([counts[0][i], counts[1][i], counts[2][i]])?)?;
        }
        frames += n[0] as u64;
        bar.update(frames - 1, sims[0].samples_total());
    }
    w.flush()?;
    Ok(frames)
}

/// Write the frames of the whole run; returns the number of frames.
fn write_frames<W: std::io::Write>(
    sim: &mut Simulator,
    out: W,
    bar: &mut DelayedBar,
) -> anyhow::Result<u64> {
    let mut enc = FrameEncoder::new(SIM_START_SEQ, SIM_START_COUNTER);
    if let Some(t) = sim.temperature_at(0.0) {
        enc.set_temp_c(t);
    }
    let thermal = sim.has_temperature();
    let mut w = FrameWriter::new(std::io::BufWriter::with_capacity(1 << 20, out), enc);
    w.start()?;
    let (mut counts, mut temps) = (Vec::with_capacity(BLOCK), Vec::with_capacity(BLOCK));
    let mut frames = 1u64;
    loop {
        counts.clear();
        temps.clear();
        let n = sim.next_block_with_temp(BLOCK, &mut counts, &mut temps);
        if n == 0 {
            break;
        }
        for (i, &c) in counts.iter().enumerate() {
            if thermal {
                w.encoder_mut().set_temp_c(temps[i]);
            }
            w.write_increment(c)?;
        }
        frames += n as u64;
        bar.update(frames - 1, sim.samples_total());
    }
    w.into_inner()?;
    Ok(frames)
}

/// Samples per `/gyro/raw` message.
const MCAP_BATCH: usize = 1000;

/// Write the run as `/gyro/raw` messages to `out`; returns the number of messages.
fn write_mcap(
    sim: &mut Simulator,
    meta: &RecordingMeta,
    out: &Path,
    bar: &mut DelayedBar,
) -> anyhow::Result<u64> {
    // The recorder names its file by time in a directory: write next to `out`
    // under that name, then rename.
    // The directory must exist (the recorder would create it), and the rename
    // replaces what is at `out`: only a regular file (or nothing).
    let dir = super::output_dir(out)?;
    if let Ok(m) = std::fs::symlink_metadata(out)
        && !m.file_type().is_file()
    {
        bail!(
            "cannot write {}: it exists and is not a regular file (an MCAP file is written beside it and renamed)",
            out.display()
        );
    }
    let config = RecorderConfig {
        record_dir: dir,
        ..RecorderConfig::default()
    };
    let recorder = Recorder::start_with_metadata(&config, std::time::UNIX_EPOCH, Some(meta))?;
    let dt_ns = (1e9 / sim.sample_rate_hz()).round() as u64;
    let period_ns = 1e9 / sim.sample_rate_hz();
    let (mut counts, mut temps) = (
        Vec::with_capacity(MCAP_BATCH),
        Vec::with_capacity(MCAP_BATCH),
    );
    let mut seq = 0u64;
    let mut sent = Ok(());
    loop {
        counts.clear();
        temps.clear();
        let n = sim.next_block_with_temp(MCAP_BATCH, &mut counts, &mut temps);
        if n == 0 {
            break;
        }
        let msg = SinkMessage::Raw(RawBatch {
            t0_ns: (seq as f64 * period_ns).round() as u64,
            dt_ns,
            seq0: seq,
            counts: counts.clone(),
            gaps: Vec::new(),
            temp_c: temps.last().copied(),
            status: u32::from(STATUS_ALL_OK),
        });
        seq += n as u64;
        bar.update(seq, sim.samples_total());
        if let Err(e) = recorder.send(msg) {
            sent = Err(e);
            break;
        }
    }
    let path = recorder.path().to_path_buf();
    // finish() reports the writer's first error, which explains a failed send.
    let summary = recorder.finish()?;
    sent?;
    if let Err(e) = std::fs::rename(&path, out) {
        let _ = std::fs::remove_file(&path);
        return Err(e).with_context(|| format!("renaming {} to {}", path.display(), out.display()));
    }
    Ok(summary.messages())
}
