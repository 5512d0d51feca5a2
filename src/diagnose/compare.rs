//! Comparison of the recording's statistics with the model's Monte-Carlo
//! reference: per-point z-scores on the log scale, the detection threshold,
//! mismatch regions on the tau axis and the chi-square summary.
//!
//! z-score of a point: `(ln x_obs - mean_r ln x_r) / (s sqrt(1 + 1/R))`, with
//! `x_r` the R Monte-Carlo values and `s` the larger of their standard
//! deviation and an analytic floor (chi-square EDF of the estimator under the
//! model's Gaussian terms). The floor protects against a small-R spread that
//! happens to come out narrow; the `1 + 1/R` accounts for the error of the
//! Monte-Carlo mean itself. The recording and the runs go through the same
//! estimator, so the mean of logs is the right centre whatever the estimator's
//! bias.

use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

/// Which statistic a point belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// sym8 detail variance of the rate at one level.
    Wavelet,
    /// Modified Allan variance.
    Mdev,
    /// Quarter-octave band of the Welch spectrum.
    Spectrum,
    /// Overlapping Allan variance of the raw rate (reported, not used to detect).
    RawAllan,
    /// Excess kurtosis of the low-passed rate at a model term's time scale
    /// (linear scale; the two-level test of Gauss-Markov versus telegraph).
    Kurtosis,
}

impl Family {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Family::Wavelet => "wavelet",
            Family::Mdev => "mdev",
            Family::Spectrum => "spectrum",
            Family::RawAllan => "raw_allan",
            Family::Kurtosis => "kurtosis",
        }
    }
}

/// One compared point.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    pub family: Family,
    /// Index of the point in its family's input (level, tau, band, term).
    pub index: usize,
    /// Tau interval the point speaks for, s.
    pub tau_lo_s: f64,
    pub tau_hi_s: f64,
    /// Observed value (variance or PSD, (arcsec/s)^2 or per Hz).
    pub obs: f64,
    /// Monte-Carlo mean of the model.
    pub model_mean: f64,
    /// Mean and standard deviation of the log (after the floor, before the 1/R term).
    pub mean_log: f64,
    pub sd_log: f64,
    /// Runs behind the reference.
    pub runs: usize,
    pub z: f64,
    /// The model's quantization noise carries more than half of the expected
    /// value: such points share one common random driver (the counter's pulse
    /// train) and are never combined in scan windows.
    pub qn_dominated: bool,
}

impl Point {
    /// 95 % band of the model, linear units.
    pub fn band95(&self) -> (f64, f64) {
        if self.family == Family::Kurtosis {
            let s = 1.96 * self.sd_log * (1.0 + 1.0 / self.runs as f64).sqrt();
            return (self.mean_log - s, self.mean_log + s);
        }
        let s = self.sd_log * (1.0 + 1.0 / self.runs as f64).sqrt();
        (
            (self.mean_log - 1.96 * s).exp(),
            (self.mean_log + 1.96 * s).exp(),
        )
    }
}

/// Build the points of one family. `runs[r][i]` is run r's value at point i;
/// `floor_sd[i]` the analytic floor of the log standard deviation; `taus[i]`
/// the tau interval.
pub fn points(
    family: Family,
    obs: &[f64],
    runs: &[&[f64]],
    floor_sd: &[f64],
    taus: &[(f64, f64)],
) -> Vec<Point> {
    let r = runs.len();
    (0..obs.len())
        .filter_map(|i| {
            let vals: Vec<f64> = runs.iter().map(|v| v[i]).collect();
            if !(obs[i] > 0.0 && obs[i].is_finite())
                || vals.iter().any(|v| !(*v > 0.0 && v.is_finite()))
            {
                return None;
            }
            let logs: Vec<f64> = vals.iter().map(|v| v.ln()).collect();
            let mean_log = logs.iter().sum::<f64>() / r as f64;
            let var = if r > 1 {
                logs.iter().map(|l| (l - mean_log).powi(2)).sum::<f64>() / (r - 1) as f64
            } else {
                0.0
            };
            let sd = var.sqrt().max(floor_sd[i]);
            let z = gamma_z(obs[i].ln(), mean_log, sd * (1.0 + 1.0 / r as f64).sqrt());
            Some(Point {
                family,
                index: i,
                tau_lo_s: taus[i].0,
                tau_hi_s: taus[i].1,
                obs: obs[i],
                model_mean: vals.iter().sum::<f64>() / r as f64,
                mean_log,
                sd_log: sd,
                runs: r,
                z,
                qn_dominated: false,
            })
        })
        .collect()
}

