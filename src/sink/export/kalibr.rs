//! Kalibr's IMU noise model (`imu.yaml`), from the IEEE 952 / 1293
//! coefficients of each axis of an analysis.
//!
//! Kalibr's white-noise density and random walk are the continuous-time
//! densities of the white noise and of the bias's random walk: exactly the
//! ARW / VRW and RRW / acceleration random walk coefficients in SI units.
//!
//! - `gyroscope_noise_density`, rad/s/sqrt(Hz) = rad/sqrt(s), from N in
//!   deg/sqrt(h): `N * pi/180 / 60` (sqrt(3600 s) = 60 sqrt(s));
//! - `gyroscope_random_walk`, rad/s^2/sqrt(Hz) = rad/s/sqrt(s), from K in
//!   deg/h/sqrt(h): `K * pi/180 / 3600 / 60` (deg/h to deg/s, then sqrt(h));
//! - `accelerometer_noise_density`, m/s^2/sqrt(Hz) = m/s/sqrt(s), from the
//!   VRW in m/s/sqrt(h): `VRW / 60`;
//! - `accelerometer_random_walk`, m/s^3/sqrt(Hz) = m/s^2/sqrt(s), from the
//!   acceleration random walk in m/s^2/sqrt(h): `/ 60`;
//! - `update_rate`, Hz: the sample rate; `rostopic`: the bag's topic.
//!
//! Each field is the largest of its axes (the conservative choice for a
//! filter: Kalibr has one number for three axes); the comments give every
//! axis with its interval. A coefficient the estimator did not find (only a
//! 95 % upper bound) is written as that bound, and the comment says so: a
//! bound is what a filter tuned on it should assume, but it is not a
//! measurement.

use std::f64::consts::PI;
use std::fmt::Write;

use super::ExportError;
use crate::model::estimate::{Coefficient, NoiseEstimates};
use crate::units::Quantity;

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

/// One axis of the analysis, for the Kalibr file.
#[derive(Debug, Clone, Copy)]
pub struct KalibrAxis<'a> {
    /// `gyro_x`, `accel_z`, `x`, ...
    pub label: &'a str,
    pub quantity: Quantity,
    /// Its coefficients, as the numerics name them (an accelerometer's in
    /// m/s^2 in the place of deg/h: [`crate::units::Quantity`]).
    pub estimates: &'a NoiseEstimates,
}

/// One Kalibr field: its name, the coefficient it comes from, the symbol
/// and unit of that coefficient as printed, the factor to the printed
/// unit, and the conversion to Kalibr's unit.
struct Field {
    name: &'static str,
    term: &'static str,
    sym: &'static str,
    unit: &'static str,
    quantity: Quantity,
    pick: fn(&NoiseEstimates) -> &Coefficient,
    to_printed: f64,
    to_kalibr: fn(f64) -> f64,
}

const FIELDS: [Field; 4] = [
    Field {
        name: "gyroscope_noise_density",
        term: "the ARW N",
        sym: "N",
        unit: "deg/sqrt(h)",
        quantity: Quantity::AngularRate,
        pick: |e| &e.arw_dpsh,
        to_printed: 1.0,
        to_kalibr: noise_density_from_arw,
    },
    Field {
        name: "gyroscope_random_walk",
        term: "the RRW K",
        sym: "K",
        unit: "deg/h/sqrt(h)",
        quantity: Quantity::AngularRate,
        pick: |e| &e.rrw_dphsh,
        to_printed: 1.0,
        to_kalibr: random_walk_from_rrw,
    },
    Field {
        name: "accelerometer_noise_density",
        term: "the VRW",
        sym: "VRW",
        unit: "m/s/sqrt(h)",
        quantity: Quantity::Acceleration,
        pick: |e| &e.arw_dpsh,
        to_printed: 3600.0,
        to_kalibr: |vrw_mpssh| vrw_mpssh / 60.0,
    },
    Field {
        name: "accelerometer_random_walk",
        term: "the acceleration random walk",
        sym: "AcRW",
        unit: "m/s^2/sqrt(h)",
        quantity: Quantity::Acceleration,
        pick: |e| &e.rrw_dphsh,
        to_printed: 1.0,
        to_kalibr: |rw_mps2sh| rw_mps2sh / 60.0,
    },
];

