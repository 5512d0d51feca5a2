//! Helpers shared by the integration test suites (each `tests/<suite>/main.rs`
//! includes this directory as its `support` module): the repository, the
//! reference data, the built binary, free ports, simulated recordings; and the
//! helpers of the daemon, DSP, Prometheus and sink tests in submodules.
#![allow(dead_code)]

pub mod daemon;
pub mod dsp;
pub mod prom;
mod sim;
pub mod sink;

#[allow(unused_imports)] // not every suite simulates recordings
pub use sim::simulated_recording;

use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Repository root (the crate's manifest directory).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `config/paper_gyro.toml`: the founding paper's gyro, the model most tests
/// simulate.
pub const PAPER_GYRO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/config/paper_gyro.toml");

/// The third-party reference data in `../shared/data` (relative to the repository
/// root; `SAGNAC_SHARED_DATA` overrides). When it is absent, print a notice and
/// return `None` so the caller skips, except under `CI=true`, where absence fails.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("SAGNAC_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("..").join("shared").join("data"));
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!(
            "reference data not found at {} (CI=true: absence is a failure; set SAGNAC_SHARED_DATA)",
            dir.display()
        );
    }
    eprintln!(
        "NOTICE: reference data not found at {}; skipping this test (set SAGNAC_SHARED_DATA)",
        dir.display()
    );
    None
}

/// A free loopback port (bound then released).
pub fn free_addr() -> SocketAddr {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap()
}

/// The built `sagnac` binary, to be given its arguments.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sagnac"))
}

/// Run the built `sagnac` binary with `args`.
pub fn sagnac(args: &[&str]) -> Output {
    bin().args(args).output().expect("run sagnac")
}

/// `seconds` of a 1 kHz pulse counter (pulse 1.21", input 12.3 deg/h, Q 0.35",
/// N 0.0015 deg/sqrt(h)) simulated by `sagnac simulate --seed 5` into
/// `dir/run.csv` (its model in `dir/m.toml`); the CSV's path.
pub fn simulated_csv(dir: &Path, seconds: &str) -> PathBuf {
    let model = dir.join("m.toml");
    std::fs::write(
        &model,
        "[gyro]\nsample_rate_hz = 1000.0\npulse_arcsec = 1.21\ninput_rate_dph = 12.3\n\
         [noise]\nquantization_arcsec = 0.35\narw_dpsh = 0.0015\n",
    )
    .unwrap();
    let csv = dir.join("run.csv");
    let o = sagnac(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--duration-s",
        seconds,
        "--seed",
        "5",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    csv
}
