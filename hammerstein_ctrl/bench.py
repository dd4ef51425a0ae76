"""Side-by-side speed measurements (``hammerstein-ctrl bench``).

Timings on a shared machine are noisy, so every figure here is a ratio of two
measurements taken in the same run, each the median of several repeats.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

__all__ = ["time_call", "forced_response_cost", "evaluation_speed", "optimizer_speed", "format_report",
           "synthetic_record", "memory_child", "peak_memory", "run_child", "MEMORY_BUDGETS", "SYNTHETIC_BETA",
           "identification_comparison", "format_identification_table", "IDENTIFICATION_VARIANTS"]


def time_call(fn, *, repeat: int = 5, number: int = 1) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeat`` runs of ``number`` calls."""
    fn()  # warm-up (compilation, caches)
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - t0) / number)
    return statistics.median(runs)


def forced_response_cost(case, model):
    """J of ``model`` on the case's record computed the slow way, through ``control.forced_response``."""
    import control

    t, u, y = case.data.t, case.data.u, case.data.y
    yhat = control.forced_response(model.linear, t, model.g(u)).outputs
    return float(np.sum((y - yhat) ** 2))


def evaluation_speed(case, beta=None, *, batch: int = 50, reference_repeats: int = 5) -> dict:
    """Time one cost evaluation through python-control and through our paths.

    Returns a dict with seconds per evaluation (``forced_response``,
    ``single``, ``batched`` per candidate) and the ratios, plus the largest
    relative difference between the two outputs (a correctness check).
    """
    import control

    beta = np.asarray(case.x0 if beta is None else beta, dtype=float)
    model = case.structure.model(beta)
    t, u = case.data.t, case.data.u
    rng = np.random.default_rng(0)
    betas = beta + 1e-3 * rng.standard_normal((batch, beta.size))
    ref = time_call(lambda: forced_response_cost(case, model), repeat=reference_repeats)
    single = time_call(lambda: case.cost(beta), repeat=7, number=50)
    batched = time_call(lambda: case.cost.batch(betas), repeat=7, number=5) / batch
    yref = control.forced_response(model.linear, t, model.g(u)).outputs
    err = float(np.max(np.abs(case.cost.simulate(beta) - yref)) / np.max(np.abs(yref)))
    return {
        "case": case.name, "samples": len(case.data), "forced_response_s": ref, "single_s": single,
        "batched_s": batched, "batch": batch, "single_speedup": ref / single,
        "batched_speedup": ref / batched, "max_rel_error": err,
        "J_control": forced_response_cost(case, model), "J_fast": case.cost(beta),
    }


def optimizer_speed(case, method: str = "nspsa", *, seed: int = 0, repeat: int = 3) -> dict:
    """Wall time of one preset optimisation run, and the same NFE through python-control (estimated)."""
    from .optimize import minimize

    kwargs = case.minimize_kwargs(method)
    result = minimize(case.cost, case.x0, seed=seed, **kwargs)
    seconds = time_call(lambda: minimize(case.cost, case.x0, seed=seed, **kwargs), repeat=repeat)
    return {"case": case.name, "method": method, "nfev": result.nfev, "seconds": seconds,
            "fun": result.fun, "per_eval_s": seconds / result.nfev}


def format_report(evals: list[dict], runs: list[dict]) -> str:
    """Plain-text report of :func:`evaluation_speed` and :func:`optimizer_speed` results."""
    lines = ["Cost evaluation J(beta): python-control vs hammerstein_ctrl (median wall time)", ""]
    lines.append(f"{'case':<6}{'N':>7}{'forced_response':>17}{'ours, single':>15}{'ratio':>9}"
                 f"{'ours, batched':>16}{'ratio':>9}{'max rel diff':>14}")
    for e in evals:
        lines.append(
            f"{e['case']:<6}{e['samples']:>7}{e['forced_response_s'] * 1e3:>14.2f} ms"
            f"{e['single_s'] * 1e6:>12.1f} us{e['single_speedup']:>8.0f}x"
            f"{e['batched_s'] * 1e6:>13.1f} us{e['batched_speedup']:>8.0f}x{e['max_rel_error']:>14.1e}"
        )
    if evals:
        lines.append(f"(batched: {evals[0]['batch']} candidates per call, time per candidate)")
    if runs:
        lines += ["", "Whole optimisation runs (paper presets)", ""]
        ref = {e["case"]: e["forced_response_s"] for e in evals}
        for r in runs:
            est = ref.get(r["case"], np.nan) * r["nfev"]
            lines.append(
                f"{r['case']:<6}{r['method']:<10}{r['nfev']:>6} evaluations in {r['seconds']:.3f} s "
                f"(J = {r['fun']:.4g}); through forced_response ~{est:.0f} s, "
                f"{est / r['seconds']:.0f}x"
            )
    return "\n".join(lines)


