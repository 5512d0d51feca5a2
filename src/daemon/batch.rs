//! What travels from a source task to the numeric pipeline thread: a
//! [`SourceBatch`] of decoded samples (not yet gap-filled) with the events met
//! while decoding them, built by an [`Assembler`] from the frame decoder's
//! output and delivered by a [`BatchSender`] through a bounded queue.
//!
//! # Sequence numbers and time
//! Samples are numbered by an *unwrapped* sequence number: the 16-bit frame
//! `seq` of the decoder's baseline, then +1 per sample period, gaps included
//! (its low 16 bits are the frame `seq` until a discontinuity). Time follows the
//! device's sample clock: the first sample's arrival (host clock, ns since the
//! Unix epoch) anchors it, and period `s` is at `anchor + (s - s_anchor) / rate`.
//! A discontinuity (the gyro or the link restarted with a new sequence) starts a
//! new segment, re-anchored on the host clock.
//!
//! # Gaps
//! As in the decoder ([`crate::input::frame`]): a sample that follows `lost`
//! missing samples carries the WHOLE counter difference over the `lost + 1`
//! periods, and the batch records `Gap { index, lost }` before it (the
//! representation of `/gyro/raw`). The sum of the counts is therefore the true
//! number of pulses, whatever was lost. The pipeline thread spreads such an
//! increment over the missing periods ([`crate::dsp::gaps::spread_increment`]).
//!
//! # Delivery
//! [`Delivery::Lossless`] (replays, the simulated bench) waits for room in a
//! queue of a few batches: backpressure slows the source down. [`Delivery::Live`]
//! (the serial port, which cannot be paused) never waits, and its queue is bounded
//! by a memory budget ([`crate::daemon::queue`]): a batch that does not fit in
//! what is left of it is dropped, counted in `sagnac_dropped_samples_total`, and
//! folded into the next batch that fits as a gap (its pulses are added to that
//! batch's first sample, so no angle is lost), with a `backpressure_drop` event.

use std::time::{Instant, SystemTime, UNIX_EPOCH};

use crate::daemon::queue::{self, BatchReceiver, QueueBound, QueueTx};
pub use crate::daemon::queue::{PipelineClosed, SourceBatch};
use crate::daemon::telemetry::{
    ANOMALY_DISCONTINUITY, ANOMALY_DUPLICATE, ANOMALY_OUT_OF_SEQUENCE, Telemetry,
};
use crate::input::frame::{DecodeEvent, Decoded, DecoderStats, RunEnd};
use crate::recording::messages::{Event, EventKind, Gap};
use crate::sink::metrics::FrameErrorKind;

/// Nanoseconds since the Unix epoch, host clock (0 if the clock is before 1970).
pub fn wall_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// Turns frame-decoder output into [`SourceBatch`]es and counts it in the metrics.
#[derive(Debug)]
pub struct Assembler {
    period_ns: f64,
    limit_periods: Option<u64>,
    /// Unwrapped sequence number of the next sample period (`None` before the baseline).
    next_seq: Option<u64>,
    /// Periods assembled so far.
    periods: u64,
    /// Time anchor of the current segment: (seq, t_ns).
    anchor: Option<(u64, u64)>,
    batch: SourceBatch,
    batch_started: bool,
    next_new_segment: bool,
    stats: DecoderStats,
    truncated: u64,
    telemetry: Telemetry,
    /// Whether bytes read are counted here (once per stream of several gyros).
    counts_bytes: bool,
}

impl Assembler {
    /// For a gyro sampled at `sample_rate_hz`; stop after `limit_periods` sample periods.
    pub fn new(sample_rate_hz: f64, limit_periods: Option<u64>, telemetry: Telemetry) -> Self {
        Assembler {
            period_ns: 1e9 / sample_rate_hz,
            limit_periods,
            next_seq: None,
            periods: 0,
            anchor: None,
            batch: SourceBatch::new(Instant::now()),
            batch_started: false,
            next_new_segment: false,
            stats: DecoderStats::default(),
            truncated: 0,
            telemetry,
            counts_bytes: true,
        }
    }

