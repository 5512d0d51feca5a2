//! `sagnac analyze` on a multi-axis input without `--gyro`: a ROS 2 bag's
//! six axes (gyroscope and accelerometer, in one pass over the bag), a triad
//! capture's or a recording's gyros. Each axis is analysed as it would be
//! alone ([`crate::pipeline::axes`]); the JSON carries
//! `"axes": {"gyro_x": {...}, ..., "accel_z": {...}}`, each axis with the
//! single-axis structure (an accelerometer's under its own names), and the
//! Kalibr file takes the gyroscope and accelerometer fields from them.

use std::path::Path;

use anyhow::{Context, Result};

use super::analyze_out::{
    print_quality, print_table, stream_notes, warn_about, write_kalibr, write_value,
};
use super::input_args;
use crate::input::Input;
use crate::pipeline::Analysis;
use crate::pipeline::axes::{AxisRun, run_axes};
use crate::sink::export::kalibr::KalibrAxis;
use crate::sink::provenance::{Provenance, analysis_json};

/// What the command asks of a multi-axis analysis.
#[derive(Debug, Clone, Copy)]
pub(super) struct AxesJob<'a> {
    pub kalibr: Option<&'a Path>,
    pub json: Option<&'a Path>,
    pub raw_statistics: bool,
    /// `--input` as given (the JSON's `input.path`).
    pub given_path: &'a Path,
    /// Kalibr's `rostopic`.
    pub rostopic: Option<&'a str>,
}

/// Analyse every axis of `input`.
pub(super) fn run(job: &AxesJob<'_>, input: &Input) -> Result<()> {
    let path = input.path();
    let runs = run_axes(input, !job.raw_statistics)
        .with_context(|| format!("analysing {}", path.display()))?;
    let analyses: Vec<Analysis> = runs.iter().map(|r| r.fed.analysis()).collect();
    report_findings(&runs, &analyses, path);
    if let Some(out) = job.kalibr {
        let axes: Vec<KalibrAxis> = runs
            .iter()
            .zip(&analyses)
            .map(|(r, a)| KalibrAxis {
                label: &r.label,
                quantity: r.input.meta().unit.quantity(),
                estimates: &a.estimates,
            })
            .collect();
        let rate = runs[0].fed.pipeline.config().sample_rate_hz;
        write_kalibr(out, &axes, rate, path, job.rostopic)?;
    }
    match job.json {
        Some(out) => write_value(
            out,
            &mut axes_json(job.given_path, input, &runs, &analyses)?,
        ),
        None => {
            for (r, a) in runs.iter().zip(&analyses) {
                println!("== {} ==", r.label);
                print_table(a, r.input.meta().unit.quantity())?;
                println!();
            }
            Ok(())
        }
    }
}

/// The notes of the pass (once), then each axis's data-quality findings and warnings.
fn report_findings(runs: &[AxisRun], analyses: &[Analysis], path: &Path) {
    for (kind, note) in stream_notes(&runs[0].fed.report) {
        eprintln!("{kind}: {}: {note}", path.display());
    }
    for (r, a) in runs.iter().zip(analyses) {
        let named = Path::new(&format!("{} {}", path.display(), r.label)).to_path_buf();
        if let Some(dq) = &a.data_quality {
            print_quality(dq, &named, r.input.meta().unit.quantity());
        }
        warn_about(a, &named);
    }
}

/// `{"axes": {label: the axis's single-axis JSON}, "sagnac_version", "input"}`.
fn axes_json(
    given_path: &Path,
    input: &Input,
    runs: &[AxisRun],
    analyses: &[Analysis],
) -> Result<serde_json::Value> {
    let mut axes = serde_json::Map::new();
    for (r, a) in runs.iter().zip(analyses) {
        let mut settings = input_args::settings(&r.input, given_path);
        settings.stamps = r.fed.report.stamps.clone();
        let v = analysis_json(a, None, settings, r.input.meta().unit.quantity())?;
        axes.insert(r.label.clone(), v);
    }
    let mut top = serde_json::json!({ "axes": axes });
    let mut settings = input_args::settings(input, given_path);
    settings.stamps = runs[0].fed.report.stamps.clone();
    settings.unit = None;
    Provenance::new(settings, Vec::new()).insert_into(&mut top);
    if let Some(o) = top.as_object_mut() {
        // the units are each axis's own
        o.remove("units");
    }
    Ok(top)
}
