//! `sagnac diagnose`: compare a recording with its gyro model, locate the
//! mismatch, name and fit the missing physics, and show the fit improve
//! (see [`crate::diagnose`] for the method).
//!
//! Inputs: the model TOML and a recording as CSV (`counts` column of pulse
//! increments, optional `temp_c`; for a rate-output model, `--column NAME
//! --unit dps|dph|rad_s` reads its rate column, the units as `analyze` reads them), a raw frame capture (`frames`) or an MCAP
//! recording (`mcap`, topic `/gyro/raw`). The sample rate and pulse weight come
//! from the model's `[gyro]`, except that an MCAP recording's own values
//! override them: those of its `sagnac` metadata record ([`crate::recording::meta`]),
//! or for an older recording without one its sample period (`dt_ns`). Outputs: the JSON verdict (`--json`), an SVG
//! report (`--report`; at least one of the two) and the updated model (`--write-model`).
//!
//! The JSON verdict also says how it was made: `sagnac_version`, `input` (the
//! recording, its format, the sample rate and pulse weight used and where they
//! came from, the model file) and `units`. At a terminal a spinner shows the
//! reading, then a bar the Monte-Carlo runs of each phase, once the job takes
//! more than a moment.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};

use crate::diagnose::{self, DiagnoseOptions, Recording};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::offline::RateUnit;
use crate::recording::meta::GyroOutput;
use crate::sink::provenance::{InputSettings, Provenance};
use crate::input::capture::CaptureReader;
use crate::input::frame::FilledSeries;
use crate::input::plain::{InputError, InputFormat, SampleReader};
use crate::units;

/// Recording format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RecordingFormat {
    /// CSV with a `counts` column (pulse increments) and optionally `temp_c`.
    Csv,
    /// Raw binary gyro frame capture (.bin).
    Frames,
    /// MCAP recording made by `sagnac run` (topic /gyro/raw).
    Mcap,
}

/// Diagnose a recording against a gyro model.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Gyro model (TOML).
    #[arg(long)]
    pub model: PathBuf,
    /// The recording.
    #[arg(long)]
    pub recording: PathBuf,
    /// Recording format.
    #[arg(long, value_enum, default_value_t = RecordingFormat::Csv)]
    pub format: RecordingFormat,
    /// Where to write the JSON verdict ("-" = stdout); optional with --report.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Write an SVG report (recording, old and new model, mismatch shaded).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the updated model TOML (only when the diagnosis changed the model).
    #[arg(long)]
    pub write_model: Option<PathBuf>,
    /// Monte-Carlo runs of the model (confidence bands).
    #[arg(long, default_value_t = DiagnoseOptions::default().runs)]
    pub runs: usize,
    /// Monte-Carlo runs of the updated model.
    #[arg(long, default_value_t = DiagnoseOptions::default().runs_after)]
    pub runs_after: usize,
    /// Base seed of the Monte-Carlo runs.
    #[arg(long, default_value_t = DiagnoseOptions::default().seed)]
    pub seed: u64,
    /// CSV column to read (default `counts`, or `rate_dps` with a rate --unit:
    /// what `sagnac simulate` writes).
    #[arg(long, value_name = "NAME")]
    pub column: Option<String>,
    /// Unit of the column: pulse counts per sample (a counter's recording),
    /// or a rate in deg/h, deg/s or rad/s (a rate-output gyro's, for a model
    /// with `[gyro] output = "rate"`).
    #[arg(long, value_enum, default_value = "counts")]
    pub unit: RateUnit,
    /// Which gyro of an MCAP recording of several gyros (its label, e.g. `x`):
    /// required for such a recording, refused for a recording of one gyro.
    #[arg(long, value_name = "LABEL")]
    pub gyro: Option<String>,
}

