//! Phase 2, compare and locate: every statistic of the recording against the
//! model's Monte-Carlo band, as z-scores ([`super::compare`]) at the points of
//! [`super::points`], and the per-point gate that says where they part.
//!
//! The gate: Bonferroni over all detection points and their Stouffer windows,
//! family-wise `alpha` ([`super::compare::detect`]); the mismatch regions are
//! the tau spans of the tests that pass it.

use super::compare::{self, Family, Point, Region};
use super::points::{all_points, detect_points, mean_stats};
use super::reference::Reference;
use super::stats::StatSet;

/// What the comparison with the model's band found.
#[derive(Debug, Clone)]
pub struct Located {
    /// Every compared point (wavelet, MDEV, spectrum, raw Allan, kurtosis).
    pub before: Vec<Point>,
    /// Detection threshold on |z| and the largest |z| of the detection tests.
    pub z_crit: f64,
    pub max_abs_z: f64,
    /// Where the gate fired.
    pub regions: Vec<Region>,
    /// Largest |z| of the raw overlapping Allan variance.
    pub raw_allan_max_z: f64,
    /// chi2/dof of the detection points against the model.
    pub chi2_before: f64,
    /// The Monte-Carlo mean of every statistic.
    pub mc_mean: StatSet,
}

impl Located {
    /// The recording's wavelet points.
    pub fn wavelet_points(&self) -> Vec<&Point> {
        self.before
            .iter()
            .filter(|p| p.family == Family::Wavelet)
            .collect()
    }
}

/// Compare the recording with the reference at family-wise level `alpha`.
pub fn locate(r: &Reference, alpha: f64) -> Located {
    let before = all_points(&r.layout, &r.model, &r.obs, &r.runs, &r.kurt_taus);
    let det = detect_points(&before);
    let detection = compare::detect(&det, alpha);
    let raw_allan_max_z = before
        .iter()
        .filter(|p| p.family == Family::RawAllan)
        .map(|p| p.z.abs())
        .fold(0.0, f64::max);
    let chi2_before = compare::chi2_per_dof(&det, 0);
    Located {
        z_crit: detection.z_crit,
        max_abs_z: detection.max_abs_z,
        regions: detection.regions,
        raw_allan_max_z,
        chi2_before,
        mc_mean: mean_stats(&r.runs),
        before,
    }
}
