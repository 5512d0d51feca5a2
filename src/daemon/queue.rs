//! The queue between a source and the pipeline thread, and its accounting.
//!
//! A backpressured source (replay, simulated bench) gets a queue of at most
//! `run.channel_capacity` batches and waits for room. A live source (the serial
//! port, which cannot be paused) gets a queue bounded by a **memory budget**
//! (`source.queue_budget_mib`): every queued batch is charged the bytes of sample
//! data it holds ([`charge`]: 8 bytes per pulse increment, plus its gaps, events
//! and the batch itself) as permits of a [`Semaphore`] holding one permit per byte
//! of the budget. A batch is queued only if its whole charge is free, so a burst
//! that fits in the budget loses nothing; one that does not fit is handed back to
//! the [`BatchSender`](crate::daemon::batch::BatchSender), which drops and counts
//! it. The charge is returned when the pipeline has processed the batch (the
//! permits and the `sagnac_pipeline_queue_bytes` gauge are released together by
//! one guard, so the accounting cannot drift). A batch larger than the whole
//! budget is charged the whole budget: it waits for an empty queue instead of
//! never fitting.

use std::sync::Arc;
use std::time::Instant;

use prometheus::IntGauge;
use tokio::sync::{OwnedSemaphorePermit, Semaphore, mpsc};

use crate::daemon::telemetry::Telemetry;
use crate::recording::messages::{Event, Gap};

/// Decoded samples and events, in stream order.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceBatch {
    /// Unwrapped sequence number of the first sample period the batch covers
    /// (a leading gap included).
    pub seq0: u64,
    /// Time of period `seq0`, ns since the Unix epoch.
    pub t0_ns: u64,
    /// Pulse increments; after a gap, the whole increment over the gap.
    pub counts: Vec<i64>,
    /// Missing samples: `lost` periods just before `counts[index]`.
    pub gaps: Vec<Gap>,
    /// Device temperature of the newest frame, deg C.
    pub temp_c: Option<f64>,
    /// Device status word of the newest frame.
    pub status: Option<u32>,
    /// Events, each with its own time.
    pub events: Vec<Event>,
    /// The first sample starts a new time segment (after a discontinuity).
    pub new_segment: bool,
    /// When the newest sample arrived (or was due, for a paced source).
    pub arrived: Instant,
}

impl SourceBatch {
    /// An empty batch.
    pub fn new(arrived: Instant) -> Self {
        SourceBatch {
            seq0: 0,
            t0_ns: 0,
            counts: Vec::new(),
            gaps: Vec::new(),
            temp_c: None,
            status: None,
            events: Vec::new(),
            new_segment: false,
            arrived,
        }
    }

    /// Sample periods covered: samples plus lost ones.
    pub fn periods(&self) -> u64 {
        self.counts.len() as u64 + self.gaps.iter().map(|g| g.lost).sum::<u64>()
    }

    /// No samples and no events.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty() && self.gaps.is_empty() && self.events.is_empty()
    }
}

/// The pipeline stopped (its receiver is gone).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the pipeline stopped accepting samples")]
pub struct PipelineClosed;

/// Bytes in a MiB.
pub const MIB: f64 = 1024.0 * 1024.0;

/// What bounds the queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QueueBound {
    /// At most this many batches; a full queue makes the source wait.
    Batches(usize),
    /// At most this many bytes of queued sample data; a batch that does not fit
    /// is refused (the source drops it).
    Bytes(u64),
}

/// Bytes of queue budget a batch of `counts` samples, `gaps` gaps and `events`
/// events holds.
pub fn charge(counts: usize, gaps: usize, events: usize) -> u64 {
    let bytes = std::mem::size_of::<SourceBatch>()
        + counts * std::mem::size_of::<i64>()
        + gaps * std::mem::size_of::<Gap>()
        + events * std::mem::size_of::<Event>();
    bytes as u64
}

/// [`charge`] of a batch as it is.
pub fn charge_of(b: &SourceBatch) -> u64 {
    charge(b.counts.len(), b.gaps.len(), b.events.len())
}

/// A batch's share of the queue: released (permits and gauge) when dropped.
#[derive(Debug)]
struct Share {
    bytes: u64,
    gauge: IntGauge,
    _permit: Option<OwnedSemaphorePermit>,
}

impl Share {
    fn new(bytes: u64, permit: Option<OwnedSemaphorePermit>, gauge: &IntGauge) -> Share {
        gauge.add(i64::try_from(bytes).unwrap_or(i64::MAX));
        Share {
            bytes,
            gauge: gauge.clone(),
            _permit: permit,
        }
    }
}

impl Drop for Share {
    fn drop(&mut self) {
        self.gauge
            .sub(i64::try_from(self.bytes).unwrap_or(i64::MAX));
    }
}

/// A batch in the queue with its share of the budget.
#[derive(Debug)]
pub struct Queued {
    batch: SourceBatch,
    _share: Share,
}

/// Room reserved in a byte-budget queue for one batch of known charge.
#[derive(Debug)]
pub struct Reservation<'a> {
    slot: mpsc::Permit<'a, Queued>,
    permit: OwnedSemaphorePermit,
    bytes: u64,
    gauge: &'a IntGauge,
}

impl Reservation<'_> {
    /// Queue `batch` in the reserved room (the caller reserved at least its
    /// [`charge_of`], or the whole budget).
    pub fn send(self, batch: SourceBatch) {
        let share = Share::new(self.bytes, Some(self.permit), self.gauge);
        self.slot.send(Queued {
            batch,
            _share: share,
        });
    }
}

#[derive(Debug)]
struct Budget {
    semaphore: Arc<Semaphore>,
    bytes: u64,
}