    /// Whether this assembler counts the stream's bytes read (the first gyro
    /// of a triad does; the others share its stream).
    pub fn count_bytes(&mut self, on: bool) {
        self.counts_bytes = on;
    }

    /// The gyro's telemetry.
    pub fn telemetry(&self) -> &Telemetry {
        &self.telemetry
    }

    /// Whether the period limit is reached (the source should stop).
    pub fn done(&self) -> bool {
        self.limit_periods.is_some_and(|l| self.periods >= l)
    }

    /// Sample periods assembled (samples plus lost).
    pub fn periods(&self) -> u64 {
        self.periods
    }

    /// Samples assembled and not yet taken.
    pub fn pending_samples(&self) -> usize {
        self.batch.counts.len()
    }

    /// Whether anything (samples or events) waits to be taken.
    pub fn has_pending(&self) -> bool {
        !self.batch.is_empty()
    }

    /// Partial frames dropped at an end of stream or disconnect.
    pub fn truncated(&self) -> u64 {
        self.truncated
    }

    /// Time of unwrapped period `seq` on the sample clock, or `now_ns` before
    /// the clock is anchored.
    fn time_of(&self, seq: u64, now_ns: u64) -> u64 {
        match self.anchor {
            Some((s, t)) => {
                let d = seq as f64 - s as f64;
                (t as f64 + d * self.period_ns).round().max(0.0) as u64
            }
            None => now_ns,
        }
    }

    fn event_time(&self, now_ns: u64) -> u64 {
        match self.next_seq {
            Some(s) => self.time_of(s, now_ns),
            None => now_ns,
        }
    }

    /// Add an event (device events, backpressure) at `t_ns`.
    pub fn push_event(&mut self, t_ns: u64, kind: EventKind) {
        self.batch.events.push(Event {
            t_ns,
            kind,
            gyro: None,
        });
    }

    /// Add one decoder item that arrived at `now_ns` (host clock).
    pub fn push(&mut self, item: Decoded, now_ns: u64) {
        match item {
            Decoded::Sample(s) => {
                if self.done() {
                    return;
                }
                // The decoder emits a baseline event before any sample.
                let first = self
                    .next_seq
                    .unwrap_or(u64::from(s.seq.wrapping_sub(s.lost_before)));
                let lost = u64::from(s.lost_before);
                let seq = first + lost;
                self.start_batch(first, seq, now_ns);
                if lost > 0 {
                    self.batch.gaps.push(Gap {
                        index: self.batch.counts.len() as u64,
                        lost,
                    });
                }
                self.batch.counts.push(s.increment);
                self.batch.temp_c = Some(s.temp_c);
                self.batch.status = Some(u32::from(s.status));
                self.next_seq = Some(seq + 1);
                self.periods += lost + 1;
            }
            Decoded::Event(ev) => self.push_decode_event(ev, now_ns),
        }
    }

    /// Before the first sample of the batch (unwrapped period `first`, its first
    /// received sample at `seq`): anchor the sample clock if needed, start the batch.
    fn start_batch(&mut self, first: u64, seq: u64, now_ns: u64) {
        if self.anchor.is_none() {
            self.anchor = Some((seq, now_ns));
        }
        if !self.batch_started {
            self.batch.seq0 = first;
            self.batch.t0_ns = self.time_of(first, now_ns);
            self.batch.new_segment = std::mem::take(&mut self.next_new_segment);
            self.batch_started = true;
        }
    }

    /// Sample periods left before the period limit (`usize::MAX` without one).
    pub fn room(&self) -> usize {
        self.limit_periods.map_or(usize::MAX, |l| {
            usize::try_from(l.saturating_sub(self.periods)).unwrap_or(usize::MAX)
        })
    }

