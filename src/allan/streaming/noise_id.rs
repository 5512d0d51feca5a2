//! Streaming power-law noise identification per octave: the lag-1 autocorrelation
//! method of Riley and Greenhall ("Power law noise identification using the lag 1
//! autocorrelation", EFTF 2004), fed by non-overlapping `m`-sample decimations.
//!
//! For octave `m = 2^j` the engine feeds this state the phase points `X_k = x[k m]`
//! (every `m`-th point, a cascade: octave `j+1` sees every other point of octave `j`,
//! so the whole bank does fewer than two updates per input sample). Differencing once
//! gives `m` times the non-overlapping `m`-sample frequency averages, twice their first
//! differences. For both difference orders `d = 1, 2` the state keeps shifted running
//! sums (`n`, `sum u`, `sum u^2`, `sum u_k u_{k-1}`, the first and last `u`, where
//! `u = v - v_first` removes a constant such as a large frequency offset before
//! squaring) from which the mean-removed lag-1 autocorrelation
//! `r1 = sum (u_k - mu)(u_{k+1} - mu) / sum (u_k - mu)^2` follows in O(1).
//!
//! Decision (Riley-Greenhall with `dmin = 1`, `dmax = 2`): `delta = r1 / (1 + r1)`;
//! if `delta(d=1) < 0.25` then `d = 1`, else `d = 2`; `alpha = 2 - 2 d - round(2 delta)`,
//! clamped to `-2..=2`. Starting at `d = 1` instead of the published `dmin = 0` replaces
//! the phase detrending (not possible in O(1) streaming state) by one difference, which
//! removes a frequency offset exactly; the `delta` relation still holds for the
//! over-differenced stationary cases (white PM gives `delta = -1` at `d = 1`, flicker PM
//! `-1/2`). A linear frequency drift is not removed: where it dominates, the series
//! looks like random-walk FM, which is also how it inflates the Allan variance.
//!
//! Known limitation (of the method, not of this implementation): the `m`-decimation
//! folds the `log2 m` octaves above the new Nyquist frequency into the band. For flicker
//! PM, which has equal power per octave, the folded power is white, so `delta` drifts
//! from `-1/2` towards `-1` and flicker PM is reported as white PM from about `m = 16`
//! on. AllanTools' `autocorr_noise_id` (phase decimation, `dmin = 0`) behaves the same
//! on simulated flicker PM (`delta` -0.5, -0.6, -0.65, -0.72, -0.76, -0.8 for
//! `m = 1 .. 32`). Averaging the phase instead would fix flicker PM but break white FM
//! (differences of block means of a random walk have `r1 = 1/4`, `delta = 0.2`, right at
//! the 0.25 threshold). For gyro data this matters little: quantization noise is white
//! PM anyway.
//!
//! The method needs enough points: with fewer than [`MIN_ID_POINTS`] first differences
//! an octave has no own estimate and the engine reports the alpha of the nearest
//! shorter octave that has one (0, white FM, when none has).

use super::sample::{Neumaier, PhaseValue};
use crate::dsp::isa::Isa;

/// Minimum number of non-overlapping `m`-averages (first differences) for an octave's
/// own lag-1 estimate (Riley recommends at least about 30).
pub const MIN_ID_POINTS: u64 = 32;

/// Running sums of one difference series.
#[derive(Clone, Debug, Default)]
struct SeriesSums {
    n: u64,
    /// Last shifted value `u`.
    last: f64,
    s1: Neumaier,
    s2: Neumaier,
    s11: Neumaier,
}

impl SeriesSums {
    /// Lag-1 autocorrelation (mean removed); `None` when undefined.
    fn r1(&self) -> Option<f64> {
        if self.n < 3 {
            return None;
        }
        let n = self.n as f64;
        let s1 = self.s1.value();
        let mu = s1 / n;
        let den = self.s2.value() - n * mu * mu;
        // u_first == 0 by construction of the shift.
        let num = self.s11.value() - mu * (2.0 * s1 - self.last) + (n - 1.0) * mu * mu;
        let r = num / den;
        (den > 0.0 && r.is_finite()).then_some(r)
    }

