//! What the report keeps of the samples while the pipeline runs: decimated
//! time series of the raw, clean and noise rates, of the noise's running
//! integral (the founding paper's check: quantization noise is white in
//! angle, so its integral stays within about one pulse) and of the
//! temperature; and the gap counts.
//!
//! It is fed by the pipeline's taps ([`crate::pipeline::feed`]) through
//! [`Collector::tap`].

use crate::pipeline::feed::TapBlock;

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
    /// Every pushed block carried a temperature.
    temps_complete: bool,
}

impl Collector {
    /// A collector for samples at `sample_rate_hz`.
    pub fn new(sample_rate_hz: f64) -> Collector {
        Collector {
            tau0_s: 1.0 / sample_rate_hz,
            series: Series::new(),
            noise_angle: 0.0,
            gaps: 0,
            lost_samples: 0,
            temps_complete: true,
        }
    }

    /// Sample period, s.
    pub fn tau0_s(&self) -> f64 {
        self.tau0_s
    }

    /// Take one push of the pipeline.
    pub fn tap(&mut self, b: &TapBlock<'_>) {
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
    }

    /// The temperature series, when every sample had one.
    pub fn temperature(&self) -> Option<&MinMax> {
        (self.temps_complete && !self.series.temp_c.is_empty()).then_some(&self.series.temp_c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::PipelineOutput;

    #[test]
    fn the_noise_integral_is_the_running_sum() {
        let mut c = Collector::new(100.0);
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
        assert!(c.temperature().is_none());
    }
}
