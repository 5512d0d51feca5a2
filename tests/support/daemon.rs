//! Helpers of the daemon tests: the real binary as a child process, a socat
//! pseudo-terminal pair, /metrics scraping over a plain TcpStream, promtool and
//! the independent Python MCAP reader.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use sagnac::model::estimate::Coefficient;
use sagnac::recording::messages::{EstimateUpdate, RawBatch, SinkMessage};
use sagnac::recording::reader::read_recording;

use super::repo;

pub fn paper_model() -> sagnac::model::GyroModel {
    sagnac::model::GyroModel::load(Path::new(super::PAPER_GYRO)).unwrap()
}

/// The corruption a serial stream gets in the pty tests (single and triad
/// frames): drops, bit flips, duplicates and garbage with false syncs, at
/// 0.4 % of frames each (duplicates 0.1 %), sparing the first and last frame
/// (the baseline and the final counter).
pub fn serial_faults() -> sagnac::input::frame::inject::InjectorConfig {
    sagnac::input::frame::inject::InjectorConfig {
        drop_prob: 0.004,
        flip_prob: 0.004,
        duplicate_prob: 0.001,
        garbage_prob: 0.004,
        ..Default::default()
    }
}

/// Poll `f` every 20 ms until it returns `Some`, or panic after `timeout`.
pub fn wait_for<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        if start.elapsed() > timeout {
            panic!("timed out after {timeout:?} waiting for {what}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `GET /metrics` over a plain TcpStream; the body, or `None` if unreachable.
pub fn scrape(addr: SocketAddr) -> Option<String> {
    let mut s = TcpStream::connect_timeout(&addr, Duration::from_millis(500)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    write!(
        s,
        "GET /metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut resp = String::new();
    s.read_to_string(&mut resp).ok()?;
    let (head, body) = resp.split_once("\r\n\r\n")?;
    head.starts_with("HTTP/1.1 200").then(|| body.to_string())
}

/// The value of one series (exact name with labels, e.g. `a{b="c"}`).
pub fn metric(text: &str, series: &str) -> Option<f64> {
    text.lines().filter(|l| !l.starts_with('#')).find_map(|l| {
        l.strip_prefix(series)?
            .strip_prefix(' ')?
            .trim()
            .parse()
            .ok()
    })
}

/// Scrape until `series` reaches `want` (exactly), returning the scrape.
pub fn wait_metric(addr: SocketAddr, series: &str, want: f64, timeout: Duration) -> String {
    wait_for(&format!("{series} == {want}"), timeout, || {
        let t = scrape(addr)?;
        (metric(&t, series) == Some(want)).then_some(t)
    })
}

/// `promtool check metrics` on an exposition: (passed, output).
pub fn promtool(exposition: &str) -> (bool, String) {
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
    (out.status.success(), text)
}

/// The independent Python reader's summary of a recording (scripts/read-mcap.py),
/// every message validated against its channel's JSON Schema.
pub fn read_mcap_py(path: &Path) -> serde_json::Value {
    read_mcap_py_with(path, &[])
}

/// Same without the (slow) JSON Schema validation, for long recordings.
pub fn read_mcap_py_fast(path: &Path) -> serde_json::Value {
    read_mcap_py_with(path, &["--no-schema"])
}

pub fn read_mcap_py_with(path: &Path, flags: &[&str]) -> serde_json::Value {
    let out = Command::new("python3")
        .arg(repo().join("scripts/read-mcap.py"))
        .args(flags)
        .arg(path)
        .output()
        .expect("python3 with the mcap package (scripts/install-peers)");
    assert!(
        out.status.success(),
        "read-mcap.py {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The `/gyro/summary` messages of a recording against the same windows
/// recomputed by `scripts/read-mcap.py --summary` from `/gyro/raw` and
/// `/gyro/clean`: same count, times, sample and lost counts; the raw mean within
/// its recorded 0.5e-3 deg/h rounding, the clean mean within that and the
/// rounding of `/gyro/clean`; the temperature within the raw batches' range.
/// Returns the number of messages.
pub fn check_summary(py: &serde_json::Value) -> usize {
    let rec = py["summary_recorded"]
        .as_array()
        .expect("read-mcap.py --summary");
    let exp = py["summary_expected"].as_array().unwrap();
    assert_eq!(
        rec.len(),
        exp.len(),
        "summary windows: recorded vs recomputed"
    );
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    for (i, (r, e)) in rec.iter().zip(exp).enumerate() {
        assert_eq!(
            (&r[0], &r[1], &r[2]),
            (&e[0], &e[1], &e[2]),
            "window {i}: time, samples, lost"
        );
        assert!(
            (f(&r[3]) - f(&e[3])).abs() <= 0.5e-3 + 1e-9 * f(&e[3]).abs(),
            "window {i}: raw {r:?} vs {e:?}"
        );
        assert!(
            (f(&r[4]) - f(&e[4])).abs() <= 1e-3 + 1e-9 * f(&e[4]).abs(),
            "window {i}: clean {r:?} vs {e:?}"
        );
        match (&r[5], &e[5]) {
            (serde_json::Value::Null, serde_json::Value::Null) => {}
            (t, range) => assert!(
                f(&range[0]) <= f(t) && f(t) <= f(&range[1]),
                "window {i}: temp {t} outside {range}"
            ),
        }
    }
    rec.len()
}

/// The single `.mcap` file in `dir`.
pub fn only_recording(dir: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
        .collect();
    assert_eq!(files.len(), 1, "recordings in {}: {files:?}", dir.display());
    files.into_iter().next().unwrap()
}

/// `sagnac` as a child process, its stderr going to a log file.
pub struct DaemonProc {
    pub child: Child,
    pub log: PathBuf,
}

impl DaemonProc {
    pub fn start(args: &[&str], log: &Path) -> DaemonProc {
        let err = std::fs::File::create(log).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_sagnac"))
            .args(args)
            .env_remove("RUST_LOG")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(err)
            .spawn()
            .unwrap();
        DaemonProc {
            child,
            log: log.to_path_buf(),
        }
    }

    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// SIGTERM through kill(1).
    pub fn sigterm(&self) {
        let ok = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -TERM failed");
    }

    /// Wait for the exit, at most `timeout`.
    /// SIGTERM, then an exit 0 within `timeout` (the log shown otherwise).
    pub fn stop_ok(&mut self, timeout: Duration) {
        self.sigterm();
        let status = self.wait(timeout);
        assert!(
            status.success(),
            "exit {status:?}; log:\n{}",
            self.log_text()
        );
    }

    pub fn wait(&mut self, timeout: Duration) -> ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            if start.elapsed() > timeout {
                let _ = self.child.kill();
                panic!(
                    "sagnac did not exit within {timeout:?}; log:\n{}",
                    self.log_text()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for DaemonProc {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// A socat pseudo-terminal pair linked at `a` and `b`.
pub struct Socat {
    child: Child,
    pub a: PathBuf,
    pub b: PathBuf,
}

impl Socat {
    pub fn start(a: &Path, b: &Path) -> Socat {
        let child = Command::new("socat")
            .arg("-d")
            .arg("-d")
            .arg(format!("pty,raw,echo=0,link={}", a.display()))
            .arg(format!("pty,raw,echo=0,link={}", b.display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("socat is required (scripts/install-peers): {e}"));
        wait_for("the socat pty links", Duration::from_secs(10), || {
            (a.exists() && b.exists()).then_some(())
        });
        Socat {
            child,
            a: a.to_path_buf(),
            b: b.to_path_buf(),
        }
    }

    /// Open the writing end (the emulator's side).
    pub fn writer(&self) -> std::fs::File {
        std::fs::OpenOptions::new()
            .write(true)
            .open(&self.a)
            .unwrap()
    }

    /// Terminate socat: both ptys vanish (the daemon's end reads EOF).
    pub fn stop(mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let _ = self.child.wait();
        wait_for("socat to remove its links", Duration::from_secs(10), || {
            (!self.a.exists() && !self.b.exists()).then_some(())
        });
    }
}

impl Drop for Socat {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// (final estimates, raw messages) of a recording.
pub fn final_and_raw(rec: &Path) -> (EstimateUpdate, Vec<RawBatch>) {
    let r = read_recording(rec).unwrap();
    let mut last = None;
    let mut raw = Vec::new();
    for m in r.messages {
        match m.message {
            SinkMessage::Estimates(e) => last = Some(e),
            SinkMessage::Raw(b) => raw.push(b),
            _ => {}
        }
    }
    (last.expect("estimates recorded"), raw)
}

/// Equal to rounding (relative 1e-9): the same `Pipeline` on the same samples,
/// pushed in other block sizes (its sums are not bit-invariant to the split).
/// Returns the largest relative difference.
pub fn close(a: &Coefficient, b: &Coefficient, what: &str) -> f64 {
    let (ca, cb) = (
        a.ci95.unwrap_or([f64::NAN; 2]),
        b.ci95.unwrap_or([f64::NAN; 2]),
    );
    assert_eq!(
        (a.value.is_some(), a.ci95.is_some(), a.upper95.is_some()),
        (b.value.is_some(), b.ci95.is_some(), b.upper95.is_some()),
        "{what}: {a:?} vs {b:?}"
    );
    let mut worst: f64 = 0.0;
    for (x, y) in [
        (a.value, b.value),
        (Some(ca[0]), Some(cb[0])),
        (Some(ca[1]), Some(cb[1])),
        (a.upper95, b.upper95),
    ] {
        if let (Some(x), Some(y)) = (x, y)
            && !(x.is_nan() && y.is_nan())
        {
            let rel = (x - y).abs() / x.abs().max(y.abs()).max(f64::MIN_POSITIVE);
            assert!(rel <= 1e-9, "{what}: {a:?} vs {b:?}");
            worst = worst.max(rel);
        }
    }
    worst
}

/// The five coefficients of `/gyro/estimates` and of `sagnac analyze --json`
/// (one name each, [`sagnac::units::COEFFICIENTS`]) match to rounding; the
/// largest relative difference.
pub fn close_estimates(recorded: &EstimateUpdate, analyze: &serde_json::Value, what: &str) -> f64 {
    let mut worst: f64 = 0.0;
    for (key, c) in recorded.coefficients() {
        let a: Coefficient = serde_json::from_value(analyze["estimates"][key].clone())
            .unwrap_or_else(|e| panic!("{what}: analyze's estimates.{key}: {e}"));
        worst = worst.max(close(c, &a, &format!("{key}: {what}")));
    }
    worst
}

/// `sagnac analyze --format FORMAT --input INPUT --json OUT`, its JSON report.
pub fn analyze_json(format: &str, input: &Path, out: &Path) -> serde_json::Value {
    // a frame capture carries no rate or pulse weight (the paper gyro's); an
    // MCAP recording's metadata record does
    let flags: &[&str] = if format == "mcap" {
        &[]
    } else {
        &["--sample-rate-hz", "1000", "--pulse-arcsec", "1.21"]
    };
    let r = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["analyze", "--format", format, "--input"])
        .arg(input)
        .args(flags)
        .arg("--json")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        r.status.success(),
        "analyze: {}",
        String::from_utf8_lossy(&r.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap()
}
