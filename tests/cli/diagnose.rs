//! `sagnac diagnose` end to end: the binary on recordings made by
//! `sagnac simulate` (CSV, MCAP, frame capture), the JSON contract
//! (keys, types, term names that are model-file keys), the SVG report and the
//! updated model file; and clear errors (exit code 2) on bad inputs.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

use crate::support::{self, PAPER_GYRO, bin};

const MODEL: &str = "[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
[noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\n";

/// The model plus a short-correlation Gauss-Markov term the model lacks.
const TRUTH: &str = "[gyro]\nsample_rate_hz = 500.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
[noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.001\n\
[[noise.gauss_markov]]\nsigma_dph = 0.06\ntau_c_s = 0.5\n";

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstdout: {}\nstderr: {}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn simulate(model: &Path, out: &Path, format: &str, dur: &str, seed: &str) {
    ok(&bin()
        .args(["simulate", "--model"])
        .arg(model)
        .args([
            "--duration-s",
            dur,
            "--seed",
            seed,
            "--format",
            format,
            "--out",
        ])
        .arg(out)
        .output()
        .unwrap());
}

/// `sagnac diagnose` of `dir/recording` against `dir/model.toml`, the JSON
/// verdict to `dir/out.json`.
fn diagnose(dir: &Path, recording: &str, format: &str) -> Command {
    let mut c = bin();
    c.args(["diagnose", "--model"])
        .arg(dir.join("model.toml"))
        .arg("--recording")
        .arg(dir.join(recording))
        .args(["--format", format, "--json"])
        .arg(dir.join("out.json"));
    c
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

/// Every key and type of the contract.
fn check_contract(j: &Value) {
    let obj = j.as_object().expect("top-level object");
    for k in [
        "verdict",
        "mismatch_regions",
        "parameter_changes",
        "added_terms",
        "fit_before",
        "fit_after",
        "sagnac_version",
        "input",
        "units",
    ] {
        assert!(obj.contains_key(k), "missing key {k}");
    }
    assert_eq!(j["sagnac_version"], env!("CARGO_PKG_VERSION"));
    for (key, unit, _) in sagnac::units::COEFFICIENTS {
        assert_eq!(j["units"][key], unit, "{key}");
    }
    assert!(j["units"]["mismatch_regions.tau_min_s, tau_max_s"] == "s");
    let v = j["verdict"].as_str().unwrap();
    assert!(v == "consistent" || v == "mismatch", "verdict {v}");
    for r in j["mismatch_regions"].as_array().unwrap() {
        let (a, b) = (num(&r["tau_min_s"]), num(&r["tau_max_s"]));
        assert!(0.0 < a && a <= b, "region {r}");
        assert!(num(&r["max_z"]).abs() > 0.0);
    }
    for c in j["parameter_changes"].as_array().unwrap() {
        assert!(c["term"].is_string());
        num(&c["model"]);
        num(&c["fitted"]);
        let ci = c["ci95"].as_array().unwrap();
        assert_eq!(ci.len(), 2);
        assert!(num(&ci[0]) <= num(&ci[1]));
    }
    for a in j["added_terms"].as_array().unwrap() {
        let t = a["term"].as_str().unwrap();
        assert!(
            [
                "gauss_markov",
                "sinusoid",
                "random_telegraph",
                "rrw_dphsh",
                "rate_ramp_dphh",
                "bias_instability_dph",
                "thermal",
                "readout_filter"
            ]
            .iter()
            .any(|k| t.starts_with(k)),
            "term {t} is not a model-file key"
        );
        assert!(a["params"].as_object().is_some_and(|p| !p.is_empty()));
        assert!(a["explanation"].as_str().is_some_and(|e| !e.is_empty()));
    }
    assert!(num(&j["fit_before"]["chi2_per_dof"]) > 0.0);
    assert!(num(&j["fit_after"]["chi2_per_dof"]) > 0.0);
}

#[test]
fn csv_recording_with_a_hidden_gauss_markov_gives_the_contract_json_svg_and_model() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("model.toml"), MODEL).unwrap();
    std::fs::write(p.join("truth.toml"), TRUTH).unwrap();
    simulate(&p.join("truth.toml"), &p.join("rec.csv"), "csv", "600", "5");
    let out = diagnose(p, "rec.csv", "csv")
        .arg("--report")
        .arg(p.join("out.svg"))
        .arg("--write-model")
        .arg(p.join("new.toml"))
        .output()
        .unwrap();
    ok(&out);
    let j: Value =
        serde_json::from_str(&std::fs::read_to_string(p.join("out.json")).unwrap()).unwrap();
    check_contract(&j);
    assert_eq!(j["verdict"], "mismatch", "{j:#}");
    let gm = j["added_terms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["term"] == "gauss_markov")
        .unwrap_or_else(|| panic!("no gauss_markov added: {j:#}"));
    // truth sigma 0.06 deg/h, tau_c 0.5 s: within a factor 1.5 (a 10-minute record)
    let s = num(&gm["params"]["sigma_dph"]);
    let tc = num(&gm["params"]["tau_c_s"]);
    assert!((0.04..0.09).contains(&s), "sigma_dph {s}");
    assert!((0.33..0.75).contains(&tc), "tau_c_s {tc}");
    assert!(!j["mismatch_regions"].as_array().unwrap().is_empty());
    assert!(num(&j["fit_after"]["chi2_per_dof"]) < num(&j["fit_before"]["chi2_per_dof"]));
    // the SVG report and the updated model, which parses and holds the new term
    let svg = std::fs::read_to_string(p.join("out.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") || svg.starts_with("<?xml"),
        "not an SVG"
    );
    assert!(svg.trim_end().ends_with("</svg>"));
    // recording, old model (its Monte-Carlo band) and updated model on each panel
    for legend in ["recording", "model (95 % MC band)", "updated model"] {
        assert!(svg.matches(legend).count() >= 3, "legend {legend:?}");
    }
    assert!(svg.contains("opacity=\"0.15\""), "no shaded region");
    let new = std::fs::read_to_string(p.join("new.toml")).unwrap();
    let m = sagnac::model::GyroModel::from_toml_str(&new, "new.toml").unwrap();
    assert_eq!(m.noise.gauss_markov.len(), 1);
}

#[test]
fn matched_mcap_and_frame_recordings_are_consistent_and_json_goes_to_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("model.toml"), MODEL).unwrap();
    for (format, file) in [("mcap", "rec.mcap"), ("frames", "rec.bin")] {
        simulate(&p.join("model.toml"), &p.join(file), format, "120", "8");
        let out = bin()
            .args(["diagnose", "--model"])
            .arg(p.join("model.toml"))
            .arg("--input")
            .arg(p.join(file))
            .args(["--format", format, "--json", "-"])
            .output()
            .unwrap();
        ok(&out);
        let j: Value = serde_json::from_slice(&out.stdout).unwrap();
        check_contract(&j);
        // the input settings used: the recording's own (its metadata record, the same as the model's here)
        let input = &j["input"];
        assert_eq!(
            (
                input["format"].as_str(),
                input["sample_rate_hz"].as_f64(),
                input["pulse_arcsec"].as_f64()
            ),
            (Some(format), Some(500.0), Some(1.21))
        );
        assert_eq!(input["model"].as_str(), p.join("model.toml").to_str());
        assert_eq!(input["path"].as_str(), p.join(file).to_str());
        assert_eq!(j["verdict"], "consistent", "{format}: {j:#}");
        assert!(j["added_terms"].as_array().unwrap().is_empty());
        assert!(j["parameter_changes"].as_array().unwrap().is_empty());
    }
}

