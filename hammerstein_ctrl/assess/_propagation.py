"""What the parameters' covariance says about what users look at: any function of the parameters (delta method or
samples), the poles, zeros, gains and time constants of the linear blocks, with their standard errors."""

from __future__ import annotations

from typing import Callable
import numpy as np
from ..exceptions import ParameterError
from ._uncertainty import NoiseModel, ParameterUncertainty, Propagated, _assembled, _check_level, t_factor

__all__ = ["UncertainParameters", "CharacteristicsTable", "white_covariance", "propagate", "root_gradients",
           "linear_roots", "linear_roots_by_block", "linear_characteristics"]


# -- propagation -----------------------------------------------------------------
def _derivative_steps(x: np.ndarray, se: np.ndarray) -> np.ndarray:
    """Steps for the derivative of a propagated quantity: a thousandth of each standard error (or a relative step)."""
    return np.where(np.isfinite(se) & (se > 0), 1e-3 * se, 1e-6 * np.maximum(1.0, np.abs(x)))


def propagate(fun: Callable, x, covariance, *, level: float | None = None, dof: int | None = None,
              method: str = "linear", samples: int = 2000, seed=None) -> Propagated:
    """The standard error and confidence interval of ``fun(x)`` under the parameters' covariance.

    Parameters
    ----------
    fun : callable
        ``fun(beta) -> array_like`` of real numbers.
    x : array_like, shape (p,)
    covariance : array_like, shape (p, p)
    level : float, default 0.95
    dof : int, optional
        Degrees of freedom of the Student-t factor (``linear``); normal if omitted.
    method : {"linear", "sampling"}
        ``"linear"``: first-order propagation ``D cov D^T``, ``D`` the central
        difference of ``fun`` over a thousandth of each standard error;
        ``"sampling"``: ``samples`` draws from the normal distribution of the
        parameters (seeded), the interval from their quantiles.
    samples : int
    seed : int or numpy.random.Generator, optional

    Examples
    --------
    >>> import numpy as np
    >>> p = propagate(lambda b: [b[0] * b[1]], [2.0, 3.0], np.diag([0.01, 0.04]))
    >>> np.round(p.stderr, 4)          # sqrt(3^2 0.01 + 2^2 0.04)
    array([0.5])
    """
    level = _check_level(level)
    x = np.asarray(x, dtype=float)
    cov = np.asarray(covariance, dtype=float)
    value = np.atleast_1d(np.asarray(fun(x), dtype=float))
    se = np.sqrt(np.abs(np.diag(cov)))
    if str(method) == "sampling":
        return _sampled(fun, x, cov, value, level, samples, seed)
    if str(method) != "linear":
        raise ParameterError(f"method must be 'linear' or 'sampling', got {method!r}")
    h = _derivative_steps(x, se)
    D = np.empty((value.size, x.size))
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h[j]
        D[:, j] = (np.atleast_1d(np.asarray(fun(x + e), dtype=float))
                   - np.atleast_1d(np.asarray(fun(x - e), dtype=float))) / (2 * h[j])
    moving = np.abs(D) > 0
    cov0 = np.where(np.isfinite(cov), cov, 0.0)
    with np.errstate(all="ignore"):
        var = np.einsum("ij,jk,ik->i", D, cov0, D)
    undetermined = (moving & ~np.isfinite(np.diag(cov))[None, :]).any(axis=1)
    stderr = np.where(undetermined, np.inf, np.sqrt(np.clip(var, 0.0, None)))
    k = t_factor(level, dof) if dof is not None else t_factor(level, 10**9)
    return Propagated(value, stderr, value - k * stderr, value + k * stderr)


def _sampled(fun, x, cov, value, level, samples, seed) -> Propagated:
    if not np.all(np.isfinite(np.diag(cov))):
        raise ParameterError("cannot sample parameters the record does not determine (infinite standard errors)")
    from ..optimize import as_rng

    rng = as_rng(seed)
    draws = rng.multivariate_normal(x, cov, size=int(samples), method="eigh")
    values = np.array([np.atleast_1d(np.asarray(fun(b), dtype=float)) for b in draws])
    with np.errstate(all="ignore"):
        low, high = np.nanquantile(values, [0.5 - level / 2, 0.5 + level / 2], axis=0)
        stderr = np.nanstd(values, axis=0)
    return Propagated(value, stderr, low, high)


