"""``warmup`` compiles ahead of time what identifying a structure needs, so a later process compiles nothing (numba)
and builds nothing (the C compiler)."""

import os
import subprocess
import sys
import textwrap

import pytest

from hammerstein_ctrl.cli import main
from hammerstein_ctrl.exceptions import HammersteinError
from hammerstein_ctrl.warmup import warmup, warmup_plan

from _processes import REPO

#: A fresh process: identify a record other than warmup's (another seed, length and input) and count numba's
#: compilations and the C compiler's builds of kernels; prints the count and the names.
_IDENTIFY_COUNTING_COMPILES = textwrap.dedent("""
    import warnings
    import numba.core.event as ev
    import numpy as np
    from hammerstein_ctrl import _native
    names = []
    build = _native._build
    def counting(compiler, target, kernel=None):
        names.append(target.name)
        return build(compiler, target, kernel)
    _native._build = counting
    class Count(ev.Listener):
        def on_start(self, event):
            d = event.data.get("dispatcher")
            names.append(d.py_func.__module__ + "." + d.py_func.__qualname__ if d else "?")
        def on_end(self, event):
            pass
    ev.register("numba:compile", Count())
    import control
    import hammerstein_ctrl as hc
    rng = np.random.default_rng(11)
    u = np.repeat(rng.normal(size=160), 20)
    model = hc.HammersteinModel(control.tf([6.0], [1.0, 5.0, 6.0]), hc.Polynomial(3), [1.0, 0.3, -0.2])
    data = hc.IOData(u, np.zeros(u.size), dt=0.02)
    y = model.simulate(data) + 0.01 * rng.standard_normal(u.size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hc.identify(hc.IOData(u, y, dt=0.02), hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Polynomial(3)))
    print(len(names), names)
""")


def _python(code: str, cache) -> str:
    env = {**os.environ, "PYTHONPATH": str(REPO), "HAMMERSTEIN_CTRL_CACHE": str(cache)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.slow
def test_after_warmup_a_fresh_process_identifies_the_structure_without_compiling(tmp_path):
    cache = tmp_path / "cache"
    before = _python(_IDENTIFY_COUNTING_COMPILES, tmp_path / "cold")
    assert int(before.split()[0]) >= 2                      # from empty caches it builds (the control case)
    report = _python("from hammerstein_ctrl.warmup import warmup\n"
                     "r = warmup(orders=[2], families=['polynomial'], executor='serial')\n"
                     "print(r.ok)\nprint(r.table())", cache)
    assert report.splitlines()[0] == "True", report
    after = _python(_IDENTIFY_COUNTING_COMPILES, cache)
    assert after.split()[0] == "0", after


def test_the_grid_is_checked_with_one_line_errors():
    plan = warmup_plan(orders=[1, 3], families=["Polynomial", "tanh"], holds=["zoh"])
    assert [(j.order, j.family, j.hold) for j in plan] == [(1, "polynomial", "zoh"), (3, "polynomial", "zoh"),
                                                           (1, "tanh", "zoh"), (3, "tanh", "zoh")]
    for kwargs, match in [({"orders": [0]}, "orders must be integers in 1..10"),
                          ({"orders": [2.5]}, "orders must be integers"),
                          ({"families": ["nope"]}, "unknown nonlinearity 'nope'"),
                          ({"holds": ["linear"]}, "hold must be 'foh' or 'zoh'"),
                          ({"orders": []}, "nothing to warm")]:
        with pytest.raises(HammersteinError, match=match):
            warmup_plan(**kwargs)


def test_a_structure_that_cannot_be_identified_is_reported_and_the_others_still_run():
    # friction is a feedback map of Lur'e models: as the input map of a Hammerstein structure it has no start
    report = warmup(orders=[1], families=["polynomial", "friction"], executor="serial")
    assert report.errors[0] is None and report.errors[1] is not None and not report.ok
    assert "order 1, friction, foh" in report.table() and "compiled" in report.table()


def test_the_command_line_warms_a_grid_and_exits_2_on_bad_input(capsys):
    assert main(["warmup", "--orders", "1", "--nonlinearity", "polynomial", "--jobs", "1"]) == 0
    out = capsys.readouterr().out
    assert "order 1, polynomial, foh" in out and "1 structures:" in out
    assert main(["warmup", "--orders", "11"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "orders must be integers in 1..10, got 11" in err