    /// A run of contiguous samples from [`FrameDecoder::decode_run`](crate::input::frame::FrameDecoder::decode_run):
    /// the same as [`push`](Self::push)ing each as a sample with no loss before it.
    /// The run must fit in [`room`](Self::room) (the caller bounds the decoder by it).
    pub fn push_run(&mut self, increments: &[i64], end: &RunEnd, now_ns: u64) {
        let n = increments.len();
        debug_assert!(n <= self.room(), "run of {n} beyond the period limit");
        if n == 0 || self.done() {
            return;
        }
        let first = self
            .next_seq
            .unwrap_or(u64::from(end.seq.wrapping_sub((n - 1) as u16)));
        self.start_batch(first, first, now_ns);
        self.batch.counts.extend_from_slice(increments);
        self.batch.temp_c = Some(end.temp_c);
        self.batch.status = Some(u32::from(end.status));
        self.next_seq = Some(first + n as u64);
        self.periods += n as u64;
    }

    fn push_decode_event(&mut self, ev: DecodeEvent, now_ns: u64) {
        let t_ns = self.event_time(now_ns);
        match ev {
            DecodeEvent::Baseline { seq, .. } => {
                if self.next_seq.is_none() {
                    self.next_seq = Some(u64::from(seq) + 1);
                }
            }
            DecodeEvent::Resync {
                skipped_bytes,
                at_offset,
            } => self.push_event(
                t_ns,
                EventKind::Resync {
                    byte_offset: at_offset,
                    skipped_bytes,
                },
            ),
            DecodeEvent::CrcError { offset, .. } => self.push_event(
                t_ns,
                EventKind::CrcError {
                    byte_offset: offset,
                },
            ),
            DecodeEvent::FalseSync { .. } => {} // counted from the decoder stats
            DecodeEvent::Gap { lost, .. } => {
                let seq = self.next_seq.unwrap_or(0);
                self.push_event(
                    t_ns,
                    EventKind::Gap {
                        seq,
                        lost: u64::from(lost),
                    },
                );
            }
            DecodeEvent::StatusChange { from, to, .. } => self.push_event(
                t_ns,
                EventKind::StatusChange {
                    from: u32::from(from),
                    to: u32::from(to),
                },
            ),
            DecodeEvent::Duplicate { seq, offset } => {
                tracing::debug!(seq, offset, "duplicate frame dropped");
                self.telemetry.add_sequence_anomaly(ANOMALY_DUPLICATE);
            }
            DecodeEvent::OutOfSequence {
                seq,
                expected,
                offset,
            } => {
                tracing::warn!(seq, expected, offset, "out-of-sequence frame dropped");
                self.telemetry.add_sequence_anomaly(ANOMALY_OUT_OF_SEQUENCE);
            }
            DecodeEvent::Discontinuity {
                from_seq,
                to_seq,
                offset,
            } => {
                tracing::warn!(
                    from_seq,
                    to_seq,
                    offset,
                    "sequence discontinuity: the gyro or the link restarted; new baseline, \
                     the angle across the break is unknown and not counted"
                );
                self.telemetry.add_sequence_anomaly(ANOMALY_DISCONTINUITY);
                // New time segment, anchored on the host clock at the next sample.
                self.anchor = None;
                self.next_new_segment = true;
            }
            DecodeEvent::EndOfStream {
                skipped_bytes,
                trailing_bytes,
                at_offset,
            } => {
                if trailing_bytes > 0 {
                    self.truncated += 1;
                    self.telemetry
                        .gyro
                        .add_frame_errors(FrameErrorKind::Truncated, 1);
                    let from = at_offset.saturating_sub(trailing_bytes);
                    tracing::warn!(
                        trailing_bytes,
                        offset = from,
                        "the stream ends in a partial frame: {trailing_bytes} bytes from byte \
                         offset {from} ignored (counted as a truncated frame)"
                    );
                } else {
                    tracing::debug!(
                        skipped_bytes,
                        at_offset,
                        "end of stream inside skipped bytes"
                    );
                }
            }
        }
    }

