"""Structure selection: fit candidate structures to a record and rank them.

:func:`select_structure` identifies every candidate (orders x nonlinearity
families x Hammerstein / Wiener / Hammerstein-Wiener, e.g. from
:func:`candidate_structures`), on any ``concurrent.futures.Executor`` as
studies do, and ranks them by an information criterion on the estimation
record or by their fit on a validation record.  For ``N`` samples, ``p``
parameters and ``J`` the sum of squared errors:

* ``"aic"``: ``N ln(J/N) + 2 p`` (Akaike);
* ``"bic"``: ``N ln(J/N) + p ln N`` (Schwarz; penalises parameters harder);
* ``"fpe"``: ``(J/N) (N + p) / (N - p)`` (Akaike's final prediction error);
* ``"validation"``: the fit % on ``validation`` (higher is better).

Candidates whose identification does not succeed rank after those that do,
and over-ordered ones (a pole beyond the record's bandwidth, a cancelling
pole-zero pair, undetermined parameters) after those that are not, whatever
their criterion: a validation fit, which does not charge for parameters,
can favour an over-ordered candidate by a few thousandths of a percent.
Each row keeps the result's verdicts.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> cands = candidate_structures([(0, 1), (1, 2)], [hc.Tanh(), hc.Polynomial(3)])
>>> sel = select_structure(case.data, cands, executor="serial")
>>> sel.best.structure.describe()
'H(p) = (p + b0)/(p^2 + a1 p + a0); g = tanh(d0, d1)'
>>> [r["rank"] for r in sel.table]
[1, 2, 3, 4]
"""

from __future__ import annotations

import math
import warnings
from typing import Mapping, Sequence

import numpy as np

from ..exceptions import IdentificationWarning, ParameterError
from ..blocks._structure import (BlockStructure, HammersteinStructure, HammersteinWienerStructure, LinearStructure,
                                 WienerStructure)

__all__ = ["select_structure", "candidate_structures", "SelectionResult", "CRITERIA", "information_criterion"]

#: Ranking criteria (see the module notes).
CRITERIA = ("aic", "bic", "fpe", "validation")
#: Structure kinds of :func:`candidate_structures`.
KINDS = ("hammerstein", "wiener", "hammerstein-wiener")
#: Verdict codes that mark a candidate as over-parameterised.
OVER_ORDERED = ("fast-pole", "cancellation", "undetermined")


def information_criterion(criterion: str, sse: float, n_samples: int, n_params: int) -> float:
    """AIC, BIC or FPE of a least-squares fit (module notes); ``inf`` for a non-finite or zero ``sse``.

    Examples
    --------
    >>> round(information_criterion("aic", 2.0, 100, 3), 4), round(information_criterion("fpe", 2.0, 100, 3), 6)
    (-385.2023, 0.021237)
    """
    n, p = int(n_samples), int(n_params)
    if not (np.isfinite(sse) and sse > 0) or n <= p:
        return math.inf
    if criterion == "aic":
        return n * math.log(sse / n) + 2 * p
    if criterion == "bic":
        return n * math.log(sse / n) + p * math.log(n)
    if criterion == "fpe":
        return sse / n * (n + p) / (n - p)
    raise ParameterError(f"criterion must be one of {CRITERIA[:3]} here, got {criterion!r}")


def candidate_structures(orders: Sequence, nonlinearities: Sequence = (), *, kinds: Sequence[str] = ("hammerstein",),
                         output_nonlinearities: Sequence = (), **options) -> list[BlockStructure]:
    """Every combination of linear orders, nonlinearity families and structure kinds.

    Parameters
    ----------
    orders : sequence of (num_order, den_order) or LinearStructure
    nonlinearities : sequence of Nonlinearity
        Input nonlinearities (Hammerstein, and the input side of Hammerstein-Wiener).
    kinds : sequence of {"hammerstein", "wiener", "hammerstein-wiener"}
    output_nonlinearities : sequence of Nonlinearity
        Output nonlinearities (Wiener, Hammerstein-Wiener); default: ``nonlinearities``.
    **options
        ``offset``, ``initial_state`` for every candidate.

    Examples
    --------
    >>> import hammerstein_ctrl as hc
    >>> [s.describe() for s in candidate_structures([(0, 1)], [hc.Tanh()], kinds=("hammerstein", "wiener"))]
    ['H(p) = (1)/(p + a0); g = tanh(d0, d1)', 'H(p) = (1)/(p + a0); h = tanh(d0, d1)']
    """
    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise ParameterError(f"kinds must be among {KINDS}, got {bad}")
    linears = [o if isinstance(o, LinearStructure) else _linear(o) for o in orders]
    outputs = list(output_nonlinearities) or list(nonlinearities)
    out = []
    for lin in linears:
        for kind in kinds:
            if kind == "hammerstein":
                out += [HammersteinStructure(lin, g, **options) for g in nonlinearities]
            elif kind == "wiener":
                out += [WienerStructure(lin, h, **options) for h in outputs]
            else:
                out += [HammersteinWienerStructure(lin, g, h, **options) for g in nonlinearities for h in outputs
                        if g.gain_index is not None]
    if not out:
        raise ParameterError("no candidate structures: give orders and nonlinearities for the kinds asked")
    return out


