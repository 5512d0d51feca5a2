//! Exports: Kalibr's imu.yaml gyroscope fields and the Allan
//! curves as CSV, from the library and through `analyze --kalibr/--allan-csv`
//! and `allan --csv`.

use std::path::Path;

use sagnac::allan::AllanPoint;
use sagnac::model::estimate::{Coefficient, NoiseEstimates};
use sagnac::sink::export::{ExportError, allan_csv, kalibr};

use crate::support::{sagnac, simulated_csv};

fn found(v: f64, lo: f64, hi: f64) -> Coefficient {
    Coefficient {
        value: Some(v),
        ci95: Some([lo, hi]),
        upper95: None,
    }
}
fn bound(u: f64) -> Coefficient {
    Coefficient {
        value: None,
        ci95: None,
        upper95: Some(u),
    }
}

fn estimates(arw: Coefficient, rrw: Coefficient) -> NoiseEstimates {
    NoiseEstimates {
        quantization_arcsec: found(0.35, 0.34, 0.36),
        arw_dpsh: arw,
        bias_instability_dph: bound(0.01),
        rrw_dphsh: rrw,
        rate_ramp_dphh: bound(1.0),
    }
}

/// The value of `key: value` in a YAML text (our flat file).
fn yaml_value(text: &str, key: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.starts_with(&format!("{key}:")))
        .unwrap_or_else(|| panic!("no {key} in\n{text}"));
    line[key.len() + 1..].trim().parse().unwrap()
}

#[test]
fn kalibr_conversions_in_closed_form() {
    // 1 deg/sqrt(h) = (pi/180) rad / sqrt(3600 s) = pi/10800 rad/sqrt(s)
    assert_eq!(
        kalibr::noise_density_from_arw(1.0),
        std::f64::consts::PI / 10800.0
    );
    assert!((kalibr::noise_density_from_arw(1.0) - 2.908882086657216e-4).abs() < 1e-19);
    // 1 deg/h/sqrt(h) = (pi/180 / 3600) rad/s / 60 sqrt(s) = pi/38880000 rad/s^2/sqrt(Hz)
    assert!(
        (kalibr::random_walk_from_rrw(1.0) / (std::f64::consts::PI / 38_880_000.0) - 1.0).abs()
            < 1e-15
    );
    assert!((kalibr::random_walk_from_rrw(1.0) - 8.080228018492267e-8).abs() < 1e-22);

    // the paper's gyro: N = 0.001 deg/sqrt(h); K found = 0.06 deg/h/sqrt(h)
    let y = kalibr::imu_yaml(
        &estimates(found(0.001, 0.0008, 0.0012), found(0.06, 0.03, 0.09)),
        1000.0,
        "run.csv",
    )
    .unwrap();
    // 1e-15 relative: the text holds the shortest round-trip digits
    let nd = yaml_value(&y, "gyroscope_noise_density");
    assert!((nd / 2.908882086657216e-7 - 1.0).abs() < 1e-15, "{nd}");
    let rw = yaml_value(&y, "gyroscope_random_walk");
    assert!((rw / 4.8481368110953594e-9 - 1.0).abs() < 1e-15, "{rw}");
    assert_eq!(yaml_value(&y, "update_rate"), 1000.0);
    assert!(y.contains("update_rate: 1000.0\n"), "{y}");
    // the conversions and the sources are documented in comments
    assert!(
        y.contains("* pi/180 / 60") && y.contains("* pi/180 / 3600 / 60"),
        "{y}"
    );
    assert!(
        y.contains("from N = 0.001 deg/sqrt(h) (95 % interval 0.0008 to 0.0012)"),
        "{y}"
    );
    assert!(!y.contains("NOT FOUND"), "{y}");
    for line in y.lines() {
        assert!(
            line.starts_with('#') || line.contains(": "),
            "not a comment or a key: {line}"
        );
    }
}

