//! The Grafana dashboard and the rules on the real thing: a `sagnac run`
//! daemon (the simulated bench, with a spec) serving /metrics on a free
//! loopback port, and a real Prometheus (Debian package) started on another,
//! with a temporary data directory, scraping it every second through file_sd
//! with `bench` and `unit_serial` target labels and evaluating every rules file
//! of config/prometheus. Then, through the HTTP API:
//! * every template variable's `label_values` query finds the daemon;
//! * every query of config/grafana/sagnac-dashboard.json, with the variables
//!   substituted as Grafana does (regex-escaped values), returns data with a
//!   finite value, except the device panel, which must stay empty (the
//!   simulated bench has no serial device);
//! * every recording rule returns finite data and every rule is healthy;
//! * no health alert fires on a healthy bench, and the failing-spec alert
//!   fires for exactly the coefficients whose verdict is fail.
//!
//! Everything started here is stopped by its own PID. Skips (with a notice)
//! when `prometheus` is not installed, except under CI=true.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::time::Duration;

use crate::support::daemon::DaemonProc;
use crate::support::prom::{
    Prometheus, dashboard_exprs, have, label, recorded_names, target_group, value_of, write_config,
};
use crate::support::{free_addr, repo};

const RULE_FILES: [&str; 3] = [
    "sagnac-rules.yml",
    "sagnac-spec-rules.yml",
    "sagnac-lab-rules.yml",
];

/// The alerts of sagnac-rules.yml: none may fire on a healthy simulated bench.
const HEALTH_ALERTS: [&str; 6] = [
    "SagnacDaemonDown",
    "SagnacNoSamples",
    "SagnacLostSamplesRising",
    "SagnacDroppingSamples",
    "SagnacEstimateLatencyHigh",
    "SagnacRecorderDropping",
];

/// Grafana's escaping of a multi-value variable's value in a Prometheus query
/// (`prometheusSpecialRegexEscape`): each regex metacharacter gets `\\`.
fn grafana_escape(v: &str) -> String {
    let mut out = String::new();
    for c in v.chars() {
        if "\\^$*+?.()|[]{}".contains(c) {
            out.push_str("\\\\");
        }
        out.push(c);
    }
    out
}

fn substitute(expr: &str, vars: &[(&str, String)]) -> String {
    let mut e = expr.replace("$__rate_interval", "10s");
    for (name, value) in vars {
        e = e.replace(&format!("${name}"), value);
    }
    assert!(!e.contains('$'), "unsubstituted variable in {e}");
    e
}

