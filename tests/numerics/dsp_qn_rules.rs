//! The measurement behind the QN splitter's default rule: every combination of QN
//! estimate (ARW floor, white model) and split rule (power subtraction, Wiener,
//! soft and hard threshold at 3 sigma_QN) on 1-hour simulated static runs of the
//! paper's gyro. Printed as a table (`cargo test --release --test numerics dsp_qn_rules
//! -- --nocapture`); asserted: the default has the smallest worst-case error of the
//! clean Allan deviation against the ADEV of each run's own non-QN part (ARW + BI +
//! input) over tau = 1, 2, 8, 32 s and all runs; that error is below 10 % (it is
//! largest at 1 s, measured 8 %) and below 6 % at tau >= 2 s (measured 5 %).

use sagnac::dsp::{QnConfig, QnEstimate, QnRule, QnSplitter};

use crate::support::dsp::{GyroSim, oadev};

const TAU0: f64 = 1e-3;
const TAUS: [f64; 4] = [1.0, 2.0, 8.0, 32.0];

fn case(q: f64, n: f64, b: f64, rate: f64, seed: u64) -> GyroSim {
    let mut g = GyroSim::paper(q, n, b, seed);
    g.rate_dph = rate;
    g
}

#[test]
fn default_rule_is_the_best_measured() {
    let cases = [
        (
            "Q.35 N.001 B.002 12.3dph (weak dither)",
            case(0.35, 0.001, 0.002, 12.3, 81),
        ),
        (
            "Q.35 N.001 B.002 3dph (lines 2.5 Hz)",
            case(0.35, 0.001, 0.002, 3.0, 82),
        ),
        (
            "Q.50 N.0012 B.003 12.3dph",
            case(0.5, 0.0012, 0.003, 12.3, 83),
        ),
        (
            "Q.60 N.002 B.003 12.3dph",
            case(0.6, 0.002, 0.003, 12.3, 84),
        ),
    ];
    let methods: Vec<(QnEstimate, QnRule)> = [QnEstimate::ArwFloor, QnEstimate::WhiteModel]
        .into_iter()
        .flat_map(|e| {
            [
                QnRule::PowerSubtraction,
                QnRule::Wiener,
                QnRule::SoftThreshold,
                QnRule::HardThreshold,
            ]
            .into_iter()
            .map(move |r| (e, r))
        })
        .collect();
    // worst[m] = max over cases and taus of |clean/truth - 1|; worst2: taus >= 2 s
    let mut worst = vec![0.0f64; methods.len()];
    let mut worst2 = vec![0.0f64; methods.len()];
    println!(
        "clean ADEV / ADEV of the run's non-QN part at tau = {TAUS:?} s; noise-integral sd / Q"
    );
    println!("| run | estimate / rule | tau 1 | tau 2 | tau 8 | tau 32 | int sd/Q |");
    println!("|---|---|---|---|---|---|---|");
    for (name, g) in &cases {
        let n = 3_600_000;
        let run = g.simulate(n);
        let truth: Vec<f64> = TAUS
            .iter()
            .map(|&t| oadev(&run.truth, TAU0, (t / TAU0) as usize))
            .collect();
        let raw: Vec<f64> = TAUS
            .iter()
            .map(|&t| oadev(&run.raw, TAU0, (t / TAU0) as usize))
            .collect();
        println!(
            "| {name} | raw | {} | |",
            raw.iter()
                .zip(&truth)
                .map(|(r, t)| format!("{:.3}", r / t))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        for (mi, &(est, rule)) in methods.iter().enumerate() {
            let cfg = QnConfig {
                qn_estimate: est,
                rule,
                ..QnConfig::new(1000.0)
            };
            let mut sp = QnSplitter::new(&cfg).unwrap();
            let (mut clean, mut noise) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for c in run.raw.chunks(8192) {
                sp.push(c, &mut clean, &mut noise);
            }
            sp.flush(&mut clean, &mut noise);
            let ratios: Vec<f64> = TAUS
                .iter()
                .zip(&truth)
                .map(|(&t, tr)| oadev(&clean, TAU0, (t / TAU0) as usize) / tr)
                .collect();
            for (r, &t) in ratios.iter().zip(&TAUS) {
                worst[mi] = worst[mi].max((r - 1.0).abs());
                if t >= 2.0 {
                    worst2[mi] = worst2[mi].max((r - 1.0).abs());
                }
            }
            let mut acc = 0.0;
            let (mut s1, mut s2) = (0.0, 0.0);
            for z in &noise {
                acc += z * TAU0;
                s1 += acc;
                s2 += acc * acc;
            }
            let m = s1 / n as f64;
            let sd = (s2 / n as f64 - m * m).sqrt();
            println!(
                "| | {:?} / {:?} | {} | {:.3} |",
                est,
                rule,
                ratios
                    .iter()
                    .map(|r| format!("{r:.3}"))
                    .collect::<Vec<_>>()
                    .join(" | "),
                sd / g.quantization_arcsec
            );
        }
    }
    println!("worst-case |clean/truth - 1| over runs and taus:");
    for ((m, w), w2) in methods.iter().zip(&worst).zip(&worst2) {
        println!("  {:?} / {:?}: {:.3} (tau >= 2 s: {:.3})", m.0, m.1, w, w2);
    }
    let def = QnConfig::default();
    let di = methods
        .iter()
        .position(|&m| m == (def.qn_estimate, def.rule))
        .unwrap();
    for (mi, w) in worst.iter().enumerate() {
        if mi != di {
            assert!(
                worst[di] < *w,
                "default {:?} ({:.3}) not better than {:?} ({:.3})",
                methods[di],
                worst[di],
                methods[mi],
                w
            );
        }
    }
    // Default: 10 % worst case with tau = 1 s (measured 8 %), 6 % from 2 s (measured 5 %).
    assert!(
        worst[di] < 0.10,
        "default worst-case error {:.3}",
        worst[di]
    );
    assert!(
        worst2[di] < 0.06,
        "default worst-case error from 2 s {:.3}",
        worst2[di]
    );
}
