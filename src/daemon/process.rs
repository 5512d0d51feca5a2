//! The numeric stage of the daemon: a blocking thread that takes
//! [`SourceBatch`]es from a bounded channel, runs them through the same
//! [`Pipeline`] as `sagnac analyze` (gap fill -> streaming sym8 QN removal ->
//! octave Allan accumulators -> estimator), and publishes to the sinks:
//! MCAP messages to the recorder, values to the Prometheus metrics, one log line
//! per estimator update.
//!
//! * Gaps: a sample after `lost` missing ones carries the whole increment over
//!   `lost + 1` periods; it is spread over them as integers
//!   ([`FilledSeries`]), so the pipeline sees a uniform series whose sum is
//!   the true number of pulses, with the made-up samples marked (its statistics
//!   leave them out). `/gyro/raw` records the samples as decoded
//!   (with the gaps), `/gyro/clean` and `/gyro/noise` the uniform series.
//! * Estimator updates happen every `interval_s` seconds *of samples*, at exact
//!   sample counts (the input is split there), so they do not depend on how the
//!   input was batched. One update (the ML fit with profile intervals) costs
//!   0.03-0.3 s of CPU, so a source that runs faster than real time could spend
//!   all its time estimating: with an `update_budget` (replays and the simulated
//!   bench: 5 %), an update is skipped while less than `cost / budget` of wall
//!   time has passed since the previous one started. At real-time pace (1 kHz,
//!   5 s interval) no update is skipped; a live serial source never skips while
//!   it runs. The data-quality assessments are not skipped (their schedule is
//!   by sample count) and do not count against the budget. After a shutdown
//!   request the queued batches are drained without intermediate updates or
//!   assessments. The final update after the end of the stream is
//!   always made, so final estimates are deterministic.
//! * Recording: lossless sources use the recorder's blocking `send`
//!   (backpressure all the way to the source); live sources use `try_send`, and
//!   what a full queue refuses is counted (`sagnac_dropped_messages_total
//!   {sink="mcap"}`) and reported by a `backpressure_drop` event once the queue
//!   takes messages again.
//! * Canonical pushes: the pipeline's floating-point sums depend (in the last
//!   bits) on how its input is split into calls, so samples are pushed in pieces
//!   cut at absolute sample indices (every [`PUSH_CHUNK`] samples and at every
//!   estimator boundary), whatever the source's batching: a live run, a replay
//!   of its raw capture and a replay of its recording give bit-identical
//!   estimates (with the same configuration).
//! * Time: each segment of contiguous samples has a time anchor (from its first
//!   batch); uniform sample `u` of the segment is at `t0 + u / rate`.
//! * Data quality ([`crate::daemon::quality`], unless `[quality]
//!   raw_statistics`): glitches are counted at every estimator boundary, the
//!   slow effects assessed every minute of samples or so and at the end, and their
//!   findings go into `/gyro/estimates` (`data_quality`), the metrics and the
//!   status line. Each batch's temperature goes into the pipeline with its
//!   samples (the thermal analysis). A warm-up that has settled restarts the
//!   statistics once: the old pipeline is finished (every sample it took gets
//!   its clean and noise values, so `/gyro/clean`, `/gyro/noise` and the
//!   summary windows go on without a hole or a repeat) and a new one with the
//!   same configuration takes the samples from there; only the estimates start
//!   again.
//! * Acceptance test ([`Processor::set_spec`]): at each estimator
//!   update the [`SequentialSpec`] sees the estimates (its looks are at fixed
//!   record lengths, so skipped updates only skip looks); the verdicts go to the
//!   metrics and `/gyro/verdict`, a change to the log; with a stop trigger the
//!   run is ended once every coefficient is decided, through the ordinary
//!   shutdown (drain, final estimates, finished recording).

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::daemon::shutdown::{Shutdown, ShutdownTrigger};
use crate::model::spec::{SequentialSpec, Spec, SpecReport, Verdict};

use crate::allan::AllanPoint;
use crate::daemon::batch::{Delivery, SourceBatch};
use crate::daemon::quality::LiveQuality;
use crate::daemon::queue::BatchReceiver;
use crate::daemon::status::{LiveStatus, StatusEstimate, format_coefficient};
use crate::daemon::summary::{Place, SummaryAcc};
use crate::daemon::telemetry::Telemetry;
use crate::input::frame::FilledSeries;
use crate::model::estimate::Coefficient;
use crate::pipeline::{Analysis, Pipeline, PipelineConfig, PipelineError, PipelineOutput};
use crate::recording::messages::{
    AllanCurve, AllanUpdate, EstimateUpdate, Event, EventKind, Gap, RateBatch, RawBatch,
    SinkMessage, SummaryUpdate, VerdictUpdate, recordable_quality,
};
use crate::recording::writer::{Checked, RecordError, RecordSender};
use crate::sink::metrics::{AllanChannel, Bounds95};

