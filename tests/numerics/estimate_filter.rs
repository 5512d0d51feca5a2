//! Readout filters and rate-output gyros: the filtered white-rate
//! term's exact signatures against independent lag-domain references, the
//! simulator's filter and rate word, and the estimator on filtered recordings
//! (ARW of the unfiltered band, the filter's kind and corner, no filter on
//! unfiltered data, an honest misfit flag).

use sagnac::dsp::wavelet::Wavelet;
use sagnac::model::config::GyroModel;
use sagnac::model::estimate::Coefficient;
use sagnac::model::filter::{FilterKind, ReadoutFilter};
use sagnac::model::sim::Simulator;
use sagnac::model::wvar::{LevelBasis, SpectralTerm, finite_level_vars};
use sagnac::pipeline::{Analysis, Pipeline, PipelineConfig, PipelineOutput};
use sagnac::units;

fn sym8() -> Wavelet {
    Wavelet::by_name("sym8").unwrap()
}

#[test]
fn first_order_level_variances_match_the_truncated_lag_domain_sum() {
    // The one-pole filter has an infinite autocovariance, so its level variances
    // come from spectral quadrature; the reference is the exact lag-domain
    // propagation of its geometric autocovariance, truncated where a^k < 1e-17.
    let tau0 = 1.0 / 200.0;
    let w = sym8();
    let (lo, hi) = (w.dec_lo(), w.dec_hi());
    for corner in [5.0, 30.0, 80.0] {
        let f = ReadoutFilter::first_order(corner, tau0).unwrap();
        let ReadoutFilter::FirstOrder { pole: a } = f else {
            unreachable!()
        };
        let lags = ((1e-17f64).ln() / a.ln()).ceil() as usize + 1;
        let r0: Vec<f64> = (0..lags)
            .map(|k| (1.0 - a) / (1.0 + a) * a.powi(k as i32) / tau0)
            .collect();
        let exact = finite_level_vars(lo, hi, &r0, 10);
        let levels: Vec<u32> = (1..=10).collect();
        let b = LevelBasis::new(
            lo,
            hi,
            tau0,
            &levels,
            &[SpectralTerm::FilteredWhiteRate { filter: f }],
        );
        for j in 0..10 {
            let rel = b.phi[j][0] / exact[j] - 1.0;
            assert!(
                rel.abs() < 1e-6,
                "corner {corner} Hz, level {}: {} vs {} ({rel:e})",
                j + 1,
                b.phi[j][0],
                exact[j]
            );
        }
    }
}

/// Overlapping Allan variance of a stationary rate with autocovariance `r`
/// (lags 0..), averaging factor m, sample period tau0: the variance of the
/// difference of two adjacent m-sample means.
fn allan_from_autocov(r: &dyn Fn(i64) -> f64, m: i64) -> f64 {
    let mut v = 0.0;
    // Var(mean2 - mean1) = sum_i sum_k w_i w_k r(i - k), w = -1/m on [0, m), +1/m on [m, 2m)
    let w = |i: i64| if i < m { -1.0 } else { 1.0 };
    for d in -(2 * m - 1)..=(2 * m - 1) {
        let mut s = 0.0;
        for i in 0.max(d)..(2 * m).min(2 * m + d) {
            s += w(i) * w(i - d);
        }
        v += s * r(d);
    }
    v / (m * m) as f64 / 2.0
}

#[test]
fn filtered_allan_variance_matches_the_lag_domain_reference() {
    let tau0 = 1.0 / 500.0;
    for f in [
        ReadoutFilter::moving_average(6).unwrap(),
        ReadoutFilter::first_order(40.0, tau0).unwrap(),
    ] {
        let r = |d: i64| -> f64 {
            let k = d.unsigned_abs() as f64;
            match f {
                ReadoutFilter::MovingAverage { length } => {
                    let l = length as f64;
                    if k < l { (l - k) / (l * l) / tau0 } else { 0.0 }
                }
                ReadoutFilter::FirstOrder { pole: a } => (1.0 - a) / (1.0 + a) * a.powf(k) / tau0,
            }
        };
        let t = SpectralTerm::FilteredWhiteRate { filter: f };
        for m in [1u64, 2, 3, 7, 16, 64, 300] {
            let want = allan_from_autocov(&r, m as i64);
            let got = t.allan_var(m, tau0);
            assert!(
                (got / want - 1.0).abs() < 1e-4,
                "{f:?} m={m}: {got} vs {want}"
            );
        }
        // far beyond the filter the ARW signature 1/tau returns
        let m = 100_000u64;
        assert!((t.allan_var(m, tau0) * (m as f64 * tau0) - 1.0).abs() < 1e-3);
    }
}

