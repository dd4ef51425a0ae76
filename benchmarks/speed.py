"""Side-by-side speed measurements: ``python benchmarks/speed.py [--cases emps trs] [--methods ...]``.

Timings on a shared machine are noisy, so every figure here is a ratio of two
measurements taken in the same run, each the median of several repeats.
"""

from __future__ import annotations

import contextlib
import signal
import statistics
import subprocess
import sys
import time

import numpy as np

from hammerstein_ctrl.paper.report import forced_response_cost, time_call

__all__ = ["time_call", "forced_response_cost", "evaluation_speed", "optimizer_speed", "format_report",
           "synthetic_record", "memory_child", "peak_memory", "run_child", "MEMORY_BUDGETS", "SYNTHETIC_BETA",
           "SYNTHETIC_X0", "busy_sibling", "contention_ratio", "contention_speed", "first_call_latency", "lm_speed",
           "hand_route", "identification_routes", "full_report", "MEMORY_SAMPLES", "identify_long_record",
           "identification_comparison", "format_identification_table", "IDENTIFICATION_VARIANTS",
           "pid_tuning_speed"]


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
    from hammerstein_ctrl.optimize import minimize

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
    from hammerstein_ctrl.fit import identify
    from hammerstein_ctrl.optimize import minimize

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

    Returns the median seconds of :func:`~hammerstein_ctrl.design.tune_pid`
    (after a warm-up run that compiles the kernels), its evaluation count, the
    time of one compiled loop simulation (:func:`~hammerstein_ctrl.simulate.simulate_loops`)
    and of the same loop through ``control.input_output_response``, and their ratio.
    """
    import control

    from hammerstein_ctrl._linalg import single_threaded_blas
    from hammerstein_ctrl.design import tune_pid
    from hammerstein_ctrl.simulate._loop import sampled_loop_iosys, sampled_plant, simulate_loops

    pid = tune_pid(model, rule, **tune_kwargs)
    with single_threaded_blas():
        seconds = time_call(lambda: tune_pid(model, rule, **tune_kwargs), repeat=repeat)
    from hammerstein_ctrl.design._pid import HORIZON_FACTOR

    t_final = tune_kwargs.get("t_final") or HORIZON_FACTOR * (pid.approximation["tau_c"]
                                                              + pid.approximation["theta"])
    r = np.full(int(round(t_final / pid.dt)) + 1, tune_kwargs.get("step", 1.0))
    limits = tune_kwargs.get("u_limit")
    plant = sampled_plant(model, pid.dt)
    with single_threaded_blas():
        fast = time_call(lambda: simulate_loops(plant, pid.gains, r, pid.dt, u_limit=limits), repeat=7, number=20)
    loop = sampled_loop_iosys(model, pid.gains, pid.dt, u_limit=limits)
    t = pid.dt * np.arange(r.size)
    slow = time_call(lambda: control.input_output_response(loop, t, r), repeat=reference_repeats)
    nfev = int(pid.optimize_result.nfev) if pid.optimize_result is not None else 0
    return {"rule": rule, "seconds": seconds, "nfev": nfev, "samples": r.size, "loop_fast_s": fast,
            "loop_python_control_s": slow, "loop_speedup": slow / fast, "cost": pid.cost}


# ---------------------------------------------------------------------------
# Peak memory on long records
# ---------------------------------------------------------------------------

#: Methods whose peak memory :func:`peak_memory` measures, with the evaluation budget of the run
#: (small: the peak is reached in the first iterations, and a 1e7-sample evaluation takes 0.1 s;
#: ``auto`` needs 300 for every stage to run: the start scan, its refinement and the LM polish).
MEMORY_BUDGETS = {"nspsa": 22, "lm": 25, "auto": 300, "amvo-sca": 100}
#: Hold time, in samples, of each random level of the synthetic input.
_HOLD_SAMPLES = 500
#: Sampling interval of the synthetic records (the EMPS rate).
_SYNTHETIC_DT = 1e-3
#: Parameters generating the synthetic records: the paper's best N-SPSA EMPS model (Table 8).
SYNTHETIC_BETA = (3.2870, 0.59130, -0.4448, 0.0486)
#: Initial point of the runs on synthetic records: stable, unlike the paper's EMPS start
#: (``a1 = -1``), whose response overflows on records of 1e6 samples.
SYNTHETIC_X0 = (2.0, 0.5, -0.4, 0.0)


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
    from hammerstein_ctrl.data import IOData
    from hammerstein_ctrl.fit import HammersteinCost
    from hammerstein_ctrl.paper.presets import emps_structure

    rng = np.random.default_rng(seed)
    levels = rng.uniform(-1.0, 1.0, n_samples // _HOLD_SAMPLES + 1)
    u = np.repeat(levels, _HOLD_SAMPLES)[:n_samples]
    structure = emps_structure()
    y = HammersteinCost(IOData(u, np.zeros(n_samples), dt=_SYNTHETIC_DT), structure).simulate(SYNTHETIC_BETA)
    return IOData(u, y, dt=_SYNTHETIC_DT, name=f"synthetic-emps-{n_samples}")


def identify_long_record(data, method: str, **options):
    """One small-budget identification (:data:`MEMORY_BUDGETS`) of a synthetic record, as a user would call it.

    From :data:`SYNTHETIC_X0` (``auto`` finds its own starts); AMVO-SCA in the
    paper's EMPS box with a population of half the budget (two iterations).
    """
    from hammerstein_ctrl.fit import identify
    from hammerstein_ctrl.paper.settings import EMPS_BOUNDS
    from hammerstein_ctrl.paper.presets import emps_structure

    kwargs = {"maxfev": MEMORY_BUDGETS[method], "seed": 0}
    if method != "auto":
        kwargs["x0"] = SYNTHETIC_X0
    if method == "amvo-sca":
        kwargs.update(bounds=EMPS_BOUNDS, options={"pop_size": MEMORY_BUDGETS[method] // 2})
    return identify(data, emps_structure(), method=method, **kwargs, **options)


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
    (numpy's, the compiled core's, scipy's and MINPACK's); ``tracemalloc_bytes`` counts
    the allocations Python's allocator sees (numpy arrays, not the compiled core's).
    """
    import gc
    import tracemalloc

    identify_long_record(synthetic_record(4 * _HOLD_SAMPLES), method)  # compile, load everything
    data = synthetic_record(n_samples)
    gc.collect()
    base = _proc_status_kb("VmRSS")
    _reset_peak_rss()
    tracemalloc.start()
    t0 = time.perf_counter()
    result = identify_long_record(data, method)
    seconds = time.perf_counter() - t0
    traced = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    peak = (_proc_status_kb("VmHWM") - base) * 1024
    return {"method": method, "samples": n_samples, "peak_bytes": peak, "per_sample": peak / n_samples,
            "tracemalloc_bytes": traced, "tracemalloc_per_sample": traced / n_samples,
            "record_bytes": data.u.nbytes + data.y.nbytes + data.t.nbytes, "seconds": seconds,
            "nfev": int(result.nfev)}


