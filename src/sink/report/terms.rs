//! The IEEE 952 asymptotes of the report's Allan figure: each estimated term
//! as a power law of the Allan deviation in deg/h (= arcsec/s) against tau in
//! s, and their total, the square root of the sum of the term variances
//! (SEED.md: the variances of independent sources add).
//!
//! | term | slope | deviation | coefficient, unit |
//! |---|---|---|---|
//! | QN  | -1   | sqrt(3) Q / tau       | Q, arcsec |
//! | ARW | -1/2 | N / sqrt(tau)         | N, deg/sqrt(h) (x 60: arcsec/sqrt(s)) |
//! | BI  | 0    | 0.664 B (sqrt(2 ln2 / pi) B) | B, deg/h |
//! | RRW | +1/2 | K sqrt(tau / 3)       | K, deg/h/sqrt(h) (/ 60: arcsec/s/sqrt(s)) |
//! | RR  | +1   | R tau / sqrt(2)       | R, deg/h/h (/ 3600: arcsec/s^2) |
//!
//! The coefficient conversions are [`crate::units`]'; QN, ARW, RRW and RR
//! equal [`crate::model::Term::avar`]'s square roots exactly (a test checks
//! it), BI is the flicker floor (the plateau IEEE 952 reads B from).

use crate::model::estimate::NoiseEstimates;
use crate::units;

/// Which term.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Quantization,
    AngleRandomWalk,
    BiasInstability,
    RateRandomWalk,
    RateRamp,
}

/// One asymptote: `dev(tau) = scale * tau^slope`, deg/h.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Asymptote {
    pub kind: Kind,
    /// The coefficient in its customary unit.
    pub coefficient: f64,
    /// Allan-deviation slope on log-log axes.
    pub slope: f64,
    /// deg/h at tau = 1 s.
    pub scale: f64,
}

/// sqrt(2 ln 2 / pi), the flicker floor's factor (0.664).
pub const BI_FACTOR: f64 = 0.664_282_470_267_960_1;

impl Asymptote {
    /// The asymptote of `kind` for coefficient `c` (in the unit of [`Kind::unit`]).
    pub fn new(kind: Kind, c: f64) -> Asymptote {
        let (slope, scale) = match kind {
            Kind::Quantization => (-1.0, 3f64.sqrt() * c),
            Kind::AngleRandomWalk => (-0.5, units::dpsh_to_arcsec_per_sqrt_s(c)),
            Kind::BiasInstability => (0.0, BI_FACTOR * units::dph_to_arcsec_per_s(c)),
            Kind::RateRandomWalk => (0.5, units::dphsh_to_arcsec_per_s_sqrt_s(c) / 3f64.sqrt()),
            Kind::RateRamp => (1.0, units::dphh_to_arcsec_per_s2(c).abs() / 2f64.sqrt()),
        };
        Asymptote {
            kind,
            coefficient: c,
            slope,
            scale: units::arcsec_per_s_to_dph(scale),
        }
    }

    /// Allan deviation, deg/h, at `tau_s`.
    pub fn dev(&self, tau_s: f64) -> f64 {
        self.scale * tau_s.powf(self.slope)
    }

    /// The tau range inside `[tau_lo, tau_hi]` where the deviation is inside
    /// `[dev_lo, dev_hi]` (a power law crosses the box once), if any.
    pub fn clip(
        &self,
        (tau_lo, tau_hi): (f64, f64),
        (dev_lo, dev_hi): (f64, f64),
    ) -> Option<(f64, f64)> {
        if !(self.scale > 0.0) {
            return None;
        }
        let (mut a, mut b) = (tau_lo, tau_hi);
        if self.slope == 0.0 {
            return (self.scale >= dev_lo && self.scale <= dev_hi).then_some((a, b));
        }
        // tau where dev = y
        let at = |y: f64| (y / self.scale).powf(1.0 / self.slope);
        let (t1, t2) = (at(dev_lo), at(dev_hi));
        let (lo, hi) = if t1 < t2 { (t1, t2) } else { (t2, t1) };
        a = a.max(lo);
        b = b.min(hi);
        (a < b).then_some((a, b))
    }
}

impl Kind {
    /// Short name.
    pub fn abbrev(self) -> &'static str {
        match self {
            Kind::Quantization => "QN",
            Kind::AngleRandomWalk => "ARW",
            Kind::BiasInstability => "BI",
            Kind::RateRandomWalk => "RRW",
            Kind::RateRamp => "RR",
        }
    }
    /// Full name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Quantization => "quantization noise",
            Kind::AngleRandomWalk => "angle random walk",
            Kind::BiasInstability => "bias instability",
            Kind::RateRandomWalk => "rate random walk",
            Kind::RateRamp => "rate ramp",
        }
    }
    /// The coefficient's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            Kind::Quantization => "Q",
            Kind::AngleRandomWalk => "N",
            Kind::BiasInstability => "B",
            Kind::RateRandomWalk => "K",
            Kind::RateRamp => "R",
        }
    }
    /// The coefficient's unit.
    pub fn unit(self) -> &'static str {
        match self {
            Kind::Quantization => "arcsec",
            Kind::AngleRandomWalk => "deg/\u{221a}h",
            Kind::BiasInstability => "deg/h",
            Kind::RateRandomWalk => "deg/h/\u{221a}h",
            Kind::RateRamp => "deg/h\u{b2}",
        }
    }
    /// The accelerometer's name of the term, its symbol, its unit and the
    /// factor from the gyro-named coefficient ([`crate::units::ACCEL_COEFFICIENTS`]).
    pub fn accel(self) -> (&'static str, &'static str, &'static str, f64) {
        let i = Kind::ALL
            .iter()
            .position(|k| *k == self)
            .expect("one of ALL");
        let (_, _, unit, what, f) = crate::units::ACCEL_COEFFICIENTS[i];
        let sym = ["VQ", "VRW", "B", "AcRW", "AR"][i];
        (what, sym, unit, f)
    }
    /// The deviation formula (tau in s, deviation in deg/h).
    pub fn formula(self) -> &'static str {
        match self {
            Kind::Quantization => "\u{221a}3\u{b7}Q/\u{3c4}",
            Kind::AngleRandomWalk => "N/\u{221a}\u{3c4}",
            Kind::BiasInstability => "0.664\u{b7}B",
            Kind::RateRandomWalk => "K\u{b7}\u{221a}(\u{3c4}/3)",
            Kind::RateRamp => "R\u{b7}\u{3c4}/\u{221a}2",
        }
    }
    /// The slope as text.
    pub fn slope_text(self) -> &'static str {
        match self {
            Kind::Quantization => "\u{2212}1",
            Kind::AngleRandomWalk => "\u{2212}1/2",
            Kind::BiasInstability => "0",
            Kind::RateRandomWalk => "+1/2",
            Kind::RateRamp => "+1",
        }
    }
    pub const ALL: [Kind; 5] = [
        Kind::Quantization,
        Kind::AngleRandomWalk,
        Kind::BiasInstability,
        Kind::RateRandomWalk,
        Kind::RateRamp,
    ];
}