#: Variants compared by :func:`identification_comparison`: label -> how to run one seed.
IDENTIFICATION_VARIANTS = ("nspsa-paper", "nspsa-auto", "auto", "lm-paper-start")


def _identification_run(case, variant: str, seed: int):
    from .identify import identify
    from .optimize import minimize

    paper = case.minimize_kwargs("nspsa")
    budget = 2 * paper["maxiter"] + 1
    if variant == "nspsa-paper":
        return minimize(case.cost, case.x0, seed=seed, **paper)
    if variant == "nspsa-auto":
        return minimize(case.cost, case.x0, method="nspsa", maxfev=budget, options="auto", seed=seed)
    if variant == "auto":
        return identify(case.data, case.structure, maxfev=budget, seed=seed)
    return minimize(case.cost, case.x0, method="lm", maxfev=budget)


def identification_comparison(case, seeds=range(25), variants=IDENTIFICATION_VARIANTS, *, echo=None) -> list:
    """J, evaluations and wall time of each variant over seeds on a preset case.

    Returns one dict per variant: ``mean, best, worst, std`` of the final J,
    ``success`` count, mean ``nfev`` and mean wall time ``seconds``.  ``echo``
    (e.g. ``print``) receives each finished row at once.
    """
    rows = []
    for variant in variants:
        fun, nfev, secs, ok = [], [], [], 0
        for seed in seeds:
            t0 = time.perf_counter()
            r = _identification_run(case, variant, seed)
            secs.append(time.perf_counter() - t0)
            fun.append(float(r.fun))
            nfev.append(int(r.nfev))
            ok += bool(r.success)
        f = np.array(fun)
        row = {"case": case.name, "variant": variant, "runs": len(fun), "mean": float(f.mean()),
               "best": float(f.min()), "worst": float(f.max()), "std": float(f.std(ddof=1)) if f.size > 1 else 0.0,
               "success": ok, "nfev": float(np.mean(nfev)), "seconds": float(np.mean(secs))}
        rows.append(row)
        if echo is not None:
            echo(format_identification_table([row], header=not rows[:-1]))
    return rows


