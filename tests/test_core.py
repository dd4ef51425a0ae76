"""The compiled core (hammerstein_ctrl._core): its Python doors, built at install time, and what it never does at run
time (compile, cache, write, import numba)."""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hammerstein_ctrl import _core
from hammerstein_ctrl import _kernels as kernels

SOURCES = Path(__file__).resolve().parents[1] / "hammerstein_ctrl" / "_csrc"


def _generator():
    """The build-time generator of the wrappers (not installed: read from the source tree)."""
    spec = importlib.util.spec_from_file_location("generate_wrappers", SOURCES / "generate_wrappers.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_library_function_of_the_header_has_its_checked_wrapper():
    """The wrappers are generated from hc.h's prototypes when the core is built: every function declared there for
    Python is in the module, with the argument kinds the prototype says (a const pointer read, a plain one written, a
    size never below zero, hc_signed any integer); a C type the generator does not know stops the build by name."""
    gen = _generator()
    found = gen.prototypes((SOURCES / "hc.h").read_text())
    assert found["hc_tf_discrete"] == ("ddiiiffDDDBB", "b")
    assert found["hc_fill_coefficients"] == ("diididililiDD", "")
    assert found["hc_lagged_sums"] == ("ddiIID", "")
    assert found["hc_kernel_number"] == ("iiii", "q")
    assert all(callable(getattr(_core, name)) for name in found)
    assert not set(gen.UNWRAPPED) & set(dir(_core))
    with pytest.raises(SystemExit, match="hc_g takes or gives C types the wrappers do not know: \\['char \\*'\\]"):
        gen.prototypes("void hc_g(char *x, int64_t n);")


def test_a_wrapper_refuses_arrays_the_c_function_cannot_take():
    """Every array is checked in C before the call: C order, element type, and writeable where written."""
    out = np.empty((2, 2))
    _core.hc_expm(np.eye(2), 2, out)
    np.testing.assert_allclose(out, np.e * np.eye(2), rtol=1e-15)
    with pytest.raises(TypeError, match="hc_expm: argument 0 must be a C-ordered array"):
        _core.hc_expm(np.eye(4)[::2, ::2], 2, out)
    with pytest.raises(TypeError, match="hc_expm: argument 0 has items of format 'f'"):
        _core.hc_expm(np.eye(2, dtype=np.float32), 2, out)
    frozen = np.empty((2, 2))
    frozen.flags.writeable = False
    with pytest.raises(TypeError, match="hc_expm: argument 2 must be a C-ordered, writeable array"):
        _core.hc_expm(np.eye(2), 2, frozen)
    with pytest.raises(TypeError, match="hc_expm takes 3 arguments, not 2"):
        _core.hc_expm(np.eye(2), 2)
    with pytest.raises(ValueError, match="hc_expm: argument 1 must be a size \\(>= 0\\), not -1"):
        _core.hc_expm(np.empty(0), -1, np.empty(0))
    lags = np.empty(3)
    _core.hc_lagged_sums(np.arange(4.0), np.arange(4.0), 4, -1, 1, lags)       # a negative lag is an integer
    assert lags[1] == 5.0                       # sum of (t - 1.5)^2
    out = np.full((1, 5), np.nan)
    _core.hc_combine(np.empty((1, 0)), 1, 0, np.empty((0, 5)), 5, out, 5, 0)  # no basis rows: the empty sum
    assert out.tolist() == [[0.0] * 5]
    with pytest.raises(TypeError, match="hc_tf_discrete: argument 10 has items of format 'd'"):
        _core.hc_tf_discrete(np.ones((1, 1)), np.ones((1, 2)), 1, 1, 2, 0.1, 64.0, np.empty((1, 3, 3)),
                             np.empty((1, 1)), np.empty(1), np.empty(1), np.empty(1, dtype=bool))


def test_the_kernel_door_takes_only_numbers_of_the_table():
    """call runs a kernel by its number in the core's table: a number out of the table, or of a kernel the core does
    not build, is a ValueError, never a jump to an arbitrary address."""
    number = kernels.get_kernel(1, "outputs", "zoh").number
    assert _core.hc_kernel_number(_core.SINGLE, 1, 1, 0) == number
    with pytest.raises(ValueError, match="call: no kernel number -1"):
        _core.call(-1, "k|", np.zeros(1))
    with pytest.raises(ValueError, match="call: no kernel number 1000000"):
        _core.call(10 ** 6, "k|")
    assert _core.hc_kernel_number(_core.SINGLE, 9, 0, 2) == -1                 # a basis at order 9: not built
    with pytest.raises(ValueError, match="no kernel number"):
        _core.call(_core.hc_kernel_number(_core.SINGLE, 9, 0, 2) + 0, "k|")
    assert _core.hc_kernel_number(_core.NORMAL, _core.MAX_ORDER + 1, 0, 0) == -1
    with pytest.raises(ValueError, match="the compiled core has no kernel"):
        kernels.Kernel(-1, "k|", ())
    with pytest.raises(TypeError, match="call takes a kernel number, a description and at most 16 arguments"):
        _core.call(number)


def test_the_constants_of_the_core_are_the_packages():
    """The core's limits and map codes are the package's: one definition each."""
    from hammerstein_ctrl._checks import MAX_ORDER
    from hammerstein_ctrl.blocks import NONLINEARITIES

    assert _core.MAX_ORDER == MAX_ORDER
    assert set(kernels.MAP_CODES) == set(NONLINEARITIES)
    assert sorted(kernels.MAP_CODES.values()) == list(range(len(NONLINEARITIES)))
    assert [family.name for family in NONLINEARITIES.values()] == list(NONLINEARITIES)


def _run(code: str, **env) -> str:
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env={**os.environ, **env})
    return done.stdout.strip()


