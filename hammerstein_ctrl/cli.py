"""The ``hammerstein-ctrl`` command line.

Sub-commands: ``bench`` (speed against python-control), ``reproduce`` (the
paper's comparison tables and figures), ``identify`` (fit a user's record).
Errors in the input exit with status 2 and one line on stderr, no traceback.
"""

from __future__ import annotations

import argparse
import sys

from .exceptions import HammersteinError

__all__ = ["main"]


def _cmd_bench(args) -> int:
    from . import presets
    from .bench import evaluation_speed, format_report, optimizer_speed

    cases = []
    for name in args.cases:
        try:
            cases.append(presets.get(name))
        except FileNotFoundError as exc:
            print(f"skipping {name}: {str(exc).splitlines()[0]}", file=sys.stderr)
    evals = [evaluation_speed(case, case.paper["nspsa"]["beta"]) for case in cases]
    runs = [optimizer_speed(case, m) for case in cases for m in args.methods]
    print(format_report(evals, runs))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hammerstein-ctrl",
        description="Continuous-time Hammerstein identification (N-SPSA and rivals) on python-control.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    bench = sub.add_parser("bench", help="time cost evaluations and runs against control.forced_response")
    bench.add_argument("--cases", nargs="+", default=["emps", "trs"], choices=["emps", "trs"])
    bench.add_argument("--methods", nargs="+", default=["nspsa"],
                       help="methods whose preset run is timed (default: nspsa)")
    bench.set_defaults(func=_cmd_bench)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (HammersteinError, FileNotFoundError, OSError) as exc:
        message = str(exc).strip().splitlines()
        print(f"hammerstein-ctrl: error: {message[0] if message else exc!r}", file=sys.stderr)
        for line in message[1:]:
            print(f"  {line}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hammerstein-ctrl: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
