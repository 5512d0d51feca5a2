//! `sagnac allan` end to end: the JSON contract, input formats that must agree,
//! and bad inputs that must exit 2 with a message naming the file and line.

use std::io::Write;
use std::path::{Path, PathBuf};

use sagnac::allan::{self, AllanOptions, DataKind, Phase, Stat, TauSet};
use serde_json::Value;

use crate::support::sagnac;

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Deterministic random-walk phase with white noise on top.
fn samples(n: usize) -> Vec<f64> {
    let mut s = 0x9E3779B97F4A7C15_u64;
    let mut u = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut acc = 0.0;
    (0..n)
        .map(|_| {
            acc += 1e-3 * u();
            acc + 1e-2 * u()
        })
        .collect()
}

/// Equal up to JSON parsing (2 ulp).
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 4.0 * f64::EPSILON * b.abs()
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn gz(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn text_of(v: &[f64]) -> String {
    let mut s = String::from("# phase samples\n");
    for x in v {
        s.push_str(&format!("{x:e}\n")); // shortest round-trip representation
    }
    s
}

fn run_json(args: &[&str], dir: &Path, tag: &str) -> (Value, String) {
    let out = dir.join(format!("{tag}.json"));
    let mut a: Vec<&str> = args.to_vec();
    a.extend_from_slice(&["--json", p(&out)]);
    let o = sagnac(&a);
    assert!(
        o.status.success(),
        "{tag}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    (serde_json::from_str(&text).unwrap(), text)
}

#[test]
fn json_contract_shape_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let v = samples(1000);
    let f = write(dir.path(), "x.txt", text_of(&v).as_bytes());
    let (j, _) = run_json(
        &[
            "allan",
            "--input",
            p(&f),
            "--data",
            "phase",
            "--tau0",
            "0.5",
        ],
        dir.path(),
        "shape",
    );
    let obj = j.as_object().unwrap();
    let mut keys: Vec<&str> = obj.keys().map(|k| k.as_str()).collect();
    keys.sort();
    assert_eq!(keys, ["points", "stat", "tau0_s"]);
    assert_eq!(j["stat"], "oadev"); // default statistic
    assert_eq!(j["tau0_s"].as_f64(), Some(0.5));
    let pts = j["points"].as_array().unwrap();
    // default octave set: m = 1..128 (128 * 4 < 999)
    let ms: Vec<u64> = pts.iter().map(|q| q["m"].as_u64().unwrap()).collect();
    assert_eq!(ms, [1, 2, 4, 8, 16, 32, 64, 128]);
    let lib = allan::compute(
        &Phase::F64(v.clone()),
        Stat::Oadev,
        0.5,
        TauSet::Octave,
        &AllanOptions::default(),
    )
    .unwrap();
    for (q, l) in pts.iter().zip(&lib.points) {
        let mut k: Vec<&str> = q.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        k.sort();
        assert_eq!(
            k,
            ["alpha", "ci_hi", "ci_lo", "dev", "edf", "m", "n", "tau_s"]
        );
        assert!(q["m"].is_u64() && q["n"].is_u64() && q["alpha"].is_i64());
        assert_eq!(q["n"].as_u64(), Some(l.n));
        assert_eq!(q["alpha"].as_i64(), Some(l.alpha as i64));
        for (key, want) in [
            ("tau_s", l.tau_s),
            ("dev", l.dev),
            ("ci_lo", l.ci_lo),
            ("ci_hi", l.ci_hi),
            ("edf", l.edf),
        ] {
            // serde_json prints the shortest round-trip form; its default parser may be 1 ulp off
            let got = q[key].as_f64().unwrap();
            assert!(close(got, want), "{key}: {got} vs {want}");
        }
        assert!(l.ci_lo < l.dev && l.dev < l.ci_hi);
    }
}

#[test]
fn text_csv_f64le_and_gz_inputs_agree() {
    let dir = tempfile::tempdir().unwrap();
    let v = samples(3000);
    let txt = text_of(&v);
    let mut csv = String::from("time_s,phase_s,flag\n");
    for (i, x) in v.iter().enumerate() {
        csv.push_str(&format!("{},{x:e},{}\r\n", i as f64 * 0.1, i % 2));
    }
    let bin: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let files = [
        (write(dir.path(), "a.txt", txt.as_bytes()), "text"),
        (write(dir.path(), "a.txt.gz", &gz(txt.as_bytes())), "text"),
        (write(dir.path(), "a.csv", csv.as_bytes()), "csv"),
        (write(dir.path(), "a.csv.gz", &gz(csv.as_bytes())), "csv"),
        (write(dir.path(), "a.f64", &bin), "f64le"),
        (write(dir.path(), "a.f64.gz", &gz(&bin)), "f64le"),
    ];
    for stat in ["oadev", "mdev", "totdev"] {
        let mut first: Option<String> = None;
        for (i, (f, fmt)) in files.iter().enumerate() {
            let mut args = vec![
                "allan",
                "--input",
                p(f),
                "--data",
                "phase",
                "--tau0",
                "0.1",
                "--stat",
                stat,
                "--taus",
                "decade",
                "--format",
                fmt,
            ];
            if *fmt == "csv" {
                args.extend_from_slice(&["--column", "phase_s"]);
            }
            let (j, text) = run_json(&args, dir.path(), &format!("{stat}{i}"));
            assert_eq!(j["stat"], stat);
            match &first {
                None => first = Some(text),
                Some(t) => assert_eq!(
                    &text,
                    t,
                    "{stat}: {} ({fmt}) differs from the text input",
                    f.display()
                ),
            }
        }
    }
}

#[test]
fn counts_and_freq_data_kinds() {
    let dir = tempfile::tempdir().unwrap();
    // pulse-count increments (integers) of a quantised angle ramp
    let incr: Vec<i64> = samples(2000)
        .iter()
        .enumerate()
        .map(|(i, x)| 10 + (x * 40.0).floor() as i64 + (i % 3) as i64)
        .collect();
    let txt: String = incr.iter().map(|c| format!("{c}\n")).collect();
    let f = write(dir.path(), "c.txt", txt.as_bytes());
    let (j, _) = run_json(
        &[
            "allan",
            "--input",
            p(&f),
            "--data",
            "counts",
            "--tau0",
            "0.01",
            "--stat",
            "adev",
        ],
        dir.path(),
        "counts",
    );
    let inc_f: Vec<f64> = incr.iter().map(|&c| c as f64).collect();
    let ph = Phase::from_samples(&inc_f, DataKind::Counts, 0.01).unwrap();
    assert!(matches!(ph, Phase::Counts(_)));
    let lib = allan::compute(
        &ph,
        Stat::Adev,
        0.01,
        TauSet::Octave,
        &AllanOptions::default(),
    )
    .unwrap();
    let devs: Vec<f64> = j["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|q| q["dev"].as_f64().unwrap())
        .collect();
    assert_eq!(devs.len(), lib.points.len());
    assert!(
        devs.iter().zip(&lib.points).all(|(a, b)| close(*a, b.dev)),
        "{devs:?}"
    );
    // N increments give N + 1 phase points: adev n at m = 1 is N - 1
    assert_eq!(j["points"][0]["n"].as_u64(), Some(incr.len() as u64 - 1));

    // frequency input integrates to phase (N + 1 points): oadev n at m = 1 is N - 1
    let y = samples(500);
    let f = write(dir.path(), "y.txt", text_of(&y).as_bytes());
    let (j, _) = run_json(
        &["allan", "--input", p(&f), "--data", "freq", "--tau0", "2"],
        dir.path(),
        "freq",
    );
    assert_eq!(j["points"][0]["n"].as_u64(), Some(499));
    assert_eq!(j["points"][1]["tau_s"].as_f64(), Some(4.0));
}

#[test]
fn every_stat_and_tau_set_runs_and_table_prints() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "x.txt", text_of(&samples(600)).as_bytes());
    for stat in ["oadev", "adev", "mdev", "hdev", "ohdev", "totdev"] {
        for taus in ["octave", "decade", "all"] {
            let (j, _) = run_json(
                &[
                    "allan",
                    "--input",
                    p(&f),
                    "--data",
                    "phase",
                    "--tau0",
                    "1",
                    "--stat",
                    stat,
                    "--taus",
                    taus,
                ],
                dir.path(),
                "t",
            );
            let n = j["points"].as_array().unwrap().len();
            assert!(n >= 3, "{stat} {taus}: {n} points");
        }
    }
    let o = sagnac(&[
        "allan",
        "--input",
        p(&f),
        "--data",
        "phase",
        "--tau0",
        "1",
        "--stat",
        "mdev",
        "--confidence",
        "0.95",
    ]);
    assert!(o.status.success());
    let out = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert!(
        lines[0].starts_with("# mdev of") && lines[0].contains("95.0 % confidence"),
        "{out}"
    );
    assert!(
        lines[1]
            .split_whitespace()
            .eq(["tau_s", "m", "n", "alpha", "ci_lo", "dev", "ci_hi", "edf"])
    );
    assert_eq!(lines.len(), 2 + 8, "{out}"); // mdev: m = 1..128 (128 * 4 < 599)
}

