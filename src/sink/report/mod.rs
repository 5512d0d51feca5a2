//! `sagnac report`: one self-contained HTML page (inline SVG figures, inline
//! CSS, no script, font or request from outside) and the PNG figures
//! (plotters' bitmap backend, text in the bundled font, [`crate::font`]):
//! `allan.png`, `noise_integral.png` and, when the record has a map to
//! draw, `davar.png`.
//!
//! The page holds, in order: the recording's metadata; the coefficient table
//! with 95 % intervals, the fit verdict and the readout filter; the
//! data-quality findings ([`crate::quality`]: one line per finding and the
//! stationarity test, or a line saying the stage is off); the Allan figure
//! ([`allan_fig`]: raw, clean and noise deviations with confidence bars, the
//! IEEE 952 asymptotes and their total); the noise figure ([`noise_fig`]:
//! the extracted noise and its running integral against the one-pulse band);
//! the rate and temperature figure ([`rate_fig`], with the excluded outliers,
//! the bias steps and the fitted warm-up marked); the dynamic Allan
//! deviation as a heat map ([`davar_fig`]: time against averaging time,
//! coloured by the deviation; one line instead when there is no map or too
//! few windows); and, with a gyro model, the diagnosis ([`diagnosis`]: its
//! SVG and its findings in words).
//!
//! The numbers come from a [`crate::pipeline::Analysis`] (with its
//! data-quality findings), the first pass's [`DavarMap`] and a
//! [`collect::Collector`] fed by [`crate::pipeline::feed`]'s taps during the same
//! pass; nothing here reads files or runs numerics.

pub mod allan_fig;
pub mod collect;
pub mod davar_fig;
pub mod decimate;
pub mod diagnosis;
pub mod diagnosis_fig;
pub mod html;
pub mod markup;
pub mod noise_fig;
pub mod plot;
pub mod rate_fig;
pub mod terms;

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::diagnose::Diagnosis;
use crate::input::frame::DecoderStats;
use crate::pipeline::Analysis;
use crate::quality::davar::DavarMap;

pub use collect::Collector;

/// Errors of the report writer.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("drawing a figure: {0}")]
    Draw(String),
    #[error(transparent)]
    Font(#[from] crate::font::FontError),
    #[error("writing {}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("writing {}: {reason}", path.display())]
    Png { path: PathBuf, reason: String },
}

/// What a page's numbers are in: a gyro's rate (deg/h) and angle (arcsec),
/// or an accelerometer's acceleration (m/s^2) and velocity (m/s), which the
/// numerics carry in their place ([`crate::units::Quantity`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    pub rate: &'static str,
    pub angle: &'static str,
    /// What the rate is called ("rate", "acceleration").
    pub rate_word: &'static str,
}

impl Units {
    pub const GYRO: Units = Units {
        rate: "deg/h",
        angle: "arcsec",
        rate_word: "rate",
    };
    pub const ACCEL: Units = Units {
        rate: "m/s\u{b2}",
        angle: "m/s",
        rate_word: "acceleration",
    };

    /// The units of an axis measuring `q`.
    pub fn of(q: crate::units::Quantity) -> Units {
        match q {
            crate::units::Quantity::AngularRate => Units::GYRO,
            crate::units::Quantity::Acceleration => Units::ACCEL,
        }
    }

    /// A line written in a gyro's units (the data-quality findings), in these.
    pub fn text(&self, line: &str) -> String {
        if *self == Units::GYRO {
            return line.to_string();
        }
        crate::units::accel_text(line).replace("m/s^2", self.rate)
    }
}

impl Default for Units {
    fn default() -> Self {
        Units::GYRO
    }
}

/// What the page says about the recording.
#[derive(Debug, Clone, Default)]
pub struct Metadata {
    /// The input file, as given.
    pub input: String,
    /// How it was read ("CSV, column counts, unit counts", "frame capture", ...).
    pub format: String,
    /// Where rate and pulse weight came from ("flags", "the recording's metadata record").
    pub origin: String,
    pub sample_rate_hz: f64,
    /// Pulse weight, arcsec (`None`: rate input).
    pub pulse_arcsec: Option<f64>,
    /// Gaps and samples lost in them, when the format can tell (frames, MCAP).
    pub gaps: Option<(u64, u64)>,
    /// The frame decoder's counts, for a frame capture.
    pub frame_stats: Option<DecoderStats>,
    /// Anything else worth a line (a cut recording, ...).
    pub notes: Vec<String>,
    /// The units of the axis shown.
    pub units: Units,
}

/// A diagnosis to include.
#[derive(Debug, Clone, Copy)]
pub struct DiagnosisPart<'a> {
    pub diagnosis: &'a Diagnosis,
    /// The model file, as given.
    pub model: &'a str,
}

