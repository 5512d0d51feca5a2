//! The live status of a run, for the one-line display `sagnac run` redraws at a
//! terminal: elapsed time, samples, lost samples, QN and ARW with their 95 %
//! intervals, the fit verdict, what the data-quality stage found (a warm-up
//! settling or excluded, outliers excluded, bias steps), and a replay's
//! progress through its file.
//!
//! The pipeline thread writes [`LiveStatus`] (samples at every batch, the
//! coefficients at every estimator update); the terminal side reads a
//! [`StatusSnapshot`] and draws [`format_status`], a pure function. Numbers are
//! in fixed notation ([`fixed`]), never with an exponent, here and in the
//! estimate log lines ([`format_coefficient`]).

use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use crate::model::estimate::Coefficient;
use crate::pipeline::FitSummary;
use crate::sink::metrics::Metrics;

/// The coefficients of the last estimator update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatusEstimate {
    pub quantization_arcsec: Coefficient,
    pub arw_dpsh: Coefficient,
    pub fit: FitSummary,
    /// The final update (after the end of the stream).
    pub final_update: bool,
}

/// What the data-quality stage found so far, as the status line says it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StatusQuality {
    /// A warm-up is settling: its time constant, s.
    pub warmup_settling_tau_s: Option<f64>,
    /// The statistics restarted after a warm-up: seconds of the run left out.
    pub warmup_excluded_s: Option<f64>,
    /// Outliers excluded as gaps.
    pub outliers_excluded: u64,
    /// Bias steps found.
    pub steps: u64,
}

impl StatusQuality {
    /// `warm-up settling (tau 60 s), 3 outliers excluded, 1 step`; empty when
    /// nothing was found.
    fn full(&self) -> Vec<String> {
        let mut v = Vec::new();
        if let Some(t) = self.warmup_excluded_s {
            v.push(format!("warm-up excluded: first {t:.0} s"));
        } else if let Some(tau) = self.warmup_settling_tau_s {
            v.push(format!("warm-up settling (tau {tau:.0} s)"));
        }
        if self.outliers_excluded > 0 {
            let s = if self.outliers_excluded == 1 { "" } else { "s" };
            v.push(format!("{} outlier{s} excluded", self.outliers_excluded));
        }
        if self.steps > 0 {
            let s = if self.steps == 1 { "" } else { "s" };
            v.push(format!("{} step{s}", self.steps));
        }
        v
    }

    /// `wu 60s`, `wu-excl 300s`, `3 outl`, `1 step`.
    fn compact(&self) -> Vec<String> {
        let mut v = Vec::new();
        if let Some(t) = self.warmup_excluded_s {
            v.push(format!("wu-excl {t:.0}s"));
        } else if let Some(tau) = self.warmup_settling_tau_s {
            v.push(format!("wu {tau:.0}s"));
        }
        if self.outliers_excluded > 0 {
            v.push(format!("{} outl", short_count(self.outliers_excluded)));
        }
        if self.steps > 0 {
            let s = if self.steps == 1 { "" } else { "s" };
            v.push(format!("{} step{s}", self.steps));
        }
        v
    }
}

/// What the status line shows.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StatusSnapshot {
    /// Wall time since the run started, s.
    pub elapsed_s: f64,
    /// Samples decoded.
    pub samples: u64,
    /// Sample periods lost (gaps, drops).
    pub lost: u64,
    pub estimate: Option<StatusEstimate>,
    /// What the data-quality stage found.
    pub quality: StatusQuality,
    /// A replay's (bytes read, file size).
    pub replay_bytes: Option<(u64, u64)>,
}

impl StatusSnapshot {
    /// How far a replay has got through its file, %.
    fn replay_percent(&self) -> Option<f64> {
        let (done, total) = self.replay_bytes.filter(|&(_, t)| t > 0)?;
        Some(100.0 * (done.min(total) as f64) / total as f64)
    }
}

#[derive(Debug, Default)]
struct State {
    samples: u64,
    lost: u64,
    estimate: Option<StatusEstimate>,
    quality: StatusQuality,
}

