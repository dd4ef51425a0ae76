"""The first ``identify`` of each structure kind in a fresh process: CPU time, what it imports, what it writes.

Run: ``python benchmarks/first_fit.py`` (about 30 s).  Nine records of known plants (Hammerstein, Wiener,
Hammerstein-Wiener, a piecewise-linear map, a dead zone under zero-order hold, an estimated dead time, a 2 x 2
MIMO plant, three records of one plant, a Lur'e loop with friction) are made once in this process and saved; then
each kind is identified in a fresh Python process whose home, cache folder and working folder are new empty
folders, with no C compiler to be found ($CC and $PATH point nowhere).  Each line gives the CPU time of
``import hammerstein_ctrl`` with its front door (``hc.identify`` and the classes the fit uses), the CPU time of the
first ``identify`` (no x0), whether it succeeded, whether numba was imported, and the files written under the
home and working folders (matplotlib's font cache, which python-control's import makes, is kept in a folder of
its own).  Medians of ``--repeat`` processes (default 3).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

DT = 0.02
N = 3000

CHILD = r"""
import json, os, sys, time
from pathlib import Path
kind, path = sys.argv[1], sys.argv[2]
t0 = time.process_time()
import hammerstein_ctrl as hc
front = (hc.identify, hc.IOData, hc.LinearStructure, hc.HammersteinStructure)
t1 = time.process_time()
import numpy as np
d = np.load(path)
u, y = d["u"], d["y"]
L = hc.LinearStructure
if kind == "three records":
    data = [hc.IOData(u[i], y[i], dt=d["dt"]) for i in range(3)]
else:
    data = hc.IOData(u, y, dt=float(d["dt"]), intersample="zoh" if kind == "dead zone, zoh" else "foh")
t2 = time.process_time()
structure = {
    "Hammerstein": lambda: hc.HammersteinStructure(L(1, 2), hc.Tanh()),
    "Wiener": lambda: hc.WienerStructure(L(0, 2), hc.Saturation()),
    "Hammerstein-Wiener": lambda: hc.HammersteinWienerStructure(L(0, 2), hc.Polynomial(3), hc.Tanh()),
    "piecewise-linear": lambda: hc.HammersteinStructure(L(0, 2), hc.PiecewiseLinear([-1.0, -0.3, 0.3, 1.0])),
    "dead zone, zoh": lambda: hc.HammersteinStructure(L(0, 2), hc.DeadZone()),
    "dead time, estimated": lambda: hc.HammersteinStructure(L(0, 1, delay="estimate"), hc.Tanh()),
    "2 x 2 MIMO": lambda: hc.MIMOHammersteinStructure(L(0, 2), [hc.Tanh(), hc.Tanh()], n_outputs=2),
    "three records": lambda: hc.HammersteinStructure(L(0, 2), hc.Coulomb()),
    "Lur'e": lambda: hc.lure_structure(),
}[kind]()
result = hc.identify(data, structure, seed=0)
t3 = time.process_time()
print(json.dumps({"import": t1 - t0, "identify": t3 - t2, "success": bool(result.success),
                  "numba": "numba" in sys.modules, "fun": float(result.fun)}))
