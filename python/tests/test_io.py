"""`sagnac.simulate`, `sagnac.read` and `sagnac.diagnose`: the simulator, the
input layer and the diagnosis, as the command line runs them."""
import json

import numpy as np
import pytest

import sagnac
from conftest import sagnac_cli


def test_simulate_is_the_command_lines_simulator(repo, tmp_path):
    model = repo / "config" / "paper_gyro.toml"
    sim = sagnac.simulate(model, 5.0, 42)
    out = tmp_path / "sim.csv"
    sagnac_cli("simulate", "--model", model, "--duration-s", "5", "--seed", "42", "--out", out)
    back = sagnac.read(out, sample_rate_hz=1000.0, pulse_arcsec=1.21)
    np.testing.assert_array_equal(sim["counts"], back["counts"])
    assert sim["sample_rate_hz"] == 1000.0 and sim["pulse_arcsec"] == 1.21
    assert back["meta"]["format"] == "csv" and not back["filled"].any()
    # the model as text
    again = sagnac.simulate(model.read_text(), 5.0, 42)
    np.testing.assert_array_equal(sim["counts"], again["counts"])


def test_read_a_recording_and_errors(repo, tmp_path):
    model = repo / "config" / "paper_gyro.toml"
    rec = tmp_path / "r.mcap"
    sagnac_cli("simulate", "--model", model, "--duration-s", "3", "--seed", "1", "--format", "mcap", "--out", rec)
    r = sagnac.read(rec)
    assert r["meta"]["format"] == "mcap" and r["meta"]["sample_rate_hz"] == 1000.0
    assert len(r["counts"]) == 3000
    with pytest.raises(OSError):
        sagnac.read(tmp_path / "absent.csv")
    with pytest.raises(ValueError, match="no samples"):
        sagnac.analyze(np.zeros(0), sample_rate_hz=1.0, unit="dph")


def test_diagnose_is_the_command_lines_diagnosis(repo, tmp_path):
    model = repo / "config" / "paper_gyro.toml"
    rec = tmp_path / "r.csv"
    sagnac_cli("simulate", "--model", model, "--duration-s", "120", "--seed", "4", "--out", rec)
    d = sagnac.diagnose(model, rec, sample_rate_hz=1000, pulse_arcsec=1.21, runs=8, seed=1)
    out = tmp_path / "d.json"
    sagnac_cli("diagnose", "--model", model, "--input", rec, "--sample-rate-hz", "1000",
               "--pulse-arcsec", "1.21", "--runs", "8", "--seed", "1", "--json", out)
    assert d == json.loads(out.read_text())
    assert d["verdict"] == "consistent" and d["input"]["format"] == "csv"
    with pytest.raises(ValueError, match="model"):
        sagnac.diagnose(tmp_path / "none.toml", rec, sample_rate_hz=1000, pulse_arcsec=1.21)
