//! `sagnac allan`: Allan-family deviations of a recorded file, with confidence
//! intervals, as JSON (`--json OUT`) or an aligned table on stdout.
//!
//! Thin: reading is `input::plain`, the numerics are `allan`. A run longer
//! than a moment shows its phase (reading, computing) or, with the streaming
//! engine, the samples read, on stderr at a terminal.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use super::input_args::FormatArg;
use crate::allan::{self, AllanOptions, AllanResult, DataKind, Phase, Stat, TauSet};
use crate::input::{Block, Format, Input, Request};

/// Arguments of `sagnac allan`.
#[derive(Debug, Args)]
pub struct AllanArgs {
    /// Input file: text, CSV, f64le (each plain or .gz), a frame capture or an
    /// MCAP recording (their pulse counts); the format is found by content.
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// What the samples are: phase/angle, frequency/rate, or integer pulse-count increments.
    #[arg(long, value_enum)]
    pub data: DataArg,
    /// Sample interval in seconds.
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub tau0: f64,
    /// Statistic.
    #[arg(long, value_enum, default_value = "oadev")]
    pub stat: StatArg,
    /// Averaging factors: octave (1,2,4,..), decade (1,2,4,10,20,40,..) or all.
    #[arg(long, value_enum, default_value = "octave")]
    pub taus: TausArg,
    /// Engine: whole-file batch estimators, or the streaming octave accumulators.
    #[arg(long, value_enum, default_value = "batch")]
    pub engine: EngineArg,
    /// Read the file as this format (needed for raw f64le, which has no
    /// signature; an error when the content says otherwise).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// CSV column to read.
    #[arg(long, value_name = "NAME")]
    pub column: Option<String>,
    /// Which gyro of an MCAP recording of several gyros or of a triad capture.
    #[arg(long, value_name = "LABEL")]
    pub gyro: Option<String>,
    /// Write the result as JSON to this file ("-" for stdout) instead of printing a table.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Two-sided confidence level of the intervals (Stable32's default 0.683; e.g. 0.95).
    #[arg(long, default_value_t = allan::DEFAULT_CONFIDENCE)]
    pub confidence: f64,
    /// Also write the curve as CSV (tau_s, dev, ci_lo, ci_hi, edf, n; the
    /// deviation's unit in the column names).
    #[arg(long, value_name = "OUT.csv")]
    pub csv: Option<PathBuf>,
}

/// The deviation's unit, as a column-name suffix: pulses/s for counts, the
/// input's own unit for frequency, the phase unit per second for phase.
fn dev_unit(kind: DataKind) -> &'static str {
    match kind {
        DataKind::Counts => "pulse_per_s",
        DataKind::Freq => "freq_unit",
        DataKind::Phase => "phase_unit_per_s",
    }
}

