//! Unit conversions, all in one place.
//!
//! Internally the numerics work in SI-like "angle seconds": angles in arcseconds,
//! rates in arcsec/s (which equals deg/h), times in seconds. The IEEE 952
//! coefficients users read and write carry their customary units in their names:
//!
//! | name suffix | quantity | in arcsec / s units |
//! |---|---|---|
//! | `_arcsec` | quantization noise Q | arcsec |
//! | `_dpsh` | angle random walk N, deg/sqrt(h) | 60 arcsec/sqrt(s) |
//! | `_dph` | rate, bias instability B, deg/h | 1 arcsec/s |
//! | `_dphsh` | rate random walk K, deg/h/sqrt(h) | 1/60 arcsec/s/sqrt(s) |
//! | `_dphh` | rate ramp R, deg/h/h | 1/3600 arcsec/s^2 |

/// The IEEE 952 coefficients as every output names them (`analyze --json`,
/// MCAP `/gyro/estimates`, the live status line, the spec files): key, unit,
/// and what it is. The key carries the unit; this table says it in words for
/// the JSON outputs' `units` objects and the MCAP schema.
pub const COEFFICIENTS: [(&str, &str, &str); 5] = [
    ("quantization_arcsec", "arcsec", "quantization noise Q"),
    ("arw_dpsh", "deg/sqrt(h)", "angle random walk N"),
    ("bias_instability_dph", "deg/h", "bias instability B"),
    ("rrw_dphsh", "deg/h/sqrt(h)", "rate random walk K"),
    ("rate_ramp_dphh", "deg/h/h", "rate ramp R"),
];

/// What an axis measures: the numerics are the same for both; an
/// accelerometer's samples go through them in m/s^2 where a gyro's are in
/// deg/h (= arcsec/s), so "arcsec" reads m/s, and every output renames and
/// rescales its coefficients ([`ACCEL_COEFFICIENTS`], [`accel_key`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    AngularRate,
    Acceleration,
}

/// Standard gravity, m/s^2 (`--unit g`).
pub const STANDARD_GRAVITY_MPS2: f64 = 9.80665;

/// The accelerometer's IEEE 1293/2700 coefficients, each beside the gyro
/// coefficient it is computed as: (gyro key, accelerometer key, unit, what
/// it is, factor from the gyro-named value). With m/s^2 in the place of
/// deg/h: Q in "arcsec" is m/s; N in deg/sqrt(h) = 60 arcsec/sqrt(s) reads
/// 60 m/s/sqrt(s) = 3600 m/s/sqrt(h); B, K and R keep their numbers in
/// m/s^2, m/s^2/sqrt(h) and m/s^2/h.
pub const ACCEL_COEFFICIENTS: [(&str, &str, &str, &str, f64); 5] = [
    (
        "quantization_arcsec",
        "quantization_mps",
        "m/s",
        "velocity quantization",
        1.0,
    ),
    (
        "arw_dpsh",
        "vrw_mpssh",
        "m/s/sqrt(h)",
        "velocity random walk",
        3600.0,
    ),
    (
        "bias_instability_dph",
        "bias_instability_mps2",
        "m/s^2",
        "bias instability",
        1.0,
    ),
    (
        "rrw_dphsh",
        "accel_rw_mps2sh",
        "m/s^2/sqrt(h)",
        "acceleration random walk",
        1.0,
    ),
    (
        "rate_ramp_dphh",
        "accel_ramp_mps2h",
        "m/s^2/h",
        "acceleration ramp",
        1.0,
    ),
];

/// Other gyro-unit name suffixes and what they become on an accelerometer
/// axis (longest first): suffix, accelerometer suffix, factor.
const ACCEL_SUFFIXES: [(&str, &str, f64); 6] = [
    ("_dph_per_c", "_mps2_per_c", 1.0),
    ("_dphsh", "_mps2sh", 1.0),
    ("_dphh", "_mps2h", 1.0),
    ("_dpsh", "_mpssh", 3600.0),
    ("_dph", "_mps2", 1.0),
    ("_arcsec", "_mps", 1.0),
];