fn model(fs: f64, filter: &str, extra_noise: &str) -> GyroModel {
    let text = format!(
        "[gyro]\nsample_rate_hz = {fs}\noutput = \"rate\"\nrate_lsb_dps = 0.0005\ninput_rate_dph = 10.0\n\
         [noise]\narw_dpsh = 0.05\nbias_instability_dph = 0.5\n{extra_noise}\n{filter}"
    );
    GyroModel::from_toml_str(&text, "test model").unwrap()
}

fn rates(m: &GyroModel, seed: u64, duration_s: f64) -> Vec<f64> {
    let mut sim = Simulator::new(m, seed, Some(duration_s)).unwrap();
    let (mut r, mut t) = (Vec::new(), Vec::new());
    while sim.next_block_rates(1 << 16, &mut r, &mut t) > 0 {}
    r
}

#[test]
fn simulated_rate_word_is_filtered_and_quantised() {
    let m = model(
        200.0,
        "[readout_filter]\nkind = \"moving_average\"\nlength = 5\n",
        "",
    );
    let r = rates(&m, 4, 600.0);
    assert_eq!(r.len(), 120_000);
    // every value is a multiple of the LSB
    assert!(
        r.iter()
            .all(|v| ((v / 0.0005) - (v / 0.0005).round()).abs() < 1e-6)
    );
    // a moving average of 5 white samples: lag-k correlation (5 - k) / 5
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    let c = |k: usize| {
        r.iter()
            .zip(&r[k..])
            .map(|(a, b)| (a - mean) * (b - mean))
            .sum::<f64>()
            / (r.len() - k) as f64
    };
    let c0 = c(0);
    for k in 1..=6 {
        let want = (5.0 - k as f64).max(0.0) / 5.0;
        assert!(
            (c(k) / c0 - want).abs() < 0.02,
            "lag {k}: {} vs {want}",
            c(k) / c0
        );
    }
    // the filter keeps the DC gain: the mean is the input rate (10 deg/h)
    assert!(
        (mean * 3600.0 - 10.0).abs() < 1.0,
        "mean {} deg/h",
        mean * 3600.0
    );
}

fn analyse(m: &GyroModel, seed: u64, duration_s: f64) -> Analysis {
    let fs = m.gyro.sample_rate_hz;
    let mut p = Pipeline::new(&PipelineConfig::rates(fs)).unwrap();
    let mut out = PipelineOutput::default();
    let dph: Vec<f64> = rates(m, seed, duration_s)
        .iter()
        .map(|v| v * units::S_PER_H)
        .collect();
    for c in dph.chunks(1 << 16) {
        out.clear();
        p.push_rates_dph(c, &mut out).unwrap();
    }
    out.clear();
    p.finish(&mut out);
    p.analysis()
}

fn covers(c: &Coefficient, truth: f64) -> bool {
    match (c.ci95, c.upper95) {
        (Some([lo, hi]), _) => lo <= truth && truth <= hi,
        (None, Some(u)) => truth <= u,
        _ => false,
    }
}

