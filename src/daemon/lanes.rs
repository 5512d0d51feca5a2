//! One frame stream, one or more gyros: [`Lanes`] holds the stream's frame
//! decoder and, per gyro the frame carries ([`Axes::GYROS`]: one for the
//! single frame, three for a triad), an [`Assembler`] and the [`BatchSender`]
//! of that gyro's pipeline. Every decoder item is split into each gyro's view
//! ([`Axes::axis`]): the gyros share the frame's sequence, gaps, framing
//! errors, temperature and status, and each has its own counter. So each
//! gyro's metrics count the frames and errors of its stream, and bytes read
//! are counted once per stream.

use std::time::Instant;

use bytes::BytesMut;

use crate::daemon::batch::{Assembler, BatchSender, PipelineClosed, SourceReport};
use crate::daemon::telemetry::Telemetry;
use crate::input::frame::{Axes, DecoderConfig, DecoderStats, FrameDecoder, WireDecoded};
use crate::recording::messages::EventKind;

/// One gyro of a stream: where its samples are assembled and sent.
#[derive(Debug)]
struct Lane {
    asm: Assembler,
    out: BatchSender,
}

/// A frame stream's decoder and its gyros' assemblers and senders.
#[derive(Debug)]
pub struct Lanes<W: Axes> {
    decoder: FrameDecoder<W>,
    lanes: Vec<Lane>,
    run: Vec<W::Increment>,
    split: Vec<i64>,
}

impl<W: Axes> Lanes<W> {
    /// A stream of gyros sampled at `sample_rate_hz`, stopping after `limit_periods`
    /// periods; `outs` holds each gyro's telemetry and sender, in frame order
    /// (exactly [`Axes::GYROS`] of them).
    pub fn new(
        decoder: DecoderConfig,
        sample_rate_hz: f64,
        limit_periods: Option<u64>,
        outs: Vec<(Telemetry, BatchSender)>,
    ) -> Self {
        assert_eq!(outs.len(), W::GYROS, "one sender per gyro of the frame");
        let lanes = outs
            .into_iter()
            .enumerate()
            .map(|(i, (telemetry, out))| {
                let mut asm = Assembler::new(sample_rate_hz, limit_periods, telemetry);
                asm.count_bytes(i == 0);
                Lane { asm, out }
            })
            .collect();
        Lanes {
            decoder: FrameDecoder::for_wire(decoder),
            lanes,
            run: Vec::new(),
            split: Vec::new(),
        }
    }

    fn first(&self) -> &Assembler {
        &self.lanes[0].asm
    }

    /// The decoder's counts.
    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// Whether the period limit is reached.
    pub fn done(&self) -> bool {
        self.first().done()
    }

    /// Sample periods assembled (the same for every gyro).
    pub fn periods(&self) -> u64 {
        self.first().periods()
    }

    /// Sample periods left before the limit.
    pub fn room(&self) -> usize {
        self.first().room()
    }

    /// Samples assembled and not yet sent (per gyro).
    pub fn pending_samples(&self) -> usize {
        self.first().pending_samples()
    }

    /// Whether anything waits to be sent.
    pub fn has_pending(&self) -> bool {
        self.lanes.iter().any(|l| l.asm.has_pending())
    }

    /// The telemetry of each gyro.
    pub fn telemetry(&self) -> impl Iterator<Item = &Telemetry> {
        self.lanes.iter().map(|l| l.asm.telemetry())
    }

    /// An event for every gyro of the stream (a device event).
    pub fn push_event(&mut self, t_ns: u64, kind: EventKind) {
        for l in &mut self.lanes {
            l.asm.push_event(t_ns, kind.clone());
        }
    }

    fn push(&mut self, item: &WireDecoded<W>, now_ns: u64) {
        for (i, l) in self.lanes.iter_mut().enumerate() {
            l.asm.push(W::axis(item, i), now_ns);
        }
    }

    /// Decode one item from `buf` (at end of stream with `eof`: the trailing
    /// partial frame too); `false` when there is none.
    pub fn decode_one(&mut self, buf: &mut BytesMut, eof: bool, now_ns: u64) -> bool {
        let item = if eof {
            self.decoder.decode_eof(buf)
        } else {
            self.decoder.decode(buf)
        };
        match item {
            Some(item) => {
                self.push(&item, now_ns);
                true
            }
            None => false,
        }
    }

    /// Decode what `buf` holds, stopping at the period limit.
    pub fn decode_available(&mut self, buf: &mut BytesMut, now_ns: u64) {
        while !self.done() && self.decode_one(buf, false, now_ns) {}
    }

    /// Decode a run of at most `max` contiguous frames in bulk; the samples
    /// per gyro, 0 when `buf` does not start with such a run.
    pub fn decode_run(&mut self, buf: &mut BytesMut, max: usize, now_ns: u64) -> usize {
        self.run.clear();
        let Some(end) = self.decoder.decode_run(buf, max, &mut self.run) else {
            return 0;
        };
        for (i, l) in self.lanes.iter_mut().enumerate() {
            // a single frame's run as decoded; a triad's split per gyro
            let incs = W::axis_run(&self.run, i, &mut self.split);
            l.asm.push_run(incs, &end, now_ns);
        }
        self.run.len()
    }

    /// Count what the decoder did in each gyro's metrics.
    pub fn sync_stats(&mut self) {
        let stats = *self.decoder.stats();
        for l in &mut self.lanes {
            l.asm.sync_stats(&stats);
        }
    }

    /// Send what each gyro has assembled, from async code.
    pub async fn send(&mut self) -> Result<(), PipelineClosed> {
        for l in &mut self.lanes {
            if let Some(b) = l.asm.take(Instant::now()) {
                l.out.send(b).await?;
            }
        }
        Ok(())
    }

    /// Send what each gyro has assembled, from a blocking thread.
    pub fn blocking_send(&mut self) -> Result<(), PipelineClosed> {
        for l in &mut self.lanes {
            if let Some(b) = l.asm.take(Instant::now()) {
                l.out.blocking_send(b)?;
            }
        }
        Ok(())
    }

    /// Flush what the senders hold (live delivery) and close them; the stream's report.
    pub async fn close(self, disconnects: u64) -> Result<SourceReport, PipelineClosed> {
        let report = self.report(disconnects);
        for l in self.lanes {
            l.out.close().await?;
        }
        Ok(report)
    }

    /// The stream's report (per gyro: every gyro has the same samples and periods).
    pub fn report(&self, disconnects: u64) -> SourceReport {
        let s = self.decoder.stats();
        SourceReport {
            bytes_read: s.bytes_read,
            samples: s.samples,
            periods: self.periods(),
            disconnects,
        }
    }
}
