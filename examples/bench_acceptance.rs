//! How often the live acceptance rule
//! ([`sagnac::model::spec::SequentialSpec`]) gives a wrong verdict, and how
//! soon it decides, on simulated gyros with known truth.
//!
//! ```text
//! cargo run --release --example bench_acceptance -- [--quick] [--runs N] [--jobs J] [--only qn|arw|bi|rrw|ramp] [--fixed-runs M] [--factor 0..4]
//! ```
//!
//! Each case puts one coefficient at `factor x limit` (0.5 well inside, 1/1.1
//! just inside, 1 at the limit, 1.1 just outside, 2 well outside) and cycles
//! the runs over several sample rates and pulse weights. A run streams the
//! simulator's output into the [`Pipeline`] in 5 s chunks (the daemon's default
//! estimator interval); at each update that is a look of the schedule the
//! estimates are computed and the verdict evaluated, exactly as the daemon does
//! (every other update leaves the verdict unchanged, so it is not computed). A
//! run stops when its coefficient is decided or at the case's fixed length.
//!
//! Also reported, from the same estimates: the naive rule (the fixed-sample
//! one-sided 95 % bound checked at every look, stopping at the first decisive
//! one), and, on the first `--fixed-runs` runs of each case (continued to the
//! full length), the fixed-length run (one look at the end).
//!
//! `BENCH_DEBUG=1` prints each look's estimate and interval on stderr (how the
//! estimator's calibration was measured, docs/acceptance.md).
//!
//! Wrong: `pass` when the truth is above the limit, `fail` when below; at the
//! limit both are counted (each is at most alpha by construction).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use sagnac::model::GyroModel;
use sagnac::model::sim::Simulator;
use sagnac::model::spec::{SequentialSpec, Spec, SpecCoefficient, Verdict};
use sagnac::pipeline::{Pipeline, PipelineConfig, PipelineOutput};

const CONFIDENCE: f64 = 0.95;
const UPDATE_S: f64 = 5.0;
const FACTORS: [(f64, &str); 5] = [
    (0.5, "well inside"),
    (1.0 / 1.1, "just inside"),
    (1.0, "at limit"),
    (1.1, "just outside"),
    (2.0, "well outside"),
];

#[derive(Clone, Copy)]
struct Family {
    name: &'static str,
    coef: SpecCoefficient,
    limit: f64,
    duration_s: f64,
    /// (rate Hz, pulse weight arcsec) cycled over the runs.
    configs: &'static [(f64, f64)],
}

const FAMILIES: [Family; 5] = [
    Family {
        name: "qn",
        coef: SpecCoefficient::Quantization,
        limit: 0.5,
        duration_s: 1200.0,
        configs: &[(1000.0, 0.6), (500.0, 0.4), (250.0, 0.8)],
    },
    Family {
        name: "arw",
        coef: SpecCoefficient::Arw,
        limit: 0.0035,
        duration_s: 1200.0,
        configs: &[(500.0, 1.21), (400.0, 0.6), (200.0, 2.0)],
    },
    Family {
        name: "bi",
        coef: SpecCoefficient::BiasInstability,
        limit: 0.005,
        duration_s: 7200.0,
        configs: &[(100.0, 1.21), (200.0, 0.6)],
    },
    Family {
        name: "rrw",
        coef: SpecCoefficient::Rrw,
        limit: 0.02,
        duration_s: 7200.0,
        configs: &[(100.0, 1.21), (200.0, 0.6)],
    },
    Family {
        name: "ramp",
        coef: SpecCoefficient::RateRamp,
        limit: 0.05,
        duration_s: 7200.0,
        configs: &[(100.0, 1.21), (200.0, 0.6)],
    },
];