#[test]
fn arw_behind_a_moving_average_is_the_unfiltered_white_coefficient() {
    let m = model(
        200.0,
        "[readout_filter]\nkind = \"moving_average\"\nlength = 5\n",
        "",
    );
    let corner = ReadoutFilter::moving_average(5)
        .unwrap()
        .corner_hz(1.0 / 200.0);
    for seed in 1..=3 {
        let a = analyse(&m, seed, 1200.0);
        let n = &a.estimates.arw_dpsh;
        assert!(covers(n, 0.05), "seed {seed}: ARW {n:?}");
        assert!(
            (n.value.unwrap() / 0.05 - 1.0).abs() < 0.02,
            "seed {seed}: ARW {n:?}"
        );
        let f = a
            .readout_filter
            .unwrap_or_else(|| panic!("seed {seed}: no filter found"));
        assert_eq!(f.kind, FilterKind::MovingAverage, "seed {seed}: {f:?}");
        assert_eq!(f.length, Some(5), "seed {seed}: {f:?}");
        assert!(
            f.ci95[0] <= corner * (1.0 + 1e-9) && corner <= f.ci95[1] * (1.0 + 1e-9),
            "seed {seed}: {f:?}"
        );
        assert!(a.fit.ok, "seed {seed}: fit {:?}", a.fit);
    }
}

#[test]
fn arw_behind_a_first_order_filter_and_its_corner() {
    let m = model(
        200.0,
        "[readout_filter]\nkind = \"first_order\"\ncorner_hz = 30.0\n",
        "",
    );
    for seed in 1..=3 {
        let a = analyse(&m, seed, 1200.0);
        let n = &a.estimates.arw_dpsh;
        assert!(covers(n, 0.05), "seed {seed}: ARW {n:?}");
        let f = a
            .readout_filter
            .unwrap_or_else(|| panic!("seed {seed}: no filter found"));
        assert!(f.ci95[0] <= 30.0 && 30.0 <= f.ci95[1], "seed {seed}: {f:?}");
        assert!((f.corner_hz / 30.0 - 1.0).abs() < 0.1, "seed {seed}: {f:?}");
        let b = &a.estimates.bias_instability_dph;
        assert!(
            covers(b, 0.5),
            "seed {seed}: B {b:?} (an unfiltered model reads the roll-off as bias instability)"
        );
    }
}

#[test]
fn no_filter_is_reported_on_unfiltered_rate_data() {
    let m = model(200.0, "", "");
    for seed in 1..=4 {
        let a = analyse(&m, seed, 1200.0);
        assert!(
            a.readout_filter.is_none(),
            "seed {seed}: {:?}",
            a.readout_filter
        );
        assert!(
            covers(&a.estimates.arw_dpsh, 0.05),
            "seed {seed}: {:?}",
            a.estimates.arw_dpsh
        );
    }
}

fn analyse_rates(fs: f64, dps: &[f64]) -> Analysis {
    let mut p = Pipeline::new(&PipelineConfig::rates(fs)).unwrap();
    let mut out = PipelineOutput::default();
    let dph: Vec<f64> = dps.iter().map(|v| v * units::S_PER_H).collect();
    for c in dph.chunks(1 << 16) {
        out.clear();
        p.push_rates_dph(c, &mut out).unwrap();
    }
    out.clear();
    p.finish(&mut out);
    p.analysis()
}

#[test]
fn a_model_that_does_not_fit_says_so_and_widens_its_intervals() {
    // white rate through three cascaded one-pole filters (a third-order roll-off):
    // neither a moving average nor a single pole has its shape
    let m = GyroModel::from_toml_str(
        "[gyro]\nsample_rate_hz = 200.0\noutput = \"rate\"\n[noise]\narw_dpsh = 0.05\n\
         [readout_filter]\nkind = \"first_order\"\ncorner_hz = 15.0\n",
        "m",
    )
    .unwrap();
    let mut r = rates(&m, 1, 3600.0);
    let f = ReadoutFilter::first_order(15.0, 1.0 / 200.0).unwrap();
    f.state(0.0).apply(&mut r);
    f.state(0.0).apply(&mut r);
    let a = analyse_rates(200.0, &r);
    assert!(!a.fit.ok, "fit {:?}", a.fit);
    assert!(a.fit.chi2_per_dof > 3.0, "fit {:?}", a.fit);
    let json = serde_json::to_value(&a).unwrap();
    assert_eq!(json["fit"]["ok"], serde_json::Value::Bool(false));
    assert!(json["fit"]["chi2_per_dof"].as_f64().unwrap() > 3.0);
    // the interval of N is widened: relative width at least sqrt(chi2/dof)
    // times that of a run the model describes (one pole)
    let single = analyse_rates(200.0, &rates(&m, 1, 3600.0));
    assert!(single.fit.ok, "single pole: {:?}", single.fit);
    let width = |c: &Coefficient| {
        c.ci95
            .map(|[lo, hi]| (hi - lo) / c.value.unwrap())
            .unwrap_or(f64::INFINITY)
    };
    let (w_bad, w_ok) = (
        width(&a.estimates.arw_dpsh),
        width(&single.estimates.arw_dpsh),
    );
    assert!(
        w_bad > a.fit.chi2_per_dof.sqrt() * 0.8 * w_ok,
        "misfit width {w_bad} vs {w_ok}, fit {:?}",
        a.fit
    );
}

