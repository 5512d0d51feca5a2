//! Streaming octave-spaced overlapping Allan deviation (OADEV) with noise
//! identification, EDF and chi-square confidence intervals: the accumulator the
//! daemon feeds sample by sample (or block by block) and snapshots at any moment.
//! Its batch counterpart is the plain NIST SP 1065 definition
//! `sigma^2(m) = sum_{i=0}^{N-2m-1} (x[i+2m] - 2 x[i+m] + x[i])^2 / (2 m^2 tau0^2 (N-2m))`
//! on `N` phase points, which `tests/numerics/allan_streaming.rs` evaluates naively and compares.
//!
//! # Inputs
//! * [`OctaveAllan::phase`]: phase samples `x` (f64).
//! * [`OctaveAllan::freq`]: frequency / rate samples `y` (f64), integrated to phase
//!   `x[0] = 0`, `x[k+1] = x[k] + (y[k] - y[0]) tau0`. Subtracting the first sample is
//!   a causal stand-in for the batch engines' mean removal: the Allan variance is
//!   invariant to a constant frequency offset, so the second differences are
//!   mathematically the same, and the phase stays small (a gyro at rest still sees the
//!   Earth rate). The running sum is split into 256-sample quarters: a plain prefix sum
//!   inside the quarter on top of a Neumaier-compensated sum of the earlier quarters, so
//!   a stored phase point is off by at most `eps |x| + 256 eps max|p|` (`p` the
//!   in-quarter partial sum) however long the run - no error grows with the stream
//!   length. (Internally the phase is kept in units of `y * samples`; `tau0` enters
//!   only the final scaling.)
//! * [`OctaveAllan::counts`]: integer pulse-count increments (i64), accumulated in a
//!   wrapping `i64` cumulative count: second differences are exact integers and their
//!   squares are summed exactly in `u128` (see [`sample`]).
//!
//! # Design
//! * **Octaves** `m = 2^j`, `j = 0 ..= max_octave`.
//! * **Full-overlap octaves** (`m <= cap`, [`StreamConfig::full_overlap_cap`], default
//!   `2^16`) use every starting point, exactly the batch OADEV: `n = N - 2m` terms. One
//!   shared linear buffer holds the last `2 cap` phase points plus one block of
//!   `B = max(2 cap, 4096)` new ones; each octave reads `x[i]`, `x[i-m]`, `x[i-2m]`
//!   from it. Work is done per block of `B` points whose boundaries are fixed by the
//!   absolute sample index, so how the caller splits its input never changes a single
//!   bit of the result; a report on a partial block processes the pending points on a
//!   copy of the accumulators. The block is swept in L1-sized tiles of 1024 points,
//!   all octaves per tile (octave `j`'s `x[i-2m]` is octave `j+1`'s `x[i-m]`), by a
//!   16-lane kernel (AVX2 or portable, chosen at run time; no FMA, so both give
//!   identical bits).
//!   A block of at least `PARALLEL_MIN_POINTS` (2^14) points runs this kernel on one
//!   thread and the decimation cascade below on another when there is a second
//!   core: the two halves share no state, so the bits do not depend on it.
//! * **Strided octaves** (`m > cap`) keep only every `s`-th phase point,
//!   `s = m / P` with `P` = [`StreamConfig::strided_terms_per_tau`] (default `2^12`),
//!   in a ring of `2P + 1` values, and use the second differences starting at every
//!   `s`-th point: `n = floor((N - 1 - 2m) / s) + 1` terms. (The issue suggested
//!   `P = 2^16`; that costs 1 MB per strided octave, 14 MB for a 72 h run at 10 kHz,
//!   while the EDF with `P = 2^12` is already within 0.7 % of full overlap for
//!   `alpha <= 1` at `m = 2^17` and within 1e-5 for `alpha <= 0`; only white PM, whose
//!   EDF grows like `P`, loses, and white PM does not dominate at `tau > 2^16 tau0`.)
//!   Their EDF is computed honestly for the stride by [`strided_edf`].
//! * **Noise identification** per octave by the lag-1 autocorrelation of the
//!   non-overlapping `m`-decimated phase, differenced once or twice
//!   ([`noise_id`], O(1) amortised per sample). Each block builds a decimation
//!   cascade in a scratch buffer of `B/2` points: level `L` (every `2^L`-th point) is
//!   every other point of level `L-1`, compacted in place; level `L` feeds the noise
//!   identification of octave `2^L` and the ring of the strided octave whose stride is
//!   `2^L`, so both read contiguous memory (fewer than two updates per sample).
//! * **EDF** from first principles for the stride actually used ([`edf_strided`]),
//!   cached per octave and alpha. At stride 1 and stride `m` it is Greenhall's OADEV
//!   and ADEV EDF wherever his algorithm uses the same phase model: identical for
//!   white PM, white FM and RW FM, 0.4 % lower for flicker FM (Greenhall truncates the
//!   lag sum at 3 tau), within his tables' 0.1-3 % where he uses them. For `m <= 33`
//!   and `alpha <= 0` Greenhall averages the phase over `tau0`; the engine samples it
//!   at points, which a Monte-Carlo test shows is right for integrated white FM.
//!   **CIs**: `avar * edf / chi2_{edf}(1 - p)` ... `avar * edf / chi2_{edf}(p)`,
//!   `p = (1 - confidence)/2`, reported as deviations.
//!
//! # Gaps
//! [`OctaveAllan::mark_filled`] marks phase points as filled (made up by a gap
//! fill, not measured). Every term `x[i+2m] - 2 x[i+m] + x[i]` with one of its
//! three points filled is left out and not counted in `n` (so the EDF follows
//! what remains). Only the three points matter: a pulse counter keeps the angle
//! across a gap, so a term whose points are all measured is the gap-free term
//! exactly, even when a gap lies between them (Stable32's rule for frequency
//! data, skip any term whose span holds a gap, would drop every term longer than
//! the spacing of the gaps). Full-overlap octaves sum the left-out terms
//! separately per block (the union of the filled spans shifted by 0, m, 2m) and
//! subtract them when reporting, so the all-measured kernel is unchanged; strided
//! octaves keep a flag per ring slot once a filled point has reached them. The
//! filled spans are kept while they are within the buffer (bounded by it).
//!
//! # Precision
//! Terms are the batch terms bitwise (same evaluation order) for phase input; each
//! block of at most `B` terms is summed in 16 lanes (worst-case relative error
//! `(B/16) eps`, typically `sqrt(B/16) eps` ~ 2e-14; a strided octave has at most
//! `B/s` terms per block, summed in order) and the block sums go into a Neumaier total
//! (error `2 eps`, independent of the 2e4 blocks of a 72 h, 10 kHz run). The noise
//! identification sums use 8 lanes per block and Neumaier totals as well. The counts
//! path is exact up to the final division.
//!
//! # Memory
//! Fixed at construction except for the strided rings, which grow (by doubling, capped
//! at `2P + 1`) only as their octave receives values, so the state is bounded by the
//! octave count and independent of the stream length:
//! `8 (2 cap + B + B/2) + sum_{strided octaves} 8 min(2P + 1, cap_growth(values))`
//! plus about 400 bytes per octave of fixed state. [`StreamConfig::memory_bytes_after`]
//! predicts [`OctaveAllan::memory_bytes`] exactly; for the defaults and a 72 h run at
//! 10 kHz (2.6e9 samples, octaves up to `2^30`) it is 3.7 MB, and 5.7 MB bounds a
//! stream of any length (all 62 octaves' rings full). A report on a partial block
//! briefly clones the accumulators (not the phase buffer) and allocates a `B/2`
//! scratch. Work per sample: one kernel
//! step per full-overlap octave (17 by default) plus O(1) amortised; measured about
//! 40 M samples/s on one core of the 2.5 GHz Xeon used for development
//! (`scripts/bench-allan`).

