//! Glitches: single-sample outliers, found with a robust test calibrated on
//! the record's own noise, and excluded as gaps.
//!
//! A glitch is a spike in what the sensor measures. A rate word's spike is
//! one sample off; a pulse counter's is one frame whose counter reading is
//! off while the next is right again, so the increments carry `+x` then `-x`
//! (the measured *angle* has a one-sample spike). Both are found with the
//! same statistic on the measured series `y` (the rate of a rate word, the
//! angle of a counter): its departure from the mean of its neighbours,
//!
//! ```text
//! e_k = y_k - (y_{k-1} + y_{k+1}) / 2      (a counter: e_k = (c_k - c_{k+1}) / 2 pulses)
//! ```
//!
//! which is `A` at a spike of size `A` and `-A/2` beside it, and removes the
//! slow parts of the signal (bias, drift, warm-up). Its scale `s` is measured
//! per window of [`WINDOW`] samples from the 90th percentile of `|e|` (a
//! Gaussian's `1.645 sigma`), which up to a few per cent of outliers do not
//! move, and floored at the quantization's own spread (`0.354` quanta: a
//! counter's pulse, or a rate word's LSB when the values lie on a grid). A
//! sample is an outlier when `|e_k| > T s` (`T` = [`THRESHOLD_SIGMA`] = 6: a
//! false alarm per 5e8 samples of Gaussian noise) and is the largest of its
//! neighbours. An outlier is replaced and marked filled: a counter's pair by
//! the pair's total spread over the two samples as integers (the angle after
//! it stays exact), a rate word by the mean of its neighbours; the pipeline's
//! statistics leave filled samples out.
//!
//! A sensor whose noise is heavy-tailed everywhere is not a glitch: a window
//! with more than [`MAX_FRACTION`] of its samples beyond the threshold, or
//! with the band between half the threshold and the threshold populated well
//! beyond a Gaussian's share (isolated glitches leave it empty), keeps them
//! (they are counted, and the report says the noise is heavy-tailed).
//!
//! Windows are fixed by absolute sample index, so the decisions do not depend
//! on how the samples are pushed ([`SpikeFilter`] buffers one window and
//! emits it decided); [`find_batch`] is the whole-record reference.

use std::ops::Range;

use serde::Serialize;

/// Samples per decision window.
pub const WINDOW: usize = 4096;
/// Samples after a window needed to decide its last one.
const LOOKAHEAD: usize = 2;
/// Threshold on `|e| / s`.
pub const THRESHOLD_SIGMA: f64 = 6.0;
/// Largest fraction of a window's samples that can be glitches; more is
/// heavy-tailed noise, kept.
pub const MAX_FRACTION: f64 = 0.005;
/// A Gaussian's share of `|z|` between `T/2` and `T` (`2 (Phi(-3) - Phi(-6))`).
const MID_SHARE: f64 = 0.002_699_794;
/// The 90th percentile of `|z|` for a standard normal `z`.
const Q90_ABS_NORMAL: f64 = 1.644_853_626_951_472_2;
/// Spread of `e` from quantization alone, in quanta: `sqrt(1.5 / 12)`.
const QUANT_FLOOR: f64 = 0.353_553_390_593_273_8;
/// Outliers whose times are listed.
pub const MAX_LISTED: usize = 1000;
/// Detection passes per window (a second glitch beside a replaced one).
const PASSES: usize = 3;
/// Longest run of filled samples a rate glitch's test and replacement step
/// over (adjacent glitches); a longer one is an input gap.
const MAX_RUN: usize = 4;

/// What the filter found.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SpikeReport {
    /// Outliers found (excluded, or kept in heavy-tailed windows).
    pub count: u64,
    /// Sample index of the first [`MAX_LISTED`] outliers.
    pub at: Vec<u64>,
    /// Outliers replaced and marked filled.
    pub excluded: u64,
    /// Windows whose noise was heavy-tailed (outliers kept).
    pub heavy_windows: u64,
    /// Windows decided.
    pub windows: u64,
    /// The largest `|e|` among the outliers (the statistic's unit: pulses
    /// for a counter, the rate's unit for a rate word).
    pub max_abs: f64,
    /// Sum of `e^2` and `e^4` over the samples kept, and their number (the
    /// excess kurtosis of the statistic).
    sum2: f64,
    sum4: f64,
    n: u64,
}

