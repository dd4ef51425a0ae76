"""MIMO block-oriented structures and models: several inputs, several outputs.

A plant with inputs ``u_0 .. u_{m-1}`` and outputs ``y_0 .. y_{p-1}`` (the
twin-rotor system: two rotor voltages, pitch and yaw) is modelled as

* **Hammerstein**: ``y_i = sum_j B_ij(p)/F_i(p) g_j(u_j) + y0_i``, one static
  nonlinearity per input (the actuators');
* **Wiener**: ``y_i = h_i(sum_j B_ij(p)/F_i(p) u_j) + y0_i``, one per output (the sensors');
* **Hammerstein-Wiener**: both.

**One denominator per output.**  The linear block is a ``p x m`` matrix of
transfer functions whose row ``i`` shares the denominator ``F_i``: the
dynamics that output ``i`` shows are one set of modes excited by every
input, as in a physical plant where the inputs act on the same states, and
the row is the MISO model of that output (MATLAB's ``nlhw`` keeps one
denominator per element instead: ``m`` times as many poles for what is
usually one plant).  A Wiener row is then identified as a whole: its output
nonlinearity sees the sum of all inputs' contributions.  Where outputs
really have different modes (two decoupled axes), each row finds its own.

**Gain convention.**  A gain moves freely between a nonlinearity and the
transfer functions it feeds or reads; fixing one coefficient per ambiguity
makes the parameters unique:

* an input nonlinearity ``g_j`` feeds column ``j``: the numerator ``B_0j``
  (from input ``j`` to the first output) is monic, ``g_j`` carries the gain;
* an output nonlinearity ``h_i`` reads row ``i``: ``B_i0`` (from the first
  input) is monic, ``h_i`` carries the gain;
* with both (Hammerstein-Wiener), ``g_j``'s gain parameter is fixed to 1
  instead (as in the SISO structure) and the rows keep ``B_i0`` monic.

A monic reference element must really be there: an input that does not
act on the first output (Hammerstein) needs its outputs ordered otherwise.

**Dead time per input.**  ``delay=`` gives each input its transport delay
``tau_j`` (``B_ij(p)/F_i(p) e^{-tau_j p}`` for every output): a number of
seconds fixed, or ``"estimate"`` for a parameter ``delay[uj]``, continuous and
simulated exactly under FOH and ZOH (:mod:`~hammerstein_ctrl.simulate._delay`).

Parameters are named after their channel, 0-based as python-control names
signals: ``b0[1,0]`` (numerator of output 1 from input 0), ``a1[0]``
(denominator of output 0), ``d1[g1]`` (parameter ``d1`` of input 1's
nonlinearity), ``gain[h0]``, ``y0[1]``.

The sampled simulation is exact under first- and zero-order hold: each
element ``B_ij/F_i`` is simulated by the compiled SISO pass
(:func:`~hammerstein_ctrl.simulate.simulate_batch`) on its input's
nonlinearity and the row's elements are summed (linearity).

Examples
--------
>>> from hammerstein_ctrl import LinearStructure, Tanh
>>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Tanh(), Tanh()], n_outputs=2)
>>> s.param_names                    # B_00 and B_01 are monic: g_0 and g_1 carry the gains into y_0
('a0[0]', 'b0[1,0]', 'b0[1,1]', 'a0[1]', 'd0[g0]', 'd1[g0]', 'd0[g1]', 'd1[g1]')
>>> num, den = s.coefficients([2.0, 0.5, 0.7, 3.0, 1.0, 1.0, 2.0, 0.5])
>>> num[0].tolist(), den[0].tolist()          # B (rows: outputs, columns: inputs), F per row
([[[1.0], [1.0]], [[0.5], [0.7]]], [[1.0, 2.0], [1.0, 3.0]])
"""

from __future__ import annotations

import warnings

import numpy as np

from .._checks import ESTIMATE, as_count, check_delay, check_intersample, signal_names
from ..exceptions import ChannelWarning, DataError, ParameterError
from ._nonlinearities import Nonlinearity
from ._structure import LinearStructure

__all__ = ["MIMOStructure", "mimo_structure", "MIMOHammersteinStructure", "MIMOWienerStructure",
           "MIMOHammersteinWienerStructure", "MIMOModel", "simulate_mimo_batch", "observable_realization"]


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


