//! Phase 6b, a resonance where the narrowband check found an excess
//! ([`super::narrowband`]): its centre, width and power are fitted on the
//! whole record's periodogram by the Whittle likelihood, and the broadband
//! fit and the refinement are run again with it in the model.
//!
//! Around the excess (its span and as much again on each side) the
//! periodogram is averaged over groups of bins (each group's mean is a
//! Gamma variable with `n / 1.5` degrees of freedom of a Hann window), and
//! modelled as `c M(f) exp(beta x) + sigma^2 R(f; f0, w)`: `M` the model
//! under test's PSD with a free level `c` and tilt `beta` across the window
//! (`x` from -1/2 to 1/2: what a filter or a slope the model lacks does
//! there), `R` the unit-variance spectrum of [`crate::model::resonance`]. A
//! grid over `f0` and `w` with `(c, beta, sigma^2)` by Fisher scoring at
//! each node, then coordinate steps in `f0` and `w`; the intervals are the
//! inverse Fisher information's of all five.

use std::f64::consts::PI;

use super::AddedTerm;
use super::findings::{Edit, Finding, fmt_g};
use super::line_search::LineSpectrum;
use super::narrowband::{BINS_PER_DOF, Excess};
use crate::model::filter::ReadoutFilter;
use crate::model::resonance::Ar2;
use crate::model::wvar::SpectralTerm;
use crate::model::{GyroModel, Term};
use std::collections::BTreeMap;

use crate::units;

/// Groups the fitted window is averaged into (at most).
const GROUPS: usize = 600;
/// The 95 % point of chi-square with one degree of freedom.
pub const LR_1DOF_95: f64 = 3.84;

/// A fitted resonance (sigma before the readout filter it was fitted
/// through), with 95 % intervals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResonanceFit {
    pub centre_hz: f64,
    pub width_hz: f64,
    /// Standard deviation of the narrowband rate, deg/h.
    pub sigma_dph: f64,
    pub centre_ci95: [f64; 2],
    pub width_ci95: [f64; 2],
    pub sigma_ci95: [f64; 2],
    /// The background's level against the model (1 = as the model).
    pub background: f64,
    /// The resonance's PSD at zero frequency, (deg/h)^2/Hz, and its standard
    /// error from the fit: an AR(2) mode leaves a white tail below its centre
    /// (about peak / Q^2) that the wavelet variances cannot tell from angle
    /// random walk, so a white level refitted beside it carries this error.
    pub tail_psd: f64,
    pub tail_psd_sd: f64,
    /// The Whittle negative log-likelihood at the fit.
    pub nll: f64,
}

/// How the fit holds the resonance's white tail (its PSD at zero frequency,
/// (deg/h)^2/Hz).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tail {
    /// At or below the white level the wavelet variances measured.
    AtMost(f64),
    /// Exactly this (the white level left when the model's ARW is kept).
    Exactly(f64),
}

/// The periodogram averaged over groups of bins: frequency, mean power,
/// mean model PSD, degrees of freedom.
struct Groups {
    f: Vec<f64>,
    p: Vec<f64>,
    m: Vec<f64>,
    nu: Vec<f64>,
    /// The readout filter's power at `f`.
    h2: Vec<f64>,
}

fn groups(spec: &LineSpectrum, lo_hz: f64, hi_hz: f64, filter: Option<ReadoutFilter>) -> Groups {
    let df = spec.df();
    let last = spec.psd.len() - 1;
    let (a, b) = (
        ((lo_hz / df).ceil() as usize).max(1),
        ((hi_hz / df) as usize).min(last),
    );
    let size = ((b.saturating_sub(a)) / GROUPS).max(1);
    let mut g = Groups {
        f: vec![],
        p: vec![],
        m: vec![],
        nu: vec![],
        h2: vec![],
    };
    let mut k = a;
    while k + size <= b {
        let (mut sf, mut sp, mut sm, mut n) = (0.0, 0.0, 0.0, 0usize);
        for i in k..k + size {
            if spec.usable[i] && spec.psd[i].is_finite() {
                sf += i as f64 * df;
                sp += spec.psd[i];
                sm += spec.model_psd[i];
                n += 1;
            }
        }
        if n > 0 {
            let nf = n as f64;
            g.f.push(sf / nf);
            g.p.push(sp / nf);
            g.m.push(sm / nf);
            g.nu.push((nf / BINS_PER_DOF).max(1.0));
            g.h2.push(filter.map_or(1.0, |h| h.power(sf / nf / spec.fs_hz)));
        }
        k += size;
    }
    g
}