impl SpikeReport {
    /// Excess kurtosis of the test statistic over the samples kept (0 for
    /// Gaussian noise); `None` before any sample.
    pub fn excess_kurtosis(&self) -> Option<f64> {
        (self.n > 0 && self.sum2 > 0.0).then(|| {
            let m2 = self.sum2 / self.n as f64;
            self.sum4 / self.n as f64 / (m2 * m2) - 3.0
        })
    }
}

/// What the samples are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Series {
    /// Pulse increments of a counter (a glitch is a `+x, -x` pair).
    Counts,
    /// Rate samples (a glitch is one sample).
    Rates,
}

/// The samples of one window and after it, in either form.
#[derive(Debug)]
enum Buf {
    Counts(Vec<i64>),
    Rates(Vec<f64>),
}

impl Buf {
    fn len(&self) -> usize {
        match self {
            Buf::Counts(v) => v.len(),
            Buf::Rates(v) => v.len(),
        }
    }
}

/// A decided chunk: samples and filled spans (relative to the chunk; a span
/// running past it keeps its end, as the pipeline's mask wants).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Emitted {
    pub counts: Vec<i64>,
    pub rates: Vec<f64>,
    pub filled: Vec<Range<usize>>,
}

impl Emitted {
    pub fn clear(&mut self) {
        self.counts.clear();
        self.rates.clear();
        self.filled.clear();
    }
}

/// The streaming filter: buffers one window (plus two samples), decides it,
/// and emits it.
#[derive(Debug)]
pub struct SpikeFilter {
    buf: Buf,
    /// Filled spans of `buf` (input gaps and replaced outliers).
    filled: Vec<Range<usize>>,
    /// Absolute index of `buf[0]`.
    start: u64,
    /// The last emitted rate (the left neighbour of `buf[0]`).
    prev: Option<f64>,
    /// Quantum of a rate word, when the values lie on a grid (0: none found).
    quantum: f64,
    /// The last window's scale (for a short final window).
    last_scale: Option<f64>,
    report: SpikeReport,
    e: Vec<f64>,
    scratch: Vec<f64>,
}

impl SpikeFilter {
    pub fn new(series: Series) -> SpikeFilter {
        SpikeFilter {
            buf: match series {
                Series::Counts => Buf::Counts(Vec::new()),
                Series::Rates => Buf::Rates(Vec::new()),
            },
            filled: Vec::new(),
            start: 0,
            prev: None,
            quantum: f64::NAN,
            last_scale: None,
            report: SpikeReport::default(),
            e: Vec::new(),
            scratch: Vec::new(),
        }
    }

    pub fn report(&self) -> &SpikeReport {
        &self.report
    }

    /// Samples taken but not yet emitted.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Push pulse increments (`filled`: spans made up by a gap fill,
    /// relative to `counts`); decided windows are appended to `out`.
    pub fn push_counts(&mut self, counts: &[i64], filled: &[Range<usize>], out: &mut Emitted) {
        let Buf::Counts(v) = &mut self.buf else {
            panic!("SpikeFilter::push_counts on a filter of rates");
        };
        let base = v.len();
        v.extend_from_slice(counts);
        add_spans(&mut self.filled, filled, base);
        self.drain_windows(out);
    }

    /// Push rates (any unit); as [`SpikeFilter::push_counts`].
    pub fn push_rates(&mut self, rates: &[f64], filled: &[Range<usize>], out: &mut Emitted) {
        let Buf::Rates(v) = &mut self.buf else {
            panic!("SpikeFilter::push_rates on a filter of counts");
        };
        let base = v.len();
        v.extend_from_slice(rates);
        add_spans(&mut self.filled, filled, base);
        self.drain_windows(out);
    }

    /// End of stream: decide and emit what is left.
    pub fn finish(&mut self, out: &mut Emitted) {
        let n = self.buf.len();
        if n > 0 {
            self.decide(n, true);
            self.emit(n, out);
        }
    }

    fn drain_windows(&mut self, out: &mut Emitted) {
        while self.buf.len() >= WINDOW + LOOKAHEAD {
            self.decide(WINDOW, false);
            self.emit(WINDOW, out);
        }
    }

