//! The coverage of the `readout_filter` entry's corner interval and of the
//! refitted ARW's interval, over seeds and rate gyros (docs/diagnose.md), with
//! what the tests use (tests/diagnose/rate/shared.rs). `BENCH_DEBUG=1` prints
//! each seed's fit on stderr.

use sagnac::diagnose;
use sagnac::model::GyroModel;

use crate::support;

#[path = "../../tests/diagnose/rate/shared.rs"]
mod shared;

use shared::{named_filter, opts};

/// The markdown table over `seeds` seeds per case; `only`: the cases whose
/// label contains it.
pub fn table(seeds: u64, only: Option<&str>) {
    let ma5 = sagnac::model::filter::ReadoutFilter::moving_average(5)
        .unwrap()
        .corner_hz(1.0 / 200.0);
    // (label, model text without the filter, filter, truth corner Hz, truth ARW, duration s)
    let mems = |fs: f64, lsb: f64, n: f64, b: f64| {
        format!(
            "[gyro]\nsample_rate_hz = {fs}\noutput = \"rate\"\nrate_lsb_dps = {lsb}\ninput_rate_dph = 10.0\n\
             [noise]\narw_dpsh = {n}\nbias_instability_dph = {b}\n"
        )
    };
    let cases = [
        (
            "first order 15 Hz, 200 Hz, 20 min",
            mems(200.0, 0.01, 0.5, 5.0),
            "[readout_filter]\nkind = \"first_order\"\ncorner_hz = 15.0\n",
            15.0,
            0.5,
            1200.0,
        ),
        (
            "moving average of 5, 200 Hz, 20 min",
            mems(200.0, 0.01, 0.5, 5.0),
            "[readout_filter]\nkind = \"moving_average\"\nlength = 5\n",
            ma5,
            0.5,
            1200.0,
        ),
        (
            "first order 60 Hz, 500 Hz, 10 min",
            mems(500.0, 0.005, 0.2, 2.0),
            "[readout_filter]\nkind = \"first_order\"\ncorner_hz = 60.0\n",
            60.0,
            0.2,
            600.0,
        ),
    ];
    println!(
        "| case | seeds | filter named | right kind | corner in its 95 % interval | ARW in its 95 % interval | median corner interval width |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    let only = only.unwrap_or_default();
    for (label, base, filter, corner, arw, dur) in cases {
        if !label.contains(only) {
            continue;
        }
        let truth = GyroModel::from_toml_str(&format!("{base}{filter}"), "truth").unwrap();
        let model = GyroModel::from_toml_str(&base, "model").unwrap();
        let kind = truth.readout_filter().unwrap().kind();
        let (mut named, mut right_kind, mut corner_in, mut arw_in) = (0, 0, 0, 0);
        let mut widths = Vec::new();
        for s in 0..seeds {
            let rec = support::simulated_recording(&truth, 3000 + 17 * s, dur);
            let d = diagnose::diagnose(&model, &rec, &opts(5000 + 13 * s)).unwrap();
            let Some((k, _, ci, _)) = named_filter(&d) else {
                continue;
            };
            named += 1;
            right_kind += usize::from(k == kind.name());
            corner_in += usize::from(ci[0] <= corner && corner <= ci[1]);
            widths.push((ci[1] - ci[0]) / corner);
            if let Some(c) = d
                .report
                .parameter_changes
                .iter()
                .find(|c| c.term == "arw_dpsh")
            {
                arw_in += usize::from(c.ci95[0] <= arw && arw <= c.ci95[1]);
                if std::env::var_os("BENCH_DEBUG").is_some() {
                    eprintln!(
                        "{label} seed {s}: corner {:.3} {ci:?}, arw {:.5} {:?}, notes {:?}",
                        named_filter(&d).unwrap().1,
                        c.fitted,
                        c.ci95,
                        d.notes
                    );
                }
            }
        }
        widths.sort_by(f64::total_cmp);
        let pct = |k: usize| format!("{:.0} %", 100.0 * k as f64 / seeds as f64);
        println!(
            "| {label} | {seeds} | {} | {} | {} | {} | {} |",
            pct(named),
            pct(right_kind),
            pct(corner_in),
            pct(arw_in),
            widths
                .get(widths.len() / 2)
                .map_or("-".into(), |w| format!("{:.1} % of the corner", 100.0 * w))
        );
    }
}