/// The asymptotes of the terms the estimator found (a value, not only a bound).
pub fn asymptotes(e: &NoiseEstimates) -> Vec<Asymptote> {
    let coefs = [
        e.quantization_arcsec.value,
        e.arw_dpsh.value,
        e.bias_instability_dph.value,
        e.rrw_dphsh.value,
        e.rate_ramp_dphh.value,
    ];
    Kind::ALL
        .iter()
        .zip(coefs)
        .filter_map(|(&k, c)| {
            c.filter(|c| c.is_finite() && *c != 0.0)
                .map(|c| Asymptote::new(k, c))
        })
        .collect()
}

/// The total model deviation, deg/h: the root of the summed variances.
pub fn total_dev(terms: &[Asymptote], tau_s: f64) -> f64 {
    terms
        .iter()
        .map(|t| t.dev(tau_s).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Term;

    #[test]
    fn asymptotes_are_the_ieee_terms_in_deg_per_hour() {
        // closed forms at tau = 4 s
        let t: f64 = 4.0;
        let q = Asymptote::new(Kind::Quantization, 0.35);
        assert!((q.dev(t) - 3f64.sqrt() * 0.35 / 4.0).abs() < 1e-15);
        // N = 0.001 deg/sqrt(h) = 0.06 arcsec/sqrt(s): 0.06 / 2 deg/h at 4 s
        let n = Asymptote::new(Kind::AngleRandomWalk, 0.001);
        assert!((n.dev(t) - 0.03).abs() < 1e-15);
        let b = Asymptote::new(Kind::BiasInstability, 0.01);
        assert!((b.dev(t) - 0.006642824702679601).abs() < 1e-15);
        assert!((BI_FACTOR - (2.0 * 2f64.ln() / std::f64::consts::PI).sqrt()).abs() < 1e-16);
        // K = 6 deg/h/sqrt(h) = 0.1 arcsec/s/sqrt(s): 0.1 sqrt(4/3)
        let k = Asymptote::new(Kind::RateRandomWalk, 6.0);
        assert!((k.dev(t) - 0.1 * (4.0f64 / 3.0).sqrt()).abs() < 1e-15);
        // R = 36 deg/h/h = 0.01 arcsec/s^2: 0.01 * 4 / sqrt(2)
        let r = Asymptote::new(Kind::RateRamp, 36.0);
        assert!((r.dev(t) - 0.04 / 2f64.sqrt()).abs() < 1e-15);
        // and they are the square roots of the model's own Allan variances
        for (a, term) in [
            (
                q,
                Term::Quantization {
                    quantization_arcsec: 0.35,
                },
            ),
            (n, Term::AngleRandomWalk { arw_dpsh: 0.001 }),
            (k, Term::RateRandomWalk { rrw_dphsh: 6.0 }),
            (
                r,
                Term::RateRamp {
                    rate_ramp_dphh: 36.0,
                },
            ),
        ] {
            for tau in [0.01, 1.0, 300.0] {
                let want = term.avar(tau).sqrt();
                assert!(
                    (a.dev(tau) / want - 1.0).abs() < 1e-12,
                    "{:?} at {tau}: {} vs {want}",
                    a.kind,
                    a.dev(tau)
                );
            }
        }
        // the total adds variances
        let tot = total_dev(&[q, n], t);
        assert!((tot - (q.dev(t).powi(2) + n.dev(t).powi(2)).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn clipping_keeps_the_part_inside_the_box() {
        let n = Asymptote::new(Kind::AngleRandomWalk, 1.0 / 60.0); // 1/sqrt(tau) deg/h
        // dev in [0.1, 1] <=> tau in [1, 100]
        let (a, b) = n.clip((0.01, 1e4), (0.1, 1.0)).unwrap();
        assert!((a - 1.0).abs() < 1e-12 && (b - 100.0).abs() < 1e-9);
        assert_eq!(n.clip((1e3, 1e4), (0.1, 1.0)), None);
        let bi = Asymptote::new(Kind::BiasInstability, 1.0);
        assert_eq!(bi.clip((1.0, 10.0), (0.1, 1.0)), Some((1.0, 10.0)));
        assert_eq!(bi.clip((1.0, 10.0), (0.7, 1.0)), None);
    }
}
