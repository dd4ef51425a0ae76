"""hammerstein_ctrl: continuous-time Hammerstein identification on top of python-control.

A Hammerstein model ``y = H(p) g(u)`` is a static nonlinearity ``g`` followed by
a linear transfer function ``H``.  This package identifies such models from
sampled input/output records with the normalized SPSA (N-SPSA) method of the
paper and its rivals, simulates them exactly and fast, and hands them to
python-control (``control.TransferFunction``, ``control.NonlinearIOSystem``)
for analysis and controller design.

Sub-modules and the names below are imported on first use (PEP 562), so
``import hammerstein_ctrl`` costs no numpy, scipy or python-control import
until something is actually needed.  The simulation kernels are the compiled
core ``hammerstein_ctrl._core``, built when the package is installed: nothing
is compiled, cached or written when it runs.

Examples
--------
>>> import hammerstein_ctrl as hc
>>> case = hc.presets.trs()
>>> r = hc.minimize(case.cost, case.x0, seed=0, **case.minimize_kwargs("nspsa"))
>>> model = case.structure.model(r.x)
>>> bool(r.fun < 180), type(model.linear).__name__
(True, 'TransferFunction')
"""

import importlib
import sys
import types
import warnings

from .exceptions import (ChannelWarning, DataError, HammersteinError, IdentificationWarning, ParameterError,
                         SimulationWarning, UnknownNameError)

__version__ = "0.2.0"

#: Sub-modules exposed as attributes of the package.
_SUBMODULES = ("iodata", "metrics", "nonlinearities", "optimize", "plots", "records",
               "simulate", "control_design", "exact_export", "persistence", "display", "uncertainty",
               "diagnostics", "residual_analysis", "selection", "config", "paper", "mimo", "lure", "in_loop")

#: Public name -> the sub-module that defines it.
_LAZY_NAMES = {
    "load_emps": "paper.datasets", "load_trs": "paper.datasets", "make_trs_reconstruction": "paper.datasets",
    "IOData": "iodata", "read_record": "records",
    "IdentificationResult": "result", "identify": "identify",
    "fit_percent": "metrics", "fit_report": "metrics", "nrmse": "metrics", "rmse": "metrics", "sse": "metrics",
    "BlockModel": "model", "HammersteinModel": "model", "WienerModel": "model", "HammersteinWienerModel": "model",
    "Coulomb": "nonlinearities", "CustomNonlinearity": "nonlinearities", "DeadZone": "nonlinearities",
    "Nonlinearity": "nonlinearities", "PiecewiseLinear": "nonlinearities", "Polynomial": "nonlinearities",
    "Saturation": "nonlinearities", "Tanh": "nonlinearities", "Sigmoid": "nonlinearities",
    "Friction": "nonlinearities",
    "nonlinearity_from_name": "nonlinearities",
    "HammersteinCost": "objective",
    "PerturbationGain": "optimize", "StepGain": "optimize", "minimize": "optimize",
    "BlockStructure": "structure", "HammersteinStructure": "structure", "WienerStructure": "structure",
    "HammersteinWienerStructure": "structure", "LinearStructure": "structure",
    "MIMOHammersteinStructure": "mimo", "MIMOWienerStructure": "mimo", "MIMOHammersteinWienerStructure": "mimo",
    "MIMOModel": "mimo", "mimo_structure": "mimo",
    "LureStructure": "lure", "LureModel": "lure", "lure_structure": "lure",
    "WienerHammersteinStructure": "wiener_hammerstein", "WienerHammersteinModel": "wiener_hammerstein",
    "wiener_hammerstein_structure": "wiener_hammerstein", "UnitGainBlock": "wiener_hammerstein",
    "load_model": "persistence", "save_model": "persistence", "load_result": "persistence",
    "save_result": "persistence",
    "StudyResult": "paper.study", "run_study": "paper.study",
    "select_structure": "selection", "candidate_structures": "selection", "SelectionResult": "selection",
    "tune_pid": "control_design", "identify_in_loop": "in_loop",
}

#: The documented front door: records, structures, models, nonlinearities, identification and its result,
#: persistence, errors.  Sub-modules (``hc.plots``, ``hc.control_design``, ``hc.mimo``, ``hc.config``, the paper
#: layer ``hc.paper`` ...) are reached as attributes and are not star-exported.
__all__ = [
    "IOData", "read_record",
    "LinearStructure", "HammersteinStructure", "WienerStructure", "HammersteinWienerStructure", "BlockStructure",
    "MIMOHammersteinStructure", "MIMOWienerStructure", "MIMOHammersteinWienerStructure", "mimo_structure",
    "LureStructure", "lure_structure", "WienerHammersteinStructure", "wiener_hammerstein_structure",
    "BlockModel", "HammersteinModel", "WienerModel", "HammersteinWienerModel", "MIMOModel", "LureModel",
    "WienerHammersteinModel",
    "Nonlinearity", "Tanh", "Coulomb", "Polynomial", "Saturation", "DeadZone", "PiecewiseLinear", "Sigmoid",
    "Friction",
    "CustomNonlinearity", "nonlinearity_from_name",
    "identify", "IdentificationResult", "select_structure", "candidate_structures", "SelectionResult",
    "identify_in_loop", "tune_pid",
    "minimize", "HammersteinCost", "fit_percent", "fit_report", "nrmse", "rmse", "sse",
    "load_model", "save_model", "load_result", "save_result",
    "DataError", "HammersteinError", "ParameterError", "UnknownNameError", "IdentificationWarning",
    "SimulationWarning", "ChannelWarning", "__version__",
]

#: Names removed from the front door, kept for one release with a DeprecationWarning: why each went.
_DEPRECATED = {
    "NativeBuildError": "the compiled core is built when the package is installed, so nothing raises it any more",
    "CacheWarning": "nothing is compiled or cached at run time, so nothing issues it any more",
}


#: Short names of the paper layer's modules (:mod:`hammerstein_ctrl.paper`).
_PAPER_MODULES = {"presets": "paper.presets", "datasets": "paper.datasets", "study": "paper.study",
                  "report": "paper.report"}


def __getattr__(name):
    """Import a sub-module or public name on first access (PEP 562)."""
    if name in _DEPRECATED:
        warnings.warn(f"hammerstein_ctrl.{name} is deprecated and will be removed: {_DEPRECATED[name]}",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(f"{__name__}.exceptions"), name)
    if name in _SUBMODULES or name in _PAPER_MODULES:
        value = importlib.import_module(f"{__name__}.{_PAPER_MODULES.get(name, name)}")
    elif name in _LAZY_NAMES:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY_NAMES[name]}"), name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__) | set(_SUBMODULES) | set(_LAZY_NAMES) | set(_PAPER_MODULES))


class _Package(types.ModuleType):
    """The package's module type: a public *function* wins over a same-named sub-module.

    ``hammerstein_ctrl.identify`` is both the function and the module defining
    it.  Importing the sub-module binds the module on the package; eagerly, the
    package rebound the function right after, and this keeps it that way.
    """

    def __setattr__(self, name, value):
        if not (isinstance(value, types.ModuleType) and name in _LAZY_NAMES):
            super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
