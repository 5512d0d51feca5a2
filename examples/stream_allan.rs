//! Raw throughput of the streaming octave OADEV engine on an f64 little-endian file,
//! read in 1 MB blocks (what `sagnac allan --engine streaming` will do once wired):
//!
//! ```text
//! cargo run --release --example stream_allan -- FILE [--data freq|phase] [--tau0 S] [--json OUT]
//! ```
//!
//! Prints the octave table on stdout (JSON to OUT with `--json`) and, on stderr, the
//! elapsed time and samples/s, both overall and for the engine alone (`push_block` and
//! the final report, without file reading). Used by `scripts/bench-allan` until the CLI
//! is wired.

use std::fs::File;
use std::io::{Read, Write};
use std::time::Instant;

use sagnac::allan::streaming::{OctaveAllan, StreamConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut path = None;
    let mut data = "freq".to_string();
    let mut tau0 = 1.0;
    let mut json = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--data" => data = it.next().ok_or("--data needs a value")?.clone(),
            "--tau0" => tau0 = it.next().ok_or("--tau0 needs a value")?.parse()?,
            "--json" => json = Some(it.next().ok_or("--json needs a value")?.clone()),
            other if path.is_none() => path = Some(other.to_string()),
            other => return Err(format!("unexpected argument {other}").into()),
        }
    }
    let path =
        path.ok_or("usage: stream_allan FILE [--data freq|phase] [--tau0 S] [--json OUT]")?;
    let cfg = StreamConfig::with_tau0(tau0);
    let mut acc = match data.as_str() {
        "freq" => OctaveAllan::freq(cfg)?,
        "phase" => OctaveAllan::phase(cfg)?,
        other => return Err(format!("--data must be freq or phase, not {other}").into()),
    };
    let start = Instant::now();
    let mut file = File::open(&path)?;
    let mut bytes = vec![0u8; 1 << 20];
    let mut values = Vec::with_capacity(bytes.len() / 8);
    let mut carry = 0usize;
    let mut engine = 0.0f64;
    loop {
        let n = file.read(&mut bytes[carry..])?;
        if n == 0 {
            if carry != 0 {
                return Err(format!("{path}: {carry} trailing bytes (not a multiple of 8)").into());
            }
            break;
        }
        let avail = carry + n;
        let whole = avail / 8 * 8;
        values.resize(whole / 8, 0.0);
        for (v, c) in values.iter_mut().zip(bytes[..whole].chunks_exact(8)) {
            *v = f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        }
        let t = Instant::now();
        acc.push_block(&values)?;
        engine += t.elapsed().as_secs_f64();
        bytes.copy_within(whole..avail, 0);
        carry = avail - whole;
    }
    let t = Instant::now();
    let pts = acc.points(0.683)?;
    engine += t.elapsed().as_secs_f64();
    let secs = start.elapsed().as_secs_f64();
    let out = serde_json::to_string_pretty(&pts)?;
    match json {
        Some(p) => File::create(p)?.write_all(out.as_bytes())?,
        None => {
            println!(
                "{:>12} {:>12} {:>6} {:>12} {:>14} {:>10} {:>3}",
                "m", "tau_s", "stride", "n", "adev", "edf", "a"
            );
            for p in &pts {
                println!(
                    "{:>12} {:>12.6e} {:>6} {:>12} {:>14.6e} {:>10.1} {:>3}",
                    p.m, p.tau_s, p.stride, p.n, p.dev, p.edf, p.alpha
                );
            }
        }
    }
    eprintln!(
        "samples {} seconds {:.4} samples_per_s {:.4e} engine_seconds {:.4} \
         engine_samples_per_s {:.4e} state_bytes {}",
        acc.samples(),
        secs,
        acc.samples() as f64 / secs,
        engine,
        acc.samples() as f64 / engine,
        acc.memory_bytes()
    );
    Ok(())
}
