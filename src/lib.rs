//! # sagnac
//!
//! Ring-laser-gyro (RLG) bench testing. The data flow, and so the module layout:
//!
//! ```text
//! source (serial, replay, frame decoding, file input)
//!   -> dsp (streaming wavelet bank, quantization-noise removal)
//!   -> allan (batch and streaming Allan statistics with confidence intervals)
//!   -> model (noise terms, estimation, simulation, diagnosis)
//!   -> sink (MCAP recording, Prometheus metrics)
//! ```
//!
//! `pipeline` chains dsp -> allan -> model synchronously; `analyze` and the
//! daemon both run it. `daemon` wires sources and sinks around it with tokio
//! tasks; `cli` holds the subcommands. The numeric modules (`dsp`, `allan`,
//! `model`, `pipeline`) are plain synchronous Rust and never import tokio.

pub mod allan;
pub mod cli;
pub mod daemon;
pub mod dsp;
pub mod font;
pub mod model;
pub mod offline;
pub mod pipeline;
pub mod sink;
pub mod source;
pub mod units;
