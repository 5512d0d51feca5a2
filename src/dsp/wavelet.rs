//! Orthogonal wavelet filter sets, by name.
//!
//! Role in the whole: the filter bank ([`super::bank`]) and the batch reference
//! ([`super::dwt`]) take their four filters from here. Only orthogonal wavelets are
//! offered (analysis = time-reversed synthesis), which is what makes the bank's
//! perfect reconstruction and the QN splitter's power bookkeeping exact.
//!
//! Each set is stored as its decomposition low-pass `dec_lo`: the Daubechies /
//! symlet constants derived from first principles (spectral factorisation at 60
//! digits by `scripts/gen-golden-pywt`, rounded once to the nearest double). For
//! haar, db4 and db8 these are bit for bit PyWavelets' tables. PyWavelets' sym4 and
//! sym8 tables are only good to about 1e-12 (they deviate from the exact filters by
//! up to 9e-13 and are orthonormal only to ~5e-13, which caps perfect
//! reconstruction at ~1e-12); sagnac uses the exact doubles, orthonormal to ~1e-16.
//! The other three filters follow from the quadrature-mirror relations PyWavelets uses:
//!
//! ```text
//! rec_lo[k] = dec_lo[L-1-k]
//! rec_hi[k] = (-1)^k dec_lo[k]
//! dec_hi[k] = rec_hi[L-1-k]
//! ```
//!
//! Tests (`tests/numerics/dsp_pywt_golden.rs`) check the tables bit for bit against the
//! derivation, against `pywt.Wavelet(name)` (bit for bit for haar/db, within 1e-12
//! for sym), and, independently of both, against the defining identities (unit
//! norm, double-shift orthogonality, vanishing moments; unit tests below).

use super::{DspError, Result};

/// Longest filter supported (sym8 / db8: 16 taps).
pub const MAX_TAPS: usize = 16;

const HAAR: [f64; 2] = [
    std::f64::consts::FRAC_1_SQRT_2,
    std::f64::consts::FRAC_1_SQRT_2,
];

const DB4: [f64; 8] = [
    -0.010597401785069032,
    0.0328830116668852,
    0.030841381835560764,
    -0.18703481171909309,
    -0.027983769416859854,
    0.6308807679298589,
    0.7148465705529157,
    0.2303778133088965,
];

const SYM4: [f64; 8] = [
    -0.07576571478950221,
    -0.029635527646002493,
    0.497618667632775,
    0.8037387518051321,
    0.29785779560530606,
    -0.09921954357663353,
    -0.012603967262031304,
    0.032223100604051466,
];

const DB8: [f64; 16] = [
    -0.00011747678412476953,
    0.0006754494064505693,
    -0.00039174037337694705,
    -0.004870352993451574,
    0.008746094047405777,
    0.013981027917398282,
    -0.044088253930794755,
    -0.017369301001807547,
    0.12874742662047847,
    0.0004724845739132828,
    -0.2840155429615469,
    -0.015829105256349306,
    0.5853546836542067,
    0.6756307362972898,
    0.31287159091429995,
    0.05441584224310401,
];

const SYM8: [f64; 16] = [
    -0.0033824159510050028,
    -0.0005421323318000107,
    0.03169508781152599,
    0.007607487324976609,
    -0.14329423835127267,
    -0.061273359067811076,
    0.4813596512590534,
    0.777185751699628,
    0.36444189483617895,
    -0.0519458381078818,
    -0.027219029917103486,
    0.04913717967373029,
    0.0038087520138944896,
    -0.014952258337062199,
    -0.0003029205147241331,
    0.001889950332767689,
];

/// An orthogonal wavelet: its four filters (PyWavelets conventions) and metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct Wavelet {
    name: &'static str,
    vanishing_moments: u32,
    dec_lo: Vec<f64>,
    dec_hi: Vec<f64>,
    rec_lo: Vec<f64>,
    rec_hi: Vec<f64>,
}