    /// Count what the decoder did since the last call in the metrics.
    pub fn sync_stats(&mut self, stats: &DecoderStats) {
        let m = &self.telemetry.gyro;
        let old = self.stats;
        if self.counts_bytes {
            self.telemetry
                .metrics
                .add_bytes_read(stats.bytes_read - old.bytes_read);
        }
        m.add_frames_decoded(stats.frames_decoded - old.frames_decoded);
        m.add_samples(stats.samples - old.samples);
        m.add_lost_samples(stats.lost_samples - old.lost_samples);
        m.add_frame_errors(FrameErrorKind::Crc, stats.crc_errors - old.crc_errors);
        m.add_frame_errors(
            FrameErrorKind::FalseSync,
            stats.false_syncs - old.false_syncs,
        );
        self.stats = *stats;
    }

    /// The batch assembled so far (`None` when empty); `arrived` is when its
    /// newest sample arrived or was due.
    pub fn take(&mut self, arrived: Instant) -> Option<SourceBatch> {
        if self.batch.is_empty() {
            return None;
        }
        self.batch_started = false;
        let mut b = std::mem::replace(&mut self.batch, SourceBatch::new(arrived));
        b.arrived = arrived;
        if b.counts.is_empty() {
            // Events only: place the batch at the next period.
            b.seq0 = self.next_seq.unwrap_or(0);
            b.t0_ns = b.events.first().map_or(0, |e| e.t_ns);
        }
        Some(b)
    }
}

/// What a source did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceReport {
    /// Bytes read.
    pub bytes_read: u64,
    /// Samples decoded.
    pub samples: u64,
    /// Sample periods covered (samples plus lost).
    pub periods: u64,
    /// Times the device went away.
    pub disconnects: u64,
}

/// How a source hands batches to the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Wait for room (replays, the simulated bench): backpressure.
    Lossless,
    /// Never wait (a serial port): drop, count and fold into the next batch.
    Live,
}

/// What a live source had to drop, kept compact until the next batch fits.
#[derive(Debug, Clone, PartialEq)]
struct Dropped {
    seq0: u64,
    t0_ns: u64,
    /// Periods covered (samples + lost).
    periods: u64,
    /// Sum of the dropped increments, pulses.
    pulses: i64,
    /// Samples dropped (not counting the lost ones they covered).
    samples: u64,
    events: Vec<Event>,
    new_segment: bool,
}

/// Most events kept from dropped batches.
const MAX_HELD_EVENTS: usize = 4096;

/// The sending end of the source -> pipeline queue ([`crate::daemon::queue`]).
#[derive(Debug)]
pub struct BatchSender {
    queue: QueueTx,
    delivery: Delivery,
    held: Option<Dropped>,
    telemetry: Telemetry,
}

/// A source -> pipeline queue bounded by `bound`: a batch count for lossless
/// delivery (the source waits), a byte budget for live delivery (the source drops).
pub fn channel(bound: QueueBound, telemetry: &Telemetry) -> (BatchSender, BatchReceiver) {
    let (queue, rx) = queue::channel(bound, telemetry);
    let delivery = match bound {
        QueueBound::Batches(_) => Delivery::Lossless,
        QueueBound::Bytes(_) => Delivery::Live,
    };
    let sender = BatchSender {
        queue,
        delivery,
        held: None,
        telemetry: telemetry.clone(),
    };
    (sender, rx)
}

impl BatchSender {
    /// The delivery mode.
    pub fn delivery(&self) -> Delivery {
        self.delivery
    }

    /// Samples dropped so far and not yet folded into a delivered batch.
    pub fn held_samples(&self) -> u64 {
        self.held.as_ref().map_or(0, |d| d.samples)
    }

