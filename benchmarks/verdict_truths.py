"""False alarms of the verdicts on known-truth records fitted with the correct structure.

Run: ``python benchmarks/verdict_truths.py`` (from any directory with the package installed; a few seconds).
``--jobs 2`` fits two records at a time, ``--repeats 20`` draws every record 20 times (1000 records, about
a minute on 2 cores) for the alarm rates, ``--only NAME`` runs the records whose name contains NAME (a draw:
``--repeats 6 --only 'H-sat-1/(s+1.5)-foh-wh5%-off#5'``), ``--explain`` prints the verdicts, the parameters and
the residual analysis of every alarmed record.

Fifty records of systems whose structure is known, generated here without the package's simulator
(python-control's ``forced_response`` for first-order-hold inputs, ``scipy.signal.lsim(..., interp=False)`` for
held inputs, numpy for the static maps, python-control's ZOH discretisation sample by sample in closed loop):

* 35 open-loop records: Hammerstein (tanh, cubic polynomial, saturation, dead zone), Wiener (tanh, saturation,
  cubic polynomial) and Hammerstein-Wiener plants, linear blocks of order 1 to 3 (some with a zero), some with an
  output offset (fitted with ``offset=True``), white or AR(1) (pole 0.8) measurement noise of 1 to 10 % of the
  noise-free output's standard deviation, smooth multisine inputs (``intersample="foh"``) or random staircases
  (``intersample="zoh"``), amplitudes that drive the nonlinearity hard;
* 15 closed-loop records: ``2 tanh(0.8 u) -> 1/(s^2 + 1.2 s + 2)`` in a sampled PI loop
  ``u = kp e + ki dt sum(e)``, ``e = r - y_measured`` (the white measurement noise enters ``u``), ``r`` a random
  staircase, fitted with ``closed_loop=True``.

Every record is fitted by ``hc.identify(data, structure, seed=0)`` with the true structure.  A failure
(``success`` False) or a warning verdict on such a record is a false alarm.  Per record the table gives the
failure and warning codes ("(stop)": ``success`` False with no failure verdict, an out-of-budget stop), the fit
and, for scale, the fit of the noise-free truth to the noisy record, and how many true parameters lie within 4
standard errors of the estimate.  The global optimum fits at least as well as the truth, so a fit below the
truth's is a search that missed (its alarms are right); the summary counts the alarms on the other fits apart
(the verdicts' own false alarms), besides false failures, records with any warning and each verdict code.
Targets: no false failure, at most 5 % of records with a warning.
"""

import argparse
import time
import warnings
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from typing import NamedTuple

import control as ct
import numpy as np
import scipy.signal

import hammerstein_ctrl as hc

DT = 0.05
N_OPEN = 2000
N_CLOSED = 3000
AR_POLE = 0.8
WITHIN = 4.0                                   # standard errors
TARGET_WARNED = 0.05
FIT_SLACK = 0.05                               # fit % points (the optimum fits at least as well as the truth)

# Linear blocks B(s)/A(s) with a monic numerator (the package's convention): (num, den), highest power first.
LINEAR = {
    "1/(s+1.5)": ([1.0], [1.0, 1.5]),
    "1/(s2+1.2s+2)": ([1.0], [1.0, 1.2, 2.0]),
    "(s+2)/(s2+1.5s+3)": ([1.0, 2.0], [1.0, 1.5, 3.0]),
    "1/(s+1)(s2+s+2)": ([1.0], [1.0, 2.0, 3.0, 2.0]),
    "(s+1.5)/(s+2)(s2+.6s+1.5)": ([1.0, 1.5], [1.0, 2.6, 2.7, 3.0]),
}


# Static maps in the package's parameterisations (the families' docstrings), written again here in numpy.
def tanh_map(u, p):
    return p[0] * np.tanh(p[1] * u)


def poly_map(u, p):
    return sum(c * u ** (i + 1) for i, c in enumerate(p))


def sat_map(u, p):
    return p[0] * np.clip(u, -abs(p[1]), abs(p[1]))


def dz_map(u, p):
    return p[0] * (u - np.clip(u, -abs(p[1]), abs(p[1])))


FAMILIES = {"tanh": (tanh_map, hc.Tanh), "poly3": (poly_map, lambda: hc.Polynomial(3)),
            "sat": (sat_map, hc.Saturation), "dz": (dz_map, hc.DeadZone)}