/// Gyro units and what they read on an accelerometer axis.
const ACCEL_UNITS: [(&str, &str); 6] = [
    ("deg/h/sqrt(h)", "m/s^2/sqrt(h)"),
    ("deg/h/h", "m/s^2/h"),
    ("deg/h/degC", "m/s^2/degC"),
    ("deg/sqrt(h)", "m/s/sqrt(h)"),
    ("deg/h", "m/s^2"),
    ("arcsec", "m/s"),
];

/// A field name as an accelerometer axis has it, and the factor its value
/// takes; `None` for a name that carries no gyro unit.
pub fn accel_key(key: &str) -> Option<(String, f64)> {
    if let Some((_, a, _, _, f)) = ACCEL_COEFFICIENTS.iter().find(|c| c.0 == key) {
        return Some((a.to_string(), *f));
    }
    ACCEL_SUFFIXES
        .iter()
        .find_map(|(g, a, f)| key.strip_suffix(g).map(|stem| (format!("{stem}{a}"), *f)))
}

/// A line of text written in a gyro's units (the data-quality findings) as
/// an accelerometer axis reads it: deg/h is m/s^2, arcsec is m/s.
pub fn accel_text(line: &str) -> String {
    line.replace("deg/h", "m/s^2").replace("arcsec", "m/s")
}

/// A gyro unit as an accelerometer axis reads it (other units unchanged).
pub fn accel_unit(unit: &str) -> String {
    ACCEL_UNITS
        .iter()
        .find(|(g, _)| *g == unit)
        .map_or_else(|| unit.to_string(), |(_, a)| a.to_string())
}

/// The unit of the coefficient `key` of [`COEFFICIENTS`].
pub fn coefficient_unit(key: &str) -> Option<&'static str> {
    COEFFICIENTS
        .iter()
        .find(|(k, _, _)| *k == key)
        .map(|(_, u, _)| *u)
}

/// Arcseconds in one degree.
pub const ARCSEC_PER_DEG: f64 = 3600.0;
/// Seconds in one hour.
pub const S_PER_H: f64 = 3600.0;

