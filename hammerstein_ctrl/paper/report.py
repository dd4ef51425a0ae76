"""Plain-text, Markdown and CSV renderings of a study next to the paper's numbers."""

from __future__ import annotations

import csv
import io
import math
import statistics
import time

import numpy as np

from ..data._inputs import METHOD_LABELS

__all__ = ["study_table", "best_models", "PAPER_TABLES", "time_call", "forced_response_cost"]

#: Where each case's numbers come from in the paper.
PAPER_TABLES = {"trs": "Table 3", "emps": "Table 7"}

_COLUMNS = ("mean", "best", "worst", "std")


def _num(v, digits: int = 6) -> str:
    if v is None:
        return "N/A"
    v = float(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"


def _rows(study, paper: bool, alpha: float):
    s = study.summary(alpha)
    ref = study.case.paper if paper else {}
    rows = []
    for m in study.methods:
        st = s[m]
        label = METHOD_LABELS.get(m, m)
        rows.append({
            "method": label, "source": "ours", **{c: _num(st[c]) for c in _COLUMNS},
            "nfev": f"{st['nfev']:.0f}", "diverged": f"{st['diverged']}/{st['n']}",
            "s/trial": f"{st['time_mean']:.3f}",
        })
        if m in ref:
            p = ref[m]
            rows.append({
                "method": "", "source": "paper", **{c: _num(p[c]) for c in _COLUMNS},
                "nfev": str(p["nfev"]), "diverged": "yes" if m == "spsa" else "", "s/trial": "",
            })
    notes = []
    for pair, r in s["ranksum"].items():
        a, b = pair.split(" vs ")
        line = (f"Wilcoxon rank-sum {METHOD_LABELS.get(a, a)} vs {METHOD_LABELS.get(b, b)}: "
                f"p = {r['p']:.3g}, h = {r['h']} (alpha = {alpha:g})")
        rp = ref.get("ranksum") if paper else None
        if rp and set(rp["pair"]) == {a, b}:
            line += f"; paper: p = {rp['p']:.3g}, h = {rp['h']}"
        notes.append(line)
    if "lm" in study.methods:
        notes.append("LM* = Levenberg-Marquardt on the output error (normal equations from one compiled pass, "
                     "MINPACK's lmder where they are ill-conditioned), not in the paper; deterministic from the "
                     "paper's initial point.")
    notes.append("NFE of the SPSA family includes the one evaluation of the final iterate; "
                 "AMVO-SCA is a documented reconstruction.")
    return rows, notes


def study_table(study, fmt: str = "text", *, paper: bool = True, alpha: float = 0.05) -> str:
    """Render :meth:`StudyResult.summary` as ``"text"``, ``"markdown"`` or ``"csv"``."""
    rows, notes = _rows(study, paper, alpha)
    header = ["method", "source", *_COLUMNS, "nfev", "diverged", "s/trial"]
    n = max((sum(r["method"] == m for r in study.records) for m in study.methods), default=0)
    title = (f"{study.case.name.upper()}: final J = sum (y - yhat)^2 over {n} independent trials, "
             f"seed {study.seed}" + (f"; paper: {PAPER_TABLES.get(study.case.name, '')}" if paper else ""))
    if fmt == "csv":
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=header)
        w.writeheader()
        last = ""
        for r in rows:
            last = r["method"] or last
            w.writerow({**r, "method": last})
        return buf.getvalue()
    if fmt == "markdown":
        lines = [f"**{title}**", "", "| " + " | ".join(header) + " |",
                 "|" + "|".join("---" for _ in header) + "|"]
        lines += ["| " + " | ".join(r[h] for h in header) + " |" for r in rows]
        return "\n".join(lines + [""] + [f"- {x}" for x in notes]) + "\n"
    if fmt != "text":
        raise ValueError(f"unknown table format {fmt!r}; use 'text', 'markdown' or 'csv'")
    widths = {h: max(len(h), *(len(r[h]) for r in rows)) for h in header}

    def line(r):
        return "  ".join(r[h].ljust(widths[h]) if i < 2 else r[h].rjust(widths[h]) for i, h in enumerate(header))

    out = [title, "", line({h: h for h in header}), line({h: "-" * widths[h] for h in header})]
    out += [line(r) for r in rows]
    return "\n".join(out + [""] + notes)


def best_models(study, validation=None) -> dict:
    """Per method, the best trial's parameters, transfer function and (optionally) validation fit.

    Returns a JSON-able ``{method: {"trial", "seed", "J", "params", "linear", "diverged",
    "validation"?}}``; ``validation`` (an IOData record) adds ``sse, rmse, nrmse, fit_percent``
    for every method that did not diverge.
    """
    from ..data._metrics import fit_report

    out = {}
    for m in study.methods:
        rec = study.best(m)
        model = study.best_model(m)
        entry = {"trial": rec["trial"], "seed": rec["seed"], "J": rec["fun"],
                 "params": dict(zip(study.case.structure.param_names, rec["x"])),
                 "linear": {"num": [float(v) for v in model.linear.num[0][0]],
                            "den": [float(v) for v in model.linear.den[0][0]]},
                 "diverged": rec["diverged"]}
        if validation is not None and not rec["diverged"]:
            with np.errstate(all="ignore"):
                entry["validation"] = fit_report(validation.y, model.simulate(validation))
        out[m] = entry
    return out


def time_call(fn, *, repeat: int = 5, number: int = 1) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeat`` runs of ``number`` calls."""
    fn()  # warm-up (compilation, caches)
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - t0) / number)
    return statistics.median(runs)


def forced_response_cost(case, model):
    """J of ``model`` on the case's record computed the slow way, through ``control.forced_response``."""
    import control

    t, u, y = case.data.t, case.data.u, case.data.y
    yhat = control.forced_response(model.linear, t, model.g(u)).outputs
    return float(np.sum((y - yhat) ** 2))