/// A replay's file size and where to read how far the replay has got.
struct ReplayProgress {
    total_bytes: u64,
    metrics: Arc<Metrics>,
}

/// Shared between the pipeline thread (writer) and the display (reader).
pub struct LiveStatus {
    started: Instant,
    state: Mutex<State>,
    replay: OnceLock<ReplayProgress>,
}

impl std::fmt::Debug for LiveStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveStatus")
            .field("state", &self.state)
            .finish_non_exhaustive()
    }
}

impl Default for LiveStatus {
    fn default() -> Self {
        LiveStatus {
            started: Instant::now(),
            state: Mutex::default(),
            replay: OnceLock::new(),
        }
    }
}

impl LiveStatus {
    /// A status whose elapsed time starts now.
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        // the state is plain numbers: a panic elsewhere cannot leave it half-written
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Samples decoded and periods lost so far.
    pub fn set_counts(&self, samples: u64, lost: u64) {
        let mut s = self.lock();
        (s.samples, s.lost) = (samples, lost);
    }

    /// The coefficients of an estimator update.
    pub fn set_estimate(&self, e: StatusEstimate) {
        self.lock().estimate = Some(e);
    }

    /// What the data-quality stage found so far.
    pub fn set_quality(&self, q: StatusQuality) {
        self.lock().quality = q;
    }

    /// A replay of a file of `total_bytes`: its progress is the
    /// `sagnac_bytes_read_total` counter of `metrics`.
    pub fn set_replay(&self, total_bytes: u64, metrics: Arc<Metrics>) {
        let _ = self.replay.set(ReplayProgress {
            total_bytes,
            metrics,
        });
    }

    /// What to show now.
    pub fn snapshot(&self) -> StatusSnapshot {
        let s = self.lock();
        let replay_bytes = self
            .replay
            .get()
            .map(|r| (bytes_read(&r.metrics), r.total_bytes));
        StatusSnapshot {
            elapsed_s: self.started.elapsed().as_secs_f64(),
            samples: s.samples,
            lost: s.lost,
            estimate: s.estimate,
            quality: s.quality,
            replay_bytes,
        }
    }
}

/// The `sagnac_bytes_read_total` counter.
fn bytes_read(m: &Metrics) -> u64 {
    m.registry()
        .gather()
        .iter()
        .find(|f| f.name() == "sagnac_bytes_read_total")
        .and_then(|f| {
            f.get_metric()
                .first()
                .map(|c| c.get_counter().get_value() as u64)
        })
        .unwrap_or(0)
}

/// Decimals that give `v` `sig` significant digits in fixed notation (at most 12).
fn decimals_for(v: f64, sig: usize) -> usize {
    if !v.is_finite() || v == 0.0 {
        return sig.saturating_sub(1);
    }
    let e = v.abs().log10().floor() as i64;
    (sig as i64 - 1 - e).clamp(0, 12) as usize
}

/// `v` with `sig` significant digits in fixed notation: `0.000987`, `1236`, never `9.87e-4`.
pub fn fixed(v: f64, sig: usize) -> String {
    format!("{v:.*}", decimals_for(v, sig))
}

/// "0.351 [0.349, 0.353]" (the interval with the value's decimals), "< 0.00200"
/// for a 95 % upper bound, or "-"; fixed notation, 3 significant digits.
pub fn format_coefficient(c: &Coefficient) -> String {
    match (c.value, c.ci95, c.upper95) {
        (Some(v), Some([lo, hi]), _) => {
            let d = decimals_for(v, 3);
            format!("{v:.d$} [{lo:.d$}, {hi:.d$}]")
        }
        (Some(v), None, _) => fixed(v, 3),
        (None, _, Some(u)) => format!("< {}", fixed(u, 3)),
        _ => "-".into(),
    }
}

/// The status line for a terminal `width` columns wide: [`format_status`] when
/// it fits, else [`format_status_compact`] (the same fields, shorter: it fits
/// 80 columns), else the compact line without its data-quality part. On a
/// terminal narrower than that, the compact line is drawn and the terminal
/// truncates it.
pub fn format_status_for_width(s: &StatusSnapshot, width: usize) -> String {
    let fits = |l: &String| l.chars().count() <= width;
    let full = format_status(s);
    if fits(&full) {
        return full;
    }
    let compact = format_status_compact(s);
    if fits(&compact) {
        return compact;
    }
    format_status_compact(&StatusSnapshot {
        quality: StatusQuality::default(),
        ..*s
    })
}

