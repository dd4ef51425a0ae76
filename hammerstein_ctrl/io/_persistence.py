"""Save and load Hammerstein models and identification results as versioned JSON.

The files are plain JSON (RFC 8259), read strictly and never evaluated:

* every number in a model (coefficients, parameters, offset, initial state)
  must be finite; a file holding ``NaN``/``Infinity`` literals or a non-finite
  parameter is rejected with a message naming the field;
* figures of a run that may legitimately be non-finite (``J``, ``fit_percent``,
  ``rmse``, ``nrmse`` of a diverged run) are written as the strings ``"inf"``,
  ``"-inf"`` or ``"nan"``, so the file stays valid JSON;
* a wrong ``format`` or ``schema_version``, a missing or unexpected key, an
  unknown nonlinearity or a parameter name that does not match the family are
  errors (:class:`~hammerstein_ctrl.exceptions.ParameterError` or
  :class:`~hammerstein_ctrl.exceptions.UnknownNameError`), never silently
  repaired.

Floats are written with Python's shortest round-trip representation, so a
loaded model reproduces the saved one bit for bit.

Schema, version 4 (a model file; a result file has ``"format":
"hammerstein_ctrl/result"`` and the keys of :func:`result_to_dict`)::

    {"format": "hammerstein_ctrl/model", "schema_version": 4,
     "model": {"name": "emps", "kind": "hammerstein",
               "linear": {"num": [1.0], "den": [1.0, 3.1388, 0.0]},
               "input_nonlinearity": {"family": "coulomb", "options": {},
                                      "params": {"d0": 0.5445, "d1": -0.3984, "d2": 0.0451}},
               "output_nonlinearity": null,
               "offset": 0.0, "initial_state": null, "intersample": "foh"}}

``kind`` is ``"hammerstein"``, ``"wiener"`` or ``"hammerstein-wiener"`` and
must agree with which of the two nonlinearities are present.

A MIMO model (:mod:`~hammerstein_ctrl.blocks`; ``kind`` ``"mimo-hammerstein"``,
``"mimo-wiener"`` or ``"mimo-hammerstein-wiener"``) stores ``linear.num`` as
one list of numerators per output and input, ``linear.den`` as one
denominator per output, ``inputs``/``outputs`` (the channels' names),
``input_nonlinearities``/``output_nonlinearities`` as lists of blocks (or
null) and ``offset`` as one number per output.

Examples
--------
>>> import control as ct, tempfile, os
>>> from hammerstein_ctrl import HammersteinModel, Coulomb
>>> m = HammersteinModel(ct.tf([1], [1, 3.138764, 0]), Coulomb(), [0.544501, -0.398365, 0.045066])
>>> path = os.path.join(tempfile.mkdtemp(), "emps.json")
>>> save_model(m, path)
>>> m2 = load_model(path)
>>> m2.params.tolist() == m.params.tolist(), m2.linear.den[0][0].tolist()
(True, [1.0, 3.138764, 0.0])
"""

from __future__ import annotations

import json
import math

import numpy as np

from ..exceptions import ParameterError, UnknownNameError
from .._checks import INTERSAMPLE, MAX_MAGNITUDE, check_delay, check_transfer_function
from ..blocks._json import (MODEL_FORMAT, RESULT_FORMAT, SCHEMA_VERSION, model_to_dict, nonlinearity_to_dict as
                            _nonlinearity_to_dict, save_model)
from ..blocks._families import NONLINEARITIES

__all__ = ["SCHEMA_VERSION", "MODEL_FORMAT", "RESULT_FORMAT", "model_to_dict", "model_from_dict", "save_model",
           "load_model", "READABLE_SCHEMA_VERSIONS"]

#: Versions read (others are refused): 3 added a result's ``status``, the optimiser's termination code;
#: 4 its ``covariance``, ``dof`` and ``warnings``.
READABLE_SCHEMA_VERSIONS = (2, 3, 4)

