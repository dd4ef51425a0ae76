"""Independent trials of several methods on a case: the paper's comparison tables.

:func:`run_study` runs ``trials`` independent runs of each method.  Trial ``i``
uses a seed derived only from the study seed and ``i``
(:func:`trial_seed`), so any subset of trials reruns identically, whatever the
executor, the order of completion or the other methods.  Each finished trial
is appended to a JSON-lines file at once; rerunning with the same
``results_path`` skips the trials already recorded, so an interrupted study
loses at most the trials that were running.

Trials run on any :class:`concurrent.futures.Executor`: by default a local
process pool over the machine's cores; ``executor="serial"`` runs them in
this process; a ``dask.distributed`` client's ``client.get_executor()`` works
unchanged, which is how a study scales past one machine.

Examples
--------
>>> from hammerstein_ctrl import presets, run_study
>>> study = run_study(presets.trs(), ["nspsa", "nlspsa"], trials=3, seed=0, executor="serial")
>>> s = study.summary()
>>> s["nspsa"]["n"], s["nspsa"]["mean"] < s["nlspsa"]["mean"]
(3, True)
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import json
import math
import multiprocessing
import os
import time
from pathlib import Path

import numpy as np
import scipy.stats

from .exceptions import ParameterError
from .optimize import canonical_method, minimize

__all__ = ["run_study", "StudyResult", "trial_seed", "ranksum"]

#: Points kept from each trial's convergence curve (for plots).
CURVE_POINTS = 200
#: Version of the JSON-lines record layout; part of every fingerprint, so files
#: written by an older layout are never mixed into a resumed study.
RECORD_VERSION = 2


def trial_seed(seed: int, trial: int) -> int:
    """The seed of trial ``trial`` of a study seeded with ``seed``.

    Derived with :class:`numpy.random.SeedSequence` (``spawn_key=(trial,)``),
    so it depends on nothing else.

    Examples
    --------
    >>> trial_seed(0, 3) == trial_seed(0, 3) != trial_seed(0, 4)
    True
    """
    return int(np.random.SeedSequence(int(seed), spawn_key=(int(trial),)).generate_state(1, np.uint64)[0])


def _describe(value):
    """JSON-able, stable description of a method setting (for the config fingerprint)."""
    if hasattr(value, "to_dict"):
        return value.to_dict()
    if isinstance(value, dict):
        return {k: _describe(v) for k, v in sorted(value.items())}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_describe(v) for v in np.asarray(value, dtype=object).tolist()]
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return value


def _fingerprint(case, method: str, kwargs: dict) -> str:
    """Hash of everything that determines a trial's result except its seed."""
    h = hashlib.sha256()
    h.update(json.dumps({"version": RECORD_VERSION, "case": case.name, "method": method,
                         "settings": _describe(kwargs),
                         "x0": _describe(case.x0), "structure": case.structure.describe(),
                         "reject_unstable": case.cost.reject_unstable}, sort_keys=True).encode())
    for a in (case.data.u, case.data.y):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr(case.data.dt).encode())
    return h.hexdigest()[:16]


def _curve(history: dict) -> dict:
    """J at the current estimate and best evaluated J versus NFE, at most ~:data:`CURVE_POINTS` points.

    Rows where the estimate was not measured are dropped (the SPSA family is
    monitored at about ``CURVE_POINTS / 2`` iterations, see ``monitor``).
    """
    nfev, best, est = (np.asarray(history[k]) for k in ("nfev", "best", "estimate"))
    keep = ~np.isnan(est)
    nfev, best, est = nfev[keep], best[keep], est[keep]
    if nfev.size > CURVE_POINTS:
        idx = np.unique(np.linspace(0, nfev.size - 1, CURVE_POINTS).round().astype(int))
        nfev, best, est = nfev[idx], best[idx], est[idx]
    return {"nfev": nfev.tolist(), "best": [_json_float(b) for b in best],
            "estimate": [_json_float(e) for e in est]}


def _json_float(v):
    v = float(v)
    return v if math.isfinite(v) else ("inf" if v > 0 else "-inf" if v < 0 else "nan")


def _from_json_float(v):
    return float(v)  # also parses the strings "inf", "-inf" and "nan"