"""

KINDS = ("Hammerstein", "Wiener", "Hammerstein-Wiener", "piecewise-linear", "dead zone, zoh", "dead time, estimated",
         "2 x 2 MIMO", "three records", "Lur'e")


def _records(folder: Path) -> dict:
    """One record per kind, simulated by python-control (the package's own simulator for the MIMO plant, the dead
    time and the Lur'e loop), with output noise of 1e-3; the files' paths."""
    import control

    import hammerstein_ctrl as hc

    rng = np.random.default_rng(0)
    t = DT * np.arange(N)
    u = np.repeat(rng.uniform(-1.0, 1.0, N // 40 + 1), 40)[:N]

    def noisy(y):
        return y + 1e-3 * rng.standard_normal(np.shape(y))

    def lin(num, den, v):
        return control.forced_response(control.tf(num, den), t, v).outputs

    paths = {}

    def save(kind, uu, yy):
        paths[kind] = folder / f"{len(paths)}.npz"
        np.savez(paths[kind], u=uu, y=noisy(yy), dt=DT)

    save("Hammerstein", u, lin([1.0, 2.0], [1, 2, 3], 1.5 * np.tanh(1.2 * u)))
    save("Wiener", u, np.clip(1.5 * lin([4.0], [1, 2, 4], u), -0.6, 0.6))
    save("Hammerstein-Wiener", u, np.tanh(0.8 * lin([2.0], [1, 2, 2], u + 0.3 * u ** 3)))
    save("piecewise-linear", u, lin([1.0], [1, 1.5, 1], np.interp(u, [-1, -0.3, 0.3, 1], [-0.5, -0.1, 0.2, 1.0])))
    held = control.forced_response(control.c2d(control.tf([1.0], [1, 2, 2]), DT, "zoh"), t,
                                   np.sign(u) * np.maximum(np.abs(u) - 0.2, 0)).outputs
    save("dead zone, zoh", u, held)
    model = hc.HammersteinModel(control.tf([2.0], [1, 1.5]), hc.Tanh(), [1.0, 1.5], delay=0.37)
    save("dead time, estimated", u, model.simulate(t, u))
    u2 = np.column_stack([u, np.roll(u, 37)])
    y2 = np.column_stack([lin([1.0], [1, 2, 2], np.tanh(u2[:, 0])) + lin([0.5], [1, 2, 2], np.tanh(2 * u2[:, 1])),
                          lin([0.3], [1, 1, 3], np.tanh(u2[:, 0])) + lin([1.0], [1, 1, 3], np.tanh(2 * u2[:, 1]))])
    save("2 x 2 MIMO", u2, y2)
    us = np.stack([np.roll(u, 100 * i) for i in range(3)])
    save("three records", us, np.stack([lin([1.0], [1, 2, 4], 0.8 * v + 0.2 * np.sign(v)) for v in us]))
    lure = hc.LureModel(([1 / 90.0], [1, 2.0, 0.0]), hc.Friction(), [20.0, -3.0], feedback="velocity")
    force = 60 * np.sin(0.7 * t) + 30 * u
    save("Lur'e", force, lure.simulate(t, force))
    return paths


def _child(kind: str, path: Path) -> dict:
    with tempfile.TemporaryDirectory() as scratch:
        home, work = Path(scratch) / "home", Path(scratch) / "work"
        home.mkdir()
        work.mkdir()
        env = {**os.environ, "HOME": str(home), "XDG_CACHE_HOME": str(home / ".cache"), "CC": "/nonexistent/cc",
               "PATH": "/nonexistent", "MPLCONFIGDIR": str(Path(scratch) / "matplotlib"), "PYTHONSAFEPATH": "1"}
        done = subprocess.run([sys.executable, "-c", CHILD, kind, str(path)], capture_output=True, text=True, cwd=work,
                              env=env, check=False)
        if done.returncode:
            raise RuntimeError(f"{kind}: {done.stderr.strip().splitlines()[-1]}")
        out = json.loads(done.stdout.strip().splitlines()[-1])
        out["written"] = len([p for p in home.rglob("*")] + [p for p in work.rglob("*")])
        return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per kind (medians)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        paths = _records(Path(folder))
        print(f"{'kind':22s} {'import + front door':>19s} {'first identify':>15s}  success  numba  files written")
        for kind in KINDS:
            runs = [_child(kind, paths[kind]) for _ in range(args.repeat)]
            print(f"{kind:22s} {statistics.median(r['import'] for r in runs):17.3f} s "
                  f"{statistics.median(r['identify'] for r in runs):13.3f} s  "
                  f"{str(all(r['success'] for r in runs)):7s}  {str(any(r['numba'] for r in runs)):5s}  "
                  f"{max(r['written'] for r in runs)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
