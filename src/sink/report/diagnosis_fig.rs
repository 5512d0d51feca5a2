//! The diagnosis report as an SVG figure (plotters' SVG backend; text is
//! emitted as SVG `<text>`, so no font is rasterised; plotters measures it
//! with the bundled font, [`crate::font`]).
//!
//! On top, the verdict in words, chi2/dof before and after, and the findings
//! (each added term and changed parameter with its 95 % interval). Below,
//! four log-log panels: wavelet deviations per level, modified Allan
//! deviation, the rate spectrum in quarter-octave bands and the raw Allan
//! deviation. Each shows the recording (black), the model's 95 % Monte-Carlo
//! band (blue) and, when the diagnosis changed the model, the updated model's
//! band (green); the mismatch regions are shaded red on every panel and
//! labelled with their largest z, and the spectrum panel marks the frequency
//! of each finding (a line's frequency, a Gauss-Markov or filter corner).
//! Each panel's legend sits above its plotting area, outside the data.

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::diagnose::compare::{Family, Point};
use crate::diagnose::findings::fmt_g;
use crate::diagnose::{Diagnosis, DiagnosisReport, Verdict};

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
const MARK: RGBColor = RGBColor(150, 60, 170);

/// Figure width, px.
const WIDTH: u32 = 1200;
/// Height of the four panels, px.
const PANELS_H: u32 = 900;
/// Height of one line of header text, px.
const LINE_H: u32 = 19;
/// Findings listed on the figure at most (the JSON has them all).
const MAX_FINDINGS: usize = 8;

/// Render the report of `diag` as an SVG document (`title` on top).
pub fn render(diag: &Diagnosis, title: &str) -> Result<String, SvgError> {
    // plotters measures text with the fonts registered with it (ab_glyph backend)
    crate::font::register().map_err(err)?;
    let lines = header_lines(diag);
    let head_h = 40 + LINE_H * lines.len() as u32 + 10;
    let mut out = String::new();
    {
        let root =
            SVGBackend::with_string(&mut out, (WIDTH, head_h + PANELS_H)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (head, body) = root.split_vertically(head_h);
        head.draw(&Text::new(
            title.to_string(),
            (20, 12),
            ("sans-serif", 22).into_font(),
        ))
        .map_err(err)?;
        for (i, (text, bold)) in lines.iter().enumerate() {
            let size = if *bold { 16 } else { 14 };
            let y = 40 + LINE_H as i32 * i as i32;
            head.draw(&Text::new(
                text.clone(),
                (20, y),
                ("sans-serif", size).into_font(),
            ))
            .map_err(err)?;
        }
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
            panel(area, diag, fam, name, (xl, yl))?;
        }
        root.present().map_err(err)?;
    }
    Ok(out)
}

/// The header below the title: the verdict in words (bold), the fit, and
/// the findings, one per line.
fn header_lines(diag: &Diagnosis) -> Vec<(String, bool)> {
    let r = &diag.report;
    let mut v = vec![(verdict_sentence(diag), true)];
    let fit = if r.parameter_changes.is_empty() && r.added_terms.is_empty() {
        format!(
            "Fit to the model's Monte-Carlo runs: chi2/dof {:.2}.",
            r.fit_before.chi2_per_dof
        )
    } else {
        format!(
            "Fit to the Monte-Carlo runs: chi2/dof {:.2} with the model, {:.2} with the updated model.",
            r.fit_before.chi2_per_dof, r.fit_after.chi2_per_dof
        )
    };
    v.push((fit, false));
    let found = finding_lines(r);
    let more = found.len().saturating_sub(MAX_FINDINGS);
    v.extend(found.into_iter().take(MAX_FINDINGS).map(|s| (s, false)));
    if more > 0 {
        v.push((format!("... and {more} more (see the JSON)"), false));
    }
    v
}