/// `label_values(SELECTOR, LABEL)` of a Grafana query variable, through the
/// label-values API (as Grafana runs it).
fn label_values(prom: &Prometheus, query: &str) -> Vec<String> {
    let inner = query
        .strip_prefix("label_values(")
        .and_then(|q| q.strip_suffix(')'))
        .expect(query);
    let (selector, label) = inner.rsplit_once(',').expect(query);
    let data = prom.api(
        &format!("label/{}/values", label.trim()),
        &[("match[]", selector.trim())],
    );
    data.as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn every_dashboard_query_and_rule_answers_on_a_real_prometheus() {
    if !have("prometheus") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let addr = free_addr();
    let cfg = dir.path().join("sagnac.toml");
    std::fs::write(
        &cfg,
        "[gyro]\nserial_number = \"RLG-T1\"\nmodel_name = \"paper RLG\"\n[record]\ndir = \"\"\n[estimator]\ninterval_s = 5.0\n",
    )
    .unwrap();
    let spec = repo().join("config/spec_example.toml");
    let mut daemon = DaemonProc::start(
        &[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--speed",
            "200",
            "--spec",
            spec.to_str().unwrap(),
            "--metrics-addr",
            &addr.to_string(),
        ],
        &dir.path().join("sagnac.log"),
    );
    let targets = dir.path().join("targets.yml");
    std::fs::write(
        &targets,
        target_group(addr, &[("bench", "bench-t"), ("unit_serial", "RLG-T1")]),
    )
    .unwrap();
    let rules: Vec<PathBuf> = RULE_FILES
        .iter()
        .map(|r| repo().join("config/prometheus").join(r))
        .collect();
    let config = write_config(dir.path(), &targets, &rules);
    let mut prom = Prometheus::start(&config, dir.path());

    // The template variables, resolved in order as Grafana does.
    let dash: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("config/grafana/sagnac-dashboard.json")).unwrap(),
    )
    .unwrap();
    let want = [
        ("bench", "bench-t".to_string()),
        ("instance", addr.to_string()),
        ("gyro", "gyro".to_string()),
    ];
    let mut vars: Vec<(&str, String)> = Vec::new();
    for (name, value) in &want {
        let var = dash["templating"]["list"]
            .as_array()
            .unwrap()
            .iter()
            .find(|v| v["name"] == *name)
            .unwrap();
        let query = substitute(var["query"]["query"].as_str().unwrap(), &vars);
        let found = prom.wait(&format!("variable {name}"), Duration::from_secs(30), || {
            let vals = label_values(&prom, &query);
            (!vals.is_empty()).then_some(vals)
        });
        assert_eq!(found, vec![value.clone()], "{name}: {query}");
        vars.push((name, grafana_escape(value)));
    }
    vars.push(("datasource", String::new()));

    // Every dashboard query: data with a finite value (the estimates converge within seconds at 200x).
    let exprs: Vec<String> = dashboard_exprs(&dash)
        .iter()
        .map(|e| substitute(e, &vars))
        .collect();
    let (device, data): (Vec<&String>, Vec<&String>) = exprs
        .iter()
        .partition(|e| e.contains("sagnac_device_connected"));
    assert_eq!(device.len(), 1, "{exprs:?}");
    let finite = |e: &str| prom.query(e, None).iter().any(|s| value_of(s).is_finite());
    let missing = || {
        data.iter()
            .filter(|e| !finite(e))
            .map(|e| e.to_string())
            .collect::<Vec<_>>()
    };
    let mut last = Vec::new();
    let ok = prom.wait_ok(Duration::from_secs(90), || {
        last = missing();
        last.is_empty()
    });
    assert!(
        ok,
        "dashboard queries without data after 90 s: {last:#?}\nsagnac log:\n{}",
        daemon.log_text()
    );
    eprintln!("{} dashboard queries answered with data", data.len());
    assert!(
        prom.query(device[0], None).is_empty(),
        "the simulated bench exports no device series: {}",
        device[0]
    );

    // Every recording rule evaluates to finite data; the per-bench ones per bench.
    for r in &rules {
        for name in recorded_names(r) {
            let got = prom.wait(&name, Duration::from_secs(30), || {
                let s = prom.query(&name, None);
                s.iter().any(|s| value_of(s).is_finite()).then_some(s)
            });
            if name.starts_with("bench:") {
                assert!(
                    got.iter().all(|s| label(s, "bench") == "bench-t"),
                    "{name}: {got:?}"
                );
            }
        }
    }
    let groups = prom.api("rules", &[]);
    let mut rule_count = 0;
    for g in groups["groups"].as_array().unwrap() {
        for r in g["rules"].as_array().unwrap() {
            rule_count += 1;
            assert_eq!(r["health"], "ok", "{r}");
        }
    }
    assert_eq!(rule_count, 24, "the rules of the three files: {groups}");

    // Alerts: no health alert on a healthy bench; the spec alert for exactly the failing coefficients.
    let alerts = prom.api("alerts", &[]);
    let firing = |alerts: &serde_json::Value, name: &str| -> BTreeSet<String> {
        alerts["alerts"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a["labels"]["alertname"] == name && a["state"] == "firing")
            .map(|a| {
                a["labels"]["coefficient"]
                    .as_str()
                    .unwrap_or("")
                    .to_string()
            })
            .collect()
    };
    for name in HEALTH_ALERTS {
        assert!(
            firing(&alerts, name).is_empty(),
            "{name} fires on a healthy bench: {alerts}"
        );
    }
    let ok = prom.wait_ok(Duration::from_secs(10), || {
        let failing: BTreeSet<String> = prom
            .query("sagnac_spec_verdict{coefficient!=\"overall\"} == -1", None)
            .iter()
            .map(|s| label(s, "coefficient").to_string())
            .collect();
        failing == firing(&prom.api("alerts", &[]), "SagnacGyroFailsSpec")
    });
    assert!(
        ok,
        "SagnacGyroFailsSpec does not follow sagnac_spec_verdict: {}",
        prom.api("alerts", &[])
    );

    daemon.sigterm();
    let status = daemon.wait(Duration::from_secs(20));
    assert!(status.success(), "{status:?}\n{}", daemon.log_text());
    prom.stop();
}
