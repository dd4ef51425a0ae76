"""``import hammerstein_ctrl`` and ``hammerstein-ctrl --help`` load no heavy dependency.

The package imports its sub-modules and public names on first use (PEP 562),
so the import is quick; every public name must still resolve, and the
function ``identify`` must not be shadowed by its own sub-module.
Each check runs in a fresh interpreter, where nothing is imported yet.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numpy", "scipy", "numba", "control", "matplotlib")


def fresh(code: str) -> dict:
    import os

    env = dict(os.environ)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_loads_no_heavy_dependency():
    loaded = fresh("import sys, json; import hammerstein_ctrl; "
                   f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    assert loaded == []


def test_help_loads_no_heavy_dependency():
    code = ("import sys, json, contextlib, io\n"
            "from hammerstein_ctrl.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "    try:\n"
            "        main(['--help'])\n"
            "    except SystemExit:\n"
            "        pass\n"
            f"print(json.dumps({{'loaded': [m for m in {HEAVY!r} if m in sys.modules],"
            " 'usage': 'usage: hammerstein-ctrl' in out.getvalue()}))")
    assert fresh(code) == {"loaded": [], "usage": True}


def test_every_public_name_resolves():
    import hammerstein_ctrl as hc

    for name in hc.__all__:
        assert getattr(hc, name) is not None, name
    assert set(hc.__all__) <= set(dir(hc))
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        hc.nonexistent  # noqa: B018


def test_identify_is_the_function_even_after_importing_its_old_module():
    result = fresh("import json, types, importlib, warnings; import hammerstein_ctrl as hc\n"
                   "warnings.simplefilter('ignore')\n"
                   "importlib.import_module('hammerstein_ctrl.identify')\n"
                   "from hammerstein_ctrl import identify\n"
                   "print(json.dumps([type(hc.identify).__name__, identify is hc.identify,"
                   " type(hc.presets).__name__, hc.HammersteinCost.__module__]))")
    assert result == ["function", True, "module", "hammerstein_ctrl.fit._objective"]


OLD_PATHS = {      # module paths before the re-lay, one name each that users imported from them
    "iodata": "IOData", "records": "read_record", "metrics": "fit_percent", "nonlinearities": "Tanh",
    "structure": "HammersteinStructure", "model": "HammersteinModel", "mimo": "MIMOModel", "lure": "LureStructure",
    "wiener_hammerstein": "WienerHammersteinStructure", "exact_export": "linear_ss",
    "loop_sim": "simulate_loops", "delay": "simulate_delayed", "uncertainty": "propagate", "diagnostics": "Verdict",
    "residual_analysis": "residual_analysis", "significance": "nested_f_test", "objective": "HammersteinCost",
    "identify": "identify", "in_loop": "identify_in_loop", "selection": "select_structure",
    "result": "IdentificationResult", "persistence": "save_model", "plots": "bode", "control_design": "tune_pid",
    "operating_point": "operating_point", "robust_pid": "ms_constrained_pid", "optimize.least_squares":
    "levenberg_marquardt", "kernels": "get_kernel", "auto": "auto_minimize",
}


def test_old_module_paths_import_their_new_module_with_a_deprecation_warning():
    """Each moved path of the flat layout still imports, for one release: the same objects, one warning naming the
    new home (in a fresh interpreter, where nothing is imported yet)."""
    code = ("import importlib, json, warnings\n"
            "import hammerstein_ctrl as hc\n"
            "out = {}\n"
            f"for old, name in {OLD_PATHS!r}.items():\n"
            "    with warnings.catch_warnings(record=True) as caught:\n"
            "        warnings.simplefilter('always')\n"
            "        module = importlib.import_module('hammerstein_ctrl.' + old)\n"
            "    obj = getattr(module, name)\n"
            "    public = [getattr(importlib.import_module(('hammerstein_ctrl.' + sub).rstrip('.')), name, None)\n"
            "              for sub in ('', 'data', 'blocks', 'simulate', 'assess', 'fit', 'design', 'plotting', 'io',\n"
            "                          'optimize')]\n"
            "    out[old] = [[str(w.message) for w in caught if w.category is DeprecationWarning],\n"
            "                obj.__module__.startswith('hammerstein_ctrl.'), any(p is obj for p in public)]\n"
            "print(json.dumps(out))")
    result = fresh(code)
    for old, (warned, inside, same) in result.items():
        assert len(warned) == 1 and warned[0].startswith(f"hammerstein_ctrl.{old} is deprecated"), (old, warned)
        assert ("use hammerstein_ctrl." in warned[0] or "no public replacement" in warned[0]) and inside, old
        if old not in ("kernels", "auto"):           # internals: no public home
            assert same, f"{old}.{OLD_PATHS[old]} is not the public object"


def test_the_benchmarks_left_the_package_with_a_message():
    with pytest.raises(ModuleNotFoundError, match="benchmarks/speed.py"):
        import hammerstein_ctrl.bench  # noqa: F401


def test_star_import_gives_all_names():
    namespace: dict = {}
    exec("from hammerstein_ctrl import *", namespace)
    import hammerstein_ctrl as hc

    assert set(hc.__all__) <= set(namespace)
    assert namespace["identify"] is hc.identify and callable(hc.run_study)
    assert "run_study" not in namespace and "presets" not in namespace      # the paper layer is not star-exported
    assert len(hc.__all__) < 60


def test_an_identification_and_its_printed_summary_do_not_import_python_control():
    # python-control's import (with matplotlib and scipy.signal) costs more than an EMPS fit: the command line's
    # identify prints its result without it
    code = ("import sys, json, warnings, numpy as np, hammerstein_ctrl as hc\n"
            "t = np.arange(2000) * 0.01; u = np.sign(np.sin(0.5 * t)) + 0.3 * np.sin(2.1 * t)\n"
            "s = hc.HammersteinStructure(hc.LinearStructure(0, 2), hc.Tanh())\n"
            "y = s.model([1.2, 2.0, 1.5, 0.8]).simulate(t, u)\n"
            "warnings.simplefilter('ignore')\n"
            "res = hc.identify(hc.IOData(u, y, dt=0.01), s, seed=0)\n"
            "text = res.summary() + repr(res.model)\n"
            "print(json.dumps({'control': 'control' in sys.modules, 'shown': 'p^2' in text}))")
    assert fresh(code) == {"control": False, "shown": True}


def test_a_deprecated_path_warns_at_the_users_line_under_the_default_filters():
    """Python shows a DeprecationWarning by default only where ``__main__`` triggers it: the warning must name the
    user's line, not the package's namespace module that resolved the name."""
    for code in ("from hammerstein_ctrl import plots", "import hammerstein_ctrl as hc; hc.mimo",
                 "import hammerstein_ctrl.control_design", "import hammerstein_ctrl as hc; hc.simulate.unstable"):
        err = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stderr
        assert err.startswith("<string>:1: DeprecationWarning: hammerstein_ctrl."), (code, err)


def test_names_of_old_modules_that_became_subpackages_still_resolve():
    result = fresh("import json, warnings; warnings.simplefilter('ignore'); import hammerstein_ctrl as hc\n"
                   "print(json.dumps([callable(hc.simulate.normal_pass), hc.simulate.MAX_PASS_STATES > 0,\n"
                   "                  callable(hc.cli.build_parser), hc.cli.PROG, hc.cli.EXIT_ERROR,\n"
                   "                  hc.optimize.gains.StepGain is hc.optimize.StepGain,\n"
                   "                  hasattr(hc, 'bench'), 'plotting' in dir(hc)]))")
    assert result == [True, True, True, "hammerstein-ctrl", 2, True, False, True]
