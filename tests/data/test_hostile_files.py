"""A corpus of hostile input files, generated here, each run through ``read_record``.

Every file either loads as the record it holds (its values are checked) or
raises a :class:`DataError` whose one-line message names the problem: no other
exception type, no silently accepted bad data.
"""

import codecs
import io
import re
import zipfile
from dataclasses import dataclass, field

import numpy as np
import pytest
import scipy.io
import scipy.sparse

from hammerstein_ctrl import DataError, read_record

T = 0.01 * np.arange(8)
U = np.array([0.5, -1.0, 2.0, 0.0, 1.5, -0.25, 3.0, 1.0])
Y = np.array([0.0, 0.1, -0.2, 0.4, 0.3, -0.5, 0.25, 0.75])
MAX_MESSAGE = 600


@dataclass
class Ok:
    u: np.ndarray = field(default_factory=lambda: U)
    y: np.ndarray = field(default_factory=lambda: Y)
    t: np.ndarray = field(default_factory=lambda: T)
    intersample: str = "foh"


@dataclass
class Err:
    pattern: str


@dataclass
class Case:
    id: str
    name: str
    build: object  # bytes, or a callable writing the path
    expect: object
    kwargs: dict


CASES: list[Case] = []


def case(id, name, build, expect, **kwargs):
    assert id not in {c.id for c in CASES}, id
    CASES.append(Case(id, name, build, expect, kwargs))


def rows(t=T, u=U, y=Y, sep=",", header="t,u,y", fmt=repr, newline="\n"):
    lines = [header.replace(",", sep)] if header is not None else []
    lines += [sep.join(fmt(float(v)) for v in r) for r in zip(*(c for c in (t, u, y) if c is not None))]
    return (newline.join(lines) + newline).encode()


def npz(compressed=False, **arrays):
    def build(path):
        with open(path, "wb") as fh:
            (np.savez_compressed if compressed else np.savez)(fh, **arrays)
    return build


def npz_bytes(**arrays):
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def mat(variables, **opts):
    def build(path):
        scipy.io.savemat(path, variables, **opts)
    return build


def mat_bytes(variables, **opts):
    buf = io.BytesIO()
    scipy.io.savemat(buf, variables, **opts)
    return buf.getvalue()


GOOD_CSV = rows()

# ---------------------------------------------------------------------------
# CSV / text files that hold a good record
# ---------------------------------------------------------------------------
case("csv-plain", "r.csv", GOOD_CSV, Ok())
case("csv-crlf", "r.csv", rows(newline="\r\n"), Ok())
case("csv-cr-only", "r.csv", rows(newline="\r"), Ok())
case("csv-bom", "r.csv", codecs.BOM_UTF8 + GOOD_CSV, Ok())
case("csv-semicolon-decimal-comma", "r.csv", rows(sep=";", fmt=lambda v: repr(v).replace(".", ",")), Ok())
case("csv-semicolon-dots", "r.csv", rows(sep=";"), Ok())
case("csv-tabs", "r.csv", rows(sep="\t"), Ok())
case("txt-blanks", "r.txt", rows(sep="   "), Ok())
case("txt-blanks-no-header", "r.txt", rows(sep=" ", header=None), Ok())
case("csv-no-header-3", "r.csv", rows(header=None), Ok())
case("csv-no-header-2-dt", "r.csv", rows(t=None, header=None), Ok(), dt=0.01)
case("csv-comments-blank-lines", "r.csv", b"# rig 7\n\n# units: s, V, m\n" + rows().replace(b"\n", b"\n\n"), Ok())
case("csv-units-in-header", "r.csv", rows(header="t [s],u [V],y (m)"), Ok())
case("csv-uppercase-names", "r.csv", rows(header="Time,Input,Output"), Ok())
case("csv-quoted", "r.csv", rows(fmt=lambda v: f'"{v!r}"', header='"t","u","y"'), Ok())
case("csv-extra-column", "r.csv", b"t,u,y,temp\n" + b"".join(
    f"{float(a)!r},{float(b)!r},{float(c)!r},20\n".encode() for a, b, c in zip(T, U, Y)), Ok())
case("csv-column-order", "r.csv", b"y,t,u\n" + b"".join(
    f"{float(c)!r},{float(a)!r},{float(b)!r}\n".encode() for a, b, c in zip(T, U, Y)), Ok())