/// Errors building the numeric stage.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// A setting is out of range.
    #[error("processing stage: `{key}` = {value}: {reason}")]
    Config {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The pipeline cannot be built.
    #[error("processing stage")]
    Pipeline(#[from] PipelineError),
}

/// Settings of the numeric stage.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessConfig {
    /// The numeric chain (shared with `sagnac analyze`).
    pub pipeline: PipelineConfig,
    /// Seconds of samples between estimator updates.
    pub interval_s: f64,
    /// Samples per `/gyro/raw`, `/gyro/clean` and `/gyro/noise` message.
    pub batch_samples: usize,
    /// How to hand messages to the recorder.
    pub delivery: Delivery,
    /// Largest share of wall time the estimator updates may take, in (0, 1];
    /// `None`: never skip an update.
    pub update_budget: Option<f64>,
}

/// A built numeric stage, ready to run.
#[derive(Debug)]
pub struct Processor {
    cfg: ProcessConfig,
    pipeline: Pipeline,
    interval_samples: u64,
    period_ns: f64,
    dt_ns: u64,
    spec: Option<LiveSpec>,
    /// The data-quality stage's live state (`None`: the raw statistics).
    quality: Option<LiveQuality>,
}

/// The acceptance test of a live run.
#[derive(Debug)]
struct LiveSpec {
    monitor: SequentialSpec,
    /// Ends the run once every coefficient is decided.
    stop: Option<ShutdownTrigger>,
    stopped: bool,
}

impl ProcessConfig {
    /// Validate and build the pipeline.
    pub fn build(self) -> Result<Processor, ProcessError> {
        let bad = |key, value: String, reason| ProcessError::Config { key, value, reason };
        if !(self.interval_s.is_finite() && self.interval_s > 0.0) {
            return Err(bad(
                "interval_s",
                self.interval_s.to_string(),
                "must be > 0",
            ));
        }
        if self.batch_samples == 0 {
            return Err(bad("batch_samples", "0".into(), "must be > 0"));
        }
        if let Some(b) = self.update_budget
            && !(b > 0.0 && b <= 1.0)
        {
            return Err(bad("update_budget", b.to_string(), "must be in (0, 1]"));
        }
        let pipeline = Pipeline::new(&self.pipeline)?;
        let rate: f64 = self.pipeline.sample_rate_hz;
        let interval_samples = (self.interval_s * rate).round().max(1.0) as u64;
        let quality = self
            .pipeline
            .data_quality
            .then(|| LiveQuality::new(1.0 / rate));
        Ok(Processor {
            quality,
            period_ns: 1e9 / rate,
            dt_ns: (1e9 / rate).round() as u64,
            interval_samples,
            pipeline,
            cfg: self,
            spec: None,
        })
    }
}

/// Where the numeric stage publishes.
#[derive(Clone)]
pub struct Outputs {
    /// The MCAP recorder, if recording.
    pub recorder: Option<RecordSender>,
    /// Metrics.
    pub telemetry: Telemetry,
    /// The daemon's shutdown signal: once it is requested, the queued batches are
    /// drained without intermediate estimator updates (the final update is always
    /// made), so SIGTERM is prompt even when the pipeline is far behind.
    pub stop: Option<Shutdown>,
    /// The live status a terminal shows (`sagnac run` at a terminal); while it
    /// is shown, the intermediate estimate log lines go to `debug` (the final
    /// one stays at `info`).
    pub status: Option<Arc<LiveStatus>>,
}

impl std::fmt::Debug for Outputs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Outputs")
            .field("recording", &self.recorder.is_some())
            .finish_non_exhaustive()
    }
}

/// What the numeric stage did.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessReport {
    /// The final analysis (after the wavelet bank was flushed).
    pub analysis: Analysis,
    /// Samples decoded (as delivered by the source).
    pub samples: u64,
    /// Sample periods pushed through the pipeline (samples plus lost, gap-filled).
    pub periods: u64,
    /// Lost periods (device gaps and backpressure drops).
    pub lost: u64,
    /// Estimator updates published, the final one included.
    pub updates: u64,
    /// Largest estimate latency seen, s (arrival of the sample closing an
    /// interval -> estimate in the metrics).
    pub max_estimate_latency_s: f64,
    /// Messages the recorder refused (live sources with a full queue).
    pub recorder_dropped: u64,
}

/// Samples per pipeline call (plus cuts at estimator boundaries), aligned on
/// absolute sample indices.
pub const PUSH_CHUNK: u64 = 1024;

/// A time segment: uniform sample `u_start` is period `seq_start` at `t_start_ns`.
#[derive(Debug, Clone, Copy)]
struct Segment {
    u_start: u64,
    seq_start: u64,
    t_start_ns: u64,
}

