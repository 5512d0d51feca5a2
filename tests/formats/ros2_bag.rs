//! ROS 2 bags as input, written by independent writers (mcap-ros2-support,
//! rosbags; `scripts/make-ros2-bag.py`): the same samples read from a bag
//! (one MCAP file, zstd or lz4 chunks; a rosbag2 directory, its files plain or
//! zstd-compressed whole; one split over two files) give the same analysis as read from CSV; holes, out-of-order and
//! duplicate stamps are counted exactly; topics and sqlite3 bags get clear
//! errors.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

use crate::support::{repo, sagnac};

/// Write a bag with `scripts/make-ros2-bag.py` (and its samples as CSV).
fn make_bag(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, PathBuf) {
    let out = dir.join(name);
    let csv = dir.join(format!("{name}.csv"));
    let o = Command::new("python3")
        .arg(repo().join("scripts/make-ros2-bag.py"))
        .args([
            "--out",
            out.to_str().unwrap(),
            "--csv",
            csv.to_str().unwrap(),
        ])
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("python3 is required (scripts/install-peers): {e}"));
    assert!(
        o.status.success(),
        "make-ros2-bag.py (needs mcap-ros2-support and rosbags from scripts/install-peers): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    (out, csv)
}

fn analyze(args: &[&str]) -> Value {
    let mut all = vec!["analyze", "--json", "-"];
    all.extend_from_slice(args);
    let o = sagnac(&all);
    assert!(
        o.status.success(),
        "sagnac {all:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn fails(args: &[&str]) -> String {
    let mut all = vec!["analyze"];
    all.extend_from_slice(args);
    let o = sagnac(&all);
    assert!(!o.status.success(), "sagnac {all:?} should fail");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const N: &str = "20000";

/// Every number of `a` within `rel` of the one at the same place in `b`
/// (block sizes differ between formats: sums agree to the last bits only).
fn assert_close(a: &Value, b: &Value, rel: f64, at: &str) {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= rel * y.abs().max(1e-300),
                "{at}: {x} against {y}"
            );
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{at}: lengths");
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                assert_close(p, q, rel, &format!("{at}[{i}]"));
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{at}: keys"
            );
            for (k, p) in x {
                assert_close(p, &y[k], rel, &format!("{at}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

#[test]
fn a_bag_reads_as_the_same_samples_as_csv() {
    let d = tempfile::tempdir().unwrap();
    let (bag, csv) = make_bag(d.path(), "run.mcap", &["--n", N, "--seed", "11"]);
    for (axis, column) in [("gyro_x", "gyro_x"), ("gyro_z", "gyro_z")] {
        let b = analyze(&["--input", bag.to_str().unwrap(), "--gyro", axis]);
        let c = analyze(&[
            "--input",
            csv.to_str().unwrap(),
            "--column",
            column,
            "--unit",
            "rad_s",
            "--sample-rate-hz",
            "200",
        ]);
        assert_close(&b["estimates"], &c["estimates"], 1e-9, axis);
        assert_close(&b["allan"], &c["allan"], 1e-9, axis);
        assert_eq!(b["samples"], 20000);
        let input = &b["input"];
        assert_eq!(input["format"], "ros2");
        assert_eq!(input["topic"], "/imu");
        assert_eq!(input["gyro"], axis);
        assert_eq!(input["unit"], "rad_s");
        assert_eq!(input["sample_rate_hz"], 200.0);
        let s = &input["stamps"];
        assert_eq!(
            (s["messages"].as_u64(), s["gaps"].as_u64()),
            (Some(20000), Some(0))
        );
    }
    // the truth: white rate noise of 1e-4 rad/s/sqrt(Hz) on gyro_x = 0.3438 deg/sqrt(h)
    let b = analyze(&["--input", bag.to_str().unwrap(), "--gyro", "gyro_x"]);
    let arw = &b["estimates"]["arw_dpsh"];
    let truth = 1e-4_f64.to_degrees() * 60.0;
    assert!(
        arw["ci95"][0].as_f64().unwrap() < truth && truth < arw["ci95"][1].as_f64().unwrap(),
        "ARW {arw} against {truth}"
    );
}

#[test]
fn compression_directories_and_split_bags_read_alike() {
    let d = tempfile::tempdir().unwrap();
    let common = ["--n", N, "--seed", "12"];
    let (zstd, _) = make_bag(d.path(), "zstd.mcap", &common);
    let reference = analyze(&["--input", zstd.to_str().unwrap(), "--gyro", "gyro_y"]);
    for (name, extra) in [
        ("lz4.mcap", vec!["--compression", "lz4"]),
        (
            "plain.mcap",
            vec!["--compression", "none", "--dep-form", "long"],
        ),
        ("dir", vec!["--kind", "dir"]),
        ("dir-zstd", vec!["--kind", "dir-zstd"]),
        ("split", vec!["--kind", "split"]),
    ] {
        let mut args = common.to_vec();
        args.extend(extra);
        let (bag, _) = make_bag(d.path(), name, &args);
        let b = analyze(&["--input", bag.to_str().unwrap(), "--gyro", "gyro_y"]);
        assert_eq!(b["estimates"], reference["estimates"], "{name}");
        assert_eq!(b["samples"], reference["samples"], "{name}");
        assert_eq!(b["input"]["stamps"]["messages"], 20000, "{name}");
    }
}

#[test]
fn holes_disorder_duplicates_and_jitter_are_counted() {
    let d = tempfile::tempdir().unwrap();
    let (bag, csv) = make_bag(
        d.path(),
        "rough.mcap",
        &[
            "--n",
            N,
            "--seed",
            "13",
            "--holes",
            "1000:3",
            "5000:1",
            "12000:40",
            "--swaps",
            "25",
            "--dups",
            "7",
            "--jitter-ns",
            "500000",
            "--second-topic",
        ],
    );
    let p = bag.to_str().unwrap();
    let e = fails(&["--input", p, "--gyro", "gyro_x"]);
    assert!(
        e.contains("several sensor_msgs/msg/Imu topics") && e.contains("/imu/filtered"),
        "{e}"
    );
    let e = fails(&["--input", p, "--gyro", "gyro_x", "--topic", "/odom"]);
    assert!(
        e.contains("--topic /odom") && e.contains("no such topic"),
        "{e}"
    );
    let b = analyze(&["--input", p, "--gyro", "gyro_x", "--topic", "/imu"]);
    let s = &b["input"]["stamps"];
    assert_eq!(s["messages"], 20000 - 44 + 7);
    assert_eq!(s["out_of_order"], 25);
    assert_eq!(s["duplicates"], 7);
    assert_eq!(
        (s["gaps"].as_u64(), s["lost_samples"].as_u64()),
        (Some(3), Some(44))
    );
    assert_eq!(b["samples"], 20000);
    let rate = b["input"]["sample_rate_hz"].as_f64().unwrap();
    assert!((rate - 200.0).abs() < 0.01, "{rate}");
    // the estimates stay those of the complete samples, within their intervals
    let c = analyze(&[
        "--input",
        csv.to_str().unwrap(),
        "--column",
        "gyro_x",
        "--unit",
        "rad_s",
        "--sample-rate-hz",
        "200",
    ]);
    let (bv, cv) = (&b["estimates"]["arw_dpsh"], &c["estimates"]["arw_dpsh"]);
    let rel = (bv["value"].as_f64().unwrap() / cv["value"].as_f64().unwrap() - 1.0).abs();
    assert!(rel < 0.01, "ARW {bv} against {cv}");
}

#[test]
fn sqlite_bags_and_misplaced_flags_get_clear_errors() {
    let d = tempfile::tempdir().unwrap();
    let (bag, csv) = make_bag(d.path(), "sq", &["--n", "2000", "--kind", "sqlite"]);
    for p in [bag.clone(), bag.join("sq.db3")] {
        let e = fails(&["--input", p.to_str().unwrap(), "--gyro", "gyro_x"]);
        assert!(
            e.contains("sqlite3 storage") && e.contains("rosbags-convert"),
            "{e}"
        );
    }
    let e = fails(&["--input", csv.to_str().unwrap(), "--topic", "/imu"]);
    assert!(e.contains("--topic does not apply"), "{e}");
    let (mcap, _) = make_bag(d.path(), "m.mcap", &["--n", "2000"]);
    let e = fails(&["--input", mcap.to_str().unwrap(), "--gyro", "x"]);
    assert!(
        e.contains("gyro_x, gyro_y, gyro_z, accel_x, accel_y, accel_z"),
        "{e}"
    );
    let e = fails(&[
        "--input",
        mcap.to_str().unwrap(),
        "--spec",
        "config/spec_example.toml",
    ]);
    assert!(e.contains("--spec takes one axis"), "{e}");
    let e = fails(&[
        "--input",
        mcap.to_str().unwrap(),
        "--gyro",
        "gyro_x",
        "--pulse-arcsec",
        "1",
    ]);
    assert!(e.contains("--pulse-arcsec does not apply"), "{e}");
    let e = fails(&[
        "--input",
        mcap.to_str().unwrap(),
        "--gyro",
        "gyro_x",
        "--sample-rate-hz",
        "100",
    ]);
    assert!(e.contains("--sample-rate-hz"), "{e}");
    let (nan, _) = make_bag(d.path(), "nan.mcap", &["--n", "2000", "--nan-at", "700"]);
    let e = fails(&["--input", nan.to_str().unwrap(), "--gyro", "gyro_y"]);
    assert!(
        e.contains("message #700 on /imu") && e.contains("gyro_y is not finite (NaN)"),
        "{e}"
    );
    let e = fails(&["--input", nan.to_str().unwrap()]);
    assert!(e.contains("gyro_y is not finite"), "{e}");
    let ok = analyze(&["--input", nan.to_str().unwrap(), "--gyro", "gyro_x"]);
    assert_eq!(ok["samples"], 2000);
    let empty = d.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let e = fails(&["--input", empty.to_str().unwrap()]);
    assert!(e.contains("no metadata.yaml"), "{e}");
}

/// `sagnac analyze` on a bag without `--gyro`: every axis in one pass,
/// `axes` in the JSON, each axis with the single-axis structure; the
/// accelerometer's terms under their own names and units; a full Kalibr file.
#[test]
fn six_axes_in_one_pass_and_a_complete_kalibr_file() {
    let d = tempfile::tempdir().unwrap();
    // densities per axis: gyro rad/s/sqrt(Hz), accel m/s^2/sqrt(Hz)
    let (gyro_d, accel_d) = ([1e-4, 2e-4, 3e-4], [1e-3, 2e-3, 3e-3]);
    let (bag, csv) = make_bag(
        d.path(),
        "six.mcap",
        &[
            "--n",
            "60000",
            "--seed",
            "21",
            "--gyro-density",
            "1e-4",
            "2e-4",
            "3e-4",
            "--accel-density",
            "1e-3",
            "2e-3",
            "3e-3",
            "--holes",
            "30000:5",
        ],
    );
    let yaml = d.path().join("imu.yaml");
    let j = analyze(&[
        "--input",
        bag.to_str().unwrap(),
        "--kalibr",
        yaml.to_str().unwrap(),
    ]);
    let axes = j["axes"].as_object().unwrap();
    let labels: Vec<&str> = axes.keys().map(String::as_str).collect();
    assert_eq!(
        labels,
        [
            "accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"
        ]
    );
    assert_eq!(j["input"]["topic"], "/imu");
    assert_eq!(j["input"]["stamps"]["lost_samples"], 5);
    for (i, g) in ["gyro_x", "gyro_y", "gyro_z"].iter().enumerate() {
        let a = &axes[*g];
        assert_eq!(a["input"]["gyro"], *g);
        assert_eq!(a["units"]["estimates.arw_dpsh"], "deg/sqrt(h)");
        let truth = f64::to_degrees(gyro_d[i]) * 60.0;
        let c = &a["estimates"]["arw_dpsh"]["ci95"];
        assert!(
            c[0].as_f64().unwrap() < truth && truth < c[1].as_f64().unwrap(),
            "{g}: {c} vs {truth}"
        );
    }
    for (i, g) in ["accel_x", "accel_y", "accel_z"].iter().enumerate() {
        let a = &axes[*g];
        assert_eq!(a["input"]["unit"], "mps2");
        assert_eq!(a["units"]["estimates.vrw_mpssh"], "m/s/sqrt(h)");
        assert_eq!(a["units"]["allan.*.dev, ci_lo, ci_hi"], "m/s^2");
        assert!(a["estimates"].get("arw_dpsh").is_none(), "{g}");
        // VRW in m/s/sqrt(h): density (m/s/sqrt(s)) * 60
        let truth = accel_d[i] * 60.0;
        let c = &a["estimates"]["vrw_mpssh"]["ci95"];
        assert!(
            c[0].as_f64().unwrap() < truth && truth < c[1].as_f64().unwrap(),
            "{g}: {c} vs {truth}"
        );
        // (the constant 1 g on accel_z is a bias: its VRW holds the truth like the others')
    }
    // each axis is what it is read alone (one pass, same numbers)
    let alone = analyze(&["--input", bag.to_str().unwrap(), "--gyro", "accel_y"]);
    assert_eq!(alone["estimates"], axes["accel_y"]["estimates"]);
    assert_eq!(alone["allan"], axes["accel_y"]["allan"]);
    // and the same samples as a CSV column in m/s^2 (no hole)
    let c = analyze(&[
        "--input",
        csv.to_str().unwrap(),
        "--column",
        "accel_x",
        "--unit",
        "mps2",
        "--sample-rate-hz",
        "200",
    ]);
    let v = |j: &Value| j["estimates"]["vrw_mpssh"]["value"].as_f64().unwrap();
    assert!((v(&c) / v(&axes["accel_x"]) - 1.0).abs() < 0.01);

    let y = std::fs::read_to_string(&yaml).unwrap();
    let field = |k: &str| -> f64 {
        let l = y
            .lines()
            .find(|l| l.starts_with(&format!("{k}:")))
            .unwrap_or_else(|| panic!("{k} in\n{y}"));
        l[k.len() + 1..].trim().parse().unwrap()
    };
    // the largest axis, against its truth (Kalibr's units: continuous-time densities)
    let nd = field("gyroscope_noise_density");
    assert!((nd / 3e-4 - 1.0).abs() < 0.03, "{nd}\n{y}");
    let ad = field("accelerometer_noise_density");
    assert!((ad / 3e-3 - 1.0).abs() < 0.03, "{ad}\n{y}");
    assert!(field("gyroscope_random_walk") > 0.0 && field("accelerometer_random_walk") > 0.0);
    assert_eq!(field("update_rate"), 200.0);
    assert!(y.contains("rostopic: /imu\n"), "{y}");
    assert!(
        y.contains("the largest of the 3 axes (the conservative choice)"),
        "{y}"
    );
    assert!(
        y.contains("NOT FOUND"),
        "white noise only: the random walks are bounds\n{y}"
    );
    // a gyro-only input says the accelerometer fields are absent
    let gy = d.path().join("gyro.yaml");
    let o = sagnac(&[
        "analyze",
        "--input",
        csv.to_str().unwrap(),
        "--column",
        "gyro_x",
        "--unit",
        "rad_s",
        "--sample-rate-hz",
        "200",
        "--kalibr",
        gy.to_str().unwrap(),
        "--topic",
        "/imu0",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let g = std::fs::read_to_string(&gy).unwrap();
    assert!(
        g.contains("accelerometer_noise_density and accelerometer_random_walk absent"),
        "{g}"
    );
    assert!(
        g.contains("rostopic: /imu0\n") && g.contains("gyroscope_noise_density: "),
        "{g}"
    );
}

/// `sagnac report` on a bag without `--gyro`: a page per axis (the
/// accelerometer's in its own units) and an index with every axis.
#[test]
fn a_report_of_the_six_axes() {
    let d = tempfile::tempdir().unwrap();
    let (bag, _) = make_bag(d.path(), "r.mcap", &["--n", "12000", "--seed", "31"]);
    let out = d.path().join("rep");
    let o = sagnac(&[
        "report",
        "--input",
        bag.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    for axis in [
        "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
    ] {
        assert!(
            index.contains(&format!("href=\"{axis}/index.html\"")),
            "{axis}"
        );
        for f in ["index.html", "allan.png", "noise_integral.png"] {
            assert!(out.join(axis).join(f).is_file(), "{axis}/{f}");
        }
    }
    assert!(index.contains("velocity random walk") && index.contains("angle random walk"));
    let accel = std::fs::read_to_string(out.join("accel_x/index.html")).unwrap();
    assert!(accel.contains("velocity random walk") && accel.contains("m/s\u{b2}"));
    assert!(
        !accel.contains("deg/h"),
        "an accelerometer's page speaks m/s^2"
    );
    let gyro = std::fs::read_to_string(out.join("gyro_x/index.html")).unwrap();
    assert!(gyro.contains("angle random walk") && gyro.contains("deg/h"));
    let o = sagnac(&[
        "report",
        "--input",
        bag.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--model",
        "config/paper_gyro.toml",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--model and --spec take one axis"));
}
