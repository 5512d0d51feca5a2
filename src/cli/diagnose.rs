//! `sagnac diagnose`: compare a recording with its gyro model, locate the
//! mismatch, name and fit the missing physics, and show the fit improve
//! (see [`crate::diagnose`] for the method).
//!
//! Inputs: the model TOML and a recording, any input [`crate::input::Input::open`]
//! reads: a CSV of pulse increments (`counts`, optional `temp_c`) or, for a
//! rate-output model, of rates (`--column NAME --unit dps|dph|rad_s`), a raw
//! frame capture or an MCAP recording. The sample rate and pulse weight are
//! the recording's own when it says them (an MCAP recording's metadata
//! record, or its sample period), else the model's `[gyro]`
//! ([`crate::diagnose::Recording::read`]). Outputs: the JSON verdict
//! (`--json`), an SVG report (`--report`; at least one of the two) and the
//! updated model (`--write-model`).
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
use clap::Args;

use super::input_args::{self, InputArgs};
use crate::diagnose::{self, DiagnoseOptions, Recording};
use crate::input::{Input, Unit};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::sink::provenance::Provenance;

/// Diagnose a recording against a gyro model.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Gyro model (TOML).
    #[arg(long)]
    pub model: PathBuf,
    /// The recording and how to read it (`--recording` is an alias of
    /// `--input`); a rate-output model reads a CSV rate column, `--column NAME
    /// --unit dps|dph|rad_s` (default column `rate_dps`, what `sagnac simulate` writes).
    #[command(flatten)]
    pub input: InputArgs,
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
}

/// A series without any variation has no noise to compare: a dead gyro or a
/// stuck counter, not a gyro consistent with every noise model.
pub(crate) fn check_not_constant(rec: &Recording, path: &Path) -> anyhow::Result<()> {
    if let Some(&c0) = rec.counts.first()
        && rec.counts.len() > 1
        && rec.counts.iter().all(|&c| c == c0)
    {
        bail!(
            "{}: all {} increments are {c0}: no noise to compare with the model (a dead gyro or a stuck counter?)",
            path.display(),
            rec.counts.len()
        );
    }
    Ok(())
}

/// Open the recording: a rate-output model's CSV column defaults to `rate_dps`.
fn open_input(args: &DiagnoseArgs, model: &GyroModel) -> anyhow::Result<Input> {
    let mut req = args.input.request();
    let rate_unit = req.unit.is_some_and(|u| u != Unit::Counts);
    if rate_unit && req.column.is_none() && model.gyro.output == OutputKind::Rate {
        req.column = Some("rate_dps".into());
    }
    Ok(Input::open(&args.input.input, &req)?)
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
    return_freed_buffers();
    let model = super::load_model(&args.model)?;
    let path = args.input.input.clone();
    let spinner = super::progress::Spinner::start(format!("reading {}", path.display()));
    let input = open_input(&args, &model)?;
    let rec = Recording::read(&input, &model).with_context(|| {
        format!(
            "reading {} against {}",
            path.display(),
            args.model.display()
        )
    })?;
    spinner.finish();
    check_not_constant(&rec, &path)?;
    let opts = DiagnoseOptions {
        runs: args.runs,
        runs_after: args.runs_after,
        seed: args.seed,
        data_quality: !args.input.raw_statistics,
        ..DiagnoseOptions::default()
    };
    let bar = super::progress::RunsBar::start();
    let diag = diagnose::diagnose_with_progress(&model, &rec, &opts, &bar.progress());
    bar.finish();
    let diag = diag.with_context(|| {
        format!(
            "diagnosing {} against {}",
            path.display(),
            args.model.display()
        )
    })?;
    let mut value = serde_json::to_value(&diag.report).context("serialising the verdict")?;
    if let (Some(dq), Some(obj)) = (&diag.data_quality, value.as_object_mut()) {
        obj.insert(
            "data_quality".into(),
            serde_json::to_value(dq).context("serialising the data quality")?,
        );
    }
    provenance(&args, &input, &model, &rec).insert_into(&mut value);
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
            path.file_name()
                .map_or("".into(), |f| f.to_string_lossy().into_owned()),
            args.model
                .file_name()
                .map_or("".into(), |f| f.to_string_lossy().into_owned())
        );
        let svg = crate::sink::report::diagnosis_fig::render(&diag, &title)
            .context("drawing the report")?;
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
                    path.display()
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
fn provenance(
    args: &DiagnoseArgs,
    input: &Input,
    model: &GyroModel,
    rec: &Recording,
) -> Provenance {
    let own = |v: f64, m: f64| {
        if v == m {
            "the model's [gyro]"
        } else {
            "the recording's metadata"
        }
    };
    let mut s = input_args::settings(input, &args.input.input);
    s.sample_rate_hz = rec.sample_rate_hz;
    if rec.output == OutputKind::Rate {
        s.pulse_arcsec = None;
        s.rate_lsb_dps = (model.gyro.rate_lsb_dps > 0.0).then_some(model.gyro.rate_lsb_dps);
        s.origin = Some(format!(
            "sample rate and rate LSB from the model's [gyro]; rate words counted in {} deg/s",
            rec.rate_quantum_dps()
        ));
    } else {
        s.pulse_arcsec = Some(rec.pulse_arcsec);
        s.origin = Some(format!(
            "sample rate from {}, pulse weight from {}",
            own(rec.sample_rate_hz, model.gyro.sample_rate_hz),
            own(rec.pulse_arcsec, model.gyro.pulse_arcsec)
        ));
    }
    s.model = Some(args.model.display().to_string());
    Provenance::new(s, diagnose_units())
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

/// Whole-record buffers (tens of MB an hour of data) are allocated and freed
/// by every Monte-Carlo run on every worker thread. glibc keeps a freed one in
/// its thread's arena once its dynamic mmap threshold has risen past that
/// size, and the process then holds several runs' worth. A fixed threshold of
/// 1 MiB maps each such buffer on its own and gives it back when it is freed
/// (the 1 h record of `scripts/bench-diagnose-memory`: 328 -> 197 MB peak,
/// the same time).
fn return_freed_buffers() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt sets one allocator parameter; it reads no memory of ours.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 1 << 20);
    }
}
