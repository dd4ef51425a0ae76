"""Simulation of MIMO block models: the input maps, the linear elements in one compiled batch (each with its dead
time), the output maps; and the signal and channel checks the MIMO structures and models share."""

from __future__ import annotations

import warnings
import numpy as np
from .._checks import check_delay
from ..exceptions import ChannelWarning, DataError, ParameterError
from ._nonlinearities import Nonlinearity
from ._structure import LinearStructure

__all__ = ["simulate_mimo_batch", "observable_realization"]


def _nonlinearity_list(value, count, label: str) -> tuple:
    """One nonlinearity per channel: a list of them, or one family for every channel."""
    if value is None:
        return None
    if not isinstance(value, Nonlinearity) and not isinstance(value, (list, tuple)):
        raise ParameterError(f"{label} must be a list of Nonlinearity objects (one per channel), got "
                             f"{type(value).__name__}")
    items = [value] * count if isinstance(value, Nonlinearity) else list(value)
    for k, nl in enumerate(items):
        if not isinstance(nl, Nonlinearity):
            raise ParameterError(f"{label}[{k}] must be a Nonlinearity, got {type(nl).__name__}")
    if len(items) != count:
        raise ParameterError(f"{label} has {len(items)} nonlinearities for {count} channels")
    return tuple(items)


def _signal_names(names, count: int, prefix: str, label: str) -> tuple:
    """``count`` distinct signal names (strings), python-control's ``u[j]`` by default."""
    if names is None:
        return tuple(f"{prefix}[{k}]" for k in range(count))
    if isinstance(names, str) or not all(isinstance(n, str) and n for n in names):
        raise ParameterError(f"{label} must be a list of {count} non-empty strings, got {names!r}")
    names = tuple(names)
    if len(names) != count or len(set(names)) != count:
        raise ParameterError(f"{label} must be {count} distinct names, got {list(names)}")
    return names


def _channel_order(model_names, record_names, what: str, record: str) -> np.ndarray:
    """For each of the model's channels, the record's column holding it (matched by name)."""
    if len(model_names) != len(record_names):
        raise DataError(f"record {record!r} has {len(record_names)} {what}(s) {list(record_names)}; the model has "
                        f"{len(model_names)} {list(model_names)}")
    if tuple(model_names) == tuple(record_names):
        return np.arange(len(model_names))
    if set(model_names) == set(record_names):
        return np.array([list(record_names).index(n) for n in model_names])
    prefix = "u" if what == "input" else "y"
    default = tuple(f"{prefix}[{k}]" for k in range(len(model_names)))
    singles = (prefix,)
    if tuple(record_names) in (default, singles) or tuple(model_names) in (default, singles):
        if len(model_names) > 1:                          # unnamed on one side: by position, said aloud
            pairs = ", ".join(f"{m} = {r!r}" for m, r in zip(model_names, record_names))
            warnings.warn(f"record {record!r} and the model name their {what}s differently ({list(record_names)} "
                          f"and {list(model_names)}), one side with default names: matched by position ({pairs}); "
                          f"give both the same names to match them by name", ChannelWarning, stacklevel=3)
        return np.arange(len(model_names))
    raise DataError(f"record {record!r} names its {what}s {list(record_names)}, the model {list(model_names)}: "
                    f"rename them (IOData(..., {what}_name=[...])) so they match")


def _polynomial_text(c) -> str:
    """``[1, 3, 2]`` as ``p^2 + 3 p + 2`` (descending powers; zero terms left out)."""
    c = np.trim_zeros(np.asarray(c, dtype=float), "f")
    n = c.size - 1
    terms = []
    for k, v in enumerate(c):
        power = n - k
        if v == 0:
            continue
        p = "" if power == 0 else ("p" if power == 1 else f"p^{power}")
        coef = "" if (v == 1 and p) else f"{v:.6g}"
        terms.append(f"{coef} {p}".strip())
    return " + ".join(terms).replace("+ -", "- ") or "0"


