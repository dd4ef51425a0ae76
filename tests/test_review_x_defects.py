"""Review of 807b2e5 (streamed_lstsq's ``(begin, X)`` blocks, one ``_point_scored_inf`` rule) and c7e1d23
(numba's cache made tolerant of damaged files; ``make test`` without the slow tests).

Each test is a defect found by the review and fails at c7e1d23.  What was
found sound (bit-identical factors and residuals to the previous code on the
edge cases, bounded memory, the cache guard on empty / truncated / random /
missing / foreign-version files, two processes at once) is in the review
report, not here.

Oracles: ``numpy.linalg.lstsq`` on the regression matrix formed whole, the
function's own result on a healthy cache, and the project's rules ("never
silently wrong numbers"; "a damaged cache file is compiled again, with a
CacheWarning naming the function, instead of failing").
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hammerstein_ctrl import kernels
from hammerstein_ctrl.streamed_lstsq import column_blocks, factor_of_columns, residual_of_columns, solve_scaled

REPO = Path(__file__).resolve().parents[1]


def test_residual_of_columns_never_returns_samples_no_block_covered():
    """residual_of_columns(blocks, w, y) allocates ``np.empty(y.size)`` and writes only the samples the
    blocks cover: blocks of 3 samples with a y of 5 return 2 samples of uninitialised memory as part of
    the residual, with no error (measured: ``[0, 2, 4, 3, 4]`` whose last two are left-over memory).
    The public form of 807b2e5 must refuse blocks that do not cover ``y`` (a clear ValueError), never
    return garbage.  Reproduce: ``residual_of_columns(column_blocks([np.arange(3.0)], 3), [1.0],
    np.arange(5.0))``."""
    y = 3.0 * np.arange(5.0)
    with pytest.raises(ValueError, match="sample|block|cover|length"):
        residual_of_columns(column_blocks([np.arange(3.0)], 3), [1.0], y)


def test_factor_of_columns_checks_its_blocks_against_width_and_y():
    """factor_of_columns(blocks, y, width) neither checks ``width`` against the blocks' columns nor the
    blocks' samples against ``y``: (1) one column declared as width 3 is broadcast into all three
    columns (``part[:, :-1] = X``), and the fit of ``y = 2 t`` comes out ``[2/3, 2/3, 2/3]`` instead of
    a refusal (numpy.linalg.lstsq on the one column gives ``[2]``); (2) blocks of 3 samples with a y of
    5 silently fit the first 3 samples only (the factor's residual 0 where y's tail is not fitted).
    Both are silently wrong numbers from a public function; a clear ValueError is expected.
    Reproduce: ``factor_of_columns(column_blocks([t], 5), 2 * t, 3)``."""
    t = np.arange(5.0)
    assert np.allclose(np.linalg.lstsq(t[:, None], 2 * t, rcond=None)[0], [2.0])      # the oracle
    assert np.allclose(solve_scaled(factor_of_columns(column_blocks([t], 5), 2 * t, 1), 5), [2.0])
    with pytest.raises(ValueError, match="column|width"):
        factor_of_columns(column_blocks([t], 5), 2 * t, 3)
    with pytest.raises(ValueError, match="sample|block|cover|length"):
        factor_of_columns(column_blocks([t[:3]], 3), 3.0 * t ** 2, 1)


def test_a_generated_kernel_source_that_is_not_utf8_is_written_again(tmp_path):
    """A generated kernel module in $HAMMERSTEIN_CTRL_CACHE damaged into bytes that are not UTF-8 (a
    disk error, a bad copy) makes kernels._write_once raise UnicodeDecodeError (``path.read_text()``
    catches only what it compares), so every call that needs that kernel fails, in every process,
    until someone deletes the file -- exactly what c7e1d23 promises never happens for a damaged cache
    (a truncated source that is still UTF-8 is rewritten fine).  Reproduced end to end: random bytes in
    ``kernels-*/hc_kernel_n2_outputs_foh.py`` and ``simulate_batch`` of a second-order system raised
    UnicodeDecodeError from kernels.py:_write_once in every process.  The file must be written again."""
    path = tmp_path / "hc_kernel_n2_outputs_foh.py"
    src = kernels.kernel_source(2, "outputs", "foh")
    path.write_bytes(b"\xff\xfe\xaa" + os.urandom(64))
    kernels._write_once(path, src)
    assert path.read_text() == src


_FULL_DISK_CHILD = """
import json, os, resource, signal, warnings
import numpy as np
limit = int(os.environ.get("RX_FILE_SIZE_LIMIT", "0"))
if limit:                                   # a full disk: every write past `limit` bytes fails (EFBIG)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
out = {"error": None, "h": None}
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    try:
        from hammerstein_ctrl import CacheWarning
        from hammerstein_ctrl.normal_equations import forward_steps
        out["h"] = [float(v).hex() for v in forward_steps(np.array([1.0, -2.0, 0.0, 3e5]))]
    except Exception as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    out["warnings"] = [str(w.message) for w in caught if w.category.__name__ == "CacheWarning"]
