//! Seeded sample messages for the sink tests (every channel, every event kind).

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::model::estimate::{Coefficient, NoiseEstimates};
use sagnac::model::spec::{CoefficientVerdict, Verdict};
use sagnac::quality::davar::Stationarity;
use sagnac::quality::{DataQuality, Interval, Outliers, StepFit, ThermalFit, Warmup};
use sagnac::recording::messages::{
    AllanCurve, AllanUpdate, EstimateUpdate, Event, EventKind, Gap, RateBatch, RawBatch,
    SinkMessage, SummaryUpdate, Timestamp, VerdictUpdate,
};

/// 2026-11-21T20:03:01Z, ns since the epoch.
pub const T0_NS: u64 = 1_795_291_381_000_000_000;
/// 1 kHz.
pub const DT_NS: u64 = 1_000_000;

/// A float with a random sign, mantissa and decimal exponent in [-12, 12]: the
/// kind of value that a lossy JSON float parser gets wrong in the last bit.
pub fn awkward_f64(rng: &mut ChaCha8Rng) -> f64 {
    let m: f64 = rng.random::<f64>() + 0.1;
    let e = rng.random_range(-12..=12);
    let s = if rng.random_bool(0.5) { -1.0 } else { 1.0 };
    s * m * 10f64.powi(e)
}

pub fn raw_batch(rng: &mut ChaCha8Rng, i: u64, len: usize) -> RawBatch {
    let counts: Vec<i64> = (0..len).map(|_| rng.random_range(-40..=40)).collect();
    let mut gaps = Vec::new();
    let mut next = 0u64;
    while rng.random_bool(0.3) && next <= len as u64 {
        let index = rng.random_range(next..=len as u64);
        gaps.push(Gap {
            index,
            lost: rng.random_range(1..5),
        });
        next = index + 1;
    }
    RawBatch {
        t0_ns: T0_NS + i * len as u64 * DT_NS,
        dt_ns: DT_NS,
        seq0: 1000 + i * len as u64,
        counts,
        gaps,
        temp_c: if rng.random_bool(0.8) {
            Some(25.0 + awkward_f64(rng).fract())
        } else {
            None
        },
        status: rng.random_range(0..4),
    }
}

pub fn rate_batch(rng: &mut ChaCha8Rng, i: u64, len: usize) -> RateBatch {
    RateBatch {
        t0_ns: T0_NS + i * len as u64 * DT_NS,
        dt_ns: DT_NS,
        values: (0..len).map(|_| awkward_f64(rng)).collect(),
    }
}

pub fn estimate(rng: &mut ChaCha8Rng, i: u64) -> EstimateUpdate {
    let mut coef = || {
        let v = awkward_f64(rng).abs();
        if rng.random_bool(0.7) {
            Coefficient {
                value: Some(v),
                ci95: Some([v * 0.9, v * 1.1]),
                upper95: None,
            }
        } else {
            Coefficient {
                value: None,
                ci95: None,
                upper95: Some(v),
            }
        }
    };
    EstimateUpdate {
        t_ns: T0_NS + i * 1_000_000_000,
        samples: 1000 * (i + 1),
        duration_s: (i + 1) as f64,
        estimates: NoiseEstimates {
            quantization_arcsec: coef(),
            arw_dpsh: coef(),
            bias_instability_dph: coef(),
            rrw_dphsh: coef(),
            rate_ramp_dphh: coef(),
        },
        data_quality: data_quality(i),
    }
}

/// The data-quality findings of estimate `i` (its own generator, so the other
/// messages of a stream do not depend on them): none for one in three, else
/// every kind of finding, some absent.
pub fn data_quality(i: u64) -> Option<DataQuality> {
    let mut rng = ChaCha8Rng::seed_from_u64(0xD0 ^ i);
    if i % 3 == 0 {
        return None;
    }
    let interval = |rng: &mut ChaCha8Rng| {
        let v = awkward_f64(rng);
        Interval {
            value: v,
            ci95: [v - v.abs() * 0.2, v + v.abs() * 0.3],
        }
    };
    let count = rng.random_range(0..20u64);
    Some(DataQuality {
        outliers: Outliers {
            count,
            at_s: (0..count).map(|_| rng.random_range(0.0..7200.0)).collect(),
            threshold_sigma: 6.0,
            excluded: rng.random_bool(0.8),
            excluded_count: rng.random_range(0..=count),
            excess_kurtosis: rng.random_bool(0.9).then(|| awkward_f64(&mut rng)),
            heavy_tailed_windows: rng.random_range(0..3),
        },
        warmup: rng.random_bool(0.5).then(|| Warmup {
            amplitude_dph: interval(&mut rng),
            tau_s: interval(&mut rng),
            handled: if i % 2 == 0 { "excluded" } else { "modelled" }.into(),
            excluded_s: if i % 2 == 0 { 420.0 } else { 0.0 },
        }),
        steps: (0..rng.random_range(0..3))
            .map(|_| StepFit {
                at_s: interval(&mut rng),
                amplitude_dph: interval(&mut rng),
            })
            .collect(),
        thermal: rng.random_bool(0.5).then(|| ThermalFit {
            bias_sensitivity_dph_per_c: interval(&mut rng),
            lag_s: interval(&mut rng),
            compensated: rng.random_bool(0.5),
            confounded_with_ramp: rng.random_bool(0.5),
        }),
        stationary: rng.random_bool(0.7).then(|| Stationarity {
            ok: rng.random_bool(0.5),
            test: "trend and outlying-window tests".into(),
            p_value: rng.random_range(0.0..1.0),
        }),
    })
}

