//! Is the rate ramp's interval honest on short records? Over many seeds, at
//! fixed record lengths, the spread of the ramp estimate about the truth
//! against the standard error the estimator reports, and what the standard
//! error would be under the simulated (true) spectrum, term by term.
//!
//! ```text
//! cargo run --release --example ramp_calibration -- [--runs N (200)] [--ramp DPHH (0.0455)] [--lengths 60,85,120,...]
//! ```
//!
//! The gyro is the acceptance bench's ramp case (`scripts/bench-acceptance --only
//! ramp`): Q 0.4 pulse, N 0.0005 deg/rt(h), B 0.002 deg/h, the ramp's sign
//! alternating, runs cycling over 100 Hz / 1.21 arcsec and 200 Hz / 0.6 arcsec.
//! Each run is one record; its prefixes of the listed lengths are analysed as
//! the daemon would (pipeline, estimator).
//!
//! Columns: `sd(s-R)` the spread of the slope about the truth; `rms se` the
//! reported standard error (the ramp coefficient's interval half-width / 1.96,
//! or from its upper bound `|s| + 1.96 se`); `sd z` the spread of
//! `(s - R) / se`; `|z|>1.96` the share outside the reported 95 % interval;
//! `true se` the slope's standard error under the simulated spectrum (white
//! angle Q^2, white rate N^2, flicker B^2), then each term's share of it; `fit
//! se` the same formula on the estimator's own fitted spectrum with the
//! quantization from the angle (theta[0]) in place of the low-frequency fit's
//! white-angle nuisance; `fails (rule)` the records failed at this length's
//! look `k` (`T_k = 60 s 2^(k/2)`, quantile `z_k`) by the spec's rule
//! ([`sagnac::model::spec::magnitude_fail_z`]), `fails (one-sided z_k)` with
//! the plain one-sided quantile on the magnitude; the last line counts the
//! runs failed at some listed length (a wrong verdict: the truth is inside).
//! `DIAG_DEBUG=1` prints each record whose reported standard error is 0.

use sagnac::model::GyroModel;
use sagnac::model::estimate::{slope_var_per_theta, standard_terms};
use sagnac::model::sim::Simulator;
use sagnac::model::wvar::SpectralTerm;
use sagnac::pipeline::{Pipeline, PipelineConfig, PipelineOutput};
use sagnac::units;

const CONFIGS: [(f64, f64); 2] = [(100.0, 1.21), (200.0, 0.6)];
const N_DPSH: f64 = 0.0005;
const B_DPH: f64 = 0.002;
const LIMIT: f64 = 0.05;