fn fails_with(args: &[&std::ffi::OsStr], needle: &str) {
    let o = bin().arg("diagnose").args(args).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(needle), "stderr lacks {needle:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_inputs_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("model.toml"), MODEL).unwrap();
    std::fs::write(p.join("short.csv"), "counts\n1\n0\n1\n").unwrap();
    std::fs::write(p.join("bad.csv"), "counts\n1\nx\n").unwrap();
    std::fs::write(p.join("bad.toml"), "[gyro]\nsample_rate_hz = -1\n").unwrap();
    let m = p.join("model.toml");
    let j = p.join("o.json");
    let a = |v: &[&Path]| -> Vec<std::ffi::OsString> {
        vec![
            "--model".into(),
            v[0].into(),
            "--input".into(),
            v[1].into(),
            "--json".into(),
            v[2].into(),
        ]
    };
    let run = |v: &[&Path], needle: &str| {
        let args = a(v);
        let refs: Vec<&std::ffi::OsStr> = args.iter().map(|s| s.as_os_str()).collect();
        fails_with(&refs, needle);
    };
    run(&[&m, &p.join("missing.csv"), &j], "missing.csv");
    run(&[&m, &p.join("short.csv"), &j], "at least 4096");
    run(&[&m, &p.join("bad.csv"), &j], "bad.csv");
    run(&[&p.join("bad.toml"), &p.join("short.csv"), &j], "model");
    // unusable output paths are refused before the diagnosis runs
    run(&[&m, &p.join("short.csv"), p], "is a directory");
    run(
        &[&m, &p.join("short.csv"), &p.join("no/such/o.json")],
        "is not an existing directory",
    );
    assert!(!j.exists());
}