#: The first schema version whose result files carry ``status``; and ``covariance``, ``dof``, ``warnings``.
_STATUS_VERSION = 3
_UNCERTAINTY_VERSION = 4
_UNCERTAINTY_KEYS = ("covariance", "dof", "warnings")
#: Strings standing for non-finite figures of a run.
_NONFINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}

_MODEL_KEYS = ("name", "kind", "linear", "input_nonlinearity", "output_nonlinearity", "offset", "initial_state",
               "intersample")
#: Structure kinds and which nonlinearities (input, output) each has.
_KINDS = {"hammerstein": (True, False), "wiener": (False, True), "hammerstein-wiener": (True, True)}
_RESULT_KEYS = ("format", "schema_version", "model", "structure", "params", "beta", "data", "J",
                "fit_percent", "rmse", "nrmse", "nfev", "method", "success", "message", "elapsed_s")
_DATA_KEYS = ("name", "dt", "n_samples", "input_name", "output_name", "input_unit", "output_unit",
              "intersample")


# ---------------------------------------------------------------------------
# strict readers
# ---------------------------------------------------------------------------
def _keys(obj, where: str, required, optional=()) -> dict:
    """Check that ``obj`` is an object with exactly the allowed keys."""
    if not isinstance(obj, dict):
        raise ParameterError(f"{where} must be a JSON object, got {type(obj).__name__}")
    missing = [k for k in required if k not in obj]
    if missing:
        raise ParameterError(f"{where} is missing the field(s) {missing}")
    unexpected = sorted(set(obj) - set(required) - set(optional))
    if unexpected:
        raise ParameterError(f"{where} has unexpected field(s) {unexpected}")
    return obj


def _number(value, where: str, *, finite: bool = True) -> float:
    """A JSON number (or, with ``finite=False``, one of the strings 'inf', '-inf', 'nan')."""
    if not finite and isinstance(value, str) and value in _NONFINITE:
        return _NONFINITE[value]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(f"{where} must be a number, got {value!r}")
    value = float(value)
    if finite and not math.isfinite(value):
        raise ParameterError(f"{where} must be a finite number, got {value!r}")
    if abs(value) > MAX_MAGNITUDE and math.isfinite(value):
        raise ParameterError(f"{where} = {value!r} is beyond the largest magnitude stored, {MAX_MAGNITUDE:g}")
    return value


def _numbers(value, where: str) -> np.ndarray:
    if not isinstance(value, list) or not value:
        raise ParameterError(f"{where} must be a non-empty list of numbers, got {value!r}")
    return np.array([_number(v, f"{where}[{i}]") for i, v in enumerate(value)])


def _string(value, where: str) -> str:
    if not isinstance(value, str):
        raise ParameterError(f"{where} must be a string, got {value!r}")
    return value


