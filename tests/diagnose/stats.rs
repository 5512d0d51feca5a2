//! The diagnosis statistics against closed forms and independent references:
//! wavelet level variances against `model::wvar` for white rate, white angle,
//! Gauss-Markov and sinusoidal rates; the Welch PSD against Parseval and the
//! white-noise level; the kurtosis statistic on known distributions; the
//! chi-square-calibrated z against the chi-square law; the Monte-Carlo
//! reference against the thread count.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use sagnac::diagnose::compare::{gamma_z, nu_from_log_var, sd_log_chi2, trigamma};
use sagnac::diagnose::mc::{self, McJob};
use sagnac::diagnose::stats::{self, StatLayout, Welch};
use sagnac::diagnose::two_level::TwoLevelProbe;
use sagnac::diagnose::wvar_fit::Basis;
use sagnac::model::GyroModel;
use sagnac::model::wvar::{LevelBasis, SpectralTerm};
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

fn normals(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
}

/// Check each level's mean square against `expected` within `k` standard
/// deviations of a mean square of `n_coef` coefficients with `edf` degrees of freedom.
fn check_levels(
    got: &[(u32, usize, f64)],
    expected: &[f64],
    edf: &dyn Fn(usize, usize) -> f64,
    k: f64,
    what: &str,
) {
    for (i, &(level, n, v)) in got.iter().enumerate() {
        let nu = edf(i, n);
        let rel = (v / expected[i] - 1.0).abs();
        let tol = k * (2.0 / nu).sqrt();
        assert!(
            rel < tol,
            "{what} level {level} ({n} coefs): {v} vs {} (rel {rel:.4}, tol {tol:.4})",
            expected[i]
        );
    }
}

#[test]
fn wavelet_variances_of_white_rate_and_white_angle_match_wvar() {
    let (lo, hi) = stats::sym8();
    let tau0 = 1e-3;
    let n = 1 << 20;
    // white rate of variance 4: every level has variance 4 (orthonormal DWT)
    let x: Vec<f64> = normals(n, 1).into_iter().map(|g| 2.0 * g).collect();
    let got = stats::dwt_level_mean_squares(&x, &lo, &hi, 12, 8);
    assert_eq!(got.len(), 12);
    check_levels(&got, &[4.0; 12], &|_, n| n as f64, 5.0, "white rate");
    // white angle (Q = 0.7 arcsec) seen as a rate: first difference / tau0
    let q = 0.7;
    let ang: Vec<f64> = normals(n + 1, 2).into_iter().map(|g| q * g).collect();
    let rate: Vec<f64> = ang.windows(2).map(|w| (w[1] - w[0]) / tau0).collect();
    let got = stats::dwt_level_mean_squares(&rate, &lo, &hi, 10, 8);
    let levels: Vec<u32> = got.iter().map(|g| g.0).collect();
    let lb = LevelBasis::new(&lo, &hi, tau0, &levels, &[SpectralTerm::WhiteAngle]);
    let want: Vec<f64> = lb.phi.iter().map(|r| q * q * r[0]).collect();
    // the EDF of a level of differenced white noise is below the coefficient
    // count (neighbouring coefficients correlate): LevelBasis gives it
    check_levels(
        &got,
        &want,
        &|i, n| lb.edf(i, &[q * q], n as f64),
        5.0,
        "white angle",
    );
}

