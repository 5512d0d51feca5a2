//! A [`Recording`] from any [`Input`]: the samples in full, the temperature
//! when it carries information, and the sample rate and pulse weight the
//! input says (an MCAP recording's own), else the model's `[gyro]`.

use super::types::{DiagnoseError, Recording};
use crate::input::{Input, InputError, Unit};
use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::units;

/// Why a recording cannot be read for a diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Diagnose(#[from] DiagnoseError),
    /// A rate-output model read against pulse counts.
    #[error(
        "the model has [gyro] output = \"rate\" (a rate-output gyro), but the recording is read as pulse \
         counts: give the rate column and its unit, --column NAME --unit dps|dph|rad_s"
    )]
    RateModelOnCounts,
    /// A counter's model read against rate samples.
    #[error(
        "the model is a pulse counter ([gyro] output = \"counts\"), but --unit {unit} reads rate samples: \
         diagnose a rate recording with a model that has [gyro] output = \"rate\" and rate_lsb_dps, or give \
         the counts column with --unit counts"
    )]
    CountsModelOnRates { unit: &'static str },
    /// A pulse-count column with fractions.
    #[error("{}: the diagnosis of a pulse counter needs whole pulse counts; this column has fractions", path.display())]
    NotWhole { path: std::path::PathBuf },
    /// A recording cut or damaged: the diagnosis needs all of it.
    #[error("{}: unreadable from byte {offset} ({reason}): the diagnosis needs the whole recording", path.display())]
    Broken {
        path: std::path::PathBuf,
        offset: u64,
        reason: String,
    },
}

impl Recording {
    /// Read `input` whole for a diagnosis against `model`: a counter's pulse
    /// increments, or a rate-output gyro's rates (counted in the model's LSB
    /// when they lie on its grid, [`Recording::from_rates`]).
    pub fn read(input: &Input, model: &GyroModel) -> Result<Recording, ReadError> {
        let meta = input.meta();
        check_kind(model, meta.unit)?;
        let (all, report) = input.read_all()?;
        if let Some(b) = &report.break_at {
            return Err(ReadError::Broken {
                path: input.path().to_path_buf(),
                offset: b.offset,
                reason: b.reason.clone(),
            });
        }
        let rate = meta.sample_rate_hz.unwrap_or(model.gyro.sample_rate_hz);
        let temp_c = informative(all.temp_c);
        if model.gyro.output == OutputKind::Rate {
            let tau0 = 1.0 / rate;
            let rates_dps: Vec<f64> = all
                .values
                .iter()
                .map(|&v| meta.unit.to_dph(v, 0.0, tau0) / units::S_PER_H)
                .collect();
            let mut rec = Recording::from_rates(&rates_dps, temp_c, rate, model.gyro.rate_lsb_dps)?;
            rec.filled = all.filled;
            return Ok(rec);
        }
        if !meta.integral {
            return Err(ReadError::NotWhole {
                path: input.path().to_path_buf(),
            });
        }
        Ok(Recording {
            counts: all.counts,
            filled: all.filled,
            temp_c,
            sample_rate_hz: rate,
            pulse_arcsec: meta.pulse_arcsec.unwrap_or(model.gyro.pulse_arcsec),
            output: OutputKind::Counts,
        })
    }
}

/// A model and a recording of the same kind of sensor: a pulse counter and
/// pulse counts, or a rate-output gyro and a rate in `unit`.
pub fn check_kind(model: &GyroModel, unit: Unit) -> Result<(), ReadError> {
    match (model.gyro.output, unit) {
        (OutputKind::Rate, Unit::Counts) => Err(ReadError::RateModelOnCounts),
        (OutputKind::Counts, u) if u != Unit::Counts => {
            Err(ReadError::CountsModelOnRates { unit: u.name() })
        }
        _ => Ok(()),
    }
}

/// A temperature channel carrying no information (none, constant, or with a
/// value that is not finite) is dropped.
fn informative(t: Vec<f64>) -> Option<Vec<f64>> {
    let first = *t.first()?;
    (t.iter().all(|v| v.is_finite()) && t.iter().any(|v| *v != first)).then_some(t)
}
