"""The public nonlinear benchmarks beside the EMPS: Wiener-Hammerstein 2009, Silverbox, Cascaded Tanks.

Each loader returns a :class:`Benchmark`: the estimation record, the test
record(s) and the benchmark's protocol, with the official splits of the
``nonlinear-benchmarks`` package 1.0.1.  The model is given the test input and
only the first :data:`N_INIT` test outputs (to set its initial state); the
RMSE is taken on the outputs after them, in the benchmark's unit
(:func:`test_rmse`).

The files are read from ``$HAMMERSTEIN_CTRL_DATA/benchmarks/<name>/`` (or a
``path`` given to the loader); they are third-party data and are not shipped
with the package.  Train and choose on ``estimation`` only: the test records
are for the final figure.

Examples
--------
With the files in ``$HAMMERSTEIN_CTRL_DATA/benchmarks``::

    >>> b = load_wiener_hammerstein()                       # doctest: +SKIP
    >>> len(b.estimation), len(b.tests["test"]), b.unit     # doctest: +SKIP
    (100000, 78800, 'mV')
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..exceptions import DataError, DataNotFoundError
from ..iodata import IOData
from ..safe_io import MAX_INPUT_BYTES, check_input
from .datasets import ENV_DATA

__all__ = ["Benchmark", "load_wiener_hammerstein", "load_silverbox", "load_cascaded_tanks", "test_rmse",
           "initial_samples", "N_INIT", "PUBLISHED", "SOURCES"]

#: Test outputs the model may read to set its initial state; the RMSE is taken after them.
N_INIT = 50

#: Published test RMSEs (benchmark unit) for comparison: ``{benchmark: {result: value}}``, sources in :data:`SOURCES`.
PUBLISHED = {
    "wiener_hammerstein": {"linear (BLA)": 43.4, "GRU": 3.97, "best published": 0.241},
    "silverbox/multisine": {"linear": 6.96, "GRU": 1.49, "best published (GP-NARX)": 0.301},
    "silverbox/arrow": {"GRU": 2.80, "best published (GP-NARX)": 0.60},
    "cascaded_tanks": {"linear": 0.588, "GRU": 0.396, "best published (grey-box)": 0.191},
}
#: Where the figures of :data:`PUBLISHED` come from.
SOURCES = {
    "wiener_hammerstein": "Schoukens, Suykens, Ljung: Wiener-Hammerstein benchmark, SYSID 2009; the best published "
                          "figure and the GRU baseline as tabulated by nonlinearbenchmark.org (Beintema et al., "
                          "'Deep subspace encoders for nonlinear system identification', Automatica 2023)",
    "silverbox": "Wigren, Schoukens: three free data sets for nonlinear identification, ECC 2013; GP-NARX and GRU "
                 "as tabulated by nonlinearbenchmark.org",
    "cascaded_tanks": "Schoukens, Mattsson, Wigren, Noel: Cascaded tanks benchmark, 2016; grey-box and GRU as "
                      "tabulated by nonlinearbenchmark.org",
}


class Benchmark(NamedTuple):
    """A benchmark: ``estimation`` record, ``tests`` (name -> record), ``scale`` from the records' unit to the
    benchmark's ``unit`` (e.g. 1000 for V -> mV), ``n_init`` outputs given for the initial state."""

    name: str
    estimation: IOData
    tests: dict
    unit: str
    scale: float
    n_init: int = N_INIT


def _locate(folder: str, file: str, path) -> Path:
    if path is not None:
        p = Path(path).expanduser()
        candidates = [p] if p.suffix else [p / file, p / folder / file]
    else:
        env = os.environ.get(ENV_DATA)
        candidates = [Path(env).expanduser() / "benchmarks" / folder / file] if env else []
    for cand in candidates:
        if cand.is_file():
            check_input(cand, limit=MAX_INPUT_BYTES, what="benchmark file")
            return cand
    looked = "\n".join(f"  - {c}" for c in candidates) or f"  - ${ENV_DATA}/benchmarks/{folder}/{file} (not set)"
    raise DataNotFoundError(f"the benchmark file {file} was not found. Looked in:\n{looked}\nGet it from "
                            f"https://www.nonlinearbenchmark.org and pass its folder (path=...) or point ${ENV_DATA} "
                            f"at a folder holding benchmarks/{folder}/{file}")