def format_identification_table(rows, *, header: bool = True) -> str:
    """Markdown table of :func:`identification_comparison` rows."""
    lines = ["| case | variant | mean J | best | worst | std | success | NFE | wall s |",
             "|---|---|---|---|---|---|---|---|---|"] if header else []
    for r in rows:
        lines.append(f"| {r['case']} | {r['variant']} | {r['mean']:.6g} | {r['best']:.6g} | {r['worst']:.6g} | "
                     f"{r['std']:.3g} | {r['success']}/{r['runs']} | {r['nfev']:.0f} | {r['seconds']:.3f} |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# Peak memory on long records
# ---------------------------------------------------------------------------

#: Methods whose peak memory :func:`peak_memory` measures, with the evaluation budget of the run
#: (small: the peak is reached in the first iterations, and a 1e7-sample evaluation takes 0.1 s).
MEMORY_BUDGETS = {"nspsa": 21, "lm": 25, "auto": 40, "amvo-sca": 100}
#: Hold time, in samples, of each random level of the synthetic input.
_HOLD_SAMPLES = 500
#: Sampling interval of the synthetic records (the EMPS rate).
_SYNTHETIC_DT = 1e-3
#: Parameters generating the synthetic records: the paper's best N-SPSA EMPS model (Table 8).
SYNTHETIC_BETA = (3.2870, 0.59130, -0.4448, 0.0486)


def synthetic_record(n_samples: int, *, seed: int = 0):
    """An EMPS-like record of any length: the EMPS structure at the paper's N-SPSA optimum.

    The input holds uniform random levels in [-1, 1] for 500 samples each; the
    output is simulated from that input (no noise).  Used to measure memory
    and time on records longer than the real one.

    Examples
    --------
    >>> rec = synthetic_record(1000)
    >>> len(rec), rec.dt
    (1000, 0.001)
    """
    from .iodata import IOData
    from .objective import HammersteinCost
    from .presets import emps_structure

    rng = np.random.default_rng(seed)
    levels = rng.uniform(-1.0, 1.0, n_samples // _HOLD_SAMPLES + 1)
    u = np.repeat(levels, _HOLD_SAMPLES)[:n_samples]
    structure = emps_structure()
    y = HammersteinCost(IOData(u, np.zeros(n_samples), dt=_SYNTHETIC_DT), structure).simulate(SYNTHETIC_BETA)
    return IOData(u, y, dt=_SYNTHETIC_DT, name=f"synthetic-emps-{n_samples}")


def _identify_long(data, method: str):
    """One small-budget identification of a synthetic record, as a user would call it."""
    from .identify import identify
    from .optimize.presets import EMPS_BOUNDS
    from .presets import X0, emps_structure

    kwargs = {"maxfev": MEMORY_BUDGETS[method], "seed": 0}
    if method != "auto":
        kwargs["x0"] = X0["emps"]
    if method == "amvo-sca":
        kwargs.update(bounds=EMPS_BOUNDS, options={"pop_size": MEMORY_BUDGETS[method] // 2})
    return identify(data, emps_structure(), method=method, **kwargs)


def _proc_status_kb(field: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise OSError(f"no {field} in /proc/self/status")


def _reset_peak_rss():
    """Reset the process's high-water mark of resident memory (Linux >= 4.0)."""
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")


def memory_child(method: str, n_samples: int) -> dict:
    """Measure one identification's peak memory in this process (run it in a fresh one).

    The record is built and the kernels compiled first (on a short record);
    then the peak resident memory is reset and the identification run.
    ``peak_bytes`` is the rise of resident memory above what the process held
    with the record loaded, so it counts every allocation of the run
    (numpy's, numba's, scipy's and MINPACK's); ``tracemalloc_bytes`` counts
    the allocations Python's allocator sees (numpy arrays, not numba's).
    """
    import gc
    import tracemalloc

    _identify_long(synthetic_record(4 * _HOLD_SAMPLES), method)  # compile, load everything
    data = synthetic_record(n_samples)
    gc.collect()
    base = _proc_status_kb("VmRSS")
    _reset_peak_rss()
    tracemalloc.start()
    t0 = time.perf_counter()
    result = _identify_long(data, method)
    seconds = time.perf_counter() - t0
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    peak = (_proc_status_kb("VmHWM") - base) * 1024
    return {"method": method, "samples": n_samples, "peak_bytes": peak, "per_sample": peak / n_samples,
            "tracemalloc_bytes": traced, "tracemalloc_per_sample": traced / n_samples,
            "record_bytes": data.u.nbytes + data.y.nbytes + data.t.nbytes, "seconds": seconds,
            "nfev": int(result.nfev)}


def _child_env() -> dict:
    """Environment for a child Python that imports this copy of the package."""
    import os
    from pathlib import Path

    env = dict(os.environ)
    root = str(Path(__file__).resolve().parent.parent)
    env["PYTHONPATH"] = os.pathsep.join([root] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run_child(code: str, *, timeout: float = 1800) -> dict:
    """Run ``code`` in a fresh Python process; it must print one JSON object as its last line."""
    import json
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_child_env(),
                          timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"child process failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def peak_memory(method: str, n_samples: int) -> dict:
    """Peak memory of a small-budget identification of an ``n_samples`` record, in a fresh process.

    See :func:`memory_child` for what is counted.
    """
    return run_child("import json; from hammerstein_ctrl.bench import memory_child; "
                     f"print(json.dumps(memory_child({method!r}, {int(n_samples)})))")
