//! Shared pieces of the report's figures: colours, tick formatting, time
//! axes, min/max bands, and the error conversion from plotters'.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::ReportError;
use super::decimate::Bucket;
use crate::font::FAMILY;

/// A drawing area of any backend (SVG for the page, bitmap for the PNGs).
pub type Area<DB> = DrawingArea<DB, Shift>;

pub const RAW: RGBColor = RGBColor(90, 90, 90);
pub const CLEAN: RGBColor = RGBColor(31, 100, 200);
pub const NOISE: RGBColor = RGBColor(225, 110, 20);
pub const TEMP: RGBColor = RGBColor(190, 40, 40);
/// The total model curve.
pub const MODEL: RGBColor = RGBColor(125, 125, 125);
/// What the data-quality stage handled, on the rate figure: excluded
/// outliers, bias steps (with their intervals), the fitted warm-up.
pub const OUTLIER: RGBColor = RGBColor(140, 60, 170);
pub const STEP: RGBColor = RGBColor(200, 30, 90);
pub const WARMUP: RGBColor = RGBColor(20, 140, 70);
/// QN, ARW, BI, RRW, RR.
pub const TERM_COLORS: [RGBColor; 5] = [
    RGBColor(140, 60, 170),
    RGBColor(20, 140, 70),
    RGBColor(150, 100, 30),
    RGBColor(200, 30, 90),
    RGBColor(0, 150, 160),
];

/// Font sizes, px.
pub const TITLE: u32 = 20;
pub const LABEL: u32 = 15;
pub const TICK: u32 = 13;

pub fn font(size: u32) -> TextStyle<'static> {
    (FAMILY, size).into_font().into()
}

/// plotters' errors as ours.
pub fn draw_err<E: std::fmt::Display>(e: E) -> ReportError {
    ReportError::Draw(e.to_string())
}

/// A log-axis tick: plain decimals from 0.001 to 99999, else `1e-5`.
pub fn log_tick(v: f64) -> String {
    if !(v.is_finite() && v > 0.0) {
        return String::new();
    }
    let mut e = v.log10().floor();
    // a value a rounding below a power of ten is that power
    if (v / 10f64.powf(e + 1.0) - 1.0).abs() < 1e-6 {
        e += 1.0;
    }
    let mant = v / 10f64.powf(e);
    let mant_txt = if (mant - mant.round()).abs() < 1e-6 {
        format!("{}", mant.round())
    } else {
        format!("{mant:.1}")
    };
    if (-3.0..5.0).contains(&e) {
        let decimals = if e < 0.0 {
            (-e) as usize + usize::from(mant_txt.contains('.'))
        } else {
            0
        };
        format!("{v:.decimals$}")
    } else if mant_txt == "1" {
        format!("1e{e}")
    } else {
        format!("{mant_txt}e{e}")
    }
}

