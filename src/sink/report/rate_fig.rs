//! Figure: the rate time series (raw as its mean per pixel column, clean as
//! a min/max band with its mean) and, when the input carries it, the
//! temperature below.
//!
//! What the data-quality stage handled is marked on the rate, so the reader
//! sees it in the record it came from: a tick along the top at each excluded
//! outlier, a line at each bias step over its 95 % interval (shaded), and
//! the fitted warm-up drawn over the raw rate (see [`Marks`]). With the
//! stage off (`--raw-statistics`) the figure is the plain time series.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::ReportError;
use super::collect::Collector;
use super::decimate::Bucket;
use super::plot::{self, Area, LineKind, TimeAxis, draw_err};
use crate::quality::{DataQuality, StepFit, spikes};

/// The rate chart's coordinates.
type RateChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Height of one legend row above the plot, px.
const LEGEND_ROW: u32 = 24;
/// Points the warm-up curve is drawn with.
const CURVE_POINTS: usize = 600;

/// What the figure marks of the data-quality stage's work.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Marks {
    /// Times of the excluded outliers, s (at most [`spikes::MAX_LISTED`]; none
    /// when the outliers were kept as heavy-tailed noise).
    pub outliers_s: Vec<f64>,
    /// Outliers found in all.
    pub outlier_count: u64,
    pub steps: Vec<StepFit>,
    /// The fitted bias curve: `level + amplitude exp(-t / tau)` plus the
    /// steps after their times; `None` without a warm-up.
    pub warmup: Option<Curve>,
}

/// The fitted slow bias, drawn over the raw rate.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// The settled rate before any step, deg/h: the raw rate's mean over the
    /// last half of the record, less the steps that precede each sample.
    pub level_dph: f64,
    pub amplitude_dph: f64,
    pub tau_s: f64,
    /// (time s, amplitude deg/h) of each step.
    pub steps: Vec<(f64, f64)>,
}

impl Curve {
    /// The curve at `t` s; a step counts from its time on (`after`) or
    /// only once passed.
    pub fn at(&self, t: f64, after: bool) -> f64 {
        let stepped: f64 = self
            .steps
            .iter()
            .filter(|(at, _)| if after { *at <= t } else { *at < t })
            .map(|s| s.1)
            .sum();
        self.level_dph + self.amplitude_dph * (-t / self.tau_s).exp() + stepped
    }
}

impl Marks {
    /// The marks for a record's data-quality findings (`None`: nothing to
    /// mark), the warm-up's level from the raw rate's buckets `raw` of
    /// samples `tau0_s` apart.
    pub fn new(dq: Option<&DataQuality>, raw: &[Bucket], tau0_s: f64) -> Marks {
        let Some(dq) = dq else {
            return Marks::default();
        };
        let o = &dq.outliers;
        let outliers_s = if o.excluded {
            o.at_s.iter().take(spikes::MAX_LISTED).copied().collect()
        } else {
            Vec::new()
        };
        let steps: Vec<(f64, f64)> = dq
            .steps
            .iter()
            .map(|s| (s.at_s.value, s.amplitude_dph.value))
            .collect();
        let warmup = dq.warmup.as_ref().and_then(|w| {
            let level = settled_level(raw, tau0_s, &steps)?;
            Some(Curve {
                level_dph: level,
                amplitude_dph: w.amplitude_dph.value,
                tau_s: w.tau_s.value,
                steps: steps.clone(),
            })
        });
        Marks {
            outliers_s,
            outlier_count: if o.excluded { o.count } else { 0 },
            steps: dq.steps.clone(),
            warmup,
        }
    }

    fn is_empty(&self) -> bool {
        self.outliers_s.is_empty() && self.steps.is_empty() && self.warmup.is_none()
    }

    /// One legend row per kind marked.
    fn legend(&self) -> Vec<(RGBColor, LineKind, String)> {
        let mut rows = Vec::new();
        if !self.outliers_s.is_empty() {
            let listed = self.outliers_s.len() as u64;
            rows.push((
                plot::OUTLIER,
                LineKind::Tick,
                if self.outlier_count > listed {
                    format!(
                        "excluded outliers ({}, the first {listed} marked)",
                        self.outlier_count
                    )
                } else {
                    format!("excluded outliers ({listed})")
                },
            ));
        }
        if !self.steps.is_empty() {
            rows.push((
                plot::STEP,
                LineKind::Marker,
                "bias step, 95 % interval shaded".into(),
            ));
        }
        if self.warmup.is_some() {
            rows.push((
                plot::WARMUP,
                LineKind::Solid,
                if self.steps.is_empty() {
                    "fitted warm-up".into()
                } else {
                    "fitted warm-up, with the steps".into()
                },
            ));
        }
        rows
    }
}