/// Normal score of an observed log-variance `ln_obs` when the log of the
/// estimate has mean `mean_log` and standard deviation `sd` and the estimate
/// itself is Gamma (scaled chi-square) distributed: `nu` solves
/// `trigamma(nu/2) = sd^2`, the scale puts `E[ln x]` at `mean_log`, and the
/// exact chi-square tail probability is mapped to a z. This keeps the left
/// tail of a few-EDF variance (a long tail on the log scale) honest.
pub fn gamma_z(ln_obs: f64, mean_log: f64, sd: f64) -> f64 {
    let norm = Normal::new(0.0, 1.0).expect("standard normal");
    let nu = nu_from_log_var(sd * sd);
    if !(sd > 0.0) {
        return 0.0;
    }
    if !(nu < 1e6) {
        return (ln_obs - mean_log) / sd;
    }
    let Ok(chi) = ChiSquared::new(nu) else {
        return (ln_obs - mean_log) / sd;
    };
    // E[ln(chi2_nu / nu)] = digamma(nu/2) - ln(nu/2)
    let e_ln = statrs::function::gamma::digamma(nu / 2.0) - (nu / 2.0).ln();
    let u = (ln_obs - mean_log + e_ln).exp(); // observed / scale, ~ chi2_nu / nu
    let cdf = chi.cdf(nu * u);
    let sf = chi.sf(nu * u);
    if cdf < 0.5 {
        norm.inverse_cdf(cdf.max(1e-300))
    } else {
        -norm.inverse_cdf(sf.max(1e-300))
    }
}

/// Points of a statistic compared on the linear scale with a normal law
/// (the kurtosis): `z = (obs - mean) / (max(sd, floor) sqrt(1 + 1/R))`.
/// `mean_log`/`sd_log` then hold the mean and sd themselves.
pub fn linear_points(
    family: Family,
    obs: &[f64],
    runs: &[&[f64]],
    floor_sd: f64,
    taus: &[(f64, f64)],
) -> Vec<Point> {
    let r = runs.len();
    (0..obs.len())
        .filter_map(|i| {
            let vals: Vec<f64> = runs
                .iter()
                .map(|v| v[i])
                .filter(|v| v.is_finite())
                .collect();
            if !obs[i].is_finite() || vals.len() < 2 {
                return None;
            }
            let n = vals.len() as f64;
            let mean = vals.iter().sum::<f64>() / n;
            let sd = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0))
                .sqrt()
                .max(floor_sd);
            Some(Point {
                family,
                index: i,
                tau_lo_s: taus[i].0,
                tau_hi_s: taus[i].1,
                obs: obs[i],
                model_mean: mean,
                mean_log: mean,
                sd_log: sd,
                runs: r,
                z: (obs[i] - mean) / (sd * (1.0 + 1.0 / n).sqrt()),
                qn_dominated: false,
            })
        })
        .collect()
}

/// Two-sided normal quantile with a Bonferroni correction: the |z| above which
/// one of `n` points fires with probability `alpha` under the model.
pub fn bonferroni_z(alpha: f64, n: usize) -> f64 {
    let p = alpha / (2.0 * n.max(1) as f64);
    let norm = Normal::new(0.0, 1.0).expect("standard normal");
    norm.inverse_cdf(1.0 - p)
}

/// A test of the scan: one point, or a window of adjacent points of one family
/// combined by Stouffer's rule `z = sum z_i / sqrt(k)` (valid for the wavelet
/// levels and the spectral bands, whose estimates are nearly independent,
/// except where quantization noise dominates: those points are tested singly).
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    pub family: Family,
    /// Indices (into the family's point list) covered.
    pub first: usize,
    pub last: usize,
    pub z: f64,
}

/// Widest window of wavelet levels / spectral bands in the scan.
pub const MAX_WINDOW_WAVELET: usize = 6;
pub const MAX_WINDOW_SPECTRUM: usize = 8;

/// All tests of the scan over one family's points (in their natural order).
pub fn scan(family: Family, pts: &[&Point]) -> Vec<Window> {
    let max_w = match family {
        Family::Wavelet => MAX_WINDOW_WAVELET,
        Family::Spectrum => MAX_WINDOW_SPECTRUM,
        _ => 1,
    };
    let mut out = Vec::new();
    for w in 1..=max_w.min(pts.len()) {
        for a in 0..=pts.len() - w {
            if w > 1 && pts[a..a + w].iter().any(|p| p.qn_dominated) {
                continue;
            }
            let s: f64 = pts[a..a + w].iter().map(|p| p.z).sum();
            out.push(Window {
                family,
                first: a,
                last: a + w - 1,
                z: s / (w as f64).sqrt(),
            });
        }
    }
    out
}

/// Result of the detection scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Detection {
    pub regions: Vec<Region>,
    /// Bonferroni threshold on |z| over all tests.
    pub z_crit: f64,
    pub n_tests: usize,
    /// Largest |z| of any test.
    pub max_abs_z: f64,
}

