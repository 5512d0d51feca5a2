//! Noise models: IEEE 952 terms and their Allan signatures, estimation and
//! simulation of the gyro (the diagnosis, which also runs the pipeline, is
//! [`crate::diagnose`]).
//!
//! * [`terms`]: the noise-term library. Each term (quantization, ARW, bias
//!   instability, RRW, rate ramp, and the catalog terms Gauss-Markov, sinusoid,
//!   random telegraph) knows its IEEE 952 coefficient in user units, its one-sided
//!   rate PSD and its closed-form Allan variance. The estimator fits these curves;
//!   the diagnosis ([`crate::diagnose`]) prints their physical explanations.
//! * [`config`]: the gyro model file (TOML): sample rate, pulse weight, input rate,
//!   the noise coefficients and an optional thermal profile. Parsed strictly
//!   (unknown keys are errors), validated, and serialisable back to TOML.
//! * [`sim`]: the streaming gyro simulator: integrates the true rate into a true
//!   angle, adds the white dither residual and quantises it with a cumulative
//!   pulse counter, exactly as an RLG readout does.
//!
//! * [`filter`]: readout filters (moving average, first order) that a sensor's
//!   electronics apply to the rate before output, with their exact responses.
//! * [`wvar`], [`fit`], [`estimate`]: automatic estimation of the IEEE 952
//!   coefficients from the wavelet variances and Allan curves, with model
//!   selection and profile-likelihood intervals; [`baseline`] holds the
//!   estimators users have today, for comparison.
//!
//! Units inside: angles in arcsec, rates in arcsec/s (= deg/h), times in s; see
//! [`crate::units`]. Allan variances are in (arcsec/s)^2 = (deg/h)^2.

pub mod baseline;
pub mod config;
pub mod estimate;
pub mod filter;
pub mod fit;
pub mod resonance;
pub mod sim;
pub mod spec;
pub mod spectrum;
pub mod terms;
pub mod wvar;

use std::path::PathBuf;

/// Errors of the model layer (model files, term parameters, simulation output).
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The model file could not be read.
    #[error("cannot read model file {path}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax error, unknown key, or a value of the wrong type.
    #[error("{origin}:{line}:{column}: {message}")]
    Parse {
        origin: String,
        line: usize,
        column: usize,
        message: String,
    },
    /// A value is out of its physical range (names the key and the value).
    #[error("{prefix}{key} = {value}: {reason}", prefix = origin_prefix(.origin))]
    Invalid {
        origin: Option<String>,
        key: String,
        value: String,
        reason: String,
    },
    /// The model could not be written back as TOML.
    #[error("cannot serialise the model to TOML: {0}")]
    Serialize(String),
    /// Writing simulator output failed.
    #[error("cannot write simulator output")]
    Write(#[source] std::io::Error),
}

fn origin_prefix(origin: &Option<String>) -> String {
    match origin {
        Some(o) => format!("{o}: "),
        None => String::new(),
    }
}

impl ModelError {
    /// An [`ModelError::Invalid`] without a file origin.
    pub fn invalid(
        key: impl Into<String>,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        ModelError::Invalid {
            origin: None,
            key: key.into(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// Attach a file name to an `Invalid` error (other variants are returned unchanged).
    pub fn with_origin(self, origin: impl Into<String>) -> Self {
        match self {
            ModelError::Invalid {
                key, value, reason, ..
            } => ModelError::Invalid {
                origin: Some(origin.into()),
                key,
                value,
                reason,
            },
            other => other,
        }
    }
}

pub use config::GyroModel;
pub use sim::Simulator;
pub use terms::Term;