class MIMOStructure:
    """Parameter layout of a MIMO block-oriented model (see the module's description).

    Parameters
    ----------
    linear : LinearStructure
        Orders of every element ``B_ij/F_i`` (numerator ``num_order``, denominator ``den_order``).
    input_nonlinearities : sequence of Nonlinearity or Nonlinearity, optional
        One per input (one family is used for every input); ``None``: no input nonlinearity.
    output_nonlinearities : sequence of Nonlinearity or Nonlinearity, optional
        One per output; ``None``: none.
    n_inputs, n_outputs : int
        Channel counts (taken from the nonlinearity lists where given).
    offset : bool, default False
        Estimate a constant ``y0[i]`` added to each output.
    delay : float, "estimate" or sequence of them, optional
        Each input's dead time in seconds (one value for every input, or one
        per input); ``"estimate"`` makes it a parameter ``delay[uj]``.
    """

    kind = "mimo"

    def __init__(self, linear: LinearStructure, input_nonlinearities=None, output_nonlinearities=None, *,
                 n_inputs: int | None = None, n_outputs: int | None = None, offset: bool = False,
                 initial_state: str = "zero", delay=None):
        self.linear = _check_linear(linear)
        if initial_state != "zero":
            raise ParameterError("a MIMO structure starts from rest (initial_state='zero'); estimating x(0) is "
                                 "not supported yet: trim the record to start at rest, or use offset=True")
        m = self._count(input_nonlinearities, n_inputs, "n_inputs")
        p = self._count(output_nonlinearities, n_outputs, "n_outputs")
        if m * p < 2:
            raise ParameterError("a MIMO structure needs several inputs or outputs; for one of each use "
                                 "HammersteinStructure, WienerStructure or HammersteinWienerStructure")
        self.n_inputs, self.n_outputs = m, p
        self.input_nonlinearities = _nonlinearity_list(input_nonlinearities, m, "input_nonlinearities")
        self.output_nonlinearities = _nonlinearity_list(output_nonlinearities, p, "output_nonlinearities")
        if self.input_nonlinearities is None and self.output_nonlinearities is None:
            raise ParameterError("give input or output nonlinearities (a MIMO linear model is a LinearStructure "
                                 "with identity nonlinearities: use Polynomial(1))")
        if not isinstance(offset, (bool, np.bool_)):
            raise ParameterError(f"offset must be True or False, got {offset!r}")
        self.offset = bool(offset)
        self.initial_state = "zero"
        self.delays = _input_delays(delay, m)
        self._fixed_gain = None
        if self.input_nonlinearities is not None and self.output_nonlinearities is not None:
            self._fixed_gain = [nl.gain_index for nl in self.input_nonlinearities]
            if None in self._fixed_gain:
                raise ParameterError("the input nonlinearities of a Hammerstein-Wiener structure need a gain "
                                     "parameter to fix to 1")
        self._layout()

    @staticmethod
    def _count(nonlinearities, given, label: str) -> int:
        from .._checks import MAX_CHANNELS

        if given is not None and as_count(given, label, minimum=1) > MAX_CHANNELS:
            raise ParameterError(f"{label} = {given} exceeds {MAX_CHANNELS} channels")
        if nonlinearities is not None and not isinstance(nonlinearities, Nonlinearity):
            if not isinstance(nonlinearities, (list, tuple)):
                raise ParameterError(f"the nonlinearities must be a list (one per channel), got "
                                     f"{type(nonlinearities).__name__}")
            count = len(nonlinearities)
            if given is not None and as_count(given, label, minimum=1) != count:
                raise ParameterError(f"{label} = {given} but {count} nonlinearities are given")
            return count
        if given is None:
            raise ParameterError(f"give {label} (or one nonlinearity per channel)")
        return as_count(given, label, minimum=1)

    # -- layout ---------------------------------------------------------------------
    def _monic(self, i: int, j: int) -> bool:
        """Whether element ``(i, j)``'s numerator is monic (the gain convention)."""
        return i == 0 if self.output_nonlinearities is None else j == 0

    def _layout(self) -> None:
        lin, m, p = self.linear, self.n_inputs, self.n_outputs
        nb, nf = lin.num_order, lin.den_order
        num0 = np.zeros((p, m, nb + 1))
        den0 = np.zeros((p, nf + 1))
        den0[:, 0] = 1.0
        names, num_pos, den_pos = [], [], []
        for i in range(p):
            for j in range(m):
                for k in range(nb + 1):
                    if k == nb and self._monic(i, j):
                        num0[i, j, 0] = 1.0
                        continue
                    names.append(f"b{k}[{i},{j}]")
                    num_pos.append(np.ravel_multi_index((i, j, nb - k), num0.shape))
            for k in range(nf):
                names.append(f"a{k}[{i}]")
                den_pos.append(np.ravel_multi_index((i, nf - k), den0.shape))
        self.n_linear = len(names)
        self._b_index = np.array([q for q, n in enumerate(names) if n.startswith("b")], dtype=int)
        self._a_index = np.array([q for q, n in enumerate(names) if n.startswith("a")], dtype=int)
        self._num0, self._den0 = num0, den0
        self._num_pos, self._den_pos = np.array(num_pos, dtype=int), np.array(den_pos, dtype=int)
        self._g_slices, self._h_slices = [], []
        for j, nl in enumerate(self.input_nonlinearities or ()):
            free = [n for q, n in enumerate(nl.param_names) if self._fixed_gain is None or q != self._fixed_gain[j]]
            self._g_slices.append(slice(len(names), len(names) + len(free)))
            names += [f"{n}[g{j}]" for n in free]
        for i, nl in enumerate(self.output_nonlinearities or ()):
            self._h_slices.append(slice(len(names), len(names) + nl.n_params))
            names += [f"{n}[h{i}]" for n in nl.param_names]
        self._delay_index = {j: len(names) + k for k, j in enumerate(
            j for j, d in enumerate(self.delays) if d == ESTIMATE)}
        names += [f"delay[u{j}]" for j in self._delay_index]
        self.core_names = tuple(names)
        self.param_names = self.core_names + (tuple(f"y0[{i}]" for i in range(p)) if self.offset else ())

    @property
    def n_params(self) -> int:
        """Length of beta."""
        return len(self.param_names)

    @property
    def n_core(self) -> int:
        """Parameters of the blocks (without the offsets)."""
        return len(self.core_names)

    @property
    def input_nonlinearity(self):
        """``None``: a MIMO structure's input blocks are :attr:`input_nonlinearities` (one per input)."""
        return None

    output_nonlinearity = input_nonlinearity

    def check_beta(self, beta) -> np.ndarray:
        """beta as a float array of shape ``(n,)`` or ``(B, n)`` (a :class:`ParameterError` naming the layout)."""
        from .._checks import as_real_array

        b = beta if type(beta) is np.ndarray and beta.dtype == np.float64 else as_real_array(beta, "beta")
        if b.ndim not in (1, 2) or b.shape[-1] != self.n_params:
            got = b.shape[-1] if b.ndim else "a scalar"
            raise ParameterError(f"beta must have {self.n_params} entries {list(self.param_names)}, got {got}"
                                 + (f" (an array of shape {b.shape})" if b.ndim > 1 else ""))
        return b

    def coefficients(self, beta):
        """``(num, den)``: numerators ``(B, p, m, nb+1)`` and row denominators ``(B, p, nf+1)``, descending powers."""
        b = np.atleast_2d(self.check_beta(beta))
        n = b.shape[0]
        num = np.broadcast_to(self._num0, (n,) + self._num0.shape).reshape(n, -1).copy()
        den = np.broadcast_to(self._den0, (n,) + self._den0.shape).reshape(n, -1).copy()
        num[:, self._num_pos] = b[:, self._b_index]
        den[:, self._den_pos] = b[:, self._a_index]
        return num.reshape((n,) + self._num0.shape), den.reshape((n,) + self._den0.shape)

    def input_params(self, beta) -> list | None:
        """Full parameters of each input nonlinearity (fixed gains inserted), ``[(B, n_j) or (n_j,)]``."""
        if self.input_nonlinearities is None:
            return None
        b = self.check_beta(beta)
        out = []
        for j, sl in enumerate(self._g_slices):
            free = b[..., sl]
            out.append(free if self._fixed_gain is None else np.insert(free, self._fixed_gain[j], 1.0, axis=-1))
        return out

    def output_params(self, beta) -> list | None:
        """Parameters of each output nonlinearity."""
        if self.output_nonlinearities is None:
            return None
        b = self.check_beta(beta)
        return [b[..., sl] for sl in self._h_slices]

    @property
    def has_delay(self) -> bool:
        """Whether any input has a dead time (fixed or estimated)."""
        return any(d == ESTIMATE or d > 0 for d in self.delays)

    def input_delays(self, beta) -> np.ndarray:
        """Each input's dead time ``(m,)`` or ``(B, m)``: the magnitude of the ``delay[uj]`` entries, or the fixed
        values.

        An estimated dead time is ``|delay[uj]|``: a step of the optimiser past 0
        stays a valid model (a dead time of 0 is often the answer, and a cost
        undefined beyond it would stop the search at the boundary);
        :meth:`normalize` reports the magnitude.
        """
        b = self.check_beta(beta)
        out = np.empty(b.shape[:-1] + (self.n_inputs,))
        for j, d in enumerate(self.delays):
            out[..., j] = np.abs(b[..., self._delay_index[j]]) if d == ESTIMATE else d
        return out

    def without_delays(self) -> "MIMOStructure":
        """The same blocks with no dead time (the layout of the starts' shifted record)."""
        return self._rebuilt(self, self.offset, self.initial_state, None)

    def offsets(self, beta) -> np.ndarray:
        """The output offsets ``(p,)`` or ``(B, p)`` (zeros without ``offset``)."""
        b = self.check_beta(beta)
        if not self.offset:
            return np.zeros(b.shape[:-1] + (self.n_outputs,))
        return b[..., self.n_core:]

    def row_denominator(self, row: int) -> tuple[np.ndarray, np.ndarray]:
        """``(positions, indices)``: where row ``row``'s free denominator coefficients sit in its coefficient
        array (descending powers) and in beta."""
        width = self.linear.den_order + 1
        idx = [q for q, name in enumerate(self.param_names[:self.n_linear]) if name.startswith("a")]
        pairs = [(pos % width, q) for pos, q in zip(self._den_pos, idx) if pos // width == row]
        return np.array([p for p, _ in pairs], dtype=int), np.array([q for _, q in pairs], dtype=int)

    def normalize(self, beta) -> np.ndarray:
        """beta with each nonlinearity's parameters in canonical form (the model is unchanged)."""
        b = np.array(self.check_beta(beta), dtype=float)
        if self.input_nonlinearities is not None and self._fixed_gain is None:
            for nl, sl in zip(self.input_nonlinearities, self._g_slices):
                b[..., sl] = nl.normalize(b[..., sl])
        for nl, sl in zip(self.output_nonlinearities or (), self._h_slices):
            b[..., sl] = nl.normalize(b[..., sl])
        for k in self._delay_index.values():
            b[..., k] = np.abs(b[..., k])
        return b

    def unstable(self, beta) -> np.ndarray:
        """Whether each candidate has a row denominator with a root in the closed right half-plane."""
        from ..simulate._simulate import unstable

        _, den = self.coefficients(beta)
        return unstable(den.reshape(-1, den.shape[-1])).reshape(den.shape[:2]).any(axis=1)

    # -- beta <-> models ----------------------------------------------------------------
    def model(self, beta, **kwargs) -> "MIMOModel":
        """The :class:`MIMOModel` of one beta (``kwargs``: ``intersample``, ``name``, ``input_names``, ...)."""
        b = self.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("model() takes a single beta vector, not a batch")
        num, den = self.coefficients(b)
        return MIMOModel(num[0], den[0], input_nonlinearities=self.input_nonlinearities,
                         input_params=self.input_params(b), output_nonlinearities=self.output_nonlinearities,
                         output_params=self.output_params(b), offset=self.offsets(b), kind=self.kind,
                         delays=self.input_delays(b) if self.has_delay else None, **kwargs)

    def beta(self, model: "MIMOModel") -> np.ndarray:
        """The beta of a model with this structure (the inverse of :meth:`model`).

        Raises
        ------
        ParameterError
            When the model does not have this structure: other shapes or
            nonlinearity families, a reference numerator whose leading
            coefficient is not 1 (the gain convention), other fixed dead times,
            or an offset the structure does not estimate.
        """
        num, den = np.asarray(model.numerators, dtype=float), np.asarray(model.denominators, dtype=float)
        if num.shape != self._num0.shape or den.shape != self._den0.shape:
            raise ParameterError(f"the model's blocks have shape {num.shape}/{den.shape}, the structure's "
                                 f"{self._num0.shape}/{self._den0.shape}")
        num, den = num / den[:, :1, None], den / den[:, :1]                  # monic rows: the same model
        self._check_model_blocks(model, num)
        flat_num, flat_den = num.reshape(-1), den.reshape(-1)
        lin = np.empty(self.n_linear)
        lin[self._b_index], lin[self._a_index] = flat_num[self._num_pos], flat_den[self._den_pos]
        parts = [lin]
        for j in range(len(self.input_nonlinearities or ())):
            q = np.asarray(model.input_params[j], dtype=float)
            parts.append(q if self._fixed_gain is None else np.delete(q, self._fixed_gain[j]))
        parts += [np.asarray(q, dtype=float) for q in (model.output_params or ())]
        parts.append(np.asarray([model.delays[j] for j in self._delay_index], dtype=float))
        if self.offset:
            parts.append(np.asarray(model.offset, dtype=float))
        return np.concatenate(parts)

    def _check_model_blocks(self, model, num) -> None:
        """Refuse a model whose blocks this structure cannot hold (see :meth:`beta`)."""
        for label, mine, theirs in (("input", self.input_nonlinearities, model.input_nonlinearities),
                                    ("output", self.output_nonlinearities, model.output_nonlinearities)):
            if (mine is None) != (theirs is None) or any(
                    type(a) is not type(b) or a.param_names != b.param_names for a, b in zip(mine or (), theirs or ())):
                raise ParameterError(f"the model's {label} nonlinearities {theirs} do not match the structure's {mine}")
        for i in range(self.n_outputs):
            for j in range(self.n_inputs):
                if self._monic(i, j) and not np.isclose(num[i, j, 0], 1.0, rtol=1e-9, atol=1e-12):
                    raise ParameterError(f"the model's numerator ({i}, {j}) has leading coefficient "
                                         f"{num[i, j, 0]:.6g}; the structure fixes it to 1 (move the gain into the "
                                         "nonlinearity)")
        for j, d in enumerate(self.delays):
            if d != ESTIMATE and not np.isclose(model.delays[j], d, rtol=1e-12, atol=1e-15):
                raise ParameterError(f"the model's dead time on input {j} is {model.delays[j]:g} s; the structure "
                                     f"fixes it to {d:g} s")
        if self._fixed_gain is not None:
            for j, q in enumerate(model.input_params):
                if not np.isclose(q[self._fixed_gain[j]], 1.0):
                    raise ParameterError(f"the model's input nonlinearity {j} has gain {q[self._fixed_gain[j]]:.6g}; "
                                         "the structure fixes it to 1 (move the gain into the output block)")
        if not self.offset and np.any(model.offset != 0):
            raise ParameterError("the model has output offsets, which this structure does not estimate: "
                                 "use structure.with_options(offset=True)")

    def with_options(self, *, offset: bool | None = None, initial_state: str | None = None):
        """The same blocks with another offset option."""
        return type(self)._rebuilt(self, self.offset if offset is None else offset,
                                   "zero" if initial_state is None else initial_state, self.delays)

    def with_delay(self, delay):
        """The same blocks and options with other dead times (one for all inputs, or one per input)."""
        return type(self)._rebuilt(self, self.offset, self.initial_state, delay)

    @staticmethod
    def _rebuilt(s, offset, initial_state, delay):
        return MIMOStructure(s.linear, s.input_nonlinearities, s.output_nonlinearities, n_inputs=s.n_inputs,
                             n_outputs=s.n_outputs, offset=offset, initial_state=initial_state, delay=delay)

    def describe(self) -> str:
        """One line: the matrix, its orders and the nonlinearities."""
        parts = [f"{self.n_outputs}x{self.n_inputs} H(p) = [B_ij(p)/F_i(p)], deg B = {self.linear.num_order}, "
                 f"deg F = {self.linear.den_order}"]
        if self.input_nonlinearities:
            parts.append("g = " + ", ".join(nl.name for nl in self.input_nonlinearities))
        if self.output_nonlinearities:
            parts.append("h = " + ", ".join(nl.name for nl in self.output_nonlinearities))
        if self.has_delay:
            parts.append("dead times " + ", ".join(f"u{j}: {d if d == ESTIMATE else f'{d:g} s'}"
                                                   for j, d in enumerate(self.delays)))
        return "; ".join(parts) + (" + y0" if self.offset else "")

    def __repr__(self):
        delay = f", delay={list(self.delays)!r}" if self.has_delay else ""
        return (f"{type(self).__name__}({self.linear!r}, inputs={self.n_inputs}, outputs={self.n_outputs}"
                + (", offset=True" if self.offset else "") + delay + ")")


class MIMOHammersteinStructure(MIMOStructure):
    """``y_i = sum_j B_ij(p)/F_i(p) g_j(u_j)``: one nonlinearity per input, then the MIMO linear block.

    Parameters
    ----------
    linear : LinearStructure
        Orders of each element.
    nonlinearities : sequence of Nonlinearity
        ``g_j``, one per input.
    n_outputs : int
        Number of outputs.
    offset : bool, default False

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Tanh
    >>> MIMOHammersteinStructure(LinearStructure(1, 2), [Tanh(), Tanh()], n_outputs=2).n_params
    14
    """

    kind = "mimo-hammerstein"

    def __init__(self, linear: LinearStructure, nonlinearities, n_outputs: int, *, offset: bool = False,
                 initial_state: str = "zero", delay=None):
        if nonlinearities is None or isinstance(nonlinearities, Nonlinearity):
            raise ParameterError("nonlinearities must be a list with one Nonlinearity per input")
        super().__init__(linear, nonlinearities, None, n_outputs=n_outputs, offset=offset,
                         initial_state=initial_state, delay=delay)

    @staticmethod
    def _rebuilt(s, offset, initial_state, delay):
        return MIMOHammersteinStructure(s.linear, s.input_nonlinearities, s.n_outputs, offset=offset,
                                        initial_state=initial_state, delay=delay)


class MIMOWienerStructure(MIMOStructure):
    """``y_i = h_i(sum_j B_ij(p)/F_i(p) u_j)``: the MIMO linear block, then one nonlinearity per output.

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Saturation
    >>> MIMOWienerStructure(LinearStructure(0, 1), [Saturation(), Saturation()], n_inputs=2).param_names[:4]
    ('b0[0,1]', 'a0[0]', 'b0[1,1]', 'a0[1]')
    """

    kind = "mimo-wiener"

    def __init__(self, linear: LinearStructure, nonlinearities, n_inputs: int, *, offset: bool = False,
                 initial_state: str = "zero", delay=None):
        if nonlinearities is None or isinstance(nonlinearities, Nonlinearity):
            raise ParameterError("nonlinearities must be a list with one Nonlinearity per output")
        super().__init__(linear, None, nonlinearities, n_inputs=n_inputs, offset=offset,
                         initial_state=initial_state, delay=delay)

    @staticmethod
    def _rebuilt(s, offset, initial_state, delay):
        return MIMOWienerStructure(s.linear, s.output_nonlinearities, s.n_inputs, offset=offset,
                                   initial_state=initial_state, delay=delay)


class MIMOHammersteinWienerStructure(MIMOStructure):
    """``y_i = h_i(sum_j B_ij(p)/F_i(p) g_j(u_j))``: nonlinearities on both sides (``g_j`` with unit gain).

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, DeadZone, Saturation
    >>> s = MIMOHammersteinWienerStructure(LinearStructure(0, 1), [DeadZone()] * 2, [Saturation()] * 2)
    >>> s.param_names[-4:]
    ('gain[h0]', 'limit[h0]', 'gain[h1]', 'limit[h1]')
    """

    kind = "mimo-hammerstein-wiener"

    def __init__(self, linear: LinearStructure, input_nonlinearities, output_nonlinearities, *,
                 offset: bool = False, initial_state: str = "zero", delay=None):
        for value, label in ((input_nonlinearities, "input"), (output_nonlinearities, "output")):
            if value is None or isinstance(value, Nonlinearity):
                raise ParameterError(f"{label}_nonlinearities must be a list with one Nonlinearity per {label}")
        super().__init__(linear, input_nonlinearities, output_nonlinearities, offset=offset,
                         initial_state=initial_state, delay=delay)

    @staticmethod
    def _rebuilt(s, offset, initial_state, delay):
        return MIMOHammersteinWienerStructure(s.linear, s.input_nonlinearities, s.output_nonlinearities,
                                              offset=offset, initial_state=initial_state, delay=delay)


def mimo_structure(linear: LinearStructure, input_nonlinearities=None, output_nonlinearities=None, *,
                   n_inputs: int | None = None, n_outputs: int | None = None, offset: bool = False,
                   initial_state: str = "zero", delay=None) -> MIMOStructure:
    """The MIMO structure of the right family for the blocks given (Hammerstein, Wiener or both).

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Tanh
    >>> type(mimo_structure(LinearStructure(0, 1), None, [Tanh()] * 2, n_inputs=3)).__name__
    'MIMOWienerStructure'
    """
    if input_nonlinearities is not None and output_nonlinearities is not None:
        s = MIMOHammersteinWienerStructure(linear, input_nonlinearities, output_nonlinearities, offset=offset,
                                           initial_state=initial_state, delay=delay)
    elif input_nonlinearities is not None:
        s = MIMOHammersteinStructure(linear, input_nonlinearities, n_outputs, offset=offset,
                                     initial_state=initial_state, delay=delay)
    elif output_nonlinearities is not None:
        s = MIMOWienerStructure(linear, output_nonlinearities, n_inputs, offset=offset, initial_state=initial_state,
                                delay=delay)
    else:
        raise ParameterError("give input or output nonlinearities")
    for label, given, actual in (("n_inputs", n_inputs, s.n_inputs), ("n_outputs", n_outputs, s.n_outputs)):
        if given is not None and given != actual:
            raise ParameterError(f"{label} = {given} but the nonlinearities give {actual}")
    return s


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


class MIMOModel:
    """A MIMO block-oriented model ``y_i = h_i(sum_j B_ij(p)/F_i(p) g_j(u_j)) + y0_i``.

    Parameters
    ----------
    numerators : array_like, shape (p, m, nb+1)
        ``B_ij`` in descending powers.
    denominators : array_like, shape (p, nf+1)
        ``F_i``, one per output row.
    input_nonlinearities, output_nonlinearities : sequences of Nonlinearity, optional
    input_params, output_params : sequences of array_like, optional
    offset : array_like, shape (p,), optional
    intersample : {"foh", "zoh"}, default "foh"
    name : str, optional
    input_names, output_names : sequences of str, optional
        Signal names of the python-control exports (default ``u[j]``, ``y[i]``).
    kind : str, optional
        Structure family, for reports.
    delays : array_like, shape (m,), optional
        Each input's dead time in seconds (default none), simulated exactly;
        :meth:`to_iosys` carries it as a Pade approximant.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> s = hc.mimo_structure(hc.LinearStructure(0, 1), [hc.Polynomial(1)] * 2, n_outputs=1)
    >>> m = s.model(np.ones(s.n_params))
    >>> isinstance(m, MIMOModel), (m.n_inputs, m.n_outputs)
    (True, (2, 1))
    """

    def __init__(self, numerators, denominators, *, input_nonlinearities=None, input_params=None,
                 output_nonlinearities=None, output_params=None, offset=None, intersample: str = "foh",
                 name: str | None = None, input_names=None, output_names=None, kind: str = "mimo", delays=None):
        from .._checks import as_real_array

        self.numerators = np.array(as_real_array(numerators, "numerators"), dtype=float)
        self.denominators = np.array(as_real_array(denominators, "denominators"), dtype=float)
        if self.numerators.ndim != 3 or self.denominators.ndim != 2 or \
                self.numerators.shape[0] != self.denominators.shape[0] or 0 in self.numerators.shape or \
                self.denominators.shape[1] < 2 or self.numerators.shape[2] > self.denominators.shape[1]:
            raise ParameterError(f"numerators must be (p, m, nb+1) and denominators (p, nf+1) with p, m >= 1 and "
                                 f"0 <= nb <= nf, nf >= 1; got {self.numerators.shape} and "
                                 f"{self.denominators.shape}")
        if not (np.all(np.isfinite(self.numerators)) and np.all(np.isfinite(self.denominators))) or \
                np.any(self.denominators[:, 0] == 0):
            raise ParameterError("the MIMO linear block needs finite coefficients and non-zero leading "
                                 "denominator coefficients")
        p, m = self.numerators.shape[:2]
        self.input_nonlinearities = _nonlinearity_list(input_nonlinearities, m, "input_nonlinearities")
        self.output_nonlinearities = _nonlinearity_list(output_nonlinearities, p, "output_nonlinearities")
        self.input_params = self._params(self.input_nonlinearities, input_params, "input")
        self.output_params = self._params(self.output_nonlinearities, output_params, "output")
        self.offset = np.zeros(p) if offset is None else np.array(as_real_array(offset, "offset"), dtype=float)
        if self.offset.shape not in ((p,), ()) or not np.all(np.isfinite(self.offset)):
            raise ParameterError(f"offset must be {p} finite number(s), one per output, got {offset!r}")
        self.offset = np.broadcast_to(self.offset, (p,)).copy()
        self.intersample = check_intersample(intersample)
        self.kind = str(kind)
        self.name = name or self.kind.replace("-", "_")
        self.input_names = _signal_names(input_names, m, "u", "input_names")
        self.output_names = _signal_names(output_names, p, "y", "output_names")
        self.delays = np.zeros(m) if delays is None else np.array(
            [check_delay(d, estimate=False) for d in np.ravel(delays)], dtype=float)
        if self.delays.size != m:
            raise ParameterError(f"give one dead time per input ({m}), got {self.delays.size}")

    @staticmethod
    def _params(nonlinearities, params, label):
        if nonlinearities is None:
            return None
        if params is None or isinstance(params, (str, bytes)) or not hasattr(params, "__len__") or \
                len(params) != len(nonlinearities):
            raise ParameterError(f"give one parameter vector per {label} nonlinearity ({len(nonlinearities)})")
        out = []
        for nl, q in zip(nonlinearities, params):
            q = np.array(nl.check_params(q), dtype=float)
            if q.ndim != 1 or not np.all(np.isfinite(q)):
                raise ParameterError(f"{label} nonlinearity {nl.name!r} needs one finite parameter vector")
            out.append(q)
        return out

    @property
    def n_inputs(self) -> int:
        return self.numerators.shape[1]

    @property
    def n_outputs(self) -> int:
        return self.numerators.shape[0]

    @property
    def order(self) -> int:
        """States of the realisation: ``p * deg F``."""
        return self.n_outputs * (self.denominators.shape[1] - 1)

    @property
    def linear(self):
        """The linear block as a MIMO :class:`control.TransferFunction` with named signals."""
        import control

        num = [[list(self.numerators[i, j]) for j in range(self.n_inputs)] for i in range(self.n_outputs)]
        den = [[list(self.denominators[i]) for _ in range(self.n_inputs)] for i in range(self.n_outputs)]
        return control.tf(num, den, inputs=list(self.input_names), outputs=list(self.output_names),
                          name=f"{self.name}_linear")

    def element(self, output=0, input=0):
        """The SISO model from one input to one output, the other inputs held at zero.

        ``y_i = h_i(B_ij(p)/F_i(p) e^{-tau_j p} g_j(u_j)) + y0_i`` as a
        :class:`~hammerstein_ctrl.blocks.BlockModel` (Hammerstein, Wiener or
        both): what the SISO tools (``tune_pid``, ``plots.bode``, ...) take,
        e.g. to tune one loop of a decentralised controller.  With an output
        nonlinearity this is exact only while the other inputs stay at zero.

        Parameters
        ----------
        output, input : int or str
            Channel index or name.

        Examples
        --------
        >>> import numpy as np
        >>> from hammerstein_ctrl import Tanh
        >>> m = MIMOModel([[[1.0], [2.0]]], [[1.0, 3.0]], input_nonlinearities=[Tanh(), Tanh()],
        ...               input_params=[[1.0, 1.0], [0.5, 2.0]], input_names=["a", "b"], output_names=["y"])
        >>> e = m.element("y", "b")
        >>> type(e).__name__, e.linear.num[0][0].tolist(), e.input_params.tolist()
        ('HammersteinModel', [2.0], [0.5, 2.0])
        """
        import control

        from ._model import BlockModel

        i = self._index(output, self.output_names, "output")
        j = self._index(input, self.input_names, "input")
        g = None if self.input_nonlinearities is None else self.input_nonlinearities[j]
        h = None if self.output_nonlinearities is None else self.output_nonlinearities[i]
        return BlockModel.build(control.tf(self.numerators[i, j], self.denominators[i]), input_nonlinearity=g,
                                input_params=None if g is None else self.input_params[j], output_nonlinearity=h,
                                output_params=None if h is None else self.output_params[i],
                                offset=float(self.offset[i]), intersample=self.intersample,
                                name=f"{self.name}_{self.output_names[i]}_{self.input_names[j]}",
                                delay=float(self.delays[j]))

    @staticmethod
    def _index(which, names, what: str) -> int:
        if isinstance(which, str) and which in names:
            return names.index(which)
        if isinstance(which, (int, np.integer)) and not isinstance(which, bool) and 0 <= which < len(names):
            return int(which)
        raise ParameterError(f"no {what} {which!r}: give a name in {list(names)} or an index 0..{len(names) - 1}")

    def poles(self) -> list:
        """The poles of each output row."""
        return [np.roots(d) for d in self.denominators]

    def is_stable(self) -> bool:
        """Whether every row's poles lie in the open left half-plane."""
        return all(np.all(r.real < 0) for r in self.poles())

    def to_ss(self):
        """The linear block as a :class:`control.StateSpace` (one observable canonical form per row).

        Examples
        --------
        >>> S = MIMOModel([[[1.0], [2.0]], [[0.5], [1.0]]], [[1.0, 1.0], [1.0, 3.0]]).to_ss()
        >>> S.nstates, S.input_labels, S.output_labels
        (2, ['u[0]', 'u[1]'], ['y[0]', 'y[1]'])
        """
        import control

        A, B, C, D = observable_realization(self.numerators, self.denominators)
        return control.ss(A, B, C, D, inputs=list(self.input_names), outputs=list(self.output_names),
                          name=f"{self.name}_linear")

    def g(self, u) -> np.ndarray:
        """The input nonlinearities applied to ``u`` ``(N, m)`` (the identity where there are none)."""
        u = np.asarray(u, dtype=float)
        if u.ndim > 2 or u.shape[-1] != self.n_inputs:
            raise DataError(f"u must have {self.n_inputs} column(s), one per input, got an array of shape {u.shape}")
        u = u.reshape(-1, self.n_inputs)
        if self.input_nonlinearities is None:
            return u.copy()
        return np.column_stack([nl(u[:, j], q) for j, (nl, q) in
                                enumerate(zip(self.input_nonlinearities, self.input_params))])

    def h(self, z) -> np.ndarray:
        """The output nonlinearities applied to ``z`` ``(N, p)``."""
        z = np.asarray(z, dtype=float)
        if z.ndim > 2 or z.shape[-1] != self.n_outputs:
            raise DataError(f"z must have {self.n_outputs} column(s), one per output, got an array of shape {z.shape}")
        z = z.reshape(-1, self.n_outputs)
        if self.output_nonlinearities is None:
            return z.copy()
        return np.column_stack([nl(z[:, i], q) for i, (nl, q) in
                                enumerate(zip(self.output_nonlinearities, self.output_params))])

    def _inputs(self, t, u, intersample):
        from ..data._iodata import IOData

        if isinstance(t, IOData):
            if u is not None:
                raise ParameterError("give a record, or t and u, not both")
            data = t
            order = _channel_order(self.input_names, data.input_names, "input", data.name)
            return data.inputs[:, order], data.dt, data.intersample if intersample is None else intersample
        from .._checks import as_channels, as_signal, uniform_grid

        t = as_signal(t, "t")
        _, dt = uniform_grid(t)
        u = as_channels(u, "u")
        if u.ndim == 1 and self.n_inputs == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape != (t.size, self.n_inputs):
            raise DataError(f"u must have shape (N, {self.n_inputs}) = ({t.size}, {self.n_inputs}), one column per "
                            f"input, got {u.shape}")
        return u, dt, self.intersample if intersample is None else intersample

    def _record_outputs(self, Y, t):
        """The simulated outputs ``Y`` (the model's order) in the order of a record's outputs."""
        from ..data._iodata import IOData

        if not isinstance(t, IOData):
            return Y
        order = _channel_order(self.output_names, t.output_names, "output", t.name)
        back = np.empty_like(order)
        back[order] = np.arange(order.size)
        return Y[:, back]

    def simulate(self, t, u=None, *, intersample: str | None = None) -> np.ndarray:
        """The sampled response ``(N, p)`` from rest to a record or to ``u`` ``(N, m)`` on the grid ``t``.

        Exact under the record's (or ``intersample``'s) hold, as the identification simulates.
        A record's channels are matched to the model's by name (its outputs
        come back in the record's order); a record with other names is refused,
        unless one side has python-control's default names ``u[j]``/``y[i]``.

        Examples
        --------
        >>> m = MIMOModel([[[1.0], [2.0]]], [[1.0, 1.0]])          # y = (u0 + 2 u1) / (p + 1)
        >>> t = np.arange(0, 30, 0.1)
        >>> round(float(m.simulate(t, np.ones((t.size, 2)))[-1, 0]), 6)    # the DC gain 1 + 2
        3.0
        """
        inputs, dt, hold = self._inputs(t, u, intersample)
        Y = simulate_mimo_batch(self.numerators[None], self.denominators[None], inputs, dt,
                                input_nonlinearities=self.input_nonlinearities,
                                input_params=None if self.input_params is None else [q[None] for q in
                                                                                     self.input_params],
                                output_nonlinearities=self.output_nonlinearities,
                                output_params=None if self.output_params is None else [q[None] for q in
                                                                                       self.output_params],
                                offsets=self.offset[None], intersample=check_intersample(hold),
                                delays=self.delays[None] if np.any(self.delays) else None)
        return self._record_outputs(Y[0].T, t)

    def h_input(self, t, u=None, *, intersample: str | None = None) -> np.ndarray:
        """The signals ``z`` ``(N, p)`` entering the output nonlinearities (the linear block's outputs)."""
        inputs, dt, hold = self._inputs(t, u, intersample)
        Z = simulate_mimo_batch(self.numerators[None], self.denominators[None], inputs, dt,
                                input_nonlinearities=self.input_nonlinearities,
                                input_params=None if self.input_params is None else [q[None] for q in
                                                                                     self.input_params],
                                intersample=check_intersample(hold),
                                delays=self.delays[None] if np.any(self.delays) else None)
        return self._record_outputs(Z[0].T, t)

    def save(self, path) -> None:
        """Write the model to ``path`` as versioned JSON (:func:`hammerstein_ctrl.load_model` reads it)."""
        from ._json import save_model

        save_model(self, path)

    def _pade_inputs(self, order: int):
        """``(Ap, Bp, Cp, Dp)``: the inputs' dead times as Pade approximants side by side (identity where none)."""
        import control
        from scipy.linalg import block_diag

        blocks = []
        for tau in self.delays:
            if tau > 0:
                P = control.ss(control.tf(*control.pade(float(tau), order)))
                blocks.append((P.A, P.B, P.C, P.D))
            else:
                blocks.append((np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))))
        return tuple(block_diag(*[b[k] for b in blocks]) for k in range(4))

    def to_iosys(self, dt=None, name: str | None = None, *, pade_order: int | None = None):
        """A continuous-time :class:`control.NonlinearIOSystem` with the model's named inputs and outputs.

        States: each input's dead time as a Pade approximant of order
        ``pade_order`` (default ``config.defaults["delay.pade_order"]``; none
        without dead times), then the observable canonical form of each row
        (:meth:`to_ss`): ``w = Pade(g(u))``, ``dx/dt = A x + B w``, ``y = h(C x + D w) + y0``.

        Examples
        --------
        >>> sys = MIMOModel([[[1.0], [2.0]]], [[1.0, 1.0]], delays=[0.0, 0.5]).to_iosys(pade_order=3)
        >>> sys.nstates, sys.input_labels
        (4, ['u[0]', 'u[1]'])
        """
        import control

        from .. import config

        from .._checks import as_count

        if isinstance(dt, str) and name is None:               # to_iosys("name"), as before the dt argument
            dt, name = None, dt
        if dt is not None:
            raise ParameterError("the exact sampled export takes one channel pair: model.element(output, "
                                 "input).to_iosys(dt); to_iosys() gives the continuous-time MIMO system")
        A, B, C, D = observable_realization(self.numerators, self.denominators)
        order = config.get("delay.pade_order") if pade_order is None else as_count(pade_order, "pade_order", minimum=1)
        Ap, Bp, Cp, Dp = self._pade_inputs(order)
        k, model = Ap.shape[0], self

        def updfcn(t, x, u, params):
            g = model.g(u)[0]
            w = Cp @ x[:k] + Dp @ g
            return np.concatenate([Ap @ x[:k] + Bp @ g, A @ x[k:] + B @ w])

        def outfcn(t, x, u, params):
            w = Cp @ x[:k] + Dp @ model.g(u)[0]
            return model.h(C @ x[k:] + D @ w)[0] + model.offset

        return control.nlsys(updfcn, outfcn, inputs=signal_names(self.input_names, "input"),
                             outputs=signal_names(self.output_names, "output"),
                             states=k + A.shape[0], name=name or self.name)

    def describe(self) -> str:
        """The blocks, one line each.

        Examples
        --------
        >>> print(MIMOModel([[[1.0, 2.0], [0.5, 0.0]]], [[1.0, 3.0, 2.0]]).describe())
        mimo: 1 outputs, 2 inputs
          y[0] = (p + 2) / (p^2 + 3 p + 2) u[0] + (0.5 p) / (p^2 + 3 p + 2) u[1]
        """
        lines = [f"{self.kind}: {self.n_outputs} outputs, {self.n_inputs} inputs"]
        for i in range(self.n_outputs):
            f = _polynomial_text(self.denominators[i])
            terms = " + ".join(f"({_polynomial_text(self.numerators[i, j])}) / ({f}) {self.input_names[j]}"
                               for j in range(self.n_inputs))
            lines.append(f"  {self.output_names[i]} = {terms}")
        for label, nls, ps, names in (("g", self.input_nonlinearities, self.input_params, self.input_names),
                                      ("h", self.output_nonlinearities, self.output_params, self.output_names)):
            for nl, q, n in zip(nls or (), ps or (), names):
                lines.append(f"  {label}[{n}] = {nl.describe(q)}")
        if np.any(self.offset):
            lines.append("  y0 = " + ", ".join(f"{v:.6g}" for v in self.offset))
        if np.any(self.delays):
            lines.append("  dead times: " + ", ".join(f"{n}: {d:.6g} s" for n, d in zip(self.input_names, self.delays)))
        return "\n".join(lines)

    def __repr__(self):
        return f"MIMOModel({self.kind!r}, outputs={self.n_outputs}, inputs={self.n_inputs}, order={self.order})"
