//! `sagnac analyze`: the CLI contract (JSON shape, inputs, errors).

use std::path::Path;
use std::process::Command;

use serde_json::Value;

use crate::support::{PAPER_GYRO, sagnac, simulated_csv};

fn check_coefficient(c: &Value, name: &str) {
    let obj = c
        .as_object()
        .unwrap_or_else(|| panic!("{name} is not an object"));
    assert!(obj.contains_key("value"), "{name}: no value key");
    if c["value"].is_null() {
        assert!(
            c["upper95"].as_f64().unwrap() >= 0.0,
            "{name}: null value needs upper95"
        );
        assert!(!obj.contains_key("ci95"), "{name}");
    } else {
        let v = c["value"].as_f64().unwrap();
        let ci = c["ci95"].as_array().unwrap();
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        assert!(lo <= v && v <= hi, "{name}: {lo} <= {v} <= {hi}");
    }
}

#[test]
fn json_contract_and_values_on_a_simulated_run() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path(), "600");
    let out = dir.path().join("a.json");
    let o = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--json",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    for k in [
        "quantization_arcsec",
        "arw_dpsh",
        "bias_instability_dph",
        "rrw_dphsh",
        "rate_ramp_dphh",
    ] {
        check_coefficient(&v["estimates"][k], k);
    }
    // the JSON says its units and input settings
    assert_eq!(v["sagnac_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(
        v["input"],
        serde_json::json!({"path": csv.to_str().unwrap(), "format": "csv", "sample_rate_hz": 1000.0, "pulse_arcsec": 1.21,
                           "column": "counts", "unit": "counts", "origin": "given on the command line"})
    );
    for (key, unit, _) in sagnac::units::COEFFICIENTS {
        assert_eq!(v["units"][format!("estimates.{key}")], unit, "{key}");
    }
    assert_eq!(v["units"]["allan.*.dev, ci_lo, ci_hi"], "deg/h");
    assert_eq!(v["units"]["duration_s"], "s");
    for ch in ["raw", "clean", "noise"] {
        let pts = v["allan"][ch].as_array().unwrap();
        assert!(pts.len() > 8, "{ch}: {} points", pts.len());
        for key in ["tau_s", "m", "n", "dev", "ci_lo", "ci_hi", "edf", "alpha"] {
            assert!(pts[0].get(key).is_some(), "{ch}: missing {key}");
        }
    }
    // truth: Q 0.35", N 0.0015 deg/sqrt(h); 10 minutes is enough for a few %
    let q = v["estimates"]["quantization_arcsec"]["value"]
        .as_f64()
        .unwrap();
    let n = v["estimates"]["arw_dpsh"]["value"].as_f64().unwrap();
    assert!((q / 0.35 - 1.0).abs() < 0.01, "Q {q}");
    assert!((n / 0.0015 - 1.0).abs() < 0.1, "N {n}");
    // the readable table
    let o = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("angle random walk") && text.contains("clean ADEV"),
        "{text}"
    );
}

