//! The noise-term library against independent references: SciPy golden values
//! (scripts/golden-model-terms.py -> tests/data/model_terms_golden.csv), numerical
//! integration of each term's PSD times the Allan transfer function, and known
//! closed-form features (plateau, peaks, limits).

use std::f64::consts::{LN_2, PI};

use sagnac::model::terms::{
    self, FlickerBank, Term, ci, cin, counter_readout_avar, flicker_avar, flicker_integral,
    gauss_markov_avar,
};

fn golden(kind: &str) -> Vec<(f64, f64)> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/model_terms_golden.csv");
    let text =
        std::fs::read_to_string(&path).expect("golden file (run scripts/golden-model-terms.py)");
    let rows: Vec<(f64, f64)> = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("kind"))
        .filter_map(|l| {
            let mut it = l.split(',');
            (it.next()? == kind).then(|| {
                (
                    it.next().unwrap().parse().unwrap(),
                    it.next().unwrap().parse().unwrap(),
                )
            })
        })
        .collect();
    assert!(rows.len() >= 8, "too few golden rows for {kind}");
    rows
}

// 10-point Gauss-Legendre on [-1, 1].
const GL_X: [f64; 5] = [
    0.148_874_338_981_631_2,
    0.433_395_394_129_247_2,
    0.679_409_568_299_024_4,
    0.865_063_366_688_984_5,
    0.973_906_528_517_171_7,
];
const GL_W: [f64; 5] = [
    0.295_524_224_714_752_9,
    0.269_266_719_309_996_3,
    0.219_086_362_515_982,
    0.149_451_349_150_580_6,
    0.066_671_344_308_688_1,
];

fn gl(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut s = 0.0;
    for i in 0..5 {
        s += GL_W[i] * (f(c - h * GL_X[i]) + f(c + h * GL_X[i]));
    }
    s * h
}

/// `integral_{x_lo}^{x_hi} g(x) dx` on panels of width <= pi/8 (g oscillates like sin^4 x),
/// with logarithmic panels (20 per decade) from max(x_lo, 1e-14) up to pi/8 so that PSD
/// corners at tiny x are resolved (the integrand is O(x) or O(1) near 0: the part below
/// 1e-14 is negligible).
fn integrate_panels(g: &impl Fn(f64) -> f64, x_lo: f64, x_hi: f64) -> f64 {
    let first = PI / 8.0;
    if x_lo < first {
        let a = x_lo.max(1e-14);
        let b = first.min(x_hi);
        let decades = (b / a).log10();
        let n = ((decades * 20.0).ceil() as usize).max(1);
        let r = (b / a).powf(1.0 / n as f64);
        let mut s = 0.0;
        let mut lo = a;
        for _ in 0..n {
            let hi = lo * r;
            s += gl(g, lo, hi.min(b));
            lo = hi;
        }
        return if x_hi <= first {
            s
        } else {
            s + integrate_panels(g, first, x_hi)
        };
    }
    let n = (((x_hi - x_lo) / (PI / 8.0)).ceil() as usize).max(1);
    let w = (x_hi - x_lo) / n as f64;
    (0..n)
        .map(|i| gl(g, x_lo + i as f64 * w, x_lo + (i + 1) as f64 * w))
        .sum()
}

/// AVAR(tau) = int S(f) 2 sin^4(pi f tau)/(pi f tau)^2 df, in x = pi f tau, for f in
/// [f_lo, f_hi] (f_hi may be infinite: beyond x = 2e4 pi, sin^4 is replaced by its
/// mean 3/8 and the smooth remainder integrated on logarithmic panels).
fn avar_from_psd(psd: &impl Fn(f64) -> f64, tau: f64, f_lo: f64, f_hi: f64) -> f64 {
    let g = |x: f64| {
        let f = x / (PI * tau);
        let s = x.sin();
        psd(f) * 2.0 * s * s * s * s / (x * x) / (PI * tau)
    };
    let x_lo = PI * f_lo * tau;
    let x_cut = 2.0e4 * PI;
    let x_hi = PI * f_hi * tau;
    if x_hi <= x_cut {
        return integrate_panels(&g, x_lo, x_hi);
    }
    let mut total = integrate_panels(&g, x_lo, x_cut);
    // tail: sin^4 -> 3/8, on ln x panels up to x_cut * 1e12
    let tail = |u: f64| {
        let x = u.exp();
        psd(x / (PI * tau)) * 0.75 / (x * x) / (PI * tau) * x
    };
    let (u0, u1) = (x_cut.ln(), (x_cut * 1e12).ln());
    let n = 400;
    let w = (u1 - u0) / n as f64;
    for i in 0..n {
        total += gl(&tail, u0 + i as f64 * w, u0 + (i + 1) as f64 * w);
    }
    total
}