#[test]
fn wavelet_variances_of_gauss_markov_and_sinusoid_match_the_basis() {
    let (lo, hi) = stats::sym8();
    let tau0 = 0.01;
    let n = 1 << 20;
    let levels: Vec<u32> = (1..=12).collect();
    let basis = Basis::new(&lo, &hi, tau0, &levels);
    // AR(1) = sampled Gauss-Markov, sigma 3, Tc 0.4 s
    let (sigma, tc) = (3.0, 0.4);
    let phi = (-tau0 / tc).exp();
    let g = normals(n, 3);
    let mut x = vec![0.0; n];
    let mut s = sigma * g[0];
    for k in 0..n {
        if k > 0 {
            s = phi * s + sigma * (1.0 - phi * phi).sqrt() * g[k];
        }
        x[k] = s;
    }
    let got = stats::dwt_level_mean_squares(&x, &lo, &hi, 12, 8);
    let shape = basis.gauss_markov(tc);
    let want: Vec<f64> = shape.iter().map(|p| sigma * sigma * p).collect();
    let lb = LevelBasis::new(
        &lo,
        &hi,
        tau0,
        &levels,
        &[SpectralTerm::GaussMarkov { tau_c_s: tc }],
    );
    check_levels(
        &got,
        &want,
        &|i, n| lb.edf(i, &[sigma * sigma], n as f64),
        5.0,
        "gauss-markov",
    );
    // a sinusoid averaged over each sample, amplitude 2, at 1.3 Hz and 0.11 Hz:
    // its power A^2/2 goes to the level whose band holds the frequency
    for &f in &[1.3, 0.11] {
        let a = 2.0;
        let w = 2.0 * std::f64::consts::PI * f;
        let x: Vec<f64> = (0..n)
            .map(|k| {
                let t0 = k as f64 * tau0;
                // exact average of A sin(w t + 0.3) over [t0, t0 + tau0]
                a * ((w * t0 + 0.3).cos() - (w * (t0 + tau0) + 0.3).cos()) / (w * tau0)
            })
            .collect();
        let got = stats::dwt_level_mean_squares(&x, &lo, &hi, 12, 8);
        let phi = basis.sinusoid(f);
        let total: f64 = got.iter().map(|g| g.2).sum();
        let want_total: f64 = phi.iter().map(|p| a * a * p).sum();
        // deterministic: only the finite record (phase at the ends) perturbs it
        assert!(
            (total / want_total - 1.0).abs() < 0.02,
            "sinusoid {f} Hz: total {total} vs {want_total}"
        );
        for (i, g) in got.iter().enumerate() {
            let w = a * a * phi[i];
            if w > 0.05 * want_total {
                assert!(
                    (g.2 / w - 1.0).abs() < 0.05,
                    "sinusoid {f} Hz level {}: {} vs {w}",
                    g.0,
                    g.2
                );
            }
        }
    }
}

#[test]
fn welch_psd_obeys_parseval_and_the_white_level() {
    let fs = 200.0;
    let n = 1 << 18;
    let sigma = 1.5;
    let x: Vec<f64> = normals(n, 4).into_iter().map(|g| sigma * g).collect();
    let w = Welch::new(4096);
    let p = w.psd(&x, fs);
    // white noise: one-sided level 2 sigma^2 / fs; the mean over the interior
    // bins has ~ (segments x bins) degrees of freedom
    let interior = &p[10..2040];
    let mean = interior.iter().sum::<f64>() / interior.len() as f64;
    let want = 2.0 * sigma * sigma / fs;
    assert!(
        (mean / want - 1.0).abs() < 0.01,
        "white level {mean} vs {want}"
    );
    // a sinusoid of amplitude 3 at 23.4 Hz: its integrated power is A^2/2
    let a = 3.0;
    let y: Vec<f64> = (0..n)
        .map(|k| a * (2.0 * std::f64::consts::PI * 23.4 * k as f64 / fs).sin())
        .collect();
    let py = w.psd(&y, fs);
    let df = fs / 4096.0;
    let k0 = (23.4 / df).round() as usize;
    let power: f64 = py[k0 - 4..=k0 + 4].iter().sum::<f64>() * df;
    assert!(
        (power / (a * a / 2.0) - 1.0).abs() < 1e-3,
        "line power {power} vs {}",
        a * a / 2.0
    );
}

#[test]
fn kurtosis_statistic_on_known_distributions() {
    let g = normals(200_000, 5);
    assert!(
        stats::excess_kurtosis(&g).abs() < 0.05,
        "gaussian {}",
        stats::excess_kurtosis(&g)
    );
    let u: Vec<f64> = (0..200_000)
        .map(|k| (k as f64 * 0.618_033_988_75).fract())
        .collect();
    assert!(
        (stats::excess_kurtosis(&u) + 1.2).abs() < 0.01,
        "uniform {}",
        stats::excess_kurtosis(&u)
    );
    let two: Vec<f64> = (0..1000)
        .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    assert!((stats::excess_kurtosis(&two) + 2.0).abs() < 1e-12);
    // a slow telegraph of amplitude 5 plus unit white noise, low-passed far
    // below the noise but above the switching: close to the two-point -2
    let fs = 100.0;
    let n = 1 << 19;
    let noise = normals(n, 6);
    let x: Vec<f64> = (0..n)
        .map(|k| if (k / 3000) % 2 == 0 { 5.0 } else { -5.0 } + noise[k])
        .collect();
    let (lo, _) = stats::sym8();
    let k = stats::lowpass_kurtosis(&x, 1.0 / fs, 0.5, &lo);
    assert!((k + 2.0).abs() < 0.15, "telegraph {k}");
    let k = stats::lowpass_kurtosis(&noise, 1.0 / fs, 0.5, &lo);
    assert!(k.abs() < 0.2, "white {k}");
}