    /// Add one shifted value (start-up path).
    fn push(&mut self, u: f64) {
        self.s1.add(u);
        self.s2.add(u * u);
        if self.n >= 1 {
            self.s11.add(u * self.last);
        }
        self.last = u;
        self.n += 1;
    }

    fn fold(&mut self, lanes: &SumLanes, added: u64, last: f64) {
        let red = |l: &[f64; SUM_LANES]| {
            ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]))
        };
        self.s1.add(red(&lanes.s1));
        self.s2.add(red(&lanes.s2));
        self.s11.add(red(&lanes.s11));
        self.n += added;
        self.last = last;
    }
}

/// Lanes of the partial sums of the identification series.
const SUM_LANES: usize = 8;

/// 8-lane partial sums (vectorisable; lane fixed by the position in the tile).
#[derive(Clone, Copy, Default)]
struct SumLanes {
    s1: [f64; SUM_LANES],
    s2: [f64; SUM_LANES],
    s11: [f64; SUM_LANES],
}

impl SumLanes {
    /// Add `u[i]`, `u[i]^2` and `u[i] u[i-1]` (`u[-1] = prev`): `u[0]` to lane 0, then
    /// `u[1..]` in groups of 8 (lane = position in the group), the remainder to lanes
    /// `0 ..`. The AVX2 path does the same IEEE operations lane by lane.
    #[inline(always)]
    fn add(&mut self, u: &[f64], prev: f64) {
        let Some((&first, _)) = u.split_first() else {
            return;
        };
        self.s1[0] += first;
        self.s2[0] += first * first;
        self.s11[0] += first * prev;
        let (cur, before) = (&u[1..], &u[..u.len() - 1]);
        let whole = cur.len() / SUM_LANES * SUM_LANES;
        let done = match Isa::detect() {
            Isa::Baseline => false,
            // SAFETY: an `Avx2` or `Avx512` exists only on a CPU with AVX2
            // (crate::dsp::isa), the one feature the variant enables.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 | Isa::Avx512 => {
                unsafe { self.add_avx2(&cur[..whole], &before[..whole]) };
                true
            }
        };
        if !done {
            let chunks = cur[..whole]
                .chunks_exact(SUM_LANES)
                .zip(before[..whole].chunks_exact(SUM_LANES));
            for (c, b) in chunks {
                for l in 0..SUM_LANES {
                    self.s1[l] += c[l];
                    self.s2[l] += c[l] * c[l];
                    self.s11[l] += c[l] * b[l];
                }
            }
        }
        for (l, (c, b)) in cur[whole..].iter().zip(&before[whole..]).enumerate() {
            self.s1[l] += c;
            self.s2[l] += c * c;
            self.s11[l] += c * b;
        }
    }

    /// The AVX2 variant of the grouped sums (see [`SumLanes::add`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn add_avx2(&mut self, cur: &[f64], before: &[f64]) {
        use std::arch::x86_64::*;
        let n = cur.len().min(before.len()) / SUM_LANES * SUM_LANES;
        // SAFETY: AVX2 is enabled; loads read 4 f64 at `i + 4k < n`, `i + 8 <= n` within
        // both slices; the lane arrays have 8 elements.
        unsafe {
            let mut s1a = _mm256_loadu_pd(self.s1.as_ptr());
            let mut s1b = _mm256_loadu_pd(self.s1.as_ptr().add(4));
            let mut s2a = _mm256_loadu_pd(self.s2.as_ptr());
            let mut s2b = _mm256_loadu_pd(self.s2.as_ptr().add(4));
            let mut s11a = _mm256_loadu_pd(self.s11.as_ptr());
            let mut s11b = _mm256_loadu_pd(self.s11.as_ptr().add(4));
            let mut i = 0;
            while i < n {
                let ca = _mm256_loadu_pd(cur.as_ptr().add(i));
                let cb = _mm256_loadu_pd(cur.as_ptr().add(i + 4));
                let ba = _mm256_loadu_pd(before.as_ptr().add(i));
                let bb = _mm256_loadu_pd(before.as_ptr().add(i + 4));
                s1a = _mm256_add_pd(s1a, ca);
                s1b = _mm256_add_pd(s1b, cb);
                s2a = _mm256_add_pd(s2a, _mm256_mul_pd(ca, ca));
                s2b = _mm256_add_pd(s2b, _mm256_mul_pd(cb, cb));
                s11a = _mm256_add_pd(s11a, _mm256_mul_pd(ca, ba));
                s11b = _mm256_add_pd(s11b, _mm256_mul_pd(cb, bb));
                i += SUM_LANES;
            }
            _mm256_storeu_pd(self.s1.as_mut_ptr(), s1a);
            _mm256_storeu_pd(self.s1.as_mut_ptr().add(4), s1b);
            _mm256_storeu_pd(self.s2.as_mut_ptr(), s2a);
            _mm256_storeu_pd(self.s2.as_mut_ptr().add(4), s2b);
            _mm256_storeu_pd(self.s11.as_mut_ptr(), s11a);
            _mm256_storeu_pd(self.s11.as_mut_ptr().add(4), s11b);
        }
    }
}

