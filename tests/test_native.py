"""The package's C library (hammerstein_ctrl._native): its table against the C source, its build and load."""

import os
import re
import subprocess
import sys
import sysconfig

import numpy as np
import pytest

from hammerstein_ctrl import _native
from hammerstein_ctrl.exceptions import NativeBuildError

def test_the_bindings_are_read_off_the_c_prototypes_and_refuse_unknown_types():
    """Both doors pass arguments by the kinds read off the C definitions: a const pointer is read, a plain one
    written; a C type the bindings do not know stops the build with its name, rather than passing it wrongly."""
    assert _native.SIGNATURES["hc_tf_discrete"] == ("ddiiiffDDDBB", "b")
    assert _native.SIGNATURES["hc_fill_coefficients"] == ("diididililiDD", "")
    text = "".join(source.read_text() for source in _native.SOURCES)
    assert set(_native.SIGNATURES) | set(_native.ENTRIES) == set(re.findall(r"^\w+\s+(hc_\w+)\(", text, re.M))
    assert all(_native.entry_address(name) > 0 for name in _native.ENTRIES)     # functions taking hc_arg blocks
    assert all(hasattr(_native.library(), name) for name in _native.SIGNATURES)
    with pytest.raises(NativeBuildError, match="hc_g takes C types .*'char \\*'"):
        _native.prototypes("void hc_g(char *x, int64_t n)\n{")


def test_the_python_door_refuses_arrays_the_c_function_cannot_take():
    """Every array is checked in C before the call: C order, element type, and writeable where written."""
    lib = _native.library()
    out = np.empty((2, 2))
    lib.hc_expm(np.eye(2), 2, out)
    np.testing.assert_allclose(out, np.e * np.eye(2), rtol=1e-15)
    with pytest.raises(TypeError, match="hc_expm: argument 0 must be a C-ordered array"):
        lib.hc_expm(np.eye(4)[::2, ::2], 2, out)
    with pytest.raises(TypeError, match="hc_expm: argument 0 has items of format 'f'"):
        lib.hc_expm(np.eye(2, dtype=np.float32), 2, out)
    frozen = np.empty((2, 2))
    frozen.flags.writeable = False
    with pytest.raises(TypeError, match="hc_expm: argument 2 must be a C-ordered, writeable array"):
        lib.hc_expm(np.eye(2), 2, frozen)
    with pytest.raises(TypeError, match="hc_expm takes 3 arguments, not 2"):
        lib.hc_expm(np.eye(2), 2)
    with pytest.raises(ValueError, match="hc_expm: argument 1 must be a size \\(>= 0\\), not -1"):
        lib.hc_expm(np.empty(0), -1, np.empty(0))
    out = np.full((1, 5), np.nan)
    lib.hc_combine(np.empty((1, 0)), 1, 0, np.empty((0, 5)), 5, out, 5, 0)      # no basis rows: the empty sum
    assert out.tolist() == [[0.0] * 5]
    with pytest.raises(TypeError, match="hc_tf_discrete: argument 10 has items of format 'd'"):
        lib.hc_tf_discrete(np.ones((1, 1)), np.ones((1, 2)), 1, 1, 2, 0.1, 64.0, np.empty((1, 3, 3)),
                           np.empty((1, 1)), np.empty(1), np.empty(1), np.empty(1, dtype=bool))


def test_a_missing_compiler_is_one_error_naming_it(tmp_path, monkeypatch):
    monkeypatch.setenv("CC", "no-such-compiler-hc")
    with pytest.raises(NativeBuildError, match="no C compiler ran \\(no-such-compiler-hc"):
        _native._build(_native._compiler(), tmp_path / "lib.so")
    assert list(tmp_path.iterdir()) == []           # nothing half-written left behind


def test_a_failing_compiler_is_one_error_with_its_first_line(tmp_path):
    with pytest.raises(NativeBuildError, match="failed: "):
        _native._build(["cc", "-DHC_NO_SUCH_FLAG", "--no-such-option-hc"], tmp_path / "lib.so")
    assert list(tmp_path.iterdir()) == []


