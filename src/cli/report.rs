//! `sagnac report`: analyse a recording and write a self-contained HTML page
//! (`DIR/index.html`: inline SVG figures, no outside requests) with the
//! recording's metadata, the coefficient table, the data-quality findings,
//! the Allan figure, the extracted noise and its integral, the rate and
//! temperature (with what the data-quality stage handled marked), the
//! dynamic Allan deviation and, with `--model`, the diagnosis; plus
//! `DIR/allan.png`, `DIR/noise_integral.png` and, when the record has a
//! dynamic Allan deviation of at least four windows, `DIR/davar.png`.
//!
//! Thin: the input flags are `analyze`'s (same rules: `--sample-rate-hz` and,
//! for counts, `--pulse-arcsec` are required for CSV and frame captures; an
//! MCAP recording carries them), the pipeline runs with a tap
//! ([`crate::pipeline::feed`]) that keeps the time series, and the page is
//! [`crate::sink::report`]. A diagnosis (`--model`) reads the input a second time.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use super::input_args::InputArgs;
use super::progress::RunsBar;
use crate::diagnose::{self, DiagnoseOptions, Recording};
use crate::input::{Format, Input};
use crate::model::GyroModel;
use crate::pipeline::feed::TapBlock;
use crate::sink::report::{self, Collector, DiagnosisPart, Metadata};

/// Arguments of `sagnac report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Output directory (created if missing): index.html, allan.png, noise_integral.png, davar.png.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Gyro model (TOML): also diagnose the recording against it and show the findings.
    #[arg(long, value_name = "MODEL.toml")]
    pub model: Option<PathBuf>,
    /// Acceptance test against this spec file: show the verdict per coefficient.
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Option<PathBuf>,
}

/// Run `sagnac report`.
pub fn run(args: ReportArgs) -> Result<()> {
    if args.out.exists() && !args.out.is_dir() {
        bail!(
            "--out {}: exists and is not a directory",
            args.out.display()
        );
    }
    // the model is read before a pass that may take minutes
    let model = args.model.as_deref().map(super::load_model).transpose()?;
    let spec = match &args.spec {
        Some(p) => Some(crate::model::spec::Spec::load(p)?),
        None => None,
    };
    let mut req = args.input.request();
    req.all_axes = true;
    let input = Input::open(&args.input.input, &req)?;
    if !input.axes().is_empty() {
        if args.model.is_some() || args.spec.is_some() {
            bail!(
                "--model and --spec take one axis: choose it with --gyro ({} has {})",
                input.path().display(),
                input.axes().join(", ")
            );
        }
        return super::report_axes::run(&input, &args.out, args.input.raw_statistics);
    }
    let (written, _) = one(
        &input,
        &args.out,
        model.as_ref(),
        args.model.as_deref(),
        spec.as_ref(),
        args.input.raw_statistics,
    )?;
    let mut files = vec![
        written.html.display().to_string(),
        written.allan_png.display().to_string(),
        written.noise_png.display().to_string(),
    ];
    files.extend(written.davar_png.map(|p| p.display().to_string()));
    let last = files.pop().unwrap_or_default();
    super::write_stdout(&format!("wrote {} and {last}", files.join(", ")))?;
    Ok(())
}

/// The report of one axis into `out` (created); what was written.
pub(super) fn one(
    input: &Input,
    out: &std::path::Path,
    model: Option<&GyroModel>,
    model_path: Option<&std::path::Path>,
    spec: Option<&crate::model::spec::Spec>,
    raw_statistics: bool,
) -> Result<(report::Written, crate::pipeline::Analysis)> {
    if let Some(m) = model {
        // a diagnosis of the wrong kind of sensor fails before the analysis
        diagnose::read::check_kind(m, input.meta().unit).context("--model")?;
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut collector = Collector::new(input.sample_rate_hz()?);
    let mut tap = |b: &TapBlock<'_>| collector.tap(b);
    let fed = super::analyze::feed_input(input, raw_statistics, Some(&mut tap))?;
    let meta = metadata(input, &fed, &collector);
    let analysis = fed.analysis();
    if let Some(dq) = &analysis.data_quality {
        super::analyze::print_quality(dq, input.path(), input.meta().unit.quantity());
    }
    if !analysis.fit.ok {
        eprintln!(
            "warning: {}: the noise model does not describe this recording (fit chi2/dof {:.2}); see the report",
            input.path().display(),
            analysis.fit.chi2_per_dof
        );
    }
    let diagnosis = match (model, model_path) {
        (Some(m), Some(path)) => Some((run_diagnosis(m, input)?, path.display().to_string())),
        _ => None,
    };
    let verdict = spec.map(|s| s.evaluate_fixed(&analysis.estimates, analysis.duration_s));
    let r = report::Report {
        meta: &meta,
        analysis: &analysis,
        series: &collector,
        diagnosis: diagnosis.as_ref().map(|(d, m)| DiagnosisPart {
            diagnosis: d,
            model: m,
        }),
        spec: verdict.as_ref(),
        davar: fed.davar.as_ref(),
    };
    let written = report::write(out, &r).context("writing the report")?;
    Ok((written, analysis))
}

/// What the report's metadata table says about the input.
fn metadata(input: &Input, fed: &crate::pipeline::feed::Fed, c: &Collector) -> Metadata {
    let m = input.meta();
    let format = match m.format {
        Format::Csv | Format::Text => format!(
            "{}, column {}, unit {}",
            if m.format == Format::Csv {
                "CSV"
            } else {
                "text"
            },
            m.column.as_deref().unwrap_or("(the only one)"),
            m.unit.describe()
        ),
        Format::F64le => format!("raw f64le, unit {}", m.unit.describe()),
        Format::Frames => "raw frame capture".into(),
        Format::TriadFrames => format!(
            "raw triad frame capture, gyro {}",
            m.gyro.as_deref().unwrap_or("?")
        ),
        Format::Mcap => "MCAP recording (/gyro/raw)".into(),
        Format::Array => format!("array in memory, unit {}", m.unit.describe()),
        Format::Ros2 => format!(
            "ROS 2 bag, topic {}, axis {} (rad/s)",
            m.bag.as_ref().map_or("?", |b| b.topic.as_str()),
            m.gyro.as_deref().unwrap_or("?")
        ),
    };
    let mut meta = Metadata {
        input: input.path().display().to_string(),
        format,
        origin: m.origin.clone(),
        sample_rate_hz: fed.pipeline.config().sample_rate_hz,
        pulse_arcsec: (m.unit == crate::input::Unit::Counts)
            .then_some(m.pulse_arcsec)
            .flatten(),
        frame_stats: fed.report.frames,
        units: report::Units::of(m.unit.quantity()),
        ..Metadata::default()
    };
    if m.format.holds_counts() {
        meta.gaps = Some((c.gaps, c.lost_samples));
    }
    for (kind, note) in super::analyze::stream_notes(&fed.report) {
        if kind == "warning" {
            eprintln!("warning: {}: {note}", input.path().display());
            meta.notes.push(note);
        }
    }
    meta
}

/// Diagnose the input (a second pass over it) against `model` (a bar of the
/// Monte-Carlo runs at a terminal).
fn run_diagnosis(model: &GyroModel, input: &Input) -> Result<diagnose::Diagnosis> {
    let rec = Recording::read(input, model)?;
    super::diagnose::check_not_constant(&rec, input.path())?;
    let bar = RunsBar::start();
    let d =
        diagnose::diagnose_with_progress(model, &rec, &DiagnoseOptions::default(), &bar.progress())
            .with_context(|| format!("diagnosing {} against the model", input.path().display()));
    bar.finish();
    d
}
