//! `sagnac analyze`: automatic estimation of the IEEE 952 coefficients (QN,
//! ARW, bias instability, RRW, rate ramp) with 95 % intervals, from a CSV
//! file, a raw frame capture or an MCAP recording.
//!
//! Thin: reading is `offline`, the numerics are `pipeline` (the same chain the
//! daemon runs live). `--spec SPEC.toml` adds the acceptance test's verdicts
//! (`spec` in the JSON, [`crate::model::spec`]): one look at the whole record.
//!
//! No silent defaults: a CSV file and a frame capture carry no sample rate and
//! no pulse weight, so `--rate-hz` (and `--pulse-arcsec` for pulse counts) are
//! required; an MCAP recording carries both in its `sagnac` metadata record
//! ([`crate::recording::meta`]), and a flag that contradicts it is an error.
//!
//! The JSON (`--json`) also says how it was made ([`crate::sink::provenance`]):
//! `sagnac_version`, `input` (file, format, column and unit, sample rate and
//! pulse weight, where they came from) and `units`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use crate::model::estimate::Coefficient;
use crate::model::spec::{Spec, SpecReport};
use crate::offline::{self, OfflineError, RateUnit};
use crate::pipeline::{Analysis, PipelineConfig};
use crate::sink::provenance::{InputSettings, Provenance, analysis_units};
use crate::input::plain::InputFormat;

/// Arguments of `sagnac analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
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
    /// Write the result as JSON here ("-" for stdout) instead of printing a table.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Also write Kalibr's imu.yaml gyroscope fields (noise density from ARW,
    /// random walk from RRW or its upper bound, update rate), conversions in comments.
    #[arg(long, value_name = "FILE.yaml")]
    pub kalibr: Option<PathBuf>,
    /// Also write the raw, clean and noise Allan curves as CSV
    /// (channel, tau_s, dev_dph, ci_lo_dph, ci_hi_dph, edf, n).
    #[arg(long, value_name = "OUT.csv")]
    pub allan_csv: Option<PathBuf>,
    /// Acceptance test against this spec file (config/spec_example.toml): adds
    /// `spec` (verdict per coefficient) to the output.
    #[arg(long, value_name = "SPEC.toml")]
    pub spec: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AnalyzeFormat {
    Csv,
    Frames,
    Mcap,
}

