"""Known-truth systems made by independent code (python-control and scipy): the inputs, the truths' simulation, and
the standard errors the tests compare with.  Shared by the known-truth tests of several subpackages."""

from __future__ import annotations

import control as ct
import numpy as np
import scipy.signal

from hammerstein_ctrl import (
    Coulomb,
    DeadZone,
    HammersteinStructure,
    IOData,
    LinearStructure,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    Tanh,
)

#: Parameters must lie within this many standard errors of the truth.
K_SIGMA = 5.0
#: Slack on J <= J(truth): the optimiser's tolerance.
J_SLACK = 1e-6
DT = 0.02
N = 4000


def multisine(rng, amplitude, f_lo=0.01, f_hi=2.0, lines=25):
    t = np.arange(N) * DT
    f = np.geomspace(f_lo, f_hi, lines)
    u = np.sum(np.sin(2 * np.pi * f[:, None] * t + rng.uniform(0, 2 * np.pi, lines)[:, None]), axis=0)
    return amplitude * u / np.max(np.abs(u))


def multilevel_prbs(rng, amplitude, hold=25, levels=7):
    values = rng.choice(np.linspace(-amplitude, amplitude, levels), N // hold + 1)
    return np.repeat(values, hold)[:N]


def companion(num, den):
    """Controllable canonical realisation, written out independently of the package."""
    num, den = np.asarray(num, float) / den[0], np.asarray(den, float) / den[0]
    n = den.size - 1
    num = np.concatenate([np.zeros(n + 1 - num.size), num])
    A = np.zeros((n, n))
    A[0] = -den[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    D = num[0]
    C = (num[1:] - D * den[1:])[None, :]
    return A, B, C, np.array([[D]])


def simulate_truth(num, den, v, hold="foh", x0=None):
    A, B, C, D = companion(num, den)
    t = np.arange(v.size) * DT
    x0 = np.zeros(A.shape[0]) if x0 is None else np.asarray(x0, float)
    if hold == "zoh":
        _, y, _ = scipy.signal.lsim((A, B, C, D), v, t, X0=x0, interp=False)
        return y
    return ct.forced_response(ct.ss(A, B, C, D), t, v, X0=x0).outputs


def sat(u, a):
    return np.clip(u, -a, a)


# name: (linear structure, nonlinearity, true beta, g(u) in numpy, input, noise, options)
SYSTEMS = {
    "tanh_rhp_zero": dict(
        lin=LinearStructure(1, 2), nl=Tanh(), beta=[-1.0, 2.0, 1.2, 2.0, 0.8],
        g=lambda u: 2.0 * np.tanh(0.8 * u), u=lambda r: multisine(r, 2.0), noise=0.01),
    "coulomb_integrator": dict(
        lin=LinearStructure(0, 2, fixed={"a0": 0.0}), nl=Coulomb(), beta=[2.0, 0.6, 0.3, 0.05],
        g=lambda u: 0.6 * u + 0.3 * np.sign(u) + 0.05, u=lambda r: multilevel_prbs(r, 1.0), noise=0.01),
    "saturation_first_order_10pct": dict(
        lin=LinearStructure(0, 1), nl=Saturation(), beta=[2.0, 1.5, 0.7],
        g=lambda u: 1.5 * sat(u, 0.7), u=lambda r: multisine(r, 1.5), noise=0.10),
    "deadzone_third_order": dict(
        lin=LinearStructure(0, 3), nl=DeadZone(), beta=[4.0, 5.0, 2.0, 2.0, 0.3],
        g=lambda u: 2.0 * (u - sat(u, 0.3)), u=lambda r: multilevel_prbs(r, 1.5), noise=0.01),
    "cubic_resonance_zeta005": dict(
        lin=LinearStructure(0, 2), nl=Polynomial(3), beta=[4.0, 0.2, 1.0, 0.0, 0.5],
        g=lambda u: u + 0.5 * u**3, u=lambda r: multisine(r, 1.2), noise=0.01),
    "pwl_fourth_order": dict(
        lin=LinearStructure(0, 4), nl=PiecewiseLinear([-1.0, 0.0, 1.0]),
        beta=[9.0, 12.0, 13.0, 4.0, -0.5, 0.0, 1.5],  # (p^2+p+1)(p^2+3p+9)
        g=lambda u: np.interp(u, [-1, 0, 1], [-0.5, 0.0, 1.5], left=None, right=None)
        + np.where(u > 1, 1.5 * (u - 1), 0.0) + np.where(u < -1, 0.5 * (u + 1), 0.0),
        u=lambda r: multisine(r, 1.0, lines=40), noise=0.01),
    "tanh_zoh_input": dict(
        lin=LinearStructure(0, 2), nl=Tanh(), beta=[3.0, 2.5, 1.5, 1.2],
        g=lambda u: 1.5 * np.tanh(1.2 * u), u=lambda r: multilevel_prbs(r, 1.5, hold=5), noise=0.01,
        hold="zoh"),
    "polynomial_output_offset": dict(
        lin=LinearStructure(1, 2), nl=Polynomial(2), beta=[3.0, 2.0, 1.5, 1.0, 0.4, 0.5],
        g=lambda u: u + 0.4 * u**2, u=lambda r: multisine(r, 1.5), noise=0.01, offset=True),
    "saturation_initial_state": dict(
        lin=LinearStructure(0, 2), nl=Saturation(), beta=[1.0, 0.8, 2.0, 0.8, 0.6, -0.9],
        g=lambda u: 2.0 * sat(u, 0.8), u=lambda r: multisine(r, 1.5), noise=0.01, initial_state=True),
}


def make_case(name, seed=0):
    spec = SYSTEMS[name]
    rng = np.random.default_rng(seed)
    structure = HammersteinStructure(spec["lin"], spec["nl"], offset=spec.get("offset", False),
                                     initial_state="estimate" if spec.get("initial_state") else "zero")
    beta = np.array(spec["beta"], float)
    k, m = spec["lin"].n_params, structure.n_core
    num, den = spec["lin"].coefficients(beta[:k])
    u = spec["u"](rng)
    hold = spec.get("hold", "foh")
    offset, x0 = structure.nuisance(beta)
    y = simulate_truth(num[0], den[0], spec["g"](u), hold, x0) + (0.0 if offset is None else offset)
    y = y + spec["noise"] * np.std(y) * rng.standard_normal(y.size)
    data = IOData(u, y, dt=DT, name=name, intersample=hold)
    return data, structure, beta, m


def standard_errors(cost, x):
    """Gauss-Newton standard errors at x from a central-difference Jacobian of the residuals."""
    r0 = cost.residuals(x)
    J = np.empty((r0.size, x.size))
    for i in range(x.size):
        h = 1e-6 * max(abs(x[i]), 1e-3)
        e = np.zeros(x.size)
        e[i] = h
        J[:, i] = (cost.residuals(x - e) - cost.residuals(x + e)) / (2 * h)
    s2 = (r0 @ r0) / (r0.size - x.size)
    return np.sqrt(np.diag(s2 * np.linalg.pinv(J.T @ J)))