/// The unit-variance resonance PSD per Hz at each group's frequency, seen
/// through the group's filter power (`g.h2`).
fn shape(g: &Groups, f0: f64, w: f64, tau0: f64) -> Vec<f64> {
    let ar = Ar2::new(f0, w, tau0);
    g.f.iter()
        .zip(&g.h2)
        .map(|(&f, h2)| ar.psd_cs_cos((2.0 * PI * f * tau0).cos()) * tau0 * h2)
        .collect()
}

/// Whittle negative log-likelihood of `s` (the modelled PSD per group).
fn nll(g: &Groups, s: &[f64]) -> f64 {
    g.p.iter()
        .zip(s)
        .zip(&g.nu)
        .map(|((p, s), nu)| nu * (s.ln() + p / s))
        .sum()
}

/// The background and resonance parameters for a fixed shape `r`: level
/// `c`, tilt `beta` and `sigma^2`, by Fisher scoring (`c > 0`, `s2 >= 0`).
#[derive(Debug, Clone, Copy)]
struct Linear {
    c: f64,
    beta: f64,
    s2: f64,
}

impl Groups {
    /// Position of each group across the window, -1/2 .. 1/2 (the tilt's variable).
    fn x(&self, i: usize) -> f64 {
        let (a, b) = (self.f[0], self.f[self.f.len() - 1]);
        (self.f[i] - 0.5 * (a + b)) / (b - a)
    }
    /// The modelled PSD per group.
    fn model(&self, l: Linear, r: &[f64]) -> Vec<f64> {
        (0..self.f.len())
            .map(|i| l.c * self.m[i] * (l.beta * self.x(i)).exp() + l.s2 * r[i])
            .collect()
    }
}

fn linear_part(g: &Groups, r: &[f64], start: Linear, (s2_lo, s2_hi): (f64, f64)) -> Linear {
    let mut l = start;
    l.s2 = l.s2.clamp(s2_lo, s2_hi);
    for _ in 0..40 {
        let mut grad = [0.0; 3];
        let mut info = [[0.0; 3]; 3];
        let s = g.model(l, r);
        for i in 0..g.f.len() {
            let b = g.m[i] * (l.beta * g.x(i)).exp();
            let d = [b, l.c * b * g.x(i), r[i]];
            let u = g.nu[i] * (g.p[i] - s[i]) / (s[i] * s[i]);
            let v = g.nu[i] / (s[i] * s[i]);
            for a in 0..3 {
                grad[a] += u * d[a];
                for c in 0..3 {
                    info[a][c] += v * d[a] * d[c];
                }
            }
        }
        if s2_hi <= s2_lo {
            // sigma^2 held: the step in (c, beta) alone
            grad[2] = 0.0;
            info[2] = [0.0, 0.0, 1.0];
            info[0][2] = 0.0;
            info[1][2] = 0.0;
        }
        let Some(inv) = invert(&info.map(|r| r.to_vec())) else {
            break;
        };
        let step: Vec<f64> = (0..3)
            .map(|a| (0..3).map(|c| inv[a][c] * grad[c]).sum())
            .collect();
        let next = Linear {
            c: (l.c + step[0]).max(0.1 * l.c),
            beta: (l.beta + step[1]).clamp(-20.0, 20.0),
            s2: (l.s2 + step[2]).clamp(s2_lo, s2_hi),
        };
        let small = (next.c / l.c - 1.0).abs() < 1e-10
            && (next.beta - l.beta).abs() < 1e-10
            && (next.s2 - l.s2).abs() <= 1e-10 * next.s2.max(1e-300);
        l = next;
        if small {
            break;
        }
    }
    l
}

