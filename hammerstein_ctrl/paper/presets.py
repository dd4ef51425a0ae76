"""The paper's two case studies, ready to optimise.

``presets.trs()`` and ``presets.emps()`` return a :class:`Preset`: the data,
the model structure, the paper's initial point, the objective ``cost(beta)``,
the paper's optimiser settings per method, and the paper's reported numbers
for comparison.

Examples
--------
>>> from hammerstein_ctrl import presets
>>> p = presets.trs()
>>> p.structure.param_names
('b0', 'a0', 'a1', 'd0', 'd1')
>>> p.x0.tolist()
[-2.0, 0.0, 5.0, -5.0, 0.0]
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .datasets import TRS_TRUE_BETA, IOData, load_emps, load_trs
from ..exceptions import UnknownNameError
from ..blocks._families import Coulomb, Tanh
from ..fit._objective import HammersteinCost
from ..blocks._structure import HammersteinStructure, LinearStructure

__all__ = ["Preset", "trs", "emps", "get", "PRESETS", "STRUCTURES", "X0",
           "trs_structure", "emps_structure"]


def trs_structure() -> HammersteinStructure:
    """TRS (equation 16-17): ``(p + b0)/(p^2 + a1 p + a0)`` and ``d0 tanh(d1 u)``."""
    return HammersteinStructure(LinearStructure(1, 2), Tanh())


def emps_structure() -> HammersteinStructure:
    """EMPS (equation 18-19): ``1/(p^2 + a1 p)`` and ``d0 u + d1 sign(u) + d2``."""
    return HammersteinStructure(LinearStructure(0, 2, fixed={"a0": 0.0}), Coulomb())


#: Structures of the case studies, by name.
STRUCTURES = {"trs": trs_structure, "emps": emps_structure}
#: The paper's initial points theta(0) (Tables 1 and 5).
X0 = {"trs": (-2.0, 0.0, 5.0, -5.0, 0.0), "emps": (-1.0, 0.5, -0.4, 0.0)}


@dataclass(frozen=True)
class Preset:
    """A case study: data, structure, initial point, objective and paper settings.

    Attributes
    ----------
    name : str
    data : IOData
        Estimation record.
    structure : HammersteinStructure
    x0 : ndarray
        The paper's initial point theta(0).
    cost : HammersteinCost
        ``cost(beta)`` is J (Eq. 13) on :attr:`data`.
    methods : dict
        Per method, the keyword arguments for :func:`hammerstein_ctrl.minimize`
        reproducing the paper's settings (``method``, ``maxiter``/``maxfev``,
        ``options``, ``bounds``).
    paper : dict
        The paper's results per method: ``mean, best, worst, std, nfev`` (``None``
        where the paper prints N/A) and ``beta`` (best parameters, Table 4/8).
    true_beta : ndarray or None
        The parameters that generated the data, when known (TRS reconstruction).
    validation : callable or None
        Returns a validation record, when the case has one (EMPS pulses).
    """

    name: str
    data: IOData
    structure: HammersteinStructure
    x0: np.ndarray
    cost: HammersteinCost
    methods: dict = field(default_factory=dict)
    paper: dict = field(default_factory=dict)
    true_beta: np.ndarray | None = None
    validation: object = None

    def minimize_kwargs(self, method: str) -> dict:
        """Keyword arguments for :func:`hammerstein_ctrl.minimize` for one method."""
        from ..optimize import canonical_method

        key = canonical_method(method)
        if key not in self.methods:
            raise UnknownNameError(
                f"preset {self.name!r} has no settings for {method!r}; it has {sorted(self.methods)}"
            )
        return dict(self.methods[key])


def _paper_row(mean, best, worst, std, nfev, beta):
    return {"mean": mean, "best": best, "worst": worst, "std": std, "nfev": nfev,
            "beta": None if beta is None else np.asarray(beta, dtype=float)}


def trs(data: IOData | None = None, *, reject_unstable: bool = False) -> Preset:
    """The twin-rotor system case (paper section 5.1) on the bundled reconstruction.

    ``H(p) = (p + b0)/(p^2 + a1 p + a0)``, ``g(u) = d0 tanh(d1 u)``,
    beta = [b0, a0, a1, d0, d1], theta(0) = [-2, 0, 5, -5, 0] (Table 1).

    Parameters
    ----------
    data : IOData, optional
        Another TRS-like record (default: :func:`~hammerstein_ctrl.paper.datasets.load_trs`).
    reject_unstable : bool, default False
        Passed to :class:`~hammerstein_ctrl.fit.HammersteinCost`.
    """
    from .settings import trs_methods

    data = load_trs() if data is None else data
    structure = trs_structure()
    paper = {
        "spsa": _paper_row(None, 1.41e32, None, None, 2000, [-2.3635e14, 2.3635e14, 2.3635e14, 2.3635e14, -2.3635e14]),
        "nlspsa": _paper_row(185.3377, 182.9412, 189.2094, 1.8982, 2000, [-1.95, 0.11, 4.75, -1.15, 0.49]),
        "amvo-sca": _paper_row(218.5541, 177.9563, 339.1072, 69.0269, 5000, [-1.9078, 4.7607, 0.1085, -9.8045, 0.0574]),
        "nspsa": _paper_row(179.0082, 178.4851, 179.3974, 0.2457, 2000, list(TRS_TRUE_BETA)),
        "ranksum": {"pair": ("nspsa", "nlspsa"), "p": 5.08e-8, "h": 1},
    }
    return Preset(
        name="trs",
        data=data,
        structure=structure,
        x0=np.array(X0["trs"]),
        cost=HammersteinCost(data, structure, reject_unstable=reject_unstable),
        methods=trs_methods(),
        paper=paper,
        true_beta=np.array(TRS_TRUE_BETA),
    )


def emps(path=None, *, duration: float = 12.0, reject_unstable: bool = False) -> Preset:
    """The electro-mechanical positioning system case (paper section 5.2).

    ``H(p) = 1/(p^2 + a1 p)``, ``g(u) = d0 u + d1 sign(u) + d2``,
    beta = [a1, d0, d1, d2], theta(0) = [-1, 0.5, -0.4, 0] (Table 5), on the
    first 12 s (12 000 samples) of ``DATA_EMPS.mat``.  The validation record
    (``DATA_EMPS_PULSES.mat``, same duration) is available via
    ``preset.validation()``.

    Parameters
    ----------
    path : str or Path, optional
        Where the EMPS files are (see :func:`~hammerstein_ctrl.paper.datasets.load_emps`).
    duration : float, default 12.0
        Seconds of the estimation record to use.
    reject_unstable : bool, default False
        Passed to :class:`~hammerstein_ctrl.fit.HammersteinCost`.  The
        paper's initial point is unstable (``a1 = -1``), so rejecting unstable
        candidates changes the problem.
    """
    from .settings import emps_methods

    data = load_emps("estimation", duration=duration, path=path)
    structure = emps_structure()
    paper = {
        "spsa": _paper_row(None, None, None, None, 2500, [-1.5662e6, -1.5662e6, 1.5662e6, -1.5662e6]),
        "nlspsa": _paper_row(1.8550, 0.3022, 7.2260, 1.8067, 2500, [3.1102, 0.6361, -0.5352, 0.0552]),
        "amvo-sca": _paper_row(0.7151, 0.2103, 1.6604, 0.4704, 5000, [3.1626, 0.5485, -0.4019, 0.0457]),
        "nspsa": _paper_row(0.5364, 0.2444, 1.0023, 0.2217, 2500, [3.2870, 0.59130, -0.4448, 0.0486]),
        "ranksum": {"pair": ("nspsa", "nlspsa"), "p": 0.0015, "h": 1},
    }

    return Preset(
        name="emps",
        data=data,
        structure=structure,
        x0=np.array(X0["emps"]),
        cost=HammersteinCost(data, structure, reject_unstable=reject_unstable),
        methods=emps_methods(),
        paper=paper,
        validation=functools.partial(load_emps, "validation", duration=duration, path=path),
    )


#: Preset constructors by name.
PRESETS = {"trs": trs, "emps": emps}


def get(name: str, **kwargs) -> Preset:
    """A preset by name (``"trs"`` or ``"emps"``)."""
    key = str(name).lower()
    if key not in PRESETS:
        raise UnknownNameError(f"unknown case {name!r}; choose one of {sorted(PRESETS)}")
    return PRESETS[key](**kwargs)
