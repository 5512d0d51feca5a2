//! The Prometheus and Grafana files under config/, checked by the Prometheus
//! project's own tool: `promtool check config` on prometheus.yml and lab.yml,
//! `promtool check rules` on every rules file, `promtool test rules` on
//! tests/data/sagnac-rules-test.yml (every alert firing and not firing, the
//! recording rules' values), and a mutated copy of the rules that the unit tests
//! must reject. The dashboard JSON and the provisioning files are checked
//! statically here (Grafana is not packaged on this machine); their queries run
//! on a real Prometheus in tests/monitoring/prometheus_dashboard.rs.

use std::collections::BTreeSet;
use std::path::Path;

use sagnac::daemon::telemetry::Telemetry;
use sagnac::sink::metrics::GyroInfo;

use crate::support::prom::{dashboard_exprs, have, promtool};
use crate::support::repo;

const RULE_FILES: [&str; 3] = [
    "sagnac-rules.yml",
    "sagnac-spec-rules.yml",
    "sagnac-lab-rules.yml",
];

#[test]
fn promtool_checks_both_configs_and_every_rules_file() {
    if !have("promtool") {
        return;
    }
    let dir = repo().join("config/prometheus");
    for config in ["prometheus.yml", "lab.yml"] {
        let (ok, out) = promtool(&dir, &["check", "config", config]);
        assert!(ok, "promtool check config {config}:\n{out}");
        // the config's rule files were found and checked with it
        assert!(
            out.contains("SUCCESS") && out.contains("sagnac-rules.yml"),
            "{out}"
        );
    }
    for rules in RULE_FILES {
        let (ok, out) = promtool(&dir, &["check", "rules", rules]);
        assert!(ok, "promtool check rules {rules}:\n{out}");
    }
    // lab.yml loads the lab-wide rules; both scrape through file_sd
    let lab = std::fs::read_to_string(dir.join("lab.yml")).unwrap();
    assert!(
        lab.contains("sagnac-lab-rules.yml") && lab.contains("file_sd_configs"),
        "{lab}"
    );
    let prom = std::fs::read_to_string(dir.join("prometheus.yml")).unwrap();
    assert!(prom.contains("file_sd_configs"), "{prom}");
}

#[test]
fn the_example_targets_carry_bench_and_unit_serial() {
    let text =
        std::fs::read_to_string(repo().join("config/prometheus/targets/benches.yml")).unwrap();
    let groups = text.matches("- targets:").count();
    assert!(groups >= 2, "{text}");
    assert_eq!(text.matches("bench:").count(), groups, "{text}");
    assert_eq!(text.matches("unit_serial:").count(), groups, "{text}");
}

#[test]
fn promtool_unit_tests_of_every_alert_pass() {
    if !have("promtool") {
        return;
    }
    let test = "tests/data/sagnac-rules-test.yml";
    let (ok, out) = promtool(&repo(), &["test", "rules", test]);
    assert!(ok, "promtool test rules {test}:\n{out}");
    // every alert of every rules file has a case in the unit tests
    let tests = std::fs::read_to_string(repo().join(test)).unwrap();
    for rules in RULE_FILES {
        let text = std::fs::read_to_string(repo().join("config/prometheus").join(rules)).unwrap();
        for alert in text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("- alert:"))
        {
            let cases = tests
                .matches(&format!("alertname: {}\n", alert.trim()))
                .count();
            assert!(
                cases >= 2,
                "{rules}: alert {alert} has {cases} unit-test cases (want firing and not firing)"
            );
        }
    }
}

#[test]
fn the_unit_tests_reject_broken_rules() {
    if !have("promtool") {
        return;
    }
    // A copy of the rules with two thresholds changed: the unit tests must fail
    // on exactly those alerts.
    let dir = tempfile::tempdir().unwrap();
    let conf = dir.path().join("config/prometheus");
    let data = dir.path().join("tests/data");
    std::fs::create_dir_all(&conf).unwrap();
    std::fs::create_dir_all(&data).unwrap();
    for rules in RULE_FILES {
        let mut text =
            std::fs::read_to_string(repo().join("config/prometheus").join(rules)).unwrap();
        if rules == "sagnac-rules.yml" {
            for (from, to) in [
                (
                    "sagnac:estimate_latency_seconds:p95_5m > 1\n",
                    "sagnac:estimate_latency_seconds:p95_5m > 5\n",
                ),
                (
                    "increase(sagnac_samples_total[30s]) == 0",
                    "increase(sagnac_samples_total[45s]) == 0",
                ),
            ] {
                assert!(text.contains(from), "{from}");
                text = text.replace(from, to);
            }
        }
        std::fs::write(conf.join(rules), text).unwrap();
    }
    std::fs::copy(
        repo().join("tests/data/sagnac-rules-test.yml"),
        data.join("t.yml"),
    )
    .unwrap();
    let (ok, out) = promtool(dir.path(), &["test", "rules", "tests/data/t.yml"]);
    assert!(!ok, "broken rules passed the unit tests:\n{out}");
    assert!(
        out.contains("alertname: SagnacNoSamples")
            && out.contains("alertname: SagnacEstimateLatencyHigh"),
        "{out}"
    );
    assert!(
        !out.contains("alertname: SagnacRecorderDropping"),
        "only the broken alerts fail:\n{out}"
    );
}

