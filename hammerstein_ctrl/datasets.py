"""Input/output records and the two case-study datasets.

* :class:`IOData` is a validated single-input single-output record on a
  uniform time grid (``t, u, y, dt, name``), in the spirit of
  ``nonlinear_benchmarks.Input_output_data``: it unpacks as ``u, y = data`` and
  slices as ``data[:12000]``.
* :func:`load_emps` reads the real EMPS benchmark (Janot, Gautier & Brunot,
  2019).  The files are third-party data and are not shipped; they are found
  through an explicit ``path``, then ``$HAMMERSTEIN_CTRL_DATA/emps``, then the
  ``nonlinear-benchmarks`` package (which downloads them).
* :func:`load_trs` returns the bundled TRS *reconstruction* and
  :func:`make_trs_reconstruction` regenerates it (the paper's TRS measurements
  are not public; see ``data/README.md``).
* :func:`read_record` reads a user's own CSV, MAT or NPZ file.

Examples
--------
>>> import numpy as np
>>> from hammerstein_ctrl.datasets import IOData
>>> d = IOData(u=np.zeros(5), y=np.arange(5.0), dt=0.5, name="toy")
>>> d
IOData('toy', N=5, dt=0.5 s, t=[0, 2] s)
>>> u, y = d
>>> d[1:3].t
array([0.5, 1. ])
"""

from __future__ import annotations

import csv
import functools
import os
from pathlib import Path

import numpy as np

from ._checks import GRID_TOLERANCE, as_signal, check_intersample, uniform_grid
from .exceptions import DataError

__all__ = [
    "IOData",
    "DataNotFoundError",
    "load_emps",
    "load_trs",
    "make_trs_reconstruction",
    "read_record",
    "TRS_TRUE_BETA",
    "TRS_SEED",
    "ENV_DATA",
]

#: Environment variable naming the data directory (containing ``emps/``).
ENV_DATA = "HAMMERSTEIN_CTRL_DATA"


class DataNotFoundError(DataError, FileNotFoundError):
    """A data file could not be located."""


