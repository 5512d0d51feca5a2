"""The AllanTools-compatible functions against AllanTools itself (a peer
installed by scripts/install-peers): the same taus, deviations, errors and
term counts to 1e-9, on the golden series and on random data of every kind."""
import json

import allantools
import numpy as np
import pytest

import sagnac

STATS = ["oadev", "adev", "mdev", "hdev", "ohdev", "totdev"]


def same(a, b, what):
    assert len(a) == 4 and len(b) == 4
    for name, p, q in zip(["taus", "devs", "errs", "ns"], a, b):
        p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
        assert p.shape == q.shape, f"{what} {name}: {p.shape} vs {q.shape}"
        np.testing.assert_allclose(p, q, rtol=1e-9, atol=0, err_msg=f"{what} {name}")


def golden(repo):
    return json.loads((repo / "tests" / "data" / "allantools_devs.json").read_text())["series"]


@pytest.mark.parametrize("stat", STATS)
def test_golden_series(repo, stat):
    checked = 0
    for s in golden(repo):
        if s["data"] == "counts":
            continue  # AllanTools has no pulse-count input
        x = np.asarray(s["values"], dtype=float)
        rate = 1.0 / float(s["tau0_s"])
        for taus in [None, "octave", "decade", "all"]:
            same(getattr(sagnac, stat)(x, rate=rate, data_type=s["data"], taus=taus),
                 getattr(allantools, stat)(x, rate=rate, data_type=s["data"], taus=taus),
                 f"{s['name']} {stat} {taus}")
            checked += 1
    assert checked == 16


@pytest.mark.parametrize("stat", STATS)
def test_random_data_tau_lists_and_rates(stat):
    rng = np.random.default_rng(7)
    for n, rate in [(50, 1.0), (101, 3.0), (4000, 0.25)]:
        for data_type in ["phase", "freq"]:
            x = np.cumsum(rng.standard_normal(n)) if data_type == "phase" else rng.standard_normal(n)
            for taus in [None, "decade", [0.5 / rate, 1.0 / rate, 3.3 / rate, 1e9], np.array([2.0 / rate])]:
                same(getattr(sagnac, stat)(x, rate=rate, data_type=data_type, taus=taus),
                     getattr(allantools, stat)(x, rate=rate, data_type=data_type, taus=taus),
                     f"{stat} n={n} {data_type} {taus}")


def test_a_list_of_floats_and_float32_are_taken():
    x = list(np.random.default_rng(3).standard_normal(300))
    same(sagnac.oadev(x), allantools.oadev(np.asarray(x)), "list")
    x32 = np.asarray(x, dtype=np.float32)
    same(sagnac.oadev(x32), allantools.oadev(x32.astype(float)), "float32")
    with pytest.raises(ValueError, match="data_type"):
        sagnac.oadev(x, data_type="fm")
