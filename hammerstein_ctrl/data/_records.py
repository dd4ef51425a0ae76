"""Reading a user's own input/output record from a CSV, text, MAT or NPZ file.

:func:`read_record` turns a file into an :class:`~hammerstein_ctrl.data.IOData`
or raises a :class:`~hammerstein_ctrl.exceptions.DataError` naming the file and
the problem (never a parser's traceback, never a silently wrong record):
undecodable or truncated files, object or complex arrays, wrong shapes, text
where numbers belong, duplicated or irregular time stamps.  The time-base
options of real rigs (``tolerance``, ``resample``, ``start``/``stop``,
``intersample``) are exposed, and :func:`add_record_arguments` /
:func:`record_from_args` give a command line the same options.

Examples
--------
>>> import tempfile, pathlib
>>> path = pathlib.Path(tempfile.mkdtemp()) / "rig.csv"
>>> _ = path.write_text("time [s];force [N];position [m]\\n0;0,5;1\\n0,1;1,5;2\\n0,2;2,5;3\\n")
>>> d = read_record(path, input="force", output="position")  # names match without units
>>> d.dt, d.u.tolist()
(0.1, [0.5, 1.5, 2.5])
"""

from __future__ import annotations

import argparse
import array
import codecs
import csv
import itertools
import os
import warnings
from pathlib import Path

import numpy as np

from .._checks import GRID_TOLERANCE, INTERSAMPLE, as_signal, check_dt, optional_time
from ..exceptions import DataError, DataNotFoundError
from ._iodata import RESAMPLE_METHODS, IOData
from .._safe_io import MAX_INPUT_BYTES, check_input

__all__ = ["read_record", "DataNotFoundError", "add_record_arguments", "record_from_args", "FILE_TYPES"]

#: File suffixes :func:`read_record` reads.
FILE_TYPES = (".csv", ".txt", ".mat", ".npz")
_TIME_NAMES = ("t", "time")
_INPUT_NAMES = ("u", "input")
_OUTPUT_NAMES = ("y", "output")
#: Longest excerpt of a bad field or parser message quoted in an error.
_QUOTE = 60
#: Most column names listed in an error.
_LISTED = 12
#: Bytes of a text file read first: its layout, and an early refusal of binary or UTF-16 content.
_HEAD_BYTES = 1 << 16
#: Delimiters recognised in text files, by priority (None: whitespace).
_DELIMITERS = (";", ",", "\t")




def _quote(text) -> str:
    text = " ".join(str(text).split())
    return repr(text if len(text) <= _QUOTE else text[:_QUOTE] + "...")


# ---------------------------------------------------------------------------
# text files
# ---------------------------------------------------------------------------
def _head(path: Path) -> bytes:
    """The first :data:`_HEAD_BYTES` of a text file, refused at once if they show UTF-16 or binary content."""
    with open(path, "rb") as fh:
        head = fh.read(_HEAD_BYTES)
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise DataError(f"{path}: the file is UTF-16 text; save it as UTF-8 (or plain ASCII) CSV")
    try:        # a character cut by the end of the head is not an error
        codecs.getincrementaldecoder("utf-8")().decode(head, final=len(head) < _HEAD_BYTES)
    except UnicodeDecodeError as exc:
        line = head[: exc.start].count(b"\n") + 1
        raise DataError(f"{path}: not UTF-8 text (byte 0x{head[exc.start]:02x} on line {line}); "
                        "save the file as UTF-8 (or plain ASCII) CSV") from None
    if b"\x00" in head:
        _nul(path, head[: head.index(b"\x00")].count(b"\n") + 1)
    return head


def _nul(path: Path, line: int):
    raise DataError(f"{path}: NUL bytes on line {line}: binary data, or UTF-16 text without a "
                    "byte-order mark; save the file as UTF-8 CSV")


def _text_lines(path: Path):
    """``(line number, line)`` of every line of a UTF-8 text file, decoded strictly and streamed.

    Lines are numbered as ``str.splitlines`` numbers them; memory stays within one line.
    """
    number = 0
    with open(path, "rb") as fh:
        for raw in fh:
            if b"\x00" in raw:
                _nul(path, number + 1)
            try:
                text = raw.decode("utf-8-sig" if number == 0 else "utf-8")
            except UnicodeDecodeError as exc:
                raise DataError(
                    f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} on line {number + 1}); "
                    "save the file as UTF-8 (or plain ASCII) CSV"
                ) from None
            for line in text.splitlines():
                number += 1
                yield number, line


