//! # sagnac
//!
//! Ring-laser-gyro (RLG) bench testing. The data flow, and so the module layout:
//!
//! ```text
//! source (serial, replay, frame decoding, file input)
//!   -> dsp (streaming wavelet bank, quantization-noise removal)
//!   -> allan (batch and streaming Allan statistics with confidence intervals)
//!   -> model (noise terms, estimation, simulation)
//!   -> pipeline (dsp -> allan -> model, synchronously)
//!   -> diagnose (a recording against its gyro model)
//!   -> sink (MCAP recording, Prometheus metrics, reports)
//! ```
//!
//! `analyze` and the daemon both run the `pipeline`; `diagnose` simulates the
//! model and runs the pipeline's estimators on the recording. `daemon` wires
//! sources and sinks around the pipeline with tokio tasks; `cli` holds the
//! subcommands. The numeric modules (`dsp`, `allan`, `model`, `pipeline`,
//! `diagnose`) are plain synchronous Rust and never import tokio.

pub mod allan;
pub mod chain;
pub mod cli;
pub mod daemon;
pub mod diagnose;
pub mod dsp;
pub mod font;
pub mod input;
pub mod keys;
pub mod model;
pub(crate) mod par;
pub mod pipeline;
pub mod quality;
pub mod recording;
pub mod sink;
pub mod units;
