"""Verdicts on an identified model: what the record determines, whether the linear block is plausible, what to do.

A :class:`Verdict` is one finding with a severity: a ``"failure"`` makes
the identification unusable as it stands (``success = False``), a
``"warning"`` leaves it usable but says what to look at.  Each message names
the parameters or poles concerned, says why, and says what to do.

* :func:`identifiability_verdicts`: parameters the record does not determine
  (a Jacobian column that is zero, or explained by the others to within
  1/:data:`UNDETERMINED_VIF`: infinite standard error) are failures, with the
  static block's own explanation where it has one
  (:meth:`~hammerstein_ctrl.blocks.Nonlinearity.unexcited`) and a
  verdict of its own for the offset / initial-state trade-off;
  parameters whose standard error exceeds their value are warnings.
* :func:`linear_verdicts`: a pole on the wrong side of the imaginary axis but
  within its uncertainty of it is marginal (an integrator, accepted with a
  warning); further right it is unstable (a failure unless allowed); poles far
  beyond the record's bandwidth and poles cancelled by a zero within their
  uncertainty say that the order is too high.
* :func:`offset_verdict`: residuals with a mean the model cannot produce.
* :func:`budget_advice`: what to do when a least-squares method ran out of
  evaluations, given the other verdicts (raising ``maxfev`` only helps when
  nothing else explains the slow progress).

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl import LinearStructure, HammersteinStructure, Tanh
>>> s = HammersteinStructure(LinearStructure(0, 1), Tanh())
>>> gram = np.array([[4.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, 1.0, 1.0]])   # d0 and d1 collinear
>>> from hammerstein_ctrl.assess import parameter_covariance
>>> unc = parameter_covariance(None, np.ones(100), noise="white", gram=gram)
>>> [v.code for v in identifiability_verdicts(s, np.array([1.0, 2.0, 0.5]), unc)]
['undetermined']
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..blocks._nonlinearities import constant_level
from ._uncertainty import ParameterUncertainty, scaled_eigen, t_factor
from ._propagation import linear_roots_by_block

__all__ = ["Verdict", "identifiability_verdicts", "linear_verdicts", "row_pole_verdicts", "offset_verdict",
           "budget_advice", "late_improvement", "STILL_IMPROVING", "LATE_SHARE",
           "variance_inflation", "FAILURE", "WARNING", "UNDETERMINED_VIF", "FAST_POLE_FACTOR",
           "OFFSET_T", "OFFSET_SHARE", "VERDICT_LEVEL", "TRADE_OFF_CORRELATION"]

FAILURE, WARNING = "failure", "warning"
#: A parameter whose Jacobian column the others reproduce to within 1/this (its variance inflation
#: factor) is not determined by the record.
UNDETERMINED_VIF = 1e10
#: Poles faster than this many times the Nyquist frequency ``pi/dt`` are beyond the record's bandwidth.
FAST_POLE_FACTOR = 1.0
#: Residual mean (in its standard errors) and share of the residuals' mean square past which the output
#: has an offset the model does not reproduce.
OFFSET_T, OFFSET_SHARE = 5.0, 0.01
#: Confidence level of the verdicts that compare a value with its uncertainty (marginal poles, cancellations).
VERDICT_LEVEL = 0.99


@dataclass(frozen=True)
class Verdict:
    """One finding about an identified model.

    Attributes
    ----------
    code : str
        ``"undetermined"``, ``"offset-state"``, ``"poorly-determined"``,
        ``"marginal-pole"``, ``"unstable"``, ``"fast-pole"``,
        ``"cancellation"``, ``"offset-missing"``, ``"inadequate"``, ...
    severity : {"failure", "warning"}
    message : str
    params : tuple of str
        The parameters concerned (may be empty).
    """

    code: str
    severity: str
    message: str
    params: tuple = ()

    def __str__(self):
        return self.message


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def variance_inflation(gram) -> np.ndarray:
    """Variance inflation factors of the Jacobian's columns: ``inf`` for a zero column or an exactly collinear one.

    The factor of column ``j`` is ``1 / (1 - R_j^2)``, ``R_j^2`` the share of
    the column that the other columns reproduce: 1 for a column orthogonal to
    the others.

    Examples
    --------
    >>> import numpy as np
    >>> variance_inflation(np.array([[1.0, 0.0], [0.0, 4.0]])).tolist()
    [1.0, 1.0]
    >>> variance_inflation(np.array([[1.0, 0.0], [0.0, 0.0]])).tolist()
    [1.0, inf]
    """
    eig = scaled_eigen(gram)
    if eig is None:
        return np.full(np.shape(gram)[0], np.inf)
    w, V, _, null = eig
    vif = np.einsum("ij,j,ij->i", V[:, ~null], 1.0 / w[~null], V[:, ~null])
    vif[(np.abs(V[:, null]) > 1e-6).any(axis=1)] = np.inf
    return vif


def _collinear_groups(gram, undetermined: np.ndarray, linked=()) -> list[list[int]]:
    """The undetermined parameters in groups that trade off against each other.

    Each near-null direction of the column-scaled Gram matrix links the
    parameters that load on it; directions sharing a parameter are merged,
    and so are the parameters of each list in ``linked`` (a static block
    that sees a constant signal).
    """
    eig = scaled_eigen(gram)
    if eig is None:
        return [[int(i) for i in np.flatnonzero(undetermined)]] if undetermined.any() else []
    w, V, _, _ = eig
    parent = list(range(np.shape(gram)[0]))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    directions = [[int(i) for i in np.flatnonzero((np.abs(V[:, k]) > 0.1) & undetermined)]
                  for k in np.flatnonzero(w <= max(w[-1], 0.0) / UNDETERMINED_VIF)]
    for members in directions + [list(group) for group in linked]:
        for i in members[1:]:
            parent[root(i)] = root(members[0])
    groups: dict = {}
    for i in np.flatnonzero(undetermined):
        groups.setdefault(root(int(i)), []).append(int(i))
    return list(groups.values())


def _static_blocks(structure, model, data) -> list:
    """``(nonlinearity, its parameters, its signal (a function, evaluated once), label, its beta names)`` of each
    static block."""
    if model is None or data is None:
        return []
    if hasattr(structure, "static_blocks"):
        return structure.static_blocks(model, data)
    blocks = []
    if structure.input_nonlinearity is not None:
        blocks.append((structure.input_nonlinearity, model.input_params,
                       functools.cache(lambda: np.asarray(data.u, dtype=float)), "input u"))
    if structure.output_nonlinearity is not None:
        blocks.append((structure.output_nonlinearity, model.output_params,
                       functools.cache(lambda: model.linear_output(data)), "output of H"))     # a simulation
    return [block + (names,) for block, names in zip(blocks, _block_names(structure))]


def _block_hints(blocks) -> dict:
    """Parameter name -> why the record does not excite it, from the static blocks' own knowledge."""
    hints = {}
    for nl, params, signal, label, block_names in blocks:
        with np.errstate(all="ignore"):
            reasons = nl.unexcited(params, signal())
        for i, why in reasons.items():
            if i < len(block_names) and block_names[i] is not None:
                hints[block_names[i]] = f"{why} ({label})"
    return hints


