"""N-SPSA with the paper's gains and with automatic gains on the known-truth systems.

Run: ``python benchmarks/known_truth_nspsa.py`` (from the repository root).
Each system starts 30-50 % away from the truth (seeded); a run "solves" the
system when its final J <= 1.01 J(truth).  Prints one line per system and
gain setting, then the counts.
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_known_truth import make_case  # noqa: E402

from hammerstein_ctrl import identify
from hammerstein_ctrl.fit import HammersteinCost  # noqa: E402
from hammerstein_ctrl.paper.settings import emps_methods, trs_methods  # noqa: E402

SIX = ["tanh_rhp_zero", "coulomb_integrator", "saturation_first_order_10pct", "deadzone_third_order",
       "cubic_resonance_zeta005", "pwl_fourth_order"]
BUDGET = 2501
SOLVED = 1.01


def start(truth, rng):
    return truth * (1 + rng.choice([-1, 1], truth.size) * rng.uniform(0.3, 0.5, truth.size))


def main(seeds=range(3)):
    settings = {"paper EMPS gains": emps_methods()["nspsa"]["options"],
                "paper TRS gains": trs_methods()["nspsa"]["options"], "auto gains": "auto"}
    solved = {k: 0 for k in list(settings) + ["auto method"]}
    total = 0
    for name in SIX:
        data, structure, truth, _ = make_case(name)
        cost = HammersteinCost(data, structure)
        jt = cost(truth)
        for seed in seeds:
            total += 1
            x0 = start(truth, np.random.default_rng(seed))
            line = [f"{name:30s} seed {seed}"]
            for label, opts in settings.items():
                r = identify(data, structure, method="nspsa", x0=x0, maxfev=BUDGET, seed=seed, options=opts)
                ok = r.fun <= SOLVED * jt
                solved[label] += ok
                line.append(f"{label}: {r.fun / jt:9.4g}{'*' if ok else ' '}")
            r = identify(data, structure, maxfev=BUDGET, seed=seed)
            solved["auto method"] += r.fun <= SOLVED * jt
            line.append(f"auto: {r.fun / jt:.6f}")
            print("  ".join(line), flush=True)
    print(f"solved (J <= {SOLVED} J(truth)) out of {total}: " + ", ".join(f"{k} {v}" for k, v in solved.items()))


if __name__ == "__main__":
    main()
