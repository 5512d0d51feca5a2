//! The gyro model file: config/paper_gyro.toml parses, unknown keys and
//! out-of-range values are errors naming the key (and line / value), and the
//! model round-trips through TOML.

use sagnac::model::ModelError;
use sagnac::model::config::{GyroModel, ThermalParams};
use sagnac::model::terms::Term;

use crate::support::PAPER_GYRO;

const BASE: &str = r#"
[gyro]
sample_rate_hz = 1000.0
pulse_arcsec = 1.21
input_rate_dph = 12.3

[noise]
quantization_arcsec = 0.35
arw_dpsh = 0.001

[[noise.gauss_markov]]
sigma_dph = 0.008
tau_c_s = 90.0

[[noise.sinusoid]]
amplitude_dph = 0.004
period_s = 600.0

[thermal]
temp_c0 = 25.0
ramp_c_per_h = 0.5
bias_sensitivity_dph_per_c = 0.001
"#;

fn err_of(text: &str) -> String {
    match GyroModel::from_toml_str(text, "m.toml") {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn paper_gyro_parses_with_the_papers_numbers() {
    let m = GyroModel::load(std::path::Path::new(PAPER_GYRO)).unwrap();
    assert_eq!(m.gyro.sample_rate_hz, 1000.0);
    assert_eq!(m.gyro.pulse_arcsec, 1.21);
    assert_eq!(m.gyro.input_rate_dph, 12.3);
    assert_eq!(m.noise.quantization_arcsec, Some(0.35));
    assert_eq!(m.noise.arw_dpsh, Some(0.001));
    assert_eq!(m.noise.bias_instability_dph, Some(0.002));
    assert_eq!(m.noise.rrw_dphsh, Some(0.0));
    assert_eq!(m.noise.gauss_markov.len(), 1);
    assert_eq!(m.noise.sinusoid[0].period_s, 600.0);
    assert_eq!(m.noise.random_telegraph[0].mean_dwell_s, 300.0);
    assert!(m.thermal.is_none());
    // d/sqrt(12) = 0.349297..., dither residual sqrt(0.35^2 - 1.21^2/12) = 0.022181...
    assert!((m.counter_q_arcsec() - 0.349_297_2).abs() < 1e-6);
    assert!(
        (m.dither_sigma_arcsec() - 0.022_181).abs() < 1e-5,
        "{}",
        m.dither_sigma_arcsec()
    );
    // the term list: Q, ARW, BI, GM, sinusoid, RTN (zero RRW / ramp left out)
    let names: Vec<&str> = m.terms().iter().map(|t| t.name()).collect();
    assert_eq!(
        names,
        [
            "quantization",
            "arw",
            "bias_instability",
            "gauss_markov",
            "sinusoid",
            "random_telegraph"
        ]
    );
    assert_eq!(
        m.terms()[2],
        Term::BiasInstability {
            bias_instability_dph: 0.002,
            f_lo_hz: 1e-7,
            f_hi_hz: f64::INFINITY
        }
    );
}

#[test]
fn unknown_keys_are_errors_naming_key_and_line_at_every_level() {
    let cases = [
        ("[gyro]\n", "[gyro]\nsample_rate = 1.0\n", "sample_rate"),
        (
            "arw_dpsh = 0.001\n",
            "arw_dpsh = 0.001\narw = 0.001\n",
            "arw",
        ),
        (
            "sigma_dph = 0.008\n",
            "sigma_dph = 0.008\nsigma_dphh = 1.0\n",
            "sigma_dphh",
        ),
        (
            "period_s = 600.0\n",
            "period_s = 600.0\nphase_deg = 3.0\n",
            "phase_deg",
        ),
        (
            "temp_c0 = 25.0\n",
            "temp_c0 = 25.0\ntemp_c = 3.0\n",
            "temp_c",
        ),
    ];
    for (anchor, replacement, key) in cases {
        assert!(BASE.contains(anchor), "{anchor}");
        let text = BASE.replacen(anchor, replacement, 1);
        // 1-based line of the inserted key
        let line = text
            .lines()
            .position(|l| l.starts_with(&format!("{key} =")))
            .unwrap()
            + 1;
        let msg = err_of(&text);
        assert!(
            msg.contains(&format!("`{key}`")),
            "message does not name `{key}`: {msg}"
        );
        assert!(
            msg.starts_with(&format!("m.toml:{line}:")),
            "wrong line for {key}: {msg}"
        );
    }
    // an unknown table at the top level
    let msg = err_of(&format!("{BASE}\n[dither]\nx = 1\n"));
    assert!(msg.contains("`dither`"), "{msg}");
}

#[test]
fn out_of_range_values_name_key_and_value() {
    let cases = [
        (
            "sigma_dph = 0.008",
            "sigma_dph = -0.5",
            "noise.gauss_markov[0].sigma_dph = -0.5",
        ),
        (
            "period_s = 600.0",
            "period_s = 0.0",
            "noise.sinusoid[0].period_s = 0",
        ),
        (
            "tau_c_s = 90.0",
            "tau_c_s = -1",
            "noise.gauss_markov[0].tau_c_s = -1",
        ),
        ("arw_dpsh = 0.001", "arw_dpsh = nan", "noise.arw_dpsh = NaN"),
        ("arw_dpsh = 0.001", "arw_dpsh = inf", "noise.arw_dpsh = inf"),
        (
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 0.0",
            "gyro.sample_rate_hz = 0",
        ),
        (
            "pulse_arcsec = 1.21",
            "pulse_arcsec = -1.21",
            "gyro.pulse_arcsec = -1.21",
        ),
        ("temp_c0 = 25.0", "temp_c0 = -inf", "thermal.temp_c0 = -inf"),
        // finite but absurd values that would overflow or never finish
        (
            "pulse_arcsec = 1.21",
            "pulse_arcsec = 1e300",
            "gyro.pulse_arcsec = 1e300: must be in",
        ),
        (
            "sample_rate_hz = 1000.0",
            "sample_rate_hz = 1e12",
            "gyro.sample_rate_hz = 1e12: must be in",
        ),
        (
            "input_rate_dph = 12.3",
            "input_rate_dph = -1e200",
            "gyro.input_rate_dph = -1e200: must be in",
        ),
    ];
    for (from, to, expect) in cases {
        let msg = err_of(&BASE.replacen(from, to, 1));
        assert!(msg.starts_with("m.toml: "), "{msg}");
        assert!(msg.contains(expect), "expected `{expect}` in: {msg}");
    }
    // Q below the counter's own d/sqrt(12) is an error that says why
    let msg = err_of(&BASE.replacen("quantization_arcsec = 0.35", "quantization_arcsec = 0.3", 1));
    assert!(msg.contains("noise.quantization_arcsec = 0.3"), "{msg}");
    assert!(
        msg.contains("d/sqrt(12)") && msg.contains("0.349297"),
        "{msg}"
    );
    // a telegraph dwell far below the sample period (1 ms at 1 kHz)
    let tg = "[[noise.random_telegraph]]\namplitude_dph = 0.05\nmean_dwell_s = ";
    let msg = err_of(&format!("{BASE}\n{tg}1e-300\n"));
    assert!(
        msg.contains("noise.random_telegraph[0].mean_dwell_s = 1e-300")
            && msg.contains(">= 1e-5 s"),
        "{msg}"
    );
    GyroModel::from_toml_str(&format!("{BASE}\n{tg}1e-5\n"), "m.toml")
        .expect("1/100 sample is allowed");
    // a thermal sine without a period
    let msg = err_of(&BASE.replacen(
        "temp_c0 = 25.0",
        "temp_c0 = 25.0\nsine_amplitude_c = 0.3",
        1,
    ));
    assert!(msg.contains("thermal.sine_period_s"), "{msg}");
    // a wrong type is a parse error naming the key's line
    let text = BASE.replacen("arw_dpsh = 0.001", "arw_dpsh = \"small\"", 1);
    let line = text
        .lines()
        .position(|l| l.starts_with("arw_dpsh"))
        .unwrap()
        + 1;
    let msg = err_of(&text);
    assert!(msg.starts_with(&format!("m.toml:{line}:")), "{msg}");
}

#[test]
fn model_round_trips_through_toml() {
    let paper = GyroModel::load(std::path::Path::new(PAPER_GYRO)).unwrap();
    let mut models = vec![
        paper.clone(),
        GyroModel::from_toml_str(BASE, "base").unwrap(),
    ];
    let mut with_thermal = paper;
    with_thermal.thermal = Some(ThermalParams {
        temp_c0: 21.5,
        ramp_c_per_h: -0.25,
        sine_amplitude_c: 0.4,
        sine_period_s: Some(86_400.0),
        bias_sensitivity_dph_per_c: 0.0015,
        lag_s: 30.0,
    });
    with_thermal.noise.bias_instability_f_lo_hz = Some(3e-6);
    models.push(with_thermal);
    for m in models {
        let text = m.to_toml().unwrap();
        let back = GyroModel::from_toml_str(&text, "round-trip").unwrap();
        assert_eq!(back, m, "round trip changed the model; TOML was:\n{text}");
        assert!(text.contains("[[noise.gauss_markov]]"), "{text}");
    }
}

#[test]
fn minimal_model_defaults_and_missing_file() {
    let m = GyroModel::from_toml_str("[gyro]\nsample_rate_hz = 100\npulse_arcsec = 2.0\n", "min")
        .unwrap();
    assert_eq!(m.gyro.input_rate_dph, 0.0);
    assert_eq!(m.quantization_q_arcsec(), 2.0 / 12f64.sqrt());
    assert_eq!(m.dither_sigma_arcsec(), 0.0);
    assert_eq!(m.terms().len(), 1);
    let e = GyroModel::load(std::path::Path::new("/nonexistent/dir/model.toml")).unwrap_err();
    assert!(matches!(e, ModelError::Read { .. }));
    assert!(e.to_string().contains("/nonexistent/dir/model.toml"));
}

#[test]
fn thermal_terms_are_a_ramp_and_a_sinusoid() {
    let mut m = GyroModel::from_toml_str(BASE, "base").unwrap();
    m.noise.rate_ramp_dphh = Some(0.01);
    m.thermal.as_mut().unwrap().sine_amplitude_c = 0.2;
    m.thermal.as_mut().unwrap().sine_period_s = Some(3600.0);
    let terms = m.terms();
    // model ramp + thermal ramp (0.001 dph/C * 0.5 C/h), added linearly
    assert!(terms.contains(&Term::RateRamp {
        rate_ramp_dphh: 0.01 + 0.0005
    }));
    assert!(terms.contains(&Term::Sinusoid {
        amplitude_dph: 0.0002,
        period_s: 3600.0
    }));
}

/// `pulse_weight_arcsec`, the old name of `[gyro] pulse_arcsec`, still loads
/// (to the same model), `to_toml` writes the new name, and the command line
/// warns once per file.
#[test]
fn the_old_pulse_key_loads_and_the_new_one_is_written() {
    let new = "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\n[noise]\narw_dpsh = 0.001\n";
    let old = new.replace("pulse_arcsec", "pulse_weight_arcsec");
    let a = GyroModel::from_toml_str(new, "new").unwrap();
    let b = GyroModel::from_toml_str(&old, "old").unwrap();
    assert_eq!(a, b);
    let written = b.to_toml().unwrap();
    assert!(
        written.contains("pulse_arcsec = 1.21") && !written.contains("pulse_weight"),
        "{written}"
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.toml");
    std::fs::write(&path, &old).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args([
            "simulate",
            "--model",
            path.to_str().unwrap(),
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--out",
        ])
        .arg(dir.path().join("x.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        err.matches("`gyro.pulse_weight_arcsec` is now `gyro.pulse_arcsec`")
            .count(),
        1,
        "{err}"
    );
}

/// The warm-up, bias steps, spikes and the thermal lag: a model with all
/// four.
const TRANSIENTS: &str = "
[noise.warmup]
amplitude_dph = -0.05
tau_s = 900.0

[[noise.bias_step]]
at_s = 1800.0
amplitude_dph = 0.01

[[noise.bias_step]]
at_s = 2400.5
amplitude_dph = -0.004

[noise.spikes]
rate_per_h = 2.0
amplitude_dph = 5.0
";

fn with_transients() -> GyroModel {
    let text = format!("{BASE}{TRANSIENTS}").replace(
        "bias_sensitivity_dph_per_c = 0.001",
        "bias_sensitivity_dph_per_c = 0.001\nlag_s = 120.0",
    );
    GyroModel::from_toml_str(&text, "transients").unwrap()
}

#[test]
fn transients_parse_and_round_trip_through_toml() {
    let m = with_transients();
    let n = &m.noise;
    let w = n.warmup.as_ref().unwrap();
    assert_eq!((w.amplitude_dph, w.tau_s), (-0.05, 900.0));
    assert_eq!(n.bias_step.len(), 2);
    assert_eq!(
        (n.bias_step[1].at_s, n.bias_step[1].amplitude_dph),
        (2400.5, -0.004)
    );
    let sp = n.spikes.as_ref().unwrap();
    assert_eq!((sp.rate_per_h, sp.amplitude_dph), (2.0, 5.0));
    assert_eq!(m.thermal.as_ref().unwrap().lag_s, 120.0);
    let text = m.to_toml().unwrap();
    for key in [
        "[noise.warmup]",
        "[[noise.bias_step]]",
        "[noise.spikes]",
        "lag_s = 120.0",
    ] {
        assert!(text.contains(key), "{key} not written:\n{text}");
    }
    assert_eq!(
        GyroModel::from_toml_str(&text, "round-trip").unwrap(),
        m,
        "{text}"
    );
    // absent keys are absent terms, and are not written
    let base = GyroModel::from_toml_str(BASE, "base").unwrap();
    assert!(base.noise.warmup.is_none() && base.noise.bias_step.is_empty());
    assert!(base.noise.spikes.is_none());
    assert_eq!(base.thermal.as_ref().unwrap().lag_s, 0.0);
    let text = base.to_toml().unwrap();
    for key in ["warmup", "bias_step", "spikes", "lag_s"] {
        assert!(
            !text.contains(key),
            "{key} written for a model without it:\n{text}"
        );
    }
    // an unknown key inside the new tables names the key
    let msg =
        err_of(&format!("{BASE}{TRANSIENTS}").replace("tau_s = 900.0", "tau_s = 900.0\ntau = 1"));
    assert!(msg.contains("`tau`"), "{msg}");
}

#[test]
fn transients_are_not_allan_terms() {
    // deterministic transients and sparse glitches have no stationary closed
    // form: the term list is the model's without them; a lag does not change
    // the thermal ramp and sinusoid
    let mut m = with_transients();
    m.thermal.as_mut().unwrap().sine_amplitude_c = 0.2;
    m.thermal.as_mut().unwrap().sine_period_s = Some(3600.0);
    let mut plain = m.clone();
    plain.noise.warmup = None;
    plain.noise.bias_step.clear();
    plain.noise.spikes = None;
    plain.thermal.as_mut().unwrap().lag_s = 0.0;
    assert_eq!(m.terms(), plain.terms());
}

#[test]
fn transient_mean_rate_is_the_closed_form() {
    // over D = 3600 s: warm-up -0.05 * 900 (1 - e^-4) / 3600, steps
    // 0.01 * 1800/3600 and -0.004 * 1199.5/3600, and the lag's shift
    // -0.001 deg/h/C * 0.5 C/h * 120 s / 3600 s/h
    let m = with_transients();
    let expect = -0.05 * 900.0 * (1.0 - (-4.0f64).exp()) / 3600.0 + 0.01 * 0.5
        - 0.004 * 1199.5 / 3600.0
        - 0.001 * 0.5 * 120.0 / 3600.0;
    let got = m.transient_mean_rate_dph(3600.0);
    assert!((got - expect).abs() < 1e-15, "{got} vs {expect}");
    assert_eq!(
        GyroModel::from_toml_str(BASE, "b")
            .unwrap()
            .transient_mean_rate_dph(3600.0),
        0.0
    );
}

#[test]
fn transient_values_out_of_range_name_key_and_value() {
    let t = format!("{BASE}{TRANSIENTS}");
    let cases = [
        (
            "tau_s = 900.0",
            "tau_s = 0.0",
            "noise.warmup.tau_s = 0: must be finite and > 0",
        ),
        ("tau_s = 900.0", "tau_s = -3.0", "noise.warmup.tau_s = -3"),
        ("tau_s = 900.0", "tau_s = nan", "noise.warmup.tau_s = NaN"),
        (
            "amplitude_dph = -0.05",
            "amplitude_dph = inf",
            "noise.warmup.amplitude_dph = inf",
        ),
        (
            "amplitude_dph = -0.05",
            "amplitude_dph = -2e9",
            "noise.warmup.amplitude_dph = -2e9: must be in",
        ),
        (
            "at_s = 1800.0",
            "at_s = -1.0",
            "noise.bias_step[0].at_s = -1: must be finite and >= 0",
        ),
        (
            "at_s = 2400.5",
            "at_s = inf",
            "noise.bias_step[1].at_s = inf",
        ),
        (
            "amplitude_dph = -0.004",
            "amplitude_dph = nan",
            "noise.bias_step[1].amplitude_dph = NaN",
        ),
        (
            "rate_per_h = 2.0",
            "rate_per_h = -1.0",
            "noise.spikes.rate_per_h = -1: must be in",
        ),
        (
            "rate_per_h = 2.0",
            "rate_per_h = nan",
            "noise.spikes.rate_per_h = NaN",
        ),
        // at most 100 per sample period: 3.6e8 per hour at 1 kHz
        (
            "rate_per_h = 2.0",
            "rate_per_h = 4e9",
            "noise.spikes.rate_per_h = 4e9: must be in",
        ),
        (
            "amplitude_dph = 5.0",
            "amplitude_dph = -5.0",
            "noise.spikes.amplitude_dph = -5",
        ),
        (
            "bias_sensitivity_dph_per_c = 0.001",
            "bias_sensitivity_dph_per_c = 0.001\nlag_s = -5.0",
            "thermal.lag_s = -5: must be finite and >= 0",
        ),
        (
            "bias_sensitivity_dph_per_c = 0.001",
            "bias_sensitivity_dph_per_c = 0.001\nlag_s = inf",
            "thermal.lag_s = inf",
        ),
    ];
    for (from, to, expect) in cases {
        assert!(t.contains(from), "{from}");
        let msg = err_of(&t.replacen(from, to, 1));
        assert!(msg.starts_with("m.toml: "), "{msg}");
        assert!(msg.contains(expect), "expected `{expect}` in: {msg}");
    }
    // the limits themselves are allowed
    for (from, to) in [
        ("rate_per_h = 2.0", "rate_per_h = 3.6e8"),
        ("at_s = 1800.0", "at_s = 0.0"),
    ] {
        GyroModel::from_toml_str(&t.replacen(from, to, 1), "m.toml").expect(to);
    }
}
