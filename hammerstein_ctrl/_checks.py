"""Small input-validation helpers shared by the data, model and simulation modules."""

from __future__ import annotations

import math

import numpy as np

from .exceptions import DataError, ParameterError

__all__ = ["signal_names",
           "GRID_TOLERANCE", "INTERSAMPLE", "MAX_ORDER", "MAX_MAGNITUDE", "check_intersample", "as_signal",
           "as_real_array", "as_count", "check_transfer_function", "uniform_grid", "check_delay", "ESTIMATE",
           "as_channels", "require_siso_model"]

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

#: Largest magnitude of a model's number (a coefficient, parameter or gain) the package computes with:
#: beyond it, the product of two overflows.
MAX_MAGNITUDE = 1e100

#: Intersample behaviours of an input (MATLAB ``iddata`` ``InterSample``).
INTERSAMPLE = ("foh", "zoh")


def signal_names(names, what: str) -> list[str]:
    """``names`` as python-control signal names, refused in one line where python-control would refuse them.

    Examples
    --------
    >>> signal_names(["motor_a", "u[1]"], "input")
    ['motor_a', 'u[1]']
    >>> signal_names(["motor.a"], "input")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: input name 'motor.a' contains '.', ... (e.g. 'motor_a')
    """
    names = [names] if isinstance(names, str) else list(names)
    for name in names:
        if not isinstance(name, str) or not name:
            raise ParameterError(f"{what} names must be non-empty strings, got {name!r}")
        if "." in name:
            raise ParameterError(f"{what} name {name!r} contains '.', which python-control does not allow in a "
                                 f"signal name: rename the channel (e.g. {name.replace('.', '_')!r})")
    return names


def check_intersample(value) -> str:
    """Return ``"foh"`` or ``"zoh"`` (case-insensitive) or raise a :class:`DataError`."""
    if value == "foh" or value == "zoh":        # the usual case, on every simulation call
        return value
    key = str(value).strip().lower()
    if key not in INTERSAMPLE:
        raise DataError(f"intersample must be one of {INTERSAMPLE}, got {value!r}")
    return key


def as_signal(x, name: str, *, allow_empty: bool = False) -> np.ndarray:
    """Return ``x`` as a finite 1-D float array or raise a :class:`DataError`.

    Column vectors such as MATLAB's ``(N, 1)`` arrays are flattened.  Complex,
    object and string arrays are rejected (never silently cast); so is a
    masked array with masked samples (a mask cannot be honoured by a
    simulation: fill or cut them first).
    """
    if isinstance(x, np.ma.MaskedArray):
        masked = int(np.ma.getmaskarray(x).sum())
        if masked:
            raise DataError(f"{name} has {masked} masked sample(s); a signal cannot skip samples: fill them "
                            f"({name}.filled(value)) or cut the record around them")
        x = np.ma.getdata(x)
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


def as_count(value, name: str, *, minimum: int = 0) -> int:
    """``value`` as an int (an integral float such as ``2.0`` passes) or a :class:`ParameterError` naming ``name``.

    Booleans, text, fractions, non-finite numbers and integers beyond 2**63
    are refused rather than cast.

    Examples
    --------
    >>> as_count(3.0, "den_order")
    3
    >>> as_count("a", "num_order")
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: num_order must be a non-negative integer, got 'a'
    """
    ok = isinstance(value, (int, np.integer, float, np.floating)) and not isinstance(value, (bool, np.bool_))
    try:
        ok = ok and float(value) == int(value) and minimum <= int(value) < 2**63
    except (ValueError, OverflowError):       # nan, inf, an int beyond any float
        ok = False
    if not ok:
        kind = {0: "a non-negative integer", 1: "a positive integer"}.get(minimum, f"an integer >= {minimum}")
        shown = repr(value)
        raise ParameterError(f"{name} must be {kind}, got {shown if len(shown) <= 40 else shown[:40] + '...'}")
    return int(value)