def _linear(order) -> LinearStructure:
    try:
        num, den = order
    except (TypeError, ValueError):
        raise ParameterError(f"an order must be (num_order, den_order) or a LinearStructure, got {order!r}") from None
    return LinearStructure(num, den)


def _fit(data, structure, validation, maxfev, seed, noise):
    """Identify one candidate (in a worker): the result and its validation figures, warnings kept in the result."""
    from ._identify import identify

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        res = identify(data, structure, maxfev=maxfev, seed=seed, noise=noise)
    checked = res.validate(validation) if validation is not None and res.model is not None else None
    return res, checked


class SelectionResult:
    """The ranked candidates of :func:`select_structure`.

    Attributes
    ----------
    table : list of dict
        One row per candidate, best first: ``rank``, ``structure``, ``n_params``,
        ``J``, ``fit_percent``, ``validation_fit`` (with a validation record),
        ``aic``, ``bic``, ``fpe``, ``success``, ``over_ordered``, ``verdicts``
        (codes) and ``message``.
    results : list of IdentificationResult
        In the order of ``table``.
    criterion : str
    best : IdentificationResult
        The first successful candidate (else the first).

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> t = np.arange(600) * 0.05
    >>> u = np.sin(0.7 * t) + 0.5 * np.sin(2.1 * t)
    >>> s = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Polynomial(1))
    >>> y = s.model([2.0, 3.0]).simulate(t, u) + 0.01 * np.random.default_rng(1).standard_normal(600)
    >>> data = hc.IOData(u, y, dt=0.05)
    >>> sel = hc.select_structure(data, [s], seed=0)
    >>> isinstance(sel, SelectionResult), len(sel.results)
    (True, 1)
    """

    def __init__(self, rows: list, results: list, criterion: str):
        self.table, self.results, self.criterion = rows, results, criterion
        ok = [r for r, row in zip(results, rows) if row["success"]]
        self.best = ok[0] if ok else results[0]

    def to_frame(self):
        """The table as a pandas DataFrame indexed by rank."""
        from ..data._display import require_pandas

        pd = require_pandas()
        frame = pd.DataFrame(self.table).set_index("rank")
        frame.attrs.update(criterion=self.criterion)
        return frame

    def summary(self) -> str:
        """The table as text, best first."""
        lines = [f"structures ranked by {self.criterion} (best first):"]
        for row in self.table:
            score = (f"validation fit {row['validation_fit']:.2f} %" if self.criterion == "validation"
                     else f"{self.criterion} = {row[self.criterion]:.6g}")
            flags = ("" if row["success"] else " FAILED") + (" over-ordered" if row["over_ordered"] else "")
            lines.append(f"  {row['rank']:>2}. {row['structure']}: p = {row['n_params']}, "
                         f"fit {row['fit_percent']:.2f} %, {score}{flags}")
        return "\n".join(lines)

    def __repr__(self):
        return f"<SelectionResult: {len(self.table)} candidates by {self.criterion}; best {self.table[0]['structure']}>"

    def _repr_pretty_(self, printer, cycle):
        printer.text(self.summary())

    def _repr_html_(self) -> str:
        import html

        cols = ["rank", "structure", "n_params", "J", "fit_percent"] + (
            ["validation_fit"] if any(r.get("validation_fit") is not None for r in self.table) else []) + [
            "aic", "bic", "fpe", "success", "verdicts"]
        head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)

        def cell(v):
            if isinstance(v, float):
                return f"{v:.6g}"
            if isinstance(v, (list, tuple)):
                return html.escape(", ".join(v))
            return html.escape(str(v))

        body = "".join("<tr" + ("" if r["success"] else " style='color:firebrick'") + ">"
                       + "".join(f"<td>{cell(r.get(c))}</td>" for c in cols) + "</tr>" for r in self.table)
        return (f"<table><caption style='text-align:left'>structures ranked by {self.criterion}</caption>"
                f"<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")