case("csv-scientific", "r.csv", rows(fmt=lambda v: f"{v:.17e}"), Ok())
case("csv-spaces-around", "r.csv", rows(sep=" ,  ", header="t , u , y"), Ok())
case("csv-upper-suffix", "R.CSV", GOOD_CSV, Ok())
case("csv-named-columns", "r.csv", rows(header="zeit,force,position"), Ok(),
     input="force", output="position", time="zeit")
case("csv-names-given", "r.csv", rows(header="t,vir,qm"), Ok(), input="vir", output="qm")
case("csv-names-unknown", "r.csv", rows(header="t,vir,qm"), Err("cannot tell which column is the input"))
case("csv-negative-start", "r.csv", rows(t=T - 1.0), Ok(t=T - 1.0))
case("csv-epoch-time", "r.csv", rows(t=T + 1.7e9), Ok(t=T + 1.7e9))
case("csv-two-rows", "r.csv", rows(T[:2], U[:2], Y[:2]), Ok(U[:2], Y[:2], T[:2]))
case("csv-no-final-newline", "r.csv", GOOD_CSV.rstrip(b"\n"), Ok())
case("csv-integers", "r.csv", b"t,u,y\n0,1,2\n1,3,4\n2,5,6\n", Ok([1.0, 3, 5], [2.0, 4, 6], [0.0, 1, 2]))
case("csv-utf8-names", "r.csv", rows(header="t,Spannung µV,Winkel °"), Ok(),
     input="Spannung µV", output="Winkel °")
case("csv-small-jitter", "r.csv", rows(t=T + 1e-6 * np.array([1, -1, 0, 1, 0, -1, 1, 0]) * 0.01), Ok())
case("csv-jitter-with-tolerance", "r.csv", rows(t=T + 0.05 * 0.01 * np.array([1, -1, 0, 1, 0, -1, 1, 0])),
     Ok(), tolerance=0.06)
_DROP = np.delete(np.arange(8), 4)
case("csv-dropped-resampled", "r.csv", rows(T[_DROP], U[_DROP], Y[_DROP]),
     Ok(u=np.r_[U[:4], (U[3] + U[5]) / 2, U[5:]], y=np.r_[Y[:4], (Y[3] + Y[5]) / 2, Y[5:]]), resample="linear")
case("csv-dropped-resampled-zoh", "r.csv", rows(T[_DROP], U[_DROP], Y[_DROP]),
     Ok(u=np.r_[U[:4], U[3], U[5:]], y=np.r_[Y[:4], (Y[3] + Y[5]) / 2, Y[5:]], intersample="zoh"),
     resample="zoh", intersample="zoh")
case("csv-window", "r.csv", GOOD_CSV, Ok(U[2:6], Y[2:6], T[2:6]), start=0.015, stop=0.055)
case("csv-window-around-gap", "r.csv", rows(T[_DROP], U[_DROP], Y[_DROP]), Ok(U[:4], Y[:4], T[:4]), stop=0.035)
case("csv-intersample-zoh", "r.csv", GOOD_CSV, Ok(intersample="zoh"), intersample="ZOH")
case("csv-bool-like-ints", "r.csv", b"t,u,y\n0,0,1\n1,1,0\n2,1,1\n", Ok([0.0, 1, 1], [1.0, 0, 1], [0.0, 1, 2]))
case("csv-long-record", "long.csv", rows(0.001 * np.arange(20000), np.sin(np.arange(20000.0)),
                                          np.cos(np.arange(20000.0))),
     Ok(np.sin(np.arange(20000.0)), np.cos(np.arange(20000.0)), 0.001 * np.arange(20000)))
for i, fname in enumerate(["with space.csv", "ünïcödé.csv", "-dash.csv", "semi;colon.csv", "x" * 200 + ".csv",
                           "dots.in.name.csv", ".hidden.csv"]):
    case(f"name-{i}", fname, GOOD_CSV, Ok())

# ---------------------------------------------------------------------------
# CSV / text files that must be refused
# ---------------------------------------------------------------------------
case("csv-empty", "r.csv", b"", Err("the file is empty"))
case("csv-whitespace-only", "r.csv", b"\n \n\t\n", Err("no data rows"))
case("csv-comments-only", "r.csv", b"# nothing\n# here\n", Err("no data rows"))
case("csv-header-only", "r.csv", b"t,u,y\n", Err(r"a header \(t, u, y\) but no data rows"))
case("csv-header-only-crlf", "r.csv", b"t,u,y\r\n\r\n", Err("but no data rows"))
case("csv-latin1", "r.csv", "t,u,y [°C]\n0,1,2\n".encode("latin-1"), Err(r"not UTF-8 text \(byte 0xb0 on line 1\)"))
case("csv-latin1-late", "r.csv", GOOD_CSV + "# température\n".encode("latin-1"),
     Err(r"not UTF-8 text \(byte 0xe9 on line 10\)"))
