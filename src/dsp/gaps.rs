//! Filled (not measured) samples through a wavelet analysis cascade.
//!
//! Role in the whole: the gap fill (`input::frame::fill`, with [`spread_increment`]) keeps the series
//! uniform and the angle continuous, but the samples it makes up are not
//! measurements. Statistics built from detail coefficients (the pipeline's
//! level variances, the QN energy) must leave out every coefficient whose
//! support touches a filled sample, as Stable32 and AllanTools' `gradev` leave
//! out the terms that touch a gap. [`MaskCascade`] tells which, on the levels
//! a short gap can disturb ([`SHORT_GAP`], [`GAP_SCALE`]).
//!
//! Level `j` computes `a_j[i], d_j[i]` from `a_{j-1}[2i+1-k]`, `k = 0..L`
//! (see [`super::bank`]), so coefficient `i` of level `j` touches a filled
//! value of level `j-1` in the span `[a, b)` exactly when
//! `floor(a/2) <= i < floor((b+L-1)/2)`. Applied level by level (`a_0` = the
//! input), this gives for every level the spans of coefficient indices whose
//! support in the input touches a filled sample - exactly, and in O(levels)
//! per filled span, whatever the block sizes. Spans are kept only until the
//! coefficients they cover have been produced, so memory is bounded by the
//! number of filled spans within one push (plus a few per level).

use std::collections::VecDeque;
use std::ops::Range;

/// A short filled span (`g <= SHORT_GAP` samples: isolated lost frames, a
/// noisy link) masks the coefficients of the levels `j` with
/// `2^j <= GAP_SCALE * g` only; a longer one masks every level. The fill keeps
/// the angle exactly at the measured samples and interpolates between them. A
/// level much coarser than a short gap has a support of about `15 x 2^j`
/// samples and a band far below `1/g`: the interpolation removes only the
/// within-gap wander, about half a sample's share of the variance per lost
/// sample (0.5 % of the variance at one loss in a hundred), while masking
/// every level would cost the deep levels all their coefficients (a loss
/// every 100 samples touches every coefficient beyond level 3). Long bursts
/// are few, and inside a support they take a share that does not vanish:
/// they are masked everywhere.
pub const SHORT_GAP: u64 = 16;

/// Levels coarser than `GAP_SCALE` times a short gap keep their coefficients.
pub const GAP_SCALE: u64 = 8;

/// Per level, the spans of coefficient indices that touch a filled input sample.
#[derive(Debug, Clone, Default)]
pub struct MaskCascade {
    /// Filter length L.
    len: u64,
    /// `levels[j]`: sorted disjoint spans of level `j+1` coefficient indices not
    /// yet consumed by [`Self::bad_spans`].
    levels: Vec<VecDeque<Range<u64>>>,
}

impl MaskCascade {
    /// A cascade of `levels` levels of a filter of length `filter_len`.
    pub fn new(filter_len: usize, levels: usize) -> Self {
        MaskCascade {
            len: filter_len as u64,
            levels: vec![VecDeque::new(); levels],
        }
    }

    /// Input samples `span` (absolute indices) are filled. Spans must come in
    /// increasing order of their start.
    pub fn add_input(&mut self, span: Range<u64>) {
        if span.is_empty() {
            return;
        }
        let g = span.end - span.start;
        let mut r = span;
        for (j, q) in self.levels.iter_mut().enumerate() {
            if g <= SHORT_GAP && (1u64 << (j + 1).min(63)) > GAP_SCALE * g {
                // levels this much coarser than the filled span see it as a
                // smooth interpolation inside a support of ~15 x 2^j samples:
                // their coefficients stay (the fill keeps the angle exactly)
                break;
            }
            r = r.start / 2..(r.end + self.len - 1) / 2;
            match q.back_mut() {
                Some(b) if r.start <= b.end => b.end = b.end.max(r.end),
                _ => q.push_back(r.clone()),
            }
        }
    }

    /// True while no filled span is pending at any level (the all-measured case).
    pub fn is_clear(&self) -> bool {
        self.levels.iter().all(VecDeque::is_empty)
    }

    /// The filled-touching coefficients of level `j+1` among the indices
    /// `[from, to)`, as spans relative to `from` (sorted, disjoint), appended
    /// to `out`. Afterwards the coefficients below `to` are forgotten: call it
    /// with consecutive ranges.
    pub fn bad_spans(&mut self, j: usize, from: u64, to: u64, out: &mut Vec<Range<usize>>) {
        let q = &mut self.levels[j];
        for r in q.iter() {
            if r.start >= to {
                break;
            }
            let (u, v) = (r.start.max(from), r.end.min(to));
            if u < v {
                out.push((u - from) as usize..(v - from) as usize);
            }
        }
        while q.front().is_some_and(|r| r.end <= to) {
            q.pop_front();
        }
    }

