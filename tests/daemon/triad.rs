//! A triad on a serial line: three gyros with different noise on 24-byte
//! triad frames through a socat pty, with corruption, drops, a dropped burst
//! and counter wraps. One daemon (`--frame triad`) must count every gyro's
//! lost samples and frame errors exactly (the injector's ledger), estimate
//! each gyro's QN and ARW around its own truth, and record every pulse of
//! each gyro on its own `/gyro/<label>/raw` channel (read back with the
//! independent Python `mcap` reader).

use std::time::Duration;

use sagnac::daemon::bench::write_paced;
use sagnac::input::frame::inject::{FaultPlan, FrameAction, inject_wire};
use sagnac::input::frame::{Triad, TriadEncoder, triad::encode_triad_increments};
use sagnac::model::{GyroModel, Simulator};
use sagnac::recording::reader::RawReader;

use crate::support::daemon::*;
use crate::support::free_addr;

const RATE_HZ: f64 = 1000.0;
const SPEEDUP: f64 = 20.0;
const SECONDS: f64 = 60.0;

/// x: the paper gyro; y and z: more angle random walk (20x, 8x), other inputs.
fn models() -> [GyroModel; 3] {
    let x = paper_model();
    let mut y = x.clone();
    y.gyro.input_rate_dph = -40.0;
    y.noise.arw_dpsh = Some(0.02);
    let mut z = x.clone();
    z.gyro.input_rate_dph = 5.0;
    z.noise.arw_dpsh = Some(0.008);
    [x, y, z]
}