def _unseen(blocks) -> set:
    """The names of the parameters of the static blocks driven by a constant signal: one value of the map is
    seen, so none of them is determined, whatever the covariance at the fitted point says (it tells which
    combinations the point's curvature happens to fix, which on such a record depends on where the fit ended)."""
    names = set()
    for _, _, signal, _, block_names in blocks:
        with np.errstate(all="ignore"):
            if constant_level(signal()) is not None:
                names |= {n for n in block_names if n is not None}
    return names


def _block_names(structure) -> list[list]:
    """Per static block (input first), the beta name of each of its parameters (``None`` for a fixed gain)."""
    out, names, k = [], structure.param_names, structure.linear.n_params
    if structure.input_nonlinearity is not None:
        g = []
        for i in range(structure.input_nonlinearity.n_params):
            if i == structure._fixed_gain:
                g.append(None)
            else:
                g.append(names[k])
                k += 1
        out.append(g)
    if structure.output_nonlinearity is not None:
        out.append(list(names[k:k + structure.output_nonlinearity.n_params]))
    return out


def identifiability_verdicts(structure, x, unc: ParameterUncertainty, *, model=None, data=None,
                             exempt=()) -> list[Verdict]:
    """Parameters the record does not determine (failures) or determines poorly (one warning).

    Parameters
    ----------
    structure : BlockStructure
    x : ndarray
        The fitted beta.
    unc : ParameterUncertainty
    model, data : optional
        The fitted model and the estimation record, for the static blocks'
        explanations (:meth:`~hammerstein_ctrl.blocks.Nonlinearity.unexcited`).
    exempt : iterable of str
        Parameters another verdict already explains (e.g. the ``a0`` of a marginal pole).
    """
    names = structure.param_names
    vif = variance_inflation(unc.gram)
    se = unc.stderr
    blocks = _static_blocks(structure, model, data)
    unseen = _unseen(blocks)
    undetermined = ~np.isfinite(se) | (vif > UNDETERMINED_VIF) | np.array([n in unseen for n in names], dtype=bool)
    verdicts = []
    nuisance = {i for i in range(structure.n_core, len(names))} | {
        i for i, n in enumerate(names) if n in _state_partners(structure)}
    hints = _block_hints(blocks) if undetermined.any() else {}
    zero = ~(np.diag(unc.gram) > 0)
    linked = [[names.index(n) for n in block[4] if n in unseen] for block in blocks]
    for group in _collinear_groups(unc.gram, undetermined, linked):
        verdicts.append(_undetermined([names[i] for i in group], set(group) <= nuisance, hints,
                                      bool(zero[group].all())))
    poor = [i for i in np.flatnonzero(~undetermined)
            if i < structure.n_core and names[i] not in exempt and se[i] > abs(x[i])]
    if poor:
        verdicts.append(_poorly_determined(names, x, se, unc.correlation(), poor))
    return verdicts


