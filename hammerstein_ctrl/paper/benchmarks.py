"""The public nonlinear benchmarks beside the EMPS: Wiener-Hammerstein 2009, Silverbox, Cascaded Tanks.

Each loader returns a :class:`Benchmark`: the estimation record, the test
record(s) and the benchmark's protocol, with the official splits of the
``nonlinear-benchmarks`` package 1.0.1.  The model is given the test input and
only the first :data:`N_INIT` test outputs (to set its initial state); the
RMSE is taken on the outputs after them, in the benchmark's unit
(:func:`benchmark_rmse`).

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
from ..data._iodata import IOData
from .._safe_io import MAX_INPUT_BYTES, check_input
from .datasets import ENV_DATA

__all__ = ["Benchmark", "load_wiener_hammerstein", "load_silverbox", "load_cascaded_tanks", "benchmark_rmse",
           "initial_samples", "wh_benchmark_structure", "silverbox_structure", "silverbox_duffing_structure",
           "duffing_parameters", "simulate_test", "N_INIT", "TANKS_N_INIT", "STATE_SAMPLES", "PUBLISHED", "SOURCES",
           "WH_KNOTS"]

#: Test outputs the model may read to set its initial state; the RMSE is taken after them.
N_INIT = 50
#: The same for the Cascaded Tanks (``nonlinear_benchmarks``' ``state_initialization_window_length`` there).
TANKS_N_INIT = 5
#: Fewest given outputs per state for :func:`simulate_test` to fit the initial state to them.
STATE_SAMPLES = 4

#: Published test RMSEs (benchmark unit) for comparison: ``{benchmark: {result: value}}``, sources in :data:`SOURCES`.
PUBLISHED = {
    "wiener_hammerstein": {"linear (BLA)": 43.4, "GRU": 3.97, "best published": 0.241},
    "silverbox/multisine": {"linear": 6.96, "GRU": 1.49, "best published (GP-NARX)": 0.301},
    "silverbox/arrow": {"GRU": 2.80, "best published (GP-NARX)": 0.60},
    "cascaded_tanks": {"linear": 0.588, "GRU": 0.396, "best published (grey-box)": 0.191},
}
#: Where the figures of :data:`PUBLISHED` come from.
SOURCES = {
    "baselines": "Champneys, Beintema, Toth, Schoukens, Rogers: 'Baseline results for selected nonlinear system "
                 "identification benchmarks', arXiv:2405.10779 (2024): linear, recurrent-network (GRU) and GP-NARX "
                 "baselines on these splits, beside the best published result of each benchmark",
    "wiener_hammerstein": "Schoukens, Suykens, Ljung: 'Wiener-Hammerstein benchmark', SYSID 2009 (the data)",
    "silverbox": "Wigren, Schoukens: 'Three free data sets for development and benchmarking in nonlinear system "
                 "identification', ECC 2013 (the data)",
    "cascaded_tanks": "Schoukens, Mattsson, Wigren, Noel: 'Cascaded tanks benchmark combining soft and hard "
                      "nonlinearities', Workshop on Nonlinear System Identification Benchmarks 2016 (the data)",
}


#: Knots of the Wiener-Hammerstein benchmark's piecewise-linear map, chosen on the estimation record alone: fitted
#: on its first 80 000 samples, the holdout of its last 20 000 gave 0.704 mV (11 knots), 0.574 (15), 0.512 (21),
#: 0.501 (31); 21 is the fewest within 5 % of the best.
WH_KNOTS = 21


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
    """The Cascaded Tanks (``dataBenchmark.mat``): estimation ``uEst/yEst``, test ``uVal/yVal``, Ts = 4 s; the first
    :data:`TANKS_N_INIT` test outputs set the state; RMSE in V."""
    file = "dataBenchmark.mat"
    m = _mat("cascaded_tanks", file, path)
    dt = 4.0
    return Benchmark("cascaded_tanks", _record(_vector(m, "uEst", file), _vector(m, "yEst", file), dt, "Tanks est."),
                     {"test": _record(_vector(m, "uVal", file), _vector(m, "yVal", file), dt, "Tanks test")}, "V", 1.0,
                     n_init=TANKS_N_INIT)


def initial_samples(record: IOData, n_init: int = N_INIT) -> IOData:
    """The part of a test record a model may see whole: its first ``n_init`` samples."""
    return record[:n_init]


def benchmark_rmse(y_hat, record: IOData, benchmark: Benchmark) -> float:
    """The benchmark's figure: RMSE of ``y - y_hat`` after the first ``n_init`` samples, in the benchmark's unit.

    Examples
    --------
    >>> rec = IOData(np.zeros(60), np.r_[np.zeros(50), np.full(10, 0.002)], dt=1.0)
    >>> b = Benchmark("x", rec, {"test": rec}, "mV", 1000.0)
    >>> round(benchmark_rmse(np.zeros(60), rec, b), 6)
    2.0
    """
    y = np.asarray(record.y, dtype=float).reshape(-1)
    e = (y - np.asarray(y_hat, dtype=float).reshape(-1))[benchmark.n_init:]
    return float(benchmark.scale * np.sqrt(np.mean(e * e)))


def wh_benchmark_structure(estimation: IOData, knots: int = WH_KNOTS):
    """The Wiener-Hammerstein benchmark's structure: ``G1`` of order 3 (no zero), a piecewise-linear map with
    ``knots`` breakpoints at the estimation input's quantiles 0.5 % ... 99.5 %, ``G2`` of order 3 with two zeros
    (the benchmark's circuit: a Chebyshev low-pass, a diode, an inverse Chebyshev filter), an output offset.

    Examples
    --------
    >>> rec = IOData(np.linspace(-1.0, 1.0, 200), np.zeros(200), dt=1.0)
    >>> wh_benchmark_structure(rec, knots=5).param_names[:6]
    ('g1_a1', 'g1_a2', 'g1_a3', 'g2_b1', 'g2_b2', 'g2_a1')
    """
    from ..blocks._families import PiecewiseLinear
    from ..blocks._wiener_hammerstein import WienerHammersteinStructure

    u = np.asarray(estimation.u, dtype=float).reshape(-1)
    knots_at = np.quantile(u, np.linspace(0.005, 0.995, int(knots)))
    return WienerHammersteinStructure((0, 3), PiecewiseLinear(knots_at), (2, 3), offset=True)


def silverbox_structure():
    """The Silverbox's Lur'e loop: ``B(p)/(p A'(p))`` of orders 2/4 (``a0 = 0``: the spring is the map's), a cubic
    ``d1 y + d2 y^2 + d3 y^3`` fed back on the output, an offset.  The orders were chosen on the estimation record
    alone (fitted on its first 80 %, the holdout of its last 20 % gave 0.890 mV for 0/2, 0.878 for 1/3, 0.298 for
    2/4, 0.299 for 3/5).

    Examples
    --------
    >>> silverbox_structure().param_names
    ('b0', 'b1', 'b2', 'a1', 'a2', 'a3', 'd1', 'd2', 'd3', 'y0')
    """
    from ..blocks._lure import LureStructure
    from ..blocks._families import Polynomial
    from ..blocks._structure import LinearStructure

    return LureStructure(LinearStructure(2, 4, monic_numerator=False, fixed={"a0": 0.0}), Polynomial(3),
                         feedback="output", offset=True)


def silverbox_duffing_structure():
    """The Silverbox as the physical Duffing oscillator ``m y'' + d y' + k1 y + k2 y^2 + k3 y^3 = u``:
    ``b0 / (p^2 + a1 p)`` with the cubic on the output (:func:`duffing_parameters` reads it).

    Examples
    --------
    >>> silverbox_duffing_structure().param_names
    ('b0', 'a1', 'd1', 'd2', 'd3', 'y0')
    """
    from ..blocks._lure import LureStructure
    from ..blocks._families import Polynomial
    from ..blocks._structure import LinearStructure

    return LureStructure(LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0}), Polynomial(3),
                         feedback="output", offset=True)


def duffing_parameters(x, covariance) -> dict:
    """``{name: (value, standard error)}`` of the Duffing oscillator's physical parameters from a fit of
    :func:`silverbox_duffing_structure`: mass ``m = 1/b0``, damping ``d = a1/b0``, stiffnesses ``k1, k2, k3``
    (``d1, d2, d3``; per unit of the input), natural frequency ``w0 = sqrt(b0 d1)`` (rad/s) and damping ratio
    ``zeta = a1 / (2 w0)``; standard errors by the delta method.

    Examples
    --------
    >>> p = duffing_parameters([4.0, 0.8, 1.0, 0.0, 3.0, 0.0], np.zeros((6, 6)))
    >>> p["m"][0], p["w0"][0], round(p["zeta"][0], 6)
    (0.25, 2.0, 0.2)
    """
    x = np.asarray(x, dtype=float)
    cov = np.asarray(covariance, dtype=float)[:5, :5]
    b0, a1, d1, d2, d3 = x[:5]
    w0 = np.sqrt(b0 * d1)
    rows = {  # value, gradient in (b0, a1, d1, d2, d3)
        "m": (1 / b0, [-1 / b0**2, 0, 0, 0, 0]),
        "d": (a1 / b0, [-a1 / b0**2, 1 / b0, 0, 0, 0]),
        "k1": (d1, [0, 0, 1, 0, 0]), "k2": (d2, [0, 0, 0, 1, 0]), "k3": (d3, [0, 0, 0, 0, 1]),
        "w0": (w0, [d1 / (2 * w0), 0, b0 / (2 * w0), 0, 0]),
        "zeta": (a1 / (2 * w0), [-a1 * d1 / (4 * w0**3), 1 / (2 * w0), -a1 * b0 / (4 * w0**3), 0, 0]),
    }
    return {k: (float(v), float(np.sqrt(max(0.0, np.asarray(g) @ cov @ np.asarray(g))))) for k, (v, g) in rows.items()}


def simulate_test(structure, x, record: IOData, n_init: int = N_INIT) -> np.ndarray:
    """The fitted model (``structure`` at ``x``) run on a test record, its initial state fitted by least squares to the
    record's first ``n_init`` outputs (all the benchmark protocol gives it); the other parameters stay as fitted.
    With fewer than :data:`STATE_SAMPLES` outputs per state (the Cascaded Tanks' 5 for 3 states) that fit is
    ill-posed and the model starts as fitted (at rest).

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> t = np.arange(100) * 0.1
    >>> rec = IOData(np.ones(100), 1.0 - 0.5 * np.exp(-t), dt=0.1)           # starts at 0.5, not at rest
    >>> y = simulate_test(s, [1.0, 1.0], rec)
    >>> float(np.max(np.abs(y - rec.y))) < 1e-6
    True
    """
    import scipy.optimize

    s = structure.with_options(initial_state="estimate")
    x = np.asarray(x, dtype=float)
    core = x[:structure.n_core]
    offset = x[structure.n_core:structure.n_core + 1] if structure.offset else np.empty(0)
    n_state = s.n_params - structure.n_core - offset.size
    if n_init < STATE_SAMPLES * n_state:
        return structure.model(x, intersample=record.intersample).simulate(record)
    head = record[:n_init]

    def beta(state):
        return np.concatenate([core, offset, state])

    def residuals(state):
        with np.errstate(all="ignore"):
            r = head.y - s.model(beta(state), intersample=record.intersample).simulate(head)
        return np.where(np.isfinite(r), r, 1e6)

    state = scipy.optimize.least_squares(residuals, np.zeros(n_state), method="lm").x
    return s.model(beta(state), intersample=record.intersample).simulate(record)
