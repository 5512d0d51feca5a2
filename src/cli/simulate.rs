//! `sagnac simulate`: run the gyro simulator on a model file and write the pulse
//! stream (CSV now; binary frames and MCAP once those writers are wired in).

use std::fs::File;
use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};

use crate::model::{GyroModel, Simulator, sim};

/// Output format of `sagnac simulate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SimFormat {
    /// CSV: header `counts` (plus `temp_c` with a thermal model), one row per sample.
    Csv,
    /// Binary gyro frames (not wired yet).
    Frames,
    /// MCAP recording (not wired yet).
    Mcap,
}

/// Simulate a gyro from a model file.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Gyro model (TOML), e.g. config/paper_gyro.toml.
    #[arg(long)]
    pub model: PathBuf,
    /// Run length, seconds.
    #[arg(long)]
    pub duration_s: f64,
    /// RNG seed (same model + seed = identical output).
    #[arg(long)]
    pub seed: u64,
    /// Output file ("-" = stdout).
    #[arg(long)]
    pub out: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = SimFormat::Csv)]
    pub format: SimFormat,
}

/// Run `sagnac simulate`.
pub fn run(args: SimulateArgs) -> anyhow::Result<()> {
    match args.format {
        SimFormat::Csv => {}
        SimFormat::Frames => bail!(
            "--format frames is not wired yet (the frame encoder is merged later); use --format csv"
        ),
        SimFormat::Mcap => bail!(
            "--format mcap is not wired yet (the MCAP writer is merged later); use --format csv"
        ),
    }
    let model = GyroModel::load(&args.model).context("loading the gyro model")?;
    let mut simulator = Simulator::new(&model, args.seed, Some(args.duration_s))
        .with_context(|| format!("setting up the simulator for {}", args.model.display()))?;
    let rows = if args.out.as_os_str() == "-" {
        sim::write_csv(&mut simulator, std::io::stdout().lock())
    } else {
        let file =
            File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
        sim::write_csv(&mut simulator, file)
    }
    .with_context(|| format!("writing {}", args.out.display()))?;
    tracing::debug!(rows, "simulate: done");
    Ok(())
}
