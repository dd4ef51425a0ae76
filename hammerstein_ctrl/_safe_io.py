"""Files the package writes and reads, handled so that a hostile file system cannot redirect or stall them.

**Writing.** Nothing the package writes follows a symbolic link: a path that
is a link (dangling or not) is refused with an :class:`UnsafePathError`
naming it.  Whole files (:func:`write_bytes`, :func:`write_text`,
:func:`save_figure`) are written to a fresh temporary file made by
``tempfile.mkstemp`` in the target's folder and moved over the target with
``os.replace``, so a reader never sees half a file and no fixed temporary
name can be pre-planted.  The file gets the permissions of the file it
replaces, else those a plain ``open`` gives (``0666`` less the umask).  Files appended to (:func:`open_append`) and lock
files (:func:`open_lock`) are opened with ``O_NOFOLLOW``, and must be regular
files.  With ``root`` given, the target must also lie inside that folder
once resolved.

**Reading.** :func:`read_bytes` and :func:`check_input` accept regular files
only (a FIFO, a device such as ``/dev/zero`` or a folder is refused at once,
without blocking) no larger than a limit: :data:`MAX_INPUT_BYTES` for
records, :data:`MAX_DOCUMENT_BYTES` for model and result files, both raised
through the environment variable :data:`MAX_BYTES_ENV`.

Examples
--------
>>> import os, tempfile
>>> folder = tempfile.mkdtemp()
>>> write_text(os.path.join(folder, "a.txt"), "hello")
>>> os.symlink(os.path.join(folder, "a.txt"), os.path.join(folder, "link.txt"))
>>> write_text(os.path.join(folder, "link.txt"), "redirected?")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
hammerstein_ctrl._safe_io.UnsafePathError: ... is a symbolic link: refusing to write through it ...
"""

from __future__ import annotations

import io
import os
import stat
import tempfile
from pathlib import Path

from .exceptions import DataError, DataNotFoundError, HammersteinError

__all__ = ["UnsafePathError", "write_bytes", "write_text", "save_figure", "open_append", "open_lock",
           "read_bytes", "check_input", "check_output", "input_limit", "MAX_INPUT_BYTES", "MAX_DOCUMENT_BYTES",
           "MAX_BYTES_ENV"]

#: Largest record file read (bytes), unless :data:`MAX_BYTES_ENV` says otherwise.
MAX_INPUT_BYTES = 1 << 30
#: Largest model or result file read (bytes), unless :data:`MAX_BYTES_ENV` says otherwise.
MAX_DOCUMENT_BYTES = 1 << 26
#: Environment variable raising (or lowering) both limits, in bytes.
MAX_BYTES_ENV = "HAMMERSTEIN_CTRL_MAX_FILE_BYTES"


class UnsafePathError(HammersteinError, OSError):
    """A path the package was asked to write is a symbolic link, not a regular file, or outside its folder."""


def _size(n: int) -> str:
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n} bytes"


def input_limit(default: int) -> int:
    """The size limit of a read: ``default``, or :data:`MAX_BYTES_ENV` when set to a positive integer."""
    text = os.environ.get(MAX_BYTES_ENV)
    if not text:
        return default
    try:
        value = int(float(text))
    except ValueError:
        raise DataError(f"{MAX_BYTES_ENV}={text!r} must be a number of bytes") from None
    if value <= 0:
        raise DataError(f"{MAX_BYTES_ENV}={text!r} must be a positive number of bytes")
    return value


# -- writing ---------------------------------------------------------------------
def check_output(path, *, root=None) -> Path:
    """``path`` as a Path, after checking that writing it can neither follow a link nor leave ``root``.

    Raises
    ------
    UnsafePathError
        If ``path`` is a symbolic link, exists and is not a regular file, its
        folder does not exist, or (with ``root``) it resolves outside ``root``.
    """
    p = Path(path)
    if p.is_symlink():
        raise UnsafePathError(f"{p} is a symbolic link: refusing to write through it (remove it, or choose "
                              "another name)")
    if p.exists() and not p.is_file():
        kind = "a folder" if p.is_dir() else "not a regular file"
        raise UnsafePathError(f"{p} is {kind}: give a file name")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise UnsafePathError(f"{p}: the folder {parent} does not exist")
    if root is not None:
        base = Path(root).resolve()
        where = parent.resolve() / p.name
        if where != base and base not in where.parents:
            raise UnsafePathError(f"{p} resolves to {where}, outside {base}: refusing to write there")
    return p


