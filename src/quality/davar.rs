//! The dynamic Allan deviation: the Allan deviation of each window of the
//! record, at octave taus, so that a warm-up or a bad hour shows at a glance;
//! and a test of whether the windows share one noise (stationarity).
//!
//! Each window is `2^shift` samples, fixed by absolute sample index (at most
//! [`MAX_WINDOWS`]: neighbours merge pairwise as the record grows). At octave
//! `m = 2^j` the Allan variance of a window is the mean of the squared second
//! differences of the phase (the integrated rate) at stride `m` whose first
//! point lies in the window, `AVAR = sum (x_{i+2m} - 2 x_{i+m} + x_i)^2 / (2 m^2 tau0^2 n)`
//! (the non-overlapping estimator); a term touching a filled sample is left out.
//!
//! Stationarity: at each octave where every window holds at least
//! [`MIN_TERMS`] terms and quantization noise is less than half the Allan
//! variance (a pulse counter's quantization error is a sawtooth that follows
//! the input rate: deterministic, not noise, and it changes with any change
//! of the rate), the windows' log Allan variances are tested for a
//! trend over the record and for an outlying window (a bad hour), each
//! against the windows' own scatter about the trend (Student t); the smallest
//! p-value over the tests, times their number (Bonferroni), is the record's.

use std::ops::Range;

use serde::{Deserialize, Serialize};

/// Most windows kept.
pub const MAX_WINDOWS: usize = 64;
/// Terms a window needs at an octave for the stationarity test.
pub const MIN_TERMS: u64 = 16;
/// Octaves tracked (tau up to 2^39 samples).
const OCTAVES: usize = 40;
/// Shortest window, samples (`2^10`).
const MIN_SHIFT: u32 = 10;

#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Acc {
    sum_sq: f64,
    n: u64,
}

/// Per-octave streaming state: the last two decimated phase points.
#[derive(Debug, Clone, Copy, Default)]
struct Octave {
    /// x_{i}, x_{i+m} and their absolute start index i.
    x0: f64,
    x1: f64,
    i0: u64,
    have: u8,
}

/// The accumulator.
#[derive(Debug, Clone)]
pub struct Davar {
    tau0_s: f64,
    shift: u32,
    windows: Vec<[Acc; OCTAVES]>,
    octaves: [Octave; OCTAVES],
    /// Phase (integrated rate, arcsec) at the next sample boundary, in two
    /// parts (compensated sum).
    phase: f64,
    comp: f64,
    /// Absolute index of the next sample.
    k: u64,
    /// Absolute index just past the last filled sample (and, at the start,
    /// past the samples a transient of the source affects).
    filled_end: u64,
}

/// One window's Allan deviations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DavarWindow {
    /// Window start, s.
    pub t0_s: f64,
    /// Allan deviation at each octave tau, deg/h (NaN: no term).
    pub dev: Vec<f64>,
    /// Terms at each octave.
    pub n: Vec<u64>,
}

/// The dynamic Allan deviation of a record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DavarMap {
    /// Window length, s.
    pub window_s: f64,
    /// Octave taus, s.
    pub tau_s: Vec<f64>,
    pub windows: Vec<DavarWindow>,
}

/// The stationarity test's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stationarity {
    /// False when the windows' noise differs beyond chance (p < 0.01).
    pub ok: bool,
    /// What was tested.
    pub test: String,
    /// The record's p-value (Bonferroni over the octaves tested).
    pub p_value: f64,
}

/// Significance below which the record is called non-stationary.
pub const ALPHA: f64 = 0.01;

impl Davar {
    pub fn new(tau0_s: f64) -> Davar {
        Davar {
            tau0_s,
            shift: MIN_SHIFT,
            windows: Vec::new(),
            octaves: [Octave::default(); OCTAVES],
            phase: 0.0,
            comp: 0.0,
            k: 0,
            filled_end: 0,
        }
    }

    /// Add rates (deg/h = arcsec/s) of the next samples; `filled` relative.
    pub fn push(&mut self, rates: &[f64], filled: &[Range<usize>]) {
        let base = self.k;
        let mut spans = filled.iter().peekable();
        for (i, &r) in rates.iter().enumerate() {
            while spans.next_if(|s| s.end <= i).is_some() {}
            if spans.peek().is_some_and(|s| s.start <= i) {
                self.filled_end = base + i as u64 + 1;
            }
            // compensated phase sum
            let y = r * self.tau0_s - self.comp;
            let t = self.phase + y;
            self.comp = (t - self.phase) - y;
            self.phase = t;
            self.k += 1;
            self.on_point();
        }
    }

