"""Fitting MIMO block models: the least-squares cost and the data-driven starts.

:class:`MIMOCost` is the sum of squared errors over every output channel,
with the least-squares protocol of the SISO cost (``residuals``,
``residuals_batch``, ``batch``), so the optimisers, the uncertainty and the
verdicts work on it unchanged.  Its residual vector lists output 0's samples,
then output 1's, and so on.

:func:`mimo_starts` computes a starting point from the data alone, one output
row at a time, using that each row's output is linear in its numerators once
its denominator and the static blocks are fixed:

1. **Denominators.**  A MISO ARX model of each output (lags of every input's
   basis functions, or of the input itself for other families) gives the row's discrete poles, mapped to continuous time
   (``s = log z / dt``; right-half-plane roots reflected).
2. **Input nonlinearities** (Hammerstein, H-W).  Families linear in their
   parameters: the output is fitted by least squares in the responses
   ``p^l/F_i phi_k(u_j)`` of every basis function through every numerator
   power, and each input's coefficient matrix split by its leading singular
   pair into the numerators and ``g_j``'s coefficients.  Families with a scale
   parameter: their shapes (:meth:`~hammerstein_ctrl.blocks.Nonlinearity.shape_grid`)
   are scanned one input at a time, the others held, and the scale is the
   numerator gain.
3. **Output nonlinearities** (Wiener, H-W): each row's linear output,
   scaled to the monic reference element, is the signal ``h_i`` is fitted to
   (least squares for a basis, a scanned shape with a least-squares scale otherwise).
4. The offsets come from the same solves.
5. **Dead times** (when the structure has them): whole-sample shifts of each
   input, chosen one input at a time by the MISO ARX fits of all outputs,
   give a shifted record on which steps 1-4 run without delay; the shifts
   (in seconds) start the estimated dead times.

Levenberg-Marquardt on :class:`MIMOCost` then refines everything
(:func:`hammerstein_ctrl.fit._auto_records.auto_mimo`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import DataError, ParameterError
from ..data._iodata import IOData
from ..blocks._mimo import MIMOStructure
from ..blocks._mimo_sim import simulate_mimo_batch
from ._objective import NONFINITE_RESIDUAL
from ._cost import StructureSized

__all__ = ["MIMOCost", "mimo_starts", "stabilized", "completed", "noise_weights", "WEIGHTING_RATIO", "delay_shifts",
           "shifted_inputs", "with_delays"]


class MIMOCost(StructureSized):
    """Sum of squared output errors of a MIMO structure on a record with as many channels.

    Parameters
    ----------
    data : IOData
        A record with ``structure.n_inputs`` inputs and ``structure.n_outputs`` outputs.
    structure : MIMOStructure
    reject_unstable : bool, default False
        Score candidates with a right-half-plane pole ``inf``.
    weights : array_like, shape (p,), optional
        Each output's weight on its residuals (``J = sum_i w_i^2 |e_i|^2``);
        default 1.  ``auto`` weighs outputs of different noise levels by the
        inverse of each one's residual standard deviation (:meth:`weighted`).

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import IOData, LinearStructure, Tanh
    >>> from hammerstein_ctrl.blocks import MIMOHammersteinStructure
    >>> t = np.arange(300) * 0.05
    >>> u = np.column_stack([np.sin(t), np.cos(0.7 * t)])
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Tanh(), Tanh()], n_outputs=2)
    >>> beta = [1.0, 0.5, 0.3, 2.0, 1.0, 1.0, 2.0, 0.5]
    >>> y = s.model(beta).simulate(t, u)
    >>> cost = MIMOCost(IOData(u, y, dt=0.05), s)
    >>> cost(beta), cost.residuals(beta).shape
    (0.0, (600,))
    """

    def __init__(self, data: IOData, structure: MIMOStructure, *, reject_unstable: bool = False, weights=None):
        if not isinstance(structure, MIMOStructure):
            raise ParameterError(f"structure must be a MIMO structure, got {type(structure).__name__}")
        if not isinstance(data, IOData):
            raise ParameterError(f"data must be an IOData record, got {type(data).__name__}")
        if (data.n_inputs, data.n_outputs) != (structure.n_inputs, structure.n_outputs):
            raise DataError(f"record {data.name!r} has {data.n_inputs} input(s) and {data.n_outputs} output(s); the "
                            f"structure has {structure.n_inputs} and {structure.n_outputs}")
        self.data, self.structure = data, structure
        self.reject_unstable = bool(reject_unstable)
        self._inputs = np.ascontiguousarray(data.inputs.T).T        # (N, m) with each channel contiguous
        self._workspace: dict = {}                                   # buffers reused by every evaluation
        self._y = np.ascontiguousarray(data.outputs.T).reshape(-1)
        self.weights = None
        if weights is not None:
            w = np.asarray(weights, dtype=float).reshape(-1)
            if w.size != structure.n_outputs or not np.all(np.isfinite(w) & (w > 0)):
                raise ParameterError(f"weights must be {structure.n_outputs} positive numbers, got {weights!r}")
            self.weights = w
            self._w = np.repeat(w, len(data))

    def weighted(self, weights) -> "MIMOCost":
        """The same cost with each output's residuals weighted (``None``: unweighted)."""
        return MIMOCost(self.data, self.structure, reject_unstable=self.reject_unstable, weights=weights)

    @property
    def n_samples(self) -> int:
        """Residuals: samples times outputs."""
        return self._y.size

    def simulate_batch(self, betas) -> np.ndarray:
        """Outputs ``(B, p, N)`` of a batch of candidates."""
        return self._simulated(betas).copy()

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_workspace"] = {}
        return state

    def _simulated(self, betas) -> np.ndarray:
        """:meth:`simulate_batch` in the cost's reused buffer (overwritten by the next evaluation)."""
        s = self.structure
        b = np.atleast_2d(s.check_beta(betas))
        num, den = s.coefficients(b)
        with np.errstate(all="ignore"):
            return simulate_mimo_batch(num, den, self._inputs, self.data.dt,
                                       input_nonlinearities=s.input_nonlinearities, input_params=s.input_params(b),
                                       output_nonlinearities=s.output_nonlinearities,
                                       output_params=s.output_params(b), offsets=s.offsets(b),
                                       intersample=self.data.intersample, workspace=self._workspace,
                                       delays=s.input_delays(b) if s.has_delay else None)

    def simulate(self, beta) -> np.ndarray:
        """The simulated outputs ``(N, p)`` at one beta."""
        return self.simulate_batch(beta)[0].T

    def residuals_batch(self, betas) -> np.ndarray:
        """Residual vectors ``(B, p N)``: each candidate's output errors, output by output."""
        Y = self._simulated(betas)
        R = self._y - Y.reshape(Y.shape[0], -1)
        if self.weights is not None:
            R *= self._w
        with np.errstate(all="ignore"):
            for r in R:
                if not np.isfinite(r.sum()):
                    r[~np.isfinite(r)] = NONFINITE_RESIDUAL
        if self.reject_unstable:
            R[self.structure.unstable(betas)] = NONFINITE_RESIDUAL
        return R

    def residuals(self, beta) -> np.ndarray:
        """``y - yhat`` of every output (weighted), end to end (``J = sum(residuals**2)``)."""
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("residuals(beta) takes one vector; use residuals_batch for a batch")
        return self.residuals_batch(b)[0]

    def batch(self, betas) -> np.ndarray:
        """J for each row of ``betas`` (``inf`` where the simulation fails or, with ``reject_unstable``, diverges)."""
        s = self.structure
        Y = self._simulated(betas)
        E = Y.reshape(Y.shape[0], -1)
        with np.errstate(all="ignore"):
            E -= self._y
            if self.weights is not None:
                E *= self._w
            J = np.array([e @ e for e in E])
        J[~np.isfinite(J)] = np.inf
        if self.reject_unstable:
            J[s.unstable(betas)] = np.inf
        return J

    def __call__(self, beta) -> float:
        b = self.structure.check_beta(beta)
        if b.ndim != 1:
            raise ParameterError("cost(beta) takes one vector; use cost.batch for a batch")
        return float(self.batch(b)[0])

    def unweighted_residuals(self, beta) -> np.ndarray:
        """``y - yhat`` of every output without the weights (what the fit figures measure)."""
        r = self.residuals(beta)
        return r if self.weights is None else r / self._w

    def split(self, signal) -> list:
        """A signal over all outputs (such as :meth:`residuals`) cut into one piece per output."""
        return list(np.asarray(signal).reshape(self.structure.n_outputs, -1))

    def __repr__(self):
        return f"MIMOCost({self.data.name!r}, N={len(self.data)}, {self.structure!r})"


