"""Identification results as versioned JSON: written with their record's description, covariance and verdicts, read
back (every schema since 2) into the one result type."""

from __future__ import annotations

import math
import numpy as np
from ..exceptions import ParameterError
from .._checks import INTERSAMPLE
from ..blocks._json import RESULT_FORMAT, SCHEMA_VERSION, encode_float as _encode, model_to_dict, write_json as _write
from ..fit._result import IdentificationResult
from ._persistence import (_DATA_KEYS, _RESULT_KEYS, _STATUS_VERSION, _UNCERTAINTY_KEYS, _UNCERTAINTY_VERSION, _boolean,
                           _header, _integer, _keys, _model_from_file, _number, _numbers, _read, _string,
                           _structure_from_dict, _structure_to_dict, model_from_dict)

__all__ = ["result_to_dict", "result_from_dict", "save_result", "load_result", "load_saved", "SavedResult"]


# ---------------------------------------------------------------------------
# identification results
# ---------------------------------------------------------------------------
#: The type :func:`load_result` returns: the one result type, :class:`~hammerstein_ctrl.fit.IdentificationResult`
#: (kept under this name for code written against earlier versions).
SavedResult = IdentificationResult


def _data_to_dict(data) -> dict:
    if data is None:
        return {k: None for k in _DATA_KEYS}
    out = {"name": str(getattr(data, "name", "data")), "dt": float(data.dt), "n_samples": len(data),
           "input_name": getattr(data, "input_name", "u"), "output_name": getattr(data, "output_name", "y"),
           "input_unit": getattr(data, "input_unit", ""), "output_unit": getattr(data, "output_unit", ""),
           "intersample": getattr(data, "intersample", "foh")}
    if not getattr(data, "is_siso", True):        # several channels: their names too
        out.update(input_names=list(data.input_names), output_names=list(data.output_names))
    return out


def result_to_dict(result) -> dict:
    """The JSON object of an :class:`~hammerstein_ctrl.IdentificationResult` (one just fitted or read back)."""
    structure = result.structure
    x = np.asarray(result.x, dtype=float)
    data = result.data if isinstance(result.data, dict) else _data_to_dict(getattr(result, "data", None))
    records = [r if isinstance(r, dict) else _data_to_dict(r) for r in (getattr(result, "records", None) or ())]
    return {**({"records": records} if records else {}),
        "format": RESULT_FORMAT, "schema_version": SCHEMA_VERSION,
        "model": model_to_dict(result.model), "structure": _structure_to_dict(structure),
        "params": {k: _encode(v) for k, v in zip(structure.param_names, x.tolist())},
        "beta": [_encode(v) for v in x.tolist()], "data": data,
        "J": _encode(result.fun), "fit_percent": _encode(getattr(result, "fit_percent", math.nan)),
        "rmse": _encode(getattr(result, "rmse", math.nan)), "nrmse": _encode(getattr(result, "nrmse", math.nan)),
        "nfev": int(getattr(result, "nfev", 0)), "method": str(getattr(result, "method", "")),
        "success": bool(getattr(result, "success", False)), "message": str(getattr(result, "message", "")),
        "status": _status(getattr(result, "status", None)), "elapsed_s": _encode(getattr(result, "elapsed", math.nan)),
        **_uncertainty_to_dict(result),
        **({"output_fits": {k: _encode(v) for k, v in result.output_fits.items()}}
           if getattr(result, "output_fits", None) else {}),
    }


def _uncertainty_to_dict(result) -> dict:
    cov = getattr(result, "covariance", None)
    return {"covariance": None if cov is None else [[_encode(v) for v in row] for row in np.asarray(cov).tolist()],
            "dof": None if getattr(result, "dof", None) is None else int(result.dof),
            "warnings": [str(w) for w in (getattr(result, "warnings", None) or [])]}


def _covariance_from(obj, p: int, where: str):
    """A saved covariance: ``p`` rows of ``p`` numbers ('inf'/'nan' where a parameter is undetermined),
    symmetric, with a non-negative diagonal."""
    if obj is None:
        return None
    if not isinstance(obj, list) or len(obj) != p or any(not isinstance(r, list) or len(r) != p for r in obj):
        raise ParameterError(f"{where} must be {p} rows of {p} numbers (one per parameter), or null")
    cov = np.array([[_number(v, f"{where}[{i}][{j}]", finite=False) for j, v in enumerate(r)]
                    for i, r in enumerate(obj)])
    diag = np.diag(cov)
    if np.any(diag < 0) or np.isnan(diag).any():
        raise ParameterError(f"{where}: the variances (its diagonal) must be non-negative, got {diag.tolist()}")
    finite = np.isfinite(cov) & np.isfinite(cov.T)
    if not np.allclose(cov[finite], cov.T[finite], rtol=1e-9, atol=0):
        raise ParameterError(f"{where} must be symmetric")
    return cov