/// Run `sagnac diagnose`.
pub fn run(args: DiagnoseArgs) -> anyhow::Result<()> {
    if args.json.is_none() && args.report.is_none() {
        bail!(
            "nothing to write: give --json OUT (the verdict, \"-\" for stdout), --report OUT.svg, or both"
        );
    }
    // the outputs are checked before a diagnosis that may take a minute
    let outputs = [
        ("--json", args.json.as_ref()),
        ("--report", args.report.as_ref()),
        ("--write-model", args.write_model.as_ref()),
    ];
    for (flag, path) in outputs {
        if let Some(p) = path {
            check_output_path(flag, p)?;
        }
    }
    let model = GyroModel::load(&args.model).context("loading the gyro model")?;
    check_input_kind(&args, &model)?;
    if args.gyro.is_some() && args.format != RecordingFormat::Mcap {
        bail!(
            "--gyro selects a gyro of an MCAP recording; {} is read as {}",
            args.recording.display(),
            format_name(args.format)
        );
    }
    let spinner = super::progress::Spinner::start(format!("reading {}", args.recording.display()));
    let rec = match args.format {
        RecordingFormat::Csv if args.unit != RateUnit::Counts => read_rate_csv(&args, &model)?,
        RecordingFormat::Csv => read_csv(
            &args.recording,
            args.column.as_deref().unwrap_or("counts"),
            &model,
        )?,
        RecordingFormat::Frames => read_frames(&args.recording, &model)?,
        RecordingFormat::Mcap => read_mcap(&args.recording, args.gyro.as_deref(), &model)?,
    };
    spinner.finish();
    // A series without any variation has no noise to compare: a dead gyro or a
    // stuck counter, not a gyro consistent with every noise model.
    if let Some(&c0) = rec.counts.first()
        && rec.counts.len() > 1
        && rec.counts.iter().all(|&c| c == c0)
    {
        bail!(
            "{}: all {} increments are {c0}: no noise to compare with the model (a dead gyro or a stuck counter?)",
            args.recording.display(),
            rec.counts.len()
        );
    }
    let opts = DiagnoseOptions {
        runs: args.runs,
        runs_after: args.runs_after,
        seed: args.seed,
        ..DiagnoseOptions::default()
    };
    let bar = super::progress::RunsBar::start();
    let diag = diagnose::diagnose_with_progress(&model, &rec, &opts, &bar.progress());
    bar.finish();
    let diag = diag.with_context(|| {
        format!(
            "diagnosing {} against {}",
            args.recording.display(),
            args.model.display()
        )
    })?;
    let mut value = serde_json::to_value(&diag.report).context("serialising the verdict")?;
    provenance(&args, &model, &rec).insert_into(&mut value);
    let json = serde_json::to_string_pretty(&value).context("serialising the verdict")?;
    if args.json.as_ref().is_some_and(|p| p.as_os_str() == "-") {
        super::write_stdout(&json)?;
    } else {
        if let Some(path) = &args.json {
            std::fs::write(path, json + "\n")
                .with_context(|| format!("writing {}", path.display()))?;
        }
        let r = &diag.report;
        let mut summary = format!(
            "verdict: {:?}; chi2/dof {:.2} -> {:.2}",
            r.verdict, r.fit_before.chi2_per_dof, r.fit_after.chi2_per_dof
        );
        for n in &diag.notes {
            summary.push_str(&format!("\n  {n}"));
        }
        super::write_stdout(&summary)?;
    }
    if let Some(path) = &args.report {
        let title = format!(
            "sagnac diagnose: {} vs {}",
            args.recording
                .file_name()
                .map_or("".into(), |f| f.to_string_lossy().into_owned()),
            args.model
                .file_name()
                .map_or("".into(), |f| f.to_string_lossy().into_owned())
        );
        let svg = diagnose::svg::render(&diag, &title).context("drawing the report")?;
        std::fs::write(path, svg).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = &args.write_model {
        match &diag.updated_model {
            Some(m) => {
                let text = m.to_toml().context("serialising the updated model")?;
                let mut f =
                    File::create(path).with_context(|| format!("creating {}", path.display()))?;
                writeln!(
                    f,
                    "# Updated by `sagnac diagnose` from {} against {}",
                    args.model.display(),
                    args.recording.display()
                )
                .and_then(|_| f.write_all(text.as_bytes()))
                .with_context(|| format!("writing {}", path.display()))?;
            }
            // a note, on stderr: stdout may be carrying the JSON (`--json -`)
            None => eprintln!(
                "  (no model written to {}: the diagnosis found no change that fits better)",
                path.display()
            ),
        }
    }
    Ok(())
}

/// What `--json` says about how the verdict was made.
fn provenance(args: &DiagnoseArgs, model: &GyroModel, rec: &Recording) -> Provenance {
    let own = |v: f64, m: f64| {
        if v == m {
            "the model's [gyro]"
        } else {
            "the recording's metadata"
        }
    };
    let mut input;
    if rec.output == OutputKind::Rate {
        input = InputSettings::new(
            &args.recording,
            format_name(args.format),
            rec.sample_rate_hz,
            None,
        );
        input.rate_lsb_dps = (model.gyro.rate_lsb_dps > 0.0).then_some(model.gyro.rate_lsb_dps);
        input.column = args.column.clone();
        input.unit = Some(super::analyze::unit_key(args.unit));
        input.origin = Some(format!(
            "sample rate and rate LSB from the model's [gyro]; rate words counted in {} deg/s",
            rec.rate_quantum_dps()
        ));
    } else {
        input = InputSettings::new(
            &args.recording,
            format_name(args.format),
            rec.sample_rate_hz,
            Some(rec.pulse_arcsec),
        );
        input.origin = Some(format!(
            "sample rate from {}, pulse weight from {}",
            own(rec.sample_rate_hz, model.gyro.sample_rate_hz),
            own(rec.pulse_arcsec, model.gyro.pulse_weight_arcsec)
        ));
    }
    input.model = Some(args.model.display().to_string());
    input.gyro = args.gyro.clone();
    Provenance::new(input, diagnose_units())
}

fn format_name(f: RecordingFormat) -> &'static str {
    match f {
        RecordingFormat::Csv => "csv",
        RecordingFormat::Frames => "frames",
        RecordingFormat::Mcap => "mcap",
    }
}

