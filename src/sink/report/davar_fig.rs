//! Figure: the dynamic Allan deviation ([`crate::quality::davar`]) as a heat
//! map. Time runs along x (one column per window of the record, on the rate
//! figure's time axis), the octave averaging times along y (log scale), and
//! the colour is the log10 of the window's Allan deviation on the viridis
//! scale, whose lightness rises steadily with the value so the map reads the
//! same in grey; a colour bar right of the map gives the scale in deg/h.
//!
//! A stationary noise gives the same colour along each row; a warm-up, a
//! step or a bad hour shows as a change along time. A cell with no term (a
//! tau longer than what reaches into that window, or a window of gaps) is
//! left blank rather than given a colour it has no value for; so is a cell
//! whose deviation is zero but for rounding (a pulse counter's second
//! differences, whole pulses, can cancel exactly, and the phase sum leaves
//! some 1e-14 deg/h), which has no logarithm and would otherwise stretch the
//! colour scale over twelve empty decades.

use plotters::prelude::*;

use super::ReportError;
use super::plot::{self, Area, TimeAxis, draw_err, font};
use crate::quality::davar::DavarMap;

/// Fewest windows worth a map: fewer show no change along time.
pub const MIN_WINDOWS: usize = 4;
/// Width of the colour bar's column (bar, ticks and label), px.
const BAR_COLUMN: u32 = 130;
/// Strips the colour bar is drawn with.
const BAR_STRIPS: usize = 128;
/// A deviation below this fraction of the largest in its row and the rows
/// an octave either side is zero but for rounding: the Allan deviation
/// changes by at most a factor of two an octave, and a term's chance of
/// falling this far below its expected size is about 1e-6, while a row of a
/// pulse counter can hold more exact zeros than values.
pub const ZERO_RATIO: f64 = 1e-6;
/// The figure's title.
const CAPTION: &str = "dynamic Allan deviation";

/// matplotlib's viridis (CC0) at 17 evenly spaced points, as 8-bit sRGB.
const VIRIDIS: [[u8; 3]; 17] = [
    [68, 1, 84],
    [72, 24, 106],
    [71, 45, 123],
    [66, 64, 134],
    [59, 82, 139],
    [51, 99, 141],
    [44, 114, 142],
    [38, 130, 142],
    [33, 145, 140],
    [31, 159, 136],
    [39, 173, 129],
    [61, 188, 116],
    [92, 200, 99],
    [129, 211, 77],
    [170, 220, 50],
    [213, 226, 26],
    [253, 231, 37],
];

/// The viridis colour at `t` in `[0, 1]` (clamped; not finite: the low
/// end), linear between the table's points.
pub fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let mix = |c: usize| {
        let (a, b) = (f64::from(VIRIDIS[i][c]), f64::from(VIRIDIS[i + 1][c]));
        (a + f * (b - a)).round() as u8
    };
    RGBColor(mix(0), mix(1), mix(2))
}

/// One coloured cell of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The window's span, s from the start.
    pub t_s: (f64, f64),
    /// The octave's span on the log tau axis (half an octave either side), s.
    pub tau_s: (f64, f64),
    /// log10 of the Allan deviation, deg/h.
    pub log_dev: f64,
}

/// The cells of `map` that have a value (NaN, and deviations that are zero
/// but for rounding, [`ZERO_RATIO`], are left out), the last window cut at
/// `duration_s`.
pub fn cells(map: &DavarMap, duration_s: f64) -> Vec<Cell> {
    let half = std::f64::consts::SQRT_2;
    let rows = map.tau_s.len();
    let top: Vec<f64> = (0..rows)
        .map(|j| {
            map.windows
                .iter()
                .filter_map(|w| w.dev.get(j).copied())
                .filter(|d| d.is_finite())
                .fold(0.0f64, f64::max)
        })
        .collect();
    let floor: Vec<f64> = (0..rows)
        .map(|j| {
            top[j.saturating_sub(1)..(j + 2).min(rows)]
                .iter()
                .fold(0.0f64, |a, &b| a.max(b))
                * ZERO_RATIO
        })
        .collect();
    let mut out = Vec::new();
    for w in &map.windows {
        let end = w.t0_s + map.window_s;
        let t1 = if duration_s > w.t0_s {
            end.min(duration_s)
        } else {
            end
        };
        for ((&tau, &dev), &zero) in map.tau_s.iter().zip(&w.dev).zip(&floor) {
            if dev.is_finite() && dev > zero && dev > 0.0 {
                out.push(Cell {
                    t_s: (w.t0_s, t1),
                    tau_s: (tau / half, tau * half),
                    log_dev: dev.log10(),
                });
            }
        }
    }
    out
}

/// The range of the cells' log deviations (a single value is widened so
/// the colour scale has a span).
fn color_range(cells: &[Cell]) -> Option<(f64, f64)> {
    let (lo, hi) = cells
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |r, c| {
            (r.0.min(c.log_dev), r.1.max(c.log_dev))
        });
    if lo > hi {
        return None;
    }
    Some(if hi - lo < 1e-6 {
        (lo - 0.05, hi + 0.05)
    } else {
        (lo, hi)
    })
}