fn fails_with(args: &[&str], needles: &[&str]) {
    let o = sagnac(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(2),
        "expected exit 2 for {args:?}; stderr: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "stderr lacks {n:?}: {err}");
    }
}

#[test]
fn bad_inputs_exit_2_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good = write(d, "good.txt", b"1\n2\n3\n4\n5\n6\n7\n8\n9\n10\n");
    let empty = write(d, "empty.txt", b"# only a comment\n\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&empty),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["empty.txt", "no samples"],
    );
    let bad = write(d, "bad.txt", b"1.0\n2.0\n\n# c\n3.0x\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&bad),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["bad.txt", "line 5", "\"3.0x\""],
    );
    let nan = write(d, "nan.txt", b"1\n2\nnan\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&nan),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["nan.txt", "line 3", "not finite"],
    );
    // --column on a one-value-per-line text file is a mistake, not ignored
    fails_with(
        &[
            "allan",
            "--input",
            p(&nan),
            "--format",
            "text",
            "--column",
            "x",
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["--column does not apply", "no columns"],
    );
    // finite but huge: its square would overflow the variances
    let huge = write(d, "huge.txt", b"1\n2\n3\n1e300\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&huge),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["huge.txt", "line 4", "out of range", "1e300"],
    );
    let frac = write(d, "frac.txt", b"1\n2\n3\n4.5\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&frac),
            "--data",
            "counts",
            "--tau0",
            "1",
        ],
        &["frac.txt", "line 4", "integer"],
    );
    fails_with(
        &[
            "allan",
            "--input",
            p(&good),
            "--data",
            "phase",
            "--tau0",
            "0",
        ],
        &["tau0"],
    );
    fails_with(
        &[
            "allan",
            "--input",
            p(&good),
            "--data",
            "phase",
            "--tau0",
            "-1",
        ],
        &["tau0"],
    );
    fails_with(
        &[
            "allan",
            "--input",
            p(&good),
            "--data",
            "phase",
            "--tau0",
            "nan",
        ],
        &["tau0"],
    );
    let csv = write(d, "c.csv", b"a,b\n1,2\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&csv),
            "--data",
            "phase",
            "--tau0",
            "1",
            "--format",
            "csv",
            "--column",
            "z",
        ],
        &["c.csv", "\"z\"", "\"a\", \"b\""],
    );
    let odd = write(d, "odd.f64", &[0u8; 20]);
    fails_with(
        &[
            "allan",
            "--input",
            p(&odd),
            "--data",
            "phase",
            "--tau0",
            "1",
            "--format",
            "f64le",
        ],
        &["odd.f64", "20 bytes"],
    );
    let missing = d.join("missing.txt");
    fails_with(
        &[
            "allan",
            "--input",
            p(&missing),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["missing.txt"],
    );
    let short = write(d, "short.txt", b"1\n2\n3\n");
    fails_with(
        &[
            "allan",
            "--input",
            p(&short),
            "--data",
            "phase",
            "--tau0",
            "1",
        ],
        &["short.txt", "too few"],
    );
    fails_with(
        &[
            "allan",
            "--input",
            p(&good),
            "--data",
            "phase",
            "--tau0",
            "1",
            "--engine",
            "streaming",
            "--stat",
            "mdev",
        ],
        &["--engine streaming computes --stat oadev"],
    );
    fails_with(
        &[
            "allan",
            "--input",
            p(&good),
            "--data",
            "angle",
            "--tau0",
            "1",
        ],
        &["angle"],
    ); // clap usage error
}