/// The model of run `i` of a case: the tested coefficient at `truth`, the others typical.
fn model_toml(f: &Family, truth: f64, i: usize) -> (String, f64, f64) {
    let (rate, pulse) = f.configs[i % f.configs.len()];
    let (q, n, b, k, r) = match f.coef {
        SpecCoefficient::Quantization => (truth, 0.001, 0.002, 0.0, 0.0),
        SpecCoefficient::Arw => (0.4 * pulse, truth, 0.002, 0.0, 0.0),
        SpecCoefficient::BiasInstability => (0.4 * pulse, 0.0005, truth, 0.0, 0.0),
        SpecCoefficient::Rrw => (0.4 * pulse, 0.0005, 0.002, truth, 0.0),
        // the sign of a ramp alternates over the runs: the limit is on its magnitude
        SpecCoefficient::RateRamp => (
            0.4 * pulse,
            0.0005,
            0.002,
            0.0,
            if i % 2 == 0 { truth } else { -truth },
        ),
    };
    let toml = format!(
        "[gyro]\nsample_rate_hz = {rate}\npulse_arcsec = {pulse}\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = {q}\narw_dpsh = {n}\nbias_instability_dph = {b}\n\
         rrw_dphsh = {k}\nrate_ramp_dphh = {r}\n"
    );
    (toml, rate, pulse)
}

#[derive(Debug, Clone, Copy, Default)]
struct Outcome {
    /// Sequential verdict and record length at the decision.
    seq: Option<(Verdict, f64)>,
    /// Naive peeking: first decisive look.
    naive: Option<(Verdict, f64)>,
    /// The fixed-length run's verdict, when the run went to the end.
    fixed: Option<Verdict>,
    /// Samples simulated.
    samples: u64,
}

/// The naive rule at one look: the fixed-sample one-sided bound at the spec's
/// confidence (what `sagnac analyze` does once), here applied at every look.
fn naive_verdict(
    spec: &Spec,
    c: SpecCoefficient,
    e: &sagnac::model::estimate::NoiseEstimates,
) -> Verdict {
    spec.evaluate_fixed(e, 0.0)
        .coefficients
        .get(c.name())
        .map_or(Verdict::Undecided, |v| v.verdict)
}

fn run_one(f: &Family, truth: f64, i: usize, seed: u64, to_end: bool) -> Result<Outcome, String> {
    let (toml, rate, pulse) = model_toml(f, truth, i);
    let model = GyroModel::from_toml_str(&toml, "bench").map_err(|e| e.to_string())?;
    let mut sim = Simulator::new(&model, seed, Some(f.duration_s)).map_err(|e| e.to_string())?;
    let mut pipe =
        Pipeline::new(&PipelineConfig::counts(rate, pulse)).map_err(|e| e.to_string())?;
    let mut spec = Spec {
        quantization_arcsec_max: None,
        arw_dpsh_max: None,
        bias_instability_dph_max: None,
        rrw_dphsh_max: None,
        rate_ramp_dphh_max: None,
        confidence: CONFIDENCE,
        first_look_s: None,
        systematic_rel: None,
    };
    match f.coef {
        SpecCoefficient::Quantization => spec.quantization_arcsec_max = Some(f.limit),
        SpecCoefficient::Arw => spec.arw_dpsh_max = Some(f.limit),
        SpecCoefficient::BiasInstability => spec.bias_instability_dph_max = Some(f.limit),
        SpecCoefficient::Rrw => spec.rrw_dphsh_max = Some(f.limit),
        SpecCoefficient::RateRamp => spec.rate_ramp_dphh_max = Some(f.limit),
    }
    let mut seq = SequentialSpec::new(spec.clone());
    let chunk = (UPDATE_S * rate).round() as usize;
    let mut counts = Vec::with_capacity(chunk);
    let mut out = PipelineOutput::default();
    let mut o = Outcome::default();
    let mut last_look = None;
    loop {
        counts.clear();
        let n = sim.next_block(chunk, &mut counts);
        if n == 0 {
            break;
        }
        pipe.push_counts(&counts, &mut out);
        out.clear();
        o.samples += n as u64;
        let dur = pipe.samples() as f64 / rate;
        let end = sim.remaining() == Some(0);
        let look = seq.schedule().look_at(dur);
        let is_look = look.is_some() && look != last_look;
        if !is_look && !end {
            continue;
        }
        let a = pipe.analysis();
        if is_look {
            last_look = look;
            if std::env::var_os("BENCH_DEBUG").is_some() {
                let c = f.coef.of(&a.estimates);
                eprintln!(
                    "cfg {} truth {truth} t {:.0} value {:?} ci {:?} up {:?}",
                    i % f.configs.len(),
                    a.duration_s,
                    c.value,
                    c.ci95,
                    c.upper95
                );
            }
            seq.observe(&a.estimates, a.duration_s);
            if o.seq.is_none() {
                let v = &seq.report().coefficients[f.coef.name()];
                if v.verdict != Verdict::Undecided {
                    o.seq = Some((v.verdict, a.duration_s));
                }
            }
            if o.naive.is_none() {
                let v = naive_verdict(&spec, f.coef, &a.estimates);
                if v != Verdict::Undecided {
                    o.naive = Some((v, a.duration_s));
                }
            }
        }
        if end {
            o.fixed = Some(
                spec.evaluate_fixed(&a.estimates, a.duration_s).coefficients[f.coef.name()].verdict,
            );
            break;
        }
        if o.seq.is_some() && !to_end {
            break;
        }
    }
    Ok(o)
}