pub mod noise_id;
pub mod sample;
pub mod strided_edf;

use std::ops::Range;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF};
use thiserror::Error;

pub use noise_id::{MIN_ID_POINTS, NoiseId};
pub use sample::{Neumaier, PhaseValue};
pub use strided_edf::{EdfError, edf_strided};

use crate::dsp::isa::Isa;
use noise_id::OctaveId;
use strided_edf::LagSums;

/// Errors of the streaming Allan engine.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StreamError {
    /// A configuration field is out of range.
    #[error("invalid streaming Allan configuration: {field} = {value}: {reason}")]
    Config {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: String,
        /// What is required.
        reason: &'static str,
    },
    /// A phase or frequency sample is NaN or infinite; samples before it were consumed.
    #[error(
        "non-finite input sample {value} at sample index {index} (0-based; earlier samples were consumed)"
    )]
    NonFinite {
        /// Absolute 0-based index of the sample in the stream.
        index: u64,
        /// The sample.
        value: f64,
    },
    /// Confidence level outside (0, 1).
    #[error("confidence level {confidence} must be strictly between 0 and 1")]
    Confidence {
        /// The rejected level.
        confidence: f64,
    },
    /// EDF computation failed.
    #[error(transparent)]
    Edf(#[from] EdfError),
    /// Chi-square quantile failed.
    #[error("chi-square distribution with edf = {edf}: {reason}")]
    ChiSquare {
        /// Degrees of freedom.
        edf: f64,
        /// Message from statrs.
        reason: String,
    },
}

/// Configuration of an [`OctaveAllan`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StreamConfig {
    /// Sample interval, seconds.
    pub tau0_s: f64,
    /// Largest averaging factor with full overlap (power of two, `1 ..= 2^24`).
    pub full_overlap_cap: u64,
    /// Terms per averaging time `P` beyond the cap: stride `s = m / P` (power of two,
    /// `1 ..= full_overlap_cap`).
    pub strided_terms_per_tau: u64,
    /// Largest octave `j` (`m = 2^j`), at most 62.
    pub max_octave: u32,
    /// Factor applied to the phase before the statistics (e.g. the pulse weight in
    /// arcsec for count input, giving deviations in arcsec/s); default 1.
    pub scale: f64,
}

impl Default for StreamConfig {
    fn default() -> Self {
        Self {
            tau0_s: 1.0,
            full_overlap_cap: 1 << 16,
            strided_terms_per_tau: 1 << 12,
            max_octave: 62,
            scale: 1.0,
        }
    }
}

impl StreamConfig {
    /// Defaults with the given sample interval.
    pub fn with_tau0(tau0_s: f64) -> Self {
        Self {
            tau0_s,
            ..Self::default()
        }
    }

    /// Check every field.
    pub fn validate(&self) -> Result<(), StreamError> {
        let bad = |field, value: String, reason| {
            Err(StreamError::Config {
                field,
                value,
                reason,
            })
        };
        if !(self.tau0_s.is_finite() && self.tau0_s > 0.0) {
            return bad("tau0_s", self.tau0_s.to_string(), "must be finite and > 0");
        }
        let cap = self.full_overlap_cap;
        if !cap.is_power_of_two() || cap > 1 << 24 {
            return bad(
                "full_overlap_cap",
                cap.to_string(),
                "must be a power of two between 1 and 2^24",
            );
        }
        let p = self.strided_terms_per_tau;
        if !p.is_power_of_two() || p > cap {
            return bad(
                "strided_terms_per_tau",
                p.to_string(),
                "must be a power of two between 1 and full_overlap_cap",
            );
        }
        if self.max_octave > 62 {
            return bad(
                "max_octave",
                self.max_octave.to_string(),
                "must be at most 62",
            );
        }
        if !(self.scale.is_finite() && self.scale != 0.0) {
            return bad(
                "scale",
                self.scale.to_string(),
                "must be finite and non-zero",
            );
        }
        Ok(())
    }

