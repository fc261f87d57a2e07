"""Every benchmark script imports on the current code (its ``main`` not run).

The benchmarks are not part of the test run, so an API change that breaks one went unseen
until someone ran it (``benchmarks/tracker.py`` imported a module the restructuring had
removed). Importing each file catches such drift in its imports and module-level code; what
a benchmark calls inside ``main`` is checked only by running it (``benchmarks/README.md``).
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(BENCHMARKS.glob("*.py"))


def test_the_benchmarks_are_found():
    # the parametrised test below would pass vacuously on an empty glob
    names = {p.name for p in SCRIPTS}
    assert {"run.py", "tracker.py", "batched.py", "scale.py", "scipy_baseline.py", "latency.py"} <= names


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_benchmark_imports(path, monkeypatch):
    # the scripts pin BLAS threads in os.environ and extend sys.path at import: undo both
    # afterwards so the rest of the session (and its subprocesses) is unaffected
    monkeypatch.setattr(os, "environ", os.environ.copy())
    monkeypatch.setattr(sys, "path", list(sys.path))
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # siblings import each other (scale -> batched)
    siblings = {p.stem for p in SCRIPTS}
    before = {name for name in sys.modules if name in siblings}
    name = f"benchmark_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while it executes
    try:
        spec.loader.exec_module(module)  # the module's code, not its `if __name__ == "__main__"`
    finally:
        sys.modules.pop(name, None)
        for sibling in siblings - before:
            sys.modules.pop(sibling, None)
    assert callable(getattr(module, "main", None)), f"{path.name} has no main()"
