"""Old names kept for one release: a module's ``__getattr__`` that gives each its new object with a warning."""

from __future__ import annotations

import sys
import warnings

__all__ = ["renamed"]


def renamed(module: str, renames: dict):
    """A module-level ``__getattr__`` for ``module``: each old name of ``renames`` (``old: (new, why)``) gives the
    module's object ``new`` with a DeprecationWarning; any other name is an AttributeError.

    Examples
    --------
    >>> import types, warnings
    >>> m = types.ModuleType("demo"); m.New = 1; sys.modules["demo"] = m
    >>> m.__getattr__ = renamed("demo", {"Old": ("New", "shorter")})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     value = m.Old
    >>> value, str(caught[0].message)
    (1, 'demo.Old is now New (shorter)')
    """
    def __getattr__(name):
        if name in renames:
            new, why = renames[name]
            warnings.warn(f"{module}.{name} is now {new} ({why})", DeprecationWarning, stacklevel=2)
            return getattr(sys.modules[module], new)
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
