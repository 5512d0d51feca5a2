//! Monitoring: the Prometheus rules and dashboard on a real Prometheus, the lab
//! setup, the HTTP and metrics sinks, and the Docker image.

#[path = "../support/mod.rs"]
mod support;

mod docker_image;
mod prometheus_dashboard;
mod prometheus_lab;
mod prometheus_rules;
mod sink_http;
mod sink_metrics;