#[test]
fn ci_matches_scipy() {
    for (x, v) in golden("ci") {
        let got = ci(x);
        // absolute 1e-14 (|Ci| <= 14 here; x = 0.6165 is a zero of Ci)
        assert!((got - v).abs() <= 1e-14, "Ci({x}) = {got}, scipy {v}");
        // Cin is Ci's entire companion: Ci = gamma + ln x - Cin
        let via_cin = terms::EULER_GAMMA + x.ln() - cin(x);
        assert!(
            (via_cin - v).abs() <= 1e-13,
            "Cin({x}) inconsistent: {via_cin} vs {v}"
        );
    }
}

#[test]
fn flicker_integral_matches_scipy_quadrature() {
    for (x, v) in golden("flickerG") {
        let got = flicker_integral(x);
        // SciPy quad panel sums: absolute 1e-13, and 1e-10 relative for the tiny values
        assert!(
            (got - v).abs() <= 1e-13 + 1e-10 * v.abs(),
            "G({x}) = {got}, scipy {v}"
        );
    }
    assert_eq!(flicker_integral(f64::INFINITY), LN_2);
    // continuity across the internal branch points (series / Cin / Ci), 1e-13
    for x in [1e-2, 0.5] {
        let (a, b) = (
            flicker_integral(x * (1.0 - 1e-15)),
            flicker_integral(x * (1.0 + 1e-15)),
        );
        assert!((a - b).abs() < 1e-13, "G jumps at {x}: {a} vs {b}");
    }
}

#[test]
fn gauss_markov_avar_matches_scipy_psd_integration() {
    for (tau, v) in golden("gm_avar") {
        let got = gauss_markov_avar(1.0, 1.0, tau);
        assert!(
            (got / v - 1.0).abs() < 1e-9,
            "GM avar({tau}) = {got}, scipy {v}"
        );
    }
}

#[test]
fn flicker_plateau_is_ieee_952() {
    // (2 ln 2 / pi) B^2, i.e. ADEV = 0.664 B, for every tau over an unbounded band
    let b = 0.002;
    for tau in [1e-3, 1.0, 1e3, 1e6] {
        let v = flicker_avar(b, tau, 0.0, f64::INFINITY);
        assert!(
            (v / (2.0 * LN_2 / PI * b * b) - 1.0).abs() < 1e-15,
            "tau {tau}: {v}"
        );
    }
    assert!(((2.0 * LN_2 / PI).sqrt() - 0.664).abs() < 5e-4);
}

#[test]
fn every_term_avar_equals_its_psd_through_the_allan_transfer() {
    let tau0 = 1e-3;
    let terms = [
        Term::AngleRandomWalk { arw_dpsh: 0.01 },
        Term::RateRandomWalk { rrw_dphsh: 0.3 },
        Term::GaussMarkov {
            sigma_dph: 0.008,
            tau_c_s: 90.0,
        },
        Term::GaussMarkov {
            sigma_dph: 1.0,
            tau_c_s: 0.002,
        },
        Term::RandomTelegraph {
            amplitude_dph: 0.003,
            mean_dwell_s: 300.0,
        },
        Term::BiasInstability {
            bias_instability_dph: 0.002,
            f_lo_hz: 1e-4,
            f_hi_hz: f64::INFINITY,
        },
        Term::BiasInstability {
            bias_instability_dph: 0.002,
            f_lo_hz: 1e-3,
            f_hi_hz: 500.0,
        },
        Term::BiasInstability {
            bias_instability_dph: 0.002,
            f_lo_hz: 0.0,
            f_hi_hz: 20.0,
        },
    ];
    for t in terms {
        let (f_lo, f_hi) = match t {
            Term::BiasInstability {
                f_lo_hz, f_hi_hz, ..
            } => (f_lo_hz, f_hi_hz),
            _ => (0.0, f64::INFINITY),
        };
        for tau in [1e-3, 0.05, 1.0, 37.0, 1000.0] {
            let closed = t.avar(tau);
            let numeric = avar_from_psd(&|f| t.psd(f, tau0), tau, f_lo, f_hi);
            // quadrature (10-point GL per pi/8 panel) and tail approximation: 1e-7 relative
            assert!(
                (numeric / closed - 1.0).abs() < 1e-7,
                "{} tau {tau}: closed {closed:e} vs PSD integral {numeric:e}",
                t.name()
            );
        }
    }
}

