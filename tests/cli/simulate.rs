//! `sagnac simulate`: CSV output on config/paper_gyro.toml, the thermal column,
//! determinism, and errors (exit code 2 naming the key).

use std::path::Path;

use crate::support::{PAPER_GYRO, bin};

fn simulate(
    model: &Path,
    duration: &str,
    seed: &str,
    out: &Path,
    extra: &[&str],
) -> std::process::Output {
    bin()
        .args(["simulate", "--model"])
        .arg(model)
        .args(["--duration-s", duration, "--seed", seed, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn csv_on_the_paper_gyro_has_header_and_one_row_per_sample() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim.csv");
    let r = simulate(Path::new(PAPER_GYRO), "2.5", "7", &out, &[]);
    assert!(
        r.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("counts"));
    let counts: Vec<i64> = lines
        .map(|l| l.parse().expect("integer pulse increment"))
        .collect();
    assert_eq!(counts.len(), 2500);
    // Earth rate 12.3 deg/h with 1.21 arcsec pulses: 12.3 * 2.5 / 1.21 = 25.4 pulses,
    // give or take the noise (ADEV over 2.5 s is far below one pulse) and the readout (+-1)
    let total: i64 = counts.iter().sum();
    assert!((24..=27).contains(&total), "total {total}");
    // slow input (0.01 pulse per sample): increments are 0 or +1, and -1/+2 where the
    // dither residual makes the reading flicker across a pulse boundary
    assert!(
        counts.iter().all(|c| (-1..=2).contains(c)),
        "increments out of range"
    );
    assert!(counts.iter().filter(|&&c| c == 0).count() > 2400);
    // same seed, same bytes; another seed, another stream
    let out2 = dir.path().join("sim2.csv");
    assert!(
        simulate(
            Path::new(PAPER_GYRO),
            "2.5",
            "7",
            &out2,
            &["--format", "csv"]
        )
        .status
        .success()
    );
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&out2).unwrap());
    let out3 = dir.path().join("sim3.csv");
    assert!(
        simulate(Path::new(PAPER_GYRO), "2.5", "8", &out3, &[])
            .status
            .success()
    );
    assert_ne!(std::fs::read(&out).unwrap(), std::fs::read(&out3).unwrap());
}

#[test]
fn thermal_model_adds_a_temperature_column() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("thermal.toml");
    let text = std::fs::read_to_string(PAPER_GYRO).unwrap()
        + "\n[thermal]\ntemp_c0 = 25.0\nramp_c_per_h = 36.0\nbias_sensitivity_dph_per_c = 0.001\n";
    std::fs::write(&model, text).unwrap();
    let out = dir.path().join("t.csv");
    let r = simulate(&model, "1", "1", &out, &[]);
    assert!(
        r.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("counts,temp_c"));
    let rows: Vec<(i64, f64)> = lines
        .map(|l| {
            let (c, t) = l.split_once(',').unwrap();
            (c.parse().unwrap(), t.parse().unwrap())
        })
        .collect();
    assert_eq!(rows.len(), 1000);
    // T(t) = 25 + 0.01 C/s * t at the end of each sample, printed to 1e-4 C
    for (k, &(_, t)) in rows.iter().enumerate() {
        let expect = 25.0 + 0.01 * (k + 1) as f64 * 1e-3;
        assert!(
            (t - expect).abs() <= 0.5e-4 + 1e-12,
            "row {k}: {t} vs {expect}"
        );
    }
}

#[test]
fn bad_model_exits_2_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("bad.toml");
    std::fs::write(&model, "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\n\n[noise]\nbias_instabilty_dph = 0.002\n").unwrap();
    let r = simulate(&model, "1", "1", &dir.path().join("x.csv"), &[]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("bias_instabilty_dph") && err.contains("bad.toml:6:"),
        "{err}"
    );

    std::fs::write(&model, "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\n\n[[noise.sinusoid]]\namplitude_dph = 0.1\nperiod_s = 0\n").unwrap();
    let r = simulate(&model, "1", "1", &dir.path().join("x.csv"), &[]);
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("noise.sinusoid[0].period_s = 0"), "{err}");
}

#[test]
fn bad_durations_exit_2() {
    // (--format frames / mcap are tested in tests/daemon/simulate.rs)
    let dir = tempfile::tempdir().unwrap();
    let r = simulate(
        Path::new(PAPER_GYRO),
        "0",
        "1",
        &dir.path().join("x.csv"),
        &[],
    );
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("duration_s = 0"));
}

