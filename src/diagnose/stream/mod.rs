//! The diagnosis statistics ([`StatSet`]) of a record fed in pieces, in
//! memory that does not grow with the record (apart from the approximation
//! series a kurtosis or two-level statistic reads, `8 f_c` values per second
//! for a cut-off `f_c`). The recording and every Monte-Carlo run are reduced
//! by this one type, so they are compared like with like; the batch
//! [`super::stats::compute`] is its reference (`tests/diagnose/stream.rs`):
//! equal to rounding, except the Allan points beyond
//! [`allan::FULL_OVERLAP_CAP`], which use strided terms.

pub mod allan;
pub mod dwt;
pub mod refill;
pub mod welch;

use super::stats::{self, StatLayout, StatSet, band_means};
use super::two_level::TwoLevelProbe;
use crate::model::estimate::RampAccumulator;

use self::allan::AllanStream;
use self::dwt::DwtStream;
use self::welch::WelchStream;

/// Samples a stream is fed in at a time by [`reduce_counts`] and the
/// Monte-Carlo runs.
pub const CHUNK: usize = 1 << 16;

/// What a [`StatStream`] computes besides the layout's own statistics.
#[derive(Debug, Clone, Copy)]
pub struct Extras<'a> {
    /// Temperature regressor (the recording's), one value per sample.
    pub temp_c: Option<&'a [f64]>,
    /// Low-pass cut-offs of the kurtosis statistics.
    pub lp_cutoffs_hz: &'a [f64],
    /// The two-level likelihood ratio's probe.
    pub two_level: Option<TwoLevelProbe>,
    /// All statistics (`false`: only the kurtosis and two-level ones).
    pub full: bool,
}

/// The layout's statistics that need the whole record in order.
struct Broad {
    allan: AllanStream,
    welch: WelchStream,
    ramp: RampAccumulator,
    temp: Option<Regression>,
    /// Block sums of the low-frequency rows, and the open block's.
    lf_means: Vec<f64>,
    lf_open: f64,
}

/// The statistics of one record, fed in pieces of counts.
pub struct StatStream<'a> {
    layout: &'a StatLayout,
    extras: Extras<'a>,
    g: f64,
    seen: usize,
    broad: Option<Broad>,
    dwt: DwtStream,
    /// The rate itself, when a statistic reads level 0.
    level0: Option<Vec<f64>>,
    rate: Vec<f64>,
}