def _run_trial(case, method: str, kwargs: dict, trial: int, seed: int, fingerprint: str) -> dict:
    """One independent run; returns a JSON-able record (executed in a worker).

    BLAS is held to one thread: the matrices here are tiny, and OpenBLAS's
    spinning worker threads in several processes on the same cores slow a
    trial down about 50-fold.
    """
    from threadpoolctl import threadpool_limits

    t0 = time.perf_counter()
    if kwargs.get("method") in ("spsa", "nlspsa", "nspsa"):  # curves at the iterate; never changes the run
        kwargs = {**kwargs, "options": {**(kwargs.get("options") or {}), "monitor": CURVE_POINTS // 2}}
    with threadpool_limits(limits=1):
        res = minimize(case.cost, case.x0, seed=seed, **kwargs)
    return {
        "case": case.name, "method": method, "trial": trial, "seed": seed, "config": fingerprint,
        "fun": _json_float(res.fun), "x": [_json_float(v) for v in res.x], "nfev": int(res.nfev),
        "nit": int(res.nit), "status": int(res.status), "success": bool(res.success),
        "diverged": int(res.status) == 2, "message": str(res.message),
        "best_fun": _json_float(res.best_fun), "nfev_monitor": int(res.nfev_monitor),
        "elapsed": time.perf_counter() - t0,
        "curve": _curve(res.history),
    }


def _read_records(path: Path) -> list[dict]:
    records = []
    if path.is_file():
        with open(path) as fh:
            for line in fh:
                try:
                    records.append(json.loads(line))
                except json.JSONDecodeError:  # a line cut short by an interruption
                    continue
    return records


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as fh:
        fh.seek(-1, os.SEEK_END)
        return fh.read(1) == b"\n"


def _make_executor(executor, jobs: int | None):
    if executor is None:
        workers = jobs or os.cpu_count() or 1
        if workers == 1:
            return None, False
        ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else None)
        return cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx), True
    if executor == "serial":
        return None, False
    if not hasattr(executor, "submit"):
        raise ParameterError(f"executor must be a concurrent.futures.Executor or 'serial', got {executor!r}")
    return executor, False


def run_study(case, methods, trials: int = 25, seed: int = 0, executor=None, results_path=None,
              *, jobs: int | None = None, progress: bool = False, settings: dict | None = None):
    """Run independent trials of several methods on a case.

    Parameters
    ----------
    case : Preset or str
        A :class:`~hammerstein_ctrl.presets.Preset` (or ``"trs"``/``"emps"``).
    methods : sequence of str
        Methods to compare; each uses the case's paper settings
        (``case.minimize_kwargs(method)``) unless ``settings`` overrides them.
    trials : int, default 25
    seed : int, default 0
        Study seed; trial ``i`` uses :func:`trial_seed` ``(seed, i)``.
    executor : concurrent.futures.Executor, "serial" or None
        ``None``: a local process pool with ``jobs`` workers (default: all cores).
    results_path : str or Path, optional
        JSON-lines file; trials are appended as they finish, and trials already
        in it (same case, settings, data and seed) are not run again.
    jobs : int, optional
        Worker count of the default pool.
    progress : bool, default False
        Show a tqdm progress bar.
    settings : dict, optional
        ``{method: minimize kwargs}`` replacing the paper's settings.

    Returns
    -------
    StudyResult
    """
    from . import presets

    if isinstance(case, str):
        case = presets.get(case)
    if int(trials) != trials or trials < 1:
        raise ParameterError(f"trials must be a positive integer, got {trials!r}")
    methods = [canonical_method(m) for m in methods]
    if not methods:
        raise ParameterError("give at least one method")
    settings = dict(settings or {})
    plan = {}
    for m in methods:
        kwargs = dict(settings[m]) if m in settings else case.minimize_kwargs(m)
        kwargs.setdefault("method", m)
        plan[m] = (kwargs, _fingerprint(case, m, kwargs))

    path = Path(results_path) if results_path is not None else None
    done = {}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        for r in _read_records(path):
            key = (r.get("method"), r.get("trial"))
            if key[0] in plan and r.get("config") == plan[key[0]][1] and r.get("seed") == trial_seed(seed, key[1]):
                done[key] = r
    todo = [(m, i) for m in methods for i in range(int(trials)) if (m, i) not in done]

    records = dict(done)
    pool, owned = _make_executor(executor, jobs)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(methods) * int(trials), initial=len(done), unit="trial",
                   desc=f"{case.name}: {'/'.join(methods)}")
    out = None
    if path is not None:
        out = open(path, "a")
        if path.stat().st_size and not _ends_with_newline(path):
            out.write("\n")  # close a line cut short by an interruption; it is skipped when read
            out.flush()
    started = time.perf_counter()
    try:
        def finish(rec):
            records[(rec["method"], rec["trial"])] = rec
            if out is not None:
                out.write(json.dumps(rec) + "\n")
                out.flush()
            if bar is not None:
                bar.update(1)

        if pool is None:
            for m, i in todo:
                finish(_run_trial(case, m, plan[m][0], i, trial_seed(seed, i), plan[m][1]))
        else:
            if owned and todo:  # compile both kernels once (J, and outputs for lm); forked workers inherit them
                case.cost.batch(np.stack([case.x0, case.x0]))
                case.cost.simulate(case.x0)
            futures = [pool.submit(_run_trial, case, m, plan[m][0], i, trial_seed(seed, i), plan[m][1])
                       for m, i in todo]
            try:
                for fut in cf.as_completed(futures):
                    finish(fut.result())
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise
    finally:
        if out is not None:
            out.close()
        if bar is not None:
            bar.close()
        if owned:
            pool.shutdown(wait=True, cancel_futures=True)
    ordered = [records[(m, i)] for m in methods for i in range(int(trials))]
    return StudyResult(case=case, methods=methods, records=ordered, seed=seed,
                       elapsed=time.perf_counter() - started, resumed=len(done))