/// Scan the wavelet levels and spectral bands (windows) and the MDEV points
/// (single) at family-wise level `alpha`; the regions are the tau spans of the
/// significant tests, each trimmed to its points that lean the same way
/// (`|z_i| > 1` with the window's sign).
pub fn detect(points: &[&Point], alpha: f64) -> Detection {
    let mut fams: Vec<(Family, Vec<&Point>)> = Vec::new();
    for f in [
        Family::Wavelet,
        Family::Mdev,
        Family::Spectrum,
        Family::Kurtosis,
    ] {
        let v: Vec<&Point> = points.iter().copied().filter(|p| p.family == f).collect();
        if !v.is_empty() {
            fams.push((f, v));
        }
    }
    let tests: Vec<(usize, Window)> = fams
        .iter()
        .enumerate()
        .flat_map(|(i, (f, v))| scan(*f, v).into_iter().map(move |w| (i, w)))
        .collect();
    let z_crit = bonferroni_z(alpha, tests.len());
    let max_abs_z = tests.iter().map(|t| t.1.z.abs()).fold(0.0, f64::max);
    let mut spans: Vec<(f64, f64, f64)> = Vec::new();
    for (i, w) in &tests {
        if w.z.abs() <= z_crit {
            continue;
        }
        let v = &fams[*i].1;
        let sign = w.z.signum();
        let members: Vec<&&Point> = v[w.first..=w.last]
            .iter()
            .filter(|p| p.z * sign > 1.0 || w.first == w.last)
            .collect();
        if members.is_empty() {
            continue;
        }
        let lo = members
            .iter()
            .map(|p| p.tau_lo_s)
            .fold(f64::INFINITY, f64::min);
        let hi = members.iter().map(|p| p.tau_hi_s).fold(0.0, f64::max);
        spans.push((lo, hi, w.z));
    }
    Detection {
        regions: merge(spans),
        z_crit,
        n_tests: tests.len(),
        max_abs_z,
    }
}

pub(crate) fn merge(mut hits: Vec<(f64, f64, f64)>) -> Vec<Region> {
    hits.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<Region> = Vec::new();
    for (lo, hi, z) in hits {
        if let Some(last) = out.last_mut()
            && lo <= last.tau_max_s * std::f64::consts::SQRT_2
        {
            last.tau_max_s = last.tau_max_s.max(hi);
            if z.abs() > last.max_z.abs() {
                last.max_z = z;
            }
            continue;
        }
        out.push(Region {
            tau_min_s: lo,
            tau_max_s: hi,
            max_z: z,
        });
    }
    out
}

/// A tau range where the recording leaves the model's band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Region {
    pub tau_min_s: f64,
    pub tau_max_s: f64,
    /// The z of largest magnitude inside (signed: > 0 means the recording is noisier).
    pub max_z: f64,
}

/// Merge the tau intervals of the points with `|z| > z_crit` into regions
/// (intervals closer than a factor sqrt(2) are joined).
pub fn regions(points: &[&Point], z_crit: f64) -> Vec<Region> {
    merge(
        points
            .iter()
            .filter(|p| p.z.abs() > z_crit)
            .map(|p| (p.tau_lo_s, p.tau_hi_s, p.z))
            .collect(),
    )
}

/// Chi-square per degree of freedom of a set of z-scores with `n_par` fitted parameters.
pub fn chi2_per_dof(points: &[&Point], n_par: usize) -> f64 {
    let s: f64 = points.iter().map(|p| p.z * p.z).sum();
    let dof = (points.len() as f64 - n_par as f64).max(1.0);
    s / dof
}

/// Trigamma function: recurrence up to x >= 10, then the asymptotic series
/// `1/x + 1/(2x^2) + sum B_2k / x^(2k+1)` through B_10 (truncation error below
/// 3e-14 at x = 10).
pub fn trigamma(mut x: f64) -> f64 {
    let mut acc = 0.0;
    while x < 10.0 {
        acc += 1.0 / (x * x);
        x += 1.0;
    }
    let r = 1.0 / (x * x);
    // Bernoulli numbers B2..B10
    let series =
        r * (1.0 / 6.0 + r * (-1.0 / 30.0 + r * (1.0 / 42.0 + r * (-1.0 / 30.0 + r * 5.0 / 66.0))));
    acc + 1.0 / x + 0.5 * r + series / x
}

/// Standard deviation of `ln(chi2_nu / nu)`: `sqrt(trigamma(nu/2))`.
pub fn sd_log_chi2(nu: f64) -> f64 {
    if nu.is_finite() && nu > 0.0 {
        trigamma(nu / 2.0).sqrt()
    } else {
        0.0
    }
}

/// EDF whose `ln(chi2/nu)` has variance `var` (inverse of trigamma(nu/2) = var).
pub fn nu_from_log_var(var: f64) -> f64 {
    if !(var > 0.0) {
        return f64::INFINITY;
    }
    // trigamma is decreasing: bisect on log nu
    let (mut a, mut b) = (1e-3f64.ln(), 1e9f64.ln());
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if trigamma(m.exp() / 2.0) > var {
            a = m;
        } else {
            b = m;
        }
    }
    (0.5 * (a + b)).exp()
}

/// A narrow spectral line found in the recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineHit {
    /// Bin of the whole record's periodogram (`f = bin / T`).
    pub bin: usize,
    pub f_hz: f64,
    /// Whitened periodogram over its local level.
    pub ratio: f64,
    /// Equivalent z of the Bonferroni-corrected tail probability.
    pub z: f64,
}
