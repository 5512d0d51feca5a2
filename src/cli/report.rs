//! `sagnac report`: analyse a recording and write a self-contained HTML page
//! (`DIR/index.html`: inline SVG figures, no outside requests) with the
//! Allan figure, the extracted noise and its integral, the rate and
//! temperature, the coefficient table, the recording's metadata and, with
//! `--model`, the diagnosis; plus `DIR/allan.png` and `DIR/noise_integral.png`.
//!
//! Thin: the input flags are `analyze`'s (same rules: `--rate-hz` and, for
//! counts, `--pulse-arcsec` are required for CSV and frame captures; an MCAP
//! recording carries them), reading is `offline`'s tapped readers, the page
//! is [`crate::sink::report`].

use std::path::{Path, PathBuf};

use super::progress::{DelayedBar, RunsBar};
use anyhow::{Context, Result, bail};
use clap::Args;

use super::analyze::AnalyzeFormat;
use crate::diagnose::{self, DiagnoseOptions, Recording};
use crate::model::GyroModel;
use crate::offline::{self, OfflineError, RateUnit, TapBlock};
use crate::pipeline::{Pipeline, PipelineConfig};
use crate::sink::report::{self, Collector, DiagnosisPart, Metadata};
use crate::input::plain::InputFormat;

/// Arguments of `sagnac report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Input: CSV (plain or .gz; header row), a raw frame capture, or an MCAP recording.
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Input format.
    #[arg(long, value_enum, default_value = "csv")]
    pub format: AnalyzeFormat,
    /// Sample rate, Hz: required for CSV and frame captures; an MCAP recording
    /// carries its own (the flag must then agree with it).
    #[arg(long, value_name = "F", allow_negative_numbers = true)]
    pub rate_hz: Option<f64>,
    /// Angle of one counter pulse, arcsec: required for pulse counts in CSV and
    /// frame captures; an MCAP recording carries its own (the flag must then agree).
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    pub pulse_arcsec: Option<f64>,
    /// Which gyro of an MCAP recording of several gyros (its label, e.g. `x`):
    /// required for such a recording, refused for a recording of one gyro.
    #[arg(long, value_name = "LABEL")]
    pub gyro: Option<String>,
    /// CSV column to analyse (default `counts`).
    #[arg(long, value_name = "NAME")]
    pub column: Option<String>,
    /// Unit of the column: pulse counts per sample, deg/h, deg/s or rad/s.
    #[arg(long, value_enum, default_value = "counts")]
    pub unit: RateUnit,
    /// Output directory (created if missing): index.html, allan.png, noise_integral.png.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Gyro model (TOML): also diagnose the recording against it and show the findings.
    #[arg(long, value_name = "MODEL.toml")]
    pub model: Option<PathBuf>,
    /// Acceptance test against this spec file: show the verdict per coefficient.
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Option<PathBuf>,
}

fn required(
    flag: &'static str,
    value: Option<f64>,
    input: &Path,
    what: &'static str,
) -> Result<f64> {
    value.ok_or_else(|| {
        OfflineError::FlagRequired {
            flag,
            path: input.to_path_buf(),
            what,
        }
        .into()
    })
}