    /// Find and replace the outliers among the first `n` samples.
    fn decide(&mut self, n: usize, last: bool) {
        if self.quantum.is_nan() {
            self.quantum = match &self.buf {
                Buf::Counts(_) => 1.0,
                Buf::Rates(v) => grid_quantum(v),
            };
        }
        let floor = QUANT_FLOOR * self.quantum;
        self.report.windows += 1;
        let mut scale = None;
        for pass in 0..PASSES {
            statistic(&self.buf, self.prev, &self.filled, n, last, &mut self.e);
            let s = match scale {
                Some(s) => s,
                None => {
                    let s = robust_scale(&self.e, &mut self.scratch)
                        .or(self.last_scale)
                        .unwrap_or(0.0)
                        .max(floor);
                    if !last || self.e.len() >= WINDOW / 4 {
                        self.last_scale = Some(s);
                    }
                    scale = Some(s);
                    s
                }
            };
            if !(s > 0.0) {
                break;
            }
            let across = if matches!(self.buf, Buf::Rates(_)) {
                MAX_RUN
            } else {
                0
            };
            // the sample after the window is a neighbour in the test (a
            // glitch there makes its neighbour here depart by half of it),
            // never an outlier of this window
            self.e
                .push(departure_after(&self.buf, self.prev, &self.filled, n, last));
            let mut found = local_maxima(&self.e, THRESHOLD_SIGMA * s, across);
            self.e.pop();
            found.retain(|&k| k < n);
            if found.is_empty() {
                break;
            }
            if pass == 0 && heavy_tailed(&self.e, s, found.len(), n) {
                // heavy-tailed noise, not glitches: kept
                self.report.heavy_windows += 1;
                self.count(&found, false);
                break;
            }
            self.count(&found, true);
            for &k in &found {
                self.replace(k);
            }
        }
        statistic(&self.buf, self.prev, &self.filled, n, last, &mut self.e);
        for &e in &self.e {
            if e.is_finite() {
                self.report.sum2 += e * e;
                self.report.sum4 += e * e * e * e;
                self.report.n += 1;
            }
        }
    }

    fn count(&mut self, found: &[usize], excluded: bool) {
        self.report.count += found.len() as u64;
        for &k in found {
            self.report.max_abs = self.report.max_abs.max(self.e[k].abs());
        }
        if excluded {
            self.report.excluded += found.len() as u64;
        }
        for &k in found {
            if self.report.at.len() < MAX_LISTED {
                self.report.at.push(self.start + k as u64);
            }
        }
    }

    /// Replace outlier `k` and mark it filled.
    fn replace(&mut self, k: usize) {
        match &mut self.buf {
            Buf::Counts(v) => {
                let end = (k + 2).min(v.len());
                let total: i64 = v[k..end].iter().sum();
                let n = (end - k) as u32;
                for (slot, share) in v[k..end]
                    .iter_mut()
                    .zip(crate::dsp::gaps::spread_increment(total, n))
                {
                    *slot = share;
                }
                insert_span(&mut self.filled, k..end);
            }
            Buf::Rates(v) => {
                insert_span(&mut self.filled, k..k + 1);
                // a glitch beside one replaced before: the run of them is
                // interpolated between the measured samples either side, so
                // no replacement keeps a neighbour's glitch
                let run = self
                    .filled
                    .iter()
                    .find(|r| r.contains(&k))
                    .cloned()
                    .filter(|r| r.len() <= MAX_RUN)
                    .unwrap_or(k..k + 1);
                let left = if run.start > 0 {
                    Some(v[run.start - 1])
                } else {
                    self.prev
                };
                let right = v.get(run.end).copied();
                let len = (run.len() + 1) as f64;
                for j in run.clone() {
                    v[j] = match (left, right) {
                        (Some(a), Some(b)) => {
                            let w = (j + 1 - run.start) as f64 / len;
                            (1.0 - w) * a + w * b
                        }
                        (Some(a), None) => a,
                        (None, Some(b)) => b,
                        (None, None) => v[j],
                    };
                }
            }
        }
    }

