"""The ``hammerstein-ctrl tune`` sub-command: PID tuning of a saved model.

``hammerstein-ctrl tune model.json --rule simc|imc|nspsa|auto [--u-limit LO HI]
[--reference step|FILE]`` prints the gains, the margins of the linearised loop
and the step figures of the nonlinear loop, and writes a figure.  ``FILE`` is
a text file of reference samples (one per line, at ``--dt``).

Wire it into a parser with :func:`add_tune_parser`.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from ..exceptions import DataError

__all__ = ["add_tune_parser"]


def add_tune_parser(subparsers):
    """Add the ``tune`` sub-command to an ``argparse`` sub-parsers object."""
    from ..design._pid import CRITERIA, DEFAULT_MAXFEV, RULES

    tune = subparsers.add_parser(
        "tune", help="tune a verified PID for a saved model (robust, SIMC, IMC or N-SPSA on the nonlinear loop)",
        description="Tune a PID for a model saved by model.save() or identify --out, verify it (stability, "
                    "margins, Ms, a step of the nonlinear loop), print the gains and the verification, and write a "
                    "figure of the closed loop.  Exits 1 when the controller fails its verification.")
    tune.add_argument("model", help="model or identification-result JSON file")
    tune.add_argument("--rule", default="robust", choices=RULES, help="tuning rule (default robust)")
    tune.add_argument("--kind", default="pid", choices=["pid", "pi"], help="controller structure (default pid)")
    tune.add_argument("--max-sensitivity", type=float, help="robustness target Ms (default 1.6)")
    tune.add_argument("--phase-margin", type=float, help="or a phase margin target in degrees")
    tune.add_argument("--y0", type=float, help="operating point: the output to regulate around")
    tune.add_argument("--u-limit", type=float, nargs=2, metavar=("LO", "HI"), help="actuator limits")
    tune.add_argument("--reference", default="step", help="'step' (default) or a file of reference samples")
    tune.add_argument("--step", type=float, help="step of the reference from the operating point (default: one the "
                      "actuator can make)")
    tune.add_argument("--dt", type=float, help="controller sampling interval (default: the data's, if known)")
    tune.add_argument("--u0", type=float, help="operating point: the input at rest (default: 0, or where an "
                      "integrating plant rests)")
    tune.add_argument("--tau-c", type=float, help="SIMC tau_c / IMC lambda")
    tune.add_argument("--t-final", type=float, help="horizon of a step")
    tune.add_argument("--criterion", default="itae", choices=CRITERIA)
    tune.add_argument("--maxfev", type=int, default=DEFAULT_MAXFEV, help="budget of model-based tuning")
    tune.add_argument("--seed", type=int, default=0)
    tune.add_argument("--plot", help="figure path (default MODEL_pid_RULE.png beside the model)")
    tune.set_defaults(func=_cmd_tune)
    return tune


def _model_and_dt(path: str, dt):
    from ..io._results import SavedResult, load_saved

    saved = load_saved(path)
    if isinstance(saved, SavedResult):
        return saved.model, dt if dt is not None else saved.data.get("dt")
    return saved, dt


def _reference(arg: str):
    if arg == "step":
        return "step"
    from .._safe_io import MAX_INPUT_BYTES, check_input

    check_input(arg, limit=MAX_INPUT_BYTES, what="reference file")     # a regular file, not a FIFO or device
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")      # numpy's "input contained no data": the check below says it
            values = np.loadtxt(arg, ndmin=1)
    except (ValueError, UnicodeDecodeError) as exc:
        raise DataError(f"--reference {arg}: not a file of numbers ({str(exc)[:80]})") from None
    if values.size == 0:
        raise DataError(f"--reference {arg}: the file holds no samples")
    if values.ndim != 1:
        raise DataError(f"--reference {arg}: one column of reference samples expected, got shape {values.shape}")
    return values


def _cmd_tune(args) -> int:
    from ..design._tune import tune_pid
    from ..design._loops import analyze_loop, loop_figure

    model, dt = _model_and_dt(args.model, args.dt)
    reference = _reference(args.reference)
    limits = tuple(args.u_limit) if args.u_limit else None
    kwargs = dict(u0=args.u0, y0=args.y0, dt=dt, u_limit=limits, reference=reference, step=args.step,
                  t_final=args.t_final, kind=args.kind, max_sensitivity=args.max_sensitivity,
                  phase_margin=args.phase_margin)
    pid = tune_pid(model, args.rule, tau_c=args.tau_c, criterion=args.criterion, maxfev=args.maxfev,
                   seed=args.seed, **kwargs)
    rep = analyze_loop(model, pid, u_limit=limits, reference=reference, step=args.step, dt=pid.dt,
                       t_final=args.t_final)
    print(f"{args.rule} PID for {model!r}")
    print(pid.summary())
    print(f"  sampled at dt = {dt:g} s ({'--dt' if args.dt is not None else 'the record of the fit: --dt to change'}); "
          "the verdict includes the digital loop" if dt is not None
          else "  continuous design (no sampling interval known: --dt for a digital controller)")
    print(f"  (parallel form kp + ki/s + kd s/(tf s + 1), output added to u0 = {pid.u0:.6g}); "
          f"IAE {rep['iae']:.4g}, ISE {rep['ise']:.4g}, ITAE {rep['itae']:.4g}")
    plot = Path(args.plot) if args.plot else Path(args.model).with_name(f"{Path(args.model).stem}_pid_{args.rule}.png")
    import matplotlib

    if "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    from .._safe_io import save_figure

    fig = loop_figure({args.rule: rep}, u_limit=limits)
    save_figure(fig, plot, dpi=120)
    print(f"figure written to {plot}")
    return 0 if pid.success else 1