#[test]
fn streaming_engine_equals_batch_oadev() {
    // the streaming accumulators read the file block by block; below the
    // full-overlap cap they must equal the batch OADEV (relative 1e-12), with the
    // same term counts, for phase, frequency and count data
    let dir = tempfile::tempdir().unwrap();
    let v = samples(300_000);
    let phase = write(dir.path(), "phase.txt", text_of(&v).as_bytes());
    let freq: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) * 1e3).collect();
    let freq = write(dir.path(), "freq.txt", text_of(&freq).as_bytes());
    let counts: Vec<f64> = v.iter().map(|x| (x * 1e3).round()).collect();
    let counts = write(dir.path(), "counts.txt", text_of(&counts).as_bytes());
    for (file, kind) in [(&phase, "phase"), (&freq, "freq"), (&counts, "counts")] {
        let base = [
            "allan",
            "--input",
            p(file),
            "--data",
            kind,
            "--tau0",
            "0.01",
        ];
        let (b, _) = run_json(&base, dir.path(), &format!("{kind}-batch"));
        let mut sa = base.to_vec();
        sa.extend_from_slice(&["--engine", "streaming"]);
        let (st, _) = run_json(&sa, dir.path(), &format!("{kind}-stream"));
        let bp = b["points"].as_array().unwrap();
        let sp = st["points"].as_array().unwrap();
        assert_eq!(st["stat"], "oadev");
        assert!(
            sp.len() >= bp.len() - 1 && !bp.is_empty(),
            "{kind}: {} vs {} points",
            sp.len(),
            bp.len()
        );
        for q in bp {
            let m = q["m"].as_u64().unwrap();
            let Some(r) = sp.iter().find(|r| r["m"].as_u64() == Some(m)) else {
                continue;
            };
            assert_eq!(q["n"], r["n"], "{kind} m={m}: term counts");
            let (x, y) = (q["dev"].as_f64().unwrap(), r["dev"].as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-12 * x.abs(),
                "{kind} m={m}: batch {x} streaming {y}"
            );
        }
    }
}