/// Fit a resonance to the excess `ex` of `spec` (whitened by the model
/// under test, whose readout filter is `filter`: the resonance is seen
/// through it, and its sigma is the one before it); None when the window is
/// too small or no power is found. The resonance's white tail (its PSD at
/// zero frequency) is held as `tail` says: at most the white level the
/// wavelet variances measured ([`white_budget`] of the model fitted without
/// it), which the tail and the angle random walk share, or exactly what that
/// level leaves beside the model's ARW.
pub fn fit(
    spec: &LineSpectrum,
    ex: &Excess,
    filter: Option<ReadoutFilter>,
    tail: Tail,
) -> Option<ResonanceFit> {
    let tau0 = 1.0 / spec.fs_hz;
    // the sigma^2 whose white tail is as `tail` allows
    let s2_range = |f0: f64, w: f64| {
        let unit = Ar2::new(f0, w, tau0).psd_cs_cos(1.0) * tau0;
        match tail {
            Tail::AtMost(t) => (0.0, t / unit),
            Tail::Exactly(t) => (t / unit, t / unit),
        }
    };
    let nyquist = 0.5 * spec.fs_hz;
    let (s_lo, s_hi) = ex.span_hz;
    let span = s_hi - s_lo;
    let g = groups(
        spec,
        (s_lo - span).max(0.0),
        (s_hi + span).min(nyquist),
        filter,
    );
    if g.f.len() < 24 {
        return None;
    }
    let step = (g.f[g.f.len() - 1] - g.f[0]) / g.f.len() as f64;
    // the grid: centres over the span, widths from two groups to the span
    let centres: Vec<f64> = (0..=48).map(|i| s_lo + span * i as f64 / 48.0).collect();
    let (w_lo, w_hi) = ((2.0 * step).max(spec.df() * 4.0), span.max(4.0 * step));
    let widths: Vec<f64> = (0..=24)
        .map(|i| w_lo * (w_hi / w_lo).powf(i as f64 / 24.0))
        .collect();
    let flat = Linear {
        c: 1.0,
        beta: 0.0,
        s2: 0.0,
    };
    let mut best = (f64::INFINITY, 0.0, 0.0, flat);
    for &f0 in &centres {
        for &w in &widths {
            let r = shape(&g, f0, w, tau0);
            let l = linear_part(&g, &r, flat, s2_range(f0, w));
            let v = nll(&g, &g.model(l, &r));
            if v < best.0 {
                best = (v, f0, w, l);
            }
        }
    }
    let (nll, f0, w, l) = refine(&g, best, tau0, nyquist, &s2_range);
    let (c, s2) = (l.c, l.s2);
    if !(s2 > 0.0) {
        return None;
    }
    let cov = covariance(&g, [c, s2, f0, w, l.beta], tau0)?;
    let sd = |i: usize| cov[i][i].max(0.0).sqrt();
    let s2_ci = [(s2 - 1.96 * sd(1)).max(0.0), s2 + 1.96 * sd(1)];
    let (tail_psd, tail_psd_sd) = white_tail(&cov, s2, f0, w, tau0);
    Some(ResonanceFit {
        centre_hz: f0,
        width_hz: w,
        sigma_dph: s2.sqrt(),
        centre_ci95: [f0 - 1.96 * sd(2), f0 + 1.96 * sd(2)],
        width_ci95: [(w - 1.96 * sd(3)).max(0.0), w + 1.96 * sd(3)],
        sigma_ci95: [s2_ci[0].sqrt(), s2_ci[1].sqrt()],
        background: c,
        tail_psd,
        tail_psd_sd,
        nll,
    })
}