#[test]
fn kalibr_random_walk_from_the_upper_bound_is_flagged() {
    let y = kalibr::imu_yaml(
        &estimates(found(0.001, 0.0008, 0.0012), bound(0.06)),
        400.0,
        "x.bin",
    )
    .unwrap();
    assert!((yaml_value(&y, "gyroscope_random_walk") / 4.8481368110953594e-9 - 1.0).abs() < 1e-15);
    let note = y
        .lines()
        .find(|l| l.starts_with("# gyroscope_random_walk"))
        .unwrap();
    assert!(
        note.contains("NOT FOUND") && note.contains("95 % upper bound 0.06"),
        "{note}"
    );
    // neither value nor bound: an error naming the field
    let none = Coefficient {
        value: None,
        ci95: None,
        upper95: None,
    };
    match kalibr::imu_yaml(&estimates(none, bound(0.06)), 400.0, "x.bin") {
        Err(e @ ExportError::Missing { .. }) => {
            assert!(e.to_string().contains("gyroscope_noise_density"), "{e}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn yaml_floats_are_floats_for_yaml_1_1_readers() {
    // PyYAML (Kalibr) reads a float only with a point and a signed exponent
    assert_eq!(kalibr::yaml_float(3e-7), "3.0e-7");
    assert_eq!(
        kalibr::yaml_float(2.908882086657216e-7),
        "2.908882086657216e-7"
    );
    assert_eq!(kalibr::yaml_float(1000.0), "1.0e+3");
    assert_eq!(kalibr::yaml_float(0.5), "5.0e-1");
    for v in [3e-7, 2.908882086657216e-7, 1234.5678, 1e-300] {
        assert_eq!(kalibr::yaml_float(v).parse::<f64>().unwrap(), v);
    }
}

fn point(tau_s: f64, m: u64, dev: f64) -> AllanPoint {
    AllanPoint {
        tau_s,
        m,
        n: 1000 - m,
        dev,
        ci_lo: dev * 0.9,
        ci_hi: dev * 1.25,
        edf: 12.5,
        alpha: 0,
    }
}

#[test]
fn allan_csv_text_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.csv");
    allan_csv::write_curve(
        &p,
        &[point(0.001, 1, 2.0), point(0.002, 2, 0.5)],
        "pulse_per_s",
    )
    .unwrap();
    assert_eq!(
        std::fs::read_to_string(&p).unwrap(),
        "tau_s,dev_pulse_per_s,ci_lo_pulse_per_s,ci_hi_pulse_per_s,edf,n\n\
         1e-3,2e0,1.8e0,2.5e0,1.25e1,999\n\
         2e-3,5e-1,4.5e-1,6.25e-1,1.25e1,998\n"
    );
    let curves = sagnac::pipeline::AllanCurves {
        raw: vec![point(1.0, 1, 3.0)],
        clean: vec![],
        noise: vec![point(1.0, 1, 0.25)],
    };
    allan_csv::write_channels(&p, &curves).unwrap();
    assert_eq!(
        std::fs::read_to_string(&p).unwrap(),
        "channel,tau_s,dev_dph,ci_lo_dph,ci_hi_dph,edf,n\n\
         raw,1e0,3e0,2.7e0,3.75e0,1.25e1,999\n\
         noise,1e0,2.5e-1,2.25e-1,3.125e-1,1.25e1,999\n"
    );
    // an unwritable path is an error naming it
    let bad = dir.path().join("no/such/dir/a.csv");
    let e = allan_csv::write_curve(&bad, &[], "dph").unwrap_err();
    assert!(e.to_string().contains("no/such/dir"), "{e}");
}

/// CSV rows as (first cell, the rest parsed as f64).
fn rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let body = r
        .records()
        .map(|x| x.unwrap().iter().map(String::from).collect())
        .collect();
    (header, body)
}

#[test]
fn analyze_writes_kalibr_and_the_three_allan_channels() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path(), "120");
    let (json, yaml, acsv) = (
        dir.path().join("a.json"),
        dir.path().join("imu.yaml"),
        dir.path().join("allan.csv"),
    );
    let o = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--json",
        json.to_str().unwrap(),
        "--kalibr",
        yaml.to_str().unwrap(),
        "--allan-csv",
        acsv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let y = std::fs::read_to_string(&yaml).unwrap();
    // the YAML holds the JSON's N converted (exactly the same f64 operations)
    let n = v["estimates"]["arw_dpsh"]["value"].as_f64().unwrap();
    assert_eq!(
        yaml_value(&y, "gyroscope_noise_density"),
        kalibr::noise_density_from_arw(n)
    );
    assert_eq!(yaml_value(&y, "update_rate"), 1000.0);
    let k = &v["estimates"]["rrw_dphsh"];
    let k_used = k["value"].as_f64().or(k["upper95"].as_f64()).unwrap();
    assert_eq!(
        yaml_value(&y, "gyroscope_random_walk"),
        kalibr::random_walk_from_rrw(k_used)
    );
    assert_eq!(k["value"].is_null(), y.contains("K NOT FOUND"), "{y}");
    // the CSV rows are the JSON's curves, value for value
    let (header, body) = rows(&acsv);
    assert_eq!(
        header,
        [
            "channel",
            "tau_s",
            "dev_dph",
            "ci_lo_dph",
            "ci_hi_dph",
            "edf",
            "n"
        ]
    );
    let mut at = 0;
    for ch in ["raw", "clean", "noise"] {
        for p in v["allan"][ch].as_array().unwrap() {
            let r = &body[at];
            at += 1;
            assert_eq!(r[0], ch);
            for (i, key) in ["tau_s", "dev", "ci_lo", "ci_hi", "edf"].iter().enumerate() {
                assert_eq!(
                    r[i + 1].parse::<f64>().unwrap(),
                    p[key].as_f64().unwrap(),
                    "{ch} {key}"
                );
            }
            assert_eq!(r[6].parse::<u64>().unwrap(), p["n"].as_u64().unwrap());
        }
    }
    assert_eq!(at, body.len());
    // an export into a missing directory fails before the analysis
    let o = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--sample-rate-hz",
        "1000",
        "--pulse-arcsec",
        "1.21",
        "--kalibr",
        "/no/such/dir/imu.yaml",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--kalibr"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn allan_csv_equals_its_json() {
    let dir = tempfile::tempdir().unwrap();
    let csv = simulated_csv(dir.path(), "120");
    for engine in ["batch", "streaming"] {
        let (json, out) = (dir.path().join("b.json"), dir.path().join("b.csv"));
        let o = sagnac(&[
            "allan",
            "--input",
            csv.to_str().unwrap(),
            "--format",
            "csv",
            "--column",
            "counts",
            "--data",
            "counts",
            "--tau0",
            "0.001",
            "--engine",
            engine,
            "--json",
            json.to_str().unwrap(),
            "--csv",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let (header, body) = rows(&out);
        assert_eq!(
            header,
            [
                "tau_s",
                "dev_pulse_per_s",
                "ci_lo_pulse_per_s",
                "ci_hi_pulse_per_s",
                "edf",
                "n"
            ]
        );
        let pts = v["points"].as_array().unwrap();
        assert_eq!(pts.len(), body.len(), "{engine}");
        for (p, r) in pts.iter().zip(&body) {
            for (i, key) in ["tau_s", "dev", "ci_lo", "ci_hi", "edf"].iter().enumerate() {
                assert_eq!(
                    r[i].parse::<f64>().unwrap(),
                    p[key].as_f64().unwrap(),
                    "{engine} {key}"
                );
            }
            assert_eq!(r[5].parse::<u64>().unwrap(), p["n"].as_u64().unwrap());
        }
    }
}