    /// Deliver from async code.
    pub async fn send(&mut self, batch: SourceBatch) -> Result<(), PipelineClosed> {
        match self.delivery {
            Delivery::Lossless => self.queue.push(batch).await,
            Delivery::Live => self.send_live(batch),
        }
    }

    /// Deliver from a blocking thread (never from async code).
    pub fn blocking_send(&mut self, batch: SourceBatch) -> Result<(), PipelineClosed> {
        match self.delivery {
            Delivery::Lossless => self.queue.blocking_push(batch),
            Delivery::Live => self.send_live(batch),
        }
    }

    fn send_live(&mut self, mut batch: SourceBatch) -> Result<(), PipelineClosed> {
        batch.counts.shrink_to_fit();
        let Some(mut held) = self.held.take() else {
            if let Some(refused) = self.queue.try_push(batch)? {
                self.hold(refused);
            }
            return Ok(());
        };
        if batch.counts.is_empty() {
            // Nothing to carry the dropped pulses yet: keep holding them.
            held.events.append(&mut batch.events);
            held.events.truncate(MAX_HELD_EVENTS);
            self.held = Some(held);
            return Ok(());
        }
        // Room for the batch once the held samples are folded into it: one more
        // gap, the held events and a backpressure event.
        let folded = queue::charge(
            batch.counts.len(),
            batch.gaps.len() + 1,
            batch.events.len() + held.events.len() + 1,
        );
        if let Some(room) = self.queue.try_reserve(folded)? {
            fold_into(&mut batch, held);
            room.send(batch);
            return Ok(());
        }
        self.held = Some(held);
        self.hold(batch);
        Ok(())
    }

    fn hold(&mut self, batch: SourceBatch) {
        let samples = batch.counts.len() as u64;
        self.telemetry.dropped_samples.inc_by(samples);
        let d = Dropped {
            seq0: batch.seq0,
            t0_ns: batch.t0_ns,
            periods: batch.periods(),
            pulses: batch.counts.iter().sum(),
            samples,
            events: batch.events,
            new_segment: batch.new_segment,
        };
        self.held = Some(match self.held.take() {
            None => d,
            Some(mut h) => {
                if h.periods == 0 {
                    h.seq0 = d.seq0;
                    h.t0_ns = d.t0_ns;
                }
                h.periods += d.periods;
                h.pulses += d.pulses;
                h.samples += d.samples;
                h.events.extend(d.events);
                h.events.truncate(MAX_HELD_EVENTS);
                h.new_segment |= d.new_segment;
                h
            }
        });
    }

    /// Flush what is held at the end of the stream. The source reads no more, so
    /// waiting for room in the queue costs nothing: held events are delivered, and
    /// held (dropped) samples are delivered as a gap whose pulses ride on its last
    /// period, exactly as after any gap: a shutdown in the middle of an overload
    /// loses no angle either. (The dropped samples stay counted in
    /// `sagnac_dropped_samples_total`; the last of them is the carrier, so the
    /// recording shows one lost period fewer than were dropped.)
    pub async fn close(mut self) -> Result<(), PipelineClosed> {
        if let Some(h) = self.held.take() {
            let mut b = SourceBatch::new(Instant::now());
            b.seq0 = h.seq0;
            b.t0_ns = h.t0_ns;
            b.new_segment = h.new_segment;
            b.events = h.events;
            if h.samples > 0 {
                tracing::warn!(
                    samples = h.samples,
                    pulses = h.pulses,
                    "samples dropped by backpressure at the end of the stream: delivered as a gap carried by its last period"
                );
                if h.periods > 1 {
                    b.gaps.push(Gap {
                        index: 0,
                        lost: h.periods - 1,
                    });
                }
                b.counts.push(h.pulses);
                b.events.push(Event {
                    t_ns: h.t0_ns,
                    kind: EventKind::BackpressureDrop {
                        sink: "pipeline".into(),
                        dropped: h.samples,
                    },
                    gyro: None,
                });
            }
            if !b.is_empty() {
                self.queue.push(b).await?;
            }
        }
        Ok(())
    }
}

