"""``identify(data, structure)`` (method "auto", default budget) on known-truth records of 2e3 to 1e5 samples.

Run: ``python benchmarks/auto_known_truth.py`` (from the repository root; about 1 minute).
Eight plants (Coulomb, polynomial, tanh, saturation and piecewise-linear ``g``;
first- to fourth-order blocks, offsets, an estimated initial state, a lightly
damped resonance) are simulated by python-control's ``forced_response`` from
piecewise-constant random inputs, with output noise of standard deviation 0.01
(1e-4 per sample).  A run reaches the noise level when ``J / N <= 1.5e-4``.
Prints one line per record, then the count.
"""

import time

import control
import numpy as np

import hammerstein_ctrl as hc

DT = 0.01
NOISE = 0.01
NOISE_LEVEL = 1.5 * NOISE ** 2
LENGTHS = (2_000, 20_000, 100_000)
SEEDS = (0, 1)
KNOTS = np.linspace(-1.0, 1.0, 7)


def record(n, num, den, g, seed, offset=0.0, hold=200):
    """``y = H g(u) + offset + noise`` from python-control, ``u`` random levels held ``hold`` samples."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-1.0, 1.0, n // hold + 1), hold)[:n]
    t = DT * np.arange(n)
    y = control.forced_response(control.tf(num, den), t, g(u)).outputs + offset + NOISE * rng.standard_normal(n)
    return hc.IOData(u, y, t)


PLANTS = [
    ("coulomb (0, 2)", [1.0], [1, 2, 5], lambda u: 0.8 * u + 0.2 * np.sign(u) + 0.05,
     lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Coulomb()), 0.0),
    ("coulomb (1, 2) + offset", [0.5, 1], [1, 1.2, 1.5], lambda u: 0.8 * u + 0.2 * np.sign(u) + 0.05,
     lambda: hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Coulomb(), offset=True), 0.3),
    ("cubic (0, 3)", [1.0], [1, 3, 3, 1], lambda u: u + 0.3 * u ** 2 - 0.2 * u ** 3,
     lambda: hc.HammersteinStructure(hc.LinearStructure(0, 3), hc.Polynomial(3)), 0.0),
    ("tanh (0, 2) + x(0)", [1.0], [1, 1, 4], lambda u: 2 * np.tanh(1.5 * u),
     lambda: hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh(), initial_state="estimate"), 0.0),
    ("saturation (1, 2) + offset", [1.0, 2.0], [1, 2, 2], lambda u: np.clip(1.5 * u, -0.8, 0.8),
     lambda: hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Saturation(), offset=True), 0.2),
    ("piecewise-linear (1, 3)", [1.0, 1.0], [1, 2, 2.5, 1],
     lambda u: np.interp(u, KNOTS, np.sign(KNOTS) * np.abs(KNOTS) ** 0.5),
     lambda: hc.HammersteinStructure(hc.LinearStructure(1, 3), hc.PiecewiseLinear(KNOTS)), 0.0),
    ("coulomb (0, 1), slow", [1.0], [1, 0.05], lambda u: 0.8 * u + 0.2 * np.sign(u),
     lambda: hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Coulomb()), 0.0),
    ("cubic (0, 4), resonance", [1.0], np.real(np.poly([-0.1 + 3j, -0.1 - 3j, -1, -2])), lambda u: u + 0.2 * u ** 3,
     lambda: hc.HammersteinStructure(hc.LinearStructure(0, 4), hc.Polynomial(3)), 0.0),
]


def main():
    reached = total = 0
    print(f"{'plant':28s} {'samples':>8s} seed {'J/N':>10s} success  nfev  wall")
    for n in LENGTHS:
        for name, num, den, g, structure, offset in PLANTS:
            for seed in SEEDS:
                data = record(n, num, den, g, seed, offset)
                t0 = time.perf_counter()
                r = hc.identify(data, structure(), seed=0)
                per_sample = r.fun / n
                reached += per_sample <= NOISE_LEVEL
                total += 1
                print(f"{name:28s} {n:8d} {seed:4d} {per_sample:10.3e} {str(r.success):7s} {r.nfev:5d} "
                      f"{time.perf_counter() - t0:5.2f}s", flush=True)
    print(f"\nat the noise level (J/N <= {NOISE_LEVEL:.1e}): {reached} of {total}")


if __name__ == "__main__":
    main()
