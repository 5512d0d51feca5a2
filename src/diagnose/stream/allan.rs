//! The overlapping Allan variance and the modified Allan variance of a pulse
//! count stream at octave averaging factors, in memory that does not grow
//! with the record.
//!
//! With the phase `x` (cumulative count, `x[0] = 0`, `N` phase points) the
//! terms are, at averaging factor `m`:
//! * OADEV: `d_i = x[i+2m] - 2 x[i+m] + x[i]`, `i = 0 ..= N-1-2m`;
//! * MDEV: `v_j = sum_{i=j}^{j+m-1} d_i = Q[j+3m] - 3 Q[j+2m] + 3 Q[j+m] - Q[j]`,
//!   `j = 0 ..= N-3m`, with `Q[k] = sum_{i<k} x[i]`.
//!
//! Up to [`FULL_OVERLAP_CAP`] every term is used, exactly as the batch
//! definitions (`crate::allan::deviation`): the last `3 m` phase points are
//! kept and `v_j` is a running integer sum of the `d_i`. Beyond the cap only
//! the terms starting at multiples of the stride `s = m / STRIDED_TERMS` are
//! used, from `x` and `Q` sampled at those multiples (a ring of `3 *
//! STRIDED_TERMS + 1` points per octave): the variance stays unbiased and
//! its spread grows a little, the same for a recording and its Monte-Carlo
//! runs, which is what the diagnosis compares. Differences are exact
//! integers; squares are summed per block in `f64` and the block sums with
//! Neumaier's compensation.

use crate::allan::streaming::sample::Neumaier;

/// Averaging factors up to this use every term.
pub const FULL_OVERLAP_CAP: u64 = 1 << 18;
/// Terms per averaging factor of a strided octave (the stride is `m` over this).
pub const STRIDED_TERMS: u64 = 1 << 12;
/// Phase points processed per block (full-overlap octaves).
const BLOCK: usize = 1 << 16;

/// One full-overlap octave's running state.
#[derive(Debug, Clone)]
struct Full {
    m: usize,
    /// Running `v` (sum of the last `m` second differences).
    v: i64,
    oadev: Neumaier,
    mdev: Neumaier,
}

/// One strided octave: `x` and `Q` at multiples of the stride.
#[derive(Debug, Clone)]
struct Strided {
    m: u64,
    stride: u64,
    x: Vec<i64>,
    q: Vec<i128>,
    oadev: Neumaier,
    mdev: Neumaier,
}

/// OADEV and MDEV sums at octave averaging factors of one count stream.
#[derive(Debug, Clone)]
pub struct AllanStream {
    ms: Vec<u64>,
    /// Phase points the record will have (`N`).
    n_phase: u64,
    full: Vec<Full>,
    strided: Vec<Strided>,
    /// Phase points `x[base ..]`: the last `keep` processed ones, then the pending.
    hist: Vec<i64>,
    base: u64,
    keep: usize,
    /// Phase points processed by the full octaves.
    done: u64,
    /// Phase points received, the last one and `Q` up to it (exclusive).
    k: u64,
    x: i64,
    q: i128,
}

impl AllanStream {
    /// Sums at averaging factors `ms` (powers of two, ascending) for a record
    /// of `n_samples` counts.
    pub fn new(ms: &[u64], n_samples: usize) -> AllanStream {
        let full: Vec<Full> = ms
            .iter()
            .filter(|&&m| m <= FULL_OVERLAP_CAP)
            .map(|&m| Full {
                m: m as usize,
                v: 0,
                oadev: Neumaier::default(),
                mdev: Neumaier::default(),
            })
            .collect();
        let strided = ms
            .iter()
            .filter(|&&m| m > FULL_OVERLAP_CAP)
            .map(|&m| {
                let stride = (m / STRIDED_TERMS).max(1);
                Strided {
                    m,
                    stride,
                    x: vec![0; (2 * m / stride + 1) as usize],
                    q: vec![0; (3 * m / stride + 1) as usize],
                    oadev: Neumaier::default(),
                    mdev: Neumaier::default(),
                }
            })
            .collect();
        let keep = full.last().map_or(0, |f| 3 * f.m);
        let mut s = AllanStream {
            ms: ms.to_vec(),
            n_phase: n_samples as u64 + 1,
            full,
            strided,
            hist: Vec::with_capacity(keep + BLOCK),
            base: 0,
            keep,
            done: 0,
            k: 0,
            x: 0,
            q: 0,
        };
        s.push_phase(0);
        s
    }

    /// Add count increments.
    pub fn push(&mut self, counts: &[i64]) {
        for &c in counts {
            self.push_phase(self.x.wrapping_add(c));
            if self.hist.len() >= self.keep + BLOCK {
                self.run_full();
            }
        }
    }

    fn push_phase(&mut self, x: i64) {
        let k = self.k;
        // strides are powers of two, the smallest first
        if self
            .strided
            .first()
            .is_some_and(|s| k & (s.stride - 1) == 0)
        {
            for s in &mut self.strided {
                if k & (s.stride - 1) == 0 {
                    s.take_q(k, self.q, self.n_phase);
                    s.take_x(k, x, self.n_phase);
                }
            }
        }
        self.hist.push(x);
        self.x = x;
        self.q += x as i128;
        self.k += 1;
    }