    fn geometry(&self) -> Geometry {
        let cap_oct = self.full_overlap_cap.trailing_zeros().min(self.max_octave);
        let hist = 2 * self.full_overlap_cap;
        Geometry {
            cap_oct,
            max_oct: self.max_octave,
            hist,
            block: hist.max(4096),
            p: self.strided_terms_per_tau,
        }
    }

    /// Exact prediction of [`OctaveAllan::memory_bytes`] after `phase_points` phase
    /// points (input samples + 1 for frequency and count input), without running.
    pub fn memory_bytes_after(
        &self,
        kind: InputKind,
        phase_points: u64,
    ) -> Result<usize, StreamError> {
        self.validate()?;
        let g = self.geometry();
        let done = phase_points / g.block * g.block;
        let mut bytes = match kind {
            InputKind::Counts => fixed_bytes::<i64>(&g),
            _ => fixed_bytes::<f64>(&g),
        };
        for j in g.cap_oct + 1..=g.max_oct {
            let m = 1u64 << j;
            let s = m / g.p;
            let values = if done == 0 { 0 } else { (done - 1) / s + 1 };
            bytes += ring_capacity(values, 2 * g.p as usize + 1) * 8;
        }
        Ok(bytes)
    }
}

/// What the samples fed to an [`OctaveAllan`] are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InputKind {
    /// Phase samples (f64).
    Phase,
    /// Frequency or rate samples (f64), integrated to phase.
    Freq,
    /// Pulse-count increments (i64), accumulated exactly.
    Counts,
}

/// One octave of a report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StreamPoint {
    /// Averaging factor (samples).
    pub m: u64,
    /// Averaging time `m * tau0`, seconds.
    pub tau_s: f64,
    /// Distance between starting points of the terms (1 = full overlap).
    pub stride: u64,
    /// Number of second-difference terms (`N - 2m` for full overlap).
    pub n: u64,
    /// Allan variance.
    pub avar: f64,
    /// Allan deviation `sqrt(avar)`.
    pub dev: f64,
    /// Equivalent degrees of freedom for `alpha` and the stride.
    pub edf: f64,
    /// Power-law noise exponent used for the EDF.
    pub alpha: i32,
    /// Whether `alpha` was identified at this octave (false: inherited from the
    /// nearest shorter identified octave, or 0 when none).
    pub alpha_measured: bool,
    /// Lower confidence bound of the deviation.
    pub ci_lo: f64,
    /// Upper confidence bound of the deviation.
    pub ci_hi: f64,
}

impl From<&StreamPoint> for super::AllanPoint {
    /// The batch engine's point type (what the JSON contract prints).
    fn from(p: &StreamPoint) -> Self {
        super::AllanPoint {
            tau_s: p.tau_s,
            m: p.m,
            n: p.n,
            dev: p.dev,
            ci_lo: p.ci_lo,
            ci_hi: p.ci_hi,
            edf: p.edf,
            alpha: p.alpha,
        }
    }
}