case("csv-utf16-bom", "r.csv", GOOD_CSV.decode().encode("utf-16"), Err("UTF-16 text; save it as UTF-8"))
case("csv-utf16-no-bom", "r.csv", GOOD_CSV.decode().encode("utf-16-le"),
     Err(r"NUL bytes on line 1: binary data, or UTF-16 text without a byte-order mark"))
case("csv-nul-byte", "r.csv", GOOD_CSV[:20] + b"\x00" + GOOD_CSV[20:], Err("NUL bytes on line 3"))
case("csv-random-binary", "r.csv", np.random.default_rng(0).bytes(4096), Err("not UTF-8 text"))
case("csv-huge-field", "r.csv", b"t,u,y\n0,1," + b"9" * (200 * 1024) + b"\n1,2,3\n",
     Err(r"line 2: field larger than field limit"))
case("txt-huge-field", "r.txt", b"t u y\n0 1 " + b"x" * (200 * 1024) + b"\n1 2 3\n",
     Err(r"line 2: column 'y' holds 'xxxx.*\.\.\.', not a number"))
case("txt-huge-number", "r.txt", b"t u y\n0 1 " + b"9" * (200 * 1024) + b"\n1 2 3\n",
     Err("y contains 1 non-finite value"))
case("csv-nan-u", "r.csv", b"t,u,y\n0,1,2\n1,nan,4\n2,1,1\n", Err("u contains 1 non-finite value.*NaN at sample 1"))
case("csv-inf-y", "r.csv", b"t,u,y\n0,1,2\n1,2,inf\n2,1,1\n", Err("y contains 1 non-finite value.*inf at sample 1"))
case("csv-minus-inf", "r.csv", b"t,u,y\n0,-inf,2\n1,2,3\n", Err("u contains 1 non-finite.*inf at sample 0"))
case("csv-overflow", "r.csv", b"t,u,y\n0,1e999,2\n1,2,3\n", Err("u contains 1 non-finite"))
case("csv-nan-time", "r.csv", b"t,u,y\n0,1,2\nnan,2,3\n2,1,1\n", Err("t contains 1 non-finite value.*NaN at sample 1"))
case("csv-empty-field", "r.csv", b"t,u,y\n0,1,2\n1,,4\n", Err(r"line 3: column 'u' holds '', not a number"))
case("csv-text-field", "r.csv", b"t,u,y\n0,1,2\n1,abc,4\n", Err(r"line 3: column 'u' holds 'abc', not a number"))
case("csv-complex", "r.csv", b"t,u,y\n0,1+2j,2\n1,2,4\n", Err(r"line 2: column 'u' holds the complex value '1\+2j'"))
case("csv-complex-y", "r.csv", b"t,u,y\n0,1,2\n1,2,(3-1j)\n", Err(r"column 'y' holds the complex value"))
case("csv-hex", "r.csv", b"t,u,y\n0,0x10,2\n1,2,4\n", Err(r"column 'u' holds '0x10', not a number"))
case("csv-ragged-short", "r.csv", b"t,u,y\n0,1,2\n1,2\n2,3,4\n", Err(r"line 3 has 2 fields, expected 3 \(t, u, y\)"))
case("csv-ragged-long", "r.csv", b"t,u,y\n0,1,2\n1,2,3,4\n", Err("line 3 has 4 fields, expected 3"))
case("csv-trailing-comma", "r.csv", b"t,u,y\n0,1,2,\n1,2,3,\n", Err("line 2 has 4 fields, expected 3"))
case("csv-duplicate-names", "r.csv", b"t,u,u\n0,1,2\n1,2,3\n",
     Err(r"duplicated column name 'u' in the header \(columns 2 and 3\)"))
case("csv-empty-name", "r.csv", b"t,,y\n0,1,2\n1,2,3\n", Err("column 2 of the header has no name"))
case("csv-unknown-names", "r.csv", b"a,b,c\n0,1,2\n1,2,3\n",
     Err("cannot tell which column is the input; available: a, b, c"))
case("csv-no-output", "r.csv", b"t,u,z\n0,1,2\n1,2,3\n", Err("cannot tell which column is the output"))
case("csv-missing-named-input", "r.csv", GOOD_CSV, Err("no input column 'volts'; available: t, u, y"), input="volts")
case("csv-missing-named-time", "r.csv", GOOD_CSV, Err("no time column 'clock'"), time="clock")
case("csv-ambiguous-input", "r.csv", rows(header="t,u,input"), Err("several columns could be the input: u, input; "
                                                                 "choose one with input="))
