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


import numpy as np

from .._checks import ESTIMATE, as_count
from ..exceptions import ParameterError
from ._nonlinearities import Nonlinearity
from ._structure import LinearStructure
from ._mimo_sim import _check_linear, _input_delays, _nonlinearity_list
from ._mimo_model import MIMOModel

__all__ = ["MIMOStructure", "mimo_structure", "MIMOHammersteinStructure", "MIMOWienerStructure",
           "MIMOHammersteinWienerStructure"]


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