impl Wavelet {
    /// Names accepted by [`Wavelet::by_name`].
    pub const NAMES: [&'static str; 5] = ["haar", "db4", "sym4", "db8", "sym8"];

    /// The wavelet called `name` (PyWavelets spelling; `db1` is accepted for `haar`).
    pub fn by_name(name: &str) -> Result<Wavelet> {
        let (canon, taps, vm): (&'static str, &[f64], u32) = match name {
            "haar" | "db1" => ("haar", &HAAR, 1),
            "db4" => ("db4", &DB4, 4),
            "sym4" => ("sym4", &SYM4, 4),
            "db8" => ("db8", &DB8, 8),
            "sym8" => ("sym8", &SYM8, 8),
            _ => {
                return Err(DspError::UnknownWavelet {
                    name: name.to_string(),
                });
            }
        };
        Ok(Self::from_dec_lo(canon, taps, vm))
    }

    fn from_dec_lo(name: &'static str, dec_lo: &[f64], vanishing_moments: u32) -> Wavelet {
        let l = dec_lo.len();
        let rec_lo: Vec<f64> = dec_lo.iter().rev().copied().collect();
        let rec_hi: Vec<f64> = dec_lo
            .iter()
            .enumerate()
            .map(|(k, &c)| if k % 2 == 0 { c } else { -c })
            .collect();
        let dec_hi: Vec<f64> = (0..l).map(|k| rec_hi[l - 1 - k]).collect();
        Wavelet {
            name,
            vanishing_moments,
            dec_lo: dec_lo.to_vec(),
            dec_hi,
            rec_lo,
            rec_hi,
        }
    }

    /// Canonical name (`"sym8"`, ...).
    pub fn name(&self) -> &'static str {
        self.name
    }
    /// Filter length L (taps).
    pub fn len(&self) -> usize {
        self.dec_lo.len()
    }
    /// Always false (kept for clippy's `len_without_is_empty`).
    pub fn is_empty(&self) -> bool {
        self.dec_lo.is_empty()
    }
    /// Vanishing moments of the wavelet function psi.
    pub fn vanishing_moments(&self) -> u32 {
        self.vanishing_moments
    }
    /// Decomposition low-pass filter.
    pub fn dec_lo(&self) -> &[f64] {
        &self.dec_lo
    }
    /// Decomposition high-pass filter.
    pub fn dec_hi(&self) -> &[f64] {
        &self.dec_hi
    }
    /// Reconstruction low-pass filter.
    pub fn rec_lo(&self) -> &[f64] {
        &self.rec_lo
    }
    /// Reconstruction high-pass filter.
    pub fn rec_hi(&self) -> &[f64] {
        &self.rec_hi
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent of PyWavelets: an orthonormal two-channel bank with p vanishing
    /// moments satisfies sum h = sqrt 2, sum h[k] h[k+2m] = delta_m, and
    /// sum (-1)^k k^q h[k] = 0 for q < p.
    #[test]
    fn defining_identities() {
        for name in Wavelet::NAMES {
            let w = Wavelet::by_name(name).unwrap();
            let h = w.dec_lo();
            let l = h.len();
            let sum: f64 = h.iter().sum();
            // tolerance: a few ulps of sqrt 2 (16 terms summed).
            assert!(
                (sum - std::f64::consts::SQRT_2).abs() < 1e-15,
                "{name}: sum {sum}"
            );
            for m in 0..l / 2 {
                let c: f64 = (0..l - 2 * m).map(|k| h[k] * h[k + 2 * m]).sum();
                let want = if m == 0 { 1.0 } else { 0.0 };
                // tolerance 1e-15: products of O(1) doubles summed 16 times.
                assert!((c - want).abs() < 1e-15, "{name}: shift {m}: {c}");
            }
            for q in 0..w.vanishing_moments() {
                let (mut s, mut scale) = (0.0f64, 0.0f64);
                for (k, &c) in h.iter().enumerate() {
                    let t = (k as f64).powi(q as i32) * c;
                    s += if k % 2 == 0 { t } else { -t };
                    scale += t.abs();
                }
                // tolerance: relative to the sum of |terms| (cancellation), 1e-13.
                assert!(
                    s.abs() <= 1e-13 * scale,
                    "{name}: moment {q}: {s} (scale {scale})"
                );
            }
            // dec_hi is orthogonal to dec_lo at every even shift.
            let g = w.dec_hi();
            for m in -(l as i64 / 2)..=(l as i64 / 2) {
                let c: f64 = (0..l as i64)
                    .filter_map(|k| {
                        let j = k + 2 * m;
                        (0..l as i64)
                            .contains(&j)
                            .then(|| h[k as usize] * g[j as usize])
                    })
                    .sum();
                assert!(c.abs() < 1e-15, "{name}: lo/hi shift {m}: {c}");
            }
        }
    }

    #[test]
    fn unknown_name_is_an_error() {
        let e = Wavelet::by_name("sym9").unwrap_err();
        assert!(e.to_string().contains("sym9"));
        assert_eq!(Wavelet::by_name("db1").unwrap().name(), "haar");
    }
}