case("csv-ambiguous-units", "r.csv", rows(header="t,y [m],y (filtered)"), Err("several columns could be the output"),
     input="t")
case("csv-ambiguous-wanted", "r.csv", rows(header="t,Force,force [N]"), Err("several input columns match 'FORCE'"),
     input="FORCE", output="t")
case("csv-resolved-ambiguity", "r.csv", b"t,u,input,y\n" + b"".join(
    f"{float(a)!r},{float(b)!r},9,{float(c)!r}\n".encode() for a, b, c in zip(T, U, Y)), Ok(), input="u")
case("csv-same-column-twice", "r.csv", GOOD_CSV, Err("the same column is chosen for two roles"), input="y")
case("csv-one-column", "r.csv", b"1\n2\n3\n", Err("without a header must have 2 columns .* found 1 on line 1"))
case("csv-four-columns", "r.csv", b"1,2,3,4\n5,6,7,8\n", Err("found 4 on line 1"))
case("csv-two-columns-no-dt", "r.csv", rows(t=None, header=None), Err(r"no time column \(t/time\); give dt"))
case("csv-one-row", "r.csv", rows(T[:1], U[:1], Y[:1]), Err("t needs at least two samples"))
case("csv-decreasing-time", "r.csv", rows(t=T[::-1]),
     Err(r"not strictly increasing: t\[1\] = 0.06 follows t\[0\] = 0.07"))
case("csv-duplicated-time", "r.csv", rows(t=np.r_[T[:3], T[2], T[4:]]),
     Err(r"t\[3\] = 0.02 follows t\[2\] = 0.02 \(a duplicated time stamp\)"))
case("csv-constant-time", "r.csv", rows(t=np.zeros(8)), Err("a duplicated time stamp"))
case("csv-dropped-sample", "r.csv", rows(T[_DROP], U[_DROP], Y[_DROP]),
     Err(r"1 sample\(s\) missing between sample 3 \(t = 0.03 s\) and sample 4 \(t = 0.05 s\)"))
case("csv-jitter", "r.csv", rows(t=T + 0.1 * 0.01 * np.array([1, -1, 0, 1, 0, -1, 1, 0])),
     Err(r"beyond tolerance=0.001 .* pass tolerance=0\.1\d* \(--tolerance\) to accept"))
case("csv-misplaced-stamp", "r.csv", rows(t=np.r_[T[:5], 0.041, T[6:]]),
     Err(r"extra or misplaced time stamp.* sample 4"))
case("csv-gap-too-long-to-resample", "r.csv", rows(np.r_[T, 1.0], np.r_[U, 0], np.r_[Y, 0]),
     Err(r"gap of 93\*dt .* between sample 7 \(t = 0.07 s\) and sample 8 \(t = 1 s\)"), resample="linear")
case("csv-tolerance-too-big", "r.csv", GOOD_CSV, Err(r"tolerance must be in \[0, 0.5\)"), tolerance=0.7)
case("csv-tolerance-text", "r.csv", GOOD_CSV,
     Err(r"tolerance must be in \[0, 0.5\) \(a fraction of dt\), got 'big'"), tolerance="big")
case("csv-resample-unknown", "r.csv", GOOD_CSV, Err("resample must be one of"), resample="cubic")
case("csv-intersample-unknown", "r.csv", GOOD_CSV, Err("intersample must be one of"), intersample="spline")
case("csv-dt-zero", "r.csv", rows(t=None, header=None), Err("dt:? must be a positive finite number"), dt=0.0)
case("csv-dt-negative", "r.csv", rows(t=None, header=None), Err("dt:? must be a positive finite number"), dt=-0.01)
case("csv-dt-nan", "r.csv", rows(t=None, header=None), Err("dt:? must be a positive finite number"), dt=float("nan"))
case("csv-dt-text", "r.csv", rows(t=None, header=None), Err("dt:? must be a positive finite number"), dt="fast")
case("csv-dt-disagrees", "r.csv", GOOD_CSV, Err(r"dt = 0.02 disagrees with the spacing of t"), dt=0.02)
case("csv-window-empty", "r.csv", GOOD_CSV, Err("start=1.0, stop=None keep 0 sample"), start=1.0)
case("csv-window-one", "r.csv", GOOD_CSV, Err("keep 1 sample"), start=0.07)
case("csv-window-nan", "r.csv", GOOD_CSV, Err("start must be a finite time"), start=float("nan"))
case("csv-window-text", "r.csv", GOOD_CSV, Err("stop must be a finite time in seconds, got 'end'"), stop="end")
case("csv-units-row", "r.csv", b"t,u,y\ns,V,m\n0,1,2\n1,2,3\n", Err(r"line 2: column 't' holds 's', not a number"))
case("csv-excel-sep-line", "r.csv", b"sep=;\nt;u;y\n0;1;2\n1;2;3\n", Err("column 2 of the header has no name"))
case("csv-decimal-comma-in-comma-file", "r.csv", b"t,u,y\n0,0,5,1\n1,1,5,2\n", Err("line 2 has 4 fields, expected 3"))
case("csv-thousands-separator", "r.csv", b'"t","u","y"\n0,"1,000.5",2\n1,2,3\n',
     Err(r"column 'u' holds '1,000.5', not a number"))
