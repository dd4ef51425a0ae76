"""A damaged numba cache file is compiled again (with a CacheWarning), never an error from every call.

A write cut short (a killed process, a full disk) leaves cache files that no
longer unpickle; numba itself then raised ``EOFError`` / ``UnpicklingError``
from every call in every process until the folder was deleted by hand.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

CHILD = """
import json, warnings
import numpy as np
from hammerstein_ctrl import CacheWarning
from hammerstein_ctrl.simulate import simulate_batch
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    u = np.sin(np.linspace(0.0, 6.0, 200))[None, :]
    y = simulate_batch([[0.0, 1.0]], [[1.0, 0.7, 2.0]], u, 0.03)
print(json.dumps({"y": y[0, ::40].tolist(),
                  "warnings": [str(w.message) for w in caught if issubclass(w.category, CacheWarning)]}))
"""


def _run(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO), "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "kernels"),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _cut_short(path: Path):
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def test_damaged_cache_files_are_compiled_again_with_a_warning(tmp_path):
    first = _run(tmp_path)
    assert first["warnings"] == []
    files = sorted((tmp_path / "numba").rglob("*.nb[ic]"))
    kernel_data = [f for f in files if f.name.startswith("hc_") and f.suffix == ".nbc"]
    package_index = [f for f in files if "_linalg" in f.name and f.suffix == ".nbi"]
    assert kernel_data and package_index, [f.name for f in files]
    for f in kernel_data + package_index:        # a generated kernel's data and the package's own index files
        _cut_short(f)

    damaged = _run(tmp_path)
    assert damaged["y"] == first["y"]
    assert damaged["warnings"], "no CacheWarning for the damaged files"
    assert any("hc_" in w for w in damaged["warnings"]) and any("_linalg" in w for w in damaged["warnings"])
    assert all("compiled again" in w for w in damaged["warnings"])

    again = _run(tmp_path)                       # the cache was saved afresh and reads back
    assert again == first