#: Correlation past which two poorly determined parameters are said to trade off.
TRADE_OFF_CORRELATION = 0.99


def _poorly_determined(names, x, se, corr, poor) -> Verdict:
    """One warning for the parameters whose standard error exceeds their value, naming trade-offs."""
    if [names[i] for i in poor] == ["a0"]:
        i = poor[0]
        return Verdict(
            "poorly-determined", WARNING,
            f"a0 = {_fmt(x[i])} ± {se[i]:.2g} is not distinguishable from 0: H seems to have a pole at the origin "
            "(an integrator); fix a0 = 0 (LinearStructure(..., fixed={'a0': 0.0}), --fix a0=0) to make it exact",
            ("a0",))
    listed = ", ".join(f"{names[i]} = {_fmt(x[i])} ± {se[i]:.2g}" for i in poor)
    plural = len(poor) > 1
    them = "them" if plural else "it"
    pairs = []
    for i in poor:
        c = np.where(np.isfinite(corr[i]), np.abs(corr[i]), 0.0)
        c[i] = 0.0
        j = int(np.argmax(c))
        if c[j] > TRADE_OFF_CORRELATION and (j, i) not in pairs:
            pairs.append((i, j))
    trade = "; ".join(f"{names[i]} and {names[j]} trade off (correlation {corr[i, j]:+.4f}): the record "
                      "determines a combination of them, not each" for i, j in pairs)
    why = trade or f"the record hardly shows {them}"
    return Verdict(
        "poorly-determined", WARNING,
        f"{listed} {'are' if plural else 'is'} not distinguishable from 0 (standard error above the value): "
        f"{why}; fix {them}, or excite the system more (the output is reliable where it was fitted, less so "
        "beyond)", tuple(names[i] for i in poor))


def _linear_names(structure) -> tuple[str, ...]:
    """The beta names of the linear blocks' coefficients (both blocks of a Wiener-Hammerstein structure)."""
    if hasattr(structure, "block_layout"):
        return tuple(n for lin, at in structure.block_layout for n in structure.param_names[at:at + lin.n_params])
    return structure.linear.param_names


def _state_partners(structure) -> set:
    """Names of the linear blocks' constant-term coefficients, which trade off with an offset and x(0)."""
    return {n for n in _linear_names(structure) if n == "a0" or n.endswith("_a0")}


