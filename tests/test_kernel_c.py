"""Generated kernels built in C (hammerstein_ctrl._kernel_c, kernels.CKernel): numba's bits from the same source,
the arrays they take checked at the door, and their machine code built once per machine."""

import os
import subprocess
import sys

import numpy as np
import pytest

from hammerstein_ctrl import _native, kernels
from hammerstein_ctrl._kernel_c import translate
from hammerstein_ctrl._kernel_source import kernel_source, lane_source, normal_source, vector_normal_source


def _numba_kernel(src: str, name: str):
    """numba's compile of the same generated source (in memory): the oracle the C build must match bit for bit."""
    return kernels._load_source(src.replace("cached_njit(", "cached_njit(cache=False, "), name + "_numba_oracle")


def _array(rng, *shape, scale=1.0):
    """Random entries, one in ten arrays holding one of NaN, an infinity, a huge, a signed zero or a subnormal."""
    a = rng.normal(size=shape) * scale
    if a.size and rng.random() < 0.1:
        a.flat[rng.integers(a.size)] = rng.choice([np.nan, np.inf, -np.inf, 1e300, 0.0, -0.0, 5e-324])
    return a


def _same_bits(a, b) -> bool:
    """Every entry the same bits (signed zeros told apart), or NaN in both (a NaN's payload depends on the order of
    a sum's operands, which a compiler may swap: IEEE addition and multiplication commute)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and bool(np.all((a.view(np.int64) == b.view(np.int64)) | (np.isnan(a) & np.isnan(b))))


@pytest.mark.parametrize("n, mode, hold, K", [(1, "sse", "zoh", None), (3, "outputs", "foh", None),
                                              (2, "sse", "foh", 3), (8, "outputs", "zoh", 2)])
def test_a_recursion_kernel_gives_numbas_bits_for_its_source(n, mode, hold, K):
    """The C build of a scalar recursion kernel against numba's compile of the same source: every output and sum of
    squares (overflowed ones inf) the same bits, over 60 random batches with non-finite and extreme entries."""
    src, name = kernel_source(n, mode, hold, None, K), kernels._module_name(n, mode, hold, None, K)
    c_kernel, oracle = kernels.get_kernel(n, mode, hold, None, K), _numba_kernel(src, name)
    rng = np.random.default_rng(n * 10 + (K or 0))
    for _ in range(60):
        B, N = int(rng.integers(1, 6)), int(rng.integers(1, 2500))
        args = [_array(rng, B, n + 2, n + 2, scale=0.4 / n), _array(rng, B, n), _array(rng, B), _array(rng, B, n),
                _array(rng, B)]
        args += [_array(rng, B, N)] if K is None else [_array(rng, B, K), _array(rng, K, N)]
        args += [_array(rng, N)] if mode == "sse" else []
        shape = (B,) if mode == "sse" else (B, N)
        got, expected = np.full(shape, 7.0), np.full(shape, -7.0)
        c_kernel(*args, got)
        oracle(*args, expected)
        assert _same_bits(got, expected)


@pytest.mark.parametrize("family, n, hold, lanes, K, direct, offset", [
    ("lanes", 2, "foh", None, 3, False, False), ("lanes", 3, "zoh", None, 1, True, True),
    ("vector", 2, "foh", 4, 3, False, False), ("vector", 4, "zoh", 11, 2, True, True),
    ("array", 6, "foh", 7, 2, True, False), ("outputs", 5, "zoh", 9, 1, False, True)])
def test_a_lanes_kernel_or_pass_gives_numbas_bits_for_its_source(family, n, hold, lanes, K, direct, offset):
    """SIMD lanes and normal-equation passes (vectors of four lanes, arrays of lanes, output blocks) against numba's
    compile of the same source: sums, states, previous signals and outputs the same bits, the record passed in two
    blocks at a random split, over 40 random cases each."""
    rng = np.random.default_rng(lanes or K)
    for case in range(40):
        if family == "lanes":
            B, N = int(rng.integers(1, 40)), int(rng.integers(1, 2000))
            src = lane_source(n, hold, K, direct, offset)
            kernel = kernels.get_lane_kernel(n, hold, K, direct, offset)
            args = [_array(rng, B, n + 2, n + 2, scale=0.4 / n), _array(rng, B, n),
                    _array(rng, B) if direct else np.zeros(B), _array(rng, B, n),
                    _array(rng, B) if offset else np.zeros(B), _array(rng, B, K), _array(rng, K, N), _array(rng, N)]
            if case == 0:
                oracle = _numba_kernel(src, f"lanes_{n}_{hold}_{K}_{direct}_{offset}")
            got, expected = np.empty(B), np.empty(B)
            kernel(*args, got)
            oracle(*args, expected)
            assert _same_bits(got, expected)
            continue
        outputs = family == "outputs"
        if family == "vector":
            src = vector_normal_source(n, hold, lanes, K, direct, offset)
        else:
            src = normal_source(n, hold, lanes, K, direct, offset, None, outputs)
        if case == 0:
            oracle = _numba_kernel(src, f"pass_{family}_{n}_{hold}_{lanes}_{K}_{direct}_{offset}")
        kernel = kernels.get_normal_kernel(n, hold, lanes, K, direct, offset, None, outputs)
        R, N = int(rng.integers(1, lanes + 1)), int(rng.integers(1, 1500))
        E, C, D = _array(rng, R, n + 2, n + 2, scale=0.4 / n), _array(rng, R, n), _array(rng, R)
        P, Phi, y, X, VP, Y0 = (_array(rng, lanes, K), _array(rng, K, N), _array(rng, N), _array(rng, lanes, n),
                                _array(rng, lanes), _array(rng, lanes))
        split = int(rng.integers(0, N + 1))
        results = []
        for k in (kernel, oracle):
            Xk, VPk = X.copy(), VP.copy()
            acc = np.zeros((N, lanes)) if outputs else np.zeros(1 + (lanes - 1) * lanes)
            for a, b in ((0, split), (split, N)):
                k(E, C, D, Xk, Y0, VPk, P, np.ascontiguousarray(Phi[:, a:b]), np.zeros((lanes, 0)), np.zeros(0),
                  y[a:b], a, acc[a:b] if outputs else acc)
            results.append((acc, Xk, VPk))
        assert all(_same_bits(a, b) for a, b in zip(*results))


def test_the_door_refuses_arrays_that_do_not_fit_with_the_arguments_name():
    """A kernel's arrays are checked against one another before it runs: a mismatched size, a missing sample, the
    wrong element type, a read-only output or a missing argument each raise naming the kernel and the argument."""
    k = kernels.get_kernel(2, "sse", "foh", None, 3)
    B, N = 3, 50
    args = [np.zeros((B, 4, 4)), np.zeros((B, 2)), np.zeros(B), np.zeros((B, 2)), np.zeros(B), np.zeros((B, 3)),
            np.zeros((3, N)), np.zeros(N), np.zeros(B)]
    k(*args)
    assert args[-1].tolist() == [0.0] * B

    def refused(index, value, error, match):
        given = list(args)
        given[index] = value
        with pytest.raises(error, match=match):
            k(*given)
    refused(3, np.zeros((B + 1, 2)), ValueError,
            r"hc_kernel_n2_sse_foh_k3: X0 has shape \(4, 2\), not \(B,2\+\); B = 3")
    refused(0, np.zeros((B, 3, 3)), ValueError, r"E has shape \(3, 3, 3\), not \(B,2\+,4\+\)")
    refused(6, np.zeros((3, 0)), ValueError, r"Phi has shape \(3, 0\)")              # no sample: nothing to read
    refused(7, np.zeros(N + 1), ValueError, "y has shape")
    refused(1, np.zeros((B, 2), dtype=np.float32), TypeError, "C must be a float64 array")
    refused(5, np.zeros((3, B)).T, TypeError, "P must be a C-ordered float64 array")
    frozen = np.zeros(B)
    frozen.flags.writeable = False
    refused(8, frozen, TypeError, "out must be a C-ordered, writeable float64 array")
    with pytest.raises(TypeError, match="takes 8 arguments, not 9|takes more than 8"):
        k(*args[:-1])


def test_a_pass_refuses_too_few_lanes_as_its_source_says():
    """A pass's own size checks (its source's ``raise``) reach Python as a ValueError with the source's message."""
    k = kernels.get_normal_kernel(2, "foh", 5, 3, False, False)
    with pytest.raises(ValueError, match="this pass takes 2 to 5 lanes"):
        k(np.zeros((1, 4, 4)), np.zeros((1, 2)), np.zeros(1), np.zeros((6, 2)), np.zeros(6), np.zeros(6),
          np.zeros((6, 3)), np.zeros((3, 10)), np.zeros((6, 0)), np.zeros(0), np.zeros(10), 0, np.zeros(31))