# -- starts ------------------------------------------------------------------------------------
def _continuous_denominator(a: np.ndarray, dt: float, n: int) -> np.ndarray:
    """A monic stable continuous denominator of degree ``n`` from the discrete one ``[1, a1, ..., an]``
    (:func:`~hammerstein_ctrl.fit._linear_starts.continuous_poles`; poles on the axis moved just left of it)."""
    from ._linear_starts import continuous_poles

    z = np.roots(np.concatenate([[1.0], a]))
    s = continuous_poles(np.where(np.abs(z) < 1e-8, 1e-8, z), dt)
    s = np.where(np.abs(s.real) < 1e-6 / dt, -1e-3 / dt + 1j * s.imag, s)
    den = np.real(np.poly(s)) if s.size else np.ones(1)
    return den if den.size == n + 1 else np.concatenate([den, np.zeros(n + 1 - den.size)])


def _arx_denominator(y: np.ndarray, inputs: np.ndarray, n: int, dt: float, offset: bool) -> np.ndarray:
    """Row denominator from a MISO ARX fit of order ``n`` (inputs at lags 0..n)."""
    N, m = inputs.shape
    rows = np.arange(n, N)
    cols = [-y[rows - k] for k in range(1, n + 1)]
    cols += [inputs[rows - k, j] for j in range(m) for k in range(0, n + 1)]
    if offset:
        cols.append(np.ones(rows.size))
    X = np.column_stack(cols)
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    w = np.linalg.lstsq(X / scale, y[rows], rcond=None)[0] / scale
    return _continuous_denominator(w[:n], dt, n)


