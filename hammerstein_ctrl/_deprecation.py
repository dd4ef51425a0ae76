"""Old names kept for one release: a module's ``__getattr__`` that gives each its new object with a warning."""

from __future__ import annotations

import sys
import warnings

__all__ = ["renamed", "moved_names", "MovedModules"]

#: The package whose namespace module (its ``__init__``) is no caller: a warning raised through its ``__getattr__``
#: goes to the line that asked it.
PACKAGE = __name__.split(".")[0]


def _public(module: str) -> str:
    """The public path of ``module``: the part before its first private component (``a.b._c`` -> ``a.b``)."""
    parts = module.split(".")
    cut = next((i for i, p in enumerate(parts) if p.startswith("_")), len(parts))
    return ".".join(parts[:max(cut, 1)])


def _warn(message: str) -> None:
    """A DeprecationWarning attributed to the user's line (the first frame outside the import system, this module
    and the package's namespace module), so that Python's default filters show it in ``__main__``."""
    frame = _caller()
    if frame is None:
        warnings.warn(message, DeprecationWarning, stacklevel=2)
        return
    warnings.warn_explicit(message, DeprecationWarning, frame.f_code.co_filename, frame.f_lineno,
                           module=frame.f_globals.get("__name__", "__main__"),
                           registry=frame.f_globals.setdefault("__warningregistry__", {}))


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
            _warn(f"{_public(module)}.{name} is now {new} ({why})")
            return getattr(sys.modules[module], new)
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__


def moved_names(module: str, moves: dict):
    """A module-level ``__getattr__`` for ``module``: each name of ``moves`` (``name: (path, why)``) gives the object
    of that name in the module ``path``, imported on first use, with a DeprecationWarning; any other name is an
    AttributeError.

    Examples
    --------
    >>> import types, warnings
    >>> home = types.ModuleType("demo_home"); home.THING = 2; sys.modules["demo_home"] = home
    >>> m = types.ModuleType("demo2"); sys.modules["demo2"] = m
    >>> m.__getattr__ = moved_names("demo2", {"THING": ("demo_home", "internal")})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     value = m.THING
    >>> value, str(caught[0].message)
    (2, 'demo2.THING is deprecated and will be removed (internal)')
    """
    def __getattr__(name):
        if name in moves:
            import importlib

            path, why = moves[name]
            _warn(f"{module}.{name} is deprecated and will be removed ({why})")
            return getattr(importlib.import_module(path), name)
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__


def _caller():
    """The first frame outside the import system and this module: where a moved module was imported."""
    frame = sys._getframe(1)
    while frame is not None and (frame.f_code.co_filename == __file__ or "importlib" in frame.f_code.co_filename
                                 or frame.f_code.co_filename.startswith("<frozen")
                                 or frame.f_globals.get("__name__") == PACKAGE):
        frame = frame.f_back
    return frame


def _union(name: str, modules: list):
    """A module named ``name`` whose every attribute is the one of the first of ``modules`` that has it."""
    import types

    union = types.ModuleType(name, f"The names of {', '.join(m.__name__ for m in modules)}, under their old path.")
    union.__all__ = [n for m in modules for n in getattr(m, "__all__", ())]

    def __getattr__(attr):
        for m in modules:
            try:
                return getattr(m, attr)
            except AttributeError:
                continue
        raise AttributeError(f"module {name!r} has no attribute {attr!r}")

    union.__getattr__ = __getattr__
    union.__dir__ = lambda: sorted(set(union.__all__) | {n for m in modules for n in dir(m) if not n.startswith("_")})
    return union


class MovedModules:
    """A finder on :data:`sys.meta_path` that gives each moved module of ``package`` its new one, with a warning.

    ``moved`` maps an old path (below ``package``) to ``(new path, why)``.  A new path of ``None`` means the
    module left the package: importing it raises :class:`ModuleNotFoundError` with ``why``.  The old name is
    bound to the very module object of its new path, so both give the same classes and functions.  A module split
    in several has a tuple of new paths: the old name is then a module that finds each name in the first of them
    that has it.

    Examples
    --------
    >>> import importlib, types, warnings
    >>> pkg = types.ModuleType("demo_pkg"); pkg.__path__ = []; sys.modules["demo_pkg"] = pkg
    >>> new = types.ModuleType("demo_pkg._new"); new.VALUE = 3; sys.modules["demo_pkg._new"] = new
    >>> finder = MovedModules("demo_pkg", {"old": ("_new", "renamed")}).install()
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     module = importlib.import_module("demo_pkg.old")
    >>> module.VALUE, module.__name__
    (3, 'demo_pkg._new')
    >>> str(caught[0].message)
    'demo_pkg.old is deprecated and will be removed: it was internal and has no public replacement (renamed)'
    >>> sys.meta_path.remove(finder)

    A module split in two:

    >>> other = types.ModuleType("demo_pkg._other"); other.MORE = 4; sys.modules["demo_pkg._other"] = other
    >>> finder = MovedModules("demo_pkg", {"both": (("_new", "_other"), "split")}).install()
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     module = importlib.import_module("demo_pkg.both")
    >>> module.VALUE, module.MORE
    (3, 4)
    >>> sys.meta_path.remove(finder)
    """

    def __init__(self, package: str, moved: dict):
        self.package, self.moved, self._own = package, moved, {}

    def install(self):
        if self not in sys.meta_path:
            sys.meta_path.append(self)
        return self

    def find_spec(self, fullname, path=None, target=None):
        import importlib.util
        old = fullname[len(self.package) + 1:] if fullname.startswith(self.package + ".") else None
        if old not in self.moved:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        import importlib
        new, why = self.moved[spec.name[len(self.package) + 1:]]
        if new is None:
            raise ModuleNotFoundError(f"{spec.name} is no longer part of the package: {why}", name=spec.name)
        paths = (new,) if isinstance(new, str) else tuple(new)
        home = paths[0].split(".")[0] if not paths[0].startswith("_") else None
        _warn(f"{spec.name} is deprecated and will be removed: " + (
            f"use {self.package}.{home} ({why})" if home else f"it was internal and has no public replacement ({why})"))
        if len(paths) > 1:
            return _union(spec.name, [importlib.import_module(f"{self.package}.{p}") for p in paths])
        module = importlib.import_module(f"{self.package}.{new}")
        self._own[spec.name] = (module.__spec__, module.__loader__)
        return module

    def exec_module(self, module):
        """Nothing to run: :meth:`create_module` returned the new module, already imported.  The import system
        stamped the old name's spec on it; the module gets its own back."""
        if module.__spec__.name in self._own:
            module.__spec__, module.__loader__ = self._own.pop(module.__spec__.name)