#[test]
fn rate_columns_in_every_unit_give_the_same_estimates() {
    // the same rate written in deg/h, deg/s and rad/s
    let dir = tempfile::tempdir().unwrap();
    let mut s = 0x2545F4914F6CDD1D_u64;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut text = String::from("dph,dps,rad_s,temp_c\n");
    for _ in 0..200_000 {
        let r = 30.0 + 400.0 * u();
        text.push_str(&format!(
            "{r},{},{},25.0\n",
            r / 3600.0,
            (r / 3600.0).to_radians()
        ));
    }
    let csv = dir.path().join("rates.csv");
    std::fs::write(&csv, text).unwrap();
    let mut n = Vec::new();
    for (col, unit) in [("dph", "dph"), ("dps", "dps"), ("rad_s", "rad_s")] {
        let o = sagnac(&[
            "analyze",
            "--input",
            csv.to_str().unwrap(),
            "--sample-rate-hz",
            "100",
            "--column",
            col,
            "--unit",
            unit,
            "--json",
            "-",
        ]);
        assert!(
            o.status.success(),
            "{unit}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let v: Value = serde_json::from_slice(&o.stdout).unwrap();
        n.push(v["estimates"]["arw_dpsh"]["value"].as_f64().unwrap());
    }
    // white rate noise of sd 400/sqrt(12) deg/h at 100 Hz: N = sd sqrt(tau0) / 60
    let truth = 400.0 / 12f64.sqrt() * 0.1 / 60.0;
    for x in &n {
        assert!((x / n[0] - 1.0).abs() < 1e-6, "{n:?}");
        assert!((x / truth - 1.0).abs() < 0.05, "N {x} vs {truth}");
    }
}

#[test]
fn bad_inputs_exit_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path(), "5");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "--column",
                "rate",
                "--sample-rate-hz",
                "1000",
                "--pulse-arcsec",
                "1.21",
            ],
            "no CSV column named \"rate\"",
        ),
        (
            // the old flag name is an alias of --sample-rate-hz
            vec!["--rate-hz", "-5", "--pulse-arcsec", "1.21"],
            "--sample-rate-hz must be a positive number",
        ),
        (
            vec!["--sample-rate-hz", "1000", "--pulse-arcsec", "0"],
            "--pulse-arcsec",
        ),
    ];
    for (extra, needle) in cases {
        let mut a = vec!["analyze", "--input", csv.to_str().unwrap(), "--json", "-"];
        a.extend(extra);
        let o = sagnac(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
    }
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "counts\n1\n2\nthree\n4\n").unwrap();
    let o = sagnac(&[
        "analyze",
        "--input",
        bad.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--json",
        "-",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.csv") && err.contains('4'),
        "must name the file and line: {err}"
    );
}

