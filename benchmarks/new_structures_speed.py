"""One cost evaluation of a Wiener-Hammerstein model and of a map loop against a Hammerstein one, side by side.

The issue's targets: a Wiener-Hammerstein evaluation within 3x a Hammerstein one of the same total order, a
smooth-map Lur'e evaluation within 5x.  Each case is timed in interleaved rounds (one call of each per round, after a
warm-up) on the same record, and compared by the ratio of the medians; also one fit on the Wiener-Hammerstein
benchmark's 100 000 samples when ``HAMMERSTEIN_CTRL_DATA`` holds it.

Run: ``python benchmarks/new_structures_speed.py`` (prints a table; asserts nothing).
"""

from __future__ import annotations

import os
import statistics
import time
import warnings

import numpy as np

import hammerstein_ctrl as hc
from hammerstein_ctrl.blocks import LureStructure
from hammerstein_ctrl.fit import LureCost
from hammerstein_ctrl.fit import HammersteinCost
from hammerstein_ctrl.fit import WienerHammersteinCost
from hammerstein_ctrl.blocks import WienerHammersteinStructure


def _record(n=24000, dt=1e-3, seed=0):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1, 1, n // 50), 50)
    return hc.IOData(u, np.sin(np.arange(n) * dt) + 0.01 * rng.standard_normal(n), dt=dt)


def _cases(data):
    """``{name: (cost, beta)}``: the Hammerstein references and the new structures (orders matched)."""
    h4 = hc.HammersteinStructure(hc.LinearStructure(1, 4), hc.Polynomial(3))
    wh = WienerHammersteinStructure((0, 2), hc.Polynomial(3), (1, 2), time_unit=0.01)
    h2 = hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh())
    lin = hc.LinearStructure(0, 2, monic_numerator=False, fixed={"a0": 0.0})
    duffing = LureStructure(lin, hc.Polynomial(3), feedback="output")
    tanh_friction = LureStructure(lin, hc.Tanh(), feedback="velocity")
    return {
        "Hammerstein, order 4": (HammersteinCost(data, h4), np.array([2.0, 24.0, 50.0, 35.0, 10.0, 1.0, 0.1, -0.2])),
        "Wiener-Hammerstein, 2 + 2": (WienerHammersteinCost(data, wh), np.array([0.3, 0.02, 0.1, 0.4, 0.05, 1.0, 0.1,
                                                                                 -0.2])),
        "Hammerstein, order 2": (HammersteinCost(data, h2), np.array([4.0, 2.0, 1.0, 1.0])),
        "Lur'e, Duffing on the output": (LureCost(data, duffing), np.array([2.0, 0.6, 4.0, 0.0, 3.0])),
        "Lur'e, tanh friction on velocity": (LureCost(data, tanh_friction), np.array([1.0, 0.2, 0.5, 25.0])),
    }


def timings(data, repeat=31):
    cases = _cases(data)
    for cost, beta in cases.values():
        cost(beta)
    times = {name: [] for name in cases}
    for _ in range(repeat):
        for name, (cost, beta) in cases.items():
            t0 = time.perf_counter()
            cost(beta)
            times[name].append(time.perf_counter() - t0)
    return {name: statistics.median(v) for name, v in times.items()}


def benchmark_fit():
    from hammerstein_ctrl.paper.benchmarks import load_wiener_hammerstein, benchmark_rmse, wh_benchmark_structure

    b = load_wiener_hammerstein()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = hc.identify(b.estimation, wh_benchmark_structure(b.estimation), seed=0)
    took = time.perf_counter() - t0
    test = b.tests["test"]
    return took, r.nfev, benchmark_rmse(r.model.simulate(test), test, b)


def main():
    data = _record()
    t = timings(data)
    print(f"one cost evaluation, {len(data)} samples, median of interleaved rounds")
    for name, v in t.items():
        print(f"  {name:34s} {1e6 * v:9.1f} us")
    ratio = t["Wiener-Hammerstein, 2 + 2"] / t["Hammerstein, order 4"]
    print(f"  Wiener-Hammerstein / Hammerstein (order 4): {ratio:.2f}x (target <= 3)")
    for name in ("Lur'e, Duffing on the output", "Lur'e, tanh friction on velocity"):
        print(f"  {name} / Hammerstein (order 2): {t[name] / t['Hammerstein, order 2']:.2f}x (target <= 5)")
    if os.environ.get("HAMMERSTEIN_CTRL_DATA"):
        took, nfev, rmse = benchmark_fit()
        print(f"one fit on the WH benchmark (100 000 samples): {took:.1f} s, {nfev} evaluations, test RMSE "
              f"{rmse:.3f} mV (target <= 60 s)")


if __name__ == "__main__":
    main()
