//! The `/gyro/summary` channel: 0.1 s windows of the uniform (gap-filled)
//! sample series reduced to scalars, for Foxglove's Plot panel.
//!
//! Window `k` of a time segment starting at uniform index `s` holds the periods
//! `s + k N .. s + (k + 1) N` (`N` = [`summary_window_samples`], 100 at 1 kHz),
//! cut short where the next segment starts and at the end of the run; so a run
//! of `n` periods in one segment gives `ceil(n / N)` messages. The raw side of a
//! window is known when its samples are pushed into the pipeline, the clean side
//! [`crate::pipeline::Pipeline::latency`] samples later: a window is published
//! once its last clean value is out. Naive reference: the window sums written
//! out over whole arrays (the tests below), which every split of the input into
//! pushes must reproduce: the counts and times exactly, the rates to rounding.

use std::collections::VecDeque;
use std::ops::Range;

use crate::recording::messages::{SummaryUpdate, Timestamp, summary_window_samples};

/// Where a new window starting at uniform index `u` lies: the start of its
/// time segment, the start of the next segment (if one is known), and the time
/// of sample `u`, ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Place {
    pub segment_start: u64,
    pub next_segment: Option<u64>,
    pub t_ns: u64,
}

#[derive(Debug, Clone)]
struct Window {
    start: u64,
    /// One past the last period (shortened when a segment starts inside).
    end: u64,
    t_ns: u64,
    pulses: i128,
    raw_n: u64,
    lost: u64,
    clean_sum: f64,
    clean_n: u64,
    temp_c: Option<f64>,
}

/// Builds the `/gyro/summary` messages of a run.
#[derive(Debug, Clone)]
pub struct SummaryAcc {
    window: u64,
    /// deg/h of one pulse per sample period (pulse weight x rate).
    dph_per_pulse: f64,
    windows: VecDeque<Window>,
}

impl SummaryAcc {
    /// Windows for a series at `sample_rate_hz` with `pulse_arcsec` per pulse.
    pub fn new(sample_rate_hz: f64, pulse_arcsec: f64) -> Self {
        SummaryAcc {
            window: summary_window_samples(sample_rate_hz),
            dph_per_pulse: crate::units::counts_to_dph(1.0, pulse_arcsec, 1.0 / sample_rate_hz),
            windows: VecDeque::new(),
        }
    }

    /// Samples per full window.
    pub fn window_samples(&self) -> u64 {
        self.window
    }

    /// The uniform samples `u0 .. u0 + counts.len()` as pushed into the
    /// pipeline; `filled` are the gap-filled spans, relative to `u0` (one may
    /// run past the end); `temp_c` the device temperature now.
    pub fn push_raw(
        &mut self,
        u0: u64,
        counts: &[i64],
        filled: &[Range<usize>],
        temp_c: Option<f64>,
        place: &dyn Fn(u64) -> Place,
    ) {
        let mut i = 0usize;
        while i < counts.len() {
            let u = u0 + i as u64;
            let open = self
                .windows
                .back()
                .is_some_and(|w| w.start + w.raw_n == u && u < w.end);
            if !open {
                let p = place(u);
                let aligned =
                    p.segment_start + ((u - p.segment_start) / self.window + 1) * self.window;
                let end = p
                    .next_segment
                    .filter(|&n| n > u)
                    .map_or(aligned, |n| aligned.min(n));
                self.windows.push_back(Window {
                    start: u,
                    end,
                    t_ns: p.t_ns,
                    pulses: 0,
                    raw_n: 0,
                    lost: 0,
                    clean_sum: 0.0,
                    clean_n: 0,
                    temp_c: None,
                });
            }
            let w = self.windows.back_mut().expect("a window is open");
            // a segment that starts inside the window (known only now) ends it
            if let Some(n) = place(u).next_segment.filter(|&n| n > u && n < w.end) {
                w.end = n;
            }
            let take = ((w.end - u) as usize).min(counts.len() - i);
            w.pulses += exact_sum(&counts[i..i + take]);
            w.lost += overlap(filled, i..i + take);
            w.raw_n += take as u64;
            if temp_c.is_some() {
                w.temp_c = temp_c;
            }
            i += take;
        }
    }

