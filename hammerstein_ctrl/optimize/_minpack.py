"""MINPACK's Levenberg-Marquardt (``lmder``, ``lmdif``), with its column-norm fix.

scipy 1.15 to 1.17 carry a C translation of MINPACK whose ``qrfac``, when it
recomputes a column norm that cancellation has made inaccurate, reads one
element past the column: the next column's first element, and past the end of
the Jacobian's array for the last column (fixed in scipy 1.18).  What lies
there depends on the process's heap, so an ill-conditioned fit could end at
another point in a process that had, say, compiled something before it.
This module runs the same algorithm (Moré's trust-region Levenberg-Marquardt
with column pivoting and scaling, his ``lmpar`` and ``qrsolv``) with the
norm over the column's own elements, so its iterates depend on the problem's
values alone.  It does the C translation's arithmetic in its order (sums
added left to right, ``enorm``'s three sums and constants, squares as
products, no fused multiply-adds), so where the over-read changes no pivot
its iterates are those of scipy's x86-64 wheels bit for bit (checked on
Moré, Garbow and Hillstrom's test problems and on the paper's EMPS and TRS
starts).  The long (per-sample) loops are small compiled functions and
numpy's elementwise operations; the ``n x n`` ones are MINPACK's loops in
Python, with C's division and square root where an argument can be zero or
negative (after an overflow).

Termination codes are MINPACK's (``info``): 0 improper input, 1-4
converged, 5 ``maxfev`` reached, 6-8 tolerances too small.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import _core

__all__ = ["lmder", "enorm", "MinpackResult", "CONVERGED"]

#: MINPACK's exit codes that mean convergence.
CONVERGED = (1, 2, 3, 4)

_EPSMCH = float(np.finfo(float).eps)
_DWARF = float(np.finfo(float).tiny)
_RGIANT = 2.0 ** 63.5               # enorm's constants, as the C translation computes them
_RDWARF = 0.5 / _RGIANT


class MinpackResult(NamedTuple):
    """The solution ``x``, its residual ``fvec``, MINPACK's ``info`` and the counts of
    residual vectors (``nfev``, differences included) and Jacobians (``njev``) asked for.

    Examples
    --------
    >>> MinpackResult(np.zeros(1), np.zeros(2), 2, 3, 1).converged
    True
    >>> MinpackResult(np.zeros(1), np.zeros(2), 5, 300, 1).converged   # maxfev reached
    False
    """

    x: np.ndarray
    fvec: np.ndarray
    info: int
    nfev: int
    njev: int

    @property
    def converged(self) -> bool:
        """Whether MINPACK reported convergence (``info`` in ``CONVERGED``, 1 to 4)."""
        return self.info in CONVERGED


def _fmax(a: float, b: float) -> float:
    """C's ``fmax``: the larger, and the number where one is NaN."""
    return b if (a < b or a != a) else a


def _fmin(a: float, b: float) -> float:
    """C's ``fmin``: the smaller, and the number where one is NaN."""
    return b if (a > b or a != a) else a


def _div(a: float, b: float) -> float:
    """``a / b`` as C divides: infinite or NaN where ``b`` is zero, not an exception.

    >>> _div(1.0, -0.0), _div(0.0, 0.0)
    (-inf, nan)
    """
    if b != 0.0 or b != b:
        return a / b
    if a == 0.0 or a != a:
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


def _sqrt(v: float) -> float:
    """C's ``sqrt``: NaN below zero (a damping that went through NaN), not an exception.

    >>> _sqrt(4.0), _sqrt(-1.0)
    (2.0, nan)
    """
    return math.sqrt(v) if not v < 0.0 else math.nan


def reflect(v, w) -> None:
    """``w -= (sum(v * w) / v[0]) * v``: ``w`` through the Householder reflection of vector ``v`` (scaled so
    that ``v[0]`` is its ``1 + |.|``), MINPACK's loops in the compiled core: the sum added left to right, then the
    update.  ``w`` is a writeable C-ordered float array of ``v``'s length (a row of the factored matrix).

    Examples
    --------
    >>> w = np.array([1.0, 2.0]); reflect(np.array([2.0, 1.0]), w); w
    array([-3.,  0.])
    """
    v = np.ascontiguousarray(v, dtype=float)
    if not (v.size and getattr(w, "size", None) == v.size):       # its type, order and writeability: the wrapper's
        raise TypeError(f"reflect writes into an array of {v.size} values, not {getattr(w, 'shape', type(w))}")
    _core.hc_reflect(v, w, v.size)