/// Mean of the raw rate over the last half of the record, each bucket less
/// the steps before it, weighted by its samples.
fn settled_level(raw: &[Bucket], tau0_s: f64, steps: &[(f64, f64)]) -> Option<f64> {
    let end = raw.last().map(|b| (b.first + b.count) as f64 * tau0_s)?;
    let (mut sum, mut n) = (0.0, 0.0);
    for b in raw {
        let t = (b.first as f64 + 0.5 * b.count as f64) * tau0_s;
        if t >= 0.5 * end {
            let stepped: f64 = steps.iter().filter(|s| s.0 <= t).map(|s| s.1).sum();
            sum += (b.mean - stepped) * b.count as f64;
            n += b.count as f64;
        }
    }
    (n > 0.0).then(|| sum / n)
}

/// Draw on `area`; `dq` marks what the data-quality stage handled.
pub fn draw<DB: DrawingBackend>(
    area: &Area<DB>,
    c: &Collector,
    dq: Option<&DataQuality>,
    u: super::Units,
) -> Result<(), ReportError> {
    crate::font::register()?;
    area.fill(&WHITE).map_err(draw_err)?;
    let tau0 = c.tau0_s();
    let s = &c.series;
    let axis = TimeAxis::for_duration(s.raw_dph.len() as f64 * tau0);
    let t_hi = (s.raw_dph.len().max(2) - 1) as f64 * tau0 / axis.per_unit;
    let (_, h) = area.dim_in_pixel();
    let temp = c.temperature();
    let (rate_area, temp_area) = match temp {
        Some(_) => {
            let (a, b) = area.split_vertically(h * 3 / 5);
            (a, Some(b))
        }
        None => (area.clone(), None),
    };
    // the raw rate as its mean per column: its per-sample spread is the
    // quantization noise (the noise figure), which would flatten the rest
    let raw = s.raw_dph.buckets();
    let marks = Marks::new(dq, &raw, tau0);
    let rows = if marks.is_empty() { 1 } else { 2 };
    let (head, body) = rate_area.split_vertically(10 + rows * LEGEND_ROW);
    let raw_mean = raw
        .iter()
        .map(|b| b.mean)
        .fold(None, |r: Option<(f64, f64)>, v| match r {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        });
    let clean = s.clean_dph.buckets();
    let (lo, hi) = match (raw_mean, plot::robust_range(&clean)) {
        (Some(a), Some(b)) => (a.0.min(b.0), a.1.max(b.1)),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => (-1.0, 1.0),
    };
    let (lo, hi) = plot::padded(lo, hi);
    let mut chart = plot::TimeChart {
        caption: "rate",
        caption_size: plot::TITLE,
        x_area: 44,
        y_area: 80,
        y_desc: &format!("{}, {}", u.rate_word, u.rate),
    }
    .build(&body, axis, t_hi, (lo, hi))?;
    // the steps' intervals under the data
    step_intervals(&mut chart, &marks.steps, axis, t_hi, (lo, hi))?;
    // the extreme 2 % (the wavelet bank's start-up) is drawn at the axis' edge
    let clean_c = plot::clamped(&clean, lo, hi);
    plot::draw_band(&mut chart, &clean_c, tau0, axis, plot::CLEAN, "")?;
    chart
        .draw_series(LineSeries::new(
            raw.iter()
                .map(|b| (plot::bucket_time(b, tau0, axis), b.mean.clamp(lo, hi))),
            plot::RAW.mix(0.8).stroke_width(1),
        ))
        .map_err(draw_err)?;
    // the clean mean on top: the quantization noise removed, it wanders far less
    chart
        .draw_series(LineSeries::new(
            clean_c
                .iter()
                .map(|b| (plot::bucket_time(b, tau0, axis), b.mean)),
            plot::CLEAN.stroke_width(2),
        ))
        .map_err(draw_err)?;
    handled(&mut chart, &marks, axis, t_hi, (lo, hi))?;
    legend(&head, &marks)?;
    if let (Some(t), Some(area)) = (temp, temp_area) {
        let (lo, hi) = t.range().unwrap_or((0.0, 1.0));
        let (lo, hi) = plot::padded(lo, hi);
        let mut chart = plot::TimeChart {
            caption: "temperature",
            caption_size: plot::LABEL + 2,
            x_area: 44,
            y_area: 80,
            y_desc: "temperature, \u{b0}C",
        }
        .build(&area, axis, t_hi, (lo, hi))?;
        plot::draw_band(&mut chart, &t.buckets(), tau0, axis, plot::TEMP, "")?;
    }
    Ok(())
}

