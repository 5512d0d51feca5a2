//! Prometheus metrics: exact names, HELP/TYPE lines, values after updates, and
//! `promtool check metrics` (the Prometheus project's own linter) on the exposition.

use std::collections::BTreeMap;
use std::io::Write;
use std::process::{Command, Stdio};

use sagnac::daemon::telemetry::{LATENCY_BUCKETS_S, Telemetry};
use sagnac::sink::metrics::{AllanChannel, Bounds95, FrameErrorKind, GyroInfo, Metrics, tau_label};

/// Parse the sample lines of a text exposition: "name{labels}" -> value.
pub fn samples(text: &str) -> BTreeMap<String, f64> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (k, v) = l.rsplit_once(' ').expect("sample line");
            let v = if v == "NaN" {
                f64::NAN
            } else {
                v.parse().expect("value")
            };
            (k.to_string(), v)
        })
        .collect()
}

fn promtool(exposition: &str) -> (bool, String) {
    let mut child = Command::new("promtool")
        .args(["check", "metrics"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| {
            panic!("promtool is required (apt-get install prometheus; scripts/install-peers): {e}")
        });
    child
        .stdin
        .take()
        .unwrap()
        .write_all(exposition.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success() && text.trim().is_empty(), text)
}

fn unit() -> GyroInfo {
    GyroInfo {
        label: "gyro".into(),
        serial_number: "RLG-0042".into(),
        model: "RLG-28 \"A\"".into(),
    }
}

fn filled() -> Metrics {
    let metrics = Metrics::new().unwrap();
    fill(&metrics, &unit());
    metrics
}

fn fill(metrics: &Metrics, info: &GyroInfo) {
    let m = metrics.gyro(info);
    m.add_samples(1000);
    m.add_samples(24);
    m.add_frames_decoded(1020);
    m.add_frame_errors(FrameErrorKind::Crc, 3);
    m.add_frame_errors(FrameErrorKind::FalseSync, 1);
    m.add_lost_samples(4);
    metrics.add_bytes_read(16_384);
    m.set_qn_arcsec(Bounds95 {
        estimate: Some(0.35),
        lower95: Some(0.3),
        upper95: Some(0.41),
    });
    m.set_arw_dpsh(Bounds95 {
        estimate: Some(0.002),
        lower95: Some(0.0018),
        upper95: Some(0.0023),
    });
    m.set_bias_instability_dph(Bounds95 {
        estimate: None,
        lower95: None,
        upper95: Some(0.01),
    });
    m.set_rrw_dphsh(Bounds95 {
        estimate: None,
        lower95: None,
        upper95: Some(0.2),
    });
    m.set_rate_ramp_dphh(Bounds95 {
        estimate: Some(-0.03),
        lower95: Some(-0.05),
        upper95: Some(-0.01),
    });
    let taus: Vec<f64> = (0..8).map(|k| 0.001 * 2f64.powi(k)).collect();
    let devs: Vec<f64> = taus.iter().map(|t| 0.5 / t).collect();
    m.set_allan_curve(AllanChannel::Raw, &taus, &devs).unwrap();
    m.set_allan_curve(AllanChannel::Clean, &taus[..4], &devs[..4])
        .unwrap();
    m.set_temperature_c(Some(31.5));
    m.set_processing_lag_s(0.125);
    m.add_outliers(4);
    m.add_outliers(3);
    m.add_bias_steps(1);
    m.set_warmup(true, Some((-0.3, 900.0)));
    metrics.set_recording_bytes(123_456);
}

#[test]
fn exposition_passes_promtool() {
    let text = filled().encode();
    let (ok, out) = promtool(&text);
    assert!(ok, "promtool check metrics:\n{out}\n---\n{text}");
    // A fresh (empty) registry too.
    let (ok, out) = promtool(&Metrics::new().unwrap().encode());
    assert!(ok, "fresh metrics: {out}");
}

#[test]
fn promtool_catches_bad_names() {
    // The check above can fail: promtool rejects a counter without `_total` and a
    // gauge named `*_count`.
    let bad = "# HELP sagnac_frames counter\n# TYPE sagnac_frames counter\nsagnac_frames 1\n\
               # HELP sagnac_x_count gauge\n# TYPE sagnac_x_count gauge\nsagnac_x_count 1\n";
    let (ok, out) = promtool(bad);
    assert!(!ok, "promtool accepted bad names: {out}");
}

/// The families whose every series carries the `gyro` label, and the daemon-wide ones.
const PER_GYRO: [&str; 21] = [
    "sagnac_samples_total",
    "sagnac_frames_decoded_total",
    "sagnac_frame_errors_total",
    "sagnac_lost_samples_total",
    "sagnac_qn_arcseconds",
    "sagnac_arw_degrees_per_root_hour",
    "sagnac_bias_instability_degrees_per_hour",
    "sagnac_rrw_degrees_per_hour_per_root_hour",
    "sagnac_rate_ramp_degrees_per_hour_squared",
    "sagnac_allan_deviation_degrees_per_hour",
    "sagnac_temperature_celsius",
    "sagnac_processing_lag_seconds",
    "sagnac_outliers_total",
    "sagnac_bias_steps_total",
    "sagnac_warmup_active",
    "sagnac_warmup_amplitude_dph",
    "sagnac_warmup_tau_seconds",
    "sagnac_gyro_info",
    "sagnac_spec_verdict",
    "sagnac_spec_limit",
    "sagnac_spec_decision_eta_seconds",
];
const DAEMON_WIDE: [&str; 3] = [
    "sagnac_bytes_read_total",
    "sagnac_recording_bytes",
    "sagnac_build_info",
];

/// The metric name of a sample key `name{labels}` (histogram suffixes stripped).
fn family(key: &str) -> &str {
    let name = key.split('{').next().unwrap();
    ["_bucket", "_sum", "_count"]
        .iter()
        .find_map(|s| name.strip_suffix(s))
        .unwrap_or(name)
}

#[test]
fn names_help_and_values() {
    let text = filled().encode();
    for (name, kind) in [
        ("sagnac_samples_total", "counter"),
        ("sagnac_frames_decoded_total", "counter"),
        ("sagnac_frame_errors_total", "counter"),
        ("sagnac_lost_samples_total", "counter"),
        ("sagnac_bytes_read_total", "counter"),
        ("sagnac_qn_arcseconds", "gauge"),
        ("sagnac_arw_degrees_per_root_hour", "gauge"),
        ("sagnac_bias_instability_degrees_per_hour", "gauge"),
        ("sagnac_allan_deviation_degrees_per_hour", "gauge"),
        ("sagnac_temperature_celsius", "gauge"),
        ("sagnac_processing_lag_seconds", "gauge"),
        ("sagnac_recording_bytes", "gauge"),
        ("sagnac_rrw_degrees_per_hour_per_root_hour", "gauge"),
        ("sagnac_rate_ramp_degrees_per_hour_squared", "gauge"),
        ("sagnac_build_info", "gauge"),
        ("sagnac_gyro_info", "gauge"),
        ("sagnac_outliers_total", "counter"),
        ("sagnac_bias_steps_total", "counter"),
        ("sagnac_warmup_active", "gauge"),
        ("sagnac_warmup_amplitude_dph", "gauge"),
        ("sagnac_warmup_tau_seconds", "gauge"),
    ] {
        assert!(text.contains(&format!("# HELP {name} ")), "HELP {name}");
        assert!(
            text.contains(&format!("# TYPE {name} {kind}\n")),
            "TYPE {name} {kind}"
        );
    }
    let families = text.lines().filter(|l| l.starts_with("# TYPE ")).count();
    assert_eq!(
        families, 21,
        "exactly the twenty-one metrics (no spec without a spec):\n{text}"
    );
    let build = format!(
        "sagnac_build_info{{version=\"{}\"}} 1\n",
        env!("CARGO_PKG_VERSION")
    );
    assert!(text.contains(&build), "{build} missing in\n{text}");
    // the model name's quotes are escaped as the exposition format wants
    let info =
        "sagnac_gyro_info{gyro=\"gyro\",model=\"RLG-28 \\\"A\\\"\",serial_number=\"RLG-0042\"} 1\n";
    assert!(text.contains(info), "{info} missing in\n{text}");

    let s = samples(&text);
    let get = |k: &str| *s.get(k).unwrap_or_else(|| panic!("{k} missing in\n{text}"));
    assert_eq!(get("sagnac_samples_total{gyro=\"gyro\"}"), 1024.0);
    assert_eq!(get("sagnac_frames_decoded_total{gyro=\"gyro\"}"), 1020.0);
    assert_eq!(
        get("sagnac_frame_errors_total{gyro=\"gyro\",kind=\"crc\"}"),
        3.0
    );
    assert_eq!(
        get("sagnac_frame_errors_total{gyro=\"gyro\",kind=\"false_sync\"}"),
        1.0
    );
    assert_eq!(
        get("sagnac_frame_errors_total{gyro=\"gyro\",kind=\"truncated\"}"),
        0.0
    );
    assert_eq!(get("sagnac_lost_samples_total{gyro=\"gyro\"}"), 4.0);
    assert_eq!(get("sagnac_bytes_read_total"), 16_384.0);
    assert_eq!(
        get("sagnac_qn_arcseconds{bound=\"estimate\",gyro=\"gyro\"}"),
        0.35
    );
    assert_eq!(
        get("sagnac_qn_arcseconds{bound=\"lower95\",gyro=\"gyro\"}"),
        0.3
    );
    assert_eq!(
        get("sagnac_qn_arcseconds{bound=\"upper95\",gyro=\"gyro\"}"),
        0.41
    );
    assert_eq!(
        get("sagnac_arw_degrees_per_root_hour{bound=\"upper95\",gyro=\"gyro\"}"),
        0.0023
    );
    // Unknown bounds are absent, not zero.
    assert_eq!(
        get("sagnac_bias_instability_degrees_per_hour{bound=\"upper95\",gyro=\"gyro\"}"),
        0.01
    );
    assert!(!s.contains_key(
        "sagnac_bias_instability_degrees_per_hour{bound=\"estimate\",gyro=\"gyro\"}"
    ));
    assert_eq!(
        get("sagnac_rrw_degrees_per_hour_per_root_hour{bound=\"upper95\",gyro=\"gyro\"}"),
        0.2
    );
    assert_eq!(
        get("sagnac_rate_ramp_degrees_per_hour_squared{bound=\"estimate\",gyro=\"gyro\"}"),
        -0.03
    );
    assert_eq!(
        get("sagnac_rate_ramp_degrees_per_hour_squared{bound=\"lower95\",gyro=\"gyro\"}"),
        -0.05
    );
    assert_eq!(
        get(
            "sagnac_allan_deviation_degrees_per_hour{channel=\"raw\",gyro=\"gyro\",tau_seconds=\"0.128\"}"
        ),
        0.5 / 0.128
    );
    assert_eq!(
        get(
            "sagnac_allan_deviation_degrees_per_hour{channel=\"clean\",gyro=\"gyro\",tau_seconds=\"0.008\"}"
        ),
        0.5 / 0.008
    );
    let allan = |ch: &str| {
        s.keys()
            .filter(|k| {
                k.starts_with(&format!(
                    "sagnac_allan_deviation_degrees_per_hour{{channel=\"{ch}\""
                ))
            })
            .count()
    };
    assert_eq!((allan("raw"), allan("clean")), (8, 4));
    assert_eq!(get("sagnac_temperature_celsius{gyro=\"gyro\"}"), 31.5);
    assert_eq!(get("sagnac_processing_lag_seconds{gyro=\"gyro\"}"), 0.125);
    assert_eq!(get("sagnac_recording_bytes"), 123_456.0);
    assert_eq!(get("sagnac_outliers_total{gyro=\"gyro\"}"), 7.0);
    assert_eq!(get("sagnac_bias_steps_total{gyro=\"gyro\"}"), 1.0);
    assert_eq!(get("sagnac_warmup_active{gyro=\"gyro\"}"), 1.0);
    assert_eq!(get("sagnac_warmup_amplitude_dph{gyro=\"gyro\"}"), -0.3);
    assert_eq!(get("sagnac_warmup_tau_seconds{gyro=\"gyro\"}"), 900.0);
}

/// The data-quality series of a gyro exist from the start, at 0 (with the raw
/// statistics they stay there); a warm-up's gauges read 0 when there is none,
/// never NaN.
#[test]
fn data_quality_series_start_at_zero_and_are_never_nan() {
    let metrics = Metrics::new().unwrap();
    let m = metrics.gyro(&GyroInfo::labelled("x"));
    let s = samples(&metrics.encode());
    for name in [
        "sagnac_outliers_total",
        "sagnac_bias_steps_total",
        "sagnac_warmup_active",
        "sagnac_warmup_amplitude_dph",
        "sagnac_warmup_tau_seconds",
    ] {
        assert_eq!(s[&format!("{name}{{gyro=\"x\"}}")], 0.0, "{name}");
    }
    m.set_warmup(true, Some((f64::NAN, f64::INFINITY)));
    let s = samples(&metrics.encode());
    assert_eq!(s["sagnac_warmup_active{gyro=\"x\"}"], 1.0);
    assert_eq!(s["sagnac_warmup_amplitude_dph{gyro=\"x\"}"], 0.0);
    assert_eq!(s["sagnac_warmup_tau_seconds{gyro=\"x\"}"], 0.0);
    m.set_warmup(false, None);
    let s = samples(&metrics.encode());
    assert_eq!(s["sagnac_warmup_active{gyro=\"x\"}"], 0.0);
}

#[test]
fn every_per_gyro_series_has_its_gyro_label_and_daemon_wide_ones_none() {
    // Two gyros of one daemon (as a triad source will give), the spec series too.
    let metrics = Metrics::new().unwrap();
    fill(&metrics, &GyroInfo::labelled("x"));
    fill(
        &metrics,
        &GyroInfo {
            label: "y".into(),
            serial_number: "SN-Y".into(),
            model: "FOG".into(),
        },
    );
    let y = metrics.gyro(&GyroInfo {
        label: "y".into(),
        serial_number: "SN-Y".into(),
        model: "FOG".into(),
    });
    y.add_lost_samples(6);
    y.set_spec("overall", 1.0, None, None);
    y.set_spec("arw_dpsh", 1.0, Some(0.0035), Some(0.0));
    y.set_allan_curve(AllanChannel::Raw, &[1.0], &[0.5])
        .unwrap();
    let text = metrics.encode();
    let s = samples(&text);
    for key in s.keys() {
        let fam = family(key);
        let labelled = key.contains("gyro=\"x\"") || key.contains("gyro=\"y\"");
        if PER_GYRO.contains(&fam) {
            assert!(labelled, "{key}: a per-gyro series without its gyro label");
        } else {
            assert!(DAEMON_WIDE.contains(&fam), "{key}: unknown family {fam}");
            assert!(
                !key.contains("gyro="),
                "{key}: a daemon-wide series with a gyro label"
            );
        }
    }
    // Counters add up per gyro; the daemon-wide byte counter adds up over both.
    assert_eq!(s["sagnac_lost_samples_total{gyro=\"x\"}"], 4.0);
    assert_eq!(s["sagnac_lost_samples_total{gyro=\"y\"}"], 10.0);
    assert_eq!(s["sagnac_bytes_read_total"], 2.0 * 16_384.0);
    // y's Allan curve was replaced; x's stays whole.
    let raw = |g: &str| {
        s.keys()
            .filter(|k| k.contains("channel=\"raw\"") && k.contains(&format!("gyro=\"{g}\"")))
            .count()
    };
    assert_eq!((raw("x"), raw("y")), (8, 1));
    assert_eq!(
        s["sagnac_spec_limit{coefficient=\"arw_dpsh\",gyro=\"y\"}"],
        0.0035
    );
    assert!(!text.contains("sagnac_spec_verdict{coefficient=\"overall\",gyro=\"x\"}"));
    assert_eq!(
        s["sagnac_gyro_info{gyro=\"x\",model=\"\",serial_number=\"\"}"],
        1.0
    );
    assert_eq!(
        s["sagnac_gyro_info{gyro=\"y\",model=\"FOG\",serial_number=\"SN-Y\"}"],
        1.0
    );
    let (ok, out) = promtool(&text);
    assert!(ok, "promtool check metrics:\n{out}\n---\n{text}");
}

#[test]
fn estimate_latency_is_a_histogram_and_device_series_only_on_request() {
    let t = Telemetry::standalone().unwrap();
    let text = t.metrics.encode();
    assert!(
        !text.contains("sagnac_device_"),
        "no device series before a serial source asks:\n{text}"
    );
    for v in [0.0004, 0.003, 0.003, 0.07, 0.9, 45.0] {
        t.estimate_latency.observe(v);
    }
    let dev = t.device();
    dev.connected.set(1);
    let x = t.for_gyro(&GyroInfo::labelled("x"));
    x.estimate_latency.observe(0.2);
    x.estimator_updates.inc();
    let text = t.metrics.encode();
    assert!(
        text.contains("# TYPE sagnac_estimate_latency_seconds histogram\n"),
        "{text}"
    );
    let s = samples(&text);
    // Cumulative buckets at exactly the documented bounds, counted by hand.
    let le =
        |b: &str| s[&format!("sagnac_estimate_latency_seconds_bucket{{gyro=\"gyro\",le=\"{b}\"}}")];
    let buckets = s
        .keys()
        .filter(|k| k.starts_with("sagnac_estimate_latency_seconds_bucket{gyro=\"gyro\""))
        .count();
    assert_eq!(buckets, LATENCY_BUCKETS_S.len() + 1, "the bounds plus +Inf");
    assert_eq!(
        (
            le("0.001"),
            le("0.0025"),
            le("0.005"),
            le("0.05"),
            le("0.1")
        ),
        (1.0, 1.0, 3.0, 3.0, 4.0)
    );
    assert_eq!(
        (le("0.5"), le("1"), le("30"), le("+Inf")),
        (4.0, 5.0, 5.0, 6.0)
    );
    assert_eq!(
        s["sagnac_estimate_latency_seconds_count{gyro=\"gyro\"}"],
        6.0
    );
    let sum = s["sagnac_estimate_latency_seconds_sum{gyro=\"gyro\"}"];
    assert!((sum - 45.9764).abs() < 1e-12, "{sum}");
    assert_eq!(s["sagnac_estimate_latency_seconds_count{gyro=\"x\"}"], 1.0);
    assert_eq!(s["sagnac_estimator_updates_total{gyro=\"x\"}"], 1.0);
    assert_eq!(s["sagnac_estimator_updates_total{gyro=\"gyro\"}"], 0.0);
    // the device series of the serial gyro only, the queue series daemon-wide
    assert_eq!(s["sagnac_device_connected{gyro=\"gyro\"}"], 1.0);
    assert_eq!(s["sagnac_device_reconnects_total{gyro=\"gyro\"}"], 0.0);
    assert!(!s.contains_key("sagnac_device_connected{gyro=\"x\"}"));
    assert!(s.contains_key("sagnac_pipeline_queue_bytes"));
    assert!(s.contains_key("sagnac_dropped_messages_total{sink=\"mcap\"}"));
    assert_eq!(
        s["sagnac_sequence_anomalies_total{gyro=\"x\",kind=\"duplicate\"}"],
        0.0
    );
    let (ok, out) = promtool(&text);
    assert!(ok, "promtool check metrics:\n{out}\n---\n{text}");
}

#[test]
fn updates_replace_old_series() {
    let metrics = filled();
    let m = metrics.gyro(&unit());
    // A new curve replaces the channel's series entirely; the other channel stays.
    m.set_allan_curve(AllanChannel::Raw, &[1.0, 2.0], &[0.1, 0.2])
        .unwrap();
    // An estimate that becomes unknown disappears.
    m.set_qn_arcsec(Bounds95 {
        estimate: Some(0.4),
        ..Default::default()
    });
    m.set_temperature_c(None);
    let text = metrics.encode();
    let s = samples(&text);
    let raw: Vec<&String> = s.keys().filter(|k| k.contains("channel=\"raw\"")).collect();
    assert_eq!(raw.len(), 2, "{raw:?}");
    assert_eq!(
        s["sagnac_allan_deviation_degrees_per_hour{channel=\"raw\",gyro=\"gyro\",tau_seconds=\"2\"}"],
        0.2
    );
    assert_eq!(
        s.keys().filter(|k| k.contains("channel=\"clean\"")).count(),
        4
    );
    assert_eq!(
        s["sagnac_qn_arcseconds{bound=\"estimate\",gyro=\"gyro\"}"],
        0.4
    );
    assert!(!s.contains_key("sagnac_qn_arcseconds{bound=\"lower95\",gyro=\"gyro\"}"));
    assert!(s["sagnac_temperature_celsius{gyro=\"gyro\"}"].is_nan());
    // Bad curves are refused and change nothing.
    let err = m
        .set_allan_curve(AllanChannel::Raw, &[1.0], &[])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("gyro `gyro`") && err.contains("channel `raw`"),
        "{err}"
    );
    assert!(
        m.set_allan_curve(AllanChannel::Raw, &[0.0], &[1.0])
            .is_err()
    );
    assert!(
        m.set_allan_curve(AllanChannel::Raw, &[f64::NAN], &[1.0])
            .is_err()
    );
    let sorted = |t: &str| {
        let mut l: Vec<String> = t.lines().map(str::to_string).collect();
        l.sort();
        l
    };
    assert_eq!(sorted(&metrics.encode()), sorted(&text));
    let (ok, out) = promtool(&text);
    assert!(ok, "{out}");
}

#[test]
fn tau_labels_are_short_and_faithful() {
    assert_eq!(tau_label(0.001 * 2f64.powi(7)), "0.128");
    assert_eq!(tau_label(0.1 + 0.2), "0.3");
    assert_eq!(tau_label(1.0), "1");
    assert_eq!(tau_label(1024.0 * 0.001), "1.024");
    assert_eq!(tau_label(0.005 * 2f64.powi(20)), "5242.88");
    for k in 0..40 {
        for dt in [0.001, 0.0025, 0.01, 1.0 / 3.0] {
            let tau = dt * 2f64.powi(k);
            let label = tau_label(tau);
            let back: f64 = label.parse().unwrap();
            // 9 significant digits: relative error below 5e-9.
            assert!(((back - tau) / tau).abs() < 5e-9, "{tau} -> {label}");
            let digits: String = label.chars().filter(|c| c.is_ascii_digit()).collect();
            let significant = digits.trim_start_matches('0').trim_end_matches('0');
            assert!(
                significant.len() <= 9,
                "{label}: more than 9 significant digits"
            );
        }
    }
}
