//! The comparison points of a recording against its Monte-Carlo runs: the
//! sym8 wavelet levels, the modified Allan variance, the Welch spectrum's
//! quarter-octave bands, the raw Allan variance (reported only: it shows what a
//! user's plot would have seen) and, for each Gauss-Markov or telegraph term of
//! the model, the excess kurtosis of the rate low-passed at its time scale.
//! Each log-scale spread is floored by the estimator's chi-square EDF under
//! the model's Gaussian terms ([`floors`]).

use std::f64::consts::PI;

use super::compare::{self, Family, Point};
use super::stats::{StatLayout, StatSet};
use crate::allan::{Stat, edf_for_stat};
use crate::model::GyroModel;
use crate::model::spectrum::model_spectral_terms;
use crate::model::wvar::{LevelBasis, SpectralTerm};

/// Smallest standard deviation assumed for the kurtosis statistic.
const KURTOSIS_SD_FLOOR: f64 = 0.02;

/// A model term tested by the kurtosis statistic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KTerm {
    GaussMarkov(usize),
    Telegraph(usize),
}

/// The points that detect (all but the raw Allan variance).
pub fn detect_points(pts: &[Point]) -> Vec<&Point> {
    pts.iter()
        .filter(|p| p.family != Family::RawAllan)
        .collect()
}

/// Low-pass cut-offs of the kurtosis test for the model's Gauss-Markov and
/// telegraph terms (`1/Tc`, `Tc = dwell/2`), with the tau span each speaks for.
pub fn kurtosis_scales(model: &GyroModel) -> Vec<(f64, (f64, f64), KTerm)> {
    let n = &model.noise;
    let gm = n
        .gauss_markov
        .iter()
        .enumerate()
        .filter(|(_, g)| g.sigma_dph > 0.0)
        .map(|(i, g)| (g.tau_c_s, KTerm::GaussMarkov(i)));
    let rtn = n
        .random_telegraph
        .iter()
        .enumerate()
        .filter(|(_, r)| r.amplitude_dph > 0.0)
        .map(|(i, r)| (0.5 * r.mean_dwell_s, KTerm::Telegraph(i)));
    gm.chain(rtn)
        .map(|(tc, t)| (1.0 / tc, (0.5 * tc, 4.0 * tc), t))
        .collect()
}

/// The mean of every statistic over the runs.
pub fn mean_stats(runs: &[StatSet]) -> StatSet {
    let r = runs.len() as f64;
    let avg = |f: &dyn Fn(&StatSet) -> &Vec<f64>| -> Vec<f64> {
        let n = f(&runs[0]).len();
        (0..n)
            .map(|i| runs.iter().map(|s| f(s)[i]).sum::<f64>() / r)
            .collect()
    };
    StatSet {
        wvar: avg(&|s| &s.wvar),
        mvar: avg(&|s| &s.mvar),
        avar: avg(&|s| &s.avar),
        psd: avg(&|s| &s.psd),
        band_psd: avg(&|s| &s.band_psd),
        mean_rate: runs.iter().map(|s| s.mean_rate).sum::<f64>() / r,
        slope: runs.iter().map(|s| s.slope).sum::<f64>() / r,
        temp_slope: None,
        kurtosis: avg(&|s| &s.kurtosis),
        lf_psd: avg(&|s| &s.lf_psd),
        two_level_llr: runs.iter().map(|s| s.two_level_llr).sum::<f64>() / r,
    }
}

/// Analytic floors of the log standard deviations: (wavelet, MDEV, spectral
/// bands, raw Allan).
pub fn floors(
    layout: &StatLayout,
    model: &GyroModel,
    mc_mean: &StatSet,
) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let tau0 = layout.tau0_s();
    let (terms, theta) = model_spectral_terms(model);
    let lb = LevelBasis::new(&layout.lo, &layout.hi, tau0, &layout.levels, &terms);
    let w: Vec<f64> = (0..layout.levels.len())
        .map(|j| compare::sd_log_chi2(lb.edf(j, &theta, layout.n_coef[j] as f64)))
        .collect();
    let n_phase = layout.n_samples as u64 + 1;
    let slope_alpha = |v: &[f64], i: usize, modified: bool| -> i32 {
        let ms = &layout.ms;
        let (a, b) = if i == 0 {
            (0, 1.min(ms.len() - 1))
        } else if i + 1 >= ms.len() {
            (i - 1, i)
        } else {
            (i - 1, i + 1)
        };
        if a == b || !(v[a] > 0.0 && v[b] > 0.0) {
            return 0;
        }
        let mu = (v[b] / v[a]).ln() / ((ms[b] as f64) / (ms[a] as f64)).ln();
        if modified {
            (-mu - 1.0).round().clamp(-2.0, 2.0) as i32
        } else if mu <= -1.5 {
            2
        } else {
            (-mu - 1.0).round().clamp(-2.0, 0.0) as i32
        }
    };
    let m: Vec<f64> = (0..layout.ms.len())
        .map(|i| {
            let a = slope_alpha(&mc_mean.mvar, i, true);
            compare::sd_log_chi2(edf_for_stat(Stat::Mdev, a, layout.ms[i], n_phase))
        })
        .collect();
    let o: Vec<f64> = (0..layout.ms.len())
        .map(|i| {
            let a = slope_alpha(&mc_mean.avar, i, false);
            compare::sd_log_chi2(edf_for_stat(Stat::Oadev, a, layout.ms[i], n_phase))
        })
        .collect();
    // Welch: EDF 2K/(1 + 2 c^2) per bin (Hann, 50 %: c = 1/3); adjacent bins
    // correlated (periodogram correlation 4/9 at lag 1, 1/36 at lag 2)
    let k = layout.welch_segments as f64;
    let nu_bin = 2.0 * k / (1.0 + 2.0 / 9.0);
    let p: Vec<f64> = layout
        .bands
        .iter()
        .map(|b| {
            let nb = b.bins.len() as f64;
            let eff = if nb > 1.0 {
                nb / (1.0 + 2.0 * 4.0 / 9.0 + 2.0 / 18.0)
            } else {
                1.0
            };
            compare::sd_log_chi2(nu_bin * eff.max(1.0))
        })
        .collect();
    (w, m, p, o)
}

