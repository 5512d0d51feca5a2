//! `sagnac run` as a user meets it: the default run (no source flag: the
//! built-in simulated paper gyro) serving promtool-clean metrics, draining on
//! SIGTERM and leaving a complete recording; a run that stops by itself after
//! `--duration-s` with JSON logs; and bad values exiting 2 with a message that
//! names the config key and the flag.

use std::process::Command;
use std::time::{Duration, Instant};

use crate::support::daemon::*;
use crate::support::{PAPER_GYRO, free_addr};

fn run(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .arg("run")
        .args(args)
        .env_remove("RUST_LOG")
        .output()
        .unwrap()
}

#[test]
fn bad_values_exit_2_naming_the_key_and_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec");
    let rec = rec.to_str().unwrap();
    let model = dir.path().join("m.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 1.21\n",
    )
    .unwrap();
    let bad_cfg = dir.path().join("bad.toml");
    std::fs::write(&bad_cfg, "[estimator]\ninterval = 5\n").unwrap();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["--sample-rate-hz", "-1"],
            vec!["gyro.sample_rate_hz", "--sample-rate-hz", "-1"],
        ),
        (
            vec!["--pulse-arcsec", "0"],
            vec!["gyro.pulse_arcsec", "--pulse-arcsec"],
        ),
        (
            vec!["--wavelet", "morlet"],
            vec!["dsp.wavelet", "--wavelet", "morlet"],
        ),
        (
            vec!["--metrics-addr", "localhost"],
            vec!["metrics.addr", "--metrics-addr"],
        ),
        (
            vec!["--duration-s", "-3"],
            vec!["run.duration_s", "--duration-s"],
        ),
        (
            vec!["--replay", "x.bin", "--speed", "-2"],
            vec!["source.speed", "--speed"],
        ),
        (
            vec!["--serial", "/dev/null", "--queue-budget-mib", "0"],
            vec!["source.queue_budget_mib", "--queue-budget-mib", "got 0"],
        ),
        (
            vec!["--serial", "/dev/null", "--queue-budget-mib", "1e6"],
            vec!["source.queue_budget_mib", "--queue-budget-mib"],
        ),
        (
            vec!["--replay", "/nonexistent/capture.bin"],
            vec!["/nonexistent/capture.bin"],
        ),
        (
            vec![
                "--serial",
                "/nonexistent/ttyUSB9",
                "--sample-rate-hz",
                "1000",
                "--pulse-arcsec",
                "1.21",
            ],
            vec!["cannot open serial port /nonexistent/ttyUSB9"],
        ),
        // an explicit rate that contradicts the simulated model
        (
            vec![
                "--simulate",
                model.to_str().unwrap(),
                "--sample-rate-hz",
                "1000",
            ],
            vec!["gyro.sample_rate_hz", "sample_rate_hz"],
        ),
        (
            vec!["--config", bad_cfg.to_str().unwrap()],
            vec!["bad.toml", "interval"],
        ),
        // clap: sources are exclusive, --speed does not apply to a serial port
        (
            vec!["--serial", "/dev/null", "--replay", "x"],
            vec!["cannot be used with"],
        ),
        (
            vec!["--serial", "/dev/null", "--speed", "2"],
            vec!["cannot be used with"],
        ),
        (vec!["--baud", "9600"], vec!["--serial"]),
    ];
    for (args, needles) in cases {
        let mut a = args.clone();
        a.extend_from_slice(&["--record-dir", rec, "--metrics-addr", ""]);
        // keep the metrics flag given last from overriding a bad one under test
        if args.contains(&"--metrics-addr") {
            a.truncate(args.len() + 2);
        }
        let r = run(&a);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: expected {n:?} in:\n{err}");
        }
    }
    assert!(
        !rec.is_empty() && !std::path::Path::new(rec).exists(),
        "nothing recorded on errors"
    );

    // A capture without a single valid frame is an error too (found while reading).
    let garbage = dir.path().join("garbage.bin");
    std::fs::write(
        &garbage,
        (0..5000u32)
            .map(|i| (i * 7 % 251) as u8)
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let r = run(&[
        "--replay",
        garbage.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--record-dir",
        rec,
        "--metrics-addr",
        "",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("garbage.bin: no samples in this capture (5000 bytes read)"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");

    // A bad value read from the config file is blamed on the file, not on a flag
    // that was not given; the same key given as a flag is blamed on the flag.
    let bad_rate = dir.path().join("rate.toml");
    std::fs::write(&bad_rate, "[gyro]\nrate_hz = -3.0\n").unwrap();
    let cfg = bad_rate.to_str().unwrap();
    let r = run(&["--config", cfg, "--record-dir", rec, "--metrics-addr", ""]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad value in")
            && err.contains("rate.toml")
            && err.contains("gyro.sample_rate_hz"),
        "{err}"
    );
    assert!(!err.contains("--sample-rate-hz"), "{err}");
    let r = run(&[
        "--config",
        cfg,
        "--sample-rate-hz",
        "-4",
        "--record-dir",
        rec,
        "--metrics-addr",
        "",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad value for --sample-rate-hz") && err.contains("got -4"),
        "{err}"
    );
}

/// Serial input and raw frame captures carry neither the sample rate nor the
/// pulse weight: without a flag or a config key giving them, `sagnac run`
/// exits 2 naming both (never a silent 1000 Hz / 1.21"). A key present in the
/// config file counts as given, even at the default value.
#[test]
fn raw_sources_need_the_rate_and_pulse_weight_given() {
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("cap.bin");
    let sim = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(PAPER_GYRO)
        .args([
            "--duration-s",
            "2",
            "--seed",
            "3",
            "--format",
            "frames",
            "--out",
        ])
        .arg(&bin)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let b = bin.to_str().unwrap();
    let both = [
        "--sample-rate-hz",
        "--pulse-arcsec",
        "gyro.sample_rate_hz",
        "gyro.pulse_arcsec",
    ];
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["--serial", "/nonexistent/ttyUSB9"],
            [&["serial input /nonexistent/ttyUSB9"][..], &both].concat(),
        ),
        (
            vec!["--replay", b],
            [&["raw frame capture", "cap.bin"][..], &both].concat(),
        ),
        (
            vec!["--replay", b, "--sample-rate-hz", "1000"],
            vec!["pulse weight", "--pulse-arcsec", "gyro.pulse_arcsec"],
        ),
        (
            vec!["--replay", b, "--pulse-arcsec", "1.21"],
            vec!["sample rate", "--sample-rate-hz", "gyro.sample_rate_hz"],
        ),
    ];
    for (args, needles) in cases {
        let mut a = args.clone();
        a.extend_from_slice(&["--record-dir", "", "--metrics-addr", ""]);
        let r = run(&a);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: expected {n:?} in:\n{err}");
        }
    }
    // given in the config file (by presence, at the default values): runs;
    // `rate_hz`, the key's old name, still loads, with a warning naming the new one
    let cfg = dir.path().join("gyro.toml");
    std::fs::write(&cfg, "[gyro]\nrate_hz = 1000.0\npulse_arcsec = 1.21\n").unwrap();
    let r = run(&[
        "--config",
        cfg.to_str().unwrap(),
        "--replay",
        b,
        "--record-dir",
        "",
        "--metrics-addr",
        "",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("sample_rate_hz=1000") && err.contains("pulse_arcsec=1.21"),
        "{err}"
    );
    assert!(
        err.contains("`gyro.rate_hz` is now `gyro.sample_rate_hz`"),
        "{err}"
    );
    // one key in the file, the other as a flag
    std::fs::write(&cfg, "[gyro]\nrate_hz = 1000.0\n").unwrap();
    let r = run(&[
        "--config",
        cfg.to_str().unwrap(),
        "--replay",
        b,
        "--pulse-arcsec",
        "1.21",
        "--record-dir",
        "",
        "--metrics-addr",
        "",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn short_and_cut_captures_end_cleanly() {
    // Captures too short for any statistic, and one cut inside a frame: a clear
    // message or a clean run, never a panic (here and in `sagnac analyze`).
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.bin");
    let sim = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(PAPER_GYRO)
        .args([
            "--duration-s",
            "2",
            "--seed",
            "3",
            "--format",
            "frames",
            "--out",
        ])
        .arg(&full)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let bytes = std::fs::read(&full).unwrap();
    for (frames, extra, rc) in [
        (0usize, 0usize, 2),
        (1, 0, 2),
        (2, 0, 0),
        (3, 0, 0),
        (100, 7, 0),
    ] {
        let name = format!("f{frames}_{extra}.bin");
        let path = dir.path().join(&name);
        std::fs::write(&path, &bytes[..16 * frames + extra]).unwrap();
        let p = path.to_str().unwrap();
        let r = run(&[
            "--replay",
            p,
            "--sample-rate-hz",
            "1000",
            "--pulse-arcsec",
            "1.21",
            "--record-dir",
            "",
            "--metrics-addr",
            "",
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(rc), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
        if rc == 2 {
            assert!(
                err.contains(&format!("{name}: no samples in this capture")),
                "{name}: {err}"
            );
        } else {
            assert!(
                err.contains(&format!("samples={}", frames - 1)),
                "{name}: {err}"
            );
        }
        if extra > 0 {
            let want = format!("{extra} bytes from byte offset {}", 16 * frames);
            assert!(err.contains("WARN") && err.contains(&want), "{name}: {err}");
        }
        if frames >= 2 {
            let a = Command::new(env!("CARGO_BIN_EXE_sagnac"))
                .args([
                    "analyze",
                    "--format",
                    "frames",
                    "--sample-rate-hz",
                    "1000",
                    "--pulse-arcsec",
                    "1.21",
                    "--input",
                    p,
                ])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&a.stderr);
            assert!(
                a.status.success() && !err.contains("panicked"),
                "analyze {name}: {err}"
            );
        }
    }
}

/// Whether process `pid` has a handler for SIGTERM (Linux: the `SigCgt` mask in
/// `/proc/PID/status`, bit 14).
fn catches_sigterm(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("SigCgt:"))
                .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        })
        .is_some_and(|mask| mask & (1 << 14) != 0)
}

#[test]
fn sigterm_during_startup_is_a_clean_shutdown() {
    // The signal handlers are installed before the daemon is built (tens of
    // milliseconds): a SIGTERM from then on, even before the source starts,
    // drains an empty pipeline and exits 0 with a complete (possibly empty)
    // recording. (Before the handler exists, during exec, nothing can catch it.)
    let dir = tempfile::tempdir().unwrap();
    for delay_ms in [0u64, 5, 20] {
        let rec = dir.path().join(format!("rec{delay_ms}"));
        let log = dir.path().join(format!("log{delay_ms}"));
        let mut d = DaemonProc::start(
            &[
                "run",
                "--record-dir",
                rec.to_str().unwrap(),
                "--metrics-addr",
                "",
            ],
            &log,
        );
        let pid = d.child.id();
        wait_for("the SIGTERM handler", Duration::from_secs(10), || {
            catches_sigterm(pid).then_some(())
        });
        std::thread::sleep(Duration::from_millis(delay_ms));
        d.sigterm();
        let status = d.wait(Duration::from_secs(10));
        assert_eq!(
            status.code(),
            Some(0),
            "SIGTERM {delay_ms} ms after the handler: {}",
            d.log_text()
        );
        if rec.exists() {
            let r = sagnac::recording::reader::read_recording(&only_recording(&rec));
            assert!(r.is_ok(), "after {delay_ms} ms: {r:?}");
        }
    }
}

#[test]
fn default_run_is_the_simulated_bench_promtool_clean_and_drains_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let rec_dir = dir.path().join("rec");
    let addr = free_addr();
    let cfg = dir.path().join("c.toml");
    std::fs::write(&cfg, "[estimator]\ninterval_s = 2.0\n").unwrap();
    // No source flag: the built-in paper gyro, here at 40x real time.
    let mut d = DaemonProc::start(
        &[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--speed",
            "40",
            "--metrics-addr",
            &addr.to_string(),
            "--record-dir",
            rec_dir.to_str().unwrap(),
        ],
        &dir.path().join("log"),
    );
    // The clean channel lags the input by the wavelet bank's latency (about 31 s
    // of samples with the automatic depth at 1 kHz): wait for its Allan curve.
    let clean = "sagnac_allan_deviation_degrees_per_hour{channel=\"clean\",gyro=\"gyro\",tau_seconds=\"0.001\"}";
    let text = wait_for("the clean Allan curve", Duration::from_secs(40), || {
        let t = scrape(addr)?;
        (metric(&t, "sagnac_estimator_updates_total{gyro=\"gyro\"}")? >= 2.0
            && metric(&t, clean).is_some())
        .then_some(t)
    });
    let (ok, out) = promtool(&text);
    assert!(ok, "promtool check metrics:\n{out}\n---\n{text}");
    // the simulated pulses went through the frame encoder and decoder
    let frames = metric(&text, "sagnac_frames_decoded_total{gyro=\"gyro\"}").unwrap();
    let samples = metric(&text, "sagnac_samples_total{gyro=\"gyro\"}").unwrap();
    assert!(
        samples >= 4000.0 && frames >= samples,
        "{frames} frames, {samples} samples"
    );
    assert_eq!(
        metric(
            &text,
            "sagnac_frame_errors_total{gyro=\"gyro\",kind=\"crc\"}"
        ),
        Some(0.0)
    );
    for series in [
        "sagnac_qn_arcseconds{bound=\"estimate\",gyro=\"gyro\"}",
        // ARW is not resolved in a few seconds of data: its 95 % upper bound is exported
        "sagnac_arw_degrees_per_root_hour{bound=\"upper95\",gyro=\"gyro\"}",
        "sagnac_allan_deviation_degrees_per_hour{channel=\"raw\",gyro=\"gyro\",tau_seconds=\"0.001\"}",
        "sagnac_allan_deviation_degrees_per_hour{channel=\"clean\",gyro=\"gyro\",tau_seconds=\"0.001\"}",
        "sagnac_processing_lag_seconds{gyro=\"gyro\"}",
        "sagnac_estimate_latency_seconds_sum{gyro=\"gyro\"}",
        "sagnac_estimate_latency_seconds_bucket{gyro=\"gyro\",le=\"+Inf\"}",
        "sagnac_recording_bytes",
    ] {
        let v = metric(&text, series).unwrap_or_else(|| panic!("{series} missing:\n{text}"));
        assert!(v.is_finite() && v >= 0.0, "{series} = {v}");
    }
    assert_eq!(
        metric(&text, "sagnac_temperature_celsius{gyro=\"gyro\"}"),
        Some(25.0)
    );
    // no serial device: no device series (a dashboard would read 0 as "disconnected")
    assert!(!text.contains("sagnac_device_"), "{text}");
    assert_eq!(
        metric(
            &text,
            "sagnac_gyro_info{gyro=\"gyro\",model=\"\",serial_number=\"\"}"
        ),
        Some(1.0)
    );

    let t = Instant::now();
    d.sigterm();
    let status = d.wait(Duration::from_secs(10));
    assert!(status.success(), "{status:?}\n{}", d.log_text());
    eprintln!("SIGTERM -> exit in {:?}", t.elapsed());
    let log = d.log_text();
    assert!(
        log.contains("final_update=true"),
        "final estimate logged:\n{log}"
    );
    let v = read_mcap_py(&only_recording(&rec_dir));
    assert_eq!(v["messages"], v["statistics_messages"], "complete file");
    let raw = v["raw_samples"].as_u64().unwrap();
    assert!(raw >= samples as u64);
    // wavelet bank flushed: every raw sample has its clean and noise value
    assert_eq!(v["values_total"]["/gyro/clean"].as_u64(), Some(raw));
    assert_eq!(v["values_total"]["/gyro/noise"].as_u64(), Some(raw));
    assert!(
        v["last_estimates"]["estimates"]["quantization_arcsec"]["value"]
            .as_f64()
            .is_some()
    );
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
}

#[test]
fn duration_limit_ends_the_run_and_logs_are_json() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    std::fs::write(
        &cfg,
        "[log]\nformat = \"json\"\n\n[estimator]\ninterval_s = 1.0\n",
    )
    .unwrap();
    let r = run(&[
        "--config",
        cfg.to_str().unwrap(),
        "--simulate",
        PAPER_GYRO,
        "--speed",
        "0",
        "--duration-s",
        "3",
        "--metrics-addr",
        "",
        "--record-dir",
        dir.path().join("rec").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    let lines: Vec<serde_json::Value> = err
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect();
    let estimates: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|l| l["fields"]["message"] == "estimate")
        .collect();
    let last = estimates.last().expect("estimate lines");
    assert_eq!(last["level"], "INFO");
    assert_eq!(last["fields"]["samples"], 3000);
    assert_eq!(last["fields"]["final_update"], true);
    for f in [
        "quantization_arcsec",
        "arw_dpsh",
        "bias_instability_dph",
        "lost",
    ] {
        assert!(!last["fields"][f].is_null(), "{f} in {last}");
    }
    // the coefficients in fixed notation: "0.351 [0.341, 0.360]" or "< 0.00200"
    for f in ["quantization_arcsec", "arw_dpsh", "bias_instability_dph"] {
        let text = last["fields"][f]
            .as_str()
            .unwrap_or_else(|| panic!("{f} in {last}"));
        assert!(
            !text.is_empty()
                && text
                    .chars()
                    .all(|c| c.is_ascii_digit() || " .,[]<-".contains(c)),
            "{f} = {text:?}: not fixed notation"
        );
    }
    let v = read_mcap_py(&only_recording(&dir.path().join("rec")));
    assert_eq!(v["raw_samples"], 3000);
}

/// A replayed MCAP recording says its rate and pulse weight in its
/// metadata record; the daemon uses them, a flag that contradicts them exits 2
/// naming the flag, the file and both values, and the daemon's own recording
/// carries the metadata record too (rate, pulse weight, its config).
#[test]
fn a_replayed_recording_supplies_its_rate_and_pulse_weight() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.toml");
    std::fs::write(&model, "[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 0.9\ninput_rate_dph = 12.3\n[noise]\narw_dpsh = 0.002\n").unwrap();
    let mcap = dir.path().join("sim.mcap");
    let sim = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(&model)
        .args([
            "--duration-s",
            "20",
            "--seed",
            "2",
            "--format",
            "mcap",
            "--out",
        ])
        .arg(&mcap)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let m = mcap.to_str().unwrap();
    for (flag, value, recorded) in [
        ("--sample-rate-hz", "1000", "500"),
        ("--pulse-arcsec", "1.21", "0.9"),
    ] {
        let r = run(&[
            "--replay",
            m,
            flag,
            value,
            "--record-dir",
            "",
            "--metrics-addr",
            "",
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{flag}: {err}");
        assert!(
            err.contains(&format!("bad value for {flag}")),
            "{flag}: {err}"
        );
        assert!(err.contains(&format!("{value} contradicts {m}: the recording says {recorded} in its sagnac metadata record")), "{flag}: {err}");
    }
    // agreeing flags, and none: the recording's values
    let rec = dir.path().join("rec");
    let r = run(&[
        "--replay",
        m,
        "--sample-rate-hz",
        "500",
        "--record-dir",
        rec.to_str().unwrap(),
        "--metrics-addr",
        "",
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("sample_rate_hz=500") && err.contains("pulse_arcsec=0.9"),
        "{err}"
    );
    let made: Vec<_> = std::fs::read_dir(&rec)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(made.len(), 1, "{made:?}");
    let meta = sagnac::recording::reader::read_metadata(&made[0])
        .unwrap()
        .expect("the daemon writes a metadata record");
    assert_eq!((meta.sample_rate_hz, meta.pulse_arcsec), (500.0, Some(0.9)));
    let config = meta.config.expect("the daemon's config");
    assert!(
        config.contains("sample_rate_hz = 500") && config.contains("replay_path"),
        "{config}"
    );
    assert_eq!(meta.model, None);
}

/// `/gyro/summary`: 10 Hz scalars with Foxglove's `{sec, nsec}` time, read by
/// the Python `mcap` reader: 3 s at 1 kHz give 30 windows of 100 samples whose
/// means equal the raw and clean channels averaged independently; every JSON
/// output of the recording says its units and input settings (the metadata
/// record: rate, pulse weight, version; the schemas: the unit of every field).
#[test]
fn summary_channel_is_ten_hertz_and_equals_the_averaged_raw_channel() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    std::fs::write(&cfg, "[estimator]\ninterval_s = 1.0\n").unwrap();
    let rec = dir.path().join("rec");
    let r = run(&[
        "--config",
        cfg.to_str().unwrap(),
        "--speed",
        "0",
        "--duration-s",
        "3",
        "--metrics-addr",
        "",
        "--record-dir",
        rec.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let v = read_mcap_py_with(&only_recording(&rec), &["--summary"]);
    assert_eq!(v["channels"]["/gyro/summary"], 30);
    assert_eq!(check_summary(&v), 30);
    let windows = v["summary_recorded"].as_array().unwrap();
    assert!(
        windows.iter().all(|w| w[1] == 100 && w[2] == 0),
        "full windows, no loss"
    );
    // 10 Hz: consecutive timestamps 0.1 s apart
    for pair in windows.windows(2) {
        assert_eq!(
            pair[1][0].as_u64().unwrap() - pair[0][0].as_u64().unwrap(),
            100_000_000
        );
    }
    assert_eq!(v["schema_invalid"], serde_json::json!([]));
    assert_eq!(
        v["time_mismatches"], 0,
        "log time = the payload's {{sec, nsec}}"
    );
    let meta = &v["metadata"]["sagnac"];
    assert_eq!(meta["sample_rate_hz"], "1000");
    assert_eq!(meta["pulse_arcsec"], "1.21");
    assert_eq!(meta["sagnac_version"], env!("CARGO_PKG_VERSION"));
}
