//! The daemon (`sagnac run`): its command line, the processing stage, replays,
//! serial sources over a pseudo-terminal, simulated and triad sources.

#[path = "../support/mod.rs"]
mod support;

mod cli;
mod process;
mod replay;
mod serial;
mod simulate;
mod triad;