/// A linear-axis tick with just enough decimals for a step of `step`.
pub fn lin_tick(v: f64, step: f64) -> String {
    let d = if step > 0.0 && step.is_finite() {
        (-step.log10().floor()).max(0.0) as usize
    } else {
        2
    };
    let s = format!("{v:.d$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// A time axis: seconds, minutes or hours, chosen for the record's length.
#[derive(Debug, Clone, Copy)]
pub struct TimeAxis {
    /// Seconds per displayed unit.
    pub per_unit: f64,
    pub label: &'static str,
}

impl TimeAxis {
    pub fn for_duration(duration_s: f64) -> TimeAxis {
        if duration_s > 3.0 * 3600.0 {
            TimeAxis {
                per_unit: 3600.0,
                label: "time, h",
            }
        } else if duration_s > 1800.0 {
            TimeAxis {
                per_unit: 60.0,
                label: "time, min",
            }
        } else {
            TimeAxis {
                per_unit: 1.0,
                label: "time, s",
            }
        }
    }
}

/// Centre time (in the axis unit) of a bucket.
pub fn bucket_time(b: &Bucket, tau0_s: f64, axis: TimeAxis) -> f64 {
    (b.first as f64 + 0.5 * (b.count.max(1) - 1) as f64) * tau0_s / axis.per_unit
}

/// A y range holding `lo..hi` with a margin (a flat series gets one too).
pub fn padded(lo: f64, hi: f64) -> (f64, f64) {
    let span = hi - lo;
    let pad = if span > 0.0 {
        0.06 * span
    } else {
        lo.abs().max(1.0) * 0.05
    };
    (lo - pad, hi + pad)
}

/// The range of `buckets` without their most extreme 2 % at either end
/// (such as the wavelet bank's start-up transient), widened by a tenth.
pub fn robust_range(buckets: &[Bucket]) -> Option<(f64, f64)> {
    let mut lo: Vec<f64> = buckets.iter().map(|b| b.min).collect();
    let mut hi: Vec<f64> = buckets.iter().map(|b| b.max).collect();
    if lo.is_empty() {
        return None;
    }
    lo.sort_by(f64::total_cmp);
    hi.sort_by(f64::total_cmp);
    let k = lo.len() / 50;
    let (a, b) = (lo[k], hi[hi.len() - 1 - k]);
    let pad = 0.1 * (b - a);
    Some((a - pad, b + pad))
}

/// `buckets` with their values clamped into `[lo, hi]`.
pub fn clamped(buckets: &[Bucket], lo: f64, hi: f64) -> Vec<Bucket> {
    buckets
        .iter()
        .map(|b| Bucket {
            min: b.min.clamp(lo, hi),
            max: b.max.clamp(lo, hi),
            mean: b.mean.clamp(lo, hi),
            ..*b
        })
        .collect()
}

/// Draw `buckets` as a min-max band (when buckets span several samples) and
/// the mean line on top.
/// A chart of linear time (`0..t_hi`, in `axis` units) against a linear `y`
/// range, its mesh drawn with six y and ten x ticks.
pub struct TimeChart<'c> {
    pub caption: &'c str,
    pub caption_size: u32,
    pub x_area: u32,
    pub y_area: u32,
    pub y_desc: &'c str,
}

impl TimeChart<'_> {
    /// Build the chart on `area` and draw its mesh.
    pub fn build<'a, DB: DrawingBackend>(
        &self,
        area: &'a Area<DB>,
        axis: TimeAxis,
        t_hi: f64,
        (lo, hi): (f64, f64),
    ) -> Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>, ReportError>
    {
        let mut chart = ChartBuilder::on(area)
            .caption(self.caption, font(self.caption_size))
            .margin(12)
            .x_label_area_size(self.x_area)
            .y_label_area_size(self.y_area)
            .build_cartesian_2d(0.0..t_hi, lo..hi)
            .map_err(draw_err)?;
        let (ystep, xstep) = ((hi - lo) / 6.0, t_hi / 10.0);
        chart
            .configure_mesh()
            .x_desc(axis.label)
            .y_desc(self.y_desc)
            .axis_desc_style(font(LABEL))
            .label_style(font(TICK))
            .x_label_formatter(&|v| lin_tick(*v, xstep))
            .y_label_formatter(&|v| lin_tick(*v, ystep))
            .light_line_style(RGBColor(240, 240, 240))
            .draw()
            .map_err(draw_err)?;
        Ok(chart)
    }
}

pub fn draw_band<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    buckets: &[Bucket],
    tau0_s: f64,
    axis: TimeAxis,
    color: RGBColor,
    label: &str,
) -> Result<(), ReportError> {
    if buckets.is_empty() {
        return Ok(());
    }
    let t = |b: &Bucket| bucket_time(b, tau0_s, axis);
    if buckets.iter().any(|b| b.max > b.min) {
        let mut poly: Vec<(f64, f64)> = buckets.iter().map(|b| (t(b), b.max)).collect();
        poly.extend(buckets.iter().rev().map(|b| (t(b), b.min)));
        chart
            .draw_series(std::iter::once(Polygon::new(
                poly,
                color.mix(0.25).filled(),
            )))
            .map_err(draw_err)?;
    }
    let s = chart
        .draw_series(LineSeries::new(
            buckets.iter().map(|b| (t(b), b.mean)),
            color.stroke_width(1),
        ))
        .map_err(draw_err)?;
    if !label.is_empty() {
        let c = color;
        s.label(label.to_string()).legend(move |(x, y)| {
            Rectangle::new([(x, y - 5), (x + 18, y + 5)], c.mix(0.5).filled())
        });
    }
    Ok(())
}