def enorm(x) -> float:
    """MINPACK's ``enorm``: the Euclidean norm, its squares added left to right, in three sums scaled
    where squares would overflow or underflow (components beyond ``2**63.5 / n`` or below ``2**-64.5``).

    Examples
    --------
    >>> enorm(np.array([3.0, 4.0]))
    5.0
    >>> enorm(np.array([3e-300, 4e-300])) / 1e-300
    5.0
    """
    x = np.ascontiguousarray(x, dtype=float).ravel()
    return _core.hc_enorm(x, x.size, _RDWARF, _RGIANT) if x.size else 0.0


def _norm(v: list) -> float:
    """:func:`enorm` of a short list of floats (an ``n``-vector)."""
    return enorm(np.array(v, dtype=float)) if v else 0.0


def _series(terms) -> float:
    """A short sum added left to right (Python 3.12's ``sum`` compensates)."""
    total = 0.0
    for t in terms:
        total += t
    return total


def _unpivot(w, ipvt) -> list:
    """``x`` with ``x[ipvt[j]] = w[j]``: a vector of the pivoted order back in the parameters'."""
    x = [0.0] * len(w)
    for j, col in enumerate(ipvt):
        x[col] = w[j]
    return x


def _scaled(diag, v) -> list:
    """``D v``, elementwise."""
    return [d * e for d, e in zip(diag, v)]


def _newton_correction(r, ipvt, diag, dx, dxnorm, fp, delta, sdiag=None) -> float:
    """lmpar's Newton correction of the damping: ``((fp / delta) / |w|) / |w|`` with ``w`` the solution of
    ``S^T w = P^T D dx / |D x|``; ``S`` is R (``sdiag`` None) or the damped factor of qrsolv."""
    n = len(dx)
    wa1 = [diag[ipvt[j]] * _div(dx[ipvt[j]], dxnorm) for j in range(n)]
    for j in range(n):
        if sdiag is None:
            wa1[j] = _div(wa1[j] - _series(r[j][i] * wa1[i] for i in range(j)), r[j][j])
        else:
            wa1[j] = _div(wa1[j], sdiag[j])
            for i in range(j + 1, n):
                wa1[i] -= r[j][i] * wa1[j]
    temp = _norm(wa1)
    return _div(_div(_div(fp, delta), temp), temp)


def _recomputed_norm(rest: np.ndarray) -> float:
    """The norm of a column's remaining elements, where cancellation has spoilt its running estimate:
    the elements below the current row and no more (scipy 1.15-1.17 read one element past them)."""
    return enorm(rest)


def _qrfac(a: np.ndarray):
    """Householder QR with column pivoting of the matrix whose columns are the rows of ``a`` (in place).

    MINPACK's ``qrfac``: returns ``(rdiag, acnorm, ipvt)``; ``a[j, j:]`` holds the
    j-th Householder vector, ``a[k, :k]`` the strict upper part of R's column k.
    """
    n, m = a.shape
    acnorm = np.array([enorm(col) for col in a])
    rdiag, wa, ipvt = acnorm.copy(), acnorm.copy(), list(range(n))
    for j in range(min(m, n)):
        kmax = j
        for k in range(j, n):
            if rdiag[k] > rdiag[kmax]:
                kmax = k
        if kmax != j:
            row = a[j].copy()
            a[j] = a[kmax]
            a[kmax] = row
            rdiag[kmax], wa[kmax] = rdiag[j], wa[j]
            ipvt[j], ipvt[kmax] = ipvt[kmax], ipvt[j]
        v = a[j, j:]
        ajnorm = float(acnorm[ipvt[0]]) if j == 0 else enorm(v)   # the first: a whole column, untouched
        if ajnorm == 0.0:
            rdiag[j] = -ajnorm
            continue
        if v[0] < 0.0:
            ajnorm = -ajnorm
        v /= ajnorm
        v[0] += 1.0
        for k in range(j + 1, n):
            reflect(v, a[k, j:])
            if rdiag[k] != 0.0:
                temp = a[k, j] / rdiag[k]
                rdiag[k] *= math.sqrt(_fmax(0.0, 1.0 - temp * temp))
                q = rdiag[k] / wa[k]
                if 0.05 * (q * q) <= _EPSMCH:
                    rdiag[k] = wa[k] = _recomputed_norm(a[k, j + 1:])
        rdiag[j] = -ajnorm
    return rdiag, acnorm, ipvt