def _child_env(bytecode: bool = False) -> dict:
    """Environment for a child Python that imports this copy of the package.

    With ``bytecode`` the child writes and reads Python's bytecode cache even
    where ``PYTHONDONTWRITEBYTECODE`` is set (as it is in some CI images): a
    package installed by pip has its modules byte-compiled, so first-call
    times without it would count compiling the package's own source.
    """
    import os
    from pathlib import Path

    env = dict(os.environ)
    if bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
    here = str(Path(__file__).resolve().parent)          # this folder, for ``import speed`` in the child
    env["PYTHONPATH"] = os.pathsep.join([here] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run_child(code: str, *, timeout: float = 1800, bytecode: bool = False) -> dict:
    """Run ``code`` in a fresh Python process; it must print one JSON object as its last line (``bytecode``: see
    :func:`_child_env`)."""
    import json

    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_child_env(bytecode),
                          timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"child process failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def peak_memory(method: str, n_samples: int) -> dict:
    """Peak memory of a small-budget identification of an ``n_samples`` record, in a fresh process.

    See :func:`memory_child` for what is counted.
    """
    return run_child("import json; from speed import memory_child; "
                     f"print(json.dumps(memory_child({method!r}, {int(n_samples)})))")


# ---------------------------------------------------------------------------
# Contention: a busy sibling process on the other core
# ---------------------------------------------------------------------------

#: The sibling's work: a BLAS matrix product in a loop, on one thread.
_SPIN = ("import sys, numpy as np\n"
         "a = np.random.default_rng(0).random((200, 200))\n"
         "print('ready', flush=True)\n"
         "while True:\n"
         "    a = a @ a; a /= np.abs(a).max()\n")
#: Measurement blocks of each kind (quiet, busy) in :func:`contention_ratio`.
CONTENTION_PAIRS = 7


@contextlib.contextmanager
def busy_sibling():
    """Run a process spinning a single-threaded BLAS loop for the duration of the block.

    Yields the :class:`subprocess.Popen`; pause and resume it with
    ``SIGSTOP``/``SIGCONT`` to interleave quiet and busy measurements.
    """
    env = _child_env()
    env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-c", _SPIN], stdout=subprocess.PIPE, text=True, env=env)
    try:
        proc.stdout.readline()
        yield proc
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def _per_call(fn, number: int) -> tuple[float, float]:
    """Wall and CPU (all threads of this process) seconds per call."""
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(number):
        fn()
    return (time.perf_counter() - t0) / number, (time.process_time() - c0) / number


def contention_ratio(fn, *, number: int = 100, pairs: int = CONTENTION_PAIRS) -> dict:
    """Wall time per call of ``fn`` with the sibling paused and running, interleaved.

    ``pairs`` blocks of each kind alternate (so drifts in the machine's load
    hit both alike); each figure is the median over its blocks.

    Returns
    -------
    dict
        ``quiet_s``, ``busy_s`` (wall seconds per call), ``ratio`` (busy /
        quiet) and ``cpu_ratio``, the same ratio of the process's CPU time (all its threads):
        threads spinning against each other raise both, while merely sharing
        the cores with more processes raises the wall time only (unless the
        two cores are hyper-threads of one, whose shared units slow both).
        ``busy_cpu_per_wall`` is the process's CPU time over its wall time
        in the busy blocks: above 1, more than one of its threads ran.
        ``sibling_share`` is the sibling's CPU time over the wall time of the
        busy blocks (how busy it really kept a core).
    """
    fn()  # warm-up
    quiet, busy = [], []
    with busy_sibling() as proc:
        sibling0, busy_wall = _cpu_seconds(proc.pid), 0.0
        for _ in range(pairs):
            proc.send_signal(signal.SIGSTOP)
            quiet.append(_per_call(fn, number))
            proc.send_signal(signal.SIGCONT)
            busy.append(_per_call(fn, number))
            busy_wall += busy[-1][0] * number
        sibling_share = (_cpu_seconds(proc.pid) - sibling0) / busy_wall
    (q, qc), (b, bc) = ([statistics.median(col) for col in zip(*runs)] for runs in (quiet, busy))
    return {"quiet_s": q, "busy_s": b, "ratio": b / q, "cpu_ratio": bc / qc, "busy_cpu_per_wall": bc / b,
            "sibling_share": sibling_share}


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process (Linux ``/proc``; NaN elsewhere)."""
    import os

    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def contention_speed(case, beta=None, *, batch: int = 50) -> list[dict]:
    """:func:`contention_ratio` of control.forced_response, our single and batched evaluations,
    and a whole ``identify(method="lm")`` from the case's x0 (per evaluation)."""
    from hammerstein_ctrl.fit import identify

    beta = np.asarray(case.x0 if beta is None else beta, dtype=float)
    model = case.structure.model(beta)
    betas = beta + 1e-3 * np.random.default_rng(0).standard_normal((batch, beta.size))

    def run_identify():
        return identify(case.data, case.structure, method="lm", x0=case.x0)

    rows = [("forced_response", contention_ratio(lambda: forced_response_cost(case, model), number=2, pairs=5), 1),
            ("ours, single", contention_ratio(lambda: case.cost(beta)), 1),
            ("ours, batched", contention_ratio(lambda: case.cost.batch(betas), number=5), batch),
            ("identify lm /eval", contention_ratio(run_identify, number=2, pairs=5), run_identify().nfev)]
    return [{"path": name, "quiet_s": r["quiet_s"] / per, "busy_s": r["busy_s"] / per, "ratio": r["ratio"],
             "cpu_ratio": r["cpu_ratio"]} for name, r, per in rows]


# ---------------------------------------------------------------------------
# First-call latency in a fresh process
# ---------------------------------------------------------------------------

_FIRST_CALL = """
import json, time
t0 = time.perf_counter()
import hammerstein_ctrl as hc
t1 = time.perf_counter()
import numpy, scipy.optimize, scipy.linalg, control
t2 = time.perf_counter()
case = hc.presets.emps()
t3 = time.perf_counter()
r = hc.identify(case.data, case.structure, method="lm", x0=case.x0)
t4 = time.perf_counter()
r = hc.identify(case.data, case.structure, method="lm", x0=case.x0)
t5 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "dependencies_s": t2 - t1, "load_s": t3 - t2,
                  "first_identify_s": t4 - t3, "second_identify_s": t5 - t4, "fun": r.fun}))
"""


def _wall(argv) -> float:
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, capture_output=True, env=_child_env(bytecode=True))
    return time.perf_counter() - t0


