//! Numerics: Allan deviations against Stable32 and AllanTools, the streaming
//! engine, the wavelet bank and the QN splitter, gaps, the estimator, the gyro
//! model and its simulator.

#[path = "../support/mod.rs"]
mod support;

mod allan_allantools;
mod allan_stable32;
mod allan_streaming;
mod dsp_bank;
mod dsp_pywt_golden;
mod dsp_qn;
mod dsp_qn_rules;
mod estimate_calibration;
mod estimate_filter;
mod gaps;
mod model_config;
mod model_resonance;
mod model_sim;
mod model_terms;