/// The units of the diagnosis JSON's numbers.
fn diagnose_units() -> Vec<(String, String)> {
    let mut u: Vec<(String, String)> = vec![
        ("mismatch_regions.tau_min_s, tau_max_s".into(), "s".into()),
        ("mismatch_regions.max_z".into(), "standard deviations of the model's Monte-Carlo spread".into()),
        ("fit_before, fit_after.chi2_per_dof".into(), "1 (chi-square per degree of freedom)".into()),
        (
            "parameter_changes, added_terms".into(),
            "each parameter in the unit its model-file key names (_dph deg/h, _dpsh deg/sqrt(h), _s s, _c deg C)".into(),
        ),
    ];
    u.extend(
        crate::units::COEFFICIENTS
            .iter()
            .map(|(k, unit, _)| (k.to_string(), unit.to_string())),
    );
    u
}

fn recording(
    model: &GyroModel,
    counts: Vec<i64>,
    temp_c: Option<Vec<f64>>,
    rate: Option<f64>,
    pulse: Option<f64>,
) -> Recording {
    Recording {
        counts,
        temp_c,
        sample_rate_hz: rate.unwrap_or(model.gyro.sample_rate_hz),
        pulse_arcsec: pulse.unwrap_or(model.gyro.pulse_weight_arcsec),
        output: Default::default(),
    }
}

/// A temperature channel carrying no information (constant) is dropped.
fn informative(t: Vec<f64>) -> Option<Vec<f64>> {
    let first = *t.first()?;
    t.iter().any(|v| *v != first).then_some(t)
}