case("csv-mixed-delimiters", "r.csv", b"t,u,y\n0,1,2\n1;2;3\n", Err("line 3 has 1 fields, expected 3"))
case("csv-unbalanced-quote", "r.csv", b't,u,y\n0,"1,2\n1,2,3\n2,3,4\n', Err("line 2"))
case("csv-html", "r.csv", b"<!DOCTYPE html><html><body>404 Not Found</body></html>\n",
     Err(r"a header \(<!DOCTYPE, html><html><body>404, Not, Found</body></html>\) but no data rows"))
case("csv-json", "r.csv", b'{"t": [0, 1], "u": [1, 2], "y": [3, 4]}\n', Err("cannot tell which column|no data rows"))
case("csv-many-columns", "r.csv", (",".join(["1"] * 10000) + "\n").encode() * 2, Err("found 10000 on line 1"))
case("csv-wide-header-no-match", "r.csv", (",".join(f"c{i}" for i in range(500)) + "\n" + ",".join(["1"] * 500)
                                           + "\n").encode(),
     Err(r"cannot tell which column is the input; available: c0, c1, .*, c11, \.\.\. \(500 in all\)"))
case("txt-mixed-tabs-blanks", "r.txt", b"t u y\n0\t1 2\n1  2\t3\n", Ok([1.0, 2], [2.0, 3], [0.0, 1]))
case("txt-tabs-header-comment", "r.txt", b"# logged by rig 3\n" + rows(sep="\t"), Ok())
case("txt-latin1", "r.txt", "t u y\n0 1 2 # 5 \xb5s\n".encode("latin-1"),
     Err(r"not UTF-8 text \(byte 0xb5 on line 2\)"))
case("txt-empty", "r.txt", b"", Err("the file is empty"))
case("txt-header-only", "r.txt", b"t u y\n", Err("but no data rows"))
case("txt-words", "r.txt", b"hello world\nthis is text\n", Err(r"line 2 has 3 fields, expected 2 \(hello, world\)"))
case("txt-only-numbers-one-line", "r.txt", b"1 2 3\n", Err("t needs at least two samples"))

# ---------------------------------------------------------------------------
# NPZ archives
# ---------------------------------------------------------------------------
case("npz-plain", "r.npz", npz(t=T, u=U, y=Y), Ok())
case("npz-compressed", "r.npz", npz(compressed=True, t=T, u=U, y=Y), Ok())
case("npz-columns", "r.npz", npz(t=T[:, None], u=U[:, None], y=Y[:, None]), Ok())
case("npz-rows", "r.npz", npz(t=T[None, :], u=U[None, :], y=Y[None, :]), Ok())
case("npz-float32", "r.npz", npz(t=T.astype(np.float32), u=U.astype(np.float32), y=Y.astype(np.float32)),
     Ok(U.astype(np.float32).astype(float), Y.astype(np.float32).astype(float)))
case("npz-ints", "r.npz", npz(t=np.arange(4), u=np.array([1, 2, 3, 4], np.int16), y=np.array([5, 6, 7, 8], np.uint8)),
     Ok([1.0, 2, 3, 4], [5.0, 6, 7, 8], [0.0, 1, 2, 3]))
case("npz-bool-input", "r.npz", npz(t=np.arange(3.0), u=np.array([True, False, True]), y=np.arange(3.0)),
     Ok([1.0, 0, 1], [0.0, 1, 2], [0.0, 1, 2]))