/// The value of `flag`, or the error naming it: `input` (a CSV file or a frame
/// capture) carries no `what`.
fn required(
    flag: &'static str,
    value: Option<f64>,
    input: &std::path::Path,
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

pub fn run(args: AnalyzeArgs) -> Result<()> {
    if let Some(r) = args.rate_hz
        && !(r.is_finite() && r > 0.0)
    {
        bail!("--rate-hz must be a positive number of Hz (got {r})");
    }
    if let Some(d) = args.pulse_arcsec
        && !(d.is_finite() && d > 0.0)
    {
        bail!("--pulse-arcsec must be a positive number of arcsec (got {d})");
    }
    if args.column.is_some() && args.format != AnalyzeFormat::Csv {
        bail!(
            "--column applies to CSV input only (frame captures and MCAP recordings hold pulse counts)"
        );
    }
    // the export paths are checked before the analysis
    for (flag, p) in [("--kalibr", &args.kalibr), ("--allan-csv", &args.allan_csv)] {
        if let Some(p) = p {
            if p.is_dir() {
                bail!("{flag} {}: is a directory, not a file", p.display());
            }
            super::output_dir(p).with_context(|| format!("bad {flag}"))?;
        }
    }
    // a bad spec file fails before the (long) analysis
    let spec = match &args.spec {
        Some(p) => Some(Spec::load(p)?),
        None => None,
    };
    // a bar on stderr once the job is visibly long (hidden when stderr is not a terminal)
    let mut bar = super::progress::DelayedBar::new("analysing", "samples");
    let mut progress = |done: u64, total: Option<u64>| bar.update(done, total);
    let input = &args.input;
    let given = "given on the command line";
    let settings: InputSettings;
    if args.gyro.is_some() && args.format != AnalyzeFormat::Mcap {
        anyhow::bail!(
            "--gyro selects a gyro of an MCAP recording; --format {:?} has one gyro",
            args.format
        );
    }
    let pipe = match args.format {
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
            let mut s = InputSettings::new(input, "csv", cfg.rate_hz, cfg.pulse_arcsec);
            (s.column, s.unit, s.origin) = (
                Some(column.into()),
                Some(unit_key(args.unit)),
                Some(given.into()),
            );
            settings = s;
            offline::run_file(
                input,
                InputFormat::Csv,
                Some(column),
                args.unit,
                &cfg,
                &mut progress,
            )
            .with_context(|| format!("analysing {}", input.display()))?
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
            let mut s = InputSettings::new(input, "frames", rate, Some(pulse));
            s.origin = Some(given.into());
            settings = s;
            let (pipe, stats) = offline::run_capture(input, &cfg, &mut progress)
                .with_context(|| format!("analysing frame capture {}", input.display()))?;
            if stats.lost_samples
                + stats.bytes_skipped
                + stats.crc_errors
                + stats.duplicates
                + stats.out_of_sequence
                > 0
            {
                eprintln!(
                    "note: {}: {} frames decoded; {} samples lost in {} gaps (filled, the angle kept); \
                     {} CRC errors, {} false syncs, {} bytes skipped; {} duplicate and {} out-of-sequence frames",
                    input.display(),
                    stats.frames_decoded,
                    stats.lost_samples,
                    stats.gaps,
                    stats.crc_errors,
                    stats.false_syncs,
                    stats.bytes_skipped,
                    stats.duplicates,
                    stats.out_of_sequence
                );
            }
            pipe
        }
        AnalyzeFormat::Mcap => {
            // the recording's metadata record supplies what the flags leave out
            let gyro = offline::recording_gyro(
                input,
                args.gyro.as_deref(),
                args.rate_hz,
                args.pulse_arcsec,
            )?;
            let cfg = PipelineConfig::counts(gyro.rate_hz, gyro.pulse_arcsec);
            let mut s = InputSettings::new(input, "mcap", gyro.rate_hz, Some(gyro.pulse_arcsec));
            s.gyro = args.gyro.clone();
            s.origin = Some(
                match (args.rate_hz, args.pulse_arcsec) {
                    (None, None) => "from the recording",
                    (Some(_), Some(_)) => {
                        "given on the command line (checked against the recording)"
                    }
                    _ => "from the recording and the command line",
                }
                .into(),
            );
            settings = s;
            let (pipe, broken) =
                offline::run_recording(input, args.gyro.as_deref(), &cfg, &mut progress)
                    .with_context(|| format!("analysing recording {}", input.display()))?;
            if let Some(b) = broken {
                eprintln!(
                    "warning: {}: unreadable from byte {} ({}); analysed the {} samples before it",
                    input.display(),
                    b.offset,
                    b.reason,
                    pipe.samples()
                );
            }
            pipe
        }
    };
    bar.finish();
    let analysis = pipe.analysis();
    if !analysis.allan.raw.is_empty() && analysis.allan.raw.iter().all(|p| p.dev == 0.0) {
        eprintln!(
            "warning: {}: the raw Allan deviation is 0 at every tau (every increment equal: a stuck counter \
             or a dead gyro?); nothing can be estimated",
            input.display()
        );
    }
    if !analysis.fit.ok {
        eprintln!(
            "warning: {}: {}",
            input.display(),
            misfit_message(&analysis)
        );
    }
    if let Some(path) = &args.kalibr {
        crate::sink::export::kalibr::write(
            path,
            &analysis.estimates,
            pipe.config().rate_hz,
            &input.display().to_string(),
        )
        .context("writing the Kalibr file")?;
    }
    if let Some(path) = &args.allan_csv {
        crate::sink::export::allan_csv::write_channels(path, &analysis.allan)
            .context("writing the Allan CSV")?;
    }
    let verdict = spec
        .as_ref()
        .map(|s| s.evaluate_fixed(&analysis.estimates, analysis.duration_s));
    match &args.json {
        Some(path) => {
            let mut value = serde_json::to_value(&analysis).context("serialising the analysis")?;
            if let (Some(v), Some(obj)) = (&verdict, value.as_object_mut()) {
                obj.insert(
                    "spec".into(),
                    serde_json::to_value(v).context("serialising the verdict")?,
                );
            }
            Provenance::new(settings, analysis_units()).insert_into(&mut value);
            let text = serde_json::to_string_pretty(&value).context("serialising the analysis")?;
            if path.as_os_str() == "-" {
                super::write_stdout(&text)?;
            } else {
                std::fs::write(path, text + "\n")
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
        None => {
            print_table(&analysis)?;
            if let Some(v) = &verdict {
                print_verdict(v)?;
            }
        }
    }
    Ok(())
}

/// The `--unit` value as the flag spells it.
pub(crate) fn unit_key(u: RateUnit) -> String {
    use clap::ValueEnum;
    u.to_possible_value()
        .map_or_else(|| format!("{u:?}"), |v| v.get_name().to_string())
}

fn print_verdict(r: &SpecReport) -> Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(o)?;
    writeln!(
        o,
        "spec verdict: {} (each coefficient at {} % confidence, one look at {:.1} s)",
        r.verdict.as_str().to_uppercase(),
        r.confidence * 100.0,
        r.duration_s
    )?;
    writeln!(
        o,
        "{:<22} {:>12} {:>10} {:>12} {:>12}  reason",
        "coefficient", "limit", "verdict", "estimate", "bound"
    )?;
    let f = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.6}"));
    for (name, c) in &r.coefficients {
        writeln!(
            o,
            "{name:<22} {:>12.6} {:>10} {:>12} {:>12}  {}",
            c.limit,
            c.verdict.as_str(),
            f(c.estimate),
            f(c.bound),
            c.reason.as_deref().unwrap_or("")
        )?;
    }
    Ok(())
}

