"""Shared fixtures.

The suite runs against the installed package (``make test`` installs it, building its compiled core, then runs
pytest from its console script, which puts no source folder on ``sys.path``): a package imported from the source
tree, which has no compiled core, stops the run at once with the reason.

EMPS tests need the benchmark files.  They are looked up through
``$HAMMERSTEIN_CTRL_DATA`` (CI sets it to ``../shared/data``) or, for a developer
checkout, ``../shared/data`` next to the repository.  When the files are truly
absent those tests skip with a reason, unless ``HAMMERSTEIN_CTRL_REQUIRE_DATA=1``
(set by ``.ci/run``), in which case they fail: CI must always exercise them.
"""

import os
import sys
from pathlib import Path

# the suite exercises Levenberg-Marquardt's compiled loop wherever it applies (the default, "auto", runs it too;
# tests hide it where they compare it with the Python loop)
os.environ.setdefault("HAMMERSTEIN_CTRL_COMPILED_LOOP", "always")
# child Python processes (python -c, python -m) import the installed package too: none puts its current folder,
# the checkout perhaps, first on sys.path
os.environ["PYTHONSAFEPATH"] = "1"

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _benchmark_scripts() -> None:
    """The speed benchmarks are scripts of the repository, not of the package: their tests import them by name
    (``import speed``), and get these very files whatever else is on ``sys.path``."""
    import importlib.util

    for name in ("speed", "structures_speed"):
        spec = importlib.util.spec_from_file_location(name, REPO / "benchmarks" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)



def _installed_package():
    """The package as installed: its compiled core imports, and it is not the source tree's folder."""
    try:
        import hammerstein_ctrl._core  # noqa: F401
        import hammerstein_ctrl
    except ImportError as exc:
        raise pytest.UsageError(f"hammerstein_ctrl's compiled core does not import ({exc}): install the package "
                                "(make install, or pip install .) and run pytest from its console script, which "
                                "puts no source folder on sys.path") from None
    if Path(hammerstein_ctrl.__file__).resolve().parent == REPO / "hammerstein_ctrl":
        raise pytest.UsageError("hammerstein_ctrl was imported from the source tree: the tests run against the "
                                "installed package (make test; python -m pytest puts the current folder first)")


def pytest_configure(config):
    _installed_package()
    _benchmark_scripts()


def _emps_dir():
    candidates = []
    if os.environ.get("HAMMERSTEIN_CTRL_DATA"):
        candidates.append(Path(os.environ["HAMMERSTEIN_CTRL_DATA"]) / "emps")
    candidates.append(REPO.parent / "shared" / "data" / "emps")
    for c in candidates:
        if (c / "DATA_EMPS.mat").is_file() and (c / "DATA_EMPS_PULSES.mat").is_file():
            return c
    return None


@pytest.fixture(scope="session")
def emps_dir():
    d = _emps_dir()
    if d is None:
        msg = ("EMPS files DATA_EMPS.mat / DATA_EMPS_PULSES.mat not found via $HAMMERSTEIN_CTRL_DATA "
               "or ../shared/data")
        if os.environ.get("HAMMERSTEIN_CTRL_REQUIRE_DATA") == "1":
            pytest.fail(msg + " (HAMMERSTEIN_CTRL_REQUIRE_DATA=1: CI must have them)")
        pytest.skip(msg)
    return d


@pytest.fixture(scope="session")
def emps_case(emps_dir):
    from hammerstein_ctrl import presets

    return presets.emps(path=emps_dir)


@pytest.fixture(scope="session")
def trs_case():
    from hammerstein_ctrl import presets

    return presets.trs()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def no_work(monkeypatch):
    """Record (instead of running) any fit or study: arguments must be refused before any work."""
    import importlib

    started = []
    # the module the command line calls identify from, at call time
    monkeypatch.setattr(importlib.import_module("hammerstein_ctrl.fit._identify"), "identify",
                        lambda *a, **k: started.append("fit"))
    monkeypatch.setattr(importlib.import_module("hammerstein_ctrl.paper.study"), "run_study",
                        lambda *a, **k: started.append("study"))
    return started


@pytest.fixture
def coulomb_record():
    """Make ``y = 1/(p^2 + 2p + 4) (u + 0.3 sign u + offset)`` with 1 % noise, simulated by python-control."""
    import control

    from hammerstein_ctrl import IOData

    def make(n_samples=3000, offset=-0.5):
        dt = 0.01
        t = dt * np.arange(n_samples)
        u = np.sin(t) + 0.5 * np.sin(3.3 * t)
        g = 1.0 * u + 0.3 * np.sign(u) + offset
        y = control.forced_response(control.tf([1], [1, 2, 4]), t, g).outputs
        y = y + 0.01 * np.random.default_rng(0).standard_normal(t.size)
        return IOData(u, y, dt=dt)

    return make
