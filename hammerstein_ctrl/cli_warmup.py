"""The ``hammerstein-ctrl warmup`` sub-command: compile the kernels of common structures now, on every core.

``hammerstein-ctrl warmup [--orders 1 2 3 4] [--nonlinearity polynomial tanh ...] [--holds foh zoh]
[--jobs N]`` identifies a short synthetic record with each structure of the grid
(:func:`~hammerstein_ctrl.warmup.warmup`), prints one line per structure as it
finishes and the totals, and exits 1 if a structure could not be identified.

Wire it into a parser with :func:`add_warmup_parser`.
"""

from __future__ import annotations

__all__ = ["add_warmup_parser", "WARMUP_HELP"]

WARMUP_HELP = "compile the kernels of common structures now, on every core (kept once per machine)"


def add_warmup_parser(subparsers, count):
    """Add ``warmup`` to an ``argparse`` sub-parsers object (``count``: the CLI's positive-integer type)."""
    from .warmup import DEFAULT_FAMILIES, DEFAULT_HOLDS, DEFAULT_ORDERS

    warm = subparsers.add_parser(
        "warmup", help=WARMUP_HELP,
        description="Identify a short synthetic record with each structure of a grid (linear orders x input "
                    "nonlinearities x holds, no zero), one structure per worker process, so that the compiled "
                    "code each needs is saved in the machine's cache ($HAMMERSTEIN_CTRL_CACHE) and no later "
                    "process compiles it.  Exits 1 if a structure could not be identified.")
    warm.add_argument("--orders", type=count(1), nargs="+", default=list(DEFAULT_ORDERS), metavar="N",
                      help=f"linear orders (default {' '.join(map(str, DEFAULT_ORDERS))})")
    warm.add_argument("--nonlinearity", nargs="+", default=list(DEFAULT_FAMILIES), metavar="NAME",
                      help=f"input nonlinearity families (default {' '.join(DEFAULT_FAMILIES)})")
    warm.add_argument("--holds", nargs="+", default=list(DEFAULT_HOLDS), choices=["foh", "zoh"],
                      help=f"intersample holds (default {' '.join(DEFAULT_HOLDS)})")
    warm.add_argument("--jobs", type=count(1), default=None, help="worker processes (default: all cores)")
    warm.set_defaults(func=_cmd_warmup)
    return warm


def _cmd_warmup(args) -> int:
    from .warmup import warmup, warmup_plan

    plan = warmup_plan(args.orders, args.nonlinearity, args.holds)      # bad input: one line, exit 2
    print(f"compiling for {len(plan)} structures ...", flush=True)

    def show(job, result):
        cpu, error = result
        print(f"  {job.label():32s} {cpu:6.1f} s CPU  {error or 'ok'}", flush=True)

    report = warmup(args.orders, args.nonlinearity, args.holds, jobs=args.jobs, progress=show)
    failed = [job.label() for job, err in zip(report.jobs, report.errors) if err]
    print(f"{len(report.jobs)} structures: {sum(report.cpu):.1f} s of CPU, {report.wall:.1f} s wall"
          + (f"; not compiled: {', '.join(failed)}" if failed else ""))
    return 1 if failed else 0