def root_gradients(coefficients, positions) -> tuple[np.ndarray, np.ndarray]:
    """The roots of a polynomial and their first-order sensitivity to some of its coefficients.

    Parameters
    ----------
    coefficients : array_like
        Descending powers (as :func:`numpy.roots`).
    positions : array_like of int
        Indices into ``coefficients`` of the free parameters.

    Returns
    -------
    roots : ndarray, shape (m,), complex
    gradients : ndarray, shape (m, len(positions)), complex
        ``d root / d coefficients[positions[j]]`` (``-root^k / P'(root)``, ``k``
        the power of that coefficient); ``inf`` at a repeated root.

    Examples
    --------
    >>> r, g = root_gradients([1.0, 3.0, 2.0], [1, 2])      # p^2 + 3p + 2 = (p + 1)(p + 2)
    >>> np.round(r.real, 6).tolist(), np.round(g.real, 6).tolist()
    ([-2.0, -1.0], [[-2.0, 1.0], [1.0, -1.0]])
    """
    c = np.asarray(coefficients, dtype=float)
    positions = np.asarray(positions, dtype=int)
    roots = np.roots(c) if c.size > 1 else np.zeros(0, dtype=complex)
    roots = np.sort_complex(roots.astype(complex))
    powers = c.size - 1 - positions
    slope = np.polyval(np.polyder(c), roots) if c.size > 1 else np.zeros(0)
    with np.errstate(all="ignore"):
        grads = -(roots[:, None] ** powers[None, :]) / slope[:, None]
    grads[~np.isfinite(grads)] = np.inf
    return roots, grads


def white_covariance(gram, sse: float, n_samples: int) -> ParameterUncertainty:
    """The plain Gauss-Newton covariance ``s^2 G^-1`` (``s^2 = sse / (N - p)``), from the Gram matrix alone.

    Examples
    --------
    >>> import numpy as np
    >>> u = white_covariance(np.diag([4.0, 1.0]), sse=10.0, n_samples=12)
    >>> u.stderr.tolist()
    [0.5, 1.0]
    """
    G = np.asarray(gram, dtype=float)
    dof = max(int(n_samples) - G.shape[0], 1)
    return _assembled(G, None, NoiseModel(0, np.ones(1), float(sse) / dof), int(n_samples))


class UncertainParameters:
    """Standard errors and confidence intervals of a result with ``x``, ``structure``, ``covariance`` and ``dof``."""

    @property
    def stderr(self) -> dict:
        """Standard error of each parameter by name (``inf`` where the record does not determine it)."""
        self._need_covariance()
        return dict(zip(self.structure.param_names, np.sqrt(np.abs(np.diag(self.covariance))).tolist()))

    def conf_int(self, level: float | None = None) -> dict:
        """Confidence interval of each parameter: ``{name: (low, high)}`` (Student-t with ``N - p`` degrees of freedom).

        Examples
        --------
        >>> import numpy as np, hammerstein_ctrl as hc
        >>> case = hc.presets.trs()
        >>> res = hc.identify(case.data, case.structure)
        >>> np.round(res.conf_int()["a1"], 2)          # the optimum's a1 = 4.01 with t = 1.96 standard errors
        array([3.26, 4.77])
        """
        self._need_covariance()
        k = t_factor(level, self.dof) * np.sqrt(np.abs(np.diag(self.covariance)))
        x = np.asarray(self.x, dtype=float)
        return {n: (float(v - d), float(v + d)) for n, v, d in zip(self.structure.param_names, x, k)}

    def _need_covariance(self):
        if getattr(self, "covariance", None) is None:
            raise ParameterError("this result carries no covariance (computed by identify unless uncertainty=False; "
                                 "a result saved without one has none)")


class CharacteristicsTable(list):
    """Rows ``(quantity, value, stderr, low, high)`` of :func:`linear_characteristics`."""

    def to_frame(self):
        """As a pandas DataFrame indexed by quantity."""
        from ..data._display import require_pandas

        pd = require_pandas()
        return pd.DataFrame([r[1:] for r in self], index=pd.Index([r[0] for r in self], name="quantity"),
                            columns=["value", "stderr", "low", "high"])

    def __str__(self):
        width = max((len(r[0]) for r in self), default=8)
        return "\n".join(f"{q:<{width}}  {v: .6g} ± {s:.3g}  [{lo:.6g}, {hi:.6g}]" for q, v, s, lo, hi in self)

    def _repr_pretty_(self, printer, cycle):
        printer.text(str(self))

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{h}</th>" for h in ("quantity", "value", "std. error", "low", "high"))
        body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in (r[0], *(f"{v:.6g}" for v in r[1:]))) + "</tr>"
                       for r in self)
        return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _row(name, value, gradient, cov, k):
    g = np.asarray(gradient, dtype=float)
    moving = np.abs(g) > 0
    if (moving & ~np.isfinite(np.diag(cov))).any() or not np.all(np.isfinite(g)):
        se = np.inf
    else:
        c = np.where(np.isfinite(cov), cov, 0.0)
        se = float(np.sqrt(max(g @ c @ g, 0.0)))
    return (name, float(value), se, float(value) - k * se, float(value) + k * se)