def scaled_input_params(family, p, s):
    """Parameters of ``x -> f(x / s; p)`` in the family's own form (an output map written for a unit signal)."""
    p = np.asarray(p, dtype=float)
    if family == "tanh":
        return np.array([p[0], p[1] / s])
    if family == "poly3":
        return p / s ** np.arange(1, p.size + 1)
    return np.array([p[0] / s, p[1] * s])          # saturation, dead zone: k clip(x/s, a) = (k/s) clip(x, a s)


class Spec(NamedTuple):
    name: str
    kind: str            # "H", "W", "HW" (open loop) or "CL"
    linear: str
    g: tuple | None      # (family, params); with "HW" the gain parameter is 1
    h: tuple | None      # (family, params for a unit-std intermediate signal)
    offset: float        # true output offset (0: fitted without offset)
    noise: float         # measurement noise std as a fraction of the noise-free output's std (CL: of r's)
    colour: str          # "white" or "ar1"
    hold: str            # "foh" (multisine) or "zoh" (staircase)
    amp: float           # input std
    seed: int
    kp: float = 0.0
    ki: float = 0.0


def _open(kind, lin, g, h, offset, noise, colour, hold, amp, seed):
    parts = [kind, g[0] if g else "", h[0] if h else "", lin, hold, f"{colour[:2]}{noise:.0%}"] + (
        ["off"] if offset else [])
    return Spec("-".join(p for p in parts if p), kind, lin, g, h, offset, noise, colour, hold, amp, seed)


L1, L2, L2Z, L3, L3Z = LINEAR
TANH, POLY = ("tanh", (2.0, 0.8)), ("poly3", (1.0, 0.3, -0.15))
SAT, DZ = ("sat", (1.5, 0.8)), ("dz", (1.5, 0.5))
H_TANH, H_SAT, H_POLY = ("tanh", (2.0, 1.2)), ("sat", (1.5, 0.8)), ("poly3", (1.0, 0.3, -0.15))

OPEN = [
    # Hammerstein
    _open("H", L1, TANH, None, 0.0, 0.01, "white", "foh", 1.5, 101),
    _open("H", L2, TANH, None, 0.0, 0.05, "white", "zoh", 1.5, 102),
    _open("H", L2Z, TANH, None, 0.5, 0.05, "ar1", "foh", 1.5, 103),
    _open("H", L3, TANH, None, 0.0, 0.10, "ar1", "zoh", 1.5, 104),
    _open("H", L3Z, TANH, None, -0.3, 0.03, "white", "foh", 1.5, 105),
    _open("H", L2, TANH, None, 0.0, 0.10, "white", "foh", 1.5, 106),
    _open("H", L1, POLY, None, 0.0, 0.03, "white", "zoh", 1.0, 107),
    _open("H", L2, POLY, None, 0.0, 0.05, "ar1", "foh", 1.0, 108),
    _open("H", L2Z, POLY, None, 0.4, 0.10, "white", "zoh", 1.0, 109),
    _open("H", L3, POLY, None, 0.0, 0.01, "white", "foh", 1.0, 110),
    _open("H", L2, POLY, None, 0.0, 0.03, "ar1", "zoh", 1.0, 111),
    _open("H", L1, SAT, None, 0.5, 0.05, "white", "foh", 1.0, 112),
    _open("H", L2, SAT, None, 0.0, 0.01, "white", "zoh", 1.0, 113),
    _open("H", L2Z, SAT, None, 0.0, 0.10, "ar1", "foh", 1.0, 114),
    _open("H", L3, SAT, None, 0.0, 0.05, "white", "zoh", 1.0, 115),
    _open("H", L3Z, SAT, None, 0.0, 0.05, "ar1", "zoh", 1.0, 116),
    _open("H", L1, DZ, None, 0.0, 0.05, "ar1", "zoh", 1.0, 117),
    _open("H", L2, DZ, None, 0.0, 0.03, "white", "foh", 1.0, 118),
    _open("H", L2Z, DZ, None, 0.6, 0.05, "white", "zoh", 1.0, 119),
    _open("H", L3, DZ, None, 0.0, 0.10, "white", "foh", 1.0, 120),
    _open("H", L2, DZ, None, 0.0, 0.01, "ar1", "foh", 1.0, 121),
    # Wiener (h written for a unit-std H u)
    _open("W", L1, None, H_TANH, 0.0, 0.03, "white", "foh", 1.0, 122),
    _open("W", L2, None, H_TANH, 0.5, 0.05, "ar1", "zoh", 1.0, 123),
    _open("W", L2Z, None, H_TANH, 0.0, 0.05, "white", "foh", 1.0, 124),
    _open("W", L3, None, H_TANH, 0.0, 0.01, "white", "zoh", 1.0, 125),
    _open("W", L1, None, H_SAT, 0.0, 0.05, "white", "zoh", 1.0, 126),
    _open("W", L2, None, H_SAT, 0.0, 0.10, "white", "foh", 1.0, 127),
    _open("W", L2Z, None, H_SAT, -0.4, 0.03, "ar1", "zoh", 1.0, 128),
    _open("W", L3, None, H_SAT, 0.0, 0.05, "ar1", "foh", 1.0, 129),
    _open("W", L1, None, H_POLY, 0.0, 0.03, "ar1", "foh", 1.0, 130),
    _open("W", L2, None, H_POLY, 0.0, 0.05, "white", "zoh", 1.0, 131),
    _open("W", L2Z, None, H_POLY, 0.3, 0.01, "white", "foh", 1.0, 132),
    # Hammerstein-Wiener (g's gain 1)
    _open("HW", L2, ("tanh", (1.0, 0.8)), H_SAT, 0.0, 0.03, "white", "foh", 1.5, 133),
    _open("HW", L2, ("sat", (1.0, 0.8)), H_TANH, 0.0, 0.05, "ar1", "zoh", 1.0, 134),
    _open("HW", L1, ("tanh", (1.0, 0.8)), H_SAT, 0.5, 0.05, "white", "zoh", 1.5, 135),
]

