//! What every JSON output says about itself, next to its numbers: the sagnac
//! version that wrote it, the input and the settings it was read with (sample
//! rate, pulse weight or rate unit, where each came from), and the unit of
//! every number.
//!
//! `sagnac analyze --json` and `sagnac diagnose --json` add these three keys to
//! their top-level object:
//!
//! ```json
//! "sagnac_version": "0.1.0",
//! "input": {"path": "run.bin", "format": "frames", "sample_rate_hz": 1000.0, "pulse_arcsec": 1.21,
//!           "origin": "given on the command line"},
//! "units": {"estimates.quantization_arcsec": "arcsec", "allan.*.tau_s": "s", ...}
//! ```
//!
//! The keys are those of a recording's `sagnac` metadata record
//! ([`crate::recording::meta`]: `sample_rate_hz`, `pulse_arcsec`, `rate_lsb_dps`,
//! `sagnac_version`), so a number means the same thing in every output.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;
use serde_json::Value;

/// The input of an output and the settings it was read with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InputSettings {
    /// The input file.
    pub path: String,
    /// Its format (`csv`, `frames`, `mcap`).
    pub format: String,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Angle of one counter pulse, arcsec (pulse-count input).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pulse_arcsec: Option<f64>,
    /// Weight of one rate LSB, deg/s (rate-sample recordings).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rate_lsb_dps: Option<f64>,
    /// The CSV column read.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub column: Option<String>,
    /// The unit of that column (`counts`, `dph`, `dps`, `rad_s`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// Where the rate and pulse weight came from.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub origin: Option<String>,
    /// The gyro model file compared with (`diagnose`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    /// The gyro read from a recording of several gyros (`--gyro`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro: Option<String>,
    /// A ROS 2 bag's Imu topic (`--topic`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub topic: Option<String>,
    /// A ROS 2 bag's stamps: messages, out of order, duplicates, holes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stamps: Option<crate::input::ros2::StampReport>,
}

impl InputSettings {
    pub fn new(path: &Path, format: &str, sample_rate_hz: f64, pulse_arcsec: Option<f64>) -> Self {
        InputSettings {
            path: path.display().to_string(),
            format: format.to_string(),
            sample_rate_hz,
            pulse_arcsec,
            rate_lsb_dps: None,
            column: None,
            unit: None,
            origin: None,
            model: None,
            gyro: None,
            topic: None,
            stamps: None,
        }
    }
}

/// The three keys a JSON output adds about itself.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Provenance {
    pub sagnac_version: String,
    pub input: InputSettings,
    /// Field (a dotted path, `*` for any key) -> unit.
    pub units: BTreeMap<String, String>,
}

impl Provenance {
    /// This sagnac's version, `input`, and `units`.
    pub fn new(input: InputSettings, units: Vec<(String, String)>) -> Self {
        Provenance {
            sagnac_version: env!("CARGO_PKG_VERSION").to_string(),
            input,
            units: units.into_iter().collect(),
        }
    }

    /// Add `sagnac_version`, `input` and `units` to the JSON object `v` (left
    /// alone if it is not an object).
    pub fn insert_into(&self, v: &mut Value) {
        if let (Some(obj), Ok(Value::Object(p))) = (v.as_object_mut(), serde_json::to_value(self)) {
            obj.extend(p);
        }
    }
}

