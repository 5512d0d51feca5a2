//! What the report keeps of the samples while the pipeline runs: decimated
//! time series of the raw, clean and noise rates, of the noise's running
//! integral (the founding paper's check: quantization noise is white in
//! angle, so its integral stays within about one pulse) and of the
//! temperature; the gap counts; and, for a diagnosis, the pulse increments
//! and temperatures in full.
//!
//! It is fed by [`crate::offline`]'s taps through [`Collector::tap`].

use crate::offline::TapBlock;

use super::decimate::MinMax;

/// Buckets per decimated series (a figure is about 1000 pixels wide: two
/// buckets a pixel at most).
pub const BUCKETS: usize = 1000;

/// Decimated series, all on the sample index (time = index / rate).
#[derive(Debug, Clone)]
pub struct Series {
    /// Raw rate, deg/h.
    pub raw_dph: MinMax,
    /// Clean rate (quantization noise removed), deg/h.
    pub clean_dph: MinMax,
    /// Extracted noise, deg/h.
    pub noise_dph: MinMax,
    /// Running integral of the noise, arcsec.
    pub noise_angle_arcsec: MinMax,
    /// Temperature, deg C (empty when the input has none).
    pub temp_c: MinMax,
}

impl Series {
    fn new() -> Series {
        Series {
            raw_dph: MinMax::new(BUCKETS),
            clean_dph: MinMax::new(BUCKETS),
            noise_dph: MinMax::new(BUCKETS),
            noise_angle_arcsec: MinMax::new(BUCKETS),
            temp_c: MinMax::new(BUCKETS),
        }
    }
}

/// The collector.
#[derive(Debug, Clone)]
pub struct Collector {
    tau0_s: f64,
    pub series: Series,
    noise_angle: f64,
    /// Gaps seen and samples lost in them (filled).
    pub gaps: u64,
    pub lost_samples: u64,
    keep_samples: bool,
    /// Pulse increments in full (only with [`Collector::keeping_samples`] and count input).
    pub counts: Vec<i64>,
    /// Temperatures in full, as long as every pushed block carried one.
    pub temps: Vec<f64>,
    counts_complete: bool,
    temps_complete: bool,
}

impl Collector {
    /// A collector for samples at `rate_hz`.
    pub fn new(rate_hz: f64) -> Collector {
        Collector {
            tau0_s: 1.0 / rate_hz,
            series: Series::new(),
            noise_angle: 0.0,
            gaps: 0,
            lost_samples: 0,
            keep_samples: false,
            counts: Vec::new(),
            temps: Vec::new(),
            counts_complete: true,
            temps_complete: true,
        }
    }

    /// Also keep every pulse increment and temperature (for a diagnosis).
    pub fn keeping_samples(mut self) -> Collector {
        self.keep_samples = true;
        self
    }

    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        self.tau0_s
    }

    /// Take one push of the pipeline.
    pub fn tap(&mut self, b: &TapBlock<'_>) {
        if b.first_sample == 0 && !self.series.raw_dph.is_empty() {
            // the reader started over
            *self = Collector {
                keep_samples: self.keep_samples,
                ..Collector::new(1.0 / self.tau0_s)
            };
        }
        self.series.raw_dph.extend(b.rate_dph);
        self.series.clean_dph.extend(&b.out.clean_dph);
        self.series.noise_dph.extend(&b.out.noise_dph);
        for &v in &b.out.noise_dph {
            self.noise_angle += v * self.tau0_s;
            self.series.noise_angle_arcsec.push(self.noise_angle);
        }
        if !b.rate_dph.is_empty() {
            match b.temp_c {
                Some(t) if self.temps_complete => self.series.temp_c.extend(t),
                _ => self.temps_complete = false,
            }
        }
        self.gaps += b.gaps;
        self.lost_samples += b.lost_samples;
        if self.keep_samples && !b.rate_dph.is_empty() {
            match b.counts {
                Some(c) if self.counts_complete => self.counts.extend_from_slice(c),
                _ => {
                    self.counts_complete = false;
                    self.counts = Vec::new();
                }
            }
            match b.temp_c {
                Some(t) if self.temps_complete => self.temps.extend_from_slice(t),
                _ => self.temps = Vec::new(),
            }
        }
    }

    /// The temperature series, when every sample had one.
    pub fn temperature(&self) -> Option<&MinMax> {
        (self.temps_complete && !self.series.temp_c.is_empty()).then_some(&self.series.temp_c)
    }

    /// Every pulse increment, when the input was counts all along (and kept).
    pub fn all_counts(&self) -> Option<&[i64]> {
        (self.keep_samples && self.counts_complete && !self.counts.is_empty())
            .then_some(&self.counts[..])
    }

    /// Every temperature, when each sample had one (and they were kept).
    pub fn all_temps(&self) -> Option<&[f64]> {
        (self.keep_samples && self.temps_complete && !self.temps.is_empty())
            .then_some(&self.temps[..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::PipelineOutput;

    #[test]
    fn the_noise_integral_is_the_running_sum_and_a_restart_resets() {
        let mut c = Collector::new(100.0).keeping_samples();
        let out = PipelineOutput {
            clean_dph: vec![1.0; 4],
            noise_dph: vec![100.0, -50.0, 25.0, 0.0],
        };
        let counts = [1, 2, 3, 4];
        let block = |first| TapBlock {
            first_sample: first,
            counts: Some(&counts),
            rate_dph: &[1.0, 2.0, 3.0, 4.0],
            temp_c: None,
            gaps: 1,
            lost_samples: 3,
            out: &out,
        };
        c.tap(&block(0));
        // 100 deg/h = 100 arcsec/s for 10 ms = 1 arcsec; then -0.5, +0.25
        let b = c.series.noise_angle_arcsec.buckets();
        let v: Vec<f64> = b.iter().map(|b| b.mean).collect();
        assert_eq!(v, vec![1.0, 0.5, 0.75, 0.75]);
        c.tap(&block(4));
        assert_eq!(c.series.raw_dph.len(), 8);
        assert_eq!((c.gaps, c.lost_samples), (2, 6));
        assert_eq!(c.all_counts().unwrap().len(), 8);
        assert!(c.temperature().is_none() && c.all_temps().is_none());
        c.tap(&block(0));
        assert_eq!(c.series.raw_dph.len(), 4);
        assert_eq!((c.gaps, c.lost_samples), (1, 3));
        assert_eq!(c.all_counts().unwrap(), &counts);
    }
}