/// Each step's 95 % interval in time, lightly shaded over the plot's height.
fn step_intervals<DB: DrawingBackend>(
    chart: &mut RateChart<'_, DB>,
    steps: &[StepFit],
    axis: TimeAxis,
    t_hi: f64,
    (lo, hi): (f64, f64),
) -> Result<(), ReportError> {
    let x = |t: f64| (t / axis.per_unit).clamp(0.0, t_hi);
    chart
        .draw_series(steps.iter().map(|s| {
            Rectangle::new(
                [(x(s.at_s.ci95[0]), hi), (x(s.at_s.ci95[1]), lo)],
                plot::STEP.mix(0.15).filled(),
            )
        }))
        .map_err(draw_err)?;
    Ok(())
}

/// The outliers as ticks along the top, the steps as lines, and the fitted
/// warm-up over the rate.
fn handled<DB: DrawingBackend>(
    chart: &mut RateChart<'_, DB>,
    m: &Marks,
    axis: TimeAxis,
    t_hi: f64,
    (lo, hi): (f64, f64),
) -> Result<(), ReportError> {
    let inside = |x: &f64| (0.0..=t_hi).contains(x);
    let tick_lo = hi - 0.06 * (hi - lo);
    chart
        .draw_series(
            m.outliers_s
                .iter()
                .map(|t| t / axis.per_unit)
                .filter(inside)
                .map(|x| {
                    PathElement::new(vec![(x, tick_lo), (x, hi)], plot::OUTLIER.stroke_width(1))
                }),
        )
        .map_err(draw_err)?;
    chart
        .draw_series(
            m.steps
                .iter()
                .map(|s| s.at_s.value / axis.per_unit)
                .filter(inside)
                .map(|x| PathElement::new(vec![(x, lo), (x, hi)], plot::STEP.stroke_width(2))),
        )
        .map_err(draw_err)?;
    if let Some(w) = &m.warmup {
        let end_s = t_hi * axis.per_unit;
        let mut pts: Vec<(f64, f64)> = (0..=CURVE_POINTS)
            .map(|i| {
                let t = end_s * i as f64 / CURVE_POINTS as f64;
                (t, w.at(t, true))
            })
            .collect();
        // each step drawn as a jump at its time
        for &(at, _) in w.steps.iter().filter(|s| (0.0..=end_s).contains(&s.0)) {
            pts.push((at, w.at(at, false)));
            pts.push((at, w.at(at, true)));
        }
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(
                pts.into_iter()
                    .map(|(t, v)| (t / axis.per_unit, v.clamp(lo, hi))),
                plot::WARMUP.stroke_width(2),
            ))
            .map_err(draw_err)?;
    }
    Ok(())
}

/// The legend above the plot: the rates in the first row, what the
/// data-quality stage marked in the second.
fn legend<DB: DrawingBackend>(head: &Area<DB>, m: &Marks) -> Result<(), ReportError> {
    let area = head.margin(8, 0, 90, 0);
    let (first, second) = area.split_vertically(LEGEND_ROW);
    legend_row(
        &first,
        &[
            (
                plot::RAW,
                LineKind::Solid,
                "raw rate, mean per pixel column".into(),
            ),
            (
                plot::CLEAN,
                LineKind::Band,
                "clean rate (quantization noise removed): mean, min/max band".into(),
            ),
        ],
    )?;
    legend_row(&second, &m.legend())
}

/// Legend entries side by side, each as wide as its text.
fn legend_row<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[(RGBColor, LineKind, String)],
) -> Result<(), ReportError> {
    let mut rest = area.clone();
    for e in entries {
        let (w, _) = rest
            .estimate_text_size(&e.2, &plot::font(plot::TICK))
            .map_err(draw_err)?;
        // the key (38 px), its gap (8 px) and a gap to the next entry
        let (this, next) = rest.split_horizontally(w + 46 + 36);
        plot::side_legend(&this, std::slice::from_ref(e))?;
        rest = next;
    }
    Ok(())
}
