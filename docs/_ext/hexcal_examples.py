"""Which examples of a docs page run and which are templates: plain text, no docutils.

The build's runner (``hexcal_run``) and ``tests/test_docs_site.py`` (which runs without the
docs dependencies) both use it: a shell or Python example must be a block the build runs
(``{hexcal-run}``, ``{code-cell}``) or a ``{code-block}`` marked ``:class: template``.
"""

from __future__ import annotations

import re

#: Languages of examples that must run or be marked as templates.
SHELL = {"sh", "bash", "console", "shell", "shell-session", "zsh", "sh-session"}
PYTHON = {"python", "py", "python3", "ipython", "ipython3", "pycon"}
#: Directives whose body the build runs.
RUN = {"{hexcal-run}", "{code-cell}"}
#: Directives that show code.
CODE = {"{code-block}", "{code}", "{sourcecode}"}

_FENCE = re.compile(r"^(\s*)(`{3,}|~{3,}|:{3,})\s*(\S*)\s*(\S*)")
_COMMAND = re.compile(r"^\s*(\$ |hexcal |python3? -|pip |make |import |from \S+ import |>>> )")


def _blocks(text: str) -> list[tuple[int, str, str, list[str]]]:
    """``(line, directive or language, language, body lines)`` of every top-level fence."""
    lines = text.splitlines()
    out = []
    k = 0
    while k < len(lines):
        m = _FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        fence, first, second = m.group(2), m.group(3), m.group(4)
        closing = re.compile(rf"^\s*{re.escape(fence[0])}{{{len(fence)},}}\s*$")
        end = k + 1
        while end < len(lines) and not closing.match(lines[end]):
            end += 1
        out.append((k + 1, first, second, lines[k + 1 : end]))
        k = end + 1
    return out


def _options(body: list[str]) -> dict[str, str]:
    """A directive's ``:key: value`` lines (MyST's short option form) at the top of its body."""
    opts = {}
    for line in body:
        m = re.match(r"^:([\w-]+):\s*(.*)$", line.strip())
        if not m:
            break
        opts[m.group(1)] = m.group(2)
    return opts


def classify(text: str) -> list[tuple[int, str]]:
    """``(line, kind)`` of every example of a page: ``run``, ``template`` or ``unmarked``.

    Data blocks (YAML, CSV, tables, printed output) are no examples and are not listed.
    """
    kinds = []
    for line, first, second, body in _blocks(text):
        if first in RUN:
            kinds.append((line, "run"))
        elif first in CODE:
            if second.lower() in SHELL | PYTHON:
                classes = _options(body).get("class", "").split()
                kinds.append((line, "template" if "template" in classes else "unmarked"))
        elif first.startswith("{"):
            continue  # another directive (toctree, eval-rst, a note)
        elif first.lower() in SHELL | PYTHON:
            kinds.append((line, "unmarked"))
        elif not first and body and _COMMAND.match(next((b for b in body if b.strip()), "")):
            kinds.append((line, "unmarked"))
    return kinds


def unrun_examples(text: str) -> list[int]:
    """Lines of the shell or Python examples of a page that neither run nor are templates."""
    return [line for line, kind in classify(text) if kind == "unmarked"]