def linear_characteristics(structure, x, covariance, *, level: float | None = None, dof: int = 10**9
                           ) -> CharacteristicsTable:
    """Poles, zeros, time constants, natural frequencies, damping and DC gain of a structure's ``H``, with uncertainty.

    First-order propagation through the exact root sensitivities
    (:func:`root_gradients`): a real pole ``p`` gives ``p`` and its time
    constant ``-1/p``; a complex pair gives its real and imaginary parts, the
    natural frequency ``|p|`` and the damping ratio ``-Re p / |p|``.

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import LinearStructure, HammersteinStructure, Tanh
    >>> s = HammersteinStructure(LinearStructure(0, 1), Tanh())
    >>> t = linear_characteristics(s, np.array([2.0, 1.0, 1.0]), np.diag([0.01, 0.0, 0.0]))
    >>> [(q, round(v, 4), round(e, 4)) for q, v, e, _, _ in t]
    [('pole 1', -2.0, 0.1), ('time constant 1', 0.5, 0.025), ('DC gain of H', 0.5, 0.025)]
    """
    x = np.asarray(x, dtype=float)
    cov = np.asarray(covariance, dtype=float)
    k = t_factor(level, dof)
    rows = CharacteristicsTable()
    roots = linear_roots(structure, x)
    for kind in ("pole", "zero"):
        _root_rows(rows, kind, [r[1] for r in roots if r[0] == kind], [r[2] for r in roots if r[0] == kind], cov, k)
    if hasattr(structure, "block_layout"):      # blocks of static gain 1 by construction: no DC gain to report
        return rows
    num, den = structure.linear.coefficients(x[:structure.linear.n_params])
    _, _, num_pos, den_pos = structure.linear.coefficient_template()
    rows.append(_dc_gain_row(num[0], den[0], num_pos, den_pos, x.size, cov, k))
    return rows


def row_characteristics(structure, x, covariance, *, level: float | None = None, dof: int = 10**9,
                        names=None) -> CharacteristicsTable:
    """:func:`linear_characteristics` of a MIMO structure: each output row's poles, then each element's DC gain.

    The poles come from the exact root sensitivities of the row's
    denominator; a DC gain ``B_ij(0)/F_i(0)`` from a forward-difference
    gradient (it is smooth in beta).  Quantities are named after their output
    (``pole 1 [pitch]``) or element (``DC gain [yaw <- v_main]``), with the
    channel names ``names = (inputs, outputs)`` (default ``u[j]``, ``y[i]``).

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Tanh, MIMOHammersteinStructure
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Tanh(), Tanh()], n_outputs=2)
    >>> x = np.array([2.0, 0.5, 0.7, 3.0, 1.0, 1.0, 2.0, 0.5])
    >>> t = row_characteristics(s, x, np.diag(np.full(8, 1e-4)))
    >>> [(q, round(v, 4), round(e, 4)) for q, v, e, _, _ in t][:3]
    [('pole 1 [y[0]]', -2.0, 0.01), ('time constant 1 [y[0]]', 0.5, 0.0025), ('pole 1 [y[1]]', -3.0, 0.01)]
    """
    inputs, outputs = names if names is not None else (
        [f"u[{j}]" for j in range(structure.n_inputs)], [f"y[{i}]" for i in range(structure.n_outputs)])
    x = np.asarray(x, dtype=float)
    cov = np.asarray(covariance, dtype=float)
    k = t_factor(level, dof)
    rows = CharacteristicsTable()
    num, den = structure.coefficients(x)
    for i in range(structure.n_outputs):
        pos, idx = structure.row_denominator(i)
        roots, grads = root_gradients(den[0, i], pos)
        full = np.zeros((roots.size, x.size), dtype=complex)
        full[:, idx] = grads
        part = CharacteristicsTable()
        _root_rows(part, "pole", roots, list(full), cov, k)
        rows += [(f"{q} [{outputs[i]}]", *rest) for q, *rest in part]

    def gains(b):
        n, d = structure.coefficients(b)
        return (n[0, :, :, -1] / d[0, :, -1:]).ravel()

    from ..optimize._normal_equations import forward_steps

    h = forward_steps(x)
    g0 = gains(x)
    G = np.column_stack([(gains(x + h[j] * np.eye(x.size)[j]) - g0) / h[j] for j in range(x.size)])
    for e, (value, grad) in enumerate(zip(g0, G)):
        i, j = divmod(e, structure.n_inputs)
        rows.append(_row(f"DC gain [{outputs[i]} <- {inputs[j]}]", value, grad, cov, k))
    return rows


