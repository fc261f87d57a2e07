"""hexcal's own Sphinx glue: the user guide's page list and references to existing objects.

- ``index.md`` holds the marker ``%GUIDE_PAGES%`` inside its user-guide toctree (and
  ``%TUTORIAL_PAGES%`` in the tutorials', likewise for ``docs/tutorials/*.md``): it is
  replaced by the guide pages in the order of :data:`GUIDE_ORDER`, then every other
  ``docs/*.md`` page that no other toctree of the start page names, alphabetically. A page
  added to ``docs/`` therefore joins the user guide (one click from the start page) with no
  edit here.
- A Python cross-reference that Sphinx cannot resolve (an internal module or a numpy type
  without a page of its own, a short name in a docstring) is looked up in the code: if the
  object exists it is shown as code, without a link; if it exists nowhere the warning stays,
  and ``-W`` fails the build.
"""

from __future__ import annotations

import builtins
import importlib
import pkgutil
import re
from functools import cache
from pathlib import Path
from typing import Any

#: The user guide's pages in reading order (a missing one is skipped).
GUIDE_ORDER = (
    "commands",
    "formats",
    "columns",
    "instruments",
    "sessions",
    "planning",
    "observability",
    "identification",
    "leg-models",
    "validation",
    "reports",
    "compensation",
    "simulation",
    "clusters",
    "python",
    "input-safety",
    "architecture",
    "development",
)

#: Top-level pages that belong to another toctree of the start page.
ELSEWHERE = {"index", "getting-started", "theory", "api", "changelog"}

MARKER = "%GUIDE_PAGES%"

#: The tutorials in reading order; any other ``docs/tutorials/*.md`` follows, alphabetically.
TUTORIAL_ORDER = ("paper", "tracker-linuxcnc", "jugglebot", "monte-carlo")
TUTORIAL_MARKER = "%TUTORIAL_PAGES%"


#: Folders of docs/ whose pages are listed elsewhere (or are no pages).
OWN_FOLDERS = {"api", "tutorials", "_build", "_ext", "_static", "_templates"}


def guide_pages(docs: Path) -> list[str]:
    """The user guide's page names: :data:`GUIDE_ORDER` first, then any other page of docs/
    (top level first, then pages in sub-folders other than :data:`OWN_FOLDERS`)."""
    present = {p.stem for p in docs.glob("*.md")} - ELSEWHERE - {"README"}
    ordered = [name for name in GUIDE_ORDER if name in present]
    nested = sorted(
        p.relative_to(docs).with_suffix("").as_posix()
        for p in docs.glob("*/**/*.md")
        if p.relative_to(docs).parts[0] not in OWN_FOLDERS and not p.name.startswith(".")
    )
    return ordered + sorted(present - set(ordered)) + nested


def tutorial_pages(docs: Path) -> list[str]:
    """The tutorials' page names (``tutorials/...``): :data:`TUTORIAL_ORDER`, then any other."""
    present = {p.stem for p in (docs / "tutorials").glob("*.md")} - {"README"}
    ordered = [name for name in TUTORIAL_ORDER if name in present]
    return [f"tutorials/{name}" for name in ordered + sorted(present - set(ordered))]


def _fill_guide(app: Any, docname: str, source: list[str]) -> None:
    if docname == "index":
        docs = Path(app.srcdir)
        source[0] = source[0].replace(MARKER, "\n".join(guide_pages(docs)))
        source[0] = source[0].replace(TUTORIAL_MARKER, "\n".join(tutorial_pages(docs)))


@cache
def _hexcal_modules() -> tuple[Any, ...]:
    import hexcal

    modules = [hexcal]
    for info in pkgutil.walk_packages(hexcal.__path__, "hexcal."):
        if info.name == "hexcal.__main__":  # importing it runs the command
            continue
        try:
            modules.append(importlib.import_module(info.name))
        except Exception:
            continue
    return tuple(modules)


