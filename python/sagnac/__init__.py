"""sagnac: gyro and IMU noise analysis from Python.

The same Rust code as the ``sagnac`` command line, on numpy arrays:

- ``analyze``: the IEEE 952 (gyro) and 1293 (accelerometer) coefficients with
  95 % intervals, the Allan curves and the data-quality findings: the
  dictionary ``sagnac analyze --json`` writes.
- ``oadev``, ``adev``, ``mdev``, ``hdev``, ``ohdev``, ``totdev``: AllanTools'
  functions, same arguments and same ``(taus, devs, errs, ns)``, so that
  ``import sagnac as allantools`` switches a notebook over.
- ``allan``: one Allan-family curve with EDF-based confidence intervals.
- ``simulate``, ``read``, ``diagnose``: the simulator, the input layer (CSV,
  frame captures, MCAP recordings, ROS 2 bags) and the model-vs-recording
  diagnosis.

Names follow the glossary (docs/glossary.md): ``sample_rate_hz``,
``pulse_arcsec``, ``tau_s``; units in the names.
"""

import json
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from . import _sagnac

__version__ = _sagnac.__version__

__all__ = [
    "analyze", "allan", "simulate", "read", "diagnose",
    "oadev", "adev", "mdev", "hdev", "ohdev", "totdev",
]

_GYRO_UNITS = ("counts", "dph", "dps", "rad_s")


def _f64(a, what="data"):
    """A contiguous float64 array (no copy when it already is one)."""
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{what}: expected a 1-D array, got shape {arr.shape}")
    return arr


def _axes_of(samples, axes):
    """{axis name: 1-D array} from one array, a 2-D array and `axes`, or a dict."""
    if isinstance(samples, dict):
        return {str(k): _f64(v, k) for k, v in samples.items()}
    arr = np.asarray(samples)
    if arr.ndim == 2:
        if axes is None or len(axes) != arr.shape[1]:
            raise ValueError(
                f"a 2-D array of {arr.shape[1]} columns needs axes= naming each column")
        return {str(a): _f64(arr[:, i], a) for i, a in enumerate(axes)}
    if axes is not None:
        raise ValueError("axes= names the columns of a 2-D array or is left out")
    return None


def _unit_for(unit, axis):
    if isinstance(unit, dict):
        if axis not in unit:
            raise ValueError(f"unit: no unit given for axis {axis!r}")
        return unit[axis]
    if unit is None:
        return "mps2" if axis.startswith("accel") else None
    if axis.startswith("accel") and unit in _GYRO_UNITS:
        return "mps2"
    return unit


def analyze(samples, *, sample_rate_hz, unit=None, pulse_arcsec=None, axes=None,
            raw_statistics=False):
    """The dictionary ``sagnac analyze --json`` writes, for samples in memory.

    samples: one array (one axis), a 2-D array with ``axes`` naming its
        columns, or a dict from axis name to array. Several axes give
        ``{"axes": {name: single-axis dict}, ...}``; an axis whose name starts
        with ``accel`` is an accelerometer (m/s^2 unless ``unit`` says ``g``).
    sample_rate_hz: the sample rate, Hz.
    unit: ``counts`` (pulse increments; needs ``pulse_arcsec``), ``dph``,
        ``dps``, ``rad_s`` for a gyro, ``mps2`` or ``g`` for an accelerometer;
        or a dict from axis name to unit.
    raw_statistics: turn the data-quality stage off.
    """
    several = _axes_of(samples, axes)
    if several is None:
        if unit is None:
            raise ValueError("unit is required (counts, dph, dps, rad_s, mps2 or g)")
        return json.loads(_sagnac.analyze_values(
            _f64(samples), sample_rate_hz, unit, pulse_arcsec, raw_statistics))
    units = {}
    for name in several:
        units[name] = _unit_for(unit, name)
        if units[name] is None:
            raise ValueError(f"unit is required for the gyro axis {name!r}")

    def one(name):
        return json.loads(_sagnac.analyze_values(
            several[name], sample_rate_hz, units[name], pulse_arcsec, raw_statistics, name))

    # the Rust side releases the GIL: the axes run side by side on the cores
    with ThreadPoolExecutor(max_workers=min(len(several), os.cpu_count() or 1)) as pool:
        out = dict(zip(several, pool.map(one, several)))
    return {"axes": out, "sagnac_version": __version__,
            "input": {"format": "array", "sample_rate_hz": sample_rate_hz}}


def allan(data, *, tau0, data_type="phase", stat="oadev", taus="octave", confidence=0.683):
    """One Allan-family curve with EDF-based confidence intervals.

    data_type: ``phase``, ``freq`` (integrated the AllanTools way) or
        ``counts`` (integer increments, accumulated exactly).
    stat: ``adev``, ``oadev``, ``mdev``, ``hdev``, ``ohdev`` or ``totdev``.
    taus: ``octave``, ``decade``, ``all``, or an array of taus in seconds.
    Returns a dict of arrays ``tau_s``, ``dev``, ``ci_lo``, ``ci_hi``,
    ``edf``, ``n`` (and ``m``, the averaging factors).
    """
    data = _f64(data)
    if isinstance(taus, str):
        return _sagnac.allan_curve(data, tau0, data_type, stat, taus, None, confidence)
    ms = sorted({int(round(t / tau0)) for t in np.atleast_1d(taus) if round(t / tau0) > 0})
    return _sagnac.allan_curve(data, tau0, data_type, stat, None, ms, confidence)