/// The verdict as a sentence: where the recording leaves the model, and
/// whether the raw Allan deviation alone would have shown it.
fn verdict_sentence(diag: &Diagnosis) -> String {
    let r = &diag.report;
    let raw = format!("raw Allan deviation max |z| {:.2}", diag.raw_allan_max_z);
    match r.verdict {
        Verdict::Consistent => format!(
            "Verdict: consistent. The recording is what the model predicts (max |z| {:.2}, threshold {:.2}; {raw}).",
            diag.max_abs_z, diag.z_crit
        ),
        Verdict::Mismatch if r.mismatch_regions.is_empty() => format!(
            "Verdict: mismatch. The recording departs from the model (lines or slopes, not a tau range; \
             threshold {:.2}; {raw}).",
            diag.z_crit
        ),
        Verdict::Mismatch => {
            let spans: Vec<String> = r
                .mismatch_regions
                .iter()
                .map(|g| {
                    if g.tau_max_s > g.tau_min_s * 1.0001 {
                        format!(
                            "{}-{} s (z {:.1})",
                            fmt_g(g.tau_min_s),
                            fmt_g(g.tau_max_s),
                            g.max_z
                        )
                    } else {
                        format!("{} s (z {:.1})", fmt_g(g.tau_min_s), g.max_z)
                    }
                })
                .collect();
            format!(
                "Verdict: mismatch. The recording departs from the model at tau {} (threshold {:.2}; {raw}).",
                spans.join(", "),
                diag.z_crit
            )
        }
    }
}

/// Each added term and changed parameter in a line.
fn finding_lines(r: &DiagnosisReport) -> Vec<String> {
    let ci = |c: [f64; 2]| format!("(95 % {}..{})", fmt_g(c[0]), fmt_g(c[1]));
    let mut v = Vec::new();
    for a in &r.added_terms {
        let params: Vec<String> = a
            .params
            .iter()
            .map(|(k, val)| match a.ci95.get(k) {
                Some(c) => format!("{k} {} {}", fmt_g(*val), ci(*c)),
                None => format!("{k} {}", fmt_g(*val)),
            })
            .collect();
        v.push(format!("Added: {}: {}", a.term, params.join(", ")));
    }
    for c in &r.parameter_changes {
        v.push(format!(
            "Changed: {}: {} -> {} {}",
            c.term,
            fmt_g(c.model),
            fmt_g(c.fitted),
            ci(c.ci95)
        ));
    }
    v
}

