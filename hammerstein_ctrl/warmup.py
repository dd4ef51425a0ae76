"""Compile a machine's kernels for the common structures before their first use, on every core.

Compiled code is kept once per machine (``$HAMMERSTEIN_CTRL_CACHE``, default
``~/.cache/hammerstein_ctrl``) and reused by every later process, the command
line and the test suite; what is missing is built on first use, which for a
new structure takes a fraction of a second of the C compiler's CPU (a few
seconds of numba's for kernels with an output map).  :func:`warmup` pays
that ahead of time: it identifies a short synthetic record with each structure
of a grid (linear orders x input families x intersample holds, each the
default ``identify(data, HammersteinStructure(LinearStructure(0, n), g))``),
one structure per worker process, so every worker compiles and saves what that
structure's identification needs.  The first structure runs alone (it compiles
the code every structure shares), the rest side by side.

A structure outside the grid (another numerator order, an estimated initial
state, an output nonlinearity, a Lur'e loop) still compiles on its first use; a
grid already compiled costs a second or two per structure to check.  The
structures are identified in worker processes (or, with ``executor="serial"``,
in this one); a thread pool would mix their CPU times and warnings.

Examples
--------
>>> plan = warmup_plan(orders=[1], families=["polynomial"], holds=["zoh"])
>>> [(p.order, p.family, p.hold) for p in plan]
[(1, 'polynomial', 'zoh')]
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures.process import BrokenProcessPool

import numpy as np

from .exceptions import ParameterError

__all__ = ["warmup", "warmup_plan", "row", "WarmupJob", "WarmupReport", "DEFAULT_ORDERS", "DEFAULT_FAMILIES",
           "DEFAULT_HOLDS", "WARMUP_SAMPLES"]

#: Linear orders (poles) warmed by default.
DEFAULT_ORDERS = (1, 2, 3, 4)
#: Input nonlinearity families warmed by default (names of ``nonlinearity_from_name``).
DEFAULT_FAMILIES = ("polynomial", "tanh", "deadzone", "saturation", "coulomb")
#: Intersample holds warmed by default (``"zoh"`` on request: records from a DAC).
DEFAULT_HOLDS = ("foh",)
#: Samples of the synthetic record (the kernels compiled do not depend on the length).
WARMUP_SAMPLES = 1500
_DT = 0.01


@dataclasses.dataclass(frozen=True)
class WarmupJob:
    """One structure of the grid: a linear block of ``order`` poles (no zero) after the ``family`` input map."""

    order: int
    family: str
    hold: str

    def label(self) -> str:
        """``"order 2, tanh, foh"``."""
        return f"order {self.order}, {self.family}, {self.hold}"


@dataclasses.dataclass
class WarmupReport:
    """What :func:`warmup` did: each job's CPU seconds (in its worker) and error, and the wall time."""

    jobs: list
    cpu: list
    errors: list
    wall: float

    @property
    def ok(self) -> bool:
        """Whether every structure was identified (so its compiled code is saved)."""
        return not any(self.errors)

    def table(self) -> str:
        """One line per structure, then the totals."""
        lines = [f"{'structure':32s} {'CPU s':>7s}  result"]
        lines += [row(job, (cpu, err)) for job, cpu, err in zip(self.jobs, self.cpu, self.errors)]
        return "\n".join(lines + [self.totals()])

    def totals(self) -> str:
        """The count, CPU and wall time, and the structures not compiled."""
        failed = [job.label() for job, err in zip(self.jobs, self.errors) if err]
        return (f"{len(self.jobs)} structures: {sum(self.cpu):.1f} s of CPU in the workers, {self.wall:.1f} s wall"
                + (f"; not compiled: {', '.join(failed)}" if failed else ""))


def row(job: WarmupJob, result: tuple) -> str:
    """One line of the report: the structure, its CPU seconds and ``compiled`` or its error."""
    cpu, error = result
    return f"{job.label():32s} {cpu:7.1f}  {error or 'compiled'}"


def warmup_plan(orders=DEFAULT_ORDERS, families=DEFAULT_FAMILIES, holds=DEFAULT_HOLDS) -> list:
    """The jobs of a grid, checked: orders ``1..MAX_ORDER``, known family names, holds ``"foh"``/``"zoh"``."""
    from ._checks import MAX_ORDER
    from .nonlinearities import nonlinearity_from_name

    jobs = []
    for hold in holds:
        if hold not in ("foh", "zoh"):
            raise ParameterError(f"hold must be 'foh' or 'zoh', got {hold!r}")
        for family in families:
            name = nonlinearity_from_name(family).name          # an unknown name: its one-line error
            for order in orders:
                if not _is_order(order, MAX_ORDER):
                    raise ParameterError(f"orders must be integers in 1..{MAX_ORDER}, got {order!r}")
                job = WarmupJob(int(order), name, hold)
                if job not in jobs:                             # "deadzone" and "dead-zone", [2, 2]: once
                    jobs.append(job)
    if not jobs:
        raise ParameterError("nothing to warm: give at least one order, family and hold")
    return jobs


def _is_order(order, most: int) -> bool:
    try:
        return not isinstance(order, bool) and int(order) == order and 1 <= order <= most
    except (TypeError, ValueError, OverflowError):
        return False