def first_call_latency(*, repeat: int = 3) -> dict:
    """Import time, first ``identify(method="lm")`` on EMPS and ``--help`` time, each in a fresh process.

    Python's bytecode cache is warmed by one untimed run first (see
    :func:`_child_env`; the compiled core needs no warming).  The package imports
    its dependencies on first use; ``dependencies_s`` is the import of numpy,
    scipy and python-control (the last for a model's transfer function,
    made when first asked for: an identification itself does not import it),
    so that the first call's time is the package's own; ``load_s`` reading the EMPS preset,
    ``first_identify_s`` the first call and
    ``second_identify_s`` the same call again, so their difference is the
    package's own first-call overhead.  ``python_s`` is a bare interpreter's start-up, to
    read ``help_s`` against.  Medians over ``repeat`` processes.
    """
    run_child(_FIRST_CALL, bytecode=True)
    runs = [run_child(_FIRST_CALL, bytecode=True) for _ in range(repeat)]
    out = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    out["processes"] = repeat
    out["python_s"] = statistics.median(_wall([sys.executable, "-c", "pass"]) for _ in range(repeat))
    out["help_s"] = statistics.median(_wall([sys.executable, "-m", "hammerstein_ctrl.cli", "--help"])
                                      for _ in range(repeat))
    return out


