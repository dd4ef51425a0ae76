"""Sphinx configuration of the hammerstein_ctrl documentation (``make docs``)."""

from __future__ import annotations

import shutil
from pathlib import Path

import hammerstein_ctrl as hc

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

project = "hammerstein_ctrl"
author = "the hammerstein_ctrl developers"
release = version = hc.__version__
copyright = "2026, the hammerstein_ctrl developers"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "myst_nb",
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints", "api/_front_door.rst"]
templates_path = ["_templates"]

html_theme = "pydata_sphinx_theme"
html_title = f"hammerstein_ctrl {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path: list[str] = []

autosummary_generate = True
autodoc_typehints = "none"
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# the notebooks are shown with the outputs they are committed with (make notebooks runs them)
nb_execution_mode = "off"
myst_enable_extensions = ["dollarmath", "colon_fence"]
suppress_warnings = ["myst.header"]

# a broken reference to a page of this package fails the build; names of other packages are not resolved
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|scipy|control|ct|matplotlib|pandas|dask|concurrent)(\..*)?"),
    (r"py:.*", r"(ndarray|array_like|array-like|callable|optional|default|scalar|sequence|mapping|iterable)"),
    (r"py:.*", r"(int|float|str|bool|dict|list|tuple|object|None|complex|bytes|type|Path|path-like|os\.PathLike)"),
]


def _gallery() -> None:
    """The notebooks, copied beside the pages (Sphinx reads only its own folder)."""
    target = HERE / "gallery" / "notebooks"
    target.mkdir(parents=True, exist_ok=True)
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        shutil.copyfile(nb, target / nb.name)


#: The public subpackages, bottom layer first, each with the title of its page.
SUBPACKAGES = {"data": "Records and measures of fit", "optimize": "Optimisers", "simulate": "Simulation",
               "blocks": "Structures and models", "plotting": "Figures", "assess": "How far to trust a fit",
               "fit": "Identification", "design": "Controller design", "io": "Files", "cli": "The command line"}


def _api_pages() -> None:
    """The API reference: a page for every name of ``hammerstein_ctrl.__all__`` (but the version string), and one
    page for each public subpackage, whose names not at the top level get pages of their own."""
    import importlib

    top = {id(getattr(hc, n)) for n in hc.__all__}
    lines = [":orphan:", "", ".. currentmodule:: hammerstein_ctrl", "", ".. autosummary::", "   :toctree: generated",
             ""] + [f"   {n}" for n in hc.__all__ if n != "__version__"]
    for sub, title in SUBPACKAGES.items():
        module = importlib.import_module(f"hammerstein_ctrl.{sub}")
        own = [n for n in module.__all__ if id(getattr(module, n)) not in top and not n.isupper()]
        if own:
            lines += ["", f".. currentmodule:: hammerstein_ctrl.{sub}", "", ".. autosummary::",
                      "   :toctree: generated", ""] + [f"   {n}" for n in own]
        heading = f"{title}: ``hc.{sub}``"
        (HERE / "api" / f"{sub}.rst").write_text("\n".join([
            heading, "=" * len(heading), "", f".. automodule:: hammerstein_ctrl.{sub}", "   :no-members:", ""]))
    (HERE / "api" / "_names.rst").write_text("\n".join(lines) + "\n")
    front = [".. currentmodule:: hammerstein_ctrl", "", ".. autosummary::", "   :nosignatures:", ""]
    (HERE / "api" / "_front_door.rst").write_text(
        "\n".join(front + [f"   {n}" for n in hc.__all__ if n != "__version__"]) + "\n")


_gallery()
_api_pages()


# -- references to the package's own objects --------------------------------------------------------------------------
# A docstring may name an object by the module that defines it (hammerstein_ctrl.blocks.BlockModel) where the
# reference documents it under its public name (hammerstein_ctrl.BlockModel): such a reference is sent to the public
# page.  One to an internal helper that exists but has no page is shown as code without a link.  A reference to a
# name that does not exist stays a warning, which -W makes an error.
DOCUMENTED_MODULES = tuple(f"hammerstein_ctrl.{sub}" for sub in SUBPACKAGES) + (
    "hammerstein_ctrl.config", "hammerstein_ctrl.paper.benchmarks")


def _lookup(dotted: str):
    """The object named ``dotted`` (module path then attributes), or None; an old name kept for one release counts
    as none (it has no page)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return _resolve(dotted)
        except DeprecationWarning:
            return None


def _resolve(dotted: str):
    import importlib

    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except Exception:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return None
        return obj
    return None


def _public_names() -> dict:
    """``id(object) -> public dotted name`` of everything the reference documents."""
    import importlib
    import inspect

    out = {}
    for name in hc.__all__:
        obj = getattr(hc, name)
        out.setdefault(id(obj), f"hammerstein_ctrl.{name}")
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if not attr.startswith("_"):
                    out.setdefault(id(member), f"hammerstein_ctrl.{name}.{attr}")
    for mod in DOCUMENTED_MODULES:
        module = importlib.import_module(mod)
        out.setdefault(id(module), mod)
        for attr in getattr(module, "__all__", ()):
            out.setdefault(id(getattr(module, attr)), f"{mod}.{attr}")
    return out


def _candidates(node) -> list:
    """Where a (possibly relative) target may live: itself, the documented class and module, and every enclosing
    scope of the docstring it was written in (``docstring of hammerstein_ctrl.blocks.BlockModel.to_iosys``)."""
    target = node.get("reftarget", "")
    module, cls = node.get("py:module") or "", node.get("py:class") or ""
    names = [target]
    if cls:
        names.append(f"{module}.{cls}.{target}")
    if module:
        names.append(f"{module}.{target}")
    source = str(node.source or "")
    if "docstring of " in source:
        scope = source.split("docstring of ", 1)[1].split(":")[0].split(".")
        names += [".".join(scope[:cut] + [target]) for cut in range(len(scope), 0, -1)]
    names.append(f"hammerstein_ctrl.{target}")
    return names


def _in_some_module(target: str):
    """The object a bare name denotes in the one module of the package that defines it, or None."""
    import sys

    if "." in target:
        return None
    found = [getattr(m, target) for n, m in list(sys.modules.items())
             if n.startswith("hammerstein_ctrl") and m is not None and target in vars(m)]
    return found[0] if len({id(f) for f in found}) == 1 else None


def _missing_reference(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    public = app.config._public_names
    target = node.get("reftarget", "")
    if node.get("reftype") == "attr" and node.get("py:class") and target.isidentifier():
        return contnode          # an instance attribute of the documented class (set in __init__): no page of its own
    names = _candidates(node)
    for name in names + [None]:
        obj = _lookup(name) if name and name.startswith("hammerstein_ctrl") else (
            _in_some_module(target) if name is None else None)
        if obj is None:
            continue
        alias = public.get(id(obj)) or public.get(id(getattr(obj, "__func__", None)))
        if alias is not None and alias != node.get("reftarget"):
            domain = env.get_domain("py")
            for role in ("obj", "class", "func", "meth", "attr", "mod", "data"):
                found = domain.resolve_xref(env, node["refdoc"], app.builder, role, alias, node, contnode)
                if found is not None:
                    return found
        return contnode          # an internal helper with no page of its own: code, no link
    return None


def setup(app):
    app.config._public_names = _public_names()
    app.connect("missing-reference", _missing_reference)