def _qrsolv(r, ipvt, diag, qtb):
    """MINPACK's ``qrsolv`` on ``r`` (``r[j][i]``: R's element (i, j), i <= j; the strict
    ``i > j`` part receives S transposed).  Returns ``(x, sdiag)``."""
    n = len(qtb)
    x, wa, sdiag = [0.0] * n, list(qtb), [0.0] * n
    for j in range(n):
        for i in range(j, n):
            r[j][i] = r[i][j]
        x[j] = r[j][j]
    for j in range(n):
        dl = diag[ipvt[j]]
        if dl != 0.0:
            for k in range(j, n):
                sdiag[k] = 0.0
            sdiag[j] = dl
            qtbpj = 0.0
            for k in range(j, n):
                if sdiag[k] == 0.0:
                    continue
                rk = r[k]
                if abs(rk[k]) < abs(sdiag[k]):
                    cotan = rk[k] / sdiag[k]
                    sin = 0.5 / math.sqrt(0.25 + 0.25 * (cotan * cotan))
                    cos = sin * cotan
                else:
                    tan = _div(sdiag[k], rk[k])     # NaN over a zero once the damping overflowed
                    cos = 0.5 / math.sqrt(0.25 + 0.25 * (tan * tan))
                    sin = cos * tan
                rk[k] = cos * rk[k] + sin * sdiag[k]
                temp = cos * wa[k] + sin * qtbpj
                qtbpj = -sin * wa[k] + cos * qtbpj
                wa[k] = temp
                for i in range(k + 1, n):
                    temp = cos * rk[i] + sin * sdiag[i]
                    sdiag[i] = -sin * rk[i] + cos * sdiag[i]
                    rk[i] = temp
        sdiag[j] = r[j][j]
        r[j][j] = x[j]
    nsing = next((j for j in range(n) if sdiag[j] == 0.0), n)
    wa[nsing:] = [0.0] * (n - nsing)
    for j in range(nsing - 1, -1, -1):
        s = _series(r[j][i] * wa[i] for i in range(j + 1, nsing))
        wa[j] = (wa[j] - s) / sdiag[j]
    return _unpivot(wa, ipvt), sdiag


def _gauss_newton(r, ipvt, qtb):
    """Step 1 of ``lmpar``: the Gauss-Newton direction (least-squares where R is singular) and ``nsing``."""
    n = len(qtb)
    nsing = next((j for j in range(n) if r[j][j] == 0.0), n)
    wa1 = list(qtb[:nsing]) + [0.0] * (n - nsing)
    for j in range(nsing - 1, -1, -1):
        wa1[j] /= r[j][j]
        temp = wa1[j]
        for i in range(j):
            wa1[i] -= r[j][i] * temp
    return _unpivot(wa1, ipvt), nsing