#[test]
fn json_to_a_failing_stdout_is_an_error_not_a_panic() {
    // `--json -` into a full device (and the diagnose summary likewise): exit 2
    // with a message naming standard output, never a panic.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("c.csv");
    let bin = env!("CARGO_BIN_EXE_sagnac");
    let model = PAPER_GYRO;
    let sim = std::process::Command::new(bin)
        .args([
            "simulate",
            "--model",
            model,
            "--duration-s",
            "3",
            "--seed",
            "2",
            "--format",
            "csv",
            "--out",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    for args in [
        vec![
            "analyze",
            "--input",
            csv.to_str().unwrap(),
            "--sample-rate-hz",
            "1000",
            "--pulse-arcsec",
            "1.21",
            "--json",
            "-",
        ],
        vec![
            "allan",
            "--input",
            csv.to_str().unwrap(),
            "--format",
            "csv",
            "--data",
            "freq",
            "--tau0",
            "0.001",
            "--column",
            "counts",
            "--json",
            "-",
        ],
    ] {
        let r = std::process::Command::new(bin)
            .args(&args)
            .stdout(full())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("writing to standard output") && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn damaged_inputs_are_reported_not_silently_dropped() {
    use sagnac::recording::messages::{Gap, RawBatch, SinkMessage};
    use sagnac::recording::writer::{Recorder, RecorderConfig};
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_sagnac");
    let analyze = |args: &[&str]| {
        Command::new(bin)
            .arg("analyze")
            .args(args)
            .output()
            .unwrap()
    };
    let cfg = RecorderConfig {
        record_dir: dir.path().to_path_buf(),
        flush_interval_s: 600.0,
        queue_capacity: 64,
        chunk_size: 64 * 1024,
        zstd_level: 0,
    };
    let batch = |k: u64, gaps: Vec<Gap>| {
        SinkMessage::Raw(RawBatch {
            t0_ns: k * 1_000_000_000,
            dt_ns: 1_000_000,
            seq0: k * 1000,
            counts: (0..1000).map(|i| (i * 7 % 5) as i64 - 2).collect(),
            gaps,
            temp_c: Some(25.0),
            status: 7,
        })
    };
    // 1. A recording cut in its second half: analysed up to the break, with a warning.
    let rec = Recorder::start(&cfg).unwrap();
    for k in 0..400 {
        rec.send(batch(k, vec![])).unwrap();
    }
    let full = rec.finish().unwrap().path;
    let bytes = std::fs::read(&full).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    // (recorded without a metadata record: the rate from /gyro/raw, the pulse weight by flag)
    let r = analyze(&[
        "--format",
        "mcap",
        "--pulse-arcsec",
        "1.21",
        "--input",
        cut.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("warning: ") && err.contains("cut.mcap: unreadable from byte"),
        "{err}"
    );
    // 2. A gap no running gyro could leave: an error, not a huge allocation.
    std::fs::remove_file(&full).unwrap();
    let rec = Recorder::start(&cfg).unwrap();
    rec.send(batch(
        0,
        vec![Gap {
            index: 500,
            lost: 1 << 40,
        }],
    ))
    .unwrap();
    let huge = rec.finish().unwrap().path;
    let r = analyze(&[
        "--format",
        "mcap",
        "--pulse-arcsec",
        "1.21",
        "--input",
        huge.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("gap of 1099511627776 lost samples") && !err.contains("panicked"),
        "{err}"
    );
    // ... and the same error from diagnose, which reads the recording itself
    let model = PAPER_GYRO;
    let r = Command::new(bin)
        .args([
            "diagnose", "--model", model, "--format", "mcap", "--json", "-", "--input",
        ])
        .arg(&huge)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("gap of 1099511627776 lost samples") && !err.contains("panicked"),
        "{err}"
    );
    // 3. A frame capture with lost frames: the decoder's counts on stderr.
    let cap = dir.path().join("cap.bin");
    let sim = Command::new(bin)
        .args(["simulate", "--model", PAPER_GYRO])
        .args([
            "--duration-s",
            "2",
            "--seed",
            "4",
            "--format",
            "frames",
            "--out",
        ])
        .arg(&cap)
        .output()
        .unwrap();
    assert!(sim.status.success());
    let mut frames = std::fs::read(&cap).unwrap();
    frames.drain(16 * 100..16 * 103); // three frames lost
    std::fs::write(&cap, &frames).unwrap();
    let r = analyze(&[
        "--format",
        "frames",
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--input",
        cap.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("3 samples lost in 1 gaps"), "{err}");
}

/// A stuck counter (every increment the same) has no noise: nothing may be
/// reported as found (a fit would "find" round-off-sized terms), the bounds are
/// 0, and a warning says why.
#[test]
fn a_constant_recording_finds_nothing_and_says_why() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("stuck.csv");
    let mut text = String::from("counts\n");
    for _ in 0..50_000 {
        text.push_str("3\n");
    }
    std::fs::write(&csv, text).unwrap();
    let out = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--json",
        "-",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("stuck.csv") && err.contains("stuck counter"),
        "{err}"
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    for name in [
        "quantization_arcsec",
        "arw_dpsh",
        "bias_instability_dph",
        "rrw_dphsh",
        "rate_ramp_dphh",
    ] {
        let c = &v["estimates"][name];
        assert!(c["value"].is_null(), "{name}: {c}");
        assert_eq!(c["upper95"].as_f64(), Some(0.0), "{name}: {c}");
    }
}

#[test]
fn column_is_refused_for_frame_and_mcap_input() {
    let d = tempfile::tempdir().unwrap();
    let bin = d.path().join("cap.bin");
    std::fs::write(&bin, [0u8; 32]).unwrap();
    for format in ["frames", "mcap"] {
        let out = sagnac(&[
            "analyze",
            "--input",
            bin.to_str().unwrap(),
            "--format",
            format,
            "--column",
            "counts",
        ]);
        assert_eq!(out.status.code(), Some(2), "{format}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--column does not apply") && err.contains("pulse counts"),
            "{format}: {err}"
        );
    }
}

/// A CSV file and a frame capture carry no
/// sample rate and no pulse weight, so the flags are required (exit 2 naming
/// the flag and the file), where 1000 Hz and 1.21" used to be assumed.
#[test]
fn csv_and_frames_need_the_rate_and_pulse_flags() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path(), "5");
    let c = csv.to_str().unwrap();
    let cap = dir.path().join("cap.bin");
    let model = dir.path().join("m.toml");
    let o = sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        "2",
        "--seed",
        "1",
        "--format",
        "frames",
        "--out",
        cap.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let b = cap.to_str().unwrap();
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--input", c, "--pulse-arcsec", "1.21"],
            format!("--sample-rate-hz is required: {c} carries no sample rate"),
        ),
        (
            vec!["--input", c, "--sample-rate-hz", "1000"],
            format!("--pulse-arcsec is required: {c} carries no pulse weight"),
        ),
        (
            vec!["--input", c],
            "--sample-rate-hz is required".to_string(),
        ),
        (
            vec!["--input", b, "--pulse-arcsec", "1.21"],
            format!("--sample-rate-hz is required: {b} carries no sample rate"),
        ),
        (
            vec!["--input", b, "--sample-rate-hz", "1000"],
            format!("--pulse-arcsec is required: {b} carries no pulse weight"),
        ),
    ];
    for (args, needle) in cases {
        let o = Command::new(env!("CARGO_BIN_EXE_sagnac"))
            .arg("analyze")
            .args(&args)
            .args(["--json", "-"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(&needle) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
    // a rate column needs no pulse weight
    let o = sagnac(&[
        "analyze",
        "--input",
        c,
        "--sample-rate-hz",
        "1000",
        "--unit",
        "dph",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// An MCAP recording from `simulate --format mcap` carries its rate and
/// pulse weight in its metadata record; analysed without flags it uses them (the
/// same result as with the matching flags, at the model's 400 Hz, not 1000), and
/// a flag that contradicts it is an error naming the flag, the file and both values.
#[test]
fn an_mcap_recording_carries_its_rate_and_pulse_weight() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 400.0\npulse_arcsec = 0.9\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = 0.26\narw_dpsh = 0.002\n",
    )
    .unwrap();
    let mcap = dir.path().join("sim.mcap");
    let m = mcap.to_str().unwrap();
    let o = sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        "120",
        "--seed",
        "3",
        "--format",
        "mcap",
        "--out",
        m,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the metadata record, as the library reads it
    let meta = sagnac::recording::reader::read_metadata(&mcap)
        .unwrap()
        .expect("a sagnac metadata record");
    assert_eq!((meta.sample_rate_hz, meta.pulse_arcsec), (400.0, Some(0.9)));
    assert_eq!(
        meta.model.as_deref(),
        Some(std::fs::read_to_string(&model).unwrap().as_str())
    );
    assert_eq!(meta.sagnac_version, env!("CARGO_PKG_VERSION"));

    let bare = sagnac(&["analyze", "--format", "mcap", "--input", m, "--json", "-"]);
    assert!(
        bare.status.success(),
        "{}",
        String::from_utf8_lossy(&bare.stderr)
    );
    let v: Value = serde_json::from_slice(&bare.stdout).unwrap();
    assert_eq!(v["samples"], 48_000);
    assert!(
        (v["duration_s"].as_f64().unwrap() - 120.0).abs() < 1e-9,
        "{}",
        v["duration_s"]
    );
    // truth Q 0.26" (a pulse weight of 1.21" would scale it to 0.35")
    let q = v["estimates"]["quantization_arcsec"]["value"]
        .as_f64()
        .unwrap();
    assert!((q / 0.26 - 1.0).abs() < 0.03, "Q {q}");
    let flagged = sagnac(&[
        "analyze",
        "--format",
        "mcap",
        "--input",
        m,
        "--sample-rate-hz",
        "400",
        "--pulse-arcsec",
        "0.9",
        "--json",
        "-",
    ]);
    assert!(
        flagged.status.success(),
        "{}",
        String::from_utf8_lossy(&flagged.stderr)
    );
    // the same numbers; `input` says where the rate and pulse weight came from
    let mut f: Value = serde_json::from_slice(&flagged.stdout).unwrap();
    let mut b = v.clone();
    for (j, origin) in [
        (&mut b, "from the recording"),
        (
            &mut f,
            "given on the command line (checked against the recording)",
        ),
    ] {
        assert_eq!(j["input"]["origin"], origin);
        assert_eq!(
            (&j["input"]["sample_rate_hz"], &j["input"]["pulse_arcsec"]),
            (&Value::from(400.0), &Value::from(0.9))
        );
        assert_eq!(j["input"]["format"], "mcap");
        j["input"].as_object_mut().unwrap().remove("origin");
    }
    assert_eq!(b, f, "the metadata's values are the flags' values");

    for (flag, value, recorded) in [
        ("--sample-rate-hz", "1000", "400"),
        ("--pulse-arcsec", "1.21", "0.9"),
    ] {
        let o = sagnac(&[
            "analyze", "--format", "mcap", "--input", m, flag, value, "--json", "-",
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag}: {err}");
        let want = format!(
            "{flag} {value} contradicts {m}: the recording says {recorded} in its sagnac metadata record"
        );
        assert!(err.contains(&want), "{flag}: {err}");
    }
}

/// An MCAP recording without the metadata record (made before it
/// existed) gives its rate by its sample period; the pulse weight must be given.
#[test]
fn an_mcap_recording_without_metadata_needs_the_pulse_flag() {
    use sagnac::recording::messages::{RawBatch, SinkMessage};
    use sagnac::recording::writer::{Recorder, RecorderConfig};
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(&RecorderConfig {
        record_dir: dir.path().to_path_buf(),
        ..RecorderConfig::default()
    })
    .unwrap();
    for k in 0..60u64 {
        rec.send(SinkMessage::Raw(RawBatch {
            t0_ns: k * 1_000_000_000,
            dt_ns: 5_000_000, // 200 Hz
            seq0: k * 200,
            counts: (0..200).map(|i| ((i * 7 + k as i64) % 5) - 2).collect(),
            gaps: vec![],
            temp_c: None,
            status: 7,
        }))
        .unwrap();
    }
    let path = rec.finish().unwrap().path;
    let p = path.to_str().unwrap();
    assert_eq!(
        sagnac::recording::reader::read_metadata(&path).unwrap(),
        None
    );
    let o = sagnac(&["analyze", "--format", "mcap", "--input", p, "--json", "-"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!(
            "--pulse-arcsec is required: {p} carries no pulse weight"
        )),
        "{err}"
    );
    let o = sagnac(&[
        "analyze",
        "--format",
        "mcap",
        "--input",
        p,
        "--pulse-arcsec",
        "1.21",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (v["duration_s"].as_f64().unwrap() - 60.0).abs() < 1e-9,
        "200 Hz from dt_ns: {}",
        v["duration_s"]
    );
    let o = sagnac(&[
        "analyze",
        "--format",
        "mcap",
        "--input",
        p,
        "--pulse-arcsec",
        "1.21",
        "--sample-rate-hz",
        "1000",
        "--json",
        "-",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--sample-rate-hz 1000 contradicts")
            && err.contains("says 200 as the sample period of /gyro/raw"),
        "{err}"
    );
}

/// A short record whose low-frequency fit collapses (every term at 0, a
/// chi-square that is not finite): the fit is reported as not ok, and each
/// unresolved term gets its per-level bound, which holds the truth, instead of
/// the collapsed profile's bound (ARW < 2e-122 deg/sqrt(h) before, for a true
/// 0.0005: an ARW limit would have passed on nothing).
#[test]
fn a_collapsed_low_frequency_fit_bounds_nothing_tightly() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 100\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = 0.484\narw_dpsh = 0.0005\nbias_instability_dph = 0.002\n\
         rate_ramp_dphh = 0.0455\n",
    )
    .unwrap();
    let csv = dir.path().join("s.csv");
    let out = sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        "480",
        "--seed",
        "7000057",
        "--format",
        "csv",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "100",
        "--pulse-arcsec",
        "1.21",
        "--json",
        "-",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["fit"]["ok"], false, "{}", j["fit"]);
    let e = &j["estimates"];
    let bound = |k: &str, truth: f64| {
        let c = &e[k];
        let hi = c["upper95"]
            .as_f64()
            .or_else(|| c["ci95"][1].as_f64())
            .unwrap_or(f64::INFINITY);
        assert!(hi >= truth, "{k}: bound {hi} below the truth {truth}: {c}");
    };
    bound("arw_dpsh", 0.0005);
    bound("bias_instability_dph", 0.002);
    bound("rate_ramp_dphh", 0.0455);
    let q = e["quantization_arcsec"]["ci95"].as_array().unwrap();
    assert!(
        q[0].as_f64().unwrap() < 0.484 && 0.484 < q[1].as_f64().unwrap(),
        "{q:?}"
    );
}

/// `analyze` of `path` with the given extra flags; the JSON, or the stderr.
fn analyze_json(path: &Path, extra: &[&str]) -> Result<Value, String> {
    let mut args = vec!["analyze", "--input", path.to_str().unwrap(), "--json", "-"];
    args.extend_from_slice(extra);
    let o = sagnac(&args);
    if o.status.success() {
        Ok(serde_json::from_slice(&o.stdout).unwrap())
    } else {
        assert_eq!(o.status.code(), Some(2));
        Err(String::from_utf8_lossy(&o.stderr).into_owned())
    }
}

#[test]
fn the_format_is_found_by_content_and_a_contradicting_format_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let csv = simulated_csv(d, "60");
    let model = d.join("m.toml");
    let sim = |format: &str, out: &Path, models: &str| {
        let o = sagnac(&[
            "simulate",
            "--model",
            models,
            "--duration-s",
            "60",
            "--seed",
            "9",
            "--format",
            format,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    // names that say nothing: the content decides
    let (frames, mcap, triad) = (
        d.join("capture.dat"),
        d.join("rec.dat"),
        d.join("triad.dat"),
    );
    let m = model.to_str().unwrap();
    sim("frames", &frames, m);
    sim("mcap", &mcap, m);
    sim("triad-frames", &triad, &format!("{m},{m},{m}"));
    let flags = ["--sample-rate-hz", "1000", "--pulse-arcsec", "1.21"];
    let csv_j = analyze_json(&csv, &flags).unwrap();
    assert_eq!(csv_j["input"]["format"], "csv");
    let fr = analyze_json(&frames, &flags).unwrap();
    assert_eq!(fr["input"]["format"], "frames");
    let mc = analyze_json(&mcap, &[]).unwrap();
    assert_eq!(mc["input"]["format"], "mcap");
    assert_eq!(mc["input"]["sample_rate_hz"], 1000.0);
    // a capture that starts in the middle of a frame
    let bytes = std::fs::read(&frames).unwrap();
    let cut = d.join("cut.dat");
    std::fs::write(&cut, &bytes[5..]).unwrap();
    let cj = analyze_json(&cut, &flags).unwrap();
    assert_eq!(cj["input"]["format"], "frames");
    // the cut first frame is lost, so the second sets the baseline
    assert_eq!(
        cj["samples"].as_u64().unwrap() + 1,
        fr["samples"].as_u64().unwrap()
    );
    // a triad capture: one of its gyros, by label; all three without --gyro
    let tj = analyze_json(&triad, &[&flags[..], &["--gyro", "y"]].concat()).unwrap();
    assert_eq!(tj["input"]["format"], "triad-frames");
    assert_eq!(tj["input"]["gyro"], "y");
    assert!(tj["samples"].as_u64().unwrap() > 59_000);
    let all = analyze_json(&triad, &flags).unwrap();
    let axes: Vec<&String> = all["axes"].as_object().unwrap().keys().collect();
    assert_eq!(axes, ["x", "y", "z"]);
    assert_eq!(all["axes"]["y"]["estimates"], tj["estimates"]);
    assert_eq!(all["axes"]["y"]["input"], tj["input"]);
    assert_eq!(all["input"]["format"], "triad-frames");
    let e = analyze_json(&triad, &[&flags[..], &["--gyro", "w"]].concat()).unwrap_err();
    assert!(e.contains("--gyro w") && e.contains("x, y, z"), "{e}");
    // --format overrides only what agrees with the content
    let e = analyze_json(&mcap, &["--format", "csv"]).unwrap_err();
    assert!(
        e.contains("--format csv contradicts") && e.contains("MCAP"),
        "{e}"
    );
    assert!(analyze_json(&frames, &[&flags[..], &["--format", "frames"]].concat()).is_ok());
    // raw f64 has no signature: it needs --format (or a .f64 name)
    let values: Vec<u8> = (0..5000)
        .flat_map(|i| (10.0 + ((i * 7919) % 13) as f64).to_le_bytes())
        .collect();
    let raw = d.join("rates.bin");
    std::fs::write(&raw, &values).unwrap();
    let rate_flags = ["--sample-rate-hz", "100", "--unit", "dph"];
    let e = analyze_json(&raw, &rate_flags).unwrap_err();
    assert!(e.contains("--format f64le"), "{e}");
    let rj = analyze_json(&raw, &[&rate_flags[..], &["--format", "f64le"]].concat()).unwrap();
    assert_eq!(rj["input"]["format"], "f64le");
    let named = d.join("rates.f64");
    std::fs::copy(&raw, &named).unwrap();
    assert_eq!(analyze_json(&named, &rate_flags).unwrap()["samples"], 5000);
}

/// Counts judged whole on their first samples that hold a fraction further
/// on are analysed as the rates they are: the result of the same values
/// given in deg/h (the rate path), not an error and not a truncation.
#[test]
fn a_fraction_after_the_first_samples_reads_the_counts_as_rates() {
    let dir = tempfile::tempdir().unwrap();
    let n = 3 * sagnac::input::WHOLE_CHECK_SAMPLES as usize;
    let (rate_hz, pulse) = (200.0, 1.21);
    let mut counts: Vec<f64> = (0..n).map(|i| ((i * 7919) % 5) as f64 - 2.0).collect();
    counts[2 * n / 3] += 0.5;
    let csv = |values: &mut dyn Iterator<Item = f64>| {
        let mut s = String::from("counts\n");
        for v in values {
            s.push_str(&format!("{v:?}\n"));
        }
        s
    };
    let counts_csv = dir.path().join("counts.csv");
    std::fs::write(&counts_csv, csv(&mut counts.iter().copied())).unwrap();
    let dph_csv = dir.path().join("dph.csv");
    let k = pulse * rate_hz;
    std::fs::write(&dph_csv, csv(&mut counts.iter().map(|c| c * k))).unwrap();
    let rate = ["--sample-rate-hz", "200", "--raw-statistics"];
    let mut as_counts = rate.to_vec();
    as_counts.extend(["--pulse-arcsec", "1.21"]);
    let a = analyze_json(&counts_csv, &as_counts).unwrap();
    let mut as_dph = rate.to_vec();
    as_dph.extend(["--unit", "dph"]);
    let b = analyze_json(&dph_csv, &as_dph).unwrap();
    assert_eq!(a["samples"], n as u64);
    for key in ["arw_dpsh", "bias_instability_dph"] {
        let (x, y) = (
            a["estimates"][key]["value"].as_f64(),
            b["estimates"][key]["value"].as_f64(),
        );
        let (x, y) = (x.unwrap(), y.unwrap());
        assert!((x - y).abs() <= 1e-9 * y.abs(), "{key}: {x} vs {y}");
    }
}
