//! Figure: the raw, clean and noise Allan deviations on log-log axes with
//! their confidence bars, the fitted IEEE 952 terms as dashed asymptotes and
//! their total (solid). The legend, with each term's coefficient, sits in
//! its own column right of the plot, so it never covers a curve.

use plotters::prelude::*;

use super::plot::{self, Area, LineKind, draw_err, font};
use super::terms::{self, Asymptote};
use super::{ReportError, Units, fmt_sig};
use crate::allan::AllanPoint;
use crate::pipeline::Analysis;

/// Draw the figure on `area`.
pub fn draw<DB: DrawingBackend>(
    area: &Area<DB>,
    a: &Analysis,
    u: Units,
) -> Result<(), ReportError> {
    crate::font::register()?;
    area.fill(&WHITE).map_err(draw_err)?;
    let (w, _) = area.dim_in_pixel();
    let (left, right) = area.split_horizontally(w.saturating_sub(330));
    let curves: [(&str, &[AllanPoint], RGBColor); 3] = [
        ("raw", &a.allan.raw, plot::RAW),
        ("clean", &a.allan.clean, plot::CLEAN),
        ("noise", &a.allan.noise, plot::NOISE),
    ];
    let (t_lo, t_hi, d_lo, d_hi) = bounds(&curves);
    if !(t_lo < t_hi && d_lo <= d_hi) {
        left.draw(&Text::new(
            "no Allan deviation to plot (record too short?)",
            (40, 40),
            font(plot::LABEL),
        ))
        .map_err(draw_err)?;
        return Ok(());
    }
    let (t_lo, t_hi) = (t_lo / 1.4, t_hi * 1.4);
    let (d_lo, d_hi) = (d_lo / 2.0, d_hi * 2.0);
    let mut chart = ChartBuilder::on(&left)
        .caption(
            "Allan deviation: raw, clean and extracted noise",
            font(plot::TITLE),
        )
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d((t_lo..t_hi).log_scale(), (d_lo..d_hi).log_scale())
        .map_err(draw_err)?;
    chart
        .configure_mesh()
        .x_desc("averaging time \u{3c4}, s")
        .y_desc(format!("Allan deviation, {}", u.rate))
        .axis_desc_style(font(plot::LABEL))
        .label_style(font(plot::TICK))
        .x_label_formatter(&|v| plot::log_tick(*v))
        .y_label_formatter(&|v| plot::log_tick(*v))
        .light_line_style(RGBColor(235, 235, 235))
        .bold_line_style(RGBColor(205, 205, 205))
        .draw()
        .map_err(draw_err)?;

    // the model first, under the data
    let asym = terms::asymptotes(&a.estimates);
    let grid: Vec<f64> = (0..=160)
        .map(|i| t_lo * (t_hi / t_lo).powf(i as f64 / 160.0))
        .collect();
    let total: Vec<(f64, f64)> = grid
        .iter()
        .map(|&t| (t, terms::total_dev(&asym, t)))
        .filter(|p| p.1 >= d_lo && p.1 <= d_hi)
        .collect();
    if total.len() > 1 {
        chart
            .draw_series(LineSeries::new(total, plot::MODEL.stroke_width(3)))
            .map_err(draw_err)?;
    }
    for t in &asym {
        if let Some((a0, a1)) = t.clip((t_lo, t_hi), (d_lo, d_hi)) {
            let c = color_of(t);
            chart
                .draw_series(DashedLineSeries::new(
                    vec![(a0, t.dev(a0)), (a1, t.dev(a1))],
                    9,
                    6,
                    c.stroke_width(2),
                ))
                .map_err(draw_err)?;
        }
    }
    draw_curves(&mut chart, &curves, (d_lo, d_hi))?;

    let rows = legend_rows(&asym, u);
    let legend = right.margin(50, 10, 4, 4);
    plot::side_legend(&legend, &rows)
}