case("npz-extra-arrays", "r.npz", npz(t=T, u=U, y=Y, notes=np.array([1.0, 2.0])), Ok())
case("npz-no-time-dt", "r.npz", npz(u=U, y=Y), Ok(), dt=0.01)
case("npz-named", "r.npz", npz(clock=T, force=U, pos=Y), Ok(), input="force", output="pos", time="clock")
case("npz-upper-suffix", "R.NPZ", npz(t=T, u=U, y=Y), Ok())
case("npz-object", "r.npz", npz(t=T, u=np.array([1.0, "a", None], dtype=object), y=Y),
     Err(r"array 'u' holds Python objects, which are not loaded"))
case("npz-object-ragged", "r.npz", npz(t=T, u=np.array([[1.0], [1.0, 2.0]], dtype=object), y=Y),
     Err("array 'u' holds Python objects"))
case("npz-truncated", "r.npz", npz_bytes(t=T, u=U, y=Y)[:300], Err("not a readable NPZ archive|unreadable"))
case("npz-truncated-late", "r.npz", npz_bytes(t=T, u=U, y=Y)[:-40], Err("not a readable NPZ archive|unreadable"))
case("npz-garbage", "r.npz", np.random.default_rng(1).bytes(2048), Err("not a readable NPZ archive"))
case("npz-text", "r.npz", GOOD_CSV, Err("not a readable NPZ archive"))
case("npz-empty-file", "r.npz", b"", Err("the file is empty"))
case("npz-no-arrays", "r.npz", npz(), Err("the NPZ archive holds no arrays"))


def _renamed_npy(path):
    with open(path, "wb") as fh:
        np.save(fh, np.column_stack([T, U, Y]))


case("npz-renamed-npy", "r.npz", _renamed_npy, Err(r"single NumPy array \(.npy\), not an .npz archive"))


def _pickle_file(path):
    import pickle

    path.write_bytes(pickle.dumps({"t": T, "u": U, "y": Y}))


case("npz-pickle", "r.npz", _pickle_file, Err("not a readable NPZ archive"))


def _corrupt_member(path):
    raw = bytearray(npz_bytes(t=T, u=U, y=Y))
    at = raw.index(b"\x93NUMPY", raw.index(b"u.npy"))  # flip a data byte of u: CRC mismatch
    raw[at + 130] ^= 0xFF
    path.write_bytes(bytes(raw))


case("npz-bad-crc", "r.npz", _corrupt_member, Err(r"array 'u' is unreadable.*(CRC|corrupt)"))


def _zip_with_text_member(path):
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("t.npy", GOOD_CSV)
        z.writestr("u.npy", b"not an array")
        z.writestr("y.npy", b"")


case("npz-text-members", "r.npz", _zip_with_text_member, Err(r"member 't' of the archive is not a NumPy array"))
case("npz-2d-input", "r.npz", npz(t=T, u=np.column_stack([U, U]), y=Y),
     Err(r"column 'u' has shape \(8, 2\); expected a vector"))
case("npz-3d-input", "r.npz", npz(t=T, u=U.reshape(2, 2, 2), y=Y), Err(r"column 'u' has shape \(2, 2, 2\)"))
case("npz-matrix-only", "r.npz", npz(data=np.column_stack([T, U, Y])),
     Err(r"cannot tell which column is the input; available: data \(8, 3\)"))
case("npz-scalar-input", "r.npz", npz(t=T, u=np.float64(1.0), y=Y),
     Err(r"column 'u' has shape \(\); expected a vector"))
case("npz-empty-input", "r.npz", npz(t=T, u=np.zeros(0), y=Y), Err("column 'u' is empty"))
case("npz-complex", "r.npz", npz(t=T, u=U + 1j * np.r_[0, 0, 2.0, np.zeros(5)], y=Y),
     Err(r"column 'u' holds complex values \(first at sample 2: \(2\+2j\)\)"))
case("npz-complex-zero-imag", "r.npz", npz(t=T, u=U.astype(complex), y=Y), Err("column 'u' holds complex values"))
case("npz-complex-time", "r.npz", npz(t=T.astype(complex), u=U, y=Y), Err("column 't' holds complex values"))
case("npz-strings", "r.npz", npz(t=T, u=U.astype(str), y=Y), Err("column 'u' holds text, not numbers"))
case("npz-bytes", "r.npz", npz(t=T, u=U.astype("S8"), y=Y), Err("column 'u' holds text"))
case("npz-datetime", "r.npz", npz(t=np.arange(8).astype("datetime64[ms]"), u=U, y=Y),
     Err(r"column 't' holds dates \(convert them to seconds\)"))
case("npz-timedelta", "r.npz", npz(t=np.arange(8).astype("timedelta64[ms]"), u=U, y=Y),
     Err("column 't' holds time differences"))