/// `12.3 s | 12300 samples, 0 lost | Q 0.351 [0.349, 0.353] arcsec | N 0.000990
/// [0.000641, 0.00120] deg/sqrt(h) | fit ok`, preceded by `replay 45 % |` for a
/// replay; `estimating...` before the first update; then what the data-quality
/// stage found, when anything (`| warm-up settling (tau 60 s), 3 outliers excluded`).
pub fn format_status(s: &StatusSnapshot) -> String {
    let mut parts = Vec::with_capacity(6);
    if let Some(pct) = s.replay_percent() {
        parts.push(format!("replay {pct:.0} %"));
    }
    parts.push(format!("{:.1} s", s.elapsed_s));
    parts.push(format!("{} samples, {} lost", s.samples, s.lost));
    match &s.estimate {
        Some(e) => {
            parts.push(format!(
                "Q {} arcsec",
                format_coefficient(&e.quantization_arcsec)
            ));
            parts.push(format!("N {} deg/sqrt(h)", format_coefficient(&e.arw_dpsh)));
            parts.push(if e.fit.ok {
                format!("fit ok (chi2/dof {:.2})", e.fit.chi2_per_dof)
            } else {
                format!(
                    "MODEL MISFIT (chi2/dof {:.2}): run sagnac diagnose",
                    e.fit.chi2_per_dof
                )
            });
        }
        None => parts.push("estimating...".into()),
    }
    let q = s.quality.full();
    if !q.is_empty() {
        parts.push(q.join(", "));
    }
    parts.join(" | ")
}

/// The status line in at most 80 columns: `45% 12m34s 1.23M (3 lost) Q
/// 0.35[0.34,0.36] N 0.00099[0.00064,0.0012] ok`: replay progress, elapsed
/// time, samples and lost samples, Q in arcsec and N in deg/sqrt(h) with their
/// 95 % intervals to 2 significant digits, `ok` or `MISFIT` for the fit, then
/// the data-quality findings in short (`wu 60s`, `wu-excl 300s`, `3 outl`,
/// `1 step`; without them the line fits 80 columns).
pub fn format_status_compact(s: &StatusSnapshot) -> String {
    let mut parts = Vec::with_capacity(8);
    if let Some(pct) = s.replay_percent() {
        parts.push(format!("{pct:.0}%"));
    }
    parts.push(short_duration(s.elapsed_s));
    parts.push(format!(
        "{} ({} lost)",
        short_count(s.samples),
        short_count(s.lost)
    ));
    match &s.estimate {
        Some(e) => {
            parts.push(format!("Q {}", compact_coefficient(&e.quantization_arcsec)));
            parts.push(format!("N {}", compact_coefficient(&e.arw_dpsh)));
            parts.push(if e.fit.ok { "ok" } else { "MISFIT" }.into());
        }
        None => parts.push("estimating...".into()),
    }
    parts.extend(s.quality.compact());
    parts.join(" ")
}

/// "12.3s", "12m34s", "12h34m".
fn short_duration(t_s: f64) -> String {
    let t = t_s.max(0.0);
    if t < 60.0 {
        format!("{t:.1}s")
    } else if t < 3600.0 {
        let m = (t / 60.0).floor();
        format!("{m:.0}m{:02.0}s", (t - 60.0 * m).floor())
    } else {
        let h = (t / 3600.0).floor();
        format!("{h:.0}h{:02.0}m", ((t - 3600.0 * h) / 60.0).floor())
    }
}

/// 99999, 123k, 1.23M, 4.56G: every digit up to 5 digits, then 3 significant.
fn short_count(n: u64) -> String {
    const UNITS: [(f64, &str); 3] = [(1e9, "G"), (1e6, "M"), (1e3, "k")];
    let v = n as f64;
    match UNITS.iter().find(|(scale, _)| v >= *scale && n >= 100_000) {
        Some((scale, unit)) => format!("{}{unit}", fixed(v / scale, 3)),
        None => n.to_string(),
    }
}