/// The three curves with their interval bars: noise and clean first, the
/// raw curve on top as open rings (it often coincides with one of them).
fn draw_curves<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>,
    curves: &[(&str, &[AllanPoint], RGBColor)],
    (d_lo, d_hi): (f64, f64),
) -> Result<(), ReportError> {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    for (name, pts, c) in curves.iter().rev() {
        let good: Vec<&AllanPoint> = pts.iter().filter(|p| pos(p.tau_s) && pos(p.dev)).collect();
        chart
            .draw_series(
                good.iter()
                    .filter(|p| pos(p.ci_lo) && pos(p.ci_hi))
                    .map(|p| {
                        PathElement::new(
                            vec![(p.tau_s, p.ci_lo.max(d_lo)), (p.tau_s, p.ci_hi.min(d_hi))],
                            c.stroke_width(1),
                        )
                    }),
            )
            .map_err(draw_err)?;
        chart
            .draw_series(LineSeries::new(
                good.iter().map(|p| (p.tau_s, p.dev)),
                c.mix(0.6).stroke_width(1),
            ))
            .map_err(draw_err)?;
        if *name == "raw" {
            chart
                .draw_series(
                    good.iter()
                        .map(|p| Circle::new((p.tau_s, p.dev), 5, c.stroke_width(2))),
                )
                .map_err(draw_err)?;
        } else {
            chart
                .draw_series(
                    good.iter()
                        .map(|p| Circle::new((p.tau_s, p.dev), 3, c.filled())),
                )
                .map_err(draw_err)?;
        }
    }

    Ok(())
}

/// The span of tau and of the deviations (with their intervals) to plot.
fn bounds(curves: &[(&str, &[AllanPoint], RGBColor)]) -> (f64, f64, f64, f64) {
    let pos = |v: f64| v.is_finite() && v > 0.0;
    let pts = curves
        .iter()
        .flat_map(|c| c.1.iter())
        .filter(|p| pos(p.tau_s) && pos(p.dev));
    let (mut t_lo, mut t_hi, mut d_lo, mut d_hi) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for p in pts {
        t_lo = t_lo.min(p.tau_s);
        t_hi = t_hi.max(p.tau_s);
        d_lo = d_lo.min(if pos(p.ci_lo) { p.ci_lo } else { p.dev });
        d_hi = d_hi.max(if pos(p.ci_hi) { p.ci_hi } else { p.dev });
    }
    (t_lo, t_hi, d_lo, d_hi)
}

/// The legend column: the three curves, the total model and each term.
fn legend_rows(asym: &[Asymptote], u: Units) -> Vec<(RGBColor, LineKind, String)> {
    let mut rows = vec![
        (
            plot::RAW,
            LineKind::Ring,
            format!(
                "raw (bars: {} % confidence)",
                fmt_sig(100.0 * crate::allan::DEFAULT_CONFIDENCE, 3)
            ),
        ),
        (
            plot::CLEAN,
            LineKind::Points,
            "clean: quantization noise removed".to_string(),
        ),
        (plot::NOISE, LineKind::Points, "extracted noise".to_string()),
        (
            plot::MODEL,
            LineKind::Solid,
            format!(
                "total IEEE {} model",
                if u == Units::GYRO { "952" } else { "1293" }
            ),
        ),
    ];
    for t in asym {
        let k = t.kind;
        let text = if u == Units::GYRO {
            format!(
                "{}, slope {}: {} | {} = {} {}",
                k.abbrev(),
                k.slope_text(),
                k.formula(),
                k.symbol(),
                fmt_sig(t.coefficient, 3),
                k.unit()
            )
        } else {
            let (_, sym, unit, f) = k.accel();
            format!(
                "{sym}, slope {}: {sym} = {} {unit}",
                k.slope_text(),
                fmt_sig(t.coefficient * f, 3)
            )
        };
        rows.push((color_of(t), LineKind::Dashed, text));
    }
    if asym.is_empty() {
        rows.push((
            plot::MODEL,
            LineKind::Solid,
            "no term estimated".to_string(),
        ));
    }
    rows
}

fn color_of(t: &Asymptote) -> RGBColor {
    let i = terms::Kind::ALL
        .iter()
        .position(|k| *k == t.kind)
        .unwrap_or(0);
    plot::TERM_COLORS[i]
}