#[test]
fn quantization_psd_through_the_discrete_allan_transfer_gives_3q2_over_tau2() {
    // White angle noise seen as a sampled rate: its PSD lives on [0, 1/(2 tau0)] and the
    // Allan transfer of an m-sample average is 2 sin^4(pi f m tau0)/(m sin(pi f tau0))^2.
    let (q, tau0) = (0.35, 1e-3);
    let t = Term::Quantization {
        quantization_arcsec: q,
    };
    for m in [1usize, 2, 3, 10, 100] {
        let tau = m as f64 * tau0;
        let g = |f: f64| {
            let s = (PI * f * tau).sin();
            let d = m as f64 * (PI * f * tau0).sin();
            t.psd(f, tau0) * 2.0 * s * s * s * s / (d * d)
        };
        let n = 4000 * m;
        let w = 0.5 / tau0 / n as f64;
        let numeric: f64 = (0..n)
            .map(|i| gl(&g, i as f64 * w, (i + 1) as f64 * w))
            .sum();
        let closed = t.avar(tau);
        assert!((closed - 3.0 * q * q / (tau * tau)).abs() < 1e-12 * closed);
        assert!(
            (numeric / closed - 1.0).abs() < 1e-10,
            "m={m}: {numeric} vs {closed}"
        );
    }
}

#[test]
fn sinusoid_avar_is_its_spectral_line_through_the_transfer() {
    let t = Term::Sinusoid {
        amplitude_dph: 0.004,
        period_s: 600.0,
    };
    let (f0, p) = t.spectral_line().unwrap();
    for tau in [1.0, 100.0, 222.6, 599.0, 1500.0] {
        let x = PI * f0 * tau;
        let via_line = p * 2.0 * x.sin().powi(4) / (x * x);
        assert!((via_line / t.avar(tau) - 1.0).abs() < 1e-12);
    }
    // ADEV peak at tau = 0.3710 T (x = 1.16556 maximises sin^2 x / x), zero at tau = T
    let grid: Vec<f64> = (1..20000).map(|i| i as f64 * 0.05).collect();
    let best = grid
        .iter()
        .copied()
        .max_by(|a, b| t.avar(*a).total_cmp(&t.avar(*b)))
        .unwrap();
    assert!((best / 600.0 - 0.3710).abs() < 2e-4, "peak at {best}");
    assert!(t.avar(600.0) < 1e-30 * t.avar(best) + 1e-40);
}

#[test]
fn gauss_markov_limits_and_hump() {
    let (sigma, tc) = (0.008, 90.0);
    // tau << Tc: RRW-like 2 sigma^2 tau / (3 Tc); tau >> Tc: white-like 2 sigma^2 Tc / tau
    for tau in [1e-6, 1e-3, 0.01] {
        let v = gauss_markov_avar(sigma, tc, tau);
        let lim = 2.0 * sigma * sigma * tau / (3.0 * tc);
        // next order: relative correction -3u/4, u = tau/Tc
        assert!((v / lim - 1.0).abs() < tau / tc, "tau {tau}: {v} vs {lim}");
    }
    let far = 1e6;
    let v = gauss_markov_avar(sigma, tc, far);
    assert!((v / (2.0 * sigma * sigma * tc / far) - 1.0).abs() < 2e-4);
    // ADEV hump at about 1.89 Tc
    let grid: Vec<f64> = (1..40000).map(|i| i as f64 * 0.01).collect();
    let best = grid
        .iter()
        .copied()
        .max_by(|a, b| {
            gauss_markov_avar(sigma, tc, *a).total_cmp(&gauss_markov_avar(sigma, tc, *b))
        })
        .unwrap();
    assert!(
        (best / tc - 1.89).abs() < 0.01,
        "GM hump at {} Tc",
        best / tc
    );
}

