//! Block means of the rate and of the temperature: the record at the
//! resolution of its slow effects (warm-up, bias steps, temperature), in
//! bounded memory whatever its length.
//!
//! Blocks are `2^shift` samples long and fixed by absolute sample index; when
//! there would be more than [`MAX_BLOCKS`] the neighbours merge pairwise and
//! the blocks double in length. Filled samples (gaps, excluded glitches) are
//! left out of the rate sums. Chunking never changes a block's sums except
//! for the order of floating-point additions.

use std::ops::Range;

/// Most blocks kept.
pub const MAX_BLOCKS: usize = 2048;

/// Sum and count of one block.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Acc {
    sum: f64,
    n: u64,
}

/// The accumulator.
#[derive(Debug, Clone)]
pub struct BlockMeans {
    tau0_s: f64,
    shift: u32,
    rate: Vec<Acc>,
    temp: Vec<Acc>,
    samples: u64,
}

/// Block means, ready for the low-frequency analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockSeries {
    /// Block length, s.
    pub block_s: f64,
    /// Start of each block, s (block `b` covers `[b, b+1) * block_s`).
    pub t0_s: Vec<f64>,
    /// Mean rate of the block's measured samples, deg/h (NaN: none).
    pub rate_dph: Vec<f64>,
    /// Measured samples in each block.
    pub n: Vec<u64>,
    /// Mean temperature, deg C, when every block has one.
    pub temp_c: Option<Vec<f64>>,
    /// Samples in the record.
    pub samples: u64,
    /// Sample period, s.
    pub tau0_s: f64,
}

impl BlockMeans {
    pub fn new(tau0_s: f64) -> BlockMeans {
        BlockMeans {
            tau0_s,
            shift: 0,
            rate: Vec::new(),
            temp: Vec::new(),
            samples: 0,
        }
    }

    /// Add rates (deg/h) of samples `first..`; `filled` (relative, sorted)
    /// are left out.
    pub fn push_rates(&mut self, first: u64, rates: &[f64], filled: &[Range<usize>]) {
        let end = first + rates.len() as u64;
        self.grow(&end);
        let mut k = 0usize;
        let mut spans = filled.iter().peekable();
        while k < rates.len() {
            // skip filled samples
            while let Some(r) = spans.peek() {
                if r.end <= k {
                    spans.next();
                } else {
                    break;
                }
            }
            if let Some(r) = spans.peek()
                && r.start <= k
            {
                k = r.end.min(rates.len());
                continue;
            }
            let next_fill = spans
                .peek()
                .map_or(rates.len(), |r| r.start.min(rates.len()));
            let abs = first + k as u64;
            let b = (abs >> self.shift) as usize;
            let block_end = (((b as u64) + 1) << self.shift) - first;
            let stop = next_fill.min(block_end.min(rates.len() as u64) as usize);
            let s: f64 = rates[k..stop].iter().sum();
            let a = &mut self.rate[b];
            a.sum += s;
            a.n += (stop - k) as u64;
            k = stop;
        }
        self.samples = self.samples.max(end);
    }

    /// Add temperatures (deg C) of samples `first..`.
    pub fn push_temps(&mut self, first: u64, temps: &[f64]) {
        let end = first + temps.len() as u64;
        self.grow(&end);
        for (i, &t) in temps.iter().enumerate() {
            if t.is_finite() {
                let b = ((first + i as u64) >> self.shift) as usize;
                self.temp[b].sum += t;
                self.temp[b].n += 1;
            }
        }
    }

    /// Make room for samples up to `end` (exclusive), merging when needed.
    fn grow(&mut self, end: &u64) {
        let need = |shift: u32| ((end.saturating_sub(1)) >> shift) as usize + 1;
        while need(self.shift) > MAX_BLOCKS {
            self.shift += 1;
            for v in [&mut self.rate, &mut self.temp] {
                let merged: Vec<Acc> = v
                    .chunks(2)
                    .map(|c| {
                        c.iter().fold(Acc::default(), |a, x| Acc {
                            sum: a.sum + x.sum,
                            n: a.n + x.n,
                        })
                    })
                    .collect();
                *v = merged;
            }
        }
        let n = need(self.shift);
        if self.rate.len() < n {
            self.rate.resize(n, Acc::default());
        }
        if self.temp.len() < n {
            self.temp.resize(n, Acc::default());
        }
    }

    /// The block means so far (the last block partial).
    pub fn series(&self) -> BlockSeries {
        let len = 1u64 << self.shift;
        let n_blocks = if self.samples == 0 {
            0
        } else {
            ((self.samples - 1) >> self.shift) as usize + 1
        };
        let block_s = len as f64 * self.tau0_s;
        let mean = |a: &Acc| {
            if a.n > 0 {
                a.sum / a.n as f64
            } else {
                f64::NAN
            }
        };
        let temp_c = (n_blocks > 0 && self.temp[..n_blocks].iter().all(|a| a.n > 0))
            .then(|| self.temp[..n_blocks].iter().map(mean).collect());
        BlockSeries {
            block_s,
            t0_s: (0..n_blocks).map(|b| b as f64 * block_s).collect(),
            rate_dph: self.rate[..n_blocks].iter().map(mean).collect(),
            n: self.rate[..n_blocks].iter().map(|a| a.n).collect(),
            temp_c,
            samples: self.samples,
            tau0_s: self.tau0_s,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_means_ignore_chunking_and_leave_filled_samples_out() {
        let x: Vec<f64> = (0..100_000).map(|i| ((i * 7919) % 1000) as f64).collect();
        let filled = vec![10..20, 5_000..5_001];
        let mut one = BlockMeans::new(0.001);
        one.push_rates(0, &x, &filled);
        let mut many = BlockMeans::new(0.001);
        let mut first = 0usize;
        for c in x.chunks(3_331) {
            let spans: Vec<Range<usize>> = filled
                .iter()
                .filter(|r| r.end > first && r.start < first + c.len())
                .map(|r| r.start.saturating_sub(first)..(r.end - first).min(c.len()))
                .collect();
            many.push_rates(first as u64, c, &spans);
            first += c.len();
        }
        let (a, b) = (one.series(), many.series());
        assert_eq!(a.n, b.n);
        for (p, q) in a.rate_dph.iter().zip(&b.rate_dph) {
            assert!((p - q).abs() <= 1e-9 * p.abs().max(1.0));
        }
        // 100 000 samples in at most 2048 blocks: 64-sample blocks
        assert_eq!(a.block_s, 0.064);
        assert_eq!(a.n[0], 64 - 10);
        let want: f64 = x[..64]
            .iter()
            .enumerate()
            .filter(|(i, _)| !(10..20).contains(i))
            .map(|(_, v)| v)
            .sum::<f64>()
            / 54.0;
        assert!((a.rate_dph[0] - want).abs() < 1e-9);
        assert!(a.temp_c.is_none());
    }
}
