//! Gap filling: turn the decoder's "whole increment after the gap" samples into
//! a uniformly sampled series for the Allan and wavelet stages.
//!
//! The fill spreads an increment `I` over `n = lost_before + 1` sample periods
//! as integers `share_j = floor(I*(j+1)/n) - floor(I*j/n)`, `j = 0..n`. The
//! shares sum to exactly `I` (no angle lost or invented), each share is
//! `floor(I/n)` or `floor(I/n) + 1`, and the running sum after `j+1` shares is
//! `floor(I*(j+1)/n)`: the cumulative counter linearly interpolated across the
//! gap and floored, so it stays within one pulse of the straight line. The
//! last share goes to the real frame (its `seq`), the first `n - 1` are
//! synthetic samples numbered `after_seq + 1 ..`.

use super::Sample;

/// The `n` integer shares of `total` described in the module docs (empty when
/// `n == 0`).
pub fn spread_increment(total: i64, n: u32) -> impl Iterator<Item = i64> {
    let t = i128::from(total);
    let m = i128::from(n.max(1));
    (0..n).map(move |j| {
        let j = i128::from(j);
        let hi = (t * (j + 1)).div_euclid(m);
        let lo = (t * j).div_euclid(m);
        // |hi - lo| <= |total|/n + 1 fits an i64.
        (hi - lo) as i64
    })
}

/// One sample of a uniformly sampled series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UniformSample {
    /// Sequence number (synthetic ones continue the numbering across the gap).
    pub seq: u16,
    /// Pulses in this sample period.
    pub increment: i64,
    /// `true` for a sample made up by the fill.
    pub synthetic: bool,
}

/// The `sample.lost_before + 1` uniform samples that replace `sample`.
pub fn fill_gap(sample: &Sample) -> impl Iterator<Item = UniformSample> + use<> {
    let n = u32::from(sample.lost_before) + 1;
    let first_seq = sample.seq.wrapping_sub(sample.lost_before);
    spread_increment(sample.increment, n)
        .zip(0u16..)
        .map(move |(increment, j)| UniformSample {
            seq: first_seq.wrapping_add(j),
            increment,
            synthetic: u32::from(j) + 1 < n,
        })
}

/// Iterator adapter: samples in, gap-filled uniform samples out.
#[derive(Debug, Clone)]
pub struct GapFiller<I> {
    inner: I,
    pending: std::collections::VecDeque<UniformSample>,
    synthetic: u64,
}

impl<I: Iterator<Item = Sample>> GapFiller<I> {
    /// Wrap an iterator of samples.
    pub fn new(inner: I) -> Self {
        GapFiller {
            inner,
            pending: std::collections::VecDeque::new(),
            synthetic: 0,
        }
    }

    /// Synthetic samples produced so far.
    pub fn synthetic_count(&self) -> u64 {
        self.synthetic
    }
}

impl<I: Iterator<Item = Sample>> Iterator for GapFiller<I> {
    type Item = UniformSample;

    fn next(&mut self) -> Option<UniformSample> {
        if self.pending.is_empty() {
            let s = self.inner.next()?;
            self.synthetic += u64::from(s.lost_before);
            self.pending.extend(fill_gap(&s));
        }
        self.pending.pop_front()
    }
}