# Closed loop: (seed, noise as a fraction of std(r), kp, ki); loop stable for ki < 1.5 + 1.2 kp (linearised plant).
CLOSED = [Spec(f"CL-kp{kp:g}-ki{ki:g}-wh{noise:.0%}-s{seed}", "CL", L2, ("tanh", (2.0, 0.8)), None, 0.0,
               noise, "white", "zoh", 0.0, seed, kp, ki)
          for seed, noise, kp, ki in [
              (201, 0.01, 0.5, 0.5), (202, 0.03, 0.5, 1.0), (203, 0.05, 0.5, 1.5), (204, 0.10, 0.5, 0.5),
              (205, 0.01, 1.0, 1.0), (206, 0.03, 1.0, 2.0), (207, 0.05, 1.0, 0.5), (208, 0.10, 1.0, 1.0),
              (209, 0.01, 1.5, 1.5), (210, 0.03, 1.5, 2.5), (211, 0.05, 1.5, 1.0), (212, 0.10, 1.5, 2.0),
              (213, 0.02, 2.0, 1.0), (214, 0.05, 2.0, 2.5), (215, 0.08, 0.8, 1.2)]]

SPECS = OPEN + CLOSED


# -- signals -----------------------------------------------------------------------------------------------------
def multisine(rng, n, amp, fmax=1.0):
    """Random-phase multisine, every harmonic of the record up to ``fmax`` Hz, standard deviation ``amp``."""
    t = DT * np.arange(n)
    k = np.arange(1, int(fmax * n * DT) + 1)
    phase = rng.uniform(0.0, 2 * np.pi, k.size)
    u = np.sin(2 * np.pi * np.outer(t, k) / (n * DT) + phase).sum(axis=1)
    return amp * u / u.std()


def staircase(rng, n, amp, shortest=5, longest=40):
    """Levels ~ N(0, amp^2) held a random 5-40 samples."""
    out = np.empty(n)
    i = 0
    while i < n:
        k = int(rng.integers(shortest, longest + 1))
        out[i:i + k] = amp * rng.standard_normal()
        i += k
    return out


def linear_response(lin, u, hold):
    """The linear block's response from rest: FOH by python-control, ZOH by scipy (``interp=False``)."""
    num, den = LINEAR[lin]
    t = DT * np.arange(u.size)
    if hold == "foh":
        return np.asarray(ct.forced_response(ct.tf(num, den), t, u).outputs, dtype=float)
    return scipy.signal.lsim((num, den), u, t, interp=False)[1]


def measurement_noise(rng, n, std, colour):
    w = rng.standard_normal(n)
    if colour == "ar1":
        w = scipy.signal.lfilter([1.0], [1.0, -AR_POLE], w)
    return std * w / w.std()


# -- truths and structures ---------------------------------------------------------------------------------------
def linear_beta(lin):
    """[b0 .. b_{l-1}, a0 .. a_{m-1}] of a monic block (ascending powers, the leading coefficients left out)."""
    num, den = LINEAR[lin]
    return list(num[::-1][:-1]) + list(den[::-1][:-1])


