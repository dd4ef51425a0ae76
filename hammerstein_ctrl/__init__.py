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

from ._deprecation import MovedModules as _MovedModules
from .exceptions import (ChannelWarning, DataError, HammersteinError, IdentificationWarning, ParameterError,
                         SimulationWarning, UnknownNameError)

__version__ = "0.2.0"

#: The public subpackages, by role and from the bottom layer up, reached as attributes of the package.
_SUBMODULES = ("exceptions", "config", "data", "optimize", "simulate", "blocks", "plotting", "assess", "fit",
               "design", "io", "cli", "paper")

#: Public name -> the subpackage that exports it.
_LAZY_NAMES = {
    "load_emps": "paper.datasets", "load_trs": "paper.datasets", "make_trs_reconstruction": "paper.datasets",
    "IOData": "data", "read_record": "data",
    "fit_percent": "data", "fit_report": "data", "nrmse": "data", "rmse": "data", "sse": "data",
    "BlockModel": "blocks", "HammersteinModel": "blocks", "WienerModel": "blocks", "HammersteinWienerModel": "blocks",
    "Coulomb": "blocks", "CustomNonlinearity": "blocks", "DeadZone": "blocks", "Nonlinearity": "blocks",
    "PiecewiseLinear": "blocks", "Polynomial": "blocks", "Saturation": "blocks", "Tanh": "blocks",
    "Sigmoid": "blocks", "Friction": "blocks", "nonlinearity_from_name": "blocks",
    "BlockStructure": "blocks", "HammersteinStructure": "blocks", "WienerStructure": "blocks",
    "HammersteinWienerStructure": "blocks", "LinearStructure": "blocks",
    "MIMOHammersteinStructure": "blocks", "MIMOWienerStructure": "blocks", "MIMOHammersteinWienerStructure": "blocks",
    "MIMOModel": "blocks", "mimo_structure": "blocks",
    "LureStructure": "blocks", "LureModel": "blocks", "lure_structure": "blocks",
    "WienerHammersteinStructure": "blocks", "WienerHammersteinModel": "blocks",
    "wiener_hammerstein_structure": "blocks", "UnitGainBlock": "blocks",
    "PerturbationGain": "optimize", "StepGain": "optimize", "minimize": "optimize",
    "identify": "fit", "IdentificationResult": "fit", "HammersteinCost": "fit", "identify_in_loop": "fit",
    "select_structure": "fit", "candidate_structures": "fit", "SelectionResult": "fit",
    "tune_pid": "design",
    "load_model": "io", "save_model": "io", "load_result": "io", "save_result": "io",
    "StudyResult": "paper.study", "run_study": "paper.study",
}

#: Old module paths, kept for one release: each imports its new module with a DeprecationWarning (a module split
#: in several gives one module holding all their names).
_MOVES = {
    "iodata": "data._iodata", "records": "data._records", "metrics": "data._metrics",
    "display": ("data._display", "data._inputs"),
    "safe_io": "_safe_io", "executors": "_executors", "kernels": "_kernels",
    "normal_equations": "optimize._normal_equations", "streamed_lstsq": "optimize._streamed_lstsq",
    "optimize.gains": "optimize._gains", "optimize.least_squares": "optimize._least_squares",
    "optimize.normal_lm": "optimize._normal_lm",
    "_batch": "simulate._batch", "_discretize": "simulate._discretize", "_normal_pass": "simulate._normal_pass",
    "delay": "simulate._delay", "_lure_sim": "simulate._lure_sim", "_lure_map": "simulate._lure_map",
    "loop_sim": "simulate._loop", "exact_export": "simulate._export",
    "nonlinearities": ("blocks._nonlinearities", "blocks._families"), "structure": "blocks._structure",
    "model": "blocks._model",
    "mimo": ("blocks._mimo", "blocks._mimo_model", "blocks._mimo_sim"), "lure": "blocks._lure",
    "wiener_hammerstein": ("blocks._wiener_hammerstein", "blocks._unit_gain"), "_writer": "blocks._json",
    "plots": ("plotting._figures", "plotting._spectra", "plotting._blocks", "plotting._runs", "plotting._results",
              "plotting._studies"),
    "uncertainty": ("assess._uncertainty", "assess._propagation"), "diagnostics": "assess._diagnostics",
    "residual_analysis": ("assess._residuals", "assess._input_tests"), "significance": "assess._significance",
    "objective": "fit._objective", "_output_error": "fit._output_error",
    "initialize": ("fit._initialize", "fit._linear_starts", "fit._baselines"),
    "auto": ("fit._auto", "fit._auto_records", "fit._auto_whole"), "delay_fit": "fit._delay_fit",
    "experiments": "fit._experiments", "lure_fit": "fit._lure_fit", "mimo_fit": "fit._mimo_fit",
    "wh_fit": "fit._wh_fit",
    "identify": "fit._identify", "in_loop": "fit._in_loop", "nested": "fit._nested", "result": "fit._result",
    "selection": "fit._selection",
    "control_design": ("design._tune", "design._pid", "design._loops", "design._approximate"),
    "robust_pid": "design._robust", "operating_point": "design._operating_point",
    "persistence": ("io._persistence", "io._results"),
    "cli_select": "cli._select", "cli_tune": "cli._tune",
}
_MOVED = {
    **{old: (new, "the package is laid out in subpackages by role") for old, new in _MOVES.items()},
    "bench": (None, "the speed benchmarks are scripts of the source repository (benchmarks/speed.py)"),
    "bench_structures": (None, "the speed benchmarks are scripts of the source repository "
                               "(benchmarks/structures_speed.py)"),
}

#: The documented front door: records, structures, models, nonlinearities, identification and its result,
#: persistence, errors.  The subpackages (``hc.data``, ``hc.blocks``, ``hc.fit``, ``hc.design``, ``hc.plotting``, the
#: paper layer ``hc.paper`` ...) are reached as attributes and are not star-exported.
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
    elif name in _MOVED and _MOVED[name][0] is None:         # left the package: hasattr() is False, with why
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}: {_MOVED[name][1]}")
    elif name in _MOVED:
        return importlib.import_module(f"{__name__}.{name}")      # warns
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__) | set(_SUBMODULES) | set(_LAZY_NAMES) | set(_PAPER_MODULES))


class _Package(types.ModuleType):
    """The package's module type: a public name wins over a same-named old module path.

    ``hammerstein_ctrl.identify`` is the function; ``import hammerstein_ctrl.identify``, the module path it had
    before the re-lay, still imports (with a warning) and would bind the module over the function, which this
    prevents.
    """

    def __setattr__(self, name, value):
        if not (isinstance(value, types.ModuleType) and name in _LAZY_NAMES):
            super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
_MovedModules(__name__, _MOVED).install()
