"""Side-by-side speed measurements (``hammerstein-ctrl bench``).

Timings on a shared machine are noisy, so every figure here is a ratio of two
measurements taken in the same run, each the median of several repeats.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

__all__ = ["time_call", "forced_response_cost", "evaluation_speed", "optimizer_speed", "format_report",
           "identification_comparison", "format_identification_table", "IDENTIFICATION_VARIANTS",
           "pid_tuning_speed"]


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


def pid_tuning_speed(model, rule: str = "nspsa", *, repeat: int = 3, reference_repeats: int = 1,
                     **tune_kwargs) -> dict:
    """Wall time of a whole model-based PID tuning run, and of one loop simulation both ways.

    Returns the median seconds of :func:`~hammerstein_ctrl.control_design.tune_pid`
    (after a warm-up run that compiles the kernels), its evaluation count, the
    time of one compiled loop simulation (:func:`~hammerstein_ctrl.loop_sim.simulate_loops`)
    and of the same loop through ``control.input_output_response``, and their ratio.
    """
    import control
    from threadpoolctl import threadpool_limits

    from .control_design import tune_pid
    from .loop_sim import sampled_loop_iosys, sampled_plant, simulate_loops

    pid = tune_pid(model, rule, **tune_kwargs)
    with threadpool_limits(1):
        seconds = time_call(lambda: tune_pid(model, rule, **tune_kwargs), repeat=repeat)
    from .control_design import HORIZON_FACTOR

    t_final = tune_kwargs.get("t_final") or HORIZON_FACTOR * (pid.approximation["tau_c"]
                                                              + pid.approximation["theta"])
    r = np.full(int(round(t_final / pid.dt)) + 1, tune_kwargs.get("step", 1.0))
    limits = tune_kwargs.get("u_limit")
    plant = sampled_plant(model, pid.dt)
    with threadpool_limits(1):
        fast = time_call(lambda: simulate_loops(plant, pid.gains, r, pid.dt, u_limit=limits), repeat=7, number=20)
    loop = sampled_loop_iosys(model, pid.gains, pid.dt, u_limit=limits)
    t = pid.dt * np.arange(r.size)
    slow = time_call(lambda: control.input_output_response(loop, t, r), repeat=reference_repeats)
    nfev = int(pid.optimize_result.nfev) if pid.optimize_result is not None else 0
    return {"rule": rule, "seconds": seconds, "nfev": nfev, "samples": r.size, "loop_fast_s": fast,
            "loop_python_control_s": slow, "loop_speedup": slow / fast, "cost": pid.cost}