#[test]
fn both_engines_accept_the_same_inputs_and_taus() {
    // the streaming engine follows the batch engine's tau range (AllanTools'
    // stop ratio): too few points is the same error, and the largest m agrees
    let dir = tempfile::tempdir().unwrap();
    for n in [3usize, 5] {
        let few = write(
            dir.path(),
            &format!("few{n}.txt"),
            text_of(&samples(n)).as_bytes(),
        );
        for engine in ["batch", "streaming"] {
            fails_with(
                &[
                    "allan",
                    "--input",
                    p(&few),
                    "--data",
                    "phase",
                    "--tau0",
                    "1",
                    "--engine",
                    engine,
                ],
                &["phase points are too few (need at least 6)"],
            );
        }
    }
    for n in [6usize, 7, 100, 1000] {
        let f = write(
            dir.path(),
            &format!("n{n}.txt"),
            text_of(&samples(n)).as_bytes(),
        );
        let base = ["allan", "--input", p(&f), "--data", "phase", "--tau0", "1"];
        let (b, _) = run_json(&base, dir.path(), &format!("b{n}"));
        let mut sa = base.to_vec();
        sa.extend_from_slice(&["--engine", "streaming"]);
        let (s, _) = run_json(&sa, dir.path(), &format!("s{n}"));
        let ms = |j: &Value| -> Vec<u64> {
            j["points"]
                .as_array()
                .unwrap()
                .iter()
                .map(|q| q["m"].as_u64().unwrap())
                .collect()
        };
        assert_eq!(ms(&b), ms(&s), "n = {n}");
    }
}