#[test]
fn random_telegraph_is_gauss_markov_with_half_the_dwell() {
    let rtn = Term::RandomTelegraph {
        amplitude_dph: 0.003,
        mean_dwell_s: 300.0,
    };
    let gm = Term::GaussMarkov {
        sigma_dph: 0.003,
        tau_c_s: 150.0,
    };
    for tau in [0.1, 10.0, 150.0, 1e4] {
        assert_eq!(rtn.avar(tau), gm.avar(tau));
        assert_eq!(rtn.psd(1.0 / tau, 1e-3), gm.psd(1.0 / tau, 1e-3));
    }
}

#[test]
fn ramp_rrw_arw_quantization_closed_forms_and_units() {
    // unit conversions via units.rs: 1 deg/sqrt(h) = 60 arcsec/sqrt(s), 1 deg/h/sqrt(h) = 1/60, 1 deg/h/h = 1/3600
    let tau = 7.0;
    assert!((Term::AngleRandomWalk { arw_dpsh: 1.0 }.avar(tau) - 3600.0 / tau).abs() < 1e-9);
    assert!((Term::RateRandomWalk { rrw_dphsh: 60.0 }.avar(tau) - tau / 3.0).abs() < 1e-12);
    assert!(
        (Term::RateRamp {
            rate_ramp_dphh: -3600.0
        }
        .avar(tau)
            - tau * tau / 2.0)
            .abs()
            < 1e-9
    );
    assert!(
        (Term::Quantization {
            quantization_arcsec: 0.35
        }
        .avar(tau)
            - 3.0 * 0.35 * 0.35 / 49.0)
            .abs()
            < 1e-15
    );
    // avar = coefficient^2 * unit_avar, and the grid versions agree with the scalar one
    let t = Term::GaussMarkov {
        sigma_dph: 0.008,
        tau_c_s: 90.0,
    };
    let taus = [1e-3, 0.1, 10.0, 1e3];
    let mut out = [0.0; 4];
    t.avar_into(&taus, &mut out);
    for (i, &tau) in taus.iter().enumerate() {
        assert_eq!(out[i], t.avar(tau));
        assert!((t.avar(tau) - 0.008f64.powi(2) * t.unit_avar(tau)).abs() <= 1e-18);
    }
    let both = [t, Term::AngleRandomWalk { arw_dpsh: 0.001 }];
    terms::total_avar_into(&both, &taus, &mut out);
    for (i, &tau) in taus.iter().enumerate() {
        assert!((out[i] - both[0].avar(tau) - both[1].avar(tau)).abs() < 1e-18);
    }
    assert_eq!(t.with_coefficient(0.5).coefficient(), 0.5);
    assert!(
        Term::GaussMarkov {
            sigma_dph: -1.0,
            tau_c_s: 1.0
        }
        .validate()
        .is_err()
    );
    assert!(
        Term::Sinusoid {
            amplitude_dph: 1.0,
            period_s: 0.0
        }
        .validate()
        .is_err()
    );
    assert!(
        !Term::Sinusoid {
            amplitude_dph: 1.0,
            period_s: 1.0
        }
        .explanation()
        .is_empty()
    );
}

fn max_rel_dev(bank: &FlickerBank, tau0: f64, tau_max: f64, f_lo: f64) -> f64 {
    let mut worst: f64 = 0.0;
    let mut tau = tau0;
    while tau <= tau_max {
        let ideal = flicker_avar(1.0, tau, f_lo, f64::INFINITY);
        worst = worst.max((bank.avar(tau) / ideal - 1.0).abs());
        tau *= 1.07;
    }
    worst
}