@pytest.mark.skipif(sys.platform == "win32", reason="a read-only folder, $HOME and an empty $PATH are POSIX's")
def test_a_first_fit_compiles_caches_and_writes_nothing_and_needs_no_numba(tmp_path):
    """A fresh process identifies a Hammerstein and a Wiener structure with no compiler to find ($CC and $PATH
    pointing nowhere), no cache folder it could write ($HOME, $XDG_CACHE_HOME in an empty folder) and a read-only
    working folder: nothing is written anywhere, and numba is never imported.  (matplotlib, which python-control
    imports, keeps its font cache in $MPLCONFIGDIR, given a folder of its own here.)"""
    home = tmp_path / "home"
    home.mkdir()
    work = tmp_path / "work"
    work.mkdir()
    code = ("import sys, numpy as np, hammerstein_ctrl as hc\n"
            "t = np.arange(600) * 0.05; u = np.sin(t) + 0.5 * np.sin(2.7 * t)\n"
            "from hammerstein_ctrl.simulate import simulate\n"
            "y = simulate(([1.0], [1.0, 1.0]), hc.Tanh(), [1.0, 2.0], t, u)\n"
            "data = hc.IOData(u, y, dt=0.05)\n"
            "r1 = hc.identify(data, hc.HammersteinStructure(hc.LinearStructure(0, 1), hc.Tanh()), seed=0)\n"
            "r2 = hc.identify(data, hc.WienerStructure(hc.LinearStructure(0, 1), hc.Polynomial(3)), seed=0)\n"
            "print(r1.fun < 1e-12, r2.nfev > 0, 'numba' in sys.modules, 'llvmlite' in sys.modules)\n")
    os.chmod(work, 0o555)
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=work,
                             env={**os.environ, "HOME": str(home), "XDG_CACHE_HOME": str(home / "cache"),
                                  "CC": "/nonexistent/cc", "PATH": "/nonexistent", "PYTHONDONTWRITEBYTECODE": "1",
                                  "MPLCONFIGDIR": str(tmp_path / "matplotlib")})
    finally:
        os.chmod(work, 0o755)
    assert out.stdout.split() == ["True", "True", "False", "False"], out.stderr
    assert list(home.rglob("*")) == [] and list(work.iterdir()) == []


def test_the_baseline_and_the_wide_vector_kernels_give_the_same_bits():
    """The vector kernels are built for the platform's baseline and, on x86-64, for AVX2 too; this processor runs the
    widest, and $HAMMERSTEIN_CTRL_VECTOR_ISA=baseline keeps the baseline's.  Batches and normal-equation passes of
    several orders (written out per lane up to order 4, loops over the order above) give the same bits in both."""
    code = ("import numpy as np\nfrom hammerstein_ctrl import _kernels as kernels\n"
            "from hammerstein_ctrl.simulate._simulate import sse_basis_batch, normal_pass\n"
            "rng = np.random.default_rng(3); out = [kernels.vector_isa()]\n"
            "for n in (1, 2, 4, 6):\n"
            "    den = np.column_stack([np.ones(11), rng.uniform(0.5, 3.0, (11, n))])\n"
            "    num = rng.standard_normal((11, 1)); basis = rng.standard_normal((3, 700))\n"
            "    P, y = rng.standard_normal((11, 3)), rng.standard_normal(700)\n"
            "    out += sse_basis_batch(num, den, P, basis, 0.05, y, offset=rng.standard_normal(11)).tolist()\n"
            "    blocks = [basis[:, :300], basis[:, 300:]]\n"
            "    ne = normal_pass(num[:1], den[:1], 0.05, y, P[:6], blocks, np.full(5, 1e-3))\n"
            "    out += [ne.fun] + ne.gradient.tolist() + ne.gram.ravel().tolist()\n"
            "print(out[0], np.array(out[1:]).tobytes().hex())\n")
    wide = _run(code).split()
    base = _run(code, HAMMERSTEIN_CTRL_VECTOR_ISA="baseline").split()
    assert base[0] == "baseline"
    assert wide[1] == base[1]
    if wide[0] == "baseline":
        pytest.skip("this processor runs the baseline's vector kernels only")