/// `--csv`, when given.
fn write_csv(args: &AllanArgs, kind: DataKind, r: &AllanResult) -> Result<()> {
    if let Some(path) = &args.csv {
        crate::sink::export::allan_csv::write_curve(path, &r.points, dev_unit(kind))
            .context("writing the Allan CSV")?;
    }
    Ok(())
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DataArg {
    Phase,
    Freq,
    Counts,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum StatArg {
    Oadev,
    Adev,
    Mdev,
    Hdev,
    Ohdev,
    Totdev,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum TausArg {
    Octave,
    Decade,
    All,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EngineArg {
    Batch,
    Streaming,
}

impl From<DataArg> for DataKind {
    fn from(d: DataArg) -> DataKind {
        match d {
            DataArg::Phase => DataKind::Phase,
            DataArg::Freq => DataKind::Freq,
            DataArg::Counts => DataKind::Counts,
        }
    }
}

impl From<StatArg> for Stat {
    fn from(s: StatArg) -> Stat {
        match s {
            StatArg::Oadev => Stat::Oadev,
            StatArg::Adev => Stat::Adev,
            StatArg::Mdev => Stat::Mdev,
            StatArg::Hdev => Stat::Hdev,
            StatArg::Ohdev => Stat::Ohdev,
            StatArg::Totdev => Stat::Totdev,
        }
    }
}

impl From<TausArg> for TauSet {
    fn from(t: TausArg) -> TauSet {
        match t {
            TausArg::Octave => TauSet::Octave,
            TausArg::Decade => TauSet::Decade,
            TausArg::All => TauSet::All,
        }
    }
}

impl AllanArgs {
    fn stat_name(&self) -> String {
        Stat::from(self.stat).to_string()
    }

    /// Open the input: numbers as they are, except that `--data counts` needs
    /// whole numbers.
    fn open(&self, kind: DataKind) -> Result<Input> {
        let req = Request {
            format: self.format.map(Format::from),
            column: self.column.clone(),
            gyro: self.gyro.clone(),
            values_only: kind != DataKind::Counts,
            ..Request::default()
        };
        let input = Input::open(&self.input, &req)
            .with_context(|| format!("cannot read samples from {}", self.input.display()))?;
        if kind == DataKind::Counts && !input.meta().integral {
            // read once more, for the line or byte offset of the first fraction
            let m = input.meta();
            let e = crate::input::plain::SampleReader::open(
                input.path(),
                m.format,
                m.column.as_deref(),
            )
            .and_then(|r| r.require_integers(true).read_to_end())
            .err();
            match e {
                Some(e) => return Err(e).context("--data counts needs integer pulse counts"),
                None => bail!(
                    "{}: --data counts needs integer pulse counts",
                    self.input.display()
                ),
            }
        }
        Ok(input)
    }
}

/// The next block's samples as numbers (`buf`), and as integers when the
/// input streams counts (`ints`); `false` at the end.
fn next_values(
    stream: &mut dyn crate::input::BlockSource,
    block: &mut Block,
    buf: &mut Vec<f64>,
) -> Result<bool> {
    if !stream.next_block(block)? {
        return Ok(false);
    }
    buf.clear();
    if block.counts.is_empty() {
        std::mem::swap(buf, &mut block.values);
    } else {
        buf.extend(block.counts.iter().map(|&c| c as f64));
    }
    Ok(true)
}

/// Run `sagnac allan`.
pub fn run(args: AllanArgs) -> Result<()> {
    allan::check_tau0(args.tau0).context("invalid --tau0")?;
    if !(args.confidence > 0.0 && args.confidence < 1.0) {
        bail!("--confidence must be in (0, 1) (got {})", args.confidence);
    }
    let kind = DataKind::from(args.data);
    if let Some(p) = &args.csv {
        if p.is_dir() {
            bail!("--csv {}: is a directory, not a file", p.display());
        }
        super::output_dir(p).context("bad --csv")?;
    }
    if args.engine == EngineArg::Streaming {
        return run_streaming(&args, kind);
    }
    let spinner = super::progress::Spinner::start(format!("reading {}", args.input.display()));
    let input = args.open(kind)?;
    let (all, _) = input
        .read_all()
        .with_context(|| format!("cannot read samples from {}", args.input.display()))?;
    let samples = if all.counts.is_empty() {
        all.values
    } else {
        all.counts.iter().map(|&c| c as f64).collect()
    };
    spinner.set_message(format!(
        "computing {} of {} samples",
        args.stat_name(),
        samples.len()
    ));
    let phase = Phase::from_vec(samples, kind, args.tau0)
        .with_context(|| format!("invalid samples in {}", args.input.display()))?;
    let stat = Stat::from(args.stat);
    let opts = AllanOptions {
        confidence: args.confidence,
        alpha: None,
    };
    let result = allan::compute(&phase, stat, args.tau0, args.taus.into(), &opts)
        .with_context(|| format!("cannot compute {stat} of {}", args.input.display()))?;
    spinner.finish();
    write_csv(&args, kind, &result)?;

    match &args.json {
        Some(out) => {
            let text = serde_json::to_string_pretty(&result).context("serialising the result")?;
            if out.as_os_str() == "-" {
                super::write_stdout(&text)?;
            } else {
                std::fs::write(out, text + "\n")
                    .with_context(|| format!("cannot write {}", out.display()))?;
            }
        }
        None => print_table(&result, &args, phase.len(), opts.confidence)?,
    }
    Ok(())
}

/// The streaming engine: the file is read block by block into the octave
/// accumulators (bounded memory whatever the file size); OADEV at octave taus.
fn run_streaming(args: &AllanArgs, kind: DataKind) -> Result<()> {
    use crate::allan::streaming::{OctaveAllan, StreamConfig};
    if !matches!(args.stat, StatArg::Oadev) || !matches!(args.taus, TausArg::Octave) {
        bail!("--engine streaming computes --stat oadev at --taus octave only");
    }
    let input = args.open(kind)?;
    // read (and parsed) on a second core while the accumulators run
    let mut stream = input
        .stream()
        .and_then(crate::input::Prefetch::new)
        .with_context(|| format!("cannot read samples from {}", args.input.display()))?;
    let mut block = Block::default();
    let cfg = StreamConfig::with_tau0(args.tau0);
    enum Acc {
        F(OctaveAllan),
        C(OctaveAllan<i64>),
    }
    let mut acc = match kind {
        DataKind::Phase => Acc::F(OctaveAllan::phase(cfg)?),
        DataKind::Freq => Acc::F(OctaveAllan::freq(cfg)?),
        DataKind::Counts => Acc::C(OctaveAllan::counts(cfg)?),
    };
    let mut buf = Vec::with_capacity(1 << 17);
    let mut ints: Vec<i64> = Vec::with_capacity(1 << 17);
    let mut bar = super::progress::DelayedBar::new("streaming OADEV", "samples");
    while next_values(&mut stream, &mut block, &mut buf)
        .with_context(|| format!("cannot read samples from {}", args.input.display()))?
    {
        let n = buf.len();
        match &mut acc {
            Acc::F(a) => a
                .push_block(&buf)
                .with_context(|| format!("invalid samples in {}", args.input.display()))?,
            Acc::C(a) => {
                ints.clear();
                ints.extend(buf.iter().map(|&v| v as i64));
                a.push_block(&ints);
            }
        }
        bar.inc(n as u64, None);
    }
    bar.finish();
    let (points, n_phase) = match &acc {
        Acc::F(a) => (a.points(args.confidence)?, a.phase_points()),
        Acc::C(a) => (a.points(args.confidence)?, a.phase_points()),
    };
    // the batch engine's tau range (AllanTools' stop ratio), so both engines
    // accept the same inputs and report the same taus
    let m_max = allan::batch::max_m(Stat::Oadev, n_phase);
    if m_max == 0 {
        return Err(allan::AllanError::TooFewPoints {
            n_phase,
            need: allan::batch::min_points(Stat::Oadev),
        })
        .with_context(|| format!("cannot compute oadev of {}", args.input.display()));
    }
    let result = AllanResult {
        stat: Stat::Oadev,
        tau0_s: args.tau0,
        points: points
            .iter()
            .filter(|p| p.n > 0 && p.m <= m_max)
            .map(allan::AllanPoint::from)
            .collect(),
    };
    write_csv(args, kind, &result)?;
    match &args.json {
        Some(out) => {
            let text = serde_json::to_string_pretty(&result).context("serialising the result")?;
            if out.as_os_str() == "-" {
                super::write_stdout(&text)?;
            } else {
                std::fs::write(out, text + "\n")
                    .with_context(|| format!("cannot write {}", out.display()))?;
            }
        }
        None => print_table(&result, args, n_phase as usize, args.confidence)?,
    }
    Ok(())
}

fn print_table(r: &AllanResult, args: &AllanArgs, n_phase: usize, confidence: f64) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "# {} of {} ({} phase points, tau0 = {} s, {:.1} % confidence)",
        r.stat,
        args.input.display(),
        n_phase,
        r.tau0_s,
        100.0 * confidence
    )?;
    writeln!(
        out,
        "{:>12} {:>9} {:>10} {:>5} {:>12} {:>12} {:>12} {:>10}",
        "tau_s", "m", "n", "alpha", "ci_lo", "dev", "ci_hi", "edf"
    )?;
    for p in &r.points {
        writeln!(
            out,
            "{:>12.5e} {:>9} {:>10} {:>5} {:>12.5e} {:>12.5e} {:>12.5e} {:>10.4}",
            p.tau_s, p.m, p.n, p.alpha, p.ci_lo, p.dev, p.ci_hi, p.edf
        )?;
    }
    Ok(())
}
