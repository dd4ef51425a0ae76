"""The EMPS as a Lur'e loop: friction on the carriage's velocity, and the position loop the records come from.

The EMPS records (Janot, Gautier and Brunot's benchmark) hold, besides the
motor input ``vir`` and position ``qm``: the reference ``qg``, the position
and velocity gains ``kp`` and ``kv`` of the cascade controller, the drive
gain ``gtau`` (newtons per unit of ``vir``) and, in ``DATA_EMPS_PULSES``, the
force pulses ``pulses_N`` added to the controller's output.  The controller is

.. code-block:: text

    vir_k = kv (kp (qg_k - qm_k) - (qm_k - qm_{k-1}) / dt) + pulses_k

(velocity by backward difference; on ``DATA_EMPS`` this reproduces the
recorded ``vir`` at 96.7 % fit, and on ``DATA_EMPS_PULSES`` the pulses enter
with a measured factor of 1.014).

The published physical (IDIM-LS) identification of the carriage: mass
91.2 kg, viscous friction 194 N s/m, Coulomb friction 21.5 N, offset -3.2 N.
A Lur'e model ``b / (p^2 + a1 p)`` with ``Friction`` on velocity holds the same
quantities: ``mass = gtau / b``, ``viscous = a1 mass``, ``coulomb = gtau fc``,
``offset = gtau c``.
"""

from __future__ import annotations

import numpy as np

from .datasets import _EMPS_FILES, _locate_emps
from ..exceptions import DataError, ParameterError
from ..fit._in_loop import KnownLoop
from ..data._iodata import IOData
from ..blocks._lure import LureStructure, lure_structure

__all__ = ["EMPS_PHYSICAL", "EMPS_LOOP_VARIABLES", "emps_lure_structure", "emps_controller", "load_emps_loop",
           "physical_beta", "physical_parameters"]

#: The published physical identification of the EMPS carriage (IDIM-LS): kg, N s/m, N, N.
EMPS_PHYSICAL = {"mass": 91.2, "viscous": 194.0, "coulomb": 21.5, "offset": -3.2}
#: Variables of the EMPS files that describe the loop.
EMPS_LOOP_VARIABLES = {"time": "t", "input": "vir", "output": "qm", "reference": "qg", "added": "pulses_N",
                       "kp": "kp", "kv": "kv", "gtau": "gtau"}


def emps_lure_structure(**options) -> LureStructure:
    """``b / (p^2 + a1 p)`` from ``vir`` to position, ``Friction`` (``|fc| sign(v) + c``) on velocity.

    Examples
    --------
    >>> emps_lure_structure().param_names
    ('b0', 'a1', 'fc', 'c')
    """
    return lure_structure(0, 2, **options)


def emps_controller(kp: float, kv: float, dt: float):
    """The EMPS position loop as a discrete python-control system on ``[qg, qm]`` (state: the last ``qm``).

    Examples
    --------
    >>> K = emps_controller(160.18, 243.45, 1e-3)
    >>> K.ninputs, K.noutputs, K.dt
    (2, 1, 0.001)
    """
    import control as ct

    for name, value in (("kp", kp), ("kv", kv), ("dt", dt)):
        if not (np.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number, got {value!r}")
    return ct.ss([[0.0]], [[0.0, 1.0]], [[kv / dt]], [[kv * kp, -(kv * kp + kv / dt)]], dt,
                 inputs=["qg", "qm"], outputs=["vir"], name="emps_position_loop")


def load_emps_loop(kind: str = "estimation", path=None):
    """``(record, loop, gains)`` of an EMPS file: the record (``vir`` in, ``qm`` out, zero-order hold: the
    drive holds ``vir`` between samples), the :class:`~hammerstein_ctrl.fit.KnownLoop` it was measured in
    (the controller from the stored gains, the reference ``qg``, the pulses), and ``{"kp", "kv", "gtau"}``.

    Parameters
    ----------
    kind : {"estimation", "validation"}
    path : str or Path, optional
        As for :func:`~hammerstein_ctrl.paper.datasets.load_emps`.
    """
    import scipy.io

    if kind not in _EMPS_FILES:
        raise DataError(f"unknown EMPS record {kind!r}; choose 'estimation' or 'validation'")
    file = _locate_emps(_EMPS_FILES[kind], path)
    try:
        m = scipy.io.loadmat(str(file))
    except Exception as exc:  # noqa: BLE001 - a parser of foreign files can raise anything
        raise DataError(f"{file} is not a readable MAT file ({type(exc).__name__}: {exc})") from None
    need = [v for k, v in EMPS_LOOP_VARIABLES.items() if k != "added"]
    missing = [v for v in need if v not in m]
    if missing:
        raise DataError(f"{file} is not an EMPS loop file: missing variable(s) {missing}")
    var = {k: np.asarray(m[v], dtype=float).ravel() for k, v in EMPS_LOOP_VARIABLES.items() if v in m}
    dt = float(np.median(np.diff(var["time"])))
    record = IOData(var["input"], var["output"], dt=dt, intersample="zoh", name=f"EMPS {kind} (loop)",
                    input_name="vir", output_name="qm", output_unit="m")
    gains = {k: float(var[k][0]) for k in ("kp", "kv", "gtau")}
    loop = KnownLoop(emps_controller(gains["kp"], gains["kv"], dt), var["reference"], var.get("added"),
                     initial_state=[var["output"][0]])
    return record, loop, gains


def physical_beta(gtau: float, physical: dict = EMPS_PHYSICAL) -> np.ndarray:
    """The :func:`emps_lure_structure` parameters of a physical model (default the published one).

    Examples
    --------
    >>> physical_beta(35.15).round(4).tolist()
    [0.3854, 2.1272, 0.6117, -0.091]
    """
    if not (np.isfinite(gtau) and gtau > 0):
        raise ParameterError(f"gtau must be a positive number, got {gtau!r}")
    mass = physical["mass"]
    return np.array([gtau / mass, physical["viscous"] / mass, physical["coulomb"] / gtau, physical["offset"] / gtau])


def physical_parameters(beta, gtau: float) -> dict:
    """Mass, viscous and Coulomb friction and offset of an :func:`emps_lure_structure` fit (inverse of
    :func:`physical_beta`).

    Examples
    --------
    >>> {k: round(v, 1) for k, v in physical_parameters(physical_beta(35.15), 35.15).items()}
    {'mass': 91.2, 'viscous': 194.0, 'coulomb': 21.5, 'offset': -3.2}
    """
    beta = np.asarray(beta, dtype=float).reshape(-1)
    if beta.size < 4 or not (np.isfinite(gtau) and gtau > 0):
        raise ParameterError(f"physical_parameters needs [b0, a1, fc, c] and a positive gtau, got {beta.tolist()} "
                             f"and {gtau!r}")
    b, a1, fc, c = beta[:4]
    mass = gtau / b
    return {"mass": float(mass), "viscous": float(a1 * mass), "coulomb": float(abs(fc) * gtau),
            "offset": float(c * gtau)}
