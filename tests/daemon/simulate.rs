//! `sagnac simulate --format frames | mcap` (the captures the daemon replays):
//! both carry exactly the pulse stream of `--format csv` for the same model and
//! seed; the frames decode with the frame decoder, the MCAP file is read back by
//! the independent Python reader (scripts/read-mcap.py).
//!
//! The daemon on a simulated bench with defects (`sagnac run --simulate`): the
//! data-quality stage live. A warm-up restarts the statistics once it has
//! settled (and the channels go on whole); glitches are counted and excluded;
//! `--raw-statistics` turns all of it off.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use sagnac::input::frame::{DecodeEvent, Decoded, DecoderConfig, FrameDecoder};

use crate::support::daemon::*;
use crate::support::{PAPER_GYRO, free_addr};

fn simulate(out: &Path, format: &str, duration: &str) {
    let r = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(PAPER_GYRO)
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
        .arg(PAPER_GYRO)
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

/// A 200 Hz counter gyro, 10 deg/h input; `extra` adds its defects.
fn defect_model(dir: &Path, name: &str, extra: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(
        &p,
        format!(
            "[gyro]\nsample_rate_hz = 200.0\npulse_arcsec = 1.21\ninput_rate_dph = 10.0\n\
             [noise]\nquantization_arcsec = 0.4\narw_dpsh = 0.01\nbias_instability_dph = 0.005\n{extra}"
        ),
    )
    .unwrap();
    p
}

const WARMUP: &str = "[noise.warmup]\namplitude_dph = 3.0\ntau_s = 60.0\n";
const SPIKES: &str = "[noise.spikes]\nrate_per_h = 600.0\namplitude_dph = 50000.0\n";

/// `sagnac run --simulate MODEL --speed 0 --duration-s 1200` (seed 1, the
/// default), recorded in `rec`; more flags in `extra`. Its stderr.
fn run_to_end(model: &Path, rec: &Path, extra: &[&str]) -> String {
    let r = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .arg("run")
        .arg("--simulate")
        .arg(model)
        .args(["--speed", "0", "--duration-s", "1200", "--metrics-addr", ""])
        .arg("--record-dir")
        .arg(rec)
        .args(extra)
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "{err}");
    err
}

/// Every `/gyro/estimates` message of a recording, in order.
fn estimates(rec: &Path) -> Vec<sagnac::recording::messages::EstimateUpdate> {
    sagnac::recording::reader::read_recording(rec)
        .unwrap()
        .messages
        .into_iter()
        .filter_map(|m| match m.message {
            sagnac::recording::messages::SinkMessage::Estimates(e) => Some(e),
            _ => None,
        })
        .collect()
}

