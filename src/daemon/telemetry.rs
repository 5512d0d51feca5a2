//! The daemon's own metrics, registered next to [`Metrics`] in the same
//! registry (so `GET /metrics` shows them too): backpressure drops, the pipeline
//! queue's fill and budget, the device connection state, sequence anomalies,
//! estimator updates and their latency.
//!
//! A [`Telemetry`] is the handle of one gyro: [`Telemetry::new`] makes the first
//! one, [`Telemetry::for_gyro`] another gyro's of the same daemon. Its per-gyro
//! series (and those of its [`GyroMetrics`]) carry that gyro's `gyro` label.
//!
//! | metric | type | labels |
//! |---|---|---|
//! | `sagnac_dropped_samples_total` | counter | `gyro` (samples a live source could not hand to the pipeline: its queue was full) |
//! | `sagnac_sequence_anomalies_total` | counter | `gyro`; `kind`: `duplicate`, `out_of_sequence`, `discontinuity` |
//! | `sagnac_estimator_updates_total` | counter | `gyro` |
//! | `sagnac_estimate_latency_seconds` | histogram | `gyro` (wall time from the arrival of the sample that closed an estimator interval to its estimate in the metrics; buckets [`LATENCY_BUCKETS_S`]) |
//! | `sagnac_device_connected` | gauge | `gyro` (1 while the serial device is open; serial sources only, see [`Telemetry::device`]) |
//! | `sagnac_device_reconnects_total` | counter | `gyro` (serial sources only) |
//! | `sagnac_pipeline_queue_bytes` | gauge | (daemon-wide: bytes of sample data queued between the source and the pipeline thread, see [`crate::daemon::queue`]) |
//! | `sagnac_pipeline_queue_budget_bytes` | gauge | (daemon-wide: the live source's queue budget, `source.queue_budget_mib`; 0 when the source waits for room instead) |
//! | `sagnac_dropped_messages_total` | counter | `sink`: `mcap` (daemon-wide) |

use std::sync::Arc;

use prometheus::{
    Histogram, HistogramOpts, HistogramVec, IntCounter, IntCounterVec, IntGauge, IntGaugeVec, Opts,
};

use crate::sink::metrics::{GyroInfo, GyroMetrics, Metrics, MetricsError, register};

/// Upper bounds of the `sagnac_estimate_latency_seconds` buckets, s: an update
/// normally takes milliseconds; seconds mean the pipeline is far behind.
pub const LATENCY_BUCKETS_S: [f64; 14] = [
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0,
];

/// `sequence_anomalies` label of a duplicate frame.
pub const ANOMALY_DUPLICATE: &str = "duplicate";
/// `sequence_anomalies` label of an out-of-sequence frame.
pub const ANOMALY_OUT_OF_SEQUENCE: &str = "out_of_sequence";
/// `sequence_anomalies` label of a re-baseline on a new sequence.
pub const ANOMALY_DISCONTINUITY: &str = "discontinuity";
const ANOMALIES: [&str; 3] = [
    ANOMALY_DUPLICATE,
    ANOMALY_OUT_OF_SEQUENCE,
    ANOMALY_DISCONTINUITY,
];

/// The daemon's metric families with a `gyro` label.
#[derive(Debug, Clone)]
struct DaemonFamilies {
    dropped_samples: IntCounterVec,
    sequence_anomalies: IntCounterVec,
    estimator_updates: IntCounterVec,
    estimate_latency: HistogramVec,
    device_connected: IntGaugeVec,
    device_reconnects: IntCounterVec,
}

/// [`Metrics`] plus the daemon's own series, for one gyro.
#[derive(Debug, Clone)]
pub struct Telemetry {
    /// The shared metrics (served by `/metrics`): the daemon-wide series.
    pub metrics: Arc<Metrics>,
    /// This gyro's series of [`Metrics`].
    pub gyro: GyroMetrics,
    pub dropped_samples: IntCounter,
    pub estimator_updates: IntCounter,
    pub estimate_latency: Histogram,
    pub dropped_messages: IntCounterVec,
    pub queue_bytes: IntGauge,
    pub queue_budget_bytes: IntGauge,
    families: DaemonFamilies,
}

/// The connection series of a serial device.
#[derive(Debug, Clone)]
pub struct DeviceTelemetry {
    pub connected: IntGauge,
    pub reconnects: IntCounter,
}

