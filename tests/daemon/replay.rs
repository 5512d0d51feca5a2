//! Replays through the real daemon binary:
//! * a corrupted raw frame capture (`.bin`) replays with the exact frame counts
//!   of its ledger and every pulse in `/gyro/raw`;
//! * replaying the resulting MCAP recording twice gives bit-identical final
//!   estimates (determinism), bit-identical to the `.bin` replay's (the daemon
//!   pushes canonical blocks whatever the source's batching), and the same
//!   `/gyro/raw` messages;
//! * the daemon's final estimates equal those of `sagnac analyze` on the same
//!   capture (`--format frames`) and on the daemon's recording of it (`--format
//!   mcap`) to a relative 1e-9: the same `Pipeline` on the same samples, called
//!   with other block sizes (its sums are not bit-invariant to the split);
//! * `--speed` paces a replay (lower bound on the wall time only).

use std::path::Path;
use std::time::{Duration, Instant};

use sagnac::daemon::bench::BenchEmulator;
use sagnac::input::frame::inject::{FaultPlan, InjectorConfig};

use crate::support::PAPER_GYRO;
use crate::support::daemon::*;

fn run_replay(input: &Path, rec_dir: &Path, log: &Path, extra: &[&str]) -> Duration {
    let start = Instant::now();
    let mut args = vec![
        "run",
        "--replay",
        input.to_str().unwrap(),
        "--record-dir",
        rec_dir.to_str().unwrap(),
        "--metrics-addr",
        "",
    ];
    // raw frames do not carry the rate or pulse weight (an MCAP recording does)
    if input.extension().is_some_and(|e| e == "bin") {
        args.extend_from_slice(&["--sample-rate-hz", "1000", "--pulse-arcsec", "1.21"]);
    }
    args.extend_from_slice(extra);
    let mut d = DaemonProc::start(&args, log);
    let status = d.wait(Duration::from_secs(60));
    assert!(
        status.success(),
        "replay of {}: {status:?}\n{}",
        input.display(),
        d.log_text()
    );
    start.elapsed()
}

#[test]
fn replays_are_exact_deterministic_and_equal_the_offline_pipeline() {
    let dir = tempfile::tempdir().unwrap();
    // 300 s of the paper gyro at 1 kHz, corrupted (drops, flips, duplicates, garbage).
    let emu = BenchEmulator::simulate(&paper_model(), 31, 300.0, 65_500, u32::MAX - 50).unwrap();
    let cfg = InjectorConfig {
        drop_prob: 0.003,
        flip_prob: 0.003,
        duplicate_prob: 0.001,
        garbage_prob: 0.003,
        ..InjectorConfig::default()
    };
    let injected = emu.inject(&FaultPlan::random(emu.frames.len(), &cfg, 9));
    let e = injected.ledger.expected;
    assert_eq!(e.spurious_windows, 0);
    let bin = dir.path().join("capture.bin");
    std::fs::write(&bin, &injected.bytes).unwrap();

    let r1 = dir.path().join("r1");
    run_replay(&bin, &r1, &dir.path().join("r1.log"), &[]);
    let rec1 = only_recording(&r1);
    let v = read_mcap_py_with(&rec1, &["--no-schema", "--summary"]);
    // /gyro/summary: 10 Hz over 300 s of gap-filled periods (the windows with
    // gaps count their lost samples), equal to the raw and clean channels
    // averaged independently
    assert_eq!(check_summary(&v), 3000);
    let lost: u64 = v["summary_recorded"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w[2].as_u64().unwrap())
        .sum();
    assert_eq!(lost, e.lost_samples);
    assert_eq!(
        v["raw_counts_total"].as_i64(),
        Some(emu.true_total_pulses())
    );
    assert_eq!(v["raw_samples"].as_u64(), Some(e.samples));
    assert_eq!(v["raw_lost_total"].as_u64(), Some(e.lost_samples));
    assert_eq!(
        v["events_by_kind"]["crc_error"].as_u64().unwrap_or(0),
        e.crc_errors
    );
    assert_eq!(v["events_by_kind"]["gap"].as_u64().unwrap_or(0), e.gaps);
    assert_eq!(v["values_total"]["/gyro/clean"].as_u64(), Some(300_000));

    // MCAP replay, twice.
    let (r2, r3) = (dir.path().join("r2"), dir.path().join("r3"));
    run_replay(&rec1, &r2, &dir.path().join("r2.log"), &[]);
    run_replay(&rec1, &r3, &dir.path().join("r3.log"), &[]);
    let (f1, raw1) = final_and_raw(&rec1);
    let (f2, raw2) = final_and_raw(&only_recording(&r2));
    let (f3, raw3) = final_and_raw(&only_recording(&r3));
    assert_eq!(
        f2.estimates, f3.estimates,
        "replaying the same recording twice"
    );
    assert_eq!(f1.estimates, f2.estimates, ".bin replay vs its MCAP replay");
    assert_eq!((f1.samples, f2.samples), (300_000, 300_000));
    // /gyro/raw is reproduced: same samples, gaps and sequence numbers, same times.
    assert_eq!(raw1, raw2);
    assert_eq!(raw2, raw3);

    // `sagnac analyze` on the same capture (which carries no rate or pulse weight:
    // analyze_json gives the flags), and on the daemon's recording of it (its
    // metadata record says them).
    for (format, input) in [("frames", &bin), ("mcap", &rec1)] {
        let a = analyze_json(
            format,
            input,
            &dir.path().join(format!("analyze-{format}.json")),
        );
        assert_eq!(a["samples"], 300_000);
        // The same Pipeline on the same samples, pushed in other block sizes:
        // equal to rounding (relative 1e-9; the pipeline's sums are not
        // bit-invariant to the block split).
        close_estimates(&f1, &a, &format!("daemon vs analyze --format {format}"));
    }
    // One name per quantity: /gyro/estimates, read by the Python reader, has
    // analyze's keys and interval fields, coefficient by coefficient.
    let a = analyze_json("mcap", &rec1, &dir.path().join("analyze-names.json"));
    let shape = |v: &serde_json::Value| -> Vec<(String, Vec<String>)> {
        v.as_object()
            .unwrap()
            .iter()
            .map(|(k, c)| (k.clone(), c.as_object().unwrap().keys().cloned().collect()))
            .collect()
    };
    let recorded = &v["last_estimates"]["estimates"];
    assert_eq!(shape(recorded), shape(&a["estimates"]));
    let keys: Vec<&str> = sagnac::units::COEFFICIENTS.iter().map(|c| c.0).collect();
    assert_eq!(
        recorded
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect::<Vec<_>>(),
        {
            let mut k = keys.clone();
            k.sort();
            k
        }
    );
    assert_eq!(v["last_estimates"]["samples"], a["samples"]);
}

#[test]
fn speed_paces_an_mcap_replay() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("sim.mcap");
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(PAPER_GYRO)
        .args([
            "--duration-s",
            "10",
            "--seed",
            "3",
            "--format",
            "mcap",
            "--out",
        ])
        .arg(&mcap)
        .output()
        .unwrap();
    assert!(r.status.success());
    // 10 s of data at 20x real time cannot take less than 0.5 s.
    let wall = run_replay(
        &mcap,
        &dir.path().join("rec"),
        &dir.path().join("log"),
        &["--speed", "20"],
    );
    assert!(
        wall >= Duration::from_millis(480),
        "paced replay took {wall:?}"
    );
    let v = read_mcap_py_fast(&only_recording(&dir.path().join("rec")));
    assert_eq!(v["raw_samples"], 10_000);
}
