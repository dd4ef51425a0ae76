"""The ``hammerstein-ctrl`` command line.

Sub-commands: ``reproduce`` (the
paper's comparison tables and figures), ``identify`` (fit a user's record),
``select`` (rank candidate structures on it), ``tune`` (a PID for a saved model).
Every argument and output path is checked before any work starts.  Every
failure exits with status 2 and one line ``hammerstein-ctrl: error: ...`` on
stderr; ``--debug`` shows the traceback instead (for bug reports).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import traceback
import warnings
from pathlib import Path

from ..exceptions import HammersteinError, IdentificationWarning

__all__ = ["main", "build_parser", "EXIT_ERROR", "PROG"]

#: Description of ``identify``.
IDENTIFY_DESCRIPTION = ("Fit a Hammerstein (--nonlinearity), Wiener (--output-nonlinearity) or "
                        "Hammerstein-Wiener model (both) to a record. Accepted files: CSV with a header row naming "
                    "the columns (time t/time, input u/input, output y/output by default; # lines "
                    "are comments), CSV without a header (t,u,y or u,y with --dt), MAT or NPZ files with "
                    "one vector per variable.")
#: One-line help of ``tune`` (its options come from :mod:`hammerstein_ctrl.cli._tune`).
TUNE_HELP = "tune a PID for a saved model (SIMC, IMC or N-SPSA on the nonlinear loop)"
#: One-line help of ``select`` (its options come from :mod:`hammerstein_ctrl.cli._select`).
SELECT_HELP = "rank candidate structures (orders x nonlinearities x kinds) by AIC, BIC, FPE or validation fit"
#: Program name used in messages.
PROG = "hammerstein-ctrl"
#: Exit status of every failure (argparse's convention).
EXIT_ERROR = 2
#: Exit status after Ctrl-C.
EXIT_INTERRUPTED = 130
#: Numbers accepted by ``--gain-a`` (a [A [alpha]]) and ``--gain-c`` (c [gamma]).
GAIN_A_ARGS, GAIN_C_ARGS = 3, 2


class _Parser(argparse.ArgumentParser):
    """argparse with the one-line error of the rest of the CLI (no usage block)."""

    def error(self, message):
        self.exit(EXIT_ERROR, f"{PROG}: error: {message} (see {self.prog} --help)\n")


def _count(least: int):
    """argparse type: an integer >= ``least``."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < least:
            kind = {0: "a non-negative integer", 1: "a positive integer"}.get(least, f"an integer >= {least}")
            raise argparse.ArgumentTypeError(f"must be {kind}, got {text!r}")
        return value
    return parse


def _number(*, positive: bool = False, allow_inf: bool = False):
    """argparse type: a float that is not NaN (finite unless ``allow_inf``; > 0 if ``positive``)."""
    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid float value: {text!r}") from None
        if math.isnan(value) or (math.isinf(value) and not allow_inf) or (positive and not value > 0):
            raise argparse.ArgumentTypeError(
                f"must be a {'positive ' if positive else ''}{'' if allow_inf else 'finite '}number, got {text!r}")
        return value
    return parse