def _lmpar(r, ipvt, diag, qtb, delta: float, par: float):
    """MINPACK's ``lmpar``: the damping ``par`` whose step ``x`` has ``|D x|`` within 10 % of ``delta``.

    Returns ``(par, x)``; ``r`` as for :func:`_qrsolv`.
    """
    n = len(qtb)
    x, nsing = _gauss_newton(r, ipvt, qtb)
    dx = _scaled(diag, x)
    dxnorm = _norm(dx)
    fp = dxnorm - delta
    if fp <= 0.1 * delta:
        return 0.0, x
    parl = _newton_correction(r, ipvt, diag, dx, dxnorm, fp, delta) if nsing == n else 0.0
    wa1 = [_div(_series(r[j][i] * qtb[i] for i in range(j + 1)), diag[ipvt[j]]) for j in range(n)]
    gnorm = _norm(wa1)
    paru = _div(gnorm, delta)
    if paru == 0.0:
        paru = _div(_DWARF, _fmin(delta, 0.1))
    par = _fmin(_fmax(par, parl), paru)
    if par == 0.0:
        par = _div(gnorm, dxnorm)
    for iteration in range(1, 11):
        if par == 0.0:
            par = _fmax(_DWARF, 0.001 * paru)
        sq = _sqrt(par)
        x, sdiag = _qrsolv(r, ipvt, [sq * d for d in diag], qtb)
        dx = _scaled(diag, x)
        dxnorm = _norm(dx)
        temp, fp = fp, dxnorm - delta
        if abs(fp) <= 0.1 * delta or (parl == 0.0 and fp <= temp < 0.0) or iteration == 10:
            break
        parc = _newton_correction(r, ipvt, diag, dx, dxnorm, fp, delta, sdiag)
        if fp > 0.0:
            parl = _fmax(parl, par)
        if fp < 0.0:
            paru = _fmin(paru, par)
        par = _fmax(parl, par + parc)
    return par, x


def _forward_jacobian(fun, x, fvec, epsfcn: float):
    """MINPACK's ``fdjac2``: forward differences with steps ``sqrt(max(epsfcn, eps)) |x_j|``, as rows."""
    eps = math.sqrt(_fmax(epsfcn, _EPSMCH))
    rows = np.empty((x.size, fvec.size))
    for j in range(x.size):
        temp = x[j]
        h = eps * abs(temp) or eps
        x[j] = temp + h
        rows[j] = (_residual(fun, x, fvec.size) - fvec) / h
        x[j] = temp
    return rows


def _residual(fun, x, m: int | None = None) -> np.ndarray:
    """``fun(x)`` as a copy the caller cannot touch (MINPACK copies into its own arrays), of length ``m``."""
    f = np.array(fun(x.copy()), dtype=float).ravel()
    if m is not None and f.size != m:
        raise ValueError(f"the residual function returned {f.size} values, not {m} as at the start")
    return f


class _Factor(NamedTuple):
    r: list              # r[j][i]: R's element (i, j), i <= j; i > j is qrsolv's scratch, as fjac's is in C
    ipvt: list
    acnorm: np.ndarray
    qtf: list


def _factor(rows: np.ndarray, fvec: np.ndarray) -> _Factor:
    """The pivoted QR factor of the Jacobian (columns = ``rows``, overwritten) and ``Q^T f``."""
    rdiag, acnorm, ipvt = _qrfac(rows)
    n = rows.shape[0]
    wa4 = fvec.copy()
    for j in range(n):
        v = rows[j, j:]
        if v[0] != 0.0:
            reflect(v, wa4[j:])
    r = [rows[j, :n].tolist() for j in range(n)]
    for j in range(n):
        r[j][j] = float(rdiag[j])
    return _Factor(r, ipvt, acnorm, wa4[:n].tolist())


def _gradient_cosine(fac: _Factor, fnorm: float) -> float:
    """The largest cosine between the residual and a Jacobian column (``gnorm``)."""
    gnorm = 0.0
    if fnorm != 0.0:
        for j, col in enumerate(fac.ipvt):
            if fac.acnorm[col] != 0.0:
                s = _series(fac.r[j][i] * (fac.qtf[i] / fnorm) for i in range(j + 1))
                gnorm = _fmax(gnorm, abs(s / fac.acnorm[col]))
    return gnorm


def _predicted(fac: _Factor, step, par: float, pnorm: float, fnorm: float) -> tuple[float, float]:
    """The scaled predicted reduction and directional derivative of ``step``."""
    n = len(step)
    wa3 = [0.0] * n
    for j in range(n):
        temp = step[fac.ipvt[j]]
        for i in range(j + 1):
            wa3[i] += fac.r[j][i] * temp
    temp1 = _div(_norm(wa3), fnorm)
    temp2 = _div(_sqrt(par) * pnorm, fnorm)
    return temp1 * temp1 + temp2 * temp2 / 0.5, -(temp1 * temp1 + temp2 * temp2)


