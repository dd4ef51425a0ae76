"""Compile Levenberg-Marquardt's compiled loop into the machine's cache, then say so (run in the background).

:func:`hammerstein_ctrl.optimize.normal_lm.compiled_loop_wanted` starts
``python -m hammerstein_ctrl._warm`` the first time a least-squares fit could
use the compiled loop on a machine whose cache does not hold it yet.  This
process fits small records with the loop (the families linear in their
parameters, which the loop serves, under both holds), and writes the marker file only when every fit
ran it, so the marker never claims a loop that is not there.
"""

from __future__ import annotations

import os

import numpy as np

__all__ = ["main"]


def _fits() -> bool:
    """Fit the small records with the compiled loop; True when every fit ran it."""
    from .iodata import IOData
    from .nonlinearities import Coulomb, Polynomial
    from .objective import HammersteinCost
    from .optimize import levenberg_marquardt
    from .optimize import normal_lm
    from .structure import HammersteinStructure, LinearStructure

    t = np.arange(400) * 0.01
    u = np.sin(1.3 * t) + 0.5 * np.sign(np.sin(0.4 * t))
    y = np.convolve(np.tanh(u), np.exp(-t[:50]), mode="full")[:t.size] * 0.01
    ran = True
    for nl in (Coulomb(), Polynomial(3)):
        for hold in ("foh", "zoh"):
            cost = HammersteinCost(IOData(u, y, dt=0.01, intersample=hold), HammersteinStructure(
                LinearStructure(0, 2), nl))
            passes = normal_lm._Passes(cost, None)
            ran = ran and passes.direct is not None
            levenberg_marquardt(cost, np.r_[2.0, 3.0, np.ones(nl.n_params)], maxfev=60)
    return ran


def main() -> int:
    """Compile the loop, then write the marker (atomically; nothing if the fits did not use the loop)."""
    from .optimize.normal_lm import loop_marker

    os.environ["HAMMERSTEIN_CTRL_COMPILED_LOOP"] = "always"
    marker = loop_marker()
    if marker is None:
        return 1
    try:
        ran = _fits()
    except Exception:                   # noqa: BLE001 - any failure: say so once, never retry in every process
        ran = False
    if not ran:
        marker.with_suffix(".failed").write_text("the compiled loop could not be compiled or did not run\n")
        return 1
    tmp = marker.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text("compiled\n")
    os.replace(tmp, marker)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