fn fmt_coef(c: &Coefficient) -> String {
    match (c.value, c.ci95, c.upper95) {
        (Some(v), Some([lo, hi]), _) => format!("{v:<12.6} [{lo:.6}, {hi:.6}]"),
        (Some(v), None, _) => format!("{v:.6}"),
        (None, _, Some(u)) => format!("{:<12} < {u:.6} (95 % upper bound)", "not found"),
        _ => "n/a".to_string(),
    }
}

/// What a failed fit means, for stderr and the table.
fn misfit_message(a: &Analysis) -> String {
    format!(
        "the noise model does not describe this recording (fit chi2/dof {:.2} on {} degrees of freedom); \
         intervals widened by sqrt(chi2/dof); run `sagnac diagnose`",
        a.fit.chi2_per_dof, a.fit.dof
    )
}

fn print_table(a: &Analysis) -> Result<()> {
    let mut o = std::io::stdout().lock();
    let e = &a.estimates;
    writeln!(
        o,
        "{} samples, {:.1} s; fit chi2/dof {:.2}",
        a.samples, a.duration_s, a.fit.chi2_per_dof
    )?;
    if !a.fit.ok {
        writeln!(o, "WARNING: {}", misfit_message(a))?;
    }
    match &a.readout_filter {
        Some(f) => writeln!(
            o,
            "readout filter: {}{}, corner {:.4} Hz [{:.4}, {:.4}], delay {:.4} s",
            f.kind.name(),
            f.length
                .map_or(String::new(), |l| format!(" of {l} samples")),
            f.corner_hz,
            f.ci95[0],
            f.ci95[1],
            f.delay_s
        )?,
        None => writeln!(o, "readout filter: none found")?,
    }
    writeln!(o, "{:<32} {:<12} 95 % interval", "coefficient", "value")?;
    for (name, c) in [
        ("quantization Q, arcsec", &e.quantization_arcsec),
        ("angle random walk N, deg/sqrt(h)", &e.arw_dpsh),
        ("bias instability B, deg/h", &e.bias_instability_dph),
        ("rate random walk K, deg/h/sqrt(h)", &e.rrw_dphsh),
        ("rate ramp R, deg/h/h", &e.rate_ramp_dphh),
    ] {
        writeln!(o, "{name:<32} {}", fmt_coef(c))?;
    }
    writeln!(o)?;
    writeln!(
        o,
        "{:>12} {:>14} {:>14} {:>14}",
        "tau, s", "raw ADEV", "clean ADEV", "noise ADEV"
    )?;
    for p in &a.allan.raw {
        let find = |v: &[crate::allan::AllanPoint]| v.iter().find(|q| q.m == p.m).map(|q| q.dev);
        let f = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.6e}"));
        writeln!(
            o,
            "{:>12.4} {:>14} {:>14} {:>14}",
            p.tau_s,
            format!("{:.6e}", p.dev),
            f(find(&a.allan.clean)),
            f(find(&a.allan.noise))
        )?;
    }
    writeln!(o, "(Allan deviations in deg/h)")?;
    Ok(())
}