impl Budget {
    /// The permits a batch charged `bytes` takes: at most the whole budget (and
    /// a `u32`, what one acquisition can take).
    fn clamp(&self, bytes: u64) -> u64 {
        bytes.min(self.bytes).min(u64::from(u32::MAX))
    }
}

/// The sending end.
#[derive(Debug)]
pub struct QueueTx {
    tx: mpsc::Sender<Queued>,
    budget: Option<Budget>,
    gauge: IntGauge,
}

/// The receiving end (the pipeline thread).
#[derive(Debug)]
pub struct BatchReceiver {
    rx: mpsc::Receiver<Queued>,
}

/// A queue bounded by `bound`, reported in `telemetry`'s queue gauges.
pub fn channel(bound: QueueBound, telemetry: &Telemetry) -> (QueueTx, BatchReceiver) {
    let (capacity, budget) = match bound {
        QueueBound::Batches(n) => (n.max(1), None),
        QueueBound::Bytes(bytes) => {
            // Every batch is charged at least its own size: the byte budget binds
            // before this count does.
            let most = bytes / charge(0, 0, 0) + 1;
            let capacity = usize::try_from(most)
                .unwrap_or(usize::MAX)
                .min(Semaphore::MAX_PERMITS);
            let permits = usize::try_from(bytes)
                .unwrap_or(usize::MAX)
                .min(Semaphore::MAX_PERMITS);
            let semaphore = Arc::new(Semaphore::new(permits));
            (
                capacity,
                Some(Budget {
                    semaphore,
                    bytes: permits as u64,
                }),
            )
        }
    };
    let budget_bytes = budget.as_ref().map_or(0, |b| b.bytes);
    telemetry
        .queue_budget_bytes
        .set(i64::try_from(budget_bytes).unwrap_or(i64::MAX));
    let (tx, rx) = mpsc::channel(capacity);
    let tx = QueueTx {
        tx,
        budget,
        gauge: telemetry.queue_bytes.clone(),
    };
    (tx, BatchReceiver { rx })
}

impl QueueTx {
    /// The byte budget, if the queue has one.
    pub fn budget_bytes(&self) -> Option<u64> {
        self.budget.as_ref().map(|b| b.bytes)
    }

    /// Wait for room (budget and slot) and queue.
    pub async fn push(&self, batch: SourceBatch) -> Result<(), PipelineClosed> {
        let bytes = charge_of(&batch);
        let (bytes, permit) = match &self.budget {
            Some(budget) => {
                let bytes = budget.clamp(bytes);
                let permit = Arc::clone(&budget.semaphore)
                    .acquire_many_owned(u32::try_from(bytes).unwrap_or(u32::MAX))
                    .await
                    .map_err(|_| PipelineClosed)?;
                (bytes, Some(permit))
            }
            None => (bytes, None),
        };
        let slot = self.tx.reserve().await.map_err(|_| PipelineClosed)?;
        let share = Share::new(bytes, permit, &self.gauge);
        slot.send(Queued {
            batch,
            _share: share,
        });
        Ok(())
    }

    /// Wait for room and queue, from a blocking thread (never from async code).
    /// The batch is counted in the gauge while it waits for a slot.
    pub fn blocking_push(&self, batch: SourceBatch) -> Result<(), PipelineClosed> {
        let share = Share::new(charge_of(&batch), None, &self.gauge);
        self.tx
            .blocking_send(Queued {
                batch,
                _share: share,
            })
            .map_err(|_| PipelineClosed)
    }

    /// Reserve room for a batch charged `bytes` without waiting: `Ok(None)` if
    /// the byte budget has not that much left (or the queue has no byte budget).
    pub fn try_reserve(&self, bytes: u64) -> Result<Option<Reservation<'_>>, PipelineClosed> {
        let Some(budget) = &self.budget else {
            return Ok(None);
        };
        let bytes = budget.clamp(bytes);
        let slot = match self.tx.try_reserve() {
            Ok(slot) => slot,
            Err(mpsc::error::TrySendError::Full(())) => return Ok(None),
            Err(mpsc::error::TrySendError::Closed(())) => return Err(PipelineClosed),
        };
        // `bytes` fits in a u32 (bounded above).
        let n = u32::try_from(bytes).unwrap_or(u32::MAX);
        match Arc::clone(&budget.semaphore).try_acquire_many_owned(n) {
            Ok(permit) => Ok(Some(Reservation {
                slot,
                permit,
                bytes,
                gauge: &self.gauge,
            })),
            Err(_) => Ok(None),
        }
    }

    /// Queue `batch` now if its charge fits in the byte budget; otherwise hand
    /// it back (`Ok(Some(batch))`).
    pub fn try_push(&self, batch: SourceBatch) -> Result<Option<SourceBatch>, PipelineClosed> {
        match self.try_reserve(charge_of(&batch))? {
            Some(room) => {
                room.send(batch);
                Ok(None)
            }
            None => Ok(Some(batch)),
        }
    }
}

impl BatchReceiver {
    /// Call `f` on each batch, on this (blocking) thread, until every sender is
    /// gone; a batch's share of the queue is released once `f` has processed it.
    pub fn for_each_blocking(mut self, mut f: impl FnMut(SourceBatch)) {
        while let Some(q) = self.rx.blocking_recv() {
            let Queued { batch, _share } = q;
            f(batch);
            drop(_share);
        }
    }

    /// The next batch (its share released at once), from async code.
    pub async fn recv(&mut self) -> Option<SourceBatch> {
        self.rx.recv().await.map(|q| q.batch)
    }

    /// The next batch (its share released at once), from a blocking thread.
    pub fn blocking_recv(&mut self) -> Option<SourceBatch> {
        self.rx.blocking_recv().map(|q| q.batch)
    }
}