/// `/gyro/raw` being assembled.
#[derive(Debug, Default)]
struct RawAcc {
    /// Uniform index of the first period covered.
    u0: u64,
    counts: Vec<i64>,
    gaps: Vec<Gap>,
}

/// `/gyro/clean` + `/gyro/noise` being assembled.
#[derive(Debug, Default)]
struct RateAcc {
    /// Uniform index of the first value.
    u0: u64,
    clean: Vec<f64>,
    noise: Vec<f64>,
}

struct Run<'a> {
    p: &'a mut Processor,
    out: &'a mut Outputs,
    segments: VecDeque<Segment>,
    /// Uniform samples pushed into the pipeline.
    pushed: u64,
    /// Clean/noise values received from the pipeline.
    emitted: u64,
    samples: u64,
    lost: u64,
    raw: RawAcc,
    rates: RateAcc,
    temp_c: Option<f64>,
    /// (uniform index from which a batch's temperature holds, the temperature),
    /// oldest first, for the samples not yet pushed.
    temps: VecDeque<(u64, f64)>,
    /// Temperatures of one push (scratch).
    push_temps: Vec<f64>,
    status: u32,
    /// Gap-filled samples not yet pushed into the pipeline.
    pending: FilledSeries,
    /// Filled spans of one push (scratch).
    push_filled: Vec<std::ops::Range<usize>>,
    /// (uniform index one past a batch's last sample, its arrival), oldest first.
    arrivals: VecDeque<(u64, Instant)>,
    pout: PipelineOutput,
    /// `/gyro/summary` windows being assembled, and those ready to record.
    summary: SummaryAcc,
    summaries: Vec<SummaryUpdate>,
    next_update_at: u64,
    /// Start and cost of the last estimator update.
    last_update: Option<(Instant, Duration)>,
    updates: u64,
    max_latency_s: f64,
    recorder_dropped: u64,
    unreported_drops: u64,
    recorder_failed: bool,
    /// Messages of the current input batch, not yet handed to the recorder.
    outbox: Vec<Checked>,
}

impl Processor {
    /// The pipeline (e.g. its latency).
    pub fn pipeline(&self) -> &Pipeline {
        &self.pipeline
    }

    /// Judge `spec` at each estimator update; with `stop`, trigger it once every
    /// coefficient is decided (`--stop-when-decided`).
    pub fn set_spec(&mut self, spec: Spec, stop: Option<ShutdownTrigger>) {
        self.spec = Some(LiveSpec {
            monitor: SequentialSpec::new(spec),
            stop,
            stopped: false,
        });
    }

    /// End the run through `stop` once every coefficient of the spec (if any) is decided.
    pub fn attach_spec_stop(&mut self, stop: ShutdownTrigger) {
        if let Some(s) = self.spec.as_mut() {
            s.stop = Some(stop);
        }
    }

    /// The acceptance test's current verdicts, if there is a spec.
    pub fn spec_report(&self) -> Option<SpecReport> {
        self.spec.as_ref().map(|s| s.monitor.report())
    }

    /// Run on the calling (blocking) thread until every sender of `input` is
    /// gone, then flush the wavelet bank and publish the final estimates.
    pub fn run(mut self, input: BatchReceiver, mut outputs: Outputs) -> ProcessReport {
        let first_update = self.interval_samples;
        let summary = SummaryAcc::new(
            self.cfg.pipeline.sample_rate_hz,
            self.cfg.pipeline.pulse_arcsec.unwrap_or(1.0),
        );
        let mut run = Run {
            p: &mut self,
            out: &mut outputs,
            segments: VecDeque::new(),
            pushed: 0,
            emitted: 0,
            samples: 0,
            lost: 0,
            raw: RawAcc::default(),
            rates: RateAcc::default(),
            temp_c: None,
            temps: VecDeque::new(),
            push_temps: Vec::new(),
            status: 0,
            pending: FilledSeries::default(),
            push_filled: Vec::new(),
            arrivals: VecDeque::new(),
            pout: PipelineOutput::default(),
            summary,
            summaries: Vec::new(),
            next_update_at: first_update,
            last_update: None,
            updates: 0,
            max_latency_s: 0.0,
            recorder_dropped: 0,
            unreported_drops: 0,
            recorder_failed: false,
            outbox: Vec::new(),
        };
        input.for_each_blocking(|batch| {
            run.batch(batch);
            run.send_outbox();
        });
        run.finish()
    }
}

fn bounds(c: &Coefficient) -> Bounds95 {
    Bounds95 {
        estimate: c.value,
        lower95: c.ci95.map(|c| c[0]),
        upper95: c.ci95.map(|c| c[1]).or(c.upper95),
    }
}

