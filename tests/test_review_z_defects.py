"""Review of f91b47f and 610e000 (LM's loop compiled around the normal-equation pass): one failing test per defect.

Oracle: the Python loop of :func:`~hammerstein_ctrl.optimize.normal_lm.normal_equations_lm`, which the
compiled loop claims to reproduce bit for bit in every case; it runs when the cost's ``direct_pass``
is hidden (returns None).
"""

import numpy as np
import pytest

import hammerstein_ctrl as hc
from hammerstein_ctrl.exceptions import ParameterError
from hammerstein_ctrl.objective import HammersteinCost
from hammerstein_ctrl.optimize import levenberg_marquardt


def _cost(hold="foh", N=400, seed=0):
    """A plain Hammerstein cost ((p + b0) / (p^2 + a1 p + a0), a cubic-free polynomial g): 5 parameters."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-2.0, 2.0, N // 20), 20)
    y = np.sin(np.arange(N) * 0.01) + 0.1 * rng.normal(size=N)
    data = hc.IOData(u, y, dt=0.01, intersample=hold, name="syn")
    return HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Polynomial(2)))


def _python_loop(monkeypatch):
    """Hide the compiled loop: LM then runs its loop in Python around the same pass."""
    monkeypatch.setattr(HammersteinCost, "direct_pass", lambda self: None)


@pytest.mark.parametrize("hide", [True, False], ids=["python loop", "compiled loop"])
def test_a_start_of_the_wrong_length_is_refused_as_by_the_python_loop(hide, monkeypatch):
    """A start one entry longer than the cost's parameters: the Python loop refuses it (ParameterError,
    naming the parameters); the compiled loop ran the pass kernel with 7 lanes on a 5-parameter
    structure (the sixth entry moving nothing) and, with a gtol any start meets, reported success with
    a 6-vector for a 5-parameter model.  (Shorter starts have the compiled loop read past the end of
    its arrays: not run here.)"""
    cost = _cost()
    x0 = np.r_[0.5, 2.0, 3.0, 0.3, 1.2, 0.7]
    if hide:
        _python_loop(monkeypatch)
    with pytest.raises(ParameterError, match="beta must have 5 entries"):
        levenberg_marquardt(cost, x0, gtol=1.0)


_RUN_LM = """
import numpy as np
import hammerstein_ctrl as hc
from hammerstein_ctrl.objective import HammersteinCost
from hammerstein_ctrl.optimize import levenberg_marquardt, normal_lm
rng = np.random.default_rng(0)
u = np.repeat(rng.uniform(-2.0, 2.0, 20), 20)
data = hc.IOData(u, np.sin(np.arange(400) * 0.01), dt=0.01, name="syn")
cost = HammersteinCost(data, hc.HammersteinStructure(hc.LinearStructure(1, 2), hc.Polynomial(2)))
try:
    levenberg_marquardt(cost, [0.5, 2.0, 3.0, 0.3, 1.2])
    outcome = "ran"
except Exception as exc:
    outcome = type(exc).__name__
print(outcome, len(normal_lm._compiled_loop.stats.cache_hits))
"""


@pytest.mark.slow
def test_the_compiled_loop_is_not_loaded_from_numbas_cache_after_the_kernel_module_changes(tmp_path):
    """_compiled_loop calls the pass kernel through a pointer, its argument types checked by
    kernels.call_normal_kernel only when _compiled_loop is compiled.  numba's disk cache of _compiled_loop
    is keyed on normal_lm.py alone (its bytecode and the file's stamp), so after an edit of kernels.py
    (here: the check made to refuse every call, as a changed kernel signature would) a fresh process
    loaded the stale machine code and called the kernel unchecked; the generated kernels themselves
    are keyed on kernels.py's source (kernels.cache_dir).  Oracle: numba's own cache statistics."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    package = Path(hc.__file__).parent
    root = tmp_path / "copy"
    shutil.copytree(package, root / "hammerstein_ctrl")        # copy2: the stamps numba's cache checks are kept
    env = {**os.environ, "PYTHONPATH": str(root), "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "kernels")}

    def run():
        out = subprocess.run([sys.executable, "-c", _RUN_LM], env=env, cwd=tmp_path, capture_output=True, text=True,
                             timeout=600)     # cwd: "-c" puts it first on sys.path
        assert out.returncode == 0, out.stderr[-2000:]
        outcome, hits = out.stdout.split()
        return outcome, int(hits)

    run()
    assert run() == ("ran", 1)          # the control: the second process loads _compiled_loop from the cache
    kernels = root / "hammerstein_ctrl" / "kernels.py"
    text = kernels.read_text()
    check = "    if address != numba.types.int64 or"
    assert check in text
    kernels.write_text(text.replace(check, "    if True or address != numba.types.int64 or"))
    assert run() == ("TypingError", 0)