#[test]
fn mcap_output_only_replaces_a_regular_file_in_an_existing_directory() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_sagnac");
    let model = PAPER_GYRO;
    let sim = |out: &std::path::Path| {
        std::process::Command::new(bin)
            .args([
                "simulate",
                "--model",
                model,
                "--duration-s",
                "1",
                "--seed",
                "1",
                "--format",
                "mcap",
                "--out",
            ])
            .arg(out)
            .output()
            .unwrap()
    };
    let missing = dir.path().join("no_such_dir");
    let r = sim(&missing.join("x.mcap"));
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("is not an existing directory"));
    assert!(!missing.exists(), "the directory must not be created");
    let link = dir.path().join("link.mcap");
    std::os::unix::fs::symlink(dir.path().join("target.mcap"), &link).unwrap();
    let r = sim(&link);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("not a regular file"));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink(),
        "the link is left alone"
    );
    let ok = dir.path().join("ok.mcap");
    assert!(sim(&ok).status.success());
    // nothing left behind but the outputs
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["link.mcap", "ok.mcap"]);
}

/// `--format triad-frames`: three models in one 24-byte-frame capture; each
/// axis decodes to exactly the pulses its model writes as CSV with seeds S,
/// S + 1, S + 2; models with different sample rates, or a count other than
/// three, are errors.
#[test]
fn triad_frames_carry_each_axis_csv_stream() {
    use sagnac::input::frame::{Decoded, DecoderConfig, FrameDecoder, Triad};
    let dir = tempfile::tempdir().unwrap();
    let mut models = Vec::new();
    for (k, arw) in [0.001, 0.003, 0.0005].iter().enumerate() {
        let m = dir.path().join(format!("m{k}.toml"));
        std::fs::write(&m, format!("[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 1.21\ninput_rate_dph = {}\n[noise]\narw_dpsh = {arw}\n", 10.0 * k as f64)).unwrap();
        models.push(m);
    }
    let list = models
        .iter()
        .map(|m| m.to_str().unwrap())
        .collect::<Vec<_>>()
        .join(",");
    let out = dir.path().join("triad.bin");
    let r = bin()
        .args([
            "simulate",
            "--model",
            &list,
            "--duration-s",
            "3",
            "--seed",
            "11",
            "--format",
            "triad-frames",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(bytes.len(), (1500 + 1) * 24);
    let (items, st) = FrameDecoder::<Triad>::decode_all_wire(&bytes, DecoderConfig::default());
    assert_eq!(
        (st.bytes_skipped, st.crc_errors, st.lost_samples),
        (0, 0, 0)
    );
    let incs: Vec<[i64; 3]> = items
        .iter()
        .filter_map(|d| {
            if let Decoded::Sample(s) = d {
                Some(s.increment)
            } else {
                None
            }
        })
        .collect();
    for (k, m) in models.iter().enumerate() {
        let csv = dir.path().join(format!("axis{k}.csv"));
        let r = simulate(m, "3", &(11 + k).to_string(), &csv, &[]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let want: Vec<i64> = std::fs::read_to_string(&csv)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.parse().unwrap())
            .collect();
        let got: Vec<i64> = incs.iter().map(|i| i[k]).collect();
        assert_eq!(got, want, "axis {k}");
    }
    // errors: two models; a model with another rate; three models without triad-frames
    let two = format!("{},{}", models[0].display(), models[1].display());
    let r = bin()
        .args([
            "simulate",
            "--model",
            &two,
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--format",
            "triad-frames",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.code() == Some(2) && err.contains("three models") && err.contains("got 2"),
        "{err}"
    );
    std::fs::write(
        &models[2],
        "[gyro]\nsample_rate_hz = 400.0\npulse_arcsec = 1.21\n",
    )
    .unwrap();
    let r = bin()
        .args([
            "simulate",
            "--model",
            &list,
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--format",
            "triad-frames",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.code() == Some(2) && err.contains("m2.toml") && err.contains("sample clock"),
        "{err}"
    );
    let r = bin()
        .args([
            "simulate",
            "--model",
            &list,
            "--duration-s",
            "1",
            "--seed",
            "1",
            "--format",
            "frames",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        r.status.code() == Some(2) && err.contains("one model file"),
        "{err}"
    );
}