class IOData:
    """A SISO input/output record on a uniform time grid.

    Parameters
    ----------
    u, y : array_like, shape (N,)
        Input and output samples (``(N, 1)`` columns are accepted).
    t : array_like, shape (N,), optional
        Sample times.  Must be strictly increasing and uniform to within
        ``tolerance * dt``; it is then regularised to exactly ``t0 + k*dt``.
    dt : float, optional
        Sampling interval, used when ``t`` is not given (``t = k*dt``).
    name : str
        Label used in reports and plots.
    input_name, output_name, input_unit, output_unit : str
        Labels and units used on plot axes.
    tolerance : float, default 1e-3
        Allowed deviation of ``t`` from the uniform grid, as a fraction of dt.
    intersample : {"foh", "zoh"}, default "foh"
        How the input behaves between samples, as MATLAB's ``iddata``
        ``InterSample`` property: ``"foh"`` (linear between samples, the
        paper's semantics) or ``"zoh"`` (held constant, as from a DAC).
        Simulation and identification on this record honour it exactly.

    Raises
    ------
    DataError
        On NaN/inf samples, empty or mismatched signals, a non-increasing or
        irregular time grid, or a missing/invalid ``dt``.
    """

    def __init__(
        self,
        u,
        y,
        t=None,
        *,
        dt: float | None = None,
        name: str = "data",
        input_name: str = "u",
        output_name: str = "y",
        input_unit: str = "",
        output_unit: str = "",
        tolerance: float = GRID_TOLERANCE,
        intersample: str = "foh",
    ):
        self.intersample = check_intersample(intersample)
        u = as_signal(u, "u")
        y = as_signal(y, "y")
        if u.size != y.size:
            raise DataError(f"length mismatch: u has {u.size} samples but y has {y.size}")
        if t is not None:
            t_arr = as_signal(t, "t")
            if t_arr.size != u.size:
                raise DataError(f"length mismatch: t has {t_arr.size} samples but u and y have {u.size}")
            t_grid, step = uniform_grid(t_arr, tolerance=tolerance)
            if dt is not None and not np.isclose(step, dt, rtol=tolerance, atol=0):
                raise DataError(f"dt = {dt!r} disagrees with the spacing of t ({step!r})")
        else:
            if dt is None:
                raise DataError("give the sample times t or the sampling interval dt")
            if not (np.isfinite(dt) and dt > 0):
                raise DataError(f"dt must be a positive finite number, got {dt!r}")
            step = float(dt)
            t_grid = step * np.arange(u.size)
        if u.size < 2:
            raise DataError("a record needs at least two samples")
        for a in (t_grid, u, y):
            a.setflags(write=False)
        self.t, self.u, self.y, self.dt = t_grid, u, y, float(step)
        self.name = str(name)
        self.input_name, self.output_name = input_name, output_name
        self.input_unit, self.output_unit = input_unit, output_unit

    # -- container protocol -------------------------------------------------
    def __len__(self) -> int:
        return self.u.size

    def __iter__(self):
        return iter((self.u, self.y))

    def __getitem__(self, index) -> "IOData":
        if not isinstance(index, slice):
            raise TypeError("IOData supports slicing only, e.g. data[:12000] or data[::2]")
        start, stop, step = index.indices(len(self))
        if step <= 0:
            raise DataError("IOData slices must have a positive step (time runs forward)")
        idx = np.arange(start, stop, step)
        if idx.size < 2:
            raise DataError(f"slice {index} leaves {idx.size} sample(s); a record needs at least two")
        return self._replace(u=self.u[idx], y=self.y[idx], t=self.t[idx])

    def _replace(self, **changes) -> "IOData":
        kw = dict(
            u=self.u, y=self.y, t=self.t, name=self.name, input_name=self.input_name,
            output_name=self.output_name, input_unit=self.input_unit, output_unit=self.output_unit,
            intersample=self.intersample,
        )
        kw.update(changes)
        return IOData(**kw)

    # -- convenience ----------------------------------------------------------
    @property
    def sampling_time(self) -> float:
        """Alias of :attr:`dt` (the name used by ``nonlinear_benchmarks``)."""
        return self.dt

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]``."""
        return float(self.t[-1] - self.t[0])

    def segment(self, start: float | None = None, stop: float | None = None) -> "IOData":
        """Samples with ``start <= t < stop`` (seconds); ``None`` means open-ended."""
        lo = 0 if start is None else int(np.ceil((start - self.t[0]) / self.dt - 1e-9))
        hi = len(self) if stop is None else int(np.ceil((stop - self.t[0]) / self.dt - 1e-9))
        return self[max(lo, 0) : max(hi, 0)]

    def to_csv(self, path) -> Path:
        """Write ``t,u,y`` with full precision (readable by :func:`read_record`)."""
        path = Path(path)
        header = (
            f"# {self.name}\n# input: {self.input_name} [{self.input_unit}], "
            f"output: {self.output_name} [{self.output_unit}], dt = {self.dt!r} s\nt,u,y"
        )
        np.savetxt(path, np.column_stack([self.t, self.u, self.y]), delimiter=",", fmt="%.17g",
                   header=header, comments="")
        return path

    def __repr__(self) -> str:
        return (
            f"IOData({self.name!r}, N={len(self)}, dt={self.dt:g} s, "
            f"t=[{self.t[0]:g}, {self.t[-1]:g}] s)"
        )


# ---------------------------------------------------------------------------
# EMPS
# ---------------------------------------------------------------------------
_EMPS_FILES = {"estimation": "DATA_EMPS.mat", "validation": "DATA_EMPS_PULSES.mat"}

_EMPS_HELP = """\
The EMPS benchmark files ({file}) were not found. Looked in:
{looked}
Get them in one of these ways:
  1. download EMPS.zip from https://www.nonlinearbenchmark.org/benchmarks/emps, unzip it and
     pass the folder:  load_emps(path="/path/to/EMPS")
  2. or point the environment variable {env} at a folder holding emps/{file}:
     export {env}=/path/to/data
  3. or `pip install nonlinear-benchmarks` (downloads the files on first use)."""


def _emps_from_benchmark_package(file: str) -> Path | None:
    try:
        import nonlinear_benchmarks
    except ImportError:
        return None
    try:  # pragma: no cover - needs the optional package and the internet
        locations = nonlinear_benchmarks.EMPS(data_file_locations=True)
    except Exception:  # pragma: no cover
        return None
    stack = [locations]  # pragma: no cover
    while stack:  # pragma: no cover
        item = stack.pop()
        if isinstance(item, (list, tuple)):
            stack.extend(item)
        elif isinstance(item, (str, os.PathLike)):
            p = Path(item)
            for cand in (p, p / file, p.parent / file):
                if cand.name == file and cand.is_file():
                    return cand
    return None  # pragma: no cover


def _locate_emps(file: str, path) -> Path:
    looked = []
    candidates = []
    if path is not None:
        p = Path(path).expanduser()
        candidates += [p] if p.suffix == ".mat" else [p / file, p / "emps" / file]
    env = os.environ.get(ENV_DATA)
    if env:
        candidates += [Path(env).expanduser() / "emps" / file, Path(env).expanduser() / file]
    for cand in candidates:
        looked.append(f"  - {cand}")
        if cand.is_file():
            return cand
    if not env:
        looked.append(f"  - ${ENV_DATA}/emps/{file} (variable not set)")
    found = _emps_from_benchmark_package(file)
    if found is not None:  # pragma: no cover
        return found
    looked.append("  - the nonlinear-benchmarks package (not installed or download failed)")
    raise DataNotFoundError(_EMPS_HELP.format(file=file, looked="\n".join(looked), env=ENV_DATA))


@functools.lru_cache(maxsize=4)
def _read_emps(file: str, mtime: float):
    import scipy.io

    m = scipy.io.loadmat(file)
    missing = [k for k in ("t", "vir", "qm") if k not in m]
    if missing:
        raise DataError(f"{file} is not an EMPS file: missing variable(s) {missing}")
    return m["t"].ravel(), m["vir"].ravel(), m["qm"].ravel()


def load_emps(kind: str = "estimation", duration: float | None = None, path=None) -> IOData:
    """Load the EMPS benchmark record (input ``vir`` force in N, output ``qm`` position in m).

    Parameters
    ----------
    kind : {"estimation", "validation"}
        ``DATA_EMPS.mat`` or ``DATA_EMPS_PULSES.mat`` (24 841 samples at 1 kHz each).
    duration : float, optional
        Keep the first ``duration`` seconds (the paper uses 12 s = 12 000 samples).
    path : str or Path, optional
        A ``.mat`` file or a folder holding it (directly or in ``emps/``).

    Returns
    -------
    IOData

    Raises
    ------
    DataNotFoundError
        With instructions for obtaining the files.

    Examples
    --------
    With the files in ``$HAMMERSTEIN_CTRL_DATA/emps`` (exercised by ``tests/test_datasets.py``)::

        d = load_emps(duration=12)      # the paper's first 12 s
        len(d), d.dt                    # (12000, 0.001)
    """
    if kind not in _EMPS_FILES:
        raise DataError(f"unknown EMPS record {kind!r}; choose 'estimation' or 'validation'")
    file = _locate_emps(_EMPS_FILES[kind], path)
    t, u, y = _read_emps(str(file), file.stat().st_mtime)
    data = IOData(
        u, y, t, name=f"EMPS {kind}", input_name="force vir", output_name="position qm",
        input_unit="N", output_unit="m",
    )
    if duration is not None:
        n = int(round(duration / data.dt))
        if not 2 <= n <= len(data):
            raise DataError(
                f"duration {duration!r} s gives {n} samples; the record has {len(data)} "
                f"({data.duration:g} s)"
            )
        data = data[:n]
    return data


# ---------------------------------------------------------------------------
# TRS reconstruction
# ---------------------------------------------------------------------------
#: The "true" TRS system of the reconstruction: Table 4's N-SPSA column with the
#: sign of b0 corrected (printed +1.8160; every other column and the initial point
#: are negative, and the sign decides on which side of the imaginary axis the zero
#: lies, so it is taken as a typo).  Order: [b0, a0, a1, d0, d1].
TRS_TRUE_BETA = (-1.8160, 0.1180, 4.7681, -4.7132, 0.1229)
#: Seed of the bundled reconstruction.
TRS_SEED = 20250101
_TRS_FILE = "trs_reconstruction.csv"


def make_trs_reconstruction(
    seed=TRS_SEED,
    *,
    duration: float = 600.0,
    dt: float = 0.1,
    noise_std: float = 0.17,
    noise_sse: float | None = 178.5,
) -> IOData:
    """Generate the TRS reconstruction (DESIGN.md section 2 recipe).

    1. ``u``: i.i.d. uniform on [-1, 1] V, one value per sample (drawn first);
    2. ``y_true``: the true model :data:`TRS_TRUE_BETA` simulated with the
       sampled FOH semantics from rest;
    3. ``e``: white Gaussian noise with standard deviation ``noise_std`` (drawn
       second), rescaled so that ``sum(e**2) == noise_sse`` exactly, which makes
       J at the true parameters equal ``noise_sse`` for every seed
       (Table 3's best N-SPSA value is 178.49);
    4. ``y = y_true + e``.

    Parameters
    ----------
    seed : int or numpy.random.Generator
    duration, dt : float
        600 s at 0.1 s gives 6 001 samples.
    noise_std : float
    noise_sse : float or None
        Target sum of squares of the noise; ``None`` keeps the raw draw.

    Returns
    -------
    IOData
    """
    from .nonlinearities import Tanh
    from .simulate import simulate

    rng = np.random.default_rng(seed)
    n = int(round(duration / dt)) + 1
    t = dt * np.arange(n)
    u = rng.uniform(-1.0, 1.0, n)
    b0, a0, a1, d0, d1 = TRS_TRUE_BETA
    y_true = simulate(([1.0, b0], [1.0, a1, a0]), Tanh(), [d0, d1], t, u)
    e = rng.normal(0.0, noise_std, n)
    if noise_sse is not None:
        e *= np.sqrt(noise_sse / np.sum(e**2))
    return IOData(
        u, y_true + e, t, name="TRS reconstruction", input_name="voltage u",
        output_name="pitch y", input_unit="V", output_unit="rad",
    )


def _bundled(name: str) -> Path:
    here = Path(__file__).resolve().parent
    for cand in (here / "_bundled" / name, here.parent / "data" / name):
        if cand.is_file():
            return cand
    raise DataNotFoundError(
        f"bundled file {name} is missing from the installation; regenerate it with "
        "make_trs_reconstruction() or reinstall hammerstein_ctrl"
    )


def load_trs() -> IOData:
    """The bundled TRS reconstruction (600 s at 0.1 s, 6 001 samples).

    Generated by :func:`make_trs_reconstruction` with :data:`TRS_SEED`; see
    ``data/README.md``.  J at :data:`TRS_TRUE_BETA` is 178.5.
    """
    rec = read_record(_bundled(_TRS_FILE), name="TRS reconstruction")
    return rec._replace(input_name="voltage u", output_name="pitch y", input_unit="V", output_unit="rad")


# ---------------------------------------------------------------------------
# user files
# ---------------------------------------------------------------------------
_TIME_NAMES = ("t", "time", "Time", "T")
_INPUT_NAMES = ("u", "input", "vir", "U")
_OUTPUT_NAMES = ("y", "output", "qm", "Y")


def _pick(columns: dict, wanted, defaults, role: str, path) -> np.ndarray | None:
    if wanted is not None:
        if wanted not in columns:
            raise DataError(
                f"{path}: no {role} column {wanted!r}; available: {', '.join(columns)}"
            )
        return columns[wanted]
    for name in defaults:
        if name in columns:
            return columns[name]
    return None


def _read_csv_columns(path: Path) -> dict:
    with open(path, newline="") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise DataError(f"{path}: no data rows")

    def numeric(row):
        try:
            [float(x) for x in row]
            return True
        except ValueError:
            return False

    if numeric(rows[0]):
        names = {2: ["u", "y"], 3: ["t", "u", "y"]}.get(len(rows[0]))
        if names is None:
            raise DataError(
                f"{path}: a CSV without a header must have 2 columns (u, y) or 3 (t, u, y), "
                f"found {len(rows[0])}"
            )
        body = rows
    else:
        names = [c.strip() for c in rows[0]]
        body = rows[1:]
    values = np.empty((len(body), len(names)))
    for i, row in enumerate(body):
        if len(row) != len(names):
            raise DataError(f"{path}: data row {i + 1} has {len(row)} fields, expected {len(names)}")
        try:
            values[i] = [float(x) for x in row]
        except ValueError:
            raise DataError(f"{path}: data row {i + 1} has a non-numeric field: {row}") from None
    return {n: values[:, j] for j, n in enumerate(names)}


def read_record(
    path,
    *,
    input: str | None = None,
    output: str | None = None,
    time: str | None = None,
    dt: float | None = None,
    name: str | None = None,
) -> IOData:
    """Read a user's input/output record from a CSV, MAT or NPZ file.

    Accepted layouts:

    * **CSV** with a header row naming the columns (``#`` lines are comments);
      by default the time column is ``t``/``time``, the input ``u``/``input``/``vir``
      and the output ``y``/``output``/``qm``.  Without a header, 3 columns mean
      ``t, u, y`` and 2 columns ``u, y`` (then ``dt`` is required).
    * **MAT** (``scipy.io.loadmat``) or **NPZ** files with one vector per
      variable, named as above (e.g. the EMPS files work unchanged).

    Parameters
    ----------
    path : str or Path
    input, output, time : str, optional
        Column/variable names overriding the defaults.
    dt : float, optional
        Sampling interval when the file has no time column.
    name : str, optional
        Record name (defaults to the file name).

    Raises
    ------
    DataNotFoundError
        If the file does not exist.
    DataError
        For an unknown format or column, non-numeric fields, or any problem
        :class:`IOData` detects.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise DataNotFoundError(f"data file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt"):
        columns = _read_csv_columns(path)
    elif suffix == ".mat":
        import scipy.io

        try:
            raw = scipy.io.loadmat(path)
        except Exception as exc:
            raise DataError(f"{path}: cannot read MAT file: {exc}") from None
        columns = {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
    elif suffix == ".npz":
        with np.load(path) as raw:
            columns = {k: raw[k] for k in raw.files}
    else:
        raise DataError(f"{path}: unsupported file type {suffix!r}; use .csv, .mat or .npz")
    u = _pick(columns, input, _INPUT_NAMES, "input", path)
    y = _pick(columns, output, _OUTPUT_NAMES, "output", path)
    t = _pick(columns, time, _TIME_NAMES, "time", path)
    if u is None or y is None:
        role = "input" if u is None else "output"
        raise DataError(
            f"{path}: cannot tell which column is the {role}; available: {', '.join(columns)} "
            f"(name it with input=/output=, or --input/--output on the command line)"
        )
    if t is None and dt is None:
        raise DataError(f"{path}: no time column ({'/'.join(_TIME_NAMES)}); give dt")
    return IOData(u, y, t if t is not None else None, dt=dt if t is None else None,
                  name=name or path.stem)
