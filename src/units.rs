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
}