def require_siso_model(model, what: str, hint: str = ""):
    """``model`` if it (or the model of a result) has one input and one output; a MIMO one is refused in one line
    (``hint``: what else to use, appended to the message).

    Examples
    --------
    >>> require_siso_model(object(), "tune_pid") is not None
    True
    """
    inner = model.model if getattr(model, "is_identification_result", False) else model
    if getattr(inner, "n_inputs", 1) * getattr(inner, "n_outputs", 1) > 1 and hasattr(inner, "element"):
        raise ParameterError(f"{what} takes a SISO model; this one has {inner.n_inputs} inputs and "
                             f"{inner.n_outputs} outputs: pick one channel pair with model.element(output, "
                             f"input){hint}")
    return model


#: Most channels a signal may have: a wider array is taken as transposed (samples along the rows).
MAX_CHANNELS = 64


def as_channels(x, name: str) -> np.ndarray:
    """``x`` as a finite signal: 1-D ``(N,)`` for one channel, ``(N, m)`` float columns for several.

    A 2-D array with more than one column holds one channel per column (each
    checked as :func:`as_signal` checks a signal, its errors naming the column);
    one with more columns than rows and more than :data:`MAX_CHANNELS` columns
    is refused as a likely transposition.

    Examples
    --------
    >>> as_channels([[1, 2], [3, 4], [5, 6]], "u").shape
    (3, 2)
    >>> as_channels([[1], [2]], "u").shape
    (2,)
    """
    if isinstance(x, np.ma.MaskedArray):
        if np.ma.getmaskarray(x).any():
            return as_signal(x, name)                   # refused there, naming the masked samples
        x = np.ma.getdata(x)
    raw = x
    try:
        shape = np.shape(raw)
    except ValueError:                          # a ragged nested list
        raise DataError(f"{name} has rows of different lengths; give one row per sample with one value per "
                        "channel") from None
    if len(shape) == 2 and 0 in shape:
        raise DataError(f"{name} is empty (an array of shape {shape})")
    if len(shape) > 2:
        raise DataError(f"{name} must be one signal (N,) or channels as columns (N, m), got an array of shape "
                        f"{shape}")
    if len(shape) != 2 or 1 in shape:
        return as_signal(x, name)
    rows, cols = shape
    if cols > rows and cols > MAX_CHANNELS:
        raise DataError(f"{name} has shape {shape}: channels must be columns, one row per sample "
                        f"({cols}, {rows}); pass {name}.T")
    arr = np.asarray(raw)
    columns = [as_signal(arr[:, j], f"{name}[:, {j}]") for j in range(cols)]
    return np.ascontiguousarray(np.column_stack(columns))


def as_real_array(x, name: str) -> np.ndarray:
    """``x`` as a float array, or a :class:`ParameterError` naming ``name`` for complex or non-numeric values.

    NaN and inf pass (a cost scores them ``inf``); values are never silently cast.

    Examples
    --------
    >>> as_real_array([1, 2.5], "beta")
    array([1. , 2.5])
    >>> as_real_array([1 + 2j], "beta")
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: beta is complex; parameters must be real
    """
    raw = np.asarray(x)
    if raw.dtype.kind == "c":
        raise ParameterError(f"{name} is complex; parameters must be real")
    if raw.dtype.kind in "USV":
        raise ParameterError(f"{name} must be numbers, got text or bytes: {str(x)[:80]}")
    if raw.dtype.kind not in "biuf":
        try:
            return raw.astype(float)
        except OverflowError:
            raise ParameterError(f"{name} holds an integer too large for a float: {str(x)[:80]}") from None
        except (TypeError, ValueError):
            raise ParameterError(f"{name} must be numbers, got {str(x)[:80]}") from None
    return raw.astype(float, copy=False)


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


def check_transfer_function(num, den, name: str = "transfer function", *,
                            advice: str = "pass a control.StateSpace") -> tuple[np.ndarray, np.ndarray]:
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
                             f"realisation loses accuracy beyond it): {advice}")
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


