"""A tuned controller in its loop: the closed loop as a python-control system, its analysis and figure."""

from __future__ import annotations

import math
import numpy as np
from ..exceptions import ParameterError
from ..simulate._loop import check_limits, sampled_loop_iosys, saturation_iosys, simulate_loops
from ._operating_point import operating_point, small_signal
from ._robust import loop_figures
from ._pid import CRITERIA, PIDResult, _criterion, _overshoot, _reference, _step_figures, _tuning_grid
from ._approximate import _rational, _siso_model

__all__ = ["closed_loop", "analyze_loop", "loop_figure"]


# ---------------------------------------------------------------------------
# loops and their analysis
# ---------------------------------------------------------------------------
def _continuous_pid_iosys(pid: PIDResult):
    """Continuous PID with back-calculation: inputs ``e, u``, output ``uc`` (the operating point's ``u0`` added);
    states ``I, xf``."""
    import control

    kp, ki, kd, tf, kt = pid.gains
    bias = pid.u0

    def parts(x, e):
        deriv = kd * (e - x[1]) / tf if kd != 0 else 0.0
        return kp * e + x[0] + deriv + bias

    def rhs(t, x, u, p):
        e, act = u[0], u[1]
        return np.array([ki * e + kt * (act - parts(x, e)), (e - x[1]) / tf if kd != 0 else 0.0])

    return control.nlsys(rhs, lambda t, x, u, p: np.array([parts(x, u[0])]), inputs=["e", "u"],
                         outputs=["uc"], states=["I", "xf"], name="pid")


def closed_loop(model, pid: PIDResult, u_limit=None, *, dt: float | None = None, name: str = "loop"):
    """The PID loop around the nonlinear plant as a ``control.interconnect``, at rest at the operating point.

    Error junction ``e = r - y``, the PID (its output plus the operating
    point's input ``u0``) with back-calculation anti-windup (it reads the
    actuator's output ``u``), the actuator limit ``u = clip(uc, lo, hi)`` and
    the plant, whose initial state is the operating point's.  With ``dt`` the
    loop is the sampled one of :mod:`hammerstein_ctrl.simulate._loop` (plant
    ``to_iosys(dt, intersample="zoh")``, the PID discretised); without, it is
    continuous (plant ``to_iosys()``).  Input ``r`` (absolute, e.g.
    ``y0 + step``); outputs ``y`` and ``u``; from zero initial conditions the
    loop is at the operating point.  A model with a dead time enters as its
    Pade form (:meth:`~hammerstein_ctrl.blocks.BlockModel.without_delay`), the
    plant :func:`tune_pid` designed and verified the loop on.

    Examples
    --------
    >>> import control as ct
    >>> from hammerstein_ctrl import HammersteinModel, Coulomb, tune_pid
    >>> m = HammersteinModel(ct.tf([1], [1, 3.14, 0]), Coulomb(), [0.54, -0.4, 0.045])
    >>> loop = closed_loop(m, tune_pid(m, "simc", tau_c=0.2), u_limit=(-4, 4))
    >>> loop.input_labels, loop.output_labels, loop.nstates
    (['r'], ['y', 'u'], 4)
    """
    model = _siso_model(model, "closed_loop")
    import control

    from ._operating_point import rest_model

    if not isinstance(pid, PIDResult):
        raise ParameterError(f"pid must be a PIDResult (from tune_pid), got {type(pid).__name__}")
    model = _rational(model)
    plant_model = rest_model(model, pid.operating_point) if pid.operating_point is not None else model
    if dt is not None:
        return sampled_loop_iosys(plant_model, pid.gains, dt, u_limit=u_limit, bias=pid.u0, name=name)
    check_limits(u_limit)
    err = control.summing_junction(inputs=["r", "-y"], output="e", name="error")
    plant = plant_model.to_iosys(name="plant", inputs="u", outputs="y")
    return control.interconnect([err, _continuous_pid_iosys(pid), saturation_iosys(u_limit), plant],
                                inputs=["r"], outputs=["y", "u"], name=name)