/// deg/h -> arcsec/s (identical numerically: 1 deg/h = 3600 arcsec / 3600 s).
#[inline]
pub fn dph_to_arcsec_per_s(rate_dph: f64) -> f64 {
    rate_dph
}
/// arcsec/s -> deg/h.
#[inline]
pub fn arcsec_per_s_to_dph(rate_arcsec_s: f64) -> f64 {
    rate_arcsec_s
}
/// deg/s -> deg/h.
#[inline]
pub fn dps_to_dph(rate_dps: f64) -> f64 {
    rate_dps * S_PER_H
}
/// rad/s -> deg/h.
#[inline]
pub fn rad_s_to_dph(rate_rad_s: f64) -> f64 {
    rate_rad_s.to_degrees() * S_PER_H
}
/// deg/sqrt(h) -> arcsec/sqrt(s): 1 deg/sqrt(h) = 3600 arcsec / 60 sqrt(s) = 60 arcsec/sqrt(s).
#[inline]
pub fn dpsh_to_arcsec_per_sqrt_s(arw_dpsh: f64) -> f64 {
    arw_dpsh * 60.0
}
/// arcsec/sqrt(s) -> deg/sqrt(h).
#[inline]
pub fn arcsec_per_sqrt_s_to_dpsh(arw: f64) -> f64 {
    arw / 60.0
}
/// deg/h/sqrt(h) -> arcsec/s/sqrt(s): 1 deg/h/sqrt(h) = (1 arcsec/s) / (60 sqrt(s)).
#[inline]
pub fn dphsh_to_arcsec_per_s_sqrt_s(rrw_dphsh: f64) -> f64 {
    rrw_dphsh / 60.0
}
/// arcsec/s/sqrt(s) -> deg/h/sqrt(h).
#[inline]
pub fn arcsec_per_s_sqrt_s_to_dphsh(rrw: f64) -> f64 {
    rrw * 60.0
}
/// deg/h/h -> arcsec/s^2.
#[inline]
pub fn dphh_to_arcsec_per_s2(ramp_dphh: f64) -> f64 {
    ramp_dphh / S_PER_H
}
/// arcsec/s^2 -> deg/h/h.
#[inline]
pub fn arcsec_per_s2_to_dphh(ramp: f64) -> f64 {
    ramp * S_PER_H
}
/// Pulse increments per sample -> rate in deg/h, given the pulse weight and sample period.
#[inline]
pub fn counts_to_dph(counts: f64, pulse_arcsec: f64, dt_s: f64) -> f64 {
    counts * pulse_arcsec / dt_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_md_conversions() {
        // SEED.md: 1 deg/sqrt(h) = 60 arcsec/sqrt(s); 1 deg/h = 1 arcsec/s.
        assert_eq!(dpsh_to_arcsec_per_sqrt_s(1.0), 60.0);
        assert_eq!(dph_to_arcsec_per_s(1.0), 1.0);
        // 1 deg/s = 3600 deg/h; pi rad/s = 180 deg/s.
        assert_eq!(dps_to_dph(1.0), 3600.0);
        assert!((rad_s_to_dph(std::f64::consts::PI) - 180.0 * 3600.0).abs() < 1e-6);
        // RRW: K^2 tau / 3 must be in arcsec^2/s^2 when K is in arcsec/s/sqrt(s).
        assert!((dphsh_to_arcsec_per_s_sqrt_s(60.0) - 1.0).abs() < 1e-15);
        assert!((dphh_to_arcsec_per_s2(3600.0) - 1.0).abs() < 1e-15);
        for x in [0.001, 0.37, 12.0] {
            assert!((arcsec_per_sqrt_s_to_dpsh(dpsh_to_arcsec_per_sqrt_s(x)) - x).abs() < 1e-15);
            assert!(
                (arcsec_per_s_sqrt_s_to_dphsh(dphsh_to_arcsec_per_s_sqrt_s(x)) - x).abs() < 1e-15
            );
            assert!((arcsec_per_s2_to_dphh(dphh_to_arcsec_per_s2(x)) - x).abs() < 1e-15);
        }
        // 1.21 arcsec pulses, 1 count per ms = 1210 arcsec/s = 1210 deg/h.
        assert!((counts_to_dph(1.0, 1.21, 1e-3) - 1210.0).abs() < 1e-9);
    }

    #[test]
    fn accelerometer_names_and_factors() {
        // white acceleration noise of 1e-3 m/s^2/sqrt(Hz) = 1e-3 m/s/sqrt(s) = 0.06 m/s/sqrt(h):
        // through the numerics in the place of deg/h it reads N = 1e-3 / 60 "deg/sqrt(h)"
        let (key, f) = accel_key("arw_dpsh").unwrap();
        assert_eq!(key, "vrw_mpssh");
        assert!((1e-3 / 60.0 * f - 0.06).abs() < 1e-15);
        assert_eq!(
            accel_key("amplitude_dph").unwrap(),
            ("amplitude_mps2".into(), 1.0)
        );
        assert_eq!(
            accel_key("bias_sensitivity_dph_per_c").unwrap().0,
            "bias_sensitivity_mps2_per_c"
        );
        assert_eq!(accel_key("rrw_dphsh").unwrap().0, "accel_rw_mps2sh");
        assert_eq!(accel_key("tau_s"), None);
        assert_eq!(accel_unit("deg/h/sqrt(h)"), "m/s^2/sqrt(h)");
        assert_eq!(accel_unit("s"), "s");
    }
}