def _uncertainty_from(obj, version: int, p: int, where: str) -> dict:
    if version < _UNCERTAINTY_VERSION:
        return {}
    warnings = obj["warnings"]
    if not isinstance(warnings, list):
        raise ParameterError(f"{where}: warnings must be a list of strings, got {warnings!r}")
    dof = None if obj["dof"] is None else _integer(obj["dof"], f"{where}: dof")
    if dof is not None and dof < 1:
        raise ParameterError(f"{where}: dof must be a positive integer, got {dof}")
    covariance = _covariance_from(obj["covariance"], p, f"{where}: covariance")
    if covariance is not None and dof is None:
        raise ParameterError(f"{where}: dof is null beside a covariance: the intervals need the residuals' degrees "
                             "of freedom (N - p)")
    return {"covariance": covariance, "dof": dof,
            "warnings": [_string(w, f"{where}: warnings[{i}]") for i, w in enumerate(warnings)]}


def _status_code(value, where: str) -> int:
    from ..optimize import STATUS_CODES

    code = _integer(value, where)
    if code not in STATUS_CODES:
        raise ParameterError(f"{where} must be one of the optimisers' codes {list(STATUS_CODES)}, got {code}")
    return code


def _status(status) -> int | None:
    return None if status is None else int(status)


def _data_from_dict(obj, where: str) -> dict:
    _keys(obj, where, _DATA_KEYS, ("input_names", "output_names"))
    out = dict(obj)
    for key in ("input_names", "output_names"):
        if key in obj and (not isinstance(obj[key], list) or not all(isinstance(v, str) for v in obj[key])):
            raise ParameterError(f"{where}.{key} must be a list of channel names")
    if obj["dt"] is not None:
        out["dt"] = _number(obj["dt"], f"{where}.dt")
        if out["dt"] <= 0:
            raise ParameterError(f"{where}.dt must be a positive sampling interval, got {out['dt']!r}")
    if obj["n_samples"] is not None:
        out["n_samples"] = _integer(obj["n_samples"], f"{where}.n_samples", minimum=1)
    for key in ("name", "input_name", "output_name", "input_unit", "output_unit", "intersample"):
        if out[key] is not None:
            _string(out[key], f"{where}.{key}")
    if out["intersample"] is not None and out["intersample"] not in INTERSAMPLE:
        raise ParameterError(f"{where}.intersample must be one of {list(INTERSAMPLE)}, got {out['intersample']!r}")
    return out