/// A window's length for the page: whole seconds, or two significant
/// digits when shorter than 10 s.
pub fn window_text(window_s: f64) -> String {
    if window_s >= 10.0 {
        format!("{window_s:.0}")
    } else {
        super::fmt_sig(window_s, 2)
    }
}

/// The map when it makes a figure, else why not (one sentence for the page).
pub fn drawable(map: Option<&DavarMap>) -> Result<&DavarMap, String> {
    let Some(m) = map else {
        return Err(
            "no dynamic Allan deviation: the data-quality stage is off (--raw-statistics)".into(),
        );
    };
    if m.windows.len() < MIN_WINDOWS {
        return Err(format!(
            "not drawn: the record holds {} window{} of {} s, fewer than the {MIN_WINDOWS} a map needs",
            m.windows.len(),
            if m.windows.len() == 1 { "" } else { "s" },
            window_text(m.window_s)
        ));
    }
    if cells(m, f64::INFINITY).is_empty() {
        return Err("not drawn: no window holds an Allan deviation term".into());
    }
    Ok(m)
}

/// Draw the map of a record of `duration_s` on `area`.
pub fn draw<DB: DrawingBackend>(
    area: &Area<DB>,
    map: &DavarMap,
    duration_s: f64,
    u: super::Units,
) -> Result<(), ReportError> {
    crate::font::register()?;
    area.fill(&WHITE).map_err(draw_err)?;
    let cells = cells(map, duration_s);
    let Some((c_lo, c_hi)) = color_range(&cells) else {
        area.draw(&Text::new(
            "no dynamic Allan deviation to plot",
            (40, 40),
            font(plot::LABEL),
        ))
        .map_err(draw_err)?;
        return Ok(());
    };
    let end_s = cells.iter().fold(duration_s, |e, c| e.max(c.t_s.1));
    let axis = TimeAxis::for_duration(end_s);
    let t_hi = end_s / axis.per_unit;
    let (tau_lo, tau_hi) = cells.iter().fold((f64::INFINITY, 0.0f64), |r, c| {
        (r.0.min(c.tau_s.0), r.1.max(c.tau_s.1))
    });
    let (w, _) = area.dim_in_pixel();
    let (left, right) = area.split_horizontally(w.saturating_sub(BAR_COLUMN));
    let mut chart = ChartBuilder::on(&left)
        .caption(CAPTION, font(plot::TITLE))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..t_hi, (tau_lo..tau_hi).log_scale())
        .map_err(draw_err)?;
    let xstep = t_hi / 10.0;
    chart
        .configure_mesh()
        .x_desc(axis.label)
        .y_desc("averaging time \u{3c4}, s")
        .axis_desc_style(font(plot::LABEL))
        .label_style(font(plot::TICK))
        .x_label_formatter(&|v| plot::lin_tick(*v, xstep))
        .y_label_formatter(&|v| plot::log_tick(*v))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(220, 220, 220))
        .draw()
        .map_err(draw_err)?;
    let shade = |v: f64| viridis((v - c_lo) / (c_hi - c_lo));
    let pu = axis.per_unit;
    chart
        .draw_series(cells.iter().map(|c| {
            Rectangle::new(
                [(c.t_s.0 / pu, c.tau_s.1), (c.t_s.1 / pu, c.tau_s.0)],
                shade(c.log_dev).filled(),
            )
        }))
        .map_err(draw_err)?;
    color_bar(&left, &right, (c_lo, c_hi), u)
}