/// Chi-square confidence interval of a deviation with `edf` degrees of freedom:
/// `(dev sqrt(edf / chi2(1-p)), dev sqrt(edf / chi2(p)))`, `p = (1 - confidence) / 2`.
pub fn chi2_dev_interval(dev: f64, edf: f64, confidence: f64) -> Result<(f64, f64), StreamError> {
    if !(confidence > 0.0 && confidence < 1.0) {
        return Err(StreamError::Confidence { confidence });
    }
    let chi = ChiSquared::new(edf).map_err(|e| StreamError::ChiSquare {
        edf,
        reason: e.to_string(),
    })?;
    let p = 0.5 * (1.0 - confidence);
    let q_lo = chi.inverse_cdf(p);
    let q_hi = chi.inverse_cdf(1.0 - p);
    Ok((dev * (edf / q_hi).sqrt(), dev * (edf / q_lo).sqrt()))
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Geometry {
    cap_oct: u32,
    max_oct: u32,
    hist: u64,
    block: u64,
    p: u64,
}

/// Capacity of a strided ring after `values` pushes (growth: 8, 16, ... capped at `cap`).
fn ring_capacity(values: u64, cap: usize) -> usize {
    let mut c = 0usize;
    while (c as u64) < values.min(cap as u64) {
        c = (c + c.max(8)).min(cap);
    }
    c
}

type EdfCache = [OnceLock<Result<LagSums, EdfError>>; 5];

fn fixed_bytes<P: PhaseValue>(g: &Geometry) -> usize {
    use std::mem::size_of;
    let octaves = g.max_oct as usize + 1;
    let full = g.cap_oct as usize + 1;
    size_of::<OctaveAllan<P>>()
        + (g.hist + g.block + g.block / 2) as usize * size_of::<P>()
        + full * size_of::<P::Total>()
        + full * (size_of::<P::Total>() + size_of::<u64>())
        + (octaves - full) * size_of::<Strided<P>>()
        + octaves * size_of::<OctaveId<P>>()
        + octaves * size_of::<EdfCache>()
}

/// Phase points per tile of the full-overlap kernel (8 KB per stream).
const TILE: u64 = 1024;
/// `full_overlap_cap <= 2^24` gives at most 25 full-overlap octaves.
const MAX_FULL_OCTAVES: usize = 25;

/// One strided octave: ring of every `s`-th phase point.
#[derive(Clone, Debug)]
struct Strided<P: PhaseValue> {
    /// Stride in samples.
    s: u64,
    /// Terms per averaging time, `m / s`.
    sp: usize,
    ring: Vec<P>,
    /// Values pushed so far.
    count: u64,
    total: P::Total,
    /// Per ring slot: the value is a filled phase point (empty until the first
    /// filled point arrives, then kept parallel to `ring`).
    flags: Vec<bool>,
    /// Terms left out because one of their three points is filled.
    bad: u64,
}

impl<P: PhaseValue> Strided<P> {
    fn new(m: u64, p: u64) -> Self {
        Self {
            s: m / p,
            sp: p as usize,
            ring: Vec::new(),
            count: 0,
            total: P::Total::default(),
            flags: Vec::new(),
            bad: 0,
        }
    }

    /// Push the next decimated phase points (consecutive multiples of `s`);
    /// `flags[i]`: `values[i]` is a filled point (`None`: none is).
    #[inline(always)]
    fn feed(&mut self, values: &[P], flags: Option<&[bool]>) {
        if values.is_empty() {
            return;
        }
        if flags.is_some() || !self.flags.is_empty() {
            return self.feed_flagged(values, flags);
        }
        let len = 2 * self.sp + 1;
        let mut partial = P::Partial::default();
        // Write position `w = count mod len`; with len = 2S + 1 the values S and 2S
        // points back sit at `w + S + 1` and `w + 1` (mod len).
        let mut w = (self.count % len as u64) as usize;
        for &x in values {
            if self.count >= 2 * self.sp as u64 {
                let ia = if w + 1 == len { 0 } else { w + 1 };
                let ib = if w + self.sp + 1 >= len {
                    w + self.sp + 1 - len
                } else {
                    w + self.sp + 1
                };
                P::sq_add(&mut partial, self.ring[ia], self.ring[ib], x);
            }
            if self.ring.len() < len {
                if self.ring.len() == self.ring.capacity() {
                    let cap = self.ring.capacity();
                    self.ring.reserve_exact((cap.max(8)).min(len - cap));
                }
                self.ring.push(x);
            } else {
                self.ring[w] = x;
            }
            self.count += 1;
            w = if w + 1 == len { 0 } else { w + 1 };
        }
        P::total_add(&mut self.total, partial);
    }

    /// [`Self::feed`] once filled points have been seen: a term whose three
    /// points include a filled one is left out (and counted in `bad`).
    #[inline(never)]
    fn feed_flagged(&mut self, values: &[P], flags: Option<&[bool]>) {
        let len = 2 * self.sp + 1;
        if self.flags.len() < self.ring.len() {
            self.flags.resize(self.ring.len(), false);
        }
        let mut partial = P::Partial::default();
        let mut w = (self.count % len as u64) as usize;
        for (k, &x) in values.iter().enumerate() {
            let f = flags.is_some_and(|f| f[k]);
            if self.count >= 2 * self.sp as u64 {
                let ia = if w + 1 == len { 0 } else { w + 1 };
                let ib = if w + self.sp + 1 >= len {
                    w + self.sp + 1 - len
                } else {
                    w + self.sp + 1
                };
                if f || self.flags[ia] || self.flags[ib] {
                    self.bad += 1;
                } else {
                    P::sq_add(&mut partial, self.ring[ia], self.ring[ib], x);
                }
            }
            if self.ring.len() < len {
                if self.ring.len() == self.ring.capacity() {
                    let cap = self.ring.capacity();
                    self.ring.reserve_exact((cap.max(8)).min(len - cap));
                }
                self.ring.push(x);
                self.flags.push(f);
            } else {
                self.ring[w] = x;
                self.flags[w] = f;
            }
            self.count += 1;
            w = if w + 1 == len { 0 } else { w + 1 };
        }
        P::total_add(&mut self.total, partial);
    }

    /// Terms in the total (all terms less those left out).
    fn terms(&self) -> u64 {
        self.count.saturating_sub(2 * self.sp as u64) - self.bad
    }
}

/// Everything that a block of phase points updates.
#[derive(Clone, Debug)]
struct Accumulators<P: PhaseValue> {
    /// Phase points whose terms are accumulated.
    done: u64,
    full: Vec<P::Total>,
    /// Per full-overlap octave: the part of `full` from terms touching a
    /// filled phase point, and their count (subtracted when reporting).
    bad_full: Vec<P::Total>,
    bad_n: Vec<u64>,
    strided: Vec<Strided<P>>,
    id: Vec<OctaveId<P>>,
}

impl<P: PhaseValue> Accumulators<P> {
    fn new(g: &Geometry) -> Self {
        let full = vec![P::Total::default(); g.cap_oct as usize + 1];
        let strided = (g.cap_oct + 1..=g.max_oct)
            .map(|j| Strided::new(1u64 << j, g.p))
            .collect();
        let id = (0..=g.max_oct).map(|_| OctaveId::default()).collect();
        Self {
            done: 0,
            bad_full: full.clone(),
            bad_n: vec![0; full.len()],
            full,
            strided,
            id,
        }
    }

    /// Accumulate the phase points `[done, end)`; `buf[0]` is point `base`; `done` is
    /// a multiple of `g.block`. `scratch` (capacity `block / 2`) holds the decimation
    /// cascade.
    /// `filled`: sorted, disjoint spans of filled phase points (at least all
    /// those below `end`).
    fn process(
        &mut self,
        g: &Geometry,
        buf: &[P],
        base: u64,
        end: u64,
        scratch: &mut Vec<P>,
        filled: &[Range<u64>],
    ) {
        let b0 = self.done;
        if !filled.is_empty() && end > b0 {
            self.subtract_filled(buf, base, b0, end, filled);
        }
        if end <= b0 {
            return;
        }
        let Self {
            full, id, strided, ..
        } = self;
        let mut kernel = || full_overlap(full, buf, base, b0, end);
        let cascade = Cascade {
            g,
            id,
            strided,
            buf,
            base,
            b0,
            end,
            scratch,
            filled,
        };
        let cascade = || decimate(cascade);
        if end - b0 >= PARALLEL_MIN_POINTS {
            crate::par::join(kernel, cascade);
        } else {
            kernel();
            cascade();
        }
        self.done = end;
    }

    /// Full-overlap octaves: sum, separately, the terms ending in `[b0, end)`
    /// whose three points `x[i-2m], x[i-m], x[i]` include a filled one (the
    /// union of the filled spans shifted by 0, m and 2m), so that reports
    /// subtract them. The main kernel stays unmasked: an all-measured stream
    /// costs nothing here.
    fn subtract_filled(&mut self, buf: &[P], base: u64, b0: u64, end: u64, filled: &[Range<u64>]) {
        let mut iv: Vec<(u64, u64)> = Vec::new();
        for j in 0..self.full.len() {
            let m = 1u64 << j;
            let lo = b0.max(2 * m);
            if lo >= end {
                continue;
            }
            iv.clear();
            for sp in filled {
                if sp.start >= end {
                    break;
                }
                for sh in [0, m, 2 * m] {
                    let (u, v) = ((sp.start + sh).max(lo), (sp.end + sh).min(end));
                    if u < v {
                        iv.push((u, v));
                    }
                }
            }
            if iv.is_empty() {
                continue;
            }
            iv.sort_unstable();
            let mut lanes = P::Lanes::default();
            let mut n = 0;
            let (mut cu, mut cv) = iv[0];
            for &(u, v) in iv[1..].iter().chain(std::iter::once(&(u64::MAX, u64::MAX))) {
                if u <= cv {
                    cv = cv.max(v);
                    continue;
                }
                let (l, h, mu) = ((cu - base) as usize, (cv - base) as usize, m as usize);
                P::sq_acc(
                    &buf[l - 2 * mu..h - 2 * mu],
                    &buf[l - mu..h - mu],
                    &buf[l..h],
                    &mut lanes,
                );
                n += cv - cu;
                (cu, cv) = (u, v);
            }
            P::total_add(&mut self.bad_full[j], P::lanes_partial(&lanes));
            self.bad_n[j] += n;
        }
    }
}

/// Blocks of at least this many phase points run the full-overlap kernel and
/// the decimation cascade on two threads (each half computes exactly what it
/// computes alone, so the bits do not depend on it).
const PARALLEL_MIN_POINTS: u64 = 1 << 14;

/// Full-overlap octaves: the terms ending in `[b0, end)` added to `full`
/// (`buf[0]` is point `base`).
fn full_overlap<P: PhaseValue>(full: &mut [P::Total], buf: &[P], base: u64, b0: u64, end: u64) {
    match Isa::detect() {
        Isa::Baseline => full_overlap_body(full, buf, base, b0, end),
        // SAFETY: an `Avx2` or `Avx512` exists only on a CPU with AVX2
        // (crate::dsp::isa), the one feature the variant enables.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 => unsafe { full_overlap_avx2(full, buf, base, b0, end) },
    }
}

/// The same code compiled for 256-bit vectors (no FMA: identical results).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn full_overlap_avx2<P: PhaseValue>(
    full: &mut [P::Total],
    buf: &[P],
    base: u64,
    b0: u64,
    end: u64,
) {
    full_overlap_body(full, buf, base, b0, end)
}