/// The PSD at zero frequency of a resonance `(s2, f0, w)` and its standard
/// error by the delta method over `cov` (of `(c, s2, f0, w, beta)`).
fn white_tail(cov: &[Vec<f64>], s2: f64, f0: f64, w: f64, tau0: f64) -> (f64, f64) {
    let at = |q: [f64; 3]| q[0] * Ar2::new(q[1], q[2], tau0).psd_cs_cos(1.0) * tau0;
    let p = [s2, f0, w];
    let grad: Vec<f64> = (0..3)
        .map(|k| {
            let h = 1e-5 * p[k].abs().max(1e-9);
            let (mut a, mut b) = (p, p);
            a[k] += h;
            b[k] -= h;
            (at(a) - at(b)) / (2.0 * h)
        })
        .collect();
    let var: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| grad[i] * cov[i + 1][j + 1] * grad[j])
        .sum();
    (at(p), var.max(0.0).sqrt())
}

/// The white-like PSD at zero frequency of `model`'s angle random walk and
/// Gauss-Markov terms (a telegraph as its twin), (deg/h)^2/Hz: what a
/// resonance's white tail may take of the model fitted without it. A rate
/// word's LSB rounding is left out (the sensor's, not the fit's).
pub(crate) fn white_budget(model: &GyroModel) -> f64 {
    let tau0 = model.tau0_s();
    let n = &model.noise;
    let arw = units::dpsh_to_arcsec_per_sqrt_s(n.arw_dpsh.unwrap_or(0.0));
    let gm = |tau_c_s: f64, sigma: f64| {
        SpectralTerm::GaussMarkov { tau_c_s }.psd_cs(0.0, tau0) * tau0 * sigma * sigma
    };
    2.0 * arw * arw
        + n.gauss_markov
            .iter()
            .map(|g| gm(g.tau_c_s, g.sigma_dph))
            .sum::<f64>()
        + n.random_telegraph
            .iter()
            .map(|r| gm(0.5 * r.mean_dwell_s, r.amplitude_dph))
            .sum::<f64>()
}

/// Widen the angle random walk's interval in `findings` (refitted beside the
/// resonance of `fit`, whose finding is among them) by the error of the
/// resonance's white tail, which the wavelet variances fit as one white level
/// with it: on `N^2` each half-width becomes `hypot(half-width, 1.96 sd)`,
/// `sd` the tail's standard error as an ARW-equivalent `N^2` (a white rate
/// PSD of `2 N^2`). Returns whether an ARW change came to include the
/// model's value (no longer significant).
pub(crate) fn widen_white(findings: &mut [Finding], fit: &ResonanceFit) -> bool {
    // the finding's sigma is the fit's through the ratio of two filters' gains
    let scale = findings
        .iter()
        .find_map(|f| match f.edit {
            Edit::Resonance { sigma_dph, .. } if fit.sigma_dph > 0.0 => {
                Some((sigma_dph / fit.sigma_dph).powi(2))
            }
            _ => None,
        })
        .unwrap_or(1.0);
    let sd_n2 = 0.5 * scale * fit.tail_psd_sd;
    if !(sd_n2 > 0.0) {
        return false;
    }
    let to_n2 = |v: f64| units::dpsh_to_arcsec_per_sqrt_s(v).powi(2);
    let from_n2 = |v: f64| units::arcsec_per_sqrt_s_to_dpsh(v.max(0.0).sqrt());
    let (mut moved, mut insignificant) = (false, false);
    for f in findings.iter_mut() {
        for c in f.changes.iter_mut().filter(|c| c.term == "arw_dpsh") {
            let n2 = to_n2(c.fitted);
            let (lo, hi) = (n2 - to_n2(c.ci95[0]), to_n2(c.ci95[1]) - n2);
            let extra = 1.96 * sd_n2;
            c.ci95 = [from_n2(n2 - lo.hypot(extra)), from_n2(n2 + hi.hypot(extra))];
            moved = true;
            if (c.ci95[0]..=c.ci95[1]).contains(&c.model) {
                insignificant = true;
                f.note.push_str(&format!(
                    " With the error of the resonance's white tail its interval [{}, {}] \
                     includes the model's {}: the change is not significant.",
                    fmt_g(c.ci95[0]),
                    fmt_g(c.ci95[1]),
                    fmt_g(c.model)
                ));
            }
        }
    }
    if moved
        && let Some(f) = findings
            .iter_mut()
            .find(|f| matches!(f.edit, Edit::Resonance { .. }))
    {
        f.note.push_str(&format!(
            " Its white tail below the centre ({} (deg/h)^2/Hz, +- {}) trades off with the \
             angle random walk refitted beside it: that interval carries its error.",
            fmt_g(scale * fit.tail_psd),
            fmt_g(scale * fit.tail_psd_sd)
        ));
    }
    insignificant
}