    /// Spans held (for memory accounting).
    pub fn pending(&self) -> usize {
        self.levels.iter().map(VecDeque::len).sum()
    }
}

/// The segments of `0..n` outside the sorted, disjoint `bad` spans.
pub fn good_segments(n: usize, bad: &[Range<usize>]) -> impl Iterator<Item = Range<usize>> + '_ {
    let mut at = 0usize;
    let mut i = 0usize;
    std::iter::from_fn(move || {
        while at < n {
            let next_bad = bad.get(i).map_or(n..n, |b| b.start.min(n)..b.end.min(n));
            if at < next_bad.start {
                let seg = at..next_bad.start;
                at = next_bad.start;
                return Some(seg);
            }
            at = at.max(next_bad.end);
            i += 1;
            if next_bad.start >= n {
                at = n;
            }
        }
        None
    })
}

/// Sorted, disjoint spans of the `true` entries of `filled`.
pub fn spans_of(filled: &[bool]) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < filled.len() {
        if filled[i] {
            let s = i;
            while i < filled.len() && filled[i] {
                i += 1;
            }
            out.push(s..i);
        } else {
            i += 1;
        }
    }
    out
}

/// The `n` integer shares of an increment `total` spread over `n` sample
/// periods (empty when `n == 0`): `share_j = floor(total (j+1)/n) -
/// floor(total j/n)`. They sum to exactly `total` (no angle lost or invented),
/// each is `floor(total/n)` or one more, and the running sum is the cumulative
/// counter linearly interpolated and floored, within one pulse of the line.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn good_segments_complement_the_bad_ones() {
        let g: Vec<_> = good_segments(10, &[0..2, 4..5, 5..7, 9..12]).collect();
        assert_eq!(g, vec![2..4, 7..9]);
        let g: Vec<_> = good_segments(5, &[]).collect();
        assert_eq!(g, vec![0..5]);
        let g: Vec<_> = good_segments(5, &[7..9]).collect();
        assert_eq!(g, vec![0..5]);
        assert_eq!(spans_of(&[true, true, false, true]), vec![0..2, 3..4]);
    }

    #[test]
    fn cascade_matches_the_support_definition() {
        // brute force: level-j coefficient i's input support, recursively
        let l = 16usize;
        let n = 4096usize;
        let mut filled = vec![false; n];
        for i in (300..340).chain(1000..1001).chain(2500..2900) {
            filled[i] = true;
        }
        let mut c = MaskCascade::new(l, 5);
        for s in spans_of(&filled) {
            c.add_input(s.start as u64..s.end as u64);
        }
        // each span's support mask level by level; a span of g samples counts
        // at level j+1 only while 2^(j+1) <= GAP_SCALE g
        let spans = spans_of(&filled);
        let mut prev: Vec<Vec<bool>> = spans
            .iter()
            .map(|s| (0..n).map(|i| s.contains(&i)).collect())
            .collect();
        for j in 0..5 {
            let m = n >> (j + 1);
            let step = |p: &Vec<bool>| -> Vec<bool> {
                (0..m)
                    .map(|i| {
                        (0..l).any(|k| {
                            (2 * i + 1)
                                .checked_sub(k)
                                .is_some_and(|q| q < p.len() && p[q])
                        })
                    })
                    .collect()
            };
            let next: Vec<Vec<bool>> = prev.iter().map(step).collect();
            let cur: Vec<bool> = (0..m)
                .map(|i| {
                    spans.iter().zip(&next).any(|(s, v)| {
                        (s.len() as u64 > SHORT_GAP
                            || (1u64 << (j + 1)) <= GAP_SCALE * s.len() as u64)
                            && v[i]
                    })
                })
                .collect();
            let mut got = vec![false; m];
            let mut bad = Vec::new();
            let h = m / 2;
            c.bad_spans(j, 0, h as u64, &mut bad);
            for r in bad.drain(..) {
                got[r].iter_mut().for_each(|x| *x = true);
            }
            c.bad_spans(j, h as u64, m as u64, &mut bad);
            for r in bad {
                got[h + r.start..h + r.end]
                    .iter_mut()
                    .for_each(|x| *x = true);
            }
            assert_eq!(got, cur, "level {}", j + 1);
            prev = next;
        }
    }
}
