"""Text from an input made safe for a file another program reads: one line, printable.

Every writer of a file that another program reads (CSV comments, HAL and INI comments, G-code
comments, HTML pages, figure titles) passes text that came from an input (a geometry's name,
a file name, an id) through :func:`printable`: line breaks, tabs, other control and format
characters and the Unicode line and paragraph separators (U+2028, U+2029, U+0085) become
visible escapes, so that no input can start a line, a key or a command of its own.
"""

from __future__ import annotations


def printable(value: object, most: int | None = None) -> str:
    """``str(value)`` with every character that is not printable escaped, cut to ``most``.

    Line breaks, tabs, other control and format characters and the Unicode line and
    paragraph separators become ``\\xNN``, ``\\uNNNN`` or ``\\UNNNNNNNN``; printable
    characters (accents included) stay as they are.

    Parameters
    ----------
    value : object
        The text (or anything with a ``str``).
    most : int, optional
        The longest result; a longer one is cut and ends in ``...``.

    Returns
    -------
    str
        One line of printable characters.

    >>> printable("m1\\nloadusr -w touch x")
    'm1\\\\x0aloadusr -w touch x'
    >>> printable("x" * 100, most=10)
    'xxxxxxx...'
    """
    text = str(value)
    if not text.isprintable():
        out = []
        for ch in text:
            code = ord(ch)
            if ch.isprintable():
                out.append(ch)
            elif code < 0x100:
                out.append(f"\\x{code:02x}")
            elif code < 0x10000:
                out.append(f"\\u{code:04x}")
            else:
                out.append(f"\\U{code:08x}")
        text = "".join(out)
    return text if most is None or len(text) <= most else text[: max(0, most - 3)] + "..."


def printable_lines(value: object) -> str:
    """``str(value)`` with its line breaks (``\\n``) kept and every other character that is not
    printable escaped as in :func:`printable` (a report's text block, a figure's title).

    >>> printable_lines("a\\nb\\u2028c")
    'a\\nb\\\\u2028c'
    """
    text = str(value)
    if text.isprintable():
        return text
    return "\n".join(printable(line) for line in text.split("\n"))
