"""The package's import graph: no cycle, and the layers import downwards only.

The graph is read from the source with :mod:`ast`: every ``import`` and
``from ... import`` of a ``hammerstein_ctrl`` module counts, including those
inside functions (a lazy import is still a dependency), so a cycle cannot hide
behind a function-level import.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "hammerstein_ctrl"


def _modules(root: Path = PACKAGE) -> dict:
    out = {}
    for path in sorted(root.rglob("*.py")):
        if "_csrc" in path.parts:          # the build's code generator: not installed, imports nothing of ours
            continue
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _targets(module: str, node, is_package: bool, known) -> set:
    """The package modules one import statement of ``module`` loads."""
    if isinstance(node, ast.Import):
        return {parent for a in node.names if a.name in known for parent in _loaded_with(a.name, module)}
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module or ""
    out = set()
    for alias in node.names:
        full = f"{source}.{alias.name}"
        out.add(full if full in known else source)
    return {parent for m in out for parent in _loaded_with(m, module)} & set(known)


def _loaded_with(module: str, importer: str) -> list:
    """``module`` and the sub-packages above it that importing it runs.

    The lazy top-level package is left out, and so are the packages holding
    ``importer`` (they are already being initialised when it runs).
    """
    parts = module.split(".")
    return [name for name in (".".join(parts[:k]) for k in range(2, len(parts) + 1))
            if name == module or not importer.startswith(name + ".")]


def import_graph(root: Path = PACKAGE) -> dict:
    """``{module: set of package modules it imports}``, function-level imports included."""
    modules = _modules(root)
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                deps |= _targets(name, node, path.name == "__init__.py", modules)
        graph[name] = deps - {name}
    return graph


def cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_planted_cycle(tmp_path):
    pkg = tmp_path / "hammerstein_ctrl"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from .b import f\n")
    (pkg / "b.py").write_text("def f():\n    from .sub import c\n")
    (pkg / "sub" / "__init__.py").write_text("from . import c\n")
    (pkg / "sub" / "c.py").write_text("from .. import a\nimport numpy\n")
    (pkg / "d.py").write_text("from .a import x\n")
    graph = import_graph(pkg)
    assert graph["hammerstein_ctrl.sub.c"] == {"hammerstein_ctrl.a"}
    assert cycles(graph) == [["hammerstein_ctrl.a", "hammerstein_ctrl.b", "hammerstein_ctrl.sub",
                              "hammerstein_ctrl.sub.c"]]


def test_the_package_has_no_import_cycle():
    found = cycles(import_graph())
    assert found == [], "import cycles (function-level imports count): " + "; ".join(" <-> ".join(c) for c in found)


def _reaches(graph: dict, start: str) -> set:
    seen, todo = set(), [start]
    while todo:
        for w in graph[todo.pop()]:
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


#: The package's floors, bottom first: each subpackage is one role, and a module imports only from its own
#: subpackage and from lower floors.  Two subpackages on one floor never import each other.
FLOORS = [
    ("foundation", ("exceptions", "config", "_checks", "_deprecation", "_linalg", "_kernels", "_safe_io",
                    "_executors", "_core")),
    ("records and optimisers", ("data", "optimize")),
    ("simulation", ("simulate",)),
    ("models", ("blocks",)),
    ("figures", ("plotting",)),
    ("trust", ("assess",)),
    ("identification and design", ("fit", "design")),
    ("files", ("io",)),
    ("the paper", ("paper",)),
    ("the command line", ("cli",)),
]
FLOOR_OF = {part: level for level, (_, parts) in enumerate(FLOORS) for part in parts}


def _part(module: str) -> str:
    return module.split(".")[1] if module.count(".") >= 1 else ""


def _upward(graph: dict) -> list:
    """The imports that neither stay in their subpackage nor go down a floor (the foundation imports itself)."""
    return sorted((a, b) for a, deps in graph.items() for b in deps
                  if a != "hammerstein_ctrl" and _part(a) != _part(b)
                  and not (FLOOR_OF[_part(b)] < FLOOR_OF[_part(a)] or FLOOR_OF[_part(a)] == FLOOR_OF[_part(b)] == 0))


def test_every_module_has_a_floor():
    unplaced = sorted(m for m in import_graph() if m != "hammerstein_ctrl" and _part(m) not in FLOOR_OF)
    assert not unplaced, f"modules outside every floor: {unplaced}"


def test_every_import_goes_down_a_floor_or_stays_in_its_subpackage():
    upward = _upward(import_graph())
    assert not upward, "imports that do not go down a floor: " + "; ".join(f"{a} -> {b}" for a, b in upward)


def test_the_floor_test_finds_a_planted_upward_import(tmp_path):
    pkg = tmp_path / "hammerstein_ctrl"
    for sub in ("data", "fit", "design"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "data" / "_a.py").write_text("def f():\n    from ..fit import _b\n")
    (pkg / "fit" / "_b.py").write_text("from ..data import _a\n")
    (pkg / "design" / "_c.py").write_text("from ..fit._b import g\n")
    assert _upward(import_graph(pkg)) == [("hammerstein_ctrl.data._a", "hammerstein_ctrl.fit"),
                                          ("hammerstein_ctrl.data._a", "hammerstein_ctrl.fit._b"),
                                          ("hammerstein_ctrl.design._c", "hammerstein_ctrl.fit"),
                                          ("hammerstein_ctrl.design._c", "hammerstein_ctrl.fit._b")]


def test_implementation_modules_are_private():
    """scipy's rule: below a subpackage, every module is private (underscored); the paper layer is the exception,
    its modules being its public faces."""
    public = sorted(m for m in import_graph() if m.count(".") >= 2 and not m.split(".")[-1].startswith("_")
                    and _part(m) != "paper")
    assert public == [], f"implementation modules without an underscore: {public}"


#: Modules that may use the paper's material: the paper layer itself, the command line and the benchmarks
#: (applications), and the package namespace (its short names ``hc.presets``, ``hc.load_emps``, ...).
PAPER_USERS = ("paper", "cli")


def test_general_code_never_reaches_the_paper_layer():
    graph = import_graph()
    general = [m for m in graph if m.count(".") >= 1 and m.split(".")[1] not in PAPER_USERS]
    assert len(general) > 40
    offenders = {m: sorted(w for w in _reaches(graph, m) if w.startswith("hammerstein_ctrl.paper"))
                 for m in general}
    offenders = {m: w for m, w in offenders.items() if w}
    assert not offenders, f"general modules reaching the paper layer: {offenders}"


def test_the_paper_layer_holds_the_paper_facts():
    """The EMPS loader, the presets, the paper's optimiser settings and its tables are all under paper/."""
    graph = import_graph()
    for name in ("presets", "datasets", "settings", "study", "report"):
        assert f"hammerstein_ctrl.paper.{name}" in graph
    for moved in ("presets", "datasets", "study", "report"):
        assert f"hammerstein_ctrl.{moved}" not in graph


