"""Writing models as versioned JSON: the encoder below the model classes.

:meth:`BlockModel.save <hammerstein_ctrl.blocks.BlockModel.save>` and
:mod:`hammerstein_ctrl.io` both write through here; reading (which
needs the model classes) lives in :mod:`~hammerstein_ctrl.io`. The
split keeps the model layer free of an import of the persistence layer above it.
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..simulate._export import model_settings
from ..exceptions import ParameterError
from ._families import NONLINEARITIES, PiecewiseLinear, Polynomial

__all__ = ["SCHEMA_VERSION", "MODEL_FORMAT", "RESULT_FORMAT", "model_to_dict", "save_model", "write_json",
           "encode_float", "json_safe", "nonlinearity_to_dict"]

#: Version of the JSON schema written by this module.
SCHEMA_VERSION = 4
MODEL_FORMAT = "hammerstein_ctrl/model"
RESULT_FORMAT = "hammerstein_ctrl/result"


def encode_float(value):
    """A float for JSON: finite floats as numbers, non-finite ones as the strings ``"inf"``, ``"-inf"``, ``"nan"``.

    Examples
    --------
    >>> encode_float(1), encode_float(float("-inf")), encode_float(float("nan"))
    (1.0, '-inf', 'nan')
    """
    value = float(value)
    if math.isfinite(value):
        return value
    return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")


def json_safe(obj):
    """``obj`` with every float (numpy's included) passed through :func:`encode_float`, recursively.

    Arrays become lists, so ``json.dumps(json_safe(x), allow_nan=False)`` writes
    standard JSON.

    Examples
    --------
    >>> json_safe({"J": float("inf"), "x": np.array([1.0, np.nan])})
    {'J': 'inf', 'x': [1.0, 'nan']}
    """
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return encode_float(obj)
    return obj


def nonlinearity_to_dict(nl) -> dict:
    """``{"family", "options"}`` of a named nonlinearity family (a custom class is refused)."""
    if type(nl) not in NONLINEARITIES.values():
        raise ParameterError(
            f"cannot save a {type(nl).__name__} nonlinearity: only the named families "
            f"{sorted(NONLINEARITIES)} can be stored (a custom function is code, not data)"
        )
    options = {}
    if isinstance(nl, Polynomial):
        options["degree"] = nl.degree
    elif isinstance(nl, PiecewiseLinear):
        options["breakpoints"] = nl.breakpoints.tolist()
    return {"family": nl.name, "options": options}



def _block_to_dict(nl, params) -> dict | None:
    if nl is None:
        return None
    out = nonlinearity_to_dict(nl)
    out["params"] = dict(zip(nl.param_names, np.asarray(params, float).tolist()))
    return out


def _mimo_model_to_dict(model) -> dict:
    """The ``"model"`` object of a MIMO model: every element's numerator, each row's denominator, one block
    per channel, and the channels' names."""
    def blocks(nls, params):
        return None if nls is None else [_block_to_dict(nl, q) for nl, q in zip(nls, params)]

    out = {"name": str(model.name), "kind": model.kind,
           "linear": {"num": model.numerators.tolist(), "den": model.denominators.tolist()},
           "inputs": list(model.input_names), "outputs": list(model.output_names),
           "input_nonlinearities": blocks(model.input_nonlinearities, model.input_params),
           "output_nonlinearities": blocks(model.output_nonlinearities, model.output_params),
           "offset": model.offset.tolist(), "intersample": model.intersample}
    if np.any(model.delays):            # only then: files of models without dead times stay as they were
        out["delays"] = model.delays.tolist()
    params = [v for key in ("input_nonlinearities", "output_nonlinearities") for b in (out[key] or ())
              for v in b["params"].values()]
    numbers = (model.numerators.ravel().tolist() + model.denominators.ravel().tolist() + params + out["offset"]
               + out.get("delays", []))
    if not all(math.isfinite(v) for v in numbers):
        raise ParameterError("cannot save a model with non-finite coefficients or parameters")
    return out


def _lure_model_to_dict(model) -> dict:
    """The ``"model"`` object of a Lur'e loop: the linear block, the feedback signal and map."""
    x0 = model.initial_state
    out = {"name": str(model.name), "kind": "lure",
           "linear": {"num": model._num.tolist(), "den": model._den.tolist()}, "feedback": model.feedback,
           "feedback_nonlinearity": _block_to_dict(model.nonlinearity, model.params), "offset": model.offset,
           "initial_state": None if x0 is None or not np.any(x0) else x0.tolist(), "intersample": model.intersample}
    if model.substeps != 1:             # only then: files of friction loops stay as they were
        out["substeps"] = model.substeps
    numbers = (out["linear"]["num"] + out["linear"]["den"] + list(out["feedback_nonlinearity"]["params"].values())
               + [out["offset"]] + (out["initial_state"] or []))
    if not all(math.isfinite(v) for v in numbers):
        raise ParameterError("cannot save a model with non-finite coefficients or parameters")
    return out


def _wh_model_to_dict(model) -> dict:
    """The ``"model"`` object of a Wiener-Hammerstein model: both blocks, the map, offset, states and substeps."""
    (n1, d1), (n2, d2) = model._blocks
    x0 = model.initial_state
    out = {"name": str(model.name), "kind": "wiener-hammerstein",
           "first": {"num": n1.tolist(), "den": d1.tolist()}, "second": {"num": n2.tolist(), "den": d2.tolist()},
           "nonlinearity": _block_to_dict(model.nonlinearity, model.params), "offset": model.offset,
           "initial_state": None if x0 is None else [x0[0].tolist(), x0[1].tolist()],
           "intersample": model.intersample, "substeps": model.substeps,
           **({"delay": model.delay} if model.delay else {})}
    numbers = (n1.tolist() + d1.tolist() + n2.tolist() + d2.tolist() + list(out["nonlinearity"]["params"].values())
               + [model.offset] + ([] if x0 is None else x0[0].tolist() + x0[1].tolist()))
    if not all(math.isfinite(v) for v in numbers):
        raise ParameterError("cannot save a model with non-finite coefficients or parameters")
    return out


def model_to_dict(model) -> dict:
    """The ``"model"`` object of the schema for a Hammerstein, Wiener or Hammerstein-Wiener model (SISO or MIMO).

    Raises
    ------
    ParameterError
        For a custom nonlinearity (code cannot be stored) or non-finite numbers.
    """
    if str(getattr(model, "kind", "")).startswith("mimo"):
        return _mimo_model_to_dict(model)
    if getattr(model, "kind", "") == "lure":
        return _lure_model_to_dict(model)
    if getattr(model, "kind", "") == "wiener-hammerstein":
        return _wh_model_to_dict(model)
    settings = model_settings(model)
    num, den = (np.trim_zeros(c, "f") for c in model.coefficients())
    x0 = settings["initial_state"]
    blocks = {"input_nonlinearity": _block_to_dict(model.input_nonlinearity, model.input_params),
              "output_nonlinearity": _block_to_dict(model.output_nonlinearity, model.output_params)}
    out = {"name": str(model.name), "kind": model.kind,
           "linear": {"num": (num if num.size else np.zeros(1)).tolist(), "den": den.tolist()},
           **blocks, "offset": settings["offset"],
           "initial_state": x0.tolist() if np.any(x0 != 0) else None,
           "intersample": settings["intersample"]}
    if model.delay:                     # only then: files of models without a dead time stay as they were
        out["delay"] = float(model.delay)
    params = [v for b in blocks.values() if b is not None for v in b["params"].values()]
    numbers = out["linear"]["num"] + out["linear"]["den"] + params + [out["offset"]]
    if not all(math.isfinite(v) for v in numbers + (out["initial_state"] or [])):
        raise ParameterError("cannot save a model with non-finite coefficients or parameters")
    return out


def write_json(obj: dict, path) -> None:
    """Write ``obj`` as JSON, whole and never through a link (:func:`~hammerstein_ctrl._safe_io.write_text`)."""
    from .._safe_io import write_text

    write_text(path, json.dumps(obj, indent=2, allow_nan=False) + "\n")


def save_model(model, path) -> None:
    """Write ``model`` to ``path`` as a model file (:func:`hammerstein_ctrl.io.load_model` reads it).

    Examples
    --------
    >>> import os, tempfile, hammerstein_ctrl as hc
    >>> path = os.path.join(tempfile.mkdtemp(), "model.json")
    >>> save_model(hc.HammersteinModel(([1.0], [1.0, 2.0]), hc.Tanh(), [1.0, 0.5]), path)
    >>> hc.load_model(path).linear.den[0][0].tolist()
    [1.0, 2.0]
    """
    write_json({"format": MODEL_FORMAT, "schema_version": SCHEMA_VERSION, "model": model_to_dict(model)}, path)