/// The lines of one field: its comments and `name: value`, the largest of
/// the axes of its quantity; nothing when no axis measures that quantity.
fn field_lines(f: &Field, axes: &[KalibrAxis], y: &mut String) -> Result<bool, ExportError> {
    let mut chosen: Option<(f64, String, &str)> = None;
    let mut notes = Vec::new();
    for a in axes.iter().filter(|a| a.quantity == f.quantity) {
        let c = (f.pick)(a.estimates).scaled(f.to_printed);
        let (v, note) = describe(basis(&c, f.name, f.term)?, f.sym, f.unit);
        notes.push(format!("{}: {note}", a.label));
        if chosen.as_ref().is_none_or(|(best, _, _)| v > *best) {
            chosen = Some((v, note, a.label));
        }
    }
    let Some((v, note, label)) = chosen else {
        return Ok(false);
    };
    if notes.len() == 1 {
        let _ = writeln!(y, "# {} {note}", f.name);
    } else {
        let _ = writeln!(
            y,
            "# {}: the largest of the {} axes (the conservative choice), {label}:",
            f.name,
            notes.len()
        );
        for n in &notes {
            let _ = writeln!(y, "#   {n}");
        }
    }
    let _ = writeln!(y, "{}: {}", f.name, yaml_float((f.to_kalibr)(v)));
    Ok(true)
}

/// The YAML text of the axes given (gyroscope and accelerometer fields for
/// the quantities present, a comment for an absent one). `source` names the
/// analysed recording in the header comment; `rostopic` is written when given.
pub fn imu_yaml_axes(
    axes: &[KalibrAxis],
    sample_rate_hz: f64,
    source: &str,
    rostopic: Option<&str>,
) -> Result<String, ExportError> {
    let mut y = String::new();
    let source = source.replace(['\n', '\r'], " ");
    let _ = writeln!(y, "# Kalibr IMU noise model (imu.yaml).");
    let _ = writeln!(
        y,
        "# Written by sagnac {} (`sagnac analyze --kalibr`) from {source}.",
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        y,
        "# Continuous-time densities, from the IEEE 952 / 1293 coefficients of a static recording:"
    );
    let _ = writeln!(
        y,
        "#   gyroscope_noise_density [rad/s/sqrt(Hz)]   = N [deg/sqrt(h)]   * pi/180 / 60"
    );
    let _ = writeln!(
        y,
        "#   gyroscope_random_walk   [rad/s^2/sqrt(Hz)] = K [deg/h/sqrt(h)] * pi/180 / 3600 / 60"
    );
    let _ = writeln!(
        y,
        "#   accelerometer_noise_density [m/s^2/sqrt(Hz)] = VRW [m/s/sqrt(h)] / 60"
    );
    let _ = writeln!(
        y,
        "#   accelerometer_random_walk   [m/s^3/sqrt(Hz)] = AcRW [m/s^2/sqrt(h)] / 60"
    );
    for pair in FIELDS.chunks(2) {
        let mut any = false;
        for f in pair {
            any |= field_lines(f, axes, &mut y)?;
        }
        if !any {
            let what = match pair[0].quantity {
                Quantity::AngularRate => "gyroscope",
                Quantity::Acceleration => "accelerometer",
            };
            let _ = writeln!(
                y,
                "# {what}_noise_density and {what}_random_walk absent: the input has no {what} axis"
            );
        }
    }
    match rostopic {
        Some(t) => {
            let _ = writeln!(y, "rostopic: {t}");
        }
        None => {
            let _ = writeln!(
                y,
                "# rostopic absent: not a ROS 2 bag (give --topic to write one)"
            );
        }
    }
    let _ = writeln!(y, "# update_rate: the sample rate, Hz");
    let rate = if sample_rate_hz.fract() == 0.0 && sample_rate_hz.abs() < 1e15 {
        format!("{sample_rate_hz:.1}")
    } else {
        yaml_float(sample_rate_hz)
    };
    let _ = writeln!(y, "update_rate: {rate}");
    Ok(y)
}

/// The YAML text of one gyro (see [`imu_yaml_axes`]).
pub fn imu_yaml(
    e: &NoiseEstimates,
    sample_rate_hz: f64,
    source: &str,
) -> Result<String, ExportError> {
    let axis = KalibrAxis {
        label: "gyro",
        quantity: Quantity::AngularRate,
        estimates: e,
    };
    imu_yaml_axes(&[axis], sample_rate_hz, source, None)
}

/// Write [`imu_yaml_axes`] to `path`.
pub fn write(
    path: &std::path::Path,
    axes: &[KalibrAxis],
    sample_rate_hz: f64,
    source: &str,
    rostopic: Option<&str>,
) -> Result<(), ExportError> {
    let y = imu_yaml_axes(axes, sample_rate_hz, source, rostopic)?;
    std::fs::write(path, y).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}
