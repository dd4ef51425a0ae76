"""The validated input/output record :class:`IOData` and its preprocessing.

A record from a real rig rarely arrives ready to identify: the time stamps
jitter or a sample was dropped, the interesting part is a window of a longer
run, the output sits on an offset or drifts.  :class:`IOData` holds a record on
an exactly uniform grid and offers the usual preparations, each returning a new
record:

* ``IOData(u, y, t, resample="linear")`` builds a record from jittered or gappy
  time stamps by interpolation (see :meth:`IOData.resample` for the methods);
* :meth:`IOData.window` keeps ``start <= t < stop`` (seconds);
* :meth:`IOData.detrend` removes the mean or a straight line;
* :meth:`IOData.remove_offset` subtracts given constants (or the first sample);
* :meth:`IOData.check_identifiable` rejects records with nothing to identify.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.data import IOData
>>> d = IOData(u=np.zeros(5), y=np.arange(5.0), dt=0.5, name="toy")
>>> d
IOData('toy', N=5, dt=0.5 s, t=[0, 2] s)
>>> u, y = d
>>> d[1:3].t
array([0.5, 1. ])
>>> d.window(0.5, 1.5).y
array([1., 2.])
>>> d.detrend().y
array([-2., -1.,  0.,  1.,  2.])
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks import (GRID_TOLERANCE, as_channels, as_signal, check_dt, check_intersample, check_tolerance,
                       finite_float, optional_time, resampling_grid, uniform_grid)
from ..exceptions import DataError, ParameterError

__all__ = ["IOData", "RESAMPLE_METHODS", "DETREND_KINDS", "time_and_input"]

#: Interpolation methods of :meth:`IOData.resample` (for the input; the output
#: is always interpolated linearly).
RESAMPLE_METHODS = ("linear", "zoh")
#: Trends :meth:`IOData.detrend` removes.
DETREND_KINDS = ("constant", "linear")
_SIGNAL_CHOICES = ("y", "u", "both")
#: A time stamp this fraction of dt after a grid point counts as on it (ZOH lookup).
_ON_GRID = 1e-9


def _check_choice(value, choices, what: str) -> str:
    key = str(value).strip().lower()
    if key not in choices:
        raise DataError(f"{what} must be one of {choices}, got {value!r}")
    return key


def _linear(grid, t, x):
    """``x`` (one channel, or channels as columns) interpolated linearly at ``grid``."""
    if x.ndim == 1:
        return np.interp(grid, t, x)
    return np.column_stack([np.interp(grid, t, x[:, j]) for j in range(x.shape[1])])


def _interpolate(t, u, y, grid, method: str, dt: float):
    """Values of ``u`` (linear or held) and ``y`` (linear) at the times ``grid``."""
    y_new = _linear(grid, t, y)
    if method == "linear":
        return _linear(grid, t, u), y_new
    idx = np.searchsorted(t, grid + _ON_GRID * dt, side="right") - 1
    return u[np.clip(idx, 0, t.size - 1)], y_new


def _channel_labels(value, count: int, default: str, what: str, unique: bool = True) -> tuple:
    """One label per channel: a sequence of ``count`` strings, or one string (indexed ``name[k]`` for several)."""
    if value is None:
        value = default
    if isinstance(value, str):
        return (value,) if count == 1 else tuple(f"{value}[{k}]" for k in range(count))
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise DataError(f"{what} must be a string or a list of strings (one per channel), got {value!r}")
    labels = tuple(value)
    if len(labels) != count:
        raise DataError(f"{what} has {len(labels)} label(s) {list(labels)} for {count} channel(s)")
    if unique and len(set(labels)) != len(labels):
        raise DataError(f"{what} repeats a label: {list(labels)}")
    return labels


class IOData:
    """An input/output record on a uniform time grid, with one or several channels.

    Parameters
    ----------
    u, y : array_like, shape (N,) or (N, m) and (N, p)
        Input and output samples (``(N, 1)`` columns are accepted).  A 2-D
        array holds one channel per column: a record of a MIMO plant
        (:mod:`~hammerstein_ctrl.blocks`).
    t : array_like, shape (N,), optional
        Sample times, strictly increasing.  Without ``resample`` they must be
        uniform to within ``tolerance * dt`` and are regularised to exactly
        ``t0 + k*dt``; with ``resample`` they may jitter or have short gaps.
    dt : float, optional
        Sampling interval, used when ``t`` is not given (``t = k*dt``), or the
        interval of the resampled grid.
    name : str
        Label used in reports and plots.
    input_name, output_name, input_unit, output_unit : str or sequence of str
        Labels and units used on plot axes; one per channel (a single string
        names the channels ``name[0]``, ``name[1]``, ..., python-control's
        convention, and gives every channel the same unit).
    tolerance : float, default 1e-3
        Allowed deviation of ``t`` from the uniform grid, as a fraction of dt
        (``0 <= tolerance < 0.5``).  Time stamps that are noisy readings of a
        uniform clock (the samples themselves were uniform) are accepted by
        raising it; the error message says how far.
    intersample : {"foh", "zoh"}, default "foh"
        How the input behaves between samples, as MATLAB's ``iddata``
        ``InterSample`` property: ``"foh"`` (linear between samples, the
        paper's semantics) or ``"zoh"`` (held constant, as from a DAC).
        Simulation and identification on this record honour it exactly.
    resample : {None, "linear", "zoh"}
        Interpolate samples truly taken at the irregular times ``t`` onto the
        uniform grid fitted to them (or of interval ``dt``); see
        :meth:`resample`.  Gaps longer than ``MAX_RESAMPLE_GAP`` intervals
        are refused.

    Raises
    ------
    DataError
        On NaN/inf samples, empty or mismatched signals, a non-increasing or
        irregular time grid (naming the sample and the tolerance or resampling
        that would help), or a missing/invalid ``dt``.

    Examples
    --------
    One dropped sample, interpolated back:

    >>> t = np.array([0.0, 0.1, 0.2, 0.4, 0.5])
    >>> d = IOData(2 * t, 3 * t, t, resample="linear")
    >>> d.dt, d.y.round(12).tolist()
    (0.1, [0.0, 0.3, 0.6, 0.9, 1.2, 1.5])

    Two inputs and two outputs, named:

    >>> m = IOData(np.ones((4, 2)), np.zeros((4, 2)), dt=0.1, input_name=["pitch", "yaw"], output_name="y")
    >>> m.n_inputs, m.n_outputs, m.input_names, m.output_names
    (2, 2, ('pitch', 'yaw'), ('y[0]', 'y[1]'))
    >>> m.channel(outputs="y[1]")
    IOData('data', N=4, dt=0.1 s, t=[0, 0.3] s, 2 inputs, 1 output)
    """

    def __init__(
        self,
        u,
        y,
        t=None,
        *,
        dt: float | None = None,
        name: str = "data",
        input_name="u",
        output_name="y",
        input_unit="",
        output_unit="",
        tolerance: float = GRID_TOLERANCE,
        intersample: str = "foh",
        resample: str | None = None,
        _sliced: bool = False,
    ):
        self.intersample = check_intersample(intersample)
        tolerance = check_tolerance(tolerance)
        u = as_channels(u, "u")
        y = as_channels(y, "y")
        if len(u) != len(y):
            hint = next((f" (channels are columns: pass {name}.T?)" for name, a, b in (("u", u, y), ("y", y, u))
                         if a.ndim == 2 and a.shape[1] == len(b)), "")
            raise DataError(f"length mismatch: u has {len(u)} samples but y has {len(y)}{hint}")
        if t is not None:
            t_arr = as_signal(t, "t")
            if t_arr.size != len(u):
                raise DataError(f"length mismatch: t has {t_arr.size} samples but u and y have {len(u)}")
            if resample is not None:
                method = _check_choice(resample, RESAMPLE_METHODS, "resample")
                t_grid, step = resampling_grid(t_arr, dt)
                u, y = _interpolate(t_arr, u, y, t_grid, method, step)
            else:
                t_grid, step = uniform_grid(t_arr, tolerance=tolerance)
                if dt is not None and not np.isclose(step, check_dt(dt), rtol=max(tolerance, 1e-12), atol=0):
                    raise DataError(f"dt = {dt!r} disagrees with the spacing of t ({step!r})")
        else:
            if resample is not None:
                raise DataError("resample needs the sample times t")
            if dt is None:
                raise DataError("give the sample times t or the sampling interval dt")
            step = check_dt(dt)
            t_grid = step * np.arange(len(u))
        if len(u) < 2:
            raise DataError("a record needs at least two samples")
        channels = (1 if u.ndim == 1 else u.shape[1]) + (1 if y.ndim == 1 else y.shape[1])
        if channels > len(u) and not _sliced:
            raise DataError(f"u and y hold {channels} channels over {len(u)} samples: channels are columns, one row "
                            "per sample; pass u.T and y.T")
        for a in (t_grid, u, y):
            a.setflags(write=False)
        self.t, self.u, self.y, self.dt = t_grid, u, y, float(step)
        self.name = str(name)
        self._labels(input_name, output_name, input_unit, output_unit)

    def _labels(self, input_name, output_name, input_unit, output_unit) -> None:
        m, p = self.n_inputs, self.n_outputs
        self.input_names = _channel_labels(input_name, m, "u", "input_name")
        self.output_names = _channel_labels(output_name, p, "y", "output_name")
        self.input_units = (input_unit,) * m if isinstance(input_unit, str) else _channel_labels(
            input_unit, m, "", "input_unit", unique=False)
        self.output_units = (output_unit,) * p if isinstance(output_unit, str) else _channel_labels(
            output_unit, p, "", "output_unit", unique=False)
        # one string per side: the channel's own for a single channel, the labels joined for several
        self.input_name, self.output_name = ", ".join(self.input_names), ", ".join(self.output_names)
        self.input_unit = self.input_units[0] if len(set(self.input_units)) == 1 else ", ".join(self.input_units)
        self.output_unit = self.output_units[0] if len(set(self.output_units)) == 1 else ", ".join(self.output_units)

    # -- channels -----------------------------------------------------------------
    @property
    def n_inputs(self) -> int:
        """Number of input channels."""
        return 1 if self.u.ndim == 1 else self.u.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of output channels."""
        return 1 if self.y.ndim == 1 else self.y.shape[1]

    @property
    def is_siso(self) -> bool:
        """Whether the record has one input and one output."""
        return self.u.ndim == 1 and self.y.ndim == 1

    @property
    def inputs(self) -> np.ndarray:
        """The input samples as columns, shape ``(N, m)`` (also for one input)."""
        return self.u.reshape(len(self), -1)

    @property
    def outputs(self) -> np.ndarray:
        """The output samples as columns, shape ``(N, p)`` (also for one output)."""
        return self.y.reshape(len(self), -1)

    def _channel_index(self, which, names, what: str) -> list:
        if which is None:
            return list(range(len(names)))
        if isinstance(which, np.ndarray) and which.ndim == 0:
            which = which.item()
        if not isinstance(which, (str, int, np.integer, list, tuple)) or isinstance(which, bool):
            raise DataError(f"{what} channel {which!r} is neither a name in {list(names)} nor an index "
                            f"0..{len(names) - 1} (nor a list of them)")
        items = [which] if isinstance(which, (str, int, np.integer)) else list(which)
        out = []
        for item in items:
            if isinstance(item, str):
                if item not in names:
                    raise DataError(f"record {self.name!r} has no {what} channel {item!r}; it has {list(names)}")
                out.append(names.index(item))
            elif isinstance(item, (int, np.integer)) and not isinstance(item, bool) and 0 <= item < len(names):
                out.append(int(item))
            else:
                raise DataError(f"{what} channel {item!r} is neither a name in {list(names)} nor an index "
                                f"0..{len(names) - 1}")
        if not out:
            raise DataError(f"select at least one {what} channel")
        return out

    def channel(self, inputs=None, outputs=None) -> "IOData":
        """The record with only some channels (by name or index; ``None`` keeps all).

        One input and one output give a SISO record; e.g. ``data.channel(0, 1)``
        is the record from input 0 to output 1.
        """
        i = self._channel_index(inputs, self.input_names, "input")
        o = self._channel_index(outputs, self.output_names, "output")
        u, y = self.inputs[:, i], self.outputs[:, o]
        return self._replace(u=u[:, 0] if len(i) == 1 else u, y=y[:, 0] if len(o) == 1 else y,
                             input_name=[self.input_names[k] for k in i],
                             output_name=[self.output_names[k] for k in o],
                             input_unit=[self.input_units[k] for k in i],
                             output_unit=[self.output_units[k] for k in o])

    def require_siso(self, what: str, *, mimo_hint: str = "use a MIMO structure (hc.MIMOHammersteinStructure, ...)"
                     ) -> "IOData":
        """``self`` if it has one input and one output, else a :class:`DataError` saying what to use instead."""
        if not self.is_siso:
            raise DataError(f"record {self.name!r} has {self.n_inputs} inputs and {self.n_outputs} outputs; {what} "
                            f"takes one of each: pick channels (data.channel(input, output)) or {mimo_hint}")
        return self

    # -- container protocol -------------------------------------------------
    def __len__(self) -> int:
        return self.u.shape[0]

    def __iter__(self):
        return iter((self.u, self.y))

    def __getitem__(self, index) -> "IOData":
        if not isinstance(index, slice):
            raise TypeError("IOData supports slicing only, e.g. data[:12000] or data[::2]")
        start, stop, step = index.indices(len(self))
        if step <= 0:
            raise DataError("IOData slices must have a positive step (time runs forward)")
        idx = np.arange(start, stop, step)
        if idx.size < 2:
            raise DataError(f"slice {index} leaves {idx.size} sample(s); a record needs at least two")
        return self._replace(u=self.u[idx], y=self.y[idx], t=self.t[idx])

    def _replace(self, **changes) -> "IOData":
        kw = dict(
            u=self.u, y=self.y, t=self.t, name=self.name, input_name=list(self.input_names),
            output_name=list(self.output_names), input_unit=list(self.input_units),
            output_unit=list(self.output_units), intersample=self.intersample, _sliced=True,
        )
        kw.update(changes)
        return IOData(**kw)

    # -- convenience ----------------------------------------------------------
    @property
    def sampling_time(self) -> float:
        """Alias of :attr:`dt` (the name used by ``nonlinear_benchmarks``)."""
        return self.dt

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]``."""
        return float(self.t[-1] - self.t[0])

    # -- preprocessing ------------------------------------------------------------
    def window(self, start: float | None = None, stop: float | None = None) -> "IOData":
        """The samples with ``start <= t < stop`` (seconds; ``None`` is open-ended).

        Times keep their origin (a window from 2 s starts at ``t = 2``).

        Raises
        ------
        DataError
            If the window keeps fewer than two samples or a bound is not a finite number.

        Examples
        --------
        >>> d = IOData(np.arange(10.0), np.arange(10.0), dt=0.5)
        >>> d.window(1.0, 3.0).t.tolist()
        [1.0, 1.5, 2.0, 2.5]
        """
        start = optional_time(start, "start")
        stop = optional_time(stop, "stop")
        t0 = self.t[0]
        lo = 0 if start is None else int(np.ceil((start - t0) / self.dt - _ON_GRID))
        hi = len(self) if stop is None else int(np.ceil((stop - t0) / self.dt - _ON_GRID))
        lo, hi = min(max(lo, 0), len(self)), min(max(hi, 0), len(self))
        if hi - lo < 2:
            raise DataError(
                f"window(start={start}, stop={stop}) keeps {max(hi - lo, 0)} sample(s) of the record's "
                f"t = [{self.t[0]:g}, {self.t[-1]:g}] s; a record needs at least two"
            )
        return self[lo:hi]

    def detrend(self, kind: str = "constant", which: str = "y") -> "IOData":
        """Remove the mean (``kind="constant"``) or the least-squares line in t (``"linear"``).

        Parameters
        ----------
        kind : {"constant", "linear"}
        which : {"y", "u", "both"}
            The signal(s) to detrend.

        Examples
        --------
        >>> d = IOData(np.ones(4), [1.0, 3.0, 5.0, 7.0], dt=1.0)
        >>> (d.detrend("linear").y.round(12) + 0.0).tolist()    # + 0.0: no negative zeros
        [0.0, 0.0, 0.0, 0.0]
        """
        kind = _check_choice(kind, DETREND_KINDS, "kind")
        which = _check_choice(which, _SIGNAL_CHOICES, "which")
        tau = self.t - self.t[0]

        def trend_free(x):
            if kind == "constant":
                return x - x.mean(axis=0)
            slope, intercept = np.polyfit(tau, x, 1)
            return x - (intercept + np.multiply.outer(tau, slope))

        return self._replace(
            u=trend_free(self.u) if which in ("u", "both") else self.u,
            y=trend_free(self.y) if which in ("y", "both") else self.y,
        )

    def remove_offset(self, y=0.0, u=0.0) -> "IOData":
        """Subtract constants from the output and input.

        Parameters
        ----------
        y, u : float or "initial"
            The constant to subtract, or ``"initial"`` for the first sample
            (so the signal starts at 0, as the from-rest simulation assumes).

        Examples
        --------
        >>> d = IOData([1.0, 2.0], [5.0, 6.0], dt=1.0)
        >>> d.remove_offset(y="initial", u=1.0).y.tolist(), d.remove_offset(u=1.0).u.tolist()
        ([0.0, 1.0], [0.0, 1.0])
        """
        def offset(value, x, label):
            if isinstance(value, str):
                _check_choice(value, ("initial",), f"{label} offset")
                return x[0]
            return finite_float(value, f"{label} offset", "a finite number or 'initial'")

        return self._replace(u=self.u - offset(u, self.u, "u"), y=self.y - offset(y, self.y, "y"))

    def resample(self, dt: float, method: str | None = None) -> "IOData":
        """The record interpolated onto the uniform grid of interval ``dt``.

        The grid starts at ``t[0]`` and keeps the points up to ``t[-1]``.  No
        anti-aliasing filter is applied: to lower the rate of a record with
        content above the new Nyquist frequency, filter it first.  Irregular
        time stamps are resampled when the record is built
        (``IOData(u, y, t, resample=...)`` or ``read_record(..., resample=...)``),
        with the same methods.

        Parameters
        ----------
        dt : float
            The new sampling interval (s).
        method : {"linear", "zoh"}, optional
            How the input is interpolated: ``"linear"`` between samples, or
            ``"zoh"`` holding the latest sample at or before each grid time (an
            input held by a DAC).  The output is always interpolated linearly
            (a measured output is continuous).  The default follows
            :attr:`intersample` (``"zoh"`` for a held input).

        Examples
        --------
        >>> d = IOData([0.0, 1.0, 2.0], [0.0, 2.0, 4.0], dt=1.0)
        >>> d.resample(0.5).y.tolist(), d.resample(0.5, "zoh").u.tolist()
        ([0.0, 1.0, 2.0, 3.0, 4.0], [0.0, 0.0, 1.0, 1.0, 2.0])
        """
        if method is None:
            method = "zoh" if self.intersample == "zoh" else "linear"
        method = _check_choice(method, RESAMPLE_METHODS, "method")
        grid, step = resampling_grid(self.t, check_dt(dt), max_gap=np.inf)
        u, y = _interpolate(self.t, self.u, self.y, grid, method, step)
        return self._replace(u=u, y=y, t=grid)

    def check_identifiable(self, n_params: int | None = None) -> None:
        """Raise a :class:`DataError` if the record cannot identify a model.

        The problems checked: an output that never changes (nothing to
        identify), an input that is zero throughout (nothing excites the
        system), and, given ``n_params``, fewer samples than parameters.

        Examples
        --------
        >>> IOData([0.0, 1.0, 0.0], [0.5, 0.5, 0.5], dt=1.0).check_identifiable()  # doctest: +NORMALIZE_WHITESPACE
        Traceback (most recent call last):
        ...
        hammerstein_ctrl.exceptions.DataError: record 'data': output y is constant (every sample is 0.5); nothing to
        identify
        """
        problems = []
        siso = self.is_siso
        for k, y in enumerate(self.outputs.T):
            if np.ptp(y) == 0:
                label = "output y" if siso else f"output {self.output_names[k]!r}"
                problems.append(f"{label} is constant (every sample is {y[0]:g}); nothing to identify")
        for k, u in enumerate(self.inputs.T):
            if not np.any(u):
                label = "input u" if siso else f"input {self.input_names[k]!r}"
                problems.append(f"{label} is zero throughout; nothing excites the system")
        if n_params is not None and len(self) < n_params:
            problems.append(f"only {len(self)} samples for {n_params} parameters")
        if problems:
            raise DataError(f"record {self.name!r}: " + "; ".join(problems))

    def to_csv(self, path) -> Path:
        """Write ``t,u,y`` with full precision (readable by :func:`~hammerstein_ctrl.data.read_record`)."""
        path = Path(path)
        columns = "t,u,y" if self.is_siso else ",".join(("t",) + self.input_names + self.output_names)
        header = (
            f"# {self.name}\n# input: {self.input_name} [{self.input_unit}], "
            f"output: {self.output_name} [{self.output_unit}], dt = {self.dt!r} s\n{columns}"
        )
        np.savetxt(path, np.column_stack([self.t, self.u, self.y]), delimiter=",", fmt="%.17g",
                   header=header, comments="")
        return path

    def __repr__(self) -> str:
        channels = "" if self.is_siso else (
            f", {self.n_inputs} input{'s' * (self.n_inputs > 1)}, {self.n_outputs} output{'s' * (self.n_outputs > 1)}")
        return (
            f"IOData({self.name!r}, N={len(self)}, dt={self.dt:g} s, "
            f"t=[{self.t[0]:g}, {self.t[-1]:g}] s{channels})"
        )


def time_and_input(t, u, intersample: str) -> tuple:
    """``(t, u, intersample)`` of a model's ``simulate(t, u)`` call: a record's own (``u`` must then be left out),
    or the given ``(t, u)`` with the model's ``intersample``.

    Examples
    --------
    >>> rec = IOData([0.0, 1.0, 0.5], [0.0, 0.1, 0.2], dt=0.1, intersample="zoh")
    >>> time_and_input(rec, None, "foh")[2]
    'zoh'
    """
    if isinstance(t, IOData):
        if u is not None:
            raise ParameterError("pass either a record or (t, u), not both")
        return t.t, t.u, t.intersample
    if u is None:
        raise ParameterError("simulate needs the input u (or an IOData record)")
    return t, u, intersample

