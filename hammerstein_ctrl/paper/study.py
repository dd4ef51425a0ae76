"""Independent trials of several methods on a case: the paper's comparison tables.

:func:`run_study` runs ``trials`` independent runs of each method.  Trial ``i``
uses a seed derived only from the study seed and ``i``
(:func:`trial_seed`), so any subset of trials reruns identically, whatever the
executor, the order of completion or the other methods.  Each finished trial
is appended to a JSON-lines file at once; rerunning with the same
``results_path`` skips the trials already recorded, so an interrupted study
loses at most the trials that were running.  The file is checked, never
trusted: every line carries a digest of its content and settings and must
match :data:`RECORD_SCHEMA`, or it is moved aside, reported and its trial run
again.  One run at a time writes a results file (a lock refuses the second),
and the worker processes end with the run, even when it is killed.

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
import contextlib
import hashlib
import json
import math
import os
import time
import warnings
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np
import scipy.stats

from .._linalg import single_threaded_blas
from ..exceptions import HammersteinError, ParameterError
from .._executors import make_executor
from .._safe_io import MAX_INPUT_BYTES, check_output, open_append, open_lock, read_bytes, write_bytes, write_text
from ..optimize import canonical_method, minimize
from ..blocks._json import encode_float as json_float, json_safe

__all__ = ["run_study", "StudyResult", "trial_seed", "ranksum", "validate_record", "record_digest", "RECORD_SCHEMA",
           "StudyLockedError", "StudyInterrupted", "ResultsFileWarning"]

#: Points kept from each trial's convergence curve (for plots).
CURVE_POINTS = 200
#: Version of the JSON-lines record layout and of the meaning of its fields; part of every
#: fingerprint, so files written by an older layout are never mixed into a resumed study
#: (4: status 5, BUDGET_EXHAUSTED, and nit as steps for LM and scipy's methods stopped by maxfev).
RECORD_VERSION = 4

class StudyLockedError(HammersteinError):
    """Another run is writing into the same results file."""


class StudyInterrupted(RuntimeError):
    """A worker process died (killed by the system); finished trials are kept."""


class ResultsFileWarning(UserWarning):
    """Lines of a results file were rejected (damaged, edited or duplicated) and their trials rerun."""


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
    return {"nfev": nfev.tolist(), "best": [json_float(b) for b in best],
            "estimate": [json_float(e) for e in est]}


def _from_json_float(v):
    return float(v)  # also parses the strings "inf", "-inf" and "nan"


def _run_trial(case, method: str, kwargs: dict, trial: int, seed: int, fingerprint: str) -> dict:
    """One independent run; returns a JSON-able record (executed in a worker).

    BLAS is held to one thread: the matrices here are tiny, and OpenBLAS's
    spinning worker threads in several processes on the same cores slow a
    trial down about 50-fold.
    """
    t0 = time.perf_counter()
    if kwargs.get("method") in ("spsa", "nlspsa", "nspsa"):  # curves at the iterate; never changes the run
        kwargs = {**kwargs, "options": {**(kwargs.get("options") or {}), "monitor": CURVE_POINTS // 2}}
    with single_threaded_blas():
        res = minimize(case.cost, case.x0, seed=seed, **kwargs)
    record = {
        "case": case.name, "method": method, "trial": trial, "seed": seed, "config": fingerprint,
        "fun": json_float(res.fun), "x": [json_float(v) for v in res.x], "nfev": int(res.nfev),
        "nit": int(res.nit), "status": int(res.status), "success": bool(res.success),
        "diverged": int(res.status) == 2, "message": str(res.message),
        "best_fun": json_float(res.best_fun), "nfev_monitor": int(res.nfev_monitor),
        "elapsed": time.perf_counter() - t0,
        "curve": _curve(res.history),
    }
    record["digest"] = record_digest(record)
    return record


def record_digest(record: dict) -> str:
    """SHA-256 of a record's content (every field but ``digest``, settings fingerprint included).

    Examples
    --------
    >>> r = {"trial": 0, "fun": 1.5, "config": "abc"}
    >>> record_digest(r) == record_digest(dict(r)) != record_digest({**r, "fun": 1.25})
    True
    """
    body = {k: v for k, v in record.items() if k != "digest"}
    return hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=True).encode()).hexdigest()


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _is_count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def _is_value(v) -> bool:
    """A JSON-encoded float: a number or one of the strings written for non-finite values."""
    return _is_number(v) or v in ("inf", "-inf", "nan")


def _is_curve(v) -> bool:
    if not isinstance(v, dict) or not all(isinstance(v.get(k), list) for k in ("nfev", "best", "estimate")):
        return False
    return (len({len(v["nfev"]), len(v["best"]), len(v["estimate"])}) == 1
            and all(map(_is_count, v["nfev"])) and all(map(_is_value, v["best"] + v["estimate"])))


#: Every field of a results line and the check its value must pass.
RECORD_SCHEMA = {
    "case": lambda v: isinstance(v, str), "method": lambda v: isinstance(v, str), "trial": _is_count,
    "seed": _is_count, "config": lambda v: isinstance(v, str), "fun": _is_value,
    "x": lambda v: isinstance(v, list) and len(v) > 0 and all(map(_is_value, v)),
    "nfev": _is_count, "nit": _is_count, "status": _is_count, "success": lambda v: isinstance(v, bool),
    "diverged": lambda v: isinstance(v, bool), "message": lambda v: isinstance(v, str),
    "best_fun": _is_value, "nfev_monitor": _is_count,
    "elapsed": lambda v: _is_number(v) and math.isfinite(v) and v >= 0, "curve": _is_curve,
    "digest": lambda v: isinstance(v, str),
}


def validate_record(record) -> str | None:
    """Why ``record`` (a parsed results line) cannot be trusted, or None if it can.

    It must be an object with exactly the fields of :data:`RECORD_SCHEMA`, each
    of the right type, and its ``digest`` must match its content.

    Examples
    --------
    >>> validate_record(42)
    'not a JSON object'
    >>> validate_record({"trial": None}).split(" [")[0]
    'missing field(s)'
    """
    if not isinstance(record, dict):
        return "not a JSON object"
    missing = sorted(set(RECORD_SCHEMA) - set(record))
    if missing:
        return f"missing field(s) {missing}"
    extra = sorted(set(record) - set(RECORD_SCHEMA))
    if extra:
        return f"unknown field(s) {extra}"
    for key, check in RECORD_SCHEMA.items():
        if not check(record[key]):
            return f"field {key!r} has an invalid value {str(record[key])[:40]!r}"
    if record["digest"] != record_digest(record):
        return "content does not match its digest (edited or damaged)"
    return None


def _parse_line(raw: bytes):
    """``(record, None)`` for a trustworthy line, ``(None, reason)`` otherwise."""
    if not raw.endswith(b"\n"):
        return None, "cut short (no end of line: an interrupted write)"
    try:
        record = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except json.JSONDecodeError as exc:
        return None, f"not JSON ({exc.msg})"
    reason = validate_record(record)
    return (None, reason) if reason else (record, None)


def _load_results(path: Path, accept) -> tuple[dict, list]:
    """Trusted records of ``path`` for which ``accept(record)`` holds, keyed by (method, trial).

    Lines that fail :func:`validate_record`, and repeats of a trial already
    read, are moved to ``<name>.rejected<suffix>`` next to ``path`` (byte for
    byte, so nothing is lost) and returned as ``(line number, reason)``.
    """
    done, rejected, keep, bad, seen = {}, [], [], [], set()
    check_output(path)                          # a link (even dangling) or a folder is refused, never followed
    if not path.exists():
        return done, rejected
    data = read_bytes(path, limit=MAX_INPUT_BYTES, what="results file")
    lines = [line + b"\n" for line in data.split(b"\n")[:-1]] + ([data.rsplit(b"\n", 1)[-1]] if not
                                                                 data.endswith(b"\n") else [])
    for number, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        record, reason = _parse_line(raw)
        if record is not None:
            key = (record["method"], record["trial"], record["config"], record["seed"])
            reason = "a repeat of a trial already in the file" if key in seen else None
            seen.add(key)
        if reason:
            rejected.append((number, reason))
            bad.append(raw if raw.endswith(b"\n") else raw + b"\n")
            continue
        keep.append(raw)
        if accept(record):
            done[(record["method"], record["trial"])] = record
    if rejected:
        with open_append(path.with_name(f"{path.stem}.rejected{path.suffix}"), binary=True) as fh:
            fh.write(b"".join(bad))
        write_bytes(path, b"".join(keep))       # a fresh mkstemp file moved over it: no fixed temporary name
    return done, rejected


@contextlib.contextmanager
def _locked(path: Path):
    """Hold an exclusive lock on ``<path>.lock`` or raise :class:`StudyLockedError` at once.

    The lock is an ``flock`` on an open file: the system releases it when the
    holder exits, however it exits, so a killed run leaves no stale lock.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no locking
        yield
        return
    lock = path.with_name(path.name + ".lock")
    with open_lock(lock) as fh:                 # O_NOFOLLOW: a planted link is refused, never truncated
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "unknown"
            raise StudyLockedError(
                f"another run (pid {holder}) is writing {path}; wait for it to finish or choose "
                "another output directory"
            ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(str(os.getpid()))
        fh.flush()
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def run_study(case, methods, trials: int = 25, seed: int = 0, executor=None, results_path=None,
              *, jobs: int | None = None, progress: bool = False, settings: dict | None = None):
    """Run independent trials of several methods on a case.

    Parameters
    ----------
    case : Preset or str
        A :class:`~hammerstein_ctrl.paper.presets.Preset` (or ``"trs"``/``"emps"``).
    methods : sequence of str
        Methods to compare (aliases such as ``"N-SPSA"`` name the same method
        and are counted once); each uses the case's paper settings
        (``case.minimize_kwargs(method)``) unless ``settings`` overrides them.
    trials : int, default 25
    seed : int, default 0
        Study seed; trial ``i`` uses :func:`trial_seed` ``(seed, i)``.
    executor : concurrent.futures.Executor, "serial" or None
        ``None``: a local process pool with ``jobs`` workers (default: all cores).
    results_path : str or Path, optional
        JSON-lines file; trials are appended as they finish, and trials already
        in it (same case, settings, data and seed) are not run again.  Each line
        carries a digest of its content (settings fingerprint included) and is
        checked against :data:`RECORD_SCHEMA`: a damaged, edited or repeated
        line is moved to ``<name>.rejected.jsonl``, reported with a
        :class:`ResultsFileWarning`, and its trial is run again.  A lock
        (``<name>.lock``) makes a second concurrent run into the same file
        raise :class:`StudyLockedError` at once.
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
    if isinstance(trials, bool) or int(trials) != trials or trials < 1:
        raise ParameterError(f"trials must be a positive integer, got {trials!r}")
    trials = int(trials)
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
    methods = list(dict.fromkeys(canonical_method(m) for m in methods))  # "nspsa", "N-SPSA": one method
    if not methods:
        raise ParameterError("give at least one method")
    settings = {canonical_method(m): v for m, v in (settings or {}).items()}
    plan = {}
    for m in methods:
        kwargs = dict(settings[m]) if m in settings else case.minimize_kwargs(m)
        kwargs.setdefault("method", m)
        plan[m] = (kwargs, _fingerprint(case, m, kwargs))
    pool, owned = make_executor(executor, jobs)

    path = Path(results_path) if results_path is not None else None
    try:
        if path is None:
            return _execute(case, methods, trials, seed, plan, pool, owned, None, progress)
        path.parent.mkdir(parents=True, exist_ok=True)
        with _locked(path):
            return _execute(case, methods, trials, seed, plan, pool, owned, path, progress)
    finally:
        if owned:
            pool.shutdown(wait=True, cancel_futures=True)


def _resume(path: Path, plan: dict, seed: int, trials: int) -> tuple[dict, list]:
    """Records of ``path`` usable by this study, and the lines rejected (reported as a warning)."""
    def usable(r):
        m, i = r["method"], r["trial"]
        return m in plan and r["config"] == plan[m][1] and i < trials and r["seed"] == trial_seed(seed, i)

    done, rejected = _load_results(path, usable)
    if rejected:
        shown = "; ".join(f"line {n}: {why}" for n, why in rejected[:5])
        more = f"; and {len(rejected) - 5} more" if len(rejected) > 5 else ""
        warnings.warn(f"{path}: {len(rejected)} line(s) rejected and moved to "
                      f"{path.stem}.rejected{path.suffix} (trials left without a trusted line run again): "
                      f"{shown}{more}",
                      ResultsFileWarning, stacklevel=4)
    return done, rejected


def _execute(case, methods, trials, seed, plan, pool, owned, path, progress):
    """Run the trials not already in ``path``; append each to it as it finishes."""
    done, rejected = _resume(path, plan, seed, trials) if path is not None else ({}, [])
    todo = [(m, i) for m in methods for i in range(trials) if (m, i) not in done]
    records = dict(done)
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(methods) * trials, initial=len(done), unit="trial",
                   desc=f"{case.name}: {'/'.join(methods)}")
    out = open_append(path) if path is not None else None
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
            _run_pool(case, plan, seed, todo, pool, owned, finish, path)
    finally:
        if out is not None:
            out.close()
        if bar is not None:
            bar.close()
    ordered = [records[(m, i)] for m in methods for i in range(trials)]
    return StudyResult(case=case, methods=methods, records=ordered, seed=seed,
                       elapsed=time.perf_counter() - started, resumed=len(done), rejected=rejected)


def _run_pool(case, plan, seed, todo, pool, owned, finish, path):
    if owned and todo:  # compile both kernels once (J, and outputs for lm); forked workers inherit them
        case.cost.batch(np.stack([case.x0, case.x0]))
        case.cost.simulate(case.x0)
    futures = [pool.submit(_run_trial, case, m, plan[m][0], i, trial_seed(seed, i), plan[m][1])
               for m, i in todo]
    try:
        for fut in cf.as_completed(futures):
            finish(fut.result())
    except BrokenProcessPool:
        for fut in futures:
            fut.cancel()
        where = f"; the finished trials are saved in {path}, rerun to resume" if path is not None else ""
        raise StudyInterrupted("a worker process died unexpectedly (killed by the system, e.g. out of "
                               f"memory){where}") from None
    except BaseException:
        for fut in futures:
            fut.cancel()
        raise


def _rank_value(v) -> float:
    """A final J for ranking: NaN (a failed trial) ranks last."""
    v = _from_json_float(v)
    return math.inf if math.isnan(v) else v


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
    rejected : list of (int, str)
        Lines of the results file that could not be trusted (line number,
        reason); they were moved aside and their trials run again.
    """

    def __init__(self, case, methods, records, seed, elapsed, resumed=0, rejected=()):
        self.case, self.methods, self.records = case, list(methods), list(records)
        self.seed, self.elapsed, self.resumed = seed, elapsed, resumed
        self.rejected = list(rejected)

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
        return min(rs, key=lambda r: _rank_value(r["fun"]))

    def best_model(self, method: str):
        """The :class:`~hammerstein_ctrl.blocks.HammersteinModel` of :meth:`best`."""
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
        path = Path(path)
        summary = self.summary(alpha)
        data = json_safe(summary)
        data["_meta"] = {"case": self.case.name, "seed": self.seed, "elapsed_s": self.elapsed,
                         "trials": max(v["n"] for k, v in summary.items() if k != "ranksum")}
        write_text(path, json.dumps(data, indent=2))
        return path

    def __repr__(self):
        return f"StudyResult({self.case.name!r}, methods={self.methods}, trials={len(self.records)})"

    # -- notebook display (logic in display.py) -----------------------------------
    def _repr_html_(self) -> str:
        from ..data._display import study_html
        return study_html(self)

    def to_frame(self, trials: bool = False):
        """Summary per method, or one row per trial, as a DataFrame
        (:func:`hammerstein_ctrl.data._display.study_frame`)."""
        from ..data._display import study_frame
        return study_frame(self, trials=trials)
