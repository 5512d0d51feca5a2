//! The serial source end to end over a real pseudo-terminal: a bench emulator (a simulated
//! paper gyro with known truth, encoded into frames and corrupted by the seeded
//! injector, whose ledger says exactly what a decoder must count) writes into one
//! end of a socat pty pair; the real `sagnac` binary reads the other end through
//! tokio-serial. The test scrapes /metrics over a plain TcpStream and checks the
//! frame and sample counts EXACTLY against the ledger and the live QN estimate
//! against the model's truth, runs promtool on the live scrape, stops the daemon
//! with SIGTERM (exit 0), and reads the MCAP file back with the independent
//! Python reader: the raw channel holds every pulse the gyro produced.

use std::path::Path;
use std::time::Duration;

use sagnac::daemon::bench::{BenchEmulator, write_paced};
use sagnac::input::frame::inject::{FaultPlan, FrameAction, Ledger};

use crate::support::daemon::*;
use crate::support::free_addr;

/// Frame rate of the emulated gyro, Hz, and the emulator's speed-up over real time.
const RATE_HZ: f64 = 1000.0;
const SPEEDUP: f64 = 20.0;
/// The paper gyro's quantization coefficient (config/paper_gyro.toml), arcsec.
const TRUE_QN_ARCSEC: f64 = 0.35;

fn config_file(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("daemon.toml");
    std::fs::write(
        &p,
        // serial frames do not carry the rate or pulse weight: the file gives them
        // (present at the default values, which is enough)
        "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.21\n\n[estimator]\ninterval_s = 10.0\n\n[source]\nreconnect_initial_s = 0.1\nreconnect_max_s = 0.4\n",
    )
    .unwrap();
    p
}

fn faults(n_frames: usize, seed: u64) -> FaultPlan {
    let cfg = serial_faults();
    let mut plan = FaultPlan::random(n_frames, &cfg, seed);
    // and one burst of 50 dropped frames
    for i in 7_000..7_050 {
        plan.set_action(i, FrameAction::Drop);
    }
    plan
}

fn check_ledger_valid(l: &Ledger) {
    // The ledger's derivation holds under these two conditions (see inject docs).
    assert_eq!(l.expected.spurious_windows, 0);
    assert!(l.expected.max_seq_step <= 4097);
    assert!(l.dropped > 50 && l.bit_flipped > 0 && l.duplicated > 0 && l.garbage_runs > 0);
}

fn exact_counts(text: &str, l: &Ledger) {
    let e = &l.expected;
    for (series, want) in [
        ("sagnac_bytes_read_total", e.bytes_read),
        (
            "sagnac_frames_decoded_total{gyro=\"gyro\"}",
            e.frames_decoded,
        ),
        ("sagnac_samples_total{gyro=\"gyro\"}", e.samples),
        ("sagnac_lost_samples_total{gyro=\"gyro\"}", e.lost_samples),
        (
            "sagnac_frame_errors_total{gyro=\"gyro\",kind=\"crc\"}",
            e.crc_errors,
        ),
        (
            "sagnac_frame_errors_total{gyro=\"gyro\",kind=\"false_sync\"}",
            e.false_syncs,
        ),
        (
            "sagnac_frame_errors_total{gyro=\"gyro\",kind=\"truncated\"}",
            0,
        ),
        (
            "sagnac_sequence_anomalies_total{gyro=\"gyro\",kind=\"duplicate\"}",
            e.duplicates,
        ),
        ("sagnac_dropped_samples_total{gyro=\"gyro\"}", 0),
    ] {
        assert_eq!(metric(text, series), Some(want as f64), "{series}");
    }
}

fn check_recording(
    rec: &Path,
    emu: &BenchEmulator,
    l: &Ledger,
    periods: u64,
    schemas: bool,
) -> serde_json::Value {
    let v = if schemas {
        read_mcap_py(rec)
    } else {
        read_mcap_py_fast(rec)
    };
    let e = &l.expected;
    // Every pulse the gyro produced is in /gyro/raw, whatever was lost on the wire.
    assert_eq!(
        v["raw_counts_total"].as_i64(),
        Some(emu.true_total_pulses())
    );
    assert_eq!(v["raw_samples"].as_u64(), Some(e.samples));
    assert_eq!(v["raw_lost_total"].as_u64(), Some(e.lost_samples));
    assert_eq!(v["gap_lost_total"].as_u64(), Some(e.lost_samples));
    assert_eq!(v["events_by_kind"]["gap"].as_u64().unwrap_or(0), e.gaps);
    assert_eq!(
        v["events_by_kind"]["crc_error"].as_u64().unwrap_or(0),
        e.crc_errors
    );
    assert_eq!(
        v["events_by_kind"]["resync"].as_u64().unwrap_or(0),
        e.resyncs
    );
    // clean/noise cover every period (the wavelet bank was flushed at shutdown)
    assert_eq!(v["values_total"]["/gyro/clean"].as_u64(), Some(periods));
    assert_eq!(v["values_total"]["/gyro/noise"].as_u64(), Some(periods));
    assert_eq!(v["time_mismatches"], 0);
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
    assert_eq!(
        v["messages"], v["statistics_messages"],
        "complete file with a summary"
    );
    v
}