# ---------------------------------------------------------------------------
# Levenberg-Marquardt: wall time per iteration, Jacobian cost
# ---------------------------------------------------------------------------

class _PassCounter:
    """A cost's methods, counting the normal-equation passes (one per accepted step) and Jacobians.

    It has no ``direct_pass``, so LM runs its loop in Python around the
    compiled pass (the same steps, bit for bit, as the compiled loop's).
    """

    def __init__(self, cost):
        self.cost, self.passes = cost, 0

    def __call__(self, beta):
        return self.cost(beta)

    def residuals(self, beta):
        return self.cost.residuals(beta)

    def residuals_batch(self, betas):
        self.passes += 1
        return self.cost.residuals_batch(betas)

    def normal_equations(self, beta, steps=None):
        self.passes += 1
        return self.cost.normal_equations(beta, steps)


def lm_speed(case, *, repeat: int = 5) -> dict:
    """Levenberg-Marquardt on a preset: wall time per iteration and Jacobian cost, in single evaluations.

    ``single_s`` is one residual vector and ``cost_s`` one value of J.
    ``pass_s`` is the normal-equation pass (the point and its forward-difference
    neighbours simulated side by side, ``J.T J`` and ``J.T r`` accumulated in
    the same compiled loop), ``jacobian_s`` the same Jacobian as an ``N x p``
    array from one batched call, and ``jacobian_2point_s`` scipy's own 2-point
    scheme (one call per column), all at the paper's N-SPSA vector.  The run
    starts there too (a stable point, as identify's data-driven starts are)
    and goes to the least-squares optimum; ``iteration_s`` is its wall time
    over its steps, ``step_s`` the same without the call's set-up and first
    pass (the run with a budget of one pass, subtracted), and
    ``python_iteration_s`` the same steps with the loop in Python around the
    compiled pass (the LM loop is compiled around the pass for structures such as EMPS's).
    """
    import scipy.optimize

    from hammerstein_ctrl.optimize._normal_equations import forward_steps, neighbours
    from hammerstein_ctrl.optimize import minimize

    x = np.asarray(case.paper["nspsa"]["beta"], dtype=float)
    steps = forward_steps(x)
    X = neighbours(x, steps)
    single = time_call(lambda: case.cost.residuals(x), repeat=7, number=20)
    value = time_call(lambda: case.cost(x), repeat=7, number=20)
    normal = time_call(lambda: case.cost.normal_equations(x, steps), repeat=7, number=10)
    jac = time_call(lambda: case.cost.residuals_batch(X), repeat=7, number=10)
    two_point = time_call(lambda: scipy.optimize.approx_fprime(x, case.cost.residuals, steps), repeat=7)
    counter = _PassCounter(case.cost)
    result = minimize(counter, x, method="lm")
    run = time_call(lambda: minimize(case.cost, x, method="lm"), repeat=repeat)
    # the counter has no direct_pass: the same steps with the loop in Python around the compiled pass
    python_run = time_call(lambda: minimize(_PassCounter(case.cost), x, method="lm"), repeat=repeat)
    # the call's set-up and its first pass alone: a budget of one pass (p + 1 evaluations)
    start = time_call(lambda: minimize(case.cost, x, method="lm", maxfev=x.size + 1), repeat=repeat)
    steps = max(1, result.nit)
    return {"case": case.name, "n_params": x.size, "single_s": single, "cost_s": value, "pass_s": normal,
            "jacobian_s": jac, "jacobian_2point_s": two_point, "run_s": run, "nfev": int(result.nfev),
            "iterations": int(result.nit), "passes": counter.passes, "iteration_s": run / steps,
            "python_iteration_s": python_run / steps,
            "step_s": (run - start) / steps, "fun": float(result.fun), "message": result.message}


