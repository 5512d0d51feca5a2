//! Digital signal processing: the streaming orthogonal wavelet filter bank and
//! the block-wise quantization-noise (QN) removal built on it.
//!
//! Role in the whole: `source` hands rate samples (arcsec/s) to [`qn::QnSplitter`],
//! which splits each sample into a `clean` part (ARW, bias instability, ...) and a
//! `noise` part (quantization noise) with `clean + noise == raw`; `allan` then
//! analyses both channels and `model` reads QN from `noise` and ARW from `clean`.
//! The daemon and the offline commands run this same synchronous code.
//!
//! Layers, bottom up:
//! - [`wavelet`]: orthogonal filter sets by name (`haar`, `db4`, `sym4`, `db8`, `sym8`).
//! - [`dwt`]: the batch reference (plain convolution and decimation, PyWavelets'
//!   definitions for modes `zero` and `periodization`).
//! - `isa` (crate-private): the one SIMD dispatch of the crate, `Isa`,
//!   also used by the Allan accumulators.
//! - `kernel` (private): the auto-vectorised block kernels the streaming code uses.
//! - [`bank`]: the streaming analysis ([`bank::StreamingAnalysis`]) and
//!   analysis + synthesis bank ([`bank::StreamingBank`]) with a fixed latency.
//! - [`gaps`]: which coefficients of a cascade touch filled (gap) samples.
//! - [`qn`]: the QN splitter ([`qn::QnSplitter`], [`qn::QnConfig`]).

pub mod bank;
pub mod dwt;
pub mod gaps;
pub(crate) mod isa;
mod kernel;
pub mod qn;
pub mod wavelet;

pub use bank::{CoeffHook, StreamingAnalysis, StreamingBank};
pub use qn::{LevelStats, QnConfig, QnEstimate, QnEstimates, QnRule, QnSplitter};
pub use wavelet::Wavelet;

/// Errors of the `dsp` layer. Messages name the offending key and value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DspError {
    /// A wavelet name that is not in [`wavelet::Wavelet::NAMES`].
    #[error("unknown wavelet {name:?}; known: haar, db4, sym4, db8, sym8")]
    UnknownWavelet {
        /// The name asked for.
        name: String,
    },
    /// A decomposition depth outside the supported range.
    #[error("invalid `levels` = {levels}: must be in 1..={max} ({why})")]
    InvalidLevels {
        /// The depth asked for.
        levels: u32,
        /// The largest depth allowed here.
        max: u32,
        /// Why the bound applies.
        why: &'static str,
    },
    /// A configuration value out of range.
    #[error("invalid `{key}` = {value}: {why}")]
    InvalidConfig {
        /// Config key (as spelled in the TOML/serde struct).
        key: &'static str,
        /// The offending value, printed.
        value: String,
        /// What is required.
        why: &'static str,
    },
    /// Batch transform inputs whose lengths do not fit together.
    #[error("length mismatch in {what}: {detail}")]
    LengthMismatch {
        /// Which operation.
        what: &'static str,
        /// The lengths involved.
        detail: String,
    },
}

/// `Result` alias for the `dsp` layer.
pub type Result<T> = std::result::Result<T, DspError>;
