"""A damaged numba cache file is compiled again (with a CacheWarning), never an error from every call.

A write cut short (a killed process, a full disk) leaves cache files that no
longer unpickle; numba itself then raised ``EOFError`` / ``UnpicklingError``
from every call in every process until the folder was deleted by hand.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hammerstein_ctrl import kernels

REPO = Path(__file__).resolve().parents[1]

CHILD = """
import json, warnings
import numpy as np
from hammerstein_ctrl import CacheWarning, kernels
from hammerstein_ctrl.residual_analysis import _lagged_sums
from hammerstein_ctrl.simulate import simulate_batch
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    u = np.sin(np.linspace(0.0, 6.0, 200))[None, :]
    y = simulate_batch([[0.0, 1.0]], [[1.0, 0.7, 2.0]], u, 0.03)
    h = _lagged_sums(np.array([1.0, -2.0, 0.5]), np.array([0.5, 1.0, -1.0]), -1, 1)  # the package's own
    E = np.array([[[0.9, 0.05, 0.01, 0.003], [-0.1, 0.95, 0.02, 0.001]]])
    w = np.empty((1, 50))                 # a kernel whose output map C does not take: generated and compiled by numba
    kernels.get_kernel(2, "outputs", "foh", "piecewise_linear_map")(
        E, np.ones((1, 2)), np.zeros(1), np.zeros((1, 2)), np.zeros(1), u[:, :50].copy(), np.array([[-1.0, 0.0, 2.0]]),
        np.array([-1.0, 0.0, 1.0]), w)