def _content_lines(lines):
    """(line number, line) of the lines that are neither blank nor ``#`` comments."""
    return ((i, ln) for i, ln in lines if ln.strip() and not ln.lstrip().startswith("#"))


def _delimiter(first: str):
    return next((d for d in _DELIMITERS if d in first), None)


def _split_rows(path: Path, lines, delimiter):
    """``(line number, fields)`` of the content lines, split on ``delimiter`` (None: whitespace), streamed."""
    if delimiter is None:
        for n, ln in lines:
            yield n, ln.split()
        return
    pending = []            # the lines the reader took for the current row (several inside a quoted field)

    def text():
        for n, ln in lines:
            pending.append(n)
            yield ln

    reader = csv.reader(text(), delimiter=delimiter)
    try:
        for fields in reader:
            n = pending[0]
            pending.clear()
            yield n, [f.strip() for f in fields]
    except csv.Error as exc:
        raise DataError(f"{path}: line {pending[0] if pending else '?'}: {exc} (a corrupt or non-CSV file?)") from None


def _number(field: str, delimiter) -> float:
    if delimiter == ";" and "," in field and "." not in field:
        field = field.replace(",", ".")  # decimal comma (semicolon-separated files)
    return float(field)


def _is_numeric_row(fields, delimiter) -> bool:
    try:
        [_number(f, delimiter) for f in fields]
    except ValueError:
        return False
    return True


def _header_names(path: Path, fields) -> list[str]:
    names = []
    for j, name in enumerate(fields):
        if not name:
            raise DataError(f"{path}: column {j + 1} of the header has no name")
        if name in names:
            raise DataError(f"{path}: duplicated column name {name!r} in the header "
                            f"(columns {names.index(name) + 1} and {j + 1})")
        names.append(name)
    return names


def _bad_field_message(path, n, fields, names, delimiter) -> str:
    for name, f in zip(names, fields):
        try:
            _number(f, delimiter)
        except ValueError:
            pass
        else:
            continue
        try:
            complex(f.replace(" ", ""))
        except ValueError:
            return f"{path}: line {n}: column {name!r} holds {_quote(f)}, not a number"
        return (f"{path}: line {n}: column {name!r} holds the complex value {_quote(f)}; "
                "hammerstein_ctrl needs real signals")
    return f"{path}: line {n}: a field is not a number"  # pragma: no cover - guarded by the caller


def _layout(path: Path, first, delimiter):
    """``(names, header line or None)`` from the first content row ``(n, fields)``."""
    n, fields = first
    if _is_numeric_row(fields, delimiter):
        names = {2: ["u", "y"], 3: ["t", "u", "y"]}.get(len(fields))
        if names is None:
            raise DataError(
                f"{path}: a file without a header must have 2 columns (u, y) or 3 (t, u, y), "
                f"found {len(fields)} on line {n}"
            )
        return names, None
    return _header_names(path, fields), n


def _careful_columns(path: Path) -> dict:
    """Every line checked, for the exact message on a bad file (streamed: 8 bytes per value held)."""
    lines = _content_lines(_text_lines(path))
    first = next(lines, None)
    if first is None:
        raise DataError(f"{path}: no data rows (the file is empty or holds only comments)")
    delimiter = _delimiter(first[1])
    rows = _split_rows(path, itertools.chain([first], lines), delimiter)
    names, header = _layout(path, next(rows), delimiter)
    if header is None:
        rows = itertools.chain([_split_rows(path, iter([first]), delimiter).__next__()], rows)
    values = array.array("d")
    for n, fields in rows:
        if len(fields) != len(names):
            raise DataError(f"{path}: line {n} has {len(fields)} fields, expected {len(names)} "
                            f"({', '.join(names)})")
        try:
            values.extend([_number(f, delimiter) for f in fields])
        except ValueError:
            raise DataError(_bad_field_message(path, n, fields, names, delimiter)) from None
    if not values:
        raise DataError(f"{path}: a header ({', '.join(names)}) but no data rows")
    table = np.frombuffer(values, dtype=float).reshape(-1, len(names))
    return {name: table[:, j].copy() for j, name in enumerate(names)}