#[inline(always)]
fn full_overlap_body<P: PhaseValue>(
    full: &mut [P::Total],
    buf: &[P],
    base: u64,
    b0: u64,
    end: u64,
) {
    // In L1-sized tiles at absolute boundaries (b0 is a multiple of the
    // block, hence of TILE): octave j reads x[i-2m], which octave j+1 reads
    // next as x[i-m], so the tile's working set stays in cache.
    let mut lanes = [P::Lanes::default(); MAX_FULL_OCTAVES];
    let lanes = &mut lanes[..full.len()];
    let mut t0 = b0;
    while t0 < end {
        let t1 = (t0 + TILE).min(end);
        for (j, lane) in lanes.iter_mut().enumerate() {
            let m = 1u64 << j;
            let lo = t0.max(2 * m);
            if lo >= t1 {
                continue;
            }
            let (lo, hi, mu) = ((lo - base) as usize, (t1 - base) as usize, m as usize);
            P::sq_acc(
                &buf[lo - 2 * mu..hi - 2 * mu],
                &buf[lo - mu..hi - mu],
                &buf[lo..hi],
                lane,
            );
        }
        t0 = t1;
    }
    for (total, lane) in full.iter_mut().zip(lanes.iter()) {
        P::total_add(total, P::lanes_partial(lane));
    }
}

/// One block's decimation cascade: the points `[b0, end)` of `buf` (`buf[0]`
/// is point `base`), the noise identification of every octave and the
/// strided octaves' rings they feed, and `scratch` (capacity `block / 2`)
/// for the cascade.
struct Cascade<'a, P: PhaseValue> {
    g: &'a Geometry,
    id: &'a mut [OctaveId<P>],
    strided: &'a mut [Strided<P>],
    buf: &'a [P],
    base: u64,
    b0: u64,
    end: u64,
    scratch: &'a mut Vec<P>,
    filled: &'a [Range<u64>],
}

/// Run the cascade.
fn decimate<P: PhaseValue>(c: Cascade<'_, P>) {
    match Isa::detect() {
        Isa::Baseline => decimate_body(c),
        // SAFETY: as in `full_overlap`.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 => unsafe { decimate_avx2(c) },
    }
}

/// The same code compiled for 256-bit vectors (no FMA: identical results).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn decimate_avx2<P: PhaseValue>(c: Cascade<'_, P>) {
    decimate_body(c)
}