    /// A new phase point at index `k` (after `k` samples): feed every octave
    /// `m` that divides `k`.
    fn on_point(&mut self) {
        let k = self.k;
        let tz = (k.trailing_zeros() as usize).min(OCTAVES - 1);
        for j in 0..=tz {
            let m = 1u64 << j;
            let o = &mut self.octaves[j];
            if o.have == 2 {
                let i = o.i0;
                let term = self.phase - 2.0 * o.x1 + o.x0;
                if self.filled_end <= i {
                    let w = (i >> self.shift) as usize;
                    if w >= self.windows.len() {
                        self.windows.resize(w + 1, [Acc::default(); OCTAVES]);
                    }
                    let a = &mut self.windows[w][j];
                    a.sum_sq += term * term;
                    a.n += 1;
                }
                o.x0 = o.x1;
                o.x1 = self.phase;
                o.i0 += m;
            } else if o.have == 1 {
                o.x1 = self.phase;
                o.have = 2;
            } else {
                // the first point of this octave is the phase at k - m... start here
                o.x0 = self.phase;
                o.i0 = k;
                o.have = 1;
            }
        }
        if self.windows.len() > MAX_WINDOWS {
            self.merge();
        }
    }

    fn merge(&mut self) {
        self.shift += 1;
        let merged: Vec<[Acc; OCTAVES]> = self
            .windows
            .chunks(2)
            .map(|c| {
                let mut w = [Acc::default(); OCTAVES];
                for x in c {
                    for (a, b) in w.iter_mut().zip(x) {
                        a.sum_sq += b.sum_sq;
                        a.n += b.n;
                    }
                }
                w
            })
            .collect();
        self.windows = merged;
    }

    /// The map: every window, at the octaves with a term in some window.
    pub fn map(&self) -> DavarMap {
        let window_s = (1u64 << self.shift) as f64 * self.tau0_s;
        let top = (0..OCTAVES)
            .filter(|&j| self.windows.iter().any(|w| w[j].n > 0))
            .max()
            .map_or(0, |j| j + 1);
        let tau_s: Vec<f64> = (0..top).map(|j| (1u64 << j) as f64 * self.tau0_s).collect();
        let windows = self
            .windows
            .iter()
            .enumerate()
            .map(|(w, accs)| DavarWindow {
                t0_s: w as f64 * window_s,
                dev: (0..top)
                    .map(|j| {
                        let a = accs[j];
                        let m = (1u64 << j) as f64;
                        if a.n == 0 {
                            f64::NAN
                        } else {
                            (a.sum_sq / (2.0 * m * m * self.tau0_s * self.tau0_s * a.n as f64))
                                .sqrt()
                        }
                    })
                    .collect(),
                n: (0..top).map(|j| accs[j].n).collect(),
            })
            .collect();
        DavarMap {
            window_s,
            tau_s,
            windows,
        }
    }

    /// Whether the windows' Allan variances change over the record: at each
    /// octave where every window has [`MIN_TERMS`] terms, the log variances
    /// of the windows get a linear trend test and an outlying-window test,
    /// each against the windows' own scatter (Student t), so that a noise
    /// whose windows vary more than theory says (a counter's sawtooth,
    /// mode hops) is judged by its own spread. Octaves where quantization
    /// (`quantization_arcsec`, the record's Q) is half the Allan variance or
    /// more are left out.
    pub fn stationarity(&self, quantization_arcsec: f64) -> Option<Stationarity> {
        // the last window is usually partial: leave it out
        let full = self.windows.len().saturating_sub(1);
        if full < 8 {
            return None;
        }
        let win = &self.windows[..full];
        let mut p_min = 1.0f64;
        let mut tests = 0usize;
        for j in 0..OCTAVES {
            if win
                .iter()
                .any(|w| w[j].n < MIN_TERMS || !(w[j].sum_sq > 0.0))
            {
                continue;
            }
            let tau = (1u64 << j) as f64 * self.tau0_s;
            let (s2, n) = win
                .iter()
                .fold((0.0, 0u64), |a, w| (a.0 + w[j].sum_sq, a.1 + w[j].n));
            let pooled = s2 / (2.0 * tau * tau * n as f64);
            if 3.0 * quantization_arcsec.powi(2) / (tau * tau) >= 0.5 * pooled {
                continue;
            }
            let l: Vec<f64> = win
                .iter()
                .map(|w| (w[j].sum_sq / w[j].n as f64).ln())
                .collect();
            let (p_trend, p_window) = change_tests(&l);
            p_min = p_min.min(p_trend).min(p_window);
            tests += 2;
        }
        (tests > 0).then(|| {
            let p = (p_min * tests as f64).min(1.0);
            Stationarity {
                ok: p >= ALPHA,
                test: format!(
                    "trend and outlying-window tests of the log Allan variance over {full} windows of {:.0} s, \
                     at {} octave taus (Student t against the windows' scatter, Bonferroni)",
                    (1u64 << self.shift) as f64 * self.tau0_s,
                    tests / 2
                ),
                p_value: p,
            }
        })
    }
}

