"""`sagnac.allan`: the curve and its EDF-based intervals, as `sagnac allan
--json` computes them, and its deviations as AllanTools'."""
import json

import allantools
import numpy as np
import pytest

import sagnac
from conftest import sagnac_cli


def test_allan_matches_the_command_line_and_allantools(tmp_path):
    rng = np.random.default_rng(11)
    y = rng.standard_normal(20000)
    f = tmp_path / "y.txt"
    np.savetxt(f, y, fmt="%.17g")
    for stat in ["oadev", "mdev", "totdev"]:
        py = sagnac.allan(y, tau0=0.5, data_type="freq", stat=stat, taus="octave")
        cli = json.loads(sagnac_cli("allan", "--input", f, "--data", "freq", "--tau0", "0.5",
                                    "--stat", stat, "--json", "-"))
        pts = cli["points"]
        assert len(py["tau_s"]) == len(pts)
        for key in ["tau_s", "dev", "ci_lo", "ci_hi", "edf", "n"]:
            np.testing.assert_allclose(py[key], [p[key] for p in pts], rtol=1e-12, err_msg=f"{stat} {key}")
        assert np.all(py["ci_lo"] < py["dev"]) and np.all(py["dev"] < py["ci_hi"])
        taus, devs, _, _ = getattr(allantools, stat)(y, rate=2.0, data_type="freq", taus=py["tau_s"])
        np.testing.assert_allclose(py["dev"], devs, rtol=1e-9)


def test_explicit_taus_counts_and_errors():
    counts = np.random.default_rng(2).integers(-3, 4, 5000).astype(float)
    r = sagnac.allan(counts, tau0=1e-3, data_type="counts", stat="oadev", taus=[1e-3, 1e-2, 0.1])
    np.testing.assert_allclose(r["tau_s"], [1e-3, 1e-2, 0.1])
    assert list(r["m"]) == [1, 10, 100]
    with pytest.raises(ValueError, match="stat"):
        sagnac.allan(counts, tau0=1.0, stat="xdev")
    with pytest.raises(ValueError, match="tau0"):
        sagnac.allan(counts, tau0=-1.0)