def _undetermined(group: list, nuisance_only: bool, hints: dict, zero: bool) -> Verdict:
    listed = ", ".join(group)
    if nuisance_only and any(n.startswith("xi") for n in group) and "y0" in group:
        return Verdict(
            "offset-state", FAILURE,
            f"the offset y0 and the initial state x(0) are not separately determined ({listed} trade off: with a "
            "pole at or near the origin a constant output can come from either); fix one of them: offset=False "
            "or initial_state='zero'", tuple(group))
    reasons: dict = {}
    for n in group:
        if n in hints:
            reasons.setdefault(hints[n], []).append(n)
    if len(reasons) == 1:
        why = next(iter(reasons))
    elif reasons:
        why = "; ".join(f"{', '.join(ns)}: {r}" for r, ns in reasons.items())
    elif zero:
        why = "the output does not depend on " + ("them" if len(group) > 1 else "it") + " on this record"
    else:
        why = ("their effects on the output cannot be told apart" if len(group) > 1 else
               "its effect on the output is matched by the other parameters'")
    one = len(group) == 1
    return Verdict(
        "undetermined", FAILURE,
        f"{listed} {'is' if one else 'are'} not determined by this record ({why}): {'its' if one else 'their'} "
        f"value is arbitrary, and so is the model's output wherever {'it matters' if one else 'they matter'}; "
        f"excite the system over the range the model must cover, or fix or remove {'it' if one else 'them'}",
        tuple(group))


# -- the linear block ---------------------------------------------------------------
def _component_se(gradient: np.ndarray, covariance: np.ndarray) -> tuple[float, float]:
    """Standard errors of the real and imaginary parts of a quantity with this complex gradient."""
    cov = np.where(np.isfinite(covariance), covariance, 0.0)
    moving = np.abs(gradient) > 0
    if (moving & ~np.isfinite(np.diag(covariance))).any() or not np.all(np.isfinite(gradient)):
        return np.inf, np.inf
    re, im = gradient.real, gradient.imag
    return float(np.sqrt(max(re @ cov @ re, 0.0))), float(np.sqrt(max(im @ cov @ im, 0.0)))


def linear_verdicts(structure, x, unc: ParameterUncertainty | None, dt: float, *,
                    allow_unstable: bool = False) -> tuple[list[Verdict], bool]:
    """Verdicts on the poles and zeros of ``H``, and whether the model counts as stable.

    A pole in the right half-plane within its uncertainty of the imaginary
    axis (at :data:`VERDICT_LEVEL`) is marginal: an integrator the noise put
    on the wrong side, accepted with a warning.
    """
    rows = [{"kind": k, "value": v, "gradient": g, "block": b} for k, v, g, b in linear_roots_by_block(structure, x)]
    cov = None if unc is None else unc.covariance
    k = t_factor(VERDICT_LEVEL, unc.dof if unc is not None else 10**9)
    verdicts, stable = [], True
    poles = [r for r in rows if r["kind"] == "pole"]
    zeros = [r for r in rows if r["kind"] == "zero"]
    for row in poles:
        v = row["value"]
        if v.real <= 1e-12 * max(1.0, abs(v)):
            continue
        se_re = _component_se(row["gradient"], cov)[0] if cov is not None else 0.0
        if v.real <= k * se_re:
            real = abs(v.imag) <= 1e-12 * max(1.0, abs(v))
            verdicts.append(Verdict(
                "marginal-pole", WARNING,
                f"the pole at {_complex(v)} is within its uncertainty (± {se_re:.2g}) of the imaginary axis: taken "
                f"as {'an integrator' if real else 'an undamped oscillation'}, "
                f"not as unstable; {_fix_hint(structure, v)}",
                ("a0",) if real and "a0" in _linear_names(structure) else ()))
            continue
        stable = False
        verdicts.append(Verdict(
            "unstable", WARNING if allow_unstable else FAILURE,
            f"the model is unstable: a pole at {_complex(v)} (± {se_re:.2g}) lies in the right half-plane"
            + ("" if allow_unstable else "; pass allow_unstable=True to accept it"), ()))
    nyquist = np.pi / dt
    for row in poles:
        v = row["value"]
        if abs(v) > FAST_POLE_FACTOR * nyquist:
            verdicts.append(Verdict(
                "fast-pole", WARNING,
                f"the pole at {_complex(v)} rad/s lies far beyond the record's bandwidth (Nyquist frequency "
                f"{nyquist:.4g} rad/s): the record cannot show it, and the order seems too high; lower den_order "
                "(and num_order)", ()))
    if cov is not None:
        verdicts.extend(_cancellations(poles, zeros, cov, k))
    return verdicts, stable


