"""Shell examples that run during the docs build, and the check that no example escapes.

``{hexcal-run}`` is a fenced directive whose body is a bash script. The build runs it with
``bash -e -o pipefail`` in a scratch folder of its page (one folder per page, made afresh, so a
later block sees the files of an earlier one), with the build's own ``hexcal`` first on
``PATH`` and ``$HEXCAL_JUGGLEBOT`` naming the test data's real sessions. The page shows the
script, then what it printed. A non-zero exit, a time-out or an expected text missing from
the output is a warning, and ``-W`` fails the build. Options (MyST's ``:key: value`` lines):

``:hide:``
    run, show nothing (a preamble that makes the files the next blocks need);
``:output: none``
    show the script only;
``:show: REGEX``
    show only the output lines that match (a gap becomes ``...``);
``:max-lines: N``
    show at most N lines of output (default 40), then say how many more;
``:expect: TEXT``
    each line of TEXT must occur in the output (spaces normalised): the figures the page's
    prose states are checked against the run, each to the digits the page states (a stated
    ``0.0582`` matches a printed ``0.05823`` or ``0.0583``: one unit in its last digit, the
    rounding a page's figure carries; machines of one kind differ in a float's last bits,
    which a converged iteration can carry into the fourth digit). Several lines need MyST's
    YAML option block (``---`` / ``expect: |`` / the lines indented / ``---``).

A shell or Python example that does not run is a template for the user's own files and says
so: a ``{code-block}`` with ``:class: template`` (and a caption naming it a template).
:func:`unrun_examples` finds any other (a plain ````` ```sh ````` block, a bare block that
starts with a ``hexcal`` command or a Python import); the build warns on each, and
``tests/test_docs_site.py`` checks every page with it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, ClassVar

from docutils import nodes
from docutils.parsers.rst import directives
from hexcal_examples import unrun_examples
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

LOGGER = logging.getLogger(__name__)

#: Seconds one block may run.
TIMEOUT = 300


def _check_page(app: Any, docname: str, source: list[str]) -> None:
    for line in unrun_examples(source[0]):
        LOGGER.warning(
            "a shell or Python example that does not run: make it a {hexcal-run} block or a "
            "{code-block} with :class: template",
            location=(docname, line), type="hexcal", subtype="example",
        )


def _scratch(env: Any) -> Path:
    """The page's scratch folder (made at its first block, kept for its later ones)."""
    if "hexcal_run_dir" not in env.temp_data:
        prefix = f"hexcal-docs-{env.docname.replace('/', '-')}-"
        env.temp_data["hexcal_run_dir"] = tempfile.mkdtemp(prefix=prefix)
    return Path(env.temp_data["hexcal_run_dir"])


def _environment(srcdir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env.setdefault("HEXCAL_JUGGLEBOT", str(srcdir.parent / "tests" / "data" / "jugglebot"))
    env["MPLBACKEND"] = "Agg"
    env["COLUMNS"] = "100"
    return env


def _shown(output: str, show: str | None, max_lines: int) -> str:
    lines = output.rstrip("\n").splitlines()
    if show:
        pattern = re.compile(show)
        kept: list[str] = []
        for line in lines:
            if pattern.search(line):
                kept.append(line)
            elif kept and kept[-1] != "...":
                kept.append("...")
        lines = kept[:-1] if kept and kept[-1] == "..." else kept
    if len(lines) > max_lines:
        lines = [*lines[:max_lines], f"... ({len(lines) - max_lines} more lines)"]
    return "\n".join(lines)


def _squash(text: str) -> str:
    return " ".join(text.split())


#: A number as the pages state them (sign, digits, a decimal point, an exponent).
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _unit(stated: str) -> float:
    """One unit in the last digit of a stated number (``0.0582`` -> 1e-4, ``12`` -> 1)."""
    mantissa, _, exponent = stated.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 10.0 ** (int(exponent or 0) - decimals)


def contains_figures(output: str, wanted: str) -> bool:
    """Whether ``output`` holds ``wanted`` (spaces normalised), its numbers each within one unit
    of their last stated digit and its text as it is.

    >>> contains_figures("position RMS 0.05823 mm", "RMS 0.0582 mm")
    True
    >>> contains_figures("position RMS 0.0565 mm", "RMS 0.0582 mm")
    False
    """
    text, wanted = _squash(output), _squash(wanted)
    numbers = _NUMBER.findall(wanted)
    parts = _NUMBER.split(wanted)
    group = "(" + _NUMBER.pattern + ")"
    pieces = [re.escape(p) + (group if k < len(numbers) else "") for k, p in enumerate(parts)]
    pattern = re.compile("".join(pieces))
    for match in pattern.finditer(text):
        found = zip(match.groups(), numbers, strict=True)
        if all(abs(float(got) - float(n)) <= _unit(n) * (1 + 1e-9) for got, n in found):
            return True
    # the regular expression takes the leftmost match of each start: try every start
    return any(
        contains_figures(text[start + 1 :], wanted) for start in (m.start() for m in pattern.finditer(text))
    )


class HexcalRun(SphinxDirective):
    """The ``{hexcal-run}`` directive (see the module docstring)."""

    has_content = True
    option_spec: ClassVar[dict[str, Any]] = {
        "hide": directives.flag,
        "output": directives.unchanged,
        "show": directives.unchanged,
        "max-lines": directives.nonnegative_int,
        "expect": directives.unchanged,
    }

    def run(self) -> list[nodes.Node]:
        script = "\n".join(self.content)
        where = (self.env.docname, self.lineno)
        try:
            done = subprocess.run(
                ["bash", "-e", "-o", "pipefail", "-c", script], cwd=_scratch(self.env),
                env=_environment(Path(self.env.srcdir)), stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, text=True, timeout=TIMEOUT, check=False,
            )
            output, code = done.stdout, done.returncode
        except subprocess.TimeoutExpired as exc:
            output, code = str(exc.stdout or ""), f"no exit within {TIMEOUT} s"
        if code != 0:
            LOGGER.warning("the example failed (exit %s):\n%s", code, output[-3000:],
                           location=where, type="hexcal", subtype="run")
        for wanted in filter(None, (w.strip() for w in self.options.get("expect", "").splitlines())):
            if not contains_figures(output, wanted):
                LOGGER.warning("the example's output does not contain %r (the page states it)", wanted,
                               location=where, type="hexcal", subtype="expect")
        if "hide" in self.options:
            return []
        shown = [nodes.literal_block(script, script, language="bash", classes=["hexcal-run"])]
        text = _shown(output, self.options.get("show"), self.options.get("max-lines", 40))
        if self.options.get("output") != "none" and text:
            shown.append(nodes.literal_block(text, text, language="text", classes=["hexcal-output"]))
        return shown


def setup(app: Any) -> dict[str, Any]:
    app.add_directive("hexcal-run", HexcalRun)
    app.connect("source-read", _check_page)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
