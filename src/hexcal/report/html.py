"""The HTML page: one self-contained file that opens from disk with no network.

Everything is inline: the styles, a few lines of script (sortable tables), and the figures
as SVG text (drawn by :mod:`hexcal.report.figures`). This module holds what every page is
made of: escaping, numbers, sections, the verdict block, tables, the figure grid, the
inputs that make a report traceable, the page shell, a page of tables and figures, and
the check of the ``--html`` target. The pages of the commands (built from the same
``to_dict()`` dictionaries the text and JSON reports use) are in
:mod:`hexcal.report.calibration_pages`, :mod:`hexcal.report.study_pages` and
:mod:`hexcal.report.planning_pages`. Readable on a laptop screen and printable (a print
style sheet drops the interactive parts). Standard library only.

>>> page = html_page("Demo", [section("Numbers", key_value_table({"poses": 15}))])
>>> page.startswith("<!DOCTYPE html>") and "poses" in page and "http" not in page
True
"""

from __future__ import annotations

import html
import math
import re
import shlex
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from hexcal.core.text import printable_lines

_STYLE = """
:root { --fg: #1d232a; --muted: #5b6570; --line: #d7dce1; --pass: #1a7f37; --warn: #9a6700;
        --fail: #cf222e; --bg-alt: #f6f8fa; }
* { box-sizing: border-box; }
body { font: 15px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg);
       margin: 0 auto; max-width: 1180px; padding: 1.2rem 1.5rem 3rem; }
h1 { font-size: 1.55rem; margin: 0 0 .2rem; }
h2 { font-size: 1.15rem; margin: 1.8rem 0 .6rem; border-bottom: 1px solid var(--line);
     padding-bottom: .2rem; }
.subtitle { color: var(--muted); margin: 0 0 1rem; }
.verdict { display: flex; gap: 1rem; align-items: baseline; padding: .8rem 1rem; border-radius: 8px;
           border: 2px solid var(--line); margin: .8rem 0 .4rem; }
.verdict .word { font-size: 1.6rem; font-weight: 700; text-transform: uppercase; letter-spacing: .04em; }
.verdict.pass { border-color: var(--pass); } .verdict.pass .word { color: var(--pass); }
.verdict.warn { border-color: var(--warn); } .verdict.warn .word { color: var(--warn); }
.verdict.fail { border-color: var(--fail); } .verdict.fail .word { color: var(--fail); }
.reasons { margin: .3rem 0 0 0; padding-left: 1.2rem; }
.reasons li.fail { color: var(--fail); } .reasons li.warn { color: var(--warn); }
table { border-collapse: collapse; font-variant-numeric: tabular-nums; margin: .3rem 0 1rem; }
th, td { padding: .22rem .6rem; border-bottom: 1px solid var(--line); text-align: right; }
th:first-child, td:first-child, th.text, td.text { text-align: left; }
th { background: var(--bg-alt); position: sticky; top: 0; }
table.sortable th { cursor: pointer; user-select: none; }
table.sortable th[aria-sort="ascending"]::after { content: " \\25B2"; font-size: .7em; }
table.sortable th[aria-sort="descending"]::after { content: " \\25BC"; font-size: .7em; }
.scroll { max-height: 32rem; overflow: auto; border: 1px solid var(--line); border-radius: 6px; }
.figures { display: grid; grid-template-columns: repeat(auto-fit, minmax(520px, 1fr)); gap: 1rem; }
figure { margin: 0; border: 1px solid var(--line); border-radius: 6px; padding: .5rem; background: #fff; }
figure.wide { grid-column: 1 / -1; }
figure.square svg { max-width: 980px; margin: 0 auto; }
table.kv td:last-child { text-align: left; overflow-wrap: anywhere; }
figure svg { width: 100%; height: auto; display: block; }
figcaption { color: var(--muted); font-size: .88rem; margin-top: .3rem; }
code, .mono { font-family: ui-monospace, "SFMono-Regular", Menlo, monospace; font-size: .9em; }
.muted { color: var(--muted); }
@media print {
  body { max-width: none; padding: 0; font-size: 11pt; }
  .scroll { max-height: none; overflow: visible; border: 0; }
  .figures { display: block; } figure { break-inside: avoid; margin-bottom: 1rem; }
  table.sortable th { cursor: auto; } table.sortable th::after { content: "" !important; }
}
"""

