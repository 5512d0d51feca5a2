//! Noise models: IEEE 952 terms and their Allan signatures, estimation,
//! simulation of the gyro, and diagnosis of model-versus-recording mismatch.

pub mod wvar;
pub mod fit;
pub mod estimate;
pub mod baseline;