    /// Process the pending phase points of the full octaves, then keep only
    /// the last `keep` points.
    fn run_full(&mut self) {
        let end = self.base + self.hist.len() as u64;
        for f in &mut self.full {
            f.run(&self.hist, self.base, self.done, end, self.n_phase);
        }
        self.done = end;
        let drop = self.hist.len().saturating_sub(self.keep);
        self.hist.drain(..drop);
        self.base += drop as u64;
    }

    /// Variances in squared pulses per sample period (multiply by
    /// `(pulse / tau0)^2` for a rate), `(oadev, mdev)` per averaging factor;
    /// NaN where a factor leaves no term.
    pub fn finish(mut self) -> (Vec<f64>, Vec<f64>) {
        self.run_full();
        let (k, q, n) = (self.k, self.q, self.n_phase);
        for s in &mut self.strided {
            if k % s.stride == 0 {
                s.take_q(k, q, n);
            }
        }
        let mut oadev = Vec::with_capacity(self.ms.len());
        let mut mdev = Vec::with_capacity(self.ms.len());
        for &m in &self.ms {
            let (so, sm, no, nm) = if let Some(f) = self.full.iter().find(|f| f.m as u64 == m) {
                let no = n.saturating_sub(2 * m);
                let nm = (n + 1).saturating_sub(3 * m);
                (f.oadev.value(), f.mdev.value(), no, nm)
            } else {
                let s = self
                    .strided
                    .iter()
                    .find(|s| s.m == m)
                    .expect("every factor");
                let no = n.checked_sub(1 + 2 * m).map_or(0, |r| r / s.stride + 1);
                let nm = n.checked_sub(3 * m).map_or(0, |r| r / s.stride + 1);
                (s.oadev.value(), s.mdev.value(), no, nm)
            };
            let mf = m as f64;
            let var = |sum: f64, terms: u64, scale: f64| {
                if terms == 0 {
                    f64::NAN
                } else {
                    sum / (2.0 * scale * terms as f64)
                }
            };
            oadev.push(var(so, no, mf * mf));
            mdev.push(var(sm, nm, mf * mf * mf * mf));
        }
        (oadev, mdev)
    }
}

impl Full {
    /// Terms completed by phase points `done .. end` (absolute), read from
    /// `hist` (which starts at `base` and holds `3 m` points before `done`).
    fn run(&mut self, hist: &[i64], base: u64, done: u64, end: u64, n_phase: u64) {
        let m = self.m as u64;
        let first = done.max(2 * m);
        let (mut so, mut sm) = (0.0f64, 0.0f64);
        let mut v = self.v;
        let at = |k: u64| (k - base) as usize;
        let m_us = self.m;
        let mut k = first;
        // the first m - 1 terms only build v; then v's window is not full
        while k < end && k < 3 * m {
            let i = at(k);
            let d = hist[i] - 2 * hist[i - m_us] + hist[i - 2 * m_us];
            so += (d as f64) * (d as f64);
            v += d;
            if k + 1 >= 3 * m {
                sm += (v as f64) * (v as f64);
            }
            k += 1;
        }
        if k < end {
            // the bulk: v slides, every step completes one term of each
            let (a, b) = (at(k), at(end));
            let mut s2 = [0.0f64; 2];
            for i in a..b {
                let d = hist[i] - 2 * hist[i - m_us] + hist[i - 2 * m_us];
                let old = hist[i - m_us] - 2 * hist[i - 2 * m_us] + hist[i - 3 * m_us];
                v += d - old;
                s2[0] += (d as f64) * (d as f64);
                s2[1] += (v as f64) * (v as f64);
            }
            so += s2[0];
            sm += s2[1];
        }
        debug_assert!(end <= n_phase);
        self.v = v;
        self.oadev.add(so);
        self.mdev.add(sm);
    }
}

impl Strided {
    /// `Q[k]` (the sum of the phase points before `k`) at a multiple of the
    /// stride: completes the MDEV term starting at `k - 3m`.
    fn take_q(&mut self, k: u64, q: i128, n_phase: u64) {
        let slot = |j: u64, len: usize| ((j / self.stride) % len as u64) as usize;
        let len = self.q.len();
        self.q[slot(k, len)] = q;
        if k >= 3 * self.m && k <= n_phase {
            let m = self.m;
            let v = self.q[slot(k, len)] - 3 * self.q[slot(k - m, len)]
                + 3 * self.q[slot(k - 2 * m, len)]
                - self.q[slot(k - 3 * m, len)];
            let v = v as f64;
            self.mdev.add(v * v);
        }
    }

    /// Phase point `x[k]` at a multiple of the stride: completes the OADEV
    /// term starting at `k - 2m`.
    fn take_x(&mut self, k: u64, x: i64, n_phase: u64) {
        let len = self.x.len() as u64;
        let slot = |j: u64| ((j / self.stride) % len) as usize;
        self.x[slot(k)] = x;
        if k >= 2 * self.m && k < n_phase {
            let m = self.m;
            let d = x - 2 * self.x[slot(k - m)] + self.x[slot(k - 2 * m)];
            let d = d as f64;
            self.oadev.add(d * d);
        }
    }
}
