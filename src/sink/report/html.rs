//! The page: one HTML document with inline CSS and inline SVG figures. It
//! loads nothing (its Content-Security-Policy forbids every outside source)
//! and runs no script.

use std::fmt::Write;

use super::markup::{esc, inline_svg};
use super::{
    Report, ReportError, allan_fig, davar_fig, diagnosis, fmt_sig, noise_fig, rate_fig, svg,
};
use crate::model::estimate::Coefficient;
use crate::pipeline::Analysis;

const STYLE: &str = "
body{font-family:sans-serif;margin:24px auto;max-width:1200px;color:#222;line-height:1.4;padding:0 12px}
h1{font-size:1.5em;margin-bottom:4px}
h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:3px;margin-top:28px}
h3{font-size:1.02em}
table{border-collapse:collapse;margin:8px 0}
td,th{border:1px solid #ccc;padding:3px 9px;text-align:left;vertical-align:top}
th{background:#f3f3f3}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
figure{margin:10px 0}
figure svg{width:100%;height:auto;display:block}
figcaption{font-size:.92em;color:#444;margin-top:4px}
.verdict{padding:6px 10px;border-radius:3px}
.ok{background:#e6f4ea}
.bad{background:#fdecea}
.muted{color:#666}
";

/// One axis of a multi-axis input, as the index page lists it.
#[derive(Debug, Clone, Copy)]
pub struct AxisPage<'a> {
    pub label: &'a str,
    pub units: super::Units,
    pub analysis: &'a Analysis,
    /// Its own report, relative to the index (`gyro_x/index.html`).
    pub link: &'a str,
}

/// The index of a multi-axis report: each axis's coefficients and fit, and a
/// link to its own page (figures, data quality).
pub fn index_page(input: &str, axes: &[AxisPage<'_>]) -> String {
    let mut h = String::new();
    let name = std::path::Path::new(input)
        .file_name()
        .map_or(input.to_string(), |f| f.to_string_lossy().into_owned());
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>sagnac report: {0}</title><style>{STYLE}</style></head><body>\n\
         <h1>IMU bench report: {0}</h1><p class=\"muted\">Written by sagnac {1} (<code>sagnac report</code>): \
         {2} axes of {0}, each analysed as it would be alone; each axis's page has its figures and data-quality \
         findings.</p>\n",
        esc(&name),
        env!("CARGO_PKG_VERSION"),
        axes.len()
    );
    for a in axes {
        let _ = write!(
            h,
            "<h2 id=\"{0}\"><a href=\"{1}\">{0}</a> ({2})</h2>",
            esc(a.label),
            esc(a.link),
            a.units.rate_word
        );
        coefficients(&mut h, a.analysis, a.units);
        if let Some(dq) = &a.analysis.data_quality {
            for l in dq.lines() {
                let _ = write!(h, "<p class=\"muted\">{}</p>", esc(&a.units.text(&l)));
            }
        }
    }
    h.push_str("</body></html>\n");
    h
}

/// The whole page.
pub fn page(r: &Report<'_>) -> Result<String, ReportError> {
    let a = r.analysis;
    let m = r.meta;
    let mut h = String::new();
    let name = std::path::Path::new(&m.input)
        .file_name()
        .map_or(m.input.clone(), |f| f.to_string_lossy().into_owned());
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>sagnac report: {}</title><style>{STYLE}</style></head><body>\n",
        esc(&name)
    );
    let _ = write!(h, "<h1>Gyro bench report: {}</h1>", esc(&name));
    let _ = write!(
        h,
        "<p class=\"muted\">Written by sagnac {} (<code>sagnac report</code>): IEEE 952 noise coefficients, \
         wavelet (sym8) quantization-noise removal and Allan deviations of a static recording.</p>\n",
        env!("CARGO_PKG_VERSION")
    );
    let u = r.meta.units;
    metadata(&mut h, r);
    coefficients(&mut h, a, u);
    quality_section(&mut h, a.data_quality.as_ref(), u);
    if let Some(v) = r.spec {
        spec_section(&mut h, v);
    }
    let allan = svg(super::ALLAN_SIZE, |area| allan_fig::draw(area, a, u))?;
    let terms_in = if u == super::Units::GYRO {
        "with Q in arcsec, N in deg/\u{221a}h, B in deg/h, K in deg/h/\u{221a}h, R in deg/h\u{b2}, \u{3c4} in s, \
         deviations in deg/h"
    } else {
        "here the accelerometer's IEEE 1293 terms in their places (velocity quantization, velocity random \
         walk, bias instability, acceleration random walk and ramp; values and units in the legend), \u{3c4} in s, \
         deviations in m/s\u{b2}"
    };
    let _ = write!(
        h,
        "<section id=\"allan\"><h2>Allan deviation</h2><figure>{}<figcaption>Overlapping Allan deviation of the raw \
         rate, of the clean rate (quantization noise removed by the wavelet bank) and of the extracted noise, \
         with their {} % confidence intervals (bars). Dashed: the IEEE 952 term of each coefficient found \
         (QN \u{221a}3\u{b7}Q/\u{3c4}, ARW N/\u{221a}\u{3c4}, BI 0.664\u{b7}B, RRW K\u{b7}\u{221a}(\u{3c4}/3), \
         RR R\u{b7}\u{3c4}/\u{221a}2, {terms_in}); grey: their total, the square root of the summed \
         variances.</figcaption></figure></section>\n",
        inline_svg(&allan),
        fmt_sig(100.0 * crate::allan::DEFAULT_CONFIDENCE, 3)
    );
    let noise = svg(super::NOISE_SIZE, |area| {
        noise_fig::draw(area, r.series, m.pulse_arcsec, u)
    })?;
    let check = match (noise_fig::max_abs_angle(r.series), m.pulse_arcsec) {
        (Some(p), Some(d)) => format!(
            " Here the integral stays within {} pulse{} of zero ({} arcsec at most).",
            fmt_sig(p / d, 3),
            if p / d > 1.0 { "s" } else { "" },
            fmt_sig(p, 3)
        ),
        _ => String::new(),
    };
    let _ = write!(
        h,
        "<section id=\"noise\"><h2>Extracted noise and its integral</h2><figure>{}<figcaption>The quantization \
         noise the wavelet bank separated from the rate (top) and its running integral, an angle (bottom). \
         Quantization noise is white in angle, so its integral stays bounded, within about one pulse \
         (shaded band), instead of wandering like a random walk: the founding paper's check of the \
         separation.{check} Each series is drawn as its minimum-maximum band per pixel column and its \
         mean.</figcaption></figure></section>\n",
        inline_svg(&noise)
    );
    rate_section(&mut h, r)?;
    davar_section(&mut h, r)?;
    if let Some(d) = &r.diagnosis {
        h.push_str(&diagnosis::section(d)?);
        h.push('\n');
    }
    h.push_str("</body></html>\n");
    Ok(h)
}

/// The rate figure, with what the data-quality stage handled marked on it.
fn rate_section(h: &mut String, r: &Report<'_>) -> Result<(), ReportError> {
    let dq = r.analysis.data_quality.as_ref();
    let rate = svg(super::RATE_SIZE, |area| {
        rate_fig::draw(area, r.series, dq, r.meta.units)
    })?;
    let temp = r.series.temperature().is_some();
    let marked = if dq.is_some_and(|d| d.handled_anything()) {
        " Marked on the rate: what the data-quality stage handled (excluded outliers as ticks along the \
         top, bias steps as lines over their 95 % interval, the fitted warm-up over the raw rate)."
    } else {
        ""
    };
    let _ = write!(
        h,
        "<section id=\"rate\"><h2>Rate{}</h2><figure>{}<figcaption>The rate over the recording: the raw rate \
         as its mean per pixel column (its sample-to-sample spread is the quantization noise above), the clean \
         rate as minimum-maximum band per pixel column and mean (the axis leaves out the most extreme 2 % of \
         the columns, such as the wavelet bank's start-up, drawn at its edge){}.{marked}</figcaption></figure></section>\n",
        if temp { " and temperature" } else { "" },
        inline_svg(&rate),
        if temp {
            "; below, the temperature the frames carry"
        } else {
            "; the input has no temperature"
        }
    );
    Ok(())
}

/// The dynamic Allan deviation's heat map, or one line saying why there is none.
fn davar_section(h: &mut String, r: &Report<'_>) -> Result<(), ReportError> {
    h.push_str("<section id=\"davar\"><h2>Dynamic Allan deviation</h2>");
    match davar_fig::drawable(r.davar) {
        Ok(m) => {
            let fig = svg(super::DAVAR_SIZE, |area| {
                davar_fig::draw(area, m, r.analysis.duration_s, r.meta.units)
            })?;
            let _ = write!(
                h,
                "<figure>{}<figcaption>The Allan deviation of each {} s window of the record (columns) at \
                 octave averaging times (rows), coloured by its logarithm: a stationary noise keeps each \
                 row one colour, and a warm-up, a step or a bad hour shows as a change along time. Glitches \
                 are excluded, nothing else is handled. Blank cells have no term, or a deviation of zero (a pulse \
                 counter's whole pulses can cancel exactly); a cell at an averaging time near the window's \
                 length or beyond rests on one or two terms and scatters by a factor of a \
                 few.</figcaption></figure>",
                inline_svg(&fig),
                davar_fig::window_text(m.window_s)
            );
        }
        Err(why) => {
            let _ = write!(h, "<p class=\"muted\">{}.</p>", esc(&why));
        }
    }
    h.push_str("</section>\n");
    Ok(())
}

/// What the data-quality stage found and did, one line per finding, and
/// the stationarity test of what remains.
fn quality_section(h: &mut String, dq: Option<&crate::quality::DataQuality>, u: super::Units) {
    h.push_str("<section id=\"quality\"><h2>Data quality</h2>");
    let Some(dq) = dq else {
        h.push_str(
            "<p class=\"muted\">data-quality stage off (--raw-statistics): the estimates are of the \
             record as it is.</p></section>\n",
        );
        return;
    };
    h.push_str(
        "<p>Before the final estimates the record is searched for glitches, a warm-up, bias steps and a \
         thermal response; what is found is excluded or modelled, and the estimates above are of the \
         handled record.</p>",
    );
    let lines = dq.lines();
    if lines.is_empty() {
        h.push_str("<p>Findings: nothing found.</p>");
    } else {
        h.push_str("<ul>");
        for l in &lines {
            let _ = write!(h, "<li>{}</li>", esc(&u.text(l)));
        }
        h.push_str("</ul>");
    }
    match &dq.stationary {
        Some(s) => {
            let _ = write!(
                h,
                "<p class=\"verdict {}\">Stationarity of what remains: {} (p = {}; {}).</p>",
                if s.ok { "ok" } else { "bad" },
                if s.ok {
                    "ok, the windows share one noise"
                } else {
                    "NOT stationary, the noise changes over the record"
                },
                esc(&fmt_sig(s.p_value, 3)),
                esc(&s.test)
            );
        }
        None => h.push_str(
            "<p class=\"muted\">Stationarity: not tested (fewer than 8 full windows, or no averaging time with enough \
             terms in every window).</p>",
        ),
    }
    h.push_str("</section>\n");
}

/// The acceptance test: overall verdict and one row per coefficient.
fn spec_section(h: &mut String, v: &crate::model::spec::SpecReport) {
    let _ = write!(
        h,
        "<section id=\"spec\"><h2>Acceptance test: {}</h2><p>Each verdict holds at {} % confidence. \
         A coefficient passes when its upper bound is below the limit, fails when its lower bound is above \
         it, and is undecided otherwise.</p><table><tr><th>coefficient</th><th>limit</th><th>estimate</th>\
         <th>deciding bound</th><th>verdict</th><th>why undecided</th></tr>",
        esc(v.verdict.as_str()),
        fmt_sig(100.0 * v.confidence, 3)
    );
    let num = |x: Option<f64>| x.map_or("-".to_string(), |x| fmt_sig(x, 4));
    for (name, c) in &v.coefficients {
        let _ = write!(
            h,
            "<tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(name),
            fmt_sig(c.limit, 4),
            num(c.estimate),
            num(c.bound),
            esc(c.verdict.as_str()),
            esc(c.reason.as_deref().unwrap_or(""))
        );
    }
    h.push_str("</table></section>\n");
}

fn row(h: &mut String, k: &str, v: &str) {
    let _ = write!(h, "<tr><th>{}</th><td>{}</td></tr>", esc(k), esc(v));
}

fn metadata(h: &mut String, r: &Report<'_>) {
    let m = r.meta;
    let a = r.analysis;
    h.push_str("<section id=\"recording\"><h2>Recording</h2><table>");
    row(h, "input", &m.input);
    row(h, "format", &m.format);
    row(h, "samples", &a.samples.to_string());
    row(
        h,
        "duration",
        &format!(
            "{} s ({} h)",
            a.duration_s,
            fmt_sig(a.duration_s / 3600.0, 3)
        ),
    );
    row(
        h,
        "sample rate",
        &format!("{} Hz ({})", m.sample_rate_hz, m.origin),
    );
    match m.pulse_arcsec {
        Some(d) => row(h, "pulse weight", &format!("{d} arcsec ({})", m.origin)),
        None => row(h, "pulse weight", "none: rate input"),
    }
    match m.gaps {
        Some((g, lost)) => row(
            h,
            "gaps",
            &format!("{g} gaps, {lost} samples lost (filled, the angle kept)"),
        ),
        None => row(h, "gaps", "not recorded by this format"),
    }
    if let Some(s) = &m.frame_stats {
        row(
            h,
            "frames",
            &format!(
                "{} decoded; {} CRC errors, {} false syncs, {} bytes skipped, {} resyncs; {} duplicate, \
                 {} out-of-sequence frames dropped",
                s.frames_decoded,
                s.crc_errors,
                s.false_syncs,
                s.bytes_skipped,
                s.resyncs,
                s.duplicates,
                s.out_of_sequence
            ),
        );
    }
    for n in &m.notes {
        row(h, "note", n);
    }
    h.push_str("</table></section>\n");
}

fn coefficients(h: &mut String, a: &Analysis, u: super::Units) {
    let e = &a.estimates;
    h.push_str("<section id=\"coefficients\"><h2>Noise coefficients</h2>");
    let (class, verdict) = if a.fit.ok {
        ("ok", "the noise model describes the recording".to_string())
    } else {
        (
            "bad",
            "the noise model does NOT describe this recording: the intervals are widened by \
             \u{221a}(\u{3c7}\u{b2}/dof); run <code>sagnac diagnose</code> (or this report with --model)"
                .to_string(),
        )
    };
    let _ = write!(
        h,
        "<p class=\"verdict {class}\">Fit: {verdict} (\u{3c7}\u{b2}/dof {} on {} degrees of freedom, {} observations; \
         <code>fit.ok = {}</code>).</p>",
        fmt_sig(a.fit.chi2_per_dof, 3),
        if a.fit.dof.fract() == 0.0 {
            format!("{}", a.fit.dof)
        } else {
            fmt_sig(a.fit.dof, 4)
        },
        a.fit.observations,
        a.fit.ok
    );
    h.push_str("<table><tr><th>term</th><th>coefficient</th><th>value</th><th>95 % interval</th><th>unit</th></tr>");
    let coefs = [
        &e.quantization_arcsec,
        &e.arw_dpsh,
        &e.bias_instability_dph,
        &e.rrw_dphsh,
        &e.rate_ramp_dphh,
    ];
    for (k, c) in super::terms::Kind::ALL.into_iter().zip(coefs) {
        let (name, sym, unit, c) = if u == super::Units::GYRO {
            (k.name(), k.symbol(), k.unit(), *c)
        } else {
            let (name, sym, unit, f) = k.accel();
            (name, sym, unit, c.scaled(f))
        };
        let (v, ci) = coef_cells(&c);
        let _ = write!(
            h,
            "<tr><td>{name}</td><td>{sym}</td><td class=\"num\">{v}</td><td class=\"num\">{ci}</td><td>{unit}</td></tr>"
        );
    }
    h.push_str("</table>");
    match &a.readout_filter {
        Some(f) => {
            let _ = write!(
                h,
                "<p>Readout filter found: {}{}, corner {} Hz (95 %: {} to {} Hz), delay {} s.</p>",
                esc(&f.kind.name().replace('_', " ")),
                f.length.map_or(String::new(), |l| format!(" of {l} samples")),
                fmt_sig(f.corner_hz, 4),
                fmt_sig(f.ci95[0], 4),
                fmt_sig(f.ci95[1], 4),
                fmt_sig(f.delay_s, 4)
            );
        }
        None => h.push_str("<p>Readout filter: none found (the short-\u{3c4} Allan deviation shows no smoothing).</p>"),
    }
    h.push_str("</section>\n");
}

/// The value and interval cells of a coefficient.
fn coef_cells(c: &Coefficient) -> (String, String) {
    match (c.value, c.ci95, c.upper95) {
        (Some(v), Some([lo, hi]), _) => (
            fmt_sig(v, 4),
            format!("{} to {}", fmt_sig(lo, 3), fmt_sig(hi, 3)),
        ),
        (Some(v), None, _) => (fmt_sig(v, 4), "\u{2013}".into()),
        (None, _, Some(u)) => (
            "not found".into(),
            format!("&lt; {} (upper bound)", fmt_sig(u, 3)),
        ),
        _ => ("n/a".into(), "\u{2013}".into()),
    }
}