def row_pole_verdicts(structure, x, unc, names, *, allow_unstable: bool = False) -> list[Verdict]:
    """Stability verdicts of a MIMO structure's output rows, with the SISO rule for a marginal pole.

    A right-half-plane pole of row ``i`` within its uncertainty of the
    imaginary axis (at :data:`VERDICT_LEVEL`) is marginal (an integrating
    output, a warning); farther out it fails the fit unless ``allow_unstable``.

    Examples
    --------
    >>> from hammerstein_ctrl import LinearStructure, Tanh, MIMOHammersteinStructure
    >>> s = MIMOHammersteinStructure(LinearStructure(0, 1), [Tanh(), Tanh()], n_outputs=2)
    >>> [v.code for v in row_pole_verdicts(s, np.array([2.0, 0.5, 0.7, -1.0, 1, 1, 2, 0.5]), None, ["a", "b"])]
    ['unstable']
    """
    from ._propagation import root_gradients

    cov = None if unc is None else unc.covariance
    k = t_factor(VERDICT_LEVEL, unc.dof if unc is not None else 10**9)
    _, den = structure.coefficients(x)
    out = []
    for i, name in enumerate(names):
        pos, idx = structure.row_denominator(i)
        roots, grads = root_gradients(den[0, i], pos)
        for v, g in zip(roots, grads):
            if v.real <= 1e-12 * max(1.0, abs(v)):
                continue
            full = np.zeros(np.size(x), dtype=complex)
            full[idx] = g
            se_re = _component_se(full, cov)[0] if cov is not None else 0.0
            if v.real <= k * se_re:
                out.append(Verdict("marginal-pole", WARNING, f"output {name!r}: the pole at {_complex(v)} is within "
                                   f"its uncertainty (± {se_re:.2g}) of the imaginary axis: taken as an integrating "
                                   "output, not as unstable", ()))
            elif not allow_unstable:
                out.append(Verdict("unstable", FAILURE, f"output {name!r}: the pole at {_complex(v)} (± {se_re:.2g}) "
                                   "lies in the right half-plane and the model diverges from rest; try other orders, "
                                   "offset=True, or allow_unstable=True for a plant that is really unstable", ()))
    return out


def _cancellations(poles, zeros, cov, k) -> list[Verdict]:
    out, used = [], set()
    for p in poles:
        for j, z in enumerate(zeros):
            if j in used or z["block"] != p["block"]:     # a pole and a zero with a map between them never cancel
                continue
            d = p["value"] - z["value"]
            se_re, se_im = _component_se(p["gradient"] - z["gradient"], cov)
            if abs(d.real) <= k * se_re and abs(d.imag) <= k * se_im + 1e-12 * abs(p["value"]):
                used.add(j)
                out.append(Verdict(
                    "cancellation", WARNING,
                    f"the pole at {_complex(p['value'])} and the zero at {_complex(z['value'])} cancel within "
                    "their uncertainty: the order seems too high; lower num_order and den_order by one", ()))
                break
    return out


def _complex(v: complex) -> str:
    if abs(v.imag) <= 1e-12 * max(1.0, abs(v)):
        return f"{v.real:.4g}"
    return f"{v.real:.4g} {'+' if v.imag >= 0 else '-'} {abs(v.imag):.4g}j"


def _fix_hint(structure, pole: complex) -> str:
    if "a0" in _linear_names(structure) and abs(pole.imag) <= 1e-12 * max(1.0, abs(pole)):
        return ("to make it an exact integrator, fix a0 = 0 (LinearStructure(..., fixed={'a0': 0.0}), "
                "--fix a0=0)")
    return "fix the coefficient that places it, if the plant is known to be marginal"