/// The recording must be of the model's kind of sensor: `--unit` counts for
/// a counter, a rate unit for a rate-output model; a rate comes from a CSV column.
fn check_input_kind(args: &DiagnoseArgs, model: &GyroModel) -> anyhow::Result<()> {
    let rate_input = args.unit != RateUnit::Counts;
    if args.column.is_some() && args.format != RecordingFormat::Csv {
        bail!(
            "--column applies to CSV recordings only (frame captures and MCAP recordings hold pulse counts)"
        );
    }
    match (model.gyro.output, rate_input) {
        (OutputKind::Rate, false) => bail!(
            "{}: the model has [gyro] output = \"rate\" (a rate-output gyro), but the recording is read as pulse \
             counts: give the rate column and its unit, --column NAME --unit dps|dph|rad_s",
            args.model.display()
        ),
        (OutputKind::Counts, true) => bail!(
            "{}: the model is a pulse counter ([gyro] output = \"counts\"), but --unit {} reads rate samples: \
             diagnose a rate recording with a model that has [gyro] output = \"rate\" and rate_lsb_dps, or give \
             the counts column with --unit counts",
            args.model.display(),
            super::analyze::unit_key(args.unit)
        ),
        _ => {}
    }
    if rate_input && args.format != RecordingFormat::Csv {
        bail!(
            "--unit {} reads a CSV rate column: use --format csv",
            super::analyze::unit_key(args.unit)
        );
    }
    Ok(())
}

/// A rate-output gyro's recording: the CSV column `--column` in `--unit`,
/// at the model's sample rate, counted in the model's LSB when its values
/// lie on that grid ([`Recording::from_rates`]).
fn read_rate_csv(args: &DiagnoseArgs, model: &GyroModel) -> anyhow::Result<Recording> {
    let path = &args.recording;
    let column = args.column.as_deref().unwrap_or("rate_dps");
    let tau0 = model.tau0_s();
    let rates_dps: Vec<f64> = SampleReader::open(path, InputFormat::Csv, Some(column))
        .and_then(|mut r| r.read_to_end())
        .with_context(|| format!("reading the {column} column of {}", path.display()))?
        .into_iter()
        .map(|v| args.unit.to_dph(v, 0.0, tau0) / units::S_PER_H)
        .collect();
    let temp = read_temp(path, rates_dps.len())?;
    Recording::from_rates(
        &rates_dps,
        temp.and_then(informative),
        model.gyro.sample_rate_hz,
        model.gyro.rate_lsb_dps,
    )
    .with_context(|| format!("{}: column {column}", path.display()))
}