/// Two-sided p-values of a linear trend in `l` and of its most outlying
/// element (leave-one-out, Bonferroni over the elements), each a Student t
/// against the scatter about the trend.
fn change_tests(l: &[f64]) -> (f64, f64) {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    let n = l.len() as f64;
    let xm = (n - 1.0) / 2.0;
    let ym = l.iter().sum::<f64>() / n;
    let sxx: f64 = (0..l.len()).map(|i| (i as f64 - xm).powi(2)).sum();
    let sxy: f64 = l
        .iter()
        .enumerate()
        .map(|(i, y)| (i as f64 - xm) * (y - ym))
        .sum();
    let slope = sxy / sxx;
    let resid: Vec<f64> = l
        .iter()
        .enumerate()
        .map(|(i, y)| y - ym - slope * (i as f64 - xm))
        .collect();
    let sse: f64 = resid.iter().map(|r| r * r).sum();
    let df = n - 2.0;
    let s2 = (sse / df).max(1e-300);
    let two_sided =
        |t: f64, df: f64| StudentsT::new(0.0, 1.0, df).map_or(1.0, |d| 2.0 * d.sf(t.abs()));
    let p_trend = two_sided(slope / (s2 / sxx).sqrt(), df);
    // leave-one-out studentized residual of each window
    let p_window = resid
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let h = 1.0 / n + (i as f64 - xm).powi(2) / sxx;
            let s2_i = ((sse - r * r / (1.0 - h)) / (df - 1.0)).max(1e-300);
            let t = r / (s2_i * (1.0 - h)).sqrt();
            two_sided(t, df - 1.0)
        })
        .fold(1.0f64, f64::min)
        * n;
    (p_trend, p_window.min(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, seed: u64, sd: f64) -> Vec<f64> {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut r);
                sd * z
            })
            .collect()
    }

    #[test]
    fn white_rate_windows_match_the_closed_form_and_test_stationary() {
        // white rate of sd 10 deg/h at 100 Hz: AVAR(tau) = 100 tau0 / tau
        let x = white(400_000, 1, 10.0);
        let mut d = Davar::new(0.01);
        for c in x.chunks(999) {
            d.push(c, &[]);
        }
        let map = d.map();
        assert!(map.windows.len() <= MAX_WINDOWS && map.windows.len() >= 32);
        for w in &map.windows[..map.windows.len() - 1] {
            for (j, dev) in w.dev.iter().enumerate().take(6) {
                let want = (100.0 / (1u64 << j) as f64).sqrt();
                let rel = (dev / want - 1.0).abs();
                assert!(rel < 0.25, "octave {j}: {dev} vs {want}");
            }
        }
        let s = d.stationarity(0.0).unwrap();
        assert!(s.ok, "{s:?}");
    }

    #[test]
    fn a_noisy_hour_is_not_stationary() {
        let mut x = white(400_000, 2, 10.0);
        for v in &mut x[200_000..212_000] {
            *v *= 1.6;
        }
        let mut d = Davar::new(0.01);
        d.push(&x, &[]);
        let s = d.stationarity(0.0).unwrap();
        assert!(!s.ok && s.p_value < 1e-6, "{s:?}");
    }
}
