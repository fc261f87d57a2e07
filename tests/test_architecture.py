"""The architecture as the folder tree shows it, checked on the source (issue 8).

Layers, lowest first: ``errors`` and ``_lazy`` (anyone may import them), ``core``,
``instruments``, ``estimation``, ``design``, ``simulation``, ``report``, then ``io`` and ``cli``
(the edges). A module may import its own layer and lower ones, never a higher one; no
module imports a private (underscore) name of another module; modules stay small; only the
figure module imports matplotlib; numpy and scipy stay out of the command line's start-up.
"""

from __future__ import annotations

import ast
import subprocess
import sys
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
    "cli": 9,
    "__init__": 10,
    "__main__": 10,
}

#: "No module over about 400 lines" (issue 8); a margin for docstrings.
MAX_LINES = 450


def _modules() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def _layer(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0].removesuffix(".py") if len(rel.parts) > 1 else rel.stem


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """``(module, imported names)`` of every ``import`` and ``from ... import`` in a file."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append((node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
    return out


def _hexcal_layer(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] != "hexcal":
        return None
    return parts[1] if len(parts) > 1 else "__init__"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_lower_layers_never_import_higher_ones(path: Path) -> None:
    own = LAYERS[_layer(path)]
    for module, _ in _imports(path):
        layer = _hexcal_layer(module)
        if layer is None:
            continue
        assert LAYERS[layer] <= own, f"{path.relative_to(SRC)} ({_layer(path)}) imports {module}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_no_private_name_is_imported_across_modules(path: Path) -> None:
    for module, names in _imports(path):
        if module.startswith("hexcal"):
            private = [n for n in names if n.startswith("_")]
            assert not private, f"{path.relative_to(SRC)} imports private {private} from {module}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(SRC)))
def test_modules_stay_small(path: Path) -> None:
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{path.relative_to(SRC)} has {lines} lines"


def test_only_the_figure_modules_import_matplotlib() -> None:
    users = [
        str(p.relative_to(SRC))
        for p in _modules()
        if any(m.split(".")[0] == "matplotlib" for m, _ in _imports(p))
    ]
    assert users and all(u.startswith("report/figures") for u in users), users


def test_every_subpackage_says_what_it_holds() -> None:
    for package in sorted(p for p in SRC.iterdir() if (p / "__init__.py").exists()):
        doc = ast.get_docstring(ast.parse((package / "__init__.py").read_text(encoding="utf-8")))
        assert doc and "import" in doc.lower(), f"{package.name}: the docstring must say what it may import"


def test_no_import_cycle_between_modules() -> None:
    graph: dict[str, set[str]] = {}
    for path in _modules():
        rel = path.relative_to(SRC).with_suffix("")
        name = ".".join(("hexcal", *rel.parts)).removesuffix(".__init__")
        graph[name] = set()
        for node in ast.parse(path.read_text(encoding="utf-8")).body:  # module level only
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hexcal"):
                # ``from package import submodule`` depends on the submodule, not the package
                subs = [f"{node.module}.{a.name}" for a in node.names]
                found = [s for s in subs if (SRC.parent / s.replace(".", "/")).with_suffix(".py").exists()]
                graph[name] |= set(found) if len(found) == len(subs) else {node.module}
            elif isinstance(node, ast.Import):
                graph[name] |= {a.name for a in node.names if a.name.startswith("hexcal")}
    seen: dict[str, int] = {}

    def visit(node: str, stack: list[str]) -> None:
        seen[node] = 1
        for dep in graph.get(node, ()):
            if dep not in graph:
                continue
            assert seen.get(dep) != 1, f"import cycle: {' -> '.join([*stack, node, dep])}"
            if dep not in seen:
                visit(dep, [*stack, node])
        seen[node] = 2

    for node in graph:
        if node not in seen:
            visit(node, [])


def test_the_command_line_starts_without_numpy() -> None:
    code = "import sys; from hexcal.cli import main; import hexcal; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