#[test]
fn flicker_bank_allan_curve_is_close_to_ideal_flicker() {
    // The simulator's flicker generator against the ideal B^2/(pi f) on [f_lo, inf).
    for (fs, f_lo) in [(1000.0, 1e-7), (100.0, 1e-7), (1000.0, 1e-5)] {
        let bank = FlickerBank::for_sample_rate(1.0, f_lo, fs).unwrap();
        let tau0 = 1.0 / fs;
        let d1 = max_rel_dev(&bank, tau0, 1e-4 / f_lo, f_lo);
        let d2 = max_rel_dev(&bank, tau0, 1e-3 / f_lo, f_lo);
        let d3 = max_rel_dev(&bank, tau0, 1e-2 / f_lo, f_lo);
        println!(
            "fs {fs} f_lo {f_lo}: max |bank/ideal - 1| = {d1:.2e} (tau <= 1e-4/f_lo), {d2:.2e} (1e-3/f_lo), {d3:.2e} (1e-2/f_lo)"
        );
        assert!(d1 < 7e-4, "{d1}");
        assert!(d2 < 4e-3, "{d2}");
        assert!(d3 < 3.5e-2, "{d3}");
        // PSD: within 0.3 % of 1/f on [1000 f_lo, Nyquist], 0.8 % on [100 f_lo, Nyquist]
        let psd_dev = |lo: f64| {
            let mut worst: f64 = 0.0;
            let mut f = lo;
            while f <= fs / 2.0 {
                worst = worst.max((bank.psd(f) * PI * f - 1.0).abs());
                f *= 1.01;
            }
            worst
        };
        let (p1, p2) = (psd_dev(1000.0 * f_lo), psd_dev(100.0 * f_lo));
        println!(
            "  PSD max |S pi f / B^2 - 1| = {p1:.2e} on [1000 f_lo, fs/2], {p2:.2e} on [100 f_lo, fs/2]"
        );
        assert!(p1 < 3e-3 && p2 < 8e-3, "{p1} {p2}");
        // corners at most 1.5 octaves apart from f_lo to 8 fs
        let n = bank.components().len();
        assert_eq!(
            n,
            ((8.0 * fs / f_lo).log2() / 1.5 - 1e-9).ceil() as usize + 1
        );
        assert!((bank.f_top_hz() / (8.0 * fs) - 1.0).abs() < 1e-15);
    }
}

#[test]
fn counter_readout_formula_limits() {
    let d = 1.21;
    // a dither residual of >= d/2 makes the counter error white: 3 Q^2 / tau^2, Q^2 = d^2/12 + sigma^2
    let sigma = 0.6 * d;
    for tau in [1e-3, 0.0123, 0.1, 1.0, 33.3] {
        let q2 = d * d / 12.0 + sigma * sigma;
        let v = counter_readout_avar(d, sigma, 12.3, tau);
        // residual sawtooth correlation exp(-4 pi^2 s^2) = 6.6e-7
        assert!(
            (v / (3.0 * q2 / (tau * tau)) - 1.0).abs() < 1e-5,
            "tau {tau}: {v}"
        );
    }
    // no dither, advance of half a pulse per tau: AVAR = 0.5 d^2/tau^2 = twice the white value
    let tau = 0.5 * d / 12.3;
    let v = counter_readout_avar(d, 0.0, 12.3, tau);
    assert!((v * tau * tau / (d * d) - 0.5).abs() < 1e-12, "{v}");
    // advance of a whole number of pulses per tau: the sawtooth cancels, AVAR = 0
    let v = counter_readout_avar(d, 0.0, 12.3, 3.0 * d / 12.3);
    assert!(v.abs() < 1e-12, "{v}");
    // the Fourier sum (small dither) joins the closed sawtooth form
    for tau in [0.01, 0.037, 0.25] {
        let a = counter_readout_avar(d, 0.0, 12.3, tau);
        let b = counter_readout_avar(d, 2e-5 * d, 12.3, tau);
        assert!(
            (a - b).abs() < 2e-4 * d * d / (tau * tau),
            "tau {tau}: {a} vs {b}"
        );
    }
}