# ---------------------------------------------------------------------------
# A whole identification against the route a user would write by hand
# ---------------------------------------------------------------------------

def hand_route(case) -> dict:
    """``scipy.optimize.least_squares`` on ``control.forced_response`` residuals, from the case's x0."""
    import control
    import scipy.optimize

    t, u, y = case.data.t, case.data.u, case.data.y

    def residuals(beta):
        model = case.structure.model(beta)
        return y - control.forced_response(model.linear, t, model.g(u)).outputs

    t0 = time.perf_counter()
    res = scipy.optimize.least_squares(residuals, case.x0)
    return {"route": "least_squares on forced_response", "seconds": time.perf_counter() - t0,
            "fun": float(2 * res.cost), "nfev": int(res.nfev + res.njev * case.x0.size)}


def identification_routes(case, *, repeat: int = 3) -> list[dict]:
    """A whole identification of ``case``: by hand through python-control, and by :func:`identify`."""
    from hammerstein_ctrl.fit import identify

    rows = [hand_route(case)]
    for method, x0 in (("lm", case.x0), ("auto", None)):
        r = identify(case.data, case.structure, method=method, x0=x0)
        secs = time_call(lambda method=method, x0=x0: identify(case.data, case.structure, method=method, x0=x0),
                         repeat=repeat)
        rows.append({"route": f"identify(method={method!r})", "seconds": secs, "fun": float(r.fun),
                     "nfev": int(r.nfev)})
    return rows


def uncertainty_cost(case, *, pairs: int = 30) -> list[dict]:
    """What the covariance, verdicts and residual analysis add to ``identify`` (``auto``, and ``lm`` from the
    paper's start): calls with and without them interleaved, medians compared."""
    import warnings

    from hammerstein_ctrl.exceptions import IdentificationWarning
    from hammerstein_ctrl.fit import identify

    rows = []
    for method, x0 in (("auto", None), ("lm", case.x0)):
        times = {True: [], False: []}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentificationWarning)
            for flag in (True, False):          # warm both paths first
                identify(case.data, case.structure, method=method, x0=x0, uncertainty=flag)
            for _ in range(pairs):
                for flag in (False, True):
                    started = time.perf_counter()
                    r = identify(case.data, case.structure, method=method, x0=x0, uncertainty=flag)
                    times[flag].append(time.perf_counter() - started)
        bare, full = float(np.median(times[False])), float(np.median(times[True]))
        rows.append({"method": method, "without": bare, "with": full, "ratio": full / bare,
                     "noise": r.uncertainty.noise.describe()})
    return rows