impl<'a> StatStream<'a> {
    /// A stream for a record of `layout.n_samples` counts.
    pub fn new(layout: &'a StatLayout, extras: Extras<'a>) -> StatStream<'a> {
        let tau0 = layout.tau0_s();
        let mut keep: Vec<u32> = extras
            .lp_cutoffs_hz
            .iter()
            .map(|&fc| stats::kurtosis_level(tau0, fc))
            .collect();
        if let Some(p) = extras.two_level {
            keep.push(p.level(tau0));
        }
        let wvar_depth = if extras.full {
            layout.levels.len() as u32
        } else {
            0
        };
        let depth = keep.iter().copied().max().unwrap_or(0).max(wvar_depth);
        let n = layout.n_samples;
        let broad = extras.full.then(|| Broad {
            allan: AllanStream::new(&layout.ms, n),
            welch: WelchStream::new(&layout.welch, n, layout.fs_hz),
            ramp: RampAccumulator::default(),
            temp: extras.temp_c.map(|_| Regression::default()),
            lf_means: Vec::new(),
            lf_open: 0.0,
        });
        StatStream {
            layout,
            extras,
            g: layout.pulse_arcsec * layout.fs_hz,
            seen: 0,
            broad,
            dwt: DwtStream::new(&layout.lo, &layout.hi, depth, &keep),
            level0: keep.contains(&0).then(Vec::new),
            rate: Vec::new(),
        }
    }

    /// Add the next counts (at most the layout's length in all).
    pub fn push(&mut self, counts: &[i64]) {
        let room = self.layout.n_samples - self.seen;
        let counts = &counts[..counts.len().min(room)];
        self.rate.clear();
        self.rate.extend(counts.iter().map(|&c| c as f64 * self.g));
        if let Some(b) = &mut self.broad {
            b.allan.push(counts);
            b.welch.push(&self.rate);
            b.ramp.push_slice(&self.rate);
            if let (Some(r), Some(t)) = (&mut b.temp, self.extras.temp_c) {
                let t = &t[self.seen.min(t.len())..(self.seen + counts.len()).min(t.len())];
                r.push(t, &self.rate);
            }
            lf_push(self.layout, self.seen, &self.rate, b);
        }
        self.dwt.push(&self.rate);
        if let Some(l0) = &mut self.level0 {
            l0.extend_from_slice(&self.rate);
        }
        self.seen += counts.len();
    }

    /// The statistics; `push` must have been given the whole record.
    pub fn finish(mut self) -> StatSet {
        debug_assert_eq!(self.seen, self.layout.n_samples, "the whole record");
        let tau0 = self.layout.tau0_s();
        let mut out = StatSet {
            two_level_llr: f64::NAN,
            ..StatSet::default()
        };
        let kurt_levels: Vec<(f64, u32)> = self
            .extras
            .lp_cutoffs_hz
            .iter()
            .map(|&fc| (fc, stats::kurtosis_level(tau0, fc)))
            .collect();
        for (fc, level) in kurt_levels {
            let dt = tau0 * 2f64.powi(level as i32);
            out.kurtosis.push(stats::lowpass_kurtosis_of(
                self.approximation(level),
                dt,
                fc,
            ));
        }
        if let Some(p) = self.extras.two_level {
            let y = self.approximation(p.level(tau0)).to_vec();
            out.two_level_llr = p.llr_of(y, tau0);
        }
        if let Some(b) = self.broad.take() {
            self.finish_broad(b, &mut out);
        }
        out
    }

    /// The approximation coefficients at `level` (level 0: the rate).
    fn approximation(&self, level: u32) -> &[f64] {
        match level {
            0 => self.level0.as_deref().unwrap_or(&[]),
            _ => self.dwt.approximation(level),
        }
    }

    fn finish_broad(&self, b: Broad, out: &mut StatSet) {
        let lay = self.layout;
        let tau0 = lay.tau0_s();
        let to_rate = (lay.pulse_arcsec / tau0).powi(2);
        let (avar, mvar) = b.allan.finish();
        out.avar = avar.iter().map(|v| v * to_rate).collect();
        out.mvar = mvar.iter().map(|v| v * to_rate).collect();
        let full = b.welch.finish();
        out.psd = full[lay.k_lo..lay.k_hi].to_vec();
        out.band_psd = band_means(lay, &out.psd);
        out.mean_rate = b.ramp.mean();
        out.slope = b.ramp.slope_per_sample() / tau0;
        out.temp_slope = b.temp.map(|r| r.slope());
        out.lf_psd = if b.lf_means.len() == super::lowfreq::LF_BLOCKS {
            lay.lf.psd_of_means(&b.lf_means)
        } else {
            Vec::new()
        };
        out.wvar = self
            .dwt
            .level_mean_squares()
            .into_iter()
            .take(lay.levels.len())
            .map(|(_, ms)| ms)
            .collect();
    }
}

/// Add rate samples starting at record index `at` to the low-frequency
/// block means (summed in order, as the whole-record means are).
fn lf_push(layout: &StatLayout, at: usize, rate: &[f64], b: &mut Broad) {
    let len = layout.lf.block_len;
    if len == 0 {
        return;
    }
    let end = len * super::lowfreq::LF_BLOCKS;
    for (k, &r) in rate.iter().enumerate() {
        let i = at + k;
        if i >= end {
            break;
        }
        b.lf_open += r;
        if (i + 1).is_multiple_of(len) {
            b.lf_means.push(b.lf_open / len as f64);
            b.lf_open = 0.0;
        }
    }
}

/// Least-squares slope of `y` on `x` from sums about the first pair (a
/// stream's [`stats::regression_slope`]).
#[derive(Debug, Clone, Copy, Default)]
struct Regression {
    n: f64,
    x0: f64,
    y0: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
}

impl Regression {
    fn push(&mut self, x: &[f64], y: &[f64]) {
        for (&xi, &yi) in x.iter().zip(y) {
            if self.n == 0.0 {
                (self.x0, self.y0) = (xi, yi);
            }
            let (dx, dy) = (xi - self.x0, yi - self.y0);
            self.n += 1.0;
            self.sx += dx;
            self.sy += dy;
            self.sxx += dx * dx;
            self.sxy += dx * dy;
        }
    }

    fn slope(&self) -> f64 {
        if self.n < 2.0 {
            return 0.0;
        }
        let sxx = self.sxx - self.sx * self.sx / self.n;
        let sxy = self.sxy - self.sx * self.sy / self.n;
        if sxx > 0.0 { sxy / sxx } else { 0.0 }
    }
}

/// The statistics of a whole record of counts, fed to a [`StatStream`] in
/// [`CHUNK`]s.
pub fn reduce_counts(layout: &StatLayout, counts: &[i64], extras: Extras) -> StatSet {
    let mut s = StatStream::new(layout, extras);
    for c in counts.chunks(CHUNK) {
        s.push(c);
    }
    s.finish()
}
