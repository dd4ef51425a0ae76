"""Compiled scalar forms of the static nonlinearities, derived from their formulas.

An output nonlinearity ``h`` (Wiener and Hammerstein-Wiener models) acts on
every simulated sample, so the kernels apply it in the same compiled pass as
the linear recursion instead of storing the whole output first; the
closed-loop simulator applies ``g`` and ``h`` at every step the same way.
Nothing here is written by hand: for every family registered in
:data:`~hammerstein_ctrl.nonlinearities.NONLINEARITIES` with a
:attr:`~hammerstein_ctrl.nonlinearities.Nonlinearity.formula`, the module
holds ``<name>_map = compiled(formula)``, with the signature
``map(z, p, extra) -> float``: ``z`` one sample, ``p`` the parameter vector
of one candidate, ``extra`` fixed data of the family (the breakpoints of a
piecewise-linear map, else an empty array).  They agree with the vectorised
:meth:`~hammerstein_ctrl.nonlinearities.Nonlinearity.evaluate` to rounding.

Examples
--------
>>> import numpy as np
>>> float(saturation_map(3.0, np.array([2.0, 1.0]), np.empty(0)))
2.0
>>> float(piecewise_linear_map(0.5, np.array([-1.0, 0.0, 2.0]), np.array([-1.0, 0.0, 1.0])))
1.0
>>> FAMILY_CODES[NONLINEARITIES["tanh"]] == 0
True
"""

from __future__ import annotations

from ._jit import cached_njit
from .nonlinearities import NONLINEARITIES

#: The compiled maps, in the order of the registry (the closed-loop simulator picks one by its position).
#: numba compiles a callee with its first caller's floating-point flags unless the callee sets its own, then
#: serves that one version (and its cached copy) to every caller: a kernel's bits would depend on what the
#: machine had compiled first.  So the numba-compiled kernels (the generated kernels whose map C does not take,
#: and the tests' oracles of the others, which translate the formulas into C) inline the maps
#: (``inline="always"``: a map follows
#: its kernel's own flags), and the version compiled on its own (for Python calls and the closed-loop
#: simulator, which picks a map from this tuple and so links it) has its flags fixed, keyed on this file.
MAPS = tuple(cached_njit(inline="always", fastmath=False, depends=("compiled_maps.py",))(family.formula)
             for family in NONLINEARITIES.values() if family.formula is not None)
#: Position in :data:`MAPS` of each family's map.
FAMILY_CODES = {family: i for i, family in enumerate(f for f in NONLINEARITIES.values() if f.formula is not None)}

for _family, _code in FAMILY_CODES.items():
    globals()[f"{_family.name}_map"] = MAPS[_code]

__all__ = ["MAPS", "FAMILY_CODES", "NONLINEARITIES"] + [f"{family.name}_map" for family in FAMILY_CODES]