def format_uncertainty(rows) -> str:
    lines = ["Uncertainty, verdicts and residual analysis after an EMPS fit (identify with and without them,",
             "interleaved, medians)", "",
             f"{'method':<8}{'without':>12}{'with':>12}{'ratio':>8}   noise model of the residuals"]
    for r in rows:
        lines.append(f"{r['method']:<8}{r['without'] * 1e3:>10.2f}ms{r['with'] * 1e3:>10.2f}ms{r['ratio']:>8.3f}   "
                     f"{r['noise']}")
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# The whole report
# ---------------------------------------------------------------------------

#: Record lengths of the peak-memory table.
MEMORY_SAMPLES = (10**6, 10**7)


def full_report(cases, methods=("nspsa",), *, memory_samples=MEMORY_SAMPLES, echo=None) -> str:
    """Everything ``python benchmarks/speed.py`` prints, measured in this one run.

    The cost-evaluation table and the preset runs for every case; for the
    EMPS case also contention, first-call latency, Levenberg-Marquardt
    iteration cost, peak memory on long records and a whole identification
    against the hand-written python-control route.  ``echo`` (e.g. ``print``)
    receives each section as soon as it is measured.
    """
    sections = []

    def emit(text):
        sections.append(text)
        if echo is not None:
            echo(text + "\n")

    evals = [evaluation_speed(case, case.paper["nspsa"]["beta"]) for case in cases]
    emit(format_report(evals, [optimizer_speed(case, m) for case in cases for m in methods]))
    for case in cases:
        if case.name != "emps":
            continue
        beta = case.paper["nspsa"]["beta"]
        emit(format_contention(contention_speed(case, beta)))
        emit(format_first_call(first_call_latency()))
        emit(format_lm_speed(lm_speed(case)))
        if memory_samples:
            emit(format_memory([peak_memory(m, n) for n in memory_samples for m in MEMORY_BUDGETS]))
        emit(format_routes(identification_routes(case)))
        emit(format_uncertainty(uncertainty_cost(case)))
        emit(format_mimo_speed(mimo_speed(len(case.data))))
        emit(format_lure_speed(lure_speed(case)))
    return "\n\n".join(sections)


def mimo_speed(n_samples: int, *, batch: int = 15, pairs: int = 7, number: int = 50) -> dict:
    """A 2 x 2 second-order Hammerstein evaluation against a SISO second-order one on records of one length.

    Both with tanh input blocks, on random signals; single evaluations and
    batches (per candidate) timed in interleaved pairs, medians of the
    per-pair ratios.
    """
    from hammerstein_ctrl.data import IOData
    from hammerstein_ctrl.blocks import MIMOHammersteinStructure
    from hammerstein_ctrl.fit import MIMOCost
    from hammerstein_ctrl.blocks import Tanh
    from hammerstein_ctrl.fit import HammersteinCost
    from hammerstein_ctrl.blocks import HammersteinStructure, LinearStructure

    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((n_samples, 2)), rng.standard_normal((n_samples, 2))
    mimo = MIMOCost(IOData(u, y, dt=1e-3), MIMOHammersteinStructure(LinearStructure(1, 2), [Tanh(), Tanh()],
                                                                    n_outputs=2))
    siso = HammersteinCost(IOData(u[:, 0], y[:, 0], dt=1e-3), HammersteinStructure(LinearStructure(1, 2), Tanh()))
    b2 = np.array([2.0, 0.5, 2.0, 1.2, 1.0, 0.6, 3.0, 0.8, 1.5, 2.5, 2.0, 1.5, 0.8, 0.7])
    b1 = np.array([2.0, 2.0, 1.2, 2.0, 1.5])
    B2, B1 = np.tile(b2, (batch, 1)), np.tile(b1, (batch, 1))
    out = {"n_samples": n_samples, "batch": batch}
    for label, f1, f2, per in (("single", lambda: siso(b1), lambda: mimo(b2), 1),
                               ("batched", lambda: siso.batch(B1), lambda: mimo.batch(B2), batch)):
        f1(), f2()
        t1, t2 = [], []
        for _ in range(pairs):
            t1.append(time_call(f1, repeat=1, number=number) / per)
            t2.append(time_call(f2, repeat=1, number=number) / per)
        out[label] = {"siso_s": float(np.median(t1)), "mimo_s": float(np.median(t2)),
                      "ratio": float(np.median(np.array(t2) / np.array(t1)))}
    return out


