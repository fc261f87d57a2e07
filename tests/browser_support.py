"""Headless Chromium for the HTML report tests (Playwright driving the system's browser).

Playwright's own browser download cannot be used here, so the tests drive the operating
system's Chromium (Debian's ``chromium`` package, ``/usr/bin/chromium``). Without it, or
without the ``playwright`` Python package, the browser tests are skipped with a message
saying how to install them: never silently.

Every page is opened from ``file://`` with all other requests blocked and recorded, and
with the console errors and uncaught exceptions collected, so a test can assert that a
report is self-contained and runs cleanly.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

INSTALL_HINT = (
    "browser tests need Chromium and Playwright: apt-get install chromium && "
    "pip install playwright (or: make test, which installs them via .ci/run)"
)

#: Where screenshots of the rendered reports are kept (a test artefact; not in git).
ARTIFACTS = Path(
    os.environ.get("HEXCAL_ARTIFACTS", Path(__file__).resolve().parents[1] / "build" / "test-artifacts")
)

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def chromium_path() -> str | None:
    """The system Chromium, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@dataclass
class OpenedPage:
    """A page opened from disk, with what it asked for and what went wrong."""

    page: Any
    console_errors: list[str] = field(default_factory=list)
    page_errors: list[str] = field(default_factory=list)
    blocked: list[str] = field(default_factory=list)


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """A headless Chromium (session-wide), or skip with the install hint."""
    exe = chromium_path()
    if exe is None:
        pytest.skip(f"no Chromium on this machine; {INSTALL_HINT}")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip(f"the playwright package is missing; {INSTALL_HINT}")
    with sync_playwright() as pw:
        instance = pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        try:
            yield instance
        finally:
            instance.close()


def open_report(browser: Any, path: Path, width: int = 1366, height: int = 900) -> OpenedPage:
    """Open ``path`` from disk in a fresh context with every non-file request blocked."""
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    opened = OpenedPage(page)

    def route(request_route: Any) -> None:
        url = request_route.request.url
        if url.startswith("file://"):
            request_route.continue_()
        else:
            opened.blocked.append(url)
            request_route.abort()

    page.route("**/*", route)
    page.on("console", lambda msg: opened.console_errors.append(msg.text) if msg.type == "error" else None)
    page.on("pageerror", lambda exc: opened.page_errors.append(str(exc)))
    page.goto(path.resolve().as_uri(), wait_until="load")
    return opened


def screenshot(opened: OpenedPage, name: str) -> Path:
    """Save a full-page screenshot as a test artefact and return its path."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    target = ARTIFACTS / f"{name}.png"
    opened.page.screenshot(path=str(target), full_page=True)
    return target