def _row(res, checked, n: int) -> dict:
    p = len(res.x)
    codes = [v.code for v in res.verdicts]
    return {"structure": res.structure.describe(), "n_params": p, "J": float(res.fun),
            "fit_percent": float(res.fit_percent),
            "validation_fit": None if checked is None else float(checked["fit_percent"]),
            **{c: information_criterion(c, res.fun, n, p) for c in CRITERIA[:3]},
            "success": bool(res.success), "over_ordered": any(c in OVER_ORDERED for c in codes),
            "verdicts": codes, "message": res.message}


def select_structure(data, candidates, validation=None, criterion: str = "aic", *, maxfev: int | None = None,
                     seed=0, noise: str = "colored", executor=None, jobs: int | None = None) -> SelectionResult:
    """Fit each candidate structure and rank them (module notes).

    Parameters
    ----------
    data : IOData
        The estimation record.
    candidates : sequence or mapping of BlockStructure
        E.g. :func:`candidate_structures`; a mapping's keys are not used.
    validation : IOData, optional
        A record to validate each fit on (needed by ``criterion="validation"``).
    criterion : {"aic", "bic", "fpe", "validation"}, default "aic"
    maxfev, seed, noise
        Passed to :func:`~hammerstein_ctrl.fit` for every candidate.
    executor, jobs
        Where the fits run (:func:`~hammerstein_ctrl._executors.make_executor`):
        a local process pool by default, ``"serial"`` for this process, or any
        ``concurrent.futures.Executor`` (a ``dask.distributed`` client's too).

    Returns
    -------
    SelectionResult

    Examples
    --------
    >>> import numpy as np, hammerstein_ctrl as hc
    >>> t = np.arange(1500) * 0.05
    >>> u = 2 * np.sin(0.4 * t) + np.sin(1.3 * t)
    >>> truth = hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh()).model([1.0, 2.0, 0.8])
    >>> rng = np.random.default_rng(0)
    >>> data = hc.IOData(u, truth.simulate(t, u) + 0.01 * rng.standard_normal(t.size), dt=0.05)
    >>> sel = select_structure(data, hc.candidate_structures([(0, 1), (0, 2)], [hc.Tanh(), hc.Polynomial(3)]), seed=0)
    >>> sel.best.structure.describe()
    'H(p) = (1)/(p + a0); g = tanh(d0, d1)'
    """
    from ..data._inputs import as_iodata
    from .._executors import make_executor

    criterion = str(criterion).strip().lower()
    if criterion not in CRITERIA:
        raise ParameterError(f"criterion must be one of {CRITERIA}, got {criterion!r}")
    if criterion == "validation" and validation is None:
        raise ParameterError("criterion='validation' needs a validation record")
    cands = list(candidates.values() if isinstance(candidates, Mapping) else candidates)
    if not cands or not all(isinstance(c, BlockStructure) for c in cands):
        raise ParameterError("candidates must be a non-empty sequence of structures (e.g. candidate_structures(...))")
    data = as_iodata(data).require_siso("select_structure")
    validation = None if validation is None else as_iodata(validation).require_siso("select_structure")
    pool, owned = make_executor(executor, jobs)
    try:
        if pool is None:
            fits = [_fit(data, c, validation, maxfev, seed, noise) for c in cands]
        else:
            fits = [f.result() for f in [pool.submit(_fit, data, c, validation, maxfev, seed, noise) for c in cands]]
    finally:
        if owned:
            pool.shutdown()
    rows = [_row(res, checked, len(data)) for res, checked in fits]
    order = sorted(range(len(rows)), key=lambda i: (not rows[i]["success"], rows[i]["over_ordered"],
                                                    _score(rows[i], criterion)))
    ranked = [{"rank": k + 1, **rows[i]} for k, i in enumerate(order)]
    return SelectionResult(ranked, [fits[i][0] for i in order], criterion)


def _score(row: dict, criterion: str) -> float:
    if criterion == "validation":
        fit = row["validation_fit"]
        return -fit if fit is not None and np.isfinite(fit) else math.inf
    value = row[criterion]
    return value if np.isfinite(value) else math.inf
