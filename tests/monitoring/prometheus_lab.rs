//! A lab of benches on one real Prometheus: three `sagnac run` daemons
//! (simulated benches with different models, seeds, serial numbers and model
//! names) on two benches, bench-a with two units and bench-b with one, and a
//! Prometheus running config/prometheus/lab.yml itself (only its intervals
//! shortened to 1 s and its paths made absolute), scraping them through a
//! file_sd targets file with `bench` and `unit_serial` labels. Through the HTTP
//! API, the lab-wide recording rules of sagnac-lab-rules.yml give one series
//! per bench, and each equals the same aggregation of the raw series at the
//! rule's own evaluation time: the worst ARW of a bench is the largest ARW of its
//! units (the noisier model's), the lab's the largest of all. Everything is
//! stopped by its own PID. Skips (with a notice) without `prometheus`, except
//! under CI=true.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use crate::support::daemon::DaemonProc;
use crate::support::prom::{Prometheus, have, label, target_group, time_of, value_of};
use crate::support::{PAPER_GYRO, free_addr, repo};

struct Unit {
    bench: &'static str,
    serial: &'static str,
    model_name: &'static str,
    /// ARW of the simulated model, deg/sqrt(h)
    arw_dpsh: f64,
    seed: u64,
}

const UNITS: [Unit; 3] = [
    Unit {
        bench: "bench-a",
        serial: "RLG-A1",
        model_name: "RLG-28",
        arw_dpsh: 0.001,
        seed: 11,
    },
    Unit {
        bench: "bench-a",
        serial: "RLG-A2",
        model_name: "RLG-28 noisy",
        arw_dpsh: 0.004,
        seed: 12,
    },
    Unit {
        bench: "bench-b",
        serial: "RLG-B1",
        model_name: "RLG-28 mid",
        arw_dpsh: 0.002,
        seed: 13,
    },
];

fn start_unit(dir: &Path, u: &Unit, addr: std::net::SocketAddr) -> DaemonProc {
    let paper = std::fs::read_to_string(PAPER_GYRO).unwrap();
    assert!(
        paper.contains("\narw_dpsh = 0.001\n"),
        "config/paper_gyro.toml changed"
    );
    let model = dir.join(format!("{}.toml", u.serial));
    std::fs::write(
        &model,
        paper.replace(
            "\narw_dpsh = 0.001\n",
            &format!("\narw_dpsh = {}\n", u.arw_dpsh),
        ),
    )
    .unwrap();
    let cfg = dir.join(format!("{}-sagnac.toml", u.serial));
    std::fs::write(
        &cfg,
        format!(
            // an estimator update every 1500 s of data (15 s of wall time at
            // speed 100): the rule check needs 5 s in which no unit's ARW
            // changed, whatever an update costs (the 5 % budget alone let cheap
            // updates come every 2-4 s)
            "[source]\nseed = {}\n[gyro]\nserial_number = \"{}\"\nmodel_name = \"{}\"\n[record]\ndir = \"\"\n[estimator]\ninterval_s = 1500.0\n",
            u.seed, u.serial, u.model_name
        ),
    )
    .unwrap();
    DaemonProc::start(
        &[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--simulate",
            model.to_str().unwrap(),
            "--speed",
            "100",
            "--metrics-addr",
            &addr.to_string(),
        ],
        &dir.join(format!("{}.log", u.serial)),
    )
}

