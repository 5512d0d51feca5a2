//! The MCAP recording: the file `sagnac run` writes and `replay`, `analyze`,
//! `report` and `diagnose` read.
//!
//! - [`messages`]: the typed messages of the channels and their JSON Schemas;
//! - [`meta`]: the `sagnac` Metadata record (sample rate, pulse weight, model,
//!   config) and the rule for a flag that meets a recorded value;
//! - [`writer`]: the [`writer::Recorder`], one zstd-chunked MCAP file per run,
//!   written on its own thread with a bounded-loss flush policy;
//! - [`reader`]: reading recordings back and recovering truncated ones.

pub mod messages;
pub mod meta;
pub mod reader;
pub mod writer;