/// The colour bar in `column`, its top level with the map's plot (below
/// the caption `beside` carries).
fn color_bar<DB: DrawingBackend>(
    beside: &Area<DB>,
    column: &Area<DB>,
    (lo, hi): (f64, f64),
    u: super::Units,
) -> Result<(), ReportError> {
    // the height plotters gives a caption: the text and twice its padding
    let (_, text_h) = beside
        .estimate_text_size(CAPTION, &font(plot::TITLE))
        .map_err(draw_err)?;
    let top = 2 * (text_h / 2).min(5) + text_h;
    let mut bar = ChartBuilder::on(&column.margin(top, 0, 0, 0))
        .margin(12)
        .margin_left(0)
        .x_label_area_size(44)
        .right_y_label_area_size(60)
        .build_cartesian_2d(0.0..1.0, (10f64.powf(lo)..10f64.powf(hi)).log_scale())
        .map_err(draw_err)?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(format!("ADEV, {}", u.rate))
        .axis_desc_style(font(plot::LABEL))
        .label_style(font(plot::TICK))
        .x_label_formatter(&|_| String::new())
        .y_label_formatter(&|v| plot::log_tick(*v))
        .draw()
        .map_err(draw_err)?;
    let n = BAR_STRIPS as f64;
    bar.draw_series((0..BAR_STRIPS).map(|i| {
        let (a, b) = (i as f64 / n, (i + 1) as f64 / n);
        let v = |f: f64| 10f64.powf(lo + f * (hi - lo));
        Rectangle::new([(0.0, v(b)), (1.0, v(a))], viridis(0.5 * (a + b)).filled())
    }))
    .map_err(draw_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::davar::DavarWindow;

    /// CIE L* of an 8-bit sRGB colour.
    fn lightness(c: RGBColor) -> f64 {
        let lin = |v: u8| {
            let v = f64::from(v) / 255.0;
            if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        };
        let y = 0.2126 * lin(c.0) + 0.7152 * lin(c.1) + 0.0722 * lin(c.2);
        if y > 216.0 / 24389.0 {
            116.0 * y.cbrt() - 16.0
        } else {
            y * 24389.0 / 27.0
        }
    }

    #[test]
    fn viridis_runs_from_dark_violet_to_yellow_with_rising_lightness() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        // clamped, and a NaN takes the low end
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        // L* rises at every step of 1/1000 (8-bit rounding: 0.3 L* slack),
        // and over the whole scale by what viridis spans (about 16 to 92)
        let l: Vec<f64> = (0..=1000)
            .map(|i| lightness(viridis(i as f64 / 1000.0)))
            .collect();
        for (i, p) in l.windows(2).enumerate() {
            assert!(
                p[1] >= p[0] - 0.3,
                "L* falls at t = {}: {p:?}",
                i as f64 / 1000.0
            );
        }
        for p in l.windows(50) {
            assert!(p[49] > p[0] + 2.0, "L* flat over 0.05 of the scale: {p:?}");
        }
        assert!(
            (l[0] - 16.0).abs() < 2.0 && (l[1000] - 91.5).abs() < 2.0,
            "{} {}",
            l[0],
            l[1000]
        );
    }

    fn map() -> DavarMap {
        let w = |t0: f64, dev: [f64; 4]| DavarWindow {
            t0_s: t0,
            dev: dev.to_vec(),
            n: dev.iter().map(|d| u64::from(d.is_finite())).collect(),
        };
        DavarMap {
            window_s: 10.0,
            tau_s: vec![0.5, 1.0, 2.0, 4.0],
            windows: vec![
                w(0.0, [4.0, 2.0, f64::NAN, f64::NAN]),
                w(10.0, [4.0, f64::NAN, 1.0, 1e-14]),
                w(20.0, [4.0, 2.0, f64::NAN, f64::NAN]),
                w(30.0, [1e-15, 0.0, 100.0, f64::NAN]),
            ],
        }
    }

    #[test]
    fn nan_cells_are_blank_and_leave_the_colour_scale_alone() {
        let m = map();
        let c = cells(&m, 35.0);
        // 16 cells, of which 6 NaN, one zero and two zero but for rounding
        // (one in a row of its own, judged by the row below)
        assert_eq!(c.len(), 7);
        assert!(c.iter().all(|c| c.log_dev.is_finite()));
        let at = |t: f64, tau: f64| {
            c.iter()
                .any(|c| c.t_s.0 == t && c.tau_s.0 < tau && tau < c.tau_s.1)
        };
        assert!(!at(0.0, 2.0) && !at(10.0, 1.0) && !at(30.0, 0.5) && !at(30.0, 1.0));
        assert!(!at(10.0, 4.0));
        assert!(at(10.0, 2.0) && at(30.0, 2.0));
        // the last window is cut at the record's end; octaves meet halfway
        let last = c.iter().find(|c| c.t_s.0 == 30.0).unwrap();
        assert_eq!(last.t_s, (30.0, 35.0));
        assert!((c[0].tau_s.1 - c[1].tau_s.0).abs() < 1e-12);
        assert_eq!(color_range(&c), Some((0.0, 2.0)));
        // drawn: no NaN reaches the SVG, and one rectangle per cell besides the
        // bar's strips and the background
        let svg = super::super::svg((600, 400), |a| draw(a, &m, 35.0, super::super::Units::GYRO))
            .unwrap();
        assert!(!svg.contains("NaN"));
        assert_eq!(svg.matches("<rect").count() - BAR_STRIPS, 7 + 1);
    }

    #[test]
    fn too_few_windows_or_no_map_make_no_figure() {
        let m = map();
        assert!(drawable(Some(&m)).is_ok());
        let mut short = m.clone();
        short.windows.truncate(3);
        let why = drawable(Some(&short)).unwrap_err();
        assert!(why.contains("3 windows of 10 s"), "{why}");
        assert_eq!(window_text(40.96), "41");
        assert_eq!(window_text(5.12), "5.1");
        assert!(drawable(None).unwrap_err().contains("--raw-statistics"));
        let mut empty = m;
        for w in &mut empty.windows {
            w.dev.iter_mut().for_each(|d| *d = f64::NAN);
        }
        assert!(drawable(Some(&empty)).is_err());
    }
}
