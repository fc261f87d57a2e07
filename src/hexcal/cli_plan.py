"""Planning subcommands of ``hexcal`` (observability, error maps, pose selection)."""

from __future__ import annotations

import argparse
from typing import Any


def register(sub: Any, geometry_help: str) -> None:
    """Add the planning subcommands to the ``hexcal`` parser's subparsers."""
    del sub, geometry_help  # filled in by the observability work (issue 4)


def _unused(args: argparse.Namespace) -> None:  # pragma: no cover
    del args
