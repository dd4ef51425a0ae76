"""The MIMO model: its linear blocks, static maps and dead times, simulated and exported to python-control."""

from __future__ import annotations

import numpy as np
from .._checks import check_delay, check_intersample, signal_names
from ..exceptions import DataError, ParameterError
from ._mimo_sim import (_channel_order, _nonlinearity_list, _polynomial_text, _signal_names, observable_realization,
                        simulate_mimo_batch)

__all__ = ["MIMOModel"]


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