def _responses(den, signals, nb, data) -> np.ndarray:
    """``(K, nb+1, N)``: the responses of ``p^l/F`` (l = 0..nb) to each of the ``K`` signals."""
    from ..simulate._simulate import simulate_batch

    K, N = signals.shape
    n = den.size - 1
    num = np.zeros((nb + 1, n + 1))
    for power in range(nb + 1):
        num[power, n - power] = 1.0
    nums = np.tile(num, (K, 1))
    dens = np.tile(den, (K * (nb + 1), 1))
    S = np.repeat(signals, nb + 1, axis=0)
    with np.errstate(all="ignore"):
        Y = simulate_batch(nums, dens, S, data.dt, intersample=data.intersample)
    return Y.reshape(K, nb + 1, N)


def _lstsq(columns: np.ndarray, y: np.ndarray):
    """``(coefficients, sse)`` of ``y ~ columns.T @ w`` (columns scaled; non-finite columns give ``None``)."""
    X = columns.T
    if not np.all(np.isfinite(X)):
        return None, np.inf
    scale = np.linalg.norm(X, axis=0)
    scale[scale == 0] = 1.0
    w = np.linalg.lstsq(X / scale, y, rcond=None)[0] / scale
    r = y - X @ w
    return w, float(r @ r)


def _features(nl, u):
    """``(K, N)`` regressors of an input nonlinearity's basis, or ``None`` for a scanned family."""
    if nl is None:
        return u[None, :]
    phi = nl.checked_basis(u)
    return None if phi is None else np.asarray(phi, dtype=float)