/// Run `sagnac report`.
pub fn run(args: ReportArgs) -> Result<()> {
    for (flag, v) in [
        ("--rate-hz", args.rate_hz),
        ("--pulse-arcsec", args.pulse_arcsec),
    ] {
        if let Some(x) = v
            && !(x.is_finite() && x > 0.0)
        {
            bail!("{flag} must be a positive number (got {x})");
        }
    }
    if args.column.is_some() && args.format != AnalyzeFormat::Csv {
        bail!(
            "--column applies to CSV input only (frame captures and MCAP recordings hold pulse counts)"
        );
    }
    if args.out.exists() && !args.out.is_dir() {
        bail!(
            "--out {}: exists and is not a directory",
            args.out.display()
        );
    }
    // the model is read before a pass that may take minutes
    let model = match &args.model {
        Some(p) => Some(
            GyroModel::load(p)
                .with_context(|| format!("loading the gyro model {}", p.display()))?,
        ),
        None => None,
    };
    let spec = match &args.spec {
        Some(p) => Some(crate::model::spec::Spec::load(p)?),
        None => None,
    };
    if model.is_some() && args.format == AnalyzeFormat::Csv && args.unit != RateUnit::Counts {
        bail!(
            "--model diagnoses pulse counts: it needs --unit counts (the input is a rate in {:?})",
            args.unit
        );
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;

    // a bar on stderr once the job is visibly long (hidden when stderr is not a terminal)
    let mut bar = DelayedBar::new("analysing", "samples");
    let mut progress = |done: u64, total: Option<u64>| bar.update(done, total);
    let input = &args.input;
    let mut meta = Metadata {
        input: input.display().to_string(),
        ..Metadata::default()
    };
    if args.gyro.is_some() && args.format != AnalyzeFormat::Mcap {
        anyhow::bail!(
            "--gyro selects a gyro of an MCAP recording; --format {:?} has one gyro",
            args.format
        );
    }
    let (pipe, collector) = match args.format {
        AnalyzeFormat::Csv => {
            let rate = required("--rate-hz", args.rate_hz, input, "sample rate")?;
            let cfg = match args.unit {
                RateUnit::Counts => PipelineConfig::counts(
                    rate,
                    required(
                        "--pulse-arcsec",
                        args.pulse_arcsec,
                        input,
                        "pulse weight (--unit counts)",
                    )?,
                ),
                _ => PipelineConfig::rates(rate),
            };
            let column = args.column.as_deref().unwrap_or("counts");
            meta.format = format!("CSV, column {column}, unit {}", unit_name(args.unit));
            meta.origin = "given on the command line".into();
            let mut col = collector_for(&cfg, model.is_some());
            let mut tap = |b: &TapBlock<'_>| col.tap(b);
            let pipe = offline::run_file_tapped(
                input,
                InputFormat::Csv,
                Some(column),
                args.unit,
                &cfg,
                &mut progress,
                Some(&mut tap),
            )
            .with_context(|| format!("analysing {}", input.display()))?;
            (finish(pipe, &mut meta, &cfg), col)
        }
        AnalyzeFormat::Frames => {
            let rate = required(
                "--rate-hz",
                args.rate_hz,
                input,
                "sample rate (a frame capture)",
            )?;
            let pulse = required(
                "--pulse-arcsec",
                args.pulse_arcsec,
                input,
                "pulse weight (a frame capture)",
            )?;
            let cfg = PipelineConfig::counts(rate, pulse);
            meta.format = "raw frame capture".into();
            meta.origin = "given on the command line".into();
            let mut col = collector_for(&cfg, model.is_some());
            let mut tap = |b: &TapBlock<'_>| col.tap(b);
            let (pipe, stats) =
                offline::run_capture_tapped(input, &cfg, &mut progress, Some(&mut tap))
                    .with_context(|| format!("analysing frame capture {}", input.display()))?;
            meta.gaps = Some((stats.gaps, stats.lost_samples));
            meta.frame_stats = Some(stats);
            (finish(pipe, &mut meta, &cfg), col)
        }
        AnalyzeFormat::Mcap => {
            let gyro = offline::recording_gyro(
                input,
                args.gyro.as_deref(),
                args.rate_hz,
                args.pulse_arcsec,
            )?;
            let cfg = PipelineConfig::counts(gyro.rate_hz, gyro.pulse_arcsec);
            meta.format = "MCAP recording (/gyro/raw)".into();
            meta.origin = "from the recording".into();
            let mut col = collector_for(&cfg, model.is_some());
            let mut tap = |b: &TapBlock<'_>| col.tap(b);
            let (pipe, broken) = offline::run_recording_tapped(
                input,
                args.gyro.as_deref(),
                &cfg,
                &mut progress,
                Some(&mut tap),
            )
            .with_context(|| format!("analysing recording {}", input.display()))?;
            if let Some(b) = broken {
                let note = format!(
                    "unreadable from byte {} ({}); analysed the {} samples before it",
                    b.offset,
                    b.reason,
                    pipe.samples()
                );
                eprintln!("warning: {}: {note}", input.display());
                meta.notes.push(note);
            }
            meta.gaps = Some((col.gaps, col.lost_samples));
            (finish(pipe, &mut meta, &cfg), col)
        }
    };
    bar.finish();
    let analysis = pipe.analysis();
    if !analysis.fit.ok {
        eprintln!(
            "warning: {}: the noise model does not describe this recording (fit chi2/dof {:.2}); see the report",
            input.display(),
            analysis.fit.chi2_per_dof
        );
    }

    let diagnosis = match (&model, &args.model) {
        (Some(m), Some(path)) => Some((
            run_diagnosis(m, &collector, &meta, input)?,
            path.display().to_string(),
        )),
        _ => None,
    };
    let verdict = spec
        .as_ref()
        .map(|s| s.evaluate_fixed(&analysis.estimates, analysis.duration_s));
    let r = report::Report {
        meta: &meta,
        analysis: &analysis,
        series: &collector,
        diagnosis: diagnosis.as_ref().map(|(d, m)| DiagnosisPart {
            diagnosis: d,
            model: m,
        }),
        spec: verdict.as_ref(),
    };
    let written = report::write(&args.out, &r).context("writing the report")?;
    super::write_stdout(&format!(
        "wrote {}, {} and {}",
        written.html.display(),
        written.allan_png.display(),
        written.noise_png.display()
    ))?;
    Ok(())
}

fn unit_name(u: RateUnit) -> &'static str {
    match u {
        RateUnit::Counts => "pulse counts per sample",
        RateUnit::Dph => "deg/h",
        RateUnit::Dps => "deg/s",
        RateUnit::RadS => "rad/s",
    }
}

