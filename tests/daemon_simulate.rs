//! `sagnac simulate --format frames | mcap` (the captures the daemon replays):
//! both carry exactly the pulse stream of `--format csv` for the same model and
//! seed; the frames decode with the frame decoder, the MCAP file is read back by
//! the independent Python reader (scripts/read-mcap.py).

use std::path::{Path, PathBuf};
use std::process::Command;

use sagnac::input::frame::{DecodeEvent, Decoded, DecoderConfig, FrameDecoder};

fn paper() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("config/paper_gyro.toml")
}

fn simulate(out: &Path, format: &str, duration: &str) {
    let r = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(paper())
        .args([
            "--duration-s",
            duration,
            "--seed",
            "11",
            "--format",
            format,
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap();
    assert!(
        r.status.success(),
        "simulate --format {format}: {}",
        String::from_utf8_lossy(&r.stderr)
    );
}

fn csv_counts(dir: &Path, duration: &str) -> Vec<i64> {
    let csv = dir.join("sim.csv");
    simulate(&csv, "csv", duration);
    std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.parse().unwrap())
        .collect()
}

#[test]
fn frames_carry_exactly_the_csv_stream() {
    let dir = tempfile::tempdir().unwrap();
    let want = csv_counts(dir.path(), "3.2");
    let bin = dir.path().join("sim.bin");
    simulate(&bin, "frames", "3.2");
    let bytes = std::fs::read(&bin).unwrap();
    // N samples -> N + 1 frames of 16 bytes, exactly
    assert_eq!(bytes.len(), (want.len() + 1) * 16);
    let (items, stats) = FrameDecoder::decode_all(&bytes, DecoderConfig::default());
    let got: Vec<i64> = items
        .iter()
        .filter_map(|d| match d {
            Decoded::Sample(s) => Some(s.increment),
            _ => None,
        })
        .collect();
    assert_eq!(got, want);
    assert_eq!(
        stats.bytes_skipped + stats.crc_errors + stats.lost_samples,
        0
    );
    // the run starts at seq 65000: the 16-bit sequence wraps inside 3.2 s
    assert!(
        items
            .iter()
            .any(|d| matches!(d, Decoded::Event(DecodeEvent::Baseline { seq: 65_000, .. })))
    );
    // same seed, same bytes
    let again = dir.path().join("again.bin");
    simulate(&again, "frames", "3.2");
    assert_eq!(std::fs::read(&again).unwrap(), bytes);
}

#[test]
fn mcap_carries_exactly_the_csv_stream() {
    let dir = tempfile::tempdir().unwrap();
    let want = csv_counts(dir.path(), "2.5");
    let out = dir.path().join("sim.mcap");
    simulate(&out, "mcap", "2.5");
    // Rust reader: /gyro/raw batches of 1000 samples, contiguous seq0 and t0 from 0.
    let rec = sagnac::recording::reader::read_recording(&out).unwrap();
    let mut got = Vec::new();
    for (i, m) in rec.messages.iter().enumerate() {
        let sagnac::recording::messages::SinkMessage::Raw(r) = &m.message else {
            panic!("unexpected message {m:?}")
        };
        assert_eq!(r.seq0, 1000 * i as u64);
        assert_eq!(r.t0_ns, 1_000_000_000 * i as u64);
        assert_eq!(r.dt_ns, 1_000_000);
        got.extend_from_slice(&r.counts);
    }
    assert_eq!(rec.messages.len(), 3);
    assert_eq!(got, want);
    // Independent reader (Python `mcap`): same sample count and pulse sum.
    let py = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/read-mcap.py"))
        .arg(&out)
        .output()
        .expect("python3 (scripts/install-peers)");
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&py.stdout).unwrap();
    assert_eq!(v["raw_samples"], want.len() as u64);
    assert_eq!(v["raw_counts_total"], want.iter().sum::<i64>());
    assert_eq!(v["raw_lost_total"], 0);
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
    // deterministic bytes
    let again = dir.path().join("again.mcap");
    simulate(&again, "mcap", "2.5");
    assert_eq!(std::fs::read(&again).unwrap(), std::fs::read(&out).unwrap());
}

#[test]
fn mcap_to_stdout_is_refused_with_exit_2() {
    let r = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(paper())
        .args([
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--format",
            "mcap",
            "--out",
            "-",
        ])
        .output()
        .unwrap();
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("--format mcap cannot go to stdout"));
}