def test_the_translator_names_python_it_does_not_take():
    """Source outside the subset the generators write is refused by name, not translated wrongly."""
    head = '@cached_njit(signatures=(kernel_signature("r1 w1"),))\ndef kernel(x, out):\n'
    for body, what in (("    out[0] = np.sqrt(x[0])", "call np.sqrt"), ("    out[0] = x.shape[0] / 2", "operator"),
                       ("    for i in x:\n        out[0] = i", "loop x"), ("    out[0] = np.pi", "name np.pi"),
                       # where C would mean something else than Python
                       ("    a, b = 1, 2\n    a, b = b, a", "values read the targets"),
                       ("    out[0] = x[0] // 2.0", "operator"),
                       ("    out[0] = min(x[0], x[1])", "min of two integers"),
                       ("    n = 3\n    for i in range(n):\n        n = n - 1", "its body assigns"),
                       ("    out[0] = x[0] or 2.0", "not truth values"), ("    out[0] = x[-1]", "non-negative"),
                       ("    a = 1\n    b = a or 3\n    out[0] = x[b]", "not truth values"),
                       ("    m = 3\n    for i in range(m):\n        m, q = 0, 1", "its body assigns"),
                       ("    L = np.empty(4)\n    L = np.empty(8)", "made with shapes"),
                       ("    out[0] = x[0] if x[0] is x[1] else 0.0", "comparison")):
        with pytest.raises(NotImplementedError, match=what):
            translate(head + body)
    with pytest.raises(NotImplementedError, match="no output map given"):       # a map's call needs its formula
        translate(kernel_source(2, "sse", "foh", "tanh_map"))
    with pytest.raises(NotImplementedError, match="reads extra"):       # fixed data sized with the parameters
        translate(kernel_source(2, "sse", "foh", "piecewise_linear_map"),
                  "def formula(z, p, extra):\n    return p[0] * extra[0] * z\n")


