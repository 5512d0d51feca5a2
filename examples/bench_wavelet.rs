//! Throughput of the streaming sym8 filter bank and QN splitter, driven by
//! `scripts/bench-wavelet` (which also times PyWavelets on the same samples).
//!
//! Usage: `bench_wavelet [N] [LEVELS] [DATA_OUT] [REPEATS]`: N samples (default
//! 10 M) of a gyro-like rate signal (integer pulse counts of a 1.21" gyro at 1 kHz,
//! as arcsec/s), depth LEVELS (default 10). When DATA_OUT is given (not `-`), the samples are
//! written there as little-endian f64 for the PyWavelets side. Each case runs
//! REPEATS times (default 5). Prints one line per case: `name  M samples/s (wall,
//! median of the runs)  (slowest-fastest)  M samples/s (cpu, median)`; CPU time
//! is the thread's on-CPU time from /proc (Linux), which stays meaningful on a
//! busy machine.

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

/// Wall and CPU seconds of `repeats` runs of `f`.
struct Runs {
    wall: Vec<f64>,
    cpu: Vec<f64>,
}

fn time<F: FnMut()>(repeats: usize, mut f: F) -> Runs {
    let mut runs = Runs {
        wall: Vec::new(),
        cpu: Vec::new(),
    };
    for _ in 0..repeats {
        let c0 = cpu_ns();
        let t0 = Instant::now();
        f();
        runs.wall.push(t0.elapsed().as_secs_f64());
        if let (Some(a), Some(b)) = (c0, cpu_ns()) {
            runs.cpu.push((b - a) as f64 * 1e-9);
        }
    }
    runs
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let k = s.len() / 2;
    if s.len() % 2 == 1 {
        s[k]
    } else {
        0.5 * (s[k - 1] + s[k])
    }
}

fn report(name: &str, n: usize, runs: Runs) {
    let ms = |t: f64| n as f64 / t / 1e6;
    let c = if runs.cpu.is_empty() {
        "n/a".to_string()
    } else {
        format!("{:.1}", ms(median(&runs.cpu)))
    };
    let (slow, fast) = runs
        .wall
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &t| {
            (a.min(ms(t)), b.max(ms(t)))
        });
    println!(
        "{name:<58} {:>8.1} {:>13} {:>8}",
        ms(median(&runs.wall)),
        format!("({slow:.1}-{fast:.1})"),
        c
    );
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(10_000_000, |s| s.parse().expect("N"));
    let levels: u32 = args.next().map_or(10, |s| s.parse().expect("LEVELS"));
    let data_out = args.next();
    let repeats: usize = args.next().map_or(5, |s| s.parse().expect("REPEATS"));
    let x = signal(n);
    if let Some(path) = data_out.filter(|p| !p.is_empty() && p != "-") {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&path).expect("create DATA_OUT"));
        for v in &x {
            f.write_all(&v.to_le_bytes()).expect("write");
        }
    }
    let w = Wavelet::by_name("sym8").expect("sym8");
    println!("# sagnac, N = {n}, sym8, J = {levels}, medians of {repeats} runs");
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