def _delay_value(text):
    """argparse type of --delay: 'estimate', or a dead time in seconds (a finite number >= 0)."""
    if text.strip().lower() == "estimate":
        return "estimate"
    value = _number()(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a dead time >= 0 in seconds, or 'estimate', got {text!r}")
    return value


def _writable_file(option: str, path: str) -> Path:
    """``path`` as a Path, after checking that a file can be written there (never through a link)."""
    from .._safe_io import UnsafePathError, check_output

    p = Path(path)
    if p.is_dir() and not p.is_symlink():
        raise HammersteinError(f"{option} {path}: is a directory, give a file name")
    try:
        check_output(p)
    except UnsafePathError as exc:
        raise HammersteinError(f"{option} {exc}") from None
    parent = p.parent if str(p.parent) else Path(".")
    if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise HammersteinError(f"{option} {path}: not writable")
    return p


def _check_plot_path(path: str) -> Path:
    from matplotlib.backend_bases import FigureCanvasBase

    p = _writable_file("--plot", path)
    formats = FigureCanvasBase.get_supported_filetypes()
    if p.suffix.lower().lstrip(".") not in formats:
        raise HammersteinError(f"--plot {path}: unknown figure format {p.suffix or '(none)'!r}; "
                               f"use one of {', '.join('.' + f for f in sorted(formats))}")
    return p


def _output_dir(path: str) -> Path:
    """The output folder (created; a link the user named is resolved once: everything is written inside it)."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise HammersteinError(f"--out {path}: exists and is not a directory")
    if out.is_symlink() and not out.exists():
        raise HammersteinError(f"--out {path}: is a dangling symbolic link")
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK):
        raise HammersteinError(f"--out {path}: directory not writable")
    return out.resolve()


DEFAULT_METHODS = ["spsa", "nlspsa", "amvo-sca", "nspsa", "lm"]


def _use_agg():
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")


def _cmd_reproduce(args) -> int:
    import json
    from pathlib import Path

    from ..paper import presets
    from ..plotting._studies import study_figures
    from ..blocks._json import json_safe
    from ..paper.report import best_models
    from .._safe_io import write_text
    from ..paper.study import run_study

    kwargs = {"path": args.data} if (args.case == "emps" and args.data) else {}
    if args.case == "trs" and args.data:
        raise HammersteinError("--data applies to the EMPS case only (the TRS reconstruction is bundled)")
    if args.data and not Path(args.data).exists():
        raise HammersteinError(f"--data {args.data}: no such file or folder")
    methods = _unique_methods(args.methods)
    case = presets.get(args.case, **kwargs)                # the data first: a bad --data creates no folder
    out = _output_dir(args.out or f"results/{args.case}")
    _check_outputs(out, figures=not args.no_figures)
    progress = sys.stderr.isatty() if args.progress is None else args.progress
    study = run_study(case, methods, trials=args.trials, seed=args.seed, jobs=args.jobs,
                      results_path=out / "results.jsonl", progress=progress)
    print(study.table("text"))
    write_text(out / "summary.md", study.table("markdown"), root=out)
    write_text(out / "summary.csv", study.table("csv"), root=out)
    study.to_json(out / "summary.json")

    validation = case.validation() if case.validation is not None else None
    best = best_models(study, validation)
    write_text(out / "best_models.json", json.dumps(json_safe(best), indent=2, default=str, allow_nan=False),
               root=out)
    if validation is not None:
        print(f"\nBest models on the validation record ({validation.name}):")
        for m, e in best.items():
            v = e.get("validation")
            print(f"  {m:<9} " + ("diverged" if v is None else
                                  f"fit {v['fit_percent']:6.2f} %  RMSE {v['rmse']:.4g} {validation.output_unit}"))
    _print_cost_comparison(case, study, out)
    if not args.no_figures:
        _use_agg()
        formats = ("png", "svg") if args.svg else ("png",)
        with warnings.catch_warnings():  # empty legends when every method diverged
            warnings.filterwarnings("ignore", message="No artists with labels")
            paths = study_figures(study, out / "figures", formats=formats, validation=validation)
        print(f"figures: {len(paths)} files in {out / 'figures'}")
    print(f"results: {out}/results.jsonl, summary.json, summary.md, summary.csv, best_models.json")
    return 0


#: Every file ``reproduce`` writes in its output folder (figures go to ``figures/``).
REPRODUCE_OUTPUTS = ("results.jsonl", "results.jsonl.lock", "results.rejected.jsonl", "summary.md", "summary.csv",
                     "summary.json", "best_models.json")


def _check_outputs(out: Path, *, figures: bool) -> None:
    """Refuse, before any work, an output name in ``out`` that is a link, a folder or resolves outside it."""
    from .._safe_io import UnsafePathError, check_output

    try:
        for name in REPRODUCE_OUTPUTS:
            check_output(out / name, root=out)
        folder = out / "figures"
        if figures and (folder.is_symlink() or (folder.exists() and not folder.is_dir())):
            raise UnsafePathError(f"{folder} is a symbolic link or not a folder: refusing to write figures there")
    except UnsafePathError as exc:
        raise HammersteinError(f"--out: {exc}") from None


def _unique_methods(names) -> list[str]:
    """Canonical method names, each once; a note on stderr for the repeats dropped."""
    from ..optimize import canonical_method

    methods = [canonical_method(m) for m in names]
    unique = list(dict.fromkeys(methods))
    if len(unique) < len(methods):
        print(f"{PROG}: note: --methods names {len(methods)} methods but only {len(unique)} different "
              f"ones ({' '.join(unique)}); each is run once", file=sys.stderr)
    return unique


def _print_cost_comparison(case, study, out):
    """Evaluations and time per evaluation, against control.forced_response on the best model."""
    import numpy as np

    from ..paper.report import forced_response_cost, time_call

    nfev = sum(r["nfev"] for r in study.records)
    ours = sum(r["elapsed"] for r in study.records) / max(nfev, 1)
    reused = (f" ({study.resumed} trials reused from {out / 'results.jsonl'})" if study.resumed else "")
    print(f"\n{len(study.records)} trials, {nfev} evaluations: {study.elapsed:.1f} s wall here{reused}")
    # time python-control on a representative model: the best one found (at the TRS initial point
    # g(u) = 0 and forced_response would take its zero-input shortcut)
    finite = [r for r in study.records if np.isfinite(float(r["fun"]))]
    if not finite:
        print("no trial ended with a finite J: no model to time control.forced_response on")
        return
    model = case.structure.model(np.array(min(finite, key=lambda r: float(r["fun"]))["x"], dtype=float))
    reference = time_call(lambda: forced_response_cost(case, model), repeat=3)
    print(f"per evaluation: ours {ours * 1e6:.0f} us (in the trials) vs control.forced_response "
          f"{reference * 1e3:.1f} ms (measured now): {reference / ours:.0f}x; the same evaluations through "
          f"forced_response would take ~{nfev * reference / 3600:.2f} h")


def _structure_from_args(args):
    from ..paper import presets
    from ..blocks._families import nonlinearity_from_name
    from ..blocks._structure import HammersteinStructure, HammersteinWienerStructure, LinearStructure, WienerStructure

    if args.structure:
        extra = [flag for flag, given in (("--orders", args.orders), ("--nonlinearity", args.nonlinearity),
                                          ("--output-nonlinearity", args.output_nonlinearity),
                                          ("--fix", args.fix), ("--degree", args.degree is not None),
                                          ("--breakpoints", args.breakpoints), ("--free-gain", args.free_gain),
                                          ("--delay", args.delay is not None), ("--feedback", args.feedback),
                                          ("--second-orders", args.second_orders),
                                          ("--substeps", args.substeps is not None))
                 if given]
        if extra:
            raise HammersteinError(f"{', '.join(extra)} cannot be combined with --structure {args.structure} "
                                   "(use --orders/--nonlinearity to build your own structure)")
        if args.structure == "emps-lure":
            from ..paper.emps_loop import emps_lure_structure

            return emps_lure_structure(), None
        return presets.STRUCTURES[args.structure](), presets.X0[args.structure]
    if not (args.orders and (args.nonlinearity or args.output_nonlinearity)):
        raise HammersteinError("give --structure trs|emps, or --orders L M and --nonlinearity NAME "
                               "and/or --output-nonlinearity NAME")
    fixed = {}
    for item in args.fix or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise HammersteinError(f"--fix expects NAME=VALUE, got {item!r}")
        try:
            fixed[name.strip()] = float(value)
        except ValueError:
            raise HammersteinError(f"--fix {item!r}: {value!r} is not a number") from None
    if args.feedback:
        return _lure_structure_from_args(args, fixed), None
    if args.second_orders:
        return _wh_structure_from_args(args, fixed), None
    if args.substeps is not None:
        raise HammersteinError("--substeps applies to a Wiener-Hammerstein model (--second-orders) or a Lur'e loop "
                               "(--feedback)")
    linear = LinearStructure(args.orders[0], args.orders[1], monic_numerator=not args.free_gain, fixed=fixed,
                             delay=args.delay)
    g = h = None
    if args.nonlinearity:
        g = nonlinearity_from_name(args.nonlinearity, **_family_options(args.degree, args.breakpoints))
    if args.output_nonlinearity:
        h = nonlinearity_from_name(args.output_nonlinearity,
                                   **_family_options(args.output_degree, args.output_breakpoints))
    if g is not None and h is not None:
        return HammersteinWienerStructure(linear, g, h), None
    return (HammersteinStructure(linear, g) if h is None else WienerStructure(linear, h)), None


def _lure_structure_from_args(args, fixed):
    """``--feedback velocity|output`` with ``--orders`` and ``--nonlinearity friction|coulomb``: a Lur'e loop."""
    from ..blocks._lure import LureStructure
    from ..blocks._families import nonlinearity_from_name
    from ..blocks._structure import LinearStructure

    extra = [flag for flag, given in (("--output-nonlinearity", args.output_nonlinearity),
                                      ("--delay", args.delay is not None), ("--free-gain", args.free_gain),
                                      ("--second-orders", args.second_orders))
             if given]
    if extra:
        raise HammersteinError(f"{', '.join(extra)} cannot be combined with --feedback (a Lur'e loop)")
    if not args.nonlinearity:
        raise HammersteinError("--feedback needs --nonlinearity NAME (the map fed back)")
    linear = LinearStructure(args.orders[0], args.orders[1], monic_numerator=False, fixed=fixed)
    nl = nonlinearity_from_name(args.nonlinearity, **_family_options(args.degree, args.breakpoints))
    return LureStructure(linear, nl, feedback=args.feedback,
                         substeps=1 if args.substeps is None else args.substeps)


def _wh_structure_from_args(args, fixed):
    """``--orders`` (G1), ``--nonlinearity`` (the map) and ``--second-orders`` (G2): a Wiener-Hammerstein model."""
    from ..blocks._families import nonlinearity_from_name
    from ..blocks._wiener_hammerstein import WienerHammersteinStructure

    extra = [flag for flag, given in (("--output-nonlinearity", args.output_nonlinearity),
                                      ("--delay estimate", isinstance(args.delay, str)),
                                      ("--free-gain", args.free_gain), ("--fix", fixed)) if given]
    if extra:
        raise HammersteinError(f"{', '.join(extra)} cannot be combined with --second-orders (a Wiener-Hammerstein "
                               "model: both blocks of static gain 1, the gain in the map; a fixed dead time only)")
    if not args.nonlinearity:
        raise HammersteinError("--second-orders needs --nonlinearity NAME (the map between the blocks)")
    nl = nonlinearity_from_name(args.nonlinearity, **_family_options(args.degree, args.breakpoints))
    return WienerHammersteinStructure(tuple(args.orders), nl, tuple(args.second_orders),
                                      substeps=1 if args.substeps is None else args.substeps,
                                      delay=args.delay or 0.0)


def _family_options(degree, breakpoints) -> dict:
    """Keyword arguments of a nonlinearity family from --degree/--breakpoints style options."""
    options = {}
    if degree is not None:
        options["degree"] = degree
    if breakpoints is not None:
        options["breakpoints"] = breakpoints
    return options


def _cmd_identify(args) -> int:
    from ..fit._identify import AUTO, identify
    from ..optimize import canonical_method
    from ..io._results import save_result
    from ..data._records import record_from_args

    auto = args.method.strip().lower() == AUTO
    if not auto:
        canonical_method(args.method)
    options = _gain_options(args)
    plot = _check_plot_path(args.plot) if args.plot else None
    out = _writable_file("--out", args.out) if args.out else None
    if str(args.structure).startswith("emps") and not (args.input or args.inputs or args.output or args.outputs):
        from ..paper.datasets import EMPS_COLUMNS       # the case study's file: its own column names

        args.input, args.output = EMPS_COLUMNS["input"], EMPS_COLUMNS["output"]
    data = record_from_args(args)
    structure, default_x0 = _structure_from_args(args) if data.is_siso else _mimo_structure_from_args(args, data)
    data.check_identifiable(structure.n_params)
    x0 = args.x0 if args.x0 is not None else (None if auto else default_x0)
    bounds = None
    if args.bounds is not None:
        if len(args.bounds) != 2 * structure.n_params:
            raise HammersteinError(f"--bounds needs {2 * structure.n_params} numbers (low high per parameter "
                                   f"{list(structure.param_names)}), got {len(args.bounds)}")
        bounds = list(zip(args.bounds[0::2], args.bounds[1::2]))
    maxfev = args.maxfev if args.maxfev is not None else (None if args.maxiter or auto else 2501)
    with warnings.catch_warnings():     # the summary lists the verdicts' warnings
        warnings.simplefilter("ignore", IdentificationWarning)
        result = identify(data, structure, method=args.method, x0=x0, maxfev=maxfev, maxiter=args.maxiter,
                          seed=args.seed, options=options or None, bounds=bounds, offset=args.offset or None,
                          initial_state=args.initial_state, allow_unstable=args.allow_unstable)
    print(result.summary())
    if result.model is None:  # nothing finite to save or draw; the summary says why
        return 1
    if out is not None:
        save_result(result, out)
        print(f"result written to {out}")
    if plot is not None:
        _use_agg()
        from ..plotting._figures import time_response

        from .._safe_io import save_figure

        fig = time_response(data, {result.method: result.model}) if data.is_siso else result.compare()
        save_figure(fig, plot, dpi=120)
        print(f"figure written to {plot}")
    return 0 if result.success else 1


def _mimo_structure_from_args(args, data):
    """A MIMO structure for a record with several channels: --orders for every element, --nonlinearity on every
    input, --output-nonlinearity on every output."""
    from ..blocks._mimo import mimo_structure
    from ..blocks._families import nonlinearity_from_name
    from ..blocks._structure import LinearStructure

    unsupported = [flag for flag, given in (("--structure", args.structure), ("--fix", args.fix),
                                            ("--free-gain", args.free_gain), ("--feedback", args.feedback),
                                            ("--initial-state estimate", args.initial_state == "estimate"))
                   if given]
    if unsupported:
        raise HammersteinError(f"{', '.join(unsupported)} cannot be used with a record of {data.n_inputs} inputs and "
                               f"{data.n_outputs} outputs (a MIMO fit takes --orders, --nonlinearity, "
                               "--output-nonlinearity, --delay and --offset)")
    if not (args.orders and (args.nonlinearity or args.output_nonlinearity)):
        raise HammersteinError("a MIMO record needs --orders L M and --nonlinearity NAME (every input) and/or "
                               "--output-nonlinearity NAME (every output)")
    g = h = None
    if args.nonlinearity:
        g = [nonlinearity_from_name(args.nonlinearity, **_family_options(args.degree, args.breakpoints))
             for _ in range(data.n_inputs)]
    if args.output_nonlinearity:
        h = [nonlinearity_from_name(args.output_nonlinearity,
                                    **_family_options(args.output_degree, args.output_breakpoints))
             for _ in range(data.n_outputs)]
    return mimo_structure(LinearStructure(args.orders[0], args.orders[1]), g, h, n_inputs=data.n_inputs,
                          n_outputs=data.n_outputs, delay=args.delay), None


def _gain_options(args) -> dict:
    """Optimiser options from --gain-a, --gain-c, --norm-limit, --pop-size (checked before any work)."""
    from ..optimize import PerturbationGain, StepGain

    options = {}
    for flag, given, cls, most in (("--gain-a", args.gain_a, StepGain, GAIN_A_ARGS),
                                   ("--gain-c", args.gain_c, PerturbationGain, GAIN_C_ARGS)):
        if given is not None:
            if len(given) > most:
                raise HammersteinError(f"{flag} takes at most {most} numbers, got {len(given)}")
            options[flag[-1]] = cls(*given)
    if args.norm_limit is not None:
        options["norm_limit"] = args.norm_limit
    if args.pop_size is not None:
        options["pop_size"] = args.pop_size
    return options


def _add_identify_arguments(ide):
    from ..data._records import add_record_arguments

    add_record_arguments(ide)
    ide.add_argument("--structure", choices=["trs", "emps", "emps-lure"],
                     help="a case study's structure (and x0); emps-lure: the EMPS as a mass with friction fed back "
                          "on its velocity")
    ide.add_argument("--orders", type=_count(0), nargs=2, metavar=("L", "M"),
                     help="numerator and denominator degrees of H(p)")
    ide.add_argument("--nonlinearity", help="tanh, coulomb, polynomial, saturation, deadzone, piecewise_linear, "
                                            "sigmoid, friction")
    ide.add_argument("--feedback", choices=["output", "velocity", "acceleration"],
                     help="a Lur'e loop: the nonlinearity fed back on the output or a derivative of it; the gain in "
                          "H(p); friction or coulomb need M - L = 1 (output) or 2 (velocity), any other map M - L "
                          "above the derivative")
    ide.add_argument("--second-orders", type=_count(0), nargs=2, metavar=("L", "M"),
                     help="a Wiener-Hammerstein model: the degrees of G2(p); --orders are G1's and --nonlinearity "
                          "the map between them (both blocks of static gain 1)")
    ide.add_argument("--substeps", type=_count(1),
                     help="instants per sample at which a Wiener-Hammerstein middle signal or a Lur'e map (not "
                          "friction) is computed (default 1)")
    ide.add_argument("--degree", type=_count(0), help="polynomial degree")
    ide.add_argument("--breakpoints", type=_number(), nargs="+", help="piecewise-linear breakpoints")
    ide.add_argument("--output-nonlinearity", metavar="NAME",
                     help="a static output nonlinearity after H: a Wiener model, or Hammerstein-Wiener "
                          "with --nonlinearity")
    ide.add_argument("--output-degree", type=_count(0), help="polynomial degree of the output nonlinearity")
    ide.add_argument("--output-breakpoints", type=_number(), nargs="+",
                     help="piecewise-linear breakpoints of the output nonlinearity")
    ide.add_argument("--fix", nargs="+", metavar="NAME=VALUE", help="fixed coefficients, e.g. a0=0")
    ide.add_argument("--free-gain", action="store_true", help="do not fix the leading numerator coefficient to 1")
    ide.add_argument("--delay", metavar="SECONDS|estimate", type=_delay_value,
                     help="input dead time of the linear block: fixed in seconds, or 'estimate' (a parameter)")
    ide.add_argument("--method", default="auto",
                     help="auto (default: needs no x0 or tuning), nspsa, nlspsa, spsa, amvo-sca, lm, nelder-mead, ...")
    ide.add_argument("--x0", type=_number(), nargs="+",
                     help="initial parameter vector beta (optional with --method auto)")
    ide.add_argument("--offset", action="store_true", help="estimate a constant output offset y0")
    ide.add_argument("--initial-state", choices=["zero", "estimate"], default=None,
                     help="start H from rest (default) or estimate its initial state")
    ide.add_argument("--allow-unstable", action="store_true", help="accept an unstable model as a success")
    ide.add_argument("--bounds", type=_number(allow_inf=True), nargs="+", metavar="LO HI",
                     help="low high for each parameter")
    ide.add_argument("--maxfev", type=_count(1),
                     help="evaluation budget (default: config auto.maxfev, 3000, for auto; auto.wh_maxfev, 10000, "
                          "for a Wiener-Hammerstein model; 2501 for the others unless --maxiter)")
    ide.add_argument("--maxiter", type=_count(1), help="iteration limit")
    ide.add_argument("--seed", type=_count(0), default=0, help="seed of the stochastic methods (>= 0)")
    ide.add_argument("--gain-a", type=_number(), nargs="+", metavar="A", help="a [A [alpha]] of a(k) = a/(k+A)^alpha")
    ide.add_argument("--gain-c", type=_number(), nargs="+", metavar="C", help="c [gamma] of c(k) = c/(k+1)^gamma")
    ide.add_argument("--norm-limit", type=_number(positive=True), help="NL-SPSA's delta")
    ide.add_argument("--pop-size", type=_count(2), help="AMVO-SCA population")
    ide.add_argument("--out", help="write the result as versioned JSON (hammerstein_ctrl.load_result reads it)")
    ide.add_argument("--plot", help="write a time-response figure (PNG/SVG/PDF)")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command-line parser.

    With ``command`` given, only that sub-command gets its full options (the
    ``identify`` and ``tune`` options need the numeric libraries): the others
    are listed by name, which keeps ``hammerstein-ctrl --help`` instant.
    """
    parser = _Parser(
        prog="hammerstein-ctrl",
        description="Continuous-time Hammerstein identification (N-SPSA and rivals) on python-control.",
    )
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of a failure (for bug reports); accepted anywhere")
    sub = parser.add_subparsers(dest="command", required=True)

    rep = sub.add_parser("reproduce", help="run the paper's comparison (Table 3 / Table 7) and write figures")
    rep.add_argument("case", choices=["trs", "emps"])
    rep.add_argument("--trials", type=_count(1), default=25, help="independent trials per method (default 25)")
    rep.add_argument("--methods", nargs="+", default=DEFAULT_METHODS,
                     help=f"methods to compare (default: {' '.join(DEFAULT_METHODS)})")
    rep.add_argument("--seed", type=_count(0), default=0, help="study seed (trial i uses a seed derived from it)")
    rep.add_argument("--out", help="output directory (default results/CASE); rerunning resumes")
    rep.add_argument("--jobs", type=_count(1), default=None, help="worker processes (default: all cores)")
    rep.add_argument("--data", help="folder or file of the EMPS data (default: $HAMMERSTEIN_CTRL_DATA)")
    rep.add_argument("--svg", action="store_true", help="also write SVG figures")
    rep.add_argument("--no-figures", action="store_true", help="skip the figures")
    rep.add_argument("--progress", dest="progress", action="store_true", default=None,
                     help="show a progress bar (default: when stderr is a terminal)")
    rep.add_argument("--no-progress", dest="progress", action="store_false")
    rep.set_defaults(func=_cmd_reproduce)

    ide = sub.add_parser(
        "identify", help="fit a Hammerstein, Wiener or Hammerstein-Wiener model to your own record",
        description=IDENTIFY_DESCRIPTION)
    if command in (None, "identify"):
        _add_identify_arguments(ide)
    ide.set_defaults(func=_cmd_identify)
    if command in (None, "tune"):
        from ._tune import add_tune_parser

        add_tune_parser(sub)
    else:
        sub.add_parser("tune", help=TUNE_HELP)
    if command in (None, "select"):
        from ._select import add_select_parser

        add_select_parser(sub, _count, _number, _writable_file)
    else:
        sub.add_parser("select", help=SELECT_HELP)
    return parser


def _one_line(exc: BaseException) -> str:
    """The error message of ``exc`` on one line; the exception type for anything unexpected."""
    text = " ".join(line.strip() for line in str(exc).strip().splitlines() if line.strip())
    if isinstance(exc, (HammersteinError, OSError)):
        return text or type(exc).__name__
    return f"{type(exc).__name__}: {text} (an unexpected failure: rerun with --debug for the traceback)"


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {' '.join(str(message).split())}", file=sys.stderr)


def main(argv=None) -> int:
    """Run the command line; returns the exit status (0, 1 for a fit that failed, 2 for errors)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser(next((a for a in argv if not a.startswith("-")), ""))
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:  # --help, --version, or an argument error already printed as one line
        return stop.code if isinstance(stop.code, int) else EXIT_ERROR
    try:
        with warnings.catch_warnings():
            if not debug:
                warnings.showwarning = _show_warning
            return args.func(args)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # every failure: one line and exit 2 (the traceback with --debug)
        if debug:
            traceback.print_exc()
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