/// A 3 deg/h warm-up with a 60 s time constant on 20 min at 200 Hz: reported
/// `modelled` while it settles, then the statistics restart once, after at
/// least 5 time constants (300 s); the final estimates are of the data after
/// it (no rate random walk left from the settling), `excluded` with the
/// seconds left out. The restart leaves the channels whole: every sample has
/// its clean and noise value, the 10 Hz summary windows equal the raw and
/// clean channels averaged independently, and the independent reader
/// validates every message (data_quality included) against its schema.
#[test]
fn a_settled_warmup_restarts_the_statistics_once() {
    let dir = tempfile::tempdir().unwrap();
    let model = defect_model(dir.path(), "warm.toml", WARMUP);
    let rec = dir.path().join("rec");
    let log = run_to_end(&model, &rec, &[]);
    let restarts = log.matches("statistics restarted").count();
    assert_eq!(restarts, 1, "one restart:\n{log}");
    let path = only_recording(&rec);
    let v = read_mcap_py_with(&path, &["--summary"]);
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
    let n = 1200 * 200;
    assert_eq!(v["raw_samples"], n);
    assert_eq!(v["values_total"]["/gyro/clean"], n);
    assert_eq!(v["values_total"]["/gyro/noise"], n);
    assert_eq!(check_summary(&v), 12_000);
    let last = &v["last_estimates"];
    let w = &last["data_quality"]["warmup"];
    assert_eq!(w["handled"], "excluded", "{last}");
    let excluded_s = w["excluded_s"].as_f64().unwrap();
    // the restart comes at a whole minute of samples, 5 taus (at the upper end
    // of tau's interval) after the start
    assert!(
        (300.0..=900.0).contains(&excluded_s) && excluded_s % 60.0 == 0.0,
        "{w}"
    );
    let tau = w["tau_s"]["value"].as_f64().unwrap();
    let amp = w["amplitude_dph"]["value"].as_f64().unwrap();
    assert!(
        (30.0..120.0).contains(&tau) && (2.0..4.5).contains(&amp),
        "{w}"
    );
    assert!(
        last["estimates"]["rrw_dphsh"]["value"].is_null(),
        "no rate random walk from the settling: {last}"
    );
    // the final statistics are of the samples after the restart
    let used = n as f64 - excluded_s * 200.0;
    assert_eq!(last["samples"].as_f64().unwrap(), used, "{last}");
    // the Rust reader gives back the same findings (the updates before the
    // restart, `modelled`, are skipped at this pace: tests/daemon/process.rs
    // publishes every one)
    let all = estimates(&path);
    let fin = all.last().unwrap().data_quality.as_ref().unwrap();
    assert_eq!(
        serde_json::to_value(fin).unwrap(),
        last["data_quality"],
        "round trip"
    );
}

/// The same warm-up run with `--raw-statistics`: no data-quality stage, so
/// no `data_quality` in any estimate, no restart, every sample in the
/// statistics (where the settling reads as a rate random walk).
#[test]
fn raw_statistics_leave_the_warmup_in() {
    let dir = tempfile::tempdir().unwrap();
    let model = defect_model(dir.path(), "warm.toml", WARMUP);
    let rec = dir.path().join("rec");
    let log = run_to_end(&model, &rec, &["--raw-statistics"]);
    assert!(!log.contains("statistics restarted"), "{log}");
    let path = only_recording(&rec);
    let all = estimates(&path);
    assert!(!all.is_empty());
    assert!(all.iter().all(|e| e.data_quality.is_none()));
    assert_eq!(all.last().unwrap().samples, 1200 * 200);
    assert!(
        all.last().unwrap().estimates.rrw_dphsh.value.is_some(),
        "{:?}",
        all.last().unwrap().estimates
    );
    let v = read_mcap_py_fast(&path);
    assert!(v["last_estimates"].get("data_quality").is_none());
}