def _tau_ms(n_phase, rate, taus):
    """AllanTools' averaging factors for ``taus`` (its tau_generator rules)."""
    if taus is None or (isinstance(taus, list) and len(taus) == 0):
        taus = "octave"
    if isinstance(taus, str):
        if taus == "all":
            taus = (1.0 / rate) * np.linspace(1.0, n_phase, n_phase)
        elif taus == "octave":
            maxn = np.floor(np.log2(n_phase))
            taus = (1.0 / rate) * np.logspace(0, int(maxn), int(maxn + 1), base=2.0)
        elif taus == "decade":
            maxn = np.floor(np.log10(n_phase))
            taus = [f * (1.0 / rate) * pow(10.0, k)
                    for k in range(int(maxn + 1)) for f in (1.0, 2.0, 4.0)]
        elif taus == "log10":
            maxn = np.log10(n_phase)
            taus = (1.0 / rate) * np.logspace(0, maxn, int(10 * maxn), base=10.0)
        else:
            raise ValueError(f"taus {taus!r}: expected all, octave, decade, log10 or an array")
    m = np.round(np.asarray(taus, dtype=float) * float(rate))
    m = m[(m < n_phase) & (m > 0)]
    return np.unique(m).astype(np.uint64)


def _allantools(stat, data, rate, data_type, taus):
    data = _f64(data)
    n_phase = _sagnac.phase_len(len(data), data_type)
    ms = _tau_ms(n_phase, rate, taus)
    _, kept, devs, ns = _sagnac.deviations(data, float(rate), data_type, stat, [int(x) for x in ms])
    kept, devs, ns = np.asarray(kept, dtype=float), np.asarray(devs), np.asarray(ns, dtype=float)
    big = ns > 1
    kept, devs, ns = kept[big], devs[big], ns[big]
    return kept / float(rate), devs, devs / np.sqrt(ns), ns


def oadev(data, rate=1.0, data_type="phase", taus=None):
    """Overlapping Allan deviation, as ``allantools.oadev``: ``(taus, devs, errs, ns)``."""
    return _allantools("oadev", data, rate, data_type, taus)


def adev(data, rate=1.0, data_type="phase", taus=None):
    """Allan deviation, as ``allantools.adev``: ``(taus, devs, errs, ns)``."""
    return _allantools("adev", data, rate, data_type, taus)


def mdev(data, rate=1.0, data_type="phase", taus=None):
    """Modified Allan deviation, as ``allantools.mdev``: ``(taus, devs, errs, ns)``."""
    return _allantools("mdev", data, rate, data_type, taus)


def hdev(data, rate=1.0, data_type="phase", taus=None):
    """Hadamard deviation, as ``allantools.hdev``: ``(taus, devs, errs, ns)``."""
    return _allantools("hdev", data, rate, data_type, taus)


def ohdev(data, rate=1.0, data_type="phase", taus=None):
    """Overlapping Hadamard deviation, as ``allantools.ohdev``: ``(taus, devs, errs, ns)``."""
    return _allantools("ohdev", data, rate, data_type, taus)


def totdev(data, rate=1.0, data_type="phase", taus=None):
    """Total deviation, as ``allantools.totdev``: ``(taus, devs, errs, ns)``."""
    return _allantools("totdev", data, rate, data_type, taus)


def simulate(model, duration_s, seed):
    """A simulated run of a gyro model (a TOML file's path or its text).

    Returns a dict: ``counts`` (pulse increments) and ``pulse_arcsec``, or
    ``rate_dps`` for a rate-output model; ``temp_c`` when the model has a
    thermal section; ``sample_rate_hz``, ``duration_s``, ``seed``.
    """
    return _sagnac.simulate(str(model), float(duration_s), int(seed))


def read(path, **input_options):
    """Anything ``sagnac analyze --input`` opens (CSV or text, a frame
    capture, an MCAP recording, a ROS 2 bag), read whole.

    input_options: ``format``, ``column``, ``unit``, ``sample_rate_hz``,
    ``pulse_arcsec``, ``gyro``, ``topic``, as the command line's flags.
    Returns a dict: ``counts`` (whole pulse counts) or ``values`` (in
    ``meta["unit"]``), ``filled`` (samples made up to fill gaps),
    ``temp_c`` when present, and ``meta``.
    """
    return _sagnac.read(os.fspath(path), **input_options)


def diagnose(model, recording, **options):
    """The dictionary ``sagnac diagnose --json`` writes: ``model`` is the gyro
    model file, ``recording`` anything the input layer opens. ``options`` are
    the command's flags without dashes (``sample_rate_hz=1000``,
    ``runs=20``, ``raw_statistics=True``, ...)."""
    args = ["--model", os.fspath(model), "--input", os.fspath(recording)]
    for k, v in options.items():
        flag = "--" + k.replace("_", "-")
        if v is True:
            args.append(flag)
        elif v is not False and v is not None:
            args += [flag, str(v)]
    with tempfile.TemporaryDirectory() as d:
        return json.loads(_sagnac.diagnose_cli(args, os.path.join(d, "diagnosis.json")))