/// Everything the report shows.
#[derive(Debug, Clone, Copy)]
pub struct Report<'a> {
    pub meta: &'a Metadata,
    pub analysis: &'a Analysis,
    pub series: &'a Collector,
    pub diagnosis: Option<DiagnosisPart<'a>>,
    /// The acceptance test's verdict, with `--spec`.
    pub spec: Option<&'a crate::model::spec::SpecReport>,
    /// The dynamic Allan deviation (`None`: the data-quality stage is off).
    pub davar: Option<&'a DavarMap>,
}

/// Sizes of the figures, px.
pub const ALLAN_SIZE: (u32, u32) = (1150, 640);
pub const NOISE_SIZE: (u32, u32) = (1150, 620);
pub const RATE_SIZE: (u32, u32) = (1150, 560);
pub const DAVAR_SIZE: (u32, u32) = (1150, 520);

/// The files written.
#[derive(Debug, Clone)]
pub struct Written {
    pub html: PathBuf,
    pub allan_png: PathBuf,
    pub noise_png: PathBuf,
    /// `davar.png`, when the record has a map to draw ([`davar_fig::drawable`]).
    pub davar_png: Option<PathBuf>,
}

/// Render an SVG document of `size` with `draw`.
pub fn svg<F>(size: (u32, u32), draw: F) -> Result<String, ReportError>
where
    F: FnOnce(&plot::Area<SVGBackend<'_>>) -> Result<(), ReportError>,
{
    crate::font::register()?;
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        draw(&root)?;
        root.present().map_err(plot::draw_err)?;
    }
    Ok(out)
}

/// Render a PNG file of `size` with `draw`.
pub fn png<F>(path: &Path, size: (u32, u32), draw: F) -> Result<(), ReportError>
where
    F: FnOnce(&plot::Area<BitMapBackend<'_>>) -> Result<(), ReportError>,
{
    crate::font::register()?;
    let root = BitMapBackend::new(path, size).into_drawing_area();
    draw(&root)?;
    // the file is encoded and written here
    root.present().map_err(|e| ReportError::Png {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Write `dir/index.html`, `dir/allan.png`, `dir/noise_integral.png` and,
/// when the record has a dynamic Allan deviation to draw, `dir/davar.png`
/// (`dir` must exist; a `davar.png` left there by an earlier report is
/// removed when this one has none, so the directory never shows another
/// record's map).
pub fn write(dir: &Path, r: &Report<'_>) -> Result<Written, ReportError> {
    let page = html::page(r)?;
    let davar = davar_fig::drawable(r.davar).ok();
    let w = Written {
        html: dir.join("index.html"),
        allan_png: dir.join("allan.png"),
        noise_png: dir.join("noise_integral.png"),
        davar_png: davar.map(|_| dir.join("davar.png")),
    };
    let u = r.meta.units;
    png(&w.allan_png, ALLAN_SIZE, |a| {
        allan_fig::draw(a, r.analysis, u)
    })?;
    png(&w.noise_png, NOISE_SIZE, |a| {
        noise_fig::draw(a, r.series, r.meta.pulse_arcsec, u)
    })?;
    match (davar, &w.davar_png) {
        (Some(m), Some(p)) => png(p, DAVAR_SIZE, |a| {
            davar_fig::draw(a, m, r.analysis.duration_s, u)
        })?,
        _ => remove_if_present(&dir.join("davar.png"))?,
    }
    std::fs::write(&w.html, page).map_err(|source| ReportError::Io {
        path: w.html.clone(),
        source,
    })?;
    Ok(w)
}

/// Remove `path` if it exists.
fn remove_if_present(path: &Path) -> Result<(), ReportError> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(ReportError::Io {
            path: path.to_path_buf(),
            source: e,
        }),
        _ => Ok(()),
    }
}

/// `v` with `sig` significant digits, plain or in exponent form.
pub fn fmt_sig(v: f64, sig: usize) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if v == 0.0 {
        return "0".into();
    }
    let e = v.abs().log10().floor() as i32;
    if (-4..6).contains(&e) {
        let decimals = (sig as i32 - 1 - e).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{:.*e}", sig.saturating_sub(1), v)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn significant_digits() {
        use super::fmt_sig;
        assert_eq!(fmt_sig(0.35123, 3), "0.351");
        assert_eq!(fmt_sig(1235.6, 3), "1236");
        assert_eq!(fmt_sig(0.000123456, 3), "0.000123");
        assert_eq!(fmt_sig(1.5e-7, 2), "1.5e-7");
        assert_eq!(fmt_sig(0.0, 3), "0");
    }
}
