//! Helpers of the Prometheus tests: finding `promtool` and `prometheus` (skip
//! with a notice when absent, fail under `CI=true`), a real Prometheus started
//! on 127.0.0.1 with a free port and a temporary data directory and stopped by
//! its own PID, and its HTTP API over a plain TcpStream.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::free_addr;

/// Whether the Debian `prometheus` package's program `tool` runs here. When it
/// does not: a notice and `false` (the caller skips), or a panic under `CI=true`.
pub fn have(tool: &str) -> bool {
    let found = Command::new(tool)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!(
                "{tool} not found (CI=true: absence is a failure; apt-get install prometheus, or scripts/install-peers)"
            );
        }
        eprintln!(
            "NOTICE: {tool} not found; skipping this test (apt-get install prometheus, or scripts/install-peers)"
        );
    }
    found
}

/// Run `promtool ARGS` in `dir`: (success, stdout + stderr).
pub fn promtool(dir: &Path, args: &[&str]) -> (bool, String) {
    let out = Command::new("promtool")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("promtool runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// A Prometheus server of the test's own: loopback, a free port, a temporary
/// data directory; ended by its PID on drop.
pub struct Prometheus {
    child: Child,
    pub addr: SocketAddr,
    log: PathBuf,
}

impl Prometheus {
    /// Start `prometheus --config.file=CONFIG` with its data in `dir/data` and
    /// wait until it is ready.
    pub fn start(config: &Path, dir: &Path) -> Prometheus {
        let addr = free_addr();
        let log = dir.join("prometheus.log");
        let err = std::fs::File::create(&log).unwrap();
        let child = Command::new("prometheus")
            .arg(format!("--config.file={}", config.display()))
            .arg(format!(
                "--storage.tsdb.path={}",
                dir.join("data").display()
            ))
            .arg(format!("--web.listen-address={addr}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(err)
            .spawn()
            .expect("prometheus starts");
        let mut p = Prometheus { child, addr, log };
        let start = Instant::now();
        while http_get(addr, "/-/ready").is_none_or(|(status, _)| status != 200) {
            if let Ok(Some(status)) = p.child.try_wait() {
                panic!(
                    "prometheus exited ({status}) before ready:\n{}",
                    p.log_text()
                );
            }
            assert!(
                start.elapsed() < Duration::from_secs(30),
                "prometheus not ready in 30 s:\n{}",
                p.log_text()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        p
    }

    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// `GET /api/v1/PATH?QUERY`: the `data` of a successful answer (panics otherwise).
    pub fn api(&self, path: &str, params: &[(&str, &str)]) -> Value {
        let query: Vec<String> = params
            .iter()
            .map(|(k, v)| format!("{k}={}", url_encode(v)))
            .collect();
        let target = format!("/api/v1/{path}?{}", query.join("&"));
        let (status, body) =
            http_get(self.addr, &target).unwrap_or_else(|| panic!("no answer to {target}"));
        let v: Value =
            serde_json::from_str(&body).unwrap_or_else(|e| panic!("{target}: {e}: {body}"));
        assert!(
            status == 200 && v["status"] == "success",
            "{target}: HTTP {status}: {body}"
        );
        v["data"].clone()
    }

    /// An instant query's result vector (at `time`, Unix s, or now).
    pub fn query(&self, expr: &str, time: Option<f64>) -> Vec<Value> {
        let t = time.map(|t| format!("{t:.3}"));
        let mut params = vec![("query", expr)];
        if let Some(t) = &t {
            params.push(("time", t));
        }
        let data = self.api("query", &params);
        assert_eq!(data["resultType"], "vector", "{expr}: {data}");
        data["result"].as_array().unwrap().clone()
    }

    /// Poll `f` every 250 ms until it returns `Some`, or panic after `timeout`
    /// with the server's log.
    pub fn wait<T>(&self, what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
        let start = Instant::now();
        loop {
            if let Some(v) = f() {
                return v;
            }
            assert!(
                start.elapsed() < timeout,
                "timed out after {timeout:?} waiting for {what}; prometheus log:\n{}",
                self.log_text()
            );
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    /// Poll `f` every 250 ms until it returns `true` (then `true`), at most `timeout` (then `false`).
    pub fn wait_ok(&self, timeout: Duration, mut f: impl FnMut() -> bool) -> bool {
        let start = Instant::now();
        loop {
            if f() {
                return true;
            }
            if start.elapsed() > timeout {
                return false;
            }
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    /// SIGTERM to our own child by its PID, then wait (SIGKILL after 10 s).
    pub fn stop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = Command::new("kill")
                .args(["-TERM", &self.child.id().to_string()])
                .status();
            let start = Instant::now();
            while let Ok(None) = self.child.try_wait() {
                if start.elapsed() > Duration::from_secs(10) {
                    let _ = self.child.kill();
                    let _ = self.child.wait();
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
    }
}

impl Drop for Prometheus {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A sample's value (the second element of `"value": [t, "v"]`).
pub fn value_of(sample: &Value) -> f64 {
    sample["value"][1].as_str().unwrap().parse().unwrap()
}

/// A sample's timestamp, Unix s.
pub fn time_of(sample: &Value) -> f64 {
    sample["value"][0].as_f64().unwrap()
}

/// A label of a sample ("" when absent).
pub fn label<'a>(sample: &'a Value, name: &str) -> &'a str {
    sample["metric"][name].as_str().unwrap_or("")
}

/// HTTP/1.0 GET (so the answer is not chunked): (status, body).
pub fn http_get(addr: SocketAddr, target: &str) -> Option<(u16, String)> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_millis(500)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    write!(s, "GET {target} HTTP/1.0\r\nHost: {addr}\r\n\r\n").ok()?;
    let mut resp = String::new();
    s.read_to_string(&mut resp).ok()?;
    let (head, body) = resp.split_once("\r\n\r\n")?;
    let status = head.split(' ').nth(1)?.parse().ok()?;
    Some((status, body.to_string()))
}

/// Percent-encoding of a query parameter (RFC 3986 unreserved characters kept).
pub fn url_encode(s: &str) -> String {
    let mut out = String::with_capacity(s.len() * 3);
    for b in s.bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                out.push(b as char)
            }
            _ => out.push_str(&format!("%{b:02X}")),
        }
    }
    out
}

/// The `record:` names of a rules file.
pub fn recorded_names(rules: &Path) -> Vec<String> {
    std::fs::read_to_string(rules)
        .unwrap()
        .lines()
        .filter_map(|l| {
            l.trim()
                .strip_prefix("- record:")
                .map(|n| n.trim().to_string())
        })
        .collect()
}

/// A Prometheus config scraping `targets_file` (file_sd) every second and
/// evaluating `rule_files` every second.
pub fn write_config(dir: &Path, targets_file: &Path, rule_files: &[PathBuf]) -> PathBuf {
    let rules: Vec<String> = rule_files
        .iter()
        .map(|p| format!("  - {}\n", p.display()))
        .collect();
    let text = format!(
        "global:\n  scrape_interval: 1s\n  scrape_timeout: 1s\n  evaluation_interval: 1s\n\
         rule_files:\n{}\
         scrape_configs:\n  - job_name: sagnac-test\n    file_sd_configs:\n      - files: [\"{}\"]\n        refresh_interval: 1s\n",
        rules.concat(),
        targets_file.display()
    );
    let path = dir.join("prometheus.yml");
    std::fs::write(&path, text).unwrap();
    path
}

/// One file_sd target group: `addr` with its labels.
pub fn target_group(addr: SocketAddr, labels: &[(&str, &str)]) -> String {
    let labels: Vec<String> = labels
        .iter()
        .map(|(k, v)| format!("    {k}: \"{v}\"\n"))
        .collect();
    format!("- targets: [\"{addr}\"]\n  labels:\n{}", labels.concat())
}

/// Every PromQL expression of the dashboard's panels (rows' nested panels too).
pub fn dashboard_exprs(dash: &serde_json::Value) -> Vec<String> {
    fn walk(panels: &serde_json::Value, out: &mut Vec<String>) {
        for p in panels.as_array().into_iter().flatten() {
            for t in p["targets"].as_array().into_iter().flatten() {
                out.push(
                    t["expr"]
                        .as_str()
                        .expect("every target has an expr")
                        .to_string(),
                );
            }
            walk(&p["panels"], out);
        }
    }
    let mut out = Vec::new();
    walk(&dash["panels"], &mut out);
    out
}
