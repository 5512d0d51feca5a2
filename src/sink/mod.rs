//! Sinks: where the daemon's results leave the process.
//!
//! - [`messages`]: the typed messages of the MCAP channels and their JSON Schemas;
//! - [`mcap`]: the [`mcap::Recorder`], one zstd-chunked MCAP file per run, written on
//!   its own thread with a bounded-loss flush policy;
//! - [`meta`]: the recording's `sagnac` Metadata record (sample rate, pulse weight,
//!   model, config), and the rule for a flag that meets a recorded value;
//! - [`reader`]: reading recordings back (replay, `analyze --format mcap`) and
//!   recovering truncated ones;
//! - [`provenance`]: what every JSON output says about itself (version, input
//!   settings, units);
//! - [`metrics`]: the Prometheus metrics served by [`crate::daemon::http`];
//! - [`report`]: `sagnac report`'s self-contained HTML page and PNG figures;
//! - [`export`]: files for other tools (Kalibr's `imu.yaml`, Allan curves as CSV).

pub mod export;
pub mod metrics;
pub mod provenance;
pub mod report;
