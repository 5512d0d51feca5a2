//! Phase 7, report: the JSON document (`sagnac diagnose --json`) and the
//! findings in words.
//!
//! The JSON holds the verdict, the mismatch regions, the parameter changes
//! (one per parameter, from the model's value to the last fitted one), the
//! added terms with their physical explanations and 95 % intervals, and
//! chi2/dof before and after. Term names are model-file keys. The notes are
//! the same findings as sentences, with what the tests saw.

use serde::{Deserialize, Serialize};

use super::candidates::ModelComparison;
use super::compare::Region;
use super::findings::{Finding, fmt_g, merged_changes};
pub use super::types::{AddedTerm, ParameterChange};

/// `"consistent"` or `"mismatch"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    Consistent,
    Mismatch,
}

/// A tau range of mismatch (JSON).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MismatchRegion {
    pub tau_min_s: f64,
    pub tau_max_s: f64,
    pub max_z: f64,
}

/// Chi-square per degree of freedom over the compared points (JSON).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitQuality {
    pub chi2_per_dof: f64,
}

/// The JSON document of `sagnac diagnose --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiagnosisReport {
    pub verdict: Verdict,
    pub mismatch_regions: Vec<MismatchRegion>,
    pub parameter_changes: Vec<ParameterChange>,
    pub added_terms: Vec<AddedTerm>,
    pub fit_before: FitQuality,
    pub fit_after: FitQuality,
}

/// The JSON document of the findings.
pub(crate) fn document(
    mismatch: bool,
    regions: &[Region],
    findings: &[Finding],
    chi2_before: f64,
    chi2_after: f64,
) -> DiagnosisReport {
    DiagnosisReport {
        verdict: if mismatch {
            Verdict::Mismatch
        } else {
            Verdict::Consistent
        },
        mismatch_regions: regions
            .iter()
            .map(|g| MismatchRegion {
                tau_min_s: g.tau_min_s,
                tau_max_s: g.tau_max_s,
                max_z: g.max_z,
            })
            .collect(),
        parameter_changes: merged_changes(findings),
        added_terms: findings.iter().filter_map(|f| f.added.clone()).collect(),
        fit_before: FitQuality {
            chi2_per_dof: chi2_before,
        },
        fit_after: FitQuality {
            chi2_per_dof: chi2_after,
        },
    }
}

/// The note of a recording simulated at another rate than the model's.
pub(crate) fn rate_note(fs: f64, model_fs: f64) -> Option<String> {
    ((fs - model_fs).abs() > 1e-9 * model_fs).then(|| {
        format!(
            "The recording's sample rate ({} Hz) differs from the model's ({} Hz): the model was simulated, \
             and an updated model is written, at the recording's rate.",
            fmt_g(fs),
            fmt_g(model_fs)
        )
    })
}

/// The note of a detection by model comparison.
pub(crate) fn comparison_note(
    c: &ModelComparison,
    alpha: f64,
    max_abs_z: f64,
    z_crit: f64,
) -> String {
    format!(
        "Model comparison: the best catalog change ({}) improves the wavelet-variance likelihood by LR = {:.1}, \
         above the {:.0} % threshold {:.1} calibrated on the model's own runs (leave-one-out bootstrap, \
         max over the catalog: c chi2_k with c = {:.2}, k = {:.1}); largest single-point |z| {:.2} (threshold {:.2}).",
        c.best,
        c.max_lr,
        100.0 * alpha,
        c.lr_crit,
        c.tail.0,
        c.tail.1,
        max_abs_z,
        z_crit
    )
}

/// The closing notes: each finding in words, the alternatives the wavelet
/// variances do not exclude, and the verdict when nothing was explained or
/// nothing was found.
pub(crate) fn closing_notes(
    findings: &[Finding],
    comparison: Option<&ModelComparison>,
    mismatch: bool,
    max_abs_z: f64,
    z_crit: f64,
) -> Vec<String> {
    let mut notes: Vec<String> = findings.iter().map(|f| f.note.clone()).collect();
    if let Some(c) = comparison.filter(|c| c.detected) {
        let near = c.near_best(4.0);
        if near.len() > 1 {
            notes.push(format!(
                "The wavelet variances do not exclude these alternatives (AIC within 4 of the best): {}.",
                near.iter().map(|e| format!("{} (LR {:.1})", e.0, e.1)).collect::<Vec<_>>().join(", ")
            ));
        }
    }
    if findings.is_empty() && mismatch {
        notes.push(
            "The recording departs from the model but no catalog term explains it significantly."
                .into(),
        );
    }
    if !mismatch {
        let lr = comparison.map_or(String::new(), |c| {
            format!(
                "best catalog change {} at LR {:.1} (threshold {:.1}), ",
                c.best, c.max_lr, c.lr_crit
            )
        });
        notes.push(format!(
            "The recording is consistent with the model: max |z| = {max_abs_z:.2} (threshold {z_crit:.2}), {lr}no lines, \
             slopes within their bands."
        ));
    }
    notes
}