def write_bytes(path, data: bytes, *, root=None) -> None:
    """Write ``data`` to ``path`` whole: a ``mkstemp`` file in its folder, then ``os.replace`` (module notes)."""
    p = check_output(path, root=root)
    mode = _mode_for(p)
    fd, tmp = tempfile.mkstemp(dir=p.parent if str(p.parent) else ".", prefix=f".{p.name}.", suffix=".tmp")
    try:
        if hasattr(os, "fchmod"):   # mkstemp's 0600 would hide every file from the user's group
            os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _mode_for(p: Path) -> int:
    """The permissions a written file gets: those of the file it replaces, else ``0666`` less the umask (as a
    plain ``open`` gives)."""
    try:
        return stat.S_IMODE(os.stat(p, follow_symlinks=False).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _umask() -> int:
    """The process's umask, read without changing it where the system says it (Linux), else set and put back."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path, text: str, *, root=None) -> None:
    """:func:`write_bytes` of UTF-8 text."""
    write_bytes(path, text.encode("utf-8"), root=root)


def save_figure(fig, path, *, root=None, **kwargs) -> None:
    """``fig.savefig`` into memory (the format from the file's suffix), then :func:`write_bytes`."""
    p = check_output(path, root=root)
    buffer = io.BytesIO()
    fmt = kwargs.pop("format", None) or (p.suffix.lstrip(".").lower() or None)
    fig.savefig(buffer, format=fmt, **kwargs)
    write_bytes(p, buffer.getvalue(), root=root)


def _open_nofollow(path: Path, flags: int, what: str) -> int:
    try:
        fd = os.open(path, flags | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError:
        if Path(path).is_symlink():
            raise UnsafePathError(f"{path} is a symbolic link: refusing to {what} it (remove it, or choose "
                                  "another folder)") from None
        raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise UnsafePathError(f"{path} is not a regular file: refusing to {what} it")
    return fd


def open_append(path, *, root=None, binary: bool = False):
    """A file opened for appending (created if missing; text unless ``binary``), never through a link."""
    p = check_output(path, root=root)
    fd = _open_nofollow(p, os.O_WRONLY | os.O_APPEND | os.O_CREAT, "append to")
    return os.fdopen(fd, "ab") if binary else os.fdopen(fd, "a", encoding="utf-8")


def open_lock(path, *, root=None, readonly: bool = False):
    """A lock file opened for reading and writing (created if missing, not truncated), never through a link;
    ``readonly``: for reading alone, which is all ``flock`` needs (a lock file another user created)."""
    p = check_output(path, root=root)
    if readonly:
        return os.fdopen(_open_nofollow(p, os.O_RDONLY | os.O_CREAT, "lock"), "r")
    return os.fdopen(_open_nofollow(p, os.O_RDWR | os.O_CREAT, "lock"), "r+")


# -- reading ---------------------------------------------------------------------
def check_input(path, *, limit: int, what: str = "file") -> int:
    """The size of ``path`` after checking it is a regular file within ``limit`` bytes (opened without blocking).

    Raises
    ------
    DataError
        A FIFO, device or folder; a file larger than the limit (naming its
        size and :data:`MAX_BYTES_ENV`).
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except IsADirectoryError:
        raise DataError(f"{p} is a folder; give the {what} itself") from None
    except FileNotFoundError:
        raise DataNotFoundError(f"{what} not found: {p}") from None
    except PermissionError:
        raise DataError(f"{p}: permission denied; the {what} is not readable") from None
    try:
        info = os.fstat(fd)
    finally:
        os.close(fd)
    if stat.S_ISDIR(info.st_mode):
        raise DataError(f"{p} is a folder; give the {what} itself")
    if not stat.S_ISREG(info.st_mode):
        kind = ("a FIFO" if stat.S_ISFIFO(info.st_mode) else "a device" if stat.S_ISCHR(info.st_mode)
                or stat.S_ISBLK(info.st_mode) else "a socket" if stat.S_ISSOCK(info.st_mode) else "not a file")
        raise DataError(f"{p} is {kind}, not a regular file; give the {what} itself")
    limit = input_limit(limit)
    if info.st_size > limit:
        raise DataError(f"{p} is {_size(info.st_size)}, larger than the limit of {_size(limit)} for a {what}; "
                        f"raise it with the environment variable {MAX_BYTES_ENV}=<bytes>")
    return info.st_size


def read_bytes(path, *, limit: int, what: str = "file") -> bytes:
    """The bytes of ``path`` (:func:`check_input` first; at most ``limit`` bytes are read whatever happens)."""
    check_input(path, limit=limit, what=what)
    cap = input_limit(limit)
    with open(path, "rb") as fh:
        data = fh.read(cap + 1)
    if len(data) > cap:
        raise DataError(f"{path} grew past the limit of {_size(cap)} for a {what} while it was read; raise it "
                        f"with {MAX_BYTES_ENV}=<bytes>")
    return data