def _check_linear(linear) -> LinearStructure:
    if not isinstance(linear, LinearStructure):
        raise ParameterError(f"linear must be a LinearStructure (the orders of every element), got "
                             f"{type(linear).__name__}")
    extra = {k: v for k, v in linear.fixed.items() if k != f"b{linear.num_order}"}
    if extra or not linear.monic_numerator or linear.delay:
        raise ParameterError("a MIMO structure takes the orders of its LinearStructure only (no fixed "
                             "coefficients or monic_numerator yet; dead times per input are the structure's "
                             "delay=): LinearStructure(num_order, den_order)")
    return linear


def _input_delays(delay, m: int) -> tuple:
    """One dead time per input (seconds, or ``"estimate"``) from one value for all or a sequence."""
    if delay is None or isinstance(delay, (str, int, float, np.integer, np.floating)):
        return (check_delay(delay),) * m
    if not isinstance(delay, (list, tuple, np.ndarray)):
        raise ParameterError(f"delay must be a number of seconds, 'estimate', or a list of them (one per input), "
                             f"got {delay!r}")
    values = list(delay)
    if len(values) != m:
        raise ParameterError(f"delay has {len(values)} values for {m} inputs: give one per input, or one for all")
    return tuple(check_delay(v) for v in values)


# -- simulation ----------------------------------------------------------------------------
def _buffer(workspace, key: str, shape: tuple) -> np.ndarray:
    """An array of ``shape`` from ``workspace`` (a dict kept by the caller), made once per shape."""
    if workspace is None:
        return np.empty(shape)
    a = workspace.get(key)
    if a is None or a.shape != shape:
        a = workspace[key] = np.empty(shape)
    return a


def _input_signals(inputs, input_nonlinearities, input_params, batch: int, workspace=None) -> np.ndarray:
    """``(batch, m, N)``: each candidate's ``g_j(u_j)`` (or the inputs themselves).

    The channels are read as contiguous rows (``inputs.T``; free when ``inputs``
    is the transpose of a C-ordered ``(m, N)`` array, as :class:`~hammerstein_ctrl.fit.MIMOCost` keeps
    it): a strided column makes a nonlinearity's evaluation several times slower.
    """
    U = np.ascontiguousarray(np.asarray(inputs, dtype=float).T)
    m, n_samples = U.shape
    if input_nonlinearities is None:
        return np.broadcast_to(U, (batch, m, n_samples))
    V = _buffer(workspace, "V", (batch, m, n_samples))
    with np.errstate(all="ignore"):
        for j, nl in enumerate(input_nonlinearities):
            params = nl.check_params(np.asarray(input_params[j], dtype=float).reshape(batch, -1))
            for b in range(batch):          # one candidate at a time: its temporaries stay in cache
                V[b, j] = nl._evaluate(U[j], params[b])
    return V


