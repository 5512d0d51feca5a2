//! Digital signal processing: the streaming orthogonal wavelet filter bank and
//! the block-wise quantization-noise (QN) removal built on it.