    /// Emit the first `n` samples and drop them from the buffer.
    fn emit(&mut self, n: usize, out: &mut Emitted) {
        let base = match &mut self.buf {
            Buf::Counts(v) => {
                let base = out.counts.len();
                out.counts.extend(v.drain(..n));
                base
            }
            Buf::Rates(v) => {
                let base = out.rates.len();
                self.prev = Some(v[n - 1]);
                out.rates.extend(v.drain(..n));
                base
            }
        };
        for r in &self.filled {
            if r.start >= n {
                break;
            }
            // a span running past the window was emitted whole with the last
            // window: its remainder continues it, not a span of its own
            let span = r.start + base..r.end + base;
            match out.filled.last_mut() {
                Some(last) if last.end >= span.start => last.end = last.end.max(span.end),
                _ => out.filled.push(span),
            }
        }
        self.filled.retain_mut(|r| {
            r.start = r.start.saturating_sub(n);
            r.end = r.end.saturating_sub(n);
            r.start < r.end
        });
        self.start += n as u64;
    }
}

/// Append `spans` (relative to a push) at offset `base`, merged and sorted.
fn add_spans(filled: &mut Vec<Range<usize>>, spans: &[Range<usize>], base: usize) {
    for r in spans {
        insert_span(filled, r.start + base..r.end + base);
    }
}

/// Insert a span into a sorted list of disjoint spans, merging overlaps.
fn insert_span(filled: &mut Vec<Range<usize>>, r: Range<usize>) {
    if r.is_empty() {
        return;
    }
    let i = filled.partition_point(|s| s.end < r.start);
    let mut merged = r;
    while i < filled.len() && filled[i].start <= merged.end {
        let s = filled.remove(i);
        merged = merged.start.min(s.start)..merged.end.max(s.end);
    }
    filled.insert(i, merged);
}

/// Whether sample `k` is inside one of the sorted `filled` spans.
fn is_filled(filled: &[Range<usize>], k: usize) -> bool {
    let i = filled.partition_point(|s| s.end <= k);
    filled.get(i).is_some_and(|s| s.start <= k)
}

/// `e_k` for the first `n` samples of `buf` (NaN where a neighbour is
/// missing or filled); `last`: no sample follows the buffer.
fn statistic(
    buf: &Buf,
    prev: Option<f64>,
    filled: &[Range<usize>],
    n: usize,
    last: bool,
    e: &mut Vec<f64>,
) {
    e.clear();
    let bad = |k: usize| is_filled(filled, k);
    match buf {
        Buf::Counts(v) => {
            for k in 0..n {
                let ok = k + 1 < v.len() && !(last && k + 1 >= n) && !bad(k) && !bad(k + 1);
                e.push(if ok {
                    0.5 * (v[k] - v[k + 1]) as f64
                } else {
                    f64::NAN
                });
            }
        }
        Buf::Rates(v) => {
            for k in 0..n {
                e.push(if bad(k) {
                    f64::NAN
                } else {
                    rate_departure(v, prev, k, n, last, &bad)
                });
            }
        }
    }
}

/// The statistic of the first sample after the window's `n` (NaN at the end
/// of the stream, or when it cannot be formed yet).
fn departure_after(
    buf: &Buf,
    prev: Option<f64>,
    filled: &[Range<usize>],
    n: usize,
    last: bool,
) -> f64 {
    let bad = |k: usize| is_filled(filled, k);
    if last || bad(n) {
        return f64::NAN;
    }
    match buf {
        Buf::Counts(v) if n + 1 < v.len() && !bad(n + 1) => 0.5 * (v[n] - v[n + 1]) as f64,
        Buf::Counts(_) => f64::NAN,
        Buf::Rates(v) if n < v.len() => rate_departure(v, prev, n, n, false, &bad),
        Buf::Rates(_) => f64::NAN,
    }
}

/// A rate sample's departure from the line between its nearest measured
/// neighbours, stepping over at most [`MAX_RUN`] filled samples either side
/// (a glitch beside a replaced one is tested too); NaN without them.
fn rate_departure(
    v: &[f64],
    prev: Option<f64>,
    k: usize,
    n: usize,
    last: bool,
    bad: &dyn Fn(usize) -> bool,
) -> f64 {
    let mut l = k;
    let left = loop {
        if l == 0 {
            // the sample before the buffer, past at most MAX_RUN filled ones
            break if k <= MAX_RUN {
                prev.map(|a| (a, -1.0))
            } else {
                None
            };
        }
        l -= 1;
        if !bad(l) {
            break Some((v[l], l as f64));
        }
        if k - l > MAX_RUN {
            break None;
        }
    };
    let mut r = k + 1;
    let right = loop {
        // past the window only the next sample: what lies beyond is decided
        // with the next window
        if r >= v.len() || (last && r >= n) || (r > k + 1 && r >= n) {
            break None;
        }
        if !bad(r) {
            break Some((v[r], r as f64));
        }
        if r - k > MAX_RUN {
            break None;
        }
        r += 1;
    };
    match (left, right) {
        (Some((a, xa)), Some((b, xb))) => {
            let w = (k as f64 - xa) / (xb - xa);
            v[k] - ((1.0 - w) * a + w * b)
        }
        _ => f64::NAN,
    }
}