print(json.dumps(out))
"""


def _full_disk_child(tmp_path, limit=0):
    env = {**os.environ, "PYTHONPATH": str(REPO), "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "kernels"),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONDONTWRITEBYTECODE": "1",
           "RX_FILE_SIZE_LIMIT": str(limit)}
    proc = subprocess.run([sys.executable, "-c", _FULL_DISK_CHILD], capture_output=True, text=True, env=env,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_damaged_cache_compiled_again_on_a_full_disk_does_not_raise(tmp_path):
    """The guard of c7e1d23 wraps only numba's load: the version compiled again is then saved by
    numba's ``save_overload``, which raises OSError when the write fails -- the full disk (or a cache
    directory that turned read-only) the README names as the cause of the damage.  Reproduced: a
    damaged (emptied) data file of ``normal_equations._forward_steps``, then a process whose writes
    past 64 bytes fail (RLIMIT_FSIZE, as a full disk): the CacheWarning is given and then
    ``forward_steps`` raises ``OSError: [Errno 27] File too large`` from numba's caching.py to the user
    (measured the same with the generated simulation kernel).  The compiled function works in
    memory; failing to save it must not fail the call (a CacheWarning, as for a failed load)."""
    healthy = _full_disk_child(tmp_path)
    assert healthy["error"] is None and healthy["warnings"] == []
    data = sorted((tmp_path / "numba").rglob("normal_equations._forward_steps-*.nbc"))
    assert data, sorted(p.name for p in (tmp_path / "numba").rglob("*"))
    for f in data:
        f.write_bytes(b"")
    full = _full_disk_child(tmp_path, limit=64)
    assert full["error"] is None, full
    assert full["h"] == healthy["h"]
    assert any("_forward_steps" in w for w in full["warnings"]), full["warnings"]
    after = _full_disk_child(tmp_path)                  # the disk has room again: saved, then read back
    assert after["error"] is None and after["h"] == healthy["h"]
    again = _full_disk_child(tmp_path)
    assert again == healthy


_TWO_SIGNATURES_MODULE = """
from hammerstein_ctrl._jit import cached_njit


@cached_njit()
def twice(x):
    return x + x
"""

_TWO_SIGNATURES_CHILD = """
import json, warnings
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    from rx_two_signatures import twice
    values = [twice(3), twice(1.5)]
print(json.dumps({"values": values, "misses": sorted(str(k) for k in twice.stats.cache_misses),
                  "warnings": [str(w.message) for w in caught if w.category.__name__ == "CacheWarning"]}))
"""


def _two_signatures_child(tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), str(tmp_path / "module")]),
           "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "kernels"), "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONDONTWRITEBYTECODE": "1"}
    proc = subprocess.run([sys.executable, "-c", _TWO_SIGNATURES_CHILD], capture_output=True, text=True, env=env,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_damaged_data_file_costs_no_healthy_signature_of_the_same_function(tmp_path):
    """The guard sets a damaged cache aside by deleting the whole index (``_set_aside``), even when only
    one signature's data file is damaged and the index itself reads fine.  The version compiled again
    is then saved under a fresh index as data file 1 -- overwriting the healthy data file of another
    signature -- so the next process, with no warning, misses that healthy signature and compiles it
    again (seconds per generated kernel on a cold compile; the package's ``_linalg._combine3`` has two
    signatures).  Reproduced with a cached_njit function called with int64 and float64: empty the
    float64 data file (``.2.nbc``); the damaged run warns and compiles float64 (right), and the next
    process reports a cache miss for int64, whose file the previous run overwrote with float64's code
    (a process reading the old index at that moment would load one signature's machine code for
    another).  Expected: only the damaged entry is set aside; the next process hits both signatures."""
    (tmp_path / "module").mkdir()
    (tmp_path / "module" / "rx_two_signatures.py").write_text(_TWO_SIGNATURES_MODULE)
    cold = _two_signatures_child(tmp_path)
    assert cold["values"] == [6, 3.0] and cold["warnings"] == []
    warm = _two_signatures_child(tmp_path)
    assert warm["misses"] == [] and warm["warnings"] == []
    data = sorted((tmp_path / "numba").rglob("rx_two_signatures.twice-*.nbc"))
    assert [f.name.split(".")[-2] for f in data] == ["1", "2"], data
    data[1].write_bytes(b"")                             # the second signature compiled (float64)
    damaged = _two_signatures_child(tmp_path)
    assert damaged["values"] == [6, 3.0]
    assert damaged["misses"] == ["(float64,)"]
    assert any("twice" in w for w in damaged["warnings"]), damaged["warnings"]
    after = _two_signatures_child(tmp_path)
    assert after["warnings"] == []
    assert after["misses"] == [], "a healthy signature was compiled again after the damaged one was repaired"
