"""The two case-study datasets, and the record type and reader they use.

* :class:`IOData` (from :mod:`hammerstein_ctrl.data`) is a validated
  single-input single-output record on a uniform time grid (``t, u, y, dt,
  name``), in the spirit of ``nonlinear_benchmarks.Input_output_data``: it
  unpacks as ``u, y = data`` and slices as ``data[:12000]``.
* :func:`load_emps` reads the real EMPS benchmark (Janot, Gautier & Brunot,
  2019).  The files are third-party data and are not shipped; they are found
  through an explicit ``path`` (and only there when it is given), else
  ``$HAMMERSTEIN_CTRL_DATA/emps``, then the ``nonlinear-benchmarks`` package
  (which downloads them).
* :func:`load_trs` returns the bundled TRS *reconstruction* and
  :func:`make_trs_reconstruction` regenerates it (the paper's TRS measurements
  are not public; see ``data/README.md``).
* :func:`read_record` (from :mod:`hammerstein_ctrl.data`) reads a user's
  own CSV, text, MAT or NPZ file.

Examples
--------
>>> d = load_trs()
>>> d
IOData('TRS reconstruction', N=6001, dt=0.1 s, t=[0, 600] s)
>>> u, y = d[:3000]
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from ..exceptions import DataError
from ..data._iodata import IOData
from ..data._records import DataNotFoundError, read_record
from .._safe_io import MAX_INPUT_BYTES, check_input

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
#: The EMPS files' variables: time, input (the motor force ``vir``) and output (the position ``qm``).
EMPS_COLUMNS = {"time": "t", "input": "vir", "output": "qm"}


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
    """The EMPS file: only under an explicit ``path`` when one is given, else the usual places."""
    looked = []
    if path is not None:
        p = Path(path).expanduser()
        if p.exists() and not p.is_dir() and p.suffix.lower() != ".mat":
            raise DataError(f"{p} is neither a folder nor a .mat file: give the folder holding {file} "
                            "(or that file itself)")
        if p.suffix.lower() == ".mat" and (p.exists() or p.is_symlink()):
            check_input(p, limit=MAX_INPUT_BYTES, what="EMPS file")      # a regular file, not a FIFO or device
        candidates = [p] if p.suffix.lower() == ".mat" else [p / file, p / "emps" / file]
    else:
        env = os.environ.get(ENV_DATA)
        candidates = [Path(env).expanduser() / "emps" / file, Path(env).expanduser() / file] if env else []
    for cand in candidates:
        looked.append(f"  - {cand}")
        if cand.is_file():
            return cand
    if path is not None:
        looked.append(f"  (an explicit path is the only place searched; ${ENV_DATA} is not used)")
    else:
        if not candidates:
            looked.append(f"  - ${ENV_DATA}/emps/{file} (variable not set)")
        found = _emps_from_benchmark_package(file)
        if found is not None:  # pragma: no cover
            return found
        looked.append("  - the nonlinear-benchmarks package (not installed or download failed)")
    raise DataNotFoundError(_EMPS_HELP.format(file=file, looked="\n".join(looked), env=ENV_DATA))


@functools.lru_cache(maxsize=4)
def _read_emps(file: str, mtime: float):
    import scipy.io

    try:
        m = scipy.io.loadmat(file)
    except Exception as exc:  # noqa: BLE001 - a parser of foreign files can raise anything
        raise DataError(f"{file} is not a readable MAT file ({type(exc).__name__}: {exc})") from None
    missing = [k for k in EMPS_COLUMNS.values() if k not in m]
    if missing:
        raise DataError(f"{file} is not an EMPS file: missing variable(s) {missing}")
    return tuple(m[EMPS_COLUMNS[k]].ravel() for k in ("time", "input", "output"))


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
        When given, it is the only place searched.

    Returns
    -------
    IOData

    Raises
    ------
    DataNotFoundError
        Naming the places searched, with instructions for obtaining the files.

    Examples
    --------
    With the files in ``$HAMMERSTEIN_CTRL_DATA/emps`` (exercised by ``tests/paper/test_datasets.py``)::

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
    """Generate the TRS reconstruction by this recipe.

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
    from ..blocks._families import Tanh
    from ..simulate._simulate import simulate

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
    here = Path(__file__).resolve().parent.parent         # the package folder (this file is in paper/)
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
