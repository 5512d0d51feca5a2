//! Phase value types of the streaming Allan engine and their summation kernels.
//!
//! The engine in [`super`] is generic over the type of the stored phase points so the
//! integer pulse-count path stays exact end to end:
//!
//! * `f64` (phase or integrated frequency): the second difference
//!   `z = (c - (b + b)) + a` is evaluated in exactly the order of the NIST SP 1065 /
//!   AllanTools formula `x[i+2m] - 2 x[i+m] + x[i]` (`b + b == 2 b` exactly), so each
//!   term is bitwise the one a batch evaluation produces. Squares are summed into 16
//!   independent lanes (explicit AVX2 or AVX-512 as [`Isa`] picks, else a portable loop doing
//!   the same IEEE operations per lane - no FMA - so both give identical bits). The lane
//!   of a term is fixed by tile boundaries at absolute sample indices, so the order never
//!   depends on how the caller split its input. Each block's lanes are reduced pairwise
//!   and added to a Neumaier compensated total. Error bound: a block of `B` terms adds
//!   at most about `(B/16) eps` relative error (1.8e-12 worst case for `B = 2^17`,
//!   typically `sqrt(B/16) eps`, 2e-14); the Neumaier total adds `2 eps` regardless of
//!   how many blocks (2.6e9 samples = 2e4 blocks) are summed.
//! * `i64` (cumulative pulse count): the cumulative count is kept in wrapping
//!   two's-complement arithmetic, so a second difference is exact whenever its true
//!   value fits in `i64` (`|z| <= 4 m max|increment| < 2^63`), even if the cumulative
//!   count itself wraps. `z^2` is formed in `i128` and summed in a saturating `u128`,
//!   exact while the sum stays below `2^128` (always for `|z| < 2^48` over 2^32 terms).

use std::fmt::Debug;

use crate::dsp::isa::Isa;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for i64 {}
}

/// A stored phase point: `f64` (phase/frequency input) or `i64` (pulse-count input).
///
/// Sealed: only the engine's two representations implement it.
pub trait PhaseValue:
    sealed::Sealed + Copy + Default + PartialEq + Send + Sync + Debug + 'static
{
    /// Running total of squared second differences over the whole stream.
    type Total: Copy + Default + Send + Sync + Debug + PartialEq;
    /// Partial sum of squared second differences over one block.
    type Partial: Copy + Default + Send + Sync + Debug;
    /// Lane accumulators of the block kernel (16 f64 lanes, or one exact `u128`).
    type Lanes: Copy + Default + Send + Sync + Debug;

    /// Add `(c[i] - 2 b[i] + a[i])^2` over equal-length slices to the lanes: element
    /// `i` goes to lane `i mod 16` for the whole multiples of 16, the remainder `r`
    /// elements to lanes `0 .. r`.
    fn sq_acc(a: &[Self], b: &[Self], c: &[Self], lanes: &mut Self::Lanes);
    /// Reduce lanes to a partial sum (fixed pairwise order).
    fn lanes_partial(lanes: &Self::Lanes) -> Self::Partial;
    /// Add one squared second difference `(c - 2 b + a)^2` to a partial sum.
    fn sq_add(p: &mut Self::Partial, a: Self, b: Self, c: Self);
    /// Fold a block partial into the running total.
    fn total_add(t: &mut Self::Total, p: Self::Partial);
    /// The running total as `f64` (correctly rounded for `i64`, compensated for `f64`).
    fn total_value(t: &Self::Total) -> f64;
    /// `t - u` as `f64` (exact before rounding for `i64`): a total less the part
    /// of it that is left out (terms touching filled samples).
    fn total_diff(t: &Self::Total, u: &Self::Total) -> f64;
    /// `a - b` in the representation (wrapping, hence exact, for `i64`).
    fn sub(a: Self, b: Self) -> Self;
    /// Conversion to `f64` (rounded once).
    fn to_f64(self) -> f64;
}

/// Neumaier (improved Kahan-Babuska) compensated sum.
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub struct Neumaier {
    sum: f64,
    comp: f64,
}

