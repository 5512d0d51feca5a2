//! A topic's sample timing, from its `header.stamp`s in the order the bag
//! holds them: the nominal period (the median interval between sorted
//! stamps), the messages out of order (sorted back), the duplicates
//! (an interval under half a period: the later one dropped), and the holes
//! (an interval of `k` periods, rounded, leaves `k - 1` samples out: gaps).
//! Rounding each interval on its own tolerates jitter and a clock that runs a
//! little off the nominal rate; the sample rate is the number of periods
//! over the span of the stamps.
//!
//! [`Timing`] is what the opening pass finds; [`Placer`] makes the same
//! decisions sample by sample on the stream, so both agree by construction.

/// What a topic's stamps say.
#[derive(Debug, Clone, PartialEq)]
pub struct Timing {
    /// Messages on the topic.
    pub messages: u64,
    /// Median interval between consecutive sorted stamps, ns.
    pub period_ns: f64,
    /// Sample rate: periods over the span of the stamps, Hz.
    pub sample_rate_hz: f64,
    /// Messages whose stamp is earlier than one before them in the bag.
    pub out_of_order: u64,
    /// The most a stamp lags the latest stamp before it in the bag, ns.
    pub max_lateness_ns: i64,
    /// Messages dropped as duplicates (less than half a period after the one before).
    pub duplicates: u64,
    /// Holes, and the samples missing in them.
    pub gaps: u64,
    pub lost_samples: u64,
    /// Samples handed out: messages kept plus samples filled.
    pub samples: u64,
}

impl Timing {
    /// The timing of `stamps` (ns, in bag order); `None` for fewer than two
    /// distinct stamps.
    pub fn from_stamps(stamps: &[i64]) -> Option<Timing> {
        let mut out_of_order = 0;
        let mut max_lateness_ns = 0;
        let mut newest = i64::MIN;
        for &s in stamps {
            if s < newest {
                out_of_order += 1;
                max_lateness_ns = max_lateness_ns.max(newest - s);
            }
            newest = newest.max(s);
        }
        let mut sorted = stamps.to_vec();
        sorted.sort_unstable();
        let mut intervals: Vec<i64> = sorted
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&d| d > 0)
            .collect();
        if intervals.is_empty() {
            return None;
        }
        let mid = intervals.len() / 2;
        let period_ns = *intervals.select_nth_unstable(mid).1 as f64;
        let mut placer = Placer::new(period_ns);
        let (mut periods, mut lost_samples, mut gaps, mut duplicates) = (0u64, 0u64, 0u64, 0u64);
        for &s in &sorted {
            match placer.place(s) {
                Place::First => {}
                Place::Duplicate => duplicates += 1,
                Place::After(k) => {
                    periods += k;
                    gaps += u64::from(k > 1);
                    lost_samples += k - 1;
                }
            }
        }
        let span = (sorted[sorted.len() - 1] - sorted[0]) as f64;
        Some(Timing {
            messages: stamps.len() as u64,
            period_ns,
            sample_rate_hz: periods as f64 * 1e9 / span,
            out_of_order,
            max_lateness_ns,
            duplicates,
            gaps,
            lost_samples,
            samples: periods + 1,
        })
    }
}

/// Where a stamp falls after the last kept one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// The first stamp.
    First,
    /// Less than half a period after the last kept stamp: dropped.
    Duplicate,
    /// `k >= 1` periods after it (`k - 1` samples missing).
    After(u64),
}

/// Places sorted stamps on the sample grid, one interval at a time.
#[derive(Debug, Clone)]
pub struct Placer {
    period_ns: f64,
    last: Option<i64>,
}

impl Placer {
    pub fn new(period_ns: f64) -> Self {
        Placer {
            period_ns,
            last: None,
        }
    }

    /// Place the next stamp (stamps come sorted).
    pub fn place(&mut self, stamp: i64) -> Place {
        let Some(last) = self.last else {
            self.last = Some(stamp);
            return Place::First;
        };
        let k = ((stamp - last) as f64 / self.period_ns).round();
        if k < 1.0 {
            return Place::Duplicate;
        }
        self.last = Some(stamp);
        Place::After(k as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: i64, period: i64) -> Vec<i64> {
        (0..n).map(|i| 1_000_000 + i * period).collect()
    }

    #[test]
    fn clean_stamps() {
        let t = Timing::from_stamps(&grid(1000, 5_000_000)).unwrap();
        assert_eq!(t.period_ns, 5e6);
        assert_eq!(t.sample_rate_hz, 200.0);
        assert_eq!(
            (t.out_of_order, t.duplicates, t.gaps, t.lost_samples),
            (0, 0, 0, 0)
        );
        assert_eq!(t.samples, 1000);
    }

    #[test]
    fn holes_swaps_duplicates_and_jitter() {
        let mut s = grid(1000, 5_000_000);
        // jitter of +-20 % of a period on every stamp (deterministic pattern)
        for (i, v) in s.iter_mut().enumerate() {
            *v += ((i * 7919) % 41) as i64 * 50_000 - 1_000_000;
        }
        s.drain(500..503); // a hole of 3
        s.remove(100); // a hole of 1
        s.swap(10, 11);
        s.swap(20, 21);
        s.insert(300, s[299]); // a duplicate
        let t = Timing::from_stamps(&s).unwrap();
        assert_eq!((t.gaps, t.lost_samples), (2, 4));
        assert_eq!(t.duplicates, 1);
        assert_eq!(t.out_of_order, 2);
        assert_eq!(t.samples, 1000);
        assert!(
            (t.sample_rate_hz - 200.0).abs() < 0.1,
            "{}",
            t.sample_rate_hz
        );
    }

    #[test]
    fn a_clock_off_the_nominal_rate_adds_no_gap() {
        // 199.9 Hz over 100 000 samples: intervals round to one period each
        let s: Vec<i64> = (0..100_000)
            .map(|i| (i as f64 * 1e9 / 199.9) as i64)
            .collect();
        let t = Timing::from_stamps(&s).unwrap();
        assert_eq!((t.gaps, t.lost_samples), (0, 0));
        assert!(
            (t.sample_rate_hz - 199.9).abs() < 1e-6,
            "{}",
            t.sample_rate_hz
        );
        assert!(Timing::from_stamps(&[5, 5, 5]).is_none());
    }
}