def analyze_loop(model, pid: PIDResult, *, u_limit=None, reference="step", step: float | None = None,
                 dt: float | None = None, t_final: float | None = None) -> dict:
    """Margins, ``Ms``, ``Mt`` and poles of the linearised loop; step figures and costs of the nonlinear one.

    The nonlinear loop is the sampled one (:func:`~hammerstein_ctrl.simulate.simulate_loops`,
    equal to ``control.input_output_response`` of ``closed_loop(..., dt=dt)``)
    started at rest at the operating point; ``reference`` (a step of ``step``,
    default the verification's, or samples) is relative to its output ``y0``,
    and so are the step figures.

    Returns
    -------
    dict
        ``gain_margin``, ``phase_margin``, ``delay_margin``,
        ``w_gain_crossover``, ``w_phase_crossover``, ``Ms``, ``Mt``, ``poles``,
        ``stable``; ``step_info`` (python-control's figures relative to the
        operating point, overshoot in %), ``iae``, ``ise``, ``itae``,
        ``max_overshoot`` (fraction) and the response ``t, r, y, u`` (absolute).
    """
    model = _siso_model(model, "analyze_loop")
    model = _rational(model)
    op = pid.operating_point if pid.operating_point is not None else operating_point(model)
    P = small_signal(model, op)
    num, den = np.asarray(P.num[0][0], float), np.asarray(P.den[0][0], float)
    out = loop_figures(num, den, pid.kp, pid.ki, pid.kd, pid.tf)
    step = pid.step.get("step", 1.0) if step is None else float(step)
    dt, t_final = _tuning_grid((pid.kp, pid.ki, pid.kd, pid.tf), op, num, den, dt or pid.dt or pid.step.get("dt"),
                               t_final or pid.step.get("t_final"))
    r, is_step = _reference(reference, step, dt, t_final)
    Y, U = simulate_loops(model, pid.gains[None, :], r + op.y0, dt, u_limit=u_limit, bias=op.u0, x0=op.x0)
    t = dt * np.arange(r.size)
    with np.errstate(all="ignore"):
        for crit in CRITERIA:
            out[crit] = float(_criterion(r - (Y[0] - op.y0), dt, crit))
    out["step_info"] = _step_figures(Y[0] - op.y0, t, r[-1]) if is_step else {}
    out["max_overshoot"] = float(_overshoot(Y - op.y0, r)[0]) if is_step else math.nan
    out.update(t=t, r=r + op.y0, y=Y[0], u=U[0])
    return out


def loop_figure(reports: dict, *, u_limit=None, title: str | None = None):
    """Output and actuator signals of one or more :func:`analyze_loop` reports, by label.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from ..data._display import register_figure_formatter

    register_figure_formatter()          # a Figure ending a notebook cell shows once, as a PNG
    fig = Figure(figsize=(7, 5), layout="constrained")
    ax_y, ax_u = fig.subplots(2, 1, sharex=True)
    first = next(iter(reports.values()))
    ax_y.plot(first["t"], first["r"], "k--", lw=1, label="reference")
    for label, rep in reports.items():
        info = rep.get("step_info", {})
        extra = f", overshoot {info['Overshoot']:.1f} %" if "Overshoot" in info else ""
        ax_y.plot(rep["t"], rep["y"], label=f"{label} (ITAE {rep['itae']:.3g}{extra})")
        ax_u.plot(rep["t"], rep["u"], label=label)
    lo, hi = check_limits(u_limit)
    for lim in (lo, hi):
        if math.isfinite(lim):
            ax_u.axhline(lim, color="grey", lw=0.8, ls=":")
    ax_y.set_ylabel("y")
    ax_u.set_ylabel("u (actuator)")
    ax_u.set_xlabel("t [s]")
    ax_y.legend(fontsize=8)
    ax_y.set_title(title or "closed loop on the nonlinear model")
    return fig