def _small(actred: float, prered: float, ratio: float, tol: float) -> bool:
    """MINPACK's test of a step's actual and predicted reductions against ``tol``."""
    return abs(actred) <= tol and prered <= tol and 0.5 * ratio <= 1.0


def _termination(actred, prered, ratio, delta, xnorm, ftol, xtol) -> int:
    """MINPACK's tests after a trial step, in its order (0: go on)."""
    small = _small(actred, prered, ratio, ftol)
    info = 1 if small else 0
    if delta <= xtol * xnorm:
        info = 3 if small else 2
    return info


def _stalled(actred, prered, ratio, delta, xnorm, gnorm, nfev: int, maxfev: int) -> int:
    """MINPACK's tests that stop a run short of its tolerances, in its order (0: go on)."""
    info = 5 if nfev >= maxfev else 0
    if _small(actred, prered, ratio, _EPSMCH):
        info = 6
    if delta <= _EPSMCH * xnorm:
        info = 7
    if gnorm <= _EPSMCH:
        info = 8
    return info


def lmder(fun, jac, x0, *, ftol: float = 1.49012e-8, xtol: float = 1.49012e-8, gtol: float = 0.0,
          maxfev: int = 0, factor: float = 100.0, epsfcn: float = 0.0) -> MinpackResult:
    """Minimise ``sum(fun(x)**2)`` by MINPACK's Levenberg-Marquardt, deterministically.

    Parameters
    ----------
    fun : callable
        ``fun(x)``: the residual vector (length ``m >= n``, the same at every
        point).  A trial point whose residuals are not finite is a rejected
        step, as in MINPACK (a difference point's make the Jacobian non-finite).
    jac : callable or None
        ``jac(x)``: the Jacobian as rows, one per parameter (shape ``(n, m)``,
        scipy's ``col_deriv=True``); ``None``: MINPACK's forward differences
        (``lmdif``, each column one evaluation).
    x0 : array_like
        The start (``n`` parameters).
    ftol, xtol, gtol : float
        MINPACK's tolerances on the relative reduction, the relative step and
        the gradient's cosine.
    maxfev : int
        Most residual vectors; ``0`` (or less): MINPACK's ``100 (n + 1)`` with
        ``jac``, ``200 (n + 1)`` without.
    factor : float
        The first trust region, ``factor |D x0|``; scaling ``D`` is MINPACK's
        ``mode=1`` (the columns' norms).
    epsfcn : float
        Forward differences' relative step squared (at least machine epsilon).

    Returns
    -------
    MinpackResult
        ``info`` 0 for improper input (no parameters, ``m < n``, a negative
        tolerance, ``factor <= 0``), after the one evaluation at ``x0``.

    Raises
    ------
    ValueError
        A start or its residuals not finite; residuals whose length changes;
        a Jacobian of another shape or not finite (where MINPACK would go on
        with NaN).  Exceptions raised by ``fun`` or ``jac`` propagate.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 20)
    >>> y = 2.0 * np.exp(-1.5 * t)
    >>> res = lmder(lambda p: p[0] * np.exp(-p[1] * t) - y,
    ...             lambda p: np.array([np.exp(-p[1] * t), -p[0] * t * np.exp(-p[1] * t)]), [1.0, 1.0])
    >>> res.converged, np.round(res.x, 8).tolist()
    (True, [2.0, 1.5])
    """
    x = np.array(x0, dtype=float).ravel()
    fvec = _residual(fun, x)
    n, m = x.size, fvec.size
    if not (np.isfinite(x).all() and np.isfinite(fvec).all()):
        raise ValueError("lmder needs a finite start and finite residuals there")
    if maxfev <= 0:
        maxfev = (100 if jac is not None else 200) * (n + 1)
    run = _Run(fun, x, fvec, maxfev=maxfev, factor=factor)
    if n == 0 or m < n or ftol < 0.0 or xtol < 0.0 or gtol < 0.0 or factor <= 0.0:
        return run.result(0)
    while True:
        if jac is None:
            rows = _forward_jacobian(fun, run.x, run.fvec, epsfcn)
            run.nfev += n
        else:
            rows = np.array(jac(run.x.copy()), dtype=float, order="C")
            run.njev += 1
            if rows.shape != (n, m):
                raise ValueError(f"the Jacobian has shape {rows.shape}, not (n, m) = {(n, m)} (a row a parameter)")
        if not np.isfinite(rows).all():
            raise ValueError("the Jacobian has non-finite entries")
        fac = _factor(rows, run.fvec)
        run.scale(fac.acnorm)
        gnorm = _gradient_cosine(fac, run.fnorm)
        if gnorm <= gtol:
            return run.result(4)
        run.diag = [_fmax(d, float(c)) for d, c in zip(run.diag, fac.acnorm)]
        info = run.steps(fac, gnorm, ftol, xtol)
        if info:
            return run.result(info)


