//! Command-line interface: one file per subcommand, thin; the logic lives in the library.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub mod allan;
pub mod analyze;
mod analyze_axes;
pub(crate) mod analyze_out;
pub mod completions;
pub mod diagnose;
pub mod input_args;
pub mod progress;
pub mod report;
mod report_axes;
mod report_one;
pub mod run;
pub mod simulate;

#[derive(Debug, Parser)]
#[command(
    name = "sagnac",
    version,
    about = "Ring-laser-gyro bench testing: acquisition, wavelet QN removal, Allan variance, noise estimation"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Allan-family deviations (OADEV, ADEV, MDEV, HDEV, OHDEV, TOTDEV) of a file, with confidence intervals.
    Allan(allan::AllanArgs),
    /// Estimate QN, ARW, bias instability, RRW and rate ramp with 95 % intervals.
    Analyze(analyze::AnalyzeArgs),
    /// The acquisition daemon: serial gyro, replayed capture or simulated bench -> QN removal,
    /// Allan variance, live estimates -> MCAP recording and Prometheus metrics.
    Run(run::RunArgs),
    /// Simulate a gyro from a model file and write its pulse stream.
    Simulate(simulate::SimulateArgs),
    /// Compare a recording with its gyro model: locate the mismatch, name and fit the missing physics.
    Diagnose(diagnose::DiagnoseArgs),
    /// Analyse a recording and write a self-contained HTML report (inline SVG figures) and PNG figures.
    Report(report::ReportArgs),
    /// Print a shell completion script (bash, zsh or fish) to standard output.
    Completions(completions::CompletionsArgs),
}

/// Parse the command line, run, print the error chain and exit 2 on failure.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err}");
            for cause in err.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Allan(args) => allan::run(args),
        Command::Analyze(args) => analyze::run(args),
        Command::Run(args) => run::run(args),
        Command::Simulate(args) => simulate::run(args),
        Command::Diagnose(args) => diagnose::run(args),
        Command::Report(args) => report::run(args),
        Command::Completions(args) => completions::run(args),
    }
}

/// `text` and a newline on standard output: a closed pipe or a full disk is an
/// error naming standard output, not a panic (as `println!` would make it).
pub(crate) fn write_stdout(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush())
        .map_err(|e| anyhow::anyhow!("writing to standard output: {e}"))
}

/// Load a gyro model file, saying on stderr which of its keys have new names.
pub(crate) fn load_model(path: &std::path::Path) -> anyhow::Result<crate::model::GyroModel> {
    use anyhow::Context;
    let model = crate::model::GyroModel::load(path)
        .with_context(|| format!("loading the gyro model {}", path.display()))?;
    if let Ok(text) = std::fs::read_to_string(path) {
        for (old, new) in crate::keys::renamed_in(&text, crate::keys::MODEL_RENAMES) {
            eprintln!(
                "warning: {}",
                crate::keys::rename_warning(&path.display().to_string(), old, new)
            );
        }
    }
    Ok(model)
}

/// The directory an output file goes into (`.` for a bare name); an error
/// naming both when it is not an existing directory (nothing creates it).
pub(crate) fn output_dir(out: &std::path::Path) -> anyhow::Result<std::path::PathBuf> {
    let dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    if !dir.is_dir() {
        anyhow::bail!(
            "cannot write {}: {} is not an existing directory",
            out.display(),
            dir.display()
        );
    }
    Ok(dir)
}
