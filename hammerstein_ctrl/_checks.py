"""Small input-validation helpers shared by the data, model and simulation modules."""

from __future__ import annotations

import numpy as np

from .exceptions import DataError, ParameterError

__all__ = ["GRID_TOLERANCE", "INTERSAMPLE", "MAX_ORDER", "check_intersample", "as_signal",
           "check_transfer_function", "uniform_grid"]

#: Largest allowed deviation of a sample time from the uniform grid ``t0 + k*dt``,
#: as a fraction of ``dt``.  Grids within this tolerance are regularised to exactly
#: ``t0 + k*dt``; EMPS's stored ``t`` deviates by at most 3.2e-5*dt.
GRID_TOLERANCE = 1e-3


#: Highest transfer-function order simulated.  The companion (controllable
#: canonical) realisation used for transfer functions loses accuracy fast with
#: the order: against a balanced realisation, order 10 is good to ~7e-6 and
#: order 12 is off by ~5 % (python-control's own conversion behaves the same).
#: Higher orders are rejected; pass a ``control.StateSpace`` built from a
#: well-conditioned realisation instead.
MAX_ORDER = 10

#: Intersample behaviours of an input (MATLAB ``iddata`` ``InterSample``).
INTERSAMPLE = ("foh", "zoh")


def check_intersample(value) -> str:
    """Return ``"foh"`` or ``"zoh"`` (case-insensitive) or raise a :class:`DataError`."""
    key = str(value).strip().lower()
    if key not in INTERSAMPLE:
        raise DataError(f"intersample must be one of {INTERSAMPLE}, got {value!r}")
    return key


def as_signal(x, name: str, *, allow_empty: bool = False) -> np.ndarray:
    """Return ``x`` as a finite 1-D float array or raise a :class:`DataError`.

    Column vectors such as MATLAB's ``(N, 1)`` arrays are flattened.  Complex,
    object and string arrays are rejected (never silently cast).
    """
    raw = np.asarray(x)
    if raw.dtype.kind == "c":
        raise DataError(f"{name} is complex; a signal must be real (pass x.real if the imaginary "
                        "part is really meant to be dropped)")
    if raw.dtype.kind not in "biuf":
        raise DataError(f"{name} must be numeric, got an array of dtype {raw.dtype} ({raw.dtype.kind!r})")
    a = raw.astype(float, copy=False)
    if a.ndim == 2 and 1 in a.shape:
        a = a.ravel()
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise DataError(f"{name} must be a 1-D signal, got an array of shape {a.shape}")
    if a.size == 0 and not allow_empty:
        raise DataError(f"{name} is empty")
    bad = ~np.isfinite(a)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        kind = "NaN" if np.isnan(a[k]) else "inf"
        raise DataError(
            f"{name} contains {int(bad.sum())} non-finite value(s); first is {kind} at sample {k}"
        )
    return a


def _trimmed(c, label: str) -> np.ndarray:
    """1-D finite float coefficients with leading zeros removed (at least one kept)."""
    raw = np.asarray(c)
    if raw.dtype.kind not in "biuf":
        raise ParameterError(f"{label} coefficients must be real numbers, got dtype {raw.dtype}")
    if sum(d > 1 for d in raw.shape) > 1 or raw.size == 0:
        raise ParameterError(f"{label} must be a non-empty 1-D coefficient vector, got shape {raw.shape}")
    a = raw.astype(float).reshape(-1)
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"{label} has non-finite coefficients: {a.tolist()}")
    nz = np.flatnonzero(a)
    return a[nz[0]:] if nz.size else a[-1:]


def check_transfer_function(num, den, name: str = "transfer function") -> tuple[np.ndarray, np.ndarray]:
    """Validate ``num(p)/den(p)`` (highest power first) and return it with leading zeros trimmed.

    Raises
    ------
    ParameterError
        For non-finite coefficients, an all-zero denominator, an improper
        system (numerator degree above the denominator's) or an order above
        :data:`MAX_ORDER`.

    Examples
    --------
    >>> check_transfer_function([0.0, 2.0], [0.0, 1.0, 3.0])
    (array([2.]), array([1., 3.]))
    >>> check_transfer_function([1.0], [0.0, 0.0])
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: transfer function: the denominator is zero
    """
    num, den = _trimmed(num, f"{name}: numerator"), _trimmed(den, f"{name}: denominator")
    if den[0] == 0.0:
        raise ParameterError(f"{name}: the denominator is zero")
    order = den.size - 1
    if num.size > den.size:
        raise ParameterError(f"{name} is improper: numerator degree {num.size - 1} exceeds denominator "
                             f"degree {order}")
    if order > MAX_ORDER:
        raise ParameterError(f"{name} has order {order}; at most {MAX_ORDER} is supported (the companion "
                             "realisation loses accuracy beyond it): pass a control.StateSpace")
    return num, den


def _simplest_decimal(x: float, radius: float) -> float:
    """The value with the fewest significant digits within ``radius`` of ``x``."""
    if abs(x) <= radius:
        return 0.0
    for digits in range(1, 17):
        r = float(f"{x:.{digits}g}")
        if abs(r - x) <= radius:
            return r
    return x


def uniform_grid(t, name: str = "t", *, tolerance: float = GRID_TOLERANCE) -> tuple[np.ndarray, float]:
    """Check that ``t`` is a uniform time grid and return ``(t0 + k*dt, dt)``.

    ``t0`` and ``dt`` are fitted by least squares and then rounded to the
    simplest decimal consistent with the observed jitter (so a grid stored in
    single precision, such as EMPS's ``0.00100002`` spacing, gives exactly
    ``dt = 0.001`` and ``t0 = 0``).  Every sample must lie within
    ``tolerance * dt`` of ``t0 + k*dt``; the regularised grid is returned.

    Raises
    ------
    DataError
        If ``t`` has fewer than two samples, is not strictly increasing, or is
        irregular beyond the tolerance.
    """
    t = as_signal(t, name)
    if t.size < 2:
        raise DataError(f"{name} needs at least two samples to define a sampling interval")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        raise DataError(
            f"{name} is not strictly increasing: {name}[{k + 1}] = {t[k + 1]!r} "
            f"follows {name}[{k}] = {t[k]!r}"
        )
    n = t.size
    k = np.arange(n)
    dt, t0 = np.polyfit(k, t, 1) if n > 2 else (t[1] - t[0], t[0])
    jitter = float(np.max(np.abs(t - (t0 + dt * k))))
    dt = _simplest_decimal(float(dt), 2.0 * jitter / (n - 1))
    t0 = _simplest_decimal(float(t0), jitter)
    grid = t0 + dt * k
    dev = np.abs(t - grid)
    i = int(np.argmax(dev))
    if dev[i] > tolerance * dt:
        raise DataError(
            f"{name} is an irregular time grid: sample {i} is {dev[i]:.3g} s away from the uniform "
            f"grid t0 + k*dt with dt = {dt:.6g} s (allowed: {tolerance:g}*dt); resample the record "
            "onto a uniform grid first"
        )
    return grid, dt
