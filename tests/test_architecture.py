"""The architecture as the folder tree shows it, checked on the source (issue 8).

Layers, lowest first: ``errors`` and ``_lazy`` (anyone may import them), ``core``,
``instruments``, ``estimation``, ``calibration``, ``design``, ``simulation``, ``report``,
then ``io``, ``workflow`` (the calibration workflow, which writes its result with ``io``) and
``cli``. A module may import its own layer and lower ones, never a higher one; no module
imports a private (underscore) name of another module; there is no import cycle between
modules; only the figure module imports
matplotlib; numpy and scipy stay out of the command line's start-up. Modules are split by
concept, not by length (issue 29: a line cap split one concept into thirds), so no test counts
their lines.

Every import counts, wherever it is: at module level (also under ``if`` or ``try``) and
inside functions, where deferred imports keep start-up light (issue 18: a layer's deferred
import of a higher layer is still a dependency on it, and two modules that import each
other inside functions are still a cycle). Imports are resolved to the module that really
provides the name: ``from hexcal.estimation import Problem`` depends on
``hexcal.estimation.problem`` (through the package's lazy map, :mod:`hexcal._lazy`), not on
the package's ``__init__``, which imports nothing.
"""

from __future__ import annotations

import ast
import itertools
import subprocess
import sys
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "hexcal"

#: Rank of each layer; a module may import only layers of equal or lower rank.
LAYERS = {
    "errors": 0,
    "_lazy": 0,
    "core": 1,
    "instruments": 2,
    "estimation": 3,
    "calibration": 4,
    "design": 5,
    "simulation": 6,
    "report": 7,
    "io": 8,
    "workflow": 9,
    "cli": 10,
    "__init__": 11,
    "__main__": 11,
}


def _modules() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def _layer(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0].removesuffix(".py") if len(rel.parts) > 1 else rel.stem


@dataclass(frozen=True)
class Import:
    """One ``import`` or ``from ... import`` statement of a source file."""

    module: str  # the module imported (``from`` imports: the module imported from)
    names: tuple[str, ...]  # the names of a ``from`` import (empty for ``import``)
    line: int
    in_function: bool  # inside a function body (a deferred import)

    def where(self) -> str:
        return f"line {self.line}" + (" (inside a function)" if self.in_function else "")


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC).with_suffix("")
    return ".".join(("hexcal", *rel.parts)).removesuffix(".__init__")


def _imports(path: Path) -> list[Import]:
    """Every import of a file, at module level and in function bodies (relative ones made
    absolute)."""
    package = _module_name(path).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    out: list[Import] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            if isinstance(child, ast.ImportFrom):
                base = package[: len(package) - child.level + 1] if child.level else []
                module = ".".join([*base, *([child.module] if child.module else [])])
                out.append(Import(module, tuple(a.name for a in child.names), child.lineno, inside))
            elif isinstance(child, ast.Import):
                out.extend(Import(a.name, (), child.lineno, inside) for a in child.names)
            visit(child, inside)

    visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return out


def _source(module: str) -> Path | None:
    """The file of a hexcal module or package, if there is one."""
    base = SRC.parent / module.replace(".", "/")
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.exists():
            return candidate
    return None


@cache
def _lazy_names(package: str) -> dict[str, str]:
    """A package's lazy map (``attach(__name__, {name: submodule})`` in its ``__init__``)."""
    path = SRC.parent / package.replace(".", "/") / "__init__.py"
    if not path.exists():
        return {}
    tree = ast.parse(path.read_text(encoding="utf-8"))
    assigned = {
        t.id: node.value
        for node in tree.body
        if isinstance(node, ast.Assign)
        for t in node.targets
        if isinstance(t, ast.Name)
    }
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "attach" and len(node.args) == 2:
            table = node.args[1]
            table = assigned.get(table.id, table) if isinstance(table, ast.Name) else table
            return ast.literal_eval(table)
    return {}


def _provider(module: str, name: str) -> str:
    """The hexcal module that provides ``name`` of ``from module import name``: a submodule
    of that name, the submodule of the package's lazy map (followed through packages), or
    ``module`` itself."""
    sub = f"{module}.{name}"
    if _source(sub) is not None:
        return sub
    lazy = _lazy_names(module)
    if name in lazy:
        target = f"{module}.{lazy[name]}"
        return _provider(target, name) if (SRC.parent / target.replace(".", "/")).is_dir() else target
    return module


