"""The package's tuning defaults, in one registry (as ``control.config.defaults``).

Every default a user may want to change for a whole session lives here, under
``"<module>.<name>"``; the functions read it when they are called, so a change
applies to every later call that does not pass the value itself.

============================  =======  ==============================================================
key                           default  meaning
============================  =======  ==============================================================
``auto.maxfev``                 3000   evaluations of ``identify(method="auto")`` without ``maxfev`` (a
                                       quarter kept back for a drift rescue where the block has a zero)
``auto.wh_maxfev``             10000   the same for a Wiener-Hammerstein structure (its linear start
                                       takes up to 40 %: a whole-order linear model converges slowly)
``auto.records_joint_share``    0.25   share of that budget kept for the joint refinement of several records
``auto.delay_joint_share``      0.25   share kept for the continuous refinement of a dead time
``delay.max_samples``            500   longest dead time (in samples) the ``auto`` scan considers
``delay.candidates``               3   whole-sample dead times ``auto`` fits before refining
``delay.pade_order``               6   order of the Pade approximant that stands for a dead time in exports
``uncertainty.level``           0.95   confidence level of intervals and bands
``residual_analysis.lags``        25   lags of the residual correlations
``verdicts.significance``       1e-4   level of the F-tests against the models nested in a fit (a
                                       constant, a static affine gain, the linear model of the same
                                       order): a fit not better at this level fails
``verdicts.nested_tests``       True   fit those nested models and test against them; False skips it
                                       (for Monte-Carlo studies of a known structure: the fits cost
                                       about as much as the fit itself)
``control.max_sensitivity``      1.6   robustness target ``max(Ms, Mt)`` of the PID rules
``control.simc_ti_factor``       4.0   SIMC's ``tau_I = min(tau1, factor (tau_c + theta))``
``lm.compiled_loop``            auto   Levenberg-Marquardt's compiled loop (C, in the compiled core):
                                       ``"auto"`` and ``"always"`` run it, ``"never"`` the same steps in
                                       Python; the initial value is ``$HAMMERSTEIN_CTRL_COMPILED_LOOP``
                                       when set
============================  =======  ==============================================================

Examples
--------
>>> from hammerstein_ctrl import config
>>> config.defaults["auto.maxfev"]
3000
>>> config.set_defaults("auto", maxfev=5000)
>>> config.defaults["auto.maxfev"]
5000
>>> config.reset_defaults()
>>> config.set_defaults("auto", maxfev=0)
Traceback (most recent call last):
...
hammerstein_ctrl.exceptions.ParameterError: auto.maxfev must be a whole number >= 1, got 0
"""

from __future__ import annotations

import math
import os

from .exceptions import ParameterError

__all__ = ["defaults", "set_defaults", "reset_defaults"]

#: ``key: (initial value, kind, low, high)``: kind "int" (whole, >= low), "float" (low < value < high),
#: "bool" or "choice" (one of the strings ``low``).
_SPEC = {
    "auto.maxfev": (3000, "int", 1, None),
    "auto.wh_maxfev": (10000, "int", 1, None),
    "auto.records_joint_share": (0.25, "float", 0.0, 1.0),
    "auto.delay_joint_share": (0.25, "float", 0.0, 1.0),
    "delay.max_samples": (500, "int", 0, None),
    "delay.candidates": (3, "int", 1, None),
    "delay.pade_order": (6, "int", 1, 20),
    "uncertainty.level": (0.95, "float", 0.0, 1.0),
    "residual_analysis.lags": (25, "int", 1, None),
    "verdicts.significance": (1e-4, "float", 0.0, 1.0),
    "verdicts.nested_tests": (True, "bool", None, None),
    "control.max_sensitivity": (1.6, "float", 1.0, math.inf),
    "control.simc_ti_factor": (4.0, "float", 0.0, math.inf),
    "lm.compiled_loop": (os.environ.get("HAMMERSTEIN_CTRL_COMPILED_LOOP", "auto"), "choice",
                         ("auto", "always", "never"), None),
}

#: The current defaults, ``{"module.name": value}``.
defaults: dict = {key: spec[0] for key, spec in _SPEC.items()}


def _checked(key: str, value):
    _, kind, low, high = _SPEC[key]
    if kind == "choice":
        if value not in low:
            raise ParameterError(f"{key} must be one of {list(low)}, got {value!r}")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            raise ParameterError(f"{key} must be True or False, got {value!r}")
        return value
    if kind == "int":
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= low and (high is None or value <= high)
        if not ok:
            bound = f" and <= {high}" if high is not None else ""
            raise ParameterError(f"{key} must be a whole number >= {low}{bound}, got {value!r}")
        return int(value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if isinstance(value, bool) or not (low < number < high):
        raise ParameterError(f"{key} must be a number between {low:g} and {high:g} (exclusive), got {value!r}")
    return number


def set_defaults(module: str, **keywords) -> None:
    """Set defaults of one module, e.g. ``set_defaults("auto", maxfev=5000)``.

    Raises
    ------
    ParameterError
        For an unknown key (naming the known ones) or a value out of its range; nothing is changed then.
    """
    new = {}
    for name, value in keywords.items():
        key = f"{module}.{name}"
        if key not in _SPEC:
            known = ", ".join(sorted(_SPEC))
            raise ParameterError(f"unknown default {key!r}; known: {known}")
        new[key] = _checked(key, value)
    defaults.update(new)


def reset_defaults() -> None:
    """Put every default back to its initial value."""
    defaults.clear()
    defaults.update({key: spec[0] for key, spec in _SPEC.items()})


def get(key: str):
    """The current value of ``key``, checked (a default set by assigning into :data:`defaults` is checked here)."""
    try:
        return _checked(key, defaults[key])
    except KeyError:
        raise ParameterError(f"the default {key!r} is missing from hammerstein_ctrl.config.defaults "
                             "(reset_defaults() restores it)") from None
