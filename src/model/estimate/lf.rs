//! The low-frequency fit's observations: which wavelet levels carry only
//! low-frequency noise (the QN-band cut), the rows of the linear model for a
//! set of spectral terms, and the EDF of each row under a fitted spectrum.

use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::{AllanObs, CUT_RISE_Z, TRIM_EXCESS_Z};
use crate::model::fit::{LevelObs, ml_theta};
use crate::model::wvar::{Domain, LevelBasis, SpectralTerm};

/// Everything the low-frequency fit reads, for any set of terms.
pub(super) struct Lf<'a> {
    pub tau0: f64,
    pub dec_lo: &'a [f64],
    pub dec_hi: &'a [f64],
    /// Usable rate-domain levels, fine to deep.
    pub levels: Vec<LevelObs>,
    /// Long-tau Allan points kept for the fit.
    pub allan: Vec<AllanObs>,
    /// Q^2 from the first angle-domain pass (subtracted from the Allan points).
    pub q2_first: f64,
    /// Whether the rows carry a ramp column (there are Allan points).
    pub ramp_col: bool,
}

/// Rows of the linear model: expected value per unit theta, observation, EDF.
pub(super) struct Rows {
    pub phi: Vec<Vec<f64>>,
    pub y: Vec<f64>,
    pub edf0: Vec<f64>,
}

