"""hammerstein_ctrl: continuous-time Hammerstein identification on top of python-control.

A Hammerstein model ``y = H(p) g(u)`` is a static nonlinearity ``g`` followed by
a linear transfer function ``H``.  This package identifies such models from
sampled input/output records with the normalized SPSA (N-SPSA) method of the
paper and its rivals, simulates them exactly and fast, and hands them to
python-control (``control.TransferFunction``, ``control.NonlinearIOSystem``)
for analysis and controller design.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> r = hc.minimize(case.cost, case.x0, seed=0, **case.minimize_kwargs("nspsa"))
>>> model = case.structure.model(r.x)
>>> bool(r.fun < 180), type(model.linear).__name__
(True, 'TransferFunction')
"""

from . import datasets, iodata, metrics, nonlinearities, optimize, plots, presets, records, simulate, study
from . import control_design, exact_export, persistence
from .datasets import load_emps, load_trs, make_trs_reconstruction
from .iodata import IOData
from .records import read_record
from .exceptions import DataError, HammersteinError, ParameterError, UnknownNameError
from .identify import IdentificationResult, identify
from .metrics import fit_percent, fit_report, nrmse, rmse, sse
from .model import HammersteinModel
from .nonlinearities import (
    Coulomb,
    CustomNonlinearity,
    DeadZone,
    Nonlinearity,
    PiecewiseLinear,
    Polynomial,
    Saturation,
    Tanh,
    nonlinearity_from_name,
)
from .objective import HammersteinCost
from .optimize import PerturbationGain, StepGain, minimize
from .persistence import load_model, load_result, save_model, save_result
from .structure import HammersteinStructure, LinearStructure
from .study import StudyResult, run_study

__version__ = "0.1.0"

__all__ = [
    "datasets", "iodata", "metrics", "nonlinearities", "optimize", "plots", "presets", "records", "simulate",
    "study", "control_design", "exact_export", "persistence", "load_model", "save_model", "load_result",
    "save_result",
    "IOData", "load_emps", "load_trs", "make_trs_reconstruction", "read_record",
    "DataError", "HammersteinError", "ParameterError", "UnknownNameError",
    "fit_percent", "fit_report", "nrmse", "rmse", "sse",
    "HammersteinModel", "identify", "IdentificationResult",
    "Nonlinearity", "Tanh", "Coulomb", "Polynomial", "Saturation", "DeadZone", "PiecewiseLinear",
    "CustomNonlinearity", "nonlinearity_from_name",
    "HammersteinCost", "HammersteinStructure", "LinearStructure",
    "minimize", "StepGain", "PerturbationGain", "run_study", "StudyResult",
    "__version__",
]
