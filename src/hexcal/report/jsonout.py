"""Strict JSON of result dictionaries: NaN and infinities are written as ``null``.

Python's :mod:`json` writes the invalid tokens ``NaN`` and ``Infinity`` by default; every
JSON file hexcal writes goes through :func:`json_text` instead. Standard library only.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any


def strict(data: Any) -> Any:
    """``data`` with every non-finite float replaced by None (mappings and sequences walked).

    >>> strict({"a": float("nan"), "b": [1.0, float("inf")], "c": "x"})
    {'a': None, 'b': [1.0, None], 'c': 'x'}
    """
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, Mapping):
        return {key: strict(value) for key, value in data.items()}
    if isinstance(data, list | tuple):
        return [strict(value) for value in data]
    return data


def json_text(data: Any) -> str:
    """Strict JSON of ``data``, indented by 2, with a final newline.

    >>> print(json_text({"error": float("nan"), "poses": 15}), end="")
    {
      "error": null,
      "poses": 15
    }
    """
    return json.dumps(strict(data), indent=2, allow_nan=False) + "\n"