def test_a_damaged_cut_short_or_linked_library_is_not_loaded(tmp_path):
    """A library cut short (a killed write) would crash the process with SIGBUS when loaded: its digest, written
    after it, must not match, and a link (in or out of the cache) is never followed."""
    name = "_hc_native" + sysconfig.get_config_var("EXT_SUFFIX")
    (tmp_path / "built").mkdir()
    built = tmp_path / "built" / name
    _native._build(_native._compiler(), built)
    assert _native._load(built) is not None
    data = built.read_bytes()
    for folder, content in (("short", data[:len(data) // 2]), ("damaged", b"\x7fELF not really")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / name).write_bytes(content)
        (tmp_path / folder / (name + ".sha256")).write_text((tmp_path / "built" / (name + ".sha256")).read_text())
        assert _native._load(tmp_path / folder / name) is None
    (tmp_path / "link").mkdir()
    (tmp_path / "link" / name).symlink_to(built)
    (tmp_path / "link" / (name + ".sha256")).write_text((tmp_path / "built" / (name + ".sha256")).read_text())
    assert _native._load(tmp_path / "link" / name) is None
    (tmp_path / "built" / (name + ".sha256")).unlink()
    assert _native._load(built) is None                  # no digest: not trusted


def test_a_build_folder_that_is_a_link_out_of_the_cache_is_not_written(tmp_path, monkeypatch):
    outside = tmp_path / "outside"
    outside.mkdir()
    cache = tmp_path / "cache"
    cache.mkdir()
    digest = "native-" + _native._digest()
    (cache / digest).symlink_to(outside, target_is_directory=True)
    monkeypatch.setenv("HAMMERSTEIN_CTRL_CACHE", str(cache))
    monkeypatch.setattr(_native, "machine_cache_dir", lambda: cache)
    assert _native._cache_folder(digest) is None          # the library is then built in a temporary folder
    assert list(outside.iterdir()) == []


def test_the_build_key_follows_the_sources_and_flags_not_the_compiler(monkeypatch):
    """A library built once stays usable when the compiler is gone (any C99 compiler gives the sources'
    arithmetic); new flags or sources build a new one."""
    base = _native._digest()
    monkeypatch.setenv("CC", "no-such-compiler-hc")
    assert _native._digest() == base
    monkeypatch.setenv("CC", "gcc -ffast-math")          # options that change code key their own build
    fast, kernels = _native._digest(), _native._host_digest()
    monkeypatch.setenv("CC", "gcc")
    assert fast != _native._digest() == base and kernels != _native._host_digest()
    monkeypatch.setattr(_native, "BUILD_FLAGS", _native.BUILD_FLAGS + ("-O1",))
    assert _native._digest() != base


def test_a_fresh_cache_builds_once_and_later_processes_load_it(tmp_path):
    """The first process builds the library into the machine cache; the next one loads that file (not rebuilt:
    same inode and time) and gets the same bits from its exponential."""
    code = ("import numpy as np; from hammerstein_ctrl._linalg import expm_batch; "
            "print(expm_batch(np.array([[[0.0, 1.0], [-2.0, -3.0]]])).tobytes().hex())")
    env = {**os.environ, "HAMMERSTEIN_CTRL_CACHE": str(tmp_path)}
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    name = "_hc_native" + sysconfig.get_config_var("EXT_SUFFIX")
    built = sorted(tmp_path.glob("native-*/*"))
    assert sorted(p.name for p in built) == sorted([".lock", name, name + ".sha256"])
    built = [p for p in built if p.name == name]
    before = built[0].stat()
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert first.stdout == second.stdout and first.stdout.strip()
    after = built[0].stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    assert len(list(tmp_path.glob("native-*/*"))) == 3           # no second build, no temporary left
    import scipy.linalg
    expected = scipy.linalg.expm(np.array([[0.0, 1.0], [-2.0, -3.0]]))
    got = np.frombuffer(bytes.fromhex(first.stdout.strip()), dtype=float).reshape(2, 2)
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-15)


def test_processes_finding_no_library_build_it_once(tmp_path):
    """Two processes starting on an empty cache at once: one builds (under the folder's lock), the other loads
    that build; the compiler runs for one process only (a wrapper logs the parent of each run)."""
    log = tmp_path / "runs.log"
    wrapper = tmp_path / "cc-logged"
    wrapper.write_text(f"#!/bin/sh\necho $PPID >> {log}\nexec {' '.join(_native._compiler())} \"$@\"\n")
    wrapper.chmod(0o755)
    env = {**os.environ, "HAMMERSTEIN_CTRL_CACHE": str(tmp_path / "cache"), "CC": str(wrapper)}
    code = "import hammerstein_ctrl._native as n; print(n.library().hc_one_norm(__import__('numpy').eye(2), 2))"
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, text=True)
             for _ in range(2)]
    outputs = [p.communicate(timeout=300)[0] for p in procs]
    assert [p.returncode for p in procs] == [0, 0] and outputs == ["1.0\n", "1.0\n"]
    assert len(set(log.read_text().split())) == 1          # every compiler run came from one process
    assert not list((tmp_path / "cache").glob("native-*/*.tmp"))


def test_the_command_line_without_a_compiler_says_so_in_one_line(tmp_path):
    """On a machine whose library is not built and that has no C compiler, the CLI exits 2 with one line naming
    the compiler it tried, no traceback."""
    env = {**os.environ, "HAMMERSTEIN_CTRL_CACHE": str(tmp_path), "CC": "no-such-compiler-hc"}
    data = tmp_path / "record.csv"
    t = np.arange(200) * 0.01
    np.savetxt(data, np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",", header="t,u,y", comments="")
    done = subprocess.run([sys.executable, "-m", "hammerstein_ctrl.cli", "identify", "--data", str(data)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no C compiler ran (no-such-compiler-hc" in lines[0], done.stderr
    assert "unexpected" not in lines[0] and "Traceback" not in done.stderr


def test_a_full_disk_or_a_folder_without_locks_builds_in_a_temporary_folder(tmp_path, monkeypatch):
    """A cache folder that cannot take the library (writes fail) or cannot be locked is not an error: the build
    goes to a temporary folder, and nothing half-written stays in the cache."""
    folder = tmp_path / "native"
    folder.mkdir()
    name = "_hc_native" + sysconfig.get_config_var("EXT_SUFFIX")
    real_replace = os.replace

    def full(src, dst):
        if str(dst).startswith(str(folder)):
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)
    monkeypatch.setattr(_native.os, "replace", full)
    assert _native._locked_build(_native._compiler(), folder / name) is None
    assert sorted(p.name for p in folder.iterdir()) == [".lock"]
    monkeypatch.setattr(_native.os, "replace", real_replace)

    def no_locks(fd, operation):
        raise OSError(37, "No locks available")
    monkeypatch.setattr(_native.fcntl, "flock", no_locks)
    assert _native._locked_build(_native._compiler(), folder / name) is None