#: Largest accepted grid ``tolerance`` (a fraction of dt): beyond half a step,
#: sample k could be taken for sample k +- 1.
MAX_GRID_TOLERANCE = 0.5
#: A step longer than this many typical steps is a gap (missing samples); one
#: shorter than ``2 - GAP_STEPS`` steps is an extra sample.
GAP_STEPS = 1.5
#: Longest gap (in sampling intervals) that resampling interpolates across.
MAX_RESAMPLE_GAP = 10
#: Largest ratio of resampled to original samples (guards against dt typos).
MAX_UPSAMPLING = 100
#: Significant digits of a suggested tolerance.
_SUGGESTION_DIGITS = 2


def finite_float(value, what: str, expected: str = "a finite number", *, error=DataError) -> float:
    """``value`` as a finite float, else ``error`` (a :class:`DataError`) "``what`` must be ``expected``".

    Booleans are refused (``True`` is not a number of seconds).
    """
    try:
        v = np.nan if isinstance(value, (bool, np.bool_)) else float(value)
    except (TypeError, ValueError, OverflowError):
        v = np.nan
    if not np.isfinite(v):
        shown = repr(value)
        raise error(f"{what} must be {expected}, got {shown if len(shown) <= 40 else shown[:40] + '...'}")
    return v


def check_tolerance(tolerance) -> float:
    """Return ``tolerance`` as a float in ``[0, 0.5)`` or raise a :class:`DataError`."""
    expected = f"in [0, {MAX_GRID_TOLERANCE:g}) (a fraction of dt)"
    tol = finite_float(tolerance, "tolerance", expected)
    if not 0.0 <= tol < MAX_GRID_TOLERANCE:
        raise DataError(f"tolerance must be {expected}, got {tolerance!r}; "
                        "for larger irregularities resample the record instead")
    return tol


def check_dt(dt, *, error=DataError) -> float:
    """Return ``dt`` as a positive finite float or raise ``error`` (a :class:`DataError`)."""
    step = finite_float(dt, "dt", "a positive finite number", error=error)
    if step <= 0:
        raise error(f"dt must be a positive finite number, got {dt!r}")
    return step


def optional_time(value, what: str) -> float | None:
    """``None`` or ``value`` as a finite float (a time in seconds), else a :class:`DataError`."""
    return None if value is None else finite_float(value, what, "a finite time in seconds")


def increasing_times(t, name: str = "t") -> np.ndarray:
    """Return ``t`` as a finite, strictly increasing 1-D array of >= 2 samples or raise."""
    t = as_signal(t, name)
    if t.size < 2:
        raise DataError(f"{name} needs at least two samples to define a sampling interval")
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        what = "a duplicated time stamp" if steps[k] == 0 else "time runs backwards"
        raise DataError(
            f"{name} is not strictly increasing: {name}[{k + 1}] = {float(t[k + 1])!r} follows "
            f"{name}[{k}] = {float(t[k])!r} ({what}); sort the samples or remove the repeated ones"
        )
    return t


