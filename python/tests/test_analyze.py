"""`sagnac.analyze` on arrays: the dictionary `sagnac analyze --json` gives
for the same samples in a file, one axis or several, gyro and accelerometer."""
import json

import numpy as np
import pytest

import sagnac
from conftest import sagnac_cli


def close(a, b, rel=1e-9, at=""):
    """Every number of `a` within `rel` of `b`'s (block sizes may differ: last bits)."""
    if isinstance(a, dict):
        assert sorted(a) == sorted(b), at
        for k in a:
            close(a[k], b[k], rel, f"{at}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), at
        for i, (p, q) in enumerate(zip(a, b)):
            close(p, q, rel, f"{at}[{i}]")
    elif isinstance(a, float) and b is not None:
        assert abs(a - b) <= rel * abs(b), f"{at}: {a} vs {b}"
    else:
        assert a == b, f"{at}: {a} vs {b}"


def csv_of(tmp_path, name, columns):
    f = tmp_path / name
    names = list(columns)
    rows = np.column_stack([columns[n] for n in names])
    np.savetxt(f, rows, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return f


def test_one_gyro_axis_is_the_command_lines_analysis(tmp_path):
    rng = np.random.default_rng(5)
    rate = 0.01 + 1e-4 * np.sqrt(200) * rng.standard_normal(40000)  # rad/s
    py = sagnac.analyze(rate, sample_rate_hz=200.0, unit="rad_s")
    f = csv_of(tmp_path, "g.csv", {"gyro_x": rate})
    cli = json.loads(sagnac_cli("analyze", "--input", f, "--column", "gyro_x", "--unit", "rad_s",
                                "--sample-rate-hz", "200", "--json", "-"))
    for key in ["estimates", "allan", "baselines", "fit", "samples", "duration_s", "units"]:
        close(py[key], cli[key], at=key)
    assert py["input"]["format"] == "array" and py["input"]["unit"] == "rad_s"
    truth = np.degrees(1e-4) * 60  # deg/sqrt(h)
    lo, hi = py["estimates"]["arw_dpsh"]["ci95"]
    assert lo < truth < hi


def test_pulse_counts_take_the_exact_path(repo, tmp_path):
    sim = sagnac.simulate(repo / "config" / "paper_gyro.toml", 60.0, 3)
    counts = sim["counts"]
    assert counts.dtype == np.int64 and len(counts) == 60000
    py = sagnac.analyze(counts, sample_rate_hz=1000.0, unit="counts", pulse_arcsec=1.21)
    f = csv_of(tmp_path, "c.csv", {"counts": counts})
    cli = json.loads(sagnac_cli("analyze", "--input", f, "--sample-rate-hz", "1000",
                                "--pulse-arcsec", "1.21", "--json", "-"))
    close(py["estimates"], cli["estimates"])
    assert py["input"]["pulse_arcsec"] == 1.21
    with pytest.raises(ValueError, match="pulse"):
        sagnac.analyze(counts, sample_rate_hz=1000.0, unit="counts")


def test_several_axes_gyro_and_accelerometer():
    rng = np.random.default_rng(9)
    n = 30000
    gyro = 2e-4 * np.sqrt(100) * rng.standard_normal((n, 3))
    accel = 2e-3 * np.sqrt(100) * rng.standard_normal((n, 3)) + [0.0, 0.0, 9.80665]
    names = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
    r = sagnac.analyze(np.hstack([gyro, accel]), sample_rate_hz=100.0, unit="rad_s", axes=names)
    assert sorted(r["axes"]) == sorted(names)
    for a in names[3:]:
        e = r["axes"][a]["estimates"]
        assert "arw_dpsh" not in e
        lo, hi = e["vrw_mpssh"]["ci95"]
        assert lo < 2e-3 * 60 < hi, (a, e["vrw_mpssh"])
        assert r["axes"][a]["units"]["estimates.vrw_mpssh"] == "m/s/sqrt(h)"
    # a dict, and units per axis (g for the accelerometer)
    d = sagnac.analyze({"gyro_x": gyro[:, 0], "accel_x": accel[:, 0] / 9.80665},
                       sample_rate_hz=100.0, unit={"gyro_x": "rad_s", "accel_x": "g"})
    close(d["axes"]["accel_x"]["estimates"], r["axes"]["accel_x"]["estimates"], rel=1e-6)
    with pytest.raises(ValueError, match="axes="):
        sagnac.analyze(gyro, sample_rate_hz=100.0, unit="rad_s")
    with pytest.raises(ValueError, match="unit"):
        sagnac.analyze(gyro[:, 0], sample_rate_hz=100.0)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        sagnac.analyze(gyro[:, 0], sample_rate_hz=-1.0, unit="rad_s")