/// Frequencies the findings point at (Hz), with a label: a sinusoid's
/// frequency, a Gauss-Markov term's corner `1/(2 pi Tc)`, a telegraph's
/// `1/(pi dwell)`, a readout filter's -3 dB corner.
fn markers(r: &DiagnosisReport) -> Vec<(f64, String)> {
    let mut v = Vec::new();
    for a in &r.added_terms {
        let p = |k: &str| a.params.get(k).copied().filter(|x| *x > 0.0);
        let m = match a.term.as_str() {
            "sinusoid" => p("period_s").map(|t| (1.0 / t, format!("sinusoid {} s", fmt_g(t)))),
            "gauss_markov" => p("tau_c_s").map(|t| {
                (
                    1.0 / (2.0 * std::f64::consts::PI * t),
                    "GM corner".to_string(),
                )
            }),
            "random_telegraph" => {
                p("mean_dwell_s").map(|t| (1.0 / (std::f64::consts::PI * t), "RTN corner".into()))
            }
            "readout_filter" => p("corner_hz").map(|f| (f, "filter -3 dB".into())),
            _ => None,
        };
        v.extend(m);
    }
    v
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

/// The plotted ranges of x and y over the points, their observations and bands.
fn extent(before: &[&Point], after: &[&Point]) -> ((f64, f64), (f64, f64)) {
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
    (range(&xs), range(&ys))
}

/// One panel: caption, a legend strip, and the chart below them.
fn panel(
    area: &DrawingArea<SVGBackend, Shift>,
    diag: &Diagnosis,
    fam: Family,
    name: &str,
    (xlabel, ylabel): (&str, &str),
) -> Result<(), SvgError> {
    let before: Vec<&Point> = diag.before.iter().filter(|p| p.family == fam).collect();
    let after: Vec<&Point> = diag.after.iter().filter(|p| p.family == fam).collect();
    if before.is_empty() {
        return Ok(());
    }
    let (top, chart_area) = area.split_vertically(50);
    let (w, _) = top.dim_in_pixel();
    top.draw(&Text::new(
        name.to_string(),
        (w as i32 / 2 - 6 * name.len() as i32 / 2, 8),
        ("sans-serif", 16).into_font(),
    ))
    .map_err(err)?;
    legend(
        &top,
        !after.is_empty(),
        !diag.report.mismatch_regions.is_empty(),
    )?;
    let ((x0, x1), (y0, y1)) = extent(&before, &after);
    let mut chart = ChartBuilder::on(&chart_area)
        .margin(12)
        .margin_top(4)
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
    // mismatch regions, labelled with their largest z
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
            let label = format!("z {:.1}", g.max_z);
            chart
                .draw_series(std::iter::once(Text::new(
                    label,
                    (a, y1 / 1.15),
                    ("sans-serif", 12).into_font().color(&SHADE),
                )))
                .map_err(err)?;
        }
    }
    if fam == Family::Spectrum {
        for (f, label) in markers(&diag.report)
            .into_iter()
            .filter(|(f, _)| *f > x0 && *f < x1)
        {
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(f, y0), (f, y1)],
                    MARK.stroke_width(1),
                )))
                .map_err(err)?;
            chart
                .draw_series(std::iter::once(Text::new(
                    label,
                    (f * 1.05, y0 * 1.6),
                    ("sans-serif", 12).into_font().color(&MARK),
                )))
                .map_err(err)?;
        }
    }
    for (pts, color) in [(&before, OLD), (&after, NEW)] {
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
            .map_err(err)?;
    }
    chart
        .draw_series(LineSeries::new(
            before.iter().map(|p| xy(p, p.obs)),
            BLACK.stroke_width(1),
        ))
        .map_err(err)?;
    chart
        .draw_series(
            before
                .iter()
                .map(|p| Circle::new(xy(p, p.obs), 3, BLACK.filled())),
        )
        .map_err(err)?;
    Ok(())
}

/// The legend strip above a panel's plotting area: recording, model band,
/// updated model band (when there is one), mismatch shading (when there is any).
fn legend(
    area: &DrawingArea<SVGBackend, Shift>,
    updated: bool,
    shaded: bool,
) -> Result<(), SvgError> {
    let font = ("sans-serif", 12).into_font();
    let y = 36;
    let mut x = 80;
    let mut entry =
        |sym: &dyn Fn(i32) -> Result<(), SvgError>, text: &str| -> Result<(), SvgError> {
            sym(x)?;
            area.draw(&Text::new(text.to_string(), (x + 24, y - 6), font.clone()))
                .map_err(err)?;
            x += 24 + 6 * text.len() as i32 + 20;
            Ok(())
        };
    let line_band = |c: RGBColor| {
        move |x: i32| -> Result<(), SvgError> {
            area.draw(&Rectangle::new(
                [(x, y - 6), (x + 18, y + 6)],
                c.mix(0.25).filled(),
            ))
            .map_err(err)?;
            area.draw(&PathElement::new(
                vec![(x, y), (x + 18, y)],
                c.stroke_width(2),
            ))
            .map_err(err)
        }
    };
    entry(
        &|x| {
            area.draw(&PathElement::new(
                vec![(x, y), (x + 18, y)],
                BLACK.stroke_width(1),
            ))
            .map_err(err)?;
            area.draw(&Circle::new((x + 9, y), 4, BLACK.filled()))
                .map_err(err)
        },
        "recording",
    )?;
    entry(&line_band(OLD), "model (95 % MC band)")?;
    if updated {
        entry(&line_band(NEW), "updated model")?;
    }
    if shaded {
        entry(
            &|x| {
                area.draw(&Rectangle::new(
                    [(x, y - 6), (x + 18, y + 6)],
                    SHADE.mix(0.15).filled(),
                ))
                .map_err(err)
            },
            "mismatch",
        )?;
    }
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