    /// The clean values of the uniform samples `u0 ..`; completed windows go to `out`.
    pub fn push_clean(&mut self, u0: u64, clean_dph: &[f64], out: &mut Vec<SummaryUpdate>) {
        let mut i = 0usize;
        while i < clean_dph.len() {
            let u = u0 + i as u64;
            // the windows are in time order, and the clean side completes them
            // from the front: the first that ends after u, almost always the front
            let Some(w) = self
                .windows
                .iter_mut()
                .find(|w| u < w.end)
                .filter(|w| w.start <= u)
            else {
                // a clean value without its raw sample cannot happen; skip it
                i += 1;
                continue;
            };
            let take = ((w.end - u) as usize).min(clean_dph.len() - i);
            w.clean_sum += lane_sum(&clean_dph[i..i + take]);
            w.clean_n += take as u64;
            i += take;
            self.drain_complete(out);
        }
    }

    /// End of the run after `pushed` uniform samples, every clean value out:
    /// close the last window there and publish everything.
    pub fn finish(&mut self, pushed: u64, out: &mut Vec<SummaryUpdate>) {
        if let Some(w) = self.windows.back_mut()
            && w.end > pushed
        {
            w.end = pushed.max(w.start);
        }
        self.drain_complete(out);
    }

    fn drain_complete(&mut self, out: &mut Vec<SummaryUpdate>) {
        while let Some(w) = self.windows.front() {
            let n = w.end - w.start;
            if w.raw_n < n || w.clean_n < n {
                break;
            }
            let w = self.windows.pop_front().expect("front exists");
            if n == 0 {
                continue;
            }
            out.push(SummaryUpdate {
                timestamp: Timestamp::from_ns(w.t_ns),
                samples: n,
                lost_samples: w.lost,
                raw_rate_dph: w.pulses as f64 / n as f64 * self.dph_per_pulse,
                clean_rate_dph: w.clean_sum / n as f64,
                temp_c: w.temp_c,
            });
        }
    }
}

/// `sum c_i`, exactly: the high and low 32 bits summed apart (each sum fits
/// an `i64` for up to 2^31 values), so the loop vectorises.
fn exact_sum(counts: &[i64]) -> i128 {
    let (mut hi, mut lo) = (0i64, 0i64);
    for &c in counts {
        hi += c >> 32;
        lo += c & 0xFFFF_FFFF;
    }
    (i128::from(hi) << 32) + i128::from(lo)
}