def _lookup(path: str) -> bool:
    """Whether the dotted ``path`` names an existing module or attribute."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:cut]))
        except Exception:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return hasattr(builtins, path) or _numpy_has(path)


def _numpy_has(path: str) -> bool:
    """``ndarray``, ``np.float64``, ``NDArray``: numpy's names as docstrings write them."""
    import numpy
    import numpy.typing

    name = path.removeprefix("np.").removeprefix("numpy.")
    return hasattr(numpy, name) or hasattr(numpy.typing, name)


@cache
def exists(target: str, module: str | None, cls: str | None) -> bool:
    """Whether ``target`` (as written in a reference, in its module and class) exists."""
    target = target.lstrip(".~")
    candidates = [target]
    if module:
        candidates += [f"{module}.{cls}.{target}" if cls else "", f"{module}.{target}"]
    if any(c and _lookup(c) for c in candidates):
        return True
    head, _, rest = target.partition(".")
    for mod in _hexcal_modules():  # a short name from a docstring of another module
        obj = getattr(mod, head, None)
        if obj is not None and (not rest or _lookup(f"{getattr(obj, '__module__', '')}.{target}")
                                or _has(obj, rest)):
            return True
    return False


def _has(obj: Any, rest: str) -> bool:
    for attr in rest.split("."):
        if not hasattr(obj, attr):
            return False
        obj = getattr(obj, attr)
    return True


#: Words of numpydoc type descriptions ("ndarray, shape (n, 6), optional") that are no names.
TYPE_WORDS = {"optional", "array_like", "array-like", "sequence", "shape", "callable", "default",
              "of", "or", "mapping", "iterable", "scalar", "path-like", "file-like", "int-like"}


def _type_text(target: str) -> bool:
    """A piece of a parameter's type description, not a Python name: shown as it is."""
    return target in TYPE_WORDS or not all(part.isidentifier() for part in target.split("."))


def _missing_reference(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"]
    if node.get("reftype") in ("class", "obj") and _type_text(target):
        return contnode
    if exists(target, node.get("py:module"), node.get("py:class")):
        return contnode
    return None


def _inline_attribute_types(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    """Napoleon's ``:vartype x: ndarray, shape (n, 6)`` into the ``:ivar x:`` line as text.

    A type description is prose ("shape (n, 6)"); as a field of its own each word would be a
    cross-reference (``n`` is a name of several classes).
    """
    types = {}
    kept = []
    for line in lines:
        if line.startswith(":vartype "):
            field, _, text = line[len(":vartype "):].partition(":")
            types[field.strip()] = text.strip()
        else:
            kept.append(line)
    for k, line in enumerate(kept):
        if line.startswith(":ivar "):
            field, _, text = line[len(":ivar "):].partition(":")
            if types.get(field.strip()):
                kept[k] = f":ivar {field.strip()}: (*{types[field.strip()]}*) {text.strip()}"
    lines[:] = kept


_FORWARD_REF = re.compile(r"TypeAliasForwardRef\('(?:[\w.]+\.)?(\w+)'\)")


def _alias_names(app: Any, what: str, name: str, obj: Any, options: Any, signature: str | None,
                 return_annotation: str | None) -> tuple[str | None, str | None]:
    """``NDArray | None`` as written: autodoc shows a bare alias in a union as its forward
    reference object, ``TypeAliasForwardRef('numpy.typing.NDArray')``."""
    def fix(text: str | None) -> str | None:
        return _FORWARD_REF.sub(r"\1", text) if text else text

    return fix(signature), fix(return_annotation)


def setup(app: Any) -> dict[str, Any]:
    app.connect("autodoc-process-signature", _alias_names)
    app.connect("autodoc-process-docstring", _inline_attribute_types, priority=600)
    from pygments.lexers.special import TextLexer

    app.add_lexer("csv", TextLexer)  # tables shown as they are (Pygments has no CSV lexer)
    app.connect("source-read", _fill_guide)
    app.connect("missing-reference", _missing_reference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