/// `c` as recorded: non-finite numbers dropped (JSON cannot carry them).
fn recordable(c: &Coefficient) -> Coefficient {
    let finite = |v: Option<f64>| v.filter(|x| x.is_finite());
    Coefficient {
        value: finite(c.value),
        ci95: c.ci95.filter(|ci| ci.iter().all(|x| x.is_finite())),
        upper95: finite(c.upper95),
    }
}

/// Uniform sample `u` of the time segments `segments` (each anchored at its
/// first sample), ns: `t0 + (u - u_start) * period_ns`.
fn time_at(segments: &VecDeque<Segment>, period_ns: f64, u: u64) -> u64 {
    let seg = segments
        .iter()
        .rev()
        .find(|s| s.u_start <= u)
        .or(segments.front());
    match seg {
        Some(s) => {
            let d = u as f64 - s.u_start as f64;
            (s.t_start_ns as f64 + d * period_ns).round().max(0.0) as u64
        }
        None => 0,
    }
}

fn curve(points: &[AllanPoint]) -> AllanCurve {
    let ok: Vec<&AllanPoint> = points
        .iter()
        .filter(|p| {
            [p.tau_s, p.dev, p.ci_lo, p.ci_hi]
                .iter()
                .all(|v| v.is_finite())
        })
        .collect();
    AllanCurve {
        tau_s: ok.iter().map(|p| p.tau_s).collect(),
        dev: ok.iter().map(|p| p.dev).collect(),
        ci_lo: ok.iter().map(|p| p.ci_lo).collect(),
        ci_hi: ok.iter().map(|p| p.ci_hi).collect(),
        n: ok.iter().map(|p| p.n).collect(),
    }
}

