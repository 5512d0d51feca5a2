//! Figure: the extracted quantization noise and its running integral, with
//! the +/- one-pulse band: the founding paper's check (SEED.md), quantization
//! noise is white in angle, so its integral stays within about one pulse
//! instead of wandering off like a random walk.

use plotters::prelude::*;

use super::collect::Collector;
use super::plot::{self, Area, TimeAxis, draw_err};
use super::{ReportError, fmt_sig};

/// The largest |running integral|, arcsec, if any.
pub fn max_abs_angle(c: &Collector) -> Option<f64> {
    c.series
        .noise_angle_arcsec
        .range()
        .map(|(lo, hi)| lo.abs().max(hi.abs()))
}

/// Draw the two panels on `area`; `pulse_arcsec` gives the band.
pub fn draw<DB: DrawingBackend>(
    area: &Area<DB>,
    c: &Collector,
    pulse_arcsec: Option<f64>,
    u: super::Units,
) -> Result<(), ReportError> {
    crate::font::register()?;
    area.fill(&WHITE).map_err(draw_err)?;
    let tau0 = c.tau0_s();
    let s = &c.series;
    let axis = TimeAxis::for_duration(s.noise_dph.len() as f64 * tau0);
    let t_hi = (s.noise_dph.len().max(2) - 1) as f64 * tau0 / axis.per_unit;
    let (_, h) = area.dim_in_pixel();
    let (top, bottom) = area.split_vertically(h * 2 / 5);

    // the noise rate
    let (lo, hi) = s.noise_dph.range().unwrap_or((-1.0, 1.0));
    let (lo, hi) = plot::padded(lo, hi);
    let mut chart = plot::TimeChart {
        caption: "extracted quantization noise (rate)",
        caption_size: plot::TITLE,
        x_area: 42,
        y_area: 72,
        y_desc: &format!("noise, {}", u.rate),
    }
    .build(&top, axis, t_hi, (lo, hi))?;
    plot::draw_band(
        &mut chart,
        &s.noise_dph.buckets(),
        tau0,
        axis,
        plot::NOISE,
        "",
    )?;

    // its running integral
    let (mut lo, mut hi) = s.noise_angle_arcsec.range().unwrap_or((-1.0, 1.0));
    if let Some(d) = pulse_arcsec {
        lo = lo.min(-1.25 * d);
        hi = hi.max(1.25 * d);
    }
    let (lo, hi) = plot::padded(lo, hi);
    let peak = max_abs_angle(c).unwrap_or(0.0);
    let caption = match pulse_arcsec {
        Some(d) => format!(
            "running integral of the noise: max |angle| {} arcsec = {} pulse (band: \u{b1}1 pulse = \u{b1}{} arcsec)",
            fmt_sig(peak, 3),
            fmt_sig(peak / d, 3),
            fmt_sig(d, 4)
        ),
        None => format!(
            "running integral of the noise: max |{}| {} {} (rate input: no pulse weight)",
            if u == super::Units::GYRO {
                "angle"
            } else {
                "velocity"
            },
            fmt_sig(peak, 3),
            u.angle
        ),
    };
    let mut chart = plot::TimeChart {
        caption: &caption,
        caption_size: plot::LABEL + 2,
        x_area: 48,
        y_area: 72,
        y_desc: &format!("integrated noise, {}", u.angle),
    }
    .build(&bottom, axis, t_hi, (lo, hi))?;
    if let Some(d) = pulse_arcsec {
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, -d), (t_hi, d)],
                plot::CLEAN.mix(0.10).filled(),
            )))
            .map_err(draw_err)?;
        for y in [-d, d] {
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(0.0, y), (t_hi, y)],
                    9,
                    6,
                    plot::CLEAN.stroke_width(2),
                ))
                .map_err(draw_err)?;
        }
    }
    plot::draw_band(
        &mut chart,
        &s.noise_angle_arcsec.buckets(),
        tau0,
        axis,
        plot::NOISE,
        "",
    )?;
    Ok(())
}