#[inline(always)]
fn decimate_body<P: PhaseValue>(c: Cascade<'_, P>) {
    let Cascade {
        g,
        id,
        strided,
        buf,
        base,
        b0,
        end,
        scratch,
        filled,
    } = c;
    // Level 0 (the noise identification of m = 1) and the level-1 decimation,
    // tile by tile (t0 is even).
    scratch.clear();
    let mut t0 = b0;
    while t0 < end {
        let t1 = (t0 + TILE).min(end);
        let tile = &buf[(t0 - base) as usize..(t1 - base) as usize];
        id[0].feed(tile);
        if g.max_oct >= 1 {
            scratch.extend(tile.iter().step_by(2).copied());
        }
        t0 = t1;
    }
    // Decimation cascade: level L holds the points at multiples of 2^L in
    // [b0, end). It feeds the noise identification of octave 2^L and the strided
    // octave whose stride is 2^L (octave L + log2 P; never level 0, as P <= cap).
    // Level 0 was fed tile by tile above, level 1 gathered there. While
    // 2^L <= block, b0 is a multiple of 2^L and level L + 1 is every other point of
    // level L (compacted in place); beyond, a level has at most one point.
    let p_oct = g.p.trailing_zeros();
    // filled spans that reach into this block (for the strided octaves' flags)
    let touching = filled
        .iter()
        .skip_while(|r| r.end <= b0)
        .take_while(|r| r.start < end);
    let touching: Vec<Range<u64>> = touching.cloned().collect();
    let mut flags: Vec<bool> = Vec::new();
    for level in 1..=g.max_oct {
        let step = 1u64 << level;
        let single;
        let first = if step <= g.block {
            b0
        } else {
            b0.next_multiple_of(step)
        };
        let values: &[P] = if step <= g.block {
            if level >= 2 {
                let n = scratch.len().div_ceil(2);
                for k in 0..n {
                    scratch[k] = scratch[2 * k];
                }
                scratch.truncate(n);
            }
            scratch
        } else {
            let first = b0.next_multiple_of(step);
            if first >= end {
                continue;
            }
            single = [buf[(first - base) as usize]];
            &single
        };
        id[level as usize].feed(values);
        let j = level + p_oct;
        if j > g.cap_oct && j <= g.max_oct {
            let fl = if touching.is_empty() {
                None
            } else {
                flags.clear();
                let mut r = touching.iter().peekable();
                flags.extend((0..values.len() as u64).map(|k| {
                    let p = first + k * step;
                    while r.next_if(|s| s.end <= p).is_some() {}
                    r.peek().is_some_and(|s| s.start <= p)
                }));
                Some(&flags[..])
            };
            strided[(j - g.cap_oct - 1) as usize].feed(values, fl);
        }
    }
}

/// Index of the first NaN or infinity: a branch-free (vectorisable) scan first, the
/// position only when there is one.
fn first_non_finite(v: &[f64]) -> Option<usize> {
    if v.iter().fold(true, |ok, x| ok & x.is_finite()) {
        None
    } else {
        v.iter().position(|x| !x.is_finite())
    }
}

/// Samples per integration quarter (see [`Integrator::integrate`]).
const QUARTER: usize = 256;

/// Running state of the input integration.
#[derive(Clone, Copy, Debug, Default)]
struct Integrator {
    /// First frequency sample (the causal offset removed before integrating).
    y0: f64,
    /// Compensated sum of all completed quarters.
    base: Neumaier,
    /// `base` at the start of the current quarter.
    off: f64,
    /// Prefix sum within the current quarter.
    p: f64,
    /// Cumulative pulse count (wrapping).
    count: i64,
}

impl Integrator {
    /// Integrate `ys` (input samples `k0, k0 + 1, ...`) to phase points
    /// `x[k+1] = x[k] + (y[k] - y0)`, appended to `out`.
    ///
    /// Quarters of [`QUARTER`] samples at absolute sample indices: within a quarter a
    /// plain prefix sum `p`, each point stored as `off + p`, where `off` is the
    /// Neumaier sum of all earlier quarter totals. The stored value depends only on the
    /// samples up to it, never on how the input was split. Four whole quarters in a
    /// row are integrated as four independent chains (4x the speed of one dependent
    /// chain) with exactly the same operations. Error of a stored point: at most
    /// `eps |x| + 256 eps max|p|`, independent of the stream length.
    fn integrate(&mut self, k0: u64, ys: &[f64], out: &mut Vec<f64>) {
        let y0 = self.y0;
        let q = QUARTER as u64;
        let mut k = k0;
        let mut i = 0;
        while i < ys.len() {
            if k.is_multiple_of(q) && ys.len() - i >= 4 * QUARTER {
                let mut tmp = [0.0f64; 4 * QUARTER];
                let mut pq = [0.0f64; 4];
                let group = &ys[i..i + 4 * QUARTER];
                for j in 0..QUARTER {
                    for l in 0..4 {
                        pq[l] += group[l * QUARTER + j] - y0;
                        tmp[l * QUARTER + j] = pq[l];
                    }
                }
                let mut prev = self.p;
                let mut offs = [0.0f64; 4];
                for (l, off) in offs.iter_mut().enumerate() {
                    self.base.add(prev);
                    *off = self.base.value();
                    prev = pq[l];
                }
                self.off = offs[3];
                self.p = prev;
                for (l, &off) in offs.iter().enumerate() {
                    out.extend(tmp[l * QUARTER..(l + 1) * QUARTER].iter().map(|&v| v + off));
                }
                i += 4 * QUARTER;
                k += 4 * q;
                continue;
            }
            let until = ys.len().min(i + (q - k % q) as usize);
            for &y in &ys[i..until] {
                if k.is_multiple_of(q) {
                    self.base.add(self.p);
                    self.off = self.base.value();
                    self.p = 0.0;
                }
                self.p += y - y0;
                out.push(self.off + self.p);
                k += 1;
            }
            i = until;
        }
    }
}

