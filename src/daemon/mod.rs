//! The acquisition daemon: tokio tasks that move bytes from a source through
//! the synchronous numerics into the sinks.

pub mod config;
pub mod http;