fn wrong(v: Verdict, factor: f64) -> bool {
    match v {
        Verdict::Pass => factor >= 1.0,
        Verdict::Fail => factor <= 1.0,
        Verdict::Undecided => false,
    }
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut runs = 200usize;
    let mut jobs = 2usize;
    let mut only: Option<String> = None;
    let mut fixed_runs = 20usize;
    let mut quick = false;
    let mut factor_only: Option<usize> = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--quick" => quick = true,
            "--runs" => runs = val()?.parse().map_err(|e| format!("--runs: {e}"))?,
            "--jobs" => jobs = val()?.parse().map_err(|e| format!("--jobs: {e}"))?,
            "--fixed-runs" => {
                fixed_runs = val()?.parse().map_err(|e| format!("--fixed-runs: {e}"))?
            }
            "--only" => only = Some(val()?.clone()),
            "--factor" => factor_only = Some(val()?.parse().map_err(|e| format!("--factor: {e}"))?),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if quick {
        runs = runs.min(20);
        fixed_runs = fixed_runs.min(5);
    }
    let jobs = jobs.max(1);
    let families: Vec<Family> = FAMILIES
        .iter()
        .copied()
        .filter(|f| only.as_deref().is_none_or(|o| o == f.name))
        .collect();
    if families.is_empty() {
        return Err("--only: qn, arw, bi, rrw or ramp".into());
    }
    // every (family, factor, run) as one job
    let mut work = Vec::new();
    for fi in 0..families.len() {
        for (ci, _) in FACTORS.iter().enumerate() {
            if factor_only.is_some_and(|f| f != ci) {
                continue;
            }
            for i in 0..runs {
                work.push((fi, ci, i));
            }
        }
    }
    // long jobs first (at-limit cases run to the end)
    work.sort_by_key(|&(fi, ci, _)| {
        (
            std::cmp::Reverse((families[fi].duration_s as u64) * if ci == 2 { 2 } else { 1 }),
            fi,
            ci,
        )
    });
    let work = Arc::new(work);
    let next = Arc::new(AtomicUsize::new(0));
    let results: Arc<Mutex<Vec<Vec<Vec<Outcome>>>>> =
        Arc::new(Mutex::new(vec![
            vec![Vec::new(); FACTORS.len()];
            families.len()
        ]));
    let started = Instant::now();
    let errors = Arc::new(Mutex::new(Vec::<String>::new()));
    std::thread::scope(|s| {
        for _ in 0..jobs {
            let (work, next, results, errors, families) =
                (&work, &next, &results, &errors, &families);
            s.spawn(move || {
                loop {
                    let j = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(fi, ci, i)) = work.get(j) else {
                        break;
                    };
                    let f = &families[fi];
                    let truth = f.limit * FACTORS[ci].0;
                    let seed = 1_000_003 * (fi as u64 + 1) + 10_007 * ci as u64 + i as u64;
                    match run_one(f, truth, i, seed, i < fixed_runs) {
                        Ok(o) => results.lock().unwrap_or_else(|p| p.into_inner())[fi][ci].push(o),
                        Err(e) => errors.lock().unwrap_or_else(|p| p.into_inner()).push(e),
                    }
                }
            });
        }
    });
    let errors = errors.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(e) = errors.first() {
        return Err(format!("{} runs failed, first: {e}", errors.len()));
    }
    let results = results.lock().unwrap_or_else(|p| p.into_inner());
    println!(
        "sagnac acceptance bench: confidence {CONFIDENCE}, {runs} runs per case, updates every {UPDATE_S} s of data, \
         looks at 60 s x 2^(k/2); {} s wall, {jobs} jobs",
        started.elapsed().as_secs()
    );
    println!();
    println!(
        "| coefficient (limit) | rates Hz / pulse arcsec | truth | runs | pass | fail | undecided | wrong | median decision s (decided) | fixed length s | naive peeking wrong | fixed-length run: wrong / decided (runs) |"
    );
    println!("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (fi, f) in families.iter().enumerate() {
        let cfgs: Vec<String> = f.configs.iter().map(|(r, p)| format!("{r}/{p}")).collect();
        for (ci, (factor, label)) in FACTORS.iter().enumerate() {
            let os = &results[fi][ci];
            if os.is_empty() {
                continue;
            }
            let n = os.len().max(1) as f64;
            let pct = |k: usize| format!("{:.1} %", 100.0 * k as f64 / n);
            let count = |v: Verdict| os.iter().filter(|o| o.seq.map(|s| s.0) == Some(v)).count();
            let (p, fl) = (count(Verdict::Pass), count(Verdict::Fail));
            let und = os.len() - p - fl;
            let wr = os
                .iter()
                .filter(|o| o.seq.is_some_and(|s| wrong(s.0, *factor)))
                .count();
            let naive_wr = os
                .iter()
                .filter(|o| o.naive.is_some_and(|s| wrong(s.0, *factor)))
                .count();
            let times: Vec<f64> = os.iter().filter_map(|o| o.seq.map(|s| s.1)).collect();
            let med = median(times).map_or("-".to_string(), |m| format!("{m:.0}"));
            let fixed: Vec<Verdict> = os.iter().filter_map(|o| o.fixed).collect();
            let fixed_wrong = fixed.iter().filter(|v| wrong(**v, *factor)).count();
            let fixed_dec = fixed.iter().filter(|v| **v != Verdict::Undecided).count();
            println!(
                "| {} ({}) | {} | {label} ({:.4}) | {} | {} | {} | {} | **{}** | {med} ({}) | {} | {} | {} / {} ({}) |",
                f.coef.name(),
                f.limit,
                cfgs.join(", "),
                f.limit * factor,
                os.len(),
                pct(p),
                pct(fl),
                pct(und),
                pct(wr),
                p + fl,
                f.duration_s,
                pct(naive_wr),
                if fixed.is_empty() {
                    "-".into()
                } else {
                    format!("{:.0} %", 100.0 * fixed_wrong as f64 / fixed.len() as f64)
                },
                if fixed.is_empty() {
                    "-".into()
                } else {
                    format!("{:.0} %", 100.0 * fixed_dec as f64 / fixed.len() as f64)
                },
                fixed.len(),
            );
        }
    }
    let sim_h: f64 = results
        .iter()
        .zip(&families)
        .map(|(r, f)| {
            r.iter().flatten().map(|o| o.samples as f64).sum::<f64>()
                / f.configs.iter().map(|c| c.0).sum::<f64>()
                * f.configs.len() as f64
                / 3600.0
        })
        .sum();
    eprintln!(
        "about {sim_h:.0} h of gyro data simulated in {} s",
        started.elapsed().as_secs()
    );
    Ok(())
}