class _Rows:
    """Each output row's denominator and the responses of its numerator powers."""

    def __init__(self, data: IOData, structure: MIMOStructure):
        self.data, self.s = data, structure
        self.U, self.Y = data.inputs, data.outputs
        n, nb = structure.linear.den_order, structure.linear.num_order
        self.nb = nb
        nls = structure.input_nonlinearities
        drives = []
        for j in range(structure.n_inputs):
            phi = _features(None if nls is None else nls[j], self.U[:, j])
            drives.append(self.U[:, j][None, :] if phi is None else phi)
        drives = np.concatenate(drives).T
        self.dens = [_arx_denominator(self.Y[:, i], drives, n, data.dt, structure.offset)
                     for i in range(structure.n_outputs)]
        #: Each output's unit in the start's comparisons: its spread when the spreads differ by more than
        #: :data:`SPREAD_RATIO` (mm beside m then changes nothing), else 1.
        w = _inverse_levels(np.std(self.Y, axis=0), SPREAD_RATIO)
        self.scales = np.ones(structure.n_outputs) if w is None else 1.0 / w

    def columns(self, i: int, signals: list) -> np.ndarray:
        """Regressors of row ``i``: for each input, its signals' responses through every numerator power."""
        blocks = [_responses(self.dens[i], sig, self.nb, self.data).reshape(-1, len(self.data)) for sig in signals]
        if self.s.offset:
            blocks.append(np.ones((1, len(self.data))))
        return np.concatenate(blocks)

    def fit(self, signals: list):
        """``(per-row coefficients, total sse)`` of every row on the given input signals."""
        out, total = [], 0.0
        for i in range(self.s.n_outputs):
            w, sse = _lstsq(self.columns(i, signals), self.Y[:, i])
            if w is None:
                return None, np.inf
            out.append(w)
            total += sse / self.scales[i] ** 2
        return out, total


def _scale_shapes(nl, u):
    grid = nl.shape_grid(u)
    if grid is None or nl.scale_index is None:
        raise ParameterError(f"no automatic start for the {nl.name!r} nonlinearity in a MIMO structure (it has "
                             "neither a basis nor a scan); give x0")
    return np.asarray(grid, dtype=float)


def _input_signals(rows: _Rows, structure: MIMOStructure):
    """Each input's regressor signals ``(K_j, N)`` and, for scanned families, the chosen shape."""
    U, nls = rows.U, structure.input_nonlinearities
    signals = [_features(None if nls is None else nls[j], U[:, j]) for j in range(structure.n_inputs)]
    shapes = [None] * structure.n_inputs
    scanned = [j for j in range(structure.n_inputs) if signals[j] is None]
    current = [U[:, j][None, :] if sig is None else sig for j, sig in enumerate(signals)]
    for j in scanned:                    # one input at a time, the others held at their current signal
        best = None
        for p in _scale_shapes(nls[j], U[:, j]):
            with np.errstate(all="ignore"):
                v = nls[j](U[:, j], p)[None, :]
            trial = current[:j] + [v] + current[j + 1:]
            _, sse = rows.fit(trial)
            if best is None or sse < best[0]:
                best = (sse, p, v)
        if best is not None:
            shapes[j], current[j] = best[1], best[2]
    return current, shapes


def _split_columns(rows: _Rows, coefficients: list, signals: list, structure: MIMOStructure):
    """``(numerators (p, m, nb+1), g weights per input, offsets)`` from the rows' least-squares coefficients."""
    p, m, nb = structure.n_outputs, structure.n_inputs, rows.nb
    num = np.zeros((p, m, nb + 1))
    weights, offsets = [], np.zeros(p)
    sizes = [sig.shape[0] for sig in signals]
    for j in range(m):
        start = sum(sizes[:j]) * (nb + 1)
        M = np.stack([c[start:start + sizes[j] * (nb + 1)].reshape(sizes[j], nb + 1).T / rows.scales[i]
                      for i, c in enumerate(coefficients)])                      # each output in its own units
        # M[i, l, k]: row i, numerator power l, basis function k; rank one: b_il w_k
        flat = M.reshape(p * (nb + 1), sizes[j])
        U_, S_, Vt = np.linalg.svd(flat, full_matrices=False)
        b, w = (U_[:, 0] * S_[0]).reshape(p, nb + 1) * rows.scales[:, None], Vt[0]
        num[:, j, :] = b[:, ::-1]                     # descending powers
        weights.append(w)
    if structure.offset:
        offsets = np.array([c[-1] for c in coefficients])
    return num, weights, offsets


