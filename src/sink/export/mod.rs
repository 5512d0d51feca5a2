//! Files for other tools, from an analysis:
//!
//! - [`kalibr`]: the gyroscope fields of Kalibr's `imu.yaml`, converted from
//!   the IEEE 952 coefficients, each conversion written out in a comment;
//! - [`allan_csv`]: Allan curves as CSV (`tau_s, dev, ci_lo, ci_hi, edf, n`,
//!   units in the column names), one curve or the raw/clean/noise channels.

pub mod allan_csv;
pub mod kalibr;

use std::path::PathBuf;

/// Errors of the exporters.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("writing {}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("writing {}", path.display())]
    Csv { path: PathBuf, source: csv::Error },
    /// A value the export needs that the analysis neither estimated nor bounded.
    #[error(
        "{field} cannot be written: the analysis gives neither a value nor an upper bound of {term}"
    )]
    Missing {
        field: &'static str,
        term: &'static str,
    },
}