class _Run:
    """The state of one ``lmder`` run between Jacobians: the point, its residual, the scaling,
    the trust region, the damping and the counts."""

    def __init__(self, fun, x, fvec, *, maxfev: int, factor: float):
        self.fun, self.x, self.fvec, self.fnorm = fun, x, fvec, enorm(fvec)
        self.maxfev, self.factor = maxfev, factor
        self.nfev, self.njev, self.iteration = 1, 0, 1
        self.par = self.delta = self.xnorm = 0.0
        self.diag = None

    def result(self, info: int) -> MinpackResult:
        return MinpackResult(self.x, self.fvec, info, self.nfev, self.njev)

    def scale(self, acnorm):
        """At the first Jacobian: MINPACK's scaling (the columns' norms) and the initial trust region."""
        if self.iteration == 1:
            self.diag = [float(c) if c != 0.0 else 1.0 for c in acnorm]
            self.xnorm = _norm(_scaled(self.diag, self.x))
            self.delta = self.factor * self.xnorm or self.factor

    def steps(self, fac: _Factor, gnorm: float, ftol: float, xtol: float) -> int:
        """Trial steps from one factor until one is accepted (0), the ratio is NaN (0, as C's loop
        leaves), or a test ends the run (its code)."""
        while True:
            self.par, p = _lmpar(fac.r, fac.ipvt, self.diag, fac.qtf, self.delta, self.par)
            step = [-v for v in p]
            trial = self.x + np.array(step)
            pnorm = _norm(_scaled(self.diag, step))
            if self.iteration == 1:
                self.delta = _fmin(self.delta, pnorm)
            ftrial = _residual(self.fun, trial, self.fvec.size)
            self.nfev += 1
            fnorm1 = enorm(ftrial)
            actred = -1.0
            if 0.1 * fnorm1 < self.fnorm:
                q = fnorm1 / self.fnorm
                actred = 1.0 - q * q
            prered, dirder = _predicted(fac, step, self.par, pnorm, self.fnorm)
            ratio = actred / prered if prered != 0.0 else 0.0
            self._update_region(ratio, actred, dirder, pnorm, fnorm1)
            if ratio >= 1e-4:
                self.x, self.fvec, self.fnorm = trial, ftrial, fnorm1
                self.xnorm = _norm(_scaled(self.diag, self.x))
                self.iteration += 1
            info = (_termination(actred, prered, ratio, self.delta, self.xnorm, ftol, xtol)
                    or _stalled(actred, prered, ratio, self.delta, self.xnorm, gnorm, self.nfev, self.maxfev))
            if info or not ratio < 1e-4:
                return info

    def _update_region(self, ratio: float, actred: float, dirder: float, pnorm: float, fnorm1: float):
        """MINPACK's trust-region radius and damping after a trial of reduction ratio ``ratio``."""
        if ratio <= 0.25:
            temp = _div(0.5 * dirder, dirder + 0.5 * actred) if actred < 0.0 else 0.5
            if 0.1 * fnorm1 >= self.fnorm or temp < 0.1:
                temp = 0.1
            self.delta = temp * _fmin(self.delta, pnorm / 0.1)
            self.par /= temp
        elif self.par == 0.0 or ratio >= 0.75:
            self.delta = pnorm / 0.5
            self.par *= 0.5
