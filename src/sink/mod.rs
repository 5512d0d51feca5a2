//! Sinks: MCAP recording and Prometheus metrics.
