"""The renderer registry: ``render(kind, data, fmt)`` for every result kind and format.

:data:`RENDERERS` maps ``(kind, fmt)`` to a function of the result's plain dictionary
(and keyword options) that returns a string. Formats are ``text``, ``json``
(strict: NaN written as ``null``) and ``html`` (self-contained pages, whose modules, with
their figures, are imported only when a page is rendered). Figures, which write files, are
in :mod:`hexcal.report.figures`. Standard library only at import.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

from hexcal.report import iso_summary, plan, text
from hexcal.report.jsonout import json_text

#: ``(kind, fmt)`` -> renderer of the kind's dictionary.
RENDERERS: dict[tuple[str, str], Callable[..., str]] = {}


def register(kind: str, fmt: str, renderer: Callable[..., str]) -> None:
    """Add (or replace) the renderer of ``kind`` results in format ``fmt``."""
    RENDERERS[(kind, fmt)] = renderer


def _json(data: Any, **_options: Any) -> str:
    return json_text(data)


def _select_json(data: dict[str, Any], **_options: Any) -> str:
    return json_text(plan.select_json(data))


#: The kinds of results and their text renderers.
TEXT_RENDERERS: dict[str, Callable[..., str]] = {
    "identification": text.identification_text,
    "validation": text.validation_text,
    "paper": text.paper_text,
    "study": text.study_text,
    "observability": plan.observability_text,
    "select": plan.select_text,
    "claims": plan.claims_text,
    "iso": iso_summary.iso_text,
}

for _kind, _renderer in TEXT_RENDERERS.items():
    register(_kind, "text", _renderer)
    register(_kind, "json", _select_json if _kind == "select" else _json)


def page(spec: str) -> Callable[..., str]:
    """The renderer ``"module:function"`` of :mod:`hexcal.report`, imported when first called
    (a page's module draws figures: matplotlib is not loaded for a text report)."""
    module, _, name = spec.partition(":")

    def renderer(data: Any, **options: Any) -> str:
        return getattr(importlib.import_module(f"hexcal.report.{module}"), name)(data, **options)

    renderer.__name__ = name
    renderer.__doc__ = f"The page of :func:`hexcal.report.{module}.{name}`."
    return renderer


#: HTML pages (self-contained, figures inline): their dictionaries carry figures and inputs.
HTML_PAGES = {
    "identification": "calibration_pages:identification_page",
    "validation": "validation_pages:validation_page",
    "paper": "html:tables_page",
    "study": "html:tables_page",
    "observability": "html:tables_page",
    "select": "html:tables_page",
    "tables": "html:tables_page",
    "iso": "validation_pages:iso_page",
}

for _kind, _spec in HTML_PAGES.items():
    register(_kind, "html", page(_spec))


def formats(kind: str | None = None) -> list[tuple[str, str]]:
    """The registered ``(kind, fmt)`` pairs, of one kind or of all.

    >>> ("paper", "json") in formats("paper")
    True
    """
    return sorted(key for key in RENDERERS if kind is None or key[0] == kind)


def render(kind: str, data: Any, fmt: str = "text", **options: Any) -> str:
    """Render the plain dictionary ``data`` of a ``kind`` result in format ``fmt``.

    Raises ``KeyError`` naming the registered formats when there is no such renderer.

    >>> s = dict(poses=3, leg_rms=0.01, leg_max=0.02, position_rms=0.1, position_max=0.2,
    ...          orientation_rms=1e-5, orientation_max=2e-5)
    >>> print(render("validation", {"calibrated": s, "nominal": None}).splitlines()[0])
    Validation on 3 held-out pose(s)
    >>> print(render("study", [], "json"), end="")
    []
    """
    try:
        renderer = RENDERERS[(kind, fmt)]
    except KeyError:
        known = ", ".join(f"{k}/{f}" for k, f in sorted(RENDERERS))
        raise KeyError(f"no renderer for {kind!r} as {fmt!r}; registered: {known}") from None
    return renderer(data, **options)


def render_html(report: Mapping[str, Any]) -> str:
    """The HTML page of a report mapping (one of the ``*_report`` functions): its ``kind``
    picks the page (a page of tables and figures for the studies and the planning)."""
    return render(report.get("kind", "tables"), report, "html")
