"""The package's import graph: no cycle, and the layers import downwards only.

The graph is read from the source with :mod:`ast`: every ``import`` and
``from ... import`` of a ``hammerstein_ctrl`` module counts, including those
inside functions (a lazy import is still a dependency), so a cycle cannot hide
behind a function-level import.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "hammerstein_ctrl"


def _modules(root: Path = PACKAGE) -> dict:
    out = {}
    for path in sorted(root.rglob("*.py")):
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


#: (lower module, higher modules it must never reach, directly or through others).
LAYERS = [
    ("hammerstein_ctrl.optimize", ("structure", "model", "objective", "identify", "simulate", "auto", "display",
                                   "plots", "persistence")),
    ("hammerstein_ctrl.model", ("persistence", "identify", "plots", "structure", "objective", "optimize")),
    ("hammerstein_ctrl.display", ("identify", "plots", "model", "structure", "optimize")),
    ("hammerstein_ctrl.structure", ("identify", "objective", "optimize", "persistence", "plots")),
    ("hammerstein_ctrl.uncertainty", ("identify", "model", "structure", "plots")),
    ("hammerstein_ctrl.significance", ("identify", "nested", "auto", "objective", "structure", "model")),
    ("hammerstein_ctrl.nested", ("identify", "selection", "result", "persistence", "plots")),
]


@pytest.mark.parametrize("lower, higher", LAYERS, ids=[layer[0].rsplit(".", 1)[-1] for layer in LAYERS])
def test_a_lower_layer_never_reaches_a_higher_one(lower, higher):
    graph = import_graph()
    reached = {m.split(".")[1] for m in _reaches(graph, lower) if m.count(".") >= 1}
    assert reached.isdisjoint(higher), f"{lower} reaches {sorted(reached & set(higher))}"


#: Modules that may use the paper's material: the paper layer itself, the command line and the benchmarks
#: (applications), and the package namespace (its short names ``hc.presets``, ``hc.load_emps``, ...).
PAPER_USERS = ("paper", "cli", "cli_select", "cli_tune", "bench", "bench_structures")


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
