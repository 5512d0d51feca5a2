//! The diagnosis measured over many seeds, on simulated gyros with known
//! truth: the tables of docs/diagnose.md.
//!
//! ```text
//! cargo run --release --example bench_diagnose -- concealed [--seeds N]
//! cargo run --release --example bench_diagnose -- power [--seeds N] [--only TEXT] [--size X]
//! cargo run --release --example bench_diagnose -- lines [--seeds N]
//! cargo run --release --example bench_diagnose -- rate [--seeds N] [--only TEXT]
//! cargo run --release --example bench_diagnose -- candidates [--seeds 1,2,3]
//! ```
//!
//! * `concealed` (`scripts/bench-diagnose`): each concealed-effect case of
//!   the tests at its own seed and N-1 more (default 3 in all).
//! * `power` (`scripts/bench-diagnose --power`): for each catalog effect, at
//!   three sizes, how often the diagnosis names it over N seeds (default 10);
//!   `--only` keeps the effects whose name contains TEXT, `--size` runs that
//!   size of each alone.
//! * `lines`: the coverage of the line search's intervals and its false
//!   alarms on matched records (default 40 seeds).
//! * `rate`: the coverage of the readout filter's corner and of the ARW
//!   (default 20 seeds); `--only` keeps the cases whose label contains TEXT.
//! * `candidates`: the model comparison's candidates on the concealed
//!   Gauss-Markov case, seed by seed (default seed 1), on stderr.
//!
//! Tables go to standard output, progress to standard error. The cases,
//! gyros and judgements are the tests' own: the files of tests/diagnose that
//! this example includes by their paths.

/// The recordings the tests simulate (the shared case files call
/// `crate::support::simulated_recording`, as in the test suites).
#[path = "../../tests/support/sim.rs"]
mod support;

mod candidates;
mod concealed;
mod lines;
mod power;
mod rate;

const USAGE: &str = "usage: bench_diagnose concealed|power|lines|rate|candidates [--seeds N] [--only TEXT] [--size X]";

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (bench, rest) = args.split_first().ok_or(USAGE)?;
    let mut seeds: Option<String> = None;
    let mut only: Option<String> = None;
    let mut size: Option<f64> = None;
    let mut it = rest.iter();
    while let Some(a) = it.next() {
        let mut val = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--seeds" => seeds = Some(val()?.clone()),
            "--only" => only = Some(val()?.clone()),
            "--size" => size = Some(val()?.parse().map_err(|e| format!("--size: {e}"))?),
            other => return Err(format!("unknown argument {other}\n{USAGE}")),
        }
    }
    let count = |default: u64| -> Result<u64, String> {
        seeds.as_deref().map_or(Ok(default), |s| {
            s.parse().map_err(|e| format!("--seeds: {e}"))
        })
    };
    let only = only.as_deref().filter(|o| !o.is_empty());
    match bench.as_str() {
        "concealed" => concealed::table(count(3)?),
        "power" => power::table(count(10)?, only, size),
        "lines" => lines::table(count(40)?),
        "rate" => rate::table(count(20)?, only),
        "candidates" => {
            let list = seeds
                .as_deref()
                .unwrap_or("1")
                .split(',')
                .map(|x| x.trim().parse().map_err(|e| format!("--seeds: {e}")))
                .collect::<Result<Vec<u64>, _>>()?;
            candidates::dump(&list);
        }
        other => return Err(format!("unknown bench {other}\n{USAGE}")),
    }
    Ok(())
}
