//! Quantization from the angle-domain levels, as the paper reads it from the
//! noise component, made exact: QN is white-or-periodic noise in *angle*, so
//! its variance is the high-frequency energy of the angle signal,
//! `Q^2 = sum_j 2^{-j} v_j` over the angle-domain detail levels (Parseval for
//! an orthonormal DWT), minus the small share of the low-frequency terms.
//! This holds whatever the shape of the readout error: white (a well-dithered
//! counter) or the sawtooth of a slowly moving angle read by an integer
//! counter, whose Allan variance oscillates around `3Q^2/tau^2`.

use super::{Coefficient, EstimatorInput, MIN_BATCHES, sawtooth, usable};
use crate::model::fit::LevelObs;
use crate::model::wvar::{Domain, LevelBasis, SpectralTerm};

/// `Q^2` and its standard deviation, arcsec^2, with the low-frequency terms
/// `terms[1..]` at `theta_lf[1..]` subtracted (`theta_lf[0]`, the white-angle
/// nuisance, is not). `final_read`: the sum also ends at a level, past the
/// counter's sawtooth lines, that holds far more than white quantization
/// noise continued ([`MAX_EXCESS`]): low-frequency noise the fitted terms
/// miss (a Gauss-Markov bias, terms fitted below their size) would
/// otherwise be read as quantization. The first reading, which places the
/// quantization band for the low-frequency fit, sums as far as the terms'
/// share allows.
pub(super) fn q_from_angle(
    input: &EstimatorInput,
    terms: &[SpectralTerm],
    theta_lf: &[f64],
    final_read: bool,
) -> QReading {
    let angle: Vec<LevelObs> = input.angle_levels.iter().copied().filter(usable).collect();
    if angle.is_empty() {
        return QReading {
            q2: 0.0,
            sd: f64::INFINITY,
        };
    }
    let ids: Vec<u32> = angle.iter().map(|l| l.level).collect();
    let b = LevelBasis::new_in(
        input.dec_lo,
        input.dec_hi,
        input.tau0_s,
        &ids,
        terms,
        Domain::Angle,
    );
    let lf_share = |j: usize| -> f64 { (1..terms.len()).map(|k| theta_lf[k] * b.phi[j][k]).sum() };
    let lines = match (&input.counter, final_read) {
        (_, false) => u32::MAX,
        (Some(c), true) => sawtooth::deepest_line_level(c),
        (None, true) => 0,
    };
    let mut jmax = 1u32;
    let (mut q2, mut var) = (0.0, 0.0);
    for (j, l) in angle.iter().enumerate() {
        let w = 2f64.powi(-(l.level as i32));
        let lf = lf_share(j);
        if lf > 0.5 * l.mean_sq && l.level > 1 {
            // beyond the QN band: the angle here is mostly random walk
            break;
        }
        if l.level > lines.max(2)
            && w * (l.mean_sq - lf) > MAX_EXCESS * white_share(q2, jmax, l.level)
        {
            // beyond the counter's lines, far more than white QN continued:
            // low-frequency noise the fitted terms do not hold
            break;
        }
        q2 += w * (l.mean_sq - lf);
        jmax = l.level;
        var += w * w * 2.0 * l.mean_sq * l.mean_sq / l.n_coef;
    }
    let norm = 1.0 - 2f64.powi(-(jmax as i32));
    // The chi-square variance assumes the QN energy is stationary. A counter
    // read with little dither is not: the readout error's variance depends on
    // where the true angle sits within a pulse, and a slowly moving angle
    // visits few of those places. The spread of the same statistic over blocks
    // of the record (batch means) sees that; the larger variance is used.
    let per_block: Vec<f64> = input
        .angle_blocks
        .iter()
        .map(|blk| {
            let mut q = 0.0;
            for (j, l) in angle
                .iter()
                .enumerate()
                .take_while(|(_, l)| l.level <= jmax)
            {
                let ms = blk
                    .iter()
                    .find(|x| x.level == l.level)
                    .map_or(l.mean_sq, |x| x.mean_sq);
                q += 2f64.powi(-(l.level as i32)) * (ms - lf_share(j));
            }
            q
        })
        .collect();
    var = var.max(batch_means_var(per_block));
    let q2 = q2 / norm;
    let q2 = match &input.counter {
        Some(c) => sawtooth_corrected(input, c, q2, theta_lf, jmax),
        None => q2,
    };
    QReading {
        q2,
        sd: var.sqrt() / norm,
    }
}

