"""What users pass in, normalised, each checked with a one-line error.

* :func:`as_models` turns one model, a list, a dict of named models or an
  :class:`~hammerstein_ctrl.fit.IdentificationResult` into the
  ``{label: model}`` mapping every plot helper works on.
* :func:`as_iodata` accepts an :class:`~hammerstein_ctrl.data.IOData` or any
  record with ``u``, ``y`` and ``sampling_time`` attributes, such as the
  ``nonlinear_benchmarks`` package's ``Input_output_data``.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> m = case.structure.model(case.true_beta)
>>> list(as_models(m)), list(as_models([m, m])), list(as_models({"truth": m}))
(['hammerstein'], ['model 1', 'model 2'], ['truth'])
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
import numpy as np
from .._checks import require_siso_model
from ..exceptions import DataError, ParameterError

__all__ = ["as_models", "labelled", "as_iodata", "is_identification_result", "method_label"]


#: Display names of the methods (in tables, figures and reports).
METHOD_LABELS = {"spsa": "SPSA", "nlspsa": "NL-SPSA", "nspsa": "N-SPSA", "amvo-sca": "AMVO-SCA", "lm": "LM*"}


def method_label(method: str) -> str:
    """Display name of a method key (``"nspsa"`` -> ``"N-SPSA"``); unknown keys pass through."""
    return METHOD_LABELS.get(method, method)


# -- input normalisation -------------------------------------------------------
def is_identification_result(obj) -> bool:
    """Whether ``obj`` is an :class:`~hammerstein_ctrl.fit._identify.IdentificationResult` (or behaves as one).

    Checked by the class flag ``is_identification_result`` rather than by
    importing the class, so this layer never imports the identification layer above it.
    """
    return bool(getattr(type(obj), "is_identification_result", False))


def _is_system(obj) -> bool:
    import control

    return isinstance(obj, control.LTI)


def _default_label(obj, index: int | None) -> str:
    if is_identification_result(obj):
        return method_label(obj.method)
    if isinstance(obj, (np.ndarray, list, tuple)):
        return "simulated" if index is None else f"simulated {index + 1}"
    name = getattr(obj, "name", None)
    if index is None:
        return str(name or type(obj).__name__)
    default = str(getattr(obj, "kind", "hammerstein")).replace("-", "_")
    if isinstance(name, str) and name and name != default and not _is_system(obj):
        return name
    return f"model {index + 1}"


def _check_item(label, obj, *, arrays: bool, systems: bool, need: tuple, siso: bool = True):
    """One model (IdentificationResult unwrapped), array or LTI system, checked for what is needed."""
    if is_identification_result(obj):
        obj = obj.model
    if siso:
        require_siso_model(obj, f"this (model {label!r})", ", or use result.compare() and result.plot(), which draw "
                           "every channel")
    if isinstance(obj, (np.ndarray, list, tuple)) and arrays:
        return np.asarray(obj, dtype=float)
    if systems and _is_system(obj):
        return obj
    if all(hasattr(obj, attr) for attr in need):
        return obj
    kinds = "a HammersteinModel or an IdentificationResult"
    kinds += ", a control.TransferFunction" if systems else ""
    kinds += ", a simulated output array" if arrays else ""
    raise ParameterError(f"model {label!r} must be {kinds}, got {type(obj).__name__}")


def as_models(models, *, arrays: bool = False, systems: bool = False, need=("simulate",),
              allow_empty: bool = False, siso: bool = True) -> dict:
    """Normalise what a user passes as "models" to ``{label: model}``.

    Parameters
    ----------
    models : model, IdentificationResult, list/tuple of them, dict ``{label: model}`` or None
        Labels of list items are the result's method (``"N-SPSA"``), the
        model's own ``name`` when it was given one, else ``"model 1"``, ...
    arrays : bool
        Also accept simulated output arrays as dict values.
    systems : bool
        Also accept python-control LTI systems (for Bode plots).
    need : tuple of str
        Attributes a model must have (e.g. ``("g",)`` for nonlinearity plots).
    allow_empty : bool
        Accept ``None`` or an empty collection (returns ``{}``).
    siso : bool, default True
        Refuse MIMO models (naming ``model.element``) where only SISO ones make sense.

    Raises
    ------
    ParameterError
        On an unsupported type, or an empty collection when not allowed.
    """
    return {key: _check_item(key, obj, arrays=arrays, systems=systems, need=need, siso=siso)
            for key, obj in labelled(models, arrays=arrays, allow_empty=allow_empty).items()}


def labelled(models, *, arrays: bool = False, allow_empty: bool = False) -> dict:
    """``{label: object as given}``, labelled as :func:`as_models` labels them (results are not unwrapped).

    Examples
    --------
    >>> list(labelled([1.0, "x"]))
    ['model 1', 'model 2']
    """
    if models is None:
        items = []
    elif isinstance(models, Mapping):
        items = [(str(k), v) for k, v in models.items()]
    elif isinstance(models, (list, tuple)) and not (arrays and models and isinstance(models[0], numbers.Number)):
        items = [(_default_label(m, i), m) for i, m in enumerate(models)]
    else:
        items = [(_default_label(models, None), models)]
    if not items and not allow_empty:
        raise ParameterError("give at least one model (a model, a list or a dict {label: model})")
    out = {}
    for label, obj in items:
        key, k = label, 2
        while key in out:
            key, k = f"{label} ({k})", k + 1
        out[key] = obj
    return out


def as_iodata(obj):
    """Return ``obj`` as an :class:`~hammerstein_ctrl.data.IOData` record.

    Accepts an ``IOData`` (returned unchanged) or any object with ``u``, ``y``
    and ``sampling_time`` attributes and optionally ``name`` -- the
    ``nonlinear_benchmarks`` package's ``Input_output_data``.

    Raises
    ------
    ParameterError
        When ``obj`` is not a record (a list of records names how many it holds).
    DataError
        When the record has no sampling time or bad samples.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rec = SimpleNamespace(u=[0.0, 1.0, 0.5], y=[0.0, 0.1, 0.3], sampling_time=0.01, name="train")
    >>> d = as_iodata(rec)
    >>> d.name, d.dt, len(d)
    ('train', 0.01, 3)
    """
    from ._iodata import IOData

    if isinstance(obj, IOData):
        return obj
    if isinstance(obj, (list, tuple)) and obj and all(hasattr(o, "u") for o in obj):
        raise ParameterError(f"expected one input/output record, got a {type(obj).__name__} of {len(obj)}; "
                             "pass one of them")
    if not (hasattr(obj, "u") and hasattr(obj, "y")):
        raise ParameterError(f"expected an IOData record or an object with u, y and sampling_time, "
                             f"got {type(obj).__name__}")
    dt = getattr(obj, "sampling_time", None)
    if dt is None:
        dt = getattr(obj, "dt", None)
    if dt is None:
        raise DataError(f"record {getattr(obj, 'name', '')!r} has no sampling_time: "
                        "build IOData(u, y, dt=...) yourself")
    return IOData(obj.u, obj.y, dt=float(dt), name=str(getattr(obj, "name", None) or "data"))
