//! The command line: `sagnac allan`, `analyze`, `completions`, `diagnose`,
//! `simulate`, the terminal output, the exports, `report`, the spec and the
//! data-quality checks, each through the built binary.

#[path = "../support/mod.rs"]
mod support;

mod allan;
mod analyze;
mod completions;
mod diagnose;
mod export;
mod quality;
mod report;
mod simulate;
mod spec;
mod terminal;