impl DaemonFamilies {
    fn new(m: &Metrics) -> Result<DaemonFamilies, MetricsError> {
        let r = m.registry();
        let counter = |name: &'static str, help: &str, labels: &[&str]| {
            register(r, name, IntCounterVec::new(Opts::new(name, help), labels))
        };
        Ok(DaemonFamilies {
            dropped_samples: counter(
                "sagnac_dropped_samples_total",
                "Samples a live source dropped because the pipeline queue was full (their pulses are carried by the next sample, as after a gap).",
                &["gyro"],
            )?,
            sequence_anomalies: counter(
                "sagnac_sequence_anomalies_total",
                "Valid frames out of the expected sequence, by kind: duplicate (dropped), out_of_sequence (dropped), discontinuity (new baseline).",
                &["gyro", "kind"],
            )?,
            estimator_updates: counter("sagnac_estimator_updates_total", "Estimator updates published.", &["gyro"])?,
            estimate_latency: register(
                r,
                "sagnac_estimate_latency_seconds",
                HistogramVec::new(
                    HistogramOpts::new(
                        "sagnac_estimate_latency_seconds",
                        "Wall time from the arrival of the sample that closed an estimator interval to the publication of its estimate, seconds.",
                    )
                    .buckets(LATENCY_BUCKETS_S.to_vec()),
                    &["gyro"],
                ),
            )?,
            device_connected: register(
                r,
                "sagnac_device_connected",
                IntGaugeVec::new(
                    Opts::new("sagnac_device_connected", "1 while the serial device is open, 0 while reconnecting."),
                    &["gyro"],
                ),
            )?,
            device_reconnects: counter(
                "sagnac_device_reconnects_total",
                "Times the serial device was opened again after it went away.",
                &["gyro"],
            )?,
        })
    }
}

impl Telemetry {
    /// Register the daemon series in `metrics`' registry; the handle of the gyro `gyro`.
    pub fn new(metrics: Arc<Metrics>, gyro: &GyroInfo) -> Result<Telemetry, MetricsError> {
        let m = &*metrics;
        let r = m.registry();
        let gauge = |name: &'static str, help: &str| register(r, name, IntGauge::new(name, help));
        let families = DaemonFamilies::new(m)?;
        let dropped_messages = register(
            r,
            "sagnac_dropped_messages_total",
            IntCounterVec::new(
                Opts::new(
                    "sagnac_dropped_messages_total",
                    "Messages dropped because a sink queue was full, by sink.",
                ),
                &["sink"],
            ),
        )?;
        dropped_messages.with_label_values(&["mcap"]);
        let queue_bytes = gauge(
            "sagnac_pipeline_queue_bytes",
            "Bytes of sample data queued between the source and the pipeline thread (held until the pipeline has processed them).",
        )?;
        let queue_budget_bytes = gauge(
            "sagnac_pipeline_queue_budget_bytes",
            "Budget of the pipeline queue of a live (serial) source, bytes: past it, samples are dropped; 0 for a source that waits for room (replay, simulated bench).",
        )?;
        Ok(Telemetry::with_families(
            metrics,
            families,
            dropped_messages,
            queue_bytes,
            queue_budget_bytes,
            gyro,
        ))
    }

    fn with_families(
        metrics: Arc<Metrics>,
        families: DaemonFamilies,
        dropped_messages: IntCounterVec,
        queue_bytes: IntGauge,
        queue_budget_bytes: IntGauge,
        gyro: &GyroInfo,
    ) -> Telemetry {
        let g = gyro.label.as_str();
        for kind in ANOMALIES {
            families.sequence_anomalies.with_label_values(&[g, kind]);
        }
        Telemetry {
            gyro: metrics.gyro(gyro),
            metrics,
            dropped_samples: families.dropped_samples.with_label_values(&[g]),
            estimator_updates: families.estimator_updates.with_label_values(&[g]),
            estimate_latency: families.estimate_latency.with_label_values(&[g]),
            dropped_messages,
            queue_bytes,
            queue_budget_bytes,
            families,
        }
    }

    /// The handle of another gyro of the same daemon (same registry and daemon-wide series).
    pub fn for_gyro(&self, gyro: &GyroInfo) -> Telemetry {
        Telemetry::with_families(
            Arc::clone(&self.metrics),
            self.families.clone(),
            self.dropped_messages.clone(),
            self.queue_bytes.clone(),
            self.queue_budget_bytes.clone(),
            gyro,
        )
    }

    /// Count a sequence anomaly of `kind` (one of the `ANOMALY_*` labels).
    pub fn add_sequence_anomaly(&self, kind: &str) {
        self.families
            .sequence_anomalies
            .with_label_values(&[self.gyro.label(), kind])
            .inc();
    }

    /// The connection series of this gyro's serial device. Only serial sources
    /// call it: a replay or the simulated bench has no device and exports none.
    pub fn device(&self) -> DeviceTelemetry {
        let g = self.gyro.label();
        DeviceTelemetry {
            connected: self.families.device_connected.with_label_values(&[g]),
            reconnects: self.families.device_reconnects.with_label_values(&[g]),
        }
    }

    /// A fresh [`Metrics`] with the daemon series of the default gyro (tests, offline runs).
    pub fn standalone() -> Result<Telemetry, MetricsError> {
        let gyro = GyroInfo::labelled(crate::sink::metrics::DEFAULT_GYRO);
        Telemetry::new(Arc::new(Metrics::new()?), &gyro)
    }
}
