"""CSV table builders: each returns ``(columns, rows, ids, comment)`` for
:func:`hexcal.io.write_table` (``rows`` an array of shape (n, len(columns)); ``ids`` None
for tables without an id column). Imports numpy.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: A CSV table: columns, rows (n, k), ids (or None) and the comment line.
Table = tuple[list[str], NDArray[np.float64], list[str] | None, str]

#: Numeric columns of ``study.csv``.
STUDY_COLUMNS = ["poses", "error_mean", "error_std", "bound", "efficiency", "position_rms", "orientation_rms"]

#: Columns of the pose of the error-map tables.
POSE_COLUMNS = ["x", "y", "z", "a", "b", "c"]


def study_table(rows: Sequence[dict[str, Any]]) -> Table:
    """``study.csv`` of the ``StudyCell.row()`` dictionaries of a study.

    >>> row = {"strategy": "corners", "poses": 15, "noise": "x1", "method": "ml", "error_mean": 0.3,
    ...        "error_std": 0.1, "bound": 0.25, "efficiency": 1.2, "position_rms": 0.01,
    ...        "orientation_rms": 2e-6}
    >>> columns, values, ids, comment = study_table([row])
    >>> values.shape, ids
    ((1, 7), ['corners/x1/ml'])
    """
    values = np.array([[r[k] for k in STUDY_COLUMNS] for r in rows], dtype=float)
    ids = [f"{r['strategy']}/{r['noise']}/{r['method']}" for r in rows]
    return list(STUDY_COLUMNS), values, ids, "id: strategy/noise/method; mm and rad"


def validation_table(validation: Any, nominal: Any | None = None, ids: Sequence[str] | None = None) -> Table:
    """Per-observation validation table (``hexcal validate --out``): leg residual RMS, position and
    orientation error of the platform pose, and the instrument's own errors, for the calibrated
    geometry and, when validated, the nominal one (``nominal_`` columns); empty cells where the
    instrument gives no value.

    ``validation`` is a validation's one dictionary (:func:`hexcal.report.validation_report_dict`),
    or the calibrated machine's :class:`hexcal.calibration.ValidationResult` (then ``nominal``
    the nominal one's, or None; ``ids`` are the result's own).
    """
    if isinstance(validation, Mapping):
        per_pose = validation["per_pose"]
    else:
        from hexcal.report.convert import validation_per_pose

        per_pose = validation_per_pose(validation, nominal)
    ids = list(per_pose["ids"]) if ids is None else list(ids)
    labels = per_pose.get("value_labels") or []
    columns, table = [], []
    for prefix, res in (("", per_pose["calibrated"]), ("nominal_", per_pose.get("nominal"))):
        if res is None:
            continue
        columns += [f"{prefix}leg_rms", f"{prefix}position_error", f"{prefix}orientation_error"]
        table += [_floats(res[k]) for k in ("leg_rms", "position_error", "orientation_error")]
        for name, values in res["instrument_errors"].items():
            values = _floats(values).reshape(len(ids), -1)
            if values.shape[1] == 1:  # the instrument's own (a tool's position beside the platform's)
                columns.append(f"{prefix}instrument_{name}_error")
                table.append(values[:, 0])
            else:
                own = labels if len(labels) == values.shape[1] else None
                columns += [
                    f"{prefix}{own[k] if own else f'{name}{k + 1}'}_error" for k in range(values.shape[1])
                ]
                table += list(values.T)
    comment = "per-pose validation: mm and rad; leg_rms is the RMS of the six leg residuals; empty: no value"
    return columns, np.column_stack(table), ids, comment


def _floats(values: Any) -> NDArray[np.float64]:
    """Values of a dictionary (None where the JSON has null) as floats (NaN)."""
    return np.array(values, dtype=float)


def errormap_tables(maps: Any) -> dict[str, Table]:
    """The CSV tables of error maps (:class:`hexcal.design.ErrorMaps`) by table name
    (``x``, ``y``, ``z``, the angle pairs, ``corners``, ``interior``): file
    ``errormap_<name>.csv``."""
    tables: dict[str, Table] = {}
    for axis, line in maps.lines.items():
        stats = line.to_dict()  # the mean and sd over the draws, from the library
        rows = np.column_stack(
            [
                line.poses.reshape(-1, 6),
                np.repeat(line.levels, line.values.size),
                *(
                    np.asarray(stats[key], dtype=float).ravel()
                    for key in (
                        "position_mean_mm",
                        "position_sd_mm",
                        "orientation_mean_rad",
                        "orientation_sd_rad",
                    )
                ),
            ]
        )
        columns = [
            *POSE_COLUMNS,
            f"level_{line.level_axis}",
            "position_mm",
            "position_sd_mm",
            "orientation_rad",
            "orientation_sd_rad",
        ]
        comment = (
            f"pose error along {axis}, mean and sd over {maps.draws} draws of parameter errors "
            f"uniform in ±{maps.amplitude:g} mm ({maps.method}); angles in rad"
        )
        tables[axis] = (columns, rows, None, comment)
    for name, grid in maps.angles.items():
        rows = np.column_stack([grid.poses.reshape(-1, 6), grid.position.ravel(), grid.orientation.ravel()])
        comment = f"mean pose error over {name} at every z level, {maps.draws} parameter draws; rad"
        tables[name] = ([*POSE_COLUMNS, "position_mm", "orientation_rad"], rows, None, comment)
    for name, ref in (("corners", maps.corners), ("interior", maps.interior)):
        rows = np.column_stack([ref["poses"], ref["position"], ref["orientation"]])
        comment = f"mean pose error at the {name} reference poses, {maps.draws} parameter draws; rad"
        tables[name] = ([*POSE_COLUMNS, "position_mm", "orientation_rad"], rows, None, comment)
    return tables