print(json.dumps({"y": y[0, ::40].tolist() + h.tolist() + w[0, ::10].tolist(),
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


@pytest.mark.slow
def test_damaged_cache_files_are_compiled_again_with_a_warning(tmp_path):
    first = _run(tmp_path)
    assert first["warnings"] == []
    files = sorted(tmp_path.rglob("*.nb[ic]"))           # the package's own in the machine cache, kernels' in numba's
    kernel_data = [f for f in files if f.name.startswith("hc_") and f.suffix == ".nbc"]
    package_index = [f for f in files if "residual_analysis" in f.name and f.suffix == ".nbi"]
    assert kernel_data and package_index, [f.name for f in files]
    for f in kernel_data + package_index:        # a generated kernel's data and the package's own index files
        _cut_short(f)

    damaged = _run(tmp_path)
    assert damaged["y"] == first["y"]
    assert damaged["warnings"], "no CacheWarning for the damaged files"
    assert any("hc_" in w for w in damaged["warnings"]) and any("residual_analysis" in w for w in damaged["warnings"])
    assert all("compiled again" in w for w in damaged["warnings"])

    again = _run(tmp_path)                       # the cache was saved afresh and reads back
    assert again == first


def test_a_generated_kernel_source_that_is_not_utf8_is_written_again(tmp_path):
    """A generated kernel module in $HAMMERSTEIN_CTRL_CACHE damaged into bytes that are not UTF-8 (a
    disk error, a bad copy) makes kernels._write_once raise UnicodeDecodeError (``path.read_text()``
    catches only what it compares), so every call that needs that kernel fails, in every process,
    until someone deletes the file -- what must never happen for a damaged cache
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
limit = int(os.environ.get("TEST_FILE_SIZE_LIMIT", "0"))
if limit:                                   # a full disk: every write past `limit` bytes fails (EFBIG)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
out = {"error": None, "h": None}
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    try:
        from hammerstein_ctrl import CacheWarning
        from hammerstein_ctrl.residual_analysis import _lagged_sums
        sums = _lagged_sums(np.array([1.0, -2.0, 0.0, 3e5]), np.array([2.0, 1.0, -1.0, 0.5]), -1, 1)
        out["h"] = [float(v).hex() for v in sums]
    except Exception as exc:
        out["error"] = f"{type(exc).__name__}: {exc}"
    out["warnings"] = [str(w.message) for w in caught if w.category.__name__ == "CacheWarning"]
print(json.dumps(out))
"""


def _full_disk_child(tmp_path, limit=0):
    env = {**os.environ, "PYTHONPATH": str(REPO), "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "kernels"),
           "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONDONTWRITEBYTECODE": "1",
           "TEST_FILE_SIZE_LIMIT": str(limit)}
    proc = subprocess.run([sys.executable, "-c", _FULL_DISK_CHILD], capture_output=True, text=True, env=env,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_a_damaged_cache_compiled_again_on_a_full_disk_does_not_raise(tmp_path):
    """The cache guard wrapped only numba's load: the version compiled again is then saved by
    numba's ``save_overload``, which raises OSError when the write fails -- the full disk (or a cache
    directory that turned read-only) the README names as the cause of the damage.  Reproduced: a
    damaged (emptied) data file of ``residual_analysis._lagged_sums``, then a process whose writes
    past 64 bytes fail (RLIMIT_FSIZE, as a full disk): the CacheWarning is given and then
    the call raised ``OSError: [Errno 27] File too large`` from numba's caching.py to the user
    (measured the same with the generated simulation kernel).  The compiled function works in
    memory; failing to save it must not fail the call (a CacheWarning, as for a failed load)."""
    healthy = _full_disk_child(tmp_path)
    assert healthy["error"] is None and healthy["warnings"] == []
    data = sorted(tmp_path.rglob("residual_analysis._lagged_sums-*.nbc"))
    assert data, sorted(p.name for p in tmp_path.rglob("*"))
    for f in data:
        f.write_bytes(b"")
    full = _full_disk_child(tmp_path, limit=64)
    assert full["error"] is None, full
    assert full["h"] == healthy["h"]
    assert any("_lagged_sums" in w for w in full["warnings"]), full["warnings"]
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
    from two_signatures_module import twice
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
    again (seconds per generated kernel on a cold compile; a function of the package with two
    signatures).  Reproduced with a cached_njit function called with int64 and float64: empty the
    float64 data file (``.2.nbc``); the damaged run warns and compiles float64 (right), and the next
    process reports a cache miss for int64, whose file the previous run overwrote with float64's code
    (a process reading the old index at that moment would load one signature's machine code for
    another).  Expected: only the damaged entry is set aside; the next process hits both signatures."""
    (tmp_path / "module").mkdir()
    (tmp_path / "module" / "two_signatures_module.py").write_text(_TWO_SIGNATURES_MODULE)
    cold = _two_signatures_child(tmp_path)
    assert cold["values"] == [6, 3.0] and cold["warnings"] == []
    warm = _two_signatures_child(tmp_path)
    assert warm["misses"] == [] and warm["warnings"] == []
    data = sorted((tmp_path / "numba").rglob("two_signatures_module.twice-*.nbc"))
    assert [f.name.split(".")[-2] for f in data] == ["1", "2"], data
    data[1].write_bytes(b"")                             # the second signature compiled (float64)
    damaged = _two_signatures_child(tmp_path)
    assert damaged["values"] == [6, 3.0]
    assert damaged["misses"] == ["(float64,)"]
    assert any("twice" in w for w in damaged["warnings"]), damaged["warnings"]
    after = _two_signatures_child(tmp_path)
    assert after["warnings"] == []
    assert after["misses"] == [], "a healthy signature was compiled again after the damaged one was repaired"


_MACHINE_CHILD = """
import json, sys
from hammerstein_ctrl.residual_analysis import _lagged_sums
import numpy as np
_lagged_sums(np.array([1.0, 2.0]), np.array([2.0, 1.0]), 0, 1)
from numba.core.caching import CacheImpl
print(json.dumps({"file": __import__("hammerstein_ctrl").__file__}))
"""


def test_the_compiled_code_is_kept_once_per_machine_and_shared_by_copies_of_the_package(tmp_path):
    """numba's cache of the package's functions lives under $HAMMERSTEIN_CTRL_CACHE keyed on file content:
    a second copy of the package (another clone, another virtual environment) reuses it; an edited file
    gets its own."""
    copy = tmp_path / "copy"
    shutil.copytree(REPO / "hammerstein_ctrl", copy / "hammerstein_ctrl",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "cache"), "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("NUMBA_CACHE_DIR", None)
    for root in (REPO, copy):
        proc = subprocess.run([sys.executable, "-c", _MACHINE_CHILD], capture_output=True, text=True,
                              env={**env, "PYTHONPATH": str(root)}, timeout=600, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert json.loads(proc.stdout.splitlines()[-1])["file"].startswith(str(root))
    index = sorted((tmp_path / "cache").rglob("residual_analysis._lagged_sums-*.nbi"))
    assert len(index) == 1 and "numba-" in str(index[0])                  # one copy for both
    assert not list((copy / "hammerstein_ctrl").rglob("*.nbi"))            # nothing beside the sources
    (copy / "hammerstein_ctrl" / "residual_analysis.py").write_text(
        (copy / "hammerstein_ctrl" / "residual_analysis.py").read_text() + "\n# edited\n")
    proc = subprocess.run([sys.executable, "-c", _MACHINE_CHILD], capture_output=True, text=True,
                          env={**env, "PYTHONPATH": str(copy)}, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(sorted((tmp_path / "cache").rglob("residual_analysis._lagged_sums-*.nbi"))) == 2


def test_an_address_is_refused_to_callers_that_would_misread_its_result():
    """function_address checks the return type its callers read: a float function asked for as a boolean
    one raises instead of handing compiled code an address whose result it would misinterpret."""
    import numba

    from hammerstein_ctrl._jit import cached_njit, function_address, kernel_signature

    @cached_njit(cache=False)
    def half(x):
        return 0.5 * x
    assert function_address(half, kernel_signature("f"), numba.types.float64) > 0
    with pytest.raises(TypeError, match="half returns float64, not the bool"):
        function_address(half, kernel_signature("f"), numba.types.boolean)


_HASHING_MODULE = """
import numpy as np

from hammerstein_ctrl._jit import cached_njit


@cached_njit()
def text_hash(n):
    return hash("friction" * n)


@cached_njit()
def plain(x):
    return np.full(2, 2.0 * x)          # allocates: needs numba's runtime started before the load
"""

_LOAD_CHILD = """
import json, sys
import numba.core.base
import llvmlite.binding
import hammerstein_ctrl._cache_load as fast
seen, refreshed, parsed = [], [], []
needs = fast.needs_registries
fast.needs_registries = lambda data: seen.append(needs(data)) or seen[-1]
refresh = numba.core.base.BaseContext.refresh
numba.core.base.BaseContext.refresh = lambda self: refreshed.append(1) or refresh(self)
parse = llvmlite.binding.parse_bitcode
llvmlite.binding.parse_bitcode = lambda bitcode: parsed.append(1) or parse(bitcode)
import cachedmod
value = cachedmod.plain(1.5).tolist()
compiler_loaded = len(refreshed)
numpy_registry_loaded = "numba.np.arrayobj" in sys.modules
bitcode_parsed = len(parsed)
text = cachedmod.text_hash(2)
linked = numba.njit(lambda x: cachedmod.plain(x).sum())(2.5)      # a new compile links plain's cached library
parsed_to_link = len(parsed) - bitcode_parsed
print(json.dumps({"plain": value, "compiler_loaded_for_plain": compiler_loaded, "seen": seen,
                  "numpy_registry_loaded_for_plain": numpy_registry_loaded, "bitcode_parsed_for_plain": bitcode_parsed,
                  "linked": linked, "parsed_to_link": parsed_to_link,
                  "hash_ok": text == hash("friction" * 2),
                  "hits": [cachedmod.plain.stats.cache_hits.get(s, 0) for s in cachedmod.plain.signatures]
                          + [cachedmod.text_hash.stats.cache_hits.get(s, 0) for s in cachedmod.text_hash.signatures]}))
"""


def test_cached_code_runs_without_loading_numbas_compiler_unless_it_needs_its_symbols(tmp_path):
    """A fresh process loads cached machine code, one that allocates an array among it, without importing
    numba's compiler registries (about 200 modules, half a second) or parsing its bitcode until a compile
    links it; code that refers to a symbol the registries provide (a string hash uses the interpreter's hash
    secret) is loaded after them, and gives the interpreter's own hash."""
    (tmp_path / "cachedmod.py").write_text(_HASHING_MODULE)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(REPO)]), "PYTHONHASHSEED": "7"}

    def run():
        proc = subprocess.run([sys.executable, "-c", _LOAD_CHILD], capture_output=True, text=True, env=env,
                              timeout=600, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return json.loads(proc.stdout.splitlines()[-1])

    first = run()                                      # compiles and saves both
    assert first["hash_ok"] and first["hits"] == [0, 0]
    second = run()
    assert second["hits"] == [1, 1]                    # both loaded from the cache
    assert second["plain"] == [3.0, 3.0] and not second["compiler_loaded_for_plain"]
    # np.full's compiled code keeps an environment named after numba's array module: rebuilt without importing it
    assert first["numpy_registry_loaded_for_plain"] and not second["numpy_registry_loaded_for_plain"]
    # the library's bitcode is parsed only when a compile links it (then it is, and the new function runs)
    assert not second["bitcode_parsed_for_plain"] and second["parsed_to_link"] >= 1
    assert first["linked"] == second["linked"] == 10.0
    # the string hash refers to the hash secret: loaded after the registries (the load would import the module
    # that adds the secret anyway, so this is the check itself, not a crash avoided)
    assert second["seen"] == [False, True] and second["hash_ok"]


def test_a_cache_layout_the_fast_load_does_not_know_is_loaded_by_numba_itself():
    """The load without numba's registries reads parts of numba's cache object; where one is missing (another
    numba version), numba's own load is used instead of every load failing and compiling again.  This checks
    the test that chooses between them, on numba's cache and on one without a part."""
    from hammerstein_ctrl._cache_load import fast_load_possible
    from hammerstein_ctrl._jit import cached_njit

    @cached_njit()
    def triple(x):
        return 3.0 * x
    assert fast_load_possible(triple._cache)
    cache = triple._cache
    missing = type("Cache", (), {"_impl": cache._impl,            # every part but numba's _load_overload
                                 "_guard_against_spurious_io_errors": cache._guard_against_spurious_io_errors})()
    assert not fast_load_possible(missing)


_SYMBOLS_CHILD = """
import json
import llvmlite.binding as ll
from numba.core.registry import cpu_target
from numba.core.runtime import rtsys
added = []
real = ll.add_symbol
ll.add_symbol = lambda name, address: added.append(name) or real(name, address)
context = cpu_target.target_context
rtsys.initialize(context)
started = len(added)
context.refresh()
print(json.dumps(added[started:]))
"""


def test_numbas_compiler_adds_no_symbol_that_cached_code_is_not_checked_for():
    """Loading numba's compiler (its registries) adds symbols to the loader's table; cached code is loaded
    before that unless it refers to one of _cache_load.LATE_SYMBOLS.  Every symbol the registries add must be one
    of those, or a load could meet a symbol it cannot resolve (a new numba version fails here first)."""
    from hammerstein_ctrl._cache_load import LATE_SYMBOLS

    proc = subprocess.run([sys.executable, "-c", _SYMBOLS_CHILD], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    added = json.loads(proc.stdout.splitlines()[-1])
    assert added                                       # the control: the registries do add symbols
    assert all(name.encode().startswith(LATE_SYMBOLS) for name in added), added


def _compiled_library(function, *args):
    """``(library, object code, bitcode)`` of ``function`` compiled afresh for ``args`` (every nopython compile keeps
    its object code until the library is loaded)."""
    function(*args)
    library = function.overloads[function.signatures[0]].library
    _, kind, (code, bitcode) = library.serialize_using_object_code()
    assert kind == "object"
    return library, code, bitcode


def test_the_symbols_read_from_the_object_code_are_those_numba_lists_from_the_bitcode():
    """A cached library's defined symbols are read from its object code's symbol table instead of its parsed
    bitcode (7 ms a library): the names numba lists from the bitcode, but for private definitions (a switch's
    lookup table), which have no symbol and which numba never looks up; for a function that links numba's array
    code and has a switch."""
    import types

    import llvmlite.binding
    import numba.core.codegen
    import numpy as np

    from hammerstein_ctrl._cache_load import defined_symbols
    from hammerstein_ctrl._jit import cached_njit

    @cached_njit(cache=False)
    def spread(x, k):
        scale = 1.5 if k == 0 else 2.5 if k == 1 else 3.5 if k == 2 else 4.5 if k == 3 else 5.5
        return np.full(3, x).sum() * scale + np.exp(x)
    _, code, bitcode = _compiled_library(spread, 1.0, 2)
    module = llvmlite.binding.parse_bitcode(bitcode)
    engine = types.SimpleNamespace(_defined_symbols=set())
    numba.core.codegen.JitEngine._load_defined_symbols(engine, module)         # numba's own listing
    private = {g.name for group in (module.functions, module.global_variables) for g in group
               if not g.is_declaration and g.linkage == llvmlite.binding.Linkage.private}
    assert len(engine._defined_symbols) > 3 and private                         # the control: a private table
    assert defined_symbols(code) == engine._defined_symbols - private


def test_a_cached_library_the_fast_load_cannot_read_is_loaded_by_numba_itself():
    """numba's own load takes a library without the symbols it will look up, with damaged bitcode, in another
    object format or another cached form; an ELF file without a symbol table lists none (not an empty set)."""
    import numba

    from hammerstein_ctrl._cache_load import _unserialize, defined_symbols
    from hammerstein_ctrl._jit import cached_njit

    @cached_njit(cache=False)
    def quarter(x):
        return 0.25 * x
    library, code, bitcode = _compiled_library(quarter, 2.0)
    codegen = numba.core.registry.cpu_target.target_context.codegen()
    fndesc = quarter.overloads[quarter.signatures[0]].fndesc
    entry = (fndesc.llvm_func_name, fndesc.llvm_cpython_wrapper_name)
    assert set(entry) <= defined_symbols(code)

    def numbas(state):
        return "numba's own load"
    for state, points in [(("q", "object", (code, bitcode)), ("no_such_symbol",)),          # a symbol missing
                          (("q", "object", (code, b"damaged" + bitcode)), entry),            # no bitcode magic
                          (("q", "object", (b"\xcf\xfa\xed\xfe" + code[4:], bitcode)), entry),  # not ELF
                          (("q", "bitcode", bitcode), entry), (("q", "object", code), entry)]:
        assert _unserialize(codegen, numbas, points, None, state) == "numba's own load"
    header = bytearray(code[:64])
    header[0x3C:0x3E] = (0).to_bytes(2, "little")                              # no section headers at all
    assert defined_symbols(bytes(header)) is None


def test_environments_of_numba_modules_not_imported_get_a_stand_in_that_pickles_as_numbas(monkeypatch):
    """While cached code loads, an environment named after a numba module not imported yet gets its name alone
    for globals; one named after a module whose import adds symbols (the hash secret) is rebuilt by numba, as
    is any with another numba's arguments.  The swapped rebuild keeps numba's name: an environment pickled
    meanwhile loads with numba's own.  A rebuild numba no longer has as a plain function is not swapped."""
    import functools
    import pickle

    import numba.core.environment as environment

    from hammerstein_ctrl._cache_load import _environments_without_imports, _rebuild_env

    def numbas(*args):
        return "numba's own rebuild"
    monkeypatch.delitem(sys.modules, "numba.cpython.hashing", raising=False)   # as in a fresh process
    stand_in = _rebuild_env(numbas, "numba.no_such_module", [1.5], "hc_test_env_stand_in")
    assert stand_in.globals == {"__name__": "numba.no_such_module"} and list(stand_in.consts) == [1.5]
    assert _rebuild_env(numbas, "numba.cpython.hashing", [], "hc_test_env_hashing") == "numba's own rebuild"
    assert _rebuild_env(numbas, "mypackage.module", [], "hc_test_env_other") == "numba's own rebuild"
    assert _rebuild_env(numbas, "numba.no_such_module", [], "hc_test_env_four", "more") == "numba's own rebuild"
    original = environment._rebuild_env
    with _environments_without_imports():
        assert environment._rebuild_env is not original
        data = pickle.dumps(stand_in)
    assert environment._rebuild_env is original
    assert pickle.loads(data) is stand_in                       # numba's rebuild finds it among the living ones
    other = functools.partial(original)
    monkeypatch.setattr(environment, "_rebuild_env", other)
    with _environments_without_imports():
        assert environment._rebuild_env is other


def test_cached_bitcode_that_cannot_be_linked_fails_once_and_drops_its_folders_index(tmp_path):
    """Bitcode damaged past the first bytes the load checks fails the compile that links it, naming the library
    and its folder, whose index files are removed so that the next process compiles afresh."""
    import types

    from hammerstein_ctrl._cache_load import _module_for_linking

    (tmp_path / "f-1.py39.nbi").write_bytes(b"index")
    (tmp_path / "f-1.py39.1.nbc").write_bytes(b"data")
    library = types.SimpleNamespace(_shared_module=None, name="cached_function")
    with pytest.raises(RuntimeError, match=f"cached_function in {tmp_path} cannot be linked"):
        _module_for_linking(library, b"BC\xc0\xde" + b"damaged", tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f-1.py39.1.nbc"]


_MAP_ORDER_CHILD = r"""
import hashlib, sys
import numpy as np
from hammerstein_ctrl import kernels
lanes, N = 7, 400                                   # the shape of the EMPS Wiener fit's pass
rng = np.random.default_rng(0)
E = np.zeros((lanes, 2, 4))
E[:, :, :2], E[:, :, 2:] = [[0.9, 0.05], [-0.1, 0.95]], [[0.01, 0.003], [0.02, 0.001]]
E += 1e-3 * rng.normal(size=E.shape)
C, D, X, Y0, VP = rng.normal(size=(lanes, 2)), np.zeros(lanes), np.zeros((lanes, 2)), np.zeros(lanes), np.zeros(lanes)
P, Phi, y = np.ones((lanes, 1)), rng.normal(size=(1, N)), rng.normal(size=N)
HP, HX = np.abs(rng.normal(size=(lanes, 3))), np.zeros(0)
if sys.argv[1] == "scalar kernel first":           # compiles the map as the callee of a kernel without fastmath
    kernels.get_kernel(2, "outputs", "foh", "coulomb_map")
acc = np.zeros(1 + (lanes - 1) * lanes)
kernels.get_normal_kernel(2, "foh", lanes, 1, False, False, "coulomb_map")(E, C, D, X, Y0, VP, P, Phi, HP, HX, y,
                                                                             0, acc)
print(hashlib.sha256(acc.tobytes()).hexdigest())
"""


def test_a_passs_bits_do_not_depend_on_which_kernel_compiled_its_output_map_first(tmp_path):
    """The summing pass and the scalar kernel both call a compiled output map (the pass with contracting
    multiply-adds when this was found).
    numba compiles a callee with its first caller's floating-point flags and then serves that one version (and
    its cached copy) to every caller, so the pass's bits depended on which kernel the machine had compiled first;
    the kernels inline the maps instead, so every kernel's map follows the kernel's own flags."""
    digests = []
    for order in ("scalar kernel first", "pass alone"):
        env = {**os.environ, "PYTHONPATH": str(REPO), "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / order.replace(" ", "-"))}
        proc = subprocess.run([sys.executable, "-c", _MAP_ORDER_CHILD, order], capture_output=True, text=True,
                              env=env, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        digests.append(proc.stdout.strip())
    assert digests[0] == digests[1]
