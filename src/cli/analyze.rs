//! `sagnac analyze`: automatic estimation of the IEEE 952 coefficients (QN,
//! ARW, bias instability, RRW, rate ramp) with 95 % intervals, from any input
//! [`crate::input::Input::open`] reads (CSV or text, a frame capture, an MCAP
//! recording; the format is found by content).
//!
//! Thin: reading is `input`, the numerics are `pipeline` (the same chain the
//! daemon runs live, driven by [`crate::pipeline::feed`]). `--spec SPEC.toml` adds the acceptance test's verdicts
//! (`spec` in the JSON, [`crate::model::spec`]): one look at the whole record.
//!
//! No silent defaults: a CSV file and a frame capture carry no sample rate and
//! no pulse weight, so `--sample-rate-hz` (and `--pulse-arcsec` for pulse counts) are
//! required; an MCAP recording carries both in its `sagnac` metadata record
//! ([`crate::recording::meta`]), and a flag that contradicts it is an error.
//!
//! The JSON (`--json`) also says how it was made ([`crate::sink::provenance`]):
//! `sagnac_version`, `input` (file, format, column and unit, sample rate and
//! pulse weight, where they came from) and `units`.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use super::analyze_axes::{self, AxesJob};
use super::analyze_out::{
    feed_input, print_quality, print_table, stream_notes, warn_about, write_kalibr, write_value,
};
use super::input_args::{self, InputArgs};
use crate::input::{Input, InputError};
use crate::model::spec::{Spec, SpecReport};
use crate::sink::export::kalibr::KalibrAxis;
use crate::sink::provenance::{self, analysis_json};
use crate::units::Quantity;

/// Arguments of `sagnac analyze`.
#[derive(Debug, Args)]
pub struct AnalyzeArgs {
    #[command(flatten)]
    pub input: InputArgs,
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

/// The export paths must name files in existing directories (checked before the analysis).
fn check_exports(args: &AnalyzeArgs) -> Result<()> {
    for (flag, p) in [("--kalibr", &args.kalibr), ("--allan-csv", &args.allan_csv)] {
        if let Some(p) = p {
            if p.is_dir() {
                bail!("{flag} {}: is a directory, not a file", p.display());
            }
            super::output_dir(p).with_context(|| format!("bad {flag}"))?;
        }
    }
    Ok(())
}

pub fn run(args: AnalyzeArgs) -> Result<()> {
    check_exports(&args)?;
    // a bad spec file fails before the (long) analysis
    let spec = args.spec.as_deref().map(Spec::load).transpose()?;
    let (input, rostopic) = open(&args)?;
    if !input.axes().is_empty() {
        for (flag, given) in [
            ("--spec", args.spec.is_some()),
            ("--allan-csv", args.allan_csv.is_some()),
        ] {
            if given {
                bail!(
                    "{flag} takes one axis: choose it with --gyro ({} has {})",
                    input.path().display(),
                    input.axes().join(", ")
                );
            }
        }
        let job = AxesJob {
            kalibr: args.kalibr.as_deref(),
            json: args.json.as_deref(),
            raw_statistics: args.input.raw_statistics,
            given_path: &args.input.input,
            rostopic: rostopic.as_deref(),
        };
        return analyze_axes::run(&job, &input);
    }
    let path = input.path().to_path_buf();
    let quantity = input.meta().unit.quantity();
    let fed = feed_input(&input, args.input.raw_statistics, None)?;
    for (kind, note) in stream_notes(&fed.report) {
        eprintln!("{kind}: {}: {note}", path.display());
    }
    let analysis = fed.analysis();
    if let Some(dq) = &analysis.data_quality {
        print_quality(dq, &path, quantity);
    }
    warn_about(&analysis, &path);
    let rate = fed.pipeline.config().sample_rate_hz;
    if let Some(out) = &args.kalibr {
        let label = input.meta().gyro.clone().unwrap_or_else(|| match quantity {
            Quantity::AngularRate => "gyro".into(),
            Quantity::Acceleration => "accel".into(),
        });
        let axis = KalibrAxis {
            label: &label,
            quantity,
            estimates: &analysis.estimates,
        };
        write_kalibr(out, &[axis], rate, &path, rostopic.as_deref())?;
    }
    if let Some(out) = &args.allan_csv {
        crate::sink::export::allan_csv::write_channels(out, &analysis.allan)
            .context("writing the Allan CSV")?;
    }
    let verdict = spec
        .as_ref()
        .map(|s| s.evaluate_fixed(&analysis.estimates, analysis.duration_s));
    match &args.json {
        Some(out) => {
            let mut settings = input_args::settings(&input, &args.input.input);
            settings.stamps = fed.report.stamps.clone();
            let mut value = analysis_json(&analysis, verdict.as_ref(), settings, quantity)?;
            if quantity == Quantity::Acceleration && verdict.is_some() {
                bail!("--spec holds gyro limits: it does not apply to an accelerometer axis");
            }
            write_value(out, &mut value)
        }
        None => {
            print_table(&analysis, quantity)?;
            if let Some(v) = &verdict {
                print_verdict(v, analysis.data_quality.as_ref())?;
            }
            Ok(())
        }
    }
}

/// Open the input, every axis of a multi-axis one unless `--gyro` picks
/// one; `--topic` on an input that is not a bag only names the Kalibr
/// file's `rostopic`. Returns the input and the rostopic.
fn open(args: &AnalyzeArgs) -> Result<(Input, Option<String>)> {
    let mut req = args.input.request();
    req.all_axes = true;
    // the one pass of the analysis checks the rest of the counts
    req.whole_on_first_samples = true;
    match Input::open(&args.input.input, &req) {
        Ok(input) => {
            let topic = input.meta().bag.as_ref().map(|b| b.topic.clone());
            Ok((input, topic))
        }
        Err(InputError::FlagNotApplicable {
            flag: "--topic", ..
        }) if args.kalibr.is_some() => {
            let topic = req.topic.take();
            Ok((Input::open(&args.input.input, &req)?, topic))
        }
        Err(e) => Err(e.into()),
    }
}

fn print_verdict(r: &SpecReport, dq: Option<&crate::quality::DataQuality>) -> Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(o)?;
    if let Some(dq) = dq.filter(|d| d.handled_anything()) {
        writeln!(
            o,
            "spec verdict on the handled record ({}):",
            provenance::handled_lines(dq).join("; ")
        )?;
    }
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