def _fast_columns(path: Path, head: bytes) -> dict | None:
    """The columns through numpy's compiled reader, or None to let :func:`_careful_columns` decide.

    The layout (header, delimiter) comes from the first lines as the careful
    reader sees them; any doubt (a decimal comma, quoting, a line numpy
    refuses) falls back to the careful reader, so both give the same record.
    """
    text = head.decode("utf-8-sig", errors="replace")
    complete = text if len(head) < _HEAD_BYTES else text[: text.rfind("\n") + 1]
    first = next(_content_lines(enumerate(complete.splitlines(), 1)), None)
    if first is None or '"' in complete:
        return None
    delimiter = _delimiter(first[1])
    if delimiter == ";":          # a decimal comma is possible: the careful reader knows it
        return None
    try:
        names, header = _layout(path, next(_split_rows(path, iter([first]), delimiter)), delimiter)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")       # numpy's "empty input file" warning: the careful reader explains
            table = np.loadtxt(path, delimiter=delimiter, comments="#", skiprows=header or 0, ndmin=2,
                               encoding="utf-8-sig")
    except (ValueError, UnicodeDecodeError, DataError):
        return None
    if table.shape[0] == 0 or table.shape[1] != len(names) or not np.isfinite(table).all():
        return None         # the careful reader names the line (a number too long, a NaN, ...)
    return {name: table[:, j] for j, name in enumerate(names)}     # views: the record copies what it keeps


def _read_text_columns(path: Path) -> dict:
    return _fast_columns(path, _head(path)) or _careful_columns(path)


# ---------------------------------------------------------------------------
# binary files
# ---------------------------------------------------------------------------
def _read_mat_columns(path: Path) -> dict:
    import scipy.io

    try:
        raw = scipy.io.loadmat(path)
    except NotImplementedError:
        raise DataError(f"{path}: MATLAB v7.3 (HDF5) MAT files are not supported; "
                        "save with save(..., '-v7') or export a CSV") from None
    except Exception as exc:  # noqa: BLE001 - a parser of foreign files can raise anything
        raise DataError(f"{path}: not a readable MAT file ({type(exc).__name__}: {_quote(exc)})") from None
    columns = {k: v for k, v in raw.items() if not k.startswith("__")}
    if not columns:
        raise DataError(f"{path}: the MAT file holds no variables")
    return columns