#[test]
fn rate_output_model_keys_are_checked() {
    let bad = |text: &str, key: &str| {
        let e = GyroModel::from_toml_str(text, "m.toml")
            .and_then(|m| m.validate().map(|_| m))
            .unwrap_err()
            .to_string();
        assert!(e.contains(key), "{e} should name {key}");
    };
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\npulse_arcsec = 1.0\n",
        "gyro.pulse_arcsec",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\npulse_arcsec = 1.0\nrate_lsb_dps = 0.05\n",
        "gyro.rate_lsb_dps",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\nrate_lsb_dps = -1.0\n",
        "gyro.rate_lsb_dps",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\n[readout_filter]\nkind = \"first_order\"\ncorner_hz = 60.0\n",
        "readout_filter.corner_hz",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\n[readout_filter]\nkind = \"moving_average\"\n",
        "readout_filter.length",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\n[readout_filter]\nkind = \"boxcar\"\nlength = 3\n",
        "m.toml:5",
    );
    bad(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\n[readout_filter]\nkind = \"moving_average\"\nlength = 3\ntaps = 2\n",
        "taps",
    );
    // a written model reads back the same
    let m = GyroModel::from_toml_str(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\nrate_lsb_dps = 0.05\n[readout_filter]\nkind = \"first_order\"\ncorner_hz = 20.0\n",
        "m.toml",
    )
    .unwrap();
    let back = GyroModel::from_toml_str(&m.to_toml().unwrap(), "back").unwrap();
    assert_eq!(m, back);
}

#[test]
fn rate_word_rounding_is_white_rate_noise_of_lsb_squared_over_12() {
    // ARW 1 deg/sqrt(h) at 100 Hz: 0.1667 deg/s per sample; LSB 0.2 deg/s adds
    // 0.2^2/12 to the variance of every sample, and nothing to its correlation
    let m = GyroModel::from_toml_str(
        "[gyro]\nsample_rate_hz = 100.0\noutput = \"rate\"\nrate_lsb_dps = 0.2\n[noise]\narw_dpsh = 1.0\n",
        "m",
    )
    .unwrap();
    let r = rates(&m, 9, 10_000.0);
    let n = r.len() as f64;
    let mean = r.iter().sum::<f64>() / n;
    let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    let white = (1.0f64 / 60.0).powi(2) / 0.01;
    let want = white + 0.2f64.powi(2) / 12.0;
    assert!(
        (var / want - 1.0).abs() < 0.01,
        "variance {var} vs {want} (without the LSB term {white})"
    );
    let lag1 = r
        .iter()
        .zip(&r[1..])
        .map(|(a, b)| (a - mean) * (b - mean))
        .sum::<f64>()
        / (n - 1.0)
        / var;
    assert!(lag1.abs() < 0.01, "lag-1 correlation {lag1}");
    // the model's terms say the same: ARW plus the rate quantization term
    let tau0 = 0.01;
    let total: f64 = m.terms().iter().map(|t| t.avar(tau0)).sum();
    let want_dph2 = want * 3600f64.powi(2);
    assert!(
        (total / want_dph2 - 1.0).abs() < 1e-9,
        "model AVAR at tau0 {total} vs {want_dph2}"
    );
}