def test_integer_floor_division_and_modulo_round_as_pythons():
    """C's ``/`` and ``%`` truncate towards zero; the translation rounds integer ``//`` and ``%`` by a positive
    literal as Python does, for dividends of either sign (a divisor that is not a positive literal is refused)."""
    src = ('@cached_njit(signatures=(kernel_signature("w1 i"),))\ndef kernel(out, a):\n'
           '    out[0] = a // 3\n    out[1] = a % 3\n    out[2] = (a - 7) // 4\n    out[3] = (a - 7) % 4\n')
    address = _native.kernel_address("hc_test_floor", translate(src).text)
    for a in (-8, -7, -1, 0, 1, 7, 8):
        out = np.empty(4)
        _native.library().call(address, "floor|out:w:4 a:i", out, a)
        assert out.tolist() == [a // 3, a % 3, (a - 7) // 4, (a - 7) % 4]
    with pytest.raises(NotImplementedError, match="by a positive literal only"):
        translate(src.replace("a // 3", "a // a"))


def test_a_kernel_that_does_not_build_names_the_compilers_error_once_per_process(tmp_path, monkeypatch):
    """A failed build is a NativeBuildError with the compiler's error line (not its "In function" preamble); asking
    again in the process gives the same error at once, without running the compiler again."""
    from hammerstein_ctrl._kernel_c import HEADER
    from hammerstein_ctrl.exceptions import NativeBuildError

    monkeypatch.setenv("HAMMERSTEIN_CTRL_CACHE", str(tmp_path))
    text = HEADER + "int64_t kernel(const hc_arg *args)\n{\n    return no_such_name;\n}\n"
    with pytest.raises(NativeBuildError, match="error.*no_such_name"):
        _native.kernel_address("hc_test_broken", text)
    runs = []
    monkeypatch.setattr(_native, "_run", lambda *a, **k: runs.append(a))
    with pytest.raises(NativeBuildError, match="no_such_name"):
        _native.kernel_address("hc_test_broken", text)
    assert runs == []


def test_a_kernel_is_built_once_per_machine_and_a_damaged_build_is_rebuilt(tmp_path):
    """The first process builds a kernel into the machine cache; the next loads that file (not rebuilt); a build
    cut short is refused by its digest and built again, with the same results."""
    code = ("import numpy as np; from hammerstein_ctrl.kernels import get_kernel; out = np.empty((1, 4)); "
            "get_kernel(1, 'outputs', 'zoh')(np.array([[[1.0, 0.5, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]]]), "
            "np.ones((1, 1)), np.zeros(1), np.zeros((1, 1)), np.zeros(1), np.ones((1, 4)), out); print(out.tolist())")
    env = {**os.environ, "HAMMERSTEIN_CTRL_CACHE": str(tmp_path)}

    def run():
        done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stdout

    assert run() == "[[0.0, 0.5, 1.0, 1.5]]\n"
    built = sorted(tmp_path.glob("ckernels-*/hc_kernel_n1_outputs_zoh-*.so"))
    assert len(built) == 1 and built[0].with_name(built[0].name + ".lock").is_file()     # a lock of its own
    before = built[0].stat()
    assert run() == "[[0.0, 0.5, 1.0, 1.5]]\n"
    after = built[0].stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    built[0].write_bytes(built[0].read_bytes()[:100])                  # cut short
    assert run() == "[[0.0, 0.5, 1.0, 1.5]]\n"
    assert built[0].stat().st_size == before.st_size
    assert not list(tmp_path.glob("ckernels-*/*.tmp"))


def test_compiled_code_calls_a_kernel_through_its_address_with_the_doors_bits():
    """Compiled callers pass their arrays to the C kernel's address (shapes and data pointers): the compiled
    single evaluation gives the Python door's sum bit for bit."""
    from hammerstein_ctrl.simulate import COMPILED_EXPM_MAX_NORM

    rng = np.random.default_rng(2)
    num, den = np.array([[0.5, 1.0]]), np.array([[1.0, 1.2, 0.8]])
    P, basis, y = rng.normal(size=(1, 2)), rng.normal(size=(2, 400)), rng.normal(size=400)
    J = np.empty(1)
    assert kernels.get_coefficient_kernel(2, "foh", 2)(num, den, 0.01, COMPILED_EXPM_MAX_NORM, np.zeros((1, 2)),
                                                       np.zeros(1), P, basis, y, J)
    from hammerstein_ctrl._linalg import tf_discrete
    E, C, D, _, _, clean = tf_discrete(num, den, 0.01, COMPILED_EXPM_MAX_NORM)
    expected = np.empty(1)
    kernels.get_kernel(2, "sse", "foh", None, 2)(E, C, D, np.zeros((1, 2)), np.zeros(1), P, basis, y, expected)
    assert clean and _same_bits(J, expected)
    assert _native.kernel_address.cache_info().currsize >= 2


def test_the_single_evaluation_from_coefficients_checks_what_the_kernel_reads():
    """get_coefficient_kernel's call (the library's discretisation, then the kernel by address) checks every array
    against the kernel's order and basis before it runs: a block of another order, a short output, too few basis
    rows or an improper block are refused by name; a row the compiled path cannot take leaves out untouched."""
    from hammerstein_ctrl.simulate import COMPILED_EXPM_MAX_NORM

    f = kernels.get_coefficient_kernel(3, "foh", 1)
    num, den = np.ones((1, 1)), np.array([[1.0, 3.0, 3.0, 1.0]])
    args = [np.zeros((1, 3)), np.zeros(1), np.ones((1, 1)), np.ones((1, 40)), np.zeros(40), np.empty(1)]
    assert f(num, den, 0.1, COMPILED_EXPM_MAX_NORM, *args) and np.isfinite(args[-1][0])

    def refused(error, match, num=num, den=den, **changed):
        given = dict(zip(("X0", "Y0", "P", "Phi", "y", "out"), args), **changed)
        with pytest.raises(error, match=match):
            f(num, den, 0.1, COMPILED_EXPM_MAX_NORM, *given.values())
    refused(ValueError, r"hc_coefficient_pass_n3_k1: den has shape \(1, 3\), not \(B,4\)", den=np.ones((1, 3)))
    refused(ValueError, r"out has shape \(0\), not \(B\); B = 1", out=np.empty(0))
    refused(ValueError, r"Phi has shape \(0, 40\)", Phi=np.ones((0, 40)))
    refused(ValueError, "num has more coefficients than den", num=np.ones((1, 5)))
    out = np.full(1, 7.0)
    assert not f(num, np.array([[0.0, 3.0, 3.0, 1.0]]), 0.1, COMPILED_EXPM_MAX_NORM, *args[:-1], out)
    assert out[0] == 7.0


@pytest.mark.parametrize("family", ["tanh", "polynomial", "saturation", "coulomb"])
def test_an_output_map_kernel_gives_numbas_bits_for_its_source(family):
    """A kernel with an output map (the family's formula translated into it: tanh, a loop over the coefficients,
    numpy's minimum and maximum, sign) against numba's compile of the same source: the same bits over 30 random
    batches with non-finite, signed-zero and extreme entries, and a normal-equation pass through the map too."""
    outmap = f"{family}_map"
    kernel = kernels.get_kernel(2, "sse", "zoh", outmap)
    assert isinstance(kernel, kernels.CKernel)
    oracle = _numba_kernel(kernel_source(2, "sse", "zoh", outmap), f"map_{family}")
    rng = np.random.default_rng(len(family))
    for _ in range(30):
        B, N = int(rng.integers(1, 6)), int(rng.integers(1, 1500))
        args = [_array(rng, B, 4, 4, scale=0.2), _array(rng, B, 2), _array(rng, B), _array(rng, B, 2),
                _array(rng, B), _array(rng, B, N), _array(rng, B, 3), np.zeros(0), _array(rng, N)]
        got, expected = np.empty(B), np.empty(B)
        kernel(*args, got)
        oracle(*args, expected)
        assert _same_bits(got, expected)
    lanes = 4
    normal = kernels.get_normal_kernel(2, "foh", lanes, 1, True, True, outmap)
    oracle = _numba_kernel(normal_source(2, "foh", lanes, 1, True, True, outmap), f"map_pass_{family}")
    N = 700
    E, C, D, P, Phi, y = (_array(rng, lanes, 4, 4, scale=0.2), _array(rng, lanes, 2), _array(rng, lanes),
                          _array(rng, lanes, 1), _array(rng, 1, N), _array(rng, N))
    HP, Y0 = _array(rng, lanes, 3), _array(rng, lanes)
    sums = []
    for k in (normal, oracle):
        acc = np.zeros(1 + (lanes - 1) * lanes)
        k(E, C, D, np.zeros((lanes, 2)), Y0, np.zeros(lanes), P, Phi, HP, np.zeros(0), y, 0, acc)
        sums.append(acc)
    assert _same_bits(*sums)
    with pytest.raises(ValueError, match="HP has shape"):      # fewer parameters than the map reads
        kernel(*args[:6], np.ones((args[0].shape[0], 0)), np.zeros(0), args[8], np.empty(args[0].shape[0]))
