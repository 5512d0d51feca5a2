//! The diagnosis: model comparison, concealed effects, spectral lines, null
//! honesty, power, rate-output gyros, resonances, its statistics and random
//! telegraph noise.

#[path = "../support/mod.rs"]
mod support;

mod compare;
mod concealed;
mod lines;
mod null;
mod power;
mod rate;
mod resonance;
mod stats;
mod telegraph;