def result_from_dict(obj, where: str = "result") -> IdentificationResult:
    """Build an :class:`~hammerstein_ctrl.fit.IdentificationResult` from the object written by
    :func:`result_to_dict` (``data``: the record's description; ``saved``: its status and dof)."""
    version = _header(obj, RESULT_FORMAT, where)
    _keys(obj, where, _RESULT_KEYS + (("status",) if version >= _STATUS_VERSION else ())
          + (_UNCERTAINTY_KEYS if version >= _UNCERTAINTY_VERSION else ()), ("records", "output_fits"))
    model = model_from_dict(obj["model"], f"{where}: model")
    structure = _structure_from_dict(obj["structure"], f"{where}: structure")
    beta = _numbers(obj["beta"], f"{where}: beta")
    if beta.size != structure.n_params:
        raise ParameterError(f"{where}: beta has {beta.size} entries, the structure has {structure.n_params}")
    params = _keys(obj["params"], f"{where}: params", structure.param_names)
    named = np.array([_number(params[k], f"{where}: params.{k}") for k in structure.param_names])
    if not np.array_equal(named, beta):
        raise ParameterError(f"{where}: params {params} disagree with beta {beta.tolist()}")
    joint = hasattr(structure, "n_records")
    own = structure.local(beta, 0) if joint else beta          # a joint fit's model: its first record's
    if not np.allclose((structure.base if joint else structure).beta(model), own, rtol=1e-12, atol=0):
        raise ParameterError(f"{where}: the model does not have the parameters beta = {own.tolist()}")
    records = _records_from(obj, structure, where) if joint else ()
    extra = _uncertainty_from(obj, version, structure.n_params, where)
    saved = {"status": None if obj.get("status") is None else _status_code(obj["status"], f"{where}: status")}
    if "dof" in extra:
        saved["dof"] = extra.pop("dof")
    return IdentificationResult(
        model=model, structure=structure, x=beta, fun=_number(obj["J"], f"{where}: J", finite=False),
        fit_percent=_number(obj["fit_percent"], f"{where}: fit_percent", finite=False),
        rmse=_number(obj["rmse"], f"{where}: rmse", finite=False),
        nrmse=_number(obj["nrmse"], f"{where}: nrmse", finite=False),
        nfev=_integer(obj["nfev"], f"{where}: nfev", minimum=0), method=_string(obj["method"], f"{where}: method"),
        success=_boolean(obj["success"], f"{where}: success"),
        message=_string(obj["message"], f"{where}: message"),
        elapsed=_number(obj["elapsed_s"], f"{where}: elapsed_s", finite=False),
        data=_data_from_dict(obj["data"], f"{where}: data"), history={}, optimize_result=None, saved=saved,
        records=records, models=tuple(structure.model(beta, k, intersample=r["intersample"] or "foh", name=r["name"])
                                      for k, r in enumerate(records)),
        output_fits=_output_fits(obj.get("output_fits"), where, getattr(model, "output_names", None)), **extra,
    )


def _output_fits(obj, where: str, names) -> dict:
    if obj is None:
        return {}
    loop = ["y (in loop)", "u (in loop)"]         # a fit inside a known loop: the loop's two signals
    allowed = [list(names)] if names is not None else []
    if not isinstance(obj, dict) or list(obj) not in allowed + [loop]:
        expected = " or ".join(str(a) for a in allowed + [loop])
        raise ParameterError(f"{where}: output_fits must map the model's outputs ({expected}) to fit percentages")
    return {str(k): _number(v, f"{where}: output_fits.{k}", finite=False) for k, v in obj.items()}


def _records_from(obj, structure, where: str) -> tuple:
    """The descriptions of a joint fit's records, one per record of its structure."""
    records = obj.get("records")
    if not isinstance(records, list) or len(records) != structure.n_records:
        raise ParameterError(f"{where}: records must list the {structure.n_records} records of the fit")
    return tuple(_data_from_dict(r, f"{where}: records[{k}]") for k, r in enumerate(records))


def save_result(result, path) -> None:
    """Write an identification result to ``path`` (see :func:`result_to_dict`).

    Examples
    --------
    >>> import os, tempfile, numpy as np, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> t = np.arange(300) * 0.1
    >>> y = s.model([2.0, 3.0]).simulate(t, np.sin(t)) + 1e-3 * np.cos(7 * t)
    >>> res = hc.identify(hc.IOData(np.sin(t), y, dt=0.1), s)
    >>> path = os.path.join(tempfile.mkdtemp(), "result.json")
    >>> save_result(res, path)
    >>> load_result(path).structure.param_names
    ('a0', 'd1')
    """
    _write(result_to_dict(result), path)


def load_result(path) -> IdentificationResult:
    """Read a result written by :func:`save_result`.

    Examples
    --------
    >>> import os, tempfile, numpy as np, hammerstein_ctrl as hc
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> t = np.arange(300) * 0.1
    >>> y = s.model([2.0, 3.0]).simulate(t, np.sin(t)) + 1e-3 * np.cos(7 * t)
    >>> res = hc.identify(hc.IOData(np.sin(t), y, dt=0.1), s)
    >>> path = os.path.join(tempfile.mkdtemp(), "result.json")
    >>> save_result(res, path)
    >>> np.allclose(load_result(path).x, res.x)
    True
    """
    return result_from_dict(_read(path), str(path))


def load_saved(path):
    """A model file's model, or a result file's :class:`~hammerstein_ctrl.IdentificationResult` (the file read
    once, by its ``format``).

    Raises
    ------
    ParameterError, UnknownNameError, DataError
        As :func:`load_model` and :func:`load_result`.
    """
    obj = _read(path)
    if isinstance(obj, dict) and obj.get("format") == RESULT_FORMAT:
        return result_from_dict(obj, str(path))
    return _model_from_file(obj, path)