case("npz-structured", "r.npz", npz(t=T, u=np.zeros(8, dtype=[("a", float), ("b", float)]), y=Y),
     Err("column 'u' holds a MATLAB struct or record array"))
case("npz-nan", "r.npz", npz(t=T, u=U, y=np.r_[Y[:5], np.nan, Y[6:]]),
     Err("y contains 1 non-finite value.*NaN at sample 5"))
case("npz-length-mismatch", "r.npz", npz(t=T, u=U[:7], y=Y), Err("length mismatch: u has 7 samples but y has 8"))
case("npz-time-mismatch", "r.npz", npz(t=T[:6], u=U, y=Y), Err("length mismatch: t has 6 samples"))
case("npz-missing-output", "r.npz", npz(t=T, u=U), Err("cannot tell which column is the output"))
case("npz-jitter", "r.npz", npz(t=T + 0.01 * np.r_[0, 0.2, 0, 0, 0, 0, 0, 0], u=U, y=Y),
     Err(r"sample 1 \(t = 0.012 s\) is 0.2\d*\*dt away"))

# ---------------------------------------------------------------------------
# MAT files
# ---------------------------------------------------------------------------
case("mat-plain", "r.mat", mat({"t": T, "u": U, "y": Y}), Ok())
case("mat-columns", "r.mat", mat({"t": T[:, None], "u": U[:, None], "y": Y[:, None]}), Ok())
case("mat-names-given", "r.mat", mat({"t": T, "vir": U, "qm": Y}), Ok(), input="vir", output="qm")
case("mat-v4", "r.mat", mat({"t": T, "u": U, "y": Y}, format="4"), Ok())
case("mat-compressed", "r.mat", mat({"t": T, "u": U, "y": Y}, do_compression=True), Ok())
case("mat-ints", "r.mat", mat({"t": np.arange(3, dtype=np.int32), "u": np.array([1, 2, 3], np.int8),
                               "y": np.array([4, 5, 6], np.uint16)}), Ok([1.0, 2, 3], [4.0, 5, 6], [0.0, 1, 2]))
case("mat-sparse", "r.mat", mat({"t": T, "u": scipy.sparse.csc_matrix(U[:, None]), "y": Y}), Ok())
case("mat-upper-suffix", "R.MAT", mat({"t": T, "u": U, "y": Y}), Ok())
case("mat-no-time-dt", "r.mat", mat({"u": U, "y": Y}), Ok(), dt=0.01)
case("mat-struct", "r.mat", mat({"t": T, "u": {"a": U}, "y": Y}), Err("column 'u' holds a MATLAB struct"))
case("mat-cell", "r.mat", mat({"t": T, "u": np.array([U, U[:3]], dtype=object), "y": Y}),
     Err("column 'u' holds Python objects or a MATLAB cell array"))
case("mat-string", "r.mat", mat({"t": T, "u": "hello", "y": Y}), Err("column 'u' holds text"))
case("mat-complex", "r.mat", mat({"t": T, "u": U + 1j, "y": Y}),
     Err(r"column 'u' holds complex values \(first at sample 0"))
case("mat-2d", "r.mat", mat({"t": T, "u": np.column_stack([U, U]), "y": Y}), Err(r"column 'u' has shape \(8, 2\)"))
case("mat-empty-var", "r.mat", mat({"t": T, "u": np.zeros((0, 0)), "y": Y}), Err("column 'u' is empty"))
case("mat-nan", "r.mat", mat({"t": T, "u": np.r_[np.nan, U[1:]], "y": Y}),
     Err("u contains 1 non-finite value.*NaN at sample 0"))
case("mat-no-variables", "r.mat", mat({}), Err("the MAT file holds no variables"))
case("mat-garbage", "r.mat", np.random.default_rng(2).bytes(4096), Err("not a readable MAT file"))
case("mat-text", "r.mat", GOOD_CSV, Err("not a readable MAT file"))
case("mat-empty-file", "r.mat", b"", Err("the file is empty"))
case("mat-truncated", "r.mat", mat_bytes({"t": T, "u": U, "y": Y})[:200], Err("not a readable MAT file"))
case("mat-truncated-header", "r.mat", mat_bytes({"t": T, "u": U, "y": Y})[:100], Err("not a readable MAT file"))
case("mat-npz-inside", "r.mat", npz_bytes(t=T, u=U, y=Y), Err("not a readable MAT file"))
_HDF5_HEADER = (b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
                .ljust(116) + b"\x00" * 8 + b"\x00\x02" + b"IM")
