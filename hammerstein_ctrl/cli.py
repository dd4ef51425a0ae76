"""The ``hammerstein-ctrl`` command line.

Sub-commands: ``bench`` (speed against python-control), ``reproduce`` (the
paper's comparison tables and figures), ``identify`` (fit a user's record).
Errors in the input exit with status 2 and one line on stderr, no traceback.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

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


DEFAULT_METHODS = ["spsa", "nlspsa", "amvo-sca", "nspsa", "lm"]


def _use_agg():
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")


def _cmd_reproduce(args) -> int:
    import json
    from pathlib import Path

    from . import presets
    from .bench import forced_response_cost, time_call
    from .plots import study_figures
    from .report import best_models
    from .study import run_study

    kwargs = {"path": args.data} if (args.case == "emps" and args.data) else {}
    if args.case == "trs" and args.data:
        raise HammersteinError("--data applies to the EMPS case only (the TRS reconstruction is bundled)")
    case = presets.get(args.case, **kwargs)
    out = Path(args.out or f"results/{args.case}")
    out.mkdir(parents=True, exist_ok=True)
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    study = run_study(case, args.methods, trials=args.trials, seed=args.seed, jobs=args.jobs,
                      results_path=out / "results.jsonl", progress=progress)
    print(study.table("text"))
    (out / "summary.md").write_text(study.table("markdown"))
    (out / "summary.csv").write_text(study.table("csv"))
    study.to_json(out / "summary.json")

    validation = case.validation() if case.validation is not None else None
    best = best_models(study, validation)
    (out / "best_models.json").write_text(json.dumps(best, indent=2, default=str))
    if validation is not None:
        print(f"\nBest models on the validation record ({validation.name}):")
        for m, e in best.items():
            v = e.get("validation")
            print(f"  {m:<9} " + ("diverged" if v is None else
                                  f"fit {v['fit_percent']:6.2f} %  RMSE {v['rmse']:.4g} {validation.output_unit}"))

    nfev = sum(r["nfev"] for r in study.records)
    ours = sum(r["elapsed"] for r in study.records) / max(nfev, 1)
    # time python-control on a representative model: the best one found (at the TRS initial point
    # g(u) = 0 and forced_response would take its zero-input shortcut)
    finite = [r for r in study.records if np.isfinite(float(r["fun"]))]
    model = case.structure.model(np.array(min(finite, key=lambda r: float(r["fun"]))["x"], dtype=float))
    reference = time_call(lambda: forced_response_cost(case, model), repeat=3)
    print(f"\n{len(study.records)} trials, {nfev} evaluations: {study.elapsed:.1f} s wall here"
          + (f" ({study.resumed} trials reused from {out / 'results.jsonl'})" if study.resumed else ""))
    print(f"per evaluation: ours {ours * 1e6:.0f} us (in the trials) vs control.forced_response "
          f"{reference * 1e3:.1f} ms (measured now): {reference / ours:.0f}x; the same evaluations through "
          f"forced_response would take ~{nfev * reference / 3600:.2f} h")
    if not args.no_figures:
        _use_agg()
        formats = ("png", "svg") if args.svg else ("png",)
        paths = study_figures(study, out / "figures", formats=formats, validation=validation)
        print(f"figures: {len(paths)} files in {out / 'figures'}")
    print(f"results: {out}/results.jsonl, summary.json, summary.md, summary.csv, best_models.json")
    return 0


def _structure_from_args(args):
    from . import presets
    from .nonlinearities import nonlinearity_from_name
    from .structure import HammersteinStructure, LinearStructure

    if args.structure:
        extra = [flag for flag, given in (("--orders", args.orders), ("--nonlinearity", args.nonlinearity),
                                          ("--fix", args.fix), ("--degree", args.degree is not None),
                                          ("--breakpoints", args.breakpoints), ("--free-gain", args.free_gain))
                 if given]
        if extra:
            raise HammersteinError(f"{', '.join(extra)} cannot be combined with --structure {args.structure} "
                                   "(use --orders/--nonlinearity to build your own structure)")
        return presets.STRUCTURES[args.structure](), presets.X0[args.structure]
    if not (args.orders and args.nonlinearity):
        raise HammersteinError("give --structure trs|emps, or --orders L M and --nonlinearity NAME")
    fixed = {}
    for item in args.fix or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise HammersteinError(f"--fix expects NAME=VALUE, got {item!r}")
        try:
            fixed[name.strip()] = float(value)
        except ValueError:
            raise HammersteinError(f"--fix {item!r}: {value!r} is not a number") from None
    nl_kwargs = {}
    if args.degree is not None:
        nl_kwargs["degree"] = args.degree
    if args.breakpoints is not None:
        nl_kwargs["breakpoints"] = args.breakpoints
    linear = LinearStructure(args.orders[0], args.orders[1], monic_numerator=not args.free_gain, fixed=fixed)
    return HammersteinStructure(linear, nonlinearity_from_name(args.nonlinearity, **nl_kwargs)), None


def _cmd_identify(args) -> int:
    import json

    from .datasets import read_record
    from .identify import identify
    from .optimize import PerturbationGain, StepGain

    data = read_record(args.data, input=args.input, output=args.output, time=args.time, dt=args.dt)
    structure, default_x0 = _structure_from_args(args)
    x0 = args.x0 if args.x0 is not None else default_x0
    options = {}
    if args.gain_a is not None:
        options["a"] = StepGain(*args.gain_a)
    if args.gain_c is not None:
        options["c"] = PerturbationGain(*args.gain_c)
    if args.norm_limit is not None:
        options["norm_limit"] = args.norm_limit
    if args.pop_size is not None:
        options["pop_size"] = args.pop_size
    bounds = None
    if args.bounds is not None:
        if len(args.bounds) != 2 * structure.n_params:
            raise HammersteinError(f"--bounds needs {2 * structure.n_params} numbers (low high per parameter "
                                   f"{list(structure.param_names)}), got {len(args.bounds)}")
        bounds = list(zip(args.bounds[0::2], args.bounds[1::2]))
    maxfev = args.maxfev if args.maxfev is not None else (None if args.maxiter else 2501)
    result = identify(data, structure, method=args.method, x0=x0, maxfev=maxfev, maxiter=args.maxiter,
                      seed=args.seed, options=options or None, bounds=bounds)
    print(result.summary())
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(result.to_dict(), fh, indent=2, default=str)
        print(f"model written to {args.out}")
    if args.plot:
        _use_agg()
        from .plots import time_response

        fig = time_response(data, {result.method: result.model})
        fig.savefig(args.plot, dpi=120)
        print(f"figure written to {args.plot}")
    return 0 if result.success else 1


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

    rep = sub.add_parser("reproduce", help="run the paper's comparison (Table 3 / Table 7) and write figures")
    rep.add_argument("case", choices=["trs", "emps"])
    rep.add_argument("--trials", type=int, default=25, help="independent trials per method (default 25)")
    rep.add_argument("--methods", nargs="+", default=DEFAULT_METHODS,
                     help=f"methods to compare (default: {' '.join(DEFAULT_METHODS)})")
    rep.add_argument("--seed", type=int, default=0, help="study seed (trial i uses a seed derived from it)")
    rep.add_argument("--out", help="output directory (default results/CASE); rerunning resumes")
    rep.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    rep.add_argument("--data", help="folder or file of the EMPS data (default: $HAMMERSTEIN_CTRL_DATA)")
    rep.add_argument("--svg", action="store_true", help="also write SVG figures")
    rep.add_argument("--no-figures", action="store_true", help="skip the figures")
    rep.add_argument("--progress", dest="progress", action="store_true", default=None,
                     help="show a progress bar (default: when stderr is a terminal)")
    rep.add_argument("--no-progress", dest="progress", action="store_false")
    rep.set_defaults(func=_cmd_reproduce)

    ide = sub.add_parser(
        "identify", help="fit a Hammerstein model to your own record",
        description="Fit a Hammerstein model to a record. Accepted files: CSV with a header row naming "
                    "the columns (time t/time, input u/input/vir, output y/output/qm by default; # lines "
                    "are comments), CSV without a header (t,u,y or u,y with --dt), MAT or NPZ files with "
                    "one vector per variable.")
    ide.add_argument("--data", required=True, help="CSV, MAT or NPZ file")
    ide.add_argument("--input", help="input column/variable name")
    ide.add_argument("--output", help="output column/variable name")
    ide.add_argument("--time", help="time column/variable name")
    ide.add_argument("--dt", type=float, help="sampling interval when the file has no time column")
    ide.add_argument("--structure", choices=["trs", "emps"], help="a case study's structure (and x0)")
    ide.add_argument("--orders", type=int, nargs=2, metavar=("L", "M"),
                     help="numerator and denominator degrees of H(p)")
    ide.add_argument("--nonlinearity", help="tanh, coulomb, polynomial, saturation, deadzone, piecewise_linear")
    ide.add_argument("--degree", type=int, help="polynomial degree")
    ide.add_argument("--breakpoints", type=float, nargs="+", help="piecewise-linear breakpoints")
    ide.add_argument("--fix", nargs="+", metavar="NAME=VALUE", help="fixed coefficients, e.g. a0=0")
    ide.add_argument("--free-gain", action="store_true", help="do not fix the leading numerator coefficient to 1")
    ide.add_argument("--method", default="nspsa", help="nspsa (default), nlspsa, spsa, amvo-sca, lm, nelder-mead, ...")
    ide.add_argument("--x0", type=float, nargs="+", help="initial parameter vector beta")
    ide.add_argument("--bounds", type=float, nargs="+", metavar="LO HI", help="low high for each parameter")
    ide.add_argument("--maxfev", type=int, help="evaluation budget (default 2501 unless --maxiter)")
    ide.add_argument("--maxiter", type=int, help="iteration limit")
    ide.add_argument("--seed", type=int, default=0)
    ide.add_argument("--gain-a", type=float, nargs="+", metavar="A", help="a [A [alpha]] of a(k) = a/(k+A)^alpha")
    ide.add_argument("--gain-c", type=float, nargs="+", metavar="C", help="c [gamma] of c(k) = c/(k+1)^gamma")
    ide.add_argument("--norm-limit", type=float, help="NL-SPSA's delta")
    ide.add_argument("--pop-size", type=int, help="AMVO-SCA population")
    ide.add_argument("--out", help="write the fitted model as JSON")
    ide.add_argument("--plot", help="write a time-response figure (PNG/SVG/PDF)")
    ide.set_defaults(func=_cmd_identify)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (HammersteinError, FileNotFoundError, OSError) as exc:
        message = str(exc).strip().splitlines()
        print(f"hammerstein-ctrl: error: {message[0] if message else repr(exc)}", file=sys.stderr)
        for line in message[1:]:
            print(f"  {line}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hammerstein-ctrl: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
