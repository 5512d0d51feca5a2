//! Figure: the rate time series (raw as its mean per pixel column, clean as
//! a min/max band with its mean) and, when the input carries it, the temperature below.

use plotters::prelude::*;

use super::ReportError;
use super::collect::Collector;
use super::plot::{self, Area, LineKind, TimeAxis, draw_err};

/// Draw on `area`.
pub fn draw<DB: DrawingBackend>(area: &Area<DB>, c: &Collector) -> Result<(), ReportError> {
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
    let (head, body) = rate_area.split_vertically(34);
    // the raw rate as its mean per column: its per-sample spread is the
    // quantization noise (the noise figure), which would flatten the rest
    let raw = s.raw_dph.buckets();
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
        y_desc: "rate, deg/h",
    }
    .build(&body, axis, t_hi, (lo, hi))?;
    // the extreme 2 % (the wavelet bank's start-up) is drawn at the axis' edge
    plot::draw_band(
        &mut chart,
        &plot::clamped(&clean, lo, hi),
        tau0,
        axis,
        plot::CLEAN,
        "",
    )?;
    chart
        .draw_series(LineSeries::new(
            raw.iter()
                .map(|b| (plot::bucket_time(b, tau0, axis), b.mean.clamp(lo, hi))),
            plot::RAW.mix(0.8).stroke_width(1),
        ))
        .map_err(draw_err)?;
    // the clean mean on top: the quantization noise removed, it wanders far less
    let clean_c = plot::clamped(&clean, lo, hi);
    chart
        .draw_series(LineSeries::new(
            clean_c
                .iter()
                .map(|b| (plot::bucket_time(b, tau0, axis), b.mean)),
            plot::CLEAN.stroke_width(2),
        ))
        .map_err(draw_err)?;
    // the legend above the plot, in one row
    let legend = head.margin(8, 0, 90, 0);
    let (l1, l2) = legend.split_horizontally(360);
    plot::side_legend(
        &l1,
        &[(
            plot::RAW,
            LineKind::Solid,
            "raw rate, mean per pixel column".into(),
        )],
    )?;
    plot::side_legend(
        &l2,
        &[(
            plot::CLEAN,
            LineKind::Band,
            "clean rate (quantization noise removed): mean, min/max band".into(),
        )],
    )?;

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
