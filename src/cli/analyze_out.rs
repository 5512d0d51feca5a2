//! What `analyze` prints and writes for one axis, shared by the single-axis
//! command ([`super::analyze`]), the multi-axis one ([`super::analyze_axes`])
//! and `report`: the pipeline run with its progress bar, the notes of the
//! pass, the data-quality lines, the coefficient table, the Kalibr file and
//! the JSON file.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};

use crate::input::{Format, Input, StreamReport};
use crate::model::estimate::{Coefficient, NoiseEstimates};
use crate::pipeline::{Analysis, feed};
use crate::sink::export::kalibr::KalibrAxis;
use crate::units::{ACCEL_COEFFICIENTS, Quantity};

/// What the pass over the input met that the user should know, each with
/// its kind (`note`, `warning`): a frame capture's corruption and gaps, a
/// recording's break.
pub(crate) fn stream_notes(r: &StreamReport) -> Vec<(&'static str, String)> {
    let mut notes = Vec::new();
    if let Some(st) = &r.frames
        && st.lost_samples + st.bytes_skipped + st.crc_errors + st.duplicates + st.out_of_sequence
            > 0
    {
        notes.push(("note", format!(
            "{} frames decoded; {} samples lost in {} gaps (filled, the angle kept); \
             {} CRC errors, {} false syncs, {} bytes skipped; {} duplicate and {} out-of-sequence frames",
            st.frames_decoded,
            st.lost_samples,
            st.gaps,
            st.crc_errors,
            st.false_syncs,
            st.bytes_skipped,
            st.duplicates,
            st.out_of_sequence
        )));
    }
    if let Some(s) = &r.stamps
        && s.out_of_order + s.duplicates + s.gaps > 0
    {
        notes.push((
            "note",
            format!(
                "topic {}: {} messages; {} out of order (sorted by header.stamp), {} duplicates dropped; \
                 {} samples missing in {} holes (filled, left out of the statistics)",
                s.topic, s.messages, s.out_of_order, s.duplicates, s.lost_samples, s.gaps
            ),
        ));
    }
    if let Some(b) = &r.break_at {
        notes.push((
            "warning",
            format!(
                "unreadable from byte {} ({}); analysed the {} samples before it",
                b.offset, b.reason, r.samples
            ),
        ));
    }
    notes
}

/// Run the input through the pipeline (a bar on stderr once the job is
/// visibly long; hidden when stderr is not a terminal).
pub(crate) fn feed_input(input: &Input, raw: bool, tap: Option<feed::Tap>) -> Result<feed::Fed> {
    let mut cfg = feed::config_for(input)?;
    cfg.data_quality = !raw;
    let mut bar = super::progress::DelayedBar::new("analysing", "samples");
    let mut progress = |done: u64, total: Option<u64>| bar.update(done, total);
    let fed = feed::run(input, &cfg, &mut progress, tap)
        .with_context(|| format!("analysing {}", describe(input)))?;
    bar.finish();
    Ok(fed)
}

/// The input, as an error's context names it.
pub(crate) fn describe(input: &Input) -> String {
    let what = match input.meta().format {
        Format::Frames | Format::TriadFrames => "frame capture ",
        Format::Mcap => "recording ",
        Format::Ros2 => "bag ",
        _ => "",
    };
    format!("{what}{}", input.path().display())
}

/// Write the Kalibr file of `axes`.
pub(crate) fn write_kalibr(
    out: &Path,
    axes: &[KalibrAxis],
    rate: f64,
    path: &Path,
    rostopic: Option<&str>,
) -> Result<()> {
    crate::sink::export::kalibr::write(out, axes, rate, &path.display().to_string(), rostopic)
        .context("writing the Kalibr file")
}

/// One line per data-quality finding on stderr, and a warning when anything
/// was handled.
pub(crate) fn print_quality(dq: &crate::quality::DataQuality, path: &Path, q: Quantity) {
    let lines = dq.lines();
    if lines.is_empty() {
        return;
    }
    if dq.handled_anything() {
        eprintln!(
            "warning: {}: the record is not stationary noise alone; the estimates are of the handled record \
             (--raw-statistics for the record as it is):",
            path.display()
        );
    } else {
        eprintln!("note: {}:", path.display());
    }
    for l in lines {
        match q {
            Quantity::AngularRate => eprintln!("  {l}"),
            Quantity::Acceleration => eprintln!("  {}", crate::units::accel_text(&l)),
        }
    }
}

pub(crate) fn warn_about(analysis: &Analysis, path: &Path) {
    if !analysis.allan.raw.is_empty() && analysis.allan.raw.iter().all(|p| p.dev == 0.0) {
        eprintln!(
            "warning: {}: the raw Allan deviation is 0 at every tau (every increment equal: a stuck counter \
             or a dead gyro?); nothing can be estimated",
            path.display()
        );
    }
    if !analysis.fit.ok {
        eprintln!("warning: {}: {}", path.display(), misfit_message(analysis));
    }
}

/// Write a JSON value to `out` ("-": stdout).
pub(crate) fn write_value(out: &Path, value: &mut serde_json::Value) -> Result<()> {
    let text = serde_json::to_string_pretty(value).context("serialising the analysis")?;
    if out.as_os_str() == "-" {
        super::write_stdout(&text)
    } else {
        std::fs::write(out, text + "\n").with_context(|| format!("writing {}", out.display()))
    }
}