def _integer(value, where: str, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ParameterError(f"{where} must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise ParameterError(f"{where} must be at least {minimum}, got {value}")
    return value


def _boolean(value, where: str) -> bool:
    if not isinstance(value, bool):
        raise ParameterError(f"{where} must be true or false, got {value!r}")
    return value


def _header(obj, fmt: str, where: str) -> int:
    """Check the format and schema version of a file's top-level object; return the version."""
    if not isinstance(obj, dict):
        raise ParameterError(f"{where}: not a hammerstein_ctrl file (top level is not a JSON object)")
    if obj.get("format") != fmt:
        raise ParameterError(f"{where}: format is {obj.get('format')!r}, expected {fmt!r}")
    if "schema_version" not in obj:
        raise ParameterError(f"{where} is missing the field(s) ['schema_version']")
    version = obj["schema_version"]
    if version not in READABLE_SCHEMA_VERSIONS or isinstance(version, bool):
        readable = " and ".join(str(v) for v in READABLE_SCHEMA_VERSIONS)
        raise ParameterError(
            f"{where}: unsupported schema_version {version!r}; this version of hammerstein_ctrl "
            f"reads versions {readable}"
        )
    return version


# ---------------------------------------------------------------------------
# nonlinearities and structures
# ---------------------------------------------------------------------------
def _nonlinearity_from_dict(obj, where: str):
    family = _string(obj["family"], f"{where}.family")
    if family not in NONLINEARITIES:
        raise UnknownNameError(
            f"{where}.family: unknown nonlinearity {family!r}; known: {', '.join(sorted(NONLINEARITIES))}"
        )
    options = _keys(obj["options"], f"{where}.options", (), ("degree", "breakpoints"))
    kwargs = {}
    if "degree" in options:
        kwargs["degree"] = _integer(options["degree"], f"{where}.options.degree")
    if "breakpoints" in options:
        kwargs["breakpoints"] = _numbers(options["breakpoints"], f"{where}.options.breakpoints")
    try:
        return NONLINEARITIES[family](**kwargs)
    except TypeError as exc:
        raise ParameterError(f"{where}.options do not fit the {family!r} family: {exc}") from None


def _check_kind(obj, where: str) -> tuple:
    kind = _string(obj["kind"], f"{where}.kind")
    if kind not in _KINDS:
        raise UnknownNameError(f"{where}.kind: unknown structure {kind!r}; known: {', '.join(_KINDS)}")
    for present, key in zip(_KINDS[kind], ("input_nonlinearity", "output_nonlinearity")):
        if present != (obj[key] is not None):
            raise ParameterError(f"{where}.{key} must be {'an object' if present else 'null'} in a {kind} "
                                 "structure")
    return kind, _KINDS[kind]


def _block_structure_to_dict(structure) -> dict:
    from ..blocks._structure import BlockStructure

    if not isinstance(structure, BlockStructure) or structure.kind not in _KINDS:
        raise ParameterError(f"cannot save a structure of type {type(structure).__name__}")
    return {"kind": structure.kind, "linear": _linear_structure_to_dict(structure.linear),
            **{key: None if nl is None else _nonlinearity_to_dict(nl)
               for key, nl in (("input_nonlinearity", structure.input_nonlinearity),
                               ("output_nonlinearity", structure.output_nonlinearity))},
            "offset": structure.offset, "initial_state": structure.initial_state}


def _linear_structure_to_dict(lin) -> dict:
    """A :class:`~hammerstein_ctrl.blocks.LinearStructure` as JSON (its delay only when it has one)."""
    linear = {"num_order": lin.num_order, "den_order": lin.den_order,
              "monic_numerator": lin.monic_numerator, "fixed": dict(lin.fixed)}
    if lin.delay:
        linear["delay"] = lin.delay
    return linear


def _linear_structure_from_dict(obj, where: str, *, delay: bool = True):
    """The :class:`~hammerstein_ctrl.blocks.LinearStructure` of ``obj`` (a ``delay`` key only if ``delay``)."""
    from ..blocks._structure import LinearStructure

    lin = _keys(obj, where, ("num_order", "den_order", "monic_numerator", "fixed"), ("delay",) if delay else ())
    if not isinstance(lin["fixed"], dict):
        raise ParameterError(f"{where}.fixed must be a JSON object")
    return LinearStructure(_integer(lin["num_order"], f"{where}.num_order"),
                           _integer(lin["den_order"], f"{where}.den_order"),
                           monic_numerator=_boolean(lin["monic_numerator"], f"{where}.monic_numerator"),
                           fixed={k: _number(v, f"{where}.fixed.{k}") for k, v in lin["fixed"].items()},
                           delay=_delay(lin.get("delay"), f"{where}.delay", estimate=True))


def _mimo_structure_to_dict(structure) -> dict:
    lin = structure.linear
    return {"kind": structure.kind, "linear": {"num_order": lin.num_order, "den_order": lin.den_order,
                                               "monic_numerator": True, "fixed": {}},
            **{key: None if nls is None else [_nonlinearity_to_dict(nl) for nl in nls]
               for key, nls in (("input_nonlinearities", structure.input_nonlinearities),
                                ("output_nonlinearities", structure.output_nonlinearities))},
            "n_inputs": structure.n_inputs, "n_outputs": structure.n_outputs, "offset": structure.offset,
            "initial_state": structure.initial_state,
            **({"delays": list(structure.delays)} if structure.has_delay else {})}


def _lure_structure_to_dict(structure) -> dict:
    return {"kind": "lure", "linear": _linear_structure_to_dict(structure.linear),
            "feedback": structure.feedback, "feedback_nonlinearity": _nonlinearity_to_dict(structure.nonlinearity),
            "offset": structure.offset, "initial_state": structure.initial_state,
            **({"substeps": structure.substeps} if structure.substeps != 1 else {})}


def _wh_structure_to_dict(structure) -> dict:
    return {"kind": "wiener-hammerstein",
            "first": [structure.first.num_order, structure.first.den_order],
            "second": [structure.second.num_order, structure.second.den_order],
            "nonlinearity": _nonlinearity_to_dict(structure.nonlinearity), "offset": structure.offset,
            "initial_state": structure.initial_state, "substeps": structure.substeps,
            "time_unit": structure.time_unit, **({"delay": structure.delay} if structure.delay else {})}


def _orders(obj, where: str) -> tuple:
    if not isinstance(obj, list) or len(obj) != 2:
        raise ParameterError(f"{where} must be [num_order, den_order], got {obj!r}")
    return tuple(_integer(v, f"{where}[{i}]", minimum=0) for i, v in enumerate(obj))


def _wh_structure_from_dict(obj, where: str):
    from ..blocks._wiener_hammerstein import WienerHammersteinStructure

    _keys(obj, where, ("kind", "first", "second", "nonlinearity", "offset", "initial_state", "substeps", "time_unit"),
          ("delay",))
    key = f"{where}.nonlinearity"
    nl = _nonlinearity_from_dict(_keys(obj["nonlinearity"], key, ("family", "options")), key)
    unit = obj["time_unit"]
    return WienerHammersteinStructure(
        _orders(obj["first"], f"{where}.first"), nl, _orders(obj["second"], f"{where}.second"),
        offset=_boolean(obj["offset"], f"{where}.offset"),
        initial_state=_string(obj["initial_state"], f"{where}.initial_state"),
        substeps=_integer(obj["substeps"], f"{where}.substeps", minimum=1),
        time_unit=None if unit is None else _number(unit, f"{where}.time_unit"),
        delay=_number(obj.get("delay", 0.0), f"{where}.delay"))


def _wh_model_from_dict(obj, where: str):
    from ..blocks._wiener_hammerstein import WienerHammersteinModel

    _keys(obj, where, ("name", "kind", "first", "second", "nonlinearity", "offset", "initial_state", "intersample",
                       "substeps"), ("delay",))
    blocks = []
    for key in ("first", "second"):
        lin = _keys(obj[key], f"{where}.{key}", ("num", "den"))
        blocks.append(check_transfer_function(_numbers(lin["num"], f"{where}.{key}.num"),
                                              _numbers(lin["den"], f"{where}.{key}.den"), f"{where}.{key}",
                                              advice="this file is not a usable model"))
    nl, params = _block_from_dict(obj["nonlinearity"], f"{where}.nonlinearity")
    if nl is None:
        raise ParameterError(f"{where}.nonlinearity must be an object")
    x0 = obj["initial_state"]
    if x0 is not None and (not isinstance(x0, list) or len(x0) != 2):
        raise ParameterError(f"{where}.initial_state must be null or [G1's state, G2's state]")
    return WienerHammersteinModel(
        blocks[0], nl, params, blocks[1], offset=_number(obj["offset"], f"{where}.offset"),
        initial_state=None if x0 is None else [_numbers(x, f"{where}.initial_state") for x in x0],
        intersample=_string(obj["intersample"], f"{where}.intersample"),
        substeps=_integer(obj["substeps"], f"{where}.substeps", minimum=1), name=_string(obj["name"], f"{where}.name"),
        delay=_number(obj.get("delay", 0.0), f"{where}.delay"))


def _lure_structure_from_dict(obj, where: str):
    from ..blocks._lure import LureStructure

    _keys(obj, where, ("kind", "linear", "feedback", "feedback_nonlinearity", "offset", "initial_state"),
          ("substeps",))
    linear = _linear_structure_from_dict(obj["linear"], f"{where}.linear", delay=False)
    key = f"{where}.feedback_nonlinearity"
    nl = _nonlinearity_from_dict(_keys(obj["feedback_nonlinearity"], key, ("family", "options")), key)
    return LureStructure(linear, nl, feedback=_string(obj["feedback"], f"{where}.feedback"),
                         offset=_boolean(obj["offset"], f"{where}.offset"),
                         initial_state=_string(obj["initial_state"], f"{where}.initial_state"),
                         substeps=_integer(obj.get("substeps", 1), f"{where}.substeps", minimum=1))


def _lure_model_from_dict(obj, where: str):
    from ..blocks._lure import LureModel

    _keys(obj, where, ("name", "kind", "linear", "feedback", "feedback_nonlinearity", "offset", "initial_state",
                       "intersample"), ("substeps",))
    lin = _keys(obj["linear"], f"{where}.linear", ("num", "den"))
    num, den = _numbers(lin["num"], f"{where}.linear.num"), _numbers(lin["den"], f"{where}.linear.den")
    num, den = check_transfer_function(num, den, f"{where}.linear", advice="this file is not a usable model")
    nl, params = _block_from_dict(obj["feedback_nonlinearity"], f"{where}.feedback_nonlinearity")
    if nl is None:
        raise ParameterError(f"{where}.feedback_nonlinearity must be an object")
    x0 = obj["initial_state"]
    return LureModel((num, den), nl, params, feedback=_string(obj["feedback"], f"{where}.feedback"),
                     offset=_number(obj["offset"], f"{where}.offset"),
                     initial_state=None if x0 is None else _numbers(x0, f"{where}.initial_state"),
                     intersample=_string(obj["intersample"], f"{where}.intersample"),
                     name=_string(obj["name"], f"{where}.name"),
                     substeps=_integer(obj.get("substeps", 1), f"{where}.substeps", minimum=1))


def _structure_to_dict(structure) -> dict:
    """A block structure's object; a fit to several records adds ``n_records`` (its blocks shared by them)."""
    if str(structure.kind).startswith("mimo"):
        return _mimo_structure_to_dict(structure)
    if structure.kind == "lure":
        return _lure_structure_to_dict(structure)
    if structure.kind == "wiener-hammerstein":
        return _wh_structure_to_dict(structure)
    base = getattr(structure, "base", None)
    if base is not None and hasattr(structure, "n_records"):
        return {**_block_structure_to_dict(base), "n_records": int(structure.n_records)}
    return _block_structure_to_dict(structure)


#: MIMO kinds and which lists of nonlinearities (input, output) each has.
_MIMO_KINDS = {"mimo-hammerstein": (True, False), "mimo-wiener": (False, True),
               "mimo-hammerstein-wiener": (True, True)}


def _mimo_kind(obj, where: str) -> str:
    kind = _string(obj["kind"], f"{where}.kind")
    if kind not in _MIMO_KINDS:
        raise UnknownNameError(f"{where}.kind: unknown structure {kind!r}; known: {', '.join(_MIMO_KINDS)}")
    for present, key in zip(_MIMO_KINDS[kind], ("input_nonlinearities", "output_nonlinearities")):
        value = obj[key]
        if present != (value is not None) or (present and (not isinstance(value, list) or not value)):
            raise ParameterError(f"{where}.{key} must be {'a list of blocks' if present else 'null'} in a {kind} "
                                 "structure")
    return kind


def _mimo_structure_from_dict(obj, where: str):
    from ..blocks._mimo import mimo_structure
    from ..blocks._structure import LinearStructure

    _keys(obj, where, ("kind", "linear", "input_nonlinearities", "output_nonlinearities", "n_inputs", "n_outputs",
                       "offset", "initial_state"), ("delays",))
    _mimo_kind(obj, where)
    delays = obj.get("delays")
    if delays is not None:
        if not isinstance(delays, list):
            raise ParameterError(f"{where}.delays must be a list with one dead time per input")
        delays = [_delay(d, f"{where}.delays[{k}]", estimate=True) for k, d in enumerate(delays)]
    lin = _keys(obj["linear"], f"{where}.linear", ("num_order", "den_order", "monic_numerator", "fixed"))
    if lin["fixed"] != {} or lin["monic_numerator"] is not True:
        raise ParameterError(f"{where}.linear: a MIMO structure has no fixed coefficients and keeps its gain "
                             "convention (fixed {}, monic_numerator true)")
    linear = LinearStructure(_integer(lin["num_order"], f"{where}.linear.num_order"),
                             _integer(lin["den_order"], f"{where}.linear.den_order"))
    blocks = {key: None if obj[key] is None else [
        _nonlinearity_from_dict(_keys(b, f"{where}.{key}[{k}]", ("family", "options")), f"{where}.{key}[{k}]")
        for k, b in enumerate(obj[key])] for key in ("input_nonlinearities", "output_nonlinearities")}
    return mimo_structure(linear, blocks["input_nonlinearities"], blocks["output_nonlinearities"],
                          n_inputs=_integer(obj["n_inputs"], f"{where}.n_inputs", minimum=1),
                          n_outputs=_integer(obj["n_outputs"], f"{where}.n_outputs", minimum=1),
                          offset=_boolean(obj["offset"], f"{where}.offset"),
                          initial_state=_string(obj["initial_state"], f"{where}.initial_state"), delay=delays)


def _mimo_model_from_dict(obj, where: str):
    from ..blocks._mimo_model import MIMOModel

    _keys(obj, where, ("name", "kind", "linear", "inputs", "outputs", "input_nonlinearities",
                       "output_nonlinearities", "offset", "intersample"), ("delays",))
    kind = _mimo_kind(obj, where)
    lin = _keys(obj["linear"], f"{where}.linear", ("num", "den"))
    try:
        num = np.array(lin["num"], dtype=float)
        den = np.array(lin["den"], dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{where}.linear must hold numbers: num as outputs x inputs x coefficients, den as "
                             "outputs x coefficients") from None
    for name, value in (("inputs", obj["inputs"]), ("outputs", obj["outputs"])):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ParameterError(f"{where}.{name} must be a list of channel names")
    blocks = {}
    for key in ("input_nonlinearities", "output_nonlinearities"):
        pairs = [] if obj[key] is None else [_block_from_dict(b, f"{where}.{key}[{k}]") for k, b in enumerate(obj[key])]
        blocks[key] = (None, None) if obj[key] is None else ([p[0] for p in pairs], [p[1] for p in pairs])
    intersample = _string(obj["intersample"], f"{where}.intersample")
    if intersample not in INTERSAMPLE:
        raise ParameterError(f"{where}.intersample must be one of {list(INTERSAMPLE)}, got {intersample!r}")
    if np.abs(num).max(initial=0) > MAX_MAGNITUDE or np.abs(den).max(initial=0) > MAX_MAGNITUDE:
        raise ParameterError(f"{where}.linear has coefficients beyond {MAX_MAGNITUDE:g}")
    offset = _numbers(obj["offset"], f"{where}.offset")
    return MIMOModel(num, den, input_nonlinearities=blocks["input_nonlinearities"][0],
                     input_params=blocks["input_nonlinearities"][1],
                     output_nonlinearities=blocks["output_nonlinearities"][0],
                     output_params=blocks["output_nonlinearities"][1], offset=offset, intersample=intersample,
                     name=_string(obj["name"], f"{where}.name"), input_names=obj["inputs"],
                     output_names=obj["outputs"], kind=kind,
                     delays=None if obj.get("delays") is None else [
                         _delay(d, f"{where}.delays[{k}]", estimate=False) for k, d in enumerate(
                             obj["delays"] if isinstance(obj["delays"], list) else [obj["delays"]])])


def _structure_from_dict(obj, where: str):
    if isinstance(obj, dict) and str(obj.get("kind", "")).startswith("mimo"):
        return _mimo_structure_from_dict(obj, where)
    if isinstance(obj, dict) and obj.get("kind") == "lure":
        return _lure_structure_from_dict(obj, where)
    if isinstance(obj, dict) and obj.get("kind") == "wiener-hammerstein":
        return _wh_structure_from_dict(obj, where)
    from ..blocks._structure import INITIAL_STATES, HammersteinStructure, HammersteinWienerStructure, WienerStructure

    _keys(obj, where, ("kind", "linear", "input_nonlinearity", "output_nonlinearity", "offset", "initial_state"),
          ("n_records",))
    kind, _ = _check_kind(obj, where)
    linear = _linear_structure_from_dict(obj["linear"], f"{where}.linear")
    blocks = [_nonlinearity_from_dict(_keys(obj[key], f"{where}.{key}", ("family", "options")), f"{where}.{key}")
              for key in ("input_nonlinearity", "output_nonlinearity") if obj[key] is not None]
    initial_state = _string(obj["initial_state"], f"{where}.initial_state")
    if initial_state not in INITIAL_STATES:
        raise ParameterError(f"{where}.initial_state must be one of {list(INITIAL_STATES)}, got {initial_state!r}")
    cls = {"hammerstein": HammersteinStructure, "wiener": WienerStructure,
           "hammerstein-wiener": HammersteinWienerStructure}[kind]
    structure = cls(linear, *blocks, offset=_boolean(obj["offset"], f"{where}.offset"), initial_state=initial_state)
    if obj.get("n_records") is None:
        return structure
    from ..fit._experiments import RecordsStructure

    return RecordsStructure(structure, _integer(obj["n_records"], f"{where}.n_records", minimum=1))


# ---------------------------------------------------------------------------
# models
# ---------------------------------------------------------------------------
def _block_from_dict(obj, where: str):
    if obj is None:
        return None, None
    nl_obj = _keys(obj, where, ("family", "options", "params"))
    nl = _nonlinearity_from_dict(nl_obj, where)
    params = _keys(nl_obj["params"], f"{where}.params", nl.param_names)
    return nl, [_number(params[k], f"{where}.params.{k}") for k in nl.param_names]


def model_from_dict(obj, where: str = "model"):
    """Build a model (Hammerstein, Wiener or Hammerstein-Wiener) from its ``"model"`` object.

    Raises
    ------
    ParameterError, UnknownNameError
        On any deviation from the schema (see the module notes).
    """
    import control

    from ..blocks._model import BlockModel

    if isinstance(obj, dict) and str(obj.get("kind", "")).startswith("mimo"):
        return _mimo_model_from_dict(obj, where)
    if isinstance(obj, dict) and obj.get("kind") == "lure":
        return _lure_model_from_dict(obj, where)
    if isinstance(obj, dict) and obj.get("kind") == "wiener-hammerstein":
        return _wh_model_from_dict(obj, where)
    _keys(obj, where, _MODEL_KEYS, ("delay",))
    _check_kind(obj, where)
    lin = _keys(obj["linear"], f"{where}.linear", ("num", "den"))
    num, den = _numbers(lin["num"], f"{where}.linear.num"), _numbers(lin["den"], f"{where}.linear.den")
    num, den = check_transfer_function(num, den, f"{where}.linear", advice="this file is not a usable model")
    g, g_params = _block_from_dict(obj["input_nonlinearity"], f"{where}.input_nonlinearity")
    h, h_params = _block_from_dict(obj["output_nonlinearity"], f"{where}.output_nonlinearity")
    x0 = obj["initial_state"]
    x0 = None if x0 is None else _numbers(x0, f"{where}.initial_state")
    intersample = _string(obj["intersample"], f"{where}.intersample")
    if intersample not in INTERSAMPLE:
        raise ParameterError(f"{where}.intersample must be one of {list(INTERSAMPLE)}, got {intersample!r}")
    return BlockModel.build(control.tf(num, den), input_nonlinearity=g, input_params=g_params,
                            output_nonlinearity=h, output_params=h_params,
                            offset=_number(obj["offset"], f"{where}.offset"), initial_state=x0,
                            intersample=intersample, name=_string(obj["name"], f"{where}.name"),
                            delay=_delay(obj.get("delay"), f"{where}.delay", estimate=False))


def _delay(value, where: str, *, estimate: bool):
    """A saved dead time: absent (none), a number >= 0, or (in a structure) the string 'estimate'."""
    if value is None:
        return None
    if not (isinstance(value, str) and estimate):
        value = _number(value, where)
    try:
        return check_delay(value, estimate=estimate)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None


#: Most digits of an integer in a saved file (orders, counts and codes are short).
_MAX_DIGITS = 18


def _unique_object(where: str):
    """An ``object_pairs_hook`` refusing a key given twice in one object (JSON leaves that undefined)."""
    def hook(pairs):
        obj = {}
        for key, value in pairs:
            if key in obj:
                raise ParameterError(f"{where}: the field {key!r} appears twice in one object")
            obj[key] = value
        return obj
    return hook


def _parse_int(where: str):
    def parse(text: str) -> int:
        if len(text.lstrip("-")) > _MAX_DIGITS:
            raise ParameterError(f"{where}: an integer with {len(text.lstrip('-'))} digits (at most {_MAX_DIGITS})")
        return int(text)
    return parse


def _decode(data: bytes, where: str) -> str:
    """The UTF-8 text of a saved file (a BOM tolerated); UTF-16/32 or binary content is a clear error."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in data[:4096]:
        raise ParameterError(f"{where}: not a UTF-8 text file (binary, or UTF-16/32 encoded); model and result "
                             "files are UTF-8 JSON")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ParameterError(f"{where}: not UTF-8 text (byte {exc.start}); model and result files are UTF-8 "
                             "JSON") from None


def _read(path) -> dict:
    """The JSON object of a model or result file, read strictly (module notes) and within a size limit."""
    from .._safe_io import MAX_DOCUMENT_BYTES, read_bytes

    where = str(path)

    def reject(constant):
        raise ParameterError(f"{where}: the non-standard JSON constant {constant} is not allowed "
                             "(non-finite figures are written as the strings 'inf', '-inf', 'nan')")

    text = _decode(read_bytes(path, limit=MAX_DOCUMENT_BYTES, what="model or result file"), where)
    try:
        return json.loads(text, parse_constant=reject, parse_int=_parse_int(where),
                          object_pairs_hook=_unique_object(where))
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{where}: not valid JSON ({exc})") from None
    except RecursionError:
        raise ParameterError(f"{where}: JSON nested too deeply to be a model or result file") from None


def load_model(path):
    """Read a model written by :func:`save_model` (or the model of a result file).

    Raises
    ------
    ParameterError, UnknownNameError
        With a message naming the offending field.
    FileNotFoundError
        If ``path`` does not exist.

    Examples
    --------
    >>> import os, tempfile, hammerstein_ctrl as hc
    >>> path = os.path.join(tempfile.mkdtemp(), "model.json")
    >>> hc.HammersteinModel(([1.0], [1.0, 2.0]), hc.Tanh(), [1.0, 0.5]).save(path)
    >>> load_model(path).params.tolist()
    [1.0, 0.5]
    """
    return _model_from_file(_read(path), path)


def _model_from_file(obj, path):
    if isinstance(obj, dict) and obj.get("format") == RESULT_FORMAT:
        _header(obj, RESULT_FORMAT, str(path))
    else:
        _header(obj, MODEL_FORMAT, str(path))
        _keys(obj, str(path), ("format", "schema_version", "model"))
    return model_from_dict(obj.get("model"), f"{path}: model")