def structure_of(spec, h_scale=1.0):
    """``(structure, true beta)``; ``h_scale`` is the std of the signal entering ``h``."""
    num, den = LINEAR[spec.linear]
    lin = hc.LinearStructure(len(num) - 1, len(den) - 1)
    beta = linear_beta(spec.linear)
    g = h = None
    if spec.g is not None:
        g = FAMILIES[spec.g[0]][1]()
        gp = list(spec.g[1])
        beta += gp[1:] if spec.kind == "HW" else gp          # HW: g's gain (first parameter) is fixed to 1
    if spec.h is not None:
        h = FAMILIES[spec.h[0]][1]()
        beta += list(scaled_input_params(spec.h[0], spec.h[1], h_scale))
    off = spec.offset != 0.0
    if off:
        beta.append(spec.offset)
    if spec.kind in ("H", "CL"):
        s = hc.HammersteinStructure(lin, g, offset=off)
    elif spec.kind == "W":
        s = hc.WienerStructure(lin, h, offset=off)
    else:
        s = hc.HammersteinWienerStructure(lin, g, h, offset=off)
    return s, s.normalize(np.array(beta, dtype=float))


def open_record(spec):
    """``(IOData, noise-free output, structure, true beta)`` of an open-loop spec."""
    rng = np.random.default_rng(spec.seed)
    u = multisine(rng, N_OPEN, spec.amp) if spec.hold == "foh" else staircase(rng, N_OPEN, spec.amp)
    v = FAMILIES[spec.g[0]][0](u, spec.g[1]) if spec.g is not None else u
    x = linear_response(spec.linear, v, spec.hold)
    scale = 1.0
    if spec.h is not None:
        scale = float(x.std())
        x = FAMILIES[spec.h[0]][0](x / scale, spec.h[1])
    y0 = x + spec.offset
    y = y0 + measurement_noise(rng, N_OPEN, spec.noise * x.std(), spec.colour)
    s, beta = structure_of(spec, scale)
    return hc.IOData(u, y, dt=DT, intersample=spec.hold, name=spec.name), y0, s, beta


def closed_record(spec):
    """The PI loop simulated sample by sample on python-control's ZOH discretisation of the linear block."""
    rng = np.random.default_rng(spec.seed)
    num, den = LINEAR[spec.linear]
    sys_d = ct.ss(ct.sample_system(ct.tf(num, den), DT, method="zoh"))
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys_d.A, sys_d.B, sys_d.C, sys_d.D))
    r = staircase(rng, N_CLOSED, 1.0, 80, 200)
    r = 0.9 * np.tanh(r)                                       # reachable set points, |r| < 1 = max |g| / a0
    v_noise = spec.noise * r.std() * rng.standard_normal(N_CLOSED)
    g = FAMILIES[spec.g[0]][0]
    x = np.zeros(A.shape[0])
    u, y_true = np.empty(N_CLOSED), np.empty(N_CLOSED)
    integral = 0.0
    for k in range(N_CLOSED):
        y_true[k] = (C @ x)[0]                                # D = 0: y(k) depends on inputs before k
        e = r[k] - (y_true[k] + v_noise[k])
        integral += e
        u[k] = spec.kp * e + spec.ki * DT * integral
        x = A @ x + B[:, 0] * g(u[k], spec.g[1])
    s, beta = structure_of(spec)
    return hc.IOData(u, y_true + v_noise, dt=DT, intersample="zoh", name=spec.name), y_true, s, beta


def fit_percent(y, yhat):
    return 100.0 * (1.0 - np.linalg.norm(y - yhat) / np.linalg.norm(y - y.mean()))


# -- one record --------------------------------------------------------------------------------------------------
def run(spec, explain=False):
    data, y0, structure, beta = (closed_record if spec.kind == "CL" else open_record)(spec)
    t0 = time.perf_counter()
    with warnings.catch_warnings():            # the verdicts are read from the result, not from the warnings
        warnings.simplefilter("ignore", hc.IdentificationWarning)
        res = hc.identify(data, structure, seed=0, closed_loop=spec.kind == "CL")
    wall = time.perf_counter() - t0
    truth = dict(zip(structure.param_names, beta))
    se = res.stderr or {}
    within = sum(1 for k, v in truth.items()
                 if k in res.params and k in se and abs(res.params[k] - v) <= WITHIN * se[k])
    failures = [v.code for v in res.verdicts if v.severity == "failure"]
    if not res.success and not failures:                 # e.g. an out-of-budget stop: no verdict of its own
        failures = ["(stop)"]
    out = dict(name=spec.name, kind=spec.kind, success=bool(res.success), failures=list(dict.fromkeys(failures)),
               warnings=list(dict.fromkeys(v.code for v in res.verdicts if v.severity == "warning")),
               fit=float(res.fit_percent), truth_fit=fit_percent(np.asarray(data.y).ravel(), y0),
               within=within, n_params=len(truth), wall=wall, detail="")
    if explain and (out["failures"] or out["warnings"]):
        lines = [f"--- {spec.name}: {res.message}"]
        lines += [f"  [{v.severity}] {v.code}: {v.message}" for v in res.verdicts]
        lines += ["  truth: " + ", ".join(f"{k}={v:.4g}" for k, v in truth.items()),
                  "  fit:   " + ", ".join(f"{k}={v:.4g}±{se.get(k, np.nan):.2g}" for k, v in res.params.items())]
        analysis = res.analysis if res.analysis is not None else res.residual_analysis()
        lines.append("  " + analysis.summary().replace("\n", "\n  "))
        out["detail"] = "\n".join(lines)
    return out


