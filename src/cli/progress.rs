//! Progress on stderr for the long commands: a bar (or a spinner when the total
//! is unknown) that appears once a job has run [`SHOW_AFTER`], the live status
//! line of `sagnac run`, and a tracing writer that prints log lines above it.
//!
//! Everything here draws only when stderr is a terminal: indicatif's stderr
//! target hides itself otherwise, and the status line is not made at all, so
//! a redirected stderr carries the log lines and nothing else (no carriage
//! returns, no escape codes).

use std::io::{IsTerminal, Write};
use std::sync::Arc;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::daemon::status::{LiveStatus, format_status_for_width};

/// A job shorter than this shows no progress at all.
pub const SHOW_AFTER: Duration = Duration::from_millis(700);

/// [`SHOW_AFTER`], or the seconds in `SAGNAC_PROGRESS_DELAY_S` (0 shows every
/// bar at once: the terminal tests use it, so a fast run still draws one).
pub fn show_after() -> Duration {
    std::env::var("SAGNAC_PROGRESS_DELAY_S")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|v| v.is_finite() && *v >= 0.0)
        .map_or(SHOW_AFTER, Duration::from_secs_f64)
}

/// Whether stderr is a terminal (progress is drawn only then).
pub fn stderr_is_terminal() -> bool {
    std::io::stderr().is_terminal()
}

fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar())
}

/// A bar of `what` ("samples", "frames") that appears after [`SHOW_AFTER`]:
/// `[elapsed] [bar] pos/len what (eta)`, or a spinner with the count when the
/// total is unknown. Feed it with [`DelayedBar::update`].
pub struct DelayedBar {
    bar: ProgressBar,
    started: Instant,
    shown: bool,
    label: String,
    what: &'static str,
}

impl DelayedBar {
    /// `label` (e.g. "analysing") in front of the counts of `what`.
    pub fn new(label: impl Into<String>, what: &'static str) -> Self {
        DelayedBar {
            bar: ProgressBar::hidden(),
            started: Instant::now(),
            shown: false,
            label: label.into(),
            what,
        }
    }

