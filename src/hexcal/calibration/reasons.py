"""A finding of the verdict (:class:`Reason`) and the verdict itself (:class:`Verdict`).

Kept apart from :mod:`hexcal.calibration.verdict` so that the modules that find reasons
(:mod:`~hexcal.calibration.diagnosis`, :mod:`~hexcal.calibration.accuracy_reasons`) and the one that
judges (:mod:`~hexcal.calibration.verdict`) share the types without importing each other.

>>> Verdict((Reason("a", "info", "fine"), Reason("b", "warn", "look"))).status
'warn'
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

SEVERITIES = ("info", "warn", "fail")


@dataclass(frozen=True)
class Reason:
    """One finding: ``code`` (stable, for programs), ``severity`` (info|warn|fail), ``message``."""

    code: str
    severity: str
    message: str
    data: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"code": self.code, "severity": self.severity, "message": self.message}
        if self.data:
            out["data"] = self.data
        return out


@dataclass(frozen=True)
class Verdict:
    """``status`` (pass|warn|fail) and the reasons; ``accuracy`` the predicted pose accuracy."""

    reasons: tuple[Reason, ...]
    accuracy: dict[str, float] | None = None

    @property
    def status(self) -> str:
        worst = max((SEVERITIES.index(r.severity) for r in self.reasons), default=0)
        return ("pass", "warn", "fail")[worst]

    @property
    def failed(self) -> bool:
        """True when the calibrated geometry should not be written (without ``--force``)."""
        return self.status == "fail"

    def codes(self, severity: str | None = None) -> tuple[str, ...]:
        return tuple(r.code for r in self.reasons if severity is None or r.severity == severity)

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.status,
            "reasons": [r.to_dict() for r in self.reasons],
            "accuracy": self.accuracy,
        }
