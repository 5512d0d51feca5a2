//! Streaming min/max decimation of a long series for plotting: at most
//! `2 * buckets` buckets of `span` consecutive samples (a power of two), each
//! keeping its minimum, maximum and mean. When the series outgrows them,
//! neighbouring buckets merge pairwise and the span doubles, so memory is
//! bounded whatever the record length and the length need not be known in
//! advance. Drawn as a min-max band, every excursion of the series stays
//! visible at any zoom the bucket count allows (a plain "every k-th sample"
//! thinning would hide spikes).
//!
//! Reference: the batch form is "cut the series into runs of `span` samples,
//! take min, max and mean of each"; `tests` hold the streaming form to it.

/// One bucket: `count` samples starting at sample `first`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bucket {
    /// Index of the bucket's first sample.
    pub first: u64,
    /// Samples in the bucket (the non-finite ones are not counted).
    pub count: u64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
}

/// The streaming decimator.
#[derive(Debug, Clone)]
pub struct MinMax {
    span: u64,
    max_buckets: usize,
    n: u64,
    // (first, count, min, max, sum)
    buckets: Vec<(u64, u64, f64, f64, f64)>,
}

impl MinMax {
    /// At most `2 * buckets` buckets (at least 1).
    pub fn new(buckets: usize) -> MinMax {
        MinMax {
            span: 1,
            max_buckets: 2 * buckets.max(1),
            n: 0,
            buckets: Vec::new(),
        }
    }

    /// Samples pushed (finite or not).
    pub fn len(&self) -> u64 {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Samples per bucket.
    pub fn span(&self) -> u64 {
        self.span
    }

    /// Append one sample; a non-finite one takes its place in time but no value.
    pub fn push(&mut self, v: f64) {
        let mut b = (self.n / self.span) as usize;
        if b >= self.max_buckets {
            self.merge();
            b = (self.n / self.span) as usize;
        }
        while self.buckets.len() <= b {
            let first = self.buckets.len() as u64 * self.span;
            self.buckets
                .push((first, 0, f64::INFINITY, f64::NEG_INFINITY, 0.0));
        }
        if v.is_finite() {
            let x = &mut self.buckets[b];
            x.1 += 1;
            x.2 = x.2.min(v);
            x.3 = x.3.max(v);
            x.4 += v;
        }
        self.n += 1;
    }

    pub fn extend(&mut self, v: &[f64]) {
        for &x in v {
            self.push(x);
        }
    }

    fn merge(&mut self) {
        self.span *= 2;
        let merged = self
            .buckets
            .chunks(2)
            .map(|c| {
                c.iter().skip(1).fold(c[0], |a, x| {
                    (a.0, a.1 + x.1, a.2.min(x.2), a.3.max(x.3), a.4 + x.4)
                })
            })
            .collect();
        self.buckets = merged;
    }

    /// The buckets holding at least one finite sample, in time order.
    pub fn buckets(&self) -> Vec<Bucket> {
        self.buckets
            .iter()
            .filter(|b| b.1 > 0)
            .map(|b| Bucket {
                first: b.0,
                count: b.1,
                min: b.2,
                max: b.3,
                mean: b.4 / b.1 as f64,
            })
            .collect()
    }

    /// Smallest and largest finite value, if any.
    pub fn range(&self) -> Option<(f64, f64)> {
        self.buckets
            .iter()
            .filter(|b| b.1 > 0)
            .fold(None, |r, b| match r {
                None => Some((b.2, b.3)),
                Some((lo, hi)) => Some((f64::min(lo, b.2), f64::max(hi, b.3))),
            })
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.span = 1;
        self.n = 0;
        self.buckets.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batch reference: runs of `span` samples.
    fn batch(x: &[f64], span: usize) -> Vec<Bucket> {
        x.chunks(span)
            .enumerate()
            .map(|(i, c)| Bucket {
                first: (i * span) as u64,
                count: c.len() as u64,
                min: c.iter().cloned().fold(f64::INFINITY, f64::min),
                max: c.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
                mean: c.iter().sum::<f64>() / c.len() as f64,
            })
            .collect()
    }

    #[test]
    fn streaming_buckets_equal_the_batch_runs() {
        let mut s = 0x2545_F491_4F6C_DD1D_u64;
        let x: Vec<f64> = (0..100_003)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64
            })
            .collect();
        for buckets in [1, 7, 500] {
            let mut d = MinMax::new(buckets);
            d.extend(&x);
            assert!(d.buckets().len() <= 2 * buckets);
            let want = batch(&x, d.span() as usize);
            let got = d.buckets();
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(
                    (g.first, g.count, g.min, g.max),
                    (w.first, w.count, w.min, w.max)
                );
                // the mean: sums in another order, 1e-12 relative
                assert!((g.mean - w.mean).abs() <= 1e-12 * w.mean.abs());
            }
        }
    }

    #[test]
    fn non_finite_samples_keep_their_place_but_no_value() {
        let mut d = MinMax::new(2);
        d.extend(&[1.0, f64::NAN, 3.0, f64::INFINITY, 5.0]);
        assert_eq!(d.len(), 5);
        assert_eq!(d.range(), Some((1.0, 5.0)));
        let b = d.buckets();
        // 5 samples into at most 4 buckets: span 2
        assert_eq!(d.span(), 2);
        assert_eq!(b.iter().map(|b| b.count).collect::<Vec<_>>(), vec![1, 1, 1]);
        assert_eq!(b[1].first, 2);
        let mut e = MinMax::new(4);
        e.push(f64::NAN);
        assert!(e.buckets().is_empty() && e.range().is_none());
    }
}
