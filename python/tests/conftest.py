"""Shared fixtures: the repository, the built command line, scratch files."""
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BIN = REPO / "target" / "release" / "sagnac"


def sagnac_cli(*args):
    """Run the command line (built by `cargo test --release`); its stdout."""
    if not BIN.exists():
        pytest.fail(f"{BIN} is missing: run `cargo build --release` first (scripts/test does)")
    out = subprocess.run([str(BIN), *map(str, args)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


@pytest.fixture
def repo():
    return REPO