#[test]
fn chi_square_calibrated_z_and_trigamma() {
    let pi2 = std::f64::consts::PI.powi(2);
    assert!((trigamma(1.0) - pi2 / 6.0).abs() < 1e-12);
    assert!((trigamma(0.5) - pi2 / 2.0).abs() < 1e-12);
    assert!((trigamma(7.3) - 0.146_795_768_131_427).abs() < 1e-12); // scipy polygamma(1, 7.3)
    for nu in [3.0, 12.0, 400.0] {
        let sd = sd_log_chi2(nu);
        assert!((nu_from_log_var(sd * sd) / nu - 1.0).abs() < 1e-9);
        // a chi2_nu/nu variable at its p-quantile maps to the normal p-quantile
        let chi = ChiSquared::new(nu).unwrap();
        let norm = Normal::new(0.0, 1.0).unwrap();
        let e_ln = statrs::function::gamma::digamma(nu / 2.0) - (nu / 2.0).ln();
        for p in [0.001, 0.1, 0.5, 0.9, 0.999] {
            let x = chi.inverse_cdf(p) / nu;
            // centre: the mean of ln x is e_ln; put it at mean_log = 2.0
            let z = gamma_z(x.ln() - e_ln + 2.0, 2.0, sd);
            assert!(
                (z - norm.inverse_cdf(p)).abs() < 1e-6,
                "nu {nu} p {p}: z {z}"
            );
        }
    }
}

/// A 1.21" counter at `fs_hz` with Q, ARW and a Gauss-Markov term (Monte-Carlo jobs).
pub fn gauss_markov_gyro(fs_hz: f64) -> GyroModel {
    GyroModel::from_toml_str(
        &format!(
            "[gyro]\nsample_rate_hz = {fs_hz}\npulse_arcsec = 1.21\ninput_rate_dph = 9.0\n\
             [noise]\nquantization_arcsec = 0.4\narw_dpsh = 0.002\n\
             [[noise.gauss_markov]]\nsigma_dph = 0.05\ntau_c_s = 3.0\n"
        ),
        "t",
    )
    .unwrap()
}

#[test]
fn monte_carlo_reference_does_not_depend_on_threads() {
    let model = gauss_markov_gyro(200.0);
    let layout = StatLayout::new(60_000, 200.0, 1.21);
    let seeds = [11u64, 12, 13, 14, 15];
    // each run done is reported once, with the phase and the number of runs
    let reports = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let sink = std::sync::Arc::clone(&reports);
    let progress = mc::Progress::new(move |phase, done, total| {
        sink.lock().unwrap().push((phase.to_string(), done, total))
    });
    let job = McJob {
        model: &model,
        layout: &layout,
        temp_c: None,
        lp_cutoffs_hz: &[0.3],
        threads: 1,
        full: true,
        two_level: Some(TwoLevelProbe {
            amp: 0.5,
            mean_dwell_s: 4.0,
        }),
        phase: "test runs",
        progress: &progress,
    };
    let one = mc::run(&job, &seeds).unwrap();
    let told: Vec<_> = reports.lock().unwrap().clone();
    let want: Vec<_> = (0..=5).map(|d| ("test runs".to_string(), d, 5)).collect();
    assert_eq!(told, want);
    let two = mc::run(&McJob { threads: 2, ..job }, &seeds).unwrap();
    let three = mc::run(&McJob { threads: 3, ..job }, &seeds).unwrap();
    assert_eq!(one, two);
    assert_eq!(one, three);
    assert!(one.iter().all(|s| s.wvar.len() == layout.levels.len()
        && s.kurtosis.len() == 1
        && s.two_level_llr.is_finite()));
}
