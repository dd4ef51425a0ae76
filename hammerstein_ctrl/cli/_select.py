"""The ``hammerstein-ctrl select`` sub-command: rank candidate structures on a record.

``hammerstein-ctrl select --data rig.csv --orders 0 1 1 2 --nonlinearity tanh
polynomial [--kinds hammerstein wiener] [--criterion bic] [--validation
val.csv]`` fits every combination (:func:`~hammerstein_ctrl.fit.candidate_structures`),
prints the ranked table and can write it as CSV (``--table``) and the best
fit as a result file (``--out``).

Wire it into a parser with :func:`add_select_parser`.
"""

from __future__ import annotations

import csv
import io

from ..exceptions import HammersteinError

__all__ = ["add_select_parser"]


def add_select_parser(subparsers, count, number, writable):
    """Add ``select`` to an ``argparse`` sub-parsers object (``count``, ``number``: the CLI's argument types;
    ``writable``: its output-path check)."""
    from ..data._records import add_record_arguments
    from ..fit._selection import CRITERIA, KINDS

    help_text = ("rank candidate structures (orders x nonlinearities x kinds) by AIC, BIC, FPE or "
                 "validation fit")
    sel = subparsers.add_parser("select", help=help_text, description=help_text + ".")
    add_record_arguments(sel)
    sel.add_argument("--orders", type=count(0), nargs="+", required=True, metavar="L M",
                     help="pairs of numerator and denominator degrees, e.g. 0 1 1 2")
    sel.add_argument("--nonlinearity", nargs="+", default=[], metavar="NAME",
                     help="input nonlinearity families (tanh, coulomb, polynomial, saturation, deadzone)")
    sel.add_argument("--output-nonlinearity", nargs="+", default=[], metavar="NAME",
                     help="output nonlinearity families (default: those of --nonlinearity)")
    sel.add_argument("--degree", type=count(1), default=3, help="degree of a polynomial family (default 3)")
    sel.add_argument("--kinds", nargs="+", default=["hammerstein"], choices=KINDS, help="structure kinds")
    sel.add_argument("--criterion", default="aic", choices=CRITERIA, help="ranking criterion (default aic)")
    sel.add_argument("--validation", help="a validation record (same column options as --data)")
    sel.add_argument("--offset", action="store_true", help="estimate an output offset in every candidate")
    sel.add_argument("--initial-state", choices=["zero", "estimate"], default="zero")
    sel.add_argument("--maxfev", type=count(1), help="evaluation budget of each fit (default: config auto.maxfev, "
                     "3000)")
    sel.add_argument("--seed", type=count(0), default=0)
    sel.add_argument("--jobs", type=count(1), help="worker processes (default: all cores)")
    sel.add_argument("--table", help="write the ranked table as CSV")
    sel.add_argument("--out", help="write the best fit as a result JSON (hammerstein_ctrl.load_result reads it)")
    sel.set_defaults(func=_cmd_select, writable=writable)
    return sel


def _families(names, degree):
    from ..blocks._families import nonlinearity_from_name

    return [nonlinearity_from_name(n, **({"degree": degree} if n.strip().lower() == "polynomial" else {}))
            for n in names]


def _cmd_select(args) -> int:
    from ..io._results import save_result
    from ..data._records import read_record, record_from_args
    from ..fit._selection import candidate_structures, select_structure

    if len(args.orders) % 2:
        raise HammersteinError(f"--orders takes pairs L M, got {len(args.orders)} numbers")
    table = args.writable("--table", args.table) if args.table else None
    out = args.writable("--out", args.out) if args.out else None
    orders = list(zip(args.orders[0::2], args.orders[1::2]))
    cands = candidate_structures(orders, _families(args.nonlinearity, args.degree), kinds=args.kinds,
                                 output_nonlinearities=_families(args.output_nonlinearity, args.degree),
                                 offset=args.offset, initial_state=args.initial_state)
    data = record_from_args(args)
    validation = None
    if args.validation:
        validation = read_record(args.validation, input=args.input, output=args.output, time=args.time, dt=args.dt,
                                 tolerance=args.tolerance, resample=args.resample, intersample=args.intersample)
    sel = select_structure(data, cands, validation=validation, criterion=args.criterion, maxfev=args.maxfev,
                           seed=args.seed, jobs=args.jobs)
    print(sel.summary())
    if table is not None:
        from .._safe_io import write_text

        fields = [k for k in sel.table[0] if k != "message"]
        buffer = io.StringIO(newline="")
        writer = csv.DictWriter(buffer, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows({k: (" ".join(v) if isinstance(v, list) else v) for k, v in row.items()}
                         for row in sel.table)
        write_text(table, buffer.getvalue())
        print(f"table written to {table}")
    if out is not None:
        save_result(sel.best, out)
        print(f"best fit written to {out}")
    return 0 if sel.table[0]["success"] else 1