#: Smallest size of a reference element (the one the gain convention makes monic) relative to the largest
#: element it is compared with, in the linear start: below it the convention cannot hold on this plant.
MIN_REFERENCE_SHARE = 0.02


def _reference_lead(block: np.ndarray, what: str, scales=None) -> float:
    """The leading coefficient of the reference element ``block[0]`` (numerators, descending powers), checked
    against the others of ``block``, each row in units of its output's spread ``scales``."""
    lead = float(block[0, 0])
    relative = np.abs(block[:, 0]) / (1.0 if scales is None else np.asarray(scales, dtype=float))
    largest = float(relative.max()) * (1.0 if scales is None else float(scales[0]))
    if not np.isfinite(lead) or abs(lead) < MIN_REFERENCE_SHARE * largest:
        share = 0.0 if not largest else abs(lead) / largest
        raise ParameterError(f"{what} ({100 * share:.1f} % of the largest in the linear start): the gain convention "
                             "makes that element's leading coefficient 1, so it must be there; reorder the channels, "
                             "lower num_order if that numerator has a lower degree, or fit the outputs one at a time")
    return lead


def _normalized_inputs(structure, num, weights, shapes, scales=None):
    """Input nonlinearities' parameters with ``B_0j`` monic (its leading coefficient moved into ``g_j``)."""
    params = []
    for j in range(structure.n_inputs):
        lead = _reference_lead(num[:, j], f"input {j} hardly acts on output 0", scales)
        num[:, j] /= lead
        nl = structure.input_nonlinearities[j]
        if shapes[j] is None:
            params.append(weights[j] * lead)
        else:
            q = np.array(shapes[j], dtype=float)
            q[nl.scale_index] = weights[j][0] * lead
            params.append(q)
    return params


def _fit_output(nl, z, y, offset: bool):
    """``(parameters of h, offset)`` fitting ``y ~ h(z) (+ c)``."""
    const = [np.ones((1, z.size))] if offset else []
    phi = nl.checked_basis(z)
    if phi is not None:
        w, _ = _lstsq(np.concatenate([np.asarray(phi, dtype=float)] + const), y)
        return w[:nl.n_params], (w[-1] if offset else 0.0)
    best = None
    for p in _scale_shapes(nl, z):
        with np.errstate(all="ignore"):
            v = nl(z, p)[None, :]
        w, sse = _lstsq(np.concatenate([v] + const), y)
        if w is not None and (best is None or sse < best[0]):
            q = np.array(p, dtype=float)
            q[nl.scale_index] = w[0]
            best = (sse, q, w[-1] if offset else 0.0)
    if best is None:
        raise ParameterError(f"no automatic start for the output nonlinearity {nl.name!r}; give x0")
    return best[1], best[2]


def _output_blocks(structure, data, num, dens, g_params):
    """Rows scaled so ``B_i0`` is monic, and each ``h_i`` fitted to the scaled row output."""
    p = structure.n_outputs
    h_params, offsets = [], np.zeros(p)
    for i in range(p):
        num[i] /= _reference_lead(num[i], f"output {i} hardly responds to input 0")
    Z = simulate_mimo_batch(num[None], np.asarray(dens)[None], data.inputs, data.dt,
                            input_nonlinearities=structure.input_nonlinearities,
                            input_params=None if g_params is None else [q[None] for q in g_params],
                            intersample=data.intersample)[0]
    for i, nl in enumerate(structure.output_nonlinearities):
        h_params.append(None)
        h_params[i], offsets[i] = _fit_output(nl, Z[i], data.outputs[:, i], structure.offset)
    return h_params, offsets


def _unit_gain_inputs(structure, num, g_params):
    """H-W: each ``g_j``'s gain parameter set to 1, the gain moved into column ``j`` of the numerators."""
    out = []
    for j, nl in enumerate(structure.input_nonlinearities):
        q = np.array(g_params[j], dtype=float)
        k = nl.gain_index
        gain = q[k] if np.isfinite(q[k]) and q[k] != 0 else 1.0
        if nl.scale_index is not None:
            q[k] = 1.0
        else:                                     # linear in its parameters: scale them all
            q = q / gain
        num[:, j] *= gain
        out.append(q)
    return out