pub fn summary(rng: &mut ChaCha8Rng, i: u64) -> SummaryUpdate {
    let lost = rng.random_range(0..3);
    SummaryUpdate {
        timestamp: Timestamp::from_ns(T0_NS + i * 100_000_000 + rng.random_range(0..1_000_000)),
        samples: 100,
        lost_samples: lost,
        raw_rate_dph: awkward_f64(rng),
        clean_rate_dph: awkward_f64(rng),
        temp_c: rng
            .random_bool(0.7)
            .then(|| 25.0 + awkward_f64(rng).fract()),
    }
}

pub fn allan(rng: &mut ChaCha8Rng, i: u64) -> AllanUpdate {
    let mut curves = BTreeMap::new();
    for ch in ["raw", "clean"] {
        let k = rng.random_range(0..12);
        let tau_s: Vec<f64> = (0..k).map(|j| 0.001 * 2f64.powi(j)).collect();
        let dev: Vec<f64> = (0..k).map(|_| awkward_f64(rng).abs()).collect();
        curves.insert(
            ch.to_string(),
            AllanCurve {
                ci_lo: dev.iter().map(|d| d * 0.8).collect(),
                ci_hi: dev.iter().map(|d| d * 1.25).collect(),
                n: (0..k).map(|j| 100_000 >> j).collect(),
                tau_s,
                dev,
            },
        );
    }
    AllanUpdate::new(T0_NS + i * 1_000_000_000, curves)
}

/// One event of each kind, in order, then random ones.
pub fn event(rng: &mut ChaCha8Rng, i: u64) -> Event {
    let kind = match i % 7 {
        0 => EventKind::Gap {
            seq: rng.random(),
            lost: rng.random_range(1..100),
        },
        1 => EventKind::Resync {
            byte_offset: rng.random(),
            skipped_bytes: rng.random_range(1..50),
        },
        2 => EventKind::CrcError {
            byte_offset: rng.random(),
        },
        3 => EventKind::StatusChange {
            from: rng.random(),
            to: rng.random(),
        },
        4 => EventKind::DeviceDisconnected {
            device: "/dev/ttyUSB0".into(),
            reason: "EOF \"quoted\" \u{e9}".into(),
        },
        5 => EventKind::DeviceReconnected {
            device: "/dev/ttyUSB0".into(),
        },
        _ => EventKind::BackpressureDrop {
            sink: "mcap".into(),
            dropped: rng.random_range(1..1000),
        },
    };
    Event {
        t_ns: T0_NS + i * 10_000_000,
        kind,
        gyro: None,
    }
}

/// An acceptance-test verdict: decided, undecided with a reason, bound-only terms.
pub fn verdict(rng: &mut ChaCha8Rng, i: u64) -> VerdictUpdate {
    let v = |k: u64| match k % 3 {
        0 => Verdict::Pass,
        1 => Verdict::Fail,
        _ => Verdict::Undecided,
    };
    let mut coefficients = BTreeMap::new();
    for (j, name) in ["arw_dpsh", "bias_instability_dph", "quantization_arcsec"]
        .into_iter()
        .enumerate()
    {
        let verdict = v(i + j as u64);
        let bound_only = rng.random_bool(0.3);
        coefficients.insert(
            name.to_string(),
            CoefficientVerdict {
                limit: awkward_f64(rng).abs().max(1e-9),
                verdict,
                estimate: (!bound_only).then(|| awkward_f64(rng)),
                bound: rng.random_bool(0.9).then(|| awkward_f64(rng)),
                lower: (!bound_only).then(|| awkward_f64(rng)),
                upper: rng.random_bool(0.9).then(|| awkward_f64(rng)),
                reason: (verdict == Verdict::Undecided)
                    .then(|| "more data needed: \"quoted\" \u{e9}".to_string()),
                decided_at_s: (verdict != Verdict::Undecided).then(|| rng.random_range(60.0..1e5)),
                eta_s: (verdict == Verdict::Undecided && rng.random_bool(0.5))
                    .then(|| rng.random_range(0.0..1e6)),
            },
        );
    }
    VerdictUpdate {
        t_ns: T0_NS + i * 10_000_000,
        verdict: v(i),
        confidence: 0.95,
        look: (i % 4 != 0).then_some(i as u32),
        z: rng.random_range(1.6..4.0),
        duration_s: rng.random_range(0.0..1e5),
        coefficients,
    }
}

/// A deterministic stream of `n` messages cycling over all eight channels.
pub fn stream(seed: u64, n: usize) -> Vec<SinkMessage> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n as u64)
        .map(|i| match i % 8 {
            0 => SinkMessage::Raw(raw_batch(&mut rng, i, 64)),
            1 => SinkMessage::Clean(rate_batch(&mut rng, i, 64)),
            2 => SinkMessage::Noise(rate_batch(&mut rng, i, 64)),
            3 => SinkMessage::Estimates(estimate(&mut rng, i)),
            4 => SinkMessage::Allan(allan(&mut rng, i)),
            5 => SinkMessage::Event(event(&mut rng, i / 8)),
            6 => SinkMessage::Verdict(verdict(&mut rng, i)),
            _ => SinkMessage::Summary(summary(&mut rng, i)),
        })
        .collect()
}

/// What a recording of `msgs` gives back: the messages with their rate values on
/// the 1e-3 deg/h grid of the recorder ([`SinkMessage::recorded`]).
pub fn recorded(msgs: &[SinkMessage]) -> Vec<SinkMessage> {
    msgs.iter().map(SinkMessage::recorded).collect()
}