def linear_roots(structure, x) -> list[tuple[str, complex, np.ndarray]]:
    """``(kind, root, gradient)`` for each pole and zero of a structure's ``H``: the gradient (complex) is
    with respect to the whole beta (:func:`root_gradients` on the free coefficients).

    Examples
    --------
    >>> import numpy as np
    >>> from hammerstein_ctrl import LinearStructure, HammersteinStructure, Tanh
    >>> s = HammersteinStructure(LinearStructure(1, 2), Tanh())        # (p + b0)/(p^2 + a1 p + a0)
    >>> [(k, complex(np.round(r, 6)), np.round(g.real, 6).tolist())
    ...  for k, r, g in linear_roots(s, [3.0, 2.0, 3.0, 1.0, 1.0])]  # doctest: +NORMALIZE_WHITESPACE
    [('pole', (-2+0j), [0.0, 1.0, -2.0, 0.0, 0.0]), ('pole', (-1+0j), [0.0, -1.0, 1.0, 0.0, 0.0]),
     ('zero', (-3+0j), [-1.0, 0.0, 0.0, 0.0, 0.0])]
    """
    return [row[:3] for row in linear_roots_by_block(structure, x)]


def linear_roots_by_block(structure, x) -> list[tuple[str, complex, np.ndarray, int]]:
    """:func:`linear_roots` with the index of the linear block each root belongs to (0 but for a Wiener-Hammerstein
    structure's second block).  A block whose coefficients are its parameters times a scale
    (:meth:`~hammerstein_ctrl.blocks.UnitGainBlock.parameter_scales`) has its gradients scaled back
    to the parameters."""
    x = np.asarray(x, dtype=float)
    out = []
    layout = structure.block_layout if hasattr(structure, "block_layout") else ((structure.linear, 0),)
    for block, (linear, at) in enumerate(layout):
        num, den = linear.coefficients(x[at:at + linear.n_params])
        _, _, num_pos, den_pos = linear.coefficient_template()
        scales = linear.parameter_scales() if hasattr(linear, "parameter_scales") else np.ones(linear.n_params)
        for kind, coeffs, pos, idx in (("pole", den[0], den_pos, num_pos.size + np.arange(den_pos.size)),
                                       ("zero", num[0], num_pos, np.arange(num_pos.size))):
            lead = int(np.flatnonzero(coeffs)[0]) if np.any(coeffs) else coeffs.size
            keep = pos >= lead
            roots, grads = root_gradients(coeffs[lead:], pos[keep] - lead)
            for root, g in zip(roots, grads):
                full = np.zeros(x.size, dtype=complex)
                full[at + idx[keep]] = g * scales[idx[keep]]
                out.append((kind, complex(root), full, block))
    return out


def _root_rows(rows, kind, roots, grads, cov, k):
    n = 0
    for root, g in zip(roots, grads):
        if root.imag < -1e-12 * max(1.0, abs(root)):
            continue                                 # a complex pair is described once, by its upper root
        n += 1
        if abs(root.imag) <= 1e-12 * max(1.0, abs(root)):
            rows.append(_row(f"{kind} {n}", root.real, g.real, cov, k))
            if kind == "pole" and root.real < 0:
                rows.append(_row(f"time constant {n}", -1.0 / root.real, g.real / root.real ** 2, cov, k))
            continue
        mod = abs(root)
        d_mod = (root.real * g.real + root.imag * g.imag) / mod
        rows.append(_row(f"{kind} {n} real part", root.real, g.real, cov, k))
        rows.append(_row(f"{kind} {n} imaginary part", root.imag, g.imag, cov, k))
        rows.append(_row(f"{kind} {n} natural frequency", mod, d_mod, cov, k))
        rows.append(_row(f"{kind} {n} damping ratio", -root.real / mod,
                         -(g.real * mod - root.real * d_mod) / mod ** 2, cov, k))


def _dc_gain_row(num, den, num_pos, den_pos, p, cov, k):
    """``H(0) = b0 / a0`` (infinite for a pole at the origin)."""
    b0, a0 = float(num[-1]), float(den[-1])
    if a0 == 0:
        return ("DC gain of H", np.inf, np.inf, np.inf, np.inf)
    g = np.zeros(p)
    last_num, last_den = num.size - 1, den.size - 1
    for j, pos in enumerate(num_pos):
        if pos == last_num:
            g[j] = 1.0 / a0
    for j, pos in enumerate(den_pos):
        if pos == last_den:
            g[num_pos.size + j] = -b0 / a0 ** 2
    return _row("DC gain of H", b0 / a0, g, cov, k)