def lure_speed(case, *, pairs: int = 7, number: int = 50) -> dict:
    """A Lur'e evaluation (friction on velocity, stick-slip resolved) against the Hammerstein one of the
    same order on the case's record, each at its own optimum; interleaved pairs, median ratio."""
    from hammerstein_ctrl.fit._auto import auto_minimize
    from hammerstein_ctrl.fit._auto_whole import auto_lure
    from hammerstein_ctrl.blocks import lure_structure
    from hammerstein_ctrl.fit import LureCost

    hammerstein = case.cost
    lure = LureCost(case.data, lure_structure())
    xh, xl = auto_minimize(hammerstein, seed=0).x, auto_lure(lure, seed=0).x
    f1, f2 = (lambda: hammerstein(xh)), (lambda: lure(xl))
    f1(), f2()
    t1, t2 = [], []
    for _ in range(pairs):
        t1.append(time_call(f1, repeat=1, number=number))
        t2.append(time_call(f2, repeat=1, number=number))
    return {"n_samples": len(case.data), "hammerstein_s": float(np.median(t1)), "lure_s": float(np.median(t2)),
            "ratio": float(np.median(np.array(t2) / np.array(t1))),
            "sticking": int(np.sum(np.diff(lure.simulate(xl)) == 0))}


def format_lure_speed(r) -> str:
    name = "Lur'e"
    return (f"{name} cost (friction fed back on velocity, stick-slip resolved exactly) against the Hammerstein "
            f"cost of the same order, {r['n_samples']} samples, each at its optimum (target: <= 3x)\n\n"
            f"{'Hammerstein':<14}{r['hammerstein_s'] * 1e6:>9.1f} us\n"
            f"{name:<14}{r['lure_s'] * 1e6:>9.1f} us   ratio {r['ratio']:.2f}x ({r['sticking']} samples stuck)")


def format_mimo_speed(r) -> str:
    lines = [f"MIMO cost: a 2 x 2 second-order Hammerstein (tanh) against a SISO second-order one, "
             f"{r['n_samples']} samples (target: <= 4x)", "",
             f"{'evaluation':<22}{'SISO':>12}{'2 x 2':>12}{'ratio':>9}"]
    for label in ("single", "batched"):
        x = r[label]
        name = label if label == "single" else f"batch of {r['batch']}, each"
        lines.append(f"{name:<22}{x['siso_s'] * 1e6:>9.1f} us{x['mimo_s'] * 1e6:>9.1f} us{x['ratio']:>8.2f}x")
    return "\n".join(lines)


def format_contention(rows) -> str:
    import os

    load = ", ".join(f"{v:.1f}" for v in os.getloadavg()) if hasattr(os, "getloadavg") else "n/a"
    lines = ["With a busy sibling process (a one-thread BLAS loop; paused/running blocks interleaved, medians;",
             f"{os.cpu_count()} cores, load average {load}: when the other core is taken by other work, sharing",
             "a core with the sibling alone doubles the wall time, while spinning threads raise the CPU time)",
             "", f"{'path':<18}{'quiet':>12}{'busy':>12}{'busy/quiet':>12}{'CPU time ratio':>16}"]
    lines += [f"{r['path']:<18}{r['quiet_s'] * 1e6:>9.1f} us{r['busy_s'] * 1e6:>9.1f} us{r['ratio']:>11.2f}x"
              f"{r['cpu_ratio']:>15.2f}x" for r in rows]
    return "\n".join(lines)


def format_first_call(r) -> str:
    return "\n".join([
        f"Fresh process, bytecode cache warm (medians of {r.get('processes', 3)} processes)", "",
        f"import hammerstein_ctrl            {r['import_s']:.3f} s",
        f"then numpy, scipy, control         {r['dependencies_s']:.3f} s (imported on first use; control for a "
        "model's transfer function)",
        f"then presets.emps() (read record)  {r['load_s']:.3f} s",
        f"first identify(method='lm'), EMPS  {r['first_identify_s']:.3f} s "
        f"(the same call again: {r['second_identify_s']:.3f} s; first-call overhead "
        f"{r['first_identify_s'] - r['second_identify_s']:.3f} s)",
        f"hammerstein-ctrl --help            {r['help_s']:.3f} s (bare python start-up: {r['python_s']:.3f} s)",
    ])