/// Values per tile of the fast path.
const TILE: usize = 1024;

/// Identification state of one octave.
#[derive(Clone, Debug)]
pub(crate) struct OctaveId<P: PhaseValue> {
    /// Decimated phase points seen.
    count: u64,
    /// Last decimated phase point.
    x1: P,
    /// Last first difference (unshifted).
    d1: P,
    /// First first difference (the shift of the d = 1 series).
    shift1: P,
    /// First second difference (the shift of the d = 2 series).
    shift2: P,
    s_d1: SeriesSums,
    s_d2: SeriesSums,
    /// Work buffers of the fast path, kept between calls (zeroed only when they
    /// grow, instead of three zeroed tiles on the stack per call).
    scratch: Scratch<P>,
}

#[derive(Clone, Default)]
struct Scratch<P> {
    d: Vec<P>,
    u1: Vec<f64>,
    u2: Vec<f64>,
}

impl<P> std::fmt::Debug for Scratch<P> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Scratch({} values)", self.u1.len())
    }
}

impl<P: PhaseValue> Default for OctaveId<P> {
    fn default() -> Self {
        Self {
            count: 0,
            x1: P::default(),
            d1: P::default(),
            shift1: P::default(),
            shift2: P::default(),
            s_d1: SeriesSums::default(),
            s_d2: SeriesSums::default(),
            scratch: Scratch::default(),
        }
    }
}

/// The identification result of one octave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseId {
    /// Number of first differences (non-overlapping `m`-averages) seen.
    pub points: u64,
    /// Difference order used (1 or 2), 0 when not identified.
    pub d: u32,
    /// `r1 / (1 + r1)` at order `d` (NaN when not identified).
    pub delta: f64,
    /// Lag-1 autocorrelation at order 1 (NaN when undefined).
    pub r1_d1: f64,
    /// Lag-1 autocorrelation at order 2 (NaN when undefined).
    pub r1_d2: f64,
    /// Identified alpha, `None` when the octave has too few points.
    pub alpha: Option<i32>,
}

impl<P: PhaseValue> OctaveId<P> {
    /// Start-up: the first three points set the shifts.
    fn push_slow(&mut self, x: P) {
        if self.count >= 1 {
            let d = P::sub(x, self.x1);
            if self.count == 1 {
                self.shift1 = d;
            }
            self.s_d1.push(P::sub(d, self.shift1).to_f64());
            if self.count >= 2 {
                let e = P::sub(d, self.d1);
                if self.count == 2 {
                    self.shift2 = e;
                }
                self.s_d2.push(P::sub(e, self.shift2).to_f64());
            }
            self.d1 = d;
        }
        self.x1 = x;
        self.count += 1;
    }