def _dependencies(imp: Import) -> set[str]:
    """The hexcal modules an import depends on."""
    if not imp.module.startswith("hexcal"):
        return set()
    if not imp.names:
        return {imp.module}
    return {_provider(imp.module, n) for n in imp.names}


def _hexcal_layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "hexcal":
        return None
    return parts[1] if len(parts) > 1 else "__init__"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_lower_layers_never_import_higher_ones(path: Path) -> None:
    own = LAYERS[_layer(path)]
    bad = [
        f"{imp.module} at {imp.where()}"
        for imp in _imports(path)
        if (layer := _hexcal_layer(imp.module)) is not None and LAYERS[layer] > own
    ]
    assert not bad, f"{path.relative_to(SRC)} ({_layer(path)}) imports {'; '.join(bad)}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_no_private_name_is_imported_across_modules(path: Path) -> None:
    for imp in _imports(path):
        if imp.module.startswith("hexcal"):
            private = [n for n in imp.names if n.startswith("_")]
            assert not private, (
                f"{path.relative_to(SRC)} imports private {private} from {imp.module} at {imp.where()}"
            )


def test_only_the_figure_modules_import_matplotlib() -> None:
    users = [
        str(p.relative_to(SRC))
        for p in _modules()
        if any(imp.module.split(".")[0] == "matplotlib" for imp in _imports(p))
    ]
    assert users and all(u.startswith("report/figures") for u in users), users


def test_every_subpackage_says_what_it_holds() -> None:
    for package in sorted(p for p in SRC.iterdir() if (p / "__init__.py").exists()):
        doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text(encoding="utf-8")))
        assert doc and "import" in doc.lower(), f"{package.name}: the docstring must say what it may import"


def _import_graph() -> dict[str, dict[str, Import]]:
    """Each module's dependencies on other hexcal modules, with the import that makes each."""
    graph: dict[str, dict[str, Import]] = {}
    for path in _modules():
        name = _module_name(path)
        edges = graph.setdefault(name, {})
        for imp in _imports(path):
            for dep in _dependencies(imp):
                if dep != name and (dep not in edges or edges[dep].in_function):
                    edges[dep] = imp  # a module-level import of a dependency is the one reported
    return graph


def _cycles(graph: dict[str, dict[str, Import]]) -> list[tuple[list[str], list[str]]]:
    """The import cycles: each strongly connected set of modules (Tarjan's algorithm) and one
    closed path through it."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def connect(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for dep in graph.get(node, {}):
            if dep not in graph:
                continue
            if dep not in index:
                connect(dep)
                low[node] = min(low[node], low[dep])
            elif dep in on_stack:
                low[node] = min(low[node], index[dep])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            connect(node)
    out = []
    for component in components:  # a closed path inside the component, from its first module
        members, path = set(component), [component[0]]
        while True:
            nxt = next(d for d in sorted(graph[path[-1]]) if d in members)
            if nxt in path:
                out.append((component, path[path.index(nxt) :] + [nxt]))
                break
            path.append(nxt)
    return out


def test_no_import_cycle_between_modules() -> None:
    graph = _import_graph()
    lines = []
    for members, cycle in _cycles(graph):
        steps = [f"{a} ({graph[a][b].where()})" for a, b in itertools.pairwise(cycle)]
        more = (
            f" [in a cycle of {len(members)}: {', '.join(members)}]" if len(members) > len(cycle) - 1 else ""
        )
        lines.append(" -> ".join([*steps, cycle[-1]]) + more)
    assert not lines, "import cycle(s):\n" + "\n".join(lines)


def test_the_checks_see_imports_inside_functions() -> None:
    """The import walk finds deferred imports and resolves lazy package names (a self-check of
    this module's machinery on a known case)."""
    found = {imp.module: imp for imp in _imports(SRC / "simulation" / "instrument_trials.py")}
    assert found["hexcal.calibration"].in_function
    assert _dependencies(found["hexcal.calibration"]) == {"hexcal.calibration.identify"}
    assert _provider("hexcal", "estimate") == "hexcal.calibration.identify"
    edge = found["hexcal.calibration"]
    assert _cycles({"a": {"b": edge}, "b": {"a": edge}, "c": {"a": edge}}) == [(["a", "b"], ["a", "b", "a"])]


def test_the_command_line_starts_without_numpy() -> None:
    code = "import sys; from hexcal.cli import main; import hexcal; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