impl Run<'_> {
    fn time_of(&self, u: u64) -> u64 {
        time_at(&self.segments, self.p.period_ns, u)
    }

    fn seq_of(&self, u: u64) -> u64 {
        match self.segments.iter().rev().find(|s| s.u_start <= u) {
            Some(s) => s.seq_start + (u - s.u_start),
            None => u,
        }
    }

    /// Drop segments no pending output can refer to.
    fn prune_segments(&mut self) {
        let mut oldest = self.emitted;
        if !self.raw.counts.is_empty() {
            oldest = oldest.min(self.raw.u0);
        }
        if !self.rates.clean.is_empty() {
            oldest = oldest.min(self.rates.u0);
        }
        while self.segments.len() > 1 && self.segments[1].u_start <= oldest {
            self.segments.pop_front();
        }
    }

    /// Queue `msg` for the recorder; the messages of one input batch go to the
    /// writer thread together ([`Run::send_outbox`]).
    fn record(&mut self, msg: SinkMessage) {
        if self.recorder_failed {
            return;
        }
        let Some(rec) = &self.out.recorder else {
            return;
        };
        match rec.checked(msg) {
            Ok(m) => self.outbox.push(m),
            Err(e) => tracing::warn!(error = %crate::chain::chain(&e), "message not recorded"),
        }
    }

    /// Hand the queued messages to the recorder (entries of up to
    /// [`crate::recording::writer::GROUP_MAX`] messages, one wake of the writer thread
    /// each), blocking for lossless sources. A live source blocks for the data
    /// (raw, clean, noise, events, summaries: the record of the measurement, so a
    /// slow disk backs up into the source queue, whose drops keep the angle) and
    /// offers the statistics (estimates, Allan curves: recomputable from the data)
    /// without blocking; those a full queue refuses are dropped, counted.
    fn send_outbox(&mut self) {
        let msgs = std::mem::take(&mut self.outbox);
        let Some(rec) = &self.out.recorder else {
            return;
        };
        if msgs.is_empty() || self.recorder_failed {
            return;
        }
        let before = rec.dropped();
        let r = if self.p.cfg.delivery == Delivery::Live {
            let (stats, data): (Vec<_>, Vec<_>) =
                msgs.into_iter().partition(|m| m.message().is_statistic());
            rec.send_all(data).and_then(|()| rec.try_send_all(stats))
        } else {
            rec.send_all(msgs)
        };
        let n = rec.dropped() - before;
        match r {
            Ok(()) => {
                if self.unreported_drops > 0 {
                    let dropped = std::mem::take(&mut self.unreported_drops);
                    let ev = SinkMessage::Event(Event {
                        t_ns: self.time_of(self.pushed.saturating_sub(1)),
                        kind: EventKind::BackpressureDrop {
                            sink: "mcap".into(),
                            dropped,
                        },
                        gyro: None,
                    });
                    if rec.try_send(ev).is_err() {
                        self.unreported_drops += dropped;
                    }
                }
            }
            Err(RecordError::QueueFull { .. }) => {
                if self.recorder_dropped == 0 {
                    tracing::warn!(
                        "MCAP recorder queue full: dropping statistics messages (counted)"
                    );
                }
                self.recorder_dropped += n;
                self.unreported_drops += n;
                self.out
                    .telemetry
                    .dropped_messages
                    .with_label_values(&["mcap"])
                    .inc_by(n);
            }
            Err(e) => {
                // The writer thread stopped; finish() reports its error.
                tracing::error!(error = %crate::chain::chain(&e), "MCAP recorder stopped: recording disabled for the rest of the run");
                self.recorder_failed = true;
            }
        }
    }

    fn record_summaries(&mut self) {
        let ready = std::mem::take(&mut self.summaries);
        for m in ready {
            self.record(SinkMessage::Summary(m));
        }
    }

    fn flush_raw(&mut self) {
        if self.raw.counts.is_empty() {
            return;
        }
        let raw = std::mem::take(&mut self.raw);
        let msg = RawBatch {
            t0_ns: self.time_of(raw.u0),
            dt_ns: self.p.dt_ns,
            seq0: self.seq_of(raw.u0),
            counts: raw.counts,
            gaps: raw.gaps,
            temp_c: self.temp_c,
            status: self.status,
        };
        self.record(SinkMessage::Raw(msg));
    }

    fn flush_rates(&mut self) {
        if self.rates.clean.is_empty() {
            return;
        }
        let r = std::mem::take(&mut self.rates);
        let t0_ns = self.time_of(r.u0);
        let dt_ns = self.p.dt_ns;
        self.record(SinkMessage::Clean(RateBatch {
            t0_ns,
            dt_ns,
            values: r.clean,
        }));
        self.record(SinkMessage::Noise(RateBatch {
            t0_ns,
            dt_ns,
            values: r.noise,
        }));
    }

    /// Take the pipeline's clean/noise output into the rate messages.
    fn take_output(&mut self) {
        self.summary
            .push_clean(self.emitted, &self.pout.clean_dph, &mut self.summaries);
        self.record_summaries();
        let n = self.pout.clean_dph.len();
        let bs = self.p.cfg.batch_samples;
        let mut i = 0;
        while i < n {
            if self.rates.clean.is_empty() {
                self.rates.u0 = self.emitted;
            }
            // A message never spans the start of a new time segment.
            let seg_end = self
                .segments
                .iter()
                .map(|s| s.u_start)
                .find(|&u| u > self.emitted)
                .map_or(usize::MAX, |u| (u - self.emitted) as usize);
            let take = (bs - self.rates.clean.len()).min(n - i).min(seg_end);
            self.rates
                .clean
                .extend_from_slice(&self.pout.clean_dph[i..i + take]);
            self.rates
                .noise
                .extend_from_slice(&self.pout.noise_dph[i..i + take]);
            self.emitted += take as u64;
            i += take;
            let at_segment = self.segments.iter().any(|s| s.u_start == self.emitted);
            if self.rates.clean.len() >= bs || at_segment {
                self.flush_rates();
            }
        }
        self.pout.clear();
    }

    fn batch(&mut self, b: SourceBatch) {
        for ev in b.events {
            self.record(SinkMessage::Event(ev));
        }
        if let Some(t) = b.temp_c {
            self.temp_c = Some(t);
            self.out.telemetry.gyro.set_temperature_c(Some(t));
        }
        if let Some(s) = b.status {
            self.status = s;
        }
        if b.counts.is_empty() {
            return;
        }
        let u_next = self.pushed + self.pending.len() as u64;
        if let Some(t) = self.temp_c
            && self.p.quality.is_some()
            && self.temps.back().is_none_or(|&(_, last)| last != t)
        {
            self.temps.push_back((u_next, t));
        }
        if b.new_segment || self.segments.is_empty() {
            self.flush_raw();
            self.segments.push_back(Segment {
                u_start: u_next,
                seq_start: b.seq0,
                t_start_ns: b.t0_ns,
            });
        }
        // Gap-fill into the uniform series; assemble /gyro/raw on the way.
        // A sample after a gap is filled on its own; the gap-free run up to
        // the next gap (or a full /gyro/raw message) is copied whole.
        let bs = self.p.cfg.batch_samples;
        let (n, mut gi, mut i) = (b.counts.len(), 0, 0);
        while i < n {
            let mut lost = 0u64;
            while gi < b.gaps.len() && b.gaps[gi].index == i as u64 {
                lost += b.gaps[gi].lost;
                gi += 1;
            }
            if self.raw.counts.is_empty() {
                self.raw.u0 = self.pushed + self.pending.len() as u64;
            }
            let end = if lost > 0 {
                self.raw.gaps.push(Gap {
                    index: self.raw.counts.len() as u64,
                    lost,
                });
                self.lost += lost;
                self.pending.push(b.counts[i], lost);
                self.raw.counts.push(b.counts[i]);
                i + 1
            } else {
                let next_gap = b
                    .gaps
                    .get(gi)
                    .map_or(n, |g| (g.index as usize).clamp(i + 1, n));
                let room = bs.saturating_sub(self.raw.counts.len()).max(1);
                let end = next_gap.min(i + room);
                self.pending.push_run(&b.counts[i..end]);
                self.raw.counts.extend_from_slice(&b.counts[i..end]);
                end
            };
            i = end;
            if self.raw.counts.len() >= bs {
                self.flush_raw();
            }
        }
        self.samples += b.counts.len() as u64;
        if let Some(st) = &self.out.status {
            st.set_counts(self.samples, self.lost);
        }
        self.arrivals
            .push_back((self.pushed + self.pending.len() as u64, b.arrived));
        self.push_ready(false);
        self.prune_segments();
        if let Some(rec) = &self.out.recorder {
            self.out
                .telemetry
                .metrics
                .set_recording_bytes(rec.bytes_written());
        }
    }

    /// Push the pending uniform samples into the pipeline in canonical pieces:
    /// cut at every multiple of [`PUSH_CHUNK`] and at every estimator boundary
    /// (absolute sample indices), so the pipeline sees the same calls whatever
    /// the source's batching (a live run and the replay of its recording give
    /// bit-identical results). `all`: push the remainder too (end of stream).
    fn push_ready(&mut self, all: bool) {
        let mut start = 0usize;
        loop {
            let avail = self.pending.len() - start;
            if avail == 0 {
                break;
            }
            let to_chunk = PUSH_CHUNK - self.pushed % PUSH_CHUNK;
            let to_update = self.next_update_at - self.pushed;
            let cut = to_chunk.min(to_update) as usize;
            let n = if avail >= cut {
                cut
            } else if all {
                avail
            } else {
                break;
            };
            self.push_filled.clear();
            self.pending
                .filled_in(start..start + n, &mut self.push_filled);
            let (segments, period_ns) = (&self.segments, self.p.period_ns);
            let place = |u: u64| {
                let k = segments.partition_point(|s| s.u_start <= u);
                Place {
                    segment_start: k.checked_sub(1).map_or(0, |i| segments[i].u_start),
                    next_segment: segments.get(k).map(|s| s.u_start),
                    t_ns: time_at(segments, period_ns, u),
                }
            };
            self.summary.push_raw(
                self.pushed,
                &self.pending.counts[start..start + n],
                &self.push_filled,
                self.temp_c,
                &place,
            );
            self.push_temperatures(n);
            self.p.pipeline.push_counts_filled(
                &self.pending.counts[start..start + n],
                &self.push_filled,
                &mut self.pout,
            );
            self.pushed += n as u64;
            start += n;
            self.take_output();
            if self.pushed == self.next_update_at {
                self.next_update_at += self.p.interval_samples;
                self.boundary();
            }
        }
        self.pending.drain_front(start);
        // Processing lag: the newest batch whose samples are all in the pipeline.
        let mut newest = None;
        while let Some(&(end, arrived)) = self.arrivals.front() {
            if end > self.pushed {
                break;
            }
            newest = Some(arrived);
            self.arrivals.pop_front();
        }
        if let Some(a) = newest {
            self.out
                .telemetry
                .gyro
                .set_processing_lag_s(a.elapsed().as_secs_f64());
        }
    }

    /// The temperatures of the next `n` samples pushed (each batch's for its
    /// own samples) into the pipeline, for the thermal analysis.
    fn push_temperatures(&mut self, n: usize) {
        if self.temps.is_empty() {
            return;
        }
        let end = self.pushed + n as u64;
        self.push_temps.clear();
        let mut k = 0;
        for u in self.pushed..end {
            while k + 1 < self.temps.len() && self.temps[k + 1].0 <= u {
                k += 1;
            }
            let (from, t) = self.temps[k];
            self.push_temps.push(if from <= u { t } else { f64::NAN });
        }
        let first = self.p.pipeline.samples_in();
        self.p.pipeline.push_temperature(first, &self.push_temps);
        while self.temps.len() > 1 && self.temps[1].0 <= end {
            self.temps.pop_front();
        }
    }

    /// At an estimator boundary: count the glitches; assess the slow effects
    /// when due (by sample count, so whatever the pace); publish an update
    /// unless draining or over the update budget; restart the statistics after
    /// a warm-up that has settled.
    fn boundary(&mut self) {
        let draining = self.out.stop.as_ref().is_some_and(Shutdown::is_requested);
        let due = !draining
            && match (self.p.cfg.update_budget, self.last_update) {
                (Some(budget), Some((t, cost))) => {
                    t.elapsed().as_secs_f64() * budget >= cost.as_secs_f64()
                }
                _ => true,
            };
        let samples = self.p.pipeline.samples_in();
        let assess = !draining && self.p.quality.as_mut().is_some_and(|q| q.due(samples));
        let mut restart = false;
        if due || assess {
            let start = Instant::now();
            let mut a = self.p.pipeline.analysis();
            let estimated = start.elapsed();
            if let Some(q) = self.p.quality.as_mut() {
                if assess {
                    restart = q.assess(&self.p.pipeline, &a.estimates, false);
                    if self.p.pipeline.set_ramp_rejected(q.ramp_rejected()) {
                        a = self.p.pipeline.analysis();
                    }
                    tracing::debug!(
                        gyro = self.out.telemetry.gyro.label(),
                        cost_s = (start.elapsed() - estimated).as_secs_f64(),
                        "data-quality assessment"
                    );
                }
                a.data_quality = q.report();
            }
            if due {
                // when the sample that closed the interval arrived
                let pushed = self.pushed;
                let arrived = self
                    .arrivals
                    .iter()
                    .find(|(end, _)| *end >= pushed)
                    .map_or_else(Instant::now, |(_, a)| *a);
                let published = Instant::now();
                self.publish(&a, arrived, false);
                // the budget is the updates': the assessments are made whatever the pace
                self.last_update = Some((start, estimated + published.elapsed()));
            }
        }
        if restart {
            self.restart_statistics();
        }
        self.publish_quality();
    }

    /// Glitch counts, warm-up and steps to the metrics and the status line.
    fn publish_quality(&mut self) {
        if let Some(q) = self.p.quality.as_mut() {
            q.publish(
                &self.p.pipeline,
                &self.out.telemetry.gyro,
                self.out.status.as_deref(),
            );
        }
    }

    /// Restart the statistics after a warm-up: finish the pipeline (every
    /// sample pushed gets its clean and noise values, which go out as usual)
    /// and push the samples from here on into a new one of the same
    /// configuration.
    fn restart_statistics(&mut self) {
        let fresh = match Pipeline::new(&self.p.cfg.pipeline) {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!(error = %e, "statistics not restarted after the warm-up");
                return;
            }
        };
        self.p.pipeline.finish(&mut self.pout);
        self.take_output();
        debug_assert_eq!(self.emitted, self.pushed, "every sample pushed came out");
        let old = std::mem::replace(&mut self.p.pipeline, fresh);
        let Some(q) = self.p.quality.as_mut() else {
            return;
        };
        q.restart(&old, self.pushed);
        let w = q.report().and_then(|d| d.warmup);
        tracing::info!(
            gyro = self.out.telemetry.gyro.label(),
            excluded_s = q.excluded_s().unwrap_or(0.0),
            warmup_amplitude_dph = w.as_ref().map_or(0.0, |w| w.amplitude_dph.value),
            warmup_tau_s = w.as_ref().map_or(0.0, |w| w.tau_s.value),
            "warm-up settled: statistics restarted, the data before left out"
        );
    }

    fn publish(&mut self, a: &Analysis, arrived: Instant, last: bool) {
        let tel = self.out.telemetry.clone();
        let m = &tel.gyro;
        let e = &a.estimates;
        m.set_qn_arcsec(bounds(&e.quantization_arcsec));
        m.set_arw_dpsh(bounds(&e.arw_dpsh));
        m.set_bias_instability_dph(bounds(&e.bias_instability_dph));
        m.set_rrw_dphsh(bounds(&e.rrw_dphsh));
        m.set_rate_ramp_dphh(bounds(&e.rate_ramp_dphh));
        for (ch, pts) in [
            (AllanChannel::Raw, &a.allan.raw),
            (AllanChannel::Clean, &a.allan.clean),
        ] {
            let c = curve(pts);
            if let Err(err) = m.set_allan_curve(ch, &c.tau_s, &c.dev) {
                tracing::warn!(error = %crate::chain::chain(&err), "Allan curve not exported");
            }
        }
        tel.estimator_updates.inc();
        let latency = arrived.elapsed().as_secs_f64();
        if !last {
            tel.estimate_latency.observe(latency);
            self.max_latency_s = self.max_latency_s.max(latency);
        }
        self.updates += 1;
        let t_ns = self.time_of(self.pushed.saturating_sub(1));
        let estimates = crate::model::estimate::NoiseEstimates {
            quantization_arcsec: recordable(&e.quantization_arcsec),
            arw_dpsh: recordable(&e.arw_dpsh),
            bias_instability_dph: recordable(&e.bias_instability_dph),
            rrw_dphsh: recordable(&e.rrw_dphsh),
            rate_ramp_dphh: recordable(&e.rate_ramp_dphh),
        };
        self.record(SinkMessage::Estimates(EstimateUpdate {
            t_ns,
            samples: a.samples,
            duration_s: a.duration_s,
            estimates,
            data_quality: a.data_quality.as_ref().map(recordable_quality),
        }));
        let mut curves = BTreeMap::new();
        curves.insert("raw".to_string(), curve(&a.allan.raw));
        curves.insert("clean".to_string(), curve(&a.allan.clean));
        curves.insert("noise".to_string(), curve(&a.allan.noise));
        self.record(SinkMessage::Allan(AllanUpdate::new(t_ns, curves)));
        if let Some(st) = &self.out.status {
            st.set_estimate(StatusEstimate {
                quantization_arcsec: e.quantization_arcsec,
                arw_dpsh: e.arw_dpsh,
                fit: a.fit,
                final_update: last,
            });
        }
        // fixed notation, names as in `analyze --json`; at a terminal the status
        // line shows the intermediate updates
        macro_rules! estimate_line {
            ($level:expr) => {
                tracing::event!(
                    $level,
                    gyro = self.out.telemetry.gyro.label(),
                    final_update = last,
                    samples = a.samples,
                    duration_s = a.duration_s,
                    lost = self.lost,
                    quantization_arcsec = %format_coefficient(&e.quantization_arcsec),
                    arw_dpsh = %format_coefficient(&e.arw_dpsh),
                    bias_instability_dph = %format_coefficient(&e.bias_instability_dph),
                    fit_ok = a.fit.ok,
                    latency_s = latency,
                    "estimate"
                )
            };
        }
        if self.out.status.is_some() && !last {
            estimate_line!(tracing::Level::DEBUG);
        } else {
            estimate_line!(tracing::Level::INFO);
        }
        self.judge(a, t_ns, last);
    }

    /// The acceptance test at an estimator update.
    fn judge(&mut self, a: &Analysis, t_ns: u64, last: bool) {
        let Some(spec) = self.p.spec.as_mut() else {
            return;
        };
        let held = self.p.quality.as_ref().and_then(LiveQuality::held);
        let seen = spec.monitor.observe_held(&a.estimates, a.duration_s, held);
        let report = spec.monitor.report();
        let all_decided = spec.monitor.all_decided();
        let m = &self.out.telemetry.gyro;
        m.set_spec("overall", report.verdict.metric(), None, None);
        for (name, c) in &report.coefficients {
            let eta = if c.verdict == Verdict::Undecided {
                c.eta_s
            } else {
                Some(0.0)
            };
            m.set_spec(name, c.verdict.metric(), Some(c.limit), eta);
        }
        if seen.changed {
            let each: Vec<String> = report
                .coefficients
                .iter()
                .map(|(n, c)| format!("{n}={}", c.verdict.as_str()))
                .collect();
            tracing::info!(
                verdict = report.verdict.as_str(),
                coefficients = %each.join(" "),
                look = report.look,
                z = report.z,
                duration_s = report.duration_s,
                "spec verdict"
            );
        }
        let stop = if all_decided && !spec.stopped && !last {
            spec.stopped = true;
            spec.stop.clone()
        } else {
            None
        };
        self.record(SinkMessage::Verdict(VerdictUpdate::new(t_ns, &report)));
        if let Some(trigger) = stop {
            tracing::info!(
                verdict = report.verdict.as_str(),
                duration_s = report.duration_s,
                "every coefficient of the spec is decided: stopping (drain, final estimates, recording)"
            );
            trigger.trigger();
        }
    }

    fn finish(mut self) -> ProcessReport {
        self.push_ready(true);
        self.p.pipeline.finish(&mut self.pout);
        self.take_output();
        self.summary.finish(self.pushed, &mut self.summaries);
        self.record_summaries();
        self.flush_raw();
        self.flush_rates();
        let mut a = self.p.pipeline.analysis();
        if let Some(q) = self.p.quality.as_mut() {
            q.assess(&self.p.pipeline, &a.estimates, true);
            if self.p.pipeline.set_ramp_rejected(q.ramp_rejected()) {
                a = self.p.pipeline.analysis();
            }
            a.data_quality = q.report();
        }
        self.publish_quality();
        if a.samples > 0 {
            self.publish(&a, Instant::now(), true);
        }
        self.send_outbox();
        if self.unreported_drops > 0
            && let Some(rec) = &self.out.recorder
        {
            // Blocking: at the end there is time to wait for room.
            let _ = rec.send(SinkMessage::Event(Event {
                t_ns: self.time_of(self.pushed.saturating_sub(1)),
                kind: EventKind::BackpressureDrop {
                    sink: "mcap".into(),
                    dropped: self.unreported_drops,
                },
                gyro: None,
            }));
        }
        if let Some(rec) = &self.out.recorder {
            self.out
                .telemetry
                .metrics
                .set_recording_bytes(rec.bytes_written());
        }
        ProcessReport {
            analysis: a,
            samples: self.samples,
            periods: self.pushed,
            lost: self.lost,
            updates: self.updates,
            max_estimate_latency_s: self.max_latency_s,
            recorder_dropped: self.recorder_dropped,
        }
    }
}
