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

use anyhow::{Result, bail};
use clap::Args;

use super::input_args::InputArgs;
use super::report_one::one;
use crate::input::Input;

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
