//! The resonance term (`[[noise.resonance]]`): its closed-form Allan
//! variance against an independent quadrature of its spectrum, and the
//! simulator's output against both (variance, lag-one correlation, Allan
//! variance, where its spectrum peaks).

use sagnac::model::config::OutputKind;
use sagnac::model::wvar::SpectralTerm;
use sagnac::model::{GyroModel, Simulator, Term};

const FS: f64 = 100.0;

fn model(extra: &str) -> Result<GyroModel, sagnac::model::ModelError> {
    let text = format!(
        "[gyro]\nsample_rate_hz = {FS}\noutput = \"rate\"\n\
         [noise]\narw_dpsh = 0.0\n[[noise.resonance]]\n{extra}\n"
    );
    GyroModel::from_toml_str(&text, "resonance test")
}

fn resonance() -> GyroModel {
    model("sigma_dph = 50.0\ncentre_hz = 19.0\nwidth_hz = 1.5").unwrap()
}

/// Rates in deg/h.
fn simulate(m: &GyroModel, seed: u64, duration_s: f64) -> Vec<f64> {
    assert_eq!(m.gyro.output, OutputKind::Rate);
    let mut sim = Simulator::new(m, seed, Some(duration_s)).unwrap();
    let (mut r, mut t) = (Vec::new(), Vec::new());
    while sim.next_block_rates(1 << 16, &mut r, &mut t) > 0 {}
    r.iter().map(|v| v * 3600.0).collect()
}

/// Overlapping Allan variance of rates `y` at averaging factor `m`.
fn oavar(y: &[f64], m: usize) -> f64 {
    let mut phase = vec![0.0];
    for v in y {
        phase.push(phase.last().unwrap() + v);
    }
    let n = phase.len() - 2 * m;
    let s: f64 = (0..n)
        .map(|i| (phase[i + 2 * m] - 2.0 * phase[i + m] + phase[i]).powi(2))
        .sum();
    s / (2.0 * n as f64 * (m * m) as f64)
}

#[test]
fn closed_form_allan_variance_equals_the_spectral_quadrature() {
    let m = resonance();
    let terms = m.terms();
    let t = terms
        .iter()
        .find(|t| t.name() == "resonance")
        .expect("the resonance term");
    let tau0 = 1.0 / FS;
    let st = SpectralTerm::Resonance {
        centre_nu: 19.0 * tau0,
        width_nu: 1.5 * tau0,
        filter: None,
    };
    for mm in [1u64, 2, 3, 5, 8, 13, 40, 100, 1000, 30_000] {
        let closed = t.unit_avar(mm as f64 * tau0);
        // the spectral route in arcsec/s units per unit variance; the term's
        // unit coefficient is 1 deg/h = 1 arcsec/s
        let quad = st.allan_var(mm, tau0);
        assert!(
            (closed / quad - 1.0).abs() < 2e-4,
            "m {mm}: closed {closed} quadrature {quad}"
        );
    }
}

#[test]
fn simulated_resonance_has_the_model_statistics() {
    let m = resonance();
    let y = simulate(&m, 11, 4.0 * 3600.0);
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let var = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    // sigma 50 deg/h over 1.44 M samples correlated over about 20 (1/(pi w tau0)):
    // the sample variance's relative sd is below 1 %
    assert!((var / 2500.0 - 1.0).abs() < 0.03, "variance {var}");
    let r1 = y
        .windows(2)
        .map(|w| (w[0] - mean) * (w[1] - mean))
        .sum::<f64>()
        / (n - 1.0)
        / var;
    let ar = sagnac::model::resonance::Ar2::new(19.0, 1.5, 1.0 / FS);
    assert!(
        (r1 - ar.autocorr(1)).abs() < 0.01,
        "rho(1) {r1} vs {}",
        ar.autocorr(1)
    );
    let t = m
        .terms()
        .into_iter()
        .find(|t| t.name() == "resonance")
        .unwrap();
    for mm in [1usize, 2, 3, 5, 10, 50] {
        let got = oavar(&y, mm);
        let want = t.avar(mm as f64 / FS);
        assert!(
            (got / want - 1.0).abs() < 0.05,
            "m {mm}: simulated {got} model {want}"
        );
    }
    // the spectrum peaks at the centre: the Fourier power of 10 s blocks
    let peak = (10..=45)
        .map(|k| {
            let f = k as f64;
            let (mut c, mut s) = (0.0, 0.0);
            for (i, v) in y[..200_000].iter().enumerate() {
                let ph = 2.0 * std::f64::consts::PI * f * i as f64 / FS;
                c += v * ph.cos();
                s += v * ph.sin();
            }
            (f, c * c + s * s)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert!((peak.0 - 19.0).abs() <= 1.0, "peak at {} Hz", peak.0);
}

#[test]
fn bad_resonance_keys_are_named() {
    let e = model("sigma_dph = 1.0\ncentre_hz = 60.0\nwidth_hz = 1.0")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("noise.resonance[0].centre_hz") && e.contains("Nyquist"),
        "{e}"
    );
    let e = model("sigma_dph = 1.0\ncentre_hz = 20.0\nwidth_hz = 0.0")
        .unwrap_err()
        .to_string();
    assert!(e.contains("noise.resonance[0].width_hz"), "{e}");
    let e = model("sigma_dph = 1.0\ncentre_hz = 20.0")
        .unwrap_err()
        .to_string();
    assert!(e.contains("width_hz"), "{e}");
    // the term validates the same bounds
    assert!(
        Term::Resonance {
            sigma_dph: 1.0,
            centre_hz: 50.0,
            width_hz: 1.0,
            tau0_s: 0.01
        }
        .validate()
        .is_err()
    );
}