impl Neumaier {
    /// Add `v` with compensation of the rounding error.
    #[inline]
    pub fn add(&mut self, v: f64) {
        let t = self.sum + v;
        if self.sum.abs() >= v.abs() {
            self.comp += (self.sum - t) + v;
        } else {
            self.comp += (v - t) + self.sum;
        }
        self.sum = t;
    }

    /// The compensated value.
    #[inline]
    pub fn value(&self) -> f64 {
        self.sum + self.comp
    }
}

const LANES: usize = 16;

/// Portable kernel; the AVX2 one performs the same IEEE operations lane by lane.
#[inline(always)]
fn sq_acc_f64_body(a: &[f64], b: &[f64], c: &[f64], acc: &mut [f64; LANES]) {
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let whole = n / LANES * LANES;
    let chunks = a[..whole]
        .chunks_exact(LANES)
        .zip(b[..whole].chunks_exact(LANES))
        .zip(c[..whole].chunks_exact(LANES));
    for ((xa, xb), xc) in chunks {
        for l in 0..LANES {
            let z = (xc[l] - (xb[l] + xb[l])) + xa[l];
            acc[l] += z * z;
        }
    }
    for (l, k) in (whole..n).enumerate() {
        let z = (c[k] - (b[k] + b[k])) + a[k];
        acc[l] += z * z;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sq_acc_f64_avx2(a: &[f64], b: &[f64], c: &[f64], acc: &mut [f64; LANES]) {
    use std::arch::x86_64::*;
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let whole = n / LANES * LANES;
    // SAFETY: AVX2 is enabled for this function; every load reads 4 f64 at an offset
    // `i + 4k` with `i + 16 <= whole <= n` from slices of length `n`, and the
    // accumulator array has 16 elements.
    unsafe {
        let mut s0 = _mm256_loadu_pd(acc.as_ptr());
        let mut s1 = _mm256_loadu_pd(acc.as_ptr().add(4));
        let mut s2 = _mm256_loadu_pd(acc.as_ptr().add(8));
        let mut s3 = _mm256_loadu_pd(acc.as_ptr().add(12));
        let (pa, pb, pc) = (a.as_ptr(), b.as_ptr(), c.as_ptr());
        let mut i = 0;
        while i < whole {
            macro_rules! lane {
                ($s:ident, $k:expr) => {{
                    let xa = _mm256_loadu_pd(pa.add(i + $k));
                    let xb = _mm256_loadu_pd(pb.add(i + $k));
                    let xc = _mm256_loadu_pd(pc.add(i + $k));
                    let z = _mm256_add_pd(_mm256_sub_pd(xc, _mm256_add_pd(xb, xb)), xa);
                    $s = _mm256_add_pd($s, _mm256_mul_pd(z, z));
                }};
            }
            lane!(s0, 0);
            lane!(s1, 4);
            lane!(s2, 8);
            lane!(s3, 12);
            i += LANES;
        }
        _mm256_storeu_pd(acc.as_mut_ptr(), s0);
        _mm256_storeu_pd(acc.as_mut_ptr().add(4), s1);
        _mm256_storeu_pd(acc.as_mut_ptr().add(8), s2);
        _mm256_storeu_pd(acc.as_mut_ptr().add(12), s3);
    }
    for (l, k) in (whole..n).enumerate() {
        let z = (c[k] - (b[k] + b[k])) + a[k];
        acc[l] += z * z;
    }
}

/// The same kernel with 512-bit vectors: lanes 0-7 and 8-15 in two registers,
/// the same IEEE operations per lane (no FMA), hence the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn sq_acc_f64_avx512(a: &[f64], b: &[f64], c: &[f64], acc: &mut [f64; LANES]) {
    use std::arch::x86_64::*;
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let whole = n / LANES * LANES;
    // SAFETY: AVX-512F is enabled for this function; every load reads 8 f64 at an
    // offset `i + 8k` with `i + 16 <= whole <= n` from slices of length `n`, and the
    // accumulator array has 16 elements.
    unsafe {
        let mut s0 = _mm512_loadu_pd(acc.as_ptr());
        let mut s1 = _mm512_loadu_pd(acc.as_ptr().add(8));
        let (pa, pb, pc) = (a.as_ptr(), b.as_ptr(), c.as_ptr());
        let mut i = 0;
        while i < whole {
            macro_rules! lane {
                ($s:ident, $k:expr) => {{
                    let xa = _mm512_loadu_pd(pa.add(i + $k));
                    let xb = _mm512_loadu_pd(pb.add(i + $k));
                    let xc = _mm512_loadu_pd(pc.add(i + $k));
                    let z = _mm512_add_pd(_mm512_sub_pd(xc, _mm512_add_pd(xb, xb)), xa);
                    $s = _mm512_add_pd($s, _mm512_mul_pd(z, z));
                }};
            }
            lane!(s0, 0);
            lane!(s1, 8);
            i += LANES;
        }
        _mm512_storeu_pd(acc.as_mut_ptr(), s0);
        _mm512_storeu_pd(acc.as_mut_ptr().add(8), s1);
    }
    for (l, k) in (whole..n).enumerate() {
        let z = (c[k] - (b[k] + b[k])) + a[k];
        acc[l] += z * z;
    }
}

fn sq_acc_f64(a: &[f64], b: &[f64], c: &[f64], acc: &mut [f64; LANES]) {
    sq_acc_f64_on(Isa::detect(), a, b, c, acc)
}

/// The f64 kernel variant `isa`.
fn sq_acc_f64_on(isa: Isa, a: &[f64], b: &[f64], c: &[f64], acc: &mut [f64; LANES]) {
    match isa {
        Isa::Baseline => sq_acc_f64_body(a, b, c, acc),
        // SAFETY: an `Avx2` exists only on a CPU with AVX2 (crate::dsp::isa).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { sq_acc_f64_avx2(a, b, c, acc) },
        // SAFETY: an `Avx512` exists only on a CPU with AVX-512F (crate::dsp::isa).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { sq_acc_f64_avx512(a, b, c, acc) },
    }
}

impl PhaseValue for f64 {
    type Total = Neumaier;
    type Partial = f64;
    type Lanes = [f64; LANES];

    #[inline]
    fn sq_acc(a: &[f64], b: &[f64], c: &[f64], lanes: &mut [f64; LANES]) {
        sq_acc_f64(a, b, c, lanes)
    }
    #[inline]
    fn lanes_partial(l: &[f64; LANES]) -> f64 {
        let q = |k: usize| (l[k] + l[k + 1]) + (l[k + 2] + l[k + 3]);
        (q(0) + q(4)) + (q(8) + q(12))
    }
    #[inline]
    fn sq_add(p: &mut f64, a: f64, b: f64, c: f64) {
        let z = (c - (b + b)) + a;
        *p += z * z;
    }
    #[inline]
    fn total_add(t: &mut Neumaier, p: f64) {
        t.add(p);
    }
    #[inline]
    fn total_value(t: &Neumaier) -> f64 {
        t.value()
    }
    #[inline]
    fn total_diff(t: &Neumaier, u: &Neumaier) -> f64 {
        t.value() - u.value()
    }
    #[inline]
    fn sub(a: f64, b: f64) -> f64 {
        a - b
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

#[inline(always)]
fn d2_i64(a: i64, b: i64, c: i64) -> i64 {
    c.wrapping_sub(b.wrapping_mul(2)).wrapping_add(a)
}

#[inline(always)]
fn sq_i64(z: i64) -> u128 {
    let w = i128::from(z);
    (w * w) as u128
}

/// Exact scalar kernel of the count path: every square in `u128`.
#[inline(always)]
fn sq_acc_i64_scalar(a: &[i64], b: &[i64], c: &[i64], total: &mut u128) {
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let mut t = *total;
    for ((&xa, &xb), &xc) in a.iter().zip(b).zip(c) {
        t = t.saturating_add(sq_i64(d2_i64(xa, xb, xc)));
    }
    *total = t;
}

/// Elements per chunk of the vector count kernel: with every `|z| < 2^SMALL_Z_BITS`
/// each of its 4 lanes sums `I64_CHUNK / 4` squares below `2^(2 SMALL_Z_BITS)`,
/// i.e. below `2^62`: no `u64` lane can overflow.
const I64_CHUNK: usize = 256;
const SMALL_Z_BITS: u32 = 28;

/// The count kernel with AVX2: second differences in 64-bit lanes, squared by the
/// 32 x 32 -> 64-bit multiply and summed in `u64` lanes, exact whenever every
/// `|z| < 2^28` in a chunk of 256 (a gyro's second differences are the pulse
/// difference of two adjacent windows: noise-sized, far below that); a chunk with
/// a larger `z` is redone by the exact `u128` scalar kernel. Same integer total
/// as [`sq_acc_i64_scalar`], hence bitwise the same result.
///
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sq_acc_i64_avx2(a: &[i64], b: &[i64], c: &[i64], total: &mut u128) {
    use std::arch::x86_64::*;
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let whole = n / I64_CHUNK * I64_CHUNK;
    let mut t = *total;
    let mut k0 = 0;
    while k0 < whole {
        // SAFETY: k0 + I64_CHUNK <= n for all three slices; unaligned loads.
        let (sum, out_of_range) = unsafe {
            let bias = _mm256_set1_epi64x(1 << SMALL_Z_BITS);
            let mut acc0 = _mm256_setzero_si256();
            let mut acc1 = _mm256_setzero_si256();
            let mut bad = _mm256_setzero_si256();
            let (pa, pb, pc) = (a.as_ptr().add(k0), b.as_ptr().add(k0), c.as_ptr().add(k0));
            let mut i = 0;
            while i < I64_CHUNK {
                macro_rules! step {
                    ($acc:ident, $k:expr) => {{
                        let xa = _mm256_loadu_si256(pa.add(i + $k) as *const __m256i);
                        let xb = _mm256_loadu_si256(pb.add(i + $k) as *const __m256i);
                        let xc = _mm256_loadu_si256(pc.add(i + $k) as *const __m256i);
                        let z =
                            _mm256_add_epi64(_mm256_sub_epi64(xc, _mm256_add_epi64(xb, xb)), xa);
                        // |z| < 2^28 <=> 0 <= z + 2^28 < 2^29 (unsigned): no bit above 28
                        bad = _mm256_or_si256(
                            bad,
                            _mm256_srli_epi64(_mm256_add_epi64(z, bias), SMALL_Z_BITS as i32 + 1),
                        );
                        $acc = _mm256_add_epi64($acc, _mm256_mul_epi32(z, z));
                    }};
                }
                step!(acc0, 0);
                step!(acc1, 4);
                i += 8;
            }
            let mut lanes = [0u64; 8];
            _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, acc0);
            _mm256_storeu_si256(lanes.as_mut_ptr().add(4) as *mut __m256i, acc1);
            let sum: u128 = lanes.iter().map(|&l| u128::from(l)).sum();
            (sum, _mm256_testz_si256(bad, bad) == 0)
        };
        if out_of_range {
            let r = k0..k0 + I64_CHUNK;
            sq_acc_i64_scalar(&a[r.clone()], &b[r.clone()], &c[r], &mut t);
        } else {
            t = t.saturating_add(sum);
        }
        k0 += I64_CHUNK;
    }
    sq_acc_i64_scalar(&a[whole..], &b[whole..], &c[whole..], &mut t);
    *total = t;
}

/// The count kernel with 512-bit vectors (8 lanes, two registers; each lane sums
/// 16 squares of a chunk): exact under the same `|z| < 2^28` test, a chunk that
/// fails it redone in `u128`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn sq_acc_i64_avx512(a: &[i64], b: &[i64], c: &[i64], total: &mut u128) {
    use std::arch::x86_64::*;
    let n = c.len();
    let (a, b) = (&a[..n], &b[..n]);
    let whole = n / I64_CHUNK * I64_CHUNK;
    let mut t = *total;
    let mut k0 = 0;
    while k0 < whole {
        // SAFETY: k0 + I64_CHUNK <= n for all three slices; unaligned loads.
        let (sum, out_of_range) = unsafe {
            let bias = _mm512_set1_epi64(1 << SMALL_Z_BITS);
            let mut acc0 = _mm512_setzero_si512();
            let mut acc1 = _mm512_setzero_si512();
            let mut bad = _mm512_setzero_si512();
            let (pa, pb, pc) = (a.as_ptr().add(k0), b.as_ptr().add(k0), c.as_ptr().add(k0));
            let mut i = 0;
            while i < I64_CHUNK {
                macro_rules! step {
                    ($acc:ident, $k:expr) => {{
                        let xa = _mm512_loadu_si512(pa.add(i + $k) as *const __m512i);
                        let xb = _mm512_loadu_si512(pb.add(i + $k) as *const __m512i);
                        let xc = _mm512_loadu_si512(pc.add(i + $k) as *const __m512i);
                        let z =
                            _mm512_add_epi64(_mm512_sub_epi64(xc, _mm512_add_epi64(xb, xb)), xa);
                        // |z| < 2^28 <=> 0 <= z + 2^28 < 2^29 (unsigned): no bit above 28
                        bad = _mm512_or_si512(
                            bad,
                            _mm512_srli_epi64::<{ SMALL_Z_BITS + 1 }>(_mm512_add_epi64(z, bias)),
                        );
                        $acc = _mm512_add_epi64($acc, _mm512_mul_epi32(z, z));
                    }};
                }
                step!(acc0, 0);
                step!(acc1, 8);
                i += 16;
            }
            let mut lanes = [0u64; 16];
            _mm512_storeu_si512(lanes.as_mut_ptr() as *mut __m512i, acc0);
            _mm512_storeu_si512(lanes.as_mut_ptr().add(8) as *mut __m512i, acc1);
            let sum: u128 = lanes.iter().map(|&l| u128::from(l)).sum();
            (sum, _mm512_test_epi64_mask(bad, bad) != 0)
        };
        if out_of_range {
            let r = k0..k0 + I64_CHUNK;
            sq_acc_i64_scalar(&a[r.clone()], &b[r.clone()], &c[r], &mut t);
        } else {
            t = t.saturating_add(sum);
        }
        k0 += I64_CHUNK;
    }
    sq_acc_i64_scalar(&a[whole..], &b[whole..], &c[whole..], &mut t);
    *total = t;
}

fn sq_acc_i64(a: &[i64], b: &[i64], c: &[i64], total: &mut u128) {
    sq_acc_i64_on(Isa::detect(), a, b, c, total)
}

/// The count kernel variant `isa`.
fn sq_acc_i64_on(isa: Isa, a: &[i64], b: &[i64], c: &[i64], total: &mut u128) {
    match isa {
        Isa::Baseline => sq_acc_i64_scalar(a, b, c, total),
        // SAFETY: an `Avx2` exists only on a CPU with AVX2 (crate::dsp::isa).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { sq_acc_i64_avx2(a, b, c, total) },
        // SAFETY: an `Avx512` exists only on a CPU with AVX-512F (crate::dsp::isa).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { sq_acc_i64_avx512(a, b, c, total) },
    }
}

impl PhaseValue for i64 {
    type Total = u128;
    type Partial = u128;
    type Lanes = u128;

    #[inline]
    fn sq_acc(a: &[i64], b: &[i64], c: &[i64], lanes: &mut u128) {
        sq_acc_i64(a, b, c, lanes)
    }
    #[inline]
    fn lanes_partial(l: &u128) -> u128 {
        *l
    }
    #[inline]
    fn sq_add(p: &mut u128, a: i64, b: i64, c: i64) {
        *p = p.saturating_add(sq_i64(d2_i64(a, b, c)));
    }
    #[inline]
    fn total_add(t: &mut u128, p: u128) {
        *t = t.saturating_add(p);
    }
    #[inline]
    fn total_value(t: &u128) -> f64 {
        *t as f64
    }
    #[inline]
    fn total_diff(t: &u128, u: &u128) -> f64 {
        t.saturating_sub(*u) as f64
    }
    #[inline]
    fn sub(a: i64, b: i64) -> i64 {
        a.wrapping_sub(b)
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type F64Kernel = fn(&[f64], &[f64], &[f64], &mut [f64; LANES]);
    type I64Kernel = fn(&[i64], &[i64], &[i64], &mut u128);

    /// The dispatched kernel `$dispatched` and every variant of `$on` this CPU
    /// runs ([`Isa::available`]), named.
    macro_rules! variants {
        ($ty:ty, $dispatched:ident, $on:ident) => {{
            let mut k: Vec<(String, $ty)> = vec![("dispatched".into(), $dispatched)];
            for isa in Isa::available() {
                let f: $ty = match isa {
                    Isa::Baseline => |a, b, c, t| $on(Isa::Baseline, a, b, c, t),
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx2 => |a, b, c, t| $on(Isa::Avx2, a, b, c, t),
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx512 => |a, b, c, t| $on(Isa::Avx512, a, b, c, t),
                };
                k.push((format!("{isa:?}"), f));
            }
            k
        }};
    }

    fn f64_kernels() -> Vec<(String, F64Kernel)> {
        variants!(F64Kernel, sq_acc_f64, sq_acc_f64_on)
    }

    fn i64_kernels() -> Vec<(String, I64Kernel)> {
        variants!(I64Kernel, sq_acc_i64, sq_acc_i64_on)
    }

    #[test]
    fn dispatched_kernel_is_bitwise_the_portable_one() {
        // Whatever path the CPU takes (AVX-512, AVX2 or neither), every lane must hold the same bits.
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let x: Vec<f64> = (0..5000)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f64 / (1u64 << 53) as f64 * 1e3 - 500.0
            })
            .collect();
        for (len, m) in [(0usize, 1usize), (7, 2), (16, 3), (1023, 64), (4000, 256)] {
            let mut a = [0.5f64; 16];
            sq_acc_f64_body(&x[..len], &x[m..m + len], &x[2 * m..2 * m + len], &mut a);
            for (name, kernel) in f64_kernels() {
                let mut b = [0.5f64; 16];
                kernel(&x[..len], &x[m..m + len], &x[2 * m..2 * m + len], &mut b);
                assert_eq!(
                    a.map(f64::to_bits),
                    b.map(f64::to_bits),
                    "{name}: len {len} m {m}"
                );
            }
            // And the lanes hold the plain sum (1e-12 relative, different order).
            let plain: f64 = (0..len)
                .map(|i| {
                    let z = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    z * z
                })
                .sum::<f64>()
                + 8.0;
            let got = <f64 as PhaseValue>::lanes_partial(&a);
            assert!((got - plain).abs() <= 1e-12 * plain, "{got} vs {plain}");
        }
    }

    #[test]
    fn vector_count_kernel_is_the_exact_scalar_one() {
        // small second differences (the vector path), huge ones (chunks redone in
        // u128), wrapping cumulative counts, and every length around the chunk size
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for (scale, wrap) in [
            (3i64, 0i64),
            (1 << 20, 0),
            (1 << 27, 0),
            (1 << 40, 0),
            (5, i64::MAX - 1000),
        ] {
            let mut x = vec![wrap];
            for _ in 0..3000 {
                let inc = (next() % (2 * scale as u64 + 1)) as i64 - scale;
                let last = *x.last().unwrap();
                x.push(last.wrapping_add(inc));
            }
            // one isolated spike beyond 2^28 in the middle of a small-z stream
            if scale == 3 {
                x[1500] = x[1500].wrapping_add(1 << 30);
            }
            for len in [0, 1, 255, 256, 257, 511, 512, 1000, 2990] {
                for m in [1usize, 4] {
                    let (a, b, c) = (&x[..len], &x[m..m + len], &x[2 * m..2 * m + len]);
                    let mut exact = 7u128;
                    sq_acc_i64_scalar(a, b, c, &mut exact);
                    for (name, kernel) in i64_kernels() {
                        let mut got = 7u128;
                        kernel(a, b, c, &mut got);
                        assert_eq!(got, exact, "{name}: scale {scale} len {len} m {m}");
                    }
                }
            }
        }
    }

    #[test]
    fn neumaier_recovers_what_plain_summation_loses() {
        let mut n = Neumaier::default();
        n.add(1e16);
        for _ in 0..1000 {
            n.add(1.0);
        }
        n.add(-1e16);
        assert_eq!(n.value(), 1000.0);
    }
}
