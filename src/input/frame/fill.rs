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
//!
//! [`FilledSeries`] is the one place the series is built (the daemon, the
//! offline commands, `diagnose`): counts plus the spans of synthetic samples,
//! which the pipeline's statistics leave out
//! ([`crate::pipeline::Pipeline::push_counts_filled`]) while the counts keep the
//! angle continuous and the recordings unchanged.

use std::ops::Range;

use super::Sample;
use crate::dsp::gaps::spread_increment;

/// A gap-filled uniform series: the counts and the spans (sorted, disjoint,
/// indices into `counts`) of the samples made up by the fill.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FilledSeries {
    pub counts: Vec<i64>,
    pub filled: Vec<Range<usize>>,
}

impl FilledSeries {
    pub fn with_capacity(n: usize) -> Self {
        FilledSeries {
            counts: Vec::with_capacity(n),
            filled: Vec::new(),
        }
    }

    pub fn clear(&mut self) {
        self.counts.clear();
        self.filled.clear();
    }

    pub fn len(&self) -> usize {
        self.counts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// Append a measured sample whose `increment` covers `lost` missing
    /// periods before it and its own: `lost + 1` shares (at most `u32::MAX`),
    /// the first `lost` marked filled. Returns the number of samples appended.
    pub fn push(&mut self, increment: i64, lost: u64) -> usize {
        if lost == 0 {
            self.counts.push(increment);
            return 1;
        }
        let n = u32::try_from(lost + 1).unwrap_or(u32::MAX);
        let start = self.counts.len();
        self.counts.extend(spread_increment(increment, n));
        let span = start..start + n as usize - 1;
        match self.filled.last_mut() {
            Some(last) if last.end == span.start => last.end = span.end,
            _ => self.filled.push(span),
        }
        n as usize
    }

    /// Append measured samples with no period lost before any of them (one
    /// copy, where [`FilledSeries::push`] per sample would test and grow each).
    pub fn push_run(&mut self, increments: &[i64]) {
        self.counts.extend_from_slice(increments);
    }

    /// Append a decoded frame sample (its `lost_before` periods filled).
    pub fn push_sample(&mut self, s: &Sample) -> usize {
        self.push(s.increment, u64::from(s.lost_before))
    }

    /// Whether sample `i` was made up by the fill.
    pub fn is_filled(&self, i: usize) -> bool {
        let k = self.filled.partition_point(|r| r.end <= i);
        self.filled.get(k).is_some_and(|r| r.start <= i)
    }

    /// The filled spans within `range`, relative to its start, appended to `out`;
    /// a span that runs past the range keeps its end (for the pipeline's mask).
    pub fn filled_in(&self, range: Range<usize>, out: &mut Vec<Range<usize>>) {
        let k = self.filled.partition_point(|r| r.end <= range.start);
        for r in &self.filled[k..] {
            if r.start >= range.end {
                break;
            }
            // the end is not clipped: a gap running past the range is given whole
            out.push(r.start.max(range.start) - range.start..r.end - range.start);
        }
    }

    /// Remove the first `n` samples.
    pub fn drain_front(&mut self, n: usize) {
        self.counts.drain(..n);
        self.filled.retain_mut(|r| {
            r.start = r.start.saturating_sub(n);
            r.end = r.end.saturating_sub(n);
            r.start < r.end
        });
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filled_series_is_the_fill_with_its_mask() {
        let mut f = FilledSeries::default();
        f.push(5, 0);
        f.push(7, 3);
        f.push(-2, 1);
        f.push(1, 0);
        assert_eq!(f.counts, vec![5, 1, 2, 2, 2, -1, -1, 1]);
        // a gap-free run is the same as its samples pushed one by one
        let mut r = FilledSeries::default();
        r.push_run(&[5]);
        r.push(7, 3);
        r.push(-2, 1);
        r.push_run(&[1]);
        assert_eq!(r, f);
        assert_eq!(f.counts.iter().sum::<i64>(), 5 + 7 - 2 + 1);
        // the lost periods are filled, the sample carrying the rest is not;
        // adjacent spans stay separate only when a measured sample lies between
        assert_eq!(f.filled, vec![1..4, 5..6]);
        assert!(f.is_filled(3) && !f.is_filled(4) && f.is_filled(5) && !f.is_filled(6));
        let mut out = Vec::new();
        f.filled_in(2..6, &mut out);
        assert_eq!(out, vec![0..2, 3..4]);
        f.drain_front(3);
        assert_eq!(f.filled, vec![0..1, 2..3]);
        assert_eq!(f.counts.len(), 5);
        // the same increments as fill_gap
        let s = Sample {
            seq: 10,
            counter: 0,
            lost_before: 3,
            increment: 7,
            temp_c: 20.0,
            status: 0,
            offset: 0,
        };
        let mut g = FilledSeries::default();
        g.push_sample(&s);
        let u: Vec<UniformSample> = fill_gap(&s).collect();
        assert_eq!(g.counts, u.iter().map(|u| u.increment).collect::<Vec<_>>());
        assert_eq!(
            (0..4).map(|i| g.is_filled(i)).collect::<Vec<_>>(),
            u.iter().map(|u| u.synthetic).collect::<Vec<_>>()
        );
    }
}