/// config/prometheus/lab.yml with 1 s intervals, the test's targets file and
/// absolute rule file paths; every replaced piece must be there.
fn lab_config(dir: &Path, targets: &Path) -> std::path::PathBuf {
    let conf = repo().join("config/prometheus");
    let mut text = std::fs::read_to_string(conf.join("lab.yml")).unwrap();
    let mut replace = |from: &str, to: &str| {
        assert!(text.contains(from), "lab.yml has no `{from}`");
        text = text.replace(from, to);
    };
    replace(
        "scrape_interval: 15s",
        "scrape_interval: 1s\n  scrape_timeout: 1s",
    );
    replace("evaluation_interval: 15s", "evaluation_interval: 1s");
    replace("refresh_interval: 1m", "refresh_interval: 1s");
    replace(
        "files: [\"targets/*.yml\"]",
        &format!("files: [\"{}\"]", targets.display()),
    );
    for rules in [
        "sagnac-rules.yml",
        "sagnac-spec-rules.yml",
        "sagnac-lab-rules.yml",
    ] {
        replace(
            &format!("  - {rules}\n"),
            &format!("  - {}\n", conf.join(rules).display()),
        );
    }
    let path = dir.join("lab.yml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Values by `key` label of an instant query.
fn by(samples: &[serde_json::Value], key: &str) -> BTreeMap<String, f64> {
    samples
        .iter()
        .map(|s| (label(s, key).to_string(), value_of(s)))
        .collect()
}

#[test]
fn lab_rules_give_one_series_per_bench_equal_to_the_aggregate_of_its_units() {
    if !have("prometheus") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let addrs: Vec<_> = UNITS.iter().map(|_| free_addr()).collect();
    let mut daemons: Vec<DaemonProc> = UNITS
        .iter()
        .zip(&addrs)
        .map(|(u, a)| start_unit(dir.path(), u, *a))
        .collect();
    let targets = dir.path().join("targets.yml");
    let groups: Vec<String> = UNITS
        .iter()
        .zip(&addrs)
        .map(|(u, a)| target_group(*a, &[("bench", u.bench), ("unit_serial", u.serial)]))
        .collect();
    std::fs::write(&targets, groups.concat()).unwrap();
    let mut prom = Prometheus::start(&lab_config(dir.path(), &targets), dir.path());

    // All three scraped, each unit's ARW estimate in.
    let arw = "sagnac_arw_degrees_per_root_hour{bound=\"estimate\"}";
    prom.wait("three ARW estimates", Duration::from_secs(60), || {
        (prom.query(arw, None).len() == 3).then_some(())
    });
    let up = prom.query("up{job=\"sagnac-lab\"}", None);
    assert_eq!(up.iter().map(value_of).sum::<f64>(), 3.0, "{up:?}");

    // The daemon's serial number (its config) and the lab's unit_serial (the
    // targets file) agree on every gyro; the model names came through.
    let info = prom.query("sagnac_gyro_info", None);
    assert_eq!(info.len(), 3, "{info:?}");
    for u in &UNITS {
        let s = info
            .iter()
            .find(|s| label(s, "unit_serial") == u.serial)
            .unwrap_or_else(|| panic!("{}: {info:?}", u.serial));
        assert_eq!(
            (
                label(s, "serial_number"),
                label(s, "model"),
                label(s, "bench"),
                label(s, "gyro")
            ),
            (u.serial, u.model_name, u.bench, "gyro")
        );
    }

    // The worst ARW per bench at the rule's own evaluation time T, against the
    // raw series at T, once they have been scraped at least 3 times without a
    // change in the 5 s before T (so the rule saw the same values, whatever the
    // scrape timing).
    let (per_bench, raw, lab) = prom.wait("stable ARW estimates", Duration::from_secs(60), || {
        let rule = prom.query("bench:sagnac_arw_degrees_per_root_hour:max", None);
        let t = time_of(rule.first()?);
        // at least 3 scrapes in the 5 s before T, all with the same value
        let changes = prom.query(&format!("changes({arw}[5s])"), Some(t));
        let scrapes = prom.query(&format!("count_over_time({arw}[5s])"), Some(t));
        if changes.len() != 3
            || changes.iter().any(|s| value_of(s) != 0.0)
            || scrapes.iter().any(|s| value_of(s) < 3.0)
        {
            return None;
        }
        let lab = prom.query("lab:sagnac_arw_degrees_per_root_hour:max", Some(t));
        Some((rule, prom.query(arw, Some(t)), lab))
    });
    assert_eq!(per_bench.len(), 2, "one series per bench: {per_bench:?}");
    let worst = by(&per_bench, "bench");
    let units = by(&raw, "unit_serial");
    eprintln!("ARW per unit {units:?}; worst per bench {worst:?}");
    assert_eq!(worst["bench-a"], units["RLG-A1"].max(units["RLG-A2"]));
    assert_eq!(worst["bench-b"], units["RLG-B1"]);
    // the max picked the noisier unit (ARW 0.004 against 0.001 simulated)
    assert_eq!(worst["bench-a"], units["RLG-A2"]);
    assert!(units["RLG-A2"] > 2.0 * units["RLG-A1"], "{units:?}");
    for u in &UNITS {
        let est = units[u.serial];
        // a few minutes of data: within a factor of 2 of the model's ARW
        assert!(
            est > 0.5 * u.arw_dpsh && est < 2.0 * u.arw_dpsh,
            "{}: ARW {est} for a model of {}",
            u.serial,
            u.arw_dpsh
        );
    }
    assert_eq!(lab.len(), 1, "{lab:?}");
    assert_eq!(
        value_of(&lab[0]),
        units.values().cloned().fold(f64::MIN, f64::max)
    );

    // The other per-bench rules: gyros counted, samples flowing, nothing lost.
    let count = prom.wait("gyro counts", Duration::from_secs(10), || {
        let c = by(&prom.query("bench:sagnac_gyros:count", None), "bench");
        (c.len() == 2).then_some(c)
    });
    assert_eq!(
        count,
        BTreeMap::from([("bench-a".to_string(), 2.0), ("bench-b".to_string(), 1.0)])
    );
    assert_eq!(
        prom.query("lab:sagnac_gyros:count", None)
            .iter()
            .map(value_of)
            .collect::<Vec<_>>(),
        vec![3.0]
    );
    let rate = by(&prom.query("bench:sagnac_samples:rate1m", None), "bench");
    assert!(
        rate.len() == 2 && rate.values().all(|r| *r > 0.0),
        "{rate:?}"
    );
    let lost = by(
        &prom.query("bench:sagnac_lost_samples:increase1h", None),
        "bench",
    );
    assert_eq!(
        lost.values().cloned().collect::<Vec<_>>(),
        vec![0.0, 0.0],
        "{lost:?}"
    );

    for d in &mut daemons {
        d.sigterm();
        let status = d.wait(Duration::from_secs(20));
        assert!(status.success(), "{status:?}\n{}", d.log_text());
    }
    prom.stop();
}