def mimo_starts(data: IOData, structure: MIMOStructure) -> list[np.ndarray]:
    """Starting betas for a MIMO structure from the data alone (see the module's description).

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import IOData, LinearStructure, Polynomial
    >>> from hammerstein_ctrl.blocks import MIMOHammersteinStructure
    >>> t = np.arange(2000) * 0.02
    >>> rng = np.random.default_rng(0); u = np.cumsum(rng.standard_normal((2000, 2)), 0) * 0.05
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Polynomial(2), Polynomial(2)], n_outputs=2)
    >>> truth = [2.0, 0.5, -0.4, 1.0, 1.0, 0.3, 0.7, -0.2]
    >>> y = s.model(truth).simulate(t, u)
    >>> x = mimo_starts(IOData(u, y, dt=0.02), s)[0]
    >>> bool(np.allclose(x, truth, atol=1e-6))
    True
    """
    s = structure
    if s.has_delay:
        return _delayed_starts(data, s)
    rows = _Rows(data, s)
    if s.input_nonlinearities is not None:
        signals, shapes = _input_signals(rows, s)
    else:
        signals, shapes = [data.inputs[:, j][None, :] for j in range(s.n_inputs)], [None] * s.n_inputs
    coefficients, _ = rows.fit(signals)
    if coefficients is None:
        raise ParameterError("no automatic start: the regression on the record's inputs failed; give x0")
    num, weights, offsets = _split_columns(rows, coefficients, signals, s)
    g_params = None
    if s.input_nonlinearities is not None:
        g_params = _normalized_inputs(s, num, weights, shapes, rows.scales)
    h_params = None
    if s.output_nonlinearities is not None:
        if g_params is not None:
            g_params = _unit_gain_inputs(s, num, g_params)
        h_params, offsets = _output_blocks(s, data, num, rows.dens, g_params)
    return [_assemble(s, num, rows.dens, g_params, h_params, offsets)]


def _shift_scores(Y, inputs, n: int, shifts, j: int, top: int, first: int) -> np.ndarray:
    """For each shift ``k = 0..top`` of input ``j`` (the others at ``shifts``), the squared errors of MISO ARX fits
    of all outputs summed.

    The columns that do not move (output lags, the other inputs, a constant)
    are factored once per output; each shift then costs the projection of
    input ``j``'s ``n + 1`` lag columns on their complement and a small solve.
    """
    N = Y.shape[0]
    rows = np.arange(first, N)
    fixed = [inputs[rows - d - k, i] for i, d in enumerate(shifts) if i != j for k in range(n + 1)]
    scores = np.zeros(top + 1)
    for y in Y.T:
        A = np.column_stack([-y[rows - k] for k in range(1, n + 1)] + fixed + [np.ones(rows.size)])
        Q, _ = np.linalg.qr(A / np.maximum(np.linalg.norm(A, axis=0), 1e-300))
        target = y[rows] - Q @ (Q.T @ y[rows])
        for shift in range(top + 1):
            U = np.column_stack([inputs[rows - shift - k, j] for k in range(n + 1)])
            U -= Q @ (Q.T @ U)
            w, *_ = np.linalg.lstsq(U, target, rcond=None)
            r = target - U @ w
            scores[shift] += float(r @ r)
    return scores