case("mat-v73", "r.mat", _HDF5_HEADER + b"\x89HDF\r\n\x1a\n" + b"\x00" * 512,
     Err(r"v7.3 \(HDF5\) MAT files are not supported"))
case("mat-missing-input", "r.mat", mat({"t": T, "force": U, "y": Y}),
     Err("cannot tell which column is the input; available: t .*force"))
case("mat-length-mismatch", "r.mat", mat({"t": T, "u": U[:5], "y": Y}), Err("length mismatch"))
case("mat-decreasing", "r.mat", mat({"t": T[::-1], "u": U, "y": Y}), Err("not strictly increasing"))
case("mat-gap", "r.mat", mat({"t": T[_DROP], "u": U[_DROP], "y": Y[_DROP]}),
     Err(r"1 sample\(s\) missing between sample 3"))

# ---------------------------------------------------------------------------
# paths and file types
# ---------------------------------------------------------------------------
for suffix in (".xlsx", ".json", ".h5", ".npy", ".dat", ".csv.gz", ".parquet"):
    case(f"type{suffix}", f"r{suffix}", GOOD_CSV,
         Err(rf"unsupported file type '{re.escape('.' + suffix.rsplit('.', 1)[-1])}'; use .csv, .txt, .mat, .npz"))
case("type-no-suffix", "record", GOOD_CSV, Err(r"unsupported file type '\(no suffix\)'"))
case("path-missing", None, None, Err("data file not found"))
case("path-wrong-type", "", None, Err("path must be a file name or path, got 3"))
case("column-name-not-text", "r.csv", GOOD_CSV, Err("no input column '7'"), input=7)


def _folder(path):
    path.mkdir()


case("path-folder", "folder.csv", _folder, Err("is a folder; give the data file itself"))


def _build(c, tmp_path):
    if c.name is None:
        return tmp_path / "does-not-exist.csv"
    if c.name == "":
        return 3
    path = tmp_path / c.name
    if callable(c.build):
        c.build(path)
    else:
        path.write_bytes(c.build)
    return path


@pytest.mark.parametrize("c", CASES, ids=[c.id for c in CASES])
def test_hostile_file(c, tmp_path):
    path = _build(c, tmp_path)
    if isinstance(c.expect, Err):
        with pytest.raises(DataError) as exc:  # any other exception type fails the test
            read_record(path, **c.kwargs)
        msg = str(exc.value)
        assert re.search(c.expect.pattern, msg), msg
        assert "\n" not in msg and len(msg) < MAX_MESSAGE + len(str(path))
        assert "Traceback" not in msg
        return
    d = read_record(path, **c.kwargs)
    np.testing.assert_allclose(d.u, c.expect.u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(d.y, c.expect.y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(d.t, c.expect.t, rtol=1e-15, atol=1e-15)
    t = np.asarray(c.expect.t, dtype=float)
    assert d.dt == pytest.approx(t[1] - t[0], rel=1e-12)
    assert d.intersample == c.expect.intersample


def test_constant_output_loads_but_is_not_identifiable(tmp_path):
    path = tmp_path / "flat.csv"
    path.write_bytes(rows(y=np.full(8, 0.25)))
    d = read_record(path)
    assert np.all(d.y == 0.25)
    with pytest.raises(DataError, match=r"output y is constant \(every sample is 0.25\); nothing to identify"):
        d.check_identifiable()


_CLI_FLAGS = {"input": "--input", "output": "--output", "time": "--time", "dt": "--dt"}
CLI_CASES = [c for c in CASES if isinstance(c.expect, Err) and c.name != "" and set(c.kwargs) <= set(_CLI_FLAGS)
             and all(isinstance(v, str) if k != "dt" else isinstance(v, float) and np.isfinite(v)
                     for k, v in c.kwargs.items())]


@pytest.mark.parametrize("c", CLI_CASES, ids=[c.id for c in CLI_CASES])
def test_hostile_file_through_the_cli(c, tmp_path, capsys):
    """The command line turns each refused file into exit 2 and one line naming the problem."""
    from hammerstein_ctrl.cli import main

    path = _build(c, tmp_path)
    argv = ["identify", "--data", str(path), "--structure", "trs"]
    for key, value in c.kwargs.items():
        argv += [_CLI_FLAGS[key], str(value)]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    first, *rest = err.splitlines()
    assert first.startswith("hammerstein-ctrl: error: ") and re.search(c.expect.pattern, first), err
    assert not rest and "Traceback" not in err