#[test]
fn a_triad_over_a_pty_exact_per_gyro_counts_estimates_and_every_pulse_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let models = models();
    let n = (SECONDS * RATE_HZ) as usize;
    let mut incs = vec![Vec::new(); 3];
    for (k, m) in models.iter().enumerate() {
        Simulator::new(m, 40 + k as u64, Some(SECONDS))
            .unwrap()
            .next_block(n, &mut incs[k]);
    }
    let triad: Vec<[i64; 3]> = (0..n)
        .map(|i| [incs[0][i], incs[1][i], incs[2][i]])
        .collect();
    // the sequence wraps after 536 frames; the x and y counters wrap too
    let mut enc = TriadEncoder::new(65_000, [u32::MAX - 300, 200, 1 << 31]);
    let frames = encode_triad_increments(&mut enc, &triad).unwrap();
    let cfg = serial_faults();
    let mut plan = FaultPlan::random_for::<Triad>(frames.len(), &cfg, 9);
    for i in 20_000..20_040 {
        plan.set_action(i, FrameAction::Drop);
    }
    let injected = inject_wire::<Triad>(&frames, &plan);
    let e = injected.ledger.expected.clone();
    assert_eq!(e.spurious_windows, 0, "the ledger's derivation holds");
    assert!(e.lost_samples > 40 && e.crc_errors > 0 && e.duplicates > 0);

    let cfg_path = dir.path().join("daemon.toml");
    std::fs::write(
        &cfg_path,
        "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.21\n\n[estimator]\ninterval_s = 10.0\n\n[source]\nframe = \"triad\"\n",
    )
    .unwrap();
    let socat = Socat::start(&dir.path().join("A"), &dir.path().join("B"));
    let addr = free_addr();
    let rec_dir = dir.path().join("rec");
    let mut daemon = DaemonProc::start(
        &[
            "run",
            "--config",
            cfg_path.to_str().unwrap(),
            "--serial",
            socat.b.to_str().unwrap(),
            "--metrics-addr",
            &addr.to_string(),
            "--record-dir",
            rec_dir.to_str().unwrap(),
        ],
        &dir.path().join("daemon.log"),
    );
    wait_for("/metrics", Duration::from_secs(20), || scrape(addr));
    let mut w = socat.writer();
    write_paced(&mut w, &injected.bytes, RATE_HZ * 24.0 * SPEEDUP).unwrap();
    let _ = wait_metric(
        addr,
        "sagnac_bytes_read_total",
        e.bytes_read as f64,
        Duration::from_secs(30),
    );
    // each gyro's pipeline runs on its own thread: wait for all three (an
    // update still queued at the shutdown request is not made)
    let mut text = String::new();
    for g in ["x", "y", "z"] {
        text = wait_metric(
            addr,
            &format!("sagnac_estimator_updates_total{{gyro=\"{g}\"}}"),
            6.0,
            Duration::from_secs(30),
        );
    }
    for g in ["x", "y", "z"] {
        for (series, want) in [
            (
                format!("sagnac_frames_decoded_total{{gyro=\"{g}\"}}"),
                e.frames_decoded,
            ),
            (format!("sagnac_samples_total{{gyro=\"{g}\"}}"), e.samples),
            (
                format!("sagnac_lost_samples_total{{gyro=\"{g}\"}}"),
                e.lost_samples,
            ),
            (
                format!("sagnac_frame_errors_total{{gyro=\"{g}\",kind=\"crc\"}}"),
                e.crc_errors,
            ),
            (
                format!("sagnac_frame_errors_total{{gyro=\"{g}\",kind=\"false_sync\"}}"),
                e.false_syncs,
            ),
            (
                format!("sagnac_sequence_anomalies_total{{gyro=\"{g}\",kind=\"duplicate\"}}"),
                e.duplicates,
            ),
            (format!("sagnac_dropped_samples_total{{gyro=\"{g}\"}}"), 0),
            (format!("sagnac_device_connected{{gyro=\"{g}\"}}"), 1),
        ] {
            assert_eq!(metric(&text, &series), Some(want as f64), "{series}");
        }
    }
    assert_eq!(
        metric(&text, "sagnac_bytes_read_total"),
        Some(e.bytes_read as f64),
        "counted once"
    );
    let (ok, out) = promtool(&text);
    assert!(ok, "promtool check metrics:\n{out}");

    daemon.stop_ok(Duration::from_secs(10));
    drop(w);

    let rec = only_recording(&rec_dir);
    let v = read_mcap_py(&rec);
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
    assert_eq!(v["time_mismatches"], 0);
    for (k, g) in ["x", "y", "z"].into_iter().enumerate() {
        let gv = &v["gyros"][g];
        // every pulse of each gyro, whatever was lost on the wire
        assert_eq!(
            gv["raw_counts_total"].as_i64(),
            Some(incs[k].iter().sum::<i64>()),
            "gyro {g}"
        );
        assert_eq!(gv["raw_samples"].as_u64(), Some(e.samples), "gyro {g}");
        assert_eq!(
            gv["raw_lost_total"].as_u64(),
            Some(e.lost_samples),
            "gyro {g}"
        );
        assert_eq!(
            gv["values_total"]["clean"].as_u64(),
            Some(n as u64),
            "gyro {g}"
        );
        assert_eq!(
            gv["events_by_kind"]["crc_error"].as_u64().unwrap_or(0),
            e.crc_errors,
            "gyro {g}"
        );
        assert_eq!(
            v["channels"][format!("/gyro/{g}/estimates")],
            7,
            "6 updates and the final one"
        );
        // QN and ARW of each gyro around its own truth
        let est = &gv["last_estimates"]["estimates"];
        let q = &est["quantization_arcsec"];
        let (qv, lo, hi) = (
            q["value"].as_f64().unwrap(),
            q["ci95"][0].as_f64().unwrap(),
            q["ci95"][1].as_f64().unwrap(),
        );
        assert!(lo <= 0.35 && 0.35 <= hi, "gyro {g}: QN {qv} [{lo}, {hi}]");
        let truth = models[k].noise.arw_dpsh.unwrap();
        let a = &est["arw_dpsh"];
        match a["value"].as_f64() {
            Some(av) => {
                let (lo, hi) = (
                    a["ci95"][0].as_f64().unwrap(),
                    a["ci95"][1].as_f64().unwrap(),
                );
                assert!(
                    lo <= truth && truth <= hi,
                    "gyro {g}: ARW {av} [{lo}, {hi}] for {truth}"
                );
            }
            None => {
                let up = a["upper95"].as_f64().unwrap();
                assert!(truth <= up, "gyro {g}: ARW < {up} for {truth}");
            }
        }
    }
    // y and z were given 20x and 8x the ARW of x: both are measured
    for g in ["y", "z"] {
        assert!(
            v["gyros"][g]["last_estimates"]["estimates"]["arw_dpsh"]["value"].is_number(),
            "gyro {g}"
        );
    }
    // analyze reads one gyro of the recording
    let sagnac = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_sagnac"))
            .args(args)
            .output()
            .unwrap()
    };
    let rec_s = rec.to_str().unwrap();
    let out = sagnac(&[
        "analyze", "--input", rec_s, "--format", "mcap", "--gyro", "z", "--json", "-",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let a: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(a["input"]["gyro"], "z", "the JSON says which gyro it read");
    // without --gyro: every gyro, each as it is read alone
    let out = sagnac(&["analyze", "--input", rec_s, "--json", "-"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let all: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let labels: Vec<&String> = all["axes"].as_object().unwrap().keys().collect();
    assert_eq!(labels, ["x", "y", "z"]);
    assert_eq!(all["axes"]["z"]["estimates"], a["estimates"]);
    assert_eq!(all["axes"]["z"]["input"], a["input"]);
    let out = sagnac(&["analyze", "--input", rec_s, "--gyro", "w"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("x, y, z"), "{err}");
    // `sagnac run --replay` of the recording: three gyros again, each with its
    // label; each one's raw channel holds the recorded samples and gaps, so
    // analyze reads the same gyro z from both recordings
    let rec2_dir = dir.path().join("replayed");
    let out = sagnac(&[
        "run",
        "--replay",
        rec_s,
        "--record-dir",
        rec2_dir.to_str().unwrap(),
        "--metrics-addr",
        "",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let rec2 = only_recording(&rec2_dir);
    for g in ["x", "y", "z"] {
        let raw = |p: &std::path::Path| {
            let mut r = RawReader::open(p, Some(g), true).unwrap();
            let (mut counts, mut lost, mut first) = (Vec::new(), 0u64, None);
            while let Some(b) = r.next_batch().unwrap() {
                first.get_or_insert((b.seq0, b.t0_ns));
                counts.extend_from_slice(&b.counts);
                lost += b.gaps.iter().map(|g| g.lost).sum::<u64>();
            }
            (counts, lost, first)
        };
        let (live, replayed) = (raw(&rec), raw(&rec2));
        assert_eq!(live.0.len(), e.samples as usize, "gyro {g}");
        assert_eq!(live, replayed, "gyro {g}");
    }
    let rec2_s = rec2.to_str().unwrap();
    let out2 = sagnac(&[
        "analyze", "--input", rec2_s, "--format", "mcap", "--gyro", "z", "--json", "-",
    ]);
    let a2: serde_json::Value = serde_json::from_slice(&out2.stdout).unwrap();
    assert_eq!(
        a2["estimates"], a["estimates"],
        "analyze of z, live vs replayed"
    );
    let rec_z = &v["gyros"]["z"]["last_estimates"]["estimates"]["quantization_arcsec"]["value"];
    let an_z = a["estimates"]["quantization_arcsec"]["value"]
        .as_f64()
        .unwrap();
    assert!(
        (an_z - rec_z.as_f64().unwrap()).abs() < 1e-6 * an_z,
        "analyze {an_z} vs live {rec_z}"
    );
}
