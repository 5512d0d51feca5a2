//! The power of the diagnosis, measured. For each catalog
//! effect, on its own gyro (200 Hz .. 2 kHz, pulse 0.5 .. 2", 20 min .. 2 h,
//! counts output, and a rate-output gyro for the readout filter), at three effect sizes from "the raw Allan deviation misses
//! it" to "plainly visible", over N seeds: how often the diagnosis names the
//! right change, and what the raw Allan deviation says beside it.
//!
//! Columns: `sigma_w` = how far the TRUE model moves the wavelet variances,
//! `sqrt(sum_j ((E ln w_j | truth) - (E ln w_j | model))^2 / sd_j^2)` (the
//! clean channel, combined over levels; the truth's mean from its own
//! Monte-Carlo runs); `raw z` = median over seeds of the recording's raw
//! Allan max |z| against the model's band, over its Bonferroni 5 % threshold
//! (`concealed` = the fraction of seeds below it); `raw sep` = the TRUE
//! model's raw Allan mean against the model's band, max over taus of
//! `|mean shift| / sd`, over the same threshold (below 1: on average the raw
//! Allan deviation cannot see the effect even with the band of the simulator
//! that made the recording); `detected` = verdict mismatch; `named` = the
//! right change reported (the new term, or the change of the model's
//! parameter). `scripts/bench-diagnose --power [--quick]` runs it
//! (`bench_diagnose power`).

use std::time::Instant;

use sagnac::diagnose::compare::{Family, Point, bonferroni_z};
use sagnac::diagnose::reference::points_against;
use sagnac::diagnose::{self, DiagnoseOptions, DiagnosisReport, Verdict};
use sagnac::model::GyroModel;

use crate::support;

struct Effect {
    name: &'static str,
    fs: f64,
    pulse: f64,
    dur_s: f64,
    /// Model noise lines (besides Q from the pulse and 0.5" dither, ARW).
    model: &'static str,
    arw: f64,
    /// Truth = model + this, at each size.
    truth: fn(f64) -> String,
    sizes: [f64; 3],
    unit: &'static str,
    named: fn(&DiagnosisReport) -> bool,
    /// A rate-output gyro (rate words of `RATE_LSB_DPS`; `pulse` unused).
    rate: bool,
}

/// The rate word LSB of the rate-output rows, deg/s.
const RATE_LSB_DPS: f64 = 0.01;

fn added(r: &DiagnosisReport, t: &str) -> bool {
    r.added_terms.iter().any(|a| a.term == t)
}

fn changed(r: &DiagnosisReport, t: &str) -> bool {
    r.parameter_changes.iter().any(|c| c.term == t)
}

