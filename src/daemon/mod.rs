//! The acquisition daemon: tokio tasks that move bytes from a source through
//! the synchronous numerics into the sinks.

pub mod batch;
pub mod config;
pub mod http;
pub mod shutdown;
pub mod telemetry;
