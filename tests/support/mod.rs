//! Helpers shared by the integration test suites (each `tests/<suite>/main.rs`
//! includes this directory as its `support` module): the repository, the
//! reference data, the built binary, free ports, simulated recordings; and the
//! helpers of the daemon, DSP, Prometheus and sink tests in submodules.
#![allow(dead_code)]

pub mod daemon;
pub mod dsp;
pub mod prom;
pub mod sink;
mod sim;

#[allow(unused_imports)] // not every suite simulates recordings
pub use sim::simulated_recording;

use std::net::{SocketAddr, TcpListener};
use std::path::PathBuf;

/// Repository root (the crate's manifest directory).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

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