/// "0.35[0.34,0.36]", "<0.0012", "-": 2 significant digits.
fn compact_coefficient(c: &Coefficient) -> String {
    match (c.value, c.ci95, c.upper95) {
        (Some(v), Some([lo, hi]), _) => {
            format!("{}[{},{}]", fixed(v, 2), fixed(lo, 2), fixed(hi, 2))
        }
        (Some(v), None, _) => fixed(v, 2),
        (None, _, Some(u)) => format!("<{}", fixed(u, 2)),
        _ => "-".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coef(value: Option<f64>, ci95: Option<[f64; 2]>, upper95: Option<f64>) -> Coefficient {
        Coefficient {
            value,
            ci95,
            upper95,
        }
    }

    #[test]
    fn fixed_notation_never_has_an_exponent() {
        assert_eq!(fixed(0.35123, 3), "0.351");
        assert_eq!(fixed(0.000987654, 3), "0.000988");
        assert_eq!(fixed(1235.6, 3), "1236");
        assert_eq!(fixed(1.5e-7, 2), "0.00000015");
        assert_eq!(fixed(0.0, 3), "0.00");
        // below 1e-12 the digits run out, still without an exponent
        assert_eq!(fixed(3e-15, 3), "0.000000000000");
        for v in [1e-9, 2.5e-6, 0.5, 7.0, 3e5, 1e9] {
            assert!(!fixed(v, 3).contains('e'), "{v}: {}", fixed(v, 3));
        }
    }

    #[test]
    fn coefficients_with_intervals_and_bounds() {
        assert_eq!(
            format_coefficient(&coef(Some(0.35054), Some([0.34086, 0.35996]), None)),
            "0.351 [0.341, 0.360]"
        );
        // the interval takes the value's decimals
        assert_eq!(
            format_coefficient(&coef(Some(0.00099011), Some([0.00064116, 0.0012039]), None)),
            "0.000990 [0.000641, 0.001204]"
        );
        assert_eq!(
            format_coefficient(&coef(None, None, Some(0.1688))),
            "< 0.169"
        );
        assert_eq!(format_coefficient(&coef(Some(2.0), None, None)), "2.00");
        assert_eq!(format_coefficient(&coef(None, None, None)), "-");
    }

    #[test]
    fn the_status_line() {
        let fit = FitSummary {
            chi2_per_dof: 0.13,
            dof: 1.0,
            ok: true,
            observations: 2,
        };
        let mut s = StatusSnapshot {
            elapsed_s: 12.34,
            samples: 12_300,
            lost: 3,
            ..StatusSnapshot::default()
        };
        assert_eq!(
            format_status(&s),
            "12.3 s | 12300 samples, 3 lost | estimating..."
        );
        s.estimate = Some(StatusEstimate {
            quantization_arcsec: coef(Some(0.35054), Some([0.34086, 0.35996]), None),
            arw_dpsh: coef(None, None, Some(0.0012)),
            fit,
            final_update: false,
        });
        assert_eq!(
            format_status(&s),
            "12.3 s | 12300 samples, 3 lost | Q 0.351 [0.341, 0.360] arcsec | N < 0.00120 deg/sqrt(h) | fit ok (chi2/dof 0.13)"
        );
        s.replay_bytes = Some((450, 1000));
        s.estimate.as_mut().unwrap().fit = FitSummary {
            chi2_per_dof: 7.5,
            ok: false,
            ..fit
        };
        assert_eq!(
            format_status(&s),
            "replay 45 % | 12.3 s | 12300 samples, 3 lost | Q 0.351 [0.341, 0.360] arcsec | N < 0.00120 deg/sqrt(h) \
             | MODEL MISFIT (chi2/dof 7.50): run sagnac diagnose"
        );
    }

    #[test]
    fn the_compact_status_line_fits_80_columns() {
        let worst = StatusSnapshot {
            elapsed_s: 3.0 * 86_400.0 - 1.0,
            samples: 259_199_999,
            lost: 123_456,
            estimate: Some(StatusEstimate {
                quantization_arcsec: coef(Some(0.35054), Some([0.34086, 0.35996]), None),
                arw_dpsh: coef(Some(0.00099011), Some([0.00064116, 0.0012039]), None),
                fit: FitSummary {
                    chi2_per_dof: 17.5,
                    dof: 40.0,
                    ok: false,
                    observations: 60,
                },
                final_update: false,
            }),
            replay_bytes: Some((999, 1000)),
            ..StatusSnapshot::default()
        };
        let line = format_status_compact(&worst);
        assert_eq!(
            line,
            "100% 71h59m 259M (123k lost) Q 0.35[0.34,0.36] N 0.00099[0.00064,0.0012] MISFIT"
        );
        assert!(line.len() <= 80, "{} columns: {line}", line.len());
        // the full line is kept where it fits, the compact one where it does not
        assert!(format_status(&worst).len() > 80);
        assert_eq!(format_status_for_width(&worst, 80), line);
        assert_eq!(format_status_for_width(&worst, 200), format_status(&worst));
        assert_eq!(short_duration(75.2), "1m15s");
        assert_eq!(short_duration(12.34), "12.3s");
        assert_eq!(short_count(999), "999");
        assert_eq!(short_count(12_345), "12345");
        assert_eq!(short_count(1_234_567), "1.23M");
        assert_eq!(
            compact_coefficient(&coef(None, None, Some(0.0012))),
            "<0.0012"
        );
    }

    #[test]
    fn the_data_quality_part_of_the_status_line() {
        let mut s = StatusSnapshot {
            elapsed_s: 12.34,
            samples: 12_300,
            ..StatusSnapshot::default()
        };
        s.quality = StatusQuality {
            warmup_settling_tau_s: Some(59.6),
            outliers_excluded: 3,
            steps: 1,
            ..StatusQuality::default()
        };
        assert_eq!(
            format_status(&s),
            "12.3 s | 12300 samples, 0 lost | estimating... | warm-up settling (tau 60 s), 3 outliers excluded, 1 step"
        );
        assert_eq!(
            format_status_compact(&s),
            "12.3s 12300 (0 lost) estimating... wu 60s 3 outl 1 step"
        );
        s.quality = StatusQuality {
            warmup_settling_tau_s: Some(59.6),
            warmup_excluded_s: Some(420.0),
            outliers_excluded: 1,
            steps: 2,
        };
        assert_eq!(
            format_status(&s),
            "12.3 s | 12300 samples, 0 lost | estimating... | warm-up excluded: first 420 s, 1 outlier excluded, 2 steps"
        );
        // nothing found: no part at all
        s.quality = StatusQuality::default();
        assert_eq!(
            format_status(&s),
            "12.3 s | 12300 samples, 0 lost | estimating..."
        );
        // the widest compact line with findings: they go first when 80 columns are too few
        let worst = StatusSnapshot {
            elapsed_s: 3.0 * 86_400.0 - 1.0,
            samples: 259_199_999,
            lost: 123_456,
            estimate: Some(StatusEstimate {
                quantization_arcsec: coef(Some(0.35054), Some([0.34086, 0.35996]), None),
                arw_dpsh: coef(Some(0.00099011), Some([0.00064116, 0.0012039]), None),
                fit: FitSummary {
                    chi2_per_dof: 17.5,
                    dof: 40.0,
                    ok: false,
                    observations: 60,
                },
                final_update: false,
            }),
            quality: StatusQuality {
                warmup_excluded_s: Some(900.0),
                outliers_excluded: 12,
                ..StatusQuality::default()
            },
            replay_bytes: Some((999, 1000)),
        };
        let line = format_status_for_width(&worst, 80);
        assert_eq!(
            line,
            "100% 71h59m 259M (123k lost) Q 0.35[0.34,0.36] N 0.00099[0.00064,0.0012] MISFIT"
        );
        assert!(
            format_status_for_width(&worst, 120).ends_with("MISFIT wu-excl 900s 12 outl"),
            "{}",
            format_status_for_width(&worst, 120)
        );
    }
}