# Sort a table by a clicked column: numbers by data-value (missing last), text otherwise.
_SCRIPT = """
document.querySelectorAll("table.sortable").forEach(function (table) {
  table.querySelectorAll("th").forEach(function (th, col) {
    th.addEventListener("click", function () {
      var asc = th.getAttribute("aria-sort") !== "ascending";
      table.querySelectorAll("th").forEach(function (h) { h.removeAttribute("aria-sort"); });
      th.setAttribute("aria-sort", asc ? "ascending" : "descending");
      var body = table.tBodies[0];
      var rows = Array.prototype.slice.call(body.rows);
      rows.sort(function (a, b) {
        var x = a.cells[col].dataset.value, y = b.cells[col].dataset.value;
        if (x !== undefined && y !== undefined) {
          var fx = parseFloat(x), fy = parseFloat(y);
          if (isNaN(fx)) return 1; if (isNaN(fy)) return -1;
          return asc ? fx - fy : fy - fx;
        }
        x = a.cells[col].textContent; y = b.cells[col].textContent;
        return asc ? x.localeCompare(y) : y.localeCompare(x);
      });
      rows.forEach(function (r) { body.appendChild(r); });
    });
  });
});
"""


def esc(value: Any) -> str:
    """HTML-escaped text of a value."""
    return html.escape(printable_lines(value), quote=True)


def number(value: Any, digits: int = 6) -> str:
    """A number for a table cell (``-`` for missing or non-finite values)."""
    if value is None:
        return "-"
    try:
        v = float(value)
    except (TypeError, ValueError):
        return esc(value)
    if not math.isfinite(v):
        return "-"
    return f"{v:.{digits}g}"


