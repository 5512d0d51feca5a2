//! [`refill`](crate::diagnose::stats::refill) on a stream: a simulated run's
//! samples in the recording's made-up spans are made up as they arrive. A
//! span is held back until its right neighbour has arrived; everything
//! before the first span still open is passed on at once.

use std::ops::Range;

use crate::diagnose::stats::fill_span;

/// The made-up spans of a record of known length, applied to its stream.
#[derive(Debug, Clone)]
pub struct Refill {
    spans: Vec<Range<usize>>,
    next: usize,
    n: usize,
    rate_words: bool,
    /// Samples from `start` on, not yet passed on.
    pending: Vec<i64>,
    start: usize,
    /// The last sample passed on.
    prev: Option<i64>,
}

impl Refill {
    /// The spans `filled` of a record of `n` samples.
    pub fn new(filled: &[Range<usize>], n: usize, rate_words: bool) -> Refill {
        let mut spans: Vec<Range<usize>> = filled
            .iter()
            .map(|r| r.start.min(n)..r.end.min(n))
            .filter(|r| r.start < r.end)
            .collect();
        spans.sort_by_key(|r| r.start);
        Refill {
            spans,
            next: 0,
            n,
            rate_words,
            pending: Vec::new(),
            start: 0,
            prev: None,
        }
    }

    /// Take `chunk` (the next samples) and append to `out` the samples that
    /// are final.
    pub fn push(&mut self, chunk: &[i64], out: &mut Vec<i64>) {
        if self.spans.is_empty() {
            out.extend_from_slice(chunk);
            self.start += chunk.len();
            return;
        }
        self.pending.extend_from_slice(chunk);
        let avail = self.start + self.pending.len();
        let mut emit = avail;
        while let Some(r) = self.spans.get(self.next) {
            let (a, b) = (r.start, r.end);
            if a >= avail {
                break;
            }
            let need = if b < self.n { b + 1 } else { self.n };
            if avail < need {
                emit = a;
                break;
            }
            let left = match a {
                0 => None,
                _ if a > self.start => Some(self.pending[a - 1 - self.start]),
                _ => self.prev,
            };
            let right = (b < self.n).then(|| self.pending[b - self.start]);
            let (pa, pb) = (a - self.start, b - self.start);
            fill_span(&mut self.pending[pa..pb], left, right, self.rate_words);
            self.next += 1;
        }
        let k = emit - self.start;
        out.extend_from_slice(&self.pending[..k]);
        if k > 0 {
            self.prev = Some(self.pending[k - 1]);
        }
        self.pending.drain(..k);
        self.start = emit;
    }
}