/// The scale of `e` from its 90th percentile of `|e|` (None without values).
fn robust_scale(e: &[f64], scratch: &mut Vec<f64>) -> Option<f64> {
    scratch.clear();
    scratch.extend(e.iter().filter(|v| v.is_finite()).map(|v| v.abs()));
    if scratch.len() < 16 {
        return None;
    }
    let k = ((scratch.len() - 1) as f64 * 0.9).round() as usize;
    let (_, q, _) = scratch.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    Some(*q / Q90_ABS_NORMAL)
}

/// Whether a window's outliers are the tail of heavy-tailed noise: too many of
/// them, or the band `(T/2, T] s` populated far beyond a Gaussian's share.
fn heavy_tailed(e: &[f64], s: f64, outliers: usize, n: usize) -> bool {
    if outliers as f64 > MAX_FRACTION * n.max(WINDOW / 4) as f64 {
        return true;
    }
    let lo = 0.5 * THRESHOLD_SIGMA * s;
    let hi = THRESHOLD_SIGMA * s;
    let valid = e.iter().filter(|v| v.is_finite()).count();
    let mid = e.iter().filter(|v| v.abs() > lo && v.abs() <= hi).count();
    mid as f64 > 3.0 * MID_SHARE * valid as f64 + 10.0
}

/// Indices where `|e| > limit` and `|e|` is the largest of its neighbours;
/// a neighbour is the nearest value across up to `across` missing ones (a
/// replaced glitch's run: a rate glitch beside it and the measured sample
/// on its other side are then compared, and only the glitch is taken).
fn local_maxima(e: &[f64], limit: f64, across: usize) -> Vec<usize> {
    let a = |k: usize| {
        e.get(k)
            .copied()
            .filter(|v| v.is_finite())
            .map_or(0.0, f64::abs)
    };
    let finite = |k: usize| e.get(k).is_some_and(|v| v.is_finite());
    let left = |k: usize| {
        (1..=across + 1)
            .map_while(|d| k.checked_sub(d))
            .find(|&j| finite(j))
            .map_or(0.0, a)
    };
    let right = |k: usize| {
        (1..=across + 1)
            .map(|d| k + d)
            .take_while(|&j| j < e.len())
            .find(|&j| finite(j))
            .map_or(0.0, a)
    };
    (0..e.len())
        .filter(|&k| {
            let v = a(k);
            v > limit && v > left(k) && v >= right(k)
        })
        .collect()
}

/// The grid a rate word's values lie on: the smallest positive difference
/// between the distinct values of the first few thousand, when every value is
/// a whole multiple of it; 0 otherwise.
pub fn grid_quantum(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v
        .iter()
        .take(4096)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    s.sort_by(f64::total_cmp);
    s.dedup();
    let q = s
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !q.is_finite() || s.len() < 3 {
        return 0.0;
    }
    let on_grid = s.iter().all(|x| ((x / q) - (x / q).round()).abs() < 1e-6);
    if on_grid { q } else { 0.0 }
}