/// Streaming octave-spaced OADEV accumulator (see the module docs).
///
/// `P = f64` for phase and frequency input, `P = i64` for pulse-count increments.
#[derive(Clone, Debug)]
pub struct OctaveAllan<P: PhaseValue = f64> {
    cfg: StreamConfig,
    kind: InputKind,
    geo: Geometry,
    samples: u64,
    integ: Integrator,
    /// Phase points `buf_start .. buf_start + buf.len()`.
    buf: Vec<P>,
    buf_start: u64,
    acc: Accumulators<P>,
    /// Decimation cascade scratch (`block / 2` points), reused by every block.
    scratch: Vec<P>,
    edf_cache: Vec<EdfCache>,
    /// Sorted, disjoint spans of filled phase points not yet behind the buffer.
    filled: Vec<Range<u64>>,
}

impl OctaveAllan<f64> {
    /// Accumulator for phase samples.
    pub fn phase(cfg: StreamConfig) -> Result<Self, StreamError> {
        Self::build(cfg, InputKind::Phase)
    }

    /// Accumulator for frequency (rate) samples.
    pub fn freq(cfg: StreamConfig) -> Result<Self, StreamError> {
        Self::build(cfg, InputKind::Freq)
    }

    /// Add one sample.
    pub fn push(&mut self, sample: f64) -> Result<(), StreamError> {
        self.push_block(std::slice::from_ref(&sample))
    }

    /// Add a block of samples. On a non-finite sample the samples before it are
    /// consumed and an error naming its index is returned.
    pub fn push_block(&mut self, samples: &[f64]) -> Result<(), StreamError> {
        let mut rest = samples;
        if self.kind == InputKind::Freq
            && self.samples == 0
            && let Some(&y) = rest.first()
        {
            if !y.is_finite() {
                return Err(StreamError::NonFinite { index: 0, value: y });
            }
            self.integ.y0 = y;
            self.append_one(0.0);
        }
        while !rest.is_empty() {
            let take = self.room().min(rest.len());
            let (seg, tail) = rest.split_at(take);
            let bad = match self.kind {
                InputKind::Freq => {
                    // a non-finite sample makes every later phase point of
                    // the segment non-finite (the running sums carry it), so
                    // the segment is scanned only when its last point is
                    let (saved, len0) = (self.integ, self.buf.len());
                    self.integ.integrate(self.samples, seg, &mut self.buf);
                    let bad = match self.buf.last() {
                        Some(x) if !x.is_finite() => first_non_finite(seg),
                        _ => None,
                    };
                    if let Some(i) = bad {
                        self.integ = saved;
                        self.buf.truncate(len0);
                        self.integ.integrate(self.samples, &seg[..i], &mut self.buf);
                    }
                    bad
                }
                _ => match first_non_finite(seg) {
                    Some(i) => {
                        self.buf.extend_from_slice(&seg[..i]);
                        Some(i)
                    }
                    None => {
                        self.buf.extend_from_slice(seg);
                        None
                    }
                },
            };
            if let Some(i) = bad {
                self.samples += i as u64;
                self.maybe_flush();
                return Err(StreamError::NonFinite {
                    index: self.samples,
                    value: seg[i],
                });
            }
            self.samples += take as u64;
            self.maybe_flush();
            rest = tail;
        }
        Ok(())
    }
}

impl OctaveAllan<i64> {
    /// Accumulator for integer pulse-count increments.
    pub fn counts(cfg: StreamConfig) -> Result<Self, StreamError> {
        Self::build(cfg, InputKind::Counts)
    }

    /// Add one count increment.
    pub fn push(&mut self, increment: i64) {
        self.push_block(std::slice::from_ref(&increment));
    }

    /// Add a block of count increments (wrapping cumulative count: never fails).
    pub fn push_block(&mut self, increments: &[i64]) {
        if self.samples == 0 && !increments.is_empty() {
            self.append_one(0);
        }
        let mut rest = increments;
        while !rest.is_empty() {
            let take = self.room().min(rest.len());
            let (seg, tail) = rest.split_at(take);
            let mut c = self.integ.count;
            for &d in seg {
                c = c.wrapping_add(d);
                self.buf.push(c);
            }
            self.integ.count = c;
            self.samples += take as u64;
            self.maybe_flush();
            rest = tail;
        }
    }
}

impl<P: PhaseValue> OctaveAllan<P> {
    fn build(cfg: StreamConfig, kind: InputKind) -> Result<Self, StreamError> {
        cfg.validate()?;
        let geo = cfg.geometry();
        let buf = Vec::with_capacity((geo.hist + geo.block) as usize);
        let edf_cache = (0..=geo.max_oct).map(|_| EdfCache::default()).collect();
        Ok(Self {
            acc: Accumulators::new(&geo),
            cfg,
            kind,
            geo,
            samples: 0,
            integ: Integrator::default(),
            buf,
            buf_start: 0,
            scratch: Vec::with_capacity((geo.block / 2) as usize),
            edf_cache,
            filled: Vec::new(),
        })
    }

    /// Phase points until the next block boundary.
    fn room(&self) -> usize {
        (self.acc.done + self.geo.block - self.phase_points()) as usize
    }

    fn append_one(&mut self, x: P) {
        self.buf.push(x);
        self.maybe_flush();
    }

    /// Process the block when it is complete and drop history older than `2 cap`.
    fn maybe_flush(&mut self) {
        let end = self.phase_points();
        if end < self.acc.done + self.geo.block {
            return;
        }
        self.acc.process(
            &self.geo,
            &self.buf,
            self.buf_start,
            end,
            &mut self.scratch,
            &self.filled,
        );
        let keep = self.geo.hist as usize;
        if self.buf.len() > keep {
            let drop = self.buf.len() - keep;
            self.buf.copy_within(drop.., 0);
            self.buf.truncate(keep);
            self.buf_start += drop as u64;
        }
        let old = self
            .filled
            .iter()
            .take_while(|r| r.end <= self.buf_start)
            .count();
        if old > 0 {
            self.filled.drain(..old);
        }
    }