    /// Feed the next decimated phase points, in order. Differences are taken in the
    /// phase representation (exact for counts), shifted, then converted to `f64`.
    #[inline(always)]
    pub(crate) fn feed(&mut self, src: &[P]) {
        let total = src.len();
        let mut next = 0usize;
        while self.count < 3 {
            if next == total {
                return;
            }
            self.push_slow(src[next]);
            next += 1;
        }
        let mut lanes1 = SumLanes::default();
        let mut lanes2 = SumLanes::default();
        let (mut last1, mut last2) = (self.s_d1.last, self.s_d2.last);
        let added = (total - next) as u64;
        let mut scratch = std::mem::take(&mut self.scratch);
        let need = (total - next).min(TILE);
        if scratch.u1.len() < need {
            scratch.d.resize(need, P::default());
            scratch.u1.resize(need, 0.0);
            scratch.u2.resize(need, 0.0);
        }
        let (d, u1, u2) = (&mut scratch.d, &mut scratch.u1, &mut scratch.u2);
        while next < total {
            let t = (total - next).min(TILE);
            let tile = &src[next..next + t];
            let (d, u1, u2) = (&mut d[..t], &mut u1[..t], &mut u2[..t]);
            d[0] = P::sub(tile[0], self.x1);
            for ((di, &x), &xp) in d[1..].iter_mut().zip(&tile[1..]).zip(&tile[..t - 1]) {
                *di = P::sub(x, xp);
            }
            let (s1, s2) = (self.shift1, self.shift2);
            for (ui, &di) in u1.iter_mut().zip(d.iter()) {
                *ui = P::sub(di, s1).to_f64();
            }
            u2[0] = P::sub(P::sub(d[0], self.d1), s2).to_f64();
            for ((ui, &di), &dp) in u2[1..].iter_mut().zip(&d[1..]).zip(&d[..t - 1]) {
                *ui = P::sub(P::sub(di, dp), s2).to_f64();
            }
            lanes1.add(u1, last1);
            lanes2.add(u2, last2);
            last1 = u1[t - 1];
            last2 = u2[t - 1];
            self.x1 = tile[t - 1];
            self.d1 = d[t - 1];
            next += t;
        }
        self.scratch = scratch;
        self.count += added;
        self.s_d1.fold(&lanes1, added, last1);
        self.s_d2.fold(&lanes2, added, last2);
    }

    /// The octave's own identification.
    pub(crate) fn identify(&self) -> NoiseId {
        let r1a = self.s_d1.r1();
        let r1b = self.s_d2.r1();
        let mut id = NoiseId {
            points: self.s_d1.n,
            d: 0,
            delta: f64::NAN,
            r1_d1: r1a.unwrap_or(f64::NAN),
            r1_d2: r1b.unwrap_or(f64::NAN),
            alpha: None,
        };
        if self.s_d1.n < MIN_ID_POINTS {
            return id;
        }
        let delta = |r: f64| r / (1.0 + r);
        let choice = match r1a.map(delta) {
            Some(d1) if d1 < 0.25 => Some((1u32, d1)),
            _ => r1b.map(|r| (2u32, delta(r))),
        };
        if let Some((d, dl)) = choice
            && dl.is_finite()
        {
            let a = 2.0 - 2.0 * f64::from(d) - (2.0 * dl).round();
            id.d = d;
            id.delta = dl;
            id.alpha = Some((a as i32).clamp(-2, 2));
        }
        id
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lane_sums_are_bitwise_identical_on_every_path() {
        // The dispatched `add` (AVX2 when available) against a scalar transcription of
        // the lane rule; and the plain sums (1e-12).
        let u: Vec<f64> = (0..1003)
            .map(|i| ((i * 7919) % 1000) as f64 * 0.37 - 150.0)
            .collect();
        for len in [0usize, 1, 2, 5, 8, 9, 17, 1003] {
            let mut got = SumLanes::default();
            got.add(&u[..len], 2.5);
            let mut want = SumLanes::default();
            if len > 0 {
                want.s1[0] += u[0];
                want.s2[0] += u[0] * u[0];
                want.s11[0] += u[0] * 2.5;
                let whole = (len - 1) / SUM_LANES * SUM_LANES;
                for i in 0..len - 1 {
                    let l = if i < whole { i % SUM_LANES } else { i - whole };
                    let (c, b) = (u[i + 1], u[i]);
                    want.s1[l] += c;
                    want.s2[l] += c * c;
                    want.s11[l] += c * b;
                }
            }
            for (g, w) in [(got.s1, want.s1), (got.s2, want.s2), (got.s11, want.s11)] {
                assert_eq!(g.map(f64::to_bits), w.map(f64::to_bits), "len {len}");
            }
            let plain: f64 = u[..len].iter().map(|v| v * v).sum();
            let lanes: f64 = got.s2.iter().sum();
            assert!((lanes - plain).abs() <= 1e-12 * plain.max(1.0));
        }
    }
}