def format_lm_speed(r) -> str:
    s = r["single_s"]
    return "\n".join([
        f"Levenberg-Marquardt on {r['case']} ({r['n_params']} parameters; times in single residual "
        f"evaluations of {s * 1e6:.0f} us; one value of J costs {r['cost_s'] / s:.2f})", "",
        f"normal-equation pass (point + Jacobian, fused)  {r['pass_s'] / s:5.2f} evaluations",
        f"Jacobian as an N x p array, one batched call    {r['jacobian_s'] / s:5.2f} evaluations",
        f"Jacobian, scipy 2-point (one call per column)   {r['jacobian_2point_s'] / s:5.2f} evaluations",
        f"one iteration from the N-SPSA vector ({r['iterations']} steps, {r['passes']} passes, "
        f"{r['nfev']} evaluations, {r['run_s'] * 1e3:.1f} ms, J = {r['fun']:.6g})   "
        f"{r['iteration_s'] / s:5.2f} evaluations",
        f"  the same iteration in values of J ({r['cost_s'] * 1e6:.0f} us each)                "
        f"{r['iteration_s'] / r['cost_s']:5.2f} values",
        f"  one more step, beyond the call's set-up and first pass (values of J)    "
        f"{r['step_s'] / r['cost_s']:5.2f} values",
        f"  the same iteration with the loop in Python around the pass (values of J) "
        f"{r['python_iteration_s'] / r['cost_s']:5.2f} values",
    ])


def format_memory(rows) -> str:
    lines = ["Peak memory of identify() on long synthetic EMPS records (fresh process; rise of resident memory",
             "above the loaded record, whose own 24 B/sample are not counted)", "",
             f"{'method':<10}{'samples':>10}{'nfev':>6}{'peak':>11}{'per sample':>13}{'time':>9}"]
    lines += [f"{r['method']:<10}{r['samples']:>10.0e}{r['nfev']:>6}{r['peak_bytes'] / 2**20:>8.0f} MB"
              f"{r['per_sample']:>11.1f} B{r['seconds']:>8.2f}s" for r in rows]
    return "\n".join(lines)


def format_routes(rows) -> str:
    ref = rows[0]["seconds"]
    lines = ["A whole EMPS identification from the paper's x0: by hand through python-control vs identify()", "",
             f"{'route':<36}{'wall':>10}{'ratio':>9}{'J':>12}{'nfev':>7}"]
    lines += [f"{r['route']:<36}{r['seconds']:>8.3f} s{ref / r['seconds']:>8.0f}x{r['fun']:>12.6g}{r['nfev']:>7}"
              for r in rows]
    return "\n".join(lines)


def main(argv=None) -> int:
    """The command: time cost evaluations and runs against ``control.forced_response``, print the ratios."""
    import argparse

    from hammerstein_ctrl.paper import presets

    parser = argparse.ArgumentParser(prog="python benchmarks/speed.py", description=main.__doc__)
    parser.add_argument("--cases", nargs="+", default=["emps", "trs"], choices=["emps", "trs"])
    parser.add_argument("--methods", nargs="+", default=["nspsa"],
                        help="methods whose preset run is timed (default: nspsa)")
    parser.add_argument("--memory-samples", nargs="*", type=float, default=list(MEMORY_SAMPLES), metavar="N",
                        help="record lengths of the EMPS peak-memory table (default: 1e6 1e7; none: skip)")
    args = parser.parse_args(argv)
    cases = []
    for name in args.cases:
        try:
            cases.append(presets.get(name))
        except FileNotFoundError as exc:
            print(f"skipping {name}: {str(exc).splitlines()[0]}", file=sys.stderr)
    full_report(cases, args.methods, memory_samples=[int(n) for n in args.memory_samples], echo=print)
    return 0


if __name__ == "__main__":
    sys.exit(main())