/// Start `sagnac run` on the serial device `device` with config `cfg`, metrics on
/// `addr` and recording into `rec_dir`; wait until /metrics answers.
fn start_serial_daemon(
    dir: &Path,
    cfg: &Path,
    device: &Path,
    addr: std::net::SocketAddr,
    rec_dir: &Path,
) -> DaemonProc {
    let daemon = DaemonProc::start(
        &[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--serial",
            device.to_str().unwrap(),
            "--metrics-addr",
            &addr.to_string(),
            "--record-dir",
            rec_dir.to_str().unwrap(),
        ],
        &dir.join("daemon.log"),
    );
    wait_for("/metrics", Duration::from_secs(20), || scrape(addr));
    daemon
}

#[test]
fn serial_pty_exact_counts_live_qn_promtool_sigterm_and_every_pulse_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let emu = BenchEmulator::simulate(&paper_model(), 21, 60.0, 65_000, u32::MAX - 200).unwrap();
    let plan = faults(emu.frames.len(), 5);
    let injected = emu.inject(&plan);
    let ledger = injected.ledger.clone();
    check_ledger_valid(&ledger);

    let socat = Socat::start(&dir.path().join("A"), &dir.path().join("B"));
    let addr = free_addr();
    let rec_dir = dir.path().join("rec");
    let cfg = config_file(dir.path());
    let mut daemon = start_serial_daemon(dir.path(), &cfg, &socat.b, addr, &rec_dir);

    // The emulator: 60 s of 1 kHz frames at 20x real time.
    let mut w = socat.writer();
    write_paced(&mut w, &injected.bytes, RATE_HZ * 16.0 * SPEEDUP).unwrap();
    let _ = wait_metric(
        addr,
        "sagnac_bytes_read_total",
        ledger.expected.bytes_read as f64,
        Duration::from_secs(30),
    );
    // 60 000 sample periods at 10 s per update: 6 updates.
    let text = wait_metric(
        addr,
        "sagnac_estimator_updates_total{gyro=\"gyro\"}",
        6.0,
        Duration::from_secs(30),
    );
    exact_counts(&text, &ledger);

    // Live QN against the model's truth: inside the estimator's own 95 % interval
    // (about +-3 % on 60 s of data), and within 3 % (the model's readout is a
    // sawtooth, not white noise, see config/paper_gyro.toml).
    let qn = metric(
        &text,
        "sagnac_qn_arcseconds{bound=\"estimate\",gyro=\"gyro\"}",
    )
    .unwrap_or_else(|| {
        panic!(
            "{}",
            text.lines()
                .filter(|l| l.contains("qn")
                    || l.contains("arw")
                    || l.contains("lost")
                    || l.contains("samples"))
                .collect::<Vec<_>>()
                .join("\n")
        )
    });
    let lo = metric(
        &text,
        "sagnac_qn_arcseconds{bound=\"lower95\",gyro=\"gyro\"}",
    )
    .unwrap();
    let hi = metric(
        &text,
        "sagnac_qn_arcseconds{bound=\"upper95\",gyro=\"gyro\"}",
    )
    .unwrap();
    eprintln!("live QN {qn} [{lo}, {hi}] arcsec (truth {TRUE_QN_ARCSEC})");
    assert!(lo <= qn && qn <= hi);
    assert!(
        lo <= TRUE_QN_ARCSEC && TRUE_QN_ARCSEC <= hi,
        "QN {qn} [{lo}, {hi}]"
    );
    assert!(
        (qn - TRUE_QN_ARCSEC).abs() <= 0.03 * TRUE_QN_ARCSEC,
        "QN {qn}"
    );
    // the temperature of the frames (25.00 deg C) reached the gauge
    assert_eq!(
        metric(&text, "sagnac_temperature_celsius{gyro=\"gyro\"}"),
        Some(25.0)
    );
    assert_eq!(
        metric(&text, "sagnac_device_connected{gyro=\"gyro\"}"),
        Some(1.0)
    );

    let (ok, out) = promtool(&text);
    assert!(
        ok,
        "promtool check metrics on the live scrape:\n{out}\n---\n{text}"
    );

    daemon.stop_ok(Duration::from_secs(10));
    drop(w);
    let log = daemon.log_text();
    assert!(log.contains("estimate"), "{log}");

    let v = check_recording(&only_recording(&rec_dir), &emu, &ledger, 60_000, true);
    // 6 interval updates + the final one after the flush
    assert_eq!(v["channels"]["/gyro/estimates"], 7);
    let q = &v["last_estimates"]["estimates"]["quantization_arcsec"];
    let qv = q["value"].as_f64().unwrap();
    assert!(
        (qv - TRUE_QN_ARCSEC).abs() <= 0.03 * TRUE_QN_ARCSEC,
        "final QN {q}"
    );
    assert!(q["ci95"][0].as_f64().unwrap() <= qv && qv <= q["ci95"][1].as_f64().unwrap());
    assert_eq!(v["last_estimates"]["samples"], 60_000);
}

