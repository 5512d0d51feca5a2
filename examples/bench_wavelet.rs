//! Throughput of the streaming sym8 filter bank and QN splitter, driven by
//! `scripts/bench-wavelet` (which also times PyWavelets on the same samples).
//!
//! Usage: `bench_wavelet [N] [LEVELS] [DATA_OUT] [REPEATS]`: N samples (default
//! 10 M) of a gyro-like rate signal (integer pulse counts of a 1.21" gyro at 1 kHz,
//! as arcsec/s), depth LEVELS (default 10). When DATA_OUT is given (not `-`), the samples are
//! written there as little-endian f64 for the PyWavelets side. Each case runs
//! REPEATS times (default 3) and the best is kept. Prints one line per case:
//! `name  M samples/s (wall)  M samples/s (cpu)`; CPU time is the thread's on-CPU
//! time from /proc (Linux), which stays meaningful on a busy machine.

use sagnac::dsp::{QnConfig, QnSplitter, StreamingBank, Wavelet};
use std::io::Write;
use std::time::Instant;

fn cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
}

/// Deterministic test signal: pulse counts of a quantised random-walk angle.
fn signal(n: usize) -> Vec<f64> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let d = 1.21;
    let mut theta = 0.0;
    let mut c_prev = 0i64;
    (0..n)
        .map(|_| {
            // 12.3 arcsec/s input, a crude white angle error of about 0.5 d.
            theta += 12.3e-3 + 0.004 * (next() - 0.5);
            let c = ((theta + 0.6 * (next() - 0.5)) / d).floor() as i64;
            let dc = c - c_prev;
            c_prev = c;
            dc as f64 * d * 1000.0
        })
        .collect()
}

/// Best (wall, cpu) seconds over `repeats` runs of `f`.
fn time<F: FnMut()>(repeats: usize, mut f: F) -> (f64, Option<f64>) {
    let mut best = (f64::INFINITY, None::<f64>);
    for _ in 0..repeats {
        let c0 = cpu_ns();
        let t0 = Instant::now();
        f();
        let wall = t0.elapsed().as_secs_f64();
        let cpu = match (c0, cpu_ns()) {
            (Some(a), Some(b)) => Some((b - a) as f64 * 1e-9),
            _ => None,
        };
        best.0 = best.0.min(wall);
        best.1 = match (best.1, cpu) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
    }
    best
}

fn report(name: &str, n: usize, (wall, cpu): (f64, Option<f64>)) {
    let c = cpu.map_or("n/a".to_string(), |c| format!("{:.1}", n as f64 / c / 1e6));
    println!("{name:<58} {:>8.1} {:>8}", n as f64 / wall / 1e6, c);
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(10_000_000, |s| s.parse().expect("N"));
    let levels: u32 = args.next().map_or(10, |s| s.parse().expect("LEVELS"));
    let data_out = args.next();
    let repeats: usize = args.next().map_or(3, |s| s.parse().expect("REPEATS"));
    let x = signal(n);
    if let Some(path) = data_out.filter(|p| !p.is_empty() && p != "-") {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).expect("create DATA_OUT"));
        for v in &x {
            f.write_all(&v.to_le_bytes()).expect("write");
        }
    }
    let w = Wavelet::by_name("sym8").expect("sym8");
    println!("# sagnac, N = {n}, sym8, J = {levels}, best of {repeats}");
    let mut clean = Vec::with_capacity(n);
    let mut noise = Vec::with_capacity(n);
    for (block, label) in [(4096usize, "4096"), (1000, "1000"), (1, "1")] {
        // Block size 1 is slow by design (per-call overhead); time a tenth of the data.
        let m = if block == 1 { n / 10 } else { n };
        let mut cfg = QnConfig::new(1000.0);
        cfg.levels = Some(levels);
        let t = time(repeats, || {
            clean.clear();
            noise.clear();
            let mut sp = QnSplitter::new(&cfg).expect("config");
            for c in x[..m].chunks(block) {
                sp.push(c, &mut clean, &mut noise);
            }
            sp.flush(&mut clean, &mut noise);
        });
        assert_eq!(clean.len(), m);
        report(
            &format!("sagnac QnSplitter streaming (analysis+QN+synthesis), blk {label}"),
            m,
            t,
        );
    }
    let mut out = Vec::with_capacity(n + 100_000);
    let t = time(repeats, || {
        out.clear();
        let mut bank = StreamingBank::new(&w, levels).expect("bank");
        for c in x.chunks(4096) {
            bank.push(c, &mut out);
        }
        bank.flush(&mut out);
    });
    let err = out
        .iter()
        .zip(&x)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    report(
        "sagnac StreamingBank streaming (analysis+synthesis), blk 4096",
        n,
        t,
    );
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    println!(
        "# bank reconstruction max error {:.2e} (relative {:.2e})",
        err,
        err / scale
    );
}