pub(crate) fn fmt_coef(c: &Coefficient) -> String {
    match (c.value, c.ci95, c.upper95) {
        (Some(v), Some([lo, hi]), _) => format!("{v:<12.6} [{lo:.6}, {hi:.6}]"),
        (Some(v), None, _) => format!("{v:.6}"),
        (None, _, Some(u)) => format!("{:<12} < {u:.6} (95 % upper bound)", "not found"),
        _ => "n/a".to_string(),
    }
}

/// What a failed fit means, for stderr and the table.
pub(crate) fn misfit_message(a: &Analysis) -> String {
    format!(
        "the noise model does not describe this recording (fit chi2/dof {:.2} on {} degrees of freedom); \
         intervals widened by sqrt(chi2/dof); run `sagnac diagnose`",
        a.fit.chi2_per_dof, a.fit.dof
    )
}

/// The five coefficients as the table prints them: name with unit, and the
/// coefficient in that unit (an accelerometer's renamed and rescaled).
pub(crate) fn coefficient_rows(e: &NoiseEstimates, q: Quantity) -> Vec<(String, Coefficient)> {
    let gyro = [
        ("quantization Q, arcsec", &e.quantization_arcsec),
        ("angle random walk N, deg/sqrt(h)", &e.arw_dpsh),
        ("bias instability B, deg/h", &e.bias_instability_dph),
        ("rate random walk K, deg/h/sqrt(h)", &e.rrw_dphsh),
        ("rate ramp R, deg/h/h", &e.rate_ramp_dphh),
    ];
    gyro.iter()
        .zip(ACCEL_COEFFICIENTS)
        .map(|((name, c), (_, _, unit, what, f))| match q {
            Quantity::AngularRate => (name.to_string(), **c),
            Quantity::Acceleration => (format!("{what}, {unit}"), c.scaled(f)),
        })
        .collect()
}

pub(crate) fn print_table(a: &Analysis, q: Quantity) -> Result<()> {
    let mut o = std::io::stdout().lock();
    writeln!(
        o,
        "{} samples, {:.1} s; fit chi2/dof {:.2}",
        a.samples, a.duration_s, a.fit.chi2_per_dof
    )?;
    if !a.fit.ok {
        writeln!(o, "WARNING: {}", misfit_message(a))?;
    }
    match &a.readout_filter {
        Some(f) => writeln!(
            o,
            "readout filter: {}{}, corner {:.4} Hz [{:.4}, {:.4}], delay {:.4} s",
            f.kind.name(),
            f.length
                .map_or(String::new(), |l| format!(" of {l} samples")),
            f.corner_hz,
            f.ci95[0],
            f.ci95[1],
            f.delay_s
        )?,
        None => writeln!(o, "readout filter: none found")?,
    }
    let rows = coefficient_rows(&a.estimates, q);
    let w = rows
        .iter()
        .map(|(n, _)| n.len())
        .max()
        .unwrap_or(32)
        .max(32);
    writeln!(o, "{:<w$} {:<12} 95 % interval", "coefficient", "value")?;
    for (name, c) in &rows {
        writeln!(o, "{name:<w$} {}", fmt_coef(c))?;
    }
    writeln!(o)?;
    writeln!(
        o,
        "{:>12} {:>14} {:>14} {:>14}",
        "tau, s", "raw ADEV", "clean ADEV", "noise ADEV"
    )?;
    for p in &a.allan.raw {
        let find = |v: &[crate::allan::AllanPoint]| v.iter().find(|q| q.m == p.m).map(|q| q.dev);
        let f = |x: Option<f64>| x.map_or("-".to_string(), readable);
        writeln!(
            o,
            "{:>12.4} {:>14} {:>14} {:>14}",
            p.tau_s,
            readable(p.dev),
            f(find(&a.allan.clean)),
            f(find(&a.allan.noise))
        )?;
    }
    let unit = match q {
        Quantity::AngularRate => "deg/h",
        Quantity::Acceleration => "m/s^2",
    };
    writeln!(o, "(Allan deviations in {unit})")?;
    Ok(())
}

/// `v` to 5 significant digits, in fixed notation from 1e-3 to 1e6 and as
/// `1.2345e-05` outside it.
pub(crate) fn readable(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if (1e-3..1e6).contains(&a) {
        let decimals = (4 - a.log10().floor() as i32).max(0) as usize;
        return format!("{v:.decimals$}");
    }
    let s = format!("{v:.4e}");
    match s.split_once('e') {
        Some((m, e)) => {
            let (sign, digits) = e.strip_prefix('-').map_or(("+", e), |d| ("-", d));
            format!("{m}e{sign}{digits:0>2}")
        }
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::readable;

    #[test]
    fn deviations_read_in_fixed_notation_with_five_digits() {
        assert_eq!(readable(21.557541), "21.558");
        assert_eq!(readable(0.0012345678), "0.0012346");
        assert_eq!(readable(123456.7), "123457");
        assert_eq!(readable(2.5e-5), "2.5000e-05");
        assert_eq!(readable(3.0e7), "3.0000e+07");
        assert_eq!(readable(0.0), "0");
    }
}