/// Coordinate refinement of the grid's best `(nll, f0, w, linear part)`:
/// steps in `f0` and `ln w` with the linear part re-solved, halved until
/// they are a thousandth of the width.
fn refine(
    g: &Groups,
    start: (f64, f64, f64, Linear),
    tau0: f64,
    nyquist: f64,
    s2_range: &dyn Fn(f64, f64) -> (f64, f64),
) -> (f64, f64, f64, Linear) {
    let eval = |f0: f64, w: f64, st: Linear| {
        let r = shape(g, f0, w, tau0);
        let l = linear_part(g, &r, st, s2_range(f0, w));
        (nll(g, &g.model(l, &r)), f0, w, l)
    };
    let mut best = start;
    let (mut hf, mut hw) = (0.25 * best.2, 0.25f64);
    for _ in 0..80 {
        let mut moved = false;
        for (df, dlw) in [(hf, 0.0), (-hf, 0.0), (0.0, hw), (0.0, -hw)] {
            let (f0, w) = (best.1 + df, best.2 * dlw.exp());
            if f0 <= 0.0 || f0 >= nyquist {
                continue;
            }
            let t = eval(f0, w, best.3);
            if t.0 < best.0 {
                best = t;
                moved = true;
            }
        }
        if !moved {
            hf *= 0.5;
            hw *= 0.5;
            if hf < 1e-3 * best.2 && hw < 1e-3 {
                break;
            }
        }
    }
    best
}

/// Inverse Fisher information of `(c, s2, f0, w, beta)` (numerical
/// derivatives of the modelled PSD).
fn covariance(g: &Groups, p: [f64; 5], tau0: f64) -> Option<Vec<Vec<f64>>> {
    let model = |q: [f64; 5]| -> Vec<f64> {
        let l = Linear {
            c: q[0],
            beta: q[4],
            s2: q[1],
        };
        g.model(l, &shape(g, q[2], q[3], tau0))
    };
    let s = model(p);
    let mut d = Vec::with_capacity(5);
    for k in 0..5 {
        let h = 1e-5 * p[k].abs().max(1e-3);
        let (mut a, mut b) = (p, p);
        a[k] += h;
        b[k] -= h;
        let (sa, sb) = (model(a), model(b));
        d.push(
            (0..s.len())
                .map(|i| (sa[i] - sb[i]) / (2.0 * h))
                .collect::<Vec<f64>>(),
        );
    }
    let info: Vec<Vec<f64>> = (0..5)
        .map(|i| {
            (0..5)
                .map(|j| {
                    (0..s.len())
                        .map(|k| g.nu[k] * d[i][k] * d[j][k] / (s[k] * s[k]))
                        .sum()
                })
                .collect()
        })
        .collect();
    invert(&info)
}

/// Gauss-Jordan inverse of a small positive definite matrix.
fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let mut m: Vec<Vec<f64>> = a
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let mut r = row.clone();
            r.extend((0..n).map(|j| f64::from(u8::from(i == j))));
            r
        })
        .collect();
    for c in 0..n {
        let piv = (c..n).max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))?;
        if !(m[piv][c].abs() > 0.0) {
            return None;
        }
        m.swap(c, piv);
        let d = m[c][c];
        m[c].iter_mut().for_each(|v| *v /= d);
        for r in 0..n {
            if r != c {
                let f = m[r][c];
                let pivot_row = m[c].clone();
                m[r].iter_mut()
                    .zip(&pivot_row)
                    .for_each(|(v, p)| *v -= f * p);
            }
        }
    }
    Some(m.into_iter().map(|r| r[n..].to_vec()).collect())
}

