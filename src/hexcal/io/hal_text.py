"""Text that LinuxCNC parses or executes: numbers and one-line safe comments.

LinuxCNC executes a HAL file (``halcmd`` runs every line: ``loadusr`` starts programs) and
reads an INI file, so nothing from an input reaches one except as a number (:data:`NUMBER`)
or inside a one-line comment (:func:`comment_line`): characters that are not printable (line
breaks, other control and format characters, Unicode line separators) are written as
``\\xNN`` / ``\\uNNNN`` escapes, a comment never ends in a backslash (``halcmd`` and
LinuxCNC's INI reader both continue such a line onto the next, comments included) and stays
under :data:`MAX_LINE_BYTES`. Shared by the files :mod:`hexcal.io.linuxcnc` and
:mod:`hexcal.io.linuxcnc_thermal` write.
"""

from __future__ import annotations

import re

from hexcal.core.text import printable as _printable

#: A number as C's ``strtod`` reads it (no hex, inf or nan): the only values written.
NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")

#: Longest comment line written, in bytes (UTF-8). LinuxCNC's INI reader reads a line of
#: 255 bytes or more in pieces, each parsed as a line of its own (measured with LinuxCNC
#: 2.9's ``inivar``: ``#`` and 254 characters, then ``K = 1`` on the same line, sets ``K``);
#: ``halcmd`` refuses a line of about 1000 bytes.
MAX_LINE_BYTES = 200

#: Characters of one input value (a name, a path, a calibration field) in a comment.
MAX_VALUE_CHARS = 80


def printable(value: object, most: int = MAX_VALUE_CHARS) -> str:
    """``str(value)`` one line and printable (:func:`hexcal.core.text.printable`), cut to ``most``.

    >>> printable("m1\\nloadusr -w touch x")
    'm1\\\\x0aloadusr -w touch x'
    """
    return _printable(value, most)


def comment_line(text: str) -> str:
    """``# text`` as one safe comment line of a HAL or INI file (see the module's notes).

    >>> comment_line("name a\\\\")
    '# name a\\\\x5c'
    """
    line = "# " + printable(text, most=MAX_LINE_BYTES)
    if line.endswith("\\"):  # halcmd and the INI reader would join the next line to it
        line = line[:-1] + "\\x5c"
    while len(line.encode("utf-8")) > MAX_LINE_BYTES:  # printable non-ASCII: several bytes each
        line = line[:-4] + "..."
    return line


def comment_ok(line: str) -> bool:
    """Whether ``line`` is a comment as :func:`comment_line` writes it (one safe line)."""
    return (
        line.startswith("#")
        and line.isprintable()
        and not line.endswith("\\")
        and len(line.encode("utf-8")) <= MAX_LINE_BYTES
    )