def delay_shifts(data: IOData, structure: MIMOStructure) -> list[int]:
    """Whole-sample dead time of each input: fixed ones rounded, estimated ones scanned one input at a time
    (``0 .. config.defaults["delay.max_samples"]``, at most a quarter of the record) by MISO ARX fits.

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import IOData, LinearStructure, Polynomial
    >>> from hammerstein_ctrl.blocks import MIMOHammersteinStructure
    >>> rng = np.random.default_rng(1); u = np.repeat(rng.uniform(-1, 1, (100, 2)), 10, axis=0)
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Polynomial(1)] * 2, n_outputs=1, delay=[0.3, 0.0])
    >>> y = s.model([2.0, 1.5, 0.5]).simulate(np.arange(1000) * 0.1, u)
    >>> delay_shifts(IOData(u, y, dt=0.1), s.with_delay("estimate"))
    [3, 0]
    """
    from .. import config
    from ..simulate._delay import ESTIMATE

    dt, n = data.dt, structure.linear.den_order
    shifts = [0 if d == ESTIMATE else int(round(d / dt)) for d in structure.delays]
    top = min(config.get("delay.max_samples"), len(data) // 4)
    first = top + max(shifts) + n + 1
    if len(data) - first <= 4 * (n + 1) * (structure.n_inputs + 1):
        return shifts
    for j, d in enumerate(structure.delays):
        if d != ESTIMATE:
            continue
        best = int(np.argmin(_shift_scores(data.outputs, data.inputs, n, shifts, j, top, first)))
        shifts[j] = max(best - (1 if data.intersample == "zoh" else 0), 0)
    return shifts


def shifted_inputs(data: IOData, shifts) -> IOData:
    """The record with input ``j`` delayed by ``shifts[j]`` samples (zeros before the record, as at rest)."""
    U = np.zeros_like(data.inputs)
    for j, d in enumerate(shifts):
        U[d:, j] = data.inputs[:len(data) - d, j]
    return IOData(U, data.y, dt=data.dt, intersample=data.intersample, name=data.name,
                  input_name=list(data.input_names), output_name=list(data.output_names))


def with_delays(s: MIMOStructure, x, shifts, dt: float) -> np.ndarray:
    """A beta of ``s.without_delays()`` with the estimated dead times ``shifts * dt`` put in (the layout of ``s``).

    A fit on the record shifted by whole samples (:func:`shifted_inputs`) is
    the same model as ``s`` with those dead times.
    """
    from ..simulate._delay import ESTIMATE

    base = s.without_delays()
    delays = [shifts[j] * dt for j, d in enumerate(s.delays) if d == ESTIMATE]
    x = np.asarray(x, dtype=float)
    return np.concatenate([x[:base.n_core], delays, x[base.n_core:]])


def _delayed_starts(data: IOData, s: MIMOStructure) -> list[np.ndarray]:
    """Starts of a structure with dead times: the undelayed starts on the record shifted by whole samples."""
    shifts = delay_shifts(data, s)
    return [with_delays(s, x, shifts, data.dt) for x in mimo_starts(shifted_inputs(data, shifts), s.without_delays())]


def _assemble(s: MIMOStructure, num, dens, g_params, h_params, offsets) -> np.ndarray:
    from ..blocks._mimo_model import MIMOModel

    model = MIMOModel(num, np.asarray(dens), input_nonlinearities=s.input_nonlinearities, input_params=g_params,
                      output_nonlinearities=s.output_nonlinearities, output_params=h_params, offset=offsets)
    return s.normalize(s.beta(model))


#: Ratio of the outputs' residual standard deviations past which ``auto`` weighs them.
WEIGHTING_RATIO = 1.5
#: Ratio of the outputs' spreads past which ``auto`` searches with each output in units of its spread.
SPREAD_RATIO = 10.0


def spread_weighted(cost: MIMOCost) -> MIMOCost:
    """``cost`` with each output weighted by the inverse of its spread when the spreads differ by more than
    :data:`SPREAD_RATIO` (outputs in units far apart), else ``cost`` itself (as it is when already weighted)."""
    if cost.weights is not None:
        return cost
    w = _inverse_levels(np.std(np.asarray(cost.data.outputs, dtype=float), axis=0), SPREAD_RATIO)
    return cost if w is None else cost.weighted(w)


def _inverse_levels(levels, ratio: float) -> np.ndarray | None:
    """Each output's weight ``1/level`` scaled to a geometric mean of 1, or ``None`` when the levels are within
    ``ratio`` of each other (or not all finite and positive)."""
    levels = np.asarray(levels, dtype=float)
    if not (np.all(np.isfinite(levels)) and np.all(levels > 0)) or levels.max() <= ratio * levels.min():
        return None
    w = 1.0 / levels
    return w / np.exp(np.mean(np.log(w)))


def noise_weights(cost: MIMOCost, x) -> np.ndarray | None:
    """Each output's weight ``1/sigma_i`` (scaled to a geometric mean of 1) from its residuals at ``x``, or
    ``None`` when the outputs' noise levels are within :data:`WEIGHTING_RATIO` of each other."""
    with np.errstate(all="ignore"):
        sigma = np.array([np.sqrt(np.mean(e * e)) for e in cost.split(cost.unweighted_residuals(x))])
    return _inverse_levels(sigma, WEIGHTING_RATIO)


def completed(cost: "MIMOCost", x0) -> np.ndarray:
    """A user's x0 as a whole beta: the block parameters alone get the offsets that fit them (the outputs' mean
    errors), a whole beta is taken as it is."""
    s = cost.structure
    x = np.asarray(x0, dtype=float).reshape(-1)
    if x.size == s.n_core and s.offset:
        full = np.concatenate([x, np.zeros(s.n_outputs)])
        with np.errstate(all="ignore"):
            errors = cost.data.outputs - cost.simulate(full)
        full[s.n_core:] = np.where(np.isfinite(errors).all(axis=0), errors.mean(axis=0), 0.0)
        x = full
    return s.check_beta(x)


def stabilized(structure: MIMOStructure, beta) -> np.ndarray:
    """``beta`` with every row's right-half-plane poles reflected into the left half-plane.

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Tanh
    >>> from hammerstein_ctrl.blocks import MIMOHammersteinStructure
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Tanh(), Tanh()], n_outputs=2)
    >>> np.round(stabilized(s, [-2.0, 0.5, 0.7, 3.0, 1.0, 1.0, 2.0, 0.5]), 4).tolist()[:4]   # p - 2 -> p + 2
    [2.0, 0.5, 0.7, 3.0]
    """
    x = np.array(structure.check_beta(beta), dtype=float)
    _, den = structure.coefficients(x)
    for i in range(den.shape[1]):
        r = np.roots(den[0, i])
        if np.any(r.real >= 0):
            r = np.where(r.real >= 0, -np.abs(r.real) - 1e-6 + 1j * r.imag, r)
            pos, idx = structure.row_denominator(i)
            x[idx] = np.real(np.poly(r))[pos]
    return x


#: A monic reference numerator's zero past this many times its row's fastest pole: the element seems to have a
#: lower degree than ``num_order``, and its gain drifts into the static block.
ZERO_DRIFT_RATIO = 100.0


def monic_drift_verdicts(structure: MIMOStructure, x, data) -> list:
    """A failure for each monic reference element whose zero ran off past :data:`ZERO_DRIFT_RATIO` times its row's
    fastest pole (``p + b0`` with ``|b0|`` huge: the element has a lower degree, the gain convention cannot hold)."""
    from ..assess._diagnostics import FAILURE, Verdict

    if structure.linear.num_order < 1:
        return []
    num, den = structure.coefficients(np.asarray(x, dtype=float))
    out = []
    for i in range(structure.n_outputs):
        with np.errstate(all="ignore"):
            fastest = float(np.max(np.abs(np.roots(den[0][i])), initial=0.0))
        for j in range(structure.n_inputs):
            if not structure._monic(i, j):
                continue
            zeros = np.roots(num[0][i][j])
            far = float(np.max(np.abs(zeros), initial=0.0))
            if fastest > 0 and far > ZERO_DRIFT_RATIO * fastest:
                out.append(Verdict("monic-drift", FAILURE, (
                    f"the monic numerator from {data.input_names[j]!r} to {data.output_names[i]!r} has a zero at "
                    f"{far:.4g} rad/s, {far / fastest:.0f} times beyond its output's fastest pole: that element seems "
                    f"to have a lower degree than num_order = {structure.linear.num_order}, so the gain convention "
                    f"(its leading coefficient 1) pushes its gain into the static block and the search drifts; "
                    f"lower num_order, or reorder the channels so that a reference element has the full degree")))
    return out