#[test]
fn a_model_is_written_only_when_it_fits_better() {
    // A readout-only model against the paper gyro: the diagnosis may propose
    // changes, but `--write-model` gets no model whose chi2/dof is worse than the
    // original's and above an acceptable fit.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("c10.csv");
    simulate(Path::new(PAPER_GYRO), &csv, "csv", "10", "1");
    let model = dir.path().join("g.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\n",
    )
    .unwrap();
    let (json, new) = (dir.path().join("out.json"), dir.path().join("new.toml"));
    let r = bin()
        .arg("diagnose")
        .arg("--model")
        .arg(&model)
        .arg("--input")
        .arg(&csv)
        .arg("--json")
        .arg(&json)
        .arg("--write-model")
        .arg(&new)
        .output()
        .unwrap();
    let (out, err) = (
        String::from_utf8_lossy(&r.stdout),
        String::from_utf8_lossy(&r.stderr),
    );
    assert!(r.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let before = v["fit_before"]["chi2_per_dof"].as_f64().unwrap();
    let after = v["fit_after"]["chi2_per_dof"].as_f64().unwrap();
    // (an update whose chi2/dof rises but stays acceptable, <= 1.5, is still offered)
    let withheld = after > before && after > 1.5;
    assert_eq!(
        new.exists(),
        !withheld,
        "chi2/dof {before} -> {after}; stdout {out}; stderr {err}"
    );
    if withheld {
        assert!(
            out.contains("fits worse than the original") && err.contains("no model written"),
            "{out}\n{err}"
        );
    }
}

#[test]
fn a_constant_recording_is_refused_not_called_consistent() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("dead.csv");
    let mut text = String::from("counts\n");
    for _ in 0..20_000 {
        text.push_str("0\n");
    }
    std::fs::write(&csv, text).unwrap();
    let r = bin()
        .args(["diagnose", "--model", PAPER_GYRO, "--input"])
        .arg(&csv)
        .args(["--json", "-"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("dead.csv: all 20000 increments are 0") && !err.contains("panicked"),
        "{err}"
    );
}

/// A recording whose sample rate (from the MCAP's dt_ns) differs from the
/// model's: the diagnosis runs at the recording's rate, says so, and a written
/// model carries the rate it was fitted at (not the model file's).
#[test]
fn a_recording_at_another_rate_is_noted_and_the_written_model_has_its_rate() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("model.toml"), MODEL.replace("500.0", "100.0")).unwrap();
    std::fs::write(p.join("truth.toml"), TRUTH).unwrap();
    simulate(
        &p.join("truth.toml"),
        &p.join("rec.mcap"),
        "mcap",
        "300",
        "8",
    );
    let out = diagnose(p, "rec.mcap", "mcap")
        .arg("--write-model")
        .arg(p.join("new.toml"))
        .output()
        .unwrap();
    ok(&out);
    // the notes go to stdout when the JSON goes to a file
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("sample rate (500 Hz) differs from the model's (100 Hz)"),
        "{text}"
    );
    let j: Value =
        serde_json::from_str(&std::fs::read_to_string(p.join("out.json")).unwrap()).unwrap();
    assert_eq!(j["verdict"], "mismatch", "{j:#}");
    let new = std::fs::read_to_string(p.join("new.toml")).unwrap();
    let m = sagnac::model::GyroModel::from_toml_str(&new, "new.toml").unwrap();
    assert_eq!(m.gyro.sample_rate_hz, 500.0, "{new}");
}

