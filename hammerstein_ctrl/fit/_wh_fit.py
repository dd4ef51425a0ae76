"""Fitting Wiener-Hammerstein models: the least-squares cost and the data-driven starts.

:class:`WienerHammersteinCost` is the output-error objective
``J = sum (y - y_hat)^2`` of a
:class:`~hammerstein_ctrl.blocks.WienerHammersteinStructure` on a
record, with the protocol of the optimisers (``cost(beta)``, ``batch``,
``residuals``, ``residuals_batch``, ``simulate``).

The starts follow the classic route: a linear model of the whole order (the
best linear approximation, :func:`bla_structure`), then a scan of the ways its
poles and zeros split between ``G1`` and ``G2`` (:func:`splits`), each scored by
the least-squares fit of the static map through ``G2`` (:func:`split_starts`).
A split that gives a block fewer roots than its order pads it with a fast real
root (:data:`PAD_FACTOR` times the fastest root of the linear model), which the
refinement then moves.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..simulate._batch import simulate_batch
from ._output_error import OutputErrorCost
from ..exceptions import ParameterError
from ..blocks._families import Polynomial
from ..blocks._structure import HammersteinStructure, LinearStructure
from ..blocks._wiener_hammerstein import WienerHammersteinStructure
from ..blocks._unit_gain import simulate_wh

__all__ = ["WienerHammersteinCost", "bla_structure", "splits", "split_starts", "start_record", "PAD_FACTOR",
           "MAX_SPLITS", "SPLIT_STARTS"]

#: A padded root sits this many times further from the origin than the linear model's fastest root.
PAD_FACTOR = 3.0
#: Most pole-zero splits scored.
MAX_SPLITS = 256
#: Best-scoring splits handed to the refinement.
SPLIT_STARTS = 3


class WienerHammersteinCost(OutputErrorCost):
    """``J(beta) = sum (y - y_hat(beta))^2`` of a Wiener-Hammerstein structure on one SISO record.

    Never raises for a hostile candidate: one that cannot be simulated scores
    ``inf`` (its residuals :data:`NONFINITE_RESIDUAL`).  A structure without a
    time unit takes the record's sample time.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> from hammerstein_ctrl.blocks import wiener_hammerstein_structure
    >>> s = wiener_hammerstein_structure((0, 1), None, (0, 1), time_unit=1.0); truth = [0.5, 0.2, 1.0, 0.1, -0.3]
    >>> t = np.arange(2000) * 0.01; u = np.sin(0.7 * t) + np.sin(2.3 * t)
    >>> data = hc.IOData(u, s.model(truth).simulate(t, u), dt=0.01)
    >>> float(WienerHammersteinCost(data, s)(truth))
    0.0
    """

    what = "a Wiener-Hammerstein structure"

    def __init__(self, data, structure: WienerHammersteinStructure, *, reject_unstable: bool = False):
        if not isinstance(structure, WienerHammersteinStructure):
            raise ParameterError(f"structure must be a WienerHammersteinStructure, got {type(structure).__name__}")
        super().__init__(data, structure.for_record(float(data.dt)), reject_unstable=reject_unstable)

    def simulate_batch(self, betas) -> np.ndarray:
        """Simulated outputs ``(B, N)``."""
        s = self.structure
        return simulate_wh(s.nonlinearity, s.parts(self._rows(betas)), self._u, self._dt, self._hold, s.substeps,
                           s.delay)


def bla_structure(structure: WienerHammersteinStructure) -> HammersteinStructure:
    """The linear model whose fit starts a Wiener-Hammerstein one: all the poles and zeros of ``G1 G2``,
    with an output offset (the map's mean level passes to the output).

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import wiener_hammerstein_structure
    >>> bla_structure(wiener_hammerstein_structure((0, 3), None, (2, 3))).linear.describe()
    '(p^2 + b1 p + b0)/(p^6 + a5 p^5 + a4 p^4 + a3 p^3 + a2 p^2 + a1 p + a0)'
    """
    f, s = structure.first, structure.second
    return HammersteinStructure(LinearStructure(f.num_order + s.num_order, f.den_order + s.den_order), Polynomial(1),
                                offset=True)


def _groups(roots: np.ndarray) -> list[np.ndarray]:
    """Roots grouped into real ones and conjugate pairs (upper member first), slowest first."""
    roots = np.asarray(roots, dtype=complex)
    real = [np.array([r.real]) for r in roots if abs(r.imag) <= 1e-9 * max(1.0, abs(r))]
    pairs = [np.array([r, np.conj(r)]) for r in roots if r.imag > 1e-9 * max(1.0, abs(r))]
    return sorted(real + pairs, key=lambda g: (abs(g[0]), len(g)))


def _assignments(groups: list, first: int, second: int):
    """Ways to give each group to block 0, block 1, or neither (2) with at most ``first`` and ``second`` roots,
    fewest groups left out first."""
    masks = sorted(itertools.product((0, 1, 2), repeat=len(groups)), key=lambda m: (m.count(2), m))
    for mask in masks:
        sizes = [sum(len(g) for g, m in zip(groups, mask) if m == k) for k in (0, 1)]
        if sizes[0] <= first and sizes[1] <= second:
            yield [np.concatenate([g for g, m in zip(groups, mask) if m == k] or [np.empty(0)]) for k in (0, 1)]


def _padded(roots: np.ndarray, order: int, pad: float) -> np.ndarray:
    """Monic real polynomial (descending) with ``roots`` and fast real roots at ``-pad`` up to ``order``."""
    full = np.concatenate([roots, np.full(order - roots.size, -pad)])
    return np.real(np.poly(full)) if order else np.ones(1)


def splits(structure: WienerHammersteinStructure, num, den) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(G1 parameters, G2 parameters)`` of each split of ``num/den``'s roots between the blocks.

    Roots are assigned whole (conjugate pairs together), to one block or, when
    the orders leave no room for them, to neither (splits that leave out fewest
    come first); a block given fewer than its order is padded (module
    docstring).  At most :data:`MAX_SPLITS`.

    Examples
    --------
    >>> from hammerstein_ctrl.blocks import wiener_hammerstein_structure
    >>> s = wiener_hammerstein_structure((0, 1), None, (0, 1), time_unit=1.0)
    >>> [(a.tolist(), b.tolist()) for a, b in splits(s, [1.0], [1.0, 3.0, 2.0])[:2]]   # poles -1, -2
    [([1.0], [0.5]), ([0.5], [1.0])]
    """
    num, den = np.trim_zeros(np.ravel(num), "f"), np.ravel(den)
    poles, zeros = np.roots(den), np.roots(num)
    fastest = max([1.0] + [abs(r) for r in np.concatenate([poles, zeros])])
    pad = PAD_FACTOR * fastest
    f, s = structure.first, structure.second
    out = []
    for p1, p2 in _assignments(_groups(poles), f.den_order, s.den_order):
        for z1, z2 in _assignments(_groups(zeros), f.num_order, s.num_order):
            thetas = []
            for lin, z, p in ((f, z1, p1), (s, z2, p2)):
                theta = lin.free_parameters(_padded(z, lin.num_order, pad), _padded(p, lin.den_order, pad))
                thetas.append(theta)
            if all(np.all(np.isfinite(t)) for t in thetas):
                out.append(tuple(thetas))
            if len(out) >= MAX_SPLITS:
                return out
    return out


def _map_columns(nl, x):
    """``[(parameters with the fitted coefficient slots, signals (k, N))]`` of the map's candidate regressions:
    its basis (families linear in their parameters), or each shape of its scan with the scale fitted."""
    basis = nl.basis(x)
    if basis is not None:
        return [(None, np.atleast_2d(basis))]
    grid = nl.shape_grid(x) if nl.scale_index is not None else None
    if grid is None:
        return []
    with np.errstate(all="ignore"):
        return [(p, nl(x, p)[None, :]) for p in np.atleast_2d(grid)]


def _time_scale(den) -> float:
    """``w0 = |A(0)|^(1/n)`` of a monic denominator row: the block's frequency scale, which keeps the columns of
    :func:`_through_second` of one size."""
    n = den.size - 1
    w0 = abs(den[-1]) ** (1.0 / n) if n else 1.0
    return w0 if np.isfinite(w0) and w0 > 0 else 1.0


def _through_second(structure, theta2, V, dt):
    """``(columns (N, k m), m, w0)``: each signal of ``V`` (k, N) through ``A2(0) (p/w0)^j / A2(p)`` for ``j < m``
    (``m`` the numerator's powers: ``G2``'s zeros are fitted with the map; ``w0`` :func:`_time_scale`), or through
    ``G2`` itself (``m = 1``)."""
    lin = structure.second
    if lin.num_order == 0:
        return _simulate_second(structure, theta2, V, dt), 1, 1.0
    _, den2 = lin.monic(theta2)
    k, m = V.shape[0], lin.num_order + 1
    w0 = _time_scale(den2[0])
    powers = np.diag(den2[0, -1] * w0 ** -np.arange(m - 1, -1, -1.0))   # rows (p/w0)^(m-1) ... 1, descending
    cols = simulate_batch(np.tile(powers, (k, 1)), np.repeat(den2, k * m, 0), np.repeat(V, m, 0), dt)
    return cols.T, m, w0


def _rank_one(structure, theta2, w, m, k, w0):
    """``(G2's parameters, map coefficients)`` from the coefficients ``w`` of the columns of
    :func:`_through_second`: the nearest product ``B(p) c`` (a rank-one factor), ``B`` monic, ``G2`` at unit gain."""
    lin = structure.second
    if m == 1:
        return theta2, w
    W = w.reshape(k, m)                                             # rows: map coefficients; columns: powers
    U, S, Vt = np.linalg.svd(W, full_matrices=False)
    b, c = Vt[0] * w0 ** -np.arange(m - 1, -1, -1.0), U[:, 0] * S[0]
    if b[0] == 0 or b[-1] == 0:
        return None
    c, b = c * b[0], b / b[0]
    _, den2 = lin.monic(theta2)
    return lin.free_parameters(b, den2[0]), c * b[-1]


def _least_squares(cols, y):
    """``(coefficients, sse)`` of ``y`` on the columns ``cols`` (N, k) and a constant (the last coefficient), the
    columns brought to one size first (none lost to the solver's rank cut-off); ``None`` if not finite."""
    A = np.column_stack([cols, np.ones(y.size)])
    if not np.all(np.isfinite(A)):
        return None
    size = np.sqrt(np.mean(A * A, axis=0))
    size[size == 0] = 1.0
    w, *_ = np.linalg.lstsq(A / size, y, rcond=None)
    w /= size
    r = y - A @ w
    return w, float(r @ r)


def _fit_map(structure, theta2, V, y, dt):
    """``(sse, G2's parameters, map coefficients, offset)`` for the map's regressors ``V`` (k, N): ``G2``'s zeros
    from the rank-one factor of the joint fit (:func:`_through_second`), then the coefficients refitted through
    that ``G2``; ``None`` when a fit fails."""
    with np.errstate(all="ignore"):
        cols, m, w0 = _through_second(structure, theta2, V, dt)
        if m > 1:
            joint = _least_squares(cols, y)
            factored = None if joint is None else _rank_one(structure, theta2, joint[0][:-1], m, V.shape[0], w0)
            if factored is None or not np.all(np.isfinite(factored[0])):
                return None
            theta2 = factored[0]
            cols = _simulate_second(structure, theta2, V, dt)
        fitted = _least_squares(cols, y)
    if fitted is None:
        return None
    w, sse = fitted
    return sse, theta2, w[:-1], float(w[-1])


def _simulate_second(structure, theta2, V, dt):
    """Each signal of ``V`` (k, N) through ``G2`` at ``theta2``, as columns (N, k)."""
    num2, den2 = structure.second.monic(theta2)
    k = V.shape[0]
    return simulate_batch(np.repeat(num2, k, 0), np.repeat(den2, k, 0), V, dt).T


def _fit_split(structure, theta1, theta2, u, y, dt, hold):
    """``(sse, G2's parameters, map parameters, offset)`` of the map (and ``G2``'s zeros) fitted by least squares
    with the poles and ``G1`` fixed, or None."""
    nl = structure.nonlinearity
    num1, den1 = structure.first.monic(theta1)
    with np.errstate(all="ignore"):
        x = simulate_batch(num1, den1, u, dt, intersample=hold)[0]
    if not np.all(np.isfinite(x)):
        return None
    best = None
    for p, V in _map_columns(nl, x):
        fitted = _fit_map(structure, theta2, np.ascontiguousarray(V), y, dt)
        if fitted is None or (best is not None and fitted[0] >= best[0]):
            continue
        sse, theta, coefficients, offset = fitted
        params = coefficients.copy() if p is None else np.array(p, dtype=float)
        if p is not None:
            params[nl.scale_index] = coefficients[0]
        best = (sse, theta, params, offset)
    return best


def start_record(cost: WienerHammersteinCost):
    """The record the starts are computed on: the fit's own, its input delayed by the structure's dead time (its
    sampled curve read at ``t - delay``, zero before the record), so that the starts need no delay of their own.

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> s = hc.WienerHammersteinStructure((0, 1), hc.Tanh(), (0, 1), delay=0.2, time_unit=1.0)
    >>> data = hc.IOData(np.arange(5.0), np.zeros(5), dt=0.1)
    >>> start_record(WienerHammersteinCost(data, s)).u.tolist()
    [0.0, 0.0, 0.0, 1.0, 2.0]
    """
    data, delay = cost.data, cost.structure.delay
    if not delay:
        return data
    t = np.arange(len(data)) * data.dt
    u = np.asarray(data.u, dtype=float).reshape(-1)
    whole = round(delay / data.dt)
    if abs(delay / data.dt - whole) <= 1e-9:          # whole samples: the samples themselves, shifted
        return type(data)(np.r_[np.zeros(min(whole, u.size)), u[:max(u.size - whole, 0)]], data.y, dt=data.dt,
                          intersample=data.intersample, name=data.name)
    if data.intersample == "zoh":
        k = np.floor((t - delay) / data.dt + 1e-9).astype(int)
        shifted = np.where(k >= 0, u[np.clip(k, 0, u.size - 1)], 0.0)
    else:
        shifted = np.interp(t - delay, t, u, left=0.0)
    return type(data)(shifted, data.y, dt=data.dt, intersample=data.intersample, name=data.name)


def split_starts(cost: WienerHammersteinCost, bla_x, count: int = SPLIT_STARTS, record=None
                 ) -> tuple[list[np.ndarray], int]:
    """``(starts, splits scored)``: full beta starts from the best ``count`` splits of a linear fit ``bla_x`` (of
    :func:`bla_structure`).

    Each split's map is fitted by least squares through ``G2`` (with an offset
    column); the splits are ranked by that fit's J.  Empty when the map has no
    automatic start (a custom map without :meth:`~hammerstein_ctrl.blocks.Nonlinearity.basis`
    or scale parameter).  ``record`` is :func:`start_record`'s (computed when not given).
    """
    s = cost.structure
    lin = bla_structure(s).linear
    num, den = lin.coefficients(np.asarray(bla_x, dtype=float)[:lin.n_params])
    u, y = np.asarray((start_record(cost) if record is None else record).u, dtype=float), cost._y
    scored, candidates = [], splits(s, num[0], den[0])
    for theta1, theta2 in candidates:
        fitted = _fit_split(s, theta1, theta2, u, y, cost._dt, cost._hold)
        if fitted is not None and np.isfinite(fitted[0]):
            scored.append((fitted[0], theta1) + fitted[1:])
    scored.sort(key=lambda row: row[0])
    unique = []
    for row in scored:                     # a dropped root and a padded one can give the same split twice
        if not any(np.array_equal(row[1], u[1]) and np.array_equal(row[2], u[2]) for u in unique):
            unique.append(row)
    starts = []
    for _, theta1, theta2, params, y0 in unique[:count]:
        rest = ([y0] if s.offset else []) + [0.0] * (
            (s.first.den_order + s.second.den_order) if s.initial_state == "estimate" else 0)
        starts.append(np.concatenate([theta1, theta2, params, rest]))
    return starts, len(candidates)