@functools.lru_cache(maxsize=4)
def _read_mat(path: str, mtime: float) -> dict:
    import scipy.io

    try:
        return {k: v for k, v in scipy.io.loadmat(path).items() if not k.startswith("__")}
    except (ValueError, OSError, NotImplementedError) as exc:
        raise DataError(f"{path} is not a readable MATLAB file: {exc}") from None


def _mat(folder: str, file: str, path) -> dict:
    p = _locate(folder, file, path)
    return _read_mat(str(p), p.stat().st_mtime)


def _vector(mat: dict, key: str, file: str) -> np.ndarray:
    if key not in mat:
        raise DataError(f"{file} has no variable {key!r} (it has {sorted(mat)})")
    return np.asarray(mat[key], dtype=float).reshape(-1)


def _record(u, y, dt, name) -> IOData:
    return IOData(np.ascontiguousarray(u), np.ascontiguousarray(y), dt=dt, name=name, intersample="foh")


def load_wiener_hammerstein(path=None) -> Benchmark:
    """The Wiener-Hammerstein 2009 benchmark: samples ``[5200, 184000)`` of ``WienerHammerBenchMark.mat``, the first
    100 000 for estimation, the remaining 78 800 for the test; fs = 51 200 Hz; RMSE in mV."""
    file = "WienerHammerBenchMark.mat"
    m = _mat("wiener_hammerstein", file, path)
    u, y = _vector(m, "uBenchMark", file)[5200:184000], _vector(m, "yBenchMark", file)[5200:184000]
    dt = 1.0 / float(_vector(m, "fs", file)[0])
    return Benchmark("wiener_hammerstein", _record(u[:100000], y[:100000], dt, "WH estimation"),
                     {"test": _record(u[100000:], y[100000:], dt, "WH test")}, "mV", 1000.0)


def load_silverbox(path=None) -> Benchmark:
    """The Silverbox (``SNLS80mV.mat``: ``V1`` input, ``V2`` output, Ts = 1/610.35 s): estimation on the multisine
    part ``[40650, 105712)``; tests ``"multisine"`` ``[105712, 127400)``, ``"arrow"`` (full) ``[100, 40575)`` and
    ``"arrow-no-extrapolation"`` (its first 32 000 samples); RMSE in mV."""
    file = "SNLS80mV.mat"
    m = _mat("silverbox", file, path)
    u, y = _vector(m, "V1", file), _vector(m, "V2", file)
    dt = 1.0 / 610.35
    arrow = (u[100:40575], y[100:40575])
    return Benchmark("silverbox", _record(u[40650:105712], y[40650:105712], dt, "Silverbox estimation"), {
        "multisine": _record(u[105712:127400], y[105712:127400], dt, "Silverbox multisine test"),
        "arrow": _record(*arrow, dt, "Silverbox arrow (full)"),
        "arrow-no-extrapolation": _record(arrow[0][:32000], arrow[1][:32000], dt, "Silverbox arrow (no extrap.)"),
    }, "mV", 1000.0)


def load_cascaded_tanks(path=None) -> Benchmark:
    """The Cascaded Tanks (``dataBenchmark.mat``): estimation ``uEst/yEst``, test ``uVal/yVal``, Ts = 4 s; RMSE in V."""
    file = "dataBenchmark.mat"
    m = _mat("cascaded_tanks", file, path)
    dt = 4.0
    return Benchmark("cascaded_tanks", _record(_vector(m, "uEst", file), _vector(m, "yEst", file), dt, "Tanks est."),
                     {"test": _record(_vector(m, "uVal", file), _vector(m, "yVal", file), dt, "Tanks test")}, "V", 1.0)


def initial_samples(record: IOData, n_init: int = N_INIT) -> IOData:
    """The part of a test record a model may see whole: its first ``n_init`` samples."""
    return record[:n_init]


def test_rmse(y_hat, record: IOData, benchmark: Benchmark) -> float:
    """The benchmark's figure: RMSE of ``y - y_hat`` after the first ``n_init`` samples, in the benchmark's unit.

    Examples
    --------
    >>> rec = IOData(np.zeros(60), np.r_[np.zeros(50), np.full(10, 0.002)], dt=1.0)
    >>> b = Benchmark("x", rec, {"test": rec}, "mV", 1000.0)
    >>> round(test_rmse(np.zeros(60), rec, b), 6)
    2.0
    """
    y = np.asarray(record.y, dtype=float).reshape(-1)
    e = (y - np.asarray(y_hat, dtype=float).reshape(-1))[benchmark.n_init:]
    return float(benchmark.scale * np.sqrt(np.mean(e * e)))