def html_page(title: str, sections: Sequence[str], subtitle: str = "") -> str:
    """A complete, self-contained HTML document."""
    sub = f'<p class="subtitle">{esc(subtitle)}</p>' if subtitle else ""
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{esc(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
        f"<h1>{esc(title)}</h1>\n{sub}\n"
        + "\n".join(sections)
        + f"\n<script>{_SCRIPT}</script>\n</body>\n</html>\n"
    )


def section(title: str, body: str, anchor: str = "") -> str:
    """A titled section of a page."""
    ident = f' id="{esc(anchor)}"' if anchor else ""
    return f"<section{ident}>\n<h2>{esc(title)}</h2>\n{body}\n</section>"


#: The order of the verdict's reasons on a page: failures first, then warnings, then info.
SEVERITY_ORDER = {"fail": 0, "warn": 1, "info": 2}


def verdict_block(verdict: str | None, reasons: Iterable[Mapping[str, Any] | str] = ()) -> str:
    """The verdict in one line (``pass``, ``warn``, ``fail``) with its reasons, the most
    serious first (failures, warnings, then information; each kind in its given order)."""
    word = (verdict or "none").lower()
    listed = []
    for reason in reasons:
        if isinstance(reason, Mapping):
            severity = str(reason.get("severity", "info")).lower()
            text = reason.get("message", "")
        else:
            severity, text = "info", reason
        listed.append((severity, text))
    listed.sort(key=lambda item: SEVERITY_ORDER.get(item[0], len(SEVERITY_ORDER)))
    items = [
        f'<li class="{esc(severity)}" data-severity="{esc(severity)}">{esc(text)}</li>'
        for severity, text in listed
    ]
    listing = f'<ul class="reasons">{"".join(items)}</ul>' if items else ""
    return (
        f'<div class="verdict {esc(word)}" data-verdict="{esc(word)}"><span class="word">{esc(word)}</span>'
        f"<div>{listing or '<span class=muted>no reasons given</span>'}</div></div>"
    )


def key_value_table(rows: Mapping[str, Any], digits: int = 6) -> str:
    """A two-column table of labelled values."""
    cells = "".join(
        f"<tr><td>{esc(k)}</td><td>{number(v, digits) if _numeric(v) else esc(v)}</td></tr>"
        for k, v in rows.items()
    )
    return f'<table class="kv"><tbody>{cells}</tbody></table>'


_TEXT = ' class="text"'


class Rounded(float):
    """A number shown as its ``text`` (a value to the precision of its standard error), sorted
    by its value."""

    text: str

    def __new__(cls, value: float, text: str) -> Rounded:
        out = super().__new__(cls, value)
        out.text = text
        return out


#: Significant digits of a standard error, and so the last digit shown of its value.
ERROR_DIGITS = 2


def to_precision(value: Any, stderr: Any) -> Any:
    """``value`` rounded to the last digit of its standard error's :data:`ERROR_DIGITS`
    significant digits (a :class:`Rounded`); ``value`` itself without a finite positive error.

    >>> to_precision(305.401234567, 0.0123).text, to_precision(-0.00046, 0.0123).text
    ('305.401', '-0.000')
    >>> to_precision(12.7, 35.0).text, to_precision(2.0, None)
    ('13', 2.0)
    """
    try:
        v, e = float(value), float(stderr)
    except (TypeError, ValueError):
        return value
    if not (math.isfinite(v) and math.isfinite(e) and e > 0):
        return value
    decimals = min(max(ERROR_DIGITS - 1 - math.floor(math.log10(e)), 0), 15)
    return Rounded(v, f"{v:.{decimals}f}")


def _numeric(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def data_table(
    columns: Sequence[str],
    rows: Sequence[Sequence[Any]],
    sortable: bool = True,
    digits: int = 6,
    table_id: str = "",
    scroll: bool = False,
) -> str:
    """A table of rows; numeric cells carry their value for sorting, columns of text are
    aligned left (numbers right)."""
    text = [
        not any(_numeric(row[k]) for row in rows if k < len(row)) and any(k < len(row) for row in rows)
        for k in range(len(columns))
    ]
    head = "".join(
        f'<th scope="col"{_TEXT if k < len(text) and text[k] else ""}>{esc(c)}</th>'
        for k, c in enumerate(columns)
    )
    body = []
    for row in rows:
        cells = []
        for k, value in enumerate(row):
            if _numeric(value):
                v = float(value)
                data = repr(v) if math.isfinite(v) else "NaN"
                shown = esc(value.text) if isinstance(value, Rounded) else number(v, digits)
                cells.append(f'<td data-value="{data}">{shown}</td>')
            else:
                align = _TEXT if k < len(text) and text[k] else ""
                cells.append(f"<td{align}>{'-' if value is None else esc(value)}</td>")
        body.append(f"<tr>{''.join(cells)}</tr>")
    ident = f' id="{esc(table_id)}"' if table_id else ""
    kind = ' class="sortable"' if sortable else ""
    table = f"<table{ident}{kind}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    return f'<div class="scroll">{table}</div>' if scroll else table


def figure_grid(
    figures: Mapping[str, str], captions: Mapping[str, str] | None = None, wide: Iterable[str] = ()
) -> str:
    """Inline SVG figures side by side (each ``name -> svg text``); wide figures, and those
    named in ``wide``, span the row (a square one centred, at most 980 px)."""
    captions = captions or {}
    wide = set(wide)
    items = []
    for k, (name, svg) in enumerate(figures.items()):
        cap = captions.get(name, "")
        caption = f"<figcaption>{esc(cap)}</figcaption>" if cap else ""
        body = _unique_ids(_strip_xml_header(svg), f"f{k}-")
        width, aspect = _size(body)
        classes = []
        if name in wide or (width > 640 and aspect > 1.6):
            classes.append("wide")
            if aspect < 1.4:
                classes.append("square")
        kind = f' class="{" ".join(classes)}"' if classes else ""
        items.append(f'<figure data-figure="{esc(name)}"{kind}>{body}{caption}</figure>')
    return f'<div class="figures">{"".join(items)}</div>'


def _size(svg: str) -> tuple[float, float]:
    """Width (pt) and width over height of an SVG (0, 0 if unknown): wide figures, which
    would be unreadable at half the page, span the whole row of the grid."""
    size = re.search(r'<svg[^>]*?\bwidth="([\d.]+)[a-z]*"[^>]*?\bheight="([\d.]+)', svg)
    if size is None or float(size.group(2)) == 0:
        return 0.0, 0.0
    return float(size.group(1)), float(size.group(1)) / float(size.group(2))


def _unique_ids(svg: str, prefix: str) -> str:
    """Prefix every id of an inline SVG and the references to them: several SVGs on one page
    share one id space, and a clip path defined twice would clip the second figure away."""
    ids = set(re.findall(r'\bid="([^"]+)"', svg))
    if not ids:
        return svg
    pattern = re.compile(
        r'(\bid="|#)(' + "|".join(re.escape(i) for i in sorted(ids, key=len, reverse=True)) + r")\b"
    )
    return pattern.sub(lambda m: f"{m.group(1)}{prefix}{m.group(2)}", svg)


def _strip_xml_header(svg: str) -> str:
    start = svg.find("<svg")
    return svg[start:] if start >= 0 else svg


#: Options a command records for its own machinery (the output set, the executor), not
#: the user's: left out of a page's inputs.
INTERNAL_OPTIONS = frozenset({"func", "command", "inputs", "outputs", "folders", "executor"})


def user_options(options: Mapping[str, Any]) -> dict[str, Any]:
    """The options a user chose, without the command's internals: no output-set bookkeeping,
    no empty values, and no ``noise_dist`` where no noise was given (the noise was learned).

    >>> user_options({"folders": (), "outputs": ("out",), "noise_dist": "uniform", "fit": "joints"})
    {'fit': 'joints'}
    """
    out = {
        k: v
        for k, v in options.items()
        if k not in INTERNAL_OPTIONS and v not in (None, False, "", (), []) and not callable(v)
    }
    if "noise" not in out:
        out.pop("noise_dist", None)
    return out


def option_text(name: str, value: Any) -> str:
    """An option as typed: ``--fit joints,l0``, ``--force``, ``--data a.csv --data b.csv``.

    >>> option_text("max_change", 0.25), option_text("force", True), option_text("data", ["a", "b c"])
    ('--max-change 0.25', '--force', "--data a --data 'b c'")
    """
    flag = "--" + name.replace("_", "-")
    if value is True:
        return flag
    values = value if isinstance(value, list | tuple) else [value]
    return " ".join(f"{flag} {shlex.quote(str(v))}" for v in values)


def inputs_table(inputs: Mapping[str, Any]) -> str:
    """The inputs that make a report traceable: files with their SHA-256, the command and the
    options a user chose (as typed, defaults included; internals left out), version, date."""
    parts = []
    files = inputs.get("files", [])
    if files:
        rows = [(f.get("role", ""), f.get("path", ""), f.get("sha256", "")) for f in files]
        parts.append(data_table(("input", "file", "SHA-256"), rows, sortable=False))
    rest: dict[str, Any] = {}
    for key, value in inputs.items():
        if key == "files":
            continue
        if key == "options" and isinstance(value, Mapping):
            chosen = user_options(value)
            rest["options (defaults included)"] = (
                " ".join(option_text(k, v) for k, v in chosen.items()) if chosen else "none"
            )
        else:
            rest[key] = _plain_text(value)
    if rest:
        parts.append(key_value_table(rest))
    return "\n".join(parts)


def _plain_text(value: Any) -> Any:
    if isinstance(value, Mapping):
        return ", ".join(f"{k}={_plain_text(v)}" for k, v in value.items())
    if isinstance(value, list | tuple):
        return " ".join(str(v) for v in value)
    return value


def tables_page(report: Mapping[str, Any]) -> str:
    """A page of tables and figures (``hexcal paper``, ``simulate``, ``select``,
    ``observability``).

    ``report["tables"]`` maps a title to ``{"columns": [...], "rows": [[...], ...]}`` (and
    an optional ``"note"``, text below the table, and ``"sortable": False`` for a table of
    labelled values); an optional ``report["text"]`` is shown
    preformatted (the command's text table, folded); the figures come after the tables, or
    first with ``report["figures_first"]``; ``report["wide"]`` names figures that span the row.
    """
    sections = []
    for title, table in report.get("tables", {}).items():
        sortable = table.get("sortable", True)
        body = data_table(
            table["columns"],
            table["rows"],
            sortable=sortable,
            table_id=slug(title),
            scroll=len(table["rows"]) > 20,
        )
        extra = f'<p class="muted">{esc(table["note"])}</p>' if table.get("note") else ""
        hint = '<p class="muted">Click a column to sort.</p>' if sortable and len(table["rows"]) > 3 else ""
        sections.append(section(title, body + extra + hint, f"{slug(title)}-section"))
    figures = report.get("figures", {})
    if figures:
        grid = figure_grid(figures, report.get("captions", {}), report.get("wide", ()))
        at = 0 if report.get("figures_first") else len(sections)
        sections.insert(at, section("Figures", grid, "figures"))
    if report.get("text"):
        printed = (
            "<details><summary>the command's text output</summary>"
            f'<pre class="mono">{esc(report["text"])}</pre></details>'
        )
        sections.append(section("As printed", printed, "text"))
    sections.append(section("Inputs", inputs_table(report.get("inputs", {})), "inputs"))
    return html_page(report.get("title", "hexcal report"), sections, report.get("subtitle", ""))


def slug(text: str) -> str:
    """An id for an HTML element from a title.

    >>> slug("Table I: mean error (mm)")
    'table-i-mean-error-mm'
    """
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def check_html_target(html: str, inputs: Iterable[Any] = (), outputs: Iterable[Any] = ()) -> None:
    """Refuse, before any work, an ``--html`` file that is also an input or another output.

    Raises
    ------
    ValueError
        When ``html`` names the same file as one of ``inputs`` or ``outputs`` (None skipped).
    """
    target = Path(html).resolve()
    for role, paths in (("an input", inputs), ("another output", outputs)):
        for path in paths:
            if path is not None and Path(path).resolve() == target:
                raise ValueError(f"--html {html}: is also {role} ({path})")