#[test]
fn serial_device_vanishes_and_returns_angle_continuity_and_exact_loss() {
    let dir = tempfile::tempdir().unwrap();
    let emu = BenchEmulator::simulate(&paper_model(), 22, 40.0, 100, u32::MAX - 100).unwrap();
    let mut plan = faults(emu.frames.len(), 6);
    // The outage: the gyro keeps running while the device is away; 2000 frames
    // (2 s at 1 kHz, under the decoder's 4096-sample gap limit) never arrive.
    let (cut, back) = (20_000usize, 22_000usize);
    // Nothing at all is sent during the outage, and the last frames before it
    // are clean (so the daemon holds no partial frame when the device vanishes).
    for i in cut - 3..back {
        plan.faults.remove(&i);
    }
    for i in cut..back {
        plan.set_action(i, FrameAction::Drop);
    }
    let injected = emu.inject(&plan);
    let ledger = injected.ledger.clone();
    check_ledger_valid(&ledger);
    let split = emu.stream_offset_of(&plan, back);
    let (a_path, b_path) = (dir.path().join("A"), dir.path().join("B"));

    let socat = Socat::start(&a_path, &b_path);
    let addr = free_addr();
    let rec_dir = dir.path().join("rec");
    let cfg = config_file(dir.path());
    let mut daemon = start_serial_daemon(dir.path(), &cfg, &b_path, addr, &rec_dir);

    let mut w = socat.writer();
    write_paced(&mut w, &injected.bytes[..split], RATE_HZ * 16.0 * SPEEDUP).unwrap();
    wait_metric(
        addr,
        "sagnac_bytes_read_total",
        split as f64,
        Duration::from_secs(30),
    );
    drop(w);
    socat.stop(); // the device vanishes: the daemon reads EOF
    wait_metric(
        addr,
        "sagnac_device_connected{gyro=\"gyro\"}",
        0.0,
        Duration::from_secs(10),
    );

    let socat = Socat::start(&a_path, &b_path); // and comes back
    wait_metric(
        addr,
        "sagnac_device_reconnects_total{gyro=\"gyro\"}",
        1.0,
        Duration::from_secs(10),
    );
    let mut w = socat.writer();
    write_paced(&mut w, &injected.bytes[split..], RATE_HZ * 16.0 * SPEEDUP).unwrap();
    wait_metric(
        addr,
        "sagnac_bytes_read_total",
        ledger.expected.bytes_read as f64,
        Duration::from_secs(30),
    );
    // the decoder's counts continue across the reconnect: still exact
    let text = wait_metric(
        addr,
        "sagnac_estimator_updates_total{gyro=\"gyro\"}",
        4.0,
        Duration::from_secs(30),
    );
    exact_counts(&text, &ledger);
    assert!(ledger.expected.lost_samples >= 2000);

    daemon.stop_ok(Duration::from_secs(10));
    drop(w);
    let v = check_recording(&only_recording(&rec_dir), &emu, &ledger, 40_000, false);
    assert_eq!(v["events_by_kind"]["device_disconnected"], 1);
    assert_eq!(v["events_by_kind"]["device_reconnected"], 1);
}

