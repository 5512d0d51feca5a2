//! The report of one axis: the pipeline run with a tap that keeps the time
//! series, the page's metadata, the diagnosis with `--model`, and the page
//! and figures written ([`crate::sink::report`]). `sagnac report` runs it once,
//! or once per axis of a multi-axis input ([`super::report_axes`]).

use anyhow::{Context, Result};

use super::progress::RunsBar;
use crate::diagnose::{self, DiagnoseOptions, Recording};
use crate::input::{Format, Input};
use crate::model::GyroModel;
use crate::pipeline::feed::TapBlock;
use crate::sink::report::{self, Collector, DiagnosisPart, Metadata};

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
    let fed = super::analyze_out::feed_input(input, raw_statistics, Some(&mut tap))?;
    let meta = metadata(input, &fed, &collector);
    let analysis = fed.analysis();
    if let Some(dq) = &analysis.data_quality {
        super::analyze_out::print_quality(dq, input.path(), input.meta().unit.quantity());
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
    for (kind, note) in super::analyze_out::stream_notes(&fed.report) {
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