    /// `done` of `total` (if known) so far.
    pub fn update(&mut self, done: u64, total: Option<u64>) {
        if !self.shown && self.started.elapsed() >= show_after() {
            self.shown = true;
            let (label, what) = (&self.label, self.what);
            match total {
                Some(t) => {
                    self.bar.set_length(t);
                    self.bar.set_style(style(&format!(
                        "{label} [{{elapsed_precise}}] {{wide_bar}} {{human_pos}}/{{human_len}} {what} (eta {{eta}})"
                    )));
                }
                None => self.bar.set_style(style(&format!(
                    "{{spinner}} {label} [{{elapsed_precise}}] {{human_pos}} {what} ({{per_sec}})"
                ))),
            }
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        self.bar.set_position(done);
    }

    /// Add `n` to the position (total as in [`DelayedBar::update`]).
    pub fn inc(&mut self, n: u64, total: Option<u64>) {
        let done = self.bar.position() + n;
        self.update(done, total);
    }

    /// Remove the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// A spinner with a message that appears after [`SHOW_AFTER`] unless finished
/// before (for phases without a count: reading a whole file, a diagnosis).
pub struct Spinner {
    bar: ProgressBar,
    done: Option<mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl Spinner {
    pub fn start(message: impl Into<String>) -> Self {
        let bar = ProgressBar::hidden();
        bar.set_style(style("{spinner} {msg} [{elapsed_precise}]"));
        bar.set_message(message.into());
        let (tx, rx) = mpsc::channel::<()>();
        let b = bar.clone();
        let thread = std::thread::Builder::new()
            .name("sagnac-spinner".into())
            .spawn(move || {
                if let Err(RecvTimeoutError::Timeout) = rx.recv_timeout(show_after()) {
                    b.set_draw_target(ProgressDrawTarget::stderr());
                    b.enable_steady_tick(Duration::from_millis(150));
                }
            })
            .ok();
        Spinner {
            bar,
            done: Some(tx),
            thread,
        }
    }

    /// A new phase.
    pub fn set_message(&self, message: impl Into<String>) {
        self.bar.set_message(message.into());
    }

    /// Stop and clear.
    pub fn finish(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        drop(self.done.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.bar.finish_and_clear();
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A bar of the diagnosis's Monte-Carlo runs, one phase at a time
/// (`simulating the model [00:00:12] ####---- 9/16 runs`), that appears after
/// [`SHOW_AFTER`]; [`RunsBar::progress`] is what the diagnosis tells.
pub struct RunsBar {
    bar: ProgressBar,
}

impl RunsBar {
    pub fn start() -> Self {
        let bar = ProgressBar::hidden();
        bar.set_style(style(
            "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} runs (eta {eta})",
        ));
        RunsBar { bar }
    }

    /// The hook for [`crate::diagnose::diagnose_with_progress`].
    pub fn progress(&self) -> crate::diagnose::mc::Progress {
        let (bar, started, delay) = (self.bar.clone(), Instant::now(), show_after());
        let shown = Arc::new(std::sync::atomic::AtomicBool::new(false));
        crate::diagnose::mc::Progress::new(move |phase, done, total| {
            use std::sync::atomic::Ordering;
            if bar.message() != phase {
                bar.set_message(phase.to_string());
                bar.set_length(total as u64);
                bar.reset_eta();
            }
            bar.set_position(done as u64);
            if started.elapsed() >= delay && !shown.swap(true, Ordering::Relaxed) {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
        })
    }

    /// Remove the bar from the terminal.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// A writer that moves `bar` by the number of lines written through it (for
/// CSV rows written by library code), minus `skip` header lines.
pub struct LineCounter<'a, W> {
    inner: W,
    bar: &'a mut DelayedBar,
    total: Option<u64>,
    skip: u64,
}

impl<'a, W: Write> LineCounter<'a, W> {
    pub fn new(inner: W, bar: &'a mut DelayedBar, total: Option<u64>, skip: u64) -> Self {
        LineCounter {
            inner,
            bar,
            total,
            skip,
        }
    }
}

impl<W: Write> Write for LineCounter<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        let mut lines = buf[..n].iter().filter(|&&b| b == b'\n').count() as u64;
        let skipped = lines.min(self.skip);
        self.skip -= skipped;
        lines -= skipped;
        if lines > 0 {
            self.bar.inc(lines, self.total);
        }
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// The one live line of `sagnac run` at a terminal, redrawn in place every
/// 250 ms from a [`LiveStatus`] ([`format_status_for_width`], the terminal's
/// width read at each redraw); log lines go above it
/// through [`StatusLine::log_writer`].
pub struct StatusLine {
    bar: ProgressBar,
    status: Arc<LiveStatus>,
    stop: Option<mpsc::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

/// Columns of the terminal on stderr (80 when it does not say).
fn terminal_width() -> usize {
    console::Term::stderr()
        .size_checked()
        .map(|(_, cols)| usize::from(cols))
        .filter(|&c| c > 0)
        .unwrap_or(80)
}

impl StatusLine {
    /// A status line on stderr, or `None` when stderr is not a terminal.
    pub fn on_terminal() -> Option<Self> {
        if !stderr_is_terminal() {
            return None;
        }
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
        bar.set_style(style("{msg}"));
        Some(StatusLine {
            bar,
            status: LiveStatus::new(),
            stop: None,
            thread: None,
        })
    }

    /// What the pipeline updates.
    pub fn status(&self) -> Arc<LiveStatus> {
        Arc::clone(&self.status)
    }

    /// A tracing writer that prints each log line above the status line.
    pub fn log_writer(&self) -> SuspendingWriter {
        SuspendingWriter(self.bar.clone())
    }

    /// Start redrawing.
    pub fn start(&mut self) {
        let (tx, rx) = mpsc::channel::<()>();
        let (bar, status) = (self.bar.clone(), Arc::clone(&self.status));
        self.thread = std::thread::Builder::new()
            .name("sagnac-status".into())
            .spawn(move || {
                loop {
                    bar.set_message(format_status_for_width(
                        &status.snapshot(),
                        terminal_width(),
                    ));
                    match rx.recv_timeout(Duration::from_millis(250)) {
                        Err(RecvTimeoutError::Timeout) => continue,
                        _ => break,
                    }
                }
            })
            .ok();
        self.stop = Some(tx);
    }

    /// Draw the final state and leave it on the terminal.
    pub fn finish(mut self) {
        self.halt();
        self.bar.set_message(format_status_for_width(
            &self.status.snapshot(),
            terminal_width(),
        ));
        self.bar.finish();
    }

    fn halt(&mut self) {
        drop(self.stop.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for StatusLine {
    fn drop(&mut self) {
        self.halt();
        if !self.bar.is_finished() {
            self.bar.abandon();
        }
    }
}

/// Writes through [`ProgressBar::suspend`]: the status line is cleared, the
/// text written, the line redrawn below it.
#[derive(Clone)]
pub struct SuspendingWriter(ProgressBar);

impl Write for SuspendingWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.suspend(|| {
            let mut e = std::io::stderr().lock();
            e.write_all(buf).and_then(|()| e.flush())
        })?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for SuspendingWriter {
    type Writer = SuspendingWriter;
    fn make_writer(&'a self) -> Self::Writer {
        self.clone()
    }
}
