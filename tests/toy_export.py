"""A toy controller export, written the way a user of hexcal would add one: one module, one
registration (:data:`TOY_EXPORT`, registered by :func:`registered`).

The toy controller reads one file, ``toy-kins.cfg``: a line ``joint N base X Y Z platform X Y Z
l0 L gain G`` per leg (mm), numbers only. It cannot model a leg that is not linear, so it refuses
such a geometry in one line rather than drop its terms.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from hexcal.core.geometry import Geometry
from hexcal.errors import InputError, UsageError
from hexcal.io import EXPORTS, ControllerExport, Exported, register_export, unregister_export

TOY_FILE = "toy-kins.cfg"


def toy_export(geometry: Geometry, *, source: str = "(in memory)", **provenance: Any) -> Exported:
    """The toy controller's file of ``geometry``."""
    if geometry.leg_model.terms:
        raise InputError(
            f"{source}: the toy controller's struts are linear; the {geometry.leg_model.name} legs are not"
        )
    rows = [
        " ".join(
            [
                f"joint {n}",
                "base",
                *(repr(float(v)) for v in geometry.base_joints[n]),
                "platform",
                *(repr(float(v)) for v in geometry.platform_joints[n]),
                "l0",
                repr(float(geometry.initial_leg_lengths[n])),
                "gain",
                repr(float(geometry.leg_gains[n])),
            ]
        )
        for n in range(6)
    ]
    return Exported({TOY_FILE: "\n".join(rows) + "\n"}, [f"load {TOY_FILE} in the toy controller"])


TOY_EXPORT = ControllerExport("toyctl", "the toy controller", (TOY_FILE,), toy_export)


@contextmanager
def registered() -> Iterator[None]:
    """The toy export registered (one call), then removed again."""
    if TOY_EXPORT.name in EXPORTS:
        raise UsageError("the toy export's name is taken")
    register_export(TOY_EXPORT)
    try:
        yield
    finally:
        unregister_export(TOY_EXPORT.name)