def simulate_mimo_batch(num, den, inputs, dt: float, *, input_nonlinearities=None, input_params=None,
                        output_nonlinearities=None, output_params=None, offsets=None,
                        intersample: str = "foh", workspace: dict | None = None, delays=None) -> np.ndarray:
    """Outputs ``(B, p, N)`` of a batch of MIMO block models, exact under FOH/ZOH.

    Parameters
    ----------
    num, den : array_like, shapes (B, p, m, nb+1) and (B, p, nf+1)
        Numerators of every element and each row's denominator (descending powers).
    inputs : ndarray, shape (N, m)
    dt : float
    input_nonlinearities, output_nonlinearities : sequences of Nonlinearity, optional
    input_params, output_params : lists of arrays ``(B, n_j)``, optional
    offsets : array_like, shape (B, p), optional
    intersample : {"foh", "zoh"}
    workspace : dict, optional
        Buffers reused from call to call (a cost keeps one); the result is
        then one of them, overwritten by the next call.
    delays : array_like, shape (B, m), optional
        Each candidate's dead time per input (seconds; exact fractional
        delays, :func:`~hammerstein_ctrl.simulate._delay.delayed_response`); a negative
        or non-finite one gives that candidate NaN outputs.

    Examples
    --------
    Element ``(i, j)`` of the result is what python-control gives for that element alone:

    >>> import numpy as np, control as ct
    >>> t = np.arange(200) * 0.05; u = np.column_stack([np.sin(t), np.cos(2 * t)])
    >>> num = np.array([[[[1.0], [0.5]]]]); den = np.array([[[1.0, 2.0]]])
    >>> y = simulate_mimo_batch(num, den, u, 0.05)[0, 0]
    >>> ref = sum(ct.forced_response(ct.tf(b, [1, 2.0]), t, u[:, j]).outputs for j, b in enumerate([1.0, 0.5]))
    >>> bool(np.allclose(y, ref, rtol=1e-10, atol=1e-12))
    True
    """
    from ..simulate._simulate import simulate_batch

    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    batch, p, m = num.shape[:3]
    V = _input_signals(inputs, input_nonlinearities, input_params, batch, workspace)
    n_samples = V.shape[-1]
    # the row's m elements side by side in one compiled pass (their signals one row each)
    S = np.ascontiguousarray(V).reshape(batch * m, n_samples)
    Y = _buffer(workspace, "Y", (batch, p, n_samples))
    out = _buffer(workspace, "Z", (batch * m, n_samples))
    delays = None if delays is None else np.asarray(delays, dtype=float).reshape(batch, m)
    for i in range(p):
        Z = simulate_batch(num[:, i].reshape(batch * m, -1), np.repeat(den[:, i], m, axis=0), S, dt,
                           intersample=intersample, out=out).reshape(batch, m, n_samples)
        if delays is not None:
            _delayed_elements(Z, num[:, i], den[:, i], V, dt, delays, intersample)
        row = Y[:, i]
        np.copyto(row, Z[:, 0])
        for j in range(1, m):
            row += Z[:, j]
    if output_nonlinearities is not None:
        with np.errstate(all="ignore"):
            for i, nl in enumerate(output_nonlinearities):
                Y[:, i] = nl(Y[:, i], np.asarray(output_params[i], dtype=float).reshape(batch, -1))
    if offsets is not None:
        Y += np.asarray(offsets, dtype=float).reshape(batch, p, 1)
    return Y


def _delayed_elements(Z, num, den, V, dt, delays, intersample):
    """Overwrite the responses ``Z[b, j]`` of the elements whose input has a dead time with the exact delayed ones."""
    from ..simulate._delay import delayed_response

    for b, j in zip(*np.nonzero(delays != 0)):
        tau = delays[b, j]
        if not (np.isfinite(tau) and tau >= 0 and np.all(np.isfinite(num[b, j])) and np.all(np.isfinite(den[b]))
                and den[b, 0] != 0):
            Z[b, j] = np.nan
            continue
        with np.errstate(all="ignore"):
            Z[b, j] = delayed_response(num[b, j], den[b], V[b, j], dt, float(tau), intersample=intersample)


def observable_realization(num, den):
    """``(A, B, C, D)`` of a MIMO block ``[B_ij/F_i]`` with one observable canonical form per row.

    Row ``i`` gets ``deg F_i`` states (its modes are shared by every input),
    so the realisation has ``p * deg F`` states.  Each row's block is
    observable; the whole need not be minimal: rows with the same modes (two
    outputs of one second-order plant) repeat them, and a zero common to a
    row's elements leaves a mode uncontrollable.  ``control.minreal`` of
    :meth:`MIMOModel.to_ss` removes them before a controller design.

    Examples
    --------
    >>> A, B, C, D = observable_realization([[[1.0], [2.0]]], [[1.0, 3.0]])
    >>> A.tolist(), B.tolist(), C.tolist(), D.tolist()
    ([[-3.0]], [[1.0, 2.0]], [[1.0]], [[0.0, 0.0]])
    """
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    p, m = num.shape[:2]
    n = den.shape[1] - 1
    A, B = np.zeros((p * n, p * n)), np.zeros((p * n, m))
    C, D = np.zeros((p, p * n)), np.zeros((p, m))
    for i in range(p):
        f = den[i] / den[i, 0]
        s = slice(i * n, (i + 1) * n)
        block = np.zeros((n, n))
        block[:, 0] = -f[1:]
        block[:n - 1, 1:] = np.eye(n - 1)
        A[s, s] = block
        C[i, i * n] = 1.0
        for j in range(m):
            b = np.concatenate([np.zeros(n + 1 - num[i, j].size), num[i, j]]) / den[i, 0]
            D[i, j] = b[0]
            B[s, j] = b[1:] - b[0] * f[1:]
    return A, B, C, D