def _fit_grid(t: np.ndarray, k: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Least-squares ``t ~ t0 + dt*k`` rounded to the simplest decimals; returns (t0, dt, deviation)."""
    n = k[-1] - k[0] + 1
    origin = t[0]
    tc = t - origin
    if k.size > 2:      # the least-squares line through (k, tc), on centred k (no N x 2 design matrix)
        kc = k - k.mean()
        dt = float(kc @ tc) / float(kc @ kc)
        del kc
        t0 = float(tc.mean()) - dt * float(k.mean())
    else:
        dt, t0 = (t[-1] - t[0]) / (k[-1] - k[0]), 0.0
    tc -= t0 + dt * k                   # now the deviation from the fitted line
    jitter = float(np.max(np.abs(tc)))
    t0 += origin
    dt = _simplest_decimal(float(dt), 2.0 * jitter / max(n - 1, 1))
    t0 = _simplest_decimal(float(t0), jitter)
    np.subtract(t, t0 + dt * k, out=tc)
    return t0, dt, tc


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits (a tolerance to suggest)."""
    e = int(np.floor(np.log10(x))) - (_SUGGESTION_DIGITS - 1)
    return float(f"{np.ceil(x / 10.0**e) * 10.0**e:.{_SUGGESTION_DIGITS}g}")


_RESAMPLE_HINT = ("resample='linear' or 'zoh' (--resample) to interpolate the record onto a uniform grid")
_WINDOW_HINT = "keep a part without it (start=/stop=, --start/--stop)"


def _step_anomaly(t: np.ndarray, name: str) -> str | None:
    """Describe the first gap (missing samples) or extra sample in ``t``, if any."""
    steps = np.diff(t)
    h = float(np.median(steps))
    with np.errstate(over="ignore"):
        ratio = steps / h
    odd = np.flatnonzero((ratio > GAP_STEPS) | (ratio < 2.0 - GAP_STEPS))
    if odd.size == 0:
        return None
    i = int(odd[0])
    where = (f"between sample {i} ({name} = {t[i]:.10g} s) and sample {i + 1} "
             f"({name} = {t[i + 1]:.10g} s)")
    if ratio[i] > GAP_STEPS:
        missing = f"{ratio[i] - 1:.0f}" if ratio[i] < 1e6 else "many"
        what = f"a gap: about {missing} sample(s) missing {where}, a step of {ratio[i]:.3g}*dt"
    else:
        what = f"an extra or misplaced time stamp: only {ratio[i]:.3g}*dt {where}"
    more = f" ({odd.size} irregular steps in all)" if odd.size > 1 else ""
    return (
        f"{name} is an irregular time grid (typical step dt = {h:.6g} s): {what}{more}; "
        f"pass {_RESAMPLE_HINT}, or {_WINDOW_HINT}"
    )


def _jitter_message(t, dev, dt, tolerance, name) -> str:
    j = int(np.argmax(np.abs(dev)))
    worst = abs(dev[j]) / dt
    steps = np.diff(t) / dt
    bad_steps = np.flatnonzero(np.abs(steps - 1.0) > 2.0 * tolerance)
    first = ""
    if bad_steps.size and int(bad_steps[0]) + 1 != j:
        i = int(bad_steps[0])
        first = f"; the first irregular step is from sample {i} to {i + 1} ({steps[i]:.3g}*dt)"
    hint = f"pass {_RESAMPLE_HINT}"
    if _round_up(worst) < MAX_GRID_TOLERANCE:     # only a tolerance the check accepts is suggested
        hint = (f"pass tolerance={_round_up(worst)} (--tolerance) to accept the time stamps as a uniform grid "
                f"(a noisy clock), or {_RESAMPLE_HINT}")
    return (
        f"{name} is an irregular time grid beyond tolerance={tolerance:g} (a fraction of "
        f"dt = {dt:.6g} s): sample {j} ({name} = {t[j]:.10g} s) is {worst:.3g}*dt away from the "
        f"grid t0 + k*dt{first}; {hint}"
    )


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
        If ``t`` has fewer than two samples, is not strictly increasing, has a
        gap (missing samples) or an extra sample, or is irregular beyond the
        tolerance.  The message names the offending sample and suggests the
        tolerance that would accept the grid or resampling.

    Examples
    --------
    >>> uniform_grid([0.0, 0.1, 0.2, 0.3])[1]
    0.1
    >>> uniform_grid([0.0, 0.1, 0.3, 0.4])  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.DataError: t is an irregular time grid (typical step dt = 0.1 s): a gap: about 1
    sample(s) missing between sample 1 (t = 0.1 s) and sample 2 (t = 0.3 s), a step of 2*dt; pass resample='linear' or
    'zoh' (--resample) to interpolate the record onto a uniform grid, or keep a part without it (start=/stop=,
    --start/--stop)
    """
    t = increasing_times(t, name)
    tolerance = check_tolerance(tolerance)
    anomaly = _step_anomaly(t, name)
    if anomaly is not None:
        raise DataError(anomaly)
    k = np.arange(t.size)
    t0, dt, dev = _fit_grid(t, k)
    if np.max(np.abs(dev)) > tolerance * dt:
        raise DataError(_jitter_message(t, dev, dt, tolerance, name))
    return t0 + dt * k, dt


def resampling_grid(t, dt=None, *, name: str = "t", max_gap: float = MAX_RESAMPLE_GAP) -> tuple[np.ndarray, float]:
    """A uniform grid ``t0 + k*dt`` covering the span of the increasing times ``t``.

    Without ``dt``, the sampling interval and phase are fitted to ``t`` (each
    step counted as the nearest whole number of typical steps, so dropped
    samples do not bias it), then rounded like :func:`uniform_grid`; with
    ``dt``, the grid starts at ``t[0]``.  The grid keeps the points inside
    ``[t[0], t[-1]]``.

    Raises
    ------
    DataError
        If ``t`` is not strictly increasing, a step exceeds ``max_gap`` typical
        (median) steps (interpolating across it would invent data), or the grid would have
        fewer than two or more than ``MAX_UPSAMPLING`` times as many points.

    Examples
    --------
    >>> grid, dt = resampling_grid([0.0, 0.101, 0.199, 0.4, 0.502])
    >>> dt, grid.round(12).tolist()
    (0.1, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    """
    t = increasing_times(t, name)
    steps = np.diff(t)
    h = float(np.median(steps))
    i = int(np.argmax(steps))
    if steps[i] > max_gap * h:
        raise DataError(
            f"{name} has a gap of {steps[i] / h:.3g}*dt (typical step dt = {h:.6g} s) between sample {i} "
            f"({name} = {t[i]:.10g} s) and "
            f"sample {i + 1} ({name} = {t[i + 1]:.10g} s), longer than the {max_gap:g}*dt that "
            f"resampling interpolates across; {_WINDOW_HINT}"
        )
    if dt is None:
        k = np.concatenate([[0.0], np.cumsum(np.rint(steps / h))])
        t0, dt, _ = _fit_grid(t, k)
    else:
        t0, dt = float(t[0]), check_dt(dt)
    span = (t[-1] - t0) / dt
    if span > MAX_UPSAMPLING * t.size:
        raise DataError(
            f"dt = {dt:g} s would resample {t.size} samples spanning {t[-1] - t[0]:g} s into "
            f"{span:.3g} points (more than {MAX_UPSAMPLING}x); check dt"
        )
    eps = 1e-9
    first = int(np.ceil((t[0] - t0) / dt - eps))
    last = int(np.floor(span + eps))
    if last - first < 1:
        raise DataError(f"dt = {dt:g} s leaves fewer than two samples in the record's {t[-1] - t[0]:g} s")
    return t0 + dt * np.arange(first, last + 1), dt


#: The value of ``delay`` that asks for the dead time to be estimated.
ESTIMATE = "estimate"


#: Shortest dead time taken (seconds); a shorter positive one is refused rather than read as none.
MIN_DELAY = 1e-12


def check_delay(value, *, estimate: bool = True):
    """A dead time: a finite float ``>= 0``, or ``"estimate"`` when ``estimate`` allows it.

    ``None`` means no delay (0.0).

    Examples
    --------
    >>> check_delay(None), check_delay(0.25), check_delay("Estimate")
    (0.0, 0.25, 'estimate')
    >>> check_delay(-1)
    Traceback (most recent call last):
    ...
    hammerstein_ctrl.exceptions.ParameterError: delay must be a finite number >= 0 (seconds) or 'estimate', got -1
    """
    if value is None:
        return 0.0
    if isinstance(value, str):
        if estimate and value.strip().lower() == ESTIMATE:
            return ESTIMATE
    elif not isinstance(value, bool):
        try:
            tau = float(value)
        except (TypeError, ValueError, OverflowError):
            tau = math.nan
        if 0 < tau < MIN_DELAY:
            raise ParameterError(f"delay {tau!r} s is below {MIN_DELAY:g} s, too short to mean a dead time (its "
                                 "Pade approximant would divide by zero): give 0 for none")
        if math.isfinite(tau) and 0 <= tau <= MAX_MAGNITUDE:
            return tau
    allowed = " or 'estimate'" if estimate else ""
    raise ParameterError(f"delay must be a finite number >= 0 (seconds){allowed}, got {value!r}")