def _record(job: WarmupJob, offset: float = 0.0, coloured: bool = False):
    """A short, well-excited record of a known model of the job's structure (seeded: the same every time).

    With ``offset`` and ``coloured``: an output offset and AR(1) noise (pole 0.95), as on a real rig, whose
    fits take the other branches of ``identify`` (the offset estimate, the coloured-noise uncertainty).
    """
    import control

    from .iodata import IOData
    from .model import HammersteinModel
    from .nonlinearities import nonlinearity_from_name

    rng = np.random.default_rng(job.order)
    g = nonlinearity_from_name(job.family)
    poles = np.geomspace(1.0, 8.0, job.order)
    den = np.real(np.poly(-poles))
    model = HammersteinModel(control.tf([den[-1]], den), g, np.ones(g.n_params))
    u = np.repeat(rng.uniform(-2.0, 2.0, WARMUP_SAMPLES // 25 + 1), 25)[:WARMUP_SAMPLES]
    y = model.simulate(IOData(u, np.zeros(WARMUP_SAMPLES), dt=_DT, intersample=job.hold))
    e = 0.01 * np.std(y) * rng.standard_normal(y.size)
    if coloured:
        import scipy.signal

        e = 5.0 * scipy.signal.lfilter([1.0], [1.0, -0.95], e)
    return IOData(u, y + offset + e, dt=_DT, intersample=job.hold)


def _run(job: WarmupJob) -> tuple:
    """``(CPU seconds, error or None)`` of the job's fits: the clean record, then the offset record with an
    offset estimated, then single evaluations of J (the paths of a cost called directly)."""
    import warnings

    from .exceptions import CacheWarning

    started = time.process_time()
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            _fits(job)
        unsaved = [str(w.message) for w in seen if issubclass(w.category, CacheWarning)]
        error = f"CacheWarning: {' '.join(unsaved[0].split())}" if unsaved else None
    except Exception as exc:          # noqa: BLE001 - report it and go on with the other structures
        error = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    return time.process_time() - started, error


def _fits(job: WarmupJob):
    """The job's fits: the clean record, the offset record with an offset estimated, single evaluations of J."""
    from .identify import identify
    from .nonlinearities import nonlinearity_from_name
    from .objective import HammersteinCost
    from .structure import HammersteinStructure, LinearStructure

    structure = HammersteinStructure(LinearStructure(0, job.order), nonlinearity_from_name(job.family))
    data = _record(job)
    fit = identify(data, structure)
    identify(_record(job, offset=0.5, coloured=True), structure.with_options(offset=True))
    for reject in (False, True):                 # a single J through each of its two paths
        HammersteinCost(data, structure, reject_unstable=reject)(fit.x)


def warmup(orders=DEFAULT_ORDERS, families=DEFAULT_FAMILIES, holds=DEFAULT_HOLDS, *, jobs: int | None = None,
           executor=None, progress=None) -> WarmupReport:
    """Compile and save what identifying each structure of the grid needs (module notes).

    Parameters
    ----------
    orders, families, holds : sequence
        The grid (:func:`warmup_plan`); defaults :data:`DEFAULT_ORDERS`,
        :data:`DEFAULT_FAMILIES`, :data:`DEFAULT_HOLDS`.
    jobs, executor
        Where the structures are identified
        (:func:`~hammerstein_ctrl.executors.make_executor`): a local process
        pool of all cores by default, ``"serial"`` for this process.
    progress : callable, optional
        Called with each job and its ``(CPU seconds, error)``, in the plan's order.

    Returns
    -------
    WarmupReport

    Raises
    ------
    ParameterError
        For a bad grid, or when this machine has no writable cache (nothing compiled could be kept).

    Examples
    --------
    >>> report = warmup(orders=[1], families=["polynomial"], executor="serial")
    >>> report.ok, report.table().splitlines()[1].split()[:4]
    (True, ['order', '1,', 'polynomial,', 'foh'])
    """
    from ._jit import ENV_CACHE, machine_cache_dir
    from .executors import make_executor

    plan = warmup_plan(orders, families, holds)
    if machine_cache_dir() is None:
        raise ParameterError(f"no writable cache for compiled code (set ${ENV_CACHE} to a writable folder): a "
                             "warm-up would compile for this process only")
    started = time.perf_counter()
    pool, owned = make_executor(executor, jobs)          # a bad executor or jobs: said before any work
    results = []
    try:
        _collect(plan, pool, results, progress)
    finally:
        if owned:
            pool.shutdown(cancel_futures=True)
    return WarmupReport(plan, [r[0] for r in results], [r[1] for r in results], time.perf_counter() - started)


def _collect(plan: list, pool, results: list, progress):
    """Run the plan's first job here and the rest in ``pool`` (or here), appending ``(CPU, error)`` in order."""
    def done(job, result):
        results.append(result)
        if progress is not None:
            progress(job, result)

    done(plan[0], _run(plan[0]))                         # the code every structure shares, compiled once
    if pool is None:
        for job in plan[1:]:
            done(job, _run(job))
        return
    futures = [pool.submit(_run, job) for job in plan[1:]]
    for job, future in zip(plan[1:], futures):
        try:
            done(job, future.result())
        except BrokenProcessPool as exc:                  # a worker killed (out of memory): the rest say so
            done(job, (0.0, f"BrokenProcessPool: {exc}"))