/// The finding of a fitted resonance. `gain2` is the power gain at the
/// centre of the readout filter of the model it joins over that of the
/// filter it was fitted through (the simulator passes the resonance through
/// the model's filter).
pub(crate) fn finding(fit: &ResonanceFit, gain2: f64, tau0_s: f64) -> Finding {
    let k = 1.0 / gain2.max(1e-6).sqrt();
    let sigma = fit.sigma_dph * k;
    let sigma_ci = [fit.sigma_ci95[0] * k, fit.sigma_ci95[1] * k];
    let term = Term::Resonance {
        sigma_dph: sigma,
        centre_hz: fit.centre_hz,
        width_hz: fit.width_hz,
        tau0_s,
    };
    let note = format!(
        "Added a resonance at {} Hz [{}, {}], {} Hz wide at half power [{}, {}] (Q about {}), \
         sigma {} deg/h [{}, {}], fitted on the whole record's periodogram where the narrowband \
         check found an excess. {}",
        fmt_g(fit.centre_hz),
        fmt_g(fit.centre_ci95[0]),
        fmt_g(fit.centre_ci95[1]),
        fmt_g(fit.width_hz),
        fmt_g(fit.width_ci95[0]),
        fmt_g(fit.width_ci95[1]),
        fmt_g(fit.centre_hz / fit.width_hz),
        fmt_g(sigma),
        fmt_g(sigma_ci[0]),
        fmt_g(sigma_ci[1]),
        term.explanation()
    );
    Finding {
        edit: Edit::Resonance {
            sigma_dph: sigma,
            centre_hz: fit.centre_hz,
            width_hz: fit.width_hz,
        },
        changes: vec![],
        added: Some(AddedTerm {
            term: "resonance".into(),
            kind: None,
            params: BTreeMap::from([
                ("sigma_dph".to_string(), sigma),
                ("centre_hz".to_string(), fit.centre_hz),
                ("width_hz".to_string(), fit.width_hz),
            ]),
            explanation: term.explanation().into(),
            ci95: BTreeMap::from([
                ("sigma_dph".to_string(), sigma_ci),
                ("centre_hz".to_string(), fit.centre_ci95),
                ("width_hz".to_string(), fit.width_ci95),
            ]),
        }),
        n_par: 3,
        note,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::ParameterChange;

    /// A spectrum of white level `m0` plus a resonance, with a deterministic
    /// unit-mean pattern standing in for the periodogram's scatter.
    fn spectrum(n: usize, fs: f64, m0: f64, f0: f64, w: f64, s2: f64) -> LineSpectrum {
        let half = n / 2;
        let df = fs / n as f64;
        let ar = Ar2::new(f0, w, 1.0 / fs);
        let psd: Vec<f64> = (0..=half)
            .map(|k| {
                let f = k as f64 * df;
                let r = ar.psd_cs_cos((2.0 * PI * f / fs).cos()) / fs;
                (m0 + s2 * r) * [0.5, 1.5, 0.8, 1.2][k % 4]
            })
            .collect();
        LineSpectrum {
            fs_hz: fs,
            n,
            model_psd: vec![m0; half + 1],
            usable: (0..=half).map(|k| k > 0).collect(),
            psd: std::sync::Arc::new(psd),
        }
    }

    /// The unbounded fit of a 19.3 Hz, 1.2 Hz-wide, 30 deg/h resonance on a
    /// white level of 2.
    fn fitted_19hz() -> ResonanceFit {
        let spec = spectrum(1 << 21, 100.0, 2.0, 19.3, 1.2, 900.0);
        let ex = Excess {
            f_hz: 19.5,
            span_hz: (17.5, 21.5),
            ratio: 10.0,
            z: 30.0,
            z_crit: 4.0,
        };
        fit(&spec, &ex, None, Tail::AtMost(f64::INFINITY)).unwrap()
    }

    #[test]
    fn the_fit_finds_the_resonance_it_was_given() {
        let f = fitted_19hz();
        assert!((f.centre_hz / 19.3 - 1.0).abs() < 2e-3, "{f:?}");
        assert!((f.width_hz / 1.2 - 1.0).abs() < 0.02, "{f:?}");
        assert!((f.sigma_dph / 30.0 - 1.0).abs() < 0.02, "{f:?}");
        assert!((f.background - 1.0).abs() < 0.01, "{f:?}");
        assert!(f.centre_ci95[0] < f.centre_hz && f.centre_hz < f.centre_ci95[1]);
        // the filter's gain is divided out of the model's sigma
        let g = finding(&f, 0.25, 0.01);
        let Edit::Resonance { sigma_dph, .. } = g.edit else {
            panic!("{:?}", g.edit)
        };
        assert!((sigma_dph / (2.0 * f.sigma_dph) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_white_tail_is_the_autocorrelation_sum() {
        // one-sided PSD at zero frequency = 2 tau0 s2 (1 + 2 sum_k rho(k))
        let (f0, w, tau0, s2) = (50.0, 3.0, 1e-3, 100.0);
        let ar = Ar2::new(f0, w, tau0);
        let sum: f64 = (1..200_000).map(|k| ar.autocorr(k)).sum();
        let direct = 2.0 * tau0 * s2 * (1.0 + 2.0 * sum);
        let cov = vec![vec![0.0; 5]; 5];
        let (t, sd) = white_tail(&cov, s2, f0, w, tau0);
        assert!((t / direct - 1.0).abs() < 1e-6, "{t} vs {direct}");
        assert_eq!(sd, 0.0);
        // about peak / Q^2 below the peak: Q = 50/3
        let peak = s2 * ar.psd_cs_cos((2.0 * PI * f0 * tau0).cos()) * tau0;
        let q = f0 / w;
        assert!(
            (t * q * q / peak - 1.0).abs() < 0.35,
            "{}",
            t * q * q / peak
        );
    }

    #[test]
    fn the_arw_interval_carries_the_tail_error() {
        let mut f = fitted_19hz();
        f.tail_psd_sd = 2.0 * units::dpsh_to_arcsec_per_sqrt_s(0.01).powi(2);
        let arw = |fitted: f64, ci95: [f64; 2]| Finding {
            edit: Edit::Arw(fitted),
            changes: vec![ParameterChange {
                term: "arw_dpsh".into(),
                model: 0.3,
                fitted,
                ci95,
            }],
            added: None,
            n_par: 1,
            note: String::new(),
        };
        let mut findings = vec![finding(&f, 1.0, 0.01), arw(0.1, [0.09, 0.11])];
        assert!(!widen_white(&mut findings, &f));
        // N^2 half-widths 0.01^2 * (19, 21) and 1.96 * 0.01^2 in quadrature
        let ci = findings[1].changes[0].ci95;
        let want = [
            (0.01f64 - 19e-4f64.hypot(1.96e-4)).sqrt(),
            (0.01f64 + 21e-4f64.hypot(1.96e-4)).sqrt(),
        ];
        assert!((ci[0] / want[0] - 1.0).abs() < 1e-9, "{ci:?} vs {want:?}");
        assert!((ci[1] / want[1] - 1.0).abs() < 1e-9, "{ci:?} vs {want:?}");
        assert!(findings[0].note.contains("white tail"));
        assert!(!findings[1].note.contains("not significant"));
        // an interval that comes to include the model's value says so
        let mut findings = vec![finding(&f, 1.0, 0.01), arw(0.29, [0.285, 0.295])];
        f.tail_psd_sd = 2.0 * units::dpsh_to_arcsec_per_sqrt_s(0.1).powi(2);
        assert!(widen_white(&mut findings, &f));
        assert!(
            findings[1].note.contains("not significant"),
            "{}",
            findings[1].note
        );
    }
}