fn effects() -> Vec<Effect> {
    vec![
        Effect {
            name: "Gauss-Markov, Tc 2 s",
            fs: 1000.0,
            pulse: 1.21,
            dur_s: 1200.0,
            model: "",
            arw: 0.002,
            truth: |s| format!("[[noise.gauss_markov]]\nsigma_dph = {s}\ntau_c_s = 2.0\n"),
            sizes: [0.02, 0.04, 0.08],
            unit: "sigma deg/h",
            named: |r| added(r, "gauss_markov"),
            rate: false,
        },
        Effect {
            name: "rate random walk (new)",
            fs: 200.0,
            pulse: 2.0,
            dur_s: 7200.0,
            model: "",
            arw: 0.002,
            truth: |s| format!("rrw_dphsh = {s}\n"),
            sizes: [0.005, 0.01, 0.02],
            unit: "K deg/h/sqrt(h)",
            named: |r| added(r, "rrw_dphsh"),
            rate: false,
        },
        Effect {
            name: "bias instability 0.005 -> B",
            fs: 500.0,
            pulse: 0.5,
            dur_s: 2400.0,
            model: "bias_instability_dph = 0.005\n",
            arw: 0.002,
            truth: |s| format!("bias_instability_dph = {s}\n"),
            sizes: [0.008, 0.012, 0.02],
            unit: "B deg/h",
            named: |r| changed(r, "bias_instability_dph"),
            rate: false,
        },
        Effect {
            name: "ARW 0.002 -> N",
            fs: 2000.0,
            pulse: 1.21,
            dur_s: 1200.0,
            model: "",
            arw: 0.002,
            truth: |s| format!("#arw {s}\n"),
            sizes: [0.0022, 0.0025, 0.003],
            unit: "N deg/sqrt(h)",
            named: |r| changed(r, "arw_dpsh") && r.added_terms.is_empty(),
            rate: false,
        },
        Effect {
            name: "random telegraph, dwell 10 s",
            fs: 200.0,
            pulse: 1.0,
            dur_s: 3600.0,
            model: "",
            arw: 0.002,
            truth: |s| {
                format!("[[noise.random_telegraph]]\namplitude_dph = {s}\nmean_dwell_s = 10.0\n")
            },
            sizes: [0.01, 0.02, 0.04],
            unit: "amplitude deg/h",
            named: |r| added(r, "random_telegraph"),
            rate: false,
        },
        Effect {
            name: "sinusoid, period 40 s",
            fs: 1000.0,
            pulse: 1.21,
            dur_s: 1200.0,
            model: "",
            arw: 0.002,
            truth: |s| format!("[[noise.sinusoid]]\namplitude_dph = {s}\nperiod_s = 40.0\n"),
            sizes: [0.015, 0.03, 0.06],
            unit: "amplitude deg/h",
            named: |r| added(r, "sinusoid"),
            rate: false,
        },
        Effect {
            name: "rate ramp",
            fs: 200.0,
            pulse: 1.5,
            dur_s: 3600.0,
            model: "",
            arw: 0.002,
            truth: |s| format!("rate_ramp_dphh = {s}\n"),
            sizes: [0.02, 0.04, 0.08],
            unit: "deg/h/h",
            named: |r| added(r, "rate_ramp_dphh"),
            rate: false,
        },
        // narrowband noise under the quantization noise of a pulse counter
        Effect {
            name: "resonance, 50 Hz, 3 Hz wide",
            fs: 1000.0,
            pulse: 1.21,
            dur_s: 1200.0,
            model: "",
            arw: 0.002,
            truth: |s| {
                format!("[[noise.resonance]]\nsigma_dph = {s}\ncentre_hz = 50.0\nwidth_hz = 3.0\n")
            },
            sizes: [10.0, 20.0, 40.0],
            unit: "sigma deg/h",
            named: |r| added(r, "resonance"),
            rate: false,
        },
        // a readout detail below the ARW/BI crossover of a MEMS-like rate gyro
        Effect {
            name: "readout filter, first order (rate output)",
            fs: 200.0,
            pulse: 0.0,
            dur_s: 1200.0,
            model: "bias_instability_dph = 5.0\n",
            arw: 0.5,
            truth: |s| format!("[readout_filter]\nkind = \"first_order\"\ncorner_hz = {s}\n"),
            sizes: [95.0, 70.0, 30.0],
            unit: "corner Hz",
            named: |r| added(r, "readout_filter"),
            rate: true,
        },
    ]
}

fn gyro(e: &Effect, arw: f64, extra: &str) -> GyroModel {
    let q = (e.pulse * e.pulse / 12.0 + 0.25f64).sqrt();
    // the effect may set a key the model already has (a parameter change)
    let key = |l: &str| l.split('=').next().unwrap_or("").trim().to_string();
    let base: String = e
        .model
        .lines()
        .filter(|l| !extra.lines().any(|x| key(x) == key(l)))
        .map(|l| format!("{l}\n"))
        .collect();
    let text = if e.rate {
        format!(
            "[gyro]\nsample_rate_hz = {}\noutput = \"rate\"\nrate_lsb_dps = {RATE_LSB_DPS}\n\
             input_rate_dph = 10.0\n[noise]\narw_dpsh = {arw}\n{base}{extra}",
            e.fs
        )
    } else {
        format!(
            "[gyro]\nsample_rate_hz = {}\npulse_arcsec = {}\ninput_rate_dph = 10.0\n\
             [noise]\nquantization_arcsec = {q}\narw_dpsh = {arw}\n{base}{extra}",
            e.fs, e.pulse
        )
    };
    GyroModel::from_toml_str(&text, e.name).unwrap()
}

fn fam<'a>(p: &'a [Point], f: Family) -> Vec<&'a Point> {
    p.iter().filter(|x| x.family == f).collect()
}