/// The whole-record reference: the same windows decided at once.
pub fn find_batch(series: Series, counts: &[i64], rates: &[f64]) -> (Emitted, SpikeReport) {
    let mut f = SpikeFilter::new(series);
    let mut out = Emitted::default();
    match series {
        Series::Counts => f.push_counts(counts, &[], &mut out),
        Series::Rates => f.push_rates(rates, &[], &mut out),
    }
    f.finish(&mut out);
    (out, f.report.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    fn gauss(n: usize, seed: u64) -> Vec<f64> {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| r.sample::<f64, _>(StandardNormal)).collect()
    }

    #[test]
    fn rate_spikes_are_found_replaced_and_chunking_does_not_matter() {
        let mut x = gauss(50_000, 1);
        let at = [100usize, 4095, 4097, 20_000, 49_998];
        for (i, &k) in at.iter().enumerate() {
            x[k] += if i % 2 == 0 { 12.0 } else { -30.0 };
        }
        let (whole, rep) = find_batch(Series::Rates, &[], &x);
        assert_eq!(rep.at, at.iter().map(|&k| k as u64).collect::<Vec<_>>());
        assert_eq!((rep.count, rep.excluded, rep.heavy_windows), (5, 5, 0));
        assert_eq!(whole.rates.len(), x.len());
        let spans: Vec<_> = at.iter().map(|&k| k..k + 1).collect();
        assert_eq!(whole.filled, spans);
        for &k in &at {
            assert!(whole.rates[k].abs() < 4.0, "{k}: {}", whole.rates[k]);
        }
        // pushed in odd chunks: the same decisions and samples
        let mut f = SpikeFilter::new(Series::Rates);
        let mut out = Emitted::default();
        for c in x.chunks(777) {
            f.push_rates(c, &[], &mut out);
        }
        f.finish(&mut out);
        assert_eq!(out.rates, whole.rates);
        assert_eq!(f.report().at, rep.at);
        // filled spans come whole within their chunk; as a set they are the same
        let mut spans2 = out.filled.clone();
        spans2.dedup();
        assert_eq!(spans2, whole.filled);
    }

    #[test]
    fn a_gap_across_windows_is_one_span_however_the_pushes_cut_it() {
        let mut r = ChaCha8Rng::seed_from_u64(3);
        let c: Vec<i64> = (0..40_000)
            .map(|_| i64::from(r.random::<f64>() < 0.3))
            .collect();
        // a gap of 10 000 samples over three windows, pushed whole and in pieces
        let gap = 5_000..15_000;
        for block in [40_000usize, 7_000, 4_096, 333] {
            let mut f = SpikeFilter::new(Series::Counts);
            let (mut emitted, mut covered) = (Vec::new(), 0);
            // what the pipeline counts of each push: its spans clipped to it
            let mut take = |e: Emitted| {
                let n = e.counts.len();
                covered += e
                    .filled
                    .iter()
                    .map(|r| r.end.min(n) - r.start.min(n))
                    .sum::<usize>();
                emitted.extend(e.counts);
            };
            let mut spans = Vec::new();
            for at in (0..c.len()).step_by(block) {
                let end = (at + block).min(c.len());
                spans.clear();
                if gap.start < end && gap.end > at {
                    // as FilledSeries::filled_in gives it: whole, relative to the push
                    spans.push(gap.start.max(at) - at..gap.end - at);
                }
                let mut e = Emitted::default();
                f.push_counts(&c[at..end], &spans, &mut e);
                take(e);
            }
            let mut e = Emitted::default();
            f.finish(&mut e);
            take(e);
            assert_eq!(covered, gap.len(), "blocks of {block}");
            assert_eq!(emitted, c);
        }
    }

    #[test]
    fn a_counter_glitch_is_a_pair_whose_total_is_kept() {
        // a slow counter: increments 0 or 1
        let mut r = ChaCha8Rng::seed_from_u64(2);
        let mut c: Vec<i64> = (0..30_000)
            .map(|_| i64::from(r.random::<f64>() < 0.3))
            .collect();
        let total: i64 = c.iter().sum();
        for &(k, x) in &[(500usize, 6i64), (9_000, -9)] {
            c[k] += x;
            c[k + 1] -= x;
        }
        let (out, rep) = find_batch(Series::Counts, &c, &[]);
        assert_eq!(rep.at, vec![500, 9_000]);
        assert_eq!(out.counts.iter().sum::<i64>(), total);
        assert_eq!(out.filled, vec![500..502, 9_000..9_002]);
        assert!(out.counts[500..502].iter().all(|v| (0..=1).contains(v)));
    }

    /// A glitch on a window's first sample: its neighbour before it, the
    /// window's last, departs by half of it and must not be taken for it
    /// (it was, and the glitch was counted twice for a counter, three times
    /// for a rate word); on either side of the edge, one outlier where the
    /// glitch is, and a pulse counter keeps its total.
    #[test]
    fn a_glitch_at_a_window_edge_is_one_outlier_where_it_is() {
        for k in [
            WINDOW - 2,
            WINDOW - 1,
            WINDOW,
            WINDOW + 1,
            2 * WINDOW,
            3 * WINDOW - 1,
        ] {
            let mut r = ChaCha8Rng::seed_from_u64(k as u64);
            let mut c: Vec<i64> = (0..30_000)
                .map(|_| i64::from(r.random::<f64>() < 0.3))
                .collect();
            let total: i64 = c.iter().sum();
            c[k] += 6;
            c[k + 1] -= 6;
            let (out, rep) = find_batch(Series::Counts, &c, &[]);
            assert_eq!(rep.at, vec![k as u64], "counter glitch at {k}");
            assert_eq!(out.filled, vec![k..k + 2], "counter glitch at {k}");
            assert_eq!(out.counts.iter().sum::<i64>(), total);
            let mut x = gauss(30_000, k as u64);
            x[k] += 50.0;
            let (out, rep) = find_batch(Series::Rates, &[], &x);
            assert_eq!(rep.at, vec![k as u64], "rate glitch at {k}");
            assert_eq!(out.filled, vec![k..k + 1], "rate glitch at {k}");
        }
    }

    #[test]
    fn clean_gaussian_noise_gives_no_false_alarm() {
        // 2e6 samples: at T = 6 the expected false alarms are about 0.004
        let x = gauss(2_000_000, 3);
        let (_, rep) = find_batch(Series::Rates, &[], &x);
        assert_eq!(rep.count, 0);
        assert!(rep.excess_kurtosis().unwrap().abs() < 0.05);
    }

    #[test]
    fn heavy_tailed_noise_is_kept_and_said() {
        // Student-t with 3 degrees of freedom: many samples beyond 6 s
        let mut r = ChaCha8Rng::seed_from_u64(4);
        let x: Vec<f64> = (0..40_000)
            .map(|_| {
                let z: f64 = r.sample(StandardNormal);
                let chi: f64 = (0..3)
                    .map(|_| r.sample::<f64, _>(StandardNormal).powi(2))
                    .sum();
                z / (chi / 3.0).sqrt()
            })
            .collect();
        let (out, rep) = find_batch(Series::Rates, &[], &x);
        assert!(rep.heavy_windows > 0 && rep.count > rep.excluded, "{rep:?}");
        assert!(rep.excess_kurtosis().unwrap() > 1.0);
        assert!(out.filled.len() as u64 == rep.excluded);
    }

    #[test]
    fn values_on_a_grid_have_a_quantum() {
        assert_eq!(grid_quantum(&[0.5, 1.0, -0.5, 2.5, 0.0]), 0.5);
        assert_eq!(grid_quantum(&[0.1, 0.27, 0.3]), 0.0);
    }

    /// Glitches side by side (two and three in a row): each is found, and
    /// the run is interpolated between the measured samples either side, so
    /// no replacement keeps a neighbour's glitch (replaced by the mean of its
    /// neighbours, the first of a pair kept half the second, which was then
    /// never tested). Not handled: a pair across a window's edge (one pair
    /// in 4096), whose first glitch is replaced before the second is seen.
    #[test]
    fn adjacent_rate_glitches_are_all_found_and_none_is_kept_in_a_replacement() {
        let clean = gauss(30_000, 7);
        let mut x = clean.clone();
        let runs: [&[usize]; 3] = [&[1000, 1001], &[5000, 5001], &[9000, 9001, 9002]];
        for (i, run) in runs.iter().enumerate() {
            for (j, &k) in run.iter().enumerate() {
                x[k] += if (i + j) % 2 == 0 { 5000.0 } else { -3000.0 };
            }
        }
        let (out, rep) = find_batch(Series::Rates, &[], &x);
        let all: Vec<usize> = runs.iter().flat_map(|r| r.iter().copied()).collect();
        assert_eq!(rep.excluded as usize, all.len(), "{rep:?}");
        for run in runs {
            let span = run[0]..run[run.len() - 1] + 1;
            assert!(out.filled.contains(&span), "{span:?} in {:?}", out.filled);
        }
        for &k in &all {
            assert!(
                (out.rates[k] - clean[k]).abs() < 5.0,
                "{k}: {} vs {}",
                out.rates[k],
                clean[k]
            );
        }
        // the samples around the runs are the measured ones
        for (k, (&a, &b)) in out.rates.iter().zip(&clean).enumerate() {
            if !all.contains(&k) {
                assert_eq!(a, b, "{k}");
            }
        }
    }
}
