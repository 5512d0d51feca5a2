//! Which compiled variant of a SIMD kernel this CPU runs: one [`Isa`], detected
//! once per process, picks the variant of every hand-vectorised kernel of the
//! crate, the wavelet bank's (`dsp::kernel`) and the Allan accumulators'
//! (`allan::streaming`) alike.
//!
//! The style, everywhere: each variant is a safe `#[target_feature]` function;
//! its caller matches on an `Isa` and calls it in an `unsafe` block whose SAFETY
//! note rests on this module's guarantee: a value other than [`Isa::Baseline`]
//! exists only after `is_x86_feature_detected!` confirmed every feature it names
//! (`Avx2`: AVX2 and FMA; `Avx512`: AVX-512F, AVX-512VL, AVX2 and FMA). Variants
//! give bit-identical results (each kernel's tests check it), so the choice only
//! changes speed.

use std::sync::OnceLock;

/// A compiled variant of the kernels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Isa {
    /// The baseline target: no run-time feature.
    Baseline,
    /// AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// AVX-512F and AVX-512VL, with AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

#[cfg(target_arch = "x86_64")]
fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

#[cfg(target_arch = "x86_64")]
fn has_avx512() -> bool {
    has_avx2()
        && std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
}

impl Isa {
    /// The variant called `name` (`baseline`, `avx2`, `avx512`), if this CPU runs it.
    pub fn by_name(name: &str) -> Option<Isa> {
        match name {
            "baseline" => Some(Isa::Baseline),
            #[cfg(target_arch = "x86_64")]
            "avx2" if has_avx2() => Some(Isa::Avx2),
            #[cfg(target_arch = "x86_64")]
            "avx512" if has_avx512() => Some(Isa::Avx512),
            _ => None,
        }
    }

    /// The best variant this CPU runs (AVX-512 > AVX2 > baseline), detected on
    /// the first call.
    pub fn detect() -> Isa {
        static BEST: OnceLock<Isa> = OnceLock::new();
        *BEST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            if has_avx512() {
                return Isa::Avx512;
            }
            #[cfg(target_arch = "x86_64")]
            if has_avx2() {
                return Isa::Avx2;
            }
            Isa::Baseline
        })
    }

    /// Every variant this CPU runs, best last (for the tests that hold them
    /// bit-identical).
    #[cfg(test)]
    pub fn available() -> Vec<Isa> {
        ["baseline", "avx2", "avx512"]
            .into_iter()
            .filter_map(Isa::by_name)
            .collect()
    }
}
