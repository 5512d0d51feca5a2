//! The diagnosis proved on recordings where the left-out effect is
//! concealed, i.e. invisible in the raw Allan deviation within its band, yet
//! real. Each case simulates a "real" gyro (the model plus the effect) with
//! `model::sim`, diagnoses it against the model, and asserts that
//! * the raw Allan deviation alone does not see it (max |z| below its own
//!   Bonferroni 5 % threshold over its taus),
//! * the diagnosis says "mismatch", names the right physics (a parameter change
//!   when that is what happened, a new term otherwise) and its 95 % intervals
//!   cover the truth,
//! * the updated model, simulated again, fits: chi2/dof drops.
//!
//! Matched recordings (model = truth) must come out "consistent" with nothing
//! added. `scripts/bench-diagnose` prints the table of all cases over more
//! seeds (`examples/bench_diagnose`, with the cases of `concealed/shared.rs`).

use sagnac::model::GyroModel;

mod shared;

use shared::{Expect, cases, judge, run};

fn check(name: &str) {
    let case = cases().into_iter().find(|c| c.name == name).unwrap();
    let o = run(&case);
    let r = &o.diag.report;
    let (named, fit, ok) = judge(&case, &o);
    eprintln!(
        "{name}: raw-AV max|z| {:.2} (threshold {:.2}); detection max|z| {:.2} (threshold {:.2}), ramp z {:.2}; {named}; {fit}; chi2/dof {:.2} -> {:.2}",
        o.diag.raw_allan_max_z,
        o.raw_threshold,
        o.diag.max_abs_z,
        o.diag.z_crit,
        o.diag.ramp_z,
        r.fit_before.chi2_per_dof,
        r.fit_after.chi2_per_dof
    );
    eprintln!("{}", serde_json::to_string_pretty(r).unwrap());
    assert!(
        ok,
        "{name}: expected {:?}, got {named} / {fit}",
        case.expect
    );
    // concealed: the raw Allan deviation alone would not raise an alarm
    assert!(
        o.diag.raw_allan_max_z < o.raw_threshold,
        "{name}: raw Allan max |z| {} reaches its threshold {}",
        o.diag.raw_allan_max_z,
        o.raw_threshold
    );
    if !matches!(case.expect, Expect::Consistent) {
        // a thermal sensitivity (the rate regressed on the recorded temperature)
        // and a rate ramp (the rate's slope) are found by tests without a tau
        // range, and the chi2 points (wavelets, MDEV, spectrum) barely see them
        let slope_found = matches!(case.expect, Expect::Added("thermal" | "rate_ramp_dphh", _));
        // the fit improves (broadband effects), and the updated model fits
        // about as well as a matched one (all)
        assert!(
            slope_found || r.fit_after.chi2_per_dof < r.fit_before.chi2_per_dof,
            "{name}: chi2/dof {} -> {}",
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof
        );
        assert!(
            r.fit_after.chi2_per_dof < 1.5,
            "{name}: chi2/dof after {}",
            r.fit_after.chi2_per_dof
        );
        // every broadband or line effect is located in tau
        if !slope_found {
            assert!(!r.mismatch_regions.is_empty(), "{name}: no region located");
        }
        let m = o.diag.updated_model.as_ref().expect("an updated model");
        // the written model is valid and parses back
        let back = GyroModel::from_toml_str(&m.to_toml().unwrap(), "updated").unwrap();
        assert_eq!(&back, m);
    }
}

#[test]
fn gauss_markov_masquerading_as_arw_is_found() {
    check("gm_as_arw");
}

#[test]
fn sinusoid_buried_under_quantization_is_found() {
    check("sine_under_qn");
}

#[test]
fn gauss_markov_at_another_rate_duration_and_magnitude_is_found() {
    check("gm_as_arw_b");
}

#[test]
fn slow_sinusoid_under_quantization_is_found() {
    check("sine_b");
}

#[test]
fn arw_change_is_a_parameter_change_not_a_new_term() {
    check("arw_changed");
}

#[test]
fn random_telegraph_is_told_from_its_gauss_markov_twin() {
    check("telegraph");
}

#[test]
fn thermal_sensitivity_is_found_from_the_temperature_channel() {
    check("thermal");
}

/// Under a chamber ramp the response is a rate ramp; the recorded
/// temperature is named as its cause, not a ramp.
#[test]
fn a_temperature_ramp_is_named_as_the_cause_of_a_rate_ramp() {
    check("thermal_ramp");
}

#[test]
fn rate_ramp_is_found_by_the_slope_test() {
    check("rate_ramp");
}

#[test]
fn matched_paper_gyro_is_consistent() {
    check("null_paper");
}

#[test]
fn matched_rich_model_is_consistent() {
    check("null_rich");
}
