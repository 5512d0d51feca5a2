//! The model's Gaussian noise terms as spectral shapes: the rate PSD the
//! simulator's noise has, for whitening a spectrum and flooring a statistic's
//! spread by its EDF.

use crate::model::GyroModel;
use crate::model::config::OutputKind;
use crate::model::wvar::SpectralTerm;
use crate::units;

/// The model's Gaussian terms as spectral shapes with their squared
/// coefficients (arcsec/s units); sinusoids are deterministic and left out,
/// a random telegraph enters as its Gauss-Markov twin, a resonance passes
/// through the readout filter as the simulator's does. The white rate goes
/// through the model's readout filter; a rate word's LSB rounding is white
/// rate noise after it ([`rate_lsb_theta`]).
pub fn model_spectral_terms(model: &GyroModel) -> (Vec<SpectralTerm>, Vec<f64>) {
    let mut terms = vec![SpectralTerm::WhiteAngle];
    let q = model.quantization_q_arcsec();
    let mut theta = vec![q * q];
    let n = &model.noise;
    let arw = units::dpsh_to_arcsec_per_sqrt_s(n.arw_dpsh.unwrap_or(0.0));
    terms.push(match model.readout_filter() {
        Some(filter) => SpectralTerm::FilteredWhiteRate { filter },
        None => SpectralTerm::WhiteRate,
    });
    theta.push(arw * arw);
    let lsb = rate_lsb_theta(model);
    if lsb > 0.0 {
        terms.push(SpectralTerm::WhiteRate);
        theta.push(lsb);
    }
    if let Some(b) = n.bias_instability_dph.filter(|b| *b > 0.0) {
        terms.push(SpectralTerm::Flicker {
            f_lo_hz: model.flicker_f_lo_hz(),
        });
        theta.push(b * b);
    }
    if let Some(k) = n.rrw_dphsh.filter(|k| *k > 0.0) {
        let k = units::dphsh_to_arcsec_per_s_sqrt_s(k);
        terms.push(SpectralTerm::RateRandomWalk);
        theta.push(k * k);
    }
    for g in &n.gauss_markov {
        terms.push(SpectralTerm::GaussMarkov { tau_c_s: g.tau_c_s });
        theta.push(g.sigma_dph * g.sigma_dph);
    }
    for r in &n.random_telegraph {
        terms.push(SpectralTerm::GaussMarkov {
            tau_c_s: 0.5 * r.mean_dwell_s,
        });
        theta.push(r.amplitude_dph * r.amplitude_dph);
    }
    let tau0 = model.tau0_s();
    for r in &n.resonance {
        terms.push(SpectralTerm::Resonance {
            centre_nu: r.centre_hz * tau0,
            width_nu: r.width_hz * tau0,
            filter: model.readout_filter(),
        });
        theta.push(r.sigma_dph * r.sigma_dph);
    }
    (terms, theta)
}

/// A rate word's LSB rounding as white rate noise: variance `lsb^2 / 12` per
/// sample, i.e. `theta = N^2 = (lsb in arcsec/s)^2 tau0 / 12` (0 for a
/// counter or an unquantised rate).
pub fn rate_lsb_theta(model: &GyroModel) -> f64 {
    if model.gyro.output != OutputKind::Rate {
        return 0.0;
    }
    let lsb = model.gyro.rate_lsb_dps * units::ARCSEC_PER_DEG;
    lsb * lsb * model.tau0_s() / 12.0
}

/// The model's one-sided rate PSD (its Gaussian terms), (arcsec/s)^2/Hz at `f` Hz.
pub fn model_psd(model: &GyroModel) -> impl Fn(f64) -> f64 {
    let (terms, theta) = model_spectral_terms(model);
    let tau0 = 1.0 / model.gyro.sample_rate_hz;
    move |f: f64| {
        terms
            .iter()
            .zip(&theta)
            .map(|(t, th)| th * t.psd_cs(f * tau0, tau0) * tau0)
            .sum()
    }
}