/// `sum v_i` in four independent partial sums (vectorised; a fixed order for a
/// given slice).
fn lane_sum(v: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let chunks = v.chunks_exact(4);
    let tail: f64 = chunks.remainder().iter().sum();
    for c in chunks {
        for l in 0..4 {
            acc[l] += c[l];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Samples of `range` inside the spans `filled`.
fn overlap(filled: &[Range<usize>], range: Range<usize>) -> u64 {
    filled
        .iter()
        .map(|r| {
            r.end
                .min(range.end)
                .saturating_sub(r.start.max(range.start)) as u64
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// 1 kHz, 1.21 arcsec pulses: N = 100, 1210 deg/h per pulse.
    const RATE: f64 = 1000.0;
    const PULSE: f64 = 1.21;

    fn place_for(starts: &[u64], u: u64) -> Place {
        let k = starts.partition_point(|&s| s <= u);
        Place {
            segment_start: starts[k - 1],
            next_segment: starts.get(k).copied(),
            t_ns: 1_000_000_000 + u * 1_000_000 + 7_000_000_000 * (k as u64 - 1),
        }
    }

    /// The windows written out directly over the whole arrays.
    fn naive(
        counts: &[i64],
        filled: &[bool],
        clean: &[f64],
        temp: &[f64],
        starts: &[u64],
    ) -> Vec<SummaryUpdate> {
        let n = counts.len() as u64;
        let mut cuts = Vec::new();
        for (k, &s) in starts.iter().enumerate() {
            let e = starts.get(k + 1).copied().unwrap_or(n);
            let mut a = s;
            while a < e {
                cuts.push((a, (a + 100).min(e)));
                a += 100;
            }
        }
        cuts.into_iter()
            .map(|(a, b)| {
                let r = a as usize..b as usize;
                let len = (b - a) as f64;
                SummaryUpdate {
                    timestamp: Timestamp::from_ns(place_for(starts, a).t_ns),
                    samples: b - a,
                    lost_samples: filled[r.clone()].iter().filter(|f| **f).count() as u64,
                    raw_rate_dph: counts[r.clone()].iter().sum::<i64>() as f64 / len * 1210.0,
                    clean_rate_dph: clean[r.clone()].iter().sum::<f64>() / len,
                    temp_c: Some(temp[b as usize - 1]),
                }
            })
            .collect()
    }

    #[test]
    fn any_split_of_the_pushes_gives_the_naive_windows() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for case in 0..40 {
            let n = rng.random_range(1..2000usize);
            let counts: Vec<i64> = (0..n).map(|_| rng.random_range(-3..12)).collect();
            let clean: Vec<f64> = (0..n).map(|_| rng.random_range(-50.0..50.0)).collect();
            let temp: Vec<f64> = (0..n).map(|i| 20.0 + i as f64 * 1e-3).collect();
            let filled: Vec<bool> = (0..n).map(|i| (i / 37) % 5 == 3).collect();
            let mut starts = vec![0u64];
            while rng.random_bool(0.5) {
                let s = rng.random_range(1..n as u64 + 1);
                if s > *starts.last().unwrap() && s < n as u64 {
                    starts.push(s);
                }
            }
            let expected = naive(&counts, &filled, &clean, &temp, &starts);
            // pushes of random lengths; one temperature per sample; clean lagging by `lag`
            let lag = rng.random_range(0..300usize);
            let mut acc = SummaryAcc::new(RATE, PULSE);
            let mut got = Vec::new();
            let (mut u, mut emitted) = (0usize, 0usize);
            while u < n {
                let take = rng.random_range(1..150usize).min(n - u);
                for j in u..u + take {
                    // a segment is known only once its first sample has arrived
                    let known: Vec<u64> = starts
                        .iter()
                        .copied()
                        .filter(|&s| s as usize <= j + 1)
                        .collect();
                    let spans: Vec<Range<usize>> = if filled[j] { vec![0..1] } else { vec![] };
                    acc.push_raw(j as u64, &counts[j..j + 1], &spans, Some(temp[j]), &|x| {
                        place_for(&known, x)
                    });
                }
                u += take;
                let ready = u.saturating_sub(lag);
                if ready > emitted {
                    acc.push_clean(emitted as u64, &clean[emitted..ready], &mut got);
                    emitted = ready;
                }
            }
            acc.push_clean(emitted as u64, &clean[emitted..], &mut got);
            acc.finish(n as u64, &mut got);
            assert_eq!(
                got.len(),
                expected.len(),
                "case {case}: {n} samples, segments {starts:?}"
            );
            for (g, e) in got.iter().zip(&expected) {
                assert_eq!(
                    (g.timestamp, g.samples, g.lost_samples, g.temp_c),
                    (e.timestamp, e.samples, e.lost_samples, e.temp_c),
                    "case {case}"
                );
                // sums in another order: equal to rounding
                assert!(
                    (g.raw_rate_dph - e.raw_rate_dph).abs() <= 1e-9 * e.raw_rate_dph.abs().max(1.0),
                    "case {case}"
                );
                assert!(
                    (g.clean_rate_dph - e.clean_rate_dph).abs()
                        <= 1e-9 * e.clean_rate_dph.abs().max(1.0),
                    "case {case}"
                );
            }
        }
    }

    #[test]
    fn the_split_pulse_sum_is_exact_at_the_extremes() {
        let v = [i64::MAX, i64::MAX, i64::MIN, -1, 7, i64::MIN];
        let want: i128 = v.iter().map(|&c| i128::from(c)).sum();
        assert_eq!(exact_sum(&v), want);
        assert_eq!(exact_sum(&[]), 0);
        assert_eq!(lane_sum(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.5]), 21.5);
    }

    #[test]
    fn ten_hertz_at_one_kilohertz_and_the_edge_rules() {
        assert_eq!(summary_window_samples(1000.0), 100);
        assert_eq!(summary_window_samples(333.3), 33);
        assert_eq!(summary_window_samples(4.0), 1);
        // 3000 samples at 1 kHz: 30 windows of 100; 3050: a 31st of 50
        for (n, windows, last) in [(3000usize, 30usize, 100u64), (3050, 31, 50)] {
            let mut acc = SummaryAcc::new(RATE, PULSE);
            let counts = vec![1i64; n];
            acc.push_raw(0, &counts, &[], None, &|u| place_for(&[0], u));
            let mut out = Vec::new();
            acc.push_clean(0, &vec![2.5; n], &mut out);
            acc.finish(n as u64, &mut out);
            assert_eq!(out.len(), windows);
            assert_eq!(out.last().unwrap().samples, last);
            // one pulse of 1.21 arcsec per ms is 1210 deg/h
            assert!(
                out.iter()
                    .all(|m| (m.raw_rate_dph - 1210.0).abs() < 1e-9 && m.clean_rate_dph == 2.5)
            );
            assert_eq!(
                out[1].timestamp,
                Timestamp {
                    sec: 1,
                    nsec: 100_000_000
                }
            );
        }
    }
}
