//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// Repository root (the crate's manifest directory).
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The third-party reference data in `../shared/data` (relative to the repository
/// root; `SAGNAC_SHARED_DATA` overrides). When it is absent, print a notice and
/// return `None` so the caller skips, except under `CI=true`, where absence fails.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("SAGNAC_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("..").join("shared").join("data"));
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