/// Combined shift of `truth`'s log means against `model`'s band (root sum of
/// squares) and the largest single shift, over one family.
fn shift(model: &[&Point], truth: &[&Point]) -> (f64, f64) {
    let mut ss = 0.0;
    let mut mx: f64 = 0.0;
    for m in model {
        if let Some(t) = truth.iter().find(|t| t.index == m.index) {
            let z = (t.mean_log - m.mean_log) / (m.sd_log * (1.0 + 1.0 / m.runs as f64).sqrt());
            ss += z * z;
            mx = mx.max(z.abs());
        }
    }
    (ss.sqrt(), mx)
}

/// What a report named, in short: added terms and changed parameters.
fn what(r: &DiagnosisReport) -> String {
    let v: Vec<String> = r
        .added_terms
        .iter()
        .map(|a| format!("+{}", a.term))
        .chain(r.parameter_changes.iter().map(|c| c.term.clone()))
        .collect();
    if v.is_empty() {
        if r.verdict == Verdict::Mismatch {
            "unexplained".into()
        } else {
            "consistent".into()
        }
    } else {
        v.join("+")
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The power table over `seeds` seeds per row; `only`: the effects whose name
/// contains it; `size_only`: that size of each effect alone (for a rerun of one
/// row; one of its three sizes or any other).
pub fn table(seeds: u64, only: Option<&str>, size_only: Option<f64>) {
    let t_all = Instant::now();
    println!(
        "| effect | gyro | size | sigma_w | raw z/crit (median) | concealed | raw sep/crit | detected | named | named as (seeds) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for e in effects() {
        if only.is_some_and(|o| !e.name.contains(o)) {
            continue;
        }
        let model = gyro(&e, e.arw, "");
        // --size runs that size alone, one of the three or another
        let sizes = size_only.map_or(e.sizes.to_vec(), |v| vec![v]);
        for &size in &sizes {
            let extra = (e.truth)(size);
            let arw = if extra.starts_with("#arw") {
                size
            } else {
                e.arw
            };
            let truth = gyro(&e, arw, &extra);
            let (mut det, mut named, mut conc) = (0, 0, 0);
            let (mut raw_z, mut sw, mut sep) = (Vec::new(), Vec::new(), Vec::new());
            let mut tally: std::collections::BTreeMap<String, usize> = Default::default();
            let t = Instant::now();
            for s in 0..seeds {
                let rec = support::simulated_recording(&truth, 50_000 + 97 * s, e.dur_s);
                let opts = DiagnoseOptions {
                    seed: 0x5A6_AC00 + 1_000 * s,
                    ..DiagnoseOptions::default()
                };
                let d = diagnose::diagnose(&model, &rec, &opts).unwrap();
                let raw = fam(&d.before, Family::RawAllan);
                let crit = bonferroni_z(0.05, raw.len());
                raw_z.push(d.raw_allan_max_z / crit);
                if d.raw_allan_max_z <= crit {
                    conc += 1;
                }
                if d.report.verdict == Verdict::Mismatch {
                    det += 1;
                }
                *tally.entry(what(&d.report)).or_default() += 1;
                if (e.named)(&d.report) {
                    named += 1;
                }
                // the truth's own band (the simulator that made the recording)
                let topts = DiagnoseOptions {
                    runs: 8,
                    seed: 0x7_0000 + 1_000 * s,
                    ..DiagnoseOptions::default()
                };
                let tp = points_against(&truth, &rec, &topts).unwrap();
                sw.push(shift(&fam(&d.before, Family::Wavelet), &fam(&tp, Family::Wavelet)).0);
                sep.push(shift(&raw, &fam(&tp, Family::RawAllan)).1 / crit);
            }
            let n = seeds as f64;
            let readout = if e.rate {
                format!("rate words of {RATE_LSB_DPS} deg/s")
            } else {
                format!("{}\"", e.pulse)
            };
            println!(
                "| {} | {} Hz, {readout}, {} min | {} {} | {:.1} | {:.2} | {:.0} % | {:.2} | {:.0} % | {:.0} % | {} |",
                e.name,
                e.fs,
                e.dur_s / 60.0,
                e.unit,
                size,
                median(sw),
                median(raw_z),
                100.0 * conc as f64 / n,
                median(sep),
                100.0 * det as f64 / n,
                100.0 * named as f64 / n,
                tally
                    .iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            eprintln!(
                "  ({} x {seeds} seeds: {:.0} s)",
                e.name,
                t.elapsed().as_secs_f64()
            );
        }
    }
    println!(
        "\n{seeds} seeds per row; {:.0} s in all",
        t_all.elapsed().as_secs_f64()
    );
}