/// All compared points of one reference (wavelet, MDEV, spectral bands, raw
/// Allan, kurtosis).
pub fn all_points(
    layout: &StatLayout,
    model: &GyroModel,
    obs: &StatSet,
    runs: &[StatSet],
    kurt_taus: &[(f64, f64)],
) -> Vec<Point> {
    let tau0 = layout.tau0_s();
    let mean = mean_stats(runs);
    let (fw, fm, fp, _) = floors(layout, model, &mean);
    let mut pts = Vec::new();
    let tw: Vec<(f64, f64)> = layout
        .levels
        .iter()
        .map(|&j| (tau0 * 2f64.powi(j as i32 - 1), tau0 * 2f64.powi(j as i32)))
        .collect();
    // white quantization share of each wavelet level and spectral band
    let q2 = model.quantization_q_arcsec().powi(2);
    let qn_w = LevelBasis::new(
        &layout.lo,
        &layout.hi,
        tau0,
        &layout.levels,
        &[SpectralTerm::WhiteAngle],
    );
    let r: Vec<&[f64]> = runs.iter().map(|s| s.wvar.as_slice()).collect();
    let mut wp = compare::points(Family::Wavelet, &obs.wvar, &r, &fw, &tw);
    for p in &mut wp {
        p.qn_dominated = q2 * qn_w.phi[p.index][0] > 0.5 * p.model_mean;
    }
    pts.extend(wp);
    let tm: Vec<(f64, f64)> = layout
        .ms
        .iter()
        .map(|&m| (m as f64 * tau0, m as f64 * tau0))
        .collect();
    let r: Vec<&[f64]> = runs.iter().map(|s| s.mvar.as_slice()).collect();
    pts.extend(compare::points(Family::Mdev, &obs.mvar, &r, &fm, &tm));
    let tp: Vec<(f64, f64)> = layout
        .bands
        .iter()
        .map(|b| (0.5 / b.f_hi_hz, 0.5 / b.f_lo_hz))
        .collect();
    let r: Vec<&[f64]> = runs.iter().map(|s| s.band_psd.as_slice()).collect();
    let mut sp = compare::points(Family::Spectrum, &obs.band_psd, &r, &fp, &tp);
    for p in &mut sp {
        let b = &layout.bands[p.index];
        let qn: f64 = b
            .bins
            .iter()
            .map(|&k| 8.0 * q2 * (PI * layout.bin_hz(k) * tau0).sin().powi(2) / tau0)
            .sum::<f64>()
            / b.bins.len() as f64;
        p.qn_dominated = qn > 0.5 * p.model_mean;
    }
    pts.extend(sp);
    // the raw Allan variance only supports the claim that an effect is hidden
    // there: its band is the Monte-Carlo spread alone (no conservative floor)
    let r: Vec<&[f64]> = runs.iter().map(|s| s.avar.as_slice()).collect();
    let no_floor = vec![0.0; obs.avar.len()];
    pts.extend(compare::points(
        Family::RawAllan,
        &obs.avar,
        &r,
        &no_floor,
        &tm,
    ));
    let k = kurt_taus.len();
    if k > 0 && obs.kurtosis.len() >= k {
        let r: Vec<&[f64]> = runs.iter().map(|s| &s.kurtosis[..k]).collect();
        pts.extend(compare::linear_points(
            Family::Kurtosis,
            &obs.kurtosis[..k],
            &r,
            KURTOSIS_SD_FLOOR,
            kurt_taus,
        ));
    }
    pts
}