/// The optional `temp_c` column, as long as the data.
fn read_temp(path: &Path, n: usize) -> anyhow::Result<Option<Vec<f64>>> {
    let temp = match SampleReader::open(path, InputFormat::Csv, Some("temp_c")) {
        Ok(mut r) => Some(
            r.read_to_end()
                .with_context(|| format!("reading the temp_c column of {}", path.display()))?,
        ),
        Err(InputError::MissingColumn { .. }) => None,
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    if let Some(t) = &temp
        && t.len() != n
    {
        bail!(
            "{}: temp_c has {} values, the data {n}",
            path.display(),
            t.len()
        );
    }
    Ok(temp)
}

fn read_csv(path: &Path, column: &str, model: &GyroModel) -> anyhow::Result<Recording> {
    let counts: Vec<i64> = SampleReader::open(path, InputFormat::Csv, Some(column))
        .and_then(|r| r.require_integers(true).read_to_end())
        .with_context(|| format!("reading the {column} column of {}", path.display()))?
        .into_iter()
        .map(|v| v as i64)
        .collect();
    let temp = read_temp(path, counts.len())?;
    Ok(recording(
        model,
        counts,
        temp.and_then(informative),
        None,
        None,
    ))
}

fn read_frames(path: &Path, model: &GyroModel) -> anyhow::Result<Recording> {
    let summary = CaptureReader::open(path)
        .and_then(|r| r.read_all())
        .with_context(|| format!("decoding the frame capture {}", path.display()))?;
    let mut temps = Vec::with_capacity(summary.samples.len());
    for s in &summary.samples {
        for _ in 0..=s.lost_before {
            temps.push(s.temp_c);
        }
    }
    // the gap fill's mask is not passed on: `Recording` has no field for it yet
    let mut series = FilledSeries::with_capacity(temps.len());
    for s in &summary.samples {
        series.push_sample(s);
    }
    temps.truncate(series.len());
    Ok(recording(
        model,
        series.counts,
        informative(temps),
        None,
        None,
    ))
}

fn read_mcap(path: &Path, gyro: Option<&str>, model: &GyroModel) -> anyhow::Result<Recording> {
    let gyro = crate::offline::select_gyro(path, gyro)?;
    // strict: a damaged or cut recording is an error (with the offset where it breaks)
    let mut reader = crate::recording::reader::RawReader::open(path, gyro.as_deref(), true)
        .with_context(|| format!("reading the MCAP recording {}", path.display()))?;
    let mut series = FilledSeries::default();
    let mut temps: Vec<f64> = Vec::new();
    let mut any_temp = false;
    let mut dt_ns: Option<u64> = None;
    while let Some(b) = reader
        .next_batch()
        .with_context(|| format!("reading the MCAP recording {}", path.display()))?
    {
        if b.counts.is_empty() {
            continue;
        }
        match dt_ns {
            None => dt_ns = Some(b.dt_ns),
            Some(d) if d != b.dt_ns => bail!(
                "{}: /gyro/raw sample period changes from {d} ns to {} ns (at t = {} ns)",
                path.display(),
                b.dt_ns,
                b.t0_ns
            ),
            _ => {}
        }
        any_temp |= b.temp_c.is_some();
        let t = b.temp_c.unwrap_or(f64::NAN);
        let mut gaps = b.gaps.iter().peekable();
        for (i, &c) in b.counts.iter().enumerate() {
            // a sample after `lost` missing ones carries the whole difference
            // (as the frame decoder delivers it): spread it uniformly
            match gaps.peek() {
                Some(g) if g.index as usize == i => {
                    if g.lost > crate::offline::MAX_GAP_SAMPLES {
                        return Err(crate::offline::OfflineError::ImplausibleGap {
                            path: path.to_path_buf(),
                            t0_ns: b.t0_ns,
                            lost: g.lost,
                        }
                        .into());
                    }
                    let n = series.push(c, g.lost);
                    temps.extend(std::iter::repeat_n(t, n));
                    gaps.next();
                }
                _ => {
                    series.push(c, 0);
                    temps.push(t);
                }
            }
        }
    }
    // the recording's own rate and pulse weight (its metadata record), if it says them
    let meta = match &gyro {
        Some(g) => crate::recording::reader::read_metadata_of(path, Some(g))?,
        None => reader.report().metadata.clone(),
    };
    if let Some(m) = &meta
        && m.output == GyroOutput::Rate
    {
        bail!(
            "{}: its metadata says output = rate (rate samples, not pulse counts): not supported by diagnose yet",
            path.display()
        );
    }
    if series.is_empty() {
        bail!("{}: no /gyro/raw samples in the recording", path.display());
    }
    let rate = match &meta {
        Some(m) => Some(m.sample_rate_hz),
        None => dt_ns.filter(|d| *d > 0).map(|d| 1e9 / d as f64),
    };
    let temp = if any_temp && temps.iter().all(|t| t.is_finite()) {
        informative(temps)
    } else {
        None
    };
    Ok(recording(
        model,
        series.counts,
        temp,
        rate,
        meta.and_then(|m| m.pulse_arcsec),
    ))
}

/// An output path must be `-` (JSON only), or name a file (not a directory)
/// in an existing directory.
fn check_output_path(flag: &str, p: &Path) -> anyhow::Result<()> {
    if flag == "--json" && p.as_os_str() == "-" {
        return Ok(());
    }
    if p.is_dir() {
        anyhow::bail!("{flag} {}: is a directory, not a file", p.display());
    }
    super::output_dir(p).with_context(|| format!("bad {flag}"))?;
    Ok(())
}
