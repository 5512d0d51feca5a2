//! Allan curves as CSV (RFC 4180, the `csv` crate): one row per averaging
//! time, columns `tau_s, dev, ci_lo, ci_hi, edf, n` with the deviation's unit
//! in the column names (`dev_dph` for deg/h); for an analysis a first
//! `channel` column says `raw`, `clean` or `noise`. Numbers are written with
//! the shortest digits that read back to the same f64.

use std::path::Path;

use super::ExportError;
use crate::allan::AllanPoint;
use crate::pipeline::AllanCurves;

/// The header for a deviation in `unit` (a name suffix: `dph`, `pulse_per_s`, ...).
pub fn header(unit: &str, channel: bool) -> Vec<String> {
    let mut h: Vec<String> = Vec::new();
    if channel {
        h.push("channel".into());
    }
    h.push("tau_s".into());
    for c in ["dev", "ci_lo", "ci_hi"] {
        h.push(format!("{c}_{unit}"));
    }
    h.push("edf".into());
    h.push("n".into());
    h
}

fn record(channel: Option<&str>, p: &AllanPoint) -> Vec<String> {
    let mut r = Vec::with_capacity(7);
    if let Some(c) = channel {
        r.push(c.to_string());
    }
    r.push(format!("{:e}", p.tau_s));
    r.push(format!("{:e}", p.dev));
    r.push(format!("{:e}", p.ci_lo));
    r.push(format!("{:e}", p.ci_hi));
    r.push(format!("{:e}", p.edf));
    r.push(p.n.to_string());
    r
}

fn write_rows<'a>(
    path: &Path,
    unit: &str,
    channel: bool,
    rows: impl Iterator<Item = (Option<&'a str>, &'a AllanPoint)>,
) -> Result<(), ExportError> {
    let err = |source| ExportError::Csv {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    w.write_record(header(unit, channel)).map_err(err)?;
    for (c, p) in rows {
        w.write_record(record(c, p)).map_err(err)?;
    }
    w.flush().map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// One curve, its deviation in `unit`.
pub fn write_curve(path: &Path, points: &[AllanPoint], unit: &str) -> Result<(), ExportError> {
    write_rows(path, unit, false, points.iter().map(|p| (None, p)))
}

/// The three channels of an analysis (deg/h), raw then clean then noise.
pub fn write_channels(path: &Path, curves: &AllanCurves) -> Result<(), ExportError> {
    let rows = [
        ("raw", &curves.raw),
        ("clean", &curves.clean),
        ("noise", &curves.noise),
    ]
    .into_iter()
    .flat_map(|(c, pts)| pts.iter().map(move |p| (Some(c), p)));
    write_rows(path, "dph", true, rows)
}
