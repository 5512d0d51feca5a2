//! The daemon's own metrics, registered next to [`Metrics`] in the same
//! registry (so `GET /metrics` shows them too): backpressure drops, the pipeline
//! queue's fill and budget, the device
//! connection state, sequence anomalies, estimator updates and their latency.
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `sagnac_dropped_samples_total` | counter | (samples a live source could not hand to the pipeline: its queue was full) |
//! | `sagnac_pipeline_queue_bytes` | gauge | (bytes of sample data queued between the source and the pipeline thread, see [`crate::daemon::queue`]) |
//! | `sagnac_pipeline_queue_budget_bytes` | gauge | (the live source's queue budget, `source.queue_budget_mib`; 0 when the source waits for room instead) |
//! | `sagnac_dropped_messages_total` | counter | `sink`: `mcap` |
//! | `sagnac_device_connected` | gauge | (1 while the serial device is open) |
//! | `sagnac_device_reconnects_total` | counter | |
//! | `sagnac_sequence_anomalies_total` | counter | `kind`: `duplicate`, `out_of_sequence`, `discontinuity` |
//! | `sagnac_estimator_updates_total` | counter | |
//! | `sagnac_estimate_latency_seconds` | gauge | (wall time from the arrival of the sample that closed an estimator interval to its estimate in the metrics) |

use std::sync::Arc;

use prometheus::{Gauge, IntCounter, IntCounterVec, IntGauge, Opts};

use crate::sink::metrics::{Metrics, MetricsError};

/// [`Metrics`] plus the daemon's own series.
#[derive(Debug, Clone)]
pub struct Telemetry {
    /// The shared metrics (served by `/metrics`).
    pub metrics: Arc<Metrics>,
    pub dropped_samples: IntCounter,
    pub dropped_messages: IntCounterVec,
    pub queue_bytes: IntGauge,
    pub queue_budget_bytes: IntGauge,
    pub device_connected: IntGauge,
    pub device_reconnects: IntCounter,
    pub sequence_anomalies: IntCounterVec,
    pub estimator_updates: IntCounter,
    pub estimate_latency: Gauge,
}

/// `sequence_anomalies` label of a duplicate frame.
pub const ANOMALY_DUPLICATE: &str = "duplicate";
/// `sequence_anomalies` label of an out-of-sequence frame.
pub const ANOMALY_OUT_OF_SEQUENCE: &str = "out_of_sequence";
/// `sequence_anomalies` label of a re-baseline on a new sequence.
pub const ANOMALY_DISCONTINUITY: &str = "discontinuity";

impl Telemetry {
    /// Register the daemon series in `metrics`' registry.
    pub fn new(metrics: Arc<Metrics>) -> Result<Telemetry, MetricsError> {
        fn reg<C: prometheus::core::Collector + Clone + 'static>(
            metrics: &Metrics,
            name: &'static str,
            made: prometheus::Result<C>,
        ) -> Result<C, MetricsError> {
            let c = made.map_err(|source| MetricsError::Register { name, source })?;
            metrics
                .registry()
                .register(Box::new(c.clone()))
                .map_err(|source| MetricsError::Register { name, source })?;
            Ok(c)
        }
        let m = &*metrics;
        let t = Telemetry {
            dropped_samples: reg(
                m,
                "sagnac_dropped_samples_total",
                IntCounter::new(
                    "sagnac_dropped_samples_total",
                    "Samples a live source dropped because the pipeline queue was full (their pulses are carried by the next sample, as after a gap).",
                ),
            )?,
            dropped_messages: reg(
                m,
                "sagnac_dropped_messages_total",
                IntCounterVec::new(
                    Opts::new(
                        "sagnac_dropped_messages_total",
                        "Messages dropped because a sink queue was full, by sink.",
                    ),
                    &["sink"],
                ),
            )?,
            queue_bytes: reg(
                m,
                "sagnac_pipeline_queue_bytes",
                IntGauge::new(
                    "sagnac_pipeline_queue_bytes",
                    "Bytes of sample data queued between the source and the pipeline thread (held until the pipeline has processed them).",
                ),
            )?,
            queue_budget_bytes: reg(
                m,
                "sagnac_pipeline_queue_budget_bytes",
                IntGauge::new(
                    "sagnac_pipeline_queue_budget_bytes",
                    "Budget of the pipeline queue of a live (serial) source, bytes: past it, samples are dropped; 0 for a source that waits for room (replay, simulated bench).",
                ),
            )?,
            device_connected: reg(
                m,
                "sagnac_device_connected",
                IntGauge::new(
                    "sagnac_device_connected",
                    "1 while the serial device is open, 0 while reconnecting.",
                ),
            )?,
            device_reconnects: reg(
                m,
                "sagnac_device_reconnects_total",
                IntCounter::new(
                    "sagnac_device_reconnects_total",
                    "Times the serial device was opened again after it went away.",
                ),
            )?,
            sequence_anomalies: reg(
                m,
                "sagnac_sequence_anomalies_total",
                IntCounterVec::new(
                    Opts::new(
                        "sagnac_sequence_anomalies_total",
                        "Valid frames out of the expected sequence, by kind: duplicate (dropped), out_of_sequence (dropped), discontinuity (new baseline).",
                    ),
                    &["kind"],
                ),
            )?,
            estimator_updates: reg(
                m,
                "sagnac_estimator_updates_total",
                IntCounter::new(
                    "sagnac_estimator_updates_total",
                    "Estimator updates published.",
                ),
            )?,
            estimate_latency: reg(
                m,
                "sagnac_estimate_latency_seconds",
                Gauge::new(
                    "sagnac_estimate_latency_seconds",
                    "Wall time from the arrival of the sample that closed the latest estimator interval to the publication of its estimate, seconds (NaN before the first).",
                ),
            )?,
            metrics,
        };
        t.dropped_messages.with_label_values(&["mcap"]);
        for kind in [
            ANOMALY_DUPLICATE,
            ANOMALY_OUT_OF_SEQUENCE,
            ANOMALY_DISCONTINUITY,
        ] {
            t.sequence_anomalies.with_label_values(&[kind]);
        }
        t.estimate_latency.set(f64::NAN);
        Ok(t)
    }

    /// A fresh [`Metrics`] with the daemon series (tests, offline runs).
    pub fn standalone() -> Result<Telemetry, MetricsError> {
        Telemetry::new(Arc::new(Metrics::new()?))
    }
}
