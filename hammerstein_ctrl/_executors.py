"""Where independent jobs run: a local process pool whose workers end with their parent, this process, or any executor.

:func:`make_executor` turns the ``executor``/``jobs`` arguments of the
functions that run many independent jobs (``run_study``,
``select_structure``) into a ``concurrent.futures.Executor`` (or ``None`` for
this process).  A pool it makes has workers that end with the process that
started them, even when that one is killed (``SIGKILL``): Linux signals them
through ``PR_SET_PDEATHSIG``, elsewhere a daemon thread notices the change of
parent within :data:`PARENT_WATCH_INTERVAL`.

Examples
--------
>>> make_executor("serial", None)
(None, False)
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time

from .exceptions import ParameterError

__all__ = ["make_executor", "worker_init", "PARENT_WATCH_INTERVAL"]

#: Seconds between a worker's checks that the process that started it is alive.
PARENT_WATCH_INTERVAL = 0.5
#: ``prctl`` option asking Linux to signal a process when its parent dies.
_PR_SET_PDEATHSIG = 1


def _watch_parent(parent_pid: int):
    while os.getppid() == parent_pid:
        time.sleep(PARENT_WATCH_INTERVAL)
    os._exit(1)


def worker_init(parent_pid: int):
    """Make a pool worker end when the study's process dies, even by SIGKILL.

    Linux kills the worker at once through ``PR_SET_PDEATHSIG``; elsewhere a
    daemon thread notices the change of parent within :data:`PARENT_WATCH_INTERVAL`.
    """
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()
    if os.getppid() != parent_pid:  # the parent died before the watch began
        os._exit(1)


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells, else ``os.cpu_count()``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def make_executor(executor, jobs: int | None):
    """``(executor or None, owned)``: ``None`` runs in this process; ``owned`` says the caller must shut it down.

    ``executor`` is a ``concurrent.futures.Executor`` (used as is), ``"serial"``
    (this process) or ``None`` (a local process pool of ``jobs`` workers,
    default all cores; one worker means this process).  ``jobs`` past the
    cores this process may use is capped at their number: the jobs are
    CPU-bound, so more workers only add memory and processes.
    """
    if jobs is not None and (isinstance(jobs, bool) or int(jobs) != jobs or jobs < 1):
        raise ParameterError(f"jobs must be a positive integer, got {jobs!r}")
    if executor is None:
        workers = min(int(jobs or usable_cores()), usable_cores())
        if workers == 1:
            return None, False
        ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods() else None)
        return cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=worker_init,
                                      initargs=(os.getpid(),)), True
    if executor == "serial":
        return None, False
    if not hasattr(executor, "submit"):
        raise ParameterError(f"executor must be a concurrent.futures.Executor or 'serial', got {executor!r}")
    return executor, False
