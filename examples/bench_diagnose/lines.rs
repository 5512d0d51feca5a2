//! The numbers of the line search's report (docs/diagnose.md): the coverage
//! of the period and amplitude intervals and the false alarms on matched
//! records, over many seeds, with the gyros and counts of the tests
//! (tests/diagnose/lines/shared.rs).

#[path = "../../tests/diagnose/lines/shared.rs"]
mod shared;

use shared::{coverage, gyro, null_alarms, paper_gyro};

/// Coverage and false alarms over `seeds` seeds per row.
pub fn table(seeds: u64) {
    for (name, m, amp, per, dur) in [
        ("issue gyro, 10 s line", gyro(1000.0, ""), 0.08, 10.0, 600.0),
        (
            "issue gyro, 40 s line",
            gyro(1000.0, ""),
            0.06,
            40.0,
            1200.0,
        ),
        (
            "issue gyro, 0.5 s line under QN",
            gyro(1000.0, ""),
            0.12,
            0.5,
            1200.0,
        ),
        (
            "paper gyro, 0.8 s line",
            paper_gyro(250.0, ""),
            0.05,
            0.8,
            1200.0,
        ),
    ] {
        let (cp, ca, det) = coverage(&m, amp, per, dur, seeds, 5000);
        println!(
            "coverage {name} (A {amp}, T {dur} s): detected {det}/{seeds}, period {cp}/{det}, amplitude {ca}/{det}"
        );
    }
    for (name, m, dur) in [
        ("issue gyro 1 kHz", gyro(1000.0, ""), 600.0),
        ("paper gyro 1 kHz", paper_gyro(1000.0, ""), 600.0),
        ("paper gyro 250 Hz", paper_gyro(250.0, ""), 1200.0),
    ] {
        let a = null_alarms(&m, dur, seeds, 7000, 0.05);
        println!("null {name}, {dur} s: records with a line at alpha 5 %: {a}/{seeds}");
    }
}
