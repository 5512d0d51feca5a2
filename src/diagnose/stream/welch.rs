//! The Welch periodogram ([`Welch::psd`]) of a stream: segments are taken as
//! they complete, in the whole-record pairs. The offset removed is the first
//! segment's mean instead of the record's: only bins 0 and 1 depend on it,
//! and the diagnosis reads bins from 2 up.

use crate::diagnose::stats::{Welch, WelchWork};

/// A streaming [`Welch`] estimate for a record of known length.
pub struct WelchStream {
    welch: Welch,
    fs_hz: f64,
    k_seg: usize,
    /// Next segment to take (even: segments go in pairs).
    next: usize,
    /// Samples from `start` on, not yet fully used.
    buf: Vec<f64>,
    start: usize,
    offset: Option<f64>,
    work: WelchWork,
    acc: Vec<f64>,
}

impl WelchStream {
    /// The estimate of `welch` over a record of `n` samples at `fs_hz`.
    pub fn new(welch: &Welch, n: usize, fs_hz: f64) -> WelchStream {
        WelchStream {
            welch: welch.clone(),
            fs_hz,
            k_seg: welch.segments(n),
            next: 0,
            buf: Vec::new(),
            start: 0,
            offset: None,
            work: welch.work(),
            acc: vec![0.0; welch.seg() / 2 + 1],
        }
    }

    /// Add samples.
    pub fn push(&mut self, x: &[f64]) {
        if self.next >= self.k_seg {
            return;
        }
        self.buf.extend_from_slice(x);
        let (seg, half) = (self.welch.seg(), self.welch.seg() / 2);
        while self.next < self.k_seg {
            let s = self.next;
            let pair = s + 1 < self.k_seg;
            let end = if pair {
                (s + 1) * half + seg
            } else {
                s * half + seg
            };
            if self.start + self.buf.len() < end {
                break;
            }
            let a0 = s * half - self.start;
            let a = &self.buf[a0..a0 + seg];
            let offset = *self
                .offset
                .get_or_insert_with(|| a.iter().sum::<f64>() / seg as f64);
            let b = pair.then(|| &self.buf[a0 + half..a0 + half + seg]);
            self.welch
                .accumulate(a, b, offset, &mut self.work, &mut self.acc);
            self.next += 2;
            let used = (self.next * half).min(self.start + self.buf.len()) - self.start;
            self.buf.drain(..used);
            self.start += used;
        }
    }

    /// The one-sided PSD at bins `0..=seg/2`.
    pub fn finish(mut self) -> Vec<f64> {
        if self.k_seg > 0 {
            self.welch.scale(&mut self.acc, self.k_seg, self.fs_hz);
        }
        self.acc
    }
}