/// `--report` alone is enough (the summary goes to stdout); the figure says
/// the verdict in words and lists the findings; with neither `--json` nor
/// `--report` there is nothing to write, and that is said before any work.
#[test]
fn the_report_alone_suffices_and_the_figure_states_verdict_and_findings() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("model.toml"), MODEL).unwrap();
    std::fs::write(p.join("truth.toml"), TRUTH).unwrap();
    simulate(&p.join("truth.toml"), &p.join("rec.csv"), "csv", "600", "5");
    let out = bin()
        .args(["diagnose", "--model"])
        .arg(p.join("model.toml"))
        .arg("--input")
        .arg(p.join("rec.csv"))
        .arg("--report")
        .arg(p.join("out.svg"))
        .output()
        .unwrap();
    ok(&out);
    assert!(
        String::from_utf8_lossy(&out.stdout).starts_with("verdict: Mismatch"),
        "{out:?}"
    );
    let svg = std::fs::read_to_string(p.join("out.svg")).unwrap();
    assert!(
        svg.contains("Verdict: mismatch. The recording departs from the model at tau"),
        "no verdict sentence"
    );
    assert!(
        svg.contains("Added: gauss_markov: sigma_dph"),
        "no finding on the figure"
    );
    assert!(svg.contains("with the updated model"), "no chi2/dof after");
    // one legend per panel, drawn above the plotting area: each legend's
    // "recording" label sits higher than every data point of its panel's row
    // (y, content) of every text element
    let texts: Vec<(f64, String)> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| {
            let (tag, rest) = t.split_once('>')?;
            let y = tag.split(" y=\"").nth(1)?.split('"').next()?.parse().ok()?;
            Some((y, rest.split("</text>").next()?.trim().to_string()))
        })
        .collect();
    let mut legend_y: Vec<f64> = texts
        .iter()
        .filter(|t| t.1 == "recording")
        .map(|t| t.0)
        .collect();
    assert_eq!(legend_y.len(), 4, "one legend per panel");
    legend_y.sort_by(f64::total_cmp);
    let (top, bottom) = (legend_y[0], legend_y[3]);
    let circles: Vec<f64> = svg
        .split("<circle")
        .skip(1)
        // the data points (radius 3; the legend's marker has radius 4)
        .filter(|c| c.split("/>").next().is_some_and(|t| t.contains("r=\"3\"")))
        .filter_map(|c| c.split("cy=\"").nth(1)?.split('"').next()?.parse().ok())
        .collect();
    assert!(circles.len() > 20, "{} data points", circles.len());
    for cy in circles {
        let row_legend = if cy < bottom - 5.0 { top } else { bottom };
        assert!(
            cy > row_legend + 10.0,
            "a data point at y {cy} is not below its legend at y {row_legend}"
        );
    }
    fails_with(
        &[
            "--model".as_ref(),
            p.join("model.toml").as_os_str(),
            "--input".as_ref(),
            p.join("rec.csv").as_os_str(),
        ],
        "nothing to write",
    );
}

/// A rate-output gyro without a filter, and the truth with an anti-alias filter.
const RATE_MODEL: &str = "[gyro]\nsample_rate_hz = 200.0\noutput = \"rate\"\nrate_lsb_dps = 0.01\n\
[noise]\narw_dpsh = 0.5\nbias_instability_dph = 5.0\n";