/// Peak resident memory of a process, bytes (Linux `VmHWM`).
fn peak_rss_bytes(pid: u32) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The serial source cannot be paused: when the pipeline falls behind (here an
/// estimator update every 10 ms of data, which a serial source never skips,
/// with the gyro at 20x real time and a 64 KiB queue budget), batches that do not
/// fit in the budget are dropped, counted and folded into the next batch as a gap.
/// End to end over the pty: drops happen and are counted, the queue never holds
/// more than its budget, memory stays bounded, and the recording still holds every
/// pulse the gyro produced, with the dropped periods as gaps and
/// `backpressure_drop` events.
#[test]
fn serial_overload_drops_are_counted_recorded_and_lose_no_angle() {
    let dir = tempfile::tempdir().unwrap();
    let emu = BenchEmulator::simulate(&paper_model(), 23, 45.0, 40_000, u32::MAX - 300).unwrap();
    let injected = emu.inject(&FaultPlan::none());
    let bytes = &injected.bytes;
    let socat = Socat::start(&dir.path().join("A"), &dir.path().join("B"));
    let addr = free_addr();
    let rec_dir = dir.path().join("rec");
    let cfg = dir.path().join("overload.toml");
    std::fs::write(
        &cfg,
        "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.21\n\n[estimator]\ninterval_s = 0.01\n\n[source]\nqueue_budget_mib = 0.0625\n\n[record]\nbatch_samples = 100\n",
    )
    .unwrap();
    let mut daemon = start_serial_daemon(dir.path(), &cfg, &socat.b, addr, &rec_dir);
    let mut w = socat.writer();
    // 40 s of frames at 20x: once the statistics have their first samples
    // (after the wavelet bank's latency), far more estimator work than the
    // pipeline can do
    let burst = 40_000 * 16;
    write_paced(&mut w, &bytes[..burst], RATE_HZ * 16.0 * SPEEDUP).unwrap();
    let budget = 64.0 * 1024.0;
    let mut most_queued: f64 = 0.0;
    let text = wait_for("drops", Duration::from_secs(30), || {
        let t = scrape(addr)?;
        most_queued = most_queued.max(metric(&t, "sagnac_pipeline_queue_bytes")?);
        (metric(&t, "sagnac_dropped_samples_total{gyro=\"gyro\"}")? > 0.0).then_some(t)
    });
    assert_eq!(
        metric(&text, "sagnac_pipeline_queue_budget_bytes"),
        Some(budget)
    );
    assert!(
        most_queued <= budget,
        "queued {most_queued} bytes, budget {budget}"
    );
    eprintln!(
        "dropped so far: {:?}",
        metric(&text, "sagnac_dropped_samples_total{gyro=\"gyro\"}")
    );
    // then the rest at real time: the pipeline catches up, and later batches carry
    // the pulses of the dropped ones
    write_paced(&mut w, &bytes[burst..], RATE_HZ * 16.0).unwrap();
    let _ = wait_metric(
        addr,
        "sagnac_bytes_read_total",
        bytes.len() as f64,
        Duration::from_secs(30),
    );
    // the source sends its last batch right after decoding it
    std::thread::sleep(Duration::from_millis(500));
    let text = scrape(addr).unwrap();
    let queued = metric(&text, "sagnac_pipeline_queue_bytes").unwrap();
    assert!(queued <= budget, "queued {queued} bytes, budget {budget}");
    let dropped = metric(&text, "sagnac_dropped_samples_total{gyro=\"gyro\"}").unwrap();
    assert!(dropped > 0.0);
    assert_eq!(
        metric(&text, "sagnac_lost_samples_total{gyro=\"gyro\"}"),
        Some(0.0),
        "nothing lost on the wire"
    );
    let peak = peak_rss_bytes(daemon.child.id()).unwrap();
    assert!(peak < 128 << 20, "peak RSS {} MB", peak >> 20);

    daemon.stop_ok(Duration::from_secs(20));
    drop(w);

    let v = read_mcap_py_fast(&only_recording(&rec_dir));
    // every pulse is in /gyro/raw: the dropped batches' pulses ride on the next batch
    assert_eq!(
        v["raw_counts_total"].as_i64(),
        Some(emu.true_total_pulses()),
        "{v}\nmetrics:\n{}\nlog:\n{}",
        text.lines()
            .filter(|l| l.contains("dropped"))
            .collect::<Vec<_>>()
            .join("\n"),
        daemon
            .log_text()
            .lines()
            .filter(|l| !l.contains(" estimate"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    // the dropped samples are gaps of the raw channel (less the one that carries
    // them if the stream ended while samples were held), and events say why
    let lost = v["raw_lost_total"].as_f64().unwrap();
    assert!(
        lost == dropped || lost == dropped - 1.0,
        "lost {lost} dropped {dropped}: {v}"
    );
    assert!(
        v["events_by_kind"]["backpressure_drop"]
            .as_u64()
            .unwrap_or(0)
            >= 1,
        "{v}"
    );
    let periods = v["raw_samples"].as_u64().unwrap() + v["raw_lost_total"].as_u64().unwrap();
    assert_eq!(periods as usize, emu.frames.len() - 1);
    // clean/noise cover every period, dropped ones included (spread over the gap)
    assert_eq!(v["values_total"]["/gyro/clean"].as_u64(), Some(periods));
    assert_eq!(v["time_mismatches"], 0);
}

/// A burst within the queue budget loses nothing. 600 s of 1 kHz frames
/// written into the pty at full speed (the bytes arrive in a fraction of a
/// second, far faster than the pipeline runs its estimator) are all held in the
/// default 16 MiB queue: zero samples dropped, the queue gauge back to 0 once the
/// pipeline has caught up, and the final live estimates equal `sagnac analyze
/// --format frames` on the same bytes.
#[test]
fn a_600_s_burst_at_full_speed_drops_nothing_and_equals_analyze() {
    let dir = tempfile::tempdir().unwrap();
    let emu = BenchEmulator::simulate(&paper_model(), 24, 600.0, 1_000, u32::MAX - 500).unwrap();
    let bytes = emu.inject(&FaultPlan::none()).bytes;
    let capture = dir.path().join("burst.bin");
    std::fs::write(&capture, &bytes).unwrap();
    let socat = Socat::start(&dir.path().join("A"), &dir.path().join("B"));
    let addr = free_addr();
    let rec_dir = dir.path().join("rec");
    let cfg = dir.path().join("burst.toml");
    // An update per minute of data: ten updates to wait for, not 120.
    std::fs::write(
        &cfg,
        "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.21\n[estimator]\ninterval_s = 60.0\n",
    )
    .unwrap();
    let mut daemon = start_serial_daemon(dir.path(), &cfg, &socat.b, addr, &rec_dir);

    let mut w = socat.writer();
    let t = std::time::Instant::now();
    std::io::Write::write_all(&mut w, &bytes).unwrap();
    let text = wait_metric(
        addr,
        "sagnac_bytes_read_total",
        bytes.len() as f64,
        Duration::from_secs(30),
    );
    eprintln!(
        "{} bytes read in {:?}; queued then: {:?} bytes",
        bytes.len(),
        t.elapsed(),
        metric(&text, "sagnac_pipeline_queue_bytes")
    );
    assert_eq!(
        metric(&text, "sagnac_pipeline_queue_budget_bytes"),
        Some(16.0 * 1024.0 * 1024.0)
    );
    wait_metric(
        addr,
        "sagnac_estimator_updates_total{gyro=\"gyro\"}",
        10.0,
        Duration::from_secs(120),
    );
    let text = wait_metric(
        addr,
        "sagnac_pipeline_queue_bytes",
        0.0,
        Duration::from_secs(10),
    );
    assert_eq!(
        metric(&text, "sagnac_dropped_samples_total{gyro=\"gyro\"}"),
        Some(0.0)
    );
    assert_eq!(
        metric(&text, "sagnac_lost_samples_total{gyro=\"gyro\"}"),
        Some(0.0)
    );
    assert_eq!(
        metric(&text, "sagnac_samples_total{gyro=\"gyro\"}"),
        Some(600_000.0)
    );

    daemon.stop_ok(Duration::from_secs(20));
    drop(w);

    let (live, raw) = final_and_raw(&only_recording(&rec_dir));
    assert_eq!(live.samples, 600_000);
    assert_eq!(
        raw.iter()
            .map(|b| b.counts.iter().sum::<i64>())
            .sum::<i64>(),
        emu.true_total_pulses()
    );
    assert!(raw.iter().all(|b| b.gaps.is_empty()), "no gap in /gyro/raw");
    let a = analyze_json("frames", &capture, &dir.path().join("analyze.json"));
    assert_eq!(a["samples"], 600_000);
    // Relative 1e-9: analyze pushes the same samples in other block sizes.
    let worst = close_estimates(&live, &a, "live daemon vs analyze --format frames");
    // In fact equal to a few ulps (3.7e-16 when written).
    eprintln!("largest relative difference, live vs analyze: {worst:e}");
    assert!(worst <= 1e-12, "live vs analyze: relative {worst:e}");
}