def _alarmed(r) -> bool:
    return not r["success"] or bool(r["warnings"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--jobs", type=int, default=1, help="records fitted at a time (processes)")
    parser.add_argument("--only", default="", help="run only the records whose name contains this (e.g. '#5')")
    parser.add_argument("--repeats", type=int, default=1,
                        help="draws of every record (seed + 1000 k): more records for the alarm rates")
    parser.add_argument("--explain", action="store_true", help="print the verdicts and residual analysis of alarms")
    args = parser.parse_args()
    specs = [s._replace(seed=s.seed + 1000 * k, name=s.name + (f"#{k}" if k else ""))
             for k in range(args.repeats) for s in SPECS]
    specs = [s for s in specs if args.only in s.name]
    started = time.perf_counter()
    print(f"{'record':46s} {'ok':>3s} {'failures':16s} {'warnings':22s} {'fit %':>6s} {'truth':>6s} "
          f"{'in4se':>5s} {'wall':>6s}")
    with ProcessPoolExecutor(max_workers=args.jobs) if args.jobs > 1 else _Serial() as pool:
        rows = []
        for row in pool.map(run, specs, [args.explain] * len(specs)):
            rows.append(row)
            print(f"{row['name']:46s} {'yes' if row['success'] else 'NO':>3s} {','.join(row['failures']) or '-':16s} "
                  f"{','.join(row['warnings']) or '-':22s} {row['fit']:6.2f} {row['truth_fit']:6.2f} "
                  f"{row['within']:>2d}/{row['n_params']:<2d} {row['wall']:5.2f}s", flush=True)
            if row["detail"]:
                print(row["detail"], flush=True)
    total = time.perf_counter() - started
    n = len(rows)
    failed = [r for r in rows if not r["success"]]
    warned = [r for r in rows if r["warnings"]]
    # an alarm on a fit below the noise-free truth's own fit (by FIT_SLACK points) is right: the search missed
    missed = [r for r in rows if r["fit"] < r["truth_fit"] - FIT_SLACK]
    false_alarms = [r for r in rows if _alarmed(r) and r["fit"] >= r["truth_fit"] - FIT_SLACK]
    codes = Counter(c for r in rows for c in r["failures"] + r["warnings"])
    outside = sum(r["within"] < r["n_params"] for r in rows)
    print(f"\nfalse failures (success False): {len(failed)} of {n} (target 0)")
    print(f"records with a warning: {len(warned)} of {n} ({100.0 * len(warned) / max(n, 1):.1f} %, "
          f"target <= {100 * TARGET_WARNED:.0f} %)")
    print(f"fits more than {FIT_SLACK:g} points below the truth's fit (search missed; alarms there are right): "
          f"{len(missed)}, of which alarmed {sum(_alarmed(r) for r in missed)}")
    print(f"alarms on fits at the truth's level (the verdicts' own false alarms): {len(false_alarms)} of "
          f"{n - len(missed)} ({100.0 * len(false_alarms) / max(n - len(missed), 1):.1f} %)")
    for kind in ("H", "W", "HW", "CL"):
        sub = [r for r in rows if r["kind"] == kind]
        if sub:
            print(f"  {kind:3s}: {sum(not r['success'] for r in sub):3d} failed, "
                  f"{sum(bool(r['warnings']) for r in sub):3d} warned of {len(sub)}")
    print("verdict codes (records): " + (", ".join(f"{c} {k}" for c, k in sorted(codes.items())) or "none"))
    print(f"records with a true parameter beyond {WITHIN:g} standard errors: {outside} of {n}")
    print(f"runtime: {total:.1f} s")


class _Serial:
    """``map`` in this process (the ``--jobs 1`` stand-in for an executor)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map(self, fn, *iterables):
        return map(fn, *iterables)


if __name__ == "__main__":
    main()
