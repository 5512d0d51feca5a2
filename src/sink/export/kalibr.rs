//! Kalibr's IMU noise model (`imu.yaml`), gyroscope fields, from the IEEE 952
//! coefficients of an analysis.
//!
//! Kalibr's white-noise density and random walk are the continuous-time
//! densities of the rate's white noise and of the bias's random walk: exactly
//! the ARW and RRW coefficients in SI units.
//!
//! - `gyroscope_noise_density`, rad/s/sqrt(Hz) = rad/sqrt(s), from N in
//!   deg/sqrt(h): `N * pi/180 / 60` (sqrt(3600 s) = 60 sqrt(s));
//! - `gyroscope_random_walk`, rad/s^2/sqrt(Hz) = rad/s/sqrt(s), from K in
//!   deg/h/sqrt(h): `K * pi/180 / 3600 / 60` (deg/h to deg/s, then sqrt(h));
//! - `update_rate`, Hz: the sample rate.
//!
//! A coefficient the estimator did not find (only a 95 % upper bound) is
//! written as that bound, and the comment says so: a bound is what a filter
//! tuned on it should assume, but it is not a measurement.

use std::f64::consts::PI;
use std::fmt::Write;

use super::ExportError;
use crate::model::estimate::{Coefficient, NoiseEstimates};

/// N, deg/sqrt(h) -> rad/s/sqrt(Hz).
pub fn noise_density_from_arw(arw_dpsh: f64) -> f64 {
    arw_dpsh * PI / 180.0 / 60.0
}

/// K, deg/h/sqrt(h) -> rad/s^2/sqrt(Hz).
pub fn random_walk_from_rrw(rrw_dphsh: f64) -> f64 {
    rrw_dphsh * PI / 180.0 / 3600.0 / 60.0
}

/// A float YAML 1.1 readers (PyYAML, which Kalibr uses) take as a float: the
/// shortest round-trip digits, always with a point, and a signed exponent.
pub fn yaml_float(v: f64) -> String {
    let s = format!("{v:e}");
    let (mant, exp) = s.split_once('e').unwrap_or((&s, "0"));
    let mant = if mant.contains('.') {
        mant.to_string()
    } else {
        format!("{mant}.0")
    };
    let exp = if exp.starts_with('-') {
        exp.to_string()
    } else {
        format!("+{exp}")
    };
    format!("{mant}e{exp}")
}

/// Which of value or bound a field was written from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Basis {
    /// The estimate, with its 95 % interval if any.
    Estimate { value: f64, ci95: Option<[f64; 2]> },
    /// The 95 % upper bound (the term was not found).
    UpperBound(f64),
}

fn basis(c: &Coefficient, field: &'static str, term: &'static str) -> Result<Basis, ExportError> {
    match (c.value, c.upper95) {
        (Some(v), _) if v.is_finite() => Ok(Basis::Estimate {
            value: v,
            ci95: c.ci95,
        }),
        (_, Some(u)) if u.is_finite() => Ok(Basis::UpperBound(u)),
        _ => Err(ExportError::Missing { field, term }),
    }
}

fn describe(b: Basis, sym: &str, unit: &str) -> (f64, String) {
    match b {
        Basis::Estimate {
            value,
            ci95: Some([lo, hi]),
        } => (
            value,
            format!("from {sym} = {value} {unit} (95 % interval {lo} to {hi})"),
        ),
        Basis::Estimate { value, ci95: None } => (value, format!("from {sym} = {value} {unit}")),
        Basis::UpperBound(u) => (
            u,
            format!(
                "{sym} NOT FOUND: written from its 95 % upper bound {u} {unit} (a bound, not an estimate)"
            ),
        ),
    }
}

/// The YAML text. `source` names the analysed recording in the header comment.
pub fn imu_yaml(
    e: &NoiseEstimates,
    sample_rate_hz: f64,
    source: &str,
) -> Result<String, ExportError> {
    let (n, n_note) = describe(
        basis(&e.arw_dpsh, "gyroscope_noise_density", "the ARW N")?,
        "N",
        "deg/sqrt(h)",
    );
    let (k, k_note) = describe(
        basis(&e.rrw_dphsh, "gyroscope_random_walk", "the RRW K")?,
        "K",
        "deg/h/sqrt(h)",
    );
    let mut y = String::new();
    let source = source.replace(['\n', '\r'], " ");
    let _ = writeln!(
        y,
        "# Kalibr IMU noise model (imu.yaml), gyroscope fields only: add the accelerometer"
    );
    let _ = writeln!(y, "# fields and rostopic for a complete file.");
    let _ = writeln!(
        y,
        "# Written by sagnac {} (`sagnac analyze --kalibr`) from {source}.",
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        y,
        "# Continuous-time densities, from the IEEE 952 coefficients of a static recording:"
    );
    let _ = writeln!(
        y,
        "#   gyroscope_noise_density [rad/s/sqrt(Hz)]   = N [deg/sqrt(h)]   * pi/180 / 60"
    );
    let _ = writeln!(
        y,
        "#   gyroscope_random_walk   [rad/s^2/sqrt(Hz)] = K [deg/h/sqrt(h)] * pi/180 / 3600 / 60"
    );
    let _ = writeln!(y, "# gyroscope_noise_density {n_note}");
    let _ = writeln!(
        y,
        "gyroscope_noise_density: {}",
        yaml_float(noise_density_from_arw(n))
    );
    let _ = writeln!(y, "# gyroscope_random_walk {k_note}");
    let _ = writeln!(
        y,
        "gyroscope_random_walk: {}",
        yaml_float(random_walk_from_rrw(k))
    );
    let _ = writeln!(y, "# update_rate: the sample rate, Hz");
    let rate = if sample_rate_hz.fract() == 0.0 && sample_rate_hz.abs() < 1e15 {
        format!("{sample_rate_hz:.1}")
    } else {
        yaml_float(sample_rate_hz)
    };
    let _ = writeln!(y, "update_rate: {rate}");
    Ok(y)
}

/// Write [`imu_yaml`] to `path`.
pub fn write(
    path: &std::path::Path,
    e: &NoiseEstimates,
    sample_rate_hz: f64,
    source: &str,
) -> Result<(), ExportError> {
    let y = imu_yaml(e, sample_rate_hz, source)?;
    std::fs::write(path, y).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}
