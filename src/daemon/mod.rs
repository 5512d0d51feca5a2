//! The acquisition daemon (`sagnac run`): tokio tasks that move bytes from a
//! source through the synchronous numerics into the sinks.
//!
//! * [`config`]: the validated configuration (`config/default.toml`);
//! * [`batch`]: what a source hands to the pipeline ([`batch::SourceBatch`]),
//!   built from the frame decoder's output, delivered losslessly (replays,
//!   simulated bench: backpressure) or live (serial: drop, count, fold);
//! * [`queue`]: the source -> pipeline queue, bounded by a batch count
//!   (backpressure) or, for a live source, by a memory budget in bytes;
//! * [`process`]: the pipeline thread (gap fill, the shared
//!   [`crate::pipeline::Pipeline`], estimator updates) publishing to the sinks;
//! * [`quality`]: the data-quality stage of a live run (glitch counts, the
//!   slow effects assessed every minute of samples, the restart after a warm-up);
//! * [`run`]: [`run::Daemon`], wiring sources, pipeline, recorder and the
//!   `/metrics` server ([`http`]) with bounded channels and a drained shutdown
//!   ([`shutdown`]);
//! * [`summary`]: the 10 Hz `/gyro/summary` windows;
//! * [`status`]: the live status a terminal shows (`sagnac run`);
//! * [`telemetry`]: the daemon's own metrics next to [`crate::sink::metrics`].
//!
//! * the sources: [`serial`] (a serial port), [`replay`] (a frame capture or
//!   an MCAP recording), [`bench`] (the simulated bench), each feeding one
//!   [`lanes::Lanes`] per frame stream (one gyro, or a triad's three).
//!
//! The sans-IO frame decoding they use lives in [`crate::input`].

pub mod batch;
pub mod bench;
pub mod config;
pub mod http;
pub mod lanes;
pub mod process;
pub mod quality;
pub mod queue;
pub mod replay;
pub mod run;
pub mod serial;
pub mod shutdown;
pub mod status;
pub mod summary;
pub mod telemetry;