/// Every metric family a daemon can export (a serial gyro with a spec), as `Telemetry` registers them.
fn exported_families() -> BTreeSet<String> {
    let t = Telemetry::standalone().unwrap();
    let _ = t.device();
    t.gyro.set_spec("overall", 0.0, None, None);
    t.gyro.set_spec("arw_dpsh", 0.0, Some(1.0), None);
    let x = t.for_gyro(&GyroInfo::labelled("x"));
    x.gyro
        .set_allan_curve(sagnac::sink::metrics::AllanChannel::Raw, &[1.0], &[1.0])
        .unwrap();
    x.gyro.set_qn_arcsec(sagnac::sink::metrics::Bounds95 {
        estimate: Some(1.0),
        lower95: Some(1.0),
        upper95: Some(1.0),
    });
    for b in [&x.gyro, &t.gyro] {
        let all = sagnac::sink::metrics::Bounds95 {
            estimate: Some(1.0),
            lower95: Some(0.5),
            upper95: Some(2.0),
        };
        b.set_arw_dpsh(all);
        b.set_bias_instability_dph(all);
        b.set_rrw_dphsh(all);
        b.set_rate_ramp_dphh(all);
    }
    t.metrics
        .encode()
        .lines()
        .filter_map(|l| l.strip_prefix("# TYPE "))
        .map(|l| l.split(' ').next().unwrap().to_string())
        .collect()
}

/// The `sagnac_*` metric names a PromQL expression reads.
fn metric_names(expr: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = expr;
    while let Some(i) = rest.find("sagnac_") {
        // a recording rule name (`sagnac:...`) starts with `sagnac:`, not `sagnac_`
        let tail = &rest[i..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(tail.len());
        let name = &tail[..end];
        let name = ["_bucket", "_sum", "_count"]
            .iter()
            .find_map(|s| name.strip_suffix(s))
            .unwrap_or(name);
        names.push(name.to_string());
        rest = &tail[end..];
    }
    names
}

#[test]
fn the_dashboard_reads_only_exported_metrics_and_defines_its_variables() {
    let path = repo().join("config/grafana/sagnac-dashboard.json");
    let dash: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let vars: BTreeSet<String> = dash["templating"]["list"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap().to_string())
        .collect();
    for v in ["datasource", "bench", "instance", "gyro"] {
        assert!(vars.contains(v), "template variable {v} missing: {vars:?}");
    }
    let families = exported_families();
    let exprs = dashboard_exprs(&dash);
    assert!(exprs.len() >= 15, "{exprs:?}");
    let mut read = BTreeSet::new();
    for e in &exprs {
        for name in metric_names(e) {
            assert!(
                families.contains(&name),
                "the dashboard reads {name}, which sagnac does not export: {e}"
            );
            read.insert(name);
        }
        for var in e.split('$').skip(1) {
            let name: String = var
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            assert!(
                vars.contains(&name) || name == "__rate_interval",
                "undefined variable ${name} in {e}"
            );
        }
    }
    // what the dashboard must show
    for name in [
        "sagnac_qn_arcseconds",
        "sagnac_arw_degrees_per_root_hour",
        "sagnac_bias_instability_degrees_per_hour",
        "sagnac_allan_deviation_degrees_per_hour",
        "sagnac_samples_total",
        "sagnac_frame_errors_total",
        "sagnac_lost_samples_total",
        "sagnac_dropped_samples_total",
        "sagnac_processing_lag_seconds",
        "sagnac_temperature_celsius",
        "sagnac_spec_verdict",
    ] {
        assert!(read.contains(name), "the dashboard does not show {name}");
    }
    // every coefficient panel draws its interval band: estimate, lower95 and upper95
    for metric in [
        "sagnac_qn_arcseconds",
        "sagnac_arw_degrees_per_root_hour",
        "sagnac_bias_instability_degrees_per_hour",
    ] {
        for bound in ["estimate", "lower95", "upper95"] {
            let q = format!("bound=\"{bound}\"");
            assert!(
                exprs.iter().any(|e| e.contains(metric) && e.contains(&q)),
                "{metric} {bound}"
            );
        }
    }
    // panels use the datasource variable, which the provisioning's datasource fills
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        !text.contains("\"uid\": \"sagnac-prometheus\""),
        "panels should use ${{datasource}}"
    );
    let ds = std::fs::read_to_string(
        repo().join("config/grafana/provisioning/datasources/sagnac-prometheus.yml"),
    )
    .unwrap();
    assert!(
        ds.contains("type: prometheus") && ds.contains("apiVersion: 1"),
        "{ds}"
    );
    let prov =
        std::fs::read_to_string(repo().join("config/grafana/provisioning/dashboards/sagnac.yml"))
            .unwrap();
    assert!(
        prov.contains("type: file") && prov.contains("path:"),
        "{prov}"
    );
}

#[test]
fn metric_names_are_found_in_exprs() {
    // the helper above must not pass vacuously
    assert_eq!(
        metric_names(
            "histogram_quantile(0.9, rate(sagnac_estimate_latency_seconds_bucket{a=\"b\"}[5m])) + sagnac:x + sagnac_lost_samples_total"
        ),
        vec![
            "sagnac_estimate_latency_seconds",
            "sagnac_lost_samples_total"
        ]
    );
    assert!(Path::new(&repo().join("config/grafana/sagnac-dashboard.json")).is_file());
}
