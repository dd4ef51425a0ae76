"""Batched cost per candidate of the three block structures, measured side by side.

Issue 13's target: the batched cost of a Wiener model (linear block, then an
output nonlinearity applied in the compiled kernel pass) within 1.5x of the
Hammerstein one of the same order.  Timings on a shared machine are noisy, so
the structures are timed in interleaved rounds in one run (one batched call
of each per round, after a warm-up of each) and compared by the ratio of
their medians.

Examples
--------
>>> from speed import synthetic_record
>>> r = structure_cost_ratios(synthetic_record(2000), batch=4, repeat=3)
>>> sorted(r["ratios"])
['hammerstein-wiener', 'wiener', 'wiener-saturation']
>>> bool(all(v > 0 for v in r["per_candidate_s"].values()))
True
"""

from __future__ import annotations

import statistics
import time

import numpy as np

__all__ = ["benchmark_structures", "structure_cost_ratios", "format_structure_report", "WIENER_TARGET",
           "DEFAULT_BATCH", "DEFAULT_REPEAT"]

#: Issue 13's target for the Wiener / Hammerstein cost ratio.
WIENER_TARGET = 1.5
#: Candidates per batched call (the population of a batched optimiser).
DEFAULT_BATCH = 50
#: Interleaved timing rounds (the median is reported).
DEFAULT_REPEAT = 15
#: Relative spread of the candidates around the nominal beta.
_SPREAD = 1e-2
#: Name of the reference structure in the results.
REFERENCE = "hammerstein"


def benchmark_structures() -> dict:
    """The structures compared, with a nominal beta each, all on ``H(p) = 1/(p^2 + a1 p)`` (EMPS).

    * ``hammerstein``: Coulomb ``g`` then ``H`` (the paper's EMPS model);
    * ``wiener``: ``H`` then the same Coulomb map as ``h`` (same parameters,
      the block only moves to the output);
    * ``wiener-saturation``: ``H`` then a saturation ``h``;
    * ``hammerstein-wiener``: Coulomb ``g`` (gain fixed to 1) and a saturation ``h``.

    Returns
    -------
    dict
        name -> ``(structure, beta)``.
    """
    from hammerstein_ctrl.blocks import Coulomb, Saturation
    from hammerstein_ctrl.blocks import (HammersteinStructure, HammersteinWienerStructure, LinearStructure,
                                         WienerStructure)

    linear = LinearStructure(0, 2, fixed={"a0": 0.0})
    return {
        REFERENCE: (HammersteinStructure(linear, Coulomb()), np.array([3.14, 0.545, -0.398, 0.0451])),
        "wiener": (WienerStructure(linear, Coulomb()), np.array([3.14, 0.545, -0.001, 0.0001])),
        "wiener-saturation": (WienerStructure(linear, Saturation()), np.array([3.14, 0.5, 0.2])),
        "hammerstein-wiener": (HammersteinWienerStructure(linear, Coulomb(), Saturation()),
                               np.array([3.14, -0.7, 0.08, 0.5, 0.2])),
    }


def structure_cost_ratios(data, *, batch: int = DEFAULT_BATCH, repeat: int = DEFAULT_REPEAT, seed: int = 0) -> dict:
    """Time ``HammersteinCost.batch`` for each structure of :func:`benchmark_structures` on ``data``.

    Parameters
    ----------
    data : IOData
        The record (the EMPS estimation record: 12 000 samples).
    batch : int
        Candidates per call.
    repeat : int
        Interleaved rounds; each structure's figure is the median over them.
    seed : int
        Seed of the candidates' spread.

    Returns
    -------
    dict
        ``samples``, ``batch``, ``repeat``, ``per_candidate_s`` (name -> seconds
        per candidate) and ``ratios`` (name -> its time / the Hammerstein time).
    """
    from hammerstein_ctrl.fit import HammersteinCost

    rng = np.random.default_rng(seed)
    calls = {}
    for name, (structure, beta) in benchmark_structures().items():
        cost = HammersteinCost(data, structure)
        betas = beta * (1.0 + _SPREAD * rng.standard_normal((batch, beta.size)))
        calls[name] = (cost.batch, betas)
    times = {name: [] for name in calls}
    for fn, betas in calls.values():  # warm-up: compilation and caches
        fn(betas)
    for _ in range(repeat):
        for name, (fn, betas) in calls.items():
            t0 = time.perf_counter()
            fn(betas)
            times[name].append((time.perf_counter() - t0) / batch)
    per = {name: statistics.median(v) for name, v in times.items()}
    return {"samples": len(data), "batch": batch, "repeat": repeat, "per_candidate_s": per,
            "ratios": {name: per[name] / per[REFERENCE] for name in per if name != REFERENCE}}


def format_structure_report(result: dict) -> str:
    """Plain-text table of :func:`structure_cost_ratios`.

    Examples
    --------
    >>> print(format_structure_report({"samples": 10, "batch": 2, "repeat": 1,
    ...     "per_candidate_s": {"hammerstein": 1e-5, "wiener": 1.2e-5}, "ratios": {"wiener": 1.2}}))
    ... # doctest: +NORMALIZE_WHITESPACE
    Batched cost per candidate (N = 10, batch of 2, median of 1 interleaved rounds)
    hammerstein           10.0 us   1.00x
    wiener                12.0 us   1.20x
    Wiener / Hammerstein: 1.20x (target <= 1.5x: met)
    """
    lines = [f"Batched cost per candidate (N = {result['samples']}, batch of {result['batch']}, "
             f"median of {result['repeat']} interleaved rounds)"]
    for name, seconds in result["per_candidate_s"].items():
        ratio = result["ratios"].get(name, 1.0)
        lines.append(f"{name:<20}{seconds * 1e6:>8.1f} us{ratio:>7.2f}x")
    wiener = result["ratios"]["wiener"]
    verdict = "met" if wiener <= WIENER_TARGET else "NOT met"
    lines.append(f"Wiener / Hammerstein: {wiener:.2f}x (target <= {WIENER_TARGET:g}x: {verdict})")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - manual benchmark
    from hammerstein_ctrl.paper.presets import emps

    print(format_structure_report(structure_cost_ratios(emps().data)))