fn collector_for(cfg: &PipelineConfig, keep: bool) -> Collector {
    let c = Collector::new(cfg.rate_hz);
    if keep { c.keeping_samples() } else { c }
}

fn finish(pipe: Pipeline, meta: &mut Metadata, cfg: &PipelineConfig) -> Pipeline {
    meta.rate_hz = cfg.rate_hz;
    meta.pulse_arcsec = cfg.pulse_arcsec;
    pipe
}

/// Diagnose the collected counts against `model` (a bar of the Monte-Carlo
/// runs at a terminal).
fn run_diagnosis(
    model: &GyroModel,
    c: &Collector,
    meta: &Metadata,
    input: &Path,
) -> Result<diagnose::Diagnosis> {
    let Some(counts) = c.all_counts() else {
        bail!(
            "{}: --model needs the pulse counts, and this input did not give them as integers",
            input.display()
        );
    };
    if let Some(&c0) = counts.first()
        && counts.iter().all(|&v| v == c0)
    {
        bail!(
            "{}: all {} increments are {c0}: no noise to compare with the model",
            input.display(),
            counts.len()
        );
    }
    // a constant temperature carries no information
    let temp_c = c
        .all_temps()
        .filter(|t| t.iter().any(|v| *v != t[0]))
        .map(|t| t.to_vec());
    let rec = Recording {
        counts: counts.to_vec(),
        temp_c,
        sample_rate_hz: meta.rate_hz,
        pulse_arcsec: meta.pulse_arcsec.unwrap_or(f64::NAN),
        output: Default::default(),
    };
    let bar = RunsBar::start();
    let d =
        diagnose::diagnose_with_progress(model, &rec, &DiagnoseOptions::default(), &bar.progress())
            .with_context(|| format!("diagnosing {} against the model", input.display()));
    bar.finish();
    d
}