/// A legend box at the top of `area` (outside any plot, so it covers no data):
/// one row per (colour, dashed?, text).
pub fn side_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    rows: &[(RGBColor, LineKind, String)],
) -> Result<(), ReportError> {
    let f = font(TICK);
    let mut y = 12;
    for (c, kind, text) in rows {
        let (x0, x1) = (4, 38);
        match kind {
            LineKind::Solid => {
                area.draw(&PathElement::new(vec![(x0, y), (x1, y)], c.stroke_width(2)))
                    .map_err(draw_err)?;
            }
            LineKind::Dashed => {
                for s in (x0..x1).step_by(10) {
                    area.draw(&PathElement::new(
                        vec![(s, y), ((s + 6).min(x1), y)],
                        c.stroke_width(2),
                    ))
                    .map_err(draw_err)?;
                }
            }
            LineKind::Points => {
                area.draw(&PathElement::new(
                    vec![(x0 + 17, y - 7), (x0 + 17, y + 7)],
                    c.stroke_width(1),
                ))
                .map_err(draw_err)?;
                area.draw(&Circle::new((x0 + 17, y), 4, c.filled()))
                    .map_err(draw_err)?;
            }
            LineKind::Ring => {
                area.draw(&PathElement::new(
                    vec![(x0 + 17, y - 8), (x0 + 17, y + 8)],
                    c.stroke_width(1),
                ))
                .map_err(draw_err)?;
                area.draw(&Circle::new((x0 + 17, y), 5, c.stroke_width(2)))
                    .map_err(draw_err)?;
            }
            LineKind::Band => {
                area.draw(&Rectangle::new(
                    [(x0, y - 6), (x1, y + 6)],
                    c.mix(0.3).filled(),
                ))
                .map_err(draw_err)?;
            }
            LineKind::Tick => {
                area.draw(&PathElement::new(
                    vec![(x0 + 17, y - 7), (x0 + 17, y + 7)],
                    c.stroke_width(2),
                ))
                .map_err(draw_err)?;
            }
            LineKind::Marker => {
                area.draw(&Rectangle::new(
                    [(x0 + 7, y - 8), (x0 + 27, y + 8)],
                    c.mix(0.15).filled(),
                ))
                .map_err(draw_err)?;
                area.draw(&PathElement::new(
                    vec![(x0 + 17, y - 8), (x0 + 17, y + 8)],
                    c.stroke_width(2),
                ))
                .map_err(draw_err)?;
            }
        }
        // a long row wraps at " | "
        for (i, part) in text.split(" | ").enumerate() {
            area.draw(&Text::new(
                part.to_string(),
                (x1 + 8, y - 7 + 17 * i as i32),
                f.clone(),
            ))
            .map_err(draw_err)?;
            if i > 0 {
                y += 17;
            }
        }
        y += 24;
    }
    Ok(())
}

/// How a legend row shows its series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    Solid,
    Dashed,
    Points,
    Ring,
    Band,
    /// A short vertical tick (an event in time).
    Tick,
    /// A vertical line over a light band (an event and its interval).
    Marker,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_read_plainly() {
        assert_eq!(log_tick(1.0), "1");
        assert_eq!(log_tick(100.0), "100");
        assert_eq!(log_tick(0.01), "0.01");
        assert_eq!(log_tick(0.002), "0.002");
        assert_eq!(log_tick(0.0005), "5e-4");
        assert_eq!(log_tick(1e5), "1e5");
        assert_eq!(log_tick(2e-7), "2e-7");
        assert_eq!(log_tick(0.999_999_999_9), "1");
        assert_eq!(log_tick(0.009_999_999_99), "0.01");
        assert_eq!(log_tick(1e-4 * (1.0 - 1e-12)), "1e-4");
        assert_eq!(lin_tick(-0.0, 0.5), "0.0");
        assert_eq!(lin_tick(12.345, 5.0), "12");
        assert_eq!(lin_tick(0.25, 0.05), "0.25");
    }
}