/// An analysis's JSON as an accelerometer axis reads it: every field whose
/// name carries a gyro unit renamed to its accelerometer name and its numbers
/// rescaled ([`crate::units::accel_key`]); the Allan deviations are in m/s^2
/// as they are.
pub fn accel_view(v: &mut Value) {
    match v {
        Value::Object(map) => {
            let old = std::mem::take(map);
            for (k, mut val) in old {
                accel_view(&mut val);
                match crate::units::accel_key(&k) {
                    Some((key, f)) => {
                        scale(&mut val, f);
                        map.insert(key, val);
                    }
                    None => {
                        map.insert(k, val);
                    }
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(accel_view),
        _ => {}
    }
}

fn scale(v: &mut Value, f: f64) {
    if f == 1.0 {
        return;
    }
    match v {
        Value::Number(n) => {
            if let Some(x) = n.as_f64().and_then(|x| serde_json::Number::from_f64(x * f)) {
                *n = x;
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| scale(x, f)),
        Value::Object(m) => m.values_mut().for_each(|x| scale(x, f)),
        _ => {}
    }
}

/// A `units` list as an accelerometer axis has it: each dotted key's parts
/// renamed, each gyro unit replaced.
pub fn accel_units(units: Vec<(String, String)>) -> Vec<(String, String)> {
    units
        .into_iter()
        .map(|(k, u)| {
            let key: Vec<String> = k
                .split('.')
                .map(|part| {
                    crate::units::accel_key(part).map_or_else(|| part.to_string(), |(a, _)| a)
                })
                .collect();
            (key.join("."), crate::units::accel_unit(&u))
        })
        .collect()
}

/// The JSON of one axis's analysis: its numbers (an accelerometer's under
/// its own names), `spec`, and the provenance keys.
pub fn analysis_json(
    analysis: &crate::pipeline::Analysis,
    verdict: Option<&crate::model::spec::SpecReport>,
    settings: InputSettings,
    quantity: crate::units::Quantity,
) -> Result<serde_json::Value, serde_json::Error> {
    let mut value = serde_json::to_value(analysis)?;
    if let (Some(v), Some(obj)) = (verdict, value.as_object_mut()) {
        let mut spec = serde_json::to_value(v)?;
        // the verdict is decided on the handled record: say what was handled
        if let (Some(s), Some(dq)) = (spec.as_object_mut(), &analysis.data_quality) {
            s.insert("handled".into(), serde_json::to_value(handled_lines(dq))?);
        }
        obj.insert("spec".into(), spec);
    }
    let mut units = analysis_units();
    if quantity == crate::units::Quantity::Acceleration {
        accel_view(&mut value);
        units = accel_units(units);
    }
    Provenance::new(settings, units).insert_into(&mut value);
    Ok(value)
}

/// The findings the record was handled for (the verdict's basis).
pub fn handled_lines(dq: &crate::quality::DataQuality) -> Vec<String> {
    if dq.handled_anything() {
        dq.lines()
    } else {
        Vec::new()
    }
}

/// The units of `sagnac analyze --json` ([`crate::pipeline::Analysis`], and
/// `spec` with `--spec`).
pub fn analysis_units() -> Vec<(String, String)> {
    let mut u: Vec<(String, String)> = Vec::new();
    for (key, unit, _) in crate::units::COEFFICIENTS {
        u.push((format!("estimates.{key}"), unit.to_string()));
        u.push((format!("baselines.*.{key}"), unit.to_string()));
    }
    u.retain(|(k, _)| k != "baselines.*.rate_ramp_dphh");
    for (k, unit) in [
        ("samples", "samples"),
        ("duration_s", "s"),
        ("allan.*.tau_s", "s"),
        ("allan.*.dev, ci_lo, ci_hi", "deg/h"),
        ("allan.*.m", "samples (averaging factor)"),
        (
            "allan.*.n, edf",
            "1 (terms averaged, equivalent degrees of freedom)",
        ),
        ("fit.chi2_per_dof", "1 (chi-square per degree of freedom)"),
        ("readout_filter.corner_hz, ci95", "Hz"),
        ("readout_filter.delay_s", "s"),
        ("readout_filter.length", "samples"),
        (
            "spec.coefficients.*",
            "the unit the coefficient's name carries",
        ),
        ("spec.duration_s", "s"),
    ] {
        u.push((k.to_string(), unit.to_string()));
    }
    u
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accelerometer_view_renames_and_rescales() {
        let mut v = serde_json::json!({
            "estimates": {"arw_dpsh": {"value": 0.5, "ci95": [0.25, 0.75]},
                          "rrw_dphsh": {"value": null, "upper95": 2.0}},
            "data_quality": {"warmup": {"amplitude_dph": {"value": 0.5}, "tau_s": {"value": 300.0}}},
            "samples": 10
        });
        accel_view(&mut v);
        assert_eq!(
            v,
            serde_json::json!({
                "estimates": {"vrw_mpssh": {"value": 1800.0, "ci95": [900.0, 2700.0]},
                              "accel_rw_mps2sh": {"value": null, "upper95": 2.0}},
                "data_quality": {"warmup": {"amplitude_mps2": {"value": 0.5}, "tau_s": {"value": 300.0}}},
                "samples": 10
            })
        );
        let u = accel_units(vec![
            ("estimates.arw_dpsh".into(), "deg/sqrt(h)".into()),
            ("allan.*.dev, ci_lo, ci_hi".into(), "deg/h".into()),
        ]);
        assert_eq!(u[0], ("estimates.vrw_mpssh".into(), "m/s/sqrt(h)".into()));
        assert_eq!(u[1].1, "m/s^2");
    }

    #[test]
    fn added_to_an_object_only() {
        let mut input = InputSettings::new(Path::new("r.bin"), "frames", 1000.0, Some(1.21));
        input.origin = Some("given on the command line".into());
        let p = Provenance::new(input, vec![("duration_s".into(), "s".into())]);
        let mut v = serde_json::json!({"samples": 3});
        p.insert_into(&mut v);
        assert_eq!(
            v,
            serde_json::json!({
                "samples": 3,
                "sagnac_version": env!("CARGO_PKG_VERSION"),
                "input": {"path": "r.bin", "format": "frames", "sample_rate_hz": 1000.0, "pulse_arcsec": 1.21,
                          "origin": "given on the command line"},
                "units": {"duration_s": "s"},
            })
        );
        let mut not_object = serde_json::json!([1]);
        p.insert_into(&mut not_object);
        assert_eq!(not_object, serde_json::json!([1]));
        // every coefficient's unit is stated
        let units: BTreeMap<String, String> = analysis_units().into_iter().collect();
        assert_eq!(units["estimates.arw_dpsh"], "deg/sqrt(h)");
        assert_eq!(units["estimates.rate_ramp_dphh"], "deg/h/h");
    }
}