/// Put the dropped samples in front of `batch` as a gap carried by its first sample.
fn fold_into(batch: &mut SourceBatch, held: Dropped) {
    debug_assert!(!batch.counts.is_empty());
    if held.periods > 0 {
        batch.counts[0] += held.pulses;
        match batch.gaps.first_mut() {
            Some(g) if g.index == 0 => g.lost += held.periods,
            _ => batch.gaps.insert(
                0,
                Gap {
                    index: 0,
                    lost: held.periods,
                },
            ),
        }
        batch.seq0 = held.seq0;
        batch.t0_ns = held.t0_ns;
    }
    let mut events = held.events;
    if held.samples > 0 {
        events.push(Event {
            t_ns: held.t0_ns,
            kind: EventKind::BackpressureDrop {
                sink: "pipeline".into(),
                dropped: held.samples,
            },
            gyro: None,
        });
    }
    events.append(&mut batch.events);
    batch.events = events;
    batch.new_segment |= held.new_segment;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::frame::{
        DecoderConfig, FrameDecoder, FrameEncoder, encode_increments, inject,
    };

    fn telemetry() -> Telemetry {
        Telemetry::standalone().unwrap()
    }

    fn decode_into(asm: &mut Assembler, bytes: &[u8]) -> Vec<SourceBatch> {
        let (items, stats) = FrameDecoder::decode_all(bytes, DecoderConfig::default());
        let mut out = Vec::new();
        for (i, item) in items.into_iter().enumerate() {
            asm.push(item, 1_000_000_000);
            if i % 7 == 6
                && let Some(b) = asm.take(Instant::now())
            {
                out.push(b);
            }
        }
        asm.sync_stats(&stats);
        out.extend(asm.take(Instant::now()));
        out
    }

    #[test]
    fn counts_gaps_and_sequence_numbers_follow_the_decoder() {
        // 200 increments, frames 50..53 dropped (3 lost samples), seq wraps at 65536.
        let incs: Vec<i64> = (0..200).map(|i| (i % 5) - 2 + 7).collect();
        let mut enc = FrameEncoder::new(65_500, u32::MAX - 300);
        let frames = encode_increments(&mut enc, &incs).unwrap();
        let mut plan = inject::FaultPlan::none();
        for i in 50..53 {
            plan.set_action(i, inject::FrameAction::Drop);
        }
        let injected = inject::inject(&frames, &plan);
        let t = telemetry();
        let mut asm = Assembler::new(1000.0, None, t.clone());
        let batches = decode_into(&mut asm, &injected.bytes);
        let counts: Vec<i64> = batches.iter().flat_map(|b| b.counts.clone()).collect();
        let lost: u64 = batches
            .iter()
            .flat_map(|b| b.gaps.iter().map(|g| g.lost))
            .sum();
        // Exact: every pulse is kept, 3 samples lost, 197 samples decoded.
        assert_eq!(counts.iter().sum::<i64>(), incs.iter().sum::<i64>());
        assert_eq!(lost, 3);
        assert_eq!(counts.len(), 197);
        assert_eq!(asm.periods(), 200);
        // Batches tile the sequence: each starts where the previous ended.
        let mut next = u64::from(65_500u16) + 1;
        for b in &batches {
            if b.counts.is_empty() {
                continue;
            }
            assert_eq!(b.seq0, next);
            // times on the 1 kHz sample clock, anchored at the first sample
            assert_eq!(b.t0_ns, 1_000_000_000 + (b.seq0 - 65_501) * 1_000_000);
            next += b.periods();
        }
        assert_eq!(next, 65_501 + 200);
        let gap_events: Vec<_> = batches
            .iter()
            .flat_map(|b| b.events.iter())
            .filter(|e| matches!(e.kind, EventKind::Gap { .. }))
            .collect();
        // frame 50 carries increment 49 (0-based 49th sample) -> first missing period is 65_501 + 49
        assert_eq!(
            gap_events[0].kind,
            EventKind::Gap {
                seq: 65_501 + 49,
                lost: 3
            }
        );
        let text = t.metrics.encode();
        assert!(
            text.contains("sagnac_lost_samples_total{gyro=\"gyro\"} 3\n"),
            "{text}"
        );
        assert!(
            text.contains("sagnac_samples_total{gyro=\"gyro\"} 197\n"),
            "{text}"
        );
    }

    #[test]
    fn the_period_limit_stops_at_a_sample() {
        let incs = vec![1i64; 100];
        let frames = encode_increments(&mut FrameEncoder::new(0, 0), &incs).unwrap();
        let bytes: Vec<u8> = frames.concat();
        let mut asm = Assembler::new(1000.0, Some(40), telemetry());
        let batches = decode_into(&mut asm, &bytes);
        let n: usize = batches.iter().map(|b| b.counts.len()).sum();
        assert_eq!(n, 40);
        assert!(asm.done());
    }

    fn batch(seq0: u64, counts: Vec<i64>) -> SourceBatch {
        let mut b = SourceBatch::new(Instant::now());
        b.seq0 = seq0;
        b.t0_ns = seq0 * 1000;
        b.counts = counts;
        b
    }

    #[tokio::test]
    async fn live_delivery_folds_dropped_batches_into_a_gap() {
        let t = telemetry();
        let (mut s, mut rx) = channel(QueueBound::Bytes(queue::charge(3, 0, 0)), &t);
        s.send(batch(10, vec![1, 2, 3])).await.unwrap(); // fills the budget
        s.send(batch(13, vec![4, 5])).await.unwrap(); // dropped
        s.send(batch(15, vec![6])).await.unwrap(); // dropped too
        assert_eq!(s.held_samples(), 3);
        assert_eq!(rx.recv().await.unwrap().counts, vec![1, 2, 3]);
        s.send(batch(16, vec![7, 8])).await.unwrap();
        let b = rx.recv().await.unwrap();
        // 4 + 5 + 6 ride on the first sample of the delivered batch, as a gap of 3.
        assert_eq!(b.counts, vec![4 + 5 + 6 + 7, 8]);
        assert_eq!(b.gaps, vec![Gap { index: 0, lost: 3 }]);
        assert_eq!(b.seq0, 13);
        assert_eq!(b.t0_ns, 13_000);
        assert!(b.events.iter().any(|e| e.kind
            == EventKind::BackpressureDrop {
                sink: "pipeline".into(),
                dropped: 3
            }));
        assert_eq!(t.dropped_samples.get(), 3);
    }

    #[tokio::test]
    async fn samples_dropped_at_the_end_of_the_stream_keep_their_pulses() {
        let t = telemetry();
        let (mut s, mut rx) = channel(QueueBound::Bytes(queue::charge(3, 0, 0)), &t);
        s.send(batch(10, vec![1, 2, 3])).await.unwrap(); // fills the budget
        let mut dropped = batch(13, vec![4, 5]);
        dropped.gaps.push(Gap { index: 1, lost: 2 }); // 2 lost before the 5
        s.send(dropped).await.unwrap();
        s.send(batch(17, vec![6])).await.unwrap();
        assert_eq!(s.held_samples(), 3);
        let closing = tokio::spawn(s.close());
        assert_eq!(rx.recv().await.unwrap().counts, vec![1, 2, 3]);
        let b = rx.recv().await.unwrap();
        closing.await.unwrap().unwrap();
        // 5 periods held (3 samples, 2 lost): a gap of 4 carried by the last one
        assert_eq!(b.counts, vec![4 + 5 + 6]);
        assert_eq!(b.gaps, vec![Gap { index: 0, lost: 4 }]);
        assert_eq!(b.periods(), 5);
        assert_eq!((b.seq0, b.t0_ns), (13, 13_000));
        assert!(b.events.iter().any(|e| e.kind
            == EventKind::BackpressureDrop {
                sink: "pipeline".into(),
                dropped: 3
            }));
        assert_eq!(t.dropped_samples.get(), 3);
    }

    #[tokio::test]
    async fn lossless_delivery_waits_for_room() {
        let (mut s, mut rx) = channel(QueueBound::Batches(1), &telemetry());
        s.send(batch(0, vec![1])).await.unwrap();
        let sender = tokio::spawn(async move {
            s.send(batch(1, vec![2])).await.unwrap();
            s
        });
        assert_eq!(rx.recv().await.unwrap().counts, vec![1]);
        assert_eq!(rx.recv().await.unwrap().counts, vec![2]);
        assert_eq!(sender.await.unwrap().held_samples(), 0);
    }

    #[tokio::test]
    async fn a_burst_within_the_budget_is_queued_whole_and_its_bytes_released() {
        let t = telemetry();
        let one = queue::charge(100, 0, 0);
        let (mut s, mut rx) = channel(QueueBound::Bytes(10 * one), &t);
        assert_eq!(t.queue_budget_bytes.get() as u64, 10 * one);
        for i in 0..10 {
            s.send(batch(i * 100, vec![1; 100])).await.unwrap();
        }
        // Ten batches fit exactly: nothing dropped, the gauge holds their bytes.
        assert_eq!((s.held_samples(), t.dropped_samples.get()), (0, 0));
        assert_eq!(t.queue_bytes.get() as u64, 10 * one);
        s.send(batch(1000, vec![2; 100])).await.unwrap(); // one past the budget
        assert_eq!((s.held_samples(), t.dropped_samples.get()), (100, 100));
        for _ in 0..10 {
            assert_eq!(rx.recv().await.unwrap().counts, vec![1; 100]);
        }
        assert_eq!(t.queue_bytes.get(), 0);
        s.send(batch(1100, vec![3; 100])).await.unwrap();
        let b = rx.recv().await.unwrap();
        assert_eq!(b.counts[0], 200 + 3);
        assert_eq!(
            b.gaps,
            vec![Gap {
                index: 0,
                lost: 100
            }]
        );
        assert_eq!(t.queue_bytes.get(), 0);
    }

    #[tokio::test]
    async fn a_batch_larger_than_the_budget_waits_for_an_empty_queue() {
        let t = telemetry();
        let (mut s, mut rx) = channel(QueueBound::Bytes(queue::charge(10, 0, 0)), &t);
        s.send(batch(0, vec![1])).await.unwrap();
        s.send(batch(1, vec![1; 100])).await.unwrap(); // too big while the queue holds one
        assert_eq!(s.held_samples(), 100);
        assert_eq!(rx.recv().await.unwrap().counts, vec![1]);
        s.send(batch(101, vec![1; 100])).await.unwrap(); // empty queue: charged the whole budget
        assert_eq!(s.held_samples(), 0);
        assert_eq!(t.queue_bytes.get() as u64, queue::charge(10, 0, 0));
        let b = rx.recv().await.unwrap();
        assert_eq!(b.counts.iter().sum::<i64>(), 200);
        assert_eq!(b.periods(), 200);
    }

    #[test]
    fn the_pipeline_releases_a_batch_once_it_is_processed() {
        let t = telemetry();
        let (mut s, rx) = channel(QueueBound::Bytes(1 << 20), &t);
        s.blocking_send(batch(0, vec![1; 10])).unwrap();
        s.blocking_send(batch(10, vec![1; 20])).unwrap();
        drop(s);
        let (a, b) = (
            queue::charge(10, 0, 0) as i64,
            queue::charge(20, 0, 0) as i64,
        );
        let mut seen = Vec::new();
        rx.for_each_blocking(|_| seen.push(t.queue_bytes.get()));
        assert_eq!(seen, vec![a + b, b]);
        assert_eq!(t.queue_bytes.get(), 0);
    }
}