#[test]
fn coarse_pass_never_hides_a_reported_filter() {
    // The estimator profiles the full filter search only when a coarse subset
    // of the candidates comes within a third of the reporting deviance. On
    // filters from plain to barely detectable (corners near Nyquist, 2-sample
    // averages, a rate word coarse enough to fill in the attenuated levels),
    // and on unfiltered records, the estimate with the coarse pass must equal
    // the one that profiles every candidate.
    use sagnac::model::fit::FitOptions;
    let full = FitOptions {
        full_filter_search: true,
        ..FitOptions::default()
    };
    let fo = |c: f64| format!("[readout_filter]\nkind = \"first_order\"\ncorner_hz = {c}\n");
    let ma = |l: u32| format!("[readout_filter]\nkind = \"moving_average\"\nlength = {l}\n");
    // (rate Hz, LSB deg/s, filter table, seconds)
    let cases: Vec<(f64, f64, String, f64)> = vec![
        (200.0, 0.0005, fo(15.0), 600.0),
        (200.0, 0.0005, fo(85.0), 600.0),
        (200.0, 0.0005, fo(97.0), 300.0),
        (500.0, 0.0005, fo(240.0), 200.0),
        (1000.0, 0.0005, fo(480.0), 100.0),
        (100.0, 0.004, fo(30.0), 1200.0),
        (200.0, 0.04, fo(60.0), 300.0),
        (200.0, 0.03, fo(80.0), 300.0),
        (100.0, 0.02, fo(45.0), 300.0),
        (200.0, 0.0005, ma(2), 600.0),
        (200.0, 0.05, ma(2), 200.0),
        (1000.0, 0.0005, ma(3), 200.0),
        (200.0, 0.08, fo(95.0), 100.0),
        (500.0, 0.2, fo(245.0), 60.0),
        (100.0, 0.05, fo(49.0), 200.0),
        (200.0, 0.0005, fo(99.0), 60.0),
        (200.0, 0.1, ma(2), 60.0),
        (200.0, 0.0005, String::new(), 600.0),
        (500.0, 0.002, String::new(), 300.0),
        (100.0, 0.0005, String::new(), 1200.0),
    ];
    let (mut reported, mut agree) = (0, 0);
    let n = cases.len() * 2;
    for (i, (fs, lsb, filter, dur)) in cases.iter().enumerate() {
        let text = format!(
            "[gyro]\nsample_rate_hz = {fs}\noutput = \"rate\"\nrate_lsb_dps = {lsb}\ninput_rate_dph = 10.0\n\
             [noise]\narw_dpsh = 0.05\nbias_instability_dph = 0.5\n{filter}"
        );
        let m = GyroModel::from_toml_str(&text, "case").unwrap();
        for seed in [11 + i as u64, 101 + i as u64] {
            let mut p = Pipeline::new(&PipelineConfig::rates(*fs)).unwrap();
            let mut out = PipelineOutput::default();
            let dph: Vec<f64> = rates(&m, seed, *dur)
                .iter()
                .map(|v| v * units::S_PER_H)
                .collect();
            p.push_rates_dph(&dph, &mut out).unwrap();
            let quick = p.estimator_output().readout_filter;
            let reference = p.estimator_output_with(&full).readout_filter;
            let kind = |f: &Option<sagnac::model::estimate::FilterEstimate>| {
                f.as_ref().map(|f| (f.kind, f.corner_hz, f.length))
            };
            reported += usize::from(reference.is_some());
            agree += usize::from(kind(&quick) == kind(&reference));
            assert_eq!(
                kind(&quick),
                kind(&reference),
                "case {i} seed {seed}: {text}"
            );
        }
    }
    assert_eq!(agree, n);
    // the cases span both outcomes, so the comparison says something
    assert!(
        reported >= 8 && reported <= n - 6,
        "{reported} of {n} report a filter"
    );
}