#[derive(Default, Clone)]
struct Row {
    dev: Vec<f64>,
    se: Vec<f64>,
    se_narrow: Vec<f64>,
    true_se: Vec<[f64; 3]>,
    fit_se: Vec<f64>,
    reported: usize,
    /// Fails at this length's look quantile (the live rule, were it the first look).
    fails: usize,
    /// The same with the one-sided quantile `z_k` on the magnitude.
    fails_one_sided: usize,
    cfg0_dev: Vec<f64>,
    cfg0_se: Vec<f64>,
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut runs = 200usize;
    let mut ramp = 0.05 / 1.1;
    let mut lengths: Vec<f64> = vec![60.0, 85.0, 120.0, 170.0, 240.0, 480.0, 960.0];
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--runs" => runs = val()?.parse().map_err(|e| format!("--runs: {e}"))?,
            "--ramp" => ramp = val()?.parse().map_err(|e| format!("--ramp: {e}"))?,
            "--lengths" => {
                lengths = val()?
                    .split(',')
                    .map(|s| s.parse::<f64>().map_err(|e| format!("--lengths: {e}")))
                    .collect::<Result<_, _>>()?
            }
            other => return Err(format!("unknown argument {other}")),
        }
    }
    let t_max = lengths.iter().copied().fold(0.0, f64::max);
    let mut rows = vec![Row::default(); lengths.len()];
    let z = 1.959_964;
    let mut first_fails = 0usize;
    for i in 0..runs {
        let mut failed = false;
        let (rate, pulse) = CONFIGS[i % CONFIGS.len()];
        let r = if i % 2 == 0 { ramp } else { -ramp };
        let q = 0.4 * pulse;
        let toml = format!(
            "[gyro]\nsample_rate_hz = {rate}\npulse_arcsec = {pulse}\ninput_rate_dph = 12.3\n\
             [noise]\nquantization_arcsec = {q}\narw_dpsh = {N_DPSH}\nbias_instability_dph = {B_DPH}\n\
             rrw_dphsh = 0.0\nrate_ramp_dphh = {r}\n"
        );
        let model = GyroModel::from_toml_str(&toml, "diag").map_err(|e| e.to_string())?;
        let seed = 7_000_001 + i as u64;
        let mut sim = Simulator::new(&model, seed, Some(t_max)).map_err(|e| e.to_string())?;
        let mut pipe =
            Pipeline::new(&PipelineConfig::counts(rate, pulse)).map_err(|e| e.to_string())?;
        let mut out = PipelineOutput::default();
        let mut counts = Vec::new();
        let tau0 = 1.0 / rate;
        for (li, &len) in lengths.iter().enumerate() {
            let want = (len * rate).round() as u64;
            let have = pipe.samples();
            if want > have {
                counts.clear();
                sim.next_block((want - have) as usize, &mut counts);
                pipe.push_counts(&counts, &mut out);
                out.clear();
            }
            let est = pipe.estimator_output();
            let Some((s, sd_narrow)) = est.ramp_arcsec_s2 else {
                continue;
            };
            let c = est.estimates.rate_ramp_dphh;
            let s_dphh = units::arcsec_per_s2_to_dphh(s);
            let se = match (c.value, c.ci95, c.upper95) {
                (Some(_), Some([lo, hi]), _) => (hi - lo) / (2.0 * z),
                (_, _, Some(u)) => (u - s_dphh.abs()) / z,
                _ => continue,
            };
            if (se.is_nan() || se <= 0.0) && std::env::var_os("DIAG_DEBUG").is_some() {
                eprintln!(
                    "T {len} seed {seed}: s {s_dphh} sd {sd_narrow} coef {c:?}\n  theta {:?}\n  fit {:?}\n  quality {:?} est {:?}",
                    est.theta, est.fit.terms, est.quality, est.estimates
                );
            }
            let n = pipe.samples();
            let terms = standard_terms(n, tau0);
            let fl = match model.flicker_f_lo_hz() {
                f if f > 0.0 => f,
                _ => 0.0,
            };
            let truth_terms = [
                (SpectralTerm::WhiteAngle, q * q),
                (
                    SpectralTerm::WhiteRate,
                    units::dpsh_to_arcsec_per_sqrt_s(N_DPSH).powi(2),
                ),
                (
                    SpectralTerm::Flicker { f_lo_hz: fl },
                    units::dph_to_arcsec_per_s(B_DPH).powi(2),
                ),
            ];
            let tv: Vec<f64> = truth_terms
                .iter()
                .map(|(t, th)| th * slope_var_per_theta(t, n, tau0))
                .collect();
            let fit_var: f64 = terms
                .iter()
                .zip(est.theta)
                .map(|(t, th)| th.max(0.0) * slope_var_per_theta(t, n, tau0))
                .sum();
            let row = &mut rows[li];
            row.dev.push(s_dphh - r);
            row.se.push(se);
            row.se_narrow.push(units::arcsec_per_s2_to_dphh(sd_narrow));
            row.true_se.push([
                units::arcsec_per_s2_to_dphh(tv[0].sqrt()),
                units::arcsec_per_s2_to_dphh(tv[1].sqrt()),
                units::arcsec_per_s2_to_dphh(tv[2].sqrt()),
            ]);
            row.fit_se
                .push(units::arcsec_per_s2_to_dphh(fit_var.sqrt()));
            row.reported += usize::from(c.value.is_some());
            // look k of the live schedule: T_k = 60 s 2^(k/2)
            let k = (2.0 * (len / 60.0).log2()).round().max(0.0) as u32;
            let zk = sagnac::model::spec::LookSchedule {
                first_look_s: 60.0,
                alpha: 0.05,
            }
            .z(k);
            if let (Some(v), Some(_)) = (c.value, c.ci95) {
                if v.abs() - zk * se > LIMIT {
                    row.fails_one_sided += 1;
                }
                if v.abs() - sagnac::model::spec::magnitude_fail_z(zk, se, LIMIT) * se > LIMIT {
                    row.fails += 1;
                    if !failed {
                        failed = true;
                        first_fails += 1;
                    }
                }
            }
            if i % CONFIGS.len() == 0 {
                row.cfg0_dev.push(s_dphh - r);
                row.cfg0_se.push(se);
            }
        }
    }
    println!(
        "ramp calibration: {runs} runs, truth +-{ramp:.4} deg/h/h, Q 0.4 pulse, N {N_DPSH}, B {B_DPH}; \
         configs 100 Hz/1.21, 200 Hz/0.6 (deg/h/h)"
    );
    println!();
    println!(
        "| T s | runs | reported | sd(s-R) | rms se (interval) | sd z | abs z > 1.96 | rms se narrow | true se | Q part | N part | B part | fit se (Q from angle) | fails (rule) | fails (one-sided z_k) | sd z (100 Hz) |"
    );
    println!("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    for (li, len) in lengths.iter().enumerate() {
        let row = &rows[li];
        let n = row.dev.len();
        if n == 0 {
            continue;
        }
        let zs: Vec<f64> = row.dev.iter().zip(&row.se).map(|(d, s)| d / s).collect();
        let out = zs.iter().filter(|z| z.abs() > 1.959_964).count();
        let parts: Vec<f64> = (0..3)
            .map(|k| rms(&row.true_se.iter().map(|t| t[k]).collect::<Vec<_>>()))
            .collect();
        let tot = rms(&row
            .true_se
            .iter()
            .map(|t| (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt())
            .collect::<Vec<_>>());
        println!(
            "| {len:.0} | {n} | {} | {:.4} | {:.4} | {:.2} | {:.1} % | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {} | {} | {:.2} |",
            row.reported,
            rms(&row.dev),
            rms(&row.se),
            rms(&zs),
            100.0 * out as f64 / n as f64,
            rms(&row.se_narrow),
            tot,
            parts[0],
            parts[1],
            parts[2],
            rms(&row.fit_se),
            row.fails,
            row.fails_one_sided,
            rms(&row
                .cfg0_dev
                .iter()
                .zip(&row.cfg0_se)
                .map(|(d, s)| d / s)
                .collect::<Vec<_>>()),
        );
    }
    println!();
    println!(
        "runs failed (|R| limit {LIMIT}) at some listed length, looks z_k of 60 s x 2^(k/2): {first_fails} of {runs} ({:.1} %)",
        100.0 * first_fails as f64 / runs as f64
    );
    Ok(())
}