/// A ramp the data-quality stage's own test rejects (0.3 deg/h/h over 20
/// min, within what the block means' noise can make) is a bound in the
/// daemon's final estimates, as in `analyze` of the same stream; with
/// `--raw-statistics` the estimator alone calls it found, its interval
/// reaching zero.
#[test]
fn a_ramp_the_stage_rejects_is_a_bound_live_as_offline() {
    let dir = tempfile::tempdir().unwrap();
    let model = defect_model(dir.path(), "ramp.toml", "rate_ramp_dphh = 0.3\n");
    let ramp = |extra: &[&str]| {
        let rec = dir.path().join(format!("rec{}", extra.len()));
        run_to_end(&model, &rec, extra);
        estimates(&only_recording(&rec))
            .pop()
            .unwrap()
            .estimates
            .rate_ramp_dphh
    };
    let (live, raw) = (ramp(&[]), ramp(&["--raw-statistics"]));
    assert!(live.value.is_none(), "{live:?}");
    let [lo, hi] = raw.ci95.expect("found by the estimator alone");
    assert!(lo < 0.0 && 0.0 < hi, "{raw:?}");
    let bound = live.upper95.expect("a bound");
    assert!(
        (bound / lo.abs().max(hi.abs()) - 1.0).abs() < 1e-9,
        "{live:?} {raw:?}"
    );
    // analyze of the same stream (seed 1) reports the same bound
    let csv = dir.path().join("ramp.csv");
    let o = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(&model)
        .args(["--duration-s", "1200", "--seed", "1", "--out"])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args([
            "analyze",
            "--sample-rate-hz",
            "200",
            "--pulse-arcsec",
            "1.21",
            "--json",
            "-",
            "--input",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let off = &j["estimates"]["rate_ramp_dphh"];
    assert!(off["value"].is_null(), "{off}");
    let u = off["upper95"].as_f64().unwrap();
    assert!(
        (u / live.upper95.unwrap() - 1.0).abs() < 1e-9,
        "{off} {live:?}"
    );
}

/// Glitches of 5000-50000 deg/h, 10 a minute: counted live at `/metrics`
/// (`sagnac_outliers_total`, apart from the lost samples) and in the
/// recording's `data_quality.outliers`, excluded; with `--raw-statistics` the
/// counter stays at 0 and the recording has no `data_quality`.
#[test]
fn glitches_are_counted_live_and_excluded() {
    let dir = tempfile::tempdir().unwrap();
    let model = defect_model(dir.path(), "spiky.toml", SPIKES);
    for raw in [false, true] {
        let rec = dir.path().join(format!("rec-{raw}"));
        let addr = free_addr();
        let mut args = vec![
            "run".to_string(),
            "--simulate".into(),
            model.display().to_string(),
            "--speed".into(),
            "0".into(),
            "--metrics-addr".into(),
            addr.to_string(),
            "--record-dir".into(),
            rec.display().to_string(),
        ];
        if raw {
            args.push("--raw-statistics".into());
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let mut d = DaemonProc::start(&args, &dir.path().join(format!("log-{raw}")));
        let outliers = "sagnac_outliers_total{gyro=\"gyro\"}";
        // the pipeline runs behind the source (its queue holds tens of
        // seconds of samples): wait for what it counts
        let text = wait_for("glitches counted", Duration::from_secs(300), || {
            let t = scrape(addr)?;
            let done = if raw {
                metric(&t, "sagnac_estimator_updates_total{gyro=\"gyro\"}")? >= 2.0
                    && metric(&t, "sagnac_samples_total{gyro=\"gyro\"}")? >= 120_000.0
            } else {
                metric(&t, outliers)? >= 20.0
            };
            done.then_some(t)
        });
        d.stop_ok(Duration::from_secs(60));
        let live = metric(&text, outliers).unwrap();
        assert_eq!(
            metric(&text, "sagnac_lost_samples_total{gyro=\"gyro\"}"),
            Some(0.0)
        );
        let (ok, out) = promtool(&text);
        assert!(ok, "{out}");
        let last = estimates(&only_recording(&rec)).pop().unwrap();
        if raw {
            assert_eq!(live, 0.0, "raw statistics: no glitch count");
            for g in [
                "sagnac_bias_steps_total",
                "sagnac_warmup_active",
                "sagnac_warmup_amplitude_dph",
                "sagnac_warmup_tau_seconds",
            ] {
                assert_eq!(metric(&text, &format!("{g}{{gyro=\"gyro\"}}")), Some(0.0));
            }
            assert!(last.data_quality.is_none());
            continue;
        }
        assert!(live >= 20.0, "{outliers} = {live}");
        let o = &last.data_quality.as_ref().unwrap().outliers;
        assert!(o.count as f64 >= live && o.excluded, "{o:?} vs {live} live");
        assert_eq!(o.at_s.len() as u64, o.count.min(1000));
        // about 10 a minute over the record, no false alarms beyond
        let minutes = last.duration_s / 60.0;
        let rate = o.count as f64 / minutes;
        assert!((5.0..16.0).contains(&rate), "{} in {minutes} min", o.count);
    }
}