/// A reading of `Q^2` from the angle-domain levels, arcsec^2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct QReading {
    pub q2: f64,
    /// Its standard deviation.
    pub sd: f64,
}

/// `q2` read from levels `1..=jmax` with the counter's sawtooth lines
/// counted as they are ([`sawtooth::excess`], which depends on `q2`, the
/// dither: a few fixed-point steps).
fn sawtooth_corrected(
    input: &EstimatorInput,
    c: &sawtooth::Counter,
    q2: f64,
    theta_lf: &[f64],
    jmax: u32,
) -> f64 {
    let th = |k: usize| theta_lf.get(k).copied().unwrap_or(0.0).max(0.0);
    let tau0 = input.tau0_s;
    let step_var = th(1) * tau0;
    // the rate's wander over one sawtooth period (arcsec/s): bias
    // instability, and random walk over the period
    let rate = c.pulses_per_sample.abs() * c.pulse_arcsec / tau0;
    let period_s = tau0 / c.pulses_per_sample.abs().max(1e-300);
    let wander = th(2).sqrt() + (th(3) * period_s / 3.0).sqrt();
    let add_back = wander <= sawtooth::MAX_WANDER * rate;
    let (n, lo) = (input.n_samples, input.dec_lo);
    let mut q = q2;
    for _ in 0..4 {
        q = q2 - sawtooth::excess(c, q, step_var, jmax, lo, n, add_back);
    }
    q
}

/// A level past the counter's lines holding more than this many times the
/// share white quantization noise would give it ends the sum.
const MAX_EXCESS: f64 = 2.0;

/// The share of `Q^2` white quantization noise gives level `level`, with
/// `q2` the sum over levels `1..=jmax`.
fn white_share(q2: f64, jmax: u32, level: u32) -> f64 {
    q2 / (1.0 - 2f64.powi(-(jmax as i32))) * 2f64.powi(-(level as i32))
}

/// Flyvbjerg-Petersen blocking: the batch-means variance of the mean grows
/// with the block length until blocks outlast the correlation; the largest
/// over block lengths that still leave [`MIN_BATCHES`] blocks.
fn batch_means_var(mut batches: Vec<f64>) -> f64 {
    let mut var: f64 = 0.0;
    while batches.len() >= MIN_BATCHES {
        let k = batches.len() as f64;
        let mean = batches.iter().sum::<f64>() / k;
        let var_bm = batches.iter().map(|q| (q - mean).powi(2)).sum::<f64>() / (k * (k - 1.0));
        var = var.max(var_bm);
        batches = batches
            .chunks_exact(2)
            .map(|p| 0.5 * (p[0] + p[1]))
            .collect();
    }
    var
}

/// Q as a coefficient: a variance estimate with a near-normal sampling law
/// (thousands of coefficients), its standard deviation widened by `widen`;
/// an upper bound when not significant.
pub(super) fn coefficient(r: &QReading, widen: f64) -> Coefficient {
    let z = 1.959_964;
    let (q2, sd) = (r.q2, r.sd * widen);
    if q2 > z * sd {
        Coefficient {
            value: Some(q2.sqrt()),
            ci95: Some([(q2 - z * sd).max(0.0).sqrt(), (q2 + z * sd).sqrt()]),
            upper95: None,
        }
    } else {
        Coefficient {
            value: None,
            ci95: None,
            upper95: Some((q2.max(0.0) + 1.644_854 * sd).sqrt()),
        }
    }
}