def ranksum(x, y, alpha: float = 0.05) -> dict:
    """Wilcoxon rank-sum test (:func:`scipy.stats.ranksums`), two-sided.

    Returns ``{"statistic", "p", "h"}`` with ``h = 1`` when ``p < alpha``
    (MATLAB's ``ranksum`` convention).  NaN values rank as ``+inf``.
    """
    x = np.where(np.isnan(x), np.inf, np.asarray(x, dtype=float))
    y = np.where(np.isnan(y), np.inf, np.asarray(y, dtype=float))
    stat, p = scipy.stats.ranksums(x, y)
    return {"statistic": float(stat), "p": float(p), "h": int(p < alpha), "alpha": alpha}


class StudyResult:
    """Records and statistics of a study.

    Attributes
    ----------
    case : Preset
    methods : list of str
    records : list of dict
        One JSON-able record per trial (``fun``, ``x``, ``nfev``, ``status``,
        ``diverged``, ``elapsed``, ``curve``, ...), ordered by method and trial.
    elapsed : float
        Wall time of this call (trials reused from a results file cost nothing).
    resumed : int
        Trials taken from the results file instead of being run.
    """

    def __init__(self, case, methods, records, seed, elapsed, resumed=0):
        self.case, self.methods, self.records = case, list(methods), list(records)
        self.seed, self.elapsed, self.resumed = seed, elapsed, resumed

    def values(self, method: str) -> np.ndarray:
        """Final J of each trial of ``method``."""
        return np.array([_from_json_float(r["fun"]) for r in self.records if r["method"] == method])

    def summary(self, alpha: float = 0.05) -> dict:
        """Per method: ``n, mean, best, worst, std`` (sample) of the final J, ``nfev``,
        ``diverged`` count, ``time_mean``/``time_total`` (s); plus ``"ranksum"``:
        Wilcoxon rank-sum for every pair of methods."""
        out = {}
        for m in self.methods:
            rs = [r for r in self.records if r["method"] == m]
            J = self.values(m)
            with np.errstate(all="ignore"):
                out[m] = {
                    "n": len(rs), "mean": float(np.mean(J)), "best": float(np.min(J)),
                    "worst": float(np.max(J)), "std": float(np.std(J, ddof=1)) if len(J) > 1 else 0.0,
                    "median": float(np.median(J)),
                    "nfev": float(np.mean([r["nfev"] for r in rs])),
                    "diverged": int(sum(r["diverged"] for r in rs)),
                    "time_mean": float(np.mean([r["elapsed"] for r in rs])),
                    "time_total": float(np.sum([r["elapsed"] for r in rs])),
                }
        pairs = {}
        for i, a in enumerate(self.methods):
            for b in self.methods[i + 1 :]:
                pairs[f"{a} vs {b}"] = ranksum(self.values(a), self.values(b), alpha)
        out["ranksum"] = pairs
        return out

    def best(self, method: str) -> dict:
        """The record of the trial with the lowest final J."""
        rs = [r for r in self.records if r["method"] == method]
        if not rs:
            raise ParameterError(f"no trials of {method!r} in this study")
        return min(rs, key=lambda r: _from_json_float(r["fun"]))

    def best_model(self, method: str):
        """The :class:`~hammerstein_ctrl.model.HammersteinModel` of :meth:`best`."""
        return self.case.structure.model(np.array([_from_json_float(v) for v in self.best(method)["x"]]))

    # -- reports ------------------------------------------------------------------
    def table(self, fmt: str = "text", *, paper: bool = True, alpha: float = 0.05) -> str:
        """The comparison table as ``"text"``, ``"markdown"`` or ``"csv"``.

        With ``paper=True`` the paper's reported value follows each of ours.
        """
        from .report import study_table

        return study_table(self, fmt=fmt, paper=paper, alpha=alpha)

    def to_json(self, path, alpha: float = 0.05) -> Path:
        """Write ``summary()`` (with non-finite numbers as strings) to ``path``."""
        def clean(v):
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            if isinstance(v, float):
                return _json_float(v)
            return v

        path = Path(path)
        summary = self.summary(alpha)
        data = clean(summary)
        data["_meta"] = {"case": self.case.name, "seed": self.seed, "elapsed_s": self.elapsed,
                         "trials": max(v["n"] for k, v in summary.items() if k != "ranksum")}
        path.write_text(json.dumps(data, indent=2))
        return path

    def __repr__(self):
        return f"StudyResult({self.case.name!r}, methods={self.methods}, trials={len(self.records)})"

    # -- notebook display (logic in display.py) -----------------------------------
    def _repr_html_(self) -> str:
        from .display import study_html
        return study_html(self)

    def to_frame(self, trials: bool = False):
        """Summary per method, or one row per trial, as a DataFrame (:func:`hammerstein_ctrl.display.study_frame`)."""
        from .display import study_frame
        return study_frame(self, trials=trials)