def test_the_tests_mirror_the_subpackages():
    """One folder of tests for each public subpackage, and no folder that names none; the foundation's and the
    package's own tests sit at the top."""
    tests = Path(__file__).resolve().parent
    folders = {p.name for p in tests.iterdir() if p.is_dir() and not p.name.startswith(("_", "."))}
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py") if not p.parent.name.startswith("_")}
    assert folders == subpackages, f"test folders {sorted(folders)} against subpackages {sorted(subpackages)}"
    assert all(any(tests.joinpath(name).glob("test_*.py")) for name in folders)


def _namespace_imports(root: Path = PACKAGE) -> list:
    """``(module, line)`` of every import of the package's lazy namespace itself (``import hammerstein_ctrl``,
    ``from .. import identify``) by a module below it: the graph above cannot see through it."""
    modules = _modules(root)
    found = []
    for name, path in modules.items():
        if name == "hammerstein_ctrl":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import) and any(a.name == "hammerstein_ctrl" for a in node.names):
                found.append((name, node.lineno))
            elif isinstance(node, ast.ImportFrom):
                base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                source = (".".join(base[:len(base) - (node.level - 1)] + ([node.module] if node.module else []))
                          if node.level else node.module or "")
                if source == "hammerstein_ctrl" and any(f"{source}.{a.name}" not in modules
                                                        and a.name != "_core" for a in node.names):
                    found.append((name, node.lineno))
    return found


def test_no_module_imports_the_lazy_namespace():
    assert _namespace_imports() == []


def test_the_namespace_check_finds_a_planted_import(tmp_path):
    pkg = tmp_path / "hammerstein_ctrl"
    (pkg / "fit").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "config.py").write_text("")
    (pkg / "fit" / "__init__.py").write_text("")
    (pkg / "fit" / "_a.py").write_text("from .. import config\ndef f():\n    from .. import identify\n")
    (pkg / "fit" / "_b.py").write_text("import hammerstein_ctrl\n")
    assert _namespace_imports(pkg) == [("hammerstein_ctrl.fit._a", 3), ("hammerstein_ctrl.fit._b", 1)]
