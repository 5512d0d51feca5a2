//! The diagnosis: model comparison, concealed effects, spectral lines, null
//! honesty, rate-output gyros, resonances, its statistics and random
//! telegraph noise.

#[path = "../support/mod.rs"]
mod support;

mod compare;
mod concealed;
mod lines;
mod null;
mod rate;
mod resonance;
mod stats;
mod stream;
mod telegraph;
