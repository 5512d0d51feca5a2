//! The diagnosis report as an SVG figure (plotters' SVG backend; text is
//! emitted as SVG `<text>`, so no font is rasterised; plotters measures it
//! with the bundled font, [`crate::font`]).
//!
//! Four log-log panels: wavelet deviations per level, modified Allan
//! deviation, the rate spectrum in quarter-octave bands and the raw Allan
//! deviation. Each shows the recording (black), the model's 95 % Monte-Carlo
//! band (blue) and, when the diagnosis changed the model, the updated model's
//! band (green); the mismatch regions are shaded red on every panel.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::Diagnosis;
use super::compare::{Family, Point};

/// Errors of the SVG writer.
#[derive(Debug, thiserror::Error)]
#[error("cannot draw the report: {0}")]
pub struct SvgError(String);

fn err<E: std::fmt::Display>(e: E) -> SvgError {
    SvgError(e.to_string())
}

const OLD: RGBColor = RGBColor(40, 90, 200);
const NEW: RGBColor = RGBColor(20, 150, 60);
const SHADE: RGBColor = RGBColor(230, 60, 60);

/// Render the report of `diag` as an SVG document (`title` on top).
pub fn render(diag: &Diagnosis, title: &str) -> Result<String, SvgError> {
    // plotters measures text with the fonts registered with it (ab_glyph backend)
    crate::font::register().map_err(err)?;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (1200, 900)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (head, body) = root.split_vertically(60);
        head.draw(&Text::new(
            title.to_string(),
            (20, 12),
            ("sans-serif", 22).into_font(),
        ))
        .map_err(err)?;
        let r = &diag.report;
        let sub = format!(
            "verdict: {:?}   chi2/dof before {:.2}, after {:.2}   |z| threshold {:.2}   raw-Allan max |z| {:.2}",
            r.verdict,
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof,
            diag.z_crit,
            diag.raw_allan_max_z
        );
        head.draw(&Text::new(sub, (20, 38), ("sans-serif", 15).into_font()))
            .map_err(err)?;
        let panels = body.split_evenly((2, 2));
        let specs = [
            (
                Family::Wavelet,
                "sym8 wavelet deviation per level",
                "scale tau, s",
                "deg/h",
            ),
            (Family::Mdev, "modified Allan deviation", "tau, s", "deg/h"),
            (
                Family::Spectrum,
                "rate PSD, quarter-octave bands",
                "frequency, Hz",
                "(deg/h)^2/Hz",
            ),
            (
                Family::RawAllan,
                "raw Allan deviation (reported only)",
                "tau, s",
                "deg/h",
            ),
        ];
        for (area, (fam, name, xl, yl)) in panels.iter().zip(specs) {
            panel(area, diag, fam, name, xl, yl)?;
        }
        root.present().map_err(err)?;
    }
    Ok(out)
}

/// x coordinate and plotted value (deviation, or PSD for the spectrum).
fn xy(p: &Point, v: f64) -> (f64, f64) {
    let x = match p.family {
        Family::Spectrum => 0.5 / (p.tau_lo_s * p.tau_hi_s).sqrt(),
        _ => (p.tau_lo_s * p.tau_hi_s).sqrt(),
    };
    let y = match p.family {
        Family::Spectrum => v,
        _ => v.max(0.0).sqrt(),
    };
    (x, y)
}

fn panel(
    area: &DrawingArea<SVGBackend, Shift>,
    diag: &Diagnosis,
    fam: Family,
    name: &str,
    xlabel: &str,
    ylabel: &str,
) -> Result<(), SvgError> {
    let before: Vec<&Point> = diag.before.iter().filter(|p| p.family == fam).collect();
    let after: Vec<&Point> = diag.after.iter().filter(|p| p.family == fam).collect();
    if before.is_empty() {
        return Ok(());
    }
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for p in before.iter().chain(after.iter()) {
        let (lo, hi) = p.band95();
        for v in [p.obs, lo, hi] {
            let (x, y) = xy(p, v);
            xs.push(x);
            if y > 0.0 && y.is_finite() {
                ys.push(y);
            }
        }
    }
    let (x0, x1) = range(&xs);
    let (y0, y1) = range(&ys);
    let mut chart = ChartBuilder::on(area)
        .caption(name, ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(64)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(xlabel)
        .y_desc(ylabel)
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .light_line_style(WHITE)
        .draw()
        .map_err(err)?;
    // mismatch regions
    for g in &diag.report.mismatch_regions {
        let (a, b) = match fam {
            Family::Spectrum => (0.5 / g.tau_max_s, 0.5 / g.tau_min_s),
            _ => (g.tau_min_s, g.tau_max_s),
        };
        let (a, b) = (a.max(x0), b.min(x1));
        if b > a {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y0), (b, y1)],
                    SHADE.mix(0.15).filled(),
                )))
                .map_err(err)?;
        }
    }
    for (pts, color, label) in [
        (&before, OLD, "model (95 % MC band)"),
        (&after, NEW, "updated model"),
    ] {
        if pts.is_empty() {
            continue;
        }
        let mut poly: Vec<(f64, f64)> = pts.iter().map(|p| xy(p, p.band95().1)).collect();
        poly.extend(pts.iter().rev().map(|p| xy(p, p.band95().0)));
        chart
            .draw_series(std::iter::once(Polygon::new(
                poly,
                color.mix(0.25).filled(),
            )))
            .map_err(err)?;
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| xy(p, p.model_mean)),
                color.stroke_width(2),
            ))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    chart
        .draw_series(LineSeries::new(
            before.iter().map(|p| xy(p, p.obs)),
            BLACK.stroke_width(1),
        ))
        .map_err(err)?
        .label("recording")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK));
    chart
        .draw_series(
            before
                .iter()
                .map(|p| Circle::new(xy(p, p.obs), 3, BLACK.filled())),
        )
        .map_err(err)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    Ok(())
}

fn range(v: &[f64]) -> (f64, f64) {
    let lo = v
        .iter()
        .cloned()
        .filter(|x| *x > 0.0 && x.is_finite())
        .fold(f64::INFINITY, f64::min);
    let hi = v
        .iter()
        .cloned()
        .filter(|x| *x > 0.0 && x.is_finite())
        .fold(0.0, f64::max);
    if !(lo.is_finite() && hi > 0.0) {
        return (1e-3, 1.0);
    }
    let hi = if hi > lo { hi } else { lo * 10.0 };
    (lo / 1.5, hi * 1.5)
}