def _read_npz_columns(path: Path) -> dict:
    # the file is opened here so that it is closed whatever numpy makes of its contents
    with open(path, "rb") as handle:
        try:
            archive = np.load(handle, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - see _read_mat_columns
            raise DataError(f"{path}: not a readable NPZ archive ({type(exc).__name__}: {_quote(exc)})") from None
        if isinstance(archive, np.ndarray):
            raise DataError(f"{path}: this is a single NumPy array (.npy), not an .npz archive of named "
                            "arrays; save with numpy.savez(path, t=t, u=u, y=y)")
        with archive:
            columns = {key: _npz_member(path, archive, key) for key in archive.files}
    if not columns:
        raise DataError(f"{path}: the NPZ archive holds no arrays")
    return columns


def _npz_member(path: Path, archive, key: str) -> np.ndarray:
    try:
        value = archive[key]
    except ValueError as exc:
        if "allow_pickle" in str(exc):
            raise DataError(f"{path}: array {key!r} holds Python objects, which are not loaded "
                            "(unsafe pickles); save plain numeric arrays") from None
        raise DataError(f"{path}: array {key!r} is unreadable ({_quote(exc)})") from None
    except Exception as exc:  # noqa: BLE001 - truncated/corrupt members
        raise DataError(f"{path}: array {key!r} is unreadable, the archive looks truncated or "
                        f"corrupt ({type(exc).__name__}: {_quote(exc)})") from None
    if not isinstance(value, np.ndarray):  # NpzFile returns raw bytes of non-.npy members
        raise DataError(f"{path}: member {key!r} of the archive is not a NumPy array")
    return value


_KIND_NAMES = {"O": "Python objects or a MATLAB cell array", "V": "a MATLAB struct or record array",
               "U": "text", "S": "text", "M": "dates (convert them to seconds)",
               "m": "time differences (convert them to seconds)"}


def _vector(path: Path, name: str, value) -> np.ndarray:
    """The column ``name`` as a real 1-D float array, or a DataError naming the problem."""
    if hasattr(value, "toarray"):  # scipy.sparse from a MAT file
        value = value.toarray()
    a = np.asarray(value)
    kind = a.dtype.kind
    if kind == "c":
        bad = np.flatnonzero(np.imag(a).ravel())
        where = f" (first at sample {bad[0]}: {a.ravel()[bad[0]]})" if bad.size else ""
        raise DataError(f"{path}: column {name!r} holds complex values{where}; hammerstein_ctrl needs "
                        "real signals (take the real part or the magnitude first)")
    if kind not in "biuf":
        raise DataError(f"{path}: column {name!r} holds {_KIND_NAMES.get(kind, a.dtype)}, not numbers")
    if a.ndim > 1 and sum(d > 1 for d in a.shape) <= 1:
        a = a.reshape(-1)
    if a.ndim != 1:
        raise DataError(f"{path}: column {name!r} has shape {a.shape}; expected a vector (one signal)")
    if a.size == 0:
        raise DataError(f"{path}: column {name!r} is empty")
    return a.astype(float)


# ---------------------------------------------------------------------------
# columns and records
# ---------------------------------------------------------------------------
def _base(name: str) -> str:
    """A column name without units or case: ``"Time [s]"`` -> ``"time"``."""
    return name.split("[")[0].split("(")[0].strip().lower()


def _describe(columns: dict) -> str:
    parts = []
    for k, v in list(columns.items())[:_LISTED]:
        shape = np.shape(v)
        parts.append(k if len(shape) == 1 else f"{k} {shape}")
    more = f", ... ({len(columns)} in all)" if len(columns) > _LISTED else ""
    return ", ".join(parts) + more


def _pick(columns: dict, wanted, defaults, role: str, path) -> str | None:
    """The column for ``role``: ``wanted`` (exactly, else without case/units), else a default name."""
    if wanted is not None:
        wanted = str(wanted)
        if wanted in columns:
            return wanted
        matches = [c for c in columns if _base(c) == _base(wanted)]
        if len(matches) > 1:
            raise DataError(f"{path}: several {role} columns match {wanted!r}: {', '.join(matches)}; "
                            "give the exact name")
        if not matches:
            raise DataError(f"{path}: no {role} column {wanted!r}; available: {_describe(columns)}")
        return matches[0]
    matches = [c for c in columns if _base(c) in defaults]
    if len(matches) > 1:
        raise DataError(f"{path}: several columns could be the {role}: {', '.join(matches)}; "
                        f"choose one with {role}= (--{role} on the command line)")
    return matches[0] if matches else None


def _channels(columns: dict, wanted, defaults, role: str, path) -> list:
    """The columns of ``role``: one (a name or the default), or each of a list of names."""
    if wanted is None or not isinstance(wanted, (list, tuple)):
        key = _pick(columns, wanted, defaults, role, path)
        if key is None:
            raise DataError(f"{path}: cannot tell which column is the {role}; available: {_describe(columns)} "
                            "(name it with input=/output=, or --input/--output on the command line)")
        return [key]
    wanted = list(wanted)
    if not wanted:
        raise DataError(f"{path}: give at least one {role} column")
    return [_pick(columns, w, defaults, role, path) for w in wanted]


def _select(path: Path, columns: dict, input, output, time, dt):
    """``(u, y, t, names)``: the chosen columns (several channels as 2-D arrays) and their labels."""
    ins, outs = _channels(columns, input, _INPUT_NAMES, "input", path), _channels(columns, output, _OUTPUT_NAMES,
                                                                                  "output", path)
    t_key = _pick(columns, time, _TIME_NAMES, "time", path)
    chosen = ins + outs + ([t_key] if t_key is not None else [])
    if len(set(chosen)) < len(chosen):
        raise DataError(f"{path}: the same column is chosen for two roles: input {ins}, output {outs}, time {t_key}")
    if t_key is None and dt is None:
        raise DataError(f"{path}: no time column ({'/'.join(_TIME_NAMES)}); give dt (--dt)")

    def signal(keys):
        vectors = [_vector(path, k, columns[k]) for k in keys]
        if len(vectors) == 1:
            return vectors[0]
        if len({v.size for v in vectors}) > 1:
            raise DataError(f"{path}: the columns {keys} have different lengths {[v.size for v in vectors]}")
        return np.column_stack(vectors)

    names = {} if len(ins) == 1 and len(outs) == 1 else {"input_name": ins, "output_name": outs}
    return signal(ins), signal(outs), None if t_key is None else _vector(path, t_key, columns[t_key]), names


_READERS = {".csv": _read_text_columns, ".txt": _read_text_columns,
            ".mat": _read_mat_columns, ".npz": _read_npz_columns}


def _columns(path: Path) -> dict:
    if not path.exists():
        raise DataNotFoundError(f"data file not found: {path}")
    if path.is_dir():
        raise DataError(f"{path} is a folder; give the data file itself")
    suffix = path.suffix.lower()
    if suffix not in _READERS:
        raise DataError(f"{path}: unsupported file type {suffix or '(no suffix)'!r}; "
                        f"use {', '.join(FILE_TYPES)}")
    try:
        if check_input(path, limit=MAX_INPUT_BYTES, what="data file") == 0:
            raise DataError(f"{path}: the file is empty")
        return _READERS[suffix](path)
    except OSError as exc:
        raise DataError(f"{path}: cannot read the file ({exc.strerror or exc})") from None


def _window_raw(u, y, t, start, stop):
    """The samples with ``start <= t < stop`` of a record not yet on a grid."""
    start, stop = optional_time(start, "start"), optional_time(stop, "stop")
    t = as_signal(t, "t")
    keep = np.ones(t.size, dtype=bool)
    if start is not None:
        keep &= t >= start
    if stop is not None:
        keep &= t < stop
    if keep.sum() < 2:
        raise DataError(f"start={start}, stop={stop} keep {int(keep.sum())} sample(s) of the record's "
                        f"t = [{t.min():g}, {t.max():g}] s; a record needs at least two")
    return u[keep], y[keep], t[keep]


def read_record(
    path,
    *,
    input: str | None = None,
    output: str | None = None,
    time: str | None = None,
    dt: float | None = None,
    name: str | None = None,
    start: float | None = None,
    stop: float | None = None,
    tolerance: float = GRID_TOLERANCE,
    resample: str | None = None,
    intersample: str = "foh",
) -> IOData:
    """Read a user's input/output record from a CSV, text, MAT or NPZ file.

    Accepted layouts:

    * **CSV / text**, UTF-8 (a byte-order mark is fine), separated by commas,
      semicolons (then decimal commas are accepted), tabs or blanks, with a
      header row naming the columns (``#`` lines are comments).  Names match
      without case or units: ``Time [s]`` is a time column.  By default the
      time column is ``t``/``time``, the input ``u``/``input`` and the
      output ``y``/``output``; other names are given with ``input=`` and
      ``output=``.  Without a header, 3 columns mean ``t, u, y`` and 2
      columns ``u, y`` (then ``dt`` is required).
    * **MAT** (``scipy.io.loadmat``, up to v7) or **NPZ** files with one vector
      per variable, named as above.

    A record of a MIMO plant takes a list of columns for ``input`` and/or
    ``output`` (one channel each, named after its column).

    Parameters
    ----------
    path : str or Path
    input, output : str or list of str, optional
        Column/variable names overriding the defaults; a list reads several
        channels (an :class:`IOData` with one column per channel).
    time : str, optional
        The time column/variable.
    dt : float, optional
        Sampling interval when the file has no time column, or the interval of
        the resampled grid.
    name : str, optional
        Record name (defaults to the file name).
    start, stop : float, optional
        Keep the samples with ``start <= t < stop`` (seconds), applied before
        the time grid is checked, so a part without a gap can be kept.
    tolerance : float, default 1e-3
        How far (a fraction of dt) time stamps may stray from the uniform grid
        and still be taken as uniform: raise it when the stamps are noisy
        readings of a uniform clock.  Must be below 0.5.
    resample : {None, "linear", "zoh"}
        When the samples were truly taken at irregular times (jitter, a few
        dropped samples), interpolate them onto a uniform grid: the input
        linearly or held (``"zoh"``), the output linearly.  ``dt`` defaults
        to the interval fitted to the time stamps; gaps longer than 10
        intervals are refused.  See :meth:`IOData.resample`.
    intersample : {"foh", "zoh"}
        The input's behaviour between samples (:class:`IOData`).

    Raises
    ------
    DataNotFoundError
        If the file does not exist.
    DataError
        Naming the file and the problem: unknown format or column, an
        undecodable, truncated or empty file, text, object, complex or
        matrix-shaped data, or any problem :class:`IOData` detects.

    Examples
    --------
    >>> import numpy as np, tempfile, os, hammerstein_ctrl as hc
    >>> path = os.path.join(tempfile.mkdtemp(), "rig.csv")
    >>> t = np.arange(5) * 0.1
    >>> np.savetxt(path, np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",", header="t,u,y", comments="")
    >>> rec = read_record(path)
    >>> len(rec), rec.dt
    (5, 0.1)
    """
    if not isinstance(path, (str, os.PathLike)):
        raise DataError(f"path must be a file name or path, got {path!r}")
    path = Path(path).expanduser()
    columns = _columns(path)
    if dt is not None:
        dt = check_dt(dt)
    u, y, t, names = _select(path, columns, input, output, time, dt)
    try:
        if t is not None and (start is not None or stop is not None):
            u, y, t = _window_raw(u, y, t, start, stop)
        data = IOData(u, y, t, dt=dt, name=name or path.stem, tolerance=tolerance,
                      resample=resample, intersample=intersample, **names)
        if t is None and (start is not None or stop is not None):
            data = data.window(start, stop)
    except DataError as exc:
        raise DataError(f"{path}: {exc}") from None
    return data


# ---------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------
def add_record_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of :func:`read_record` to a command-line parser.

    ``--data`` (required), ``--input``, ``--output`` (or ``--inputs``/``--outputs``
    with several names), ``--time``, ``--dt``,
    ``--start``, ``--stop``, ``--tolerance``, ``--resample`` and
    ``--intersample``; :func:`record_from_args` reads the record they describe.

    Examples
    --------
    >>> p = argparse.ArgumentParser()
    >>> add_record_arguments(p)
    >>> a = p.parse_args(["--data", "rig.csv", "--resample", "zoh", "--start", "2"])
    >>> a.resample, a.start, a.tolerance
    ('zoh', 2.0, 0.001)
    """
    g = parser.add_argument_group("data")
    g.add_argument("--data", required=True, help="CSV, text, MAT or NPZ file")
    ins, outs = g.add_mutually_exclusive_group(), g.add_mutually_exclusive_group()
    ins.add_argument("--input", help="input column/variable name")
    ins.add_argument("--inputs", nargs="+", metavar="NAME", help="several input columns (a MIMO record)")
    outs.add_argument("--output", help="output column/variable name")
    outs.add_argument("--outputs", nargs="+", metavar="NAME", help="several output columns (a MIMO record)")
    g.add_argument("--time", help="time column/variable name")
    g.add_argument("--dt", type=float, help="sampling interval when the file has no time column "
                   "(or of the resampled grid)")
    g.add_argument("--start", type=float, help="keep samples with t >= START (s)")
    g.add_argument("--stop", type=float, help="keep samples with t < STOP (s)")
    g.add_argument("--tolerance", type=float, default=GRID_TOLERANCE,
                   help="allowed deviation of time stamps from a uniform grid, as a fraction of dt "
                        f"(default {GRID_TOLERANCE:g}; < 0.5)")
    g.add_argument("--resample", choices=RESAMPLE_METHODS,
                   help="interpolate irregular time stamps onto a uniform grid (input linear or held)")
    g.add_argument("--intersample", choices=INTERSAMPLE, default="foh",
                   help="the input between samples: foh (linear, default) or zoh (held)")


def record_from_args(args: argparse.Namespace) -> IOData:
    """The record described by the options of :func:`add_record_arguments`."""
    return read_record(
        args.data, input=args.inputs or args.input, output=args.outputs or args.output, time=args.time, dt=args.dt,
        start=args.start, stop=args.stop, tolerance=args.tolerance, resample=args.resample,
        intersample=args.intersample,
    )