impl Lf<'_> {
    /// The wavelet-level basis of `terms` over every usable level.
    pub fn basis(&self, terms: &[SpectralTerm]) -> LevelBasis {
        let ids: Vec<u32> = self.levels.iter().map(|l| l.level).collect();
        LevelBasis::new(self.dec_lo, self.dec_hi, self.tau0, &ids, terms)
    }

    /// The rows of [`Lf::basis`] alone (no Gram matrices: for fits whose EDFs
    /// are held fixed).
    pub fn bands(&self, terms: &[SpectralTerm]) -> Vec<Vec<f64>> {
        let ids: Vec<u32> = self.levels.iter().map(|l| l.level).collect();
        LevelBasis::bands_in(
            self.dec_lo,
            self.dec_hi,
            self.tau0,
            &ids,
            terms,
            Domain::Rate,
        )
    }

    /// Rows for levels `from..` (of the basis rows `phi`) then the Allan
    /// points; the ramp column (when there are Allan points) comes after the
    /// terms. Quantization is measured in the angle domain: on these levels its
    /// white-angle column is a free nuisance that absorbs what leaks below the
    /// QN band, and on the Allan points the angle-domain Q is subtracted.
    pub fn rows(&self, terms: &[SpectralTerm], phi: &[Vec<f64>], from: usize) -> Rows {
        let mut phi: Vec<Vec<f64>> = phi[from..].to_vec();
        if self.ramp_col {
            phi.iter_mut().for_each(|r| r.push(0.0));
        }
        let mut y: Vec<f64> = self.levels[from..].iter().map(|l| l.mean_sq).collect();
        let mut edf0: Vec<f64> = self.levels[from..].iter().map(|l| l.n_coef).collect();
        for a in &self.allan {
            let mut row: Vec<f64> = terms.iter().map(|t| t.allan_var(a.m, self.tau0)).collect();
            let qn = self.q2_first.max(0.0) * row[0];
            row[0] = 0.0;
            if self.ramp_col {
                let tau = a.m as f64 * self.tau0;
                row.push(0.5 * tau * tau);
            }
            phi.push(row);
            y.push((a.avar - qn).max(1e-300));
            edf0.push(a.edf(0));
        }
        Rows { phi, y, edf0 }
    }

    /// EDF of row `j` (levels `from..`, then Allan points) under `theta`: the
    /// level's spectral EDF, or the Allan point's EDF for the noise type of the
    /// term that dominates it.
    pub fn edf<'b>(
        &'b self,
        terms: &'b [SpectralTerm],
        basis: &'b LevelBasis,
        from: usize,
        phi: &'b [Vec<f64>],
    ) -> impl Fn(usize, &[f64]) -> f64 + 'b {
        let nl = self.levels.len() - from;
        move |j: usize, theta: &[f64]| -> f64 {
            if j < nl {
                return basis.edf(
                    from + j,
                    &theta[..terms.len()],
                    self.levels[from + j].n_coef,
                );
            }
            let a = &self.allan[j - nl];
            let tau = a.m as f64 * self.tau0;
            let dom = (0..terms.len())
                .max_by(|&p, &q| (theta[p] * phi[j][p]).total_cmp(&(theta[q] * phi[j][q])))
                .unwrap_or(1);
            a.edf(terms[dom].alpha_at(tau))
        }
    }

    /// Correlation of the rows (levels `from..`, then the Allan points) under
    /// `theta`. Overlapping Allan variances of neighbouring octaves share
    /// most of their band: their correlation is `int S^2 G_a G_b / sqrt(int
    /// S^2 G_a^2 int S^2 G_b^2)` over the Allan transfer functions `G` and
    /// the fitted rate spectrum `S` (0.6-0.7 under flicker noise). The
    /// wavelet levels are uncorrelated with each other (an orthonormal DWT)
    /// and nearly so with the Allan points, which start an octave beyond the
    /// deepest level (0.03-0.04 by the same integral): they are left
    /// independent.
    pub fn correlation(&self, terms: &[SpectralTerm], from: usize, theta: &[f64]) -> Vec<Vec<f64>> {
        let nl = self.levels.len() - from;
        let n = nl + self.allan.len();
        let mut r: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
            .collect();
        let Some(m_max) = self.allan.iter().map(|a| a.m).max() else {
            return r;
        };
        // log-spaced nodes from well below the longest tau's band to Nyquist
        let (lo, per_octave) = ((0.0625 / m_max as f64).ln(), 32.0);
        let steps = ((0.5f64.ln() - lo) / std::f64::consts::LN_2 * per_octave).ceil() as usize;
        let dln = (0.5f64.ln() - lo) / steps as f64;
        let mut s2g: Vec<Vec<f64>> = vec![Vec::with_capacity(steps + 1); self.allan.len()];
        let mut weights = Vec::with_capacity(steps + 1);
        for i in 0..=steps {
            let nu = (lo + i as f64 * dln).exp();
            let s: f64 = terms
                .iter()
                .enumerate()
                .map(|(k, t)| {
                    let th = if k == 0 {
                        self.q2_first.max(0.0)
                    } else {
                        theta[k]
                    };
                    th * t.psd_cs(nu, self.tau0)
                })
                .sum::<f64>()
                .max(0.0);
            let end = if i == 0 || i == steps { 0.5 } else { 1.0 };
            weights.push(end * nu * dln);
            for (a, out) in self.allan.iter().zip(s2g.iter_mut()) {
                out.push(s * allan_gain(a.m, nu));
            }
        }
        let dot = |a: &[f64], b: &[f64]| -> f64 {
            a.iter()
                .zip(b)
                .zip(&weights)
                .map(|((x, y), w)| x * y * w)
                .sum()
        };
        for a in 0..self.allan.len() {
            for b in a + 1..self.allan.len() {
                let den = (dot(&s2g[a], &s2g[a]) * dot(&s2g[b], &s2g[b])).sqrt();
                let rho = if den > 0.0 {
                    dot(&s2g[a], &s2g[b]) / den
                } else {
                    0.0
                };
                r[nl + a][nl + b] = rho;
                r[nl + b][nl + a] = rho;
            }
        }
        r
    }

    /// First level index free of QN. Model-free: every low-frequency term
    /// gives detail variances that are flat (ARW) or fall towards the fine
    /// levels (flicker, RRW, Gauss-Markov, a readout filter), while QN makes
    /// them rise. Walk from the deepest level towards the fine ones and stop
    /// at the first level significantly ([`CUT_RISE_Z`] sigma) above its
    /// deeper neighbour and the level beyond it (one deep level low by chance
    /// must not stop the walk; the deepest pair must rise twice as clearly).
    pub fn qn_cut(&self) -> usize {
        let lv = &self.levels;
        let rise = |a: &LevelObs, b: &LevelObs| {
            (a.mean_sq / b.mean_sq).ln() / (2.0 / a.n_coef + 2.0 / b.n_coef).sqrt()
        };
        let mut from = lv.len();
        while from > 0 {
            let j = from - 1;
            if from < lv.len() {
                let confirmed = if from + 1 >= lv.len() {
                    rise(&lv[j], &lv[from]) > 2.0 * CUT_RISE_Z
                } else {
                    rise(&lv[j], &lv[from + 1]) > CUT_RISE_Z
                };
                if rise(&lv[j], &lv[from]) > CUT_RISE_Z && confirmed {
                    break;
                }
            }
            from = j;
        }
        from
    }

    /// Drop the finest kept level while it exceeds the fit of the deeper ones
    /// by [`TRIM_EXCESS_Z`] sigma (a QN tail the neighbour test missed, not
    /// white in angle); at most twice, so a misspecified model cannot eat the
    /// levels.
    pub fn trim(&self, terms: &[SpectralTerm], basis: &LevelBasis, mut from: usize) -> usize {
        for _ in 0..2 {
            if self.levels.len() - from < 3 {
                break;
            }
            let r = self.rows(terms, &basis.phi, from + 1);
            let mut th = ml_theta(
                &r.phi,
                &r.y,
                &r.edf0,
                &self.edf(terms, basis, from + 1, &r.phi),
            );
            th[0] = 0.0;
            let mu = basis.mean(from, &th);
            let nu = basis.edf(from, &th[..terms.len()], self.levels[from].n_coef);
            // the prediction is itself uncertain: about as much as a variance
            // measured on all the deeper levels' coefficients together
            let n_deeper: f64 = self.levels[from + 1..].iter().map(|l| l.n_coef).sum();
            let z = (self.levels[from].mean_sq / mu - 1.0) / (2.0 / nu + 2.0 / n_deeper).sqrt();
            if mu > 0.0 && z > TRIM_EXCESS_Z {
                from += 1;
            } else {
                break;
            }
        }
        from
    }

    /// Upper bounds on every term's theta from the levels alone (all shares
    /// are positive): one-sided chi-square, Bonferroni over levels. Used when
    /// the record is too short to separate the terms from QN.
    pub fn level_bounds(&self, basis: &LevelBasis, k: usize) -> Vec<f64> {
        let alpha = 0.05 / self.levels.len() as f64;
        let mut up = vec![f64::INFINITY; k];
        for (j, l) in self.levels.iter().enumerate() {
            let nu = l.n_coef.max(1.0);
            let chi = ChiSquared::new(nu)
                .map(|c| c.inverse_cdf(alpha))
                .unwrap_or(0.0);
            if chi <= 0.0 {
                continue;
            }
            let y_up = l.mean_sq * nu / chi;
            for (kk, u) in up.iter_mut().enumerate().skip(1) {
                let p = basis.phi[j][kk];
                if p > 0.0 {
                    *u = u.min(y_up / p);
                }
            }
        }
        up
    }
}

/// Power gain of the overlapping Allan variance at `m` samples on the rate,
/// `sin^4(pi nu m) / (pi nu m)^2` up to a constant; past four cycles its
/// envelope with `sin^4` at its mean 3/8 (the nodes no longer resolve it).
fn allan_gain(m: u64, nu: f64) -> f64 {
    let x = std::f64::consts::PI * nu * m as f64;
    if nu * m as f64 > 4.0 {
        0.375 / (x * x)
    } else {
        x.sin().powi(4) / (x * x)
    }
}

/// Zero the columns beyond the nuisance and ARW (a saturated fit: no more
/// observations than terms, so only N is fitted and the others bounded).
pub(super) fn saturate(phi: &mut [Vec<f64>]) {
    for r in phi.iter_mut() {
        for c in r.iter_mut().skip(2) {
            *c = 0.0;
        }
    }
}