    /// Input samples consumed.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Mark the phase points `span` (absolute indices, counted like
    /// [`Self::phase_points`]) as filled, not measured: every second difference
    /// `x[i+2m] - 2 x[i+m] + x[i]` with one of its three points in a filled span
    /// is left out of the sums and of the term counts (`n`, hence the EDF).
    /// Spans may be marked ahead of their points and must come in increasing
    /// order (overlapping or adjacent ones are merged); a span must be marked
    /// before the point completing its block is pushed (marking it before the
    /// samples it covers is always in time). For frequency and count input,
    /// sample `k` ends at phase point `k + 1`: a filled sample `k` makes point
    /// `k + 1` filled (the integral up to it is unknown), while point `k` stays
    /// measured.
    pub fn mark_filled(&mut self, span: Range<u64>) {
        if span.is_empty() {
            return;
        }
        match self.filled.last_mut() {
            Some(last) if span.start <= last.end => last.end = last.end.max(span.end),
            _ => self.filled.push(span),
        }
    }

    /// Phase points seen (`samples + 1` for frequency and count input once started).
    pub fn phase_points(&self) -> u64 {
        self.buf_start + self.buf.len() as u64
    }

    /// The input kind chosen at construction.
    pub fn input_kind(&self) -> InputKind {
        self.kind
    }

    /// The configuration.
    pub fn config(&self) -> &StreamConfig {
        &self.cfg
    }

    /// Forget all samples (configuration and the EDF cache are kept).
    pub fn reset(&mut self) {
        self.samples = 0;
        self.integ = Integrator::default();
        self.buf.clear();
        self.buf_start = 0;
        self.acc = Accumulators::new(&self.geo);
        self.filled.clear();
    }

    /// Bytes of state held (struct, buffer, rings, per-octave state).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        size_of::<Self>()
            + self.buf.capacity() * size_of::<P>()
            + self.scratch.capacity() * size_of::<P>()
            + self.acc.full.capacity() * size_of::<P::Total>()
            + self.acc.strided.capacity() * size_of::<Strided<P>>()
            + self
                .acc
                .strided
                .iter()
                .map(|s| s.ring.capacity() * size_of::<P>() + s.flags.capacity())
                .sum::<usize>()
            + self.filled.capacity() * size_of::<Range<u64>>()
            + self.acc.bad_full.capacity() * size_of::<P::Total>()
            + self.acc.bad_n.capacity() * size_of::<u64>()
            + self.acc.id.capacity() * size_of::<OctaveId<P>>()
            + self.edf_cache.capacity() * size_of::<EdfCache>()
    }

    /// Accumulators including the pending partial block.
    fn current(&self) -> std::borrow::Cow<'_, Accumulators<P>> {
        if self.acc.done == self.phase_points() {
            std::borrow::Cow::Borrowed(&self.acc)
        } else {
            let mut acc = self.acc.clone();
            let mut scratch = Vec::with_capacity((self.geo.block / 2) as usize);
            acc.process(
                &self.geo,
                &self.buf,
                self.buf_start,
                self.phase_points(),
                &mut scratch,
                &self.filled,
            );
            std::borrow::Cow::Owned(acc)
        }
    }

    /// Noise identification of every octave `m = 2^j` that has at least one
    /// decimated difference, as `(m, id)`.
    pub fn noise_ids(&self) -> Vec<(u64, NoiseId)> {
        let acc = self.current();
        acc.id
            .iter()
            .enumerate()
            .map(|(j, id)| (1u64 << j, id.identify()))
            .filter(|(_, id)| id.points > 0)
            .collect()
    }

    /// The octave-spaced OADEV now, with `confidence` (e.g. 0.683) chi-square bounds,
    /// for every octave with at least one term.
    pub fn points(&self, confidence: f64) -> Result<Vec<StreamPoint>, StreamError> {
        if !(confidence > 0.0 && confidence < 1.0) {
            return Err(StreamError::Confidence { confidence });
        }
        let acc = self.current();
        let n_phi = self.phase_points();
        let unit = match self.kind {
            InputKind::Freq => self.cfg.tau0_s,
            _ => 1.0,
        } * self.cfg.scale;
        let tau0 = self.cfg.tau0_s;
        let mut out = Vec::new();
        let mut inherited: Option<i32> = None;
        for j in 0..=self.geo.max_oct {
            let m = 1u64 << j;
            if n_phi < 2 * m + 1 {
                break;
            }
            let id = acc.id[j as usize].identify();
            if id.alpha.is_some() {
                inherited = id.alpha;
            }
            let alpha = id.alpha.or(inherited).unwrap_or(0);
            let (stride, n, total) = if j <= self.geo.cap_oct {
                let jj = j as usize;
                let bad = acc.bad_n[jj];
                let total = if bad == 0 {
                    P::total_value(&acc.full[jj])
                } else {
                    P::total_diff(&acc.full[jj], &acc.bad_full[jj])
                };
                (1, n_phi - 2 * m - bad, total)
            } else {
                let st = &acc.strided[(j - self.geo.cap_oct - 1) as usize];
                (st.s, st.terms(), P::total_value(&st.total))
            };
            if n == 0 {
                // every term touches a filled point
                continue;
            }
            let mf = m as f64;
            let avar = total * unit * unit / (2.0 * mf * mf * tau0 * tau0 * n as f64);
            let dev = avar.sqrt();
            let sums = self.edf_cache[j as usize][(alpha + 2) as usize]
                .get_or_init(|| LagSums::compute(alpha, m, stride))
                .clone()?;
            let edf = sums.edf_for(alpha, m, stride, n);
            let (ci_lo, ci_hi) = chi2_dev_interval(dev, edf, confidence)?;
            out.push(StreamPoint {
                m,
                tau_s: mf * tau0,
                stride,
                n,
                avar,
                dev,
                edf,
                alpha,
                alpha_measured: id.alpha.is_some(),
                ci_lo,
                ci_hi,
            });
        }
        Ok(out)
    }
}