#[test]
fn a_rate_column_is_read_with_column_and_unit_and_its_filter_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("model.toml"), RATE_MODEL).unwrap();
    let truth = format!("{RATE_MODEL}[readout_filter]\nkind = \"first_order\"\ncorner_hz = 20.0\n");
    std::fs::write(dir.path().join("truth.toml"), truth).unwrap();
    simulate(
        &dir.path().join("truth.toml"),
        &dir.path().join("sim.csv"),
        "csv",
        "300",
        "5",
    );
    // the column under another name, as a real recording has it
    let text = std::fs::read_to_string(dir.path().join("sim.csv")).unwrap();
    assert!(text.starts_with("rate_dps\n"), "{}", &text[..40]);
    std::fs::write(
        dir.path().join("rec.csv"),
        text.replacen("rate_dps", "gyro_x_dps", 1),
    )
    .unwrap();
    let mut c = diagnose(dir.path(), "rec.csv", "csv");
    c.args(["--column", "gyro_x_dps", "--unit", "dps", "--write-model"])
        .arg(dir.path().join("new.toml"));
    ok(&c.output().unwrap());
    let j: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out.json")).unwrap())
            .unwrap();
    check_contract(&j);
    assert_eq!(j["verdict"], "mismatch");
    assert_eq!(j["input"]["column"], "gyro_x_dps");
    assert_eq!(j["input"]["unit"], "dps");
    assert_eq!(num(&j["input"]["rate_lsb_dps"]), 0.01);
    let f = j["added_terms"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["term"] == "readout_filter")
        .expect("readout_filter");
    assert_eq!(f["params"]["kind"], "first_order");
    let ci = f["ci95"]["corner_hz"].as_array().unwrap();
    assert!(
        num(&ci[0]) <= 20.0 && 20.0 <= num(&ci[1]),
        "truth 20 Hz outside {ci:?}"
    );
    let written = std::fs::read_to_string(dir.path().join("new.toml")).unwrap();
    assert!(
        written.contains("[readout_filter]") && written.contains("first_order"),
        "{written}"
    );
    sagnac::model::GyroModel::from_toml_str(&written, "written").unwrap();
    // the wrong kind of recording for the model, either way, is a clear error
    let model = dir.path().join("model.toml");
    let rec = dir.path().join("rec.csv");
    let out = dir.path().join("x.json");
    fails_with(
        &[
            "--model".as_ref(),
            model.as_os_str(),
            "--input".as_ref(),
            rec.as_os_str(),
            "--json".as_ref(),
            out.as_os_str(),
        ],
        "--column NAME --unit dps|dph|rad_s",
    );
    std::fs::write(dir.path().join("counts.toml"), MODEL).unwrap();
    let counts_model = dir.path().join("counts.toml");
    fails_with(
        &[
            "--model".as_ref(),
            counts_model.as_os_str(),
            "--input".as_ref(),
            rec.as_os_str(),
            "--column".as_ref(),
            "gyro_x_dps".as_ref(),
            "--unit".as_ref(),
            "dps".as_ref(),
            "--json".as_ref(),
            out.as_os_str(),
        ],
        "pulse counter",
    );
    // a misspelt column names the file
    let mut c = diagnose(dir.path(), "rec.csv", "csv");
    c.args(["--column", "gyro_q_dps", "--unit", "dps"]);
    let o = c.output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("gyro_q_dps") && err.contains("rec.csv"),
        "{err}"
    );
}