# -- offset and budget --------------------------------------------------------------
def offset_verdict(structure, residuals, unc: ParameterUncertainty | None) -> Verdict | None:
    """A warning when the residuals keep a mean the model does not produce (``offset=True`` forgotten)."""
    if structure.offset:
        return None
    r = np.asarray(residuals, dtype=float)
    n = r.size
    mean = float(r.mean())
    density = unc.noise.spectrum_at_zero() if unc is not None else float(r @ r) / max(n - 1, 1)
    se = np.sqrt(max(density, 0.0) / n)
    share = mean * mean / max(float(r @ r) / n, 1e-300)
    if not (abs(mean) > OFFSET_T * se and share > OFFSET_SHARE):
        return None
    return Verdict(
        "offset-missing", WARNING,
        f"the residuals keep a mean of {_fmt(mean)} ({abs(mean) / se:.0f} standard errors, {100 * share:.0f} % of "
        "their mean square): the output seems to have an offset the model cannot produce; pass offset=True "
        "(--offset)", ())


#: Verdict codes that explain a least-squares method's slow progress better than a short budget.
_SLOW_PROGRESS = ("undetermined", "offset-state", "offset-missing", "fast-pole", "cancellation")
#: Relative fall of the best J over the last :data:`LATE_SHARE` of the evaluations past which a run out of
#: budget was still improving (raising maxfev helps); crawling runs fall by 1e-5 or less.
STILL_IMPROVING = 1e-3
LATE_SHARE = 0.2


def late_improvement(history) -> float:
    """Relative fall of the best J over the last :data:`LATE_SHARE` of a run's evaluations (``inf`` when the
    best value was not finite before).

    Examples
    --------
    >>> round(late_improvement({"nfev": [10, 70, 90, 100], "best": [5.0, 1.1, 1.05, 1.0]}), 6)
    0.1
    """
    nfev = np.asarray((history or {}).get("nfev", ()), dtype=float)
    best = np.asarray((history or {}).get("best", ()), dtype=float)
    if nfev.size == 0:
        return 0.0
    early = nfev <= (1.0 - LATE_SHARE) * nfev[-1]
    before = best[early][-1] if early.any() else np.inf
    last = best[-1]
    if not np.isfinite(last) or last <= 0:
        return 0.0
    return float((before - last) / last) if np.isfinite(before) else np.inf


def budget_advice(verdicts, maxfev: int | None, improvement: float = 0.0) -> str:
    """What to do when the budget ran out before convergence, given the other verdicts and the last fifth's progress.

    Examples
    --------
    >>> budget_advice([], 2000, improvement=0.15)
    'did not converge within maxfev = 2000: raise maxfev (J still fell by 15 % over the last fifth of the evaluations)'
    >>> budget_advice([Verdict("cancellation", WARNING, "a pole and a zero cancel")], 2000,
    ...               improvement=1e-8)  # doctest: +NORMALIZE_WHITESPACE
    'did not converge within maxfev = 2000, crawling (J fell by 1e-06 % over the last fifth of the evaluations), and
    more evaluations would not help: a pole and a zero cancel'
    """
    budget = f"maxfev = {maxfev}" if maxfev else "the evaluation budget"
    if improvement > STILL_IMPROVING:
        fell = "more than halved" if improvement > 1.0 else f"fell by {100 * improvement:.2g} %"
        return f"did not converge within {budget}: raise maxfev (J still {fell} over the last fifth of the evaluations)"
    crawl = f"J fell by {100 * improvement:.1g} % over the last fifth of the evaluations"
    causes = [v for v in verdicts if v.code in _SLOW_PROGRESS] or [v for v in verdicts
                                                                   if v.code == "poorly-determined"]
    if not causes:
        return (f"did not converge within {budget}, crawling ({crawl}): raising maxfev may not help; the problem "
                "seems ill-conditioned (see the standard errors)")
    shown = [v.message for v in causes if v.severity != FAILURE][:1]
    return (f"did not converge within {budget}, crawling ({crawl}), and more evaluations would not help"
            + (": " + shown[0] if shown else " (the reasons above)"))
