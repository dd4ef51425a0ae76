"""The ``hammerstein-ctrl warmup`` sub-command: compile the kernels of common structures now, on every core.

``hammerstein-ctrl warmup [--orders 1 2 3 4] [--nonlinearity polynomial tanh ...] [--holds foh zoh]
[--jobs N]`` identifies a short synthetic record with each structure of the grid
(:func:`~hammerstein_ctrl.warmup.warmup`), prints one line per structure (in
the plan's order, each once it is done) and the totals, and exits 1 if a
structure could not be compiled.

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
    """Warm the grid of the arguments, printing as it goes; 0, or 1 if a structure was not compiled."""
    from .warmup import row, warmup, warmup_plan

    plan = warmup_plan(args.orders, args.nonlinearity, args.holds)      # bad input: one line, exit 2
    print(f"compiling for {len(plan)} structures (CPU seconds in each worker) ...", flush=True)
    report = warmup(args.orders, args.nonlinearity, args.holds, jobs=args.jobs,
                    progress=lambda job, result: print(row(job, result), flush=True))
    print(report.totals())
    return 0 if report.ok else 1