/// The ADIS16405's z gyro carries narrowband noise near 20 Hz (13-20 times the
/// white PSD, 1-2 Hz wide; `scripts/real-spectrum`), its x gyro none: the
/// diagnosis fits a resonance on the z axis (not a line, not a filter bent to
/// imitate it), and the fit improves; on the x axis it adds none, and names
/// the readout (a 2-sample average with white angle noise after it).
#[test]
fn the_adis_z_resonance_is_fitted_and_the_fit_improves() {
    let Some(data) = support::shared_data() else {
        return;
    };
    let rec = data.join("real/adis16405_ucalgary/adis16405_rep1_gyro_dps.csv.gz");
    let model = support::repo().join("config/adis16405_datasheet.toml");
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("d.json");
    for (axis, expect) in [("z", true), ("x", false)] {
        let o = bin()
            .args(["diagnose", "--model"])
            .arg(&model)
            .arg("--input")
            .arg(&rec)
            .args([
                "--column",
                &format!("gyro_{axis}_dps"),
                "--unit",
                "dps",
                "--json",
            ])
            .arg(&json)
            .output()
            .unwrap();
        ok(&o);
        let out = String::from_utf8_lossy(&o.stdout);
        let j: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let res: Vec<&Value> = j["added_terms"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["term"] == "resonance")
            .collect();
        assert_eq!(!res.is_empty(), expect, "axis {axis}: {out}");
        // What narrowband noise is left unexplained lies outside the main
        // mode's half-power span (on x: nothing at all).
        let excess_hz: Vec<f64> = out
            .lines()
            .filter_map(|l| l.trim().strip_prefix("Narrowband excess at "))
            .map(|l| l.split(' ').next().unwrap().parse().unwrap())
            .collect();
        assert!(expect || excess_hz.is_empty(), "axis {axis}: {out}");
        assert!(
            !excess_hz.iter().any(|f| (19.3..20.8).contains(f)),
            "axis {axis}: {out}"
        );
        if res.is_empty() {
            // x: the readout, a 2-sample average with about 5 arcsec of white
            // angle noise after it, fitted together (docs/diagnose.md), and
            // an updated model that fits (chi2/dof 512 -> 1.2)
            let f = j["added_terms"]
                .as_array()
                .unwrap()
                .iter()
                .find(|a| a["term"] == "readout_filter");
            let f = f.unwrap_or_else(|| panic!("axis {axis}: no readout_filter: {out}"));
            assert_eq!(f["params"]["kind"], "moving_average", "{f}");
            assert_eq!(num(&f["params"]["length"]), 2.0, "{f}");
            let q = j["parameter_changes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["term"] == "quantization_arcsec");
            let q =
                num(&q.unwrap_or_else(|| panic!("axis {axis}: Q not refitted: {out}"))["fitted"]);
            assert!((4.5..5.6).contains(&q), "axis {axis}: Q {q}");
            let after = j["fit_after"]["chi2_per_dof"].as_f64().unwrap();
            assert!(after < 2.0, "axis {axis}: chi2/dof after {after}");
            continue;
        }
        // The Welch spectrum of run 1 z peaks at 19.80 Hz, half power over
        // 19.3-20.8 Hz (docs/diagnose.md, scripts/real-spectrum): the first
        // (strongest) resonance is there.
        let p = |r: &Value, k: &str| r["params"][k].as_f64().unwrap();
        assert!((19.3..20.8).contains(&p(res[0], "centre_hz")), "{}", res[0]);
        assert!((0.4..2.0).contains(&p(res[0], "width_hz")), "{}", res[0]);
        // (the intervals are widened by sqrt(chi2/dof) of a model that still
        // does not fit, so a width's may reach zero; a centre's and a
        // sigma's stay above it)
        for r in &res {
            for k in ["centre_hz", "width_hz", "sigma_dph"] {
                let ci = &r["ci95"][k];
                let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
                assert!(lo <= p(r, k) && p(r, k) <= hi, "{k}: {r}");
                assert!(k == "width_hz" || lo > 0.0, "{k}: {r}");
            }
        }
        let (before, after) = (
            j["fit_before"]["chi2_per_dof"].as_f64().unwrap(),
            j["fit_after"]["chi2_per_dof"].as_f64().unwrap(),
        );
        // Without the resonance the updated model fitted worse than the
        // datasheet's (576 -> 604); with it, several times better.
        assert!(after < before / 4.0, "{before} -> {after}");
    }
}
